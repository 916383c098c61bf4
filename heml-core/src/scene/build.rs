//! From a [`Scene`] to a ready-to-run [`Simulation`]: the mesh loaded and converted
//! to metres, the system built with its materials, constraints and loads, the
//! integrator looked up, the step and output cadence decided.

use std::path::PathBuf;

use super::schema::{GenerateKind, MaterialSpec};
use super::Scene;
use crate::error::{HemlError, Result};
use crate::force::ForceOptions;
use crate::io::{read_mesh_data, MeshData};
use crate::mesh::generate::{box_mesh_limited, DEFAULT_MAX_GENERATED_TETS};
use crate::mesh::reorder::{morton_node_order, Permutation};
use crate::mesh::TetMesh;
use crate::registry::{closest, find_material, materials};
use crate::system::{find_integrator, integrators, Integrator, System, SystemBuilder, TimeStepPolicy};
use crate::Vec3;

/// A built scene: the system, its integrator and the run plan. Step it with
/// [`Simulation::run`].
pub struct Simulation {
    /// The simulated body.
    pub system: System,
    /// The integrator of `[solver]`.
    pub integrator: Box<dyn Integrator>,
    /// The step used: `duration / steps` (≤ the requested dt).
    pub dt: f64,
    /// Number of steps to reach the duration.
    pub steps: u64,
    /// Simulated time.
    pub duration: f64,
    /// A frame every this many steps (the last step always writes one).
    pub frame_every: u64,
    /// A CSV row every this many steps (the last step always writes one).
    pub csv_every: u64,
    /// Output directory.
    pub out_dir: PathBuf,
    /// Write VTU frames and the `.pvd`.
    pub vtu: bool,
    /// Write `energy.csv`.
    pub csv: bool,
    /// Encoding of the VTU frames (`[output] compression`).
    pub vtu_encoding: crate::io::VtuEncoding,
    /// What a dt above the stable estimate does.
    pub dt_policy: TimeStepPolicy,
    /// Warnings found while building (e.g. dt above the stable estimate).
    pub warnings: Vec<String>,
    /// The node renumbering of `[mesh] renumber`: internal node `i` (of `system`,
    /// whose arrays are all in internal order) is file node `new_to_old[i]`. The
    /// runner writes its frames back in file order and the system's messages name
    /// file ids. `None` when the system keeps the file order (`renumber = false`,
    /// or a mesh already in Morton order).
    pub node_order: Option<Permutation>,
}

impl std::fmt::Debug for Simulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simulation")
            .field("integrator", &self.integrator.name())
            .field("dt", &self.dt)
            .field("steps", &self.steps)
            .field("frame_every", &self.frame_every)
            .field("out_dir", &self.out_dir)
            .field("renumbered", &self.node_order.is_some())
            .finish_non_exhaustive()
    }
}

fn invalid<T>(msg: String) -> Result<T> {
    Err(HemlError::Invalid(msg))
}

