//! Element and cell types the readers skip, and the ones they refuse (QA D4, D6):
//! only types known to be points, lines or surfaces may be skipped; a volume other
//! than the linear tet and hex, or a number outside the format's table, is an error
//! naming the file, the line (or byte) and the type, since dropping it would remove
//! material from the body without a word. Also the line named for a short Gmsh node
//! line and the range named for a TetGen corner that is not a point.

use std::path::{Path, PathBuf};

use heml_core::io::{gmsh, read_mesh, tetgen, vtk_legacy, vtu, MeshData};
use heml_core::HemlError;

/// Gmsh types of dimension 0, 1 and 2 (GmshDefines.h and Gmsh's
/// `ElementType::getDimension`): the only ones besides 4 and 5 that may be read.
const GMSH_SURFACE_OR_LOWER: &[i64] = &[
    15, 133, // points
    1, 8, 26, 27, 28, 62, 63, 64, 65, 66, 67, 70, 84, 134, // lines
    2, 9, 20, 21, 22, 23, 24, 25, 42, 43, 44, 45, 46, 52, 53, 54, 55, 56, 68, 85, 135, 138, // triangles
    3, 10, 16, 36, 37, 38, 39, 40, 41, 47, 48, 49, 50, 51, 57, 58, 59, 60, 61, 86, // quadrangles
    34, 69, // polygons
];

/// VTK cell types that are not volumes (vtkCellType.h): empty, vertices, lines,
/// triangles, polygons, quads, of every order.
const VTK_SURFACE_OR_LOWER: &[i64] = &[
    0, 1, 2, 3, 4, 21, 35, 51, 60, 68, 75, 5, 6, 7, 22, 34, 36, 52, 53, 61, 63, 69, 76, 8, 9, 23, 28, 30, 54, 62, 70,
    77,
];

fn path(name: &str) -> PathBuf {
    PathBuf::from(format!("/inline/{name}"))
}

/// The line and message of a parse error, checking that it names `file`.
fn parse_error(e: HemlError, file: &str) -> (usize, String) {
    let text = e.to_string();
    assert!(text.contains(file), "the error does not name {file}: {text}");
    match e {
        HemlError::Parse { line, msg, .. } => (line, msg),
        other => panic!("not a parse error: {other:?}"),
    }
}

/// A Gmsh 2.2 file: two tets, then one element of type `ty` on line 16 (its node
/// list is a plausible one: the readers refuse a volume before reading nodes).
fn gmsh22(ty: i64) -> String {
    format!(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n$EndNodes\n\
         $Elements\n3\n1 4 2 1 1 1 2 3 4\n2 4 2 1 1 2 3 4 5\n3 {ty} 2 1 1 1 2 3\n$EndElements\n"
    )
}

#[test]
fn gmsh_skips_only_points_lines_and_surfaces_and_refuses_every_other_type() {
    let mut types: Vec<i64> = (0..=141).collect();
    types.extend([-1, 200, 999, i64::from(i32::MAX)]);
    for ty in types {
        if ty == 4 || ty == 5 {
            continue;
        }
        let name = format!("type_{ty}.msh");
        let result = gmsh::parse(&path(&name), gmsh22(ty).as_bytes());
        if GMSH_SURFACE_OR_LOWER.contains(&ty) {
            let (data, _) = result.unwrap_or_else(|e| panic!("type {ty} is a point, line or surface: {e}"));
            assert_eq!(data.tets.len(), 2, "type {ty}");
            assert_eq!(data.skipped.values().sum::<usize>(), 1, "type {ty}: {:?}", data.skipped);
            assert!(!data.skipped.contains_key("other"), "type {ty}: {:?}", data.skipped);
        } else {
            let e = result.expect_err(&format!("type {ty} is a volume or unknown, yet was read"));
            let (line, msg) = parse_error(e, &name);
            assert_eq!(line, 16, "type {ty}: {msg}");
            assert!(msg.contains(&format!("element type {ty} ")), "type {ty}: {msg}");
            assert!(
                msg.contains("only linear tetrahedra (type 4) and linear hexahedra (type 5"),
                "type {ty}: {msg}"
            );
        }
    }
    // the names of what is skipped
    let (data, _) = gmsh::parse(&path("t.msh"), gmsh22(66).as_bytes()).unwrap();
    assert_eq!(data.skipped.get("line"), Some(&1));
    let (data, _) = gmsh::parse(&path("t.msh"), gmsh22(138).as_bytes()).unwrap();
    assert_eq!(data.skipped.get("triangle"), Some(&1));
    let e = gmsh::parse(&path("t.msh"), gmsh22(35).as_bytes())
        .unwrap_err()
        .to_string();
    assert!(e.contains("polyhedron"), "{e}");
    let e = gmsh::parse(&path("t.msh"), gmsh22(999).as_bytes())
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a Gmsh element type"), "{e}");
}

