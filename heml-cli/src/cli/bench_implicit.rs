//! `heml bench --implicit [MESH…]`: backward Euler at dt = 10 ms (or
//! `--implicit-dt`) against the best
//! explicit integrator at its stable step on the same soft, nearly incompressible
//! scene, per mesh and thread count, measured in one run, with conjugate gradients
//! and with the reused sparse Cholesky factor side by side.
//!
//! The scene is liver-like tissue (neo-Hookean, E = 3 kPa, ν = 0.49, ρ = 1000 kg/m³)
//! under gravity with mass damping α = 15/s, the 10 % of the organ at smallest x
//! clamped. Each implicit case starts from rest and takes [`IMPLICIT_STEPS`] steps
//! (the sag's transient included); medians and ranges are over all of them. Without
//! a mesh, the shared collection's two generated kidneys (millimetres) and SOFA's
//! liver (arbitrary units, taken as centimetres as the inversion validation case
//! does: a 6.5 cm organ with slivers, so a tiny explicit stable step) are run.

use crate::threads::{thread_pool, Placement};
use heml::prelude::*;
use heml::system::{
    CgPreconditioner, CholeskyOrdering, FactorPrecision, ImplicitScheme, ImplicitSettings, ImplicitSolver,
    LinearSolver, PhaseTimes, System,
};
use heml_validation::fixtures::renumbered_at_load;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The default meshes of the shared collection and their scales to metres.
const DEFAULT_MESHES: [(&str, f64); 3] = [
    ("gen_kidney_20k.msh", 1e-3),
    ("gen_kidney_100k.msh", 1e-3),
    ("sofa_liver.msh", 1e-2),
];

/// The meshes to run with their scales to metres: `paths` at `scale`, or without
/// paths the default meshes of the shared collection ($HEML_MESHES, or
/// ../shared/meshes), with a clear error when one is missing.
pub fn meshes(paths: &[PathBuf], scale: f64) -> heml::Result<Vec<(PathBuf, f64)>> {
    if !paths.is_empty() {
        return Ok(paths.iter().map(|p| (p.clone(), scale)).collect());
    }
    let dir = std::env::var_os("HEML_MESHES").map_or_else(|| PathBuf::from("../shared/meshes"), PathBuf::from);
    let list: Vec<(PathBuf, f64)> = DEFAULT_MESHES
        .iter()
        .map(|&(name, scale)| (dir.join("msh").join(name), scale))
        .collect();
    if let Some((missing, _)) = list.iter().find(|(p, _)| !p.is_file()) {
        return Err(HemlError::Invalid(format!(
            "heml bench --implicit: {} not found (set HEML_MESHES to the shared mesh folder, or give meshes)",
            missing.display()
        )));
    }
    Ok(list)
}

/// The preconditioner named `name` (snake case, as `CgPreconditioner` serialises).
pub fn preconditioner(name: &str) -> heml::Result<CgPreconditioner> {
    match name {
        "parallel_gauss_seidel" => Ok(CgPreconditioner::ParallelGaussSeidel),
        "symmetric_gauss_seidel" => Ok(CgPreconditioner::SymmetricGaussSeidel),
        "block_jacobi" => Ok(CgPreconditioner::BlockJacobi),
        _ => Err(HemlError::Invalid(format!(
            "--preconditioner {name}: expected parallel_gauss_seidel, symmetric_gauss_seidel or block_jacobi"
        ))),
    }
}

/// The linear solvers of the runs: the Cholesky factor's ordering and the
/// precisions to run side by side, and whether CG runs too.
pub struct Direct {
    ordering: CholeskyOrdering,
    precisions: Vec<FactorPrecision>,
    cg: bool,
}

impl Direct {
    /// The options named on the command line (`--cholesky-ordering`,
    /// `--factor-precision`, comma-separated values already split; `cg` unless
    /// `--no-cg`).
    pub fn parse(ordering: &str, precisions: &[String], cg: bool) -> heml::Result<Self> {
        let precisions = precisions
            .iter()
            .map(|p| p.parse())
            .collect::<heml::Result<Vec<FactorPrecision>>>()?;
        if precisions.is_empty() {
            return Err(HemlError::Invalid(
                "--factor-precision: give at least one of auto, f64, f32".into(),
            ));
        }
        Ok(Direct {
            ordering: ordering.parse()?,
            precisions,
            cg,
        })
    }

