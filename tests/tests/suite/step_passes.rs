//! The per-node passes of a step (kick, drift, snapshot, end-of-step checks) run on
//! rayon for large systems; their results must not depend on the thread count.

use heml::integrators::{SymplecticEuler, VelocityVerlet};
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::prelude::*;

fn link() {
    let _ = (heml::integrators_list(), heml::materials_list());
}

/// A 10 164-node block, clamped, under gravity, with mass and stiffness damping; the
/// parallel-pass threshold is lowered to 8192 nodes so that the passes run on rayon
/// (the default is far higher; results must not depend on it, only speed).
fn block() -> System {
    heml::system::set_parallel_pass_threshold(8192);
    let mesh = box_mesh([0.1, 0.1, 0.1], [21, 21, 20], HexSplit::Six).unwrap();
    assert!(mesh.n_nodes() > heml::system::parallel_pass_threshold());
    heml::system(mesh)
        .material("neo_hookean", Params::from([("E", 5e3), ("nu", 0.45)]))
        .unwrap()
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .fix_where(|p| p.x < 1e-9)
        .rayleigh(5.0, 1e-4)
        .energy_every(0)
        .build()
        .unwrap()
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

/// Positions, velocities and the statistics of 8 steps of two schemes are the same
/// bits on 1, 2 and 3 threads (no tolerance: every pass computes each node from its
/// own data, and the reductions break ties by node id, so any difference is a bug);
/// a NaN injected at two nodes is reported at the first of them on every pool.
#[test]
fn step_passes_give_the_same_bits_at_any_thread_count() {
    link();
    let run = |threads: usize| {
        pool(threads).install(|| {
            let mut out = Vec::new();
            for verlet in [false, true] {
                let mut sys = block();
                let dt = 0.5 * sys.stable_dt();
                let mut stats = Vec::new();
                for _ in 0..8 {
                    let s = if verlet {
                        VelocityVerlet.step(&mut sys, dt)
                    } else {
                        SymplecticEuler.step(&mut sys, dt)
                    };
                    stats.push(s.unwrap());
                }
                out.push(format!("{:?} {:?} {:?}", sys.positions(), sys.velocities(), stats));
                sys.velocities_mut()[9000].y = f64::NAN;
                sys.velocities_mut()[9500].x = f64::INFINITY;
                let e = SymplecticEuler.step(&mut sys, dt).unwrap_err().to_string();
                assert!(e.contains("at node 9000 "), "{threads} threads: {e}");
            }
            out
        })
    };
    let one = run(1);
    assert!(one[0].contains("e-"), "the block moved");
    for threads in [2, 3] {
        assert!(run(threads) == one, "{threads} threads differ from 1");
    }
}
