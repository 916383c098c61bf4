//! Unit tests of the system layer with hand-written laws (the registered laws live in
//! `heml-materials`, which `heml-core` cannot depend on).

use super::*;
use crate::force::ForceOptions;
use crate::law::{Derivs, InvariantLaw, LinkLaw, MaterialInfo, OpCount, ParamInfo};
use crate::material::{build_link, Invariant, Link};
use crate::mesh::generate::{box_mesh, HexSplit};
use crate::params::Params;
use crate::registry::MaterialEntry;

mod lazy_snapshot;
mod logging;
mod statics;

/// Mass–spring: w = k/2 (√l − √L)².
#[derive(Debug, Clone, Copy)]
struct Spring {
    k: f64,
}

impl MaterialInfo for Spring {
    const NAME: &'static str = "test_spring";
    const PARAMS: &'static [ParamInfo] = &[ParamInfo {
        name: "k",
        doc: "",
        signed: false,
    }];
    const ENERGY: &'static str = "k / 2.0 * (l.sqrt() - L.sqrt()).powi(2)";
    const DOC: &'static str = "Test spring.";
    fn to_params(&self) -> Vec<f64> {
        vec![self.k]
    }
    fn from_params(v: &[f64]) -> Self {
        Spring { k: v[0] }
    }
}

impl LinkLaw for Spring {
    const OPS: OpCount = OpCount {
        add: 0,
        mul: 0,
        div: 0,
        func: 0,
    };
    fn w(&self, l: f64, r: f64) -> f64 {
        0.5 * self.k * (l.sqrt() - r.sqrt()).powi(2)
    }
    fn dw(&self, l: f64, r: f64) -> (f64, f64) {
        (self.w(l, r), 0.5 * self.k * (1.0 - (r / l).sqrt()))
    }
    fn d2w(&self, l: f64, r: f64) -> f64 {
        0.25 * self.k * r.sqrt() / (l * l.sqrt())
    }
}

inventory::submit! {
    MaterialEntry {
        name: "test_spring",
        params: Spring::PARAMS,
        energy: Spring::ENERGY,
        volumetric: None,
        doc: Spring::DOC,
        kind: crate::law::LawKind::Link,
        module: module_path!(),
        build: build_link::<Spring>,
        small_strain: None,
        allow_prestress: false,
        rest: crate::law::rest_state_link::<Spring>,
    }
}

/// Compressible neo-Hookean w = μ/2 (I1 − 3) − μ ln J + λ/2 (ln J)², hand derivatives.
#[derive(Debug, Clone, Copy)]
struct NeoHookean {
    mu: f64,
    lambda: f64,
}

impl NeoHookean {
    fn wj(&self, j: f64) -> f64 {
        (-self.mu + self.lambda * j.ln()) / j
    }
    fn wjj(&self, j: f64) -> f64 {
        (self.mu + self.lambda * (1.0 - j.ln())) / (j * j)
    }
}

impl MaterialInfo for NeoHookean {
    const NAME: &'static str = "test_neo_hookean";
    const PARAMS: &'static [ParamInfo] = &[
        ParamInfo {
            name: "mu",
            doc: "",
            signed: false,
        },
        ParamInfo {
            name: "lambda",
            doc: "",
            signed: false,
        },
    ];
    const ENERGY: &'static str = "";
    const DOC: &'static str = "";
    fn to_params(&self) -> Vec<f64> {
        vec![self.mu, self.lambda]
    }
    fn from_params(v: &[f64]) -> Self {
        NeoHookean { mu: v[0], lambda: v[1] }
    }
}

