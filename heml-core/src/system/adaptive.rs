//! The adaptive time step of [`TimeStepPolicy::Adapt`](super::TimeStepPolicy): a
//! step that follows the stiffness of the deformed tissue.
//!
//! The rest-state estimate ([`super::stable_time_step`]) is too large once tissue is
//! crushed: a tet squeezed to a tenth of its height is about ten times stiffer across
//! it, and its volumetric stiffness grows as J falls. [`DeformedEstimate`] redoes the
//! wave-speed estimate of the invariant regions on the current state, cheaply — one
//! parallel pass over the tets and a handful of stress evaluations per region:
//!
//! * per tet, the deformation gradient F = D_s D_m⁻¹ (D_m⁻¹ stored once), J = det F
//!   and tr C = |F|²; the region keeps J_min and the largest tr C, which bound
//!   every principal stretch of its tets between the two uniaxial stretches with
//!   these invariants (`stretch_bounds`; exact at rest and in uniaxial squeeze);
//! * the law's tangent ∂P_ii/∂F_ii (central differences of [`Material::stress`],
//!   with the system's J0 extension) at the deformations those extremes describe — a
//!   uniaxial squeeze diag(λ_min, a, a) and the uniaxial stretch diag(λ_max, b, b)
//!   at J_min,
//!   a pure volume change J_min^⅓ I, and rest — gives the largest modulus A;
//! * the undamped step is κ·[`WAVE_FACTOR`]·h_min / √(A/ρ₀) with the rest heights and
//!   density (a reference-configuration wave speed), reduced for damping and
//!   multiplied by the safety factor exactly like the rest estimate — which it
//!   equals at rest: κ is the ratio of the system's critical step (its measured
//!   ω_max, see [`super::stability`]) to the wave-speed bound at rest, fixed when the
//!   estimate is built. The wave speeds measure how much the tissue has stiffened;
//!   κ carries what the bound misses about the mesh (1.9–3.5 on organ meshes).
//!
//! Combining the extremes of different tets is conservative (their worst case need
//! not occur in one tet). Link-law regions have no continuum tangent: they keep the
//! system's rest estimate.
//!
//! [`AdaptiveStep`] runs the estimate every `every` steps and decides: lower the step
//! at once when the estimate — extrapolated one check ahead when it is falling, so
//! that the step is lowered *before* it is exceeded — drops below it; raise it back
//! by at most 25 % per check and only when the estimate is 25 % above it
//! (hysteresis, so that the step does not flicker); never above the base step (the
//! requested or rest-state one).

use nalgebra::Matrix3;
use rayon::prelude::*;

use super::stability::{damped_safe, min_height, WAVE_FACTOR};
use super::System;
use crate::force::ForceOptions;
use crate::law::LawKind;
use crate::material::Material;

/// Default number of steps between two re-estimates of the adaptive step: frequent
/// enough that a crush at tool speed (a few per cent of strain per check at the
/// stable step) is caught by the one-check extrapolation, rare enough that the
/// estimate (one pass over the tets: about 2/3 of a step of symplectic Euler on
/// 100k tets) costs ~3 % of a run (benches/adaptive_step.rs).
pub const DEFAULT_ADAPT_EVERY: u64 = 20;

/// Largest factor by which the adaptive step grows per check, and the margin by
/// which the estimate must exceed the step before it grows (hysteresis).
const RAISE: f64 = 1.25;

/// Why a step has the size it has: the `dt_reason` column of `energy.csv`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DtReason {
    /// A fixed step (`dt_policy` other than `adapt`).
    Fixed,
    /// The base step (requested, or the rest estimate): the deformation does not
    /// limit it.
    Base,
    /// Below the base step because the deformed tissue is stiffer.
    Stiffness,
    /// Being raised back towards the base step after a stiff phase.
    Recovering,
}

impl DtReason {
    /// The CSV spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            DtReason::Fixed => "fixed",
            DtReason::Base => "base",
            DtReason::Stiffness => "stiffness",
            DtReason::Recovering => "recovering",
        }
    }
}

