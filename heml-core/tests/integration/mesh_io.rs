//! Mesh input/output: fixtures of every format, the shared sample meshes, round
//! trips through every writer, a corpus of broken files, and truncation/corruption
//! fuzzing (no input may make a reader panic).

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use heml_core::io::{
    read_mesh, read_mesh_data, read_pvd, write_mesh, write_mesh_as, write_vtu, MeshFormat, PvdWriter, VtuEncoding,
    VtuFrame,
};
use heml_core::mesh::generate::{box_mesh, HexSplit};
use heml_core::{HemlError, TetMesh, Vec3};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

/// A fresh scratch directory for one test.
fn scratch(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("heml-mesh-io-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The tiny mesh every fixture holds: 5 nodes, 2 tets tagged 1 and 2.
const TINY_NODES: [[f64; 3]; 5] = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.], [1., 1., 1.]];
const TINY_TETS: [[u32; 4]; 2] = [[0, 1, 2, 3], [1, 2, 3, 4]];

fn sorted(t: [u32; 4]) -> [u32; 4] {
    let mut t = t;
    t.sort_unstable();
    t
}

#[test]
fn every_fixture_format_reads_the_tiny_mesh() {
    let one = |k: &str| BTreeMap::from([(k.to_string(), 1usize)]);
    let none = BTreeMap::new();
    // file, format, skipped elements, reoriented tets
    let cases: Vec<(&str, MeshFormat, BTreeMap<String, usize>, usize)> = vec![
        (
            "tiny_v22.msh",
            MeshFormat::Gmsh22,
            BTreeMap::from([("point".into(), 1), ("triangle".into(), 1)]),
            1,
        ),
        ("tiny_v41.msh", MeshFormat::Gmsh41, one("triangle"), 0),
        (
            "tiny_v1.msh",
            MeshFormat::Gmsh1,
            BTreeMap::from([("point".into(), 1), ("triangle".into(), 1)]),
            1,
        ),
        // written by meshio 5.3.5 (make_meshio_fixtures.py): its defaults
        ("tiny_meshio_b22.msh", MeshFormat::Gmsh22Binary, one("triangle"), 0),
        ("tiny_meshio_lzma.vtu", MeshFormat::Vtu, one("triangle/polygon"), 0),
        ("tiny_classic.vtk", MeshFormat::VtkLegacy, one("triangle/polygon"), 0),
        ("tiny_vtk5.vtk", MeshFormat::VtkLegacy, none.clone(), 0),
        ("tiny_binary.vtk", MeshFormat::VtkLegacy, one("triangle/polygon"), 0),
        ("tiny_ascii.vtu", MeshFormat::Vtu, one("triangle/polygon"), 0),
        ("tiny_appended_raw.vtu", MeshFormat::Vtu, one("triangle/polygon"), 0),
        (
            "tiny_appended_raw_zlib.vtu",
            MeshFormat::Vtu,
            one("triangle/polygon"),
            0,
        ),
        ("tiny_appended_base64.vtu", MeshFormat::Vtu, one("triangle/polygon"), 0),
        ("tiny_zero_based.node", MeshFormat::TetGen, none.clone(), 0),
        ("tiny_zero_based.ele", MeshFormat::TetGen, none.clone(), 0),
        (
            "tiny.mesh",
            MeshFormat::Medit,
            BTreeMap::from([("corners".into(), 2), ("triangles".into(), 1)]),
            0,
        ),
        // OpenSurgSim's layout (make_ply_fixtures.py), ASCII and big-endian binary
        (
            "tiny_surgsim.ply",
            MeshFormat::Ply,
            BTreeMap::from([("face".into(), 2)]),
            0,
        ),
        (
            "tiny_surgsim_be.ply",
            MeshFormat::PlyBinary,
            BTreeMap::from([("face".into(), 2)]),
            0,
        ),
    ];
    for (file, format, skipped, reoriented) in cases {
        let path = data(file);
        let (mesh, report) = read_mesh(&path).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(report.format, format, "{file}");
        assert_eq!((report.n_nodes, report.n_tets), (5, 2), "{file}");
        assert_eq!(report.skipped, skipped, "{file}");
        assert_eq!(report.reoriented, reoriented, "{file}");
        assert_eq!(report.unreferenced_nodes, 0, "{file}");
        let nodes: Vec<[f64; 3]> = mesh.nodes().iter().map(|p| [p.x, p.y, p.z]).collect();
        assert_eq!(nodes, TINY_NODES, "{file}");
        let tets: Vec<[u32; 4]> = mesh.tets().iter().map(|&t| sorted(t)).collect();
        assert_eq!(tets, TINY_TETS, "{file}");
        assert_eq!(mesh.tags(), [1, 2], "{file}");
        assert!((mesh.total_volume() - 0.5).abs() < 1e-15, "{file}");
        assert!(report.to_string().contains(file), "{report}");
    }
    // the PLY fixtures' boundary conditions (2, 0, 1, 1: a set) and material
    for file in ["tiny_surgsim.ply", "tiny_surgsim_be.ply"] {
        let (mesh, report) = read_mesh(&data(file)).unwrap();
        assert_eq!(mesh.node_set("boundary_condition"), Some(&[0, 1, 2][..]), "{file}");
        assert_eq!(
            report.node_sets,
            BTreeMap::from([("boundary_condition".into(), 3)]),
            "{file}"
        );
        let m = report.material.unwrap_or_else(|| panic!("{file}: no material"));
        assert_eq!(
            (m.density, m.young_modulus, m.poisson_ratio),
            (1000.0, 75000.0, 0.45),
            "{file}"
        );
        assert!(report.to_string().contains("E 75000, nu 0.45"), "{report}");
    }
    // one-based TetGen without attributes: tags default to 0
    let (mesh, _) = read_mesh(&data("tiny_one_based.ele")).unwrap();
    assert_eq!(mesh.tets().iter().map(|&t| sorted(t)).collect::<Vec<_>>(), TINY_TETS);
    assert_eq!(mesh.tags(), [0, 0]);
}