    /// `settings` with Cholesky and these options at `precision`.
    fn settings(&self, settings: ImplicitSettings, precision: FactorPrecision) -> ImplicitSettings {
        ImplicitSettings {
            linear_solver: LinearSolver::Cholesky,
            cholesky_ordering: self.ordering,
            factor_precision: precision,
            ..settings
        }
    }
}

/// The solver column of a run: `cg`, `cholesky` (the default precision) or
/// `chol/f32` and the like.
fn solver_label(settings: &ImplicitSettings) -> String {
    match (settings.linear_solver, settings.factor_precision) {
        (LinearSolver::Cg, _) => "cg".into(),
        (LinearSolver::Cholesky, FactorPrecision::Auto) => "cholesky".into(),
        (LinearSolver::Cholesky, p) => format!("chol/{}", p.name()),
    }
}

/// Implicit step size by default (issue 11's benchmark step).
pub const DEFAULT_DT: f64 = 0.01;
/// The largest `--implicit-dt`: 0.1 s, beyond which a soft organ's motion under a
/// tool is not resolved by one step (and no interactive loop steps that slowly).
pub const MAX_DT: f64 = 0.1;
/// Timed implicit steps per case (0.12 s simulated at 10 ms).
const IMPLICIT_STEPS: usize = 12;
/// Timed explicit steps per case.
const EXPLICIT_STEPS: usize = 50;
/// The long run's phases in simulated seconds: falling from rest, a tool pressing
/// on top, a grasp at the free end moving (2 s in all; 50, 75 and 75 steps at 10 ms).
const LONG_PHASES: [(&str, f64); 3] = [("fall", 0.5), ("press", 0.75), ("grasp", 0.75)];

