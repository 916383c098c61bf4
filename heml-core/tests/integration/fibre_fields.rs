//! Fibre directions as 3-component cell data of legacy VTK files (`VECTORS`,
//! `FIELD` arrays; ASCII and binary) and Gmsh `$ElementData` (2.2 and 4.1, ASCII
//! and binary): files written by meshio and by hand read to the written vectors,
//! kept per tet through the hexahedron split; defects (zero, non-finite, missing
//! element, wrong component count) are noted with the element the file names.
//!
//! The meshio test skips when `python3` cannot import meshio (CI installs it).

use std::path::{Path, PathBuf};
use std::process::Command;

use heml_core::io::{read_mesh, read_mesh_data, MeshData};
use heml_core::Vec3;

fn scratch(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("heml-fibre-fields-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The tets, surface triangle and hexahedron of every test file: two tets at
/// the bottom, a unit cube on top (nodes 3, 5, 4, 6 below, 8..11 above).
const POINTS: [[f64; 3]; 12] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 1.0, 1.0],
    [1.0, 0.0, 1.0],
    [0.0, 1.0, 1.0],
    [1.0, 1.0, 0.0],
    [0.0, 0.0, 2.0],
    [1.0, 0.0, 2.0],
    [1.0, 1.0, 2.0],
    [0.0, 1.0, 2.0],
];
const TETS: [[usize; 4]; 2] = [[0, 1, 2, 3], [1, 7, 2, 4]];
const HEX: [usize; 8] = [3, 5, 4, 6, 8, 9, 10, 11];
/// The directions of the two tets and of the hexahedron (not unit: the reader
/// keeps what the file says; `Fibres` normalises).
const TET_DIRS: [[f64; 3]; 2] = [[1.0, 2.0, 3.0], [4.0, 5.0, -6.5e-3]];
const HEX_DIR: [f64; 3] = [7.0, 8.0, 9.0];

/// The cell vectors a reader must find: the tets' (a triangle's value is
/// ignored), the hexahedron's for its tets.
fn assert_fibres(d: &MeshData, what: &str) {
    assert_eq!(d.tets, TETS.to_vec(), "{what}");
    assert_eq!(d.hexes, vec![HEX], "{what}");
    let v = |a: [f64; 3]| Vec3::from(a);
    assert_eq!(d.cell_vectors.get("fibres"), Some(&TET_DIRS.map(v).to_vec()), "{what}");
    assert_eq!(d.hex_vectors.get("fibres"), Some(&vec![v(HEX_DIR)]), "{what}");
    assert!(d.vector_defects.is_empty(), "{what}: {:?}", d.vector_defects);
}

const MESHIO: &str = r#"
import sys, meshio, numpy as np
pts = np.array(PTS, float)
cells = [("tetra", np.array(TETS)), ("triangle", np.array([[0, 1, 2]])), ("hexahedron", np.array([HEX]))]
fib = [np.array(TDIRS, float), np.array([[0.0, 0.0, 0.0]]), np.array([HDIR], float)]
tags = [np.array([1, 1]), np.array([2]), np.array([3])]
d = sys.argv[1]
m = meshio.Mesh(pts, cells, cell_data={"fibres": fib})
meshio.write(d + "/ascii.vtk", m, file_format="vtk", binary=False)
meshio.write(d + "/binary.vtk", m, file_format="vtk", binary=True)
m = meshio.Mesh(pts, cells, cell_data={"fibres": fib, "gmsh:physical": tags, "gmsh:geometrical": tags},
                point_data={"gmsh:dim_tags": np.array([[3, 1]] * len(pts))})
meshio.write(d + "/b22.msh", m, file_format="gmsh22", binary=True)
meshio.write(d + "/b41.msh", m, file_format="gmsh", binary=True)
"#;

