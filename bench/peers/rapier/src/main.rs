//! Benchmark-only peer: time rapier3d's soft-body step (Stable Neo-Hookean tet cells) on a
//! Gmsh 4.1 ASCII tet mesh. Not part of the HEML workspace; never built by `cargo test`.
//!
//! usage: heml-peer-rapier MESH.msh [steps] [constraints|fem]
//!
//! This is a full simulation step (rapier's constraint or implicit-FEM solver, single thread,
//! f32), not a bare force evaluation: compare it with HEML's "full step" line, not its tets/s.
use rapier3d::prelude::*;
use std::collections::HashMap;
use std::time::Instant;

fn read_msh41(path: &str) -> (Vec<[f64; 3]>, Vec<[u32; 4]>) {
    let text = std::fs::read_to_string(path).expect("read mesh");
    let lines: Vec<&str> = text.lines().collect();
    let (mut pts, mut tets, mut map) = (Vec::new(), Vec::new(), HashMap::new());
    let mut i = 0;
    while i < lines.len() {
        match lines[i].trim() {
            "$Nodes" => {
                let h: Vec<usize> = lines[i + 1].split_whitespace().map(|s| s.parse().unwrap()).collect();
                i += 2;
                for _ in 0..h[0] {
                    let b: Vec<usize> = lines[i].split_whitespace().map(|s| s.parse().unwrap()).collect();
                    let nb = b[3];
                    i += 1;
                    for k in 0..nb {
                        let tag: usize = lines[i + k].trim().parse().unwrap();
                        let c: Vec<f64> = lines[i + nb + k].split_whitespace().take(3).map(|s| s.parse().unwrap()).collect();
                        map.insert(tag, pts.len() as u32);
                        pts.push([c[0], c[1], c[2]]);
                    }
                    i += 2 * nb;
                }
            }
            "$Elements" => {
                let h: Vec<usize> = lines[i + 1].split_whitespace().map(|s| s.parse().unwrap()).collect();
                i += 2;
                for _ in 0..h[0] {
                    let b: Vec<usize> = lines[i].split_whitespace().map(|s| s.parse().unwrap()).collect();
                    let (etype, nb) = (b[2], b[3]);
                    i += 1;
                    if etype == 4 {
                        for k in 0..nb {
                            let v: Vec<usize> = lines[i + k].split_whitespace().map(|s| s.parse().unwrap()).collect();
                            tets.push([map[&v[1]], map[&v[2]], map[&v[3]], map[&v[4]]]);
                        }
                    }
                    i += nb;
                }
            }
            _ => i += 1,
        }
    }
    (pts, tets)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("usage: heml-peer-rapier MESH.msh [steps] [constraints|fem]");
    let steps: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(25);
    let solver = match args.get(3).map(|s| s.as_str()) {
        Some("fem") => SoftBodySolver::Fem,
        _ => SoftBodySolver::Constraints,
    };
    let t0 = Instant::now();
    let (pts, mut tets) = read_msh41(path);
    // positive orientation for every tet
    for t in tets.iter_mut() {
        let p = |k: usize| pts[t[k] as usize];
        let (a, b, c, d) = (p(0), p(1), p(2), p(3));
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
        let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
            + u[2] * (v[0] * w[1] - v[1] * w[0]);
        if det < 0.0 {
            t.swap(1, 2);
        }
    }
    let xmin = pts.iter().map(|p| p[0]).fold(f64::MAX, f64::min);
    let xmax = pts.iter().map(|p| p[0]).fold(f64::MIN, f64::max);
    let pinned: Vec<u32> = (0..pts.len() as u32)
        .filter(|&i| pts[i as usize][0] < xmin + 0.05 * (xmax - xmin))
        .collect();
    let positions: Vec<Vector> = pts.iter().map(|p| Vector::new(p[0] as Real, p[1] as Real, p[2] as Real)).collect();
    let n_tets = tets.len();
    let builder = SoftBodyBuilder::new(positions)
        .cells(tets)
        .cell_model(SoftBodyCellModel::NeoHookean)
        .material(SoftBodyMaterial {
            young_modulus: 1.0e5,
            poisson_ratio: 0.4,
            elastic_damping_ratio: 0.0,
            ..Default::default()
        })
        .solver(solver)
        .no_surface_collider()
        .can_sleep(false)
        .pinned_particles(pinned.clone());
    let mut world = PhysicsWorld::new();
    world.insert_soft_body(builder);
    println!(
        "rapier3d 0.36.1 soft body: {} particles ({} pinned), {} tets, solver {:?}, cells NeoHookean, built in {:.2} s",
        pts.len(), pinned.len(), n_tets, solver, t0.elapsed().as_secs_f64()
    );
    // warm-up (first steps build colorings/structures)
    let tw = Instant::now();
    for _ in 0..3 {
        world.step();
    }
    println!("warm-up 3 steps: {:.2} s", tw.elapsed().as_secs_f64());
    let mut times: Vec<f64> = (0..steps)
        .map(|_| {
            let t = Instant::now();
            world.step();
            t.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let m = times[times.len() / 2];
    println!(
        "rapier step ({:?}): median {:.3} ms/step over {} steps, {:.2} M tets/s per step, {:.1} ns/tet",
        solver, m * 1e3, steps, n_tets as f64 / m / 1e6, m / n_tets as f64 * 1e9
    );
    println!("RAPIER_RESULT tets={} solver={:?} median_s={:.9e}", n_tets, solver, m);
}
