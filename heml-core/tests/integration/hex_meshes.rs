//! Hexahedral meshes read from files are split into tets at load: every split
//! fills the hexes exactly (same volume) and conforms (a closed boundary on the
//! box's faces, every interior triangle shared by exactly two tets).
//!
//! Fixtures (`tests/data/make_meshio_fixtures.py`, written by meshio): a box of
//! 3 × 2 × 2 hexahedra with graded spacing and shuffled node ids, tags 1–12, as
//! VTU, as binary Gmsh 2.2 and 4.1, and as ASCII Gmsh 2.2.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use heml_core::io::{read_mesh, read_mesh_with, ReadOptions};
use heml_core::mesh::generate::HexSplit;
use heml_core::mesh::surface::BoundarySurface;
use heml_core::scene::Scene;
use heml_core::{TetMesh, Vec3};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

/// The fixture box: [0, 3] × [0, 2] × [0, 1.5].
const SIZE: [f64; 3] = [3.0, 2.0, 1.5];

/// Checks that `mesh` is a conforming tetrahedralisation of the box: each
/// triangle is a face of one tet (then it lies on a face of the box) or of two
/// (interior), never more; the boundary is closed and covers the box's area.
fn assert_conforming_box(mesh: &TetMesh, what: &str) {
    let mut faces: HashMap<[u32; 3], usize> = HashMap::new();
    for t in mesh.tets() {
        for skip in 0..4 {
            let mut f = [0u32; 3];
            let mut k = 0;
            for (i, &n) in t.iter().enumerate() {
                if i != skip {
                    f[k] = n;
                    k += 1;
                }
            }
            f.sort_unstable();
            *faces.entry(f).or_insert(0) += 1;
        }
    }
    let x = mesh.nodes();
    // coordinates are exact binary fractions (0.5, 0.75, 1.25, 1.5, …) and face
    // centres their means: a point on a box face has the face's coordinate exactly
    let on_box = |p: &Vec3| (0..3).any(|a| p[a] == 0.0 || p[a] == SIZE[a]);
    let mut boundary = 0;
    for (f, &n) in &faces {
        assert!(n <= 2, "{what}: triangle {f:?} shared by {n} tets");
        if n == 1 {
            boundary += 1;
            let on_one_face = (0..3)
                .any(|a| f.iter().all(|&i| x[i as usize][a] == 0.0) || f.iter().all(|&i| x[i as usize][a] == SIZE[a]));
            assert!(
                on_one_face && f.iter().all(|&i| on_box(&x[i as usize])),
                "{what}: triangle {f:?} bounds one tet but is inside the box (a crack between hexes)"
            );
        }
    }
    // overlapping covers (the ten split): the surface is cover 0's, and the faces
    // used once are each cover's boundary, one copy per cover
    let surface = BoundarySurface::of_tet_mesh(mesh);
    let covers = mesh
        .overlap()
        .map_or(1, |o| 1 + *o.covers.iter().max().unwrap_or(&0) as usize);
    assert!(surface.is_closed(), "{what}: boundary not closed");
    assert_eq!(surface.n_triangles() * covers, boundary, "{what}");
    let area: f64 = (0..surface.n_triangles())
        .map(|i| surface.area_normal(i, x).norm())
        .sum();
    let box_area = 2.0 * (SIZE[0] * SIZE[1] + SIZE[1] * SIZE[2] + SIZE[0] * SIZE[2]);
    // a sum of ~100 exact-ish triangle areas: round-off only
    assert!(
        (area - box_area).abs() < 1e-12 * box_area,
        "{what}: area {area} vs {box_area}"
    );
}

#[test]
fn meshio_hex_files_split_into_conforming_tets_of_the_same_volume() {
    let volume = SIZE[0] * SIZE[1] * SIZE[2];
    let files = [
        "hex_box_meshio.vtu",
        "hex_box_meshio_b22.msh",
        "hex_box_meshio_b41.msh",
        "hex_box_meshio_v22.msh",
    ];
    for file in files {
        for split in HexSplit::ALL {
            let what = format!("{file} {split:?}");
            let (mesh, report) = read_mesh_with(&data(file), &ReadOptions { hex_split: split })
                .unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!(report.hexes_split, 12, "{what}");
            assert_eq!(report.n_tets, 12 * split.tets_per_cell(), "{what}");
            assert!(report.to_string().contains("(from 12 hexahedra)"), "{report}");
            // the splits orient their tets: none is reoriented at validation
            assert_eq!(report.reoriented, 0, "{what}");
            // 12 hexes' volumes summed over their tets: round-off of ~300 terms
            let v = mesh.total_volume();
            assert!((v - volume).abs() < 1e-13 * volume, "{what}: volume {v} vs {volume}");
            assert_conforming_box(&mesh, &what);
            // each hex's tets carry its tag (1..12, in hex order); meshio's 4.1
            // writer puts all hexes in one element block of entity 1, their tag
            let want: Vec<i32> = (1..=12)
                .map(|t| if file.ends_with("b41.msh") { 1 } else { t })
                .flat_map(|t| std::iter::repeat_n(t, split.tets_per_cell()))
                .collect();
            assert_eq!(mesh.tags(), want, "{what}");
            let extra = if split == HexSplit::TwentyFour {
                // 12 cell centres and one centre per distinct face: x-normal faces
                // 4·2·2, y-normal 3·3·2, z-normal 3·2·3
                12 + 16 + 18 + 18
            } else {
                0
            };
            assert_eq!(report.n_nodes, 36 + extra, "{what}");
        }
    }
    // the default split is six
    let (_, report) = read_mesh(&data("hex_box_meshio.vtu")).unwrap();
    assert_eq!(report.n_tets, 72);
}

