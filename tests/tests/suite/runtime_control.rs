//! Runtime control of a running system (`heml_core::system::control`): changes made
//! between steps behave exactly like a system built from scratch with the changed
//! model and the state at that instant; a soft grasp lifts, holds and lets go of a
//! node group; bad input is a clear error that leaves the system unchanged.

use heml::integrators::{BackwardEuler, Newmark, SymplecticEuler, VelocityVerlet};
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::prelude::*;
use heml::system::control::Pose;
use heml::system::{ImplicitSettings, System, SystemBuilder};

fn link() {
    let _ = (heml::integrators_list(), heml::materials_list());
}

const L: f64 = 0.04;

/// A 4 × 4 × 4 cm soft cube (E = 5 kPa, ν = 0.45), clamped at x = 0, with mass and
/// stiffness damping (the stiffness damping makes every force evaluation use the
/// velocities too, so a stale cache would show).
fn cube() -> TetMesh {
    box_mesh([L, L, L], [3, 3, 3], HexSplit::Six).unwrap()
}

fn nodes_where(mesh: &TetMesh, pred: impl Fn(&Vec3) -> bool) -> Vec<usize> {
    (0..mesh.n_nodes()).filter(|&i| pred(&mesh.nodes()[i])).collect()
}

fn clamp(p: &Vec3) -> bool {
    p.x < 1e-9
}

fn far(p: &Vec3) -> bool {
    p.x > L - 1e-9
}

fn bottom(p: &Vec3) -> bool {
    p.z < 1e-9
}

fn builder() -> SystemBuilder {
    builder_with(5e3)
}

/// [`builder`] with Young's modulus `e`.
fn builder_with(e: f64) -> SystemBuilder {
    System::builder(cube())
        .material("neo_hookean", Params::from([("E", e), ("nu", 0.45)]))
        .unwrap()
        .density(1000.0)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .rayleigh(5.0, 2e-4)
        .energy_every(0)
}

/// A rigid motion of the far face: 5 mm up and 0.2 rad about the x axis through the
/// face centre.
fn face_pose() -> Pose {
    let c = Vec3::new(L, 0.5 * L, 0.5 * L);
    let turn = Pose::new(Vec3::zeros(), Vec3::new(0.2, 0.0, 0.0)).unwrap();
    // about c: p ↦ R (p − c) + c + u
    Pose {
        translation: c - turn.rotate(c) + Vec3::new(0.0, 0.0, 0.005),
        rotation: turn.rotation,
    }
}

/// The runtime changes the equivalence test applies at t = T.
#[derive(Clone, Copy, Debug)]
enum Change {
    /// The far face, free until then, moved to `face_pose` (prescribed).
    MoveGroup,
    /// The bottom face fixed, the clamp at x = 0 released except where it meets the
    /// bottom face.
    Refix,
    /// Gravity turned sideways and a nodal force added.
    Loads,
    /// The law four times as stiff (`System::set_material`).
    Stiffen,
}

fn apply(sys: &mut System, change: Change) {
    let mesh = sys.mesh().clone();
    match change {
        Change::MoveGroup => sys.prescribe_pose(&nodes_where(&mesh, far), &face_pose()).unwrap(),
        Change::Refix => {
            sys.fix_nodes(&nodes_where(&mesh, bottom)).unwrap();
            sys.release_nodes(&nodes_where(&mesh, |p| clamp(p) && !bottom(p)))
                .unwrap();
        }
        Change::Loads => {
            sys.set_gravity(Vec3::new(3.0, 0.0, -9.81)).unwrap();
            let tip = nodes_where(&mesh, far)[0];
            sys.set_nodal_forces(&[(tip, Vec3::new(0.0, 0.01, 0.0))]).unwrap();
        }
        Change::Stiffen => sys.set_material(0, stiff_law()).unwrap(),
    }
}