fn finite3(v: &[f64; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

impl Scene {
    /// Loads or generates the mesh, converted to metres and translated.
    pub fn load_mesh(&self) -> Result<TetMesh> {
        let m = &self.mesh;
        let what = self.table_name("mesh");
        let scale = match (m.scale, m.units) {
            (Some(_), Some(_)) => return invalid(format!("{what}: give `scale` or `units`, not both")),
            (Some(s), None) => s,
            (None, Some(u)) => u.to_metres(),
            (None, None) => 1.0,
        };
        if !(scale.is_finite() && scale > 0.0) {
            return invalid(format!("{what}: scale {scale} must be a finite number > 0"));
        }
        let translate = m.translate.unwrap_or([0.0; 3]);
        if !finite3(&translate) {
            return invalid(format!("{what}: translate {translate:?} is not finite"));
        }
        let mut data = match (&m.file, &m.generate) {
            (Some(file), None) => {
                let path = self.base_dir.join(file);
                read_mesh_data(&path)?.0
            }
            (None, Some(g)) => {
                let size = g.size.map(|s| s * scale);
                let cells: [usize; 3] = match (g.kind, g.cells.as_slice()) {
                    (_, &[nx, ny, nz]) => [nx, ny, nz],
                    (GenerateKind::Beam, &[n]) => {
                        let h = size[0] / n.max(1) as f64;
                        let across = |d: f64| ((d / h).round() as usize).max(1);
                        [n, across(size[1]), across(size[2])]
                    }
                    (kind, c) => {
                        return invalid(format!(
                            "{what}: generate.cells = {c:?}: a {} needs [nx, ny, nz]{}",
                            if kind == GenerateKind::Box { "box" } else { "beam" },
                            if kind == GenerateKind::Beam {
                                " or [n] along its length"
                            } else {
                                ""
                            }
                        ))
                    }
                };
                let limit = g.max_tets.unwrap_or(DEFAULT_MAX_GENERATED_TETS);
                let mesh = box_mesh_limited(size, cells, g.split, limit)
                    .map_err(|e| HemlError::Invalid(format!("{what}: {e}")))?;
                let data = MeshData::from_mesh(&mesh);
                return finish_mesh(data, 1.0, translate, &what);
            }
            _ => return invalid(format!("{what}: give exactly one of `file` and `generate`")),
        };
        data.skipped.clear();
        finish_mesh(data, scale, translate, &what)
    }

    /// Builds the system and the integrator. Law and integrator names are looked up
    /// in the registry (see the [module docs](super) about linking).
    pub fn build(&self) -> Result<Simulation> {
        // `mesh` stays in file order: selections (ids and geometry alike) resolve on
        // it, and their ids go through `to_internal` to the builder
        let mesh = self.load_mesh()?;
        let node_order = if self.mesh.renumber {
            let order = morton_node_order(&mesh);
            let unchanged = order.new_to_old.iter().enumerate().all(|(i, &old)| i == old);
            (!unchanged).then_some(order)
        } else {
            None
        };
        let internal_mesh = match &node_order {
            Some(p) => mesh
                .renumbered(p, &Permutation::identity(mesh.n_tets()))
                .map_err(|e| HemlError::Invalid(format!("{}: {e}", self.table_name("mesh"))))?,
            None => mesh.clone(),
        };
        let to_internal = |ids: Vec<usize>| -> Vec<usize> {
            match &node_order {
                Some(p) => ids.into_iter().map(|i| p.old_to_new[i]).collect(),
                None => ids,
            }
        };
        let solver_what = self.table_name("solver");
        let s = &self.solver;
        if !(s.duration.is_finite() && s.duration > 0.0) {
            return invalid(format!(
                "{solver_what}: duration = {} must be a finite number > 0",
                s.duration
            ));
        }
        if let Some(dt) = s.dt {
            if !(dt.is_finite() && dt > 0.0) {
                return invalid(format!("{solver_what}: dt = {dt} must be a finite number > 0"));
            }
        }
        let mut integrator = find_integrator(&s.integrator)
            .map_err(|e| HemlError::Invalid(format!("{solver_what}: {e}{}", registry_hint(integrators().is_empty()))))?
            .instantiate();
        let implicit = s.configure_implicit(integrator.as_mut(), &solver_what)?;

        let mut b = SystemBuilder::new(internal_mesh);
        if let Some(p) = &node_order {
            b = b.input_node_ids(p.new_to_old.clone());
        }
        if self.mesh.pin_unreferenced {
            b = b.pin_unreferenced();
        }
        let mut opts = ForceOptions::default();
        if let Some(j0) = s.j0 {
            opts.j0 = j0;
        }
        opts.validate()
            .map_err(|e| HemlError::Invalid(format!("{solver_what}: {e}")))?;
        b = b.force_options(opts).time_step_policy(s.dt_policy).energy_every(0);
        if let Some(safety) = s.safety {
            b = b.safety(safety);
        }
        if self.materials.is_empty() {
            return invalid(format!("{}: no [[material]]", self.origin.display()));
        }
        let mut untagged = None;
        for (i, m) in self.materials.iter().enumerate() {
            let what = self.entry_name("material", i);
            if m.tag.is_none() {
                if let Some(first) = untagged {
                    return invalid(format!(
                        "{what}: a second material without `tag` (#{} has none either); \
                         only one material may cover the untagged remainder",
                        first + 1
                    ));
                }
                untagged = Some(i);
            }
            b = add_material(b, m).map_err(|e| HemlError::Invalid(format!("{what}: {e}")))?;
        }
        for (i, f) in self.fix.iter().enumerate() {
            let what = self.entry_name("fix", i);
            b = b.fix_nodes(to_internal(f.selection(&what)?.resolve(&what, &mesh)?));
        }
        for (i, p) in self.prescribe.iter().enumerate() {
            let what = self.entry_name("prescribe", i);
            let ids = to_internal(p.selection(&what)?.resolve(&what, &mesh)?);
            if !finite3(&p.displacement) {
                return invalid(format!("{what}: displacement {:?} is not finite", p.displacement));
            }
            p.ramp
                .validate()
                .map_err(|e| HemlError::Invalid(format!("{what}: {e}")))?;
            b = b.prescribe(&ids, Vec3::from(p.displacement), p.ramp);
        }
        let loads_what = self.table_name("loads");
        if let Some(g) = self.loads.gravity {
            if !finite3(&g) {
                return invalid(format!("{loads_what}: gravity {g:?} is not finite"));
            }
            b = b.gravity(Vec3::from(g));
        }
        for (i, l) in self.loads.nodal.iter().enumerate() {
            let what = self.entry_name("loads.nodal", i);
            let ids = to_internal(l.selection(&what)?.resolve(&what, &mesh)?);
            if !finite3(&l.force) {
                return invalid(format!("{what}: force {:?} is not finite", l.force));
            }
            let share = Vec3::from(l.force) / ids.len() as f64;
            for id in ids {
                b = b.nodal_force(id, share);
            }
        }
        let d = self.damping;
        if !(d.mass.is_finite() && d.mass >= 0.0 && d.stiffness.is_finite() && d.stiffness >= 0.0) {
            return invalid(format!(
                "{}: mass = {}, stiffness = {} must be finite numbers >= 0",
                self.table_name("damping"),
                d.mass,
                d.stiffness
            ));
        }
        b = b.rayleigh(d.mass, d.stiffness);
        let system = b
            .build()
            .map_err(|e| HemlError::Invalid(format!("{}: {e}", self.origin.display())))?;

        // time step and cadence
        let stable = system.stable_dt();
        let requested = match s.dt {
            Some(dt) => dt,
            None if stable.is_finite() => stable,
            None => {
                return invalid(format!(
                    "{solver_what}: no dt given and no stable estimate (no free node?): set dt"
                ))
            }
        };
        let steps = ((s.duration / requested) * (1.0 - 1e-12)).ceil().max(1.0);
        if steps > 1e12 {
            return invalid(format!("{solver_what}: duration / dt = {steps:e} steps is too many"));
        }
        let steps = steps as u64;
        let dt = s.duration / steps as f64;
        let mut warnings = Vec::new();
        if dt > stable && !implicit {
            let msg = format!(
                "{solver_what}: dt = {dt:e} s exceeds the stable estimate {stable:e} s; \
                 the explicit integration may blow up (set a smaller dt, or dt_policy)"
            );
            match s.dt_policy {
                TimeStepPolicy::Refuse => return invalid(format!("{msg} [dt_policy = \"refuse\"]")),
                TimeStepPolicy::Warn => warnings.push(msg),
                TimeStepPolicy::Ignore => {}
            }
        }
        let o = &self.output;
        let out_what = self.table_name("output");
        let frame_every = match (o.every, o.frame_interval) {
            (Some(_), Some(_)) => return invalid(format!("{out_what}: give `every` or `frame_interval`, not both")),
            (Some(0), None) => return invalid(format!("{out_what}: every must be >= 1")),
            (Some(n), None) => n,
            (None, Some(t)) if !(t.is_finite() && t > 0.0) => {
                return invalid(format!("{out_what}: frame_interval = {t} must be a finite number > 0"))
            }
            (None, Some(t)) => ((t / dt).round() as u64).max(1),
            (None, None) => (steps / 50).max(1),
        };
        let csv_every = match o.csv_every {
            Some(0) => return invalid(format!("{out_what}: csv_every must be >= 1")),
            Some(n) => n,
            None => (frame_every / 10).max(1),
        };
        Ok(Simulation {
            system,
            integrator,
            dt,
            steps,
            duration: s.duration,
            frame_every,
            csv_every,
            out_dir: PathBuf::from(o.dir.as_deref().unwrap_or("heml-output")),
            vtu: o.vtu,
            csv: o.csv,
            vtu_encoding: o.compression.vtu_encoding(),
            dt_policy: s.dt_policy,
            warnings,
            node_order,
        })
    }
}

fn finish_mesh(mut data: MeshData, scale: f64, translate: [f64; 3], what: &str) -> Result<TetMesh> {
    let t = Vec3::from(translate);
    for p in &mut data.nodes {
        *p = *p * scale + t;
    }
    data.into_mesh().map_err(|e| HemlError::Invalid(format!("{what}: {e}")))
}

fn registry_hint(empty: bool) -> &'static str {
    if empty {
        " (the registry is empty: link heml-materials and heml-integrators, e.g. through the `heml` facade)"
    } else {
        ""
    }
}

/// Adds one `[[material]]` to the builder, with a "did you mean" for misspelt
/// parameter names.
fn add_material(b: SystemBuilder, m: &MaterialSpec) -> Result<SystemBuilder> {
    let entry = find_material(&m.law)
        .map_err(|e| HemlError::Invalid(format!("{e}{}", registry_hint(materials().is_empty()))))?;
    let mut names: Vec<&str> = entry.params.iter().map(|p| p.name).collect();
    if entry.small_strain.is_some() {
        names.extend(["E", "nu"]);
    }
    let law = entry.instantiate(&m.params).map_err(|e| {
        let hint = m
            .params
            .0
            .keys()
            .filter(|k| !names.contains(&k.as_str()) && !["young", "poisson"].contains(&k.as_str()))
            .find_map(|k| closest(k, &names).map(|c| format!(" (did you mean '{c}' for '{k}'?)")))
            .unwrap_or_default();
        HemlError::Invalid(format!("{e}{hint}"))
    })?;
    let b = match m.tag {
        None => b.material_law(law),
        Some(tag) => b.region_law(tag, law),
    };
    let b = b.region_density(m.density.unwrap_or(1000.0));
    Ok(if m.prony.is_empty() { b } else { b.prony(&m.prony) })
}
