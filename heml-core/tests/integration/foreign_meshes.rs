//! Mesh files written by other tools, read to the same nodes and tets as the
//! reference reading: meshio's defaults (binary Gmsh 2.2 and 4.1, VTU with each
//! compressor), big-endian binary Gmsh, and SOFA's Gmsh 1 meshes. Also the errors
//! for damaged binary and Gmsh 1 data (precise, never a panic or a huge
//! allocation).
//!
//! Tests that need `../shared/meshes` or a `python3` with meshio say so and skip
//! when they are absent; CI has both (`.ci/run` installs meshio).

use std::path::{Path, PathBuf};
use std::process::Command;

use heml_core::io::{gmsh, read_mesh, read_mesh_data, MeshData, MeshFormat};
use heml_core::HemlError;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

/// A fresh scratch directory for one test.
fn scratch(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("heml-foreign-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn shared_meshes(test: &str) -> Option<PathBuf> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/meshes")).to_path_buf();
    if dir.join("README.md").is_file() {
        Some(dir)
    } else {
        println!(
            "SKIPPED {test}: ../shared/meshes not found (looked in {})",
            dir.display()
        );
        None
    }
}

fn python_with_meshio(test: &str) -> bool {
    match Command::new("python3").args(["-c", "import meshio"]).output() {
        Err(e) => {
            println!("SKIPPED {test}: python3 not runnable ({e})");
            false
        }
        Ok(o) if !o.status.success() => {
            println!("SKIPPED {test}: python3 cannot import meshio (pip install meshio)");
            false
        }
        Ok(_) => true,
    }
}

/// Nodes compared bit for bit (f64 data written by every tool in full), tets
/// exactly (same numbering, same order).
fn assert_same_data(a: &MeshData, b: &MeshData, what: &str) {
    assert_eq!(a.nodes.len(), b.nodes.len(), "{what}: node count");
    for (i, (p, q)) in a.nodes.iter().zip(&b.nodes).enumerate() {
        let bits = |v: &heml_core::Vec3| v.map(f64::to_bits);
        assert_eq!(bits(p), bits(q), "{what}: node {i}");
    }
    assert_eq!(a.tets, b.tets, "{what}: tets");
}

// ------------------------------------------------------------- byte swapping

/// A big-endian copy of a little-endian binary Gmsh file. meshio and Gmsh write
/// native byte order only, so the test builds one: it walks the file's layout
/// (2.2: `$Nodes` records `int, 3 double`, `$Elements` blocks of `int` headers and
/// records; 4.1 without `$Entities`: `size_t` headers, `int`+`size_t` block headers,
/// `size_t` tags, `double` coordinates, `size_t` element records) and reverses the
/// bytes of every number, including the endianness integer 1 after `$MeshFormat`.
struct Swapper {
    b: Vec<u8>,
    pos: usize,
}

impl Swapper {
    fn seek(&mut self, marker: &str) {
        let m = marker.as_bytes();
        let at = self
            .b
            .windows(m.len())
            .position(|w| w == m)
            .unwrap_or_else(|| panic!("no {marker}"));
        self.pos = at + m.len();
    }
    /// Skips an ASCII count line, returning the count.
    fn ascii_count(&mut self) -> usize {
        let end = self.pos + self.b[self.pos..].iter().position(|&c| c == b'\n').unwrap();
        let n = std::str::from_utf8(&self.b[self.pos..end])
            .unwrap()
            .trim()
            .parse()
            .unwrap();
        self.pos = end + 1;
        n
    }
    /// Swaps one number of `size` bytes, returning its (little-endian) value.
    fn swap(&mut self, size: usize) -> u64 {
        let s = &mut self.b[self.pos..self.pos + size];
        let mut v = [0u8; 8];
        v[..size].copy_from_slice(s);
        s.reverse();
        self.pos += size;
        u64::from_le_bytes(v)
    }
    fn swap_n(&mut self, n: usize, size: usize) {
        for _ in 0..n {
            self.swap(size);
        }
    }
}

fn nodes_of(ty: u64) -> usize {
    match ty {
        1 => 2,
        2 => 3,
        4 => 4,
        15 => 1,
        other => panic!("type {other} not in the test files"),
    }
}

fn big_endian_v22(le: &[u8]) -> Vec<u8> {
    let mut s = Swapper { b: le.to_vec(), pos: 0 };
    s.seek("$MeshFormat\n2.2 1 8\n");
    s.swap(4);
    s.seek("$Nodes\n");
    let n = s.ascii_count();
    for _ in 0..n {
        s.swap(4);
        s.swap_n(3, 8);
    }
    s.seek("$Elements\n");
    let n = s.ascii_count() as u64;
    let mut done = 0;
    while done < n {
        let (ty, follow, ntags) = (s.swap(4), s.swap(4), s.swap(4));
        s.swap_n(follow as usize * (1 + ntags as usize + nodes_of(ty)), 4);
        done += follow;
    }
    s.b
}

