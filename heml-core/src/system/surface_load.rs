//! Surface loads: pressure and traction on selected faces of the boundary surface.
//!
//! * **Pressure** p (Pa) is a follower load: each face pushes with −p·(area-normal)
//!   at the current positions, split equally to its three nodes, so it turns and
//!   stretches with the deformed surface (p > 0 pushes into the body). It has no
//!   potential on an open face set, so it adds nothing to
//!   [`Energies::loads`](crate::system::Energies).
//! * **Traction** t (N/m²) is a fixed vector per unit *rest* area: t·A₀/3 on each
//!   node of each face, whatever the deformation (dead load; its work −Σ f·u is in
//!   `Energies::loads`).
//!
//! Faces are chosen once, when the load is added, from the current
//! [boundary surface](crate::system::System::surface): by the tag of the tet they
//! belong to, by a box or by a plane (tested on the faces' rest centroids, so the
//! choice does not depend on the deformation). A cut removes the faces of the tets it
//! removes from every load; the faces it exposes are not added.
//!
//! **Implicit integration.** The loads are evaluated as part of the system's forces,
//! so the implicit integrators apply them at the end-of-step positions x⁺, updated
//! at every Newton iteration. Their derivative — non-symmetric for a follower
//! pressure — is left out of the tangent (the load is lagged within each linear
//! solve), which keeps the tangent symmetric for conjugate gradients; Newton then
//! converges linearly in the pressure's share of the stiffness, quadratically when
//! it is small next to the body's.
//!
//! # Example
//!
//! ```
//! use heml_core::mesh::generate::{box_mesh, HexSplit};
//! use heml_core::system::surface_load::{FaceSelection, SurfaceLoad};
//! use heml_core::system::System;
//! use heml_core::{material::Link, Vec3};
//! # use heml_core::law::*;
//! # #[derive(Debug, Clone, Copy)] struct Spring { k: f64 }
//! # impl MaterialInfo for Spring {
//! #     const NAME: &'static str = "doc_spring"; const PARAMS: &'static [ParamInfo] = &[];
//! #     const ENERGY: &'static str = ""; const DOC: &'static str = "";
//! #     fn to_params(&self) -> Vec<f64> { vec![self.k] }
//! #     fn from_params(v: &[f64]) -> Self { Spring { k: v[0] } }
//! # }
//! # impl LinkLaw for Spring {
//! #     const OPS: OpCount = OpCount { add: 0, mul: 0, div: 0, func: 0 };
//! #     fn w(&self, l: f64, r: f64) -> f64 { 0.5 * self.k * (l.sqrt() - r.sqrt()).powi(2) }
//! #     fn dw(&self, l: f64, r: f64) -> (f64, f64) { (self.w(l, r), 0.5 * self.k * (1.0 - (r / l).sqrt())) }
//! #     fn d2w(&self, l: f64, r: f64) -> f64 { 0.25 * self.k * r.sqrt() / (l * l.sqrt()) }
//! # }
//! let mesh = box_mesh([0.1, 0.1, 0.1], [2, 2, 2], HexSplit::Six)?;
//! let mut sys = System::builder(mesh)
//!     .material_law(Box::new(Link(Spring { k: 500.0 })))
//!     .fix_where(|p| p.z < 1e-9)
//!     .build()?;
//! // 1 kPa on the top face (z = 0.1, outward normal +z)
//! let top = FaceSelection::Plane {
//!     point: Vec3::new(0.0, 0.0, 0.1),
//!     normal: Vec3::z(),
//!     distance: 1e-6,
//!     max_angle: Some(0.1),
//! };
//! let id = sys.add_surface_load(&top, SurfaceLoad::Pressure(1000.0))?;
//! assert_eq!(sys.surface_load(id)?.n_faces(), 8);
//! // 1 kPa × 0.01 m² = 10 N down, spread over the top nodes
//! let f = sys.surface_load(id)?.force(sys.positions());
//! assert!((f - Vec3::new(0.0, 0.0, -10.0)).norm() < 1e-12);
//! sys.compute_forces()?;
//! let total: Vec3 = sys.forces().iter().sum();
//! assert!((total.z + 10.0).abs() < 1e-9); // (the elastic forces vanish at rest)
//! sys.set_pressure(id, 0.0)?;
//! # Ok::<(), heml_core::HemlError>(())
//! ```

use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use crate::system::System;
use crate::Vec3;

