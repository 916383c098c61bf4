//! The haptic device's local model (`heml::system::contact::LocalModel`): its
//! contact stiffness is the derivative of the tool force, and a device rendering it
//! never waits for a stalled simulation.

use heml::mesh::generate::{box_mesh, HexSplit};
use heml::nalgebra::Matrix3;
use heml::prelude::*;
use heml::system::contact::{
    haptic_link, run_device, ContactLaw, DeviceLog, LocalModel, Palpation, StiffnessEstimator, Tool,
};
use heml::system::control::Pose;
use heml::system::System;
use std::time::{Duration, Instant};

/// The device's busy-wait before each tick, as `run_haptic_loop`'s default.
const SPIN: Duration = Duration::from_micros(200);

fn link() {
    let _ = (heml::integrators_list(), heml::materials_list());
}

/// Soft block 4 × 4 × 2 cm clamped at its base (the palpation tissue).
fn block() -> System {
    let mesh = box_mesh([0.04, 0.04, 0.02], [12, 12, 6], HexSplit::Six).unwrap();
    Palpation::tissue(mesh).unwrap()
}

/// The tool force at translation `t` (rotation of `base`), tissue at rest where it is.
fn force_at(sys: &mut System, tool: heml::system::contact::ToolId, base: Pose, t: Vec3) -> Vec3 {
    sys.set_tool_pose(tool, Pose { translation: t, ..base }).unwrap();
    sys.compute_forces().unwrap();
    sys.tool_wrench(tool).unwrap().force
}

/// The palpation of the block (0.1 s per press) and the local model of its tool
/// at device time `t`, tissue at rest.
fn model_at(t: f64) -> (Palpation, LocalModel) {
    let mut sys = block();
    let (tool, path) = Palpation::on_top(&mut sys, 0.004, 0.01, ContactLaw::stiff(200.0), 0.1).unwrap();
    sys.set_tool_pose(tool, path.at(t)).unwrap();
    sys.compute_forces().unwrap();
    let model = StiffnessEstimator::default().model(&sys, tool).unwrap();
    assert!(model.force.z > 0.0, "the tool must touch: {model:?}");
    (path, model)
}

/// A device of `ticks` ticks at 1 kHz moving along `pose` while the simulation
/// publishes `model` and then stalls (blocked on a channel until the device is done).
fn render_stalled(model: LocalModel, pose: impl Fn(f64) -> Pose, ticks: u64, max_force: f64) -> DeviceLog {
    let (mut device, mut sim) = haptic_link(pose(0.0));
    let (release, stalled) = std::sync::mpsc::channel::<()>();
    std::thread::scope(|s| {
        s.spawn(move || {
            sim.publish_model(model);
            stalled.recv().unwrap(); // stalled until the device is done
        });
        while device.model().step != model.step || device.model().force != model.force {
            std::thread::yield_now();
        }
        let log = run_device(&mut device, pose, 1000.0, ticks, max_force, Instant::now(), SPIN);
        release.send(()).unwrap();
        log
    })
}

/// `System::tool_stiffness` equals a central finite difference of the tool force
/// with respect to the tool's translation, for a sphere and for a tilted capsule
/// (shaft and cap contacts) pressed 3 mm into the block.
#[test]
fn tool_stiffness_is_the_derivative_of_the_tool_force() {
    link();
    let law = ContactLaw::stiff(200.0);
    let tools = [
        Tool::sphere(0.01, law).at(Pose::translation(Vec3::new(0.021, 0.019, 0.02 + 0.01 - 0.004))),
        Tool::capsule(0.005, 0.008, law).at(Pose::new(
            Vec3::new(0.018, 0.021, 0.02 + 0.005 - 0.0015),
            Vec3::new(1.3, 0.4, 0.0),
        )
        .unwrap()),
    ];
    for tool in tools {
        let mut sys = block();
        let id = sys.add_tool(tool).unwrap();
        let base = tool.pose;
        let f0 = force_at(&mut sys, id, base, base.translation);
        let k = sys.tool_stiffness(id).unwrap();
        let n = sys.tools().contacts().len();
        assert!(n >= 4 && f0.z > 0.0, "{n} contacts, force {f0:?}");
        // central differences, h = 0.1 µm, with the contact set unchanged (no node
        // crosses the tool surface within ±h — checked below): the force is smooth
        // there and the truncation error is O(h²/r²) ≈ (1e-7/5e-3)² ≈ 4e-10
        // relative (measured 2e-10 and 6e-10); round-off, ~1e-16·|F|/h ≈ 1e-9 N/m,
        // is 1e-12 of |K| ~ 1e3 N/m. 1e-8 leaves 15× margin. (No contact lies within
        // h of the capsule's shaft/cap junction, where the distance is only C¹.)
        let h = 1e-7;
        let mut fd = Matrix3::zeros();
        for j in 0..3 {
            let mut e = Vec3::zeros();
            e[j] = h;
            let fp = force_at(&mut sys, id, base, base.translation + e);
            let np = sys.tools().contacts().len();
            let fm = force_at(&mut sys, id, base, base.translation - e);
            assert_eq!((np, sys.tools().contacts().len()), (n, n), "contact set changed");
            fd.set_column(j, &((fp - fm) / (2.0 * h)));
        }
        let err = (k - fd).norm() / k.norm();
        assert!(
            err < 1e-8,
            "relative error {err:e}: stiffness\n{k}\nfinite difference\n{fd}"
        );
        assert!((k - k.transpose()).norm() < 1e-12 * k.norm(), "symmetric");
        // the tool pushed further down feels a stiffer push up (shallow presses:
        // the spring term k·n nᵀ outweighs the turning term φ/r)
        assert!(k[(2, 2)] < 0.0, "{k}");
    }
}

