//! Cost of a cut (issue 19): removing 1 and 100 tets from the gen_kidney_100k organ
//! mesh (≈ 90k tets) against building its system from scratch, and a blade sweep.
//! The cut topology (tet neighbours, the surface's face index) is built once, by
//! `System::prepare_cutting` or the first cut: timed separately.
//!
//! Run with `cargo bench -p heml-validation --features criterion --bench cut` (the mesh
//! is looked up like the validation cases': `HEML_MESHES`, then `../shared/meshes`; a
//! box of 100k tets stands in when it is missing). Prints medians; nothing is asserted.

use heml::mesh::generate::box_of_about;
use heml::prelude::*;
use heml::system::cut::Blade;
use std::time::Instant;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2])
}

fn main() {
    let _ = heml::materials_list();
    let opts = heml_validation::Options::quick();
    let path = opts.mesh_dir().map(|d| d.join("msh/gen_kidney_100k.msh"));
    let (name, mesh) = match path.filter(|p| p.is_file()) {
        // the organ meshes are in mm
        Some(p) => (
            "gen_kidney_100k",
            heml::io::read_mesh(&p).expect("mesh").0.scaled(1e-3).expect("scale"),
        ),
        None => ("box_of_about(100k)", box_of_about(100_000).expect("mesh")),
    };
    let params = heml_validation::fixtures::soft_tissue_params("neo_hookean", 3e3, 0.45).expect("params");
    let build = || {
        System::builder(mesh.clone())
            .material("neo_hookean", &params)
            .expect("law")
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .build()
            .expect("system")
    };
    let mut rebuild: Vec<f64> = (0..5)
        .map(|_| {
            let start = Instant::now();
            std::hint::black_box(build());
            start.elapsed().as_secs_f64()
        })
        .collect();
    let rebuild = median(&mut rebuild);

    let mut sys = build();
    let start = Instant::now();
    sys.prepare_cutting();
    let prepare = start.elapsed().as_secs_f64();
    let n = sys.mesh().n_tets();
    // single tets spread over the mesh, one cut each
    let mut one: Vec<f64> = (0..50)
        .map(|k| {
            let t = (k * 7919 + 13) % n;
            let start = Instant::now();
            std::hint::black_box(sys.remove_tets(&[t]).expect("cut"));
            start.elapsed().as_secs_f64()
        })
        .collect();
    // clusters of 100 tets: the 100 tets nearest a point (a local cut)
    let centroids: Vec<Vec3> = (0..n).map(|t| mesh.tet_points(t).iter().sum::<Vec3>() / 4.0).collect();
    let centroid = |t: usize| centroids[t];
    let mut hundred = Vec::new();
    for k in 0..10 {
        let c = centroid((k * 104_729 + 7) % n);
        let mut near: Vec<(f64, usize)> = (0..n)
            .filter(|&t| sys.tet_alive(t))
            .map(|t| ((centroid(t) - c).norm(), t))
            .collect();
        near.select_nth_unstable_by(100, |a, b| a.0.total_cmp(&b.0));
        let ids: Vec<usize> = near[..100].iter().map(|&(_, t)| t).collect();
        let start = Instant::now();
        std::hint::black_box(sys.remove_tets(&ids).expect("cut"));
        hundred.push(start.elapsed().as_secs_f64());
    }
    // blade sweeps: a 2 mm edge swept 2 mm through the body
    let (lo, hi) = sys.mesh().bounding_box();
    let mid = (lo + hi) / 2.0;
    let mut sweep = Vec::new();
    let mut swept_tets = Vec::new();
    for k in 0..10 {
        let o = mid + Vec3::new(0.0, 0.0, (k as f64 - 5.0) * 0.003);
        let blade = Blade::Sweep {
            a0: o,
            b0: o + Vec3::new(0.0, 0.0, 0.002),
            a1: o + Vec3::new(0.002, 0.0, 0.0),
            b1: o + Vec3::new(0.002, 0.0, 0.002),
        };
        let start = Instant::now();
        if let Ok(r) = sys.cut(&blade) {
            sweep.push(start.elapsed().as_secs_f64());
            swept_tets.push(r.removed_tets.len() as f64);
        }
    }
    let (m1, m100) = (median(&mut one), median(&mut hundred));
    println!(
        "cut cost on {name} ({n} tets, {} threads):",
        rayon::current_num_threads()
    );
    println!("  build the system from scratch   {:9.3} ms", rebuild * 1e3);
    println!(
        "  prepare_cutting (once)          {:9.3} ms ({:.2} % of a build)",
        prepare * 1e3,
        100.0 * prepare / rebuild
    );
    println!(
        "  remove 1 tet                    {:9.3} ms ({:.4} % of a build)",
        m1 * 1e3,
        100.0 * m1 / rebuild
    );
    println!(
        "  remove 100 tets                 {:9.3} ms ({:.3} % of a build)",
        m100 * 1e3,
        100.0 * m100 / rebuild
    );
    if !sweep.is_empty() {
        println!(
            "  blade sweep ({:.0} tets)          {:9.3} ms ({:.3} % of a build)",
            median(&mut swept_tets),
            median(&mut sweep) * 1e3,
            100.0 * median(&mut sweep) / rebuild
        );
    }
}