/// The long run's phases in steps of `dt` (at least one each).
fn long_phases(dt: f64) -> [(&'static str, usize); 3] {
    LONG_PHASES.map(|(name, secs)| (name, ((secs / dt).round() as usize).max(1)))
}

/// `dt` in milliseconds as printed: at most three decimals, trailing zeros dropped
/// (10, 33.3, 0.5).
fn ms(dt: f64) -> String {
    let t = format!("{:.3}", dt * 1e3);
    t.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// `--implicit-dt`: the implicit step in seconds, checked to lie in (0, [`MAX_DT`]].
pub fn checked_dt(dt: f64) -> heml::Result<f64> {
    if dt.is_finite() && dt > 0.0 && dt <= MAX_DT {
        Ok(dt)
    } else {
        Err(HemlError::Invalid(format!(
            "--implicit-dt {dt}: expected a time step in seconds, above 0 and at most {MAX_DT}"
        )))
    }
}

/// The liver-like scene on `mesh` (metres).
fn scene(mesh: &TetMesh) -> heml::Result<System> {
    let (lo, hi) = mesh.bounding_box();
    let cut = lo.x + 0.1 * (hi.x - lo.x);
    heml::system(mesh.clone())
        .material("neo_hookean", Params::from([("E", 3e3), ("nu", 0.49)]))?
        .density(1000.0)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .fix_where(move |p| p.x < cut)
        .rayleigh(15.0, 0.0)
        .energy_every(0)
        .build()
}

/// (median, min, max) of `v`.
fn stats(v: &[f64]) -> (f64, f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    let med = if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    };
    (med, s[0], s[n - 1])
}

/// What `IMPLICIT_STEPS` steps from rest measured, per step.
struct ImplicitRun {
    /// Wall times.
    times: Vec<f64>,
    /// CG iterations.
    cgs: Vec<f64>,
    /// Newton (or chord) iterations.
    newtons: Vec<f64>,
    /// Phase times (with the CG residuals and the factorisations).
    phases: Vec<PhaseTimes>,
    /// Nonzeros of the Cholesky factor at the end (0 with CG).
    factor_nonzeros: usize,
    /// Whether that factor is in f32.
    factor_single: bool,
    /// Wall time of [`ImplicitSolver::prepare`] before the first step (operators,
    /// pattern, symbolic analysis: not in the step times).
    prepare: f64,
}

/// `IMPLICIT_STEPS` backward-Euler steps from rest with `settings`.
fn implicit_case(
    mesh: &TetMesh,
    settings: ImplicitSettings,
    dt: f64,
    pool: &rayon::ThreadPool,
) -> heml::Result<ImplicitRun> {
    let mut sys = scene(mesh)?;
    let mut solver = ImplicitSolver::new(ImplicitScheme::BackwardEuler, settings);
    pool.install(|| {
        let t = Instant::now();
        solver.prepare(&sys)?;
        let prepare = t.elapsed().as_secs_f64();
        let (mut times, mut cgs, mut newtons, mut phases) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for _ in 0..IMPLICIT_STEPS {
            let t = Instant::now();
            let s = solver.step(&mut sys, dt)?;
            times.push(t.elapsed().as_secs_f64());
            cgs.push(s.cg_iterations as f64);
            newtons.push(s.newton_iterations as f64);
            phases.push(solver.last_phase_times());
        }
        Ok(ImplicitRun {
            times,
            cgs,
            newtons,
            phases,
            factor_nonzeros: solver.factor_nonzeros(),
            factor_single: solver.factor_is_single(),
            prepare,
        })
    })
}

/// The long run: [`LONG_PHASES`] backward-Euler steps with `settings` — the organ
/// falls from rest; then a capsule (radius 4 mm, contact stiffness 200 N/m per
/// node) presses 4 mm into its highest surface node and sweeps ±3 mm, one press per
/// 0.5 s (the haptic benchmark's palpation); then it is removed and the nodes
/// within 5 % of the free end (largest x) are grasped (50 N/m and 0.5 N·s/m per
/// node) and moved along a 1 cm circle in the x–z plane in 0.75 s. The runtime
/// changes happen between steps, as a haptic loop makes them.
fn long_case(
    mesh: &TetMesh,
    settings: ImplicitSettings,
    dt: f64,
    pool: &rayon::ThreadPool,
) -> heml::Result<(ImplicitRun, Option<HemlError>)> {
    use heml::system::contact::{ContactLaw, Palpation};
    use heml::system::control::Pose;
    let mut sys = scene(mesh)?;
    let mut solver = ImplicitSolver::new(ImplicitScheme::BackwardEuler, settings);
    let (lo, hi) = mesh.bounding_box();
    let end: Vec<usize> = (0..mesh.n_nodes())
        .filter(|&i| mesh.nodes()[i].x > hi.x - 0.05 * (hi.x - lo.x))
        .collect();
    let mut run = ImplicitRun {
        times: Vec::new(),
        cgs: Vec::new(),
        newtons: Vec::new(),
        phases: Vec::new(),
        factor_nonzeros: 0,
        factor_single: false,
        prepare: 0.0,
    };
    let out = pool.install(|| -> heml::Result<()> {
        let t = Instant::now();
        solver.prepare(&sys)?;
        run.prepare = t.elapsed().as_secs_f64();
        let mut step = |sys: &mut System, run: &mut ImplicitRun| -> heml::Result<()> {
            let t = Instant::now();
            let s = solver.step(sys, dt)?;
            run.times.push(t.elapsed().as_secs_f64());
            run.cgs.push(s.cg_iterations as f64);
            run.newtons.push(s.newton_iterations as f64);
            run.phases.push(solver.last_phase_times());
            run.factor_nonzeros = solver.factor_nonzeros();
            run.factor_single = solver.factor_is_single();
            Ok(())
        };
        let [(_, fall), (_, press), (_, grasp)] = long_phases(dt);
        for _ in 0..fall {
            step(&mut sys, &mut run)?;
        }
        let law = ContactLaw {
            stiffness: 200.0,
            damping: 0.002,
        };
        let (tool, path) = Palpation::on_top(&mut sys, 0.004, 0.01, law, 0.5)?;
        for k in 0..press {
            sys.set_tool_pose(tool, path.at((k + 1) as f64 * dt))?;
            step(&mut sys, &mut run)?;
        }
        sys.remove_tool(tool)?;
        let id = sys.grasp(&end, Pose::identity(), 50.0, 0.5)?;
        for k in 0..grasp {
            let phase = std::f64::consts::TAU * (k + 1) as f64 / grasp as f64;
            let offset = Vec3::new(0.005 * phase.sin(), 0.0, 0.005 * (1.0 - phase.cos()));
            sys.move_grasp(id, Pose::translation(offset))?;
            step(&mut sys, &mut run)?;
        }
        Ok(())
    });
    Ok((run, out.err()))
}

/// " | phases: …" — the summed phase times of a run's steps in ms, the
/// unitemised rest last: where a long run's time goes.
fn phase_totals(phases: &[heml::system::implicit::PhaseTimes]) -> String {
    let sum = |f: fn(&heml::system::implicit::PhaseTimes) -> f64| phases.iter().map(f).sum::<f64>() * 1e3;
    let parts = [
        ("forces", sum(|p| p.forces)),
        ("tangent", sum(|p| p.tangent)),
        ("asm", sum(|p| p.assembly)),
        ("fact", sum(|p| p.factor)),
        ("solve", sum(|p| p.cg)),
    ];
    let rest = sum(|p| p.total) - parts.iter().map(|p| p.1).sum::<f64>();
    let listed: Vec<String> = parts.iter().map(|(n, v)| format!("{n} {v:.1}")).collect();
    format!(" | phases: {}, rest {rest:.1}", listed.join(", "))
}

/// (p50, p90, max, mean) of `v`.
fn percentiles(v: &[f64]) -> (f64, f64, f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let at = |q: f64| s[((q * (s.len() - 1) as f64).round() as usize).min(s.len() - 1)];
    (at(0.5), at(0.9), s[s.len() - 1], s.iter().sum::<f64>() / s.len() as f64)
}

/// Prints the long run of the default preset with the Cholesky factor on `mesh` at
/// each thread count of `counts`: per phase and over the whole run, p50, p90, max
/// and mean wall time per step and the factorisations.
fn long_runs(
    mesh: &TetMesh,
    label: &str,
    counts: &[usize],
    direct: &Direct,
    dt: f64,
    placement: Placement,
) -> heml::Result<()> {
    let phases = long_phases(dt);
    let total: usize = phases.iter().map(|p| p.1).sum();
    outln!();
    outln!(
        "long run, default preset: {} ({total} steps of {} ms; ms per step p50 / p90 / max / mean, \
         factorisations (+ low-rank contact correction columns); `prepare`: operators, pattern and symbolic analysis before the first step; \
         `phases`: the whole run's wall time in ms by phase — force evaluations with line-search merits, tangent updates, assembly, \
         factorisations, triangular solves, and the rest: predictor, inverted-tet counts, bookkeeping; the run's Newton iterations; \
         and its simulated time per wall second against the explicit integrator's, measured again just before it, by the mean steps)",
        phases.map(|(name, n)| format!("{name} {n}")).join(", "),
        ms(dt)
    );
    for &n in counts {
        let (pool, _) = thread_pool(n, placement)?;
        // the explicit reference measured again right beside the long runs: the
        // machine's speed drifts between the tables (issue 11's bar is this ratio)
        let (explicit, edt, et) = explicit_case(mesh, &pool)?;
        let explicit_mean = percentiles(&et).3;
        let cholesky = direct
            .precisions
            .iter()
            .map(|&p| direct.settings(ImplicitSettings::default(), p));
        let cg = direct.cg.then(ImplicitSettings::default);
        for settings in cholesky.chain(cg) {
            let solver = solver_label(&settings);
            let (run, failed) = long_case(mesh, settings, dt, &pool)?;
            if let Some(e) = &failed {
                outln!(
                    "{label:<30} {n:>3} {solver:<8} failed after {} steps: {e}",
                    run.times.len()
                );
            }
            let mut line = format!(
                "{label:<30} {n:>3} {solver:<8} load {} | prepare {:.1} ms",
                super::haptic::load_average(),
                run.prepare * 1e3
            );
            let done = run.times.len();
            let mut start = 0;
            for (name, len) in phases.iter().copied().chain([("all", total)]) {
                let range = if name == "all" {
                    0..done
                } else {
                    start.min(done)..(start + len).min(done)
                };
                start += len;
                if range.is_empty() {
                    continue;
                }
                let (p50, p90, max, mean) = percentiles(&run.times[range.clone()]);
                let f: usize = run.phases[range.clone()].iter().map(|p| p.factorizations).sum();
                // low-rank contact corrections: column solves instead of refactorisations
                let c: usize = run.phases[range].iter().map(|p| p.correction_columns).sum();
                let c = if c > 0 { format!(" +{c} col.") } else { String::new() };
                line += &format!(
                    " | {name}: {:.2}/{:.2}/{:.1}/{:.2} ({f}{c})",
                    p50 * 1e3,
                    p90 * 1e3,
                    max * 1e3,
                    mean * 1e3
                );
            }
            line += &phase_totals(&run.phases);
            line += &format!(", Newton iterations {}", run.newtons.iter().sum::<f64>());
            if failed.is_none() && done > 0 {
                let mean = percentiles(&run.times).3;
                line += &format!(
                    " | vs {explicit} ({:.3} ms per {:.0} µs step) by the means: {:.2}×",
                    1e3 * explicit_mean,
                    edt * 1e6,
                    (dt / mean) / (edt / explicit_mean)
                );
            }
            outln!("{line}");
        }
    }
    Ok(())
}

/// The settings of the benchmark rows: (label, settings). `default` and
/// `interactive` are the presets (one Newton iteration per step); `converged`
/// iterates Newton to its tolerance 1e-6 (at most 20 iterations), the exact backward
/// Euler step. Each with CG and with the reused Cholesky factor, except the
/// interactive preset, whose CG cap does not concern the factor (its Cholesky row
/// would repeat the default's).
fn rows(preconditioner: CgPreconditioner, direct: &Direct) -> Vec<(&'static str, ImplicitSettings)> {
    let converged = ImplicitSettings {
        newton_iterations: 20,
        ..ImplicitSettings::default()
    };
    let mut out = Vec::new();
    for (label, s) in [
        ("default", ImplicitSettings::default()),
        ("interactive", ImplicitSettings::interactive()),
        ("converged", converged),
    ] {
        if direct.cg {
            out.push((label, ImplicitSettings { preconditioner, ..s }));
        }
        if label != "interactive" {
            out.extend(direct.precisions.iter().map(|&p| (label, direct.settings(s, p))));
        }
    }
    out
}

/// The fastest explicit integrator in simulated seconds per wall second at 0.9× the
/// stable step: (name, dt, wall times per step).
fn explicit_case(mesh: &TetMesh, pool: &rayon::ThreadPool) -> heml::Result<(String, f64, Vec<f64>)> {
    let mut best: Option<(String, f64, Vec<f64>)> = None;
    for name in ["symplectic_euler", "velocity_verlet"] {
        let mut sys = scene(mesh)?;
        let dt = 0.9 * sys.stable_dt();
        let mut integ = heml::integrator(name)?;
        let times = pool.install(|| -> heml::Result<Vec<f64>> {
            for _ in 0..5 {
                integ.step(&mut sys, dt)?;
            }
            (0..EXPLICIT_STEPS)
                .map(|_| {
                    let t = Instant::now();
                    integ.step(&mut sys, dt)?;
                    Ok(t.elapsed().as_secs_f64())
                })
                .collect()
        })?;
        let rate = dt / stats(&times).0;
        if best.as_ref().is_none_or(|(_, d, t)| rate > d / stats(t).0) {
            best = Some((name.to_string(), dt, times));
        }
    }
    Ok(best.expect("two candidates"))
}

/// Runs the implicit benchmark on `meshes` (each with its scale to metres) with
/// implicit steps of `dt` seconds at 1 and `threads` threads.
pub fn run(
    meshes: &[(PathBuf, f64)],
    preconditioner: CgPreconditioner,
    direct: &Direct,
    dt: f64,
    threads: usize,
    placement: Placement,
) -> heml::Result<()> {
    let mut counts = vec![1];
    if threads != 1 {
        counts.push(threads);
    }
    let ordering = direct.ordering.name();
    outln!(
        "backward Euler at dt = {} ms vs the best explicit integrator at 0.9× its stable dt; \
         neo-Hookean E = 3 kPa, ν = 0.49, ρ = 1000, gravity, α = 15/s, 10 % clamped",
        ms(dt)
    );
    outln!(
        "implicit: {IMPLICIT_STEPS} steps from rest per case after `prepare` (median [min–max]); linear solver: cg \
         (preconditioner {preconditioner:?}) or cholesky ({ordering} ordering, factor precision `auto` unless \
         `chol/f64`, `chol/f32`; sparse LLᵀ kept while chord iterations on it reach \
         0.2 + 0.8 c_fresh, at most 0.25, of the step's residual cheaper than a refactorisation; `Newton` counts them, \
         `fact.` = factorisations over the {IMPLICIT_STEPS} steps, fill = factor nonzeros); explicit: \
         {EXPLICIT_STEPS} steps; ratio = implicit ÷ explicit sim s per wall s by the median step (by the \
         mean step)"
    );
    outln!();
    outln!(
        "{:<30} {:>3} {:<11} {:<8} {:>24} {:>6} {:>6} {:>22} {:>11} {:>30} {:>9} {:>26} {:>8}",
        "mesh (tets)",
        "thr",
        "settings",
        "solver",
        "ms/step",
        "mean",
        "Newton",
        "CG it./step (residual)",
        "fact. (fill)",
        "forces/tangent/asm/fact/solve",
        "sim s/s",
        "explicit: dt, ms/step, sim s/s",
        "ratio"
    );
    for (path, scale) in meshes {
        // nodes renumbered along a Morton curve, as `heml run` loads meshes
        let mesh = renumbered_at_load(&heml::io::read_mesh(path)?.0.scaled(*scale)?)?;
        let label = format!(
            "{} ({}, ×{scale} m)",
            Path::new(path).file_stem().map_or("?".into(), |s| s.to_string_lossy()),
            mesh.n_tets()
        );
        for &n in &counts {
            let (pool, _) = thread_pool(n, placement)?;
            let (name, edt, et) = explicit_case(&mesh, &pool)?;
            let (em, emin, emax) = stats(&et);
            let explicit_rate = edt / em;
            for (sname, settings) in rows(preconditioner, direct) {
                let solver = solver_label(&settings);
                let direct = settings.linear_solver == LinearSolver::Cholesky;
                let run = match implicit_case(&mesh, settings, dt, &pool) {
                    Ok(run) => run,
                    Err(e) => {
                        outln!("{label:<30} {n:>3} {sname:<11} {solver:<8} failed: {e}");
                        continue;
                    }
                };
                let (m, lo, hi) = stats(&run.times);
                let (cg, cg_lo, cg_hi) = stats(&run.cgs);
                let median = |f: fn(&PhaseTimes) -> f64| stats(&run.phases.iter().map(f).collect::<Vec<_>>()).0;
                let phase = |f: fn(&PhaseTimes) -> f64| 1e3 * median(f);
                let factorizations: usize = run.phases.iter().map(|p| p.factorizations).sum();
                let rate = dt / m;
                let mean = percentiles(&run.times).3;
                outln!(
                    "{:<30} {:>3} {:<11} {:<8} {:>7.2} [{:>6.2}–{:>6.2}] {:>6.2} {:>6.1} {:>4} [{}–{}] ({:.0e}) {:>11} {:>5.1}/{:>5.1}/{:>4.1}/{:>5.1}/{:>5.1} {:>9.3} {:>6}: {:.2e} s, {:.3} [{:.3}–{:.3}], {:.4} {:>7.2}× ({:.2}×)",
                    label,
                    n,
                    sname,
                    solver,
                    m * 1e3,
                    lo * 1e3,
                    hi * 1e3,
                    mean * 1e3,
                    run.newtons.iter().sum::<f64>() / run.newtons.len() as f64,
                    cg,
                    cg_lo,
                    cg_hi,
                    median(|p| p.cg_residual),
                    if direct {
                        let single = if run.factor_single { " f32" } else { "" };
                        format!("{factorizations} ({:.1e}{single})", run.factor_nonzeros as f64)
                    } else {
                        "-".into()
                    },
                    phase(|p| p.forces),
                    phase(|p| p.tangent),
                    phase(|p| p.assembly),
                    phase(|p| p.factor),
                    phase(|p| p.cg),
                    rate,
                    name,
                    edt,
                    em * 1e3,
                    emin * 1e3,
                    emax * 1e3,
                    explicit_rate,
                    rate / explicit_rate,
                    dt / mean / explicit_rate
                );
            }
        }
        long_runs(&mesh, &label, &counts, direct, dt, placement)?;
    }
    outln!("(wall-clock medians on a shared machine: other processes' load widens the ranges)");
    Ok(())
}
