//! Runtime control of a `heml.System` between steps: gravity, fixed nodes, moved node
//! groups, soft grasps, rigid tools with their haptic wrench, and cuts. Each call
//! checks its input first; on error it raises `HemlError` and leaves the system
//! unchanged (the Rust library's guarantee). Grasps and tools are named by the
//! integers these calls return.

use heml::system::contact::{ContactLaw, Tool, ToolId};
use heml::system::control::{GraspId, Pose};
use heml::system::cut::{Blade, CutReport};
use numpy::PyArray1;
use pyo3::exceptions::{PyKeyError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays;
use crate::errors::IntoPyResult;
use crate::system::System;

/// A pose from a translation and an optional rotation vector (axis × angle, rad).
fn pose(translation: &Bound<'_, PyAny>, rotation: Option<&Bound<'_, PyAny>>) -> PyResult<Pose> {
    let t = arrays::vec3(translation, "translation")?;
    let r = match rotation {
        Some(r) => arrays::vec3(r, "rotation")?,
        None => heml::Vec3::zeros(),
    };
    Pose::new(t, r).py()
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

impl System {
    fn grasp_id(&self, id: u64) -> PyResult<GraspId> {
        self.sys
            .grasp_ids()
            .into_iter()
            .find(|g| g.index() == id)
            .ok_or_else(|| PyKeyError::new_err(format!("no grasp {id} in this system (released or never made)")))
    }

    fn tool_id(&self, id: usize) -> PyResult<ToolId> {
        self.sys
            .tools()
            .ids()
            .find(|t| t.index() == id)
            .ok_or_else(|| PyKeyError::new_err(format!("no tool {id} in this system (removed or never added)")))
    }
}

#[pymethods]
impl System {
    /// Sets gravity (m/s², 3 numbers) from the next step on.
    fn set_gravity(&mut self, g: &Bound<'_, PyAny>) -> PyResult<()> {
        let g = arrays::vec3(g, "gravity")?;
        self.sys.set_gravity(g).py()
    }

    /// Fixes nodes (ids or a boolean mask) where they are now.
    fn fix_nodes(&mut self, nodes: &Bound<'_, PyAny>) -> PyResult<()> {
        let ids = arrays::selection(nodes, "nodes", self.sys.mesh().n_nodes())?;
        self.sys.fix_nodes(&ids).py()
    }

    /// Frees fixed or prescribed nodes (ids or a boolean mask).
    fn release_nodes(&mut self, nodes: &Bound<'_, PyAny>) -> PyResult<()> {
        let ids = arrays::selection(nodes, "nodes", self.sys.mesh().n_nodes())?;
        self.sys.release_nodes(&ids).py()
    }

    /// Moves a node group rigidly from its rest positions to the pose
    /// (translation, rotation vector) and holds it there.
    #[pyo3(signature = (nodes, translation, rotation = None))]
    fn prescribe_pose(
        &mut self,
        nodes: &Bound<'_, PyAny>,
        translation: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let ids = arrays::selection(nodes, "nodes", self.sys.mesh().n_nodes())?;
        let p = pose(translation, rotation)?;
        self.sys.prescribe_pose(&ids, &p).py()
    }

    /// Ties `nodes` to a target pose (translation, rotation vector; identity: where
    /// they are now) by springs of `stiffness` (N/m per node) and dampers of
    /// `damping` (N·s/m per node). Returns the grasp's id.
    #[pyo3(signature = (nodes, stiffness, damping = 0.0, translation = None, rotation = None))]
    fn grasp(
        &mut self,
        nodes: &Bound<'_, PyAny>,
        stiffness: f64,
        damping: f64,
        translation: Option<&Bound<'_, PyAny>>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let ids = arrays::selection(nodes, "nodes", self.sys.mesh().n_nodes())?;
        let p = match translation {
            Some(t) => pose(t, rotation)?,
            None => Pose::identity(),
        };
        Ok(self.sys.grasp(&ids, p, stiffness, damping).py()?.index())
    }

    /// Moves a grasp's target to the pose (relative to where its nodes were grasped).
    #[pyo3(signature = (grasp, translation, rotation = None))]
    fn move_grasp(
        &mut self,
        grasp: u64,
        translation: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let id = self.grasp_id(grasp)?;
        let p = pose(translation, rotation)?;
        self.sys.move_grasp(id, p).py()
    }

    /// Lets go of a grasp.
    fn release_grasp(&mut self, grasp: u64) -> PyResult<()> {
        let id = self.grasp_id(grasp)?;
        self.sys.release_grasp(id).py()
    }

    /// The force (N, 3 numbers) the tissue applies to a grasp: what the hand feels.
    fn grasp_force(&self, grasp: u64) -> PyResult<[f64; 3]> {
        let f = self.sys.grasp_force(self.grasp_id(grasp)?).py()?;
        Ok([f.x, f.y, f.z])
    }

    /// Adds a rigid tool: `shape` "sphere" (radius), "capsule" (radius, half_length,
    /// axis along the pose's local z) or "half_space" (local z ≤ 0 is solid), touching
    /// the boundary surface through a penalty contact of `stiffness` (N/m per node)
    /// and `damping`, at the pose (translation, rotation vector). Returns its id.
    #[pyo3(signature = (shape, stiffness, radius = 0.0, half_length = 0.0, damping = 0.0, translation = None, rotation = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_tool(
        &mut self,
        shape: &str,
        stiffness: f64,
        radius: f64,
        half_length: f64,
        damping: f64,
        translation: Option<&Bound<'_, PyAny>>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<usize> {
        let law = ContactLaw { stiffness, damping };
        let tool = match shape {
            "sphere" => Tool::sphere(radius, law),
            "capsule" => Tool::capsule(radius, half_length, law),
            "half_space" => Tool::half_space(law),
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown tool shape '{other}'; known: sphere, capsule, half_space"
                )))
            }
        };
        let p = match translation {
            Some(t) => pose(t, rotation)?,
            None => Pose::identity(),
        };
        Ok(self.sys.add_tool(tool.at(p)).py()?.index())
    }

    /// Places a tool (translation, rotation vector) for the next step: it moves
    /// there at constant speed during that step.
    #[pyo3(signature = (tool, translation, rotation = None))]
    fn set_tool_pose(
        &mut self,
        tool: usize,
        translation: &Bound<'_, PyAny>,
        rotation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let id = self.tool_id(tool)?;
        let p = pose(translation, rotation)?;
        self.sys.set_tool_pose(id, p).py()
    }

    /// The force (N) and torque (N·m, about the tool's pose origin) the tissue
    /// applied to a tool at the last force evaluation: the haptic signal.
    fn tool_wrench(&self, tool: usize) -> PyResult<([f64; 3], [f64; 3])> {
        let w = self.sys.tool_wrench(self.tool_id(tool)?).py()?;
        Ok(([w.force.x, w.force.y, w.force.z], [w.torque.x, w.torque.y, w.torque.z]))
    }

    /// Removes a tool.
    fn remove_tool(&mut self, tool: usize) -> PyResult<()> {
        let id = self.tool_id(tool)?;
        self.sys.remove_tool(id).py().map(|_| ())
    }

    /// Removes the tets a blade meets at the current positions: a (3, 3) triangle, or
    /// a (4, 3) array a0, b0, a1, b1 (an edge a–b swept from a0–b0 to a1–b1).
    /// Returns removed_tets, removed_mass, orphaned_nodes, remaining_tets.
    fn cut<'py>(&mut self, py: Python<'py>, blade: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
        let p = arrays::points(blade, "blade", None)?;
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
        let r = self.sys.cut(&blade).py()?;
        report(py, &r)
    }

    /// Removes the given tets (ids); same report as `cut`.
    fn remove_tets<'py>(&mut self, py: Python<'py>, tets: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
        let ids = arrays::selection(tets, "tets", self.sys.mesh().n_tets())?;
        let r = self.sys.remove_tets(&ids).py()?;
        report(py, &r)
    }

    /// Number of tets left by cuts.
    #[getter]
    fn n_tets(&self) -> usize {
        self.sys.n_tets_alive()
    }
}
