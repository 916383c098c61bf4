//! Rigid tools in contact with the tissue (`heml::system::contact`): a sphere pressed
//! into a clamped block under gravity, stepped by backward Euler at 10 ms with a
//! contact far stiffer than the explicit step allows, then held at equilibrium —
//! penetration within the documented tolerance, Newton's third law between the tool,
//! the support and the weight, a force that grows with indentation — and bad input.

use heml::integrators::BackwardEuler;
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::prelude::*;
use heml::scene::Scene;
use heml::system::contact::{ContactLaw, Tool};
use heml::system::control::Pose;
use heml::system::{StaticOptions, System};

fn link() {
    let _ = (heml::integrators_list(), heml::materials_list());
}

/// Block 6 × 6 × 4 cm (1920 tets) of soft tissue (E = 5 kPa, ν = 0.45), clamped at
/// its base z = 0, under gravity, with mass damping.
fn block() -> System {
    let mesh = box_mesh([0.06, 0.06, 0.04], [8, 8, 5], HexSplit::Six).unwrap();
    System::builder(mesh)
        .material("neo_hookean", Params::from([("E", 5e3), ("nu", 0.45)]))
        .unwrap()
        .density(1000.0)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .fix_where(|p| p.z < 1e-9)
        .rayleigh(15.0, 0.0)
        .energy_every(0)
        .build()
        .unwrap()
}

const R: f64 = 0.015;
const TOP: f64 = 0.04;
/// Contact stiffness (N/m per node): limits the explicit step of the lightest
/// surface node (~3e-5 kg) to ~0.3 ms; backward Euler steps at 10 ms.
const K: f64 = 1000.0;

/// The sphere's centre for an indentation `depth` of the undeformed top face.
fn sphere_at(depth: f64) -> Pose {
    Pose::translation(Vec3::new(0.03, 0.03, TOP + R - depth))
}

/// Σ |f_i| over the contacts: the summed normal load the penalty springs carry.
fn normal_load(sys: &System) -> f64 {
    sys.tools().contacts().iter().map(|c| c.force.norm()).sum()
}

