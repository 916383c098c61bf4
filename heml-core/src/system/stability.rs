//! Stable time-step estimate for the explicit integrators.
//!
//! Undamped central-difference-type schemes (symplectic Euler, velocity Verlet) are
//! stable for dt < dt_crit = 2/ω_max, ω_max² the largest eigenvalue of M⁻¹K.
//!
//! **The estimate is the system's own ω_max**, by power iteration on M^(−½) K M^(−½)
//! over the free degrees of freedom, with K·u evaluated by central directional
//! differences of the elastic forces at the rest positions
//! ([`power_iteration_time_step`]): dt_crit = 2/√λ_max, for every kind of law. It is
//! tight: on gen_kidney_20k and sofa_liver (neo-Hookean, ν = 0.45, undamped
//! symplectic Euler from a random velocity, 3000 steps) the run stays bounded at
//! 0.97 × the estimate and blows up at 1.03 ×. The Rayleigh quotient approaches
//! λ_max from below, so a slowly converging iteration errs on the unsafe side:
//! hence the safety factor, and what follows when it has not converged within
//! [`REST_ITERATIONS`]. Cost: about 40–90 pairs of force evaluations (19 ms on
//! 20k tets, 190 ms on 100k, once at build, after a runtime change of the
//! constrained set or of a law).
//!
//! **When it does not settle: Lanczos.** Structured meshes (the generated boxes and
//! beams) have clusters of nearly equal top modes, and the power iteration's error
//! shrinks like (λ₂/λ₁)^k: on the example scene's beam it was still 5e-5 below λ_max
//! after 20 000 iterations. The Lanczos recurrence on the same products
//! ([`LANCZOS_ITERATIONS`] at most) converges in tens of steps whatever the gap, also
//! from below; its estimate is the measured limit there too (undamped symplectic
//! Euler bounded at 0.9×, unbounded at 1.1×; a test). Only when neither settles is
//! the wave-speed bound used (the example scene took it before Lanczos: 17 % more
//! steps, 1 714 against 1 416).
//!
//! **Last fallback: the wave-speed bound** of the invariant laws — the dilatational wave
//! speed c = √((λ+2μ)/ρ), with μ and λ the small-strain moduli of the law obtained
//! numerically from [`Material::stress`] at rest ([`lame_at_rest`]), crossing the
//! smallest tet height h_min of the region: dt ≈ h_min / c
//! ([`wave_speed_time_step`]), the CFL bound of a 1D lumped-mass element. In 3D the
//! ratio dt_crit/(h_min/c) of lumped P1 tets was measured between 0.95 and 1.13 on
//! structured and jittered box meshes (see the tests), so the wave estimate is
//! multiplied by [`WAVE_FACTOR`] = 0.8. It is safe but pessimistic on meshes from tet
//! generators, where the smallest height belongs to a sliver whose nodes carry the
//! mass of their larger neighbours: the power iteration's step is 1.9–2.5× larger on
//! the generated kidneys and blobs and 3.5× on sofa_liver. Earlier versions used
//! this bound for invariant laws; it is now used only when neither the power
//! iteration nor Lanczos converges. The adaptive step ([`super::AdaptiveStep`]) still measures
//! stiffening with wave speeds, calibrated to the rest estimate.
//!
//! Damping lowers the limit: with the modal damping ratio ξ = α/(2ω) + βω/2 at
//! ω = ω_max, dt_crit = (2/ω)(√(1+ξ²) − ξ), evaluated as (2/ω)/(hypot(1, ξ) + ξ):
//! the same number without the cancellation, and without the overflow of ξ² that
//! made an absurd damping (`[damping] mass = 1e200`) give an infinite estimate,
//! reported as a law without stiffness. Heavy damping gives a tiny step instead
//! (dt ≲ 2/α), which [`System::damping_note`] names. The estimate returned is
//! `safety × dt_crit` ([`DEFAULT_SAFETY`] = 0.9, configurable). Explicit (forward)
//! Euler is unstable for undamped oscillations at any dt; the estimate concerns the
//! symplectic schemes.
//!
//! **This estimate is made at rest.** Large compression stiffens most laws: for
//! neo-Hookean with ν = 0.45 the volumetric stiffness λ(1 − ln J)/J² is ~12× its rest
//! value at J = 0.4 (where the J0 extension freezes it), and a tet squeezed to a
//! tenth of its height is ~10× stiffer across it, so dt_crit shrinks by 3–10×.
//! [`TimeStepPolicy::Adapt`] follows the deformation instead (see
//! [`super::AdaptiveStep`], which re-estimates from the current stretches); with a
//! fixed step, scenes that crush tissue need a smaller safety factor. The NaN guard
//! stops a run that goes unstable and names the step and node.

