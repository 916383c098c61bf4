//! Runtime control of a `heml.System` between steps: gravity, fixed nodes, moved node
//! groups, soft grasps, rigid tools with their haptic wrench, cuts, and laws. Each call
//! checks its input first; on error it raises `HemlError` and leaves the system
//! unchanged (the Rust library's guarantee). Grasps and tools are named by the
//! integers these calls return.

use heml::system::contact::{ContactLaw, Tool, ToolId};
use heml::system::control::{GraspId, Pose};
use heml::system::cut::{Blade, CutReport};
use heml::Vec3;
use numpy::PyArray1;
use pyo3::exceptions::{PyKeyError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays;
use crate::errors::{HemlError, IntoPyResult};
use crate::system::System;

/// A pose from a translation and a rotation vector (axis × angle, rad), either
/// omitted: no translation, no rotation. Non-finite values, and a rotation vector
/// too long to make a rotation of, raise `HemlError` showing them as given.
fn pose(translation: Option<&Bound<'_, PyAny>>, rotation: Option<&Bound<'_, PyAny>>) -> PyResult<Pose> {
    let t = match translation {
        Some(t) => arrays::vec3(t, "translation")?,
        None => Vec3::zeros(),
    };
    let r = match rotation {
        Some(r) => arrays::vec3(r, "rotation")?,
        None => Vec3::zeros(),
    };
    if !t.iter().all(|c| c.is_finite()) {
        return Err(HemlError::new_err(format!(
            "translation {:?} is not finite",
            t.as_slice()
        )));
    }
    if !r.iter().all(|c| c.is_finite()) {
        return Err(HemlError::new_err(format!(
            "rotation {:?} (axis × angle, rad) is not finite",
            r.as_slice()
        )));
    }
    Pose::new(t, r).map_err(|_| {
        HemlError::new_err(format!(
            "rotation {:?} (axis × angle, rad) makes no finite rotation: its angle is too large \
             (reduce it modulo 2π)",
            r.as_slice()
        ))
    })
}

fn report<'py>(py: Python<'py>, r: &CutReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item(
        "removed_tets",
        PyArray1::from_slice(py, &r.removed_tets.iter().map(|&t| t as i64).collect::<Vec<_>>()),
    )?;
    d.set_item("removed_mass", r.removed_mass)?;
    d.set_item(
        "orphaned_nodes",
        PyArray1::from_slice(py, &r.orphaned_nodes.iter().map(|&i| i as i64).collect::<Vec<_>>()),
    )?;
    d.set_item("remaining_tets", r.remaining_tets)?;
    Ok(d)
}

/// The grasp `id` of `sys` (`ValueError` for a negative id, `KeyError` for an
/// unknown one).
fn grasp_id(sys: &heml::prelude::System, id: i64) -> PyResult<GraspId> {
    let id = arrays::non_negative("grasp", id)?;
    sys.grasp_ids()
        .into_iter()
        .find(|g| g.index() == id)
        .ok_or_else(|| PyKeyError::new_err(format!("no grasp {id} in this system (released or never made)")))
}

/// The tool `id` of `sys` (`ValueError` for a negative id, `KeyError` for an
/// unknown one).
fn tool_id(sys: &heml::prelude::System, id: i64) -> PyResult<ToolId> {
    let id = arrays::non_negative("tool", id)?;
    sys.tools()
        .ids()
        .find(|t| t.index() as u64 == id)
        .ok_or_else(|| PyKeyError::new_err(format!("no tool {id} in this system (removed or never added)")))
}

impl System {
    /// A node set for a runtime-control call (ids or a boolean mask; an id listed
    /// twice is a `HemlError`, see `arrays::id_set`).
    fn node_set(&self, nodes: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<usize>> {
        let n = self.lock()?.mesh().n_nodes();
        arrays::id_set(nodes, what, n, "node")
    }
}

#[pymethods]
impl System {
    /// Sets gravity (m/s², 3 numbers) from the next step on.
    fn set_gravity(&self, g: &Bound<'_, PyAny>) -> PyResult<()> {
        let g = arrays::vec3(g, "gravity")?;
        self.lock()?.set_gravity(g).py()
    }

    /// Holds nodes (ids, each once, or a boolean mask) at their rest positions: they
    /// go back there at once, with zero velocity; prescribed nodes among them become
    /// fixed.
    fn fix_nodes(&self, nodes: &Bound<'_, PyAny>) -> PyResult<()> {
        let ids = self.node_set(nodes, "fix_nodes")?;
        self.lock()?.fix_nodes(&ids).py()
    }