impl InvariantLaw for NeoHookean {
    const USES_I2: bool = false;
    const USES_J: bool = true;
    const INVERSION_FIX: bool = true;
    const OPS: OpCount = OpCount {
        add: 0,
        mul: 0,
        div: 0,
        func: 0,
    };
    fn w(&self, i1: f64, _: f64, j: f64) -> f64 {
        self.mu / 2.0 * (i1 - 3.0) - self.mu * j.ln() + self.lambda / 2.0 * j.ln().powi(2)
    }
    fn dw(&self, i1: f64, i2: f64, j: f64) -> Derivs {
        Derivs {
            w: self.w(i1, i2, j),
            d: [self.mu / 2.0, 0.0, self.wj(j)],
        }
    }
    fn d2w(&self, _: f64, _: f64, j: f64) -> [[f64; 3]; 3] {
        [[0.0; 3], [0.0; 3], [0.0, 0.0, self.wjj(j)]]
    }
    fn w_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> f64 {
        let d = j - j0;
        self.w(i1, i2, j0) + self.wj(j0) * d + 0.5 * self.wjj(j0) * d * d
    }
    fn dw_ext(&self, i1: f64, i2: f64, j: f64, j0: f64) -> Derivs {
        Derivs {
            w: self.w_ext(i1, i2, j, j0),
            d: [self.mu / 2.0, 0.0, self.wj(j0) + self.wjj(j0) * (j - j0)],
        }
    }
    fn d2w_ext(&self, _: f64, _: f64, _: f64, j0: f64) -> [[f64; 3]; 3] {
        [[0.0; 3], [0.0; 3], [0.0, 0.0, self.wjj(j0)]]
    }
}

pub(super) fn neo(mu: f64, lambda: f64) -> Box<dyn crate::Material> {
    Box::new(Invariant(NeoHookean { mu, lambda }))
}

fn spring(k: f64) -> Box<dyn crate::Material> {
    Box::new(Link(Spring { k }))
}

/// Symplectic Euler written with the system primitives (the real integrators live in
/// `heml-integrators`).
fn step(sys: &mut System, dt: f64) -> Result<StepStats> {
    sys.begin_step(dt)?;
    sys.compute_forces()?;
    sys.kick(dt);
    sys.drift(dt);
    sys.finish_step()
}

/// A regular tetrahedron of edge 1, base (nodes 0–2) in z = 0, apex (node 3) above.
fn regular_tet() -> TetMesh {
    let r = 1.0 / 3f64.sqrt();
    let h = (2.0f64 / 3.0).sqrt();
    TetMesh::from_arrays(
        &[
            [r, 0.0, 0.0],
            [-r / 2.0, 0.5, 0.0],
            [-r / 2.0, -0.5, 0.0],
            [0.0, 0.0, h],
        ],
        &[[0, 1, 2, 3]],
    )
    .unwrap()
}

pub(super) fn cube() -> TetMesh {
    box_mesh([1.0, 1.0, 1.0], [2, 2, 2], HexSplit::Six).unwrap()
}

#[test]
fn builder_errors_name_the_culprit() {
    let err = |b: SystemBuilder| b.build().unwrap_err().to_string();
    let base = || System::builder(cube()).material_law(neo(1e3, 1e3));
    let e = err(base().fix_nodes([3, 999]));
    assert!(e.contains("fixed node id 999") && e.contains("27 nodes"), "{e}");
    let e = err(base().prescribe([1000], Vec3::x(), Ramp::Step));
    assert!(e.contains("prescribed node id 1000"), "{e}");
    let e = err(base().nodal_force(77, Vec3::x()));
    assert!(e.contains("nodal force node id 77"), "{e}");
    let e = err(base().nodal_force(7, Vec3::new(f64::NAN, 0.0, 0.0)));
    assert!(e.contains("node 7"), "{e}");
    let e = err(base().fix_nodes([4]).prescribe([4], Vec3::x(), Ramp::Step));
    assert!(e.contains("node 4 is both fixed and prescribed"), "{e}");
    let e = err(base().density(-1.0));
    assert!(e.contains("density -1"), "{e}");
    let e = err(base().density(f64::NAN));
    assert!(e.contains("density NaN"), "{e}");
    let e = err(base().region_law(5, neo(1.0, 1.0)));
    assert!(e.contains("tag 5 has no tets") && e.contains("[0]"), "{e}");
    let e = err(base().prony(&[PronyTerm::new(0.7, 1.0), PronyTerm::new(0.4, 1.0)]));
    assert!(e.contains("sum to 1.1"), "{e}");
    let e = err(base().prony(&[PronyTerm::new(0.2, -1.0)]));
    assert!(e.contains("tau = -1"), "{e}");
    let e = err(base().prescribe([2], Vec3::x(), Ramp::Linear { duration: 0.0 }));
    assert!(e.contains("ramp duration 0"), "{e}");
    let e = err(base().rayleigh(-1.0, 0.0));
    assert!(e.contains("Rayleigh"), "{e}");
    let e = err(System::builder(cube()));
    assert!(e.contains("no material"), "{e}");
    let e = err(System::builder(cube()).prony(&[]));
    assert!(e.contains("prony() called before"), "{e}");
    let e = err(base().fix_where(|p| p.x > 5.0));
    assert!(e.contains("matched no node"), "{e}");
    // a tag without material and no catch-all material
    let m = cube();
    let tags: Vec<i32> = (0..m.n_tets()).map(|t| i32::from(t >= 10)).collect();
    let tagged = TetMesh::with_tags(
        m.nodes().to_vec(),
        m.tets().iter().map(|t| t.map(|i| i as usize)).collect(),
        tags,
    )
    .unwrap();
    let e = err(System::builder(tagged.clone()).region_law(0, neo(1.0, 1.0)));
    assert!(
        e.contains("have no material") && e.contains("first: tet 10") && e.contains("[1]"),
        "{e}"
    );
    assert!(System::builder(tagged)
        .region_law(0, neo(1.0, 1.0))
        .region_law(1, spring(1.0))
        .build()
        .is_ok());
    // by name, through the registry
    let e = System::builder(cube())
        .material("test_sprin", Params::new())
        .unwrap_err()
        .to_string();
    assert!(e.contains("did you mean 'test_spring'"), "{e}");
    let e = System::builder(cube())
        .material("test_spring", Params::from([("k", -1.0)]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("'k' = -1"), "{e}");
    assert!(System::builder(cube())
        .material("test_spring", Params::from([("k", 1.0)]))
        .unwrap()
        .build()
        .is_ok());
}

#[test]
fn unreferenced_nodes_are_an_error_unless_pinned() {
    let m = regular_tet();
    let mut nodes = m.nodes().to_vec();
    nodes.push(Vec3::new(5.0, 5.0, 5.0));
    let m = TetMesh::new(nodes, vec![[0, 1, 2, 3]]).unwrap();
    let e = System::builder(m.clone())
        .material_law(spring(1.0))
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("ids 4") && e.contains("pin_unreferenced"), "{e}");
    let sys = System::builder(m)
        .material_law(spring(1.0))
        .pin_unreferenced()
        .build()
        .unwrap();
    assert!(!sys.is_free(4));
    assert!(sys.warnings()[0].contains("pinned"));
}

