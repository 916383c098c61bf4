//! The step's update without copies: `kick_drift` gives the bits of `kick` then
//! `drift`, and the lazily saved start-of-step state (kept by the first kick or
//! drift of a step, or copied by any other change) restores the system exactly when
//! a step fails, whichever way the step changed it.

use super::*;

/// A clamped cube under gravity and a prescribed ramp (every kind of node: fixed,
/// prescribed, free).
fn body() -> System {
    let mesh = cube();
    let top: Vec<usize> = (0..mesh.n_nodes())
        .filter(|&i| mesh.nodes()[i].z > 1.0 - 1e-9)
        .collect();
    System::builder(mesh)
        .material_law(neo(1e4, 1e4))
        .fix_where(|p| p.z < 1e-9)
        .prescribe(&top, Vec3::new(0.0, 0.05, -0.1), Ramp::Smooth { duration: 0.05 })
        .gravity(Vec3::new(1.0, 0.0, -9.81))
        .rayleigh(2.0, 0.0)
        .time_step_policy(TimeStepPolicy::Ignore)
        .build()
        .unwrap()
}

/// Symplectic Euler with the fused update.
fn fused_step(sys: &mut System, dt: f64) -> Result<StepStats> {
    sys.begin_step(dt)?;
    sys.compute_forces()?;
    sys.kick_drift(dt);
    sys.finish_step()
}

/// Symplectic Euler through `kinematics_mut` (a custom integrator's way: the state
/// is saved by a copy).
fn custom_step(sys: &mut System, dt: f64) -> Result<StepStats> {
    sys.begin_step(dt)?;
    sys.compute_forces()?;
    let f = sys.forces().to_vec();
    let inv: Vec<f64> = (0..f.len())
        .map(|i| if sys.is_free(i) { 1.0 / sys.masses()[i] } else { 0.0 })
        .collect();
    let (x, v) = sys.kinematics_mut();
    for i in 0..x.len() {
        v[i] += f[i] * (dt * inv[i]);
        x[i] += v[i] * dt;
    }
    sys.finish_step()
}

#[test]
fn kick_drift_gives_the_bits_of_kick_then_drift() {
    let (mut a, mut b, mut c) = (body(), body(), body());
    let dt = 0.5 * a.stable_dt();
    for _ in 0..100 {
        let sa = step(&mut a, dt).unwrap();
        let sb = fused_step(&mut b, dt).unwrap();
        let sc = custom_step(&mut c, dt).unwrap();
        assert_eq!(sa.max_speed, sb.max_speed);
        assert_eq!(sa.max_speed, sc.max_speed);
    }
    // exact equality: the same arithmetic in the same order, only the buffers differ
    assert_eq!(a.positions(), b.positions());
    assert_eq!(a.velocities(), b.velocities());
    assert_eq!(a.positions(), c.positions());
    assert_eq!(a.velocities(), c.velocities());
    assert!(a.velocities().iter().any(|v| v.norm() > 0.0));
}

#[test]
fn a_failed_step_restores_the_state_bit_for_bit() {
    type Stepper = fn(&mut System, f64) -> Result<StepStats>;
    let steppers: [(&str, Stepper); 3] = [
        ("kick, drift", step),
        ("kick_drift", fused_step),
        ("kinematics_mut", custom_step),
    ];
    for (name, stepper) in steppers {
        let mut sys = body();
        // 20× the stable step blows up within a few hundred steps
        let dt = 20.0 * sys.stable_dt();
        let mut failed = false;
        for _ in 0..100_000 {
            let (x, v, t, n) = (
                sys.positions().to_vec(),
                sys.velocities().to_vec(),
                sys.time(),
                sys.step_count(),
            );
            if stepper(&mut sys, dt).is_err() {
                assert_eq!(sys.positions(), &x[..], "{name}");
                assert_eq!(sys.velocities(), &v[..], "{name}");
                assert_eq!((sys.time(), sys.step_count()), (t, n), "{name}");
                failed = true;
                break;
            }
        }
        assert!(failed, "{name}: a 20x too large step must blow up");
        // the restored system steps on (its buffers are whole)
        let small = 1e-3 * sys.stable_dt();
        stepper(&mut sys, small).unwrap();
    }
}

#[test]
fn a_step_abandoned_after_the_kick_rolls_back_exactly() {
    let mut sys = body();
    let dt = 0.5 * sys.stable_dt();
    for _ in 0..10 {
        fused_step(&mut sys, dt).unwrap();
    }
    let (x, v) = (sys.positions().to_vec(), sys.velocities().to_vec());
    sys.begin_step(dt).unwrap();
    sys.compute_forces().unwrap();
    sys.kick(dt);
    // a NaN position makes the next force evaluation fail and roll the step back
    let n = sys.positions().len();
    sys.positions_mut()[n - 1].x = f64::NAN;
    assert!(sys.compute_forces().is_err());
    assert_eq!(sys.positions(), &x[..]);
    assert_eq!(sys.velocities(), &v[..]);
    fused_step(&mut sys, dt).unwrap();
}
