//! [`SystemBuilder`]: describes a system in a few chained calls and checks everything
//! at [`SystemBuilder::build`] (errors, never panics).

use super::constraints::{Constraints, Prescribed, Ramp};
use super::control::Grasps;
use super::parts::{Diagnostics, Evaluation, Model, Scratch, Snapshot, State, Stepping};
use super::prony::{validate_prony, PronyState, PronyTerm};
use super::stability::{critical_time_step, damped_safe, TimeStepPolicy, DEFAULT_SAFETY};
use super::{Rayleigh, Region, System};
use crate::error::{HemlError, Result};
use crate::force::ForceOptions;
use crate::material::{Material, Volumetric};
use crate::mesh::surface::BoundarySurface;
use crate::mesh::TetMesh;
use crate::params::Params;
use crate::registry::find_material;
use crate::Vec3;
use std::borrow::Borrow;

#[derive(Debug)]
struct RegionSpec {
    tag: Option<i32>,
    material: Box<dyn Material>,
    density: Option<f64>,
    prony: Vec<PronyTerm>,
}

/// Describes a [`System`]; see the [module example](super).
///
/// * Materials: [`material`](Self::material) covers every tet that no
///   [`region`](Self::region) claims; a region covers the tets of one mesh tag. Every
///   tet needs a material. [`prony`](Self::prony) and
///   [`region_density`](Self::region_density) apply to the material or region declared
///   last.
/// * Masses are lumped, m_i = Σ ρ Vol_k / 4, with each tet's region density (default
///   [`density`](Self::density), itself 1000 kg/m³ unless set).
/// * Nodes that belong to no tet would have no mass: they are an error naming them,
///   unless [`pin_unreferenced`](Self::pin_unreferenced) asks to fix them in place
///   (with a warning).
pub struct SystemBuilder {
    mesh: TetMesh,
    regions: Vec<RegionSpec>,
    density: f64,
    gravity: Vec3,
    fixed: Vec<usize>,
    prescribed: Vec<Prescribed>,
    nodal: Vec<(usize, Vec3)>,
    initial_velocity: Option<Vec<Vec3>>,
    damping: Rayleigh,
    opts: ForceOptions,
    policy: TimeStepPolicy,
    safety: f64,
    energy_every: u64,
    lazy_energy: bool,
    pin_unreferenced: bool,
    input_ids: Option<Vec<usize>>,
    problems: Vec<String>,
}

impl std::fmt::Debug for SystemBuilder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SystemBuilder")
            .field("regions", &self.regions)
            .field("density", &self.density)
            .field("gravity", &self.gravity)
            .finish_non_exhaustive()
    }
}

impl SystemBuilder {
    /// A builder on `mesh` with no material, density 1000, no gravity, no constraints.
    pub fn new(mesh: TetMesh) -> Self {
        SystemBuilder {
            mesh,
            regions: Vec::new(),
            density: 1000.0,
            gravity: Vec3::zeros(),
            fixed: Vec::new(),
            prescribed: Vec::new(),
            nodal: Vec::new(),
            initial_velocity: None,
            damping: Rayleigh::default(),
            opts: ForceOptions::default(),
            policy: TimeStepPolicy::default(),
            safety: DEFAULT_SAFETY,
            energy_every: 1,
            lazy_energy: false,
            pin_unreferenced: false,
            input_ids: None,
            problems: Vec::new(),
        }
    }

    /// The law registered as `name`, with `params`, for every tet no region claims.
    /// Unknown names and bad parameters are errors here.
    pub fn material(self, name: &str, params: impl Borrow<Params>) -> Result<Self> {
        let law = find_material(name)?.instantiate(params.borrow())?;
        Ok(self.material_law(law))
    }

    /// The law registered as `name` for the tets tagged `tag`.
    pub fn region(self, tag: i32, name: &str, params: impl Borrow<Params>) -> Result<Self> {
        let law = find_material(name)?.instantiate(params.borrow())?;
        Ok(self.region_law(tag, law))
    }

    /// An already built law for every tet no region claims (replaces a previous one).
    pub fn material_law(mut self, material: Box<dyn Material>) -> Self {
        self.regions.retain(|r| r.tag.is_some());
        self.regions.push(RegionSpec {
            tag: None,
            material,
            density: None,
            prony: Vec::new(),
        });
        self
    }

