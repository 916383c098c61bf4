//! Batched, parallel, deterministic assembly shared by the optimised HEML and P1 paths.
//!
//! # Layout
//! A field's tets are put in Morton order of their centroids (see
//! [`crate::mesh::reorder`]) — this *is* the field's order, reported by
//! `tet_ids()` — and cut into fixed blocks of consecutive tets. The block size
//! depends only on the number of tets (never on the thread count), and is a
//! multiple of [`LANES`], so that batches of `LANES` tets never straddle blocks.
//! Each block numbers the nodes it touches locally, in increasing global order, and
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
//! The batch kernels are written as fixed-size loops over [`LANES`] lanes of plain
//! `f64` arithmetic. The block driver moves data between the blocks' per-node
//! buffers (each node padded to 32 bytes) and the kernels' lanes: with AVX2, one
//! aligned vector load per node and corner and a 4×4 transpose (and back for the
//! forces), instead of three scalar loads and a bounds check each. The driver is
//! compiled three times (AVX-512, AVX2+FMA, and the baseline) and the best one the
//! CPU supports is picked at run time ([`SimdLevel::detect`]). Rust never contracts
//! `a*b+c` into an FMA and all three sum in the same order, so all three give the
//! same bits (tested).
//!
//! Four lanes (one AVX2 register per lane array) measured faster than eight: the
//! kernels' intermediate arrays then fit the 16 registers with fewer spills
//! (neo-Hookean 156 against 177 instructions per tet, callgrind; 6 % less time,
//! Mooney–Rivlin 12 %).

// The kernels index fixed-size lane arrays in lock-step on purpose (it is what
// vectorises); iterator chains over several arrays would obscure that.
#![allow(clippy::needless_range_loop)]

use super::{check_sizes, ForceOptions};
use crate::error::Result;
use crate::mesh::reorder::morton_tet_order;
use crate::mesh::TetMesh;
use crate::Vec3;
use rayon::prelude::*;
use std::sync::Mutex;

/// Tets per batch (SIMD lanes of the batch kernels).
pub const LANES: usize = 4;

thread_local! {
    static FORCED_LEVEL: std::cell::Cell<Option<SimdLevel>> = const { std::cell::Cell::new(None) };
}

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

    /// The levels this CPU can run, best first (AVX-512 included when supported,
    /// although [`Self::detect`] only picks it on request).
    pub fn available() -> Vec<SimdLevel> {
        let mut v = Vec::new();
        if Self::has_avx512() {
            v.push(SimdLevel::Avx512);
        }
        if Self::has_avx2() {
            v.push(SimdLevel::Avx2);
        }
        v.push(SimdLevel::Baseline);
        v
    }

    /// Runs `f` with the batched and parallel kernels started from this thread
    /// using this level instead of the detected one: for tests and benchmarks that
    /// compare the instruction sets. `None` when the CPU cannot run it.
    pub fn run_with<R>(self, f: impl FnOnce() -> R) -> Option<R> {
        if !Self::available().contains(&self) {
            return None;
        }
        let previous = FORCED_LEVEL.with(|c| c.replace(Some(self)));
        // restored even if `f` panics
        struct Restore(Option<SimdLevel>);
        impl Drop for Restore {
            fn drop(&mut self) {
                FORCED_LEVEL.with(|c| c.set(self.0));
            }
        }
        let _restore = Restore(previous);
        Some(f())
    }

    /// The level the kernels use on this thread: forced by [`Self::run_with`], or
    /// detected.
    fn current() -> SimdLevel {
        FORCED_LEVEL.with(|c| c.get()).unwrap_or_else(SimdLevel::detect)
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

/// Positions of the four corners of each lane, `[corner][xyz][lane]`.
pub type LanePoints = [[[f64; LANES]; 3]; 4];

/// A batch kernel: the per-tet physics of a field, evaluated `LANES` tets at a time.
pub trait BatchKernel: Sync {
    /// Energies and corner forces of the tets of batch `b` (field positions
    /// `b*LANES..`), whose corner positions are `p`. Lanes past the end of the field
    /// hold padding and may produce anything (they are never used).
    fn batch(&self, b: usize, p: &LanePoints, f: &mut LaneForces, e: &mut [f64; LANES]);
}

/// A node position or force padded to four `f64` (32-byte aligned), so that one
/// aligned vector load or store moves a whole node in the SIMD gather and scatter.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(32))]
struct Node4([f64; 4]);

impl Node4 {
    fn from_vec(v: &Vec3) -> Node4 {
        Node4([v.x, v.y, v.z, 0.0])
    }
    fn to_vec(self) -> Vec3 {
        Vec3::new(self.0[0], self.0[1], self.0[2])
    }
}

/// A batch kernel's data besides the positions: the law, the force options and the
/// field's rest data, one entry per batch. The HEML and P1 fields implement
/// [`BatchKernel`] on it for their own rest data type.
pub(crate) struct LawBatches<'a, M, R> {
    pub law: &'a M,
    pub opts: ForceOptions,
    pub rest: &'a [R],
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
    /// Slot of its first local node in the scratch buffers (the blocks' local nodes
    /// lie one block after the other there).
    slot0: usize,
}

