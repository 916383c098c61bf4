//! The `heml` command.

use clap::{Parser, Subcommand};
use heml::prelude::*;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "heml",
    version,
    about = "Hyper-Elastic Mass Links: hyperelastic soft-tissue simulation"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List every registered material law with its parameters and energy.
    Materials,
    /// Evaluate every law on an embedded, generated beam (no input files needed).
    Demo,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Materials => {
            print_materials();
            Ok(())
        }
        Command::Demo => demo(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn print_materials() {
    for e in heml::materials_list() {
        let kind = match e.kind {
            LawKind::Invariant => "w(I1, I2, J)",
            LawKind::Link => "link w(l, L)",
        };
        println!("{}  [{kind}]  {}", e.name, e.title());
        for p in e.params {
            println!(
                "    {:<8} {}{}",
                p.name,
                p.doc,
                if p.signed { " (may be negative)" } else { "" }
            );
        }
        println!(
            "    w = {}\n",
            e.energy.split_whitespace().collect::<Vec<_>>().join(" ")
        );
    }
}

/// A 10×2×2 cm beam, stretched 10 % and twisted, evaluated with every law by HEML and
/// by the standard P1 path.
fn demo() -> heml::Result<()> {
    use heml::mesh::generate::{box_mesh, HexSplit};
    let mesh = box_mesh([0.1, 0.02, 0.02], [20, 4, 4], HexSplit::Six)?;
    let x: Vec<Vec3> = mesh
        .nodes()
        .iter()
        .map(|p| {
            let angle = 0.5 * p.x / 0.1;
            let (s, c) = angle.sin_cos();
            let (y, z) = (p.y - 0.01, p.z - 0.01);
            Vec3::new(1.1 * p.x, 0.01 + c * y - s * z, 0.01 + s * y + c * z)
        })
        .collect();
    println!(
        "beam 10 x 2 x 2 cm: {} nodes, {} tets; stretched 10 % and twisted 0.5 rad",
        mesh.n_nodes(),
        mesh.n_tets()
    );
    println!(
        "{:<24} {:>14} {:>14} {:>12}",
        "law", "energy (J)", "max |f| (N)", "HEML vs P1"
    );
    let opts = ForceOptions::default();
    for e in heml::materials_list() {
        let law = e.instantiate(&demo_params(e))?;
        let (energy, f) = law.force_field(&mesh, None, &opts)?.forces(&x)?;
        let fmax = f.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let versus = match law.fem_field(&mesh, None, &opts)? {
            Some(fem) => {
                let (_, g) = fem.forces(&x)?;
                let d = f.iter().zip(&g).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
                format!("{:.1e}", d / fmax)
            }
            None => "n/a".into(),
        };
        println!("{:<24} {:>14.6e} {:>14.6e} {:>12}", e.name, energy, fmax, versus);
    }
    Ok(())
}

/// Soft-tissue-like parameters (E ≈ 3 kPa, ν ≈ 0.45) for each law.
fn demo_params(e: &MaterialEntry) -> Params {
    let (mu, lambda) = heml::params::lame(3e3, 0.45);
    let kappa = lambda + 2.0 * mu / 3.0;
    let mut p = Params::new();
    for info in e.params {
        let v = match info.name {
            "mu" => mu,
            "lambda" => lambda,
            "kappa" => kappa,
            "k" => 10.0,
            "jm" => 50.0,
            "lm" => 3.0,
            "b" | "c2" if e.name != "yeoh" => 1.0,
            "c1" if e.name == "veronda_westmann" => mu,
            "c1" => mu / 2.0,
            "c10" | "c01" => mu / 4.0,
            "a" => mu,
            _ => 0.0,
        };
        p.set(info.name, v);
    }
    p
}