#[test]
fn masses_follow_region_densities() {
    let m = cube();
    let tags: Vec<i32> = (0..m.n_tets()).map(|t| i32::from(t % 2 == 0)).collect();
    let tagged = TetMesh::with_tags(
        m.nodes().to_vec(),
        m.tets().iter().map(|t| t.map(|i| i as usize)).collect(),
        tags,
    )
    .unwrap();
    let sys = System::builder(tagged.clone())
        .material_law(neo(1.0, 1.0))
        .region_law(1, neo(2.0, 1.0))
        .region_density(3000.0)
        .density(1000.0)
        .build()
        .unwrap();
    let v1: f64 = tagged.tets_with_tag(1).iter().map(|&t| tagged.tet_volume(t)).sum();
    let expected = 1000.0 * (1.0 - v1) + 3000.0 * v1;
    assert!((sys.total_mass() - expected).abs() < 1e-9 * expected);
    assert_eq!(sys.regions().len(), 2);
}

#[test]
fn stable_dt_of_a_single_spring_is_two_over_omega() {
    // apex of a regular tet on three springs (base fixed): stiffest mode is vertical
    // with k_eff = 3k cos²θ = 2k (cos²θ = 2/3); laterally k/2.
    let (k, rho) = (50.0, 1200.0);
    let mesh = regular_tet();
    let m = rho * mesh.tet_volume(0) / 4.0;
    let sys = System::builder(mesh)
        .material_law(spring(k))
        .density(rho)
        .fix_nodes([0, 1, 2])
        .build()
        .unwrap();
    let omega = (2.0 * k / m).sqrt();
    let dt = power_iteration_time_step(&sys, 300).unwrap();
    // central differences with ε = 1e-6·L on a smooth force: O(ε²) + round-off ~1e-9
    assert!((dt - 2.0 / omega).abs() < 1e-7 * dt, "{dt} vs {}", 2.0 / omega);
    assert!((sys.stable_dt() - DEFAULT_SAFETY * 2.0 / omega).abs() < 1e-7 * dt);
    // damping lowers it: ξ = α/(2ω)
    let sys = System::builder(regular_tet())
        .material_law(spring(k))
        .density(rho)
        .fix_nodes([0, 1, 2])
        .rayleigh(omega, 0.0)
        .build()
        .unwrap();
    let xi: f64 = 0.5;
    let expected = DEFAULT_SAFETY * 2.0 / omega * ((1.0 + xi * xi).sqrt() - xi);
    assert!((sys.stable_dt() - expected).abs() < 1e-6 * expected);
}

