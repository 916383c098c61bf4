//! Scripted surgery in a scene: `[[cut]]` events (a blade applied when the run
//! reaches its time) and `[[surface_load]]` entries (pressure or traction on
//! boundary faces, optionally ramped in time). Parsed here, checked by
//! [`Scene::build`](super::Scene::build) with errors naming the entry and key, and
//! applied by the runner before each step.

use serde::Deserialize;

use super::schema::BoxSpec;
use super::Scene;
use crate::error::{HemlError, Result};
use crate::system::cut::{Blade, CutReport};
use crate::system::surface_load::{FaceSelection, SurfaceLoad};
use crate::system::{Ramp, System};
use crate::Vec3;

/// `[[cut]]`: at `time`, remove the tets a blade meets (metres, at the current,
/// deformed positions). The blade is either an edge swept from `from` to `to` (two
/// points each: a scalpel's edge at the start and at the end of its move) or one
/// `triangle`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CutSpec {
    /// When (s, ≥ 0): applied before the first step that starts at or after it.
    pub time: f64,
    /// The blade's edge at the start: two points.
    #[serde(default, deserialize_with = "super::exact::opt_points")]
    pub from: Option<[[f64; 3]; 2]>,
    /// The blade's edge at the end: two points.
    #[serde(default, deserialize_with = "super::exact::opt_points")]
    pub to: Option<[[f64; 3]; 2]>,
    /// Or a triangular blade: three points.
    #[serde(default, deserialize_with = "super::exact::opt_points")]
    pub triangle: Option<[[f64; 3]; 3]>,
}

/// The plane selector of a `[[surface_load]]`: the faces whose rest centroid lies
/// within `tolerance` of the plane, facing along `normal` within `max_angle`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FacePlaneSpec {
    /// A point of the plane (metres).
    #[serde(deserialize_with = "super::exact::vec3")]
    pub point: [f64; 3],
    /// Its normal (any length > 0).
    #[serde(deserialize_with = "super::exact::vec3")]
    pub normal: [f64; 3],
    /// Largest distance (metres) of a face centroid; default 1e-6 × the mesh's
    /// bounding-box diagonal.
    pub tolerance: Option<f64>,
    /// Largest angle (degrees) between a face's outward normal and `normal`; none:
    /// both sides of a thin plate.
    pub max_angle: Option<f64>,
}

/// `[[surface_load]]`: a `pressure` (Pa, follower, > 0 pushes in) or a `traction`
/// (N/m² per rest area) on the boundary faces chosen by exactly one of `tag`,
/// `bbox` or `plane`, scaled by `ramp` over time (default: constant).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceLoadSpec {
    /// Pressure (Pa).
    pub pressure: Option<f64>,
    /// Traction (N/m²).
    #[serde(default, deserialize_with = "super::exact::opt_vec3")]
    pub traction: Option<[f64; 3]>,
    /// The faces of the tets with this tag.
    pub tag: Option<i32>,
    /// The faces whose rest centroid lies in this box.
    pub bbox: Option<BoxSpec>,
    /// The faces near a plane.
    pub plane: Option<FacePlaneSpec>,
    /// Time profile of the load (the prescribe ramps: step, linear, smooth,
    /// keyframes), sampled at the start of each step.
    pub ramp: Option<Ramp>,
}

/// A checked `[[cut]]`.
#[derive(Debug, Clone)]
struct CutEvent {
    time: f64,
    blade: Blade,
    what: String,
}

/// A `[[surface_load]]` with a ramp: its system id and full load.
#[derive(Debug, Clone)]
struct RampedLoad {
    id: usize,
    load: SurfaceLoad,
    ramp: Ramp,
}

/// The scripted events of a run: cuts waiting for their time, ramped loads.
#[derive(Debug, Clone, Default)]
pub struct Surgery {
    cuts: Vec<CutEvent>,
    next_cut: usize,
    ramped: Vec<RampedLoad>,
    /// What the cuts applied so far did.
    pub reports: Vec<CutReport>,
}

fn point(p: &[f64; 3]) -> Vec3 {
    Vec3::from(*p)
}

