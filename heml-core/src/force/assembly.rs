//! Batched, parallel, deterministic assembly shared by the optimised HEML and P1 paths.
//!
//! # Layout
//! A field's tets are put in Morton order of their centroids (see
//! [`crate::mesh::reorder`]) — this *is* the field's order, reported by
//! `tet_ids()` — and cut into fixed blocks of consecutive tets. The block size
//! depends only on the number of tets (never on the thread count), and is a
//! multiple of [`LANES`], so that batches of `LANES` tets never straddle blocks.
//! Each block numbers the nodes it touches locally, in first-touch order, and
//! stores its tets with these local indices: evaluating a block gathers its node
//! positions into a small contiguous buffer (cache-resident whatever the global
//! node numbering, so shuffled meshes cost the same as sorted ones), runs the batch
//! kernel on it, and accumulates the forces in a local buffer.
//!
//! # Determinism
//! Blocks run in parallel (rayon) with private buffers; then every node sums the
//! contributions of the blocks that touch it **in block order** (a CSR list built
//! once), in parallel over nodes. Neither order depends on the number of threads,
//! so the forces and energy are bitwise identical for any thread count. They differ
//! from the plain serial kernel only by the order of the floating-point sums at
//! nodes (and by the round-off of the vectorisable `ln`/`exp`), i.e. to round-off.
//!
//! # SIMD
//! The batch kernels are written as fixed-size loops over lanes of plain `f64`
//! arithmetic; the block driver is compiled three times (AVX-512, AVX2+FMA, and the
//! baseline) and the best one the CPU supports is picked at run time
//! ([`SimdLevel::detect`]). Rust never contracts `a*b+c` into an FMA, so all three
//! give the same bits.

// The kernels index fixed-size lane arrays in lock-step on purpose (it is what
// vectorises); iterator chains over several arrays would obscure that.
#![allow(clippy::needless_range_loop)]

use crate::mesh::reorder::morton_tet_order;
use crate::mesh::TetMesh;
use crate::Vec3;
use rayon::prelude::*;
use std::sync::Mutex;

/// Tets per batch (SIMD lanes of the batch kernels).
pub const LANES: usize = 8;

/// The instruction set the block driver is compiled for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimdLevel {
    /// x86-64 AVX-512 (F, DQ, VL) with AVX2 and FMA.
    Avx512,
    /// x86-64 AVX2 with FMA.
    Avx2,
    /// The target's baseline (SSE2 on x86-64).
    Baseline,
}

impl SimdLevel {
    /// The best level this CPU supports (detected once, at run time).
    pub fn detect() -> SimdLevel {
        static LEVEL: std::sync::OnceLock<SimdLevel> = std::sync::OnceLock::new();
        *LEVEL.get_or_init(|| {
            // AVX-512 is opt-in (HEML_SIMD=avx512): on the AMD EPYC (Zen 4) machine
            // the kernels were tuned on, LLVM's AVX-512 code for them (gathers,
            // scatters, mask moves) measured slower than the AVX2 code.
            if let Ok(v) = std::env::var("HEML_SIMD") {
                match v.as_str() {
                    "baseline" => return SimdLevel::Baseline,
                    "avx2" if Self::has_avx2() => return SimdLevel::Avx2,
                    "avx512" if Self::has_avx512() => return SimdLevel::Avx512,
                    _ => {}
                }
            }
            if Self::has_avx2() {
                SimdLevel::Avx2
            } else {
                SimdLevel::Baseline
            }
        })
    }

    #[cfg(target_arch = "x86_64")]
    fn has_avx512() -> bool {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512dq")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && Self::has_avx2()
    }
    #[cfg(target_arch = "x86_64")]
    fn has_avx2() -> bool {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    fn has_avx512() -> bool {
        false
    }
    #[cfg(not(target_arch = "x86_64"))]
    fn has_avx2() -> bool {
        false
    }

    /// Name for reports.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Avx512 => "avx512",
            SimdLevel::Avx2 => "avx2+fma",
            SimdLevel::Baseline => "baseline",
        }
    }
}

/// Forces of the four corners of each lane, `[corner][xyz][lane]`.
pub type LaneForces = [[[f64; LANES]; 3]; 4];

/// A batch kernel: the per-tet physics of a field, evaluated `LANES` tets at a time.
pub trait BatchKernel: Sync {
    /// Energies and corner forces of the tets of batch `b` (field positions
    /// `b*LANES..`), whose node indices into `x` are `idx`. Lanes past the end of the
    /// field hold padding and may produce anything (they are never used).
    fn batch(&self, b: usize, idx: &[[u32; 4]; LANES], x: &[Vec3], f: &mut LaneForces, e: &mut [f64; LANES]);
}

/// One block of consecutive field tets.
#[derive(Debug, Clone)]
struct Block {
    /// First batch of the block.
    batch_start: usize,
    /// One past its last batch.
    batch_end: usize,
    /// Global ids of its local nodes.
    nodes: Vec<u32>,
}

#[derive(Debug, Default)]
struct Scratch {
    x: Vec<Vec<Vec3>>,
    f: Vec<Vec<Vec3>>,
    energy: Vec<f64>,
}