/// Which boundary faces a surface load acts on.
#[derive(Debug, Clone, PartialEq)]
pub enum FaceSelection {
    /// The boundary faces of the tets with this tag.
    Tag(i32),
    /// The faces whose rest centroid lies in the box (bounds included).
    Box {
        /// Lower corner.
        min: Vec3,
        /// Upper corner.
        max: Vec3,
    },
    /// The faces whose rest centroid lies within `distance` of the plane through
    /// `point` with normal `normal`; with `max_angle` (radians), only those whose
    /// outward normal is within that angle of `normal` (one side of a thin plate).
    Plane {
        /// A point of the plane.
        point: Vec3,
        /// The plane's normal (any length > 0).
        normal: Vec3,
        /// Largest distance of a face centroid to the plane (m, ≥ 0).
        distance: f64,
        /// Largest angle between a face's outward normal and `normal`, if any.
        max_angle: Option<f64>,
    },
}

/// As a user writes it (`tag = 2`, `bbox = { min = [..], max = [..] }`, a plane), for
/// messages: the error of an empty selection names what was asked in the words of
/// the scene file, not in Rust's debug notation.
///
/// ```
/// use heml_core::system::surface_load::FaceSelection;
/// use heml_core::Vec3;
/// let b = FaceSelection::Box { min: Vec3::new(0.0, 0.0, 0.5), max: Vec3::new(1.0, 1.0, 1.0) };
/// assert_eq!(b.to_string(), "bbox = { min = [0, 0, 0.5], max = [1, 1, 1] } (m)");
/// assert_eq!(FaceSelection::Tag(3).to_string(), "tag = 3");
/// ```
impl std::fmt::Display for FaceSelection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = |v: &Vec3| format!("[{}, {}, {}]", v.x, v.y, v.z);
        match self {
            FaceSelection::Tag(t) => write!(f, "tag = {t}"),
            FaceSelection::Box { min, max } => write!(f, "bbox = {{ min = {}, max = {} }} (m)", v(min), v(max)),
            FaceSelection::Plane {
                point,
                normal,
                distance,
                max_angle,
            } => {
                write!(
                    f,
                    "plane = {{ point = {}, normal = {}, tolerance = {distance}",
                    v(point),
                    v(normal)
                )?;
                if let Some(a) = max_angle {
                    write!(f, ", max_angle = {} deg", a.to_degrees())?;
                }
                write!(f, " }} (m)")
            }
        }
    }
}

/// What a surface load applies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SurfaceLoad {
    /// Follower pressure (Pa; > 0 pushes into the body).
    Pressure(f64),
    /// Dead traction per unit rest area (N/m²).
    Traction(Vec3),
}

/// As a user writes it (`pressure = 1000 Pa`, `traction = [..] N/m²`), for messages.
///
/// ```
/// use heml_core::system::surface_load::SurfaceLoad;
/// assert_eq!(SurfaceLoad::Pressure(f64::NAN).to_string(), "pressure = NaN Pa");
/// ```
impl std::fmt::Display for SurfaceLoad {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SurfaceLoad::Pressure(p) => write!(f, "pressure = {p} Pa"),
            SurfaceLoad::Traction(t) => write!(f, "traction = [{}, {}, {}] N/m²", t.x, t.y, t.z),
        }
    }
}

impl SurfaceLoad {
    fn check(&self) -> Result<()> {
        let ok = match self {
            SurfaceLoad::Pressure(p) => p.is_finite(),
            SurfaceLoad::Traction(t) => t.iter().all(|c| c.is_finite()),
        };
        if ok {
            Ok(())
        } else {
            Err(HemlError::Invalid(format!("surface load: {self} is not finite")))
        }
    }
}

/// One surface load and its faces.
#[derive(Debug, Clone)]
pub struct FaceLoad {
    load: SurfaceLoad,
    /// Outward triangles (node ids).
    faces: Vec<[u32; 3]>,
    /// The tet each face belongs to.
    owners: Vec<u32>,
    /// Rest area of each face.
    rest_area: Vec<f64>,
}

