//! Deterministic mutation fuzzing of every mesh reader and of the scene parser.
//!
//! Each target starts from small seed files in its format (`tests/data/tiny_*`,
//! among them Gmsh 1 and meshio's binary Gmsh and lzma VTU,
//! `tests/fuzz_seeds/*`: the reproducers of the faults found by fuzzing before,
//! kept as regression cases; `scenes/*.toml`; the project's writers' output for a
//! small box) and applies 1–4 mutations drawn from a fixed-seed
//! ChaCha RNG: byte flips, syntax characters, truncations, duplicated, removed or
//! swapped lines, numbers replaced by huge, negative, NaN or overflowing ones,
//! inserted bytes, splices of another seed. Execution `i` of a target is fully
//! determined by the target's name and `i`.
//!
//! Every input must either parse into data that validates (indices in range; as a
//! [`TetMesh`], positive finite volumes) or give an `Err`: a panic fails the test
//! and writes the input to `$CARGO_TARGET_TMPDIR/fuzz-failures/`. Memory is
//! bounded by a counting global allocator (this test binary only): an allocation
//! that would take the live total above [`LIMIT`] writes the input to
//! `fuzz-failures/` and aborts the process (an allocation failure cannot unwind).
//!
//! Budget: [`DEFAULT_EXECS`] executions per target in the normal `cargo test`;
//! `HEML_FUZZ_EXECS=100000 cargo test --release -p heml-core --test fuzz` is the
//! long mode (docs/guide/scenes.md, "Hostile input", quotes its counts).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use heml_core::io::{gmsh, medit, ply, tetgen, vtk_legacy, vtu, MeshData};
use heml_core::scene::Scene;
use heml_core::TetMesh;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Executions per target in the normal test run.
const DEFAULT_EXECS: usize = 2_000;
/// Most bytes live at once in this test binary (all threads together).
const LIMIT: usize = 256 << 20;

// ---------------------------------------------------------------------------
// A counting allocator: total live bytes, and per thread live and peak bytes.

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static THREAD_LIVE: Cell<isize> = const { Cell::new(0) };
    static THREAD_PEAK: Cell<isize> = const { Cell::new(0) };
    /// The input being executed on this thread (pointer, length; null when none).
    static CURRENT: Cell<(*const u8, usize)> = const { Cell::new((std::ptr::null(), 0)) };
    /// Set while reporting, so that the report's own allocations pass.
    static REPORTING: Cell<bool> = const { Cell::new(false) };
}

fn track(delta: isize) {
    let _ = THREAD_LIVE.try_with(|live| {
        let now = live.get() + delta;
        live.set(now);
        let _ = THREAD_PEAK.try_with(|p| p.set(p.get().max(now)));
    });
}

/// Writes the input running on this thread to `fuzz-failures/oom.bin` before the
/// allocation fails (the process then aborts in `handle_alloc_error`).
fn report_oom(size: usize) {
    if REPORTING.try_with(|r| r.replace(true)).unwrap_or(true) {
        return;
    }
    if let Ok((ptr, len)) = CURRENT.try_with(Cell::get) {
        if !ptr.is_null() {
            // SAFETY: `CURRENT` is set by `with_input` to a slice that outlives the
            // call it wraps, and cleared before the slice is dropped; this runs on
            // the same thread, inside that call.
            let input = unsafe { std::slice::from_raw_parts(ptr, len) };
            let path = failure_dir().join("oom.bin");
            let _ = std::fs::write(&path, input);
            eprintln!(
                "fuzz: an allocation of {size} bytes would exceed {LIMIT} live bytes; input saved to {}",
                path.display()
            );
        }
    }
    let _ = REPORTING.try_with(|r| r.set(false));
}

