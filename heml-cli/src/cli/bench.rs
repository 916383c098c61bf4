//! `heml bench`: force-evaluation throughput of HEML and of the standard P1 path,
//! measured in the same run (interleaved, medians), plus the time of full
//! semi-explicit steps through the `System`.

use crate::threads::{placement_for, thread_pool, Placement};
use clap::Args;
use heml::force::{Assembly, ElasticForces, SimdLevel, TangentOperator};
use heml::mesh::generate::box_of_about;
use heml::prelude::*;
use heml::registry::MaterialEntry;
use heml_validation::fixtures::{
    self, renumbered_at_load, shuffled, smooth_deformation as deformed, with_bench_fibres,
};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

/// Arguments of `heml bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Mesh file (.msh, .vtk, .vtu, .node/.ele, .mesh); default: a generated box.
    #[arg(long)]
    pub mesh: Option<PathBuf>,
    /// Number of tets of the generated box (ignored with --mesh).
    #[arg(long, default_value_t = 100_000)]
    pub tets: usize,
    /// Law (registry name, see `heml materials`).
    #[arg(long, default_value = "neo_hookean")]
    pub law: String,
    /// Threads of the parallel runs (default: all cores; at most 4 × the CPUs, up to
    /// 1024). 1 thread is always measured too.
    #[arg(long, value_parser = crate::threads::thread_count)]
    pub threads: Option<usize>,
    /// Timed samples per measurement (the median is reported; at most 100 000).
    #[arg(long, default_value_t = 25, value_parser = repeat_count)]
    pub repeats: usize,
    /// Shuffle node and tet numbering randomly before building the fields (as real
    /// meshes often arrive).
    #[arg(long)]
    pub shuffle: bool,
    /// Also time the plain serial reference kernels.
    #[arg(long)]
    pub reference: bool,
    /// Keep the mesh's node numbering. By default the nodes are renumbered along a
    /// Morton curve as loaded, as `heml run` does.
    #[arg(long)]
    pub keep_order: bool,
    /// Instead of the usual table: cost per tet of the HEML field on generated boxes
    /// of about 10k, 100k and 1M tets and on the 1M box shuffled (renumbered at load,
    /// and kept shuffled), timed interleaved in one run.
    #[arg(long)]
    pub scaling: bool,
    /// Let the OS place the worker threads. By default the k-th worker of each
    /// thread pool is pinned to the k-th CPU this process may use.
    #[arg(long)]
    pub no_pin: bool,
    /// Instead of the usual table: the 1 kHz haptic loop (a device thread moving a
    /// capsule over the organ, the simulation in real time, a 60 Hz display) on
    /// gen_kidney_20k and gen_kidney_100k of the shared meshes ($HEML_MESHES, or
    /// ../shared/meshes; or --mesh), with symplectic and backward Euler: loop
    /// compute time and period p50/p99/max.
    #[arg(long)]
    pub haptic: bool,
    /// Device time of each --haptic run, in seconds (default 3; from 0.1 to 600): at
    /// 1 kHz, a thousand device ticks per second.
    #[arg(long, value_name = "SECONDS", default_value_t = super::haptic::DEFAULT_SECONDS)]
    pub haptic_seconds: f64,
    /// Instead of the usual table: backward Euler at dt = 10 ms (--implicit-dt) on these meshes
    /// (liver-like tissue, ν = 0.49) against the best explicit integrator at its stable
    /// step on the same scene, at 1 and --threads threads. Without a mesh:
    /// gen_kidney_20k, gen_kidney_100k (mm) and sofa_liver (coordinates taken as cm)
    /// of the shared meshes ($HEML_MESHES, or ../shared/meshes).
    #[arg(long, num_args = 0.., value_name = "MESH")]
    pub implicit: Option<Vec<PathBuf>>,
    /// Scale of the --implicit meshes given by path to metres (default 1e-3:
    /// millimetre files, as the generated organ meshes).
    #[arg(long, default_value_t = 1e-3)]
    pub implicit_scale: f64,
    /// Implicit time step of the --implicit runs, in seconds (default 0.01; at most
    /// 0.1): e.g. 0.033 for one step per frame of a 30 Hz view. The long run keeps
    /// its simulated durations (0.5 s fall, 0.75 s press, 0.75 s grasp).
    #[arg(long, value_name = "SECONDS", default_value_t = super::bench_implicit::DEFAULT_DT)]
    pub implicit_dt: f64,
    /// CG preconditioner of the --implicit runs: symmetric_gauss_seidel (sequential,
    /// the default), parallel_gauss_seidel or block_jacobi.
    #[arg(long, default_value = "symmetric_gauss_seidel", value_name = "NAME")]
    pub preconditioner: String,
    /// Fill-reducing ordering of the --implicit runs' Cholesky factor: auto (the
    /// default), amd, node_amd or nested_dissection.
    #[arg(long, default_value = "auto", value_name = "NAME")]
    pub cholesky_ordering: String,
    /// Precision of the --implicit runs' Cholesky factor: auto (the default), f64 or
    /// f32; several, comma-separated (`f64,f32`), run each Cholesky case once per
    /// precision, side by side in the same run.
    #[arg(long, default_value = "auto", value_name = "NAMES", value_delimiter = ',')]
    pub factor_precision: Vec<String>,
    /// Skip the CG rows and long runs of --implicit, keeping the Cholesky ones (CG's
    /// long run on gen_kidney_100k takes ~15 minutes per thread count).
    #[arg(long)]
    pub no_cg: bool,
    /// Instead of the usual table: this energy declared at run time against the
    /// compiled --law, one thread, timed round-robin (same energy: same forces).
    #[arg(long, value_name = "TEXT")]
    pub energy: Option<String>,
    /// Parameter NAME=VALUE of --energy (repeatable); default: --law's values.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// With --energy: its volumetric energy U(J) as text; the table then also times
    /// the anti-locking patch field of --law, of --energy along dilations and of
    /// --energy with this U, in the same round-robin.
    #[arg(long, value_name = "TEXT", requires = "energy")]
    pub volumetric_energy: Option<String>,
    /// Also time this law's HEML field on one thread, in the same round-robin, and
    /// print --law's cost relative to it (e.g. a fibre law against neo_hookean).
    #[arg(long, value_name = "LAW")]
    pub against: Option<String>,
    /// Instead of the usual table: the anti-locking volumetric formulations
    /// (`volumetric = "nodal"` and `"patch"`) of --law against the standard (element) one at
    /// ν = 0.49, cost per tet and ratio, at 1 and --threads threads, timed round-robin.
    #[arg(long)]
    pub nodal: bool,
    /// Instead of the usual table: the tangent stiffness of --law (and of --against),
    /// what implicit steps pay per tet: the update at a deformed state (projected to
    /// positive semi-definite, as by default, and exact) and the product K·dx,
    /// against the law's force evaluation, at 1 and --threads threads, timed round-robin.
    #[arg(long)]
    pub tangent: bool,
    /// Tets per patch of the patch formulation in --nodal.
    #[arg(long, value_name = "K", default_value_t = heml::force::patch_volume::DEFAULT_PATCH_SIZE)]
    pub patch_size: usize,
}

