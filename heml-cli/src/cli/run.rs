//! `heml run scene.toml`: runs a scene file with a progress bar and writes VTU
//! frames, a `.pvd` series and `energy.csv`.

use std::io::IsTerminal;
use std::path::PathBuf;

use heml::scene::Scene;
use heml::HemlError;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Options shared by `heml run` and `heml demo`.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct RunOptions {
    /// Output directory (overrides the scene's `[output] dir`).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Simulated time in seconds (overrides the scene's `[solver] duration`).
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
    /// No progress bar and no header (errors, warnings and the summary line remain).
    #[arg(long)]
    pub quiet: bool,
}

/// Arguments of `heml run`.
#[derive(clap::Args, Debug, Clone)]
pub struct RunArgs {
    /// The scene file (TOML; see scenes/example.toml).
    pub scene: PathBuf,
    #[command(flatten)]
    pub options: RunOptions,
}

/// Runs `heml run`.
pub fn run(args: RunArgs) -> heml::Result<()> {
    let scene = Scene::from_file(&args.scene)?;
    execute(scene, &args.options)
}

/// Applies the overrides, builds the scene, runs it with a progress bar and prints
/// the summary.
pub fn execute(mut scene: Scene, opts: &RunOptions) -> heml::Result<()> {
    if let Some(out) = &opts.out {
        scene.output.dir = Some(out.to_string_lossy().into_owned());
    }
    if let Some(d) = opts.duration {
        if !(d.is_finite() && d > 0.0) {
            return Err(HemlError::Invalid(format!(
                "--duration {d}: expected a finite number of seconds > 0"
            )));
        }
        scene.solver.duration = d;
    }
    // a refusal about `duration` names the flag when the flag set it (the scene's
    // [solver] line would point at a value that is not the one used)
    let mut sim = scene.build().map_err(|e| match opts.duration {
        Some(d) if e.to_string().contains("duration") => {
            HemlError::Invalid(format!("{e} (duration = {d:e} s from --duration)"))
        }
        _ => e,
    })?;
    for w in &sim.warnings {
        eprintln!("heml warning: {w}");
    }
    let sys = &sim.system;
    if !opts.quiet {
        outln!(
            "{}: {} nodes, {} tets, {} constrained; {} with dt = {:.3e} s (stable estimate {:.3e} s), {} steps, \
             a frame every {} steps -> {}; plan: {}",
            scene.origin.display(),
            sys.mesh().n_nodes(),
            sys.mesh().n_tets(),
            sys.constraints().constrained_nodes().len(),
            sim.integrator.name(),
            sim.dt,
            sys.stable_dt(),
            sim.steps,
            sim.frame_every,
            sim.out_dir.display(),
            sim.plan
        );
    }
    let bar = if opts.quiet || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::with_draw_target(Some(sim.steps), ProgressDrawTarget::stderr());
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40.cyan/blue} {pos}/{len} steps  {msg}  [{elapsed_precise}, eta {eta}]")
        {
            bar.set_style(style);
        }
        bar
    };
    // the whole run inside a pool: the main thread is then one of its workers, so
    // each force evaluation's parallel pass starts without waking a worker and
    // putting this thread to sleep (from outside a pool every pass did: two context
    // switches per evaluation, half the time of a 600-tet liver's implicit step)
    let (pool, _) = crate::threads::thread_pool(rayon::current_num_threads(), crate::threads::Placement::Os)?;
    let result = pool.install(|| {
        sim.run(|p| {
            bar.set_position(p.step);
            if p.step % 64 == 0 || p.step == p.steps {
                let cg = if p.cg_iterations > 0 {
                    format!(", {} CG it./step", p.cg_iterations)
                } else {
                    String::new()
                };
                bar.set_message(format!("t = {:.4} / {} s, {} frames{cg}", p.time, p.duration, p.frames));
            }
        })
    });
    bar.finish_and_clear();
    let summary = result?;
    outln!("done: {summary}");
    Ok(())
}