/// The system the builder makes with the model as `change` leaves it.
fn rebuilt(change: Change) -> System {
    let mesh = cube();
    let b = builder();
    match change {
        Change::MoveGroup => {
            let pose = face_pose();
            b.fix_where(clamp)
                .prescribe_with(nodes_where(&mesh, far), |x| pose.apply(*x) - x, Ramp::Step)
        }
        Change::Refix => b.fix_where(bottom),
        Change::Loads => b
            .fix_where(clamp)
            .gravity(Vec3::new(3.0, 0.0, -9.81))
            .nodal_force(nodes_where(&mesh, far)[0], Vec3::new(0.0, 0.01, 0.0)),
        Change::Stiffen => builder_with(2e4).fix_where(clamp),
    }
    .build()
    .unwrap()
}

/// Runs `steps` steps before and after `change` with integrator `make()` (one
/// instance throughout, so its caches see the change), and the same steps after the
/// change on a system rebuilt from scratch with the state at the change (a fresh
/// instance). Returns (changed run, rebuilt run, unchanged run) positions.
fn runs(change: Change, make: &dyn Fn() -> Box<dyn Integrator>, dt: f64, steps: usize) -> [Vec<Vec3>; 3] {
    let mut a = builder().fix_where(clamp).build().unwrap();
    let mut unchanged = builder().fix_where(clamp).build().unwrap();
    let (mut ia, mut iu) = (make(), make());
    for _ in 0..steps {
        ia.step(&mut a, dt).unwrap();
        iu.step(&mut unchanged, dt).unwrap();
    }
    apply(&mut a, change);
    let mut b = rebuilt(change);
    b.positions_mut().copy_from_slice(a.positions());
    b.velocities_mut().copy_from_slice(a.velocities());
    // the same model: same masses, inverse masses (through the free set) and stable step
    assert_eq!(a.constraints().constrained_nodes(), b.constraints().constrained_nodes());
    assert_eq!(a.stable_dt(), b.stable_dt(), "{change:?}");
    let mut ib = make();
    for _ in 0..steps {
        ia.step(&mut a, dt).unwrap();
        ib.step(&mut b, dt).unwrap();
        iu.step(&mut unchanged, dt).unwrap();
    }
    assert_eq!(a.reactions(), b.reactions(), "{change:?}: reactions");
    [
        a.positions().to_vec(),
        b.positions().to_vec(),
        unchanged.positions().to_vec(),
    ]
}

/// Runtime changes (move a prescribed group, add and release fixed nodes, change
/// gravity and nodal forces, replace the law) made at t = T step exactly like the system built from
/// scratch with that model and the state at T — bit for bit, for an explicit scheme
/// that reuses the accepted forces (symplectic Euler), one that reuses the forces of
/// its last evaluation (velocity Verlet) and Newmark, which keeps the acceleration of
/// its last step and its tangent operators. Bit equality is the right bar: both runs
/// do the same floating-point operations in the same order on the same inputs, so any
/// difference means a stale cache (forces, acceleration, operator, inverse mass).
/// The unchanged run shows that each change matters (else the test could not fail).
#[test]
fn runtime_changes_step_like_a_system_built_at_that_instant() {
    link();
    let explicit_dt = 0.5 * builder().fix_where(clamp).build().unwrap().stable_dt();
    type Make = Box<dyn Fn() -> Box<dyn Integrator>>;
    let schemes: [(&str, Make, f64); 3] = [
        ("symplectic_euler", Box::new(|| Box::new(SymplecticEuler)), explicit_dt),
        ("velocity_verlet", Box::new(|| Box::new(VelocityVerlet)), explicit_dt),
        (
            "newmark",
            Box::new(|| {
                Box::new(Newmark::with_settings(ImplicitSettings {
                    newton_iterations: 3,
                    ..ImplicitSettings::default()
                }))
            }),
            5e-3,
        ),
    ];
    for (name, make, dt) in &schemes {
        for change in [Change::MoveGroup, Change::Refix, Change::Loads, Change::Stiffen] {
            let [a, b, u] = runs(change, &**make, *dt, 25);
            assert!(
                a == b,
                "{name}, {change:?}: the changed run differs from the rebuilt one"
            );
            let moved = a.iter().zip(&u).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
            assert!(
                moved > 1e-5,
                "{name}, {change:?}: the change had no effect ({moved:e} m)"
            );
        }
    }
}

