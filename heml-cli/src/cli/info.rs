//! `heml info MESH`: what a mesh holds, how good its elements are, and the explicit
//! time step it allows for a given law — the questions to ask before a run.

use clap::Args;
use heml::io::read_mesh;
use heml::mesh::quality::mesh_quality;
use heml::prelude::*;
use std::path::PathBuf;

/// Arguments of `heml info`.
#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Mesh file (.msh, .vtk, .vtu, .node/.ele, .mesh, .ply).
    pub mesh: PathBuf,
    /// Multiply coordinates by this factor (e.g. 0.001 for a mesh in millimetres).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Law for the stable time step (registry name, see `heml materials`).
    #[arg(long, default_value = "neo_hookean")]
    pub law: String,
    /// Law parameter NAME=VALUE (repeatable). Default for laws set by E and nu: the
    /// material the mesh file states (OpenSurgSim .ply), else E=3000, nu=0.45 (either
    /// given alone keeps the other's default).
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// Mass density (kg/m³). Default: the mesh file's material, else 1000.
    #[arg(long)]
    pub density: Option<f64>,
}

/// Parses `NAME=VALUE` pairs into [`Params`].
/// A name without a value, a value without a name and a name given twice are
/// errors naming the flag (a repeated name would otherwise silently keep the last).
pub fn parse_params(pairs: &[String]) -> heml::Result<Params> {
    let mut p = Params::new();
    for pair in pairs {
        let (name, value) = pair
            .split_once('=')
            .ok_or_else(|| HemlError::Invalid(format!("--param '{pair}': expected NAME=VALUE, e.g. E=3000")))?;
        let name = name.trim();
        if name.is_empty() {
            return Err(HemlError::Invalid(format!(
                "--param '{pair}': the parameter name before '=' is missing (expected NAME=VALUE, e.g. E=3000)"
            )));
        }
        let value: f64 = value
            .trim()
            .parse()
            .map_err(|_| HemlError::Invalid(format!("--param '{pair}': '{value}' is not a number")))?;
        if let Some(first) = p.get(name) {
            return Err(HemlError::Invalid(format!(
                "--param {name} is given twice ({name}={first} and {name}={value}): give each parameter once"
            )));
        }
        p.set(name, value);
    }
    Ok(p)
}

/// Prints the report.
pub fn run(args: InfoArgs) -> heml::Result<()> {
    if !(args.scale.is_finite() && args.scale > 0.0) {
        return Err(HemlError::Invalid(format!(
            "--scale {} must be a positive number",
            args.scale
        )));
    }
    let (mesh, report) = read_mesh(&args.mesh)?;
    let mesh = if args.scale == 1.0 {
        mesh
    } else {
        mesh.scaled(args.scale)?
    };
    outln!("{report}");
    let (lo, hi) = mesh.bounding_box();
    let size = hi - lo;
    outln!("{:<16}{}", "nodes", mesh.n_nodes());
    outln!("{:<16}{} (regions: {:?})", "tets", mesh.n_tets(), mesh.distinct_tags());
    outln!("{:<16}{:.6e}", "volume", mesh.total_volume());
    outln!(
        "{:<16}[{:.4e}, {:.4e}, {:.4e}] – [{:.4e}, {:.4e}, {:.4e}]",
        "bounding box",
        lo.x,
        lo.y,
        lo.z,
        hi.x,
        hi.y,
        hi.z
    );
    outln!("{:<16}{:.4e} × {:.4e} × {:.4e}", "size", size.x, size.y, size.z);
    let Some(q) = mesh_quality(&mesh, None) else {
        outln!("(no tets: nothing more to report)");
        return Ok(());
    };
    let deg = |r: f64| r.to_degrees();
    outln!(
        "{:<16}min {:.4e}, max {:.4e}",
        "edge length",
        q.edge_length.0,
        q.edge_length.1
    );
    outln!(
        "{:<16}min {:.2}° (tet {}), max {:.2}° (tet {})",
        "dihedral angle",
        deg(q.min_dihedral.0),
        q.min_dihedral.1,
        deg(q.max_dihedral.0),
        q.max_dihedral.1
    );
    outln!(
        "{:<16}max {:.3} (tet {}; 1 = regular)",
        "aspect ratio",
        q.max_aspect_ratio.0,
        q.max_aspect_ratio.1
    );
    outln!(
        "{:<16}min {:.4} (tet {}; 1 = regular)",
        "radius ratio",
        q.min_radius_ratio.0,
        q.min_radius_ratio.1
    );
    outln!("{:<16}{:.4e} (tet {})", "min height", q.min_height.0, q.min_height.1);

    let entry = heml::find_material(&args.law)?;
    let mut params = parse_params(&args.params)?;
    // default soft tissue when the law's declared small-strain mapping sets every
    // parameter from E and nu
    let from_moduli = entry
        .small_strain
        .as_ref()
        .is_some_and(|s| s.fields.len() == entry.params.len());
    // (each of E and nu the user leaves out keeps its default, as the help says)
    let (e, nu, rho) = report.material.map_or((3000.0, 0.45, 1000.0), |m| {
        (m.young_modulus, m.poisson_ratio, m.density)
    });
    let density = args.density.unwrap_or(rho);
    if from_moduli && params.0.keys().all(|k| k == "E" || k == "nu") {
        for (name, value) in [("E", e), ("nu", nu)] {
            if params.get(name).is_none() {
                params.set(name, value);
            }
        }
    }
    let shown: Vec<String> = params.0.iter().map(|(k, v)| format!("{k}={v}")).collect();
    let sys = heml::system(mesh)
        .material(&args.law, &params)?
        .density(density)
        .pin_unreferenced()
        .build()?;
    outln!(
        "{:<16}{:.4e} s  ({} {}, density {} kg/m³, safety factor included)",
        "stable dt",
        sys.stable_dt(),
        args.law,
        shown.join(" "),
        density
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_params;

    #[test]
    fn params_need_a_name_a_number_and_each_name_once() {
        let p = |a: &[&str]| parse_params(&a.iter().map(|s| s.to_string()).collect::<Vec<_>>());
        let ok = p(&["E = 5000", "nu=0.3"]).unwrap();
        assert_eq!((ok.get("E"), ok.get("nu")), (Some(5000.0), Some(0.3)));
        let e = p(&["=3"]).unwrap_err().to_string();
        assert!(e.contains("name before '=' is missing"), "{e}");
        let e = p(&["mu=1", "mu=2"]).unwrap_err().to_string();
        assert!(e.contains("--param mu is given twice (mu=1 and mu=2)"), "{e}");
        let e = p(&["mu=x"]).unwrap_err().to_string();
        assert!(e.contains("'x' is not a number"), "{e}");
    }
}