#[test]
fn vtk_voxels_and_mixed_tet_hex_files_load() {
    // legacy VTK: one voxel (type 11, corners in x-y-z bit order) [0,1]^3 and one
    // tet on its x = 1 face, made of the voxel's corners 1, 3, 7 and a new apex:
    // the six-split cuts that face along 1-7, the diagonal through its smallest
    // id, so the tet's face is one of the voxel's triangles (a tet using 3-5 would
    // leave a crack, as in any tet glued to a quad face without a pyramid)
    let dir = std::env::temp_dir().join(format!("heml-hex-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("mixed.vtk");
    std::fs::write(
        &path,
        "# vtk DataFile Version 3.0\nmixed\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 9 double\n\
         0 0 0 1 0 0 0 1 0 1 1 0 0 0 1 1 0 1 0 1 1 1 1 1 2 0 0\n\
         CELLS 2 14\n8 0 1 2 3 4 5 6 7\n4 1 3 7 8\nCELL_TYPES 2\n11\n10\n",
    )
    .unwrap();
    let (mesh, report) = read_mesh(&path).unwrap();
    assert_eq!((report.hexes_split, report.n_tets), (1, 7));
    // the unit cube plus the tet (1,0,0) (1,1,0) (1,1,1) (2,0,0): volume 1/6
    assert!((mesh.total_volume() - (1.0 + 1.0 / 6.0)).abs() < 1e-15);
    assert!(BoundarySurface::of_mesh(mesh.tets()).is_closed());
    // a hexahedron with 7 nodes is an error naming the cell and its line
    std::fs::write(
        &path,
        "# vtk DataFile Version 3.0\nbad\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 double\n\
         0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1\n\
         CELLS 1 8\n7 0 1 2 3 4 5 6\nCELL_TYPES 1\n12\n",
    )
    .unwrap();
    let e = read_mesh(&path).unwrap_err().to_string();
    assert!(e.contains(":8: cell 0 is a hexahedron (type 12) with 7 nodes"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_scene_chooses_the_hex_split() {
    let dir = data("");
    let scene = |split: &str| {
        format!(
            "[mesh]\nfile = \"hex_box_meshio.vtu\"\n{split}\n[[material]]\nlaw = \"neo_hookean\"\n\
             params = {{ E = 3000.0, nu = 0.45 }}\ndensity = 1000.0\n[solver]\nduration = 0.1\n"
        )
    };
    for (key, tets) in [
        ("", 72),
        ("hex_split = \"five\"", 60),
        ("hex_split = \"twentyfour\"", 288),
        ("hex_split = \"ten\"", 120),
    ] {
        let s = Scene::from_toml_str(&scene(key), &dir).unwrap_or_else(|e| panic!("{key}: {e}"));
        let mesh = s.load_mesh().unwrap();
        assert_eq!(mesh.n_tets(), tets, "{key}");
        // the ten split's tets weigh ½: the body's volume is the file's (round-off)
        let volume = SIZE[0] * SIZE[1] * SIZE[2];
        assert!((mesh.total_volume() - volume).abs() < 1e-13 * volume, "{key}");
        assert_eq!(mesh.overlap().is_some(), key.contains("ten"), "{key}");
    }
    // a generated box takes the same split names
    let generated = "[mesh]\ngenerate = { kind = \"box\", size = [1.0, 1.0, 1.0], cells = [2, 2, 2], \
                     split = \"ten\" }\n[[material]]\nlaw = \"neo_hookean\"\n\
                     params = { E = 3000.0, nu = 0.45 }\ndensity = 1000.0\n[solver]\nduration = 0.1\n";
    let mesh = Scene::from_toml_str(generated, &dir).unwrap().load_mesh().unwrap();
    assert_eq!(mesh.n_tets(), 80);
    assert!((mesh.total_volume() - 1.0).abs() < 1e-14);
    let e = Scene::from_toml_str(&scene("hex_split = \"seven\""), &dir)
        .unwrap_err()
        .to_string();
    assert!(e.contains("hex_split") || e.contains("seven"), "{e}");
}