#[test]
fn lame_moduli_at_rest_are_recovered() {
    let (mu, lambda) = lame_at_rest(&*neo(3.0e3, 7.0e3), &ForceOptions::default()).unwrap();
    // central differences, step 1e-6: ~1e-9 relative
    assert!(
        (mu - 3.0e3).abs() < 1e-5 && (lambda - 7.0e3).abs() < 1e-5,
        "{mu} {lambda}"
    );
    assert!(lame_at_rest(&*spring(1.0), &ForceOptions::default()).is_none());
}

#[test]
fn wave_speed_estimate_is_below_the_critical_step() {
    // The wave-speed estimate (with WAVE_FACTOR) must not exceed the true critical
    // step 2/ω_max, measured by power iteration, on structured and jittered meshes.
    for (cells, nu, jitter) in [
        ([3, 3, 3], 0.3, 0.03),
        ([4, 2, 2], 0.45, 0.03),
        ([2, 2, 2], 0.0, 0.0),
        ([4, 4, 3], 0.3, 0.12),
    ] {
        let mut mesh = box_mesh([1.0, 0.7, 0.5], cells, HexSplit::Six).unwrap();
        // jitter the interior a little (irregular tets)
        let mut nodes = mesh.nodes().to_vec();
        for (i, p) in nodes.iter_mut().enumerate() {
            let s = ((i * 7919) % 101) as f64 / 101.0 - 0.5;
            *p += Vec3::new(s, -s, 0.5 * s) * jitter;
        }
        mesh = TetMesh::new(nodes, mesh.tets().iter().map(|t| t.map(|i| i as usize)).collect()).unwrap();
        let (mu, lambda) = crate::params::lame(1e4, nu);
        let sys = System::builder(mesh)
            .material_law(neo(mu, lambda))
            .fix_where(|p| p.x < 1e-9)
            .build()
            .unwrap();
        let wave = wave_speed_time_step(&sys).unwrap();
        let crit = power_iteration_time_step(&sys, 2000).unwrap();
        let ratio = crit / (wave / stability_wave_factor());
        eprintln!("cells {cells:?} nu {nu}: dt_crit / (h_min/c) = {ratio:.3}");
        assert!(wave < crit, "wave estimate {wave} above the critical step {crit}");
    }
}

/// Where the power iteration does not settle — a structured beam (the example
/// scene's: 100 × 20 × 20 mm, 20 × 4 × 4 cells, six tets each, clamped at x = 0),
/// whose symmetric top modes cluster — the Lanczos estimate does, lies above a
/// power iteration run 40× longer (both approach λ_max from below), and is the
/// measured limit: undamped symplectic
/// Euler stays bounded at 0.9× and blows up at 1.1× (the organ mesh test's bar).
/// The fallback it replaces there, the wave-speed bound, is ~20 % lower.
/// The largest node speed of undamped symplectic Euler at `dt` over 3000 steps from
/// the system `build` makes (∞ once a step fails; it stops past 1 m/s): what tells a
/// stable step from an unstable one in the stable-step tests.
fn peak_speed(build: &dyn Fn() -> System, dt: f64) -> f64 {
    let mut sys = build();
    let mut vmax = 0.0_f64;
    for _ in 0..3000 {
        if step(&mut sys, dt).is_err() {
            return f64::INFINITY;
        }
        vmax = vmax.max(sys.velocities().iter().map(|v| v.norm()).fold(0.0, f64::max));
        if vmax > 1.0 {
            break;
        }
    }
    vmax
}