// ---------------------------------------------------------------- shared meshes

fn shared_meshes() -> Option<PathBuf> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/meshes")).to_path_buf();
    if dir.join("README.md").is_file() {
        Some(dir)
    } else {
        eprintln!("skipping: ../shared/meshes not found (looked in {})", dir.display());
        None
    }
}

/// `name → (nodes, tets)` from the tables of the README (`| name | nodes | tets | …`).
fn readme_counts(readme: &str) -> BTreeMap<String, (usize, usize)> {
    let mut out = BTreeMap::new();
    for line in readme.lines() {
        let f: Vec<&str> = line.split('|').map(str::trim).collect();
        if f.len() > 4 {
            if let (Ok(n), Ok(t)) = (f[2].parse(), f[3].parse()) {
                out.insert(f[1].to_string(), (n, t));
            }
        }
    }
    out
}

/// `mesh_stats.json` rounds every number to 4 significant digits (`'%.4g'`), so
/// the exact value differs from it by at most half a unit in the 4th digit:
/// |x − g| ≤ 5·10⁻⁴·|x|. Allow that bound (on the larger magnitude, plus a hair for
/// the summation order of the volume) and nothing more.
fn close_to_4_digits(x: f64, g: f64) -> bool {
    (x - g).abs() <= 5.0e-4 * x.abs().max(g.abs()) * (1.0 + 1e-6) + 1e-300
}