/// The tets of a field in its (Morton) order, in blocks with local node numbering.
#[derive(Debug)]
pub struct Layout {
    n_nodes: usize,
    n_tets: usize,
    /// Global tet id per field tet.
    pub ids: Vec<usize>,
    /// Local node indices per field tet, padded to a multiple of `LANES`.
    local: Vec<[u32; 4]>,
    blocks: Vec<Block>,
    /// CSR: for node i, `merge[merge_off[i]..merge_off[i+1]]` = (block, local index).
    merge_off: Vec<u32>,
    merge: Vec<(u32, u32)>,
    scratch: Mutex<Scratch>,
}

impl Clone for Layout {
    fn clone(&self) -> Self {
        Layout {
            n_nodes: self.n_nodes,
            n_tets: self.n_tets,
            ids: self.ids.clone(),
            local: self.local.clone(),
            blocks: self.blocks.clone(),
            merge_off: self.merge_off.clone(),
            merge: self.merge.clone(),
            scratch: Mutex::new(Scratch::default()),
        }
    }
}

/// Tets per block for a field of `n` tets: a multiple of `LANES`, from 512 to 4096,
/// about n/32 (enough blocks for load balance, few enough to keep the merge small).
fn block_size(n: usize) -> usize {
    let b = (n / 32).clamp(512, 4096);
    b.div_ceil(LANES) * LANES
}

