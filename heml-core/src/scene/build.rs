//! From a [`Scene`] to a ready-to-run [`Simulation`]: the mesh loaded and converted
//! to metres, the system built with its materials, constraints and loads, the
//! integrator looked up, the step and output cadence decided.

use std::path::PathBuf;

use super::plan::{
    frame_bytes, plan, Limits, RunPlan, DEFAULT_MAX_OUTPUT_BYTES, DEFAULT_MAX_STEPS, DEFAULT_WARN_OUTPUT_BYTES,
    DEFAULT_WARN_STEPS,
};
use super::schema::{GenerateKind, MaterialSpec, PrescribeSpec, SolverSpec};
use super::Scene;
use crate::error::{HemlError, Result};
use crate::force::ForceOptions;
use crate::io::{read_mesh_data, MeshData};
use crate::mesh::generate::{box_mesh_limited, DEFAULT_MAX_GENERATED_TETS};
use crate::mesh::reorder::{morton_node_order, Permutation};
use crate::mesh::TetMesh;
use crate::registry::{closest, find_material, materials};
use crate::system::{
    find_integrator, integrators, Integrator, Ramp, System, SystemBuilder, TimeStepPolicy, DEFAULT_ADAPT_EVERY,
};
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
    /// Floating-point type of the frames' fields (`[output] precision`).
    pub vtu_precision: crate::io::FieldPrecision,
    /// What a dt above the stable estimate does (`Adapt`: the step follows the
    /// stiffness, `dt` being its upper bound).
    pub dt_policy: TimeStepPolicy,
    /// Steps between two re-estimates of the adaptive step.
    pub adapt_every: u64,
    /// Hard limit on the number of steps (`[solver] max_steps`): an adaptive run
    /// stops with an error there.
    pub max_steps: u64,
    /// The cost of the run, decided before it starts: show it (and its warnings)
    /// before calling [`Simulation::run`].
    pub plan: RunPlan,
    /// Warnings found while building (e.g. dt above the stable estimate).
    pub warnings: Vec<String>,
    /// The `[[tool]]`s: their ids in `system` and the paths the runner moves them
    /// along.
    pub tools: Vec<super::tools::ScriptedTool>,
    /// The node renumbering of `[mesh] renumber`: internal node `i` (of `system`,
    /// whose arrays are all in internal order) is file node `new_to_old[i]`. The
    /// runner writes its frames back in file order and the system's messages name
    /// file ids. `None` when the system keeps the file order (`renumber = false`,
    /// or a mesh already in Morton order).
    pub node_order: Option<Permutation>,
    /// The `[[cut]]` events and ramped `[[surface_load]]`s, applied by the runner
    /// before each step; its `reports` say what each cut did.
    pub surgery: super::Surgery,
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
                // a file that cannot be opened is named as the scene wrote it and as
                // resolved (relative paths are against the scene's folder)
                let mut data = read_mesh_data(&path)
                    .map_err(|e| match e {
                        HemlError::Io { path, source } => HemlError::Invalid(format!(
                            "{what}: file = {file:?}: cannot read {}: {source}",
                            path.display()
                        )),
                        // (not a mesh format, not a regular file, too large): the
                        // scene's key too; a parse error names the mesh file's line
                        HemlError::Invalid(msg) => HemlError::Invalid(format!("{what}: file = {file:?}: {msg}")),
                        e => e,
                    })?
                    .0;
                super::fibres::check_fibre_fields(&self.materials, &data, &path)?;
                data.split_hexes(m.hex_split.unwrap_or_default())
                    .map_err(|e| HemlError::Invalid(format!("{what}: {}: {e}", path.display())))?;
                data
            }
            (None, Some(_)) if m.hex_split.is_some() => {
                return invalid(format!(
                    "{what}: hex_split applies to mesh files; a generated mesh is cut by generate.split"
                ))
            }
            (None, Some(g)) => {
                let size = g.size.map(|s| s * scale);
                if let Some(&s) = size
                    .iter()
                    .find(|s| s.abs().partial_cmp(&MAX_COORDINATE) != Some(std::cmp::Ordering::Less))
                {
                    return invalid(format!(
                        "{what}: generate.size is {s:e} m after `scale`/`units` ({scale:e}): coordinates beyond \
                         {MAX_COORDINATE:e} m overflow the squared lengths the laws compute; check `scale` or `units`"
                    ));
                }
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

    /// The law of `[[material]]` entry `index` (from 0) on `mesh`, as
    /// [`Scene::build`] makes it. Errors name the entry and its line.
    pub fn material_law(&self, index: usize, mesh: &TetMesh) -> Result<Box<dyn crate::Material>> {
        let Some(m) = self.materials.get(index) else {
            return invalid(format!(
                "{}: no [[material]] #{} (the scene has {})",
                self.origin.display(),
                index + 1,
                self.materials.len()
            ));
        };
        material_law(m, &self.solver, mesh)
            .map_err(|e| HemlError::Invalid(format!("{}: {e}", self.entry_name("material", index))))
    }

    /// Gives the running system `sys`, built from this scene, the laws of the
    /// `[[material]]` entries `entries` (indices from 0) as the scene now declares
    /// them — after editing their parameters, say — through
    /// [`System::set_materials`](crate::system::System::set_materials): the state,
    /// cuts, grasps, tools and history stay. Each entry's region is the one with its
    /// tag. All laws are built before any is set: an error leaves `sys` unchanged.
    ///
    /// # Example
    ///
    /// (Not run here: heml-core's own doctests have no integrator registered; through
    /// the `heml` facade it runs as it is, and `tests/tests/suite/scene.rs` runs it.)
    ///
    /// ```no_run
    /// let mut scene = heml_core::scene::Scene::from_toml_str(
    ///     r#"
    ///     [mesh]
    ///     generate = { kind = "box", size = [0.02, 0.01, 0.01], cells = [4, 2, 2] }
    ///     [[material]]
    ///     energy = "mu/2*(I1-3) - mu*ln(J) + lam/2*ln(J).powi(2)"
    ///     params = { mu = 1e3, lam = 4e3 }
    ///     [solver]
    ///     duration = 0.01
    ///     "#,
    ///     ".",
    /// )?;
    /// let mut sim = scene.build()?;
    /// let dt = sim.system.stable_dt();
    /// scene.materials[0].params.set("mu", 4e3);
    /// scene.materials[0].params.set("lam", 16e3);
    /// scene.update_laws(&mut sim.system, &[0])?;
    /// // four times as stiff: half the stable step
    /// assert!((sim.system.stable_dt() / dt - 0.5).abs() < 1e-6);
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    pub fn update_laws(&self, sys: &mut crate::system::System, entries: &[usize]) -> Result<()> {
        let mut laws = Vec::with_capacity(entries.len());
        for &k in entries {
            let tag = self.materials.get(k).and_then(|m| m.tag);
            let region = sys.regions().iter().position(|r| r.tag() == tag).ok_or_else(|| {
                HemlError::Invalid(format!(
                    "{}: the system has no region for it (was it built from this scene?)",
                    self.entry_name("material", k)
                ))
            })?;
            laws.push((region, self.material_law(k, sys.mesh())?));
        }
        sys.set_materials(laws)
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

        if !self.mesh.pin_unreferenced {
            let loose = mesh.unreferenced_nodes();
            if !loose.is_empty() {
                let listed: Vec<String> = loose.iter().take(20).map(|i| i.to_string()).collect();
                return invalid(format!(
                    "{}: {} node(s) belong to no tet and would have no mass: ids {}{} (remove them from \
                     the file, or set `pin_unreferenced = true` in [mesh] to hold them in place)",
                    self.table_name("mesh"),
                    loose.len(),
                    listed.join(", "),
                    if loose.len() > 20 { ", …" } else { "" }
                ));
            }
        }
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
        // the adaptive step follows the explicit stability limit: an implicit
        // integrator steps at dt (held to that limit, a backward Euler scene with a
        // prescribed motion announced 10 steps and took 1 377)
        let mut policy_note = None;
        let dt_policy = match s.dt_policy {
            Some(TimeStepPolicy::Adapt) if implicit => {
                policy_note = Some(format!(
                    "{solver_what}: dt_policy = \"adapt\" follows the explicit stability limit and does not \
                     apply to the implicit integrator `{}`, which steps at dt",
                    s.integrator
                ));
                TimeStepPolicy::Ignore
            }
            Some(p) => p,
            None if self.prescribe.is_empty() || implicit => TimeStepPolicy::Warn,
            None => TimeStepPolicy::Adapt,
        };
        // without energy.csv nothing reads the energy per step (the summary asks once)
        b = b
            .force_options(opts)
            .time_step_policy(dt_policy)
            .energy_every(0)
            .lazy_energy(!self.output.csv);
        if let Some(safety) = s.safety {
            // checked here too (the builder checks it), so that the error has its line
            if !(safety.is_finite() && safety > 0.0 && safety <= 1.0) {
                return invalid(format!("{solver_what}: safety = {safety} must lie in (0, 1]"));
            }
            b = b.safety(safety);
        }
        if self.materials.is_empty() {
            return invalid(format!("{}: no [[material]]", self.origin.display()));
        }
        let mut untagged = None;
        for (i, m) in self.materials.iter().enumerate() {
            let what = self.entry_name("material", i);
            if let Some(tag) = m.tag {
                if !mesh.tags().contains(&tag) {
                    let mut tags = mesh.tags().to_vec();
                    tags.sort_unstable();
                    tags.dedup();
                    return invalid(format!(
                        "{what}: tag = {tag} has no tets (the mesh's tags are {tags:?})"
                    ));
                }
            }
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
            b = add_material(b, m, s, &mesh).map_err(|e| HemlError::Invalid(format!("{what}: {e}")))?;
        }
        // which entry holds each node (file ids), to name both entries of a conflict
        let mut holder: Vec<Option<(&str, usize)>> = vec![None; mesh.n_nodes()];
        let mut hold = |table: &'static str, i: usize, ids: &[usize]| -> Result<()> {
            for &id in ids {
                match holder[id] {
                    Some((t, j)) if t == "prescribe" || table == "prescribe" => {
                        return invalid(format!(
                            "{}: node {id} is already {} by {}; a node is fixed or prescribed once",
                            self.entry_name(table, i),
                            if t == "fix" { "fixed" } else { "prescribed" },
                            self.entry_name(t, j)
                        ));
                    }
                    Some(_) => {}
                    None => holder[id] = Some((table, i)),
                }
            }
            Ok(())
        };
        for (i, f) in self.fix.iter().enumerate() {
            let what = self.entry_name("fix", i);
            let ids = f.selection(&what)?.resolve(&what, &mesh)?;
            hold("fix", i, &ids)?;
            b = b.fix_nodes(to_internal(ids));
        }
        for (i, p) in self.prescribe.iter().enumerate() {
            let what = self.entry_name("prescribe", i);
            let ids = p.selection(&what)?.resolve(&what, &mesh)?;
            hold("prescribe", i, &ids)?;
            let ids = to_internal(ids);
            let (displacement, ramp) = prescribed_motion(p, &what)?;
            b = b.prescribe(&ids, displacement, ramp);
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
        let mut system = b
            .build()
            .map_err(|e| HemlError::Invalid(format!("{}: {e}", self.origin.display())))?;
        // [[cut]] and [[surface_load]] (surgery.rs)
        let (surgery, surgery_warnings) = self.surgery(&mut system, s.duration)?;
        let tools = self.add_tools(&mut system)?;

        // time step and cadence
        let stable = system.stable_dt();
        let requested = match s.dt {
            Some(dt) => dt,
            None if stable.is_finite() => stable,
            None if (0..system.mesh().n_nodes()).any(|i| system.is_free(i)) => {
                return invalid(format!(
                    "{solver_what}: no dt given, and the stable estimate is {stable}: {}: fix the parameters, \
                     or set dt",
                    system.infinite_estimate_reason()
                ))
            }
            None => {
                return invalid(format!(
                    "{solver_what}: no dt given, and no stable estimate: every node is fixed or prescribed; set dt"
                ))
            }
        };
        let steps = ((s.duration / requested) * (1.0 - 1e-12)).ceil().max(1.0);
        let o = &self.output;
        let out_what = self.table_name("output");
        if o.dir.as_deref().is_some_and(|d| d.trim().is_empty()) {
            // (the run's error was ": No such file or directory", naming nothing)
            return invalid(format!(
                "{out_what}: dir = \"\" is empty; name the output directory (default \"heml-output\")"
            ));
        }
        let limits = Limits {
            warn_steps: s.warn_steps.unwrap_or(DEFAULT_WARN_STEPS),
            max_steps: s.max_steps.unwrap_or(DEFAULT_MAX_STEPS),
            warn_bytes: o.warn_output_bytes.unwrap_or(DEFAULT_WARN_OUTPUT_BYTES),
            max_bytes: o.max_output_bytes.unwrap_or(DEFAULT_MAX_OUTPUT_BYTES),
        };
        if steps > limits.max_steps as f64 {
            // refused before the cast: duration / dt may not even fit a u64
            // when the step is the estimate, say what sets it if that is the damping
            let why = match (s.dt, system.damping_note()) {
                (None, Some(note)) => format!(" (the stable estimate; {note})"),
                _ => String::new(),
            };
            return invalid(format!(
                "{solver_what}: duration / dt = {:e} / {requested:e}{why} = {steps:e} steps, above max_steps = \
                 {}: shorten `duration`, raise `dt`, or raise `max_steps` if you mean it",
                s.duration, limits.max_steps
            ));
        }
        let steps = steps as u64;
        let dt = s.duration / steps as f64;
        let mut warnings = surgery_warnings;
        warnings.extend(policy_note);
        if dt > stable && dt_policy != TimeStepPolicy::Adapt && !implicit {
            let msg = format!(
                "{solver_what}: dt = {dt:e} s exceeds the stable estimate {stable:e} s; \
                 the explicit integration may blow up (set a smaller dt, or dt_policy)"
            );
            match dt_policy {
                TimeStepPolicy::Refuse => return invalid(format!("{msg} [dt_policy = \"refuse\"]")),
                TimeStepPolicy::Warn => warnings.push(msg),
                TimeStepPolicy::Ignore | TimeStepPolicy::Adapt => {}
            }
        }
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
        let adapt_every = match s.adapt_every {
            Some(0) => return invalid(format!("{solver_what}: adapt_every must be >= 1")),
            Some(n) => n,
            None => DEFAULT_ADAPT_EVERY,
        };
        let adaptive = dt_policy == TimeStepPolicy::Adapt;
        let plan = plan(
            steps,
            (frame_every, csv_every),
            (o.vtu, o.csv),
            frame_bytes(
                system.mesh().n_nodes(),
                system.mesh().n_tets(),
                o.compression.vtu_encoding(),
                o.precision,
            ),
            adaptive,
            limits,
            (&solver_what, &out_what),
        )
        .map_err(HemlError::Invalid)?;
        for w in &plan.warnings {
            log::warn!("{w}");
        }
        log::info!("run plan: {plan}");
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
            vtu_precision: o.precision,
            dt_policy,
            adapt_every,
            max_steps: limits.max_steps,
            plan,
            warnings,
            tools,
            node_order,
            surgery,
        })
    }
}

