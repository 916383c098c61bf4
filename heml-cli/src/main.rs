//! The `heml` command: run scenes, list laws, inspect meshes, validate, benchmark.

mod cli;
mod logger;
mod threads;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "heml",
    version,
    about = "Hyper-Elastic Mass Links: hyperelastic soft-tissue simulation"
)]
struct Cli {
    /// Also print the library's informational messages (solver progress, output files).
    #[arg(long, short, global = true)]
    verbose: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List every registered material law with its parameters and energy, or
    /// (--energy) check an energy given as text and print its derivatives.
    Materials(cli::materials::MaterialsArgs),
    /// Mesh statistics, element quality and the stable explicit time step.
    Info(cli::info::InfoArgs),
    /// Run a scene file: VTU frames + a .pvd series + energy.csv (see scenes/example.toml).
    Run(cli::run::RunArgs),
    /// Run the embedded demo scene: a soft block sagging under gravity, pushed by a tool.
    Demo(cli::run::RunOptions),
    /// Run the validation cases of the seed papers: pass/fail table and PNG plots.
    Validate(cli::validate::ValidateArgs),
    /// The simulation live in a browser page (or a finished run played back).
    View(cli::view::ViewArgs),
    /// Force-evaluation throughput of HEML vs the standard P1 path, and step time.
    // boxed: its many options would make every `Command` that large
    Bench(Box<cli::bench::BenchArgs>),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    logger::install(cli.verbose);
    let result = match cli.command {
        Command::Materials(args) => cli::materials::run(args),
        Command::Info(args) => cli::info::run(args),
        Command::Run(args) => cli::run::run(args),
        Command::Demo(opts) => cli::demo::run(opts),
        Command::Validate(args) => cli::validate::run(args),
        Command::Bench(args) => cli::bench::run(*args),
        Command::View(args) => cli::view::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