impl FaceLoad {
    /// What it applies.
    pub fn load(&self) -> SurfaceLoad {
        self.load
    }
    /// Number of faces it acts on.
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }
    /// Its faces (outward triangles of node ids).
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }
    /// Total rest area of its faces.
    pub fn rest_area(&self) -> f64 {
        self.rest_area.iter().sum()
    }

    /// The resultant of its nodal forces at positions `x` (what it pushes the body
    /// with, e.g. to tell a pressure's share of the support reactions).
    pub fn force(&self, x: &[Vec3]) -> Vec3 {
        match self.load {
            SurfaceLoad::Pressure(p) => {
                self.faces
                    .iter()
                    .map(|tri| {
                        let [a, b, c] = tri.map(|n| x[n as usize]);
                        (b - a).cross(&(c - a))
                    })
                    .sum::<Vec3>()
                    * (-p / 2.0)
            }
            SurfaceLoad::Traction(t) => t * self.rest_area(),
        }
    }

    /// Adds its nodal forces at positions `x` to `f`.
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) {
        match self.load {
            SurfaceLoad::Pressure(p) => {
                for tri in &self.faces {
                    let [a, b, c] = tri.map(|n| x[n as usize]);
                    let share = (b - a).cross(&(c - a)) * (-p / 6.0);
                    for &n in tri {
                        f[n as usize] += share;
                    }
                }
            }
            SurfaceLoad::Traction(t) => {
                for (tri, a) in self.faces.iter().zip(&self.rest_area) {
                    let share = t * (a / 3.0);
                    for &n in tri {
                        f[n as usize] += share;
                    }
                }
            }
        }
    }

    /// −(work of a traction) = −Σ f·(x − X); 0 for a pressure.
    fn energy(&self, x: &[Vec3], rest: &[Vec3]) -> f64 {
        match self.load {
            SurfaceLoad::Pressure(_) => 0.0,
            SurfaceLoad::Traction(t) => -self
                .faces
                .iter()
                .zip(&self.rest_area)
                .map(|(tri, a)| {
                    tri.iter()
                        .map(|&n| t.dot(&(x[n as usize] - rest[n as usize])))
                        .sum::<f64>()
                        * a
                        / 3.0
                })
                .sum::<f64>(),
        }
    }
}

/// The surface loads of a system, by id (ids are never reused).
#[derive(Debug, Clone, Default)]
pub struct SurfaceLoads {
    loads: Vec<Option<FaceLoad>>,
}

impl SurfaceLoads {
    /// The loads present, with their ids.
    pub fn iter(&self) -> impl Iterator<Item = (usize, &FaceLoad)> {
        self.loads
            .iter()
            .enumerate()
            .filter_map(|(i, l)| l.as_ref().map(|l| (i, l)))
    }

    /// Adds every load's nodal forces at `x` to `f`.
    pub(crate) fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) {
        for (_, l) in self.iter() {
            l.add_forces(x, f);
        }
    }

    /// The loads' potential energy (tractions only).
    pub(crate) fn energy(&self, x: &[Vec3], rest: &[Vec3]) -> f64 {
        self.iter().map(|(_, l)| l.energy(x, rest)).sum()
    }

    /// Drops the faces of the tets for which `alive` is false (after a cut).
    pub(crate) fn drop_tets(&mut self, alive: impl Fn(usize) -> bool) {
        for l in self.loads.iter_mut().flatten() {
            let keep: Vec<bool> = l.owners.iter().map(|&t| alive(t as usize)).collect();
            let mut k = keep.iter();
            l.faces.retain(|_| *k.next().unwrap_or(&true));
            let mut k = keep.iter();
            l.rest_area.retain(|_| *k.next().unwrap_or(&true));
            l.owners.retain(|&t| alive(t as usize));
        }
    }

    fn get_mut(&mut self, id: usize) -> Result<&mut FaceLoad> {
        self.loads
            .get_mut(id)
            .and_then(Option::as_mut)
            .ok_or_else(|| HemlError::Invalid(format!("no surface load with id {id}")))
    }
}