#[test]
fn shared_meshes_match_readme_stats_and_each_other() {
    let Some(dir) = shared_meshes() else { return };
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    let counts = readme_counts(&readme);
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("mesh_stats.json")).unwrap()).unwrap();
    let mut msh_files: Vec<PathBuf> = std::fs::read_dir(dir.join("msh"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "msh"))
        .collect();
    msh_files.sort();
    assert!(
        msh_files.len() >= 16,
        "expected the 16 sample meshes, found {}",
        msh_files.len()
    );
    for msh in msh_files {
        let name = msh.file_stem().unwrap().to_str().unwrap().to_string();
        let (m, report) = read_mesh(&msh).unwrap_or_else(|e| panic!("{e}"));
        let (v, vreport) = read_mesh(&dir.join("vtu").join(format!("{name}.vtu"))).unwrap_or_else(|e| panic!("{e}"));
        let &(n_nodes, n_tets) = counts
            .get(&name)
            .unwrap_or_else(|| panic!("{name} not in README tables"));
        assert_eq!((m.n_nodes(), m.n_tets()), (n_nodes, n_tets), "{name} msh vs README");
        assert_eq!((v.n_nodes(), v.n_tets()), (n_nodes, n_tets), "{name} vtu vs README");
        assert_eq!(report.format, MeshFormat::Gmsh41);
        assert_eq!(vreport.format, MeshFormat::Vtu);
        assert_eq!(
            (report.reoriented, vreport.reoriented),
            (0, 0),
            "{name}: README says no tet was inverted"
        );
        assert_eq!(report.unreferenced_nodes, 0, "{name}");
        // same mesh, node by node (bit-identical: both were written from one array) and tet by tet
        assert_eq!(m.nodes(), v.nodes(), "{name}: msh and vtu nodes differ");
        assert_eq!(m.tets(), v.tets(), "{name}: msh and vtu tets differ");
        assert_eq!(m.tags(), v.tags(), "{name}");
        let s = &stats[&name];
        let vol = s["volume"].as_f64().unwrap();
        assert!(
            close_to_4_digits(m.total_volume(), vol),
            "{name}: volume {} vs {vol}",
            m.total_volume()
        );
        let (lo, hi) = m.bounding_box();
        for a in 0..3 {
            let (slo, shi) = (s["bbox_min"][a].as_f64().unwrap(), s["bbox_max"][a].as_f64().unwrap());
            assert!(
                close_to_4_digits(lo[a], slo),
                "{name}: bbox_min[{a}] {} vs {slo}",
                lo[a]
            );
            assert!(
                close_to_4_digits(hi[a], shi),
                "{name}: bbox_max[{a}] {} vs {shi}",
                hi[a]
            );
        }
    }
}

// ---------------------------------------------------------------- round trips

/// A box mesh with awkward coordinates (not short decimals) and varied tags,
/// including 0 and negative ones, in non-sorted runs.
fn tagged_box() -> TetMesh {
    let m = box_mesh([1.0 / 3.0, 0.7, std::f64::consts::PI], [3, 2, 2], HexSplit::Six).unwrap();
    let nodes: Vec<Vec3> = m
        .nodes()
        .iter()
        .map(|p| p * 1.000_000_1 + Vec3::new(1e-9, -2.5e7, 1e-300))
        .collect();
    let tets: Vec<[usize; 4]> = m.tets().iter().map(|t| t.map(|i| i as usize)).collect();
    let tags: Vec<i32> = (0..tets.len())
        .map(|k| [3, -1, 0, 7, 3][k % 5] + (k / 20) as i32)
        .collect();
    TetMesh::with_tags(nodes, tets, tags).unwrap()
}

fn assert_same_mesh(a: &TetMesh, b: &TetMesh, what: &str) {
    assert_eq!(a.n_nodes(), b.n_nodes(), "{what}");
    // Binary formats store the f64 bits; text formats print the shortest decimal that
    // parses back to the same f64, so both must be exact (the bar was 1e-15 relative).
    for (i, (p, q)) in a.nodes().iter().zip(b.nodes()).enumerate() {
        assert_eq!(p, q, "{what}: node {i}");
    }
    assert_eq!(a.tets(), b.tets(), "{what}");
    assert_eq!(a.tags(), b.tags(), "{what}");
    assert_eq!(b.reoriented_count(), 0, "{what}");
}

