//! VTU frames are zlib-compressed by default (issue 13, "Output size"): they must
//! read back bit for bit, with the project's reader and with meshio (ParaView's
//! Python reader family), and be smaller than uncompressed ones.

use std::path::{Path, PathBuf};
use std::process::Command;

use heml_core::io::{vtu, write_vtu, FieldPrecision, VtuEncoding, VtuFrame};
use heml_core::mesh::generate::{box_mesh, HexSplit};
use heml_core::{TetMesh, Vec3};

fn scratch(test: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("vtu-output-{test}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A box bent and twisted by a smooth, non-polynomial displacement: positions
/// with full-precision mantissas, like a simulation's (not round numbers that
/// would compress unrealistically well).
fn deformed() -> (TetMesh, Vec<Vec3>, Vec<Vec3>) {
    let mesh = box_mesh([0.1, 0.02, 0.02], [20, 4, 4], HexSplit::Six).unwrap();
    let u: Vec<Vec3> = mesh
        .nodes()
        .iter()
        .map(|p| {
            let s = p.x / 0.1;
            Vec3::new(
                1e-3 * (3.0 * s).sin() * p.y,
                -0.01 * s * s + 1e-4 * (7.0 * p.z / 0.02).cos(),
                0.002 * s.powf(1.5) * (1.0 + p.y / 0.02).ln(),
            )
        })
        .collect();
    let x: Vec<Vec3> = mesh.nodes().iter().zip(&u).map(|(p, d)| p + d).collect();
    (mesh, x, u)
}

#[test]
fn compressed_frames_are_the_default_read_back_bitwise_and_smaller() {
    assert_eq!(VtuEncoding::default(), VtuEncoding::Base64Zlib);
    let dir = scratch("roundtrip");
    let (mesh, x, u) = deformed();
    let frame = |enc| {
        VtuFrame::deformed(&mesh, &x)
            .point_vectors("displacement", &u)
            .encoding(enc)
    };
    let zipped = dir.join("zlib.vtu");
    let plain = dir.join("plain.vtu");
    write_vtu(&zipped, &frame(VtuEncoding::default())).unwrap();
    write_vtu(&plain, &frame(VtuEncoding::Base64)).unwrap();
    let text = std::fs::read_to_string(&zipped).unwrap();
    assert!(text.contains("compressor=\"vtkZLibDataCompressor\""));

    for path in [&zipped, &plain] {
        let data = vtu::read(path).unwrap();
        assert_eq!(data.nodes.len(), x.len());
        for (k, (a, b)) in data.nodes.iter().zip(&x).enumerate() {
            let same = a.iter().zip(b.iter()).all(|(p, q)| p.to_bits() == q.to_bits());
            assert!(same, "{}: node {k}: {a:?} vs {b:?}", path.display());
        }
        let tets: Vec<[u32; 4]> = data.tets.iter().map(|t| t.map(|i| i as u32)).collect();
        assert_eq!(tets, mesh.tets());
        assert_eq!(data.tags, mesh.tags());
    }
    let (z, p) = (
        std::fs::metadata(&zipped).unwrap().len(),
        std::fs::metadata(&plain).unwrap().len(),
    );
    // full-precision doubles compress little; the connectivity, offsets, types and
    // tags a lot: anything not smaller means the compression is not applied
    assert!(z < p, "compressed {z} bytes, uncompressed {p}");
    eprintln!("deformed 1920-tet frame: {z} bytes compressed, {p} uncompressed");
}

#[test]
fn meshio_reads_compressed_frames_bitwise() {
    let probe = Command::new("python3").args(["-c", "import meshio, numpy"]).output();
    match probe {
        Err(e) => {
            println!("SKIPPED meshio_reads_compressed_frames_bitwise: python3 not runnable ({e})");
            return;
        }
        Ok(o) if !o.status.success() => {
            println!(
                "SKIPPED meshio_reads_compressed_frames_bitwise: python3 cannot import meshio/numpy (pip install meshio): {}",
                String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
            );
            return;
        }
        Ok(_) => {}
    }
    let dir = scratch("meshio");
    let (mesh, x, u) = deformed();
    let path = dir.join("frame.vtu");
    write_vtu(&path, &VtuFrame::deformed(&mesh, &x).point_vectors("displacement", &u)).unwrap();
    // meshio writes what it read as raw little-endian arrays, compared here bit for bit
    let script = r#"
import sys, meshio, numpy as np
m = meshio.read(sys.argv[1])
d = sys.argv[2]
np.asarray(m.points, dtype='<f8').tofile(d + '/points.bin')
np.asarray(m.point_data['displacement'], dtype='<f8').tofile(d + '/u.bin')
tets = [c.data for c in m.cells if c.type == 'tetra']
np.asarray(np.concatenate(tets), dtype='<i8').tofile(d + '/tets.bin')
np.asarray(np.concatenate(m.cell_data['tag']), dtype='<i4').tofile(d + '/tags.bin')
"#;
    let out = Command::new("python3")
        .args(["-c", script, path.to_str().unwrap(), dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "meshio failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let f64s = |name: &str| -> Vec<u64> {
        std::fs::read(dir.join(name))
            .unwrap()
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    };
    let bits = |v: &[Vec3]| -> Vec<u64> { v.iter().flat_map(|p| [p.x, p.y, p.z]).map(f64::to_bits).collect() };
    assert_eq!(f64s("points.bin"), bits(&x));
    assert_eq!(f64s("u.bin"), bits(&u));
    let tets: Vec<u64> = mesh.tets().iter().flatten().map(|&i| u64::from(i)).collect();
    assert_eq!(f64s("tets.bin"), tets);
    let tags: Vec<i32> = std::fs::read(dir.join("tags.bin"))
        .unwrap()
        .chunks_exact(4)
        .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(tags, mesh.tags());
}

/// `FieldPrecision::Single` writes the fields as Float32 and the positions still as
/// Float64 (read back bitwise), and shrinks a frame: the fields' mantissas are what
/// compression cannot remove.
#[test]
fn single_precision_fields_keep_exact_positions_and_shrink_frames() {
    let dir = scratch("precision");
    let (mesh, x, u) = deformed();
    let j: Vec<f64> = (0..mesh.n_tets()).map(|t| 1.0 + 1e-3 * (t as f64).sin()).collect();
    let write = |precision, name: &str| {
        let path = dir.join(name);
        let frame = VtuFrame::deformed(&mesh, &x)
            .point_vectors("displacement", &u)
            .point_vectors("velocity", &u)
            .cell_scalars("J", &j)
            .precision(precision);
        write_vtu(&path, &frame).unwrap();
        path
    };
    let double = write(FieldPrecision::default(), "double.vtu");
    let single = write(FieldPrecision::Single, "single.vtu");
    let text = std::fs::read_to_string(&single).unwrap();
    for field in ["displacement", "velocity", "J"] {
        assert!(text.contains(&format!("type=\"Float32\" Name=\"{field}\"")), "{field}");
    }
    assert!(text.contains("type=\"Float64\" Name=\"Points\""));
    let data = vtu::read(&single).unwrap();
    let exact = data
        .nodes
        .iter()
        .zip(&x)
        .all(|(a, b)| a.iter().zip(b.iter()).all(|(p, q)| p.to_bits() == q.to_bits()));
    assert!(exact, "positions must stay exact in single-precision frames");
    let (d, s) = (
        std::fs::metadata(&double).unwrap().len(),
        std::fs::metadata(&single).unwrap().len(),
    );
    // three of the four float arrays halve (before compression, which removes little
    // of them): the file must lose at least a quarter
    assert!((s as f64) < 0.75 * d as f64, "single {s} bytes, double {d}");
}