/// The boundary faces of `sys` that `sel` chooses.
fn select(sys: &System, sel: &FaceSelection) -> Result<(Vec<[u32; 3]>, Vec<u32>)> {
    let mesh: &TetMesh = sys.mesh();
    let rest = mesh.nodes();
    let s = sys.surface();
    let centroid = |tri: &[u32; 3]| tri.iter().map(|&n| rest[n as usize]).sum::<Vec3>() / 3.0;
    let keep: Box<dyn Fn(usize) -> bool> = match *sel {
        FaceSelection::Tag(tag) => Box::new(move |i| mesh.tags()[s.owners()[i] as usize] == tag),
        FaceSelection::Box { min, max } => {
            if !(min.iter().chain(max.iter()).all(|c| c.is_finite()) && (0..3).all(|d| min[d] <= max[d])) {
                return Err(HemlError::Invalid(format!(
                    "face selection box min {:?}, max {:?}: the corners must be finite with min <= max",
                    min.as_slice(),
                    max.as_slice()
                )));
            }
            Box::new(move |i| {
                let c = centroid(&s.triangles()[i]);
                (0..3).all(|d| c[d] >= min[d] && c[d] <= max[d])
            })
        }
        FaceSelection::Plane {
            point,
            normal,
            distance,
            max_angle,
        } => {
            let len = normal.norm();
            let finite = point.iter().chain(normal.iter()).all(|c| c.is_finite());
            if !(finite && len > 0.0 && distance.is_finite() && distance >= 0.0) {
                return Err(HemlError::Invalid(format!(
                    "face selection plane: point {:?} and normal {:?} must be finite, the normal nonzero and the \
                     distance {distance} finite and >= 0",
                    point.as_slice(),
                    normal.as_slice()
                )));
            }
            if let Some(a) = max_angle.filter(|a| !(a.is_finite() && *a >= 0.0)) {
                return Err(HemlError::Invalid(format!(
                    "face selection plane: max_angle {a} must be a finite angle >= 0 (radians)"
                )));
            }
            let n = normal / len;
            let cos_min = max_angle.map(f64::cos);
            Box::new(move |i| {
                let tri = &s.triangles()[i];
                if (centroid(tri) - point).dot(&n).abs() > distance {
                    return false;
                }
                cos_min.is_none_or(|c| {
                    let an = s.area_normal(i, rest);
                    an.dot(&n) >= c * an.norm()
                })
            })
        }
    };
    let ids: Vec<usize> = (0..s.n_triangles()).filter(|&i| keep(i)).collect();
    Ok((
        ids.iter().map(|&i| s.triangles()[i]).collect(),
        ids.iter().map(|&i| s.owners()[i]).collect(),
    ))
}

impl System {
    /// Adds a surface load on the boundary faces `sel` chooses (see the
    /// [module docs](self)) and returns its id. Errors, with the system unchanged:
    /// inside a step, a non-finite load or selection, a selection with no face.
    pub fn add_surface_load(&mut self, sel: &FaceSelection, load: SurfaceLoad) -> Result<usize> {
        self.check_between_steps("add_surface_load")?;
        load.check()?;
        let (faces, owners) = select(self, sel)?;
        if faces.is_empty() {
            return Err(HemlError::Invalid(format!(
                "surface load: the selection {sel} contains no boundary face"
            )));
        }
        let rest = self.model.mesh.nodes();
        let rest_area = faces
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|n| rest[n as usize]);
                0.5 * (b - a).cross(&(c - a)).norm()
            })
            .collect();
        self.model.surface_loads.loads.push(Some(FaceLoad {
            load,
            faces,
            owners,
            rest_area,
        }));
        self.invalidate();
        Ok(self.model.surface_loads.loads.len() - 1)
    }

    /// Sets the pressure of surface load `id` (a pressure load) between steps.
    pub fn set_pressure(&mut self, id: usize, pressure: f64) -> Result<()> {
        self.check_between_steps("set_pressure")?;
        let new = SurfaceLoad::Pressure(pressure);
        new.check()?;
        let l = self.model.surface_loads.get_mut(id)?;
        if !matches!(l.load, SurfaceLoad::Pressure(_)) {
            return Err(HemlError::Invalid(format!(
                "surface load {id} is a traction, not a pressure (use set_surface_load)"
            )));
        }
        l.load = new;
        self.invalidate();
        Ok(())
    }

    /// Replaces what surface load `id` applies (same faces) between steps.
    pub fn set_surface_load(&mut self, id: usize, load: SurfaceLoad) -> Result<()> {
        self.check_between_steps("set_surface_load")?;
        load.check()?;
        self.model.surface_loads.get_mut(id)?.load = load;
        self.invalidate();
        Ok(())
    }

    /// Removes surface load `id` between steps.
    pub fn remove_surface_load(&mut self, id: usize) -> Result<()> {
        self.check_between_steps("remove_surface_load")?;
        self.model.surface_loads.get_mut(id)?;
        self.model.surface_loads.loads[id] = None;
        self.invalidate();
        Ok(())
    }

    /// Surface load `id`.
    pub fn surface_load(&self, id: usize) -> Result<&FaceLoad> {
        self.model
            .surface_loads
            .loads
            .get(id)
            .and_then(Option::as_ref)
            .ok_or_else(|| HemlError::Invalid(format!("no surface load with id {id}")))
    }

    /// All surface loads.
    pub fn surface_loads(&self) -> &SurfaceLoads {
        &self.model.surface_loads
    }
}