    /// An already built law for the tets tagged `tag`.
    pub fn region_law(mut self, tag: i32, material: Box<dyn Material>) -> Self {
        if self.regions.iter().any(|r| r.tag == Some(tag)) {
            self.problems
                .push(format!("region tag {tag} is given a material twice"));
        }
        self.regions.push(RegionSpec {
            tag: Some(tag),
            material,
            density: None,
            prony: Vec::new(),
        });
        self
    }

    /// Density of the material or region declared last (overrides [`Self::density`]).
    pub fn region_density(mut self, density: f64) -> Self {
        match self.regions.last_mut() {
            Some(r) => r.density = Some(density),
            None => self
                .problems
                .push("region_density() called before any material or region".into()),
        }
        self
    }

    /// Prony series of the material or region declared last (DESIGN §1): Σα_i < 1,
    /// τ_i > 0.
    pub fn prony(mut self, terms: &[PronyTerm]) -> Self {
        match self.regions.last_mut() {
            Some(r) => r.prony = terms.to_vec(),
            None => self
                .problems
                .push("prony() called before any material or region".into()),
        }
        self
    }

    /// Volumetric formulation of the material or region declared last (e.g.
    /// [`Volumetric::nodal`] against volumetric locking of nearly incompressible
    /// tissue; see [`crate::force::nodal_volume`]). Link laws refuse it at `build()`.
    pub fn volumetric(mut self, v: Volumetric) -> Self {
        match self.regions.last_mut() {
            Some(r) => match r.material.with_volumetric(v) {
                Ok(m) => r.material = m,
                Err(e) => self.problems.push(e.to_string()),
            },
            None => self
                .problems
                .push("volumetric() called before any material or region".into()),
        }
        self
    }

    /// Default density of every region (> 0).
    pub fn density(mut self, density: f64) -> Self {
        self.density = density;
        self
    }

    /// Gravity acceleration, applied as m_i g on every node.
    pub fn gravity(mut self, g: Vec3) -> Self {
        self.gravity = g;
        self
    }

    /// Holds these nodes at their rest positions.
    pub fn fix_nodes<I>(mut self, ids: I) -> Self
    where
        I: IntoIterator,
        I::Item: Borrow<usize>,
    {
        self.fixed.extend(ids.into_iter().map(|i| *i.borrow()));
        self
    }

    /// Holds the nodes whose rest position satisfies `pred`.
    pub fn fix_where(mut self, pred: impl Fn(&Vec3) -> bool) -> Self {
        let ids: Vec<usize> = (0..self.mesh.n_nodes())
            .filter(|&i| pred(&self.mesh.nodes()[i]))
            .collect();
        if ids.is_empty() {
            self.problems.push("fix_where() matched no node".into());
        }
        self.fixed.extend(ids);
        self
    }

    /// Moves these nodes by `displacement` following `ramp`: x = X + r(t)·u.
    pub fn prescribe<I>(self, ids: I, displacement: Vec3, ramp: Ramp) -> Self
    where
        I: IntoIterator,
        I::Item: Borrow<usize>,
    {
        self.prescribe_with(ids, |_| displacement, ramp)
    }

    /// Moves each of these nodes by its own displacement `u(X)` following `ramp`.
    pub fn prescribe_with<I>(mut self, ids: I, u: impl Fn(&Vec3) -> Vec3, ramp: Ramp) -> Self
    where
        I: IntoIterator,
        I::Item: Borrow<usize>,
    {
        for node in ids.into_iter().map(|i| *i.borrow()) {
            // out-of-range ids are kept (with no displacement) and reported by build()
            let displacement = self.mesh.nodes().get(node).map_or(Vec3::zeros(), &u);
            self.prescribed.push(Prescribed {
                node,
                displacement,
                ramp: ramp.clone(),
            });
        }
        self
    }

    /// A constant force on node `id` (accumulates).
    pub fn nodal_force(mut self, id: usize, force: Vec3) -> Self {
        self.nodal.push((id, force));
        self
    }

    /// Rayleigh damping −α m_i v_i − β K v (α, β ≥ 0).
    pub fn rayleigh(mut self, alpha_mass: f64, beta_stiffness: f64) -> Self {
        self.damping = Rayleigh {
            alpha: alpha_mass,
            beta: beta_stiffness,
        };
        self
    }