/// The bisection on Sturm counts finds a tridiagonal matrix's largest eigenvalue:
/// against nalgebra's symmetric eigensolver on random matrices of 1 to 40 rows
/// (1e-12 of the spectrum's span: the bisection stops at 1e-14 of the Gershgorin
/// span, a few times wider), and on a matrix with a repeated top eigenvalue.
#[test]
fn the_largest_eigenvalue_of_a_tridiagonal_matrix() {
    use super::stability::tridiagonal_max;
    let mut next = crate::sampling::uniform(17);
    for n in 1..=40 {
        let a: Vec<f64> = (0..n).map(|_| 4.0 * next() - 1.0).collect();
        let b: Vec<f64> = (1..n).map(|_| 2.0 * next() - 1.0).collect();
        let t = nalgebra::DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
            0 => a[i],
            1 => b[i.min(j)],
            _ => 0.0,
        });
        let eig = t.symmetric_eigenvalues();
        let (lo, hi) = (eig.min(), eig.max());
        let got = tridiagonal_max(&a, &b);
        assert!(
            (got - hi).abs() <= 1e-12 * (hi - lo).max(hi.abs()),
            "n {n}: {got} vs {hi}"
        );
    }
    // two decoupled blocks with the same top eigenvalue 3 (a zero off-diagonal)
    let got = tridiagonal_max(&[2.0, 2.0, 2.0, 2.0], &[1.0, 0.0, 1.0]);
    assert!((got - 3.0).abs() < 1e-13, "{got}");
}

#[test]
fn lanczos_settles_where_the_power_iteration_does_not() {
    use super::stability::{lanczos, power_iteration, LANCZOS_ITERATIONS, REST_ITERATIONS};
    let mesh = box_mesh([0.1, 0.02, 0.02], [20, 4, 4], HexSplit::Six).unwrap();
    let (mu, lambda) = crate::params::lame(5e3, 0.45);
    let build = || {
        System::builder(mesh.clone())
            .material_law(neo(mu, lambda))
            .fix_where(|p| p.x < 1e-9)
            .time_step_policy(TimeStepPolicy::Ignore)
            .initial_velocity(|p| Vec3::new((p.x * 9137.0).sin(), (p.y * 7919.0).sin(), (p.z * 6011.0).sin()) * 1e-4)
            .build()
            .unwrap()
    };
    let sys = build();
    let rest = sys.rest_positions().to_vec();
    let (power, settled) = power_iteration(&sys, &rest, |_| true, REST_ITERATIONS).unwrap();
    assert!(!settled, "the premise: the power iteration settles here ({power:e})");
    let (l, settled) = lanczos(&sys, &rest, |_| true, LANCZOS_ITERATIONS).unwrap();
    assert!(settled, "Lanczos did not settle ({l:e})");
    // both estimates lie below λ_max, the Ritz value above the power iteration's
    // Rayleigh quotient even after 40× as many iterations, which creep up to it
    // (measured: 20 000 iterations end 4.6e-5 below; 1e-4 bounds it)
    assert!(l >= power * (1.0 - 1e-12), "{l:e} < {power:e}");
    let (long, _) = power_iteration(&sys, &rest, |_| true, 40 * REST_ITERATIONS).unwrap();
    assert!(
        long >= power && l >= long * (1.0 - 1e-12),
        "Lanczos {l:e}, power iteration ×40 {long:e}"
    );
    assert!(l - long <= 1e-4 * l, "Lanczos {l:e}, power iteration ×40 {long:e}");
    // the system's estimate is it (with the safety factor)
    let critical = 2.0 / l.sqrt();
    assert!((sys.stable_dt() / sys.safety() - critical).abs() <= 1e-12 * critical);
    let wave = wave_speed_time_step(&sys).unwrap();
    assert!(critical > 1.1 * wave, "critical {critical:e} vs wave bound {wave:e}");
    let peak = |factor: f64| peak_speed(&build, factor * critical);
    // initial speeds are ≤ 1.7e-4 m/s (as in the organ mesh test)
    let below = peak(0.9);
    let above = peak(1.1);
    assert!(below < 1e-2, "bounded at 0.9 × the estimate: peak speed {below:e}");
    assert!(above > 1.0, "must blow up at 1.1 × the estimate: peak speed {above:e}");
}

