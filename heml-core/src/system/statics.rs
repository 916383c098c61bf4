//! Quasi-static equilibrium: Newton's method with a banded direct solve, and damped
//! dynamic relaxation as the general fallback.
//!
//! [`System::solve_static`] finds positions where the total force on every free node
//! vanishes — elastic forces plus gravity and nodal loads, with the constraints
//! (fixed nodes, prescribed displacements evaluated at the system's current time)
//! imposed. The residual is always the system's own (HEML) force.
//!
//! **Newton** (used when every region's law has a stress, i.e. invariant laws): the
//! tangent stiffness is assembled per tet from the law's first Piola–Kirchhoff stress,
//! K_e = Vol·Gᵀ (∂P/∂F) G, with ∂P/∂F by central differences of
//! [`crate::Material::stress`] (step 1e-6: ~1e-10 relative, ample for a Newton
//! tangent), the free degrees of freedom ordered by reverse Cuthill–McKee, and K
//! factored as a banded LDLᵀ (no pivoting; indefinite tangents, e.g. SVK past its
//! compression peak, are fine while no pivot vanishes). Each step is damped by
//! backtracking on the Euclidean residual norm. If the band is too wide for memory, a
//! pivot vanishes or the line search stalls, the solver continues with:
//!
//! **Dynamic relaxation** (any law): a fictitious, damped motion integrated until
//! it stops. The damping is FIRE (Bitzek et al., "Structural relaxation made simple", PRL 97 (2006), with
//! the FIRE 2.0 refinements of Guénolé et al., Comput. Mater. Sci. 175 (2020)):
//! semi-implicit Euler steps with the system's lumped masses, the velocity steered
//! towards the force direction (in mass-weighted coordinates), the step grown while
//! the motion goes downhill (power P = f·v > 0) and the velocity zeroed, with a
//! half-step back, as soon as it goes uphill. Each iteration costs one force
//! evaluation; steps never exceed the system's stable time step.
//!
//! **Convergence criterion**: max |f_i| over the free nodes ≤ `tol` × the load scale,
//! where the load scale is the largest nodal external load |m_i g + f_i,nodal| or
//! reaction force on a constrained node, whichever is larger (so displacement-driven
//! problems are measured against their reactions). A run that reaches
//! `max_iterations` first is an error that states the residual reached.
//!
//! Load stepping: [`System::set_load_time`] moves the clock (and with it the ramps of
//! prescribed displacements) without dynamics; solve again at each load level.
//!
//! ```
//! use heml_core::mesh::generate::{box_mesh, HexSplit};
//! use heml_core::system::{StaticOptions, System};
//! use heml_core::{material::Link, Vec3};
//! # use heml_core::law::*;
//! # #[derive(Debug, Clone, Copy)] struct Spring { k: f64 }
//! # impl MaterialInfo for Spring {
//! #     const NAME: &'static str = "doc_spring_static"; const PARAMS: &'static [ParamInfo] = &[];
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
//! // a spring-network cube hanging from its top face
//! let mesh = box_mesh([0.1, 0.1, 0.1], [2, 2, 2], HexSplit::Six)?;
//! let mut sys = System::builder(mesh)
//!     .material_law(Box::new(Link(Spring { k: 2000.0 })))
//!     .gravity(Vec3::new(0.0, 0.0, -9.81))
//!     .fix_where(|p| p.z > 0.1 - 1e-9)
//!     .build()?;
//! let report = sys.solve_static(&StaticOptions::default())?;
//! assert!(report.converged && report.relative_residual() <= 1e-6);
//! // at equilibrium the support carries the whole weight
//! let weight = sys.total_mass() * 9.81;
//! assert!((sys.total_reaction().z - weight).abs() < 1e-5 * weight);
//! # Ok::<(), heml_core::HemlError>(())
//! ```

use super::System;
use crate::error::{HemlError, Result};
use crate::force::ForceOptions;
use crate::rest::rest_edge_matrix;
use crate::Vec3;
use nalgebra::Matrix3;

/// One coordinate of a node held at a given value while the other two move freely:
/// a frictionless roller or symmetry-plane support, used by
/// [`System::solve_static_with`] (e.g. the unconstrained uniaxial test, whose
/// loaded faces must slide laterally).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slider {
    /// Node id.
    pub node: usize,
    /// Axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// The value the coordinate is held at.
    pub value: f64,
}

