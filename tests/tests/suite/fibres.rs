//! Fibre-reinforced laws end to end: the property suites' sampling stretches and
//! compresses fibres, scenes give fibre directions (constant, helix, mesh cell
//! field), and the tension-only switch is visible in the energy.

use heml::heml_core::fibres::Fibres;
use heml::nalgebra::Matrix3;
use heml::prelude::*;
use heml::scene::Scene;
use heml_tests::*;
use std::sync::Arc;

fn link() {
    let _ = (heml::materials_list(), heml::integrators_list());
}

/// The suites' sampling (random per-tet fibres under `random_deformation` with
/// stretches 0.6–1.6) puts fibres on both sides of I4 = 1: for each of ten seeds
/// some tets on each side, and over all seeds at least a fifth on each (the split
/// is random; one side empty would leave a max(·, 0) branch untested).
#[test]
fn sampled_fibres_are_stretched_and_compressed() {
    let (mut total_s, mut total_c) = (0, 0);
    for seed in 0..10 {
        let mut rng = rng(seed);
        let mesh = jittered_box(&mut rng, [2, 2, 2]);
        let x = random_deformation(&mut rng, &mesh, 0.6, 1.6, 0.05);
        let (mut stretched, mut compressed) = (0, 0);
        for t in 0..mesh.n_tets() {
            let p = mesh.tet_points(t);
            let dm = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
            let q = mesh.tets()[t].map(|i| x[i as usize]);
            let ds = Matrix3::from_columns(&[q[1] - q[0], q[2] - q[0], q[3] - q[0]]);
            let a = random_unit(&mut rng);
            let i4 = heml::force::fibre_invariants(&(ds * dm.try_inverse().unwrap()), &[a, a], 1)[3];
            if i4 > 1.0 {
                stretched += 1;
            } else {
                compressed += 1;
            }
        }
        assert!(
            stretched > 0 && compressed > 0,
            "seed {seed}: {stretched} stretched, {compressed} compressed"
        );
        total_s += stretched;
        total_c += compressed;
    }
    let n = total_s + total_c;
    assert!(
        total_s * 5 >= n && total_c * 5 >= n,
        "{total_s} stretched, {total_c} compressed"
    );
}

const SCENE: &str = r#"
[mesh]
generate = { kind = "box", size = [1.0, 1.0, 1.0], cells = [2, 2, 2] }

[[material]]
law = "ti_mooney_rivlin"
params = { c1 = 1e3, c2 = 200.0, c3 = 500.0, c4 = 8.0, kappa = 5e4 }
FIBRES

[solver]
duration = 0.01
"#;

/// The elastic energy of the scene's body stretched by 1.2 along z.
fn stretched_energy(fibres: &str, dir: &std::path::Path) -> Result<f64> {
    link();
    body_stretched_energy(&Scene::from_toml_str(&SCENE.replace("FIBRES", fibres), dir)?.build()?)
}

/// The elastic energy of a built scene's (first) body stretched by 1.2 along z, at
/// its own (renumbered) positions.
fn body_stretched_energy(sim: &heml::scene::Simulation) -> Result<f64> {
    let x: Vec<Vec3> = sim
        .system
        .positions()
        .iter()
        .map(|p| Vec3::new(p.x, p.y, 1.2 * p.z))
        .collect();
    sim.system.regions()[0].field().energy(&x)
}