/// The per-region data of the deformed estimate.
#[derive(Debug)]
struct RegionGeometry {
    /// Index into [`System::regions`].
    region: usize,
    /// Node ids of each tet of the region.
    tets: Vec<[u32; 4]>,
    /// D_m⁻¹ of each tet (rest edge matrix inverse).
    dm_inv: Vec<Matrix3<f64>>,
    /// Smallest rest height of the region's tets.
    h0: f64,
}

/// Extremes of the deformation over a region's tets.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stretches {
    /// Largest tr C = |F|².
    tr_c_max: f64,
    /// Smallest J.
    j_min: f64,
}

impl Stretches {
    const REST: Stretches = Stretches {
        tr_c_max: 3.0,
        j_min: 1.0,
    };
    fn merge(self, o: Stretches) -> Stretches {
        Stretches {
            tr_c_max: self.tr_c_max.max(o.tr_c_max),
            j_min: self.j_min.min(o.j_min),
        }
    }
}

/// The stable-step estimate of the current deformation (see the module docs).
#[derive(Debug)]
pub struct DeformedEstimate {
    regions: Vec<RegionGeometry>,
    /// κ: the system's critical step over the wave-speed bound of its invariant
    /// regions when the estimate was built (1 when either is not finite).
    calibration: f64,
}

impl DeformedEstimate {
    /// Precomputes D_m⁻¹ and the rest heights of the invariant regions of `sys`.
    pub fn new(sys: &System) -> DeformedEstimate {
        let rest = sys.rest_positions();
        let all = sys.mesh().tets();
        let regions = sys
            .regions()
            .iter()
            .enumerate()
            .filter(|(_, r)| r.material.kind() != LawKind::Link)
            .map(|(region, r)| {
                let ids = r.field.tet_ids();
                let tets: Vec<[u32; 4]> = ids.iter().map(|&t| all[t]).collect();
                let dm_inv = tets
                    .iter()
                    .map(|t| {
                        let p = t.map(|i| rest[i as usize]);
                        Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]])
                            .try_inverse()
                            .unwrap_or_else(Matrix3::zeros)
                    })
                    .collect();
                RegionGeometry {
                    region,
                    tets,
                    dm_inv,
                    h0: min_height(sys, ids),
                }
            })
            .collect();
        let critical = sys.stepping.critical_dt;
        let calibration = match super::stability::wave_speed_time_step(sys) {
            Some(wave) if wave > 0.0 && wave.is_finite() && critical.is_finite() => critical / wave,
            _ => 1.0,
        };
        DeformedEstimate { regions, calibration }
    }

    /// The stretch extremes of a region at the current positions.
    fn stretches(g: &RegionGeometry, sys: &System) -> Stretches {
        let x = sys.positions();
        g.tets
            .par_iter()
            .zip(g.dm_inv.par_iter())
            .with_min_len(4096)
            .fold(
                || Stretches::REST,
                |acc, (t, m)| {
                    let [a, b, c, d] = crate::mesh::corners(x, t);
                    let (e1, e2, e3) = (b - a, c - a, d - a);
                    // the columns of F = D_s D_m⁻¹
                    let col = |j: usize| e1 * m[(0, j)] + e2 * m[(1, j)] + e3 * m[(2, j)];
                    let (f0, f1, f2) = (col(0), col(1), col(2));
                    let j = f0.dot(&f1.cross(&f2));
                    let tr_c = f0.norm_squared() + f1.norm_squared() + f2.norm_squared();
                    Stretches {
                        tr_c_max: acc.tr_c_max.max(tr_c),
                        j_min: acc.j_min.min(j),
                    }
                },
            )
            .reduce(|| Stretches::REST, Stretches::merge)
    }

    /// The stable step of the current state (safety and damping applied, like
    /// [`System::stable_dt`]) and the smallest J over the invariant regions (1 when
    /// there is none). Link regions contribute the system's rest estimate.
    pub fn time_step(&self, sys: &System) -> (f64, f64) {
        let opts = sys.force_options();
        let mut dt = f64::INFINITY;
        let mut j_min = 1.0_f64;
        for g in &self.regions {
            let r = &sys.regions()[g.region];
            let s = Self::stretches(g, sys);
            j_min = j_min.min(s.j_min);
            let a = largest_modulus(&*r.material, &s, &opts, !r.material.inversion_fix());
            if a > 0.0 && a.is_finite() {
                dt = dt.min(self.calibration * WAVE_FACTOR * g.h0 / (a / r.density).sqrt());
            }
        }
        let mut dt = damped_safe(sys, dt);
        if self.regions.len() < sys.regions().len() {
            dt = dt.min(sys.stable_dt());
        }
        (dt, j_min)
    }
}