/// A simulation that publishes one model in contact and then stalls (blocked on a
/// channel until the device is done): the device still completes every tick, the
/// model it renders only ages, and the force stays bounded, never pulls and does
/// no net work around the closed palpation path (passive).
#[test]
fn the_device_never_waits_for_a_stalled_simulation() {
    link();
    // the model at the deepest point of the press (device time 0.05 s)
    let (path, model) = model_at(0.05);
    // half the deepest force: the clamp must act
    let max_force = 0.5 * model.force.norm();
    // 0.2 s of device time at 1 kHz: two presses, the path closes at tick 200
    let ticks = 201u64;
    let log = render_stalled(model, |t| path.at(t), ticks, max_force);
    // every tick ran, none rendered a newer model, and the model only aged
    assert_eq!(log.forces.len() as u64, ticks);
    assert_eq!(log.fresh, 0);
    assert!(log.ages.windows(2).all(|a| a[1] > a[0]), "staleness must grow");
    // bounded by the clamp (up to the round-off of one rescaling) and never pulling
    for (_, _, f) in &log.forces {
        assert!(f.norm() <= max_force * (1.0 + 1e-12), "{f:?}");
        assert!(f.dot(&model.force) >= 0.0, "pulls: {f:?}");
    }
    // clamped at the deepest ticks, free when lifted
    assert!(log.forces.iter().any(|(_, _, f)| f.norm() > 0.99 * max_force));
    assert!(
        log.forces.iter().any(|(_, _, f)| *f == Vec3::zeros()),
        "{model:?} {:?}",
        &log.forces[..3]
    );
    // passive: the work of the rendered force around the closed path. The field is
    // a clamped gradient of one fixed potential, so the trapezoidal sum over the
    // 1 ms samples vanishes up to the error at the few ticks where a clamp
    // switches: a force jump ≤ max_force times one tick's motion (≤ 2e-5 m: 6 mm
    // of press at π/0.1 s peak speed is 0.19 m/s × 1e-3 s... bounded by 2e-4 m)
    // per switch, some 8 switches: 2e-3 m × max_force. A non-passive model gains
    // of the order of max_force × the 6 mm stroke, three times that.
    let work: f64 = log
        .forces
        .windows(2)
        .map(|w| 0.5 * (w[0].2 + w[1].2).dot(&(w[1].1 - w[0].1)))
        .sum();
    let (a, b) = (log.forces[0].1, log.forces[ticks as usize - 1].1);
    assert!((a - b).norm() < 1e-12, "the path is closed");
    assert!(work.abs() < 2e-3 * max_force, "work {work} J around a closed path");
}

/// A device that jumps 1 cm into the tissue and sweeps there while the simulation
/// stalls on one model: the rendered force stays within the model's documented
/// bound |F₀| + ‖K‖_F × reach (far below what the unbounded first-order model
/// extrapolates there), reaches it, and within the reach the model is rendered
/// unchanged.
#[test]
fn a_device_far_from_a_stalled_model_renders_a_bounded_force() {
    link();
    // the model halfway down the press (the still-tissue K: the stiffest the
    // estimator publishes, so the unbounded extrapolation is largest)
    let (_, model) = model_at(0.03);
    let x0 = model.position;
    assert!(model.stiffness.norm() > 0.0, "{model:?}");
    assert_eq!(model.reach, 2.5e-4);
    let max_force = 10.0; // a desktop device's peak: not the active limit here
    let bound = model.bound(max_force);
    assert!(bound < max_force);
    // ticks 0–19 within the reach (0.1 mm down), then a jump 1 cm down sweeping
    // ±5 mm along x for 80 ticks
    let within = Vec3::new(0.0, 0.0, -1e-4);
    let pose = move |t: f64| {
        let k = (t * 1000.0).round();
        if k < 20.0 {
            return Pose::translation(x0 + within);
        }
        let phase = (k - 20.0) / 80.0 * std::f64::consts::TAU;
        Pose::translation(x0 + Vec3::new(0.005 * phase.sin(), 0.0, -0.01))
    };
    let far = x0 + Vec3::new(0.0, 0.0, -0.01);
    // what the model says without the bound: several times more
    let unbounded = (model.force + model.stiffness * (far - x0)).norm();
    assert!(unbounded > 3.0 * bound, "unbounded {unbounded} N, bound {bound} N");
    let ticks = 100u64;
    let log = render_stalled(model, pose, ticks, max_force);
    assert_eq!(log.forces.len() as u64, ticks);
    assert_eq!(log.fresh, 0, "the simulation stalled");
    // within the reach the model is rendered as computed (one product and sum:
    // round-off of a few ulps of |F|, 1e-14 relative leaves margin)
    let exact = model.force + model.stiffness * within;
    for (_, _, f) in &log.forces[..20] {
        assert!((f - exact).norm() <= 1e-14 * exact.norm(), "{f:?} vs {exact:?}");
    }
    // beyond: never above the bound (up to one rescaling's round-off), never
    // pulling, and at the bound right after the jump
    for (_, x, f) in &log.forces[20..] {
        assert!(f.norm() <= bound * (1.0 + 1e-12), "{f:?} at {x:?}: bound {bound}");
        assert!(f.dot(&model.force) >= 0.0, "pulls: {f:?}");
    }
    assert!(
        (log.forces[20].2.norm() - bound).abs() <= 1e-12 * bound,
        "{:?}",
        log.forces[20]
    );
}