/// A constant direction, the same from a VTU cell field, and the library path
/// agree; across the stretch the (shortened) fibres carry nothing — the matrix
/// alone — and along it they add the closed-form fibre energy F(√Ī4).
#[test]
fn scene_fibre_sources_agree_and_the_switch_shows() {
    let dir = std::env::temp_dir().join(format!("heml-fibres-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let along = stretched_energy("fibres = [[0.0, 0.0, 2.0]]", &dir).unwrap();
    let across = stretched_energy("fibres = [[1.0, 0.0, 0.0]]", &dir).unwrap();

    // the matrix alone: the same law with c3 = 0 has the across energy (to round-off)
    let mesh = heml::mesh::generate::box_mesh([1.0; 3], [2, 2, 2], heml::mesh::generate::HexSplit::Six).unwrap();
    let x: Vec<Vec3> = mesh.nodes().iter().map(|p| Vec3::new(p.x, p.y, 1.2 * p.z)).collect();
    let matrix = heml::material(
        "ti_mooney_rivlin",
        &Params::from([("c1", 1e3), ("c2", 200.0), ("c3", 0.0), ("c4", 8.0), ("kappa", 5e4)]),
    )
    .unwrap()
    .with_fibres(Arc::new(Fibres::uniform(mesh.n_tets(), &[Vec3::z()]).unwrap()))
    .unwrap();
    let e_matrix = matrix
        .force_field(&mesh, None, &ForceOptions::default())
        .unwrap()
        .energy(&x)
        .unwrap();
    // sums of 48 tets' O(1e2) energies: 1e-12 relative is round-off
    assert!((across - e_matrix).abs() <= 1e-12 * e_matrix, "{across} vs {e_matrix}");
    // along: F = diag(1, 1, 1.2), Ī4 = 1.2²·J^(−2/3), unit volume:
    // F(s) = c3/c4·(exp(c4(s − 1)) − 1) − c3·(s − 1), s = √Ī4
    let s = (1.44 * 1.2f64.powf(-2.0 / 3.0)).sqrt();
    let fibre = 500.0 / 8.0 * ((8.0 * (s - 1.0)).exp() - 1.0) - 500.0 * (s - 1.0);
    assert!(
        (along - across - fibre).abs() <= 1e-10 * along,
        "fibre energy {} vs closed form {fibre}",
        along - across
    );

    // the same mesh as a VTU with a 3-component CellData "fiber" field along z
    let mut vtu = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n\
         <UnstructuredGrid>\n",
    );
    let (n, t) = (mesh.n_nodes(), mesh.n_tets());
    vtu += &format!("<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{t}\">\n<Points>\n");
    vtu += "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for p in mesh.nodes() {
        vtu += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    vtu += "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
    for c in mesh.tets() {
        vtu += &format!("{} {} {} {}\n", c[0], c[1], c[2], c[3]);
    }
    vtu += "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
    vtu += &(1..=t).map(|k| (4 * k).to_string()).collect::<Vec<_>>().join(" ");
    vtu += "\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    vtu += &vec!["10"; t].join(" ");
    vtu += "\n</DataArray>\n</Cells>\n<CellData>\n";
    vtu += "<DataArray type=\"Float64\" Name=\"fiber\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    vtu += &vec!["0 0 3"; t].join("\n");
    vtu += "\n</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
    std::fs::write(dir.join("box.vtu"), vtu).unwrap();
    let (read, _) = heml::io::read_mesh(&dir.join("box.vtu")).unwrap();
    assert_eq!(
        read.cell_vectors().get("fiber"),
        Some(&vec![Vec3::new(0.0, 0.0, 3.0); t]),
        "{:?}",
        read.cell_vectors().keys().collect::<Vec<_>>()
    );
    let from_file = SCENE
        .replace(
            "generate = { kind = \"box\", size = [1.0, 1.0, 1.0], cells = [2, 2, 2] }",
            "file = \"box.vtu\"",
        )
        .replace("FIBRES", "fibre_fields = [\"fiber\"]");
    link();
    let sim = Scene::from_toml_str(&from_file, &dir).unwrap().build().unwrap();
    // (the scene renumbers nodes: stretch its own positions)
    let e_file = body_stretched_energy(&sim).unwrap();
    assert!((e_file - along).abs() <= 1e-12 * along, "{e_file} vs {along}");

    // the same field in a legacy VTK file (CELL_DATA VECTORS) and a Gmsh 4.1 file
    // ($ElementData; element k + 1 is tet k): the same energy
    let with_field = |name: &str, bad_at: Option<(usize, &str)>| {
        let path = dir.join(name);
        heml::io::write_mesh(&path, &mesh).unwrap();
        let v = |k: usize| match bad_at {
            Some((at, bad)) if at == k => bad,
            _ => "0 0 3",
        };
        let extra = if name.ends_with(".vtk") {
            format!(
                "VECTORS fiber double\n{}\n",
                (0..t).map(v).collect::<Vec<_>>().join("\n")
            )
        } else {
            let recs: String = (0..t).map(|k| format!("{} {}\n", k + 1, v(k))).collect();
            format!("$ElementData\n1\n\"fiber\"\n1\n0.0\n3\n0\n3\n{t}\n{recs}$EndElementData\n")
        };
        let mut text = std::fs::read_to_string(&path).unwrap();
        text += &extra;
        std::fs::write(&path, text).unwrap();
        Scene::from_toml_str(&from_file.replace("box.vtu", name), &dir).and_then(|s| s.build())
    };
    for name in ["box.vtk", "box.msh"] {
        let e = body_stretched_energy(&with_field(name, None).unwrap()).unwrap();
        assert!((e - along).abs() <= 1e-12 * along, "{name}: {e} vs {along}");
    }
    // a zero vector is an error naming the file, the field and the element
    let e = with_field("zero.msh", Some((4, "0 0 0"))).unwrap_err().to_string();
    assert!(
        e.contains("zero.msh") && e.contains("'fiber'") && e.contains("element 5: the vector is zero"),
        "{e}"
    );
    let e = with_field("zero.vtk", Some((4, "0 0 0"))).unwrap_err().to_string();
    assert!(
        e.contains("zero.vtk") && e.contains("cell 4: the vector is zero"),
        "{e}"
    );
    // so is a non-finite one
    for name in ["nan.msh", "nan.vtk"] {
        let e = with_field(name, Some((2, "nan 0 3"))).unwrap_err().to_string();
        assert!(
            e.contains(name) && e.contains("'fiber'") && e.contains("not finite"),
            "{e}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Missing, misplaced or malformed fibre keys are errors naming the problem.
#[test]
fn fibre_key_errors() {
    let dir = std::env::temp_dir();
    let err = |fibres: &str| stretched_energy(fibres, &dir).unwrap_err().to_string();
    assert!(
        err("").contains("needs fibre directions") || err("").contains("fibre-reinforced"),
        "{}",
        err("")
    );
    assert!(err("fibres = [[0.0, 0.0, 0.0]]").contains("not a non-zero finite vector"));
    assert!(err("fibre_fields = [\"nope\"]").contains("no 3-component cell field 'nope'"));
    assert!(
        err("fibres = [[1.0, 0.0, 0.0]]\nfibre_helix = { axis = [0.0, 0.0, 1.0], angle = 30.0 }").contains("one of")
    );
    // a law without fibres refuses them
    link();
    let text = SCENE
        .replace("ti_mooney_rivlin", "neo_hookean")
        .replace(
            "c1 = 1e3, c2 = 200.0, c3 = 500.0, c4 = 8.0, kappa = 5e4",
            "E = 3e3, nu = 0.4",
        )
        .replace("FIBRES", "fibres = [[1.0, 0.0, 0.0]]");
    let e = Scene::from_toml_str(&text, &dir)
        .and_then(|s| s.build())
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a fibre law"), "{e}");
}

/// A helix of two families around z at ±30°: HGO builds, and its fibres at a tet
/// off the axis are tangential ± axial as asked.
#[test]
fn helical_fibres_build() {
    let dir = std::env::temp_dir();
    link();
    let text = SCENE
        .replace("ti_mooney_rivlin", "holzapfel_gasser_ogden")
        .replace(
            "c1 = 1e3, c2 = 200.0, c3 = 500.0, c4 = 8.0, kappa = 5e4",
            "c = 3e3, k1 = 2e3, k2 = 0.8, dispersion = 0.1, kappa = 5e4",
        )
        .replace(
            "FIBRES",
            "fibre_helix = { axis = [0.0, 0.0, 1.0], origin = [-1.0, 0.5, 0.0], angle = 30.0 }",
        );
    let sim = Scene::from_toml_str(&text, &dir).unwrap().build().unwrap();
    let field = sim.system.regions()[0].field();
    // stretching along the tube axis (z) loads the helical fibres: energy > 0
    let x: Vec<Vec3> = sim
        .system
        .positions()
        .iter()
        .map(|p| Vec3::new(p.x, p.y, 1.1 * p.z))
        .collect();
    assert!(field.energy(&x).unwrap() > 0.0);
}

/// Directions typed as expressions of the rest position give the same body as the
/// helix they spell out, and an expression without a direction somewhere, or with
/// a name that is not a coordinate, is an error naming the tet or the name.
#[test]
fn fibre_expressions_spell_out_a_helix() {
    let dir = std::env::temp_dir();
    link();
    let hgo = SCENE.replace("ti_mooney_rivlin", "holzapfel_gasser_ogden").replace(
        "c1 = 1e3, c2 = 200.0, c3 = 500.0, c4 = 8.0, kappa = 5e4",
        "c = 3e3, k1 = 2e3, k2 = 0.8, dispersion = 0.1, kappa = 5e4",
    );
    let energy = |fibres: &str| -> Result<f64> {
        let sim = Scene::from_toml_str(&hgo.replace("FIBRES", fibres), &dir)?.build()?;
        let x: Vec<Vec3> = sim
            .system
            .positions()
            .iter()
            .map(|p| Vec3::new(1.05 * p.x, p.y - 0.1 * p.z, 1.1 * p.z))
            .collect();
        sim.system.regions()[0].field().energy(&x)
    };
    let helix = energy("fibre_helix = { axis = [0.0, 0.0, 1.0], origin = [-1.0, 0.5, 0.0], angle = 30.0 }").unwrap();
    // circumferential θ = z × r / |r| about the axis through (−1, 0.5), ± 30° towards z
    let r = "sqrt((x + 1)^2 + (y - 0.5)^2)";
    let family = |sign: &str| {
        format!("[\"-(y - 0.5) * cos(PI / 6) / {r}\", \"(x + 1) * cos(PI / 6) / {r}\", \"{sign}sin(PI / 6)\"]")
    };
    let typed = energy(&format!("fibre_expressions = [{}, {}]", family(""), family("-"))).unwrap();
    // the directions differ from the helix's by a few roundings (cos, sin, sqrt):
    // 48 tets' energies summed, 1e-12 relative
    assert!(
        helix > 0.0 && (typed - helix).abs() <= 1e-12 * helix,
        "{typed} vs {helix}"
    );

    let err = |fibres: &str| energy(fibres).unwrap_err().to_string();
    let e = err("fibre_expressions = [[\"0 * x\", \"0\", \"0\"], [\"0\", \"0\", \"1\"]]");
    assert!(
        e.contains("family 1: the direction at tet 0") && e.contains("has no direction"),
        "{e}"
    );
    let e = err("fibre_expressions = [[\"theta\", \"0\", \"0\"], [\"0\", \"0\", \"1\"]]");
    assert!(e.contains("unknown variable 'theta'"), "{e}");
    let e = err("fibre_expressions = [[\"1\", \"0\", \"0\"]]");
    assert!(e.contains("1 direction(s); law holzapfel_gasser_ogden has 2"), "{e}");
}