/// Settings of [`System::solve_static`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticOptions {
    /// Relative residual tolerance: converged when max |f_i| over the free nodes is
    /// at most `tol` × the load scale (default 1e-6).
    pub tol: f64,
    /// Absolute residual (N) below which the solve counts as converged whatever the
    /// load scale (default 0: off; useful for unloaded systems).
    pub abs_tol: f64,
    /// Iteration (force evaluation) cap (default 500 000).
    pub max_iterations: usize,
    /// Print the residual to stderr every this many iterations (0: silent, default).
    pub progress_every: usize,
}

impl Default for StaticOptions {
    fn default() -> Self {
        StaticOptions {
            tol: 1e-6,
            abs_tol: 0.0,
            max_iterations: 500_000,
            progress_every: 0,
        }
    }
}

/// What a quasi-static solve reached.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticReport {
    /// Whether the criterion was met (always true in an `Ok` result).
    pub converged: bool,
    /// Iterations (force evaluations) used.
    pub iterations: usize,
    /// Final max |f_i| over the free nodes.
    pub residual: f64,
    /// Final load scale: max over nodes of |external load| and |reaction|.
    pub load_scale: f64,
    /// The relative tolerance asked for.
    pub tol: f64,
    /// Reaction force component on each slider of [`System::solve_static_with`], in
    /// the order given (empty for [`System::solve_static`]).
    pub slider_reactions: Vec<f64>,
}

impl StaticReport {
    /// residual / load scale (0 when both vanish).
    pub fn relative_residual(&self) -> f64 {
        if self.load_scale > 0.0 {
            self.residual / self.load_scale
        } else if self.residual == 0.0 {
            0.0
        } else {
            f64::INFINITY
        }
    }

    /// The criterion in words, with the values reached, e.g.
    /// `max|f_free| / max|load| = 3.1e-7 <= 1e-6 (1234 it.)`.
    pub fn criterion(&self) -> String {
        format!(
            "max|f_free| / max|load| = {:.1e} {} {:.0e} ({} it.)",
            self.relative_residual(),
            if self.converged { "<=" } else { ">" },
            self.tol,
            self.iterations
        )
    }
}

// FIRE 2.0 parameters (Guénolé et al. 2020, table 1).
const N_DELAY: usize = 20;
const F_INC: f64 = 1.1;
const F_DEC: f64 = 0.5;
const ALPHA0: f64 = 0.25;
const F_ALPHA: f64 = 0.99;

impl System {
    /// Moves the clock to `t` without any dynamics and imposes the constraints there
    /// (prescribed displacements follow their ramps): the load parameter of a
    /// quasi-static load-stepping loop. Velocities are zeroed.
    pub fn set_load_time(&mut self, t: f64) -> Result<()> {
        if !t.is_finite() {
            return Err(HemlError::Invalid(format!("load time {t} must be finite")));
        }
        self.t = t;
        self.v.fill(Vec3::zeros());
        self.invalidate();
        self.apply_constraints(t);
        Ok(())
    }

    /// Largest nodal external load |m_i g + f_nodal| and reaction |r_i| (reactions
    /// from the last force evaluation).
    fn load_scale(&self) -> f64 {
        let mut ext: Vec<Vec3> = self.mass.iter().map(|m| self.gravity * *m).collect();
        for &(i, f) in &self.nodal {
            ext[i] += f;
        }
        let loads = ext.iter().map(|f| f.norm()).fold(0.0, f64::max);
        let reactions = self
            .constrained_ids
            .iter()
            .map(|&i| self.reaction[i].norm())
            .fold(0.0, f64::max);
        loads.max(reactions)
    }

    /// The convergence state after `it` iterations: the largest force on a free
    /// degree of freedom against the tolerance scaled by the largest load or slider
    /// reaction (or the absolute tolerance, whichever is larger).
    fn static_report(&self, slider_reactions: &[f64], opts: &StaticOptions, it: usize) -> StaticReport {
        let residual = self.free_residual();
        let scale = slider_reactions.iter().fold(self.load_scale(), |m, r| m.max(r.abs()));
        StaticReport {
            converged: residual <= (opts.tol * scale).max(opts.abs_tol),
            iterations: it,
            residual,
            load_scale: scale,
            tol: opts.tol,
            slider_reactions: slider_reactions.to_vec(),
        }
    }

    fn free_residual(&self) -> f64 {
        // forces on constrained nodes are zeroed by compute_forces
        self.force.iter().map(|f| f.norm()).fold(0.0, f64::max)
    }