    /// Frees fixed or prescribed nodes (ids, each once, or a boolean mask).
    fn release_nodes(&self, nodes: &Bound<'_, PyAny>) -> PyResult<()> {
        let ids = self.node_set(nodes, "release_nodes")?;
        self.lock()?.release_nodes(&ids).py()
    }

    /// Moves a node group rigidly from its rest positions to the pose
    /// (translation, rotation vector: axis × angle, rad) and holds it there.
    #[pyo3(signature = (nodes, translation, rotation = None))]
    fn prescribe_pose(
        &self,
        nodes: &Bound<'_, PyAny>,
        translation: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let ids = self.node_set(nodes, "prescribe_pose")?;
        let p = pose(Some(translation), rotation)?;
        self.lock()?.prescribe_pose(&ids, &p).py()
    }

    /// Ties `nodes` by springs of `stiffness` (N/m per node) and dampers of
    /// `damping` (N·s/m per node) to where they are now. The pose (`translation`,
    /// `rotation` vector: axis × angle, rad; either may be given alone, neither is
    /// the identity) is the grasp's initial target T0, the frame of the later
    /// `move_grasp` targets: moving the target to T moves the grasped nodes rigidly
    /// by T·T0⁻¹ (so a tool's world pose can be passed as it is). Returns the
    /// grasp's id.
    #[pyo3(signature = (nodes, stiffness, damping = 0.0, translation = None, rotation = None))]
    fn grasp(
        &self,
        nodes: &Bound<'_, PyAny>,
        stiffness: f64,
        damping: f64,
        translation: Option<&Bound<'_, PyAny>>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let ids = self.node_set(nodes, "grasp")?;
        let p = pose(translation, rotation)?;
        Ok(self.lock()?.grasp(&ids, p, stiffness, damping).py()?.index())
    }

    /// Moves a grasp's target to the pose T (translation, rotation vector): the
    /// grasped nodes are pulled towards their grasp-time positions moved by T·T0⁻¹,
    /// T0 the pose given to `grasp` (identity by default: T is then the motion).
    #[pyo3(signature = (grasp, translation, rotation = None))]
    fn move_grasp(
        &self,
        grasp: i64,
        translation: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let p = pose(Some(translation), rotation)?;
        let mut sys = self.lock()?;
        let id = grasp_id(&sys, grasp)?;
        sys.move_grasp(id, p).py()
    }

    /// Lets go of a grasp.
    fn release_grasp(&self, grasp: i64) -> PyResult<()> {
        let mut sys = self.lock()?;
        let id = grasp_id(&sys, grasp)?;
        sys.release_grasp(id).py()
    }

    /// The force (N, 3 numbers) the tissue applies to a grasp: what the hand feels.
    fn grasp_force(&self, grasp: i64) -> PyResult<[f64; 3]> {
        let sys = self.lock()?;
        let f = sys.grasp_force(grasp_id(&sys, grasp)?).py()?;
        Ok([f.x, f.y, f.z])
    }