/// Largest coordinate (m) a converted mesh may have: the laws work with squared
/// edge lengths and their products, which overflow f64 (1.8e308) above ~1e77 m; a
/// body of 1e50 m is already far outside any physical use.
const MAX_COORDINATE: f64 = 1e50;

fn finish_mesh(mut data: MeshData, scale: f64, translate: [f64; 3], what: &str) -> Result<TetMesh> {
    let t = Vec3::from(translate);
    for p in &mut data.nodes {
        *p = *p * scale + t;
    }
    // NaN compares as None: it fails too
    if let Some((i, p)) = data
        .nodes
        .iter()
        .enumerate()
        .find(|(_, p)| p.amax().partial_cmp(&MAX_COORDINATE) != Some(std::cmp::Ordering::Less))
    {
        return invalid(format!(
            "{what}: node {i} is at {:?} m after `scale`/`units` ({scale:e}) and `translate`: coordinates \
             beyond {MAX_COORDINATE:e} m overflow the squared lengths the laws compute; check `scale` or `units`",
            p.as_slice()
        ));
    }
    data.into_mesh().map_err(|e| HemlError::Invalid(format!("{what}: {e}")))
}

/// The displacement and ramp of a `[[prescribe]]` entry: `displacement` with `ramp`,
/// or `keyframes` turned into one direction scaled by a keyframed ramp.
fn prescribed_motion(p: &PrescribeSpec, what: &str) -> Result<(Vec3, Ramp)> {
    let (u, ramp) = match (&p.displacement, &p.ramp, &p.keyframes) {
        (Some(u), Some(ramp), None) => {
            if !finite3(u) {
                return invalid(format!("{what}: displacement {u:?} is not finite"));
            }
            (Vec3::from(*u), ramp.clone())
        }
        (None, None, Some(k)) => keyframed(k).map_err(|e| HemlError::Invalid(format!("{what}: keyframes: {e}")))?,
        (None, Some(_), None) => return invalid(format!("{what}: `ramp` without `displacement`")),
        (Some(_), None, None) => {
            return invalid(format!(
                "{what}: `displacement` needs a `ramp` (e.g. ramp = {{ kind = \"smooth\", duration = 1.0 }})"
            ))
        }
        (None, None, None) => {
            return invalid(format!(
                "{what}: give `displacement` with `ramp`, or `keyframes = [[t, ux, uy, uz], ...]`"
            ))
        }
        _ => {
            return invalid(format!(
                "{what}: give `displacement` with `ramp`, or `keyframes`, not both"
            ))
        }
    };
    ramp.validate()
        .map_err(|e| HemlError::Invalid(format!("{what}: {e}")))?;
    Ok((u, ramp))
}

