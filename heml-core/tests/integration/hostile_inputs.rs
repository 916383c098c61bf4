//! Regression tests for the faults a hostile but fair user found in the readers and
//! generators (issue 14, items 3–7 and 11): each input here used to be accepted,
//! abort the process or give a misleading error.

use std::path::{Path, PathBuf};

use heml_core::io::read_mesh;
use heml_core::scene::{Compression, Scene};
use heml_core::HemlError;

fn seed(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_seeds")
        .join(name)
}

fn scratch(test: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("hostile-{test}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes `files` (name, text) into a fresh directory and reads the first.
fn read_text(test: &str, files: &[(&str, &str)]) -> HemlError {
    let dir = scratch(test);
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let path = dir.join(files[0].0);
    match read_mesh(&path) {
        Ok((_, report)) => panic!("{test}: accepted: {report}"),
        Err(e) => e,
    }
}

/// The line and message of a parse error naming `file`.
fn parse_error(e: &HemlError, file: &str) -> (usize, String) {
    match e {
        HemlError::Parse { file: f, line, msg } => {
            assert!(f.ends_with(file), "error names {} instead of {file}: {e}", f.display());
            (*line, msg.clone())
        }
        other => panic!("expected a parse error in {file}, got {other}"),
    }
}

const VTU_NO_CELLS: &str = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid">
<UnstructuredGrid>
<Piece NumberOfPoints="1" NumberOfCells="0">
<Points>
<DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0</DataArray>
</Points>
<Cells>
<DataArray type="Int32" Name="connectivity" format="ascii"></DataArray>
<DataArray type="Int32" Name="offsets" format="ascii"></DataArray>
<DataArray type="UInt8" Name="types" format="ascii"></DataArray>
</Cells>
</Piece>
</UnstructuredGrid>
</VTKFile>
"#;

#[test]
fn files_without_a_tet_are_refused_naming_the_file() {
    // every reader accepted these as an empty mesh (`heml info` printed an inverted
    // bounding box, `heml run` wrote empty frames and exited 0)
    for name in ["repro_no_tets.msh", "repro_no_tets.vtk", "repro_no_tets.mesh"] {
        let e = read_mesh(&seed(name)).unwrap_err();
        let (line, msg) = parse_error(&e, name);
        assert!(line > 0 && msg.contains("no tetrahedra"), "{e}");
    }
    let e = read_mesh(&seed("repro_no_tets.msh")).unwrap_err().to_string();
    assert!(e.contains("skipped 1 triangle"), "{e}");
    let e = read_text("no-tets-vtu", &[("empty.vtu", VTU_NO_CELLS)]);
    let (line, msg) = parse_error(&e, "empty.vtu");
    assert!(line == 4 && msg.contains("no tetrahedra"), "{e}");
    let e = read_text(
        "no-tets-tetgen",
        &[
            ("empty.ele", "0 4 0\n"),
            ("empty.node", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"),
        ],
    );
    let (line, msg) = parse_error(&e, "empty.ele");
    assert!(line == 1 && msg.contains("0 tetrahedra"), "{e}");
}

#[test]
fn non_finite_coordinates_are_refused_at_load_with_node_and_line() {
    let e = read_mesh(&seed("repro_nan_coord.msh")).unwrap_err();
    let (line, msg) = parse_error(&e, "repro_nan_coord.msh");
    assert_eq!(line, 8, "{e}");
    assert!(
        msg.contains("node 3") && msg.contains("'nan' is not a finite number"),
        "{e}"
    );
    let e = read_text(
        "inf-tetgen",
        &[
            ("inf.node", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1e400\n"),
            ("inf.ele", "1 4 0\n1 1 2 3 4\n"),
        ],
    );
    let (line, msg) = parse_error(&e, "inf.node");
    assert!(line == 5 && msg.contains("node 4: z coordinate '1e400'"), "{e}");
    let e = read_text(
        "inf-medit",
        &[(
            "inf.mesh",
            "MeshVersionFormatted 2\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 -inf 0 0\n0 0 1 0\nTetrahedra\n1\n1 2 3 4 1\nEnd\n",
        )],
    );
    let (line, msg) = parse_error(&e, "inf.mesh");
    assert!(line == 7 && msg.contains("node 3: y coordinate"), "{e}");
    let e = read_text(
        "nan-vtk",
        &[(
            "nan.vtk",
            "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0\n1 0 0\n0 1 0\n0 0 NaN\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n",
        )],
    );
    let (line, msg) = parse_error(&e, "nan.vtk");
    assert!(line == 9 && msg.contains("node 3: z coordinate NaN"), "{e}");
}

#[test]
fn overflowing_coordinates_are_called_overflow_with_the_tet_id() {
    // ×1e200: the rest volume is NaN and used to pass validation ("volume NaN",
    // "stable dt inf" in `heml info`)
    let e = read_mesh(&seed("repro_coords_1e200.mesh")).unwrap_err().to_string();
    assert!(
        e.contains("repro_coords_1e200.mesh") && e.contains("not finite (overflow") && e.contains("ids 0"),
        "{e}"
    );
}

#[test]
fn record_counts_must_match_their_headers() {
    // TetGen: header `1 4 0` with two tets listed was read as one tet
    let e = read_mesh(&seed("repro_extra_tet.ele")).unwrap_err();
    let (line, msg) = parse_error(&e, "repro_extra_tet.ele");
    assert!(
        line == 3 && msg.contains("after the 1 tetrahedra announced by the header (line 1)"),
        "{e}"
    );
    // … and a .node file with a point too many
    let node = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n";
    let e = read_text("extra-node", &[("x.node", node), ("x.ele", "1 4 0\n1 1 2 3 4\n")]);
    let (line, msg) = parse_error(&e, "x.node");
    assert!(line == 6 && msg.contains("after the 4 points"), "{e}");
    // fewer records than the header says
    let e = read_text(
        "short-ele",
        &[
            ("s.ele", "3 4 0\n1 1 2 3 4\n2 1 2 4 3\n"),
            ("s.node", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"),
        ],
    );
    let (_, msg) = parse_error(&e, "s.ele");
    assert!(msg.contains("announces 3 tetrahedra, the file ends after 2"), "{e}");
    // VTK legacy: a CELL_DATA count that is not the number of cells (its tags were
    // silently dropped)
    let vtk =
        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\n\
               CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\nCELL_DATA 2\nSCALARS tag int 1\nLOOKUP_TABLE default\n7 8\n";
    let e = read_text("cell-data", &[("c.vtk", vtk)]);
    let (line, msg) = parse_error(&e, "c.vtk");
    assert!(
        line == 11 && msg.contains("CELL_DATA announces 2 values but the grid has 1 cells"),
        "{e}"
    );
    // VTK legacy: more point coordinates than POINTS announces
    let vtk = "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\n5 5 5\n\
               CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
    let e = read_text("points", &[("p.vtk", vtk)]);
    let (line, msg) = parse_error(&e, "p.vtk");
    assert!(
        line == 7 && msg.contains("the POINTS section (line 5) holds more values"),
        "{e}"
    );
    // Medit: a vertex more than the count
    let medit = "MeshVersionFormatted 2\nDimension 3\nVertices\n3\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\nTetrahedra\n1\n1 2 3 4 1\nEnd\n";
    let e = read_text("medit", &[("m.mesh", medit)]);
    let (line, msg) = parse_error(&e, "m.mesh");
    assert!(
        line == 8 && msg.contains("the Vertices section (count at line 4) has more records"),
        "{e}"
    );
}

#[test]
fn vtk_ascii_cell_errors_name_the_cell_line() {
    // used to name line 8 (the CELLS header)
    let e = read_mesh(&seed("repro_bad_cell_line.vtk")).unwrap_err();
    let (line, msg) = parse_error(&e, "repro_bad_cell_line.vtk");
    assert!(line == 10 && msg.contains("cell 1 refers to node 9"), "{e}");
    // a bad cell type (13, a wedge) names the CELL_TYPES value's line (14), not the header (12)
    let vtk = "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n0 0 0 1 0 0 0 1 0\n\
               0 0 1 1 1 1\nCELLS 2 10\n4 0 1 2 3\n4 1 2 3 4\nCELL_TYPES 2\n10\n13\n";
    let e = read_text("cell-type", &[("t.vtk", vtk)]);
    let (line, msg) = parse_error(&e, "t.vtk");
    assert!(line == 13 && msg.contains("cell 1 has VTK type 13"), "{e}");
}

#[test]
fn a_huge_generated_scene_mesh_is_refused_with_its_size() {
    // `cells = [2000, 2000, 2000]` aborted: "memory allocation of 192288144024 bytes failed"
    let text = std::fs::read_to_string(seed("repro_huge_box.toml")).unwrap();
    let scene = Scene::from_toml_str(&text, ".").unwrap();
    let e = scene.load_mesh().unwrap_err().to_string();
    assert!(
        e.contains("[mesh]")
            && e.contains("48000000000 tets")
            && e.contains("limit is 50000000 tets")
            && e.contains("max_tets"),
        "{e}"
    );
    // the limit is a scene key
    let small = text.replace("cells = [2000, 2000, 2000] }", "cells = [2, 2, 2], max_tets = 47 }");
    let e = Scene::from_toml_str(&small, ".")
        .unwrap()
        .load_mesh()
        .unwrap_err()
        .to_string();
    assert!(e.contains("48 tets") && e.contains("limit is 47 tets"), "{e}");
    let ok = text.replace("cells = [2000, 2000, 2000] }", "cells = [2, 2, 2], max_tets = 48 }");
    assert_eq!(
        Scene::from_toml_str(&ok, ".").unwrap().load_mesh().unwrap().n_tets(),
        48
    );
}

#[test]
fn output_compression_is_a_scene_key_defaulting_to_zlib() {
    let text = std::fs::read_to_string(seed("repro_huge_box.toml")).unwrap();
    let scene = Scene::from_toml_str(&text, ".").unwrap();
    assert_eq!(scene.output.compression, Compression::Zlib);
    let none = format!("{text}\n[output]\ncompression = \"none\"\n");
    assert_eq!(
        Scene::from_toml_str(&none, ".").unwrap().output.compression,
        Compression::None
    );
    let bad = format!("{text}\n[output]\ncompression = \"lz4\"\n");
    let e = Scene::from_toml_str(&bad, ".").unwrap_err().to_string();
    assert!(e.contains("lz4") && e.contains("zlib"), "{e}");
}

/// Only regular files are read: a pipe named like a mesh or a scene blocked the
/// reader forever, and a link to `/dev/zero` was read until the memory ran out.
#[cfg(unix)]
#[test]
fn pipes_and_devices_are_refused_not_read() {
    let dir = std::env::temp_dir().join(format!("heml-nonregular-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let zero = dir.join("zero.msh");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let e = heml_core::io::read_mesh(&zero).unwrap_err().to_string();
    assert!(e.contains("zero.msh") && e.contains("not a regular file"), "{e}");
    let fifo = dir.join("pipe.vtu");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        // opening a pipe for reading blocks until a writer comes: open it for
        // writing too from another thread, so that a refusal is what ends the test
        let writer = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::OpenOptions::new().write(true).open(&fifo).map(drop))
        };
        let e = heml_core::io::read_mesh(&fifo).unwrap_err().to_string();
        assert!(e.contains("pipe.vtu") && e.contains("not a regular file"), "{e}");
        writer.join().unwrap().unwrap();
        let e = heml_core::scene::Scene::from_file(&zero).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// VTU header hostility: a UTF-8 byte-order mark is allowed (meshio reads such
/// files; the data slices were off by its three bytes), an unknown or repeated
/// `byte_order` is refused (the first value was used), and so is an element with
/// more attributes than VTK ever writes (100 000 took 73 s to check).
#[test]
fn vtu_headers_are_read_strictly() {
    use heml_core::mesh::generate::{box_mesh, HexSplit};
    let dir = scratch("vtu_headers");
    let path = dir.join("cube.vtu");
    let cube = box_mesh([1.0, 1.0, 1.0], [2, 2, 2], HexSplit::Six).unwrap();
    heml_core::io::write_mesh(&path, &cube).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("byte_order=\"LittleEndian\""), "{}", &text[..200]);
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let bom = [b"\xEF\xBB\xBF".as_slice(), text.as_bytes()].concat();
    let read = read_mesh(&write("bom.vtu", &bom)).unwrap().0;
    assert_eq!((read.n_nodes(), read.n_tets()), (cube.n_nodes(), cube.n_tets()));
    let middle = text.replace("byte_order=\"LittleEndian\"", "byte_order=\"Middle\"");
    let e = read_mesh(&write("middle.vtu", middle.as_bytes()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("middle.vtu") && e.contains("byte_order 'Middle'"), "{e}");
    let twice = text.replace(
        "byte_order=\"LittleEndian\"",
        "byte_order=\"LittleEndian\" byte_order=\"BigEndian\"",
    );
    let e = read_mesh(&write("twice.vtu", twice.as_bytes()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("twice.vtu") && e.contains("bad attribute"), "{e}");
    let many: String = (0..65).map(|i| format!(" a{i}=\"x\"")).collect();
    let crowded = text.replacen("<VTKFile", &format!("<VTKFile{many}"), 1);
    let e = read_mesh(&write("crowded.vtu", crowded.as_bytes()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("more than 64 attributes"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A mesh `file` the readers refuse before parsing (a directory, an unknown
/// extension) is named with the scene's key and line, not only by its path.
#[test]
fn refused_mesh_files_name_the_scene_key() {
    let dir = scratch("scene_mesh_file");
    std::fs::create_dir_all(dir.join("folder.msh")).unwrap();
    for (file, why) in [
        ("folder.msh", "not a regular file"),
        ("mesh.obj", "unknown mesh extension"),
    ] {
        std::fs::write(dir.join("mesh.obj"), "v 0 0 0\n").unwrap();
        let text =
            format!("[mesh]\nfile = \"{file}\"\n[[material]]\nlaw = \"x\"\nparams = {{}}\n[solver]\nduration = 1.0\n");
        let e = Scene::from_toml_str(&text, &dir)
            .unwrap()
            .build()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("[mesh]") && e.contains(&format!("file = \"{file}\"")) && e.contains(why),
            "{e}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A Gmsh 4.1 node block's entity dimension and parametric flag take only their
/// valid values (a flag of 2 was read as 0, a dimension of −7 clamped).
#[test]
fn gmsh_node_block_headers_are_checked() {
    let mesh = |block: &str| {
        format!(
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n{block}\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n\
             $Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n"
        )
    };
    let dir = scratch("gmsh_block_headers");
    std::fs::write(dir.join("ok.msh"), mesh("3 1 0 4")).unwrap();
    assert_eq!(read_mesh(&dir.join("ok.msh")).unwrap().0.n_tets(), 1);
    for (block, what) in [("3 1 2 4", "parametric flag 2"), ("-7 1 0 4", "entity dimension -7")] {
        let e = read_text("gmsh_block_headers_bad", &[("bad.msh", &mesh(block))]);
        let (line, msg) = parse_error(&e, "bad.msh");
        assert!(line == 6 && msg.contains(what), "{line}: {msg}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