/// The cube's law at E = 20 kPa.
fn stiff_law() -> Box<dyn Material> {
    heml::material("neo_hookean", &Params::from([("E", 2e4), ("nu", 0.45)])).unwrap()
}

/// What the bad-input test compares before and after each refused call.
fn fingerprint(sys: &System) -> String {
    format!(
        "{:?} {:?}",
        (
            sys.positions(),
            sys.velocities(),
            sys.time(),
            sys.step_count(),
            sys.gravity(),
            sys.nodal_forces(),
            &sys.constraints().fixed,
            &sys.constraints().prescribed,
            sys.constraints().constrained_nodes(),
        ),
        (
            sys.stable_dt(),
            sys.grasp_ids(),
            sys.forces(),
            sys.reactions(),
            sys.forces_current(),
        )
    )
}

/// Bad input — a grasp on no node, NaN poses, unknown node ids, an unknown (or
/// released) grasp, control inside a step — is an error naming the problem, and the
/// system is unchanged (compared field by field before and after).
#[test]
fn bad_control_input_is_refused_and_changes_nothing() {
    link();
    let mut sys = builder().fix_where(clamp).build().unwrap();
    let n = sys.positions().len();
    let top = nodes_where(sys.mesh(), |p| p.z > L - 1e-9);
    let free_top = *top.iter().find(|&&i| sys.is_free(i)).unwrap();
    let g = sys.grasp(&top, Pose::identity(), 100.0, 0.1).unwrap();
    for _ in 0..3 {
        let dt = 0.5 * sys.stable_dt();
        SymplecticEuler.step(&mut sys, dt).unwrap();
    }
    let released = sys.grasp(&top[..2], Pose::identity(), 100.0, 0.0).unwrap();
    sys.release_grasp(released).unwrap();
    let nan = Pose::translation(Vec3::new(f64::NAN, 0.0, 0.0));
    let before = fingerprint(&sys);
    type Call = Box<dyn Fn(&mut System) -> heml::Result<()>>;
    let cases: Vec<(&str, Call)> = vec![
        (
            "empty",
            Box::new(|s| s.grasp(&[], Pose::identity(), 100.0, 0.0).map(drop)),
        ),
        (
            "not finite",
            Box::new(move |s| s.grasp(&[0], nan, 100.0, 0.0).map(drop)),
        ),
        (
            "out of range",
            Box::new(move |s| s.grasp(&[n], Pose::identity(), 1.0, 0.0).map(drop)),
        ),
        (
            "listed twice",
            Box::new(|s| s.grasp(&[3, 3], Pose::identity(), 1.0, 0.0).map(drop)),
        ),
        (
            "stiffness",
            Box::new(|s| s.grasp(&[3], Pose::identity(), f64::NAN, 0.0).map(drop)),
        ),
        (
            "damping",
            Box::new(|s| s.grasp(&[3], Pose::identity(), 1.0, -1.0).map(drop)),
        ),
        ("not finite", Box::new(move |s| s.move_grasp(g, nan))),
        (
            "already released",
            Box::new(move |s| s.move_grasp(released, Pose::identity())),
        ),
        ("already released", Box::new(move |s| s.release_grasp(released))),
        ("already released", Box::new(move |s| s.grasp_force(released).map(drop))),
        ("out of range", Box::new(move |s| s.fix_nodes(&[0, n + 7]))),
        ("empty", Box::new(|s| s.fix_nodes(&[]))),
        ("not constrained", Box::new(move |s| s.release_nodes(&[free_top]))),
        ("not finite", Box::new(move |s| s.prescribe_pose(&[1], &nan))),
        (
            "2 targets for 1 nodes",
            Box::new(|s| s.prescribe_targets(&[1], &[Vec3::zeros(); 2])),
        ),
        (
            "not finite",
            Box::new(|s| s.prescribe_targets(&[1], &[Vec3::new(0.0, f64::INFINITY, 0.0)])),
        ),
        ("not finite", Box::new(|s| s.set_gravity(Vec3::new(0.0, 0.0, f64::NAN)))),
        (
            "out of range",
            Box::new(move |s| s.set_nodal_forces(&[(1, Vec3::x()), (n, Vec3::x())])),
        ),
        ("region 1 is out of range", Box::new(|s| s.set_material(1, stiff_law()))),
        (
            "region 0 is given twice",
            Box::new(|s| s.set_materials(vec![(0, stiff_law()), (0, stiff_law())])),
        ),
        (
            // a fibre law without fibre directions builds no field
            "region 0, law `holzapfel_gasser_ogden`",
            Box::new(|s| {
                let params = [
                    ("c", 1e3),
                    ("k1", 1e3),
                    ("k2", 1.0),
                    ("dispersion", 0.1),
                    ("kappa", 1e4),
                ];
                s.set_material(0, heml::material("holzapfel_gasser_ogden", &Params::from(params))?)
            }),
        ),
    ];
    for (expected, call) in &cases {
        let e = call(&mut sys).expect_err(expected).to_string();
        assert!(e.contains(expected), "expected “{expected}” in: {e}");
        assert_eq!(fingerprint(&sys), before, "changed by the failed call: {e}");
    }
    // inside a step every control call is refused, the step then completes
    let dt = 0.5 * sys.stable_dt();
    sys.begin_step(dt).unwrap();
    let inside = fingerprint(&sys);
    let calls: Vec<Call> = vec![
        Box::new(|s| s.set_gravity(Vec3::zeros())),
        Box::new(|s| s.clear_nodal_forces()),
        Box::new(|s| s.fix_nodes(&[5])),
        Box::new(move |s| s.release_nodes(&[0])),
        Box::new(|s| s.prescribe_pose(&[5], &Pose::identity())),
        Box::new(|s| s.grasp(&[5], Pose::identity(), 1.0, 0.0).map(drop)),
        Box::new(move |s| s.move_grasp(g, Pose::identity())),
        Box::new(move |s| s.release_grasp(g)),
        Box::new(|s| s.set_material(0, stiff_law())),
    ];
    for call in &calls {
        let e = call(&mut sys).unwrap_err().to_string();
        assert!(e.contains("inside a step"), "{e}");
        assert_eq!(fingerprint(&sys), inside, "changed inside a step: {e}");
    }
    sys.compute_forces().unwrap();
    sys.kick(dt);
    sys.drift(dt);
    sys.finish_step().unwrap();
    // and between steps the same calls work
    sys.release_grasp(g).unwrap();
    sys.set_gravity(Vec3::zeros()).unwrap();
}