#[test]
fn gmsh41_refuses_a_volume_block_at_its_header_line() {
    let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n\
                0 0 1\n$EndNodes\n$Elements\n2 2 1 2\n3 1 4 1\n1 1 2 3 4\n3 1 118 1\n2 1 2 3 4\n$EndElements\n";
    let (line, msg) = parse_error(gmsh::parse(&path("v41.msh"), text.as_bytes()).unwrap_err(), "v41.msh");
    assert_eq!(line, 20, "{msg}");
    assert!(msg.contains("element type 118 (pyramid)"), "{msg}");
}

/// Gmsh 4.1 node blocks list the tags, then one coordinate line per node: a line
/// short of a number or with one too many is reported at that line, in plain and
/// parametric blocks (line 11 holds node 1's coordinates).
#[test]
fn a_gmsh41_coordinate_line_short_or_long_is_reported_at_that_line() {
    let nodes = |block: &str, coords: [&str; 4]| {
        format!(
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n{block}\n1\n2\n3\n4\n{}\n$EndNodes\n\
             $Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n",
            coords.join("\n")
        )
    };
    let good = ["0 0 0", "1 0 0", "0 1 0", "0 0 1"];
    assert!(gmsh::parse(&path("v41.msh"), nodes("3 1 0 4", good).as_bytes()).is_ok());
    let error = |text: String| parse_error(gmsh::parse(&path("v41.msh"), text.as_bytes()).unwrap_err(), "v41.msh");
    // node 2 loses its z: before, its z was node 3's x, and the error came nowhere
    // near (or, with one more node line, not at all)
    let (line, msg) = error(nodes("3 1 0 4", ["0 0 0", "1 0", "0 1 0", "0 0 1"]));
    assert_eq!(line, 12, "{msg}");
    assert!(
        msg.contains("node 2: the line ends after 2 of the 3 coordinates; a node line is 'x y z'"),
        "{msg}"
    );
    let (line, msg) = error(nodes("3 1 0 4", ["0 0 0", "1 0 0", "0 1 0 5", "0 0 1"]));
    assert_eq!(line, 13, "{msg}");
    assert!(msg.contains("node 3: '5' follows the 3 coordinates"), "{msg}");
    // a parametric surface block (dimension 2): x y z u v per line
    let param = ["0 0 0 0 0", "1 0 0 1 0", "0 1 0 0 1", "0 0 1 1 1"];
    assert!(gmsh::parse(&path("v41.msh"), nodes("2 1 1 4", param).as_bytes()).is_ok());
    let (line, msg) = error(nodes("2 1 1 4", ["0 0 0 0 0", "1 0 0 1", "0 1 0 0 1", "0 0 1 1 1"]));
    assert_eq!(line, 12, "{msg}");
    assert!(
        msg.contains(
            "node 2: the line ends after 3 + 1 of its 3 + 2 numbers; a node line of this block is 'x y z u v'"
        ),
        "{msg}"
    );
    let (line, msg) = error(nodes("2 1 1 4", ["0 0 0 0 0 9", "1 0 0 1 0", "0 1 0 0 1", "0 0 1 1 1"]));
    assert_eq!(line, 11, "{msg}");
    assert!(
        msg.contains("node 1: '9' follows the node's numbers; a node line is 'x y z u v'"),
        "{msg}"
    );
}

/// Gmsh 4.1 node blocks list one tag per line: a tag line holding two numbers, or a
/// block short of a tag (its first coordinate line `0 0 0` would read as three more
/// tags), is reported at that line (the tags are lines 7-10).
#[test]
fn a_gmsh41_node_tag_line_with_more_than_a_tag_is_reported_at_that_line() {
    let text = |tags: &str, coords: &str| {
        format!(
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n{tags}\n{coords}\n$EndNodes\n\
             $Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n"
        )
    };
    let coords = "0 0 0\n1 0 0\n0 1 0\n0 0 1";
    let error = |t: String| parse_error(gmsh::parse(&path("v41.msh"), t.as_bytes()).unwrap_err(), "v41.msh");
    assert!(gmsh::parse(&path("v41.msh"), text("1\n2\n3\n4", coords).as_bytes()).is_ok());
    let (line, msg) = error(text("1\n2 3\n4", coords));
    assert_eq!(line, 8, "{msg}");
    assert!(
        msg.contains("'3' follows node tag 2 (tag 2 of 4 in its block); a node block lists one tag per line"),
        "{msg}"
    );
    // three tag lines for four nodes: the first coordinate line is not a tag line
    let (line, msg) = error(text("1\n2\n3", coords));
    assert_eq!(line, 10, "{msg}");
    assert!(msg.contains("'0' follows node tag 0 (tag 4 of 4"), "{msg}");
}