/// `[[t, ux, uy, uz], …]` as the keyframe with the largest displacement u* and the
/// ramp r_k = u_k·u*/|u*|²; an error when a keyframe leaves the direction of u*
/// (by more than 1e-9 |u*|: round-off of the user's decimals, not a second direction).
fn keyframed(k: &[[f64; 4]]) -> std::result::Result<(Vec3, Ramp), String> {
    if k.is_empty() {
        return Err("at least one [t, ux, uy, uz] is needed".into());
    }
    if k.iter().flatten().any(|c| !c.is_finite()) {
        return Err("every time and displacement must be finite".into());
    }
    let u = |r: &[f64; 4]| Vec3::new(r[1], r[2], r[3]);
    let top = k
        .iter()
        .map(u)
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
        .unwrap_or_else(Vec3::zeros);
    let n2 = top.norm_squared();
    let mut points = Vec::with_capacity(k.len());
    for (i, row) in k.iter().enumerate() {
        let r = if n2 > 0.0 { u(row).dot(&top) / n2 } else { 0.0 };
        if (u(row) - top * r).norm() > 1e-9 * n2.sqrt() {
            return Err(format!(
                "keyframe #{} {:?} is not along {:?}: one entry moves along one direction (split the nodes \
                 over several [[prescribe]] entries)",
                i + 1,
                [row[1], row[2], row[3]],
                top.as_slice()
            ));
        }
        points.push([row[0], r]);
    }
    Ok((top, Ramp::Keyframes { points }))
}