/// A grasp lifts the top face of a cube standing on its clamped bottom face by 1 cm,
/// holds it, and lets go; the body comes back to rest. Backward Euler at 5 ms (about
/// 4× the explicit stable step of the grasped cube) with mass damping α = 20/s.
///
/// * Hold: at equilibrium each grasped node sits off its target by (its share of the
///   tissue's pull)/k. The cube resists a 1 cm lift of its top face with about
///   E·A/L = 5e3 × 0.0016 / 0.04 = 200 N/m (more, ≈ 2×, with the lateral restraint of
///   the clamp and ν = 0.45); the 16 nodes at k = 500 N/m give 8000 N/m, so the mean
///   lift is short of 1 cm by 2.5–5 %: within 8 % (0.8 mm) and above 1 cm − the
///   grasp's pull / (n k), checked exactly below from the grasp force.
/// * Equilibrium (Newton's third law): at rest the tissue pulls the grasp with what
///   the clamp holds it with, grasp force = total reaction, up to the inertial and
///   damping forces of the remaining motion. After 1 s of hold that motion has decayed
///   like e^(−αt/2) = e^(−10) ≈ 5e-5 from the mass damping alone, and backward Euler
///   damps the slowest mode (ω ≈ √(400 N/m / 0.064 kg) ≈ 80 rad/s, ωh ≈ 0.4) by
///   1/√(1 + (ωh)²) ≈ 0.93 per step more, i.e. 1e-6 over 200 steps: 1e-6 relative
///   is safe. (Measured: ~1e-14, the Newton and CG tolerances.)
/// * Release: 1.5 s later the free motion has decayed by e^(−15); the body's RMS
///   distance to rest is asked to be below 1e-3 of its size (its diagonal).
#[test]
fn a_grasp_lifts_holds_and_lets_go() {
    link();
    let mesh = cube();
    let top = nodes_where(&mesh, |p| p.z > L - 1e-9);
    let size = (3.0f64).sqrt() * L;
    let mut sys = System::builder(mesh)
        .material("neo_hookean", Params::from([("E", 5e3), ("nu", 0.45)]))
        .unwrap()
        .density(1000.0)
        .fix_where(bottom)
        .rayleigh(20.0, 0.0)
        .energy_every(0)
        .build()
        .unwrap();
    let (k, c) = (500.0, 0.5);
    let dt_free = sys.stable_dt();
    let g = sys.grasp(&top, Pose::identity(), k, c).unwrap();
    assert!(
        sys.stable_dt() < dt_free,
        "the grasp springs must lower the explicit step"
    );
    let dt = 5e-3;
    let mut be = BackwardEuler::default();
    let lift = Vec3::new(0.0, 0.0, 0.01);
    // lift over 0.2 s, one pose per step
    let ramp = 40;
    for s in 1..=ramp {
        let pose = Pose::identity().lerp(&Pose::translation(lift), s as f64 / ramp as f64);
        sys.move_grasp(g, pose).unwrap();
        be.step(&mut sys, dt).unwrap();
    }
    for _ in 0..200 {
        be.step(&mut sys, dt).unwrap();
    }
    let u = sys.displacements();
    let mean_lift = top.iter().map(|&i| u[i].z).sum::<f64>() / top.len() as f64;
    let pull = sys.grasp_force(g).unwrap();
    eprintln!(
        "grasp: mean lift {mean_lift:.5} m, grasp force {:?} N, reaction {:?} N",
        pull.as_slice(),
        sys.total_reaction().as_slice()
    );
    assert!(pull.z < 0.0, "the stretched cube pulls the grasp down: {pull:?}");
    assert!((mean_lift - 0.01).abs() < 8e-4, "mean lift {mean_lift}");
    // the springs' law: Σ k (x_i − target_i) = grasp force − c Σ v_i (v ≈ 0)
    let short = 0.01 - mean_lift;
    let expected_short = -pull.z / (k * top.len() as f64);
    assert!(
        (short - expected_short).abs() < 1e-3 * expected_short,
        "{short} vs {expected_short}"
    );
    let balance = (pull - sys.total_reaction()).norm() / pull.norm();
    assert!(balance < 1e-6, "grasp force vs reaction: {balance:e}");

    sys.release_grasp(g).unwrap();
    assert_eq!(
        sys.stable_dt(),
        dt_free,
        "released, the grasp no longer limits the step"
    );
    for _ in 0..300 {
        be.step(&mut sys, dt).unwrap();
    }
    let rms = (sys.displacements().iter().map(|u| u.norm_squared()).sum::<f64>() / u.len() as f64).sqrt();
    eprintln!("released: RMS distance to rest {rms:.2e} m (size {size:.3} m)");
    assert!(rms < 1e-3 * size, "RMS distance to rest {rms:e}");
    assert!(sys.warnings().is_empty(), "{:?}", sys.warnings());
}