    /// Initial velocity as a function of the rest position (constrained nodes get
    /// their constraint's velocity instead).
    pub fn initial_velocity(mut self, v: impl Fn(&Vec3) -> Vec3) -> Self {
        self.initial_velocity = Some(self.mesh.nodes().iter().map(v).collect());
        self
    }

    /// Options of the force kernels (inversion threshold J0…).
    pub fn force_options(mut self, opts: ForceOptions) -> Self {
        self.opts = opts;
        self
    }

    /// What a step larger than the stable estimate does (default: warn once).
    pub fn time_step_policy(mut self, policy: TimeStepPolicy) -> Self {
        self.policy = policy;
        self
    }

    /// Safety factor in (0, 1] applied to the critical time step (default
    /// [`DEFAULT_SAFETY`]).
    pub fn safety(mut self, safety: f64) -> Self {
        self.safety = safety;
        self
    }

    /// Compute the energies of [`super::StepStats`] every `n` steps (0: never;
    /// default 1).
    pub fn energy_every(mut self, n: u64) -> Self {
        self.energy_every = n;
        self
    }

    /// Let explicit steps evaluate the forces without the elastic energy where a
    /// field can skip it (the fibre laws' fields: ~10 % per force evaluation for
    /// Holzapfel–Gasser–Ogden, whose `ln J` serves its energy alone), except on the
    /// steps that report energies ([`Self::energy_every`]). [`System::elastic_energy`]
    /// then evaluates the energy when asked, at the cost of one more force
    /// evaluation: for loops that never read it (a haptic loop, a run without
    /// `energy.csv`). Default off. The forces and the trajectory are the same bits.
    ///
    /// ```
    /// use heml_core::mesh::generate::{box_mesh, HexSplit};
    /// use heml_core::{material::Invariant, Params, RuntimeLaw, System};
    ///
    /// let law = RuntimeLaw::from_energy("mu/2*(I1-3) - mu*ln(J) + lambda/2*ln(J).powi(2)",
    ///     &Params::from([("mu", 1e3), ("lambda", 1e4)]))?;
    /// let mut sys = System::builder(box_mesh([0.02, 0.01, 0.01], [4, 2, 2], HexSplit::Six)?)
    ///     .material_law(Box::new(Invariant(law)))
    ///     .density(1000.0)
    ///     .energy_every(0)
    ///     .lazy_energy(true)
    ///     .build()?;
    /// sys.compute_forces()?;
    /// // evaluated when asked: at rest, zero to round-off
    /// assert!(sys.elastic_energy()?.abs() < 1e-12);
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    ///
    /// [`System::elastic_energy`]: super::System::elastic_energy
    pub fn lazy_energy(mut self, on: bool) -> Self {
        self.lazy_energy = on;
        self
    }

    /// Fix nodes that belong to no tet (with a warning) instead of refusing the mesh.
    pub fn pin_unreferenced(mut self) -> Self {
        self.pin_unreferenced = true;
        self
    }

    /// The id to show for each node in messages: `ids[i]` names node `i` (one per
    /// node). A caller that renumbered the mesh (e.g. for memory locality) passes the
    /// original ids so that errors and warnings name nodes as its users know them.
    /// The ids given to the other builder calls stay those of the builder's mesh.
    pub fn input_node_ids(mut self, ids: Vec<usize>) -> Self {
        self.input_ids = Some(ids);
        self
    }