// SAFETY: every method forwards to `System` with the caller's layout unchanged and
// only adds bookkeeping (atomics and const-initialised thread-locals, which do not
// allocate); a refused allocation returns null, as the trait allows.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let reporting = REPORTING.try_with(Cell::get).unwrap_or(true);
        if !reporting && LIVE.load(Ordering::Relaxed).saturating_add(layout.size()) > LIMIT {
            report_oom(layout.size());
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded with the caller's (valid, non-zero-size) layout.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            LIVE.fetch_add(layout.size(), Ordering::Relaxed);
            track(layout.size() as isize);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `alloc`/`realloc` above with this layout.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        track(-(layout.size() as isize));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let reporting = REPORTING.try_with(Cell::get).unwrap_or(true);
        let grow = new_size.saturating_sub(layout.size());
        if !reporting && LIVE.load(Ordering::Relaxed).saturating_add(grow) > LIMIT {
            report_oom(new_size);
            return std::ptr::null_mut();
        }
        // SAFETY: `ptr` came from this allocator with `layout`; `new_size` is the
        // caller's, valid per the trait's contract.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            LIVE.fetch_add(new_size, Ordering::Relaxed);
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            track(new_size as isize - layout.size() as isize);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` with `input` registered for the out-of-memory report, and returns its
/// result with the peak bytes this thread allocated above its level at the start.
fn with_input<T>(input: &[u8], f: impl FnOnce() -> T) -> (T, usize) {
    let base = THREAD_LIVE.with(Cell::get);
    THREAD_PEAK.with(|p| p.set(base));
    CURRENT.with(|c| c.set((input.as_ptr(), input.len())));
    let r = f();
    CURRENT.with(|c| c.set((std::ptr::null(), 0)));
    let peak = THREAD_PEAK.with(Cell::get) - base;
    (r, peak.max(0) as usize)
}

// ---------------------------------------------------------------------------
// Targets and validation.

fn failure_dir() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-failures");
    let _ = std::fs::create_dir_all(&d);
    d
}

fn manifest(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// The project's writers' output for a small box in every format and encoding,
/// written once into the target directory (seeds like those a user has).
fn writer_seed_dir() -> PathBuf {
    static ONCE: std::sync::Once = std::sync::Once::new();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-writer-seeds");
    ONCE.call_once(|| {
        use heml_core::io::{write_mesh, write_mesh_as, write_vtu, MeshFormat, VtuEncoding, VtuFrame};
        use heml_core::mesh::generate::{box_mesh, HexSplit};
        std::fs::create_dir_all(&dir).unwrap();
        let m = box_mesh([1.0, 0.5, 0.5], [2, 1, 1], HexSplit::Six).unwrap();
        write_mesh_as(&dir.join("w22.msh"), &m, MeshFormat::Gmsh22).unwrap();
        write_mesh_as(&dir.join("w1.msh"), &m, MeshFormat::Gmsh1).unwrap();
        write_mesh_as(&dir.join("wb22.msh"), &m, MeshFormat::Gmsh22Binary).unwrap();
        write_mesh_as(&dir.join("wb41.msh"), &m, MeshFormat::Gmsh41Binary).unwrap();
        write_mesh_as(&dir.join("wb.ply"), &m, MeshFormat::PlyBinary).unwrap();
        for f in ["w41.msh", "w.vtk", "w.mesh", "w.node", "w.ply"] {
            write_mesh(&dir.join(f), &m).unwrap();
        }
        for (f, enc) in [
            ("w-zlib.vtu", VtuEncoding::Base64Zlib),
            ("w-b64.vtu", VtuEncoding::Base64),
            ("w-ascii.vtu", VtuEncoding::Ascii),
        ] {
            write_vtu(&dir.join(f), &VtuFrame::from_mesh(&m).encoding(enc)).unwrap();
        }
    });
    dir
}

/// The seeds of a target: the fixtures, the reproducers, the repository's scenes
/// and the writers' output, whose names end with one of `exts`.
fn seeds(exts: &[&str]) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let writers = writer_seed_dir();
    for dir in [
        manifest("tests/data"),
        manifest("tests/fuzz_seeds"),
        manifest("../scenes"),
        writers,
    ] {
        let Ok(rd) = std::fs::read_dir(&dir) else { continue };
        let mut files: Vec<PathBuf> = rd.flatten().map(|e| e.path()).filter(|p| p.is_file()).collect();
        files.sort();
        for p in files {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if exts.iter().any(|e| name.ends_with(e)) {
                out.push((name, std::fs::read(&p).unwrap()));
            }
        }
    }
    assert!(!out.is_empty(), "no seeds for {exts:?}");
    out
}

/// What a target made of an input: a mesh that validated, or an error.
#[derive(Default, Debug)]
struct Tally {
    meshes: usize,
    errors: usize,
}

/// Checks what a reader returned: an error is fine; data must have in-range
/// indices and one tag per tet and per hex, and as a mesh (hexes split, when it
/// validates) positive finite volumes and finite nodes.
fn check_data(r: heml_core::Result<MeshData>, tally: &mut Tally) -> Result<(), String> {
    let data = match r {
        Ok(d) => d,
        Err(_) => {
            tally.errors += 1;
            return Ok(());
        }
    };
    if data.tets.is_empty() && data.hexes.is_empty() {
        return Err("a reader returned a mesh without tets or hexes".into());
    }
    if data.tags.len() != data.tets.len() {
        return Err(format!("{} tags for {} tets", data.tags.len(), data.tets.len()));
    }
    if data.hex_tags.len() != data.hexes.len() {
        return Err(format!("{} tags for {} hexes", data.hex_tags.len(), data.hexes.len()));
    }
    if let Some(t) = data.tets.iter().position(|t| t.iter().any(|&i| i >= data.nodes.len())) {
        return Err(format!("tet {t} refers to a node out of range"));
    }
    if let Some(h) = data.hexes.iter().position(|h| h.iter().any(|&i| i >= data.nodes.len())) {
        return Err(format!("hex {h} refers to a node out of range"));
    }
    if let Some(i) = data.nodes.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(format!("node {i} is not finite"));
    }
    tally_mesh(data.into_mesh(), tally)
}

/// Counts a validated mesh (checked) or an error.
fn tally_mesh(r: heml_core::Result<TetMesh>, tally: &mut Tally) -> Result<(), String> {
    match r {
        Ok(m) => {
            check_mesh(&m)?;
            tally.meshes += 1;
        }
        Err(_) => tally.errors += 1,
    }
    Ok(())
}

fn check_mesh(m: &TetMesh) -> Result<(), String> {
    if m.n_tets() == 0 {
        return Err("a TetMesh without tets".into());
    }
    for t in 0..m.n_tets() {
        let v = m.tet_volume(t);
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("tet {t} has rest volume {v}"));
        }
    }
    Ok(())
}

/// One fuzz target: a name, its seeds (each one or more files), a parser.
struct Target {
    /// Seeds: the files of one input (a TetGen input is a `.node` and an `.ele`).
    seeds: Vec<Vec<(String, Vec<u8>)>>,
    run: fn(&[Vec<u8>], &mut Tally) -> Result<(), String>,
}

fn single(exts: &[&str]) -> Vec<Vec<(String, Vec<u8>)>> {
    seeds(exts).into_iter().map(|s| vec![s]).collect()
}

/// The name parsers give their input in error messages.
const INPUT: &str = "fuzz-input";

fn target(name: &str) -> Target {
    match name {
        "gmsh" => Target {
            seeds: single(&[".msh"]),
            run: |b, t| check_data(gmsh::parse(Path::new(INPUT), &b[0]).map(|(d, _)| d), t),
        },
        "vtk_legacy" => Target {
            seeds: single(&[".vtk"]),
            run: |b, t| check_data(vtk_legacy::parse(Path::new(INPUT), &b[0]), t),
        },
        "vtu" => Target {
            seeds: single(&[".vtu"]),
            run: |b, t| check_data(vtu::parse(Path::new(INPUT), &b[0]), t),
        },
        "medit" => Target {
            seeds: single(&[".mesh"]),
            run: |b, t| check_data(medit::parse(Path::new(INPUT), &b[0]), t),
        },
        "ply" => Target {
            seeds: single(&[".ply"]),
            run: |b, t| check_data(ply::parse(Path::new(INPUT), &b[0]).map(|(d, _)| d), t),
        },
        "tetgen" => {
            // pair every .node seed with its .ele sibling
            let nodes = seeds(&[".node"]);
            let eles = seeds(&[".ele"]);
            let pairs = nodes
                .into_iter()
                .filter_map(|(n, nb)| {
                    let stem = n.trim_end_matches(".node");
                    eles.iter()
                        .find(|(e, _)| e.trim_end_matches(".ele") == stem)
                        .map(|(e, eb)| vec![(n.clone(), nb), (e.clone(), eb.clone())])
                })
                .collect::<Vec<_>>();
            Target {
                seeds: pairs,
                run: |b, t| {
                    let r = tetgen::parse_node(Path::new(INPUT), &b[0]).and_then(|(nodes, first)| {
                        let (tets, tags) = tetgen::parse_ele(Path::new(INPUT), &b[1], first, nodes.len())?;
                        Ok(MeshData {
                            nodes,
                            tets,
                            tags,
                            ..MeshData::default()
                        })
                    });
                    check_data(r, t)
                },
            }
        }
        "scene" => Target {
            seeds: single(&[".toml"]),
            run: |b, t| {
                let text = String::from_utf8_lossy(&b[0]);
                let mut scene = match Scene::from_toml_str(&text, std::env::temp_dir().join("heml-fuzz-no-such-dir")) {
                    Ok(s) => s,
                    Err(_) => {
                        t.errors += 1;
                        return Ok(());
                    }
                };
                // generate meshes of at most 20k tets here: the limit itself is
                // under test (a bigger count must be refused before allocating)
                if let Some(g) = scene.mesh.generate.as_mut() {
                    g.max_tets = Some(g.max_tets.unwrap_or(usize::MAX).min(20_000));
                }
                tally_mesh(scene.load_mesh(), t)
            },
        },
        other => panic!("no target {other}"),
    }
}

// ---------------------------------------------------------------------------
// Mutations.

const INTERESTING: &[&str] = &[
    "0",
    "-1",
    "1",
    "-0",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "1e400",
    "-1e400",
    "1e200",
    "1e-320",
    "2147483648",
    "-2147483649",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999",
    "3.5",
    "",
    "0x10",
];
const SYNTAX: &[u8] = b"0123456789 \n\t-+.eE<>/\"'=_$#xA\0\xff";

fn is_token_byte(b: u8) -> bool {
    !(b.is_ascii_whitespace() || b"<>\"'=,[]{}".contains(&b))
}

fn line_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut start = 0;
    for (i, &c) in b.iter().enumerate() {
        if c == b'\n' {
            spans.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < b.len() {
        spans.push((start, b.len()));
    }
    spans
}

fn mutate(b: &mut Vec<u8>, other: &[u8], rng: &mut ChaCha8Rng) {
    let len = b.len();
    match rng.gen_range(0..11) {
        0 if len > 0 => {
            let i = rng.gen_range(0..len);
            b[i] ^= 1 << rng.gen_range(0..8);
        }
        1 if len > 0 => {
            let i = rng.gen_range(0..len);
            b[i] = SYNTAX[rng.gen_range(0..SYNTAX.len())];
        }
        2 => {
            b.truncate(rng.gen_range(0..=len));
        }
        3..=5 => {
            let spans = line_spans(b);
            if spans.is_empty() {
                return;
            }
            let (s, e) = spans[rng.gen_range(0..spans.len())];
            match rng.gen_range(0..3) {
                0 => {
                    let line = b[s..e].to_vec();
                    b.splice(e..e, line);
                }
                1 => {
                    b.drain(s..e);
                }
                _ => {
                    let (s2, e2) = spans[rng.gen_range(0..spans.len())];
                    if e <= s2 {
                        let (l1, l2) = (b[s..e].to_vec(), b[s2..e2].to_vec());
                        b.splice(s2..e2, l1);
                        b.splice(s..e, l2);
                    }
                }
            }
        }
        6..=7 => {
            // replace a token (most often a number) by an interesting value
            if len == 0 {
                return;
            }
            let mut i = rng.gen_range(0..len);
            // prefer a position inside a digit run
            for _ in 0..16 {
                if b[i].is_ascii_digit() {
                    break;
                }
                i = rng.gen_range(0..len);
            }
            if !is_token_byte(b[i]) {
                return;
            }
            let mut s = i;
            while s > 0 && is_token_byte(b[s - 1]) {
                s -= 1;
            }
            let mut e = i;
            while e < len && is_token_byte(b[e]) {
                e += 1;
            }
            let v = INTERESTING[rng.gen_range(0..INTERESTING.len())];
            b.splice(s..e, v.bytes());
        }
        8 => {
            let at = rng.gen_range(0..=len);
            let n = rng.gen_range(1..8);
            let bytes: Vec<u8> = (0..n).map(|_| SYNTAX[rng.gen_range(0..SYNTAX.len())]).collect();
            b.splice(at..at, bytes);
        }
        9 if !other.is_empty() => {
            // splice a piece of another seed
            let s = rng.gen_range(0..other.len());
            let e = (s + rng.gen_range(1..256)).min(other.len());
            let at = rng.gen_range(0..=len);
            b.splice(at..at, other[s..e].iter().copied());
        }
        _ if len > 1 => {
            // repeat a chunk
            let s = rng.gen_range(0..len);
            let e = (s + rng.gen_range(1..64)).min(len);
            let chunk = b[s..e].to_vec();
            b.splice(e..e, chunk);
        }
        _ => {}
    }
}

/// A stable 64-bit seed for execution `i` of target `name` (FNV-1a of the name).
fn exec_seed(name: &str, i: usize) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for b in name.bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
    }
    h ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

fn execs() -> usize {
    std::env::var("HEML_FUZZ_EXECS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(DEFAULT_EXECS)
}

fn save_failure(name: &str, i: usize, parts: &[Vec<u8>]) -> PathBuf {
    let dir = failure_dir();
    for (k, p) in parts.iter().enumerate() {
        let _ = std::fs::write(dir.join(format!("{name}-{i}-part{k}.bin")), p);
    }
    dir.join(format!("{name}-{i}-part0.bin"))
}

/// Runs every seed unmutated, then `execs()` mutated inputs.
fn fuzz(name: &str) {
    let t = target(name);
    let n = execs();
    let start = Instant::now();
    let mut tally = Tally::default();
    let mut peak_max = 0usize;
    let all: Vec<&[u8]> = t
        .seeds
        .iter()
        .flat_map(|s| s.iter().map(|(_, b)| b.as_slice()))
        .collect();
    let total = t.seeds.len() + n;
    for i in 0..total {
        let (label, parts): (String, Vec<Vec<u8>>) = if i < t.seeds.len() {
            let s = &t.seeds[i];
            (format!("seed {}", s[0].0), s.iter().map(|(_, b)| b.clone()).collect())
        } else {
            let k = i - t.seeds.len();
            let mut rng = ChaCha8Rng::seed_from_u64(exec_seed(name, k));
            let seed = &t.seeds[rng.gen_range(0..t.seeds.len())];
            let mut parts: Vec<Vec<u8>> = seed.iter().map(|(_, b)| b.clone()).collect();
            // mostly one mutation (a near-valid input reaches deeper code), up to 4
            let rounds = if rng.gen_bool(0.7) { 1 } else { rng.gen_range(2..=4) };
            for _ in 0..rounds {
                let which = rng.gen_range(0..parts.len());
                let other = all[rng.gen_range(0..all.len())];
                mutate(&mut parts[which], other, &mut rng);
            }
            (format!("execution {k} (seed of {})", seed[0].0), parts)
        };
        let joined: Vec<u8> = parts.concat();
        let (outcome, peak) = with_input(&joined, || {
            catch_unwind(AssertUnwindSafe(|| (t.run)(&parts, &mut tally)))
        });
        peak_max = peak_max.max(peak);
        match outcome {
            Ok(Ok(())) => {}
            Ok(Err(invalid)) => {
                let f = save_failure(name, i, &parts);
                panic!(
                    "{name}: {label}: accepted an invalid mesh ({invalid}); input in {}",
                    f.display()
                );
            }
            Err(_) => {
                let f = save_failure(name, i, &parts);
                panic!("{name}: {label}: the parser panicked; input in {}", f.display());
            }
        }
    }
    // reported by the test (not the library), for the guide's counts
    eprintln!(
        "fuzz {name}: {total} inputs ({} seeds + {n} mutated) in {:.2} s: {} valid meshes, {} errors, peak {:.1} MB",
        t.seeds.len(),
        start.elapsed().as_secs_f64(),
        tally.meshes,
        tally.errors,
        peak_max as f64 / 1e6
    );
    assert_eq!(tally.meshes + tally.errors, total, "{name}: an input gave no verdict");
    assert!(
        tally.meshes > 0 && tally.errors > 0,
        "{name}: {tally:?}: the mutations explore nothing"
    );
}

#[test]
fn fuzz_gmsh() {
    fuzz("gmsh");
}

#[test]
fn fuzz_vtk_legacy() {
    fuzz("vtk_legacy");
}

#[test]
fn fuzz_vtu() {
    fuzz("vtu");
}

#[test]
fn fuzz_tetgen() {
    fuzz("tetgen");
}

#[test]
fn fuzz_medit() {
    fuzz("medit");
}

#[test]
fn fuzz_ply() {
    fuzz("ply");
}

#[test]
fn fuzz_scene() {
    fuzz("scene");
}

// ---------------------------------------------------------------------------
// Regression cases that need the counting allocator.

#[test]
fn zlib_bomb_fails_before_inflating() {
    // Points of 4 nodes (4 × 3 × 8 = 96 bytes) in a zlib block that declares, and
    // inflates to, 8 MiB of zeros (11 kB of file). The reader used to inflate it
    // whole (a 2.8 MB file took 4.2 GB and aborted); now the declared size is
    // compared with the Piece's counts first.
    let bytes = std::fs::read(manifest("tests/fuzz_seeds/repro_zlib_bomb.vtu")).unwrap();
    let (r, peak) = with_input(&bytes, || vtu::parse(Path::new("bomb.vtu"), &bytes));
    let e = r.unwrap_err().to_string();
    assert!(
        e.starts_with("bomb.vtu:6: DataArray 'Points'")
            && e.contains("declares 8388608 bytes")
            && e.contains("expected 96"),
        "{e}"
    );
    // the base64 text is decoded once (11 kB) and its copy without whitespace; the
    // 8 MiB block is never inflated: 1 MB leaves room for the parser's own buffers
    assert!(peak < 1 << 20, "peak {peak} bytes while reading an 11 kB file");
}

#[test]
fn lzma_dictionary_bomb_fails_before_allocating() {
    // meshio's lzma VTU fixture with the first block's xz header declaring a 4 GiB
    // dictionary (LZMA2 property byte 40, header CRC32 recomputed): the decoder
    // would allocate it before reading a byte; the reader's memory limit refuses it.
    use base64::engine::general_purpose::STANDARD;
    use base64::Engine;
    let text = std::fs::read_to_string(manifest("tests/data/tiny_meshio_lzma.vtu")).unwrap();
    let open = text.find("format=\"binary\">").unwrap() + "format=\"binary\">".len();
    // the size header (3 + 1 UInt32 words = 16 bytes, base64 "…==") then the xz stream
    let payload = open + text[open..].find("==").unwrap() + 2;
    let end = payload + text[payload..].find('<').unwrap();
    let mut xz = STANDARD.decode(text[payload..end].trim()).unwrap();
    // stream header (12 bytes), then block header: size, flags, filter 0x21 (LZMA2),
    // property size 1, dictionary property, padding, CRC32 of the first 8 bytes
    assert_eq!((&xz[..6], xz[14], xz[15]), (&b"\xfd7zXZ\0"[..], 0x21, 1));
    xz[16] = 40;
    let mut crc = flate2::Crc::new();
    crc.update(&xz[12..20]);
    xz[20..24].copy_from_slice(&crc.sum().to_le_bytes());
    let bomb = format!("{}{}{}", &text[..payload], STANDARD.encode(&xz), &text[end..]);
    let (r, peak) = with_input(bomb.as_bytes(), || vtu::parse(Path::new("bomb.vtu"), bomb.as_bytes()));
    let e = r.unwrap_err().to_string();
    assert!(
        e.contains("DataArray 'Points'") && e.contains("lzma block 0 declares a dictionary needing more than 65 MiB"),
        "{e}"
    );
    // the file is 1.3 kB: 1 MB leaves room for the parser's own buffers
    assert!(
        peak < 1 << 20,
        "peak {peak} bytes while reading a {}-byte file",
        bomb.len()
    );
}

#[test]
fn binary_gmsh_counts_are_bounded_by_the_file_size() {
    // binary 4.1 $Nodes announcing 2^63 nodes in one block, binary 2.2 announcing
    // 10^18: refused from the bytes left in the file, before any reservation
    let mut v41 = b"$MeshFormat\n4.1 1 8\n\x01\0\0\0\n$EndMeshFormat\n$Nodes\n".to_vec();
    for w in [1u64, 1 << 63, 1, 1 << 63] {
        v41.extend_from_slice(&w.to_le_bytes());
    }
    v41.extend_from_slice(&[3, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]);
    v41.extend_from_slice(&(1u64 << 63).to_le_bytes());
    let v22 = b"$MeshFormat\n2.2 1 8\n\x01\0\0\0\n$EndMeshFormat\n$Nodes\n1000000000000000000\n\x01\0\0\0".to_vec();
    for bytes in [v41, v22] {
        let (r, peak) = with_input(&bytes, || gmsh::parse(Path::new("huge.msh"), &bytes));
        let e = r.unwrap_err().to_string();
        assert!(e.contains("nodes need") && e.contains("bytes of binary data"), "{e}");
        assert!(peak < 64 * 1024, "peak {peak} bytes for a {}-byte file", bytes.len());
    }
}

#[test]
fn header_counts_do_not_drive_allocation() {
    // counts up to 2^64 in every format: at most a few times the file's size
    let cases: [(&str, &str); 7] = [
        ("ply", "ply\nformat ascii 1.0\nelement vertex 18446744073709551615\nproperty double x\nproperty double y\nproperty double z\nend_header\n0 0 0\n"),
        ("ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty uchar x\nproperty uchar y\nproperty uchar z\nelement 3d_element 4611686018427387904\nproperty list uchar uint vertex_indices\nend_header\n\0\0\0\x04"),
        ("gmsh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n18446744073709551615\n1 0 0 0\n"),
        ("vtk_legacy", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 6148914691236517205 double\n0 0 0\n"),
        ("medit", "MeshVersionFormatted 2\nDimension 3\nVertices 4611686018427387904\n0 0 0 0\n"),
        ("tetgen", "4611686018427387904 3 0 0\n1 0 0 0\n"),
        ("vtu", "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece NumberOfPoints=\"1000000000000\" NumberOfCells=\"1\"><Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0</DataArray></Points></Piece></UnstructuredGrid></VTKFile>"),
    ];
    for (name, text) in cases {
        let t = target(name);
        let parts = if name == "tetgen" {
            vec![text.as_bytes().to_vec(), b"1 4 0\n1 1 1 1 1\n".to_vec()]
        } else {
            vec![text.as_bytes().to_vec()]
        };
        let mut tally = Tally::default();
        let (r, peak) = with_input(text.as_bytes(), || (t.run)(&parts, &mut tally));
        r.unwrap();
        assert_eq!(tally.errors, 1, "{name}: accepted");
        assert!(
            peak < 64 * 1024,
            "{name}: peak {peak} bytes for a {}-byte file",
            text.len()
        );
    }
}