impl Layout {
    /// The layout of the tets `sel` (global ids) of `mesh`, reordered when `reorder`.
    pub fn new(mesh: &TetMesh, sel: &[usize], reorder: bool) -> Layout {
        let ids: Vec<usize> = if reorder {
            morton_tet_order(mesh, sel).into_iter().map(|k| sel[k]).collect()
        } else {
            sel.to_vec()
        };
        let n = ids.len();
        let n_batches = n.div_ceil(LANES);
        let bs = block_size(n) / LANES;
        let mut local = vec![[0u32; 4]; n_batches * LANES];
        let mut blocks = Vec::new();
        let mut stamp = vec![u32::MAX; mesh.n_nodes()];
        let mut map = vec![0u32; mesh.n_nodes()];
        let mut start = 0;
        while start < n_batches {
            let end = (start + bs).min(n_batches);
            let b = blocks.len() as u32;
            let mut nodes = Vec::new();
            for k in start * LANES..(end * LANES).min(n) {
                for (a, &g) in mesh.tets()[ids[k]].iter().enumerate() {
                    let g = g as usize;
                    if stamp[g] != b {
                        stamp[g] = b;
                        map[g] = nodes.len() as u32;
                        nodes.push(g as u32);
                    }
                    local[k][a] = map[g];
                }
            }
            blocks.push(Block {
                batch_start: start,
                batch_end: end,
                nodes,
            });
            start = end;
        }
        // merge lists: contributions to each node in block order
        let mut count = vec![0u32; mesh.n_nodes() + 1];
        for blk in &blocks {
            for &g in &blk.nodes {
                count[g as usize + 1] += 1;
            }
        }
        for i in 0..mesh.n_nodes() {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut merge = vec![(0u32, 0u32); count[mesh.n_nodes()] as usize];
        for (b, blk) in blocks.iter().enumerate() {
            for (li, &g) in blk.nodes.iter().enumerate() {
                let p = &mut fill[g as usize];
                merge[*p as usize] = (b as u32, li as u32);
                *p += 1;
            }
        }
        Layout {
            n_nodes: mesh.n_nodes(),
            n_tets: n,
            ids,
            local,
            blocks,
            merge_off: count,
            merge,
            scratch: Mutex::new(Scratch::default()),
        }
    }

    /// Number of tets.
    pub fn n_tets(&self) -> usize {
        self.n_tets
    }

    /// Number of batches (`n_tets` rounded up to `LANES`).
    pub fn n_batches(&self) -> usize {
        self.local.len() / LANES
    }

    /// Global node indices of field tet `k`.
    #[inline]
    pub fn global_tet(&self, k: usize) -> [u32; 4] {
        let blk = &self.blocks[self.block_of(k)];
        self.local[k].map(|l| blk.nodes[l as usize])
    }

    fn block_of(&self, k: usize) -> usize {
        let b = k / LANES;
        self.blocks.partition_point(|blk| blk.batch_end <= b)
    }

    /// Heap bytes of the layout (indices, blocks, merge lists, scratch buffers).
    pub fn heap_bytes(&self) -> usize {
        let nodes: usize = self.blocks.iter().map(|b| b.nodes.len()).sum();
        self.ids.len() * 8
            + self.local.len() * 16
            + self.blocks.len() * std::mem::size_of::<Block>()
            + nodes * 4
            + self.merge_off.len() * 4
            + self.merge.len() * 8
            // scratch: local positions and forces of every block, once allocated
            + nodes * 2 * 24
            + self.blocks.len() * 8
    }

    /// Serial batched evaluation in field order over global indices: adds the forces
    /// to `f` tet by tet, corner by corner — the plain kernel's order of summation.
    pub fn add_serial<K: BatchKernel>(&self, k: &K, x: &[Vec3], f: &mut [Vec3]) -> f64 {
        let level = SimdLevel::detect();
        let mut energy = 0.0;
        for blk in &self.blocks {
            let local = &self.local[blk.batch_start * LANES..blk.batch_end * LANES];
            energy += run_block(level, k, blk.batch_start, local, Some(&blk.nodes), self.n_tets, x, f);
        }
        energy
    }

    /// Parallel blocked evaluation (see the module doc): adds the forces to `f` and
    /// returns the energy; the same bits for any number of rayon threads.
    pub fn add_parallel<K: BatchKernel>(&self, k: &K, x: &[Vec3], f: &mut [Vec3]) -> f64 {
        let level = SimdLevel::detect();
        let mut guard = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        let s = &mut *guard;
        if s.f.len() != self.blocks.len() {
            s.x = self.blocks.iter().map(|b| vec![Vec3::zeros(); b.nodes.len()]).collect();
            s.f = s.x.clone();
            s.energy = vec![0.0; self.blocks.len()];
        }
        let n_tets = self.n_tets;
        self.blocks
            .par_iter()
            .zip(s.x.par_iter_mut())
            .zip(s.f.par_iter_mut())
            .zip(s.energy.par_iter_mut())
            .with_max_len(1)
            .for_each(|(((blk, xl), fl), e)| {
                for (xi, &g) in xl.iter_mut().zip(&blk.nodes) {
                    *xi = x[g as usize];
                }
                fl.fill(Vec3::zeros());
                let local = &self.local[blk.batch_start * LANES..blk.batch_end * LANES];
                *e = run_block(level, k, blk.batch_start, local, None, n_tets, xl, fl);
            });
        let bufs: &[Vec<Vec3>] = &s.f;
        const CHUNK: usize = 2048;
        f.par_chunks_mut(CHUNK).enumerate().for_each(|(c, chunk)| {
            for (o, fi) in chunk.iter_mut().enumerate() {
                let i = c * CHUNK + o;
                let (lo, hi) = (self.merge_off[i] as usize, self.merge_off[i + 1] as usize);
                for &(b, li) in &self.merge[lo..hi] {
                    *fi += bufs[b as usize][li as usize];
                }
            }
        });
        s.energy.iter().sum()
    }
}

/// Runs the batches of one block with the driver compiled for `level`.
#[allow(clippy::too_many_arguments)]
fn run_block<K: BatchKernel>(
    level: SimdLevel,
    k: &K,
    batch0: usize,
    local: &[[u32; 4]],
    map: Option<&[u32]>,
    n_tets: usize,
    x: &[Vec3],
    f: &mut [Vec3],
) -> f64 {
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdLevel::detect` returns Avx512 only when the CPU reports
        // avx512f, avx512dq, avx512vl, avx2 and fma, the features this function enables.
        SimdLevel::Avx512 => unsafe { block_avx512(k, batch0, local, map, n_tets, x, f) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdLevel::detect` returns Avx2 only when the CPU reports avx2 and fma.
        SimdLevel::Avx2 => unsafe { block_avx2(k, batch0, local, map, n_tets, x, f) },
        _ => block_body(k, batch0, local, map, n_tets, x, f),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn block_avx512<K: BatchKernel>(
    k: &K,
    batch0: usize,
    local: &[[u32; 4]],
    map: Option<&[u32]>,
    n_tets: usize,
    x: &[Vec3],
    f: &mut [Vec3],
) -> f64 {
    block_body(k, batch0, local, map, n_tets, x, f)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn block_avx2<K: BatchKernel>(
    k: &K,
    batch0: usize,
    local: &[[u32; 4]],
    map: Option<&[u32]>,
    n_tets: usize,
    x: &[Vec3],
    f: &mut [Vec3],
) -> f64 {
    block_body(k, batch0, local, map, n_tets, x, f)
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn block_body<K: BatchKernel>(
    k: &K,
    batch0: usize,
    local: &[[u32; 4]],
    map: Option<&[u32]>,
    n_tets: usize,
    x: &[Vec3],
    f: &mut [Vec3],
) -> f64 {
    let mut energy = 0.0;
    let mut fl = [[[0.0; LANES]; 3]; 4];
    let mut el = [0.0; LANES];
    for (bo, idx) in local.chunks_exact(LANES).enumerate() {
        let b = batch0 + bo;
        let idx: &[[u32; 4]; LANES] = idx.try_into().expect("a batch has LANES tets");
        // with a map, local indices are translated to global ones (serial path)
        let idx: [[u32; 4]; LANES] = match map {
            Some(m) => std::array::from_fn(|l| idx[l].map(|i| m[i as usize])),
            None => *idx,
        };
        k.batch(b, &idx, x, &mut fl, &mut el);
        let count = (n_tets - b * LANES).min(LANES);
        for l in 0..count {
            energy += el[l];
            for (a, &i) in idx[l].iter().enumerate() {
                let fi = &mut f[i as usize];
                fi.x += fl[a][0][l];
                fi.y += fl[a][1][l];
                fi.z += fl[a][2][l];
            }
        }
    }
    energy
}