/// The blocks' local node positions and forces, block after block in two flat
/// buffers (one indirection for the merge), and their energies; kept between calls.
#[derive(Debug, Default)]
struct Scratch {
    x: Vec<Node4>,
    f: Vec<Node4>,
    energy: Vec<f64>,
}

/// The tets of a field in its (Morton) order, in blocks with local node numbering.
#[derive(Debug)]
pub struct Layout {
    n_nodes: usize,
    n_tets: usize,
    /// Global tet id per field tet.
    pub ids: Vec<usize>,
    /// Local node indices per field tet (a block has fewer than 2^16 nodes), padded
    /// to a multiple of `LANES`.
    local: Vec<[u16; 4]>,
    blocks: Vec<Block>,
    /// CSR: for node i, `merge[merge_off[i]..merge_off[i+1]]` = the scratch slots of
    /// its copies, in block order.
    merge_off: Vec<u32>,
    merge: Vec<u32>,
    /// Local nodes of all blocks (scratch slots).
    n_slots: usize,
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
            n_slots: self.n_slots,
            scratch: Mutex::new(Scratch::default()),
        }
    }
}

/// Most tets in a block: its at most 4 × this many local nodes fit in a `u16`.
const MAX_BLOCK: usize = 4096;

/// Tets per block for a field of `n` tets: a multiple of `LANES`, from 512 to
/// [`MAX_BLOCK`], about n/32 (enough blocks for load balance, few enough to keep the
/// merge small).
fn block_size(n: usize) -> usize {
    let b = (n / 32).clamp(512, MAX_BLOCK);
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
        const _: () = assert!(4 * MAX_BLOCK <= u16::MAX as usize + 1);
        let mut local = vec![[0u16; 4]; n_batches * LANES];
        let mut blocks = Vec::new();
        let mut stamp = vec![u32::MAX; mesh.n_nodes()];
        let mut map = vec![0u16; mesh.n_nodes()];
        let mut start = 0;
        let mut n_slots = 0;
        while start < n_batches {
            let end = (start + bs).min(n_batches);
            let b = blocks.len() as u32;
            let mut nodes = Vec::new();
            for k in start * LANES..(end * LANES).min(n) {
                for &g in &mesh.tets()[ids[k]] {
                    if stamp[g as usize] != b {
                        stamp[g as usize] = b;
                        nodes.push(g);
                    }
                }
            }
            // local numbering in global order: copying positions in and merging
            // forces out then walk memory forwards, whatever order the tets touch
            // the nodes in (and the sums are the same: only the slots move)
            nodes.sort_unstable();
            for (li, &g) in nodes.iter().enumerate() {
                map[g as usize] = li as u16;
            }
            for k in start * LANES..(end * LANES).min(n) {
                for (a, &g) in mesh.tets()[ids[k]].iter().enumerate() {
                    local[k][a] = map[g as usize];
                }
            }
            let slot0 = n_slots;
            n_slots += nodes.len();
            blocks.push(Block {
                batch_start: start,
                batch_end: end,
                nodes,
                slot0,
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
        let mut merge = vec![0u32; count[mesh.n_nodes()] as usize];
        for blk in &blocks {
            for (li, &g) in blk.nodes.iter().enumerate() {
                let p = &mut fill[g as usize];
                merge[*p as usize] = (blk.slot0 + li) as u32;
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
            n_slots,
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

    /// Bytes per tet of a field with this layout and `rest` (its per-batch rest
    /// data): rest data, indices, blocks, merge lists and the scratch buffers.
    pub fn bytes_per_tet<R>(&self, rest: &[R]) -> f64 {
        let bytes = std::mem::size_of_val(rest) + self.heap_bytes();
        bytes as f64 / self.n_tets.max(1) as f64
    }

    /// Heap bytes of the layout (indices, blocks, merge lists, scratch buffers).
    pub fn heap_bytes(&self) -> usize {
        let nodes: usize = self.blocks.iter().map(|b| b.nodes.len()).sum();
        self.ids.len() * std::mem::size_of::<usize>()
            + self.local.len() * std::mem::size_of::<[u16; 4]>()
            + self.blocks.len() * std::mem::size_of::<Block>()
            + nodes * 4
            + self.merge_off.len() * 4
            + self.merge.len() * 4
            // scratch: local positions and forces of every block, once allocated
            + nodes * 2 * std::mem::size_of::<Node4>()
            + self.blocks.len() * 8
    }

    /// Adds the forces of kernel `k` at `x` to `f` and returns the energy, after
    /// checking the buffer sizes: the blocks on rayon when `parallel` (see the module
    /// doc), else one after the other on this thread; the same merge, so the same
    /// bits either way.
    pub fn add_batched<K: BatchKernel>(&self, k: &K, parallel: bool, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        Ok(self.evaluate(k, x, f, parallel))
    }

    /// Adds the forces of the plain serial kernel `tet` (energy and the four corner
    /// forces of field tet `k`, whose global nodes are `idx`) to `f`, one tet at a time
    /// in field order, node by node, and returns the energy: the reference path of the
    /// HEML and link fields.
    pub fn add_plain(
        &self,
        x: &[Vec3],
        f: &mut [Vec3],
        tet: impl Fn(usize, &[u32; 4]) -> (f64, [Vec3; 4]),
    ) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut energy = 0.0;
        for k in 0..self.n_tets {
            let idx = self.global_tet(k);
            let (e, fk) = tet(k, &idx);
            energy += e;
            for (a, &i) in idx.iter().enumerate() {
                f[i as usize] += fk[a];
            }
        }
        Ok(energy)
    }

    fn evaluate<K: BatchKernel>(&self, k: &K, x: &[Vec3], f: &mut [Vec3], parallel: bool) -> f64 {
        let level = SimdLevel::current();
        let mut guard = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        let s = &mut *guard;
        if s.f.len() != self.n_slots || s.energy.len() != self.blocks.len() {
            s.x = vec![Node4::default(); self.n_slots];
            s.f = s.x.clone();
            s.energy = vec![0.0; self.blocks.len()];
        }
        // each block's own part of the flat buffers
        type Task<'a> = (&'a Block, &'a mut [Node4], &'a mut [Node4], &'a mut f64);
        let mut tasks: Vec<Task> = Vec::with_capacity(self.blocks.len());
        let (mut xs, mut fs) = (&mut s.x[..], &mut s.f[..]);
        for (blk, e) in self.blocks.iter().zip(s.energy.iter_mut()) {
            let (xl, xr) = std::mem::take(&mut xs).split_at_mut(blk.nodes.len());
            let (fl, fr) = std::mem::take(&mut fs).split_at_mut(blk.nodes.len());
            (xs, fs) = (xr, fr);
            tasks.push((blk, xl, fl, e));
        }
        let n_tets = self.n_tets;
        let one = |(blk, xl, fl, e): Task| {
            for (xi, &g) in xl.iter_mut().zip(&blk.nodes) {
                *xi = Node4::from_vec(&x[g as usize]);
            }
            fl.fill(Node4::default());
            let local = &self.local[blk.batch_start * LANES..blk.batch_end * LANES];
            *e = run_block(level, k, blk.batch_start, local, blk.nodes.len(), n_tets, xl, fl);
        };
        if parallel {
            tasks.into_par_iter().with_max_len(1).for_each(one);
        } else {
            tasks.into_iter().for_each(one);
        }
        let bufs: &[Node4] = &s.f;
        let merge = |(c, chunk): (usize, &mut [Vec3])| {
            for (o, fi) in chunk.iter_mut().enumerate() {
                let i = c * MERGE_CHUNK + o;
                let (lo, hi) = (self.merge_off[i] as usize, self.merge_off[i + 1] as usize);
                for &slot in &self.merge[lo..hi] {
                    *fi += bufs[slot as usize].to_vec();
                }
            }
        };
        if parallel {
            f.par_chunks_mut(MERGE_CHUNK).enumerate().for_each(merge);
        } else {
            f.chunks_mut(MERGE_CHUNK).enumerate().for_each(merge);
        }
        s.energy.iter().sum()
    }
}

/// Nodes per parallel task of the merge.
const MERGE_CHUNK: usize = 2048;

/// Runs the batches of one block with the driver compiled for `level`.
#[allow(clippy::too_many_arguments)]
fn run_block<K: BatchKernel>(
    level: SimdLevel,
    k: &K,
    batch0: usize,
    local: &[[u16; 4]],
    nodes: usize,
    n_tets: usize,
    x: &[Node4],
    f: &mut [Node4],
) -> f64 {
    check_local(local, nodes, x.len(), f.len());
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdLevel::detect` returns Avx512 only when the CPU reports
        // avx512f, avx512dq, avx512vl, avx2 and fma, the features this function
        // enables; the indices the gather and scatter use are in bounds (`check_local`).
        SimdLevel::Avx512 => unsafe { block_avx512(k, batch0, local, n_tets, x, f) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdLevel::detect` returns Avx2 only when the CPU reports avx2 and
        // fma; the indices the gather and scatter use are in bounds (`check_local`).
        SimdLevel::Avx2 => unsafe { block_avx2(k, batch0, local, n_tets, x, f) },
        _ => block_body::<K, Portable>(k, batch0, local, n_tets, x, f),
    }
}

/// The buffers of a block hold its nodes. With the invariant of [`Layout::new`]
/// (every local index of a block is below its node count), every index the SIMD
/// gather and scatter use is in bounds.
#[inline]
fn check_local(local: &[[u16; 4]], nodes: usize, nx: usize, nf: usize) {
    assert!(
        local.len().is_multiple_of(LANES) && nx == nodes && nf == nodes,
        "force layout: block buffers of {nx} and {nf} nodes for a block of {nodes}"
    );
}

/// The block driver compiled with `$features` enabled (the SIMD gather and scatter
/// need AVX2 at least).
macro_rules! block_with_features {
    ($name:ident, $features:literal) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        unsafe fn $name<K: BatchKernel>(
            k: &K,
            batch0: usize,
            local: &[[u16; 4]],
            n_tets: usize,
            x: &[Node4],
            f: &mut [Node4],
        ) -> f64 {
            block_body::<K, simd_x86::Avx2>(k, batch0, local, n_tets, x, f)
        }
    };
}
block_with_features!(block_avx512, "avx512f,avx512dq,avx512vl,avx2,fma");
block_with_features!(block_avx2, "avx2,fma");

/// Moves one batch's corner positions in and corner forces out: between the
/// per-node AoS buffers of a block and the SoA lanes of the kernels.
trait LaneIo {
    /// `p[a][c][l] = x[idx[l][a]][c]`.
    fn gather(idx: &[[u16; 4]; LANES], x: &[Node4], p: &mut LanePoints);
    /// `f[idx[l][a]][c] += fl[a][c][l]` for every lane, in lane order.
    fn scatter(idx: &[[u16; 4]; LANES], fl: &LaneForces, f: &mut [Node4]);
}

/// Plain indexed loads and stores (the baseline target).
struct Portable;

impl LaneIo for Portable {
    #[inline(always)]
    fn gather(idx: &[[u16; 4]; LANES], x: &[Node4], p: &mut LanePoints) {
        for l in 0..LANES {
            for a in 0..4 {
                let q = &x[idx[l][a] as usize].0;
                for c in 0..3 {
                    p[a][c][l] = q[c];
                }
            }
        }
    }
    #[inline(always)]
    fn scatter(idx: &[[u16; 4]; LANES], fl: &LaneForces, f: &mut [Node4]) {
        // corner by corner, then lane by lane: the order of the SIMD scatter, so
        // that every instruction set gives the same bits
        for a in 0..4 {
            for l in 0..LANES {
                let q = &mut f[idx[l][a] as usize].0;
                for c in 0..3 {
                    q[c] += fl[a][c][l];
                }
            }
        }
    }
}

/// Adds the four corner forces of lane `l` to `f`.
#[inline(always)]
fn scatter_lane(idx: &[[u16; 4]; LANES], fl: &LaneForces, f: &mut [Node4], l: usize) {
    for a in 0..4 {
        let q = &mut f[idx[l][a] as usize].0;
        for c in 0..3 {
            q[c] += fl[a][c][l];
        }
    }
}

/// Gather and scatter with AVX2 4×4 transposes: one aligned load or store per node
/// and corner instead of three scalar ones plus a bounds check each.
#[cfg(target_arch = "x86_64")]
mod simd_x86 {
    use super::{LaneForces, LaneIo, LanePoints, Node4, LANES};
    use std::arch::x86_64::*;

    pub struct Avx2;

    impl LaneIo for Avx2 {
        #[inline(always)]
        fn gather(idx: &[[u16; 4]; LANES], x: &[Node4], p: &mut LanePoints) {
            // SAFETY: only reached from `block_avx2`/`block_avx512` (AVX2 enabled),
            // and every index is < x.len() (`check_local`).
            unsafe { gather(idx, x, p) }
        }
        #[inline(always)]
        fn scatter(idx: &[[u16; 4]; LANES], fl: &LaneForces, f: &mut [Node4]) {
            // SAFETY: as for `gather`, with every index < f.len().
            unsafe { scatter(idx, fl, f) }
        }
    }

    #[inline(always)]
    unsafe fn gather(idx: &[[u16; 4]; LANES], x: &[Node4], p: &mut LanePoints) {
        let base = x.as_ptr() as *const f64;
        for a in 0..4 {
            for h in 0..LANES / 4 {
                let i = &idx[4 * h..4 * h + 4];
                let r0 = _mm256_load_pd(base.add(4 * i[0][a] as usize));
                let r1 = _mm256_load_pd(base.add(4 * i[1][a] as usize));
                let r2 = _mm256_load_pd(base.add(4 * i[2][a] as usize));
                let r3 = _mm256_load_pd(base.add(4 * i[3][a] as usize));
                let t0 = _mm256_unpacklo_pd(r0, r1); // x0 x1 z0 z1
                let t1 = _mm256_unpackhi_pd(r0, r1); // y0 y1 .. ..
                let t2 = _mm256_unpacklo_pd(r2, r3); // x2 x3 z2 z3
                let t3 = _mm256_unpackhi_pd(r2, r3); // y2 y3 .. ..
                let out = &mut p[a];
                _mm256_storeu_pd(out[0][4 * h..].as_mut_ptr(), _mm256_permute2f128_pd(t0, t2, 0x20));
                _mm256_storeu_pd(out[1][4 * h..].as_mut_ptr(), _mm256_permute2f128_pd(t1, t3, 0x20));
                _mm256_storeu_pd(out[2][4 * h..].as_mut_ptr(), _mm256_permute2f128_pd(t0, t2, 0x31));
            }
        }
    }

    #[inline(always)]
    unsafe fn scatter(idx: &[[u16; 4]; LANES], fl: &LaneForces, f: &mut [Node4]) {
        let base = f.as_mut_ptr() as *mut f64;
        let zero = _mm256_setzero_pd();
        for a in 0..4 {
            for h in 0..LANES / 4 {
                let x = _mm256_loadu_pd(fl[a][0][4 * h..].as_ptr());
                let y = _mm256_loadu_pd(fl[a][1][4 * h..].as_ptr());
                let z = _mm256_loadu_pd(fl[a][2][4 * h..].as_ptr());
                let t0 = _mm256_unpacklo_pd(x, y); // x0 y0 x2 y2
                let t1 = _mm256_unpackhi_pd(x, y); // x1 y1 x3 y3
                let t2 = _mm256_unpacklo_pd(z, zero); // z0 0 z2 0
                let t3 = _mm256_unpackhi_pd(z, zero); // z1 0 z3 0
                let rows = [
                    _mm256_permute2f128_pd(t0, t2, 0x20),
                    _mm256_permute2f128_pd(t1, t3, 0x20),
                    _mm256_permute2f128_pd(t0, t2, 0x31),
                    _mm256_permute2f128_pd(t1, t3, 0x31),
                ];
                // lane by lane: two lanes may share a node
                for (l, r) in rows.into_iter().enumerate() {
                    let q = base.add(4 * idx[4 * h + l][a] as usize);
                    _mm256_store_pd(q, _mm256_add_pd(_mm256_load_pd(q), r));
                }
            }
        }
    }
}

/// The batches of one block: gather, kernel, scatter (all lanes at once for full
/// batches, lane by lane for the padded last one).
#[inline(always)]
fn block_body<K: BatchKernel, IO: LaneIo>(
    k: &K,
    batch0: usize,
    local: &[[u16; 4]],
    n_tets: usize,
    x: &[Node4],
    f: &mut [Node4],
) -> f64 {
    let mut energy = 0.0;
    let mut p = [[[0.0; LANES]; 3]; 4];
    let mut fl = [[[0.0; LANES]; 3]; 4];
    let mut el = [0.0; LANES];
    for (bo, idx) in local.chunks_exact(LANES).enumerate() {
        let b = batch0 + bo;
        let idx: &[[u16; 4]; LANES] = idx.try_into().expect("a batch has LANES tets");
        IO::gather(idx, x, &mut p);
        k.batch(b, &p, &mut fl, &mut el);
        let count = (n_tets - b * LANES).min(LANES);
        if count == LANES {
            IO::scatter(idx, &fl, f);
            for l in 0..LANES {
                energy += el[l];
            }
        } else {
            for l in 0..count {
                energy += el[l];
                scatter_lane(idx, &fl, f, l);
            }
        }
    }
    energy
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_of_about;
    use crate::mesh::reorder::Permutation;

    /// A box of about `n` tets with its nodes numbered at random, so that the order
    /// in which a block's tets first touch its nodes is far from the global order.
    fn shuffled_box(n: usize) -> TetMesh {
        let mesh = box_of_about(n).unwrap();
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut order: Vec<usize> = (0..mesh.n_nodes()).collect();
        for i in (1..order.len()).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            order.swap(i, (state % (i as u64 + 1)) as usize);
        }
        let tets = Permutation::identity(mesh.n_tets());
        mesh.renumbered(&Permutation::from_new_to_old(order), &tets).unwrap()
    }

    #[test]
    fn blocks_number_their_nodes_in_global_order() {
        let mesh = shuffled_box(5000);
        let sel: Vec<usize> = (0..mesh.n_tets()).collect();
        let lay = Layout::new(&mesh, &sel, true);
        assert!(lay.blocks.len() > 2, "the test needs several blocks");
        for blk in &lay.blocks {
            assert!(blk.nodes.windows(2).all(|w| w[0] < w[1]), "block nodes not increasing");
        }
        // the local indices still name each tet's own nodes, corner by corner
        for k in 0..lay.n_tets() {
            assert_eq!(lay.global_tet(k), mesh.tets()[lay.ids[k]], "field tet {k}");
        }
        // every copy of a node is merged exactly once: the merge lists hold every
        // scratch slot once, each under the node it copies
        let mut seen = vec![false; lay.n_slots];
        for i in 0..mesh.n_nodes() {
            for &slot in &lay.merge[lay.merge_off[i] as usize..lay.merge_off[i + 1] as usize] {
                let blk = lay.blocks.iter().rfind(|b| b.slot0 <= slot as usize).unwrap();
                assert_eq!(blk.nodes[slot as usize - blk.slot0] as usize, i);
                assert!(!std::mem::replace(&mut seen[slot as usize], true), "slot {slot} twice");
            }
        }
        assert!(seen.iter().all(|&s| s), "a slot is never merged");
    }
}