fn big_endian_v41(le: &[u8]) -> Vec<u8> {
    let mut s = Swapper { b: le.to_vec(), pos: 0 };
    s.seek("$MeshFormat\n4.1 1 8\n");
    s.swap(4);
    assert!(
        !s.b.windows(9).any(|w| w == b"$Entities"),
        "the swapper does not handle $Entities"
    );
    s.seek("$Nodes\n");
    let blocks = s.swap(8);
    s.swap_n(3, 8);
    for _ in 0..blocks {
        s.swap_n(3, 4);
        let n = s.swap(8) as usize;
        s.swap_n(n, 8);
        s.swap_n(3 * n, 8);
    }
    s.seek("$Elements\n");
    let blocks = s.swap(8);
    s.swap_n(3, 8);
    for _ in 0..blocks {
        s.swap_n(2, 4);
        let ty = s.swap(4);
        let n = s.swap(8) as usize;
        s.swap_n(n * (1 + nodes_of(ty)), 8);
    }
    s.b
}

#[test]
fn big_endian_binary_gmsh_reads_like_little_endian() {
    let dir = scratch("big-endian");
    for (file, swap, format) in [
        (
            "tiny_meshio_b22.msh",
            big_endian_v22 as fn(&[u8]) -> Vec<u8>,
            MeshFormat::Gmsh22Binary,
        ),
        ("tiny_meshio_b41.msh", big_endian_v41, MeshFormat::Gmsh41Binary),
    ] {
        let le = std::fs::read(data(file)).unwrap();
        let be = swap(&le);
        // really big-endian: the endianness integer is 00 00 00 01 now
        let at = be
            .windows(8)
            .position(|w| w == b" 1 8\n\0\0\0")
            .expect("swapped endianness integer");
        assert_eq!(be[at + 8], 1, "{file}");
        assert_ne!(be, le, "{file}");
        let path = dir.join(format!("be-{file}"));
        std::fs::write(&path, &be).unwrap();
        let (want, f1) = read_mesh_data(&data(file)).unwrap();
        let (got, f2) = read_mesh_data(&path).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!((f1, f2), (format, format), "{file}");
        assert_same_data(&want, &got, file);
        assert_eq!(want.tags, got.tags, "{file}");
        assert_eq!(want.skipped, got.skipped, "{file}");
        assert_eq!(got.tets.len(), 2, "{file}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn meshio_binary_gmsh_41_fixture_reads_the_tiny_mesh() {
    // the other meshio fixtures are in mesh_io.rs's table; this one holds the tets
    // only, in one element block of entity 1 (meshio's 4.1 writer), hence tags 1, 1
    let (mesh, report) = read_mesh(&data("tiny_meshio_b41.msh")).unwrap();
    assert_eq!(report.format, MeshFormat::Gmsh41Binary);
    assert_eq!((mesh.n_nodes(), mesh.n_tets()), (5, 2));
    let (v22, _) = read_mesh(&data("tiny_meshio_b22.msh")).unwrap();
    assert_eq!(mesh.nodes(), v22.nodes());
    assert_eq!(mesh.tets(), v22.tets());
    assert_eq!(mesh.tags(), [1, 1]);
}

// ------------------------------------------------------------ meshio, shared

/// meshio writes each shared mesh in its binary Gmsh and compressed VTU
/// defaults; every file must read to the nodes (bit for bit) and tets (same
/// order) of the reference ASCII `msh/NAME.msh`.
#[test]
fn meshio_written_files_read_like_the_reference() {
    const TEST: &str = "meshio_written_files_read_like_the_reference";
    let Some(shared) = shared_meshes(TEST) else { return };
    if !python_with_meshio(TEST) {
        return;
    }
    let dir = scratch("meshio");
    let script = r#"
import sys, meshio
src, out = sys.argv[1], sys.argv[2]
m = meshio.read(src)
meshio.write(out + "/b22.msh", m, file_format="gmsh22", binary=True)
meshio.write(out + "/b41.msh", m, file_format="gmsh", binary=True)
for c in ["none", "zlib", "lzma"]:
    meshio.write(out + "/" + c + ".vtu", m, compression=None if c == "none" else c)
"#;
    for name in ["gen_blob_2k", "sofa_liver", "sofa_truthcylinder"] {
        let src = shared.join("vtu").join(format!("{name}.vtu"));
        let out = Command::new("python3")
            .args(["-c", script, src.to_str().unwrap(), dir.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "meshio failed on {name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let (reference, _) = read_mesh_data(&shared.join("msh").join(format!("{name}.msh"))).unwrap();
        for (file, format, marker) in [
            ("b22.msh", MeshFormat::Gmsh22Binary, "2.2 1 8"),
            ("b41.msh", MeshFormat::Gmsh41Binary, "4.1 1 8"),
            ("none.vtu", MeshFormat::Vtu, "format=\"binary\""),
            ("zlib.vtu", MeshFormat::Vtu, "vtkZLibDataCompressor"),
            ("lzma.vtu", MeshFormat::Vtu, "vtkLZMADataCompressor"),
        ] {
            let path = dir.join(file);
            // the file is what the case says (meshio's defaults may change)
            let head = std::fs::read(&path).unwrap();
            let head = String::from_utf8_lossy(&head[..head.len().min(400)]).into_owned();
            assert!(head.contains(marker), "{name}/{file}: no '{marker}' in {head}");
            let (got, f) = read_mesh_data(&path).unwrap_or_else(|e| panic!("{name}/{file}: {e}"));
            assert_eq!(f, format, "{name}/{file}");
            assert_same_data(&reference, &got, &format!("{name}/{file}"));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

// ------------------------------------------------------------------ SOFA, v1

/// SOFA ships its meshes as Gmsh 1; each reads (after the same load, with its
/// reorientation) to the nodes and tets of its converted copies in `msh/` and
/// `vtu/`.
#[test]
fn sofa_gmsh1_meshes_read_like_their_converted_copies() {
    let Some(shared) = shared_meshes("sofa_gmsh1_meshes_read_like_their_converted_copies") else {
        return;
    };
    // original file, converted name, skipped surface elements (README: dropped)
    for (orig, name, lines, triangles) in [
        ("sofa_liver.msh", "sofa_liver", 0, 0),
        ("sofa_liver2.msh", "sofa_liver2", 71, 860),
        ("sofa_truthcylinder1.msh", "sofa_truthcylinder", 72, 706),
    ] {
        let (mesh, report) = read_mesh(&shared.join("original").join(orig)).unwrap_or_else(|e| panic!("{orig}: {e}"));
        assert_eq!(report.format, MeshFormat::Gmsh1, "{orig}");
        assert_eq!(report.skipped.get("line").copied().unwrap_or(0), lines, "{orig}");
        assert_eq!(
            report.skipped.get("triangle").copied().unwrap_or(0),
            triangles,
            "{orig}"
        );
        for copy in [format!("msh/{name}.msh"), format!("vtu/{name}.vtu")] {
            let (other, _) = read_mesh(&shared.join(&copy)).unwrap();
            assert_eq!(mesh.nodes(), other.nodes(), "{orig} vs {copy}: nodes");
            assert_eq!(mesh.tets(), other.tets(), "{orig} vs {copy}: tets");
            assert_eq!(mesh.reoriented_count(), other.reoriented_count(), "{orig} vs {copy}");
        }
    }
    // the truth cylinder's physical surfaces (its Gmsh 1 physical regions): the two
    // end caps (1 at y = -17.78, 3 at y = 17.78) and the side (2): node sets a scene
    // clamps by name
    let (mesh, _) = read_mesh(&shared.join("original/sofa_truthcylinder1.msh")).unwrap();
    let sizes: Vec<(&str, usize)> = mesh.node_sets().iter().map(|(k, v)| (k.as_str(), v.len())).collect();
    assert_eq!(
        sizes,
        [
            ("curve 1", 36),
            ("curve 2", 36),
            ("surface 1", 54),
            ("surface 2", 318),
            ("surface 3", 55)
        ]
    );
    let y = |set: &str| -> Vec<f64> { mesh.node_sets()[set].iter().map(|&i| mesh.nodes()[i].y).collect() };
    let (lo, hi) = mesh.bounding_box();
    assert!(
        y("surface 1").iter().all(|&v| (v - lo.y).abs() < 1e-6),
        "{:?}",
        y("surface 1")
    );
    assert!(
        y("surface 3").iter().all(|&v| (v - hi.y).abs() < 1e-6),
        "{:?}",
        y("surface 3")
    );
}

// ------------------------------------------------------------------- errors

/// The error of reading `bytes` as a `.msh` (never a panic, never success).
fn msh_error(bytes: &[u8]) -> (usize, String) {
    match gmsh::parse(Path::new("bad.msh"), bytes) {
        Ok(_) => panic!("read without error"),
        Err(HemlError::Parse { line, msg, .. }) => (line, msg),
        Err(other) => panic!("not a parse error: {other:?}"),
    }
}

#[test]
fn damaged_binary_and_gmsh1_data_give_precise_errors() {
    let b22 = std::fs::read(data("tiny_meshio_b22.msh")).unwrap();
    let nodes_at = b22.windows(9).position(|w| w == b"$Nodes\n5\n").unwrap() + 9;

    // truncated inside the node records: the count check fails before any record
    let (line, msg) = msh_error(&b22[..nodes_at + 40]);
    assert_eq!(line, 7, "{msg}");
    assert!(
        msg.contains(&format!(
            "at byte {nodes_at}: 5 nodes need 140 bytes of binary data, only 40 are left"
        )),
        "{msg}"
    );

    // an absurd count: refused from the file size, not allocated
    let mut huge = b22[..nodes_at - 2].to_vec();
    huge.extend_from_slice(b"999999999999\n");
    huge.extend_from_slice(&b22[nodes_at..]);
    let (_, msg) = msh_error(&huge);
    assert!(msg.contains("999999999999 nodes need 27999999999972 bytes"), "{msg}");

    // the endianness integer is neither 1 nor byte-swapped 1
    let mut bad = b22.clone();
    let at = bad.windows(8).position(|w| w == b"2.2 1 8\n").unwrap() + 8;
    bad[at] = 2;
    let (line, msg) = msh_error(&bad);
    assert_eq!(line, 3, "{msg}");
    assert!(msg.contains(&format!("at byte {at}: expected the integer 1")), "{msg}");

    // an element type outside Gmsh's table (1..=140): refused, as it may be a volume
    let mut bad = b22.clone();
    let el = bad.windows(12).position(|w| w == b"$Elements\n3\n").unwrap() + 12;
    bad[el] = 200;
    let (_, msg) = msh_error(&bad);
    assert!(
        msg.contains(&format!("at byte {el}: element type 200 is not a Gmsh element type")),
        "{msg}"
    );
    // a surface type without a fixed node count (a polygon): its record size is unknown
    bad[el] = 34;
    let (_, msg) = msh_error(&bad);
    assert!(
        msg.contains(&format!("at byte {el}: element type 34 has no fixed node count")),
        "{msg}"
    );

    // an element block announcing more elements than the count line
    let mut bad = b22.clone();
    bad[el + 4] = 7;
    let (_, msg) = msh_error(&bad);
    assert!(msg.contains("announces 7 elements of type"), "{msg}");

    // truncated inside the element records
    let cut = el + 12 + 10;
    let (_, msg) = msh_error(&b22[..cut]);
    assert!(msg.contains("element records need"), "{msg}");

    // Gmsh 1: a tet with 3 nodes, a node count that disagrees with the list
    let v1 = std::fs::read_to_string(data("tiny_v1.msh")).unwrap();
    let (line, msg) = msh_error(v1.replace("3 4 1 1 4 1 2 3 5", "3 4 1 1 3 1 2 3").as_bytes());
    assert_eq!(line, 13, "{msg}");
    assert!(
        msg.contains("element 3 of type 4 has 3 nodes, that type has 4"),
        "{msg}"
    );
    let (line, msg) = msh_error(v1.replace("3 4 1 1 4 1 2 3 5", "3 4 1 1 4 1 2 3").as_bytes());
    assert_eq!(line, 13, "{msg}");
    assert!(msg.contains("element 3 announces 4 nodes and lists 3"), "{msg}");
    // a v1 section in a v2 file
    let (_, msg) = msh_error(b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$NOD\n0\n$ENDNOD\n");
    assert!(msg.contains("$NOD does not belong in a Gmsh 2 file"), "{msg}");
}

#[test]
fn damaged_lzma_vtu_gives_an_error_naming_the_array() {
    let text = std::fs::read_to_string(data("tiny_meshio_lzma.vtu")).unwrap();
    // corrupt the first base64 payload of the Points array past its header
    let start = text.find("format=\"binary\">").unwrap() + 16;
    let start = start + text[start..].find('=').unwrap() + 1 + 20;
    let mut bad = text.clone().into_bytes();
    for b in &mut bad[start..start + 8] {
        *b = if *b == b'A' { b'B' } else { b'A' };
    }
    let e = heml_core::io::vtu::parse(Path::new("bad.vtu"), &bad)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("bad.vtu:"), "{e}");
    assert!(e.contains("lzma block 0"), "{e}");
}

/// The other direction: meshio reads the binary Gmsh files HEML writes (2.2, and
/// 4.1 with its binary `$Entities`) to the same points (bit for bit), tets and
/// physical tags: the writer and the reader do not merely agree with each other.
#[test]
fn meshio_reads_our_binary_gmsh_files() {
    const TEST: &str = "meshio_reads_our_binary_gmsh_files";
    if !python_with_meshio(TEST) {
        return;
    }
    use heml_core::io::write_mesh_as;
    use heml_core::mesh::generate::{box_mesh, HexSplit};
    let dir = scratch("meshio-reads");
    let m = box_mesh([1.0 / 3.0, 0.7, 0.9], [3, 2, 2], HexSplit::Five).unwrap();
    let tags: Vec<i32> = (0..m.n_tets()).map(|k| [3, 7, 5][k % 3] + (k / 20) as i32).collect();
    let tets: Vec<[usize; 4]> = m.tets().iter().map(|t| t.map(|i| i as usize)).collect();
    let mesh = heml_core::TetMesh::with_tags(m.nodes().to_vec(), tets, tags).unwrap();
    let script = r#"
import sys, meshio, numpy as np
m = meshio.read(sys.argv[1])
out = sys.argv[2]
np.asarray(m.points, dtype='<f8').tofile(out + '.points')
tets = [c.data for c in m.cells if c.type == 'tetra']
np.asarray(np.concatenate(tets), dtype='<i8').tofile(out + '.tets')
phys = [d for d, c in zip(m.cell_data['gmsh:physical'], m.cells) if c.type == 'tetra']
np.asarray(np.concatenate(phys), dtype='<i4').tofile(out + '.tags')
"#;
    for (file, format) in [
        ("b22.msh", MeshFormat::Gmsh22Binary),
        ("b41.msh", MeshFormat::Gmsh41Binary),
    ] {
        let path = dir.join(file);
        write_mesh_as(&path, &mesh, format).unwrap();
        let out = dir.join(file).with_extension("out");
        let o = Command::new("python3")
            .args(["-c", script, path.to_str().unwrap(), out.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{file}: meshio failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let words = |ext: &str, size: usize| -> Vec<u64> {
            std::fs::read(format!("{}.{ext}", out.display()))
                .unwrap()
                .chunks_exact(size)
                .map(|c| {
                    let mut a = [0u8; 8];
                    a[..size].copy_from_slice(c);
                    u64::from_le_bytes(a)
                })
                .collect()
        };
        let points: Vec<u64> = mesh
            .nodes()
            .iter()
            .flat_map(|p| p.iter().map(|x| x.to_bits()))
            .collect();
        assert_eq!(words("points", 8), points, "{file}");
        let tets: Vec<u64> = mesh.tets().iter().flatten().map(|&i| u64::from(i)).collect();
        assert_eq!(words("tets", 8), tets, "{file}");
        let tags: Vec<u64> = mesh.tags().iter().map(|&t| t as u32 as u64).collect();
        assert_eq!(words("tags", 4), tags, "{file}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

// ------------------------------------------------------------- OpenSurgSim, PLY

/// OpenSurgSim's arm wound (`original/surgsim_wound_deformable.ply`, its deformable
/// PLY layout) reads to the nodes and tets of its converted copies, with its 407
/// surface faces skipped, its 79 boundary-condition nodes as a node set (all on the
/// body's boundary surface) and its material.
#[test]
fn opensurgsim_ply_reads_like_its_converted_copies() {
    let Some(shared) = shared_meshes("opensurgsim_ply_reads_like_its_converted_copies") else {
        return;
    };
    let path = shared.join("original/surgsim_wound_deformable.ply");
    let (mesh, report) = read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(report.format, MeshFormat::Ply);
    assert_eq!((report.n_nodes, report.n_tets), (391, 1476));
    assert_eq!(report.skipped.get("face"), Some(&407));
    let m = report.material.expect("the file's material");
    assert_eq!((m.density, m.poisson_ratio, m.young_modulus), (1000.0, 0.45, 7.5e4));
    let set = mesh.node_set("boundary_condition").expect("the boundary conditions");
    assert_eq!(set.len(), 79);
    let surface = heml_core::mesh::surface::BoundarySurface::of_tet_mesh(&mesh);
    assert!(set.iter().all(|&i| surface.nodes().contains(&(i as u32))));
    for copy in ["msh/surgsim_arm_wound.msh", "vtu/surgsim_arm_wound.vtu"] {
        let (other, _) = read_mesh(&shared.join(copy)).unwrap();
        assert_eq!(mesh.nodes(), other.nodes(), "{copy}: nodes");
        assert_eq!(mesh.tets(), other.tets(), "{copy}: tets");
        assert_eq!(mesh.reoriented_count(), other.reoriented_count(), "{copy}");
    }
}