    /// Relaxes the system to static equilibrium at the current time (see the
    /// [module docs](self) for the method and the criterion). Rayleigh damping is
    /// switched off during the solve and restored afterwards; velocities end at zero.
    ///
    /// Errors: non-finite forces (with the node), or no convergence within
    /// `max_iterations` (the message states the residual reached; the system keeps
    /// the last iterate).
    pub fn solve_static(&mut self, opts: &StaticOptions) -> Result<StaticReport> {
        self.solve_static_with(&[], opts)
    }

    /// [`System::solve_static`] with additional single-coordinate supports
    /// ([`Slider`]s) on top of the system's constraints. Their reaction components
    /// are returned in [`StaticReport::slider_reactions`] and count in the load scale.
    pub fn solve_static_with(&mut self, sliders: &[Slider], opts: &StaticOptions) -> Result<StaticReport> {
        if let Some(s) = sliders
            .iter()
            .find(|s| s.node >= self.x.len() || s.axis > 2 || !s.value.is_finite())
        {
            return Err(HemlError::Invalid(format!(
                "slider on node {} axis {} at {}: node or axis out of range, or value not finite",
                s.node, s.axis, s.value
            )));
        }
        if !(opts.tol.is_finite() && opts.tol > 0.0 && opts.abs_tol.is_finite() && opts.abs_tol >= 0.0) {
            return Err(HemlError::Invalid(format!(
                "static tolerances tol = {}, abs_tol = {} must be finite, tol > 0, abs_tol >= 0",
                opts.tol, opts.abs_tol
            )));
        }
        let damping = std::mem::take(&mut self.damping);
        let result = match self.newton(sliders, opts) {
            Ok(Some(report)) => Ok(report),
            Ok(None) => self.fire(sliders, opts),
            Err(e) => Err(e),
        };
        self.damping = damping;
        self.v.fill(Vec3::zeros());
        self.invalidate();
        result
    }

    fn fire(&mut self, sliders: &[Slider], opts: &StaticOptions) -> Result<StaticReport> {
        let t = self.t;
        self.v.fill(Vec3::zeros());
        self.apply_constraints(t);
        self.apply_sliders(sliders);
        let mut slider_reactions = vec![0.0; sliders.len()];
        let dt_max = self.stable_dt;
        if !(dt_max.is_finite() && dt_max > 0.0) {
            return Err(HemlError::Numerical(format!(
                "quasi-static solve: no usable stable time step ({dt_max})"
            )));
        }
        let dt_min = 0.02 * dt_max;
        let mut dt = 0.5 * dt_max;
        let mut alpha = ALPHA0;
        let mut n_pos = 0usize;
        self.compute_forces()?;
        self.slider_forces(sliders, &mut slider_reactions);
        let mut it = 0usize;
        loop {
            let report = self.static_report(&slider_reactions, opts, it);
            let (residual, scale) = (report.residual, report.load_scale);
            if opts.progress_every > 0 && (it.is_multiple_of(opts.progress_every) || report.converged) {
                eprintln!(
                    "quasi-static: iteration {it:>7}  residual {residual:.3e}  relative {:.3e}  dt {dt:.2e}",
                    report.relative_residual()
                );
            }
            if report.converged {
                return Ok(report);
            }
            if it >= opts.max_iterations {
                return Err(HemlError::Numerical(format!(
                    "quasi-static solve did not converge in {it} iterations: residual max|f_free| = {residual:.3e} N, \
                     {:.3e} of the load scale {scale:.3e} N (tolerance {:.1e}); the system keeps the last iterate",
                    report.relative_residual(),
                    opts.tol
                )));
            }
            it += 1;
            let power: f64 = self.force.iter().zip(&self.v).map(|(f, v)| f.dot(v)).sum();
            if power > 0.0 {
                n_pos += 1;
                if n_pos > N_DELAY {
                    dt = (dt * F_INC).min(dt_max);
                    alpha *= F_ALPHA;
                }
            } else {
                n_pos = 0;
                dt = (dt * F_DEC).max(dt_min);
                alpha = ALPHA0;
                for (x, v) in self.x.iter_mut().zip(&mut self.v) {
                    *x -= *v * (0.5 * dt);
                    *v = Vec3::zeros();
                }
            }
            // semi-implicit Euler with FIRE mixing in mass-weighted coordinates:
            // v ← (1 − α) v + α (|√m v| / |f/√m|) f/m
            self.kick(dt);
            let (mut vv, mut ff) = (0.0, 0.0);
            for ((v, f), im) in self.v.iter().zip(&self.force).zip(&self.inv_mass) {
                if *im > 0.0 {
                    vv += v.norm_squared() / im;
                    ff += f.norm_squared() * im;
                }
            }
            if ff > 0.0 {
                let c = alpha * (vv / ff).sqrt();
                for ((v, f), im) in self.v.iter_mut().zip(&self.force).zip(&self.inv_mass) {
                    *v = *v * (1.0 - alpha) + f * (c * im);
                }
            }
            self.drift(dt);
            self.apply_constraints(t);
            self.apply_sliders(sliders);
            self.compute_forces()?;
            self.slider_forces(sliders, &mut slider_reactions);
        }
    }