use super::{Region, System};
use crate::error::Result;
use crate::force::ForceOptions;
use crate::law::LawKind;
use crate::material::Material;
use crate::Vec3;
use nalgebra::Matrix3;

/// Default safety factor applied to the critical time step.
pub const DEFAULT_SAFETY: f64 = 0.9;

/// Most power iterations spent on the rest estimate before falling back to the
/// wave-speed bound (the organ meshes measured converge in 40–90).
pub const REST_ITERATIONS: usize = 500;

/// Ratio applied to the wave-speed estimate h_min/c to bound 2/ω_max of lumped P1
/// tetrahedra from below (measured ratio 0.95–1.13 on box and jittered meshes).
pub const WAVE_FACTOR: f64 = 0.8;

/// What a step larger than the stable estimate does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeStepPolicy {
    /// Issue a warning (once per system: logged with `log::warn!` and kept in
    /// [`System::warnings`](crate::system::System::warnings)) and go on.
    #[default]
    Warn,
    /// Refuse the step with an error.
    Refuse,
    /// Say nothing.
    Ignore,
    /// Follow the stiffness: the step is re-estimated from the current deformation
    /// every few steps, lowered before the estimate is exceeded and raised back with
    /// hysteresis ([`super::AdaptiveStep`]; the scene runner does this). A step given
    /// straight to [`super::System::begin_step`] is not checked against the rest
    /// estimate under this policy: the controller owns the step size.
    Adapt,
}

/// Small-strain shear modulus μ and Lamé λ of an invariant law at rest, by central
/// differences of its first Piola–Kirchhoff stress: μ = ∂P12/∂F12 in simple shear,
/// λ + 2μ = ∂P11/∂F11 in uniaxial strain (step 1e-6: truncation O(1e-12) relative,
/// round-off ~1e-10 relative). `None` for link laws or non-finite results.
pub fn lame_at_rest(material: &dyn Material, opts: &ForceOptions) -> Option<(f64, f64)> {
    let s = 1e-6;
    let p = |i: usize, j: usize, d: f64| -> Option<f64> {
        let mut f = Matrix3::identity();
        f[(i, j)] += d;
        material.stress(&f, opts).map(|(_, p)| p[(i, j)])
    };
    let mu = (p(0, 1, s)? - p(0, 1, -s)?) / (2.0 * s);
    let m = (p(0, 0, s)? - p(0, 0, -s)?) / (2.0 * s);
    (mu.is_finite() && m.is_finite()).then_some((mu, m - 2.0 * mu))
}

/// Smallest height of a tet: 3·Vol / (largest face area).
pub(crate) fn min_height(sys: &System, tets: &[usize]) -> f64 {
    crate::mesh::quality::mesh_quality(sys.mesh(), Some(tets)).map_or(f64::INFINITY, |q| q.min_height.0)
}

/// The wave-speed part of the estimate for one region: `Some(WAVE_FACTOR·h_min/c)`,
/// or `None` when the law gives no positive modulus (link laws).
fn region_wave_dt(sys: &System, r: &Region, opts: &ForceOptions) -> Option<f64> {
    if r.material.kind() == LawKind::Link {
        return None;
    }
    let (mu, lambda) = lame_at_rest(&*r.material, opts)?;
    let modulus = lambda + 2.0 * mu;
    if !(modulus > 0.0 && modulus.is_finite()) {
        return None;
    }
    let c = (modulus / r.density).sqrt();
    Some(WAVE_FACTOR * min_height(sys, r.field.tet_ids()) / c)
}