#[test]
fn stable_step_is_the_measured_limit_on_an_organ_mesh() {
    // The estimate is 2/ω_max by power iteration: undamped symplectic Euler from a
    // rough velocity field must stay bounded just below it and blow up just above it
    // (measured on gen_kidney_20k and sofa_liver: bounded at 0.97×, unbounded at
    // 1.03×). ±10 % leaves room for the Rayleigh quotient's last digits and for the
    // few steps a mode needs to grow; the wave-speed bound it replaced is ~2× below.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/data/gen_kidney_2k.msh");
    let mesh = crate::io::read_mesh(&path).unwrap().0.scaled(1e-3).unwrap();
    let (mu, lambda) = crate::params::lame(5e3, 0.45);
    let build = || {
        System::builder(mesh.clone())
            .material_law(neo(mu, lambda))
            .density(1050.0)
            .time_step_policy(TimeStepPolicy::Ignore)
            .initial_velocity(|p| Vec3::new((p.x * 9137.0).sin(), (p.y * 7919.0).sin(), (p.z * 6011.0).sin()) * 1e-4)
            .build()
            .unwrap()
    };
    let sys = build();
    let critical = sys.stable_dt() / sys.safety();
    let wave = wave_speed_time_step(&sys).unwrap();
    assert!(critical > 1.5 * wave, "critical {critical:e} vs wave bound {wave:e}");
    let peak = |factor: f64| peak_speed(&build, factor * critical);
    // initial speeds are ≤ 1.7e-4 m/s; a stable run keeps that order, an unstable
    // one grows by e^(steps·growth) past 1 m/s
    let below = peak(0.9);
    let above = peak(1.1);
    assert!(below < 1e-2, "bounded at 0.9 × the estimate: peak speed {below:e}");
    assert!(above > 1.0, "must blow up at 1.1 × the estimate: peak speed {above:e}");
}

fn stability_wave_factor() -> f64 {
    WAVE_FACTOR
}

#[test]
fn policy_warns_once_refuses_or_ignores() {
    let build = |p| {
        System::builder(regular_tet())
            .material_law(spring(10.0))
            .fix_nodes([0, 1, 2])
            .time_step_policy(p)
            .build()
            .unwrap()
    };
    let mut sys = build(TimeStepPolicy::Warn);
    let big = 1.5 * sys.stable_dt();
    step(&mut sys, big).unwrap();
    step(&mut sys, big).unwrap();
    assert_eq!(sys.warnings().len(), 1);
    assert!(sys.warnings()[0].contains("exceeds the stable estimate"));
    let mut sys = build(TimeStepPolicy::Refuse);
    let e = step(&mut sys, big).unwrap_err().to_string();
    assert!(e.contains("exceeds the stable estimate"), "{e}");
    assert_eq!(sys.step_count(), 0);
    let ok = 0.5 * sys.stable_dt();
    step(&mut sys, ok).unwrap();
    let mut sys = build(TimeStepPolicy::Ignore);
    step(&mut sys, big).unwrap();
    assert!(sys.warnings().is_empty());
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = step(&mut sys, bad).unwrap_err().to_string();
        assert!(e.contains("must be a finite number > 0"), "{e}");
    }
}

#[test]
fn blow_up_is_caught_with_step_and_node_and_state_kept() {
    let mut sys = System::builder(cube())
        .material_law(neo(1e4, 1e4))
        .fix_where(|p| p.x < 1e-9)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .time_step_policy(TimeStepPolicy::Ignore)
        .build()
        .unwrap();
    let dt = 20.0 * sys.stable_dt();
    let mut failure = None;
    for _ in 0..100_000 {
        if let Err(e) = step(&mut sys, dt) {
            failure = Some(e.to_string());
            break;
        }
    }
    let e = failure.expect("a 20x too large step must blow up");
    let n = sys.step_count();
    assert!(e.contains(&format!("step {}", n + 1)) && e.contains("at node"), "{e}");
    assert!(e.contains(&format!("last good state (step {n}")), "{e}");
    assert!(sys
        .positions()
        .iter()
        .chain(sys.velocities())
        .all(|p| p.iter().all(|c| c.is_finite())));
    assert!((sys.time() - n as f64 * dt).abs() < 1e-9 * sys.time().max(1.0));
}

