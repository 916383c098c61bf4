//! `heml bench --tangent`: what a law's tangent stiffness costs per tet, the work an
//! implicit step adds to its force evaluations. The update (each tet's 12×12
//! stiffness from the generated second derivatives at a deformed state, projected to
//! positive semi-definite as implicit steps do by default, and exact) is what every
//! refactorisation starts with; the product K·dx is what each CG iteration applies.
//! Both are timed round-robin with the law's force evaluation at 1 and `--threads`
//! threads, so that their ratio to it is taken sample by sample under the same load;
//! `--against` adds another law's projected update and forces on one thread.

use super::bench::{max, median, median_ratio, min, spread, time_round_robin, tissue_params, Case, Work};
use heml::force::{ElasticForces, TangentOperator};
use heml::prelude::*;
use heml::registry::MaterialEntry;
use heml_validation::fixtures::with_bench_fibres;
use std::sync::Mutex;

/// One law's force field and tangent operators.
struct LawCases {
    name: &'static str,
    field: Box<dyn ElasticForces>,
    projected: Mutex<Box<dyn TangentOperator>>,
    /// The unprojected tangent (for the timed law only).
    exact: Option<Mutex<Box<dyn TangentOperator>>>,
}

impl LawCases {
    /// The field and tangents of `entry` at the bench's soft-tissue parameters on
    /// `mesh` (fibre laws with the bench's fibres), the exact tangent when `exact`.
    fn new(entry: &MaterialEntry, mesh: &TetMesh, exact: bool) -> heml::Result<Self> {
        let law = with_bench_fibres(entry.instantiate(&tissue_params(entry)?)?, mesh)?;
        let opts = ForceOptions::default();
        let tangent = |project: bool| -> heml::Result<Mutex<Box<dyn TangentOperator>>> {
            let op = law.tangent(mesh, None, &opts, project)?.ok_or_else(|| {
                HemlError::Invalid(format!(
                    "law '{}' has no tangent stiffness: there is nothing to time",
                    entry.name
                ))
            })?;
            Ok(Mutex::new(op))
        };
        Ok(LawCases {
            name: entry.name,
            field: law.force_field(mesh, None, &opts)?,
            projected: tangent(true)?,
            exact: if exact { Some(tangent(false)?) } else { None },
        })
    }
}

/// Times the tangent of `entry` (and of `against`) on `mesh` at the deformed
/// positions `x`, on each pool of `pools`, `repeats` round-robin samples.
pub(super) fn run(
    entry: &MaterialEntry,
    against: Option<&MaterialEntry>,
    mesh: &TetMesh,
    x: &[Vec3],
    pools: &[rayon::ThreadPool],
    repeats: usize,
) -> heml::Result<()> {
    let mine = LawCases::new(entry, mesh, true)?;
    let other = against.map(|e| LawCases::new(e, mesh, false)).transpose()?;
    let n_tets = mesh.n_tets().max(1);
    // about 20 ms per sample for the forces and the product; an update costs tens of
    // force evaluations, so it takes a tenth of the calls
    let inner = (2_000_000 / n_tets).clamp(1, 1000);
    let inner_update = (200_000 / n_tets).clamp(1, 100);
    let update = |pool, op| Case {
        pool,
        work: Work::TangentUpdate(op),
        x,
        inner: inner_update,
    };
    let mut cases = Vec::new();
    for pool in pools {
        cases.push(Case::forces(pool, mine.field.as_ref(), x, inner, true));
        cases.push(update(pool, &mine.projected));
        cases.push(update(pool, mine.exact.as_ref().expect("made with exact")));
        cases.push(Case {
            pool,
            work: Work::TangentProduct(&mine.projected),
            x,
            inner,
        });
    }
    let per_pool = 4;
    if let Some(o) = &other {
        cases.push(Case::forces(&pools[0], o.field.as_ref(), x, inner, true));
        cases.push(update(&pools[0], &o.projected));
    }
    let samples = time_round_robin(&cases, repeats)?;
    let ns = |s: &[f64]| -> Vec<f64> { s.iter().map(|t| t / n_tets as f64 * 1e9).collect() };

    outln!();
    outln!(
        "tangent stiffness of {} ({} tets): update = each tet's 12×12 stiffness at the deformed state \
         (projected to PSD, the implicit default, and exact); product = y += K·dx; forces = the force \
         evaluation with the energy",
        entry.name,
        mesh.n_tets()
    );
    outln!(
        "{:<8} {:>22} {:>26} {:>26} {:>22} {:>24}",
        "threads",
        "forces ns/tet",
        "update, PSD ns/tet",
        "update, exact ns/tet",
        "product ns/tet",
        "PSD update / forces"
    );
    for (pool, s) in pools.iter().zip(samples.chunks(per_pool)) {
        let r: Vec<f64> = s[1].iter().zip(&s[0]).map(|(u, f)| u / f).collect();
        outln!(
            "{:<8} {:>22} {:>26} {:>26} {:>22} {:>23}×",
            pool.current_num_threads(),
            spread(&ns(&s[0]), 2),
            spread(&ns(&s[1]), 1),
            spread(&ns(&s[2]), 1),
            spread(&ns(&s[3]), 2),
            format!("{:.1} [{:.1}–{:.1}]", median_ratio(&s[1], &s[0]), min(&r), max(&r))
        );
    }
    if let Some(o) = &other {
        let k = per_pool * pools.len();
        let (forces, update) = (&samples[k], &samples[k + 1]);
        let line = |what: &str, ours: &[f64], theirs: &[f64]| {
            let r: Vec<f64> = ours.iter().zip(theirs).map(|(a, b)| a / b).collect();
            outln!(
                "{} vs {} ({what}, 1 thread): {:.2}× (per-round ratios {:.2}–{:.2}); {:.1} against {:.1} ns/tet",
                mine.name,
                o.name,
                median_ratio(ours, theirs),
                min(&r),
                max(&r),
                median(&mut ns(ours)),
                median(&mut ns(theirs))
            );
        };
        line("PSD tangent update", &samples[1], update);
        line("forces", &samples[0], forces);
    }
    outln!("(medians over {repeats} rounds, range: fastest–slowest sample; ratios: medians of the per-round ratios)");
    Ok(())
}