impl Scene {
    /// Checks the `[[cut]]` and `[[surface_load]]` entries and adds the loads to
    /// `sys` (at their ramps' value at t = 0).
    pub(crate) fn surgery(&self, sys: &mut System, duration: f64) -> Result<(Surgery, Vec<String>)> {
        let mut s = Surgery::default();
        let mut warnings = Vec::new();
        for (i, c) in self.cut.iter().enumerate() {
            let what = self.entry_name("cut", i);
            if !(c.time.is_finite() && c.time >= 0.0) {
                return invalid(format!("{what}: time = {} must be a finite number >= 0 (s)", c.time));
            }
            let blade = match (c.from, c.to, c.triangle) {
                (Some(f), Some(t), None) => Blade::Sweep {
                    a0: point(&f[0]),
                    b0: point(&f[1]),
                    a1: point(&t[0]),
                    b1: point(&t[1]),
                },
                (None, None, Some(t)) => Blade::Triangle(t.map(|p| point(&p))),
                _ => {
                    return invalid(format!(
                        "{what}: give either `from` and `to` (the blade's edge, two points each) or `triangle` \
                         (three points)"
                    ))
                }
            };
            blade
                .check()
                .map_err(|e| HemlError::Invalid(format!("{what}: `from`/`to`/`triangle`: {e}")))?;
            if c.time > duration {
                warnings.push(format!(
                    "{what}: time = {} s is after the end of the run ({duration} s): it never happens",
                    c.time
                ));
            }
            s.cuts.push(CutEvent {
                time: c.time,
                blade,
                what,
            });
        }
        s.cuts.sort_by(|a, b| a.time.total_cmp(&b.time));
        if !s.cuts.is_empty() {
            // the one-time O(n log n) part of cutting, before the run rather than at
            // its first cut
            sys.prepare_cutting();
        }
        let diag = {
            let (lo, hi) = sys.mesh().bounding_box();
            (hi - lo).norm()
        };
        for (i, l) in self.surface_load.iter().enumerate() {
            let what = self.entry_name("surface_load", i);
            let load = match (l.pressure, l.traction) {
                (Some(p), None) => SurfaceLoad::Pressure(p),
                (None, Some(t)) => SurfaceLoad::Traction(point(&t)),
                _ => {
                    return invalid(format!(
                        "{what}: give exactly one of `pressure` (Pa) and `traction` (N/m²)"
                    ))
                }
            };
            // the scene gives degrees; checked here, in the user's unit (the
            // system's check speaks radians)
            if let Some(a) = l.plane.as_ref().and_then(|p| p.max_angle) {
                if !(a.is_finite() && (0.0..=180.0).contains(&a)) {
                    return invalid(format!("{what}: plane.max_angle = {a} must be in 0..=180 (degrees)"));
                }
            }
            let sel = match (l.tag, l.bbox, l.plane) {
                (Some(tag), None, None) => FaceSelection::Tag(tag),
                (None, Some(b), None) => FaceSelection::Box {
                    min: point(&b.min),
                    max: point(&b.max),
                },
                (None, None, Some(p)) => FaceSelection::Plane {
                    point: point(&p.point),
                    normal: point(&p.normal),
                    distance: p.tolerance.unwrap_or(1e-6 * diag),
                    max_angle: p.max_angle.map(f64::to_radians),
                },
                _ => return invalid(format!("{what}: give exactly one of `tag`, `bbox` and `plane`")),
            };
            let ramp = l.ramp.clone();
            if let Some(r) = &ramp {
                r.validate()
                    .map_err(|e| HemlError::Invalid(format!("{what}: ramp: {e}")))?;
            }
            let scale = ramp.as_ref().map_or(1.0, |r| r.value(0.0));
            let id = sys
                .add_surface_load(&sel, scaled(load, scale))
                .map_err(|e| HemlError::Invalid(format!("{what}: {e}")))?;
            if let Some(ramp) = ramp {
                s.ramped.push(RampedLoad { id, load, ramp });
            }
        }
        Ok((s, warnings))
    }
}

fn scaled(load: SurfaceLoad, r: f64) -> SurfaceLoad {
    match load {
        SurfaceLoad::Pressure(p) => SurfaceLoad::Pressure(p * r),
        SurfaceLoad::Traction(t) => SurfaceLoad::Traction(t * r),
    }
}

impl Surgery {
    /// Before a step that starts at the system's time: applies the cuts whose time
    /// has come (within `tol`) and sets the ramped loads to their value now.
    pub(crate) fn before_step(&mut self, sys: &mut System, tol: f64) -> Result<()> {
        let t = sys.time();
        while let Some(c) = self.cuts.get(self.next_cut).filter(|c| c.time <= t + tol) {
            let report = sys
                .cut(&c.blade)
                .map_err(|e| HemlError::Invalid(format!("{} (applied at t = {t:e} s): {e}", c.what)))?;
            log::info!(
                "{} at t = {t:e} s: removed {} tets ({:e} kg), {} orphaned node(s), {} tets left",
                c.what,
                report.removed_tets.len(),
                report.removed_mass,
                report.orphaned_nodes.len(),
                report.remaining_tets
            );
            self.reports.push(report);
            self.next_cut += 1;
        }
        for l in &self.ramped {
            // (only when it changes: a change invalidates the forces the integrator
            // would otherwise reuse from the end of the previous step)
            let now = scaled(l.load, l.ramp.value(t));
            if sys.surface_load(l.id)?.load() != now {
                sys.set_surface_load(l.id, now)?;
            }
        }
        Ok(())
    }
}

fn invalid<T>(msg: String) -> Result<T> {
    Err(HemlError::Invalid(msg))
}
