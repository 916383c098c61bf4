//! Case `mass_spring`: the mass–spring link law ½k(√l − √L)² is HEML's degenerate
//! case; its forces must be the classical spring forces k_e(|v| − L)·v/|v| of a
//! network with one spring per unique mesh edge, of stiffness k_e = k × (number of
//! tets sharing the edge), computed here independently of the kernels.

use super::plot::{draw, Chart, Mark, Series};
use super::{fmt_num, rel_max_diff, CaseReport, Options, Row};
use heml::force::ForceOptions;
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::{Params, Result, Vec3};
use std::collections::HashMap;

pub(crate) fn run(opts: &Options, report: &mut CaseReport) -> Result<()> {
    let cells = if opts.quick { [3, 2, 2] } else { [8, 6, 4] };
    let base = box_mesh([1.0, 0.75, 0.5], cells, HexSplit::Five)?;
    // jitter the interior so that edge lengths differ
    let nodes: Vec<Vec3> = base
        .nodes()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let s = (i as f64 * 12.9898).sin() * 43758.5453;
            let r = s - s.floor() - 0.5;
            p + Vec3::new(r, -0.7 * r, 0.4 * r) * 0.02
        })
        .collect();
    let tets: Vec<[usize; 4]> = base.tets().iter().map(|t| t.map(|i| i as usize)).collect();
    let mesh = heml::TetMesh::new(nodes, tets)?;
    let k = 250.0;
    let law = heml::material("mass_spring", &Params::from([("k", k)]))?;
    let x: Vec<Vec3> = mesh
        .nodes()
        .iter()
        .map(|p| {
            let a = 0.8 * p.x;
            Vec3::new(
                1.3 * p.x,
                p.y * a.cos() - p.z * a.sin(),
                0.7 * (p.y * a.sin() + p.z * a.cos()),
            )
        })
        .collect();
    let (energy, f) = law.force_field(&mesh, None, &ForceOptions::default())?.forces(&x)?;

    let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
    for t in mesh.tets() {
        for (a, b) in heml::rest::EDGES {
            let (p, q) = (t[a] as usize, t[b] as usize);
            *edges.entry((p.min(q), p.max(q))).or_default() += 1;
        }
    }
    let mut classical = vec![Vec3::zeros(); mesh.n_nodes()];
    let mut classical_energy = 0.0;
    let mut pairs = Vec::new();
    for (&(p, q), &n) in &edges {
        let ke = k * n as f64;
        let rest = (mesh.nodes()[q] - mesh.nodes()[p]).norm();
        let v = x[q] - x[p];
        let len = v.norm();
        let fs = v * (ke * (len - rest) / len);
        classical[p] += fs;
        classical[q] -= fs;
        classical_energy += 0.5 * ke * (len - rest).powi(2);
        pairs.push((len / rest, ke * (len - rest)));
    }
    // Identical formulas up to rearrangement (√l·√l vs |v|², per-tet vs per-edge
    // summation): a few ulps of the largest force, hence 1e-12.
    let d = rel_max_diff(&f, &classical);
    report.rows.push(Row::check(
        format!(
            "nodal forces, {} nodes, {} springs: max rel. difference",
            mesh.n_nodes(),
            edges.len()
        ),
        "HEML link law".into(),
        "classical springs".into(),
        d,
        1e-12,
    ));
    report.rows.push(Row::check(
        "total spring energy (J)",
        fmt_num(energy),
        fmt_num(classical_energy),
        (energy - classical_energy).abs() / classical_energy,
        1e-12,
    ));
    if let Some(path) = opts.plot_path("mass_spring")? {
        let pts: Vec<(f64, f64)> = (0..mesh.n_nodes())
            .map(|i| (classical[i].norm(), f[i].norm()))
            .collect();
        let m = pts.iter().fold(0.0_f64, |a, p| a.max(p.0));
        let chart = Chart::xy(
            "nodal force magnitude",
            "classical springs |f| (N)",
            "HEML link law |f| (N)",
            vec![
                Series::new("y = x", vec![(0.0, 0.0), (m, m)], Mark::Line),
                Series::new("nodes", pts, Mark::Points),
            ],
        );
        let law_chart = Chart::xy(
            "spring law of each edge",
            "stretch |v| / L",
            "tension k_e(|v| - L) (N)",
            vec![Series::new("edges", pairs, Mark::Points)],
        );
        draw(&path, "mass-spring as the degenerate HEML law", &[chart, law_chart])?;
        report.plot = Some(path);
    }
    Ok(())
}