/// Undamped critical time step from the wave speed of every invariant region
/// (`None` when there is none, e.g. link laws only). Regions are evaluated with the
/// default [`ForceOptions`] (the moduli at rest do not depend on J0).
pub fn wave_speed_time_step(sys: &System) -> Option<f64> {
    let opts = ForceOptions::default();
    sys.regions()
        .iter()
        .filter_map(|r| region_wave_dt(sys, r, &opts))
        .reduce(f64::min)
}

/// Undamped critical time step 2/√λ_max of M⁻¹K by power iteration over all regions
/// (free nodes only; ∞ when nothing is free or nothing is stiff), with K the tangent at
/// the current positions (the system's own estimate uses the rest positions).
pub fn power_iteration_time_step(sys: &System, max_iter: usize) -> Result<f64> {
    let (lambda, _) = power_iteration(sys, sys.positions(), |_| true, max_iter)?;
    Ok(if lambda > 0.0 {
        2.0 / lambda.sqrt()
    } else {
        f64::INFINITY
    })
}

/// y = M^(−½) K M^(−½) u over the free nodes and the regions `keep` accepts, with K
/// the tangent at positions `x`, applied by central directional differences of the
/// elastic forces: what [`power_iteration`] and [`lanczos`] iterate.
struct ScaledStiffness<'a, F> {
    sys: &'a System,
    x: &'a [Vec3],
    keep: F,
    /// M^(−½) on the free nodes, 0 on the others.
    s: Vec<f64>,
    xp: Vec<Vec3>,
    xm: Vec<Vec3>,
    fp: Vec<Vec3>,
    fm: Vec<Vec3>,
}