/// The largest diagonal tangent ∂P_ii/∂F_ii of `material` over the deformations the
/// stretch extremes describe (see the module docs). Stretches and J are floored at
/// 1e-3: an inverted tet (J ≤ 0) of a law with the inversion fix is in its J0
/// extension, whose tangent is frozen below J0, so the floor only keeps the probes
/// finite. A law physical through inversion (`inverted_probes`: no inversion fix)
/// is also probed at the inverted states with |J_min|.
fn largest_modulus(material: &dyn Material, s: &Stretches, opts: &ForceOptions, inverted_probes: bool) -> f64 {
    const FLOOR: f64 = 1e-3;
    let j = s.j_min.clamp(FLOOR, 1.0);
    let (l, big) = stretch_bounds(s.tr_c_max.max(3.0 * j.powf(2.0 / 3.0)), j);
    let l = l.max(FLOOR);
    let squeeze = Matrix3::from_diagonal(&nalgebra::Vector3::new(l, (j / l).sqrt(), (j / l).sqrt()));
    let stretch = Matrix3::from_diagonal(&nalgebra::Vector3::new(big, (j / big).sqrt(), (j / big).sqrt()));
    let volume = Matrix3::identity() * j.cbrt();
    let upright = [squeeze, stretch, volume, Matrix3::identity()];
    // inverted tets: the same probes turned inside out (one stretch negative) at
    // |J_min|, for the laws that are physical there (stable neo-Hookean's energy is
    // defined through inversion and stiffens as a tet turns over; the clamped probes
    // above saw it soften as J fell to 0, and a crush diverged once tets inverted).
    // Not for the laws with the J0 extension: their probes at negative J measured
    // stiffer than their inverted tets behave (the crushed kidney took 2x the steps
    // with neo-Hookean, 8x with Mooney–Rivlin, and was stable without).
    let inverted = (inverted_probes && s.j_min < 0.0).then(|| {
        let j = (-s.j_min).max(FLOOR);
        let (l, big) = stretch_bounds(s.tr_c_max.max(3.0 * j.powf(2.0 / 3.0)), j);
        let l = l.max(FLOOR);
        let flip = |a: f64, b: f64| Matrix3::from_diagonal(&nalgebra::Vector3::new(-a, b, b));
        [
            flip(l, (j / l).sqrt()),
            flip(big, (j / big).sqrt()),
            flip(j.cbrt(), j.cbrt()),
        ]
    });
    upright
        .iter()
        .chain(inverted.iter().flatten())
        .map(|f| diagonal_tangent(material, f, opts))
        .fold(0.0, f64::max)
}

/// Bounds of the principal stretches of any deformation with tr C ≤ `tr_c` and
/// J ≥ `j` > 0: λ₁ has λ₂λ₃ = J/λ₁ and λ₂² + λ₃² = tr C − λ₁² ≥ 2λ₂λ₃, so every
/// stretch λ satisfies g(λ) = λ² + 2J/λ ≤ tr C, and lies between the two positive
/// roots of g = tr C — the uniaxial states diag(λ, b, b) with these invariants. Both
/// are found by Newton's method on the convex g, from 2J/tr C (left of the small
/// root) and from √tr C (right of the large one), which converges monotonically. At
/// rest (3, 1) both are 1.
fn stretch_bounds(tr_c: f64, j: f64) -> (f64, f64) {
    let newton = |mut l: f64| {
        for _ in 0..100 {
            let f = l * l + 2.0 * j / l - tr_c;
            let df = 2.0 * l - 2.0 * j / (l * l);
            let step = f / df;
            if !(step.is_finite() && step.abs() > 1e-14 * l) {
                break;
            }
            l -= step;
        }
        l
    };
    (newton(2.0 * j / tr_c).min(1.0), newton(tr_c.sqrt()).max(1.0))
}

