//! Overhead of the adaptive time step (`dt_policy = "adapt"`, issue 14 item 10) on a
//! ~100k-tet box: the same system stepped with a fixed step and with
//! [`AdaptiveStep::next`] called before every step (re-estimating every
//! `DEFAULT_ADAPT_EVERY` steps), side by side in one run, in alternating rounds so
//! that both see the same machine load.
//!
//! Run with `cargo bench -p heml-validation --features criterion --bench adaptive_step`.
//! Prints the per-step time of both and the overhead's median and range over the
//! rounds; nothing is asserted.

use heml::mesh::generate::box_of_about;
use heml::prelude::*;
use heml::system::{find_integrator, AdaptiveStep, DeformedEstimate, DEFAULT_ADAPT_EVERY};
use std::time::Instant;

const ROUNDS: usize = 12;
const STEPS: usize = 100;

fn main() {
    let _ = heml::materials_list();
    let mesh = box_of_about(100_000).expect("mesh");
    let n_tets = mesh.n_tets();
    let (lo, hi) = mesh.bounding_box();
    let top: Vec<usize> = (0..mesh.n_nodes())
        .filter(|&i| mesh.nodes()[i].z > hi.z - 1e-9)
        .collect();
    let h = hi.z - lo.z;
    let params = heml_validation::fixtures::soft_tissue_params("neo_hookean", 3e3, 0.45).expect("params");
    let mut sys = System::builder(mesh)
        .material("neo_hookean", &params)
        .expect("law")
        .fix_where(|p| p.z < lo.z + 1e-9)
        // the top pressed down 10 %, slowly enough for the fixed step to stay stable
        .prescribe(&top, Vec3::new(0.0, 0.0, -0.1 * h), Ramp::Smooth { duration: 0.5 })
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .rayleigh(10.0, 0.0)
        .time_step_policy(TimeStepPolicy::Adapt)
        .build()
        .expect("system");
    let mut integrator = find_integrator("symplectic_euler").expect("integrator").instantiate();
    let dt = 0.5 * sys.stable_dt();
    let mut adapt = AdaptiveStep::new(&sys, dt, DEFAULT_ADAPT_EVERY);
    let (mut fixed, mut adaptive, mut overhead) = (vec![], vec![], vec![]);
    for round in 0..ROUNDS {
        let mut time = |with_adapt: bool, sys: &mut System| {
            let start = Instant::now();
            for _ in 0..STEPS {
                // both step with the same dt: only the controller's cost differs
                if with_adapt {
                    std::hint::black_box(adapt.next(sys));
                }
                integrator.step(sys, dt).expect("step");
            }
            start.elapsed().as_secs_f64() / STEPS as f64
        };
        // alternate which goes first
        let (f, a) = if round % 2 == 0 {
            let f = time(false, &mut sys);
            (f, time(true, &mut sys))
        } else {
            let a = time(true, &mut sys);
            (time(false, &mut sys), a)
        };
        fixed.push(f);
        adaptive.push(a);
        overhead.push(100.0 * (a - f) / f);
    }
    // the estimate alone, timed on the deformed state: the overhead per step is its
    // cost over `DEFAULT_ADAPT_EVERY` steps (steadier than the difference above on a
    // loaded machine)
    let estimate = DeformedEstimate::new(&sys);
    let mut checks: Vec<f64> = (0..ROUNDS * 4)
        .map(|_| {
            let start = Instant::now();
            std::hint::black_box(estimate.time_step(&sys));
            start.elapsed().as_secs_f64()
        })
        .collect();
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2])
    };
    let range = |v: &[f64]| (v[0], v[v.len() - 1]);
    let (mf, ma, mo) = (median(&mut fixed), median(&mut adaptive), median(&mut overhead));
    println!(
        "adaptive step on {n_tets} tets ({} threads), {ROUNDS} rounds of {STEPS} steps, re-estimate every {DEFAULT_ADAPT_EVERY}:",
        rayon::current_num_threads()
    );
    println!(
        "  fixed    {:.3} ms/step (range {:.3}..{:.3})",
        mf * 1e3,
        range(&fixed).0 * 1e3,
        range(&fixed).1 * 1e3
    );
    println!(
        "  adaptive {:.3} ms/step (range {:.3}..{:.3})",
        ma * 1e3,
        range(&adaptive).0 * 1e3,
        range(&adaptive).1 * 1e3
    );
    let mc = median(&mut checks);
    println!(
        "  one estimate {:.3} ms (range {:.3}..{:.3}) = {:.2} % of a fixed step per step at every = {DEFAULT_ADAPT_EVERY}",
        mc * 1e3,
        range(&checks).0 * 1e3,
        range(&checks).1 * 1e3,
        100.0 * mc / (DEFAULT_ADAPT_EVERY as f64 * mf)
    );
    println!(
        "  overhead median {mo:+.2} % (range {:+.2} .. {:+.2} %), {} checks, min J {:.3}",
        range(&overhead).0,
        range(&overhead).1,
        adapt.checks(),
        adapt.min_j()
    );
}