/// A little-endian binary Gmsh 2.2 file: two tets, then a block of one element of
/// type `ty` with `nn` nodes.
fn gmsh22_binary(ty: i32, nn: usize) -> Vec<u8> {
    let mut b = b"$MeshFormat\n2.2 1 8\n".to_vec();
    b.extend(1i32.to_le_bytes());
    b.extend(b"\n$EndMeshFormat\n$Nodes\n5\n");
    for (tag, p) in [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ]
    .iter()
    .enumerate()
    {
        b.extend((tag as i32 + 1).to_le_bytes());
        p.iter().for_each(|x: &f64| b.extend(x.to_le_bytes()));
    }
    b.extend(b"\n$EndNodes\n$Elements\n3\n");
    let ints = |b: &mut Vec<u8>, v: &[i32]| v.iter().for_each(|x| b.extend(x.to_le_bytes()));
    ints(&mut b, &[4, 2, 0, 1, 1, 2, 3, 4, 2, 2, 3, 4, 5]);
    ints(&mut b, &[ty, 1, 0, 3]);
    ints(&mut b, &vec![1; nn]);
    b.extend(b"\n$EndElements\n");
    b
}

#[test]
fn binary_gmsh_skips_a_high_order_line_and_refuses_a_volume_at_its_byte() {
    // LIN_5 (27): 5 nodes, a line; skipped
    let (data, _) = gmsh::parse(&path("b.msh"), &gmsh22_binary(27, 5)).unwrap();
    assert_eq!((data.tets.len(), data.skipped.get("line")), (2, Some(&1)));
    // HEX_216 (94): refused before its node count is needed
    let e = gmsh::parse(&path("b.msh"), &gmsh22_binary(94, 216))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.msh") && e.contains("at byte") && e.contains("element type 94 (hexahedron"),
        "{e}"
    );
    let e = gmsh::parse(&path("b.msh"), &gmsh22_binary(999, 4))
        .unwrap_err()
        .to_string();
    assert!(e.contains("element type 999 is not a Gmsh element type"), "{e}");
}

/// A legacy VTK file: two tets and a cell of type `ty` (the last line, 18).
fn vtk(ty: i64) -> String {
    format!(
        "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n0 0 0\n1 0 0\n0 1 0\n\
         0 0 1\n1 1 1\nCELLS 3 13\n4 0 1 2 3\n4 1 2 3 4\n2 0 1\nCELL_TYPES 3\n10\n10\n{ty}\n"
    )
}

#[test]
fn vtk_skips_only_vertices_lines_and_surfaces_and_refuses_every_other_type() {
    let mut types: Vec<i64> = (0..=82).collect();
    types.extend([-1, 200, 300, 999]);
    for ty in types {
        if [10, 11, 12].contains(&ty) {
            continue;
        }
        let name = format!("type_{ty}.vtk");
        let result = vtk_legacy::parse(&path(&name), vtk(ty).as_bytes());
        if VTK_SURFACE_OR_LOWER.contains(&ty) {
            let data: MeshData = result.unwrap_or_else(|e| panic!("type {ty} is not a volume: {e}"));
            assert_eq!(data.tets.len(), 2, "type {ty}");
            assert_eq!(data.skipped.values().sum::<usize>(), 1, "type {ty}: {:?}", data.skipped);
        } else {
            let e = result.expect_err(&format!("type {ty} is a volume or unknown, yet was read"));
            let (line, msg) = parse_error(e, &name);
            assert_eq!(line, 18, "type {ty}: {msg}");
            assert!(msg.contains(&format!("cell 2 has VTK type {ty}")), "type {ty}: {msg}");
            assert!(msg.contains("only linear tetrahedra (type 10)"), "type {ty}: {msg}");
        }
    }
}