/// meshio's legacy VTK (a `FIELD` array, ASCII and binary) and binary Gmsh 2.2
/// and 4.1 (`$ElementData`). (meshio 5.3 with NumPy 2 writes ASCII
/// `$ElementData` values as `np.float64(1.0)`: the hand-made files below cover
/// ASCII Gmsh.)
#[test]
fn meshio_files_give_their_cell_vectors() {
    match Command::new("python3").args(["-c", "import meshio"]).output() {
        Ok(o) if o.status.success() => {}
        _ => {
            println!("SKIPPED meshio_files_give_their_cell_vectors: python3 cannot import meshio");
            return;
        }
    }
    let dir = scratch("meshio");
    let script = MESHIO
        .replace("PTS", &format!("{POINTS:?}"))
        .replace("TETS", &format!("{TETS:?}"))
        .replace("HEX", &format!("{HEX:?}"))
        .replace("TDIRS", &format!("{TET_DIRS:?}"))
        .replace("HDIR", &format!("{HEX_DIR:?}"));
    let out = Command::new("python3")
        .args(["-c", &script, dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for f in ["ascii.vtk", "binary.vtk", "b22.msh", "b41.msh"] {
        let (d, _) = read_mesh_data(&dir.join(f)).unwrap();
        assert_fibres(&d, f);
    }
    // through the hexahedron split (six tets) and validation: one vector per tet
    let (mesh, _) = read_mesh(&dir.join("b41.msh")).unwrap();
    let mut want: Vec<Vec3> = TET_DIRS.map(Vec3::from).to_vec();
    want.extend([Vec3::from(HEX_DIR); 6]);
    assert_eq!(mesh.cell_vectors().get("fibres"), Some(&want));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A Gmsh file by hand: version `v` ("2.2" or "4.1") with the `$ElementData`
/// block `data` (its lines after the name: tags and records).
fn gmsh_file(v: &str, data: &str) -> String {
    let mut s = format!("$MeshFormat\n{v} 0 8\n$EndMeshFormat\n");
    if v == "2.2" {
        s += "$Nodes\n12\n";
        for (i, p) in POINTS.iter().enumerate() {
            s += &format!("{} {} {} {}\n", i + 1, p[0], p[1], p[2]);
        }
        s += "$EndNodes\n$Elements\n4\n";
        s += &format!("11 4 2 1 1 {}\n", one_based(&TETS[0]));
        s += &format!("12 4 2 1 1 {}\n", one_based(&TETS[1]));
        s += "13 2 2 2 2 1 2 3\n";
        s += &format!("14 5 2 1 1 {}\n", one_based(&HEX));
    } else {
        s += "$Nodes\n1 12 1 12\n3 1 0 12\n";
        for i in 1..=12 {
            s += &format!("{i}\n");
        }
        for p in &POINTS {
            s += &format!("{} {} {}\n", p[0], p[1], p[2]);
        }
        s += "$EndNodes\n$Elements\n3 4 11 14\n3 1 4 2\n";
        s += &format!("11 {}\n12 {}\n", one_based(&TETS[0]), one_based(&TETS[1]));
        s += "2 1 2 1\n13 1 2 3\n3 1 5 1\n";
        s += &format!("14 {}\n", one_based(&HEX));
    }
    s + "$EndElements\n$ElementData\n1\n\"fibres\"\n1\n0.0\n" + data + "$EndElementData\n"
}

fn one_based(nodes: &[usize]) -> String {
    nodes.iter().map(|n| (n + 1).to_string()).collect::<Vec<_>>().join(" ")
}

fn parse_msh(dir: &Path, name: &str, text: &str) -> MeshData {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    read_mesh_data(&path).unwrap().0
}

/// Hand-made ASCII Gmsh 2.2 and 4.1 files (element numbers 11..14, the 4.1 block
/// with the partition tag, records in another order than the elements), and the
/// defects: a zero or non-finite vector, an element without a value, one
/// component.
#[test]
fn hand_made_gmsh_element_data_and_its_defects() {
    let dir = scratch("gmsh");
    let rec = |id: u32, a: [f64; 3]| format!("{id} {:?} {:?} {:?}\n", a[0], a[1], a[2]);
    let records = rec(14, HEX_DIR) + &rec(12, TET_DIRS[1]) + &rec(13, [0.0; 3]) + &rec(11, TET_DIRS[0]);
    assert_fibres(
        &parse_msh(&dir, "a.msh", &gmsh_file("2.2", &format!("3\n0\n3\n4\n{records}"))),
        "2.2",
    );
    assert_fibres(
        &parse_msh(&dir, "b.msh", &gmsh_file("4.1", &format!("4\n0\n3\n4\n0\n{records}"))),
        "4.1",
    );

    let defect = |data: &str| {
        let d = parse_msh(&dir, "c.msh", &gmsh_file("2.2", data));
        (
            d.vector_defects.get("fibres").cloned().unwrap_or_default(),
            d.cell_vectors.contains_key("fibres"),
        )
    };
    let zero = rec(11, [0.0; 3]) + &rec(12, TET_DIRS[1]) + &rec(14, HEX_DIR);
    let (why, kept) = defect(&format!("3\n0\n3\n3\n{zero}"));
    assert!(why.contains("element 11: the vector is zero") && kept, "{why}");
    let nan = "11 1 NaN 0\n".to_string() + &rec(12, TET_DIRS[1]) + &rec(14, HEX_DIR);
    let (why, _) = defect(&format!("3\n0\n3\n3\n{nan}"));
    assert!(why.contains("element 11: (1, NaN, 0) is not finite"), "{why}");
    let missing = rec(11, TET_DIRS[0]) + &rec(14, HEX_DIR);
    let (why, kept) = defect(&format!("3\n0\n3\n2\n{missing}"));
    assert!(
        why.contains("element 12 (a tetrahedron) has no value") && !kept,
        "{why}"
    );
    let (why, kept) = defect("3\n0\n1\n3\n11 1.0\n12 2.0\n14 3.0\n");
    assert!(why.contains("1 component(s)") && !kept, "{why}");

    // a record missing at the end of the block is a parse error naming the line
    let path = dir.join("d.msh");
    std::fs::write(&path, gmsh_file("2.2", &format!("3\n0\n3\n5\n{records}"))).unwrap();
    let e = read_mesh_data(&path).unwrap_err().to_string();
    assert!(e.contains("d.msh") && e.contains("fibres"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A hand-made legacy VTK file with the fibres as `VECTORS` (ASCII), and the same
/// as big-endian binary; a zero vector is noted with its cell.
#[test]
fn hand_made_vtk_vectors_ascii_and_binary() {
    let dir = scratch("vtk");
    let vtk = |binary: bool, dirs: &[[f64; 3]; 4]| -> Vec<u8> {
        let mut s: Vec<u8> = format!(
            "# vtk DataFile Version 4.2\nfibres\n{}\nDATASET UNSTRUCTURED_GRID\nPOINTS 12 double\n",
            if binary { "BINARY" } else { "ASCII" }
        )
        .into_bytes();
        let num = |s: &mut Vec<u8>, x: f64| {
            if binary {
                s.extend(x.to_be_bytes());
            } else {
                s.extend(format!("{x:?} ").bytes());
            }
        };
        let int = |s: &mut Vec<u8>, x: i32| {
            if binary {
                s.extend(x.to_be_bytes());
            } else {
                s.extend(format!("{x} ").bytes());
            }
        };
        for p in &POINTS {
            p.iter().for_each(|&x| num(&mut s, x));
        }
        s.extend(b"\nCELLS 4 23\n");
        for c in [&TETS[0][..], &TETS[1][..], &[0, 1, 2], &HEX[..]] {
            int(&mut s, c.len() as i32);
            c.iter().for_each(|&n| int(&mut s, n as i32));
        }
        s.extend(b"\nCELL_TYPES 4\n");
        [10, 10, 5, 12].into_iter().for_each(|t| int(&mut s, t));
        s.extend(b"\nCELL_DATA 4\nVECTORS fibres double\n");
        for d in dirs {
            d.iter().for_each(|&x| num(&mut s, x));
        }
        s.push(b'\n');
        s
    };
    let dirs = [TET_DIRS[0], TET_DIRS[1], [0.0; 3], HEX_DIR];
    for binary in [false, true] {
        let path = dir.join(format!("m{binary}.vtk"));
        std::fs::write(&path, vtk(binary, &dirs)).unwrap();
        assert_fibres(&read_mesh_data(&path).unwrap().0, &format!("binary {binary}"));
    }
    let path = dir.join("zero.vtk");
    std::fs::write(&path, vtk(false, &[TET_DIRS[0], [0.0; 3], [0.0; 3], HEX_DIR])).unwrap();
    let d = read_mesh_data(&path).unwrap().0;
    assert_eq!(
        d.vector_defects.get("fibres").map(String::as_str),
        Some("cell 1: the vector is zero")
    );
    let _ = std::fs::remove_dir_all(&dir);
}