fn registry_hint(empty: bool) -> &'static str {
    if empty {
        " (the registry is empty: link heml-materials and heml-integrators, e.g. through the `heml` facade)"
    } else {
        ""
    }
}

/// Adds one `[[material]]` to the builder: its law ([`material_law`]), region,
/// density and Prony terms.
fn add_material(b: SystemBuilder, m: &MaterialSpec, solver: &SolverSpec, mesh: &TetMesh) -> Result<SystemBuilder> {
    let law = material_law(m, solver, mesh)?;
    let b = match m.tag {
        None => b.material_law(law),
        Some(tag) => b.region_law(tag, law),
    };
    let b = b.region_density(m.density.unwrap_or(1000.0));
    Ok(if m.prony.is_empty() { b } else { b.prony(&m.prony) })
}

/// The law of one `[[material]]` on `mesh`: registry law or energy text, fibre
/// directions and volumetric form, with a "did you mean" for misspelt parameter
/// names. Density and Prony terms are checked here too, so that every error of the
/// entry comes before the system is built.
pub(super) fn material_law(m: &MaterialSpec, solver: &SolverSpec, mesh: &TetMesh) -> Result<Box<dyn crate::Material>> {
    // checked before the law is built (the builder checks them too), so that the
    // errors name the [[material]] entry and its line
    if let Some(d) = m.density {
        if !(d.is_finite() && d > 0.0) {
            return Err(HemlError::Invalid(format!(
                "density = {d} must be a finite number > 0 (kg/m³)"
            )));
        }
    }
    crate::system::validate_prony(&m.prony).map_err(|e| HemlError::Invalid(format!("prony: {e}")))?;
    if m.volumetric_energy.is_some() && m.energy.is_none() {
        return Err(HemlError::Invalid(format!(
            "[[material]] gives volumetric_energy with law = \"{}\": it declares the volumetric energy of a \
             law given as `energy`; a registry law declares its own or none (`heml materials` shows it)",
            m.law
        )));
    }
    let law = match &m.energy {
        Some(energy) if m.law.is_empty() => {
            let law = crate::RuntimeLaw::from_energy(energy, &m.params)?;
            Box::new(match &m.volumetric_energy {
                Some(u) => law.with_volumetric_energy(u)?,
                None => law,
            })
        }
        Some(_) => {
            return Err(HemlError::Invalid(format!(
                "[[material]] gives both law = \"{}\" and energy: give one of them",
                m.law
            )))
        }
        None if m.law.is_empty() => {
            return Err(HemlError::Invalid(
                "[[material]] needs `law` (a registry name, `heml materials` lists them) or \
                 `energy` (an energy w(I1, I2, J) as text)"
                    .into(),
            ))
        }
        None => registered_law(m)?,
    };
    let law = match super::fibres::material_fibres(m, mesh, law.fibre_families())? {
        Some(f) => law.with_fibres(std::sync::Arc::new(f))?,
        None => law,
    };
    // the material's own volumetric keys, else [solver]'s, else the element form
    let volumetric = match (&m.volumetric, &solver.volumetric) {
        (Some(v), _) => Some((v, m.volumetric_stabilization.or(solver.volumetric_stabilization))),
        (None, Some(v)) => Some((v, m.volumetric_stabilization.or(solver.volumetric_stabilization))),
        (None, None) if m.volumetric_stabilization.is_some() || solver.volumetric_stabilization.is_some() => {
            return Err(HemlError::Invalid(
                "volumetric_stabilization is given but volumetric = \"nodal\" or \"patch\" is not".into(),
            ))
        }
        (None, None) => None,
    };
    Ok(match volumetric {
        Some((v, stab)) => law.with_volumetric(crate::material::Volumetric::parse(v, stab)?)?,
        None => law,
    })
}

/// The registered law `m.law` with `m.params`.
fn registered_law(m: &MaterialSpec) -> Result<Box<dyn crate::Material>> {
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
    Ok(law)
}