    /// Checks everything and builds the system.
    pub fn build(self) -> Result<System> {
        if let Some(p) = self.problems.first() {
            return invalid(p.clone());
        }
        let mesh = self.mesh;
        let n = mesh.n_nodes();
        if let Some(ids) = &self.input_ids {
            if ids.len() != n {
                return invalid(format!(
                    "input_node_ids() got {} ids, but the mesh has {n} nodes (one id per node)",
                    ids.len()
                ));
            }
        }
        // the caller's id of node i (only called with ids already checked to be in range)
        let shown = |i: usize| self.input_ids.as_ref().map_or(i, |ids| ids[i]);
        let check_id = |what: &str, i: usize| -> Result<()> {
            if i >= n {
                return invalid(format!(
                    "{what} node id {i} is out of range (the mesh has {n} nodes, ids 0..{})",
                    n.saturating_sub(1)
                ));
            }
            Ok(())
        };
        for &i in &self.fixed {
            check_id("fixed", i)?;
        }
        for p in &self.prescribed {
            check_id("prescribed", p.node)?;
            if !p.displacement.iter().all(|c| c.is_finite()) {
                return invalid(format!(
                    "prescribed displacement of node {} is not finite",
                    shown(p.node)
                ));
            }
            p.ramp.validate()?;
        }
        for &(i, f) in &self.nodal {
            check_id("nodal force", i)?;
            if !f.iter().all(|c| c.is_finite()) {
                return invalid(format!(
                    "nodal force on node {} is not finite: {:?}",
                    shown(i),
                    f.as_slice()
                ));
            }
        }
        let mut mask = vec![false; n];
        let mut fixed = self.fixed;
        fixed.sort_unstable();
        fixed.dedup();
        for &i in &fixed {
            mask[i] = true;
        }
        let mut prescribed_mask = vec![false; n];
        for p in &self.prescribed {
            if mask[p.node] && !prescribed_mask[p.node] {
                return invalid(format!("node {} is both fixed and prescribed", shown(p.node)));
            }
            if prescribed_mask[p.node] {
                return invalid(format!("node {} is prescribed twice", shown(p.node)));
            }
            prescribed_mask[p.node] = true;
            mask[p.node] = true;
        }
        if !(self.density.is_finite() && self.density > 0.0) {
            return invalid(format!("density {} must be a finite number > 0", self.density));
        }
        if !self.gravity.iter().all(|c| c.is_finite()) {
            return invalid(format!("gravity {:?} is not finite", self.gravity.as_slice()));
        }
        let Rayleigh { alpha, beta } = self.damping;
        if !(alpha.is_finite() && alpha >= 0.0 && beta.is_finite() && beta >= 0.0) {
            return invalid(format!(
                "Rayleigh coefficients alpha = {alpha}, beta = {beta} must be finite and >= 0"
            ));
        }
        if !(self.safety.is_finite() && self.safety > 0.0 && self.safety <= 1.0) {
            return invalid(format!("safety factor {} must lie in (0, 1]", self.safety));
        }
        self.opts.validate()?;

        // regions and their tets
        if self.regions.is_empty() {
            return invalid("no material: call .material(name, params) or .region(tag, name, params)".into());
        }
        let mut claimed = vec![false; mesh.n_tets()];
        let mut specs: Vec<(RegionSpec, Vec<usize>)> = Vec::new();
        let mut base = None;
        for spec in self.regions {
            let density = spec.density.unwrap_or(self.density);
            if !(density.is_finite() && density > 0.0) {
                return invalid(format!(
                    "density {density} of {} must be a finite number > 0",
                    describe(&spec)
                ));
            }
            validate_prony(&spec.prony).map_err(|e| HemlError::Invalid(format!("{}: {e}", describe(&spec))))?;
            match spec.tag {
                None => base = Some(spec),
                Some(tag) => {
                    let tets = mesh.tets_with_tag(tag);
                    if tets.is_empty() {
                        return invalid(format!(
                            "region tag {tag} has no tets (the mesh's tags are {:?})",
                            mesh.distinct_tags()
                        ));
                    }
                    for &t in &tets {
                        claimed[t] = true;
                    }
                    specs.push((spec, tets));
                }
            }
        }
        let rest: Vec<usize> = (0..mesh.n_tets()).filter(|&t| !claimed[t]).collect();
        match base {
            Some(spec) if !rest.is_empty() => specs.push((spec, rest)),
            Some(_) => {}
            None if !rest.is_empty() => {
                let mut tags: Vec<i32> = rest.iter().map(|&t| mesh.tags()[t]).collect();
                tags.dedup();
                tags.sort_unstable();
                tags.dedup();
                return invalid(format!(
                    "{} tet(s) have no material (first: tet {}; tags {tags:?}); add .material(…) for all remaining tets",
                    rest.len(),
                    rest[0]
                ));
            }
            None => {}
        }
        let mut mass = vec![0.0; n];
        let mut regions = Vec::with_capacity(specs.len());
        for (spec, tets) in specs {
            let density = spec.density.unwrap_or(self.density);
            let field = spec.material.force_field(&mesh, Some(&tets), &self.opts)?;
            let mut in_region = vec![false; n];
            for &t in &tets {
                let share = density * mesh.weighted_volume(t) / 4.0;
                for &i in &mesh.tets()[t] {
                    mass[i as usize] += share;
                    in_region[i as usize] = true;
                }
            }
            let prony = (!spec.prony.is_empty()).then(|| {
                let nodes = (0..n).filter(|&i| in_region[i]).collect();
                PronyState::new(spec.prony.clone(), nodes)
            });
            regions.push(Region {
                tag: spec.tag,
                material: spec.material,
                field,
                density,
                prony,
            });
        }

        let mut warnings = Vec::new();
        let unreferenced = mesh.unreferenced_nodes();
        if !unreferenced.is_empty() {
            let mut ids: Vec<usize> = unreferenced.iter().map(|&i| shown(i)).collect();
            ids.sort_unstable();
            let listed: Vec<String> = ids.iter().take(20).map(|i| i.to_string()).collect();
            let list = format!(
                "{}{}",
                listed.join(", "),
                if unreferenced.len() > 20 { ", …" } else { "" }
            );
            if !self.pin_unreferenced {
                return invalid(format!(
                    "{} node(s) belong to no tet and would have no mass: ids {list} \
                     (remove them, or call .pin_unreferenced() to hold them in place)",
                    unreferenced.len()
                ));
            }
            let msg = format!(
                "{} unreferenced node(s) pinned in place: ids {list}",
                unreferenced.len()
            );
            log::warn!("{msg}");
            warnings.push(msg);
            for &i in &unreferenced {
                if !mask[i] {
                    mask[i] = true;
                    fixed.push(i);
                }
            }
        }

        let inv_mass = mass
            .iter()
            .zip(&mask)
            .map(|(m, c)| if *c { 0.0 } else { 1.0 / m })
            .collect();
        let constraints = Constraints {
            fixed,
            prescribed: self.prescribed,
            mask,
        };
        let constrained_ids = constraints.constrained_nodes();
        let (lo, hi) = mesh.bounding_box();
        let x = mesh.nodes().to_vec();
        let v = self.initial_velocity.unwrap_or_else(|| vec![Vec3::zeros(); n]);
        if let Some(i) = v.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
            return invalid(format!("initial velocity of node {} is not finite", shown(i)));
        }
        let mut sys = System {
            model: Model {
                mass,
                inv_mass,
                regions,
                constraints,
                constrained_ids,
                gravity: self.gravity,
                nodal: self.nodal,
                damping: self.damping,
                force_options: self.opts,
                length_scale: (hi - lo).norm(),
                input_ids: self.input_ids,
                surface: BoundarySurface::of_tet_mesh(&mesh),
                mesh,
                grasps: Grasps::default(),
                revision: 0,
                laws_version: 0,
                cut: Default::default(),
                surface_loads: Default::default(),
                tools: Default::default(),
            },
            state: State {
                x,
                v,
                t: 0.0,
                step: 0,
                in_step: None,
                snapshot: Snapshot::default(),
                free_scan: None,
            },
            eval: Evaluation {
                force: vec![Vec3::zeros(); n],
                reaction: vec![Vec3::zeros(); n],
                reaction_total: Vec3::zeros(),
                elastic_energy: None,
                forces_current: false,
                accepted_forces: false,
            },
            scratch: Scratch {
                buf: vec![Vec3::zeros(); n],
                elastic: vec![Vec3::zeros(); n],
            },
            stepping: Stepping {
                critical_dt: f64::INFINITY,
                stable_dt: f64::INFINITY,
                safety: self.safety,
                policy: self.policy,
                energy_every: self.energy_every,
                lazy_energy: self.lazy_energy,
            },
            diag: Diagnostics {
                warned: false,
                warnings,
            },
        };
        sys.apply_constraints(0.0);
        sys.stepping.critical_dt = critical_time_step(&sys);
        sys.stepping.stable_dt = damped_safe(&sys, sys.stepping.critical_dt);
        Ok(sys)
    }
}

fn invalid<T>(msg: String) -> Result<T> {
    Err(HemlError::Invalid(msg))
}

fn describe(spec: &RegionSpec) -> String {
    match spec.tag {
        Some(tag) => format!("region tag {tag} ({})", spec.material.name()),
        None => format!("material {}", spec.material.name()),
    }
}