/// A grasp 100× stiffer than the tissue under it: the implicit step sees the springs
/// in its tangent, so one Newton iteration per step (backward Euler's default) puts
/// the grasped nodes on their target to the scheme's lag, while the explicit estimate
/// drops with the springs (ω² grows by k/m) — and stepping explicitly at the old
/// estimate blows up, which the system reports as an error.
///
/// Hold error bound: the tissue's pull (≈ 200–400 N/m × 5 mm ≈ 2 N in total, see the
/// lift test) spread over 16 springs of 5e4 N/m is ≈ 2.5 µm per node; the backward
/// Euler lag after 100 steps of hold is negligible (the spring mode's time constant,
/// c/k or √(m/k), is far below dt). 1e-5 m is a 4× margin.
#[test]
fn a_stiff_grasp_is_implicit_friendly_and_limits_the_explicit_step() {
    link();
    let mesh = cube();
    let top = nodes_where(&mesh, |p| p.z > L - 1e-9);
    let make = || {
        System::builder(cube())
            .material("neo_hookean", Params::from([("E", 5e3), ("nu", 0.45)]))
            .unwrap()
            .fix_where(bottom)
            .rayleigh(20.0, 0.0)
            .energy_every(0)
            .build()
            .unwrap()
    };
    let mut sys = make();
    let k = 5e4;
    let g = sys
        .grasp(&top, Pose::translation(Vec3::new(0.0, 0.0, 0.005)), k, 1.0)
        .unwrap();
    let mut be = BackwardEuler::default();
    // 100 steps (0.5 s), then the largest distance of a grasped node from height z
    let mut hold = |sys: &mut System, z: f64| {
        for _ in 0..100 {
            be.step(sys, 5e-3).unwrap();
        }
        let u = sys.displacements();
        top.iter().map(|&i| (u[i].z - z).abs()).fold(0.0, f64::max)
    };
    let worst = hold(&mut sys, 0.0);
    assert!(worst < 1e-5, "the anchors hold the grasp-time positions: {worst:e}");
    sys.move_grasp(g, Pose::translation(Vec3::new(0.0, 0.0, 0.01))).unwrap();
    let err = hold(&mut sys, 0.005);
    assert!(err < 1e-5, "grasped nodes off target by {err:e} m");

    // explicit: the estimate accounts for the springs
    let mut ex = make();
    let dt_free = ex.stable_dt();
    let g1 = ex.grasp(&top, Pose::identity(), k, 0.0).unwrap();
    let dt_grasp = ex.stable_dt();
    // a 16-node face of a 1.33 cm grid carries ~ρ h³/2 per node (≈ 1.2 g): √(k/m) ≈
    // 6.5e3 rad/s against the tissue's ≈ 1.6e3 rad/s, so the step falls by ~4×
    assert!(dt_grasp < 0.4 * dt_free, "{dt_grasp:e} vs {dt_free:e}");
    ex.move_grasp(g1, Pose::translation(Vec3::new(0.0, 0.0, 0.005)))
        .unwrap();
    let mut stable = true;
    for _ in 0..400 {
        if SymplecticEuler.step(&mut ex, dt_grasp).is_err() {
            stable = false;
            break;
        }
    }
    assert!(stable, "explicit steps below the grasp-aware estimate must stay stable");
    let mut blown = false;
    let mut ex2 = make();
    ex2.set_time_step_policy(TimeStepPolicy::Ignore);
    let g2 = ex2.grasp(&top, Pose::identity(), k, 0.0).unwrap();
    ex2.move_grasp(g2, Pose::translation(Vec3::new(0.0, 0.0, 0.005)))
        .unwrap();
    for _ in 0..400 {
        if SymplecticEuler.step(&mut ex2, 0.95 * dt_free).is_err() {
            blown = true;
            break;
        }
    }
    assert!(blown, "at the grasp-free estimate the stiff springs should blow up");
}