#[test]
fn constraints_hold_and_ramps_are_followed_exactly() {
    let mesh = cube();
    let top: Vec<usize> = (0..mesh.n_nodes())
        .filter(|&i| mesh.nodes()[i].z > 1.0 - 1e-9)
        .collect();
    let u = Vec3::new(0.0, 0.05, -0.1);
    let ramp = Ramp::Smooth { duration: 0.05 };
    let mut sys = System::builder(mesh)
        .material_law(neo(1e4, 1e4))
        .fix_where(|p| p.z < 1e-9)
        .prescribe(&top, u, ramp.clone())
        .gravity(Vec3::new(1.0, 0.0, -9.81))
        .build()
        .unwrap();
    let fixed = sys.constraints().fixed.clone();
    let dt = 0.5 * sys.stable_dt();
    let rest = sys.rest_positions().to_vec();
    for _ in 0..200 {
        step(&mut sys, dt).unwrap();
        let t = sys.time();
        for &i in &fixed {
            assert_eq!(sys.positions()[i], rest[i]);
            assert_eq!(sys.velocities()[i], Vec3::zeros());
        }
        for &i in &top {
            assert_eq!(sys.positions()[i], rest[i] + u * ramp.value(t));
            assert_eq!(sys.velocities()[i], u * ramp.rate(t));
        }
        assert!(sys
            .forces()
            .iter()
            .enumerate()
            .all(|(i, f)| sys.is_free(i) || *f == Vec3::zeros()));
    }
    assert!(sys.time() > 0.05);
}

#[test]
fn prony_step_strain_relaxes_like_alpha_at_first_order() {
    // Every node prescribed: a step stretch at t = 0 held constant. The reaction is
    // −f̂ = −f·α_h(t), so |R_i(t)|/|R_i(0)| must follow α(t) with an O(Δt) error.
    let terms = [PronyTerm::new(0.3, 0.05), PronyTerm::new(0.2, 0.4)];
    let run = |dt: f64| -> f64 {
        let mesh = cube();
        let all: Vec<usize> = (0..mesh.n_nodes()).collect();
        let mut sys = System::builder(mesh)
            .material_law(neo(1e3, 2e3))
            .prony(&terms)
            .prescribe_with(
                &all,
                |p| Vec3::new(0.1 * p.x, -0.02 * p.y, 0.03 * p.x * p.z),
                Ramp::Step,
            )
            .build()
            .unwrap();
        let probe = 26; // a corner node with a large reaction
        let mut r0 = None;
        let mut worst: f64 = 0.0;
        while sys.time() < 1.0 - 1e-9 {
            let t = sys.time();
            sys.begin_step(dt).unwrap();
            sys.compute_forces().unwrap(); // at time t
            let r = sys.reactions()[probe];
            let r0 = *r0.get_or_insert(r);
            assert!(r0.norm() > 1.0);
            // the viscous force is parallel to the elastic one here (constant strain)
            let ratio = r.dot(&r0) / r0.norm_squared();
            worst = worst.max((ratio - relaxation(&terms, t)).abs());
            sys.kick(dt);
            sys.drift(dt);
            sys.finish_step().unwrap();
        }
        worst
    };
    let (e1, e2, e3) = (run(0.01), run(0.005), run(0.0025));
    eprintln!("Prony max |α_h − α| over [0, 1]: dt=0.01 {e1:.3e}, 0.005 {e2:.3e}, 0.0025 {e3:.3e}");
    // leading error ≈ Σ α_i e^{-t/τ_i} t Δt / (2τ_i²) ≤ Σ α_i Δt / (2e τ_i) ≈ 0.0113 at Δt = 0.01
    assert!(e1 < 0.015, "{e1}");
    // first order: halving Δt halves the error (ratio 2 ± 0.2 in the asymptotic range)
    for r in [e1 / e2, e2 / e3] {
        assert!((1.8..2.2).contains(&r), "error ratio {r}");
    }
}

#[test]
fn reaction_balances_gravity_at_rest() {
    // A cube hanging from its top face, damped to rest: the reactions carry its weight.
    let rho = 1000.0;
    let g = Vec3::new(0.0, 0.0, -9.81);
    let mesh = box_mesh([0.1, 0.1, 0.1], [2, 2, 2], HexSplit::Six).unwrap();
    let (mu, lambda) = crate::params::lame(5e4, 0.3);
    let mut sys = System::builder(mesh)
        .material_law(neo(mu, lambda))
        .density(rho)
        .gravity(g)
        .fix_where(|p| p.z > 0.1 - 1e-9)
        .rayleigh(200.0, 0.0)
        .build()
        .unwrap();
    let dt = 0.5 * sys.stable_dt();
    let weight = sys.total_mass() * g;
    for _ in 0..20_000 {
        step(&mut sys, dt).unwrap();
    }
    let r = sys.total_reaction();
    // residual imbalance = Σ m_i a_i of the free nodes, which decays like e^{-αt/2};
    // after t = 20000 dt it is far below 1e-6 of the weight.
    assert!(
        (r + weight).norm() < 1e-6 * weight.norm(),
        "reaction {r:?}, weight {weight:?}"
    );
    assert!(sys.velocities().iter().all(|v| v.norm() < 1e-8));
}