#[test]
fn every_writer_round_trips_nodes_tets_and_tags() {
    let dir = scratch("roundtrip");
    let mesh = tagged_box();
    let cases = [
        ("m22.msh", Some(MeshFormat::Gmsh22), MeshFormat::Gmsh22),
        ("m41.msh", None, MeshFormat::Gmsh41),
        ("m1.msh", Some(MeshFormat::Gmsh1), MeshFormat::Gmsh1),
        ("mb22.msh", Some(MeshFormat::Gmsh22Binary), MeshFormat::Gmsh22Binary),
        ("mb41.msh", Some(MeshFormat::Gmsh41Binary), MeshFormat::Gmsh41Binary),
        ("m.vtk", None, MeshFormat::VtkLegacy),
        ("m.vtu", None, MeshFormat::Vtu),
        ("m.node", None, MeshFormat::TetGen),
        ("m.mesh", None, MeshFormat::Medit),
        ("m.ply", None, MeshFormat::Ply),
        ("mb.ply", Some(MeshFormat::PlyBinary), MeshFormat::PlyBinary),
    ];
    for (file, explicit, expected) in cases {
        let path = dir.join(file);
        match explicit {
            Some(f) => write_mesh_as(&path, &mesh, f).unwrap(),
            None => write_mesh(&path, &mesh).unwrap(),
        }
        let (back, report) = read_mesh(&path).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(report.format, expected, "{file}");
        assert_same_mesh(&mesh, &back, file);
    }
    // a node set named boundary_condition goes out and back through both PLY
    // encodings (and survives the renumbering at load)
    let z0 = mesh.nodes().iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    let bottom: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| mesh.nodes()[i].z == z0).collect();
    assert!(bottom.len() > 3);
    let with_set = mesh
        .clone()
        .with_node_set("boundary_condition", bottom.clone())
        .unwrap();
    for (file, format) in [("s.ply", MeshFormat::Ply), ("sb.ply", MeshFormat::PlyBinary)] {
        let path = dir.join(file);
        write_mesh_as(&path, &with_set, format).unwrap();
        let (back, _) = read_mesh(&path).unwrap();
        assert_eq!(back.node_set("boundary_condition"), Some(&bottom[..]), "{file}");
        let p = heml_core::mesh::reorder::morton_node_order(&back);
        let moved = back
            .renumbered(&p, &heml_core::mesh::reorder::Permutation::identity(back.n_tets()))
            .unwrap();
        let mut expect: Vec<usize> = bottom.iter().map(|&i| p.old_to_new[i]).collect();
        expect.sort_unstable();
        assert_eq!(
            moved.node_set("boundary_condition"),
            Some(&expect[..]),
            "{file}: renumbered"
        );
    }
    // TetGen: the .ele sibling was written too, and can be given instead
    let (back, _) = read_mesh(&dir.join("m.ele")).unwrap();
    assert_same_mesh(&mesh, &back, "m.ele");
    // every VTU encoding
    for enc in [VtuEncoding::Base64, VtuEncoding::Base64Zlib, VtuEncoding::Ascii] {
        let path = dir.join(format!("enc-{enc:?}.vtu"));
        write_vtu(&path, &VtuFrame::from_mesh(&mesh).encoding(enc)).unwrap();
        let (back, _) = read_mesh(&path).unwrap();
        assert_same_mesh(&mesh, &back, &format!("{enc:?}"));
    }
    // no temporary files left behind
    for e in std::fs::read_dir(&dir).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        assert!(!name.starts_with('.'), "leftover temporary {name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn vtu_frames_carry_fields_and_check_sizes() {
    let dir = scratch("frames");
    let mesh = box_mesh([1.0; 3], [2, 1, 1], HexSplit::Five).unwrap();
    let moved: Vec<Vec3> = mesh.nodes().iter().map(|p| p * 2.0).collect();
    let disp: Vec<Vec3> = mesh.nodes().to_vec();
    let j: Vec<f64> = (0..mesh.n_tets()).map(|k| k as f64 * 0.25).collect();
    let path = dir.join("f.vtu");
    let frame = VtuFrame::deformed(&mesh, &moved)
        .point_vectors("displacement", &disp)
        .cell_scalars("J & <det>", &j);
    write_vtu(&path, &frame).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("Name=\"displacement\"") && text.contains("Name=\"J &amp; &lt;det&gt;\""));
    let (back, _) = read_mesh(&path).unwrap();
    assert_eq!(back.nodes(), &moved[..]);
    assert!((back.total_volume() - 8.0).abs() < 1e-12);
    let short = vec![0.0; 3];
    let e = write_vtu(&path, &VtuFrame::from_mesh(&mesh).cell_scalars("J", &short)).unwrap_err();
    assert!(e.to_string().contains("'J' has 3 entries, expected 10"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn pvd_is_valid_after_every_frame() {
    let dir = scratch("pvd");
    let pvd_path = dir.join("run.pvd");
    let mut pvd = PvdWriter::create(&pvd_path).unwrap();
    assert!(read_pvd(&pvd_path).unwrap().is_empty());
    let mesh = box_mesh([1.0; 3], [1, 1, 1], HexSplit::Six).unwrap();
    for k in 0..3 {
        let frame = dir.join(format!("frame_{k:04}.vtu"));
        write_vtu(&frame, &VtuFrame::from_mesh(&mesh)).unwrap();
        pvd.add(k as f64 * 0.1, &frame).unwrap();
        let entries = read_pvd(&pvd_path).unwrap();
        assert_eq!(entries.len(), k + 1);
        assert_eq!(entries[k], (k as f64 * 0.1, format!("frame_{k:04}.vtu")));
        assert_eq!(entries, pvd.entries());
    }
    assert!(pvd.add(f64::NAN, &dir.join("x.vtu")).is_err());
    assert_eq!(
        read_pvd(&pvd_path).unwrap().len(),
        3,
        "a rejected frame must not change the pvd"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------- bad input

#[test]
fn unknown_extension_missing_file_and_unwritable_path_are_clear_errors() {
    let e = read_mesh(Path::new("mesh.obj")).unwrap_err().to_string();
    assert!(
        e.contains("mesh.obj") && e.contains(".msh") && e.contains(".vtu") && e.contains(".mesh"),
        "{e}"
    );
    let e = read_mesh(&data("does_not_exist.msh")).unwrap_err();
    assert!(
        matches!(e, HemlError::Io { .. }) && e.to_string().contains("does_not_exist.msh"),
        "{e}"
    );
    let mesh = box_mesh([1.0; 3], [1, 1, 1], HexSplit::Six).unwrap();
    let e = write_mesh(&data("no/such/dir/out.vtu"), &mesh).unwrap_err();
    assert!(
        matches!(e, HemlError::Io { .. }) && e.to_string().contains("out.vtu"),
        "{e}"
    );
    let e = write_mesh(Path::new("out.stl"), &mesh).unwrap_err().to_string();
    assert!(e.contains("out.stl") && e.contains(".vtk"), "{e}");
}

/// Expected failure of a broken fixture.
enum Want {
    /// `HemlError::Parse` at this line (0: any line > 0), message containing the text.
    Parse(usize, &'static str),
    /// `HemlError::Mesh` whose message contains the text.
    Mesh(&'static str),
}

#[test]
fn broken_files_give_errors_with_file_and_line() {
    use Want::*;
    let cases = [
        ("msh_truncated.msh", Parse(0, "end of file")),
        ("msh_wrong_count.msh", Parse(15, "found '$EndElements'")),
        ("msh_non_numeric.msh", Parse(7, "'1.0x'")),
        ("msh_bad_node.msh", Parse(13, "node 9")),
        ("msh_missing_elements.msh", Parse(0, "missing $Elements")),
        // declared binary, holds text: the endianness integer after line 2 is "$Nod"
        ("msh_binary.msh", Parse(3, "the integer 1 written in binary")),
        ("msh_tet10.msh", Parse(13, "type 11")),
        ("msh_unclosed.msh", Parse(4, "not closed")),
        ("msh_degenerate.msh", Mesh("degenerate")),
        (
            "msh_bad_physical_name.msh",
            Parse(7, "expected a \"quoted\" name, found 'tumour'"),
        ),
        ("vtk_truncated.vtk", Parse(0, "end of file")),
        // the line of the bad cell (8), not of the CELLS header (7) as it used to be
        ("vtk_bad_index.vtk", Parse(8, "node 7")),
        ("vtk_missing_cell_types.vtk", Parse(0, "missing CELL_TYPES")),
        ("vtk_non_numeric.vtk", Parse(6, "'abc'")),
        ("vtk_wrong_cells_size.vtk", Parse(9, "cell list, found 'CELL_TYPES'")),
        ("vtk_not_vtk.vtk", Parse(1, "# vtk DataFile")),
        ("vtu_bad_base64.vtu", Parse(6, "base64")),
        ("vtu_bad_zlib.vtu", Parse(6, "zlib")),
        ("vtu_wrong_count.vtu", Parse(6, "expected 15")),
        ("vtu_malformed.vtu", Parse(12, "XML")),
        ("vtu_missing_cells.vtu", Parse(4, "connectivity")),
        ("tetgen_oob.ele", Parse(3, "point number 9")),
        ("tetgen_dim2.node", Parse(1, "dimension 2")),
        ("medit_unknown.mesh", Parse(9, "SubDomainFromMesh")),
        ("medit_truncated.mesh", Parse(0, "end of file")),
        ("medit_bad_index.mesh", Parse(21, "vertex number 0")),
        ("ply_not_ply.ply", Parse(1, "not a PLY file")),
        ("ply_bad_version.ply", Parse(2, "version '2.0'")),
        (
            "ply_truncated.ply",
            Parse(13, "announces 5 vertex records, the file ends after 3"),
        ),
        ("ply_five_vertices.ply", Parse(16, "3d_element 1: 5 vertices")),
        ("ply_bad_index.ply", Parse(16, "3d_element 1: vertex 9 is outside 0..5")),
        ("ply_tetra_element.ply", Parse(7, "element 'tetra' lists vertices")),
        ("ply_no_z.ply", Parse(3, "no scalar property z")),
        (
            "ply_extra_records.ply",
            Parse(17, "after the records the header announces"),
        ),
    ];
    for (file, want) in cases {
        let path = data("broken").join(file);
        let result = catch_unwind(|| read_mesh(&path));
        let err = match result {
            Ok(Ok(_)) => panic!("{file}: read without error"),
            Ok(Err(e)) => e,
            Err(_) => panic!("{file}: the reader panicked"),
        };
        let msg = err.to_string();
        let stem = file.split('.').next().unwrap();
        assert!(msg.contains(stem), "{file}: message does not name the file: {msg}");
        match (want, &err) {
            (Parse(line, text), HemlError::Parse { line: got, msg: m, .. }) => {
                assert!(*got > 0, "{file}: no line number: {msg}");
                if line > 0 {
                    assert_eq!(*got, line, "{file}: {msg}");
                }
                assert!(m.contains(text), "{file}: expected '{text}' in: {msg}");
                assert!(msg.contains(&format!(":{got}: ")), "{file}: {msg}");
            }
            (Mesh(text), HemlError::Mesh(m)) => assert!(m.contains(text), "{file}: {msg}"),
            (_, other) => panic!("{file}: unexpected error kind: {other:?}"),
        }
    }
}

/// Deterministic pseudo-random numbers (64-bit LCG, Knuth's constants).
struct Lcg(u64);
impl Lcg {
    fn below(&mut self, n: usize) -> usize {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 33) as usize) % n.max(1)
    }
}

/// Reads `path` with panics caught: Ok or Err are both fine, a panic is not.
fn must_not_panic(path: &Path, what: &str) {
    let r = catch_unwind(AssertUnwindSafe(|| read_mesh_data(path).map(|(d, _)| d.into_mesh())));
    assert!(r.is_ok(), "reader panicked on {what}");
}

#[test]
fn truncated_and_corrupted_files_never_panic() {
    let dir = scratch("fuzz");
    let mesh = box_mesh([1.0, 2.0, 1.5], [2, 2, 1], HexSplit::TwentyFour).unwrap();
    // good inputs: the writers' output in every format and encoding, plus the fixtures
    let mut good: Vec<PathBuf> = Vec::new();
    for f in ["w22.msh", "w41.msh", "w.vtk", "w.mesh", "w.vtu", "w.ply", "wb.ply"] {
        let p = dir.join(format!("good-{f}"));
        if f == "w22.msh" {
            write_mesh_as(&p, &mesh, MeshFormat::Gmsh22).unwrap();
        } else if f == "wb.ply" {
            write_mesh_as(&p, &mesh, MeshFormat::PlyBinary).unwrap();
        } else {
            write_mesh(&p, &mesh).unwrap();
        }
        good.push(p);
    }
    for (k, enc) in [VtuEncoding::Base64Zlib, VtuEncoding::Ascii].into_iter().enumerate() {
        let p = dir.join(format!("good-enc{k}.vtu"));
        write_vtu(&p, &VtuFrame::from_mesh(&mesh).encoding(enc)).unwrap();
        good.push(p);
    }
    write_mesh(&dir.join("good-tg.node"), &mesh).unwrap();
    good.push(dir.join("good-tg.node"));
    good.push(dir.join("good-tg.ele"));
    for f in std::fs::read_dir(data("")).unwrap() {
        let p = f.unwrap().path();
        if p.is_file() && p.extension().is_some_and(|e| e != "py") {
            good.push(p);
        }
    }
    let mut rng = Lcg(0x5eed);
    let mut runs = 0;
    for src in &good {
        let bytes = std::fs::read(src).unwrap();
        let ext = src.extension().unwrap().to_str().unwrap().to_string();
        let stem = src.file_stem().unwrap().to_str().unwrap().to_string();
        // TetGen pairs: damage one file, copy its intact sibling next to it
        let sibling = match ext.as_str() {
            "node" => Some("ele"),
            "ele" => Some("node"),
            _ => None,
        };
        let target = dir.join(format!("cut-{stem}.{ext}"));
        if let Some(s) = sibling {
            std::fs::copy(src.with_extension(s), target.with_extension(s)).unwrap();
        }
        for k in 0..100 {
            let mut b = bytes.clone();
            if k < 50 {
                b.truncate(rng.below(bytes.len()));
            } else {
                // corrupt 1–3 bytes with characters that matter to parsers
                for _ in 0..1 + rng.below(3) {
                    let at = rng.below(b.len());
                    b[at] = b"0 9\n-.e+<>/\"_$#xA=\x00\xff"[rng.below(20)];
                }
            }
            std::fs::write(&target, &b).unwrap();
            must_not_panic(
                &target,
                &format!("{} ({} of {} bytes, case {k})", src.display(), b.len(), bytes.len()),
            );
            runs += 1;
        }
    }
    assert!(runs >= 100 * 20, "only {runs} fuzz cases");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn huge_counts_in_headers_do_not_allocate_or_panic() {
    let dir = scratch("huge");
    let cases = [
        ("a.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n18446744073709551615\n1 0 0 0\n"),
        ("b.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 9999999999999 1 2\n3 1 0 9999999999999\n1\n"),
        ("c.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 6148914691236517206 double\n0 0 0\n"),
        ("d.vtk", "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 99999999999 double\n\0\0\0\0"),
        ("e.mesh", "MeshVersionFormatted 2\nDimension 3\nTriangles 18446744073709551615\n1 2 3 4\n"),
        ("f.node", "99999999999999 3 0 0\n1 0 0 0\n"),
        (
            "g.ply",
            "ply\nformat ascii 1.0\nelement vertex 18446744073709551615\nproperty float x\nproperty float y\n\
             property float z\nend_header\n0 0 0\n",
        ),
        (
            "h.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
             element face 1\nproperty list uint uint vertex_indices\nend_header\n0 0 0\n4294967295 1 2\n",
        ),
    ];
    for (name, text) in cases {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        if name.ends_with(".node") {
            std::fs::write(p.with_extension("ele"), "1 4 0\n1 1 1 1 1\n").unwrap();
        }
        let r = catch_unwind(|| read_mesh(&p));
        assert!(
            matches!(r, Ok(Err(_))),
            "{name}: expected an error, got {:?}",
            r.map(|x| x.map(|m| m.1))
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Physical groups of points, curves and surfaces in files written by Gmsh itself
/// (4.15.2, `make_gmsh_fixtures.py`: a unit cube, 4.1 and 2.2, ASCII and binary)
/// become node sets: named ones by their `$PhysicalNames` name, the others as
/// "surface 7", "point 9". Each holds exactly the nodes on its face, edge or corner
/// (coordinates compared to 1e-12: Gmsh places them on the CAD entities), the same
/// in all four files; the volume group stays the tets' tag.
#[test]
fn gmsh_physical_groups_become_node_sets() {
    let files = [
        ("gmsh_groups_v41.msh", MeshFormat::Gmsh41),
        ("gmsh_groups_b41.msh", MeshFormat::Gmsh41Binary),
        ("gmsh_groups_v22.msh", MeshFormat::Gmsh22),
        ("gmsh_groups_b22.msh", MeshFormat::Gmsh22Binary),
    ];
    let mut first: Option<TetMesh> = None;
    for (file, format) in files {
        let (mesh, report) = read_mesh(&data(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(report.format, format, "{file}");
        assert!(mesh.n_tets() > 10 && mesh.tags().iter().all(|&t| t == 1), "{file}");
        let near = |a: f64, b: f64| (a - b).abs() < 1e-12;
        let on = |test: &dyn Fn(&Vec3) -> bool| -> Vec<usize> {
            (0..mesh.n_nodes()).filter(|&i| test(&mesh.nodes()[i])).collect()
        };
        let expect = BTreeMap::from([
            ("clamp".to_string(), on(&|p| near(p.z, 0.0))),
            ("surface 7".to_string(), on(&|p| near(p.z, 1.0))),
            ("edge".to_string(), on(&|p| near(p.x, 0.0) && near(p.y, 0.0))),
            (
                "point 9".to_string(),
                on(&|p| near(p.x, 1.0) && near(p.y, 1.0) && near(p.z, 1.0)),
            ),
        ]);
        assert!(
            expect["clamp"].len() >= 4 && expect["edge"].len() >= 2,
            "{file}: {expect:?}"
        );
        assert_eq!(expect["point 9"].len(), 1, "{file}");
        assert_eq!(mesh.node_sets(), &expect, "{file}");
        assert_eq!(report.node_sets["clamp"], expect["clamp"].len(), "{file}");
        match &first {
            None => first = Some(mesh),
            Some(m) => {
                // Gmsh prints 16 significant digits in ASCII: the same nodes to round-off
                let gap = m
                    .nodes()
                    .iter()
                    .zip(mesh.nodes())
                    .map(|(p, q)| (p - q).norm())
                    .fold(0.0, f64::max);
                assert!(gap < 1e-15, "{file}: nodes differ by {gap:e}");
                assert_eq!(m.node_sets(), mesh.node_sets(), "{file}");
            }
        }
    }
}

/// Medit boundary references (MMG's and FreeFem++'s face and edge labels) become
/// node sets named as Gmsh's unnamed groups: "surface N" for triangles and
/// quadrilaterals, "curve N" for edges; reference 0 gives none; a boundary vertex
/// out of range is an error at its line.
#[test]
fn medit_boundary_references_become_node_sets() {
    let (mesh, report) = read_mesh(&data("tiny.mesh")).unwrap();
    assert_eq!(
        mesh.node_sets(),
        &BTreeMap::from([("surface 7".to_string(), vec![0, 1, 2])])
    );
    assert_eq!(report.node_sets, BTreeMap::from([("surface 7".to_string(), 3)]));
    let text = "MeshVersionFormatted 2\nDimension 3\nVertices\n5\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n1 1 1 0\n\
                Edges\n2\n1 2 4\n4 5 4\nTriangles\n2\n1 2 3 0\n2 3 5 3\nQuadrilaterals\n1\n1 2 5 4 3\n\
                Tetrahedra\n2\n1 2 3 4 1\n2 3 4 5 2\nEnd\n";
    let dir = scratch("medit-refs");
    let path = dir.join("refs.mesh");
    std::fs::write(&path, text).unwrap();
    let (mesh, _) = read_mesh(&path).unwrap();
    let want = BTreeMap::from([
        ("curve 4".to_string(), vec![0, 1, 3, 4]),
        ("surface 3".to_string(), vec![0, 1, 2, 3, 4]),
    ]);
    assert_eq!(mesh.node_sets(), &want);
    std::fs::write(&path, text.replace("2 3 5 3", "2 3 9 3")).unwrap();
    let e = read_mesh(&path).unwrap_err().to_string();
    assert!(e.contains("refs.mesh:17: vertex number 9 is outside 1..=5"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