/// Soft-tissue parameters (E = 3 kPa, ν = 0.45) for a built-in law; link laws get a
/// spring stiffness of 10 N/m per tet edge.
pub(super) fn tissue_params(entry: &MaterialEntry) -> heml::Result<Params> {
    fixtures::tissue_params(entry, 3e3, 0.45).ok_or_else(|| {
        HemlError::Invalid(format!(
            "heml bench knows soft-tissue parameters for the built-in laws only, not '{}'",
            entry.name
        ))
    })
}

pub(super) fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// "median [min–max]" of `v` with `digits` decimals.
pub(super) fn spread(v: &[f64], digits: usize) -> String {
    format!(
        "{:.d$} [{:.d$}–{:.d$}]",
        median(&mut v.to_vec()),
        min(v),
        max(v),
        d = digits
    )
}

pub(super) fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

pub(super) fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

/// One timed case: `work` at `x` on `pool`, `inner` calls per sample.
pub(super) struct Case<'a> {
    pub(super) pool: &'a rayon::ThreadPool,
    pub(super) work: Work<'a>,
    pub(super) x: &'a [Vec3],
    pub(super) inner: usize,
}

/// What a [`Case`] times.
pub(super) enum Work<'a> {
    /// A field's forces with its energy (`add_forces`) or without (`add_forces_only`,
    /// what an explicit step evaluates).
    Forces { field: &'a dyn ElasticForces, energy: bool },
    /// A tangent operator's update at `x` (what an implicit step's refactorisation
    /// starts with).
    TangentUpdate(&'a Mutex<Box<dyn TangentOperator>>),
    /// The tangent's product y += K·x (what CG applies each iteration).
    TangentProduct(&'a Mutex<Box<dyn TangentOperator>>),
}

impl<'a> Case<'a> {
    /// The forces of `field` at `x`, with the energy when `energy`.
    pub(super) fn forces(
        pool: &'a rayon::ThreadPool,
        field: &'a dyn ElasticForces,
        x: &'a [Vec3],
        inner: usize,
        energy: bool,
    ) -> Self {
        Case {
            pool,
            work: Work::Forces { field, energy },
            x,
            inner,
        }
    }

    /// One call of the work, its output in `f` (cleared first).
    fn call(&self, f: &mut [Vec3]) -> heml::Result<()> {
        f.fill(Vec3::zeros());
        match &self.work {
            Work::Forces { field, energy: true } => {
                std::hint::black_box(field.add_forces(self.x, f)?);
            }
            Work::Forces { field, energy: false } => field.add_forces_only(self.x, f)?,
            Work::TangentUpdate(op) => op.lock().expect("not poisoned").update(self.x)?,
            Work::TangentProduct(op) => op.lock().expect("not poisoned").add_product(self.x, f)?,
        }
        std::hint::black_box(&f);
        Ok(())
    }
}

/// Seconds per call of every case, `repeats` samples each, taken round-robin (one
/// sample of each case per round), so that the machine's slow drifts hit every case
/// alike and ratios can be taken round by round.
///
/// Consecutive cases on the same pool form a group; odd rounds visit each group
/// backwards, so that whatever the first sample after a change of pool pays (its
/// workers were idle, its caches hold another case's data) falls on every case of
/// the group in turn, not always on the first one listed.
pub(super) fn time_round_robin(cases: &[Case], repeats: usize) -> heml::Result<Vec<Vec<f64>>> {
    let mut bufs: Vec<Vec<Vec3>> = cases.iter().map(|c| vec![Vec3::zeros(); c.x.len()]).collect();
    for (c, f) in cases.iter().zip(&mut bufs) {
        c.pool.install(|| c.call(f))?; // warm-up (allocates scratch; updates tangents)
    }
    let mut samples = vec![Vec::with_capacity(repeats); cases.len()];
    for round in 0..repeats {
        for i in visiting_order(cases, round % 2 == 1) {
            let (c, f) = (&cases[i], &mut bufs[i]);
            let t = c.pool.install(|| -> heml::Result<f64> {
                let t = Instant::now();
                for _ in 0..c.inner {
                    c.call(f)?;
                }
                Ok(t.elapsed().as_secs_f64() / c.inner as f64)
            })?;
            samples[i].push(t);
        }
    }
    Ok(samples)
}

/// The indices of `cases` in list order, each run of cases on the same pool
/// reversed when `backwards`.
fn visiting_order(cases: &[Case], backwards: bool) -> Vec<usize> {
    let mut order = Vec::with_capacity(cases.len());
    let mut start = 0;
    while start < cases.len() {
        let same = |c: &Case| std::ptr::eq(c.pool, cases[start].pool);
        let end = start + cases[start..].iter().take_while(|c| same(c)).count();
        if backwards {
            order.extend((start..end).rev());
        } else {
            order.extend(start..end);
        }
        start = end;
    }
    order
}

/// The median over rounds of `a[i] / b[i]`: a ratio robust to drifts that move both.
pub(super) fn median_ratio(a: &[f64], b: &[f64]) -> f64 {
    let mut r: Vec<f64> = a.iter().zip(b).map(|(a, b)| a / b).collect();
    median(&mut r)
}

/// `heml bench --scaling`: the cost per tet as the mesh grows, and on a shuffled
/// mesh, all fields timed round-robin in one run so that machine noise hits them
/// alike.
fn scaling(
    args: &BenchArgs,
    law: &dyn Fn() -> heml::Result<Box<dyn Material>>,
    pool: &rayon::ThreadPool,
) -> heml::Result<()> {
    let opts = ForceOptions::default();
    let mut cases: Vec<(String, TetMesh)> = Vec::new();
    for n in [10_000, 100_000, 1_000_000] {
        let mesh = box_of_about(n)?;
        cases.push((format!("box {} tets", mesh.n_tets()), mesh));
    }
    let big = shuffled(&cases[2].1)?;
    cases.push(("same, shuffled, renumbered at load".into(), renumbered_at_load(&big)?));
    cases.push(("same, shuffled, order kept".into(), big));
    let fields: Vec<Box<dyn ElasticForces>> = cases
        .iter()
        .map(|(_, m)| with_bench_fibres(law()?, m)?.force_field(m, None, &opts))
        .collect::<heml::Result<_>>()?;
    let xs: Vec<Vec<Vec3>> = cases.iter().map(|(_, m)| deformed(m)).collect();
    let timed: Vec<Case> = fields
        .iter()
        .zip(&xs)
        // about 20 ms per sample whatever the size
        .map(|(fl, x)| {
            Case::forces(
                pool,
                fl.as_ref(),
                x,
                (2_000_000 / fl.n_tets().max(1)).clamp(1, 1000),
                true,
            )
        })
        .collect();
    let repeats = args.repeats.max(1);
    let mut samples = time_round_robin(&timed, repeats)?;
    for (s, fl) in samples.iter_mut().zip(&fields) {
        s.iter_mut().for_each(|t| *t /= fl.n_tets().max(1) as f64);
    }
    outln!(
        "cost per tet, {} threads, {} round-robin samples (medians; ratios: medians of the per-round ratios):",
        pool.current_num_threads(),
        repeats
    );
    for ((name, _), s) in cases.iter().zip(&samples) {
        outln!(
            "  {name:<38} {:>7.2} ns/tet   {:>5.2}× the 10k box",
            median(&mut s.clone()) * 1e9,
            median_ratio(s, &samples[0])
        );
    }
    Ok(())
}

/// Most `--repeats`.
pub const MAX_REPEATS: usize = 100_000;

/// A `--repeats` value (clap parser): 0 to [`MAX_REPEATS`] (0 is taken as 1).
fn repeat_count(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n <= MAX_REPEATS => Ok(n),
        _ => Err(format!("{s:?} is not a number of repeats (at most {MAX_REPEATS})")),
    }
}

/// Runs `heml bench`.
pub fn run(args: BenchArgs) -> heml::Result<()> {
    let entry = heml::find_material(&args.law)?;
    let params = tissue_params(entry)?;
    let law = entry.instantiate(&params)?;
    let opts = ForceOptions::default();
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let placement = if args.no_pin { Placement::Os } else { Placement::Pinned };
    let pool = |n: usize| thread_pool(n, placement).map(|(p, _)| p);
    let workers = match placement_for(threads, placement) {
        Placement::Pinned => "pinned to CPUs",
        Placement::Os => "placed by the OS",
    };
    if args.haptic {
        let pinned = placement_for(threads, placement) == Placement::Pinned;
        let seconds = super::haptic::checked_seconds(args.haptic_seconds)?;
        return super::haptic::run(args.mesh.as_ref(), &pool, threads, pinned, seconds);
    }
    if let Some(meshes) = &args.implicit {
        let meshes = super::bench_implicit::meshes(meshes, args.implicit_scale)?;
        let preconditioner = super::bench_implicit::preconditioner(&args.preconditioner)?;
        let direct =
            super::bench_implicit::Direct::parse(&args.cholesky_ordering, &args.factor_precision, !args.no_cg)?;
        let dt = super::bench_implicit::checked_dt(args.implicit_dt)?;
        return super::bench_implicit::run(&meshes, preconditioner, &direct, dt, threads, placement);
    }
    if let Some(energy) = &args.energy {
        return super::bench_energy::run(&args, energy, &pool(1)?);
    }
    if args.scaling {
        outln!(
            "law: {}   SIMD: {}   workers {workers}   (--mesh, --tets and --shuffle do not apply)",
            entry.name,
            SimdLevel::detect().name()
        );
        return scaling(&args, &|| entry.instantiate(&params), &pool(threads)?);
    }
    let mut mesh = match &args.mesh {
        Some(path) => heml::io::read_mesh(path)?.0,
        None => box_of_about(args.tets)?,
    };
    if args.shuffle {
        mesh = shuffled(&mesh)?;
    }
    if !args.keep_order {
        mesh = renumbered_at_load(&mesh)?;
    }
    let n_tets = mesh.n_tets();
    let x = deformed(&mesh);
    let repeats = args.repeats.max(1);
    // about 20 ms per sample
    let inner = (2_000_000 / n_tets.max(1)).clamp(1, 1000);

    outln!(
        "mesh: {} ({} nodes, {} tets){}{}",
        args.mesh
            .as_ref()
            .map_or("generated box".to_string(), |p| p.display().to_string()),
        mesh.n_nodes(),
        n_tets,
        if args.shuffle { ", shuffled" } else { "" },
        if args.keep_order {
            ", node order kept"
        } else {
            ", nodes renumbered at load (Morton)"
        }
    );
    outln!(
        "law: {}   SIMD: {}   threads: {} ({workers})   repeats: {} × {} calls (medians)",
        entry.name,
        SimdLevel::detect().name(),
        threads,
        repeats,
        inner
    );
    let mut counts = vec![1];
    if threads != 1 {
        counts.push(threads);
    }
    let pools = counts.iter().map(|&n| pool(n)).collect::<heml::Result<Vec<_>>>()?;
    if args.nodal {
        return super::bench_nodal::run(entry, &mesh, &x, &pools, repeats, inner, args.patch_size);
    }
    if args.tangent {
        let against = args.against.as_deref().map(heml::find_material).transpose()?;
        return super::bench_tangent::run(entry, against, &mesh, &x, &pools, repeats);
    }

    let law = with_bench_fibres(law, &mesh)?;
    let heml_field = law.force_field(&mesh, None, &opts)?;
    let fem_field = law.fem_field(&mesh, None, &opts)?;
    outln!();
    outln!(
        "{:<8} {:>14} {:>10} {:>14} {:>10} {:>12}",
        "threads",
        "HEML tets/s",
        "ns/tet",
        "P1 tets/s",
        "ns/tet",
        "HEML vs P1"
    );
    // every (thread count, field) case in one round-robin, so that the speed-up and
    // the HEML/P1 ratio are taken sample by sample under the same machine load
    let mut cases = Vec::new();
    for p in &pools {
        cases.push(Case::forces(p, heml_field.as_ref(), &x, inner, true));
        if let Some(fem) = &fem_field {
            cases.push(Case::forces(p, fem.as_ref(), &x, inner, true));
        }
    }
    // --against: the other law's HEML field on one thread, last in the round-robin
    let against = match &args.against {
        Some(name) => {
            let entry = heml::find_material(name)?;
            let law = with_bench_fibres(entry.instantiate(&tissue_params(entry)?)?, &mesh)?;
            Some((entry.name, law.force_field(&mesh, None, &opts)?))
        }
        None => None,
    };
    let per_count = cases.len() / counts.len();
    // --against: both laws with the energy and without it (what explicit steps
    // evaluate), each pair of cases next to each other in the round (and visited in
    // the other order every other round), so that a per-round ratio compares samples
    // taken under the same load: --law's first case of the table is three cases (a
    // P1 and two 2-thread evaluations) away from the other law's
    if let Some((_, field)) = &against {
        for (field, energy) in [
            (heml_field.as_ref(), true),
            (field.as_ref(), true),
            (heml_field.as_ref(), false),
            (field.as_ref(), false),
        ] {
            cases.push(Case::forces(&pools[0], field, &x, inner, energy));
        }
    }
    let samples = time_round_robin(&cases, repeats)?;
    let per = |s: f64| s / n_tets as f64;
    for (k, &n) in counts.iter().enumerate() {
        let heml_s = &samples[k * per_count];
        let th = median(&mut heml_s.clone());
        if fem_field.is_some() {
            let fem_s = &samples[k * per_count + 1];
            let tf = median(&mut fem_s.clone());
            outln!(
                "{:<8} {:>14.3e} {:>10.2} {:>14.3e} {:>10.2} {:>11.2}×",
                n,
                1.0 / per(th),
                per(th) * 1e9,
                1.0 / per(tf),
                per(tf) * 1e9,
                median_ratio(fem_s, heml_s)
            );
        } else {
            outln!(
                "{:<8} {:>14.3e} {:>10.2} {:>14} {:>10} {:>12}",
                n,
                1.0 / per(th),
                per(th) * 1e9,
                "n/a",
                "n/a",
                "n/a"
            );
        }
    }
    if counts.len() == 2 {
        outln!(
            "speed-up {threads} threads vs 1: {:.2}×",
            median_ratio(&samples[0], &samples[per_count])
        );
    }
    if let Some((name, _)) = &against {
        let a = per_count * counts.len();
        let ratio_line = |what: &str, mine: &[f64], other: &[f64]| {
            let mut r: Vec<f64> = mine.iter().zip(other).map(|(a, b)| a / b).collect();
            r.sort_by(f64::total_cmp);
            outln!(
                "{} vs {name} ({what}, 1 thread): {:.2}× (per-round ratios {:.2}–{:.2}); {} {:.2}, {name} {:.2} ns/tet",
                entry.name,
                median(&mut r.clone()),
                r[0],
                r[r.len() - 1],
                entry.name,
                per(median(&mut mine.to_vec())) * 1e9,
                per(median(&mut other.to_vec())) * 1e9
            );
        };
        ratio_line("HEML, forces and energy", &samples[a], &samples[a + 1]);
        ratio_line("HEML, forces only as explicit steps", &samples[a + 2], &samples[a + 3]);
    }
    outln!("(ratios: medians of the per-round ratios; all cases timed round-robin)");
    if let Some(b) = heml_field.bytes_per_tet() {
        out!("memory: HEML {b:.1} bytes/tet");
        if let Some(b) = fem_field.as_ref().and_then(|f| f.bytes_per_tet()) {
            out!(", P1 {b:.1} bytes/tet");
        }
        outln!();
    }

    if args.reference {
        let mut h = law.force_field(&mesh, None, &opts)?;
        h.set_assembly(Assembly::Reference);
        let mut list: Vec<Box<dyn ElasticForces>> = vec![h];
        if let Some(mut f) = law.fem_field(&mesh, None, &opts)? {
            f.set_assembly(Assembly::Reference);
            list.push(f);
        }
        let cases: Vec<Case> = list
            .iter()
            .map(|b| Case::forces(&pools[0], b.as_ref(), &x, (inner / 4).max(1), true))
            .collect();
        let t: Vec<f64> = time_round_robin(&cases, repeats.min(7))?
            .iter_mut()
            .map(|s| median(s))
            .collect();
        out!(
            "plain serial reference kernels: HEML {:.2} ns/tet",
            t[0] / n_tets as f64 * 1e9
        );
        if let Some(tf) = t.get(1) {
            out!(", P1 {:.2} ns/tet", tf / n_tets as f64 * 1e9);
        }
        outln!();
    }

    // Full semi-explicit steps through the System. The body vibrates gently about its
    // rest shape (1 mm/s initial velocity): a step costs the same at any deformation,
    // and a large sag (a soft 10 cm block under gravity) would stiffen the material
    // under compression until the rest-state stable time step no longer holds.
    let (lo, hi) = mesh.bounding_box();
    let clamp = lo.x + 1e-9 * (hi - lo).norm();
    let size = hi - lo;
    let mut sys = heml::system(mesh.clone())
        .material_law(with_bench_fibres(entry.instantiate(&params)?, &mesh)?)
        .density(1000.0)
        .initial_velocity(move |p| Vec3::new(0.0, 0.0, 1e-3 * ((p.x - lo.x) / size.x).powi(2)))
        .fix_where(|p| p.x <= clamp)
        .energy_every(0)
        .lazy_energy(true)
        .build()?;
    let mut integ = heml::integrator("symplectic_euler")?;
    let dt = 0.9 * sys.stable_dt();
    for _ in 0..5 {
        integ.step(&mut sys, dt)?;
    }
    // per round and thread count: `inner` force evaluations of the field alone, then
    // `inner` full steps, so that the step/force ratio is taken under the same load
    let rounds = repeats.clamp(5, 25);
    let mut forces = vec![Vec::with_capacity(rounds); pools.len()];
    let mut steps = vec![Vec::with_capacity(rounds); pools.len()];
    let mut f = vec![Vec3::zeros(); x.len()];
    for _ in 0..rounds {
        for (k, p) in pools.iter().enumerate() {
            p.install(|| -> heml::Result<()> {
                let t = Instant::now();
                for _ in 0..inner {
                    f.fill(Vec3::zeros());
                    heml_field.add_forces_only(&x, &mut f)?;
                    std::hint::black_box(&f);
                }
                forces[k].push(t.elapsed().as_secs_f64() / inner as f64);
                let t = Instant::now();
                for _ in 0..inner {
                    integ.step(&mut sys, dt)?;
                }
                steps[k].push(t.elapsed().as_secs_f64() / inner as f64);
                Ok(())
            })?;
        }
    }
    outln!("full step (symplectic_euler: forces + update + constraints, energies off) vs the force evaluation alone (forces only, as the step's), {rounds} rounds × {inner}:");
    for (k, &n) in counts.iter().enumerate() {
        let (tf, ts) = (median(&mut forces[k].clone()), median(&mut steps[k].clone()));
        outln!(
            "  {n} thread(s): step {:.3} ms, forces {:.3} ms, step/force {:.3}×, {:.0} steps/s",
            ts * 1e3,
            tf * 1e3,
            median_ratio(&steps[k], &forces[k]),
            1.0 / ts
        );
    }
    Ok(())
}