#[test]
fn a_sphere_pressed_into_a_clamped_block() {
    link();
    let mut sys = block();
    let law = ContactLaw {
        stiffness: K,
        damping: 0.05,
    };
    let tool = sys.add_tool(Tool::sphere(R, law).at(sphere_at(-0.001))).unwrap();
    // the contact is stiffer than the explicit stable step: the system says so
    assert!(
        sys.warnings()
            .iter()
            .any(|w| w.contains("limits the explicit time step")),
        "{:?}",
        sys.warnings()
    );

    // press from 1 mm above to 4 mm deep at u = 5 mm / 0.3 s, then hold, by backward
    // Euler at dt = 10 ms (~30× the contact's explicit limit)
    let mut be = BackwardEuler::default();
    let dt = 0.01;
    let u = 0.005 / 0.3;
    for k in 1..=60 {
        let depth = (-0.001 + u * dt * k as f64).min(0.004);
        sys.set_tool_pose(tool, sphere_at(depth)).unwrap();
        be.step(&mut sys, dt).unwrap();
        let f = normal_load(&sys);
        let d = sys.tools().max_penetration();
        // the documented tolerance d ≤ F/k + u·dt (F the summed normal load: one
        // node carrying all of it is the worst case; u·dt is the tool's advance in
        // one step); 1e-9 m absorbs the Newton/CG error of one linearised step
        assert!(d <= f / K + u * dt + 1e-9, "step {k}: penetration {d:e} m, F = {f:e} N");
    }
    assert!(sys.positions().iter().all(|p| p.iter().all(|c| c.is_finite())));
    assert!(sys.tools().max_penetration() > 0.0);

    // equilibrium at three indentations: static solves to 1e-12 of the load scale
    let opts = StaticOptions {
        tol: 1e-12,
        ..StaticOptions::default()
    };
    let weight = Vec3::new(0.0, 0.0, -9.81 * sys.total_mass());
    let mut last = 0.0;
    for depth in [0.002, 0.004, 0.006] {
        sys.set_tool_pose(tool, sphere_at(depth)).unwrap();
        let report = sys.solve_static(&opts).unwrap();
        assert!(report.converged, "{report:?}");
        let w = sys.tool_wrench(tool).unwrap();
        let reaction = sys.total_reaction();
        // Newton's third law: the tissue pushes the tool with what the support and
        // gravity put in, F_tool = W + R (the elastic forces sum to zero). The free
        // nodes' residual is ≤ 1e-12 × the load scale each, so the balance holds far
        // below 1e-6 relative
        let imbalance = (w.force - (weight + reaction)).norm() / reaction.norm();
        assert!(imbalance < 1e-6, "depth {depth}: imbalance {imbalance:e}");
        // the tool is pushed up, and hardly sideways (the setup is symmetric about
        // the sphere's axis up to the mesh's diagonal splits)
        assert!(w.force.z > 0.0 && w.force.xy().norm() < 0.05 * w.force.z, "{w:?}");
        // at rest (no damping force) k·Σd = F, the summed normal load, so the
        // deepest node is within F/k (1e-9: round-off of the sum)
        let d = sys.tools().max_penetration();
        assert!(
            d > 0.0 && d <= normal_load(&sys) / K * (1.0 + 1e-9),
            "depth {depth}: {d:e}"
        );
        // the normals of a 1.5 cm sphere over a ≤ 1 cm contact patch are within
        // ~40° of vertical, so the tool force is most of the summed normal load
        assert!(w.force.z > 0.75 * normal_load(&sys));
        // and the indentation is mostly tissue, not penetration
        assert!(d < 0.25 * depth, "depth {depth}: penetration {d:e}");
        // monotonic in the indentation
        assert!(w.force.z > last, "depth {depth}: {} N after {last} N", w.force.z);
        last = w.force.z;
        eprintln!(
            "indentation {:.1} mm: tool force {:.4e} N, penetration {:.3e} mm, {} contacts",
            depth * 1e3,
            w.force.z,
            d * 1e3,
            sys.tools().contacts().len()
        );
    }
}

#[test]
fn bad_tool_input_is_refused_and_changes_nothing() {
    link();
    let mut sys = block();
    let law = ContactLaw::stiff(100.0);
    let id = sys.add_tool(Tool::sphere(0.01, law).at(sphere_at(0.002))).unwrap();
    sys.compute_forces().unwrap();
    let before = (
        sys.tool_wrench(id).unwrap(),
        *sys.tools().get(id).unwrap(),
        sys.forces().to_vec(),
    );

    let nan = Pose::translation(Vec3::new(0.03, f64::NAN, 0.05));
    let e = sys.set_tool_pose(id, nan).unwrap_err().to_string();
    assert!(e.contains("tool #0") && e.contains("not finite"), "{e}");
    let e = sys.add_tool(Tool::sphere(-0.01, law)).unwrap_err().to_string();
    assert!(e.contains("radius") && e.contains("> 0"), "{e}");
    let e = sys
        .add_tool(Tool::capsule(0.01, 0.02, ContactLaw::stiff(-5.0)))
        .unwrap_err()
        .to_string();
    assert!(e.contains("stiffness"), "{e}");
    let e = sys
        .add_tool(Tool::half_space(ContactLaw {
            stiffness: 1.0,
            damping: f64::NAN,
        }))
        .unwrap_err()
        .to_string();
    assert!(e.contains("damping"), "{e}");
    assert_eq!(sys.tools().len(), 1);
    // nothing moved: same tool, same forces at the next evaluation
    assert_eq!(*sys.tools().get(id).unwrap(), before.1);
    sys.compute_forces().unwrap();
    assert_eq!(sys.tool_wrench(id).unwrap(), before.0);
    assert_eq!(sys.forces(), &before.2[..]);

    // inside a step: refused
    sys.begin_step(1e-4).unwrap();
    let e = sys.set_tool_pose(id, sphere_at(0.0)).unwrap_err().to_string();
    assert!(e.contains("inside a step"), "{e}");
    sys.compute_forces().unwrap();
    sys.kick(1e-4);
    sys.drift(1e-4);
    sys.finish_step().unwrap();

    // an unknown id (a removed tool's) names the tool
    sys.remove_tool(id).unwrap();
    for e in [
        sys.tool_wrench(id).unwrap_err().to_string(),
        sys.set_tool_pose(id, sphere_at(0.0)).unwrap_err().to_string(),
        sys.remove_tool(id).unwrap_err().to_string(),
    ] {
        assert!(e.contains("tool #0 does not exist"), "{e}");
    }
    // without the tool the forces are those of the tissue alone: no contact left
    sys.compute_forces().unwrap();
    assert!(sys.tools().contacts().is_empty());
}