#[test]
fn stiffness_damping_dissipates_and_matches_a_linear_estimate() {
    // K v by directional differences: compare −βKv to β(f(x+hv) − f(x−hv))/2h.
    let mut sys = System::builder(cube())
        .material_law(neo(1e3, 1e3))
        .rayleigh(0.0, 0.01)
        .build()
        .unwrap();
    let v: Vec<Vec3> = (0..sys.positions().len())
        .map(|i| Vec3::new((i % 3) as f64, 1.0, -(i as f64) * 0.1))
        .collect();
    sys.velocities_mut().copy_from_slice(&v);
    sys.positions_mut().iter_mut().for_each(|p| p.x *= 1.1);
    sys.compute_forces().unwrap();
    let damped = sys.forces().to_vec();
    let x = sys.positions().to_vec();
    let f = |x: &[Vec3]| sys.regions()[0].field().forces(x).unwrap().1;
    let h = 1e-5;
    let xp: Vec<Vec3> = x.iter().zip(&v).map(|(x, v)| x + v * h).collect();
    let xm: Vec<Vec3> = x.iter().zip(&v).map(|(x, v)| x - v * h).collect();
    let (f0, fp, fm) = (f(&x), f(&xp), f(&xm));
    let scale = fp
        .iter()
        .zip(&fm)
        .map(|(a, b)| (a - b).norm() * 0.01 / (2.0 * h))
        .fold(0.0, f64::max);
    for i in 0..x.len() {
        let expected = f0[i] + (fp[i] - fm[i]) * (0.01 / (2.0 * h));
        // forward difference with ε·max|v| = 1e-7·L: relative O(1e-7) + round-off
        assert!((damped[i] - expected).norm() < 1e-5 * scale, "node {i}");
    }
}

#[test]
fn deformed_estimate_is_the_rest_estimate_at_rest_and_follows_a_squeeze() {
    let mut sys = System::builder(cube())
        .material_law(neo(1e4, 1e5))
        .fix_where(|p| p.x < 1e-9)
        .build()
        .unwrap();
    let est = DeformedEstimate::new(&sys);
    let (dt, j) = est.time_step(&sys);
    // the same wave-speed formula with tangents from central differences of the
    // stress (~1e-10 relative each) at rest: equal to 1e-6
    assert!((dt / sys.stable_dt() - 1.0).abs() < 1e-6, "{dt} vs {}", sys.stable_dt());
    assert!((j - 1.0).abs() < 1e-12);
    // squeezed to a tenth along x (J = 0.1, below J0 = 0.4, where the extension
    // freezes the volumetric stiffness at its J0 value): ∂P11/∂F11 grows ~25x over
    // its rest value here, so the step falls ~5x
    let base = sys.stable_dt();
    let mut ctrl = AdaptiveStep::new(&sys, base, 5);
    assert_eq!(ctrl.next(&sys), (base, DtReason::Base));
    for p in sys.positions_mut() {
        p.x *= 0.1;
    }
    let (squeezed, j) = est.time_step(&sys);
    assert!((j - 0.1).abs() < 1e-12, "{j}");
    assert!(squeezed < 0.25 * dt, "{squeezed} vs {dt}");
    // the controller lowers at its next check (call 5), not before, and below the
    // estimate (it extrapolates the fall once more)
    for _ in 1..5 {
        assert_eq!(ctrl.next(&sys).0, base);
    }
    let (low, why) = ctrl.next(&sys);
    assert_eq!(why, DtReason::Stiffness);
    assert!(low < squeezed, "{low} vs {squeezed}");
    assert!((ctrl.min_j() - 0.1).abs() < 1e-12);
    // released: raised back by at most 25 % per check until the base step
    for p in sys.positions_mut() {
        p.x *= 10.0;
    }
    let mut prev = low;
    let mut checks = 0;
    while ctrl.dt() < base {
        for _ in 0..5 {
            ctrl.next(&sys);
        }
        assert!(ctrl.dt() <= 1.25 * prev * (1.0 + 1e-12) && ctrl.dt() > prev);
        prev = ctrl.dt();
        checks += 1;
        assert!(checks < 100, "never recovers");
    }
    assert_eq!(ctrl.next(&sys), (base, DtReason::Base));
}