impl<'a, F: Fn(&Region) -> bool + Copy> ScaledStiffness<'a, F> {
    /// `None` when no node is free.
    fn new(sys: &'a System, x: &'a [Vec3], keep: F) -> Option<Self> {
        let n = sys.positions().len();
        let s: Vec<f64> = (0..n)
            .map(|i| {
                if sys.is_free(i) {
                    1.0 / sys.masses()[i].sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        if s.iter().all(|&v| v == 0.0) {
            return None;
        }
        Some(ScaledStiffness {
            sys,
            x,
            keep,
            s,
            xp: x.to_vec(),
            xm: x.to_vec(),
            fp: vec![Vec3::zeros(); n],
            fm: vec![Vec3::zeros(); n],
        })
    }

    /// A deterministic, well-mixed start vector on the free nodes (never orthogonal
    /// to the top mode in practice), not normalised.
    fn start(&self) -> Vec<Vec3> {
        let mut next = crate::sampling::uniform(0x9E37_79B9_7F4A_7C15_u64);
        self.s
            .iter()
            .map(|si| Vec3::new(next(), next(), next()) * si.signum())
            .collect()
    }

    /// y = M^(−½) K M^(−½) u for a unit `u` (K w ≈ −(f(x + εw) − f(x − εw)) / 2ε,
    /// w = M^(−½) u, ε a millionth of the body's size over the largest |w_i|).
    fn apply(&mut self, u: &[Vec3]) -> Result<Vec<Vec3>> {
        let s = &self.s;
        let wmax = u.iter().zip(s).map(|(v, si)| v.norm() * si).fold(0.0, f64::max);
        let eps = 1e-6 * self.sys.model.length_scale / wmax;
        for i in 0..u.len() {
            self.xp[i] = self.x[i] + u[i] * (s[i] * eps);
            self.xm[i] = self.x[i] - u[i] * (s[i] * eps);
        }
        self.sys.elastic_forces_at(&self.xp, &mut self.fp, self.keep)?;
        self.sys.elastic_forces_at(&self.xm, &mut self.fm, self.keep)?;
        Ok((0..u.len())
            .map(|i| (self.fm[i] - self.fp[i]) * (s[i] / (2.0 * eps)))
            .collect())
    }
}

fn norm(u: &[Vec3]) -> f64 {
    u.iter().map(|v| v.norm_squared()).sum::<f64>().sqrt()
}

fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(p, q)| p.dot(q)).sum()
}

/// The largest eigenvalue of M^(−½) K M^(−½) over the regions `keep` accepts, and
/// whether the Rayleigh quotient settled (relative change ≤ 1e-7) within `max_iter`.
/// K is the tangent at positions `x`.
pub(super) fn power_iteration(
    sys: &System,
    x: &[Vec3],
    keep: impl Fn(&Region) -> bool + Copy,
    max_iter: usize,
) -> Result<(f64, bool)> {
    let Some(mut op) = ScaledStiffness::new(sys, x, keep) else {
        return Ok((0.0, true));
    };
    let mut u = op.start();
    let mut lambda = 0.0;
    for it in 0..max_iter {
        let norm = norm(&u);
        if norm == 0.0 {
            return Ok((lambda, true));
        }
        u.iter_mut().for_each(|v| *v /= norm);
        let y = op.apply(&u)?;
        let new = dot(&u, &y);
        u = y;
        let converged = it > 10 && (new - lambda).abs() <= 1e-7 * new.abs();
        lambda = new;
        if converged {
            return Ok((lambda.abs(), true));
        }
    }
    Ok((lambda.abs(), false))
}

/// Most Lanczos steps of [`lanczos`] (each one product, as a power iteration's).
pub const LANCZOS_ITERATIONS: usize = 200;

/// The largest eigenvalue of M^(−½) K M^(−½) (as [`power_iteration`]) by the Lanczos
/// recurrence, and whether it settled: the largest eigenvalue θ of the tridiagonal
/// T_k grew by at most 1e-9 θ in each of the last three steps. Why: when the top
/// modes cluster (the symmetric modes of a structured mesh) the power iteration's
/// error shrinks like (λ₂/λ₁)^k and it does not settle in [`REST_ITERATIONS`], while
/// the Lanczos estimate converges in tens of steps whatever the gap. θ_k never
/// exceeds λ_max and grows with k (Cauchy interlacing), so the test errs, like the
/// power iteration's, on the side the safety factor covers. No reorthogonalisation:
/// its loss of orthogonality only repeats converged eigenvalues, not the largest's
/// value.
pub(super) fn lanczos(
    sys: &System,
    x: &[Vec3],
    keep: impl Fn(&Region) -> bool + Copy,
    max_iter: usize,
) -> Result<(f64, bool)> {
    let Some(mut op) = ScaledStiffness::new(sys, x, keep) else {
        return Ok((0.0, true));
    };
    let mut v = op.start();
    let n0 = norm(&v);
    v.iter_mut().for_each(|c| *c /= n0);
    let mut v_prev = vec![Vec3::zeros(); v.len()];
    let (mut alphas, mut betas) = (Vec::new(), Vec::new());
    let (mut theta, mut steady) = (0.0_f64, 0);
    for _ in 0..max_iter {
        let mut w = op.apply(&v)?;
        let alpha = dot(&w, &v);
        let beta_prev = betas.last().copied().unwrap_or(0.0);
        for i in 0..w.len() {
            w[i] -= v[i] * alpha + v_prev[i] * beta_prev;
        }
        alphas.push(alpha);
        let next = tridiagonal_max(&alphas, &betas);
        steady = if next - theta <= 1e-9 * next.abs() {
            steady + 1
        } else {
            0
        };
        theta = next;
        let beta = norm(&w);
        // an invariant subspace: T's eigenvalues are the operator's
        if steady >= 3 || beta <= 1e-12 * theta.abs() {
            return Ok((theta.abs(), true));
        }
        betas.push(beta);
        w.iter_mut().for_each(|c| *c /= beta);
        v_prev = std::mem::replace(&mut v, w);
    }
    Ok((theta.abs(), false))
}

/// The largest eigenvalue of the symmetric tridiagonal matrix with diagonal `a` and
/// off-diagonal `b` (`b.len() + 1 == a.len()`), by bisection on Sturm counts between
/// its Gershgorin bounds, to 1e-14 of their span.
pub(super) fn tridiagonal_max(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len();
    let off = |i: usize| if i < b.len() { b[i].abs() } else { 0.0 };
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (i, &ai) in a.iter().enumerate() {
        let r = off(i) + if i > 0 { off(i - 1) } else { 0.0 };
        lo = lo.min(ai - r);
        hi = hi.max(ai + r);
    }
    // eigenvalues above t: the count of negative pivots of T − t·I (Sturm)
    let above = |t: f64| -> usize {
        let mut d = 1.0;
        let mut count = 0;
        for (i, &ai) in a.iter().enumerate() {
            let b2 = if i > 0 { b[i - 1] * b[i - 1] } else { 0.0 };
            d = ai - t - if i > 0 { b2 / d } else { 0.0 };
            if d == 0.0 {
                d = f64::MIN_POSITIVE;
            }
            if d < 0.0 {
                count += 1;
            }
        }
        n - count
    };
    let span = hi - lo;
    while hi - lo > 1e-14 * span.max(f64::MIN_POSITIVE) {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if above(mid) >= 1 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The stable time-step estimate of a system (see the module docs): the critical step
/// 2/ω_max by power iteration (the wave-speed bound when that does not settle),
/// reduced for damping (and for the springs of its grasps, see
/// [`super::control`]) and multiplied by the system's safety factor. ∞ when no node
/// is free.
pub fn stable_time_step(sys: &System) -> f64 {
    damped_safe(sys, critical_time_step(sys))
}

/// The undamped critical step 2/ω_max of the elastic regions at rest (no safety
/// factor): the part of [`stable_time_step`] that depends on the laws, the mesh and
/// the set of free nodes only — not on the current state, so that a runtime change
/// of the constrained set gives the step a system built with it would have.
pub(crate) fn critical_time_step(sys: &System) -> f64 {
    if (0..sys.positions().len()).all(|i| !sys.is_free(i)) {
        return f64::INFINITY;
    }
    let settled = |l: f64| {
        if l > 0.0 && l.is_finite() {
            2.0 / l.sqrt()
        } else {
            f64::INFINITY
        }
    };
    match power_iteration(sys, sys.rest_positions(), |_| true, REST_ITERATIONS) {
        Ok((l, true)) => return settled(l),
        Ok((l, false)) => log::info!(
            "stable step: the power iteration did not settle in {REST_ITERATIONS} iterations \
             (last estimate {l:e}); trying Lanczos"
        ),
        Err(e) => {
            log::info!("stable step: power iteration failed ({e}); using the wave-speed bound");
            return wave_or_link_time_step(sys);
        }
    }
    match lanczos(sys, sys.rest_positions(), |_| true, LANCZOS_ITERATIONS) {
        Ok((l, true)) => settled(l),
        Ok((l, false)) => {
            log::info!(
                "stable step: Lanczos did not settle in {LANCZOS_ITERATIONS} steps either (last estimate \
                 {l:e}); using the wave-speed bound"
            );
            wave_or_link_time_step(sys)
        }
        Err(e) => {
            log::info!("stable step: Lanczos failed ({e}); using the wave-speed bound");
            wave_or_link_time_step(sys)
        }
    }
}

/// The fallback of [`critical_time_step`]: the wave-speed bound of the invariant
/// regions and a (bounded, possibly unconverged) power iteration over the others.
fn wave_or_link_time_step(sys: &System) -> f64 {
    let opts = ForceOptions::default();
    let mut dt = f64::INFINITY;
    let mut others = false;
    for r in sys.regions() {
        match region_wave_dt(sys, r, &opts) {
            Some(d) => dt = dt.min(d),
            None => others = true,
        }
    }
    if others {
        let keep = |r: &Region| region_wave_dt(sys, r, &opts).is_none();
        match power_iteration(sys, sys.rest_positions(), keep, 300) {
            Ok((l, _)) if l > 0.0 => dt = dt.min(2.0 / l.sqrt()),
            _ => {}
        }
    }
    dt
}

/// An undamped critical step reduced for the system's Rayleigh damping and
/// multiplied by its safety factor (see the module docs); ∞ stays ∞.
///
/// Grasp springs (stiffness k, damping c on a node of mass m) add k to the diagonal
/// of K and c to the mass-proportional damping of their nodes, so the estimate uses
/// ω² = ω_el² + max_i Σk/m_i (a Gershgorin-type bound on the largest eigenvalue of
/// M⁻¹(K + K_grasp)) and α + max_i Σc/m_i as mass damping: a grasp limits the step
/// only when it is stiffer than the tissue under it.
pub(crate) fn damped_safe(sys: &System, dt: f64) -> f64 {
    let (gk, gc) = sys.model.grasps.rates(&sys.model.inv_mass);
    let d = sys.damping();
    if gk == 0.0 && gc == 0.0 {
        if !dt.is_finite() {
            return dt;
        }
        return sys.safety() * dt * damping_factor(d.alpha, d.beta, 2.0 / dt);
    }
    let omega_el = if dt.is_finite() { 2.0 / dt } else { 0.0 };
    let omega = (omega_el * omega_el + gk).sqrt();
    if omega == 0.0 {
        return f64::INFINITY;
    }
    sys.safety() * (2.0 / omega) * damping_factor(d.alpha + gc, d.beta, omega)
}

/// √(1+ξ²) − ξ, the factor by which Rayleigh damping (mass α, stiffness β) cuts the
/// critical step of the mode ω (ξ = α/(2ω) + βω/2), written 1/(hypot(1, ξ) + ξ):
/// no cancellation for large ξ and no overflow of ξ² (an infinite ξ gives 0).
fn damping_factor(alpha: f64, beta: f64, omega: f64) -> f64 {
    let xi = damping_ratio(alpha, beta, omega);
    1.0 / (1.0_f64.hypot(xi) + xi)
}

/// The modal damping ratio ξ = α/(2ω) + βω/2 of Rayleigh damping at the mode ω.
fn damping_ratio(alpha: f64, beta: f64, omega: f64) -> f64 {
    alpha / (2.0 * omega) + beta * omega / 2.0
}

impl System {
    /// A note for messages about the step when the system's damping is what makes the
    /// stable estimate small (it cuts the undamped step by more than half): without
    /// it, a huge `[damping]` value shows up only as a step count too large to run.
    pub(crate) fn damping_note(&self) -> Option<String> {
        let d = self.damping();
        let dt = self.stepping.critical_dt;
        if !(dt.is_finite() && dt > 0.0) || (d.alpha == 0.0 && d.beta == 0.0) {
            return None;
        }
        let omega = 2.0 / dt;
        let factor = damping_factor(d.alpha, d.beta, omega);
        (factor < 0.5).then(|| {
            format!(
                "the Rayleigh damping (mass {:e} 1/s, stiffness {:e} s) sets it: its damping ratio {:.3e} at the \
                 highest frequency ({omega:.3e} rad/s) cuts the undamped stable step {dt:.3e} s by a factor \
                 {:.3e}; lower the damping",
                d.alpha,
                d.beta,
                damping_ratio(d.alpha, d.beta, omega),
                1.0 / factor
            )
        })
    }

    /// Why the stable estimate is infinite although some node is free: a region
    /// whose forces are not finite a little away from the rest shape (a parameter too
    /// large to evaluate, such as an Ogden exponent of 1e300: the estimate then
    /// measures nothing), else no stiffness at rest (a zero modulus). The two used to
    /// be reported alike, as the second.
    pub(crate) fn infinite_estimate_reason(&self) -> String {
        let rest = self.rest_positions();
        let eps = 1e-6 * self.model.length_scale;
        let mut next = crate::sampling::uniform(0x9E37_79B9_7F4A_7C15_u64);
        let x: Vec<Vec3> = rest
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let u = Vec3::new(next(), next(), next());
                if self.is_free(i) {
                    p + u * eps
                } else {
                    *p
                }
            })
            .collect();
        let mut f = vec![Vec3::zeros(); x.len()];
        for r in self.regions() {
            let finite = self.elastic_forces_at(&x, &mut f, |q| std::ptr::eq(q, r)).is_ok()
                && f.iter().all(|v| v.iter().all(|c| c.is_finite()));
            if !finite {
                let m = &r.material;
                return format!(
                    "the forces of material law '{}' ({}) are not finite within {eps:.1e} m of the rest shape: a \
                 parameter too large to evaluate in floating point",
                    m.name(),
                    crate::registry::with_values(m.param_info(), &m.param_values(), "")
                );
            }
        }
        "the materials give no stiffness at rest (a zero modulus or spring constant in [[material]] params?)".into()
    }
}