/// A scene with a scripted capsule (a laparoscopic tip) pressing the top of a
/// clamped block and lifting off again, stepped by backward Euler: the energy CSV
/// keeps its columns and appends the tool's force; the force rises while the tool
/// goes down and vanishes once it has lifted off.
#[test]
fn a_scene_replays_a_scripted_tool_path() {
    link();
    let dir = std::env::temp_dir().join(format!("heml-tools-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let text = format!(
        r#"
[mesh]
generate = {{ kind = "box", size = [0.04, 0.04, 0.02], cells = [6, 6, 3] }}
[[material]]
law = "neo_hookean"
params = {{ E = 5e3, nu = 0.45 }}
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
[damping]
mass = 15.0
[solver]
integrator = "backward_euler"
dt = 0.01
duration = 0.6
[output]
dir = "{}"
vtu = false
csv_every = 1
[[tool]]
name = "tip"
shape = "capsule"
radius = 0.004
half_length = 0.01
stiffness = 500.0
damping = 0.05
path = [
  {{ time = 0.0, position = [0.02, 0.02, 0.0155] }},
  {{ time = 0.3, position = [0.02, 0.02, 0.0105] }},
  {{ time = 0.4, position = [0.02, 0.02, 0.0105] }},
  {{ time = 0.5, position = [0.02, 0.02, 0.04] }},
]
"#,
        dir.display().to_string().replace('\\', "/")
    );
    let mut sim = Scene::from_toml_str(&text, ".").unwrap().build().unwrap();
    sim.run(|_| {}).unwrap();
    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    // existing columns unchanged (dt_reason at 12, cg_iterations at 13), tool after
    assert_eq!(header[12], "dt_reason");
    assert_eq!(header[13], "cg_iterations");
    assert_eq!(&header[14..], ["tool_tip_fx", "tool_tip_fy", "tool_tip_fz"]);
    let rows: Vec<(f64, f64)> = lines
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            assert_eq!(c.len(), 17, "{l}");
            (c[0].parse().unwrap(), c[16].parse().unwrap())
        })
        .collect();
    let fz = |t: f64| rows.iter().find(|(tr, _)| (tr - t).abs() < 1e-9).unwrap().1;
    // the capsule's tip (z = 0.0155 − 0.01 − 0.004 = 1.5 mm above the top at t = 0)
    // reaches the surface at t = 0.09 s and presses 3.5 mm at t = 0.3 s
    assert_eq!(fz(0.05), 0.0);
    assert!(fz(0.15) > 0.0 && fz(0.3) > fz(0.15), "{} {}", fz(0.15), fz(0.3));
    // lifted 3 cm clear by t = 0.5: no contact, no force
    assert_eq!(fz(0.6), 0.0);
    let _ = std::fs::remove_dir_all(&dir);

    // a path going back in time is named by its key
    let bad = text.replace("time = 0.4", "time = 0.3");
    let e = Scene::from_toml_str(&bad, ".")
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("[[tool]] #1") && e.contains("tool[0].path[2].time = 0.3 must increase"),
        "{e}"
    );
}