    /// Newton iterations; `Ok(None)` when not applicable or stalled (then FIRE goes on
    /// from the current iterate).
    fn newton(&mut self, sliders: &[Slider], opts: &StaticOptions) -> Result<Option<StaticReport>> {
        let fopts = ForceOptions::default();
        if self
            .regions
            .iter()
            .any(|r| r.material.stress(&Matrix3::identity(), &fopts).is_none())
        {
            return Ok(None);
        }
        let t = self.t;
        let n = self.x.len();
        // degrees of freedom: free coordinates, nodes in reverse Cuthill–McKee order
        let mut held = vec![[false; 3]; n];
        for (i, h) in held.iter_mut().enumerate() {
            if self.constraints.is_constrained(i) {
                *h = [true; 3];
            }
        }
        for s in sliders {
            held[s.node][s.axis] = true;
        }
        let order = rcm_order(n, self.mesh.tets());
        let mut dof = vec![[usize::MAX; 3]; n];
        let mut ndof = 0;
        for &i in &order {
            for a in 0..3 {
                if !held[i][a] {
                    dof[i][a] = ndof;
                    ndof += 1;
                }
            }
        }
        if ndof == 0 {
            return Ok(None);
        }
        let mut band = 0;
        for tet in self.mesh.tets() {
            let ids: Vec<usize> = tet
                .iter()
                .flat_map(|&i| dof[i as usize])
                .filter(|&d| d != usize::MAX)
                .collect();
            if let (Some(lo), Some(hi)) = (ids.iter().min(), ids.iter().max()) {
                band = band.max(hi - lo);
            }
        }
        if ndof.saturating_mul(band + 1) > 40_000_000 {
            return Ok(None);
        }
        let dm_inv: Vec<Matrix3<f64>> = (0..self.mesh.n_tets())
            .map(|k| {
                rest_edge_matrix(&self.mesh.tet_points(k))
                    .try_inverse()
                    .unwrap_or_else(Matrix3::zeros)
            })
            .collect();
        self.v.fill(Vec3::zeros());
        self.apply_constraints(t);
        self.apply_sliders(sliders);
        let mut slider_reactions = vec![0.0; sliders.len()];
        self.compute_forces()?;
        self.slider_forces(sliders, &mut slider_reactions);
        let norm2 = |f: &[Vec3]| f.iter().map(|v| v.norm_squared()).sum::<f64>();
        let mut step_taken = 0.0;
        for it in 0..=50 {
            let report = self.static_report(&slider_reactions, opts, it);
            let residual = report.residual;
            if opts.progress_every > 0 {
                eprintln!(
                    "quasi-static Newton (step {step_taken}):: iteration {it:>3}  residual {residual:.3e}  relative {:.3e}",
                    report.relative_residual()
                );
            }
            if report.converged {
                return Ok(Some(report));
            }
            if it == 50 {
                break;
            }
            let mut k = BandLdl::new(ndof, band);
            self.assemble_tangent(&dof, &dm_inv, &fopts, &mut k);
            if !k.factor() {
                return Ok(None);
            }
            let mut rhs = vec![0.0; ndof];
            for (i, d) in dof.iter().enumerate() {
                for a in 0..3 {
                    if d[a] != usize::MAX {
                        rhs[d[a]] = self.force[i][a];
                    }
                }
            }
            k.solve(&mut rhs);
            let x0 = self.x.clone();
            let r0 = norm2(&self.force);
            let e0 = self.potential()?;
            let mut step = 1.0;
            let mut accepted = false;
            for _ in 0..12 {
                for (i, d) in dof.iter().enumerate() {
                    for a in 0..3 {
                        if d[a] != usize::MAX {
                            self.x[i][a] = x0[i][a] + step * rhs[d[a]];
                        }
                    }
                }
                self.invalidate();
                let ok = self.compute_forces().is_ok();
                if ok {
                    self.slider_forces(sliders, &mut slider_reactions);
                    // merit: the total potential (the Newton step descends it when K
                    // is positive definite), or else the residual norm
                    let e = self.potential()?;
                    if e <= e0 + 1e-13 * e0.abs() || norm2(&self.force) < r0 {
                        accepted = true;
                        step_taken = step;
                        break;
                    }
                }
                step *= 0.5;
            }
            if !accepted {
                self.x.copy_from_slice(&x0);
                self.invalidate();
                return Ok(None);
            }
        }
        Ok(None)
    }

