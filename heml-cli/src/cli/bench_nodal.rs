//! `heml bench --nodal`: the cost per tet of the anti-locking (nodal and patch)
//! volumetric formulations against the standard (element) one, the fields of `--law` at
//! ν = 0.49 on the same mesh, timed round-robin at 1 and `--threads` threads, so
//! that their ratio is taken sample by sample under the same machine load.

use super::bench::{max, median_ratio, min, spread, time_round_robin, Case};
use heml::law::Volumetric;
use heml::prelude::*;
use heml::registry::MaterialEntry;
use heml_validation::fixtures::tissue_params;

/// Times the element, nodal and patch fields of `entry` on `mesh` at `x`, one case per
/// (pool, field), `repeats` samples of `inner` calls each; patches of `k` tets.
pub(super) fn run(
    entry: &MaterialEntry,
    mesh: &TetMesh,
    x: &[Vec3],
    pools: &[rayon::ThreadPool],
    repeats: usize,
    inner: usize,
    k: usize,
) -> heml::Result<()> {
    let params = tissue_params(entry, 3e3, 0.49).ok_or_else(|| {
        HemlError::Invalid(format!(
            "heml bench --nodal knows soft-tissue parameters for the built-in laws only, not '{}'",
            entry.name
        ))
    })?;
    let law = entry.instantiate(&params)?;
    let opts = ForceOptions::default();
    let element = law.force_field(mesh, None, &opts)?;
    let nodal = law
        .with_volumetric(Volumetric::nodal())?
        .force_field(mesh, None, &opts)?;
    let patch = law
        .with_volumetric(Volumetric::patch(k))?
        .force_field(mesh, None, &opts)?;
    let mut cases = Vec::new();
    for pool in pools {
        for field in [&element, &nodal, &patch] {
            cases.push(Case::forces(pool, field.as_ref(), x, inner, true));
        }
    }
    let samples = time_round_robin(&cases, repeats)?;
    let ns = |s: &[f64]| -> Vec<f64> { s.iter().map(|t| t / mesh.n_tets().max(1) as f64 * 1e9).collect() };
    outln!();
    outln!(
        "volumetric term of {} at nu = 0.49: element (standard) vs nodal and patch (k = {k}) (anti-locking, default stabilisation)",
        entry.name
    );
    outln!(
        "{:<8} {:>24} {:>24} {:>24} {:>24} {:>24}",
        "threads",
        "element ns/tet [range]",
        "nodal ns/tet [range]",
        "patch ns/tet [range]",
        "nodal/element [range]",
        "patch/element [range]"
    );
    for (pool, s) in pools.iter().zip(samples.chunks(3)) {
        let (e, n, p) = (ns(&s[0]), ns(&s[1]), ns(&s[2]));
        let ratio = |a: &[f64], i: usize| -> String {
            let r: Vec<f64> = a.iter().zip(&e).map(|(a, e)| a / e).collect();
            format!("{:.2} [{:.2}–{:.2}]", median_ratio(&s[i], &s[0]), min(&r), max(&r))
        };
        outln!(
            "{:<8} {:>24} {:>24} {:>24} {:>23}× {:>23}×",
            pool.current_num_threads(),
            spread(&e, 2),
            spread(&n, 2),
            spread(&p, 2),
            ratio(&n, 1),
            ratio(&p, 2)
        );
    }
    outln!("(medians over {repeats} rounds of {inner} calls, range: fastest–slowest sample; ratio: median of the per-round ratios)");
    if let Ok(load) = std::fs::read_to_string("/proc/loadavg") {
        outln!(
            "load average: {}",
            load.split_whitespace().take(3).collect::<Vec<_>>().join(" ")
        );
    }
    Ok(())
}