#[test]
fn vtu_refuses_an_unknown_cell_type() {
    let text =
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n\
<UnstructuredGrid>\n<Piece NumberOfPoints=\"5\" NumberOfCells=\"2\">\n<Points>\n\
<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 0 0 1 1 1 1</DataArray>\n\
</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2 3 1 2 3 4</DataArray>\n\
<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">4 8</DataArray>\n\
<DataArray type=\"Int32\" Name=\"types\" format=\"ascii\">10 300</DataArray>\n</Cells>\n</Piece>\n\
</UnstructuredGrid>\n</VTKFile>\n";
    let (line, msg) = parse_error(vtu::parse(&path("u.vtu"), text.as_bytes()).unwrap_err(), "u.vtu");
    assert_eq!(line, 11, "{msg}");
    assert!(
        msg.contains("cell 1 has VTK type 300, which is not a VTK cell type"),
        "{msg}"
    );
}

#[test]
fn a_gmsh_node_line_short_of_a_coordinate_is_reported_at_that_line() {
    let good = gmsh22(2);
    // node 2 loses its z: the error is at line 7, not where the shifted tokens collide
    let short = good.replace("2 1 0 0\n", "2 1 0\n");
    let (line, msg) = parse_error(gmsh::parse(&path("s.msh"), short.as_bytes()).unwrap_err(), "s.msh");
    assert_eq!(line, 7, "{msg}");
    assert!(
        msg.contains("node 2: the line ends after 2 of the 3 coordinates"),
        "{msg}"
    );
    // the last node, with the section's end on the next line
    let short = good.replace("5 1 1 1\n", "5 1 1\n");
    let (line, msg) = parse_error(gmsh::parse(&path("s.msh"), short.as_bytes()).unwrap_err(), "s.msh");
    assert_eq!((line, msg.contains("node 5")), (10, true), "{msg}");
    // a fourth number
    let long = good.replace("3 0 1 0\n", "3 0 1 0 7\n");
    let (line, msg) = parse_error(gmsh::parse(&path("s.msh"), long.as_bytes()).unwrap_err(), "s.msh");
    assert_eq!(line, 8, "{msg}");
    assert!(msg.contains("node 3: '7' follows the 3 coordinates"), "{msg}");
    // Gmsh 1 ($NOD) node lines are read the same way
    let v1 = "$NOD\n4\n1 0 0 0\n2 1 0\n3 0 1 0\n4 0 0 1\n$ENDNOD\n$ELM\n1\n1 4 1 1 4 1 2 3 4\n$ENDELM\n";
    let (line, _) = parse_error(gmsh::parse(&path("v1.msh"), v1.as_bytes()).unwrap_err(), "v1.msh");
    assert_eq!(line, 4);
    // and CRLF line ends do not count as content
    assert!(gmsh::parse(&path("crlf.msh"), good.replace('\n', "\r\n").as_bytes()).is_ok());
}

#[test]
fn a_tetgen_corner_outside_the_points_names_the_valid_range() {
    let node = "5 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n";
    let ele = "1 4 0\n1 1 2 3 6\n";
    let (nodes, first) = tetgen::parse_node(Path::new("m.node"), node.as_bytes()).unwrap();
    let e = tetgen::parse_ele(Path::new("m.ele"), ele.as_bytes(), first, nodes.len()).unwrap_err();
    let (line, msg) = parse_error(e, "m.ele");
    assert_eq!(line, 2);
    assert!(
        msg.contains("point number 6 is outside 1..=5 (the .node file has 5 point(s), numbered from 1)"),
        "{msg}"
    );
    // numbered from 0, the last valid number is 4
    let node0 = node.replace(
        "\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 ",
        "\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 ",
    );
    let (nodes, first) = tetgen::parse_node(Path::new("m.node"), node0.as_bytes()).unwrap();
    let ele0 = "1 4 0\n1 0 1 2 5\n";
    let msg = tetgen::parse_ele(Path::new("m.ele"), ele0.as_bytes(), first, nodes.len())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("point number 5 is outside 0..=4"), "{msg}");
}

/// The QA reproductions, read from disk as a user would (through `read_mesh`).
#[test]
fn files_on_disk_with_a_volume_type_are_refused_through_read_mesh() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("element-types");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("prism.msh");
    std::fs::write(&p, gmsh22(6)).unwrap();
    let e = read_mesh(&p).unwrap_err().to_string();
    assert!(
        e.contains("prism.msh:16:") && e.contains("element type 6 (prism)"),
        "{e}"
    );
}