    /// Adds a rigid tool: `shape` "sphere" (needs `radius`), "capsule" (needs
    /// `radius` and `half_length`, axis along the pose's local z) or "half_space"
    /// (local z ≤ 0 is solid; takes neither), touching the boundary surface through
    /// a penalty contact of `stiffness` (N/m per node) and `damping`, at the pose
    /// (`translation`, `rotation` vector: axis × angle, rad; either may be given
    /// alone, neither is the identity). A dimension the shape does not use is a
    /// `ValueError`. Returns its id.
    #[pyo3(signature = (shape, stiffness, radius = None, half_length = None, damping = 0.0, translation = None, rotation = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_tool(
        &self,
        shape: &str,
        stiffness: f64,
        radius: Option<f64>,
        half_length: Option<f64>,
        damping: f64,
        translation: Option<&Bound<'_, PyAny>>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<usize> {
        let law = ContactLaw { stiffness, damping };
        let needs = |name: &str, v: Option<f64>| {
            v.ok_or_else(|| PyValueError::new_err(format!("add_tool: a {shape} needs {name}")))
        };
        let unused = |name: &str, v: Option<f64>| match v {
            None => Ok(()),
            Some(v) => Err(PyValueError::new_err(format!(
                "add_tool: a {shape} has no {name} (got {name}={v}); omit it"
            ))),
        };
        let tool = match shape {
            "sphere" => {
                unused("half_length", half_length)?;
                Tool::sphere(needs("radius", radius)?, law)
            }
            "capsule" => Tool::capsule(needs("radius", radius)?, needs("half_length", half_length)?, law),
            "half_space" => {
                unused("radius", radius)?;
                unused("half_length", half_length)?;
                Tool::half_space(law)
            }
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown tool shape '{other}'; known: sphere, capsule, half_space"
                )))
            }
        };
        let p = pose(translation, rotation)?;
        Ok(self.lock()?.add_tool(tool.at(p)).py()?.index())
    }

    /// Places a tool (translation, rotation vector) for the next step: it moves
    /// there at constant speed during that step.
    #[pyo3(signature = (tool, translation, rotation = None))]
    fn set_tool_pose(
        &self,
        tool: i64,
        translation: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let p = pose(Some(translation), rotation)?;
        let mut sys = self.lock()?;
        let id = tool_id(&sys, tool)?;
        sys.set_tool_pose(id, p).py()
    }

    /// The force (N) and torque (N·m, about the tool's pose origin) the tissue
    /// applied to a tool at the last force evaluation: the haptic signal.
    fn tool_wrench(&self, tool: i64) -> PyResult<([f64; 3], [f64; 3])> {
        let sys = self.lock()?;
        let w = sys.tool_wrench(tool_id(&sys, tool)?).py()?;
        Ok(([w.force.x, w.force.y, w.force.z], [w.torque.x, w.torque.y, w.torque.z]))
    }

    /// Removes a tool.
    fn remove_tool(&self, tool: i64) -> PyResult<()> {
        let mut sys = self.lock()?;
        let id = tool_id(&sys, tool)?;
        sys.remove_tool(id).py().map(|_| ())
    }

    /// Removes the tets a blade meets at the current positions: a (3, 3) triangle, or
    /// a (4, 3) array a0, b0, a1, b1 (an edge a–b swept from a0–b0 to a1–b1).
    /// Returns removed_tets, removed_mass, orphaned_nodes, remaining_tets.
    fn cut<'py>(&self, py: Python<'py>, blade: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
        let p = arrays::points(blade, "blade", None)?;
        p.check_finite("blade")?;
        let p = p.as_slice();
        let blade = match p.len() {
            3 => Blade::Triangle([p[0], p[1], p[2]]),
            4 => Blade::Sweep {
                a0: p[0],
                b0: p[1],
                a1: p[2],
                b1: p[3],
            },
            n => {
                return Err(PyValueError::new_err(format!(
                    "blade: expected 3 points (a triangle) or 4 (a swept edge), got {n}"
                )))
            }
        };
        let r = self.lock()?.cut(&blade).py()?;
        report(py, &r)
    }

    /// Removes the given tets (ids, each once, or a boolean mask with one entry per
    /// tet); same report as `cut`.
    fn remove_tets<'py>(&self, py: Python<'py>, tets: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
        let n = self.lock()?.mesh().n_tets();
        let ids = arrays::id_set(tets, "tets", n, "tet")?;
        let r = self.lock()?.remove_tets(&ids).py()?;
        report(py, &r)
    }

    /// Replaces the law of a region (`region`: its mesh tag, as a key of the
    /// constructor's `regions`; `None`: the main material, the tets no tagged region
    /// claims), as the constructor takes it (a `heml.Material`, or a law name with
    /// `params`). The state, cuts, grasps, tools and viscous history stay; the stable
    /// step is estimated again.
    #[pyo3(signature = (material, params = None, *, region = None))]
    fn set_material(
        &self,
        material: &Bound<'_, PyAny>,
        params: Option<&Bound<'_, PyDict>>,
        region: Option<i32>,
    ) -> PyResult<()> {
        let law = crate::system::law_of(material, params)?;
        let mut sys = self.lock()?;
        let Some(r) = sys.regions().iter().position(|r| r.tag() == region) else {
            let tags: Vec<String> = sys
                .regions()
                .iter()
                .map(|r| r.tag().map_or("None".into(), |t| t.to_string()))
                .collect();
            return Err(PyKeyError::new_err(format!(
                "set_material: no region {} in this system (its regions: {})",
                region.map_or("None".into(), |t| t.to_string()),
                tags.join(", ")
            )));
        };
        sys.set_material(r, law).py()
    }

    /// Number of tets left by cuts.
    #[getter]
    fn n_tets(&self) -> PyResult<usize> {
        Ok(self.lock()?.n_tets_alive())
    }
}