    /// Adds the tangent stiffness K = −∂f/∂x of every region over the free DOFs.
    fn assemble_tangent(&self, dof: &[[usize; 3]], dm_inv: &[Matrix3<f64>], fopts: &ForceOptions, k: &mut BandLdl) {
        let h = 1e-6;
        for r in &self.regions {
            for &t in r.field.tet_ids() {
                let idx = self.mesh.tets()[t].map(|i| i as usize);
                let p = idx.map(|i| self.x[i]);
                let f = rest_edge_matrix(&p) * dm_inv[t];
                // A[(i,j),(k,l)] = ∂P_ij/∂F_kl by central differences
                let mut a = [[0.0; 9]; 9];
                for kk in 0..3 {
                    for ll in 0..3 {
                        let mut fp = f;
                        fp[(kk, ll)] += h;
                        let mut fm = f;
                        fm[(kk, ll)] -= h;
                        let (Some((_, pp)), Some((_, pm))) =
                            (r.material.stress(&fp, fopts), r.material.stress(&fm, fopts))
                        else {
                            continue;
                        };
                        for i in 0..3 {
                            for j in 0..3 {
                                a[3 * i + j][3 * kk + ll] = (pp[(i, j)] - pm[(i, j)]) / (2.0 * h);
                            }
                        }
                    }
                }
                let di = dm_inv[t];
                let mut g = [[0.0; 3]; 4];
                for (c, gc) in g.iter_mut().enumerate().skip(1) {
                    for j in 0..3 {
                        gc[j] = di[(c - 1, j)];
                    }
                }
                g[0] = std::array::from_fn(|j| -(g[1][j] + g[2][j] + g[3][j]));
                let vol = self.mesh.tet_volume(t);
                for na in 0..4 {
                    for i in 0..3 {
                        let row = dof[idx[na]][i];
                        if row == usize::MAX {
                            continue;
                        }
                        for nb in 0..4 {
                            for kk in 0..3 {
                                let col = dof[idx[nb]][kk];
                                if col == usize::MAX || col > row {
                                    continue;
                                }
                                let mut v = 0.0;
                                for j in 0..3 {
                                    for l in 0..3 {
                                        v += a[3 * i + j][3 * kk + l] * g[na][j] * g[nb][l];
                                    }
                                }
                                k.add(row, col, vol * v);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Elastic + gravity + load potential at the current positions.
    fn potential(&self) -> Result<f64> {
        let e = self.energies()?;
        Ok(e.elastic + e.gravity + e.loads)
    }

    fn apply_sliders(&mut self, sliders: &[Slider]) {
        for s in sliders {
            self.x[s.node][s.axis] = s.value;
            self.v[s.node][s.axis] = 0.0;
        }
        if !sliders.is_empty() {
            self.invalidate();
        }
    }

    /// Records the reaction of each slider and removes its force component.
    fn slider_forces(&mut self, sliders: &[Slider], reactions: &mut [f64]) {
        for (s, r) in sliders.iter().zip(reactions) {
            *r = -self.force[s.node][s.axis];
            self.force[s.node][s.axis] = 0.0;
        }
    }
}

/// Reverse Cuthill–McKee ordering of the nodes (graph of the tets' edges), which
/// keeps the stiffness matrix banded.
fn rcm_order(n: usize, tets: &[[u32; 4]]) -> Vec<usize> {
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); n];
    for t in tets {
        for &a in t {
            for &b in t {
                if a != b {
                    adj[a as usize].push(b as usize);
                }
            }
        }
    }
    for l in &mut adj {
        l.sort_unstable();
        l.dedup();
    }
    let bfs_last = |start: usize, seen: &mut Vec<bool>, out: &mut Vec<usize>| {
        let first = out.len();
        seen[start] = true;
        out.push(start);
        let mut head = first;
        while head < out.len() {
            let v = out[head];
            head += 1;
            let mut next: Vec<usize> = adj[v].iter().copied().filter(|&w| !seen[w]).collect();
            next.sort_by_key(|&w| adj[w].len());
            for w in next {
                seen[w] = true;
                out.push(w);
            }
        }
        out[out.len() - 1]
    };
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    for s in 0..n {
        if seen[s] {
            continue;
        }
        // a pseudo-peripheral start: the last node of a BFS from s
        let mut probe_seen = seen.clone();
        let mut probe = Vec::new();
        let start = bfs_last(s, &mut probe_seen, &mut probe);
        bfs_last(start, &mut seen, &mut order);
    }
    order.reverse();
    order
}

/// A symmetric banded matrix (lower band stored by rows) and its LDLᵀ factors.
struct BandLdl {
    n: usize,
    b: usize,
    /// Row i holds columns i−b..i−1 at [i·b .. (i+1)·b).
    low: Vec<f64>,
    diag: Vec<f64>,
}

impl BandLdl {
    fn new(n: usize, b: usize) -> Self {
        BandLdl {
            n,
            b,
            low: vec![0.0; n * b],
            diag: vec![0.0; n],
        }
    }

    /// Adds `v` at (row, col), col <= row.
    fn add(&mut self, row: usize, col: usize, v: f64) {
        if row == col {
            self.diag[row] += v;
        } else {
            self.low[row * self.b + col + self.b - row] += v;
        }
    }

    /// In-place LDLᵀ; false when a pivot vanishes or is not finite.
    fn factor(&mut self) -> bool {
        let (n, b) = (self.n, self.b);
        let scale = self.diag.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
        let mut u = vec![0.0; b];
        for i in 0..n {
            let j0 = i.saturating_sub(b);
            for j in j0..i {
                let k0 = j0.max(j.saturating_sub(b));
                let mut s = self.low[i * b + j + b - i];
                for k in k0..j {
                    s -= u[k + b - i] * self.low[j * b + k + b - j];
                }
                u[j + b - i] = s;
                self.low[i * b + j + b - i] = s / self.diag[j];
            }
            let mut d = self.diag[i];
            for j in j0..i {
                d -= u[j + b - i] * self.low[i * b + j + b - i];
            }
            if !(d.is_finite() && d.abs() > 1e-13 * scale) {
                return false;
            }
            self.diag[i] = d;
        }
        true
    }

    /// Solves (L D Lᵀ) x = r in place.
    #[allow(clippy::needless_range_loop)] // banded index arithmetic reads clearer
    fn solve(&self, r: &mut [f64]) {
        let (n, b) = (self.n, self.b);
        for i in 0..n {
            let mut s = r[i];
            for j in i.saturating_sub(b)..i {
                s -= self.low[i * b + j + b - i] * r[j];
            }
            r[i] = s;
        }
        for i in 0..n {
            r[i] /= self.diag[i];
        }
        for i in (0..n).rev() {
            let ri = r[i];
            for j in i.saturating_sub(b)..i {
                r[j] -= self.low[i * b + j + b - i] * ri;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn banded_ldl_solves_a_tridiagonal_system() {
        // −u'' = 1 discretised: tridiagonal (−1, 2, −1), plus an indefinite shift
        for shift in [0.0, -0.5] {
            let n = 50;
            let mut k = BandLdl::new(n, 2);
            for i in 0..n {
                k.add(i, i, 2.0 + shift);
                if i > 0 {
                    k.add(i, i - 1, -1.0);
                }
            }
            let mut x = vec![1.0; n];
            assert!(k.clone_factor_solve(&mut x));
            // residual check
            for i in 0..n {
                let mut ax = (2.0 + shift) * x[i];
                if i > 0 {
                    ax -= x[i - 1];
                }
                if i + 1 < n {
                    ax -= x[i + 1];
                }
                assert!((ax - 1.0).abs() < 1e-9, "row {i}: {ax}");
            }
        }
    }

    impl BandLdl {
        fn clone_factor_solve(&mut self, r: &mut [f64]) -> bool {
            if !self.factor() {
                return false;
            }
            self.solve(r);
            true
        }
    }

    #[test]
    fn rcm_orders_every_node_once() {
        let tets = [[0u32, 1, 2, 3], [1, 2, 3, 4], [5, 6, 7, 8]];
        let mut o = rcm_order(9, &tets);
        o.sort_unstable();
        assert_eq!(o, (0..9).collect::<Vec<_>>());
    }
}