/// max_i ∂P_ii/∂F_ii at `f` by central differences (relative step 1e-6: truncation
/// O(1e-12), round-off ~1e-10 relative — far below the estimate's own accuracy).
fn diagonal_tangent(material: &dyn Material, f: &Matrix3<f64>, opts: &ForceOptions) -> f64 {
    let mut best = 0.0_f64;
    for i in 0..3 {
        let h = 1e-6 * f[(i, i)].abs().max(1e-3);
        let p = |d: f64| {
            let mut g = *f;
            g[(i, i)] += d;
            material.stress(&g, opts).map(|(_, p)| p[(i, i)])
        };
        if let (Some(a), Some(b)) = (p(h), p(-h)) {
            let t = (a - b) / (2.0 * h);
            if t.is_finite() {
                best = best.max(t);
            }
        }
    }
    best
}

/// The step controller of [`TimeStepPolicy::Adapt`](super::TimeStepPolicy) (see the
/// module docs): call [`AdaptiveStep::next`] before every step.
#[derive(Debug)]
pub struct AdaptiveStep {
    estimate: DeformedEstimate,
    base: f64,
    dt: f64,
    every: u64,
    calls: u64,
    last: f64,
    reason: DtReason,
    min_j: f64,
    checks: u64,
    /// The system's [`System::topology_version`] and laws version
    /// ([`System::set_material`]) the estimate was built for.
    topology: (u64, u64),
}

impl AdaptiveStep {
    /// A controller for `sys` whose step never exceeds `base` (> 0), re-estimated
    /// every `every` (≥ 1) steps.
    pub fn new(sys: &System, base: f64, every: u64) -> AdaptiveStep {
        AdaptiveStep {
            estimate: DeformedEstimate::new(sys),
            base,
            dt: base,
            every: every.max(1),
            calls: 0,
            last: f64::INFINITY,
            reason: DtReason::Base,
            min_j: 1.0,
            checks: 0,
            topology: (sys.topology_version(), sys.model.laws_version),
        }
    }

    /// The step to take now and why; re-estimates every `every` calls (the first
    /// call included).
    pub fn next(&mut self, sys: &System) -> (f64, DtReason) {
        let now = (sys.topology_version(), sys.model.laws_version);
        if now != self.topology {
            // a cut removed tets or a law changed: the estimate follows, and is
            // checked now
            self.estimate = DeformedEstimate::new(sys);
            self.topology = now;
            self.calls = 0;
        }
        if self.calls.is_multiple_of(self.every) {
            self.check(sys);
        }
        self.calls += 1;
        (self.dt, self.reason)
    }

    fn check(&mut self, sys: &System) {
        let (e, j) = self.estimate.time_step(sys);
        self.checks += 1;
        self.min_j = self.min_j.min(j);
        // falling: assume it falls as much again before the next check
        let predicted = if e < self.last && self.last.is_finite() {
            e * (e / self.last)
        } else {
            e
        };
        self.last = e;
        // within 1e-6 of the base: the finite-difference tangents' accuracy at rest
        let target = if predicted >= self.base * (1.0 - 1e-6) {
            self.base
        } else {
            predicted
        };
        let before = self.dt;
        if target < self.dt {
            self.dt = target;
        } else if target >= RAISE * self.dt || (target == self.base && self.dt < self.base) {
            // (the base itself is reached even from within the band)
            self.dt = (self.dt * RAISE).min(target);
        }
        self.reason = if self.dt >= self.base {
            DtReason::Base
        } else if self.dt > before {
            DtReason::Recovering
        } else {
            DtReason::Stiffness
        };
    }

    /// The current step.
    pub fn dt(&self) -> f64 {
        self.dt
    }
    /// The largest step it may take.
    pub fn base(&self) -> f64 {
        self.base
    }
    /// The smallest J over the invariant regions seen at any check so far.
    pub fn min_j(&self) -> f64 {
        self.min_j
    }
    /// Re-estimates done so far.
    pub fn checks(&self) -> u64 {
        self.checks
    }
}
