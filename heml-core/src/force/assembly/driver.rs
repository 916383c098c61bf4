//! The block driver: evaluates a batch kernel block by block (in parallel or on
//! this thread), each block gathering its nodes, running its batches and scattering
//! into private buffers, then merges the blocks' forces node by node in block order.

// The lanes are indexed in lock-step on purpose (it is what vectorises).
#![allow(clippy::needless_range_loop)]

#[cfg(target_arch = "x86_64")]
use super::lane_io::Avx2;
use super::lane_io::{scatter_lane, LaneIo, LaneScalars, Node4, Portable};
use super::layout::{Block, BlockBuffers, Layout, LocalBatch, LANES};
use super::simd::Isa;
use crate::error::Result;
use crate::force::field::check_sizes;
use crate::Vec3;

/// Forces of the four corners of each lane, `[corner][xyz][lane]`.
pub(crate) type LaneForces = [[[f64; LANES]; 3]; 4];

/// Positions of the four corners of each lane, `[corner][xyz][lane]`.
pub(crate) type LanePoints = [[[f64; LANES]; 3]; 4];

/// A batch kernel: the per-tet physics of a field, evaluated `LANES` tets at a time.
pub(crate) trait BatchKernel: Sync {
    /// Energies and corner forces of the tets of batch `b` (field positions
    /// `b*LANES..`), whose corner positions are `p`. Lanes past the end of the field
    /// hold padding and may produce anything (they are never used).
    fn batch(&self, b: usize, p: &LanePoints, f: &mut LaneForces, e: &mut [f64; LANES]);

    /// Whether a forces-only pass runs the driver variant that never reads the
    /// energy lanes ([`super::super::kernel::TetKernel::SKIPS_ENERGY`]); otherwise it
    /// runs the usual one and drops the energy.
    const SKIPS_ENERGY: bool = false;

    /// Whether the driver calls [`Self::batch_w`] (with one scalar per node,
    /// [`Layout::add_batched_lumped`]) instead of [`Self::batch`].
    const USES_W: bool = false;

    /// As [`Self::batch`], with `w[a][l]` the node scalar of corner `a` of lane `l`,
    /// gathered with the positions (the padding slot of the block's node buffer):
    /// the nodal pressures of the anti-locking term, at no second gather.
    #[inline(always)]
    fn batch_w(&self, b: usize, p: &LanePoints, w: &LaneScalars, f: &mut LaneForces, e: &mut [f64; LANES]) {
        let _ = w;
        self.batch(b, p, f, e)
    }

    /// Whether the driver runs each block in two phases: [`Self::pre_batch`] over
    /// its batches, then [`Self::between`] on their per-lane results, then
    /// [`Self::batch_s`] over the batches again (on the positions the block
    /// gathered already, still in L1): the patch volumetric term, whose pressures
    /// need the volumes of a patch's tets, all in the block.
    const TWO_PHASE: bool = false;

    /// Phase 1 of a two-phase kernel: one number per lane of batch `b` from its
    /// corner positions `p` (the tets' volumes). The driver then multiplies it by the
    /// tet's weight and sets it to 0 for removed and padding lanes.
    #[inline(always)]
    fn pre_batch(&self, b: usize, p: &LanePoints, s: &mut [f64; LANES]) {
        let _ = (b, p);
        *s = [0.0; LANES];
    }

    /// Between the phases: turns the block's phase-1 numbers `s` (one array per
    /// batch, from batch `batch0`) in place into the per-lane inputs of phase 2, and
    /// returns an energy (the block's patch energies).
    #[inline(always)]
    fn between(&self, batch0: usize, s: &mut [[f64; LANES]]) -> f64 {
        let _ = (batch0, s);
        0.0
    }

    /// Phase 2 of a two-phase kernel: as [`Self::batch`], with `s` the lanes'
    /// inputs from [`Self::between`].
    #[inline(always)]
    fn batch_s(&self, b: usize, p: &LanePoints, s: &[f64; LANES], f: &mut LaneForces, e: &mut [f64; LANES]) {
        let _ = s;
        self.batch(b, p, f, e)
    }
}

/// The plain per-tet kernel of a field, for the reference path.
pub(crate) trait PlainKernel {
    /// Energy of field tet `k`, whose corner positions are `p`; its nodal forces go
    /// to `add(corner, force)`, in the order the kernel defines.
    fn tet(&self, k: usize, p: &[Vec3; 4], add: impl FnMut(usize, Vec3)) -> f64;
}

/// The blocks' local node positions and forces, block after block in two flat
/// buffers (one indirection for the merge), and their energies; kept between calls.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    pub(super) x: Vec<Node4>,
    pub(super) f: Vec<Node4>,
    energy: Vec<f64>,
    /// One scalar per slot, for [`Layout::lumped_volumes`].
    pub(super) lumped: Vec<f64>,
    /// One array per batch, for two-phase kernels ([`BatchKernel::TWO_PHASE`]).
    lanes: Vec<[f64; LANES]>,
}

impl Scratch {
    /// Sizes the buffers for `n_slots` local nodes in `n_blocks` blocks, and the
    /// lumped accumulators when `lumped`, keeping those already of the right size
    /// (so that a sweep's positions survive into the pass that follows it:
    /// [`Layout::add_batched_lumped`]).
    pub(super) fn ensure(&mut self, n_slots: usize, n_blocks: usize, lumped: bool) {
        if self.x.len() != n_slots || self.f.len() != n_slots {
            self.x = vec![Node4::default(); n_slots];
            self.f = self.x.clone();
        }
        if self.energy.len() != n_blocks {
            self.energy = vec![0.0; n_blocks];
        }
        if lumped && self.lumped.len() != n_slots {
            self.lumped = vec![0.0; n_slots];
        }
    }
}

/// How a pass fills the blocks' local node buffers.
#[derive(Clone, Copy)]
enum Gather<'a> {
    /// The positions.
    Positions,
    /// One scalar per node in the padding slots only: the positions are there
    /// already (the lumped sweep of the same call put them there).
    WOnly(&'a [f64]),
}

/// Nodes per parallel task of the merge.
pub(super) const MERGE_CHUNK: usize = 2048;

impl Layout {
    /// Adds the forces of kernel `k` at `x` to `f` and returns the energy, after
    /// checking the buffer sizes: the blocks on rayon when `parallel` (see the module
    /// doc), else one after the other on this thread; the same merge, so the same
    /// bits either way.
    pub(crate) fn add_batched<K: BatchKernel>(&self, k: &K, parallel: bool, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut guard = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        Ok(self.evaluate(&mut guard, k, x, Gather::Positions, f, parallel, Energy::Summed))
    }

    /// As [`Self::add_batched`] without the energy: on the AVX2 driver the kernel's
    /// energy lanes are then never read, so the compiler drops the arithmetic that
    /// only they need (a law's `ln J` when its forces use only 1/J, as
    /// Holzapfel–Gasser–Ogden's). The forces are the same bits: the same operations
    /// make them, and no multiply-add is contracted (Rust never does).
    pub(crate) fn add_batched_forces<K: BatchKernel>(
        &self,
        k: &K,
        parallel: bool,
        x: &[Vec3],
        f: &mut [Vec3],
    ) -> Result<()> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut guard = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        self.evaluate(&mut guard, k, x, Gather::Positions, f, parallel, Energy::Skipped);
        Ok(())
    }

    /// The lumped volumes at `x` ([`Self::lumped_volumes`]), turned in place into one
    /// scalar per node by `to_w` (which returns an energy), then the pass of `k`
    /// with those scalars ([`BatchKernel::batch_w`]); returns both energies. One
    /// gather of the positions serves both passes: the sweep leaves them in the
    /// blocks' buffers and the pass only writes the scalars beside them, under one
    /// lock of the scratch (so no other call can move them in between).
    pub(crate) fn add_batched_lumped<K: BatchKernel>(
        &self,
        k: &K,
        parallel: bool,
        x: &[Vec3],
        to_w: impl FnOnce(&mut [f64]) -> f64,
        f: &mut [Vec3],
    ) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut guard = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        let mut w = vec![0.0; self.n_nodes];
        self.lumped_in(&mut guard, x, parallel, &mut w);
        let e = to_w(&mut w);
        Ok(e + self.evaluate(&mut guard, k, x, Gather::WOnly(&w), f, parallel, Energy::Summed))
    }

    /// Adds the forces of the plain kernel `k` to `f`, one tet at a time in field
    /// order, each force added to its node as the kernel hands it over, and returns
    /// the energy: the reference path of every field.
    pub(crate) fn add_plain<K: PlainKernel>(&self, k: &K, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut energy = 0.0;
        for t in self.live_positions() {
            let idx = self.global_tet(t);
            let p = crate::mesh::corners(x, &idx);
            // the tet's weight (1 unless tets overlap; ×1 is exact)
            let w = self.weight(t);
            energy += w * k.tet(t, &p, |a, fa| f[idx[a] as usize] += w * fa);
        }
        Ok(energy)
    }

    /// Adds the blocks' private forces `bufs` into `f`, node by node in block order
    /// (outside the generic pass: the same loop for every kernel).
    fn merge_forces(&self, bufs: &[Node4], f: &mut [Vec3], parallel: bool) {
        crate::parallel::for_each_chunk_mut(f, MERGE_CHUNK, parallel, &|c, chunk| {
            for (o, fi) in chunk.iter_mut().enumerate() {
                let i = c * MERGE_CHUNK + o;
                let (lo, hi) = (self.merge_off[i] as usize, self.merge_off[i + 1] as usize);
                for &slot in &self.merge[lo..hi] {
                    *fi += bufs[slot as usize].to_vec();
                }
            }
        });
    }

    /// One pass of kernel `k`: [`Self::run_blocks`] with the kernel's work on each
    /// block as its body. Only this shell is compiled per kernel; the gathers, the
    /// task list, the parallel loop and the merge are compiled once.
    #[allow(clippy::too_many_arguments)] // the pass's inputs, each its own kind
    fn evaluate<K: BatchKernel>(
        &self,
        s: &mut Scratch,
        k: &K,
        x: &[Vec3],
        gather: Gather,
        f: &mut [Vec3],
        parallel: bool,
        energy: Energy,
    ) -> f64 {
        let isa = Isa::current();
        let n_tets = self.n_tets();
        let body = |blk: &Block, bufs: BlockBuffers, lanes: &mut [[f64; LANES]]| {
            let dead = &self.dead[blk.batch_start..blk.batch_end];
            let weights = self.weights.as_ref().map(|w| &w[blk.batch_start..blk.batch_end]);
            run_block(isa, energy, k, blk.batch_start, n_tets, dead, weights, bufs, lanes)
        };
        self.run_blocks(s, x, gather, f, parallel, energy, K::TWO_PHASE, &body)
    }

    /// Runs `body` on every block (its tets' energy returned), each with its
    /// gathered node buffers and, when `two_phase`, its slice of per-batch lanes:
    /// on rayon when `parallel`, else in order; then merges the blocks' forces into
    /// `f` and returns the energy (0 when `energy` is skipped).
    #[allow(clippy::too_many_arguments)] // the pass's inputs, each its own kind
    fn run_blocks(
        &self,
        s: &mut Scratch,
        x: &[Vec3],
        gather: Gather,
        f: &mut [Vec3],
        parallel: bool,
        energy: Energy,
        two_phase: bool,
        body: &BlockBody,
    ) -> f64 {
        let parallel = self.runs_parallel(parallel);
        let blocks = self.blocks.list();
        s.ensure(self.n_slots, blocks.len(), false);
        if two_phase && s.lanes.len() != self.n_batches() {
            s.lanes = vec![[0.0; LANES]; self.n_batches()];
        }
        // each block's own part of the flat buffers
        type Task<'a> = (usize, BlockBuffers<'a>, &'a mut f64, &'a mut [[f64; LANES]]);
        let mut tasks: Vec<Task> = Vec::with_capacity(blocks.len());
        let (mut xs, mut fs) = (&mut s.x[..], &mut s.f[..]);
        let mut ls = &mut s.lanes[..];
        for (b, e) in s.energy.iter_mut().enumerate() {
            let n = if two_phase {
                blocks[b].batch_end - blocks[b].batch_start
            } else {
                0
            };
            let (mine, rest) = std::mem::take(&mut ls).split_at_mut(n);
            ls = rest;
            tasks.push((b, self.blocks.buffers(b, &mut xs, &mut fs), e, mine));
        }
        let one = |(b, mut bufs, e, lanes): Task| {
            let blk = &blocks[b];
            match gather {
                Gather::WOnly(w) => {
                    for (xi, &g) in bufs.x_mut().iter_mut().zip(&blk.nodes) {
                        xi.set_w(w[g as usize]);
                    }
                }
                Gather::Positions => {
                    for (xi, &g) in bufs.x_mut().iter_mut().zip(&blk.nodes) {
                        *xi = Node4::from_vec(&x[g as usize]);
                    }
                }
            }
            bufs.f_mut().fill(Node4::default());
            *e = body(blk, bufs, lanes);
        };
        crate::parallel::for_each_task(tasks, parallel, &one);
        self.merge_forces(&s.f, f, parallel);
        match energy {
            Energy::Summed => s.energy.iter().sum(),
            Energy::Skipped => 0.0,
        }
    }
}

/// A pass's work on one block: its gathered buffers and (two-phase kernels) its
/// per-batch lanes in, its tets' energy out.
type BlockBody<'k> = dyn Fn(&Block, BlockBuffers, &mut [[f64; LANES]]) -> f64 + Sync + 'k;

/// Whether a pass sums the tets' energies or only wants the forces.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Energy {
    /// Forces and the total energy.
    Summed,
    /// Forces only (the pass returns 0): explicit steps, which need no energy.
    Skipped,
}

/// Runs the batches of one block with the driver compiled for `isa` (`lanes`: the
/// block's phase-1 buffer, one array per batch, for two-phase kernels). Only the
/// AVX2 driver (the default one) of kernels with [`BatchKernel::SKIPS_ENERGY`] has
/// a forces-only variant: the others sum the energy anyway (the caller drops it).
#[allow(clippy::too_many_arguments)] // the block's parts, kept apart for aliasing
fn run_block<K: BatchKernel>(
    isa: Isa,
    energy: Energy,
    k: &K,
    batch0: usize,
    n_tets: usize,
    dead: &[u8],
    weights: Option<&[[f64; LANES]]>,
    blk: BlockBuffers,
    lanes: &mut [[f64; LANES]],
) -> f64 {
    // separate references, so that the driver knows the buffers do not alias
    let (tets, x, f) = blk.into_parts();
    match isa {
        // (only with the `avx512` feature: see `simd::SimdLevel::Avx512`)
        #[cfg(all(target_arch = "x86_64", feature = "avx512"))]
        // SAFETY: the token proves the CPU has avx512f, avx512dq, avx512vl, avx2 and
        // fma, the features `block_avx512` enables; `tets`, `x` and `f` are the parts
        // of one `BlockBuffers`, so every index is below both buffers' length.
        Isa::Avx512(t) => unsafe {
            block_avx512::<K, true, false>(Avx2(t.avx2()), k, batch0, n_tets, dead, weights, tets, x, f, lanes)
        },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the token proves the CPU has avx2 and fma, the features
        // `block_avx2` enables; the indices as above.
        Isa::Avx2(t) => {
            // blocks of whole batches with no weight and no removed tet (all but the
            // last in a mesh with neither) run the `PLAIN` instance: its own function,
            // so its registers are allocated for the plain loop alone (see
            // [`block_body`])
            let whole = (batch0 + tets.len()) * LANES <= n_tets;
            let plain = weights.is_none() && whole && dead.iter().all(|&m| m == 0);
            let forces_only = K::SKIPS_ENERGY && energy == Energy::Skipped;
            // SAFETY: as above
            unsafe {
                match (forces_only, plain) {
                    (true, true) => {
                        block_avx2::<K, false, true>(Avx2(t), k, batch0, n_tets, dead, weights, tets, x, f, lanes)
                    }
                    (true, false) => {
                        block_avx2::<K, false, false>(Avx2(t), k, batch0, n_tets, dead, weights, tets, x, f, lanes)
                    }
                    (false, true) => {
                        block_avx2::<K, true, true>(Avx2(t), k, batch0, n_tets, dead, weights, tets, x, f, lanes)
                    }
                    (false, false) => {
                        block_avx2::<K, true, false>(Avx2(t), k, batch0, n_tets, dead, weights, tets, x, f, lanes)
                    }
                }
            }
        }
        // SAFETY: the indices as above (and the portable I/O checks them anyway).
        _ => unsafe {
            block_body::<K, Portable, true, false>(Portable, k, batch0, n_tets, dead, weights, tets, x, f, lanes)
        },
    }
}

/// The block driver compiled with `$features` enabled (the SIMD gather and scatter
/// need AVX2 at least).
///
/// # Safety
/// The CPU has `$features`, and the preconditions of [`block_body`] hold.
macro_rules! block_with_features {
    ($name:ident, $features:literal) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        // type-checked in every build, instantiated only where called
        #[cfg_attr(not(feature = "avx512"), allow(dead_code))]
        #[allow(clippy::too_many_arguments)] // the block's parts, kept apart for aliasing
        unsafe fn $name<K: BatchKernel, const ENERGY: bool, const PLAIN: bool>(
            io: Avx2,
            k: &K,
            batch0: usize,
            n_tets: usize,
            dead: &[u8],
            weights: Option<&[[f64; LANES]]>,
            tets: &[LocalBatch],
            x: &[Node4],
            f: &mut [Node4],
            lanes: &mut [[f64; LANES]],
        ) -> f64 {
            // SAFETY: the caller's preconditions.
            unsafe { block_body::<K, Avx2, ENERGY, PLAIN>(io, k, batch0, n_tets, dead, weights, tets, x, f, lanes) }
        }
    };
}
block_with_features!(block_avx512, "avx512f,avx512dq,avx512vl,avx2,fma");
block_with_features!(block_avx2, "avx2,fma");

/// Gathers batch `batch0 + bo` of a block (its local corner indices `idx`) and runs
/// the kernel on it, by the kernel's kind: phase 2 of a two-phase kernel (with the
/// block's phase-1 lanes `lanes`), a kernel with a node scalar (gathered with the
/// positions), or the plain batch: [`block_body`]'s batches.
///
/// # Safety
/// Every index of `idx` is below `x.len()`, as `IO` requires.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // the batch's parts, kept apart for aliasing
unsafe fn gather_and_run<K: BatchKernel, IO: LaneIo>(
    io: IO,
    k: &K,
    batch0: usize,
    bo: usize,
    idx: &LocalBatch,
    x: &[Node4],
    lanes: &[[f64; LANES]],
    p: &mut LanePoints,
    fl: &mut LaneForces,
    el: &mut [f64; LANES],
) {
    let b = batch0 + bo;
    if K::TWO_PHASE {
        // SAFETY: the caller's precondition
        unsafe { io.gather(idx, x, p) };
        k.batch_s(b, p, &lanes[bo], fl, el);
    } else if K::USES_W {
        let mut wl = [[0.0; LANES]; 4];
        // SAFETY: the caller's precondition
        unsafe { io.gather_w(idx, x, p, &mut wl) };
        k.batch_w(b, p, &wl, fl, el);
    } else {
        // SAFETY: the caller's precondition
        unsafe { io.gather(idx, x, p) };
        k.batch(b, p, fl, el);
    }
}

/// The batches of one block: gather, kernel, scatter (all lanes at once for full
/// batches, lane by lane for the padded last one and for batches with removed tets,
/// whose lanes `dead` masks, one byte per batch of the block). With `weights` (one
/// array per batch of the block, when the mesh's tets overlap) each lane's forces
/// and energy are scaled by its tet's weight before the scatter. Without `ENERGY`
/// the energy lanes are never read (and 0 is returned), so that the compiler drops
/// what only they need from the inlined kernel.
///
/// `PLAIN` (the caller's promise: whole batches, no weights, no removed tet) leaves
/// out the weight and removed-lane paths: gather, kernel, scatter. Its AVX2 instance
/// is a function of its own, so its registers serve that loop alone: with the other
/// paths in the same loop the kernels' lane arrays spilled to a ~2.6 kB stack frame,
/// and the neo-Hookean HEML pass ran ~20 % slower (24.4–25.8 against 19.5–19.6
/// ns/tet at 1 thread; see the performance guide). The same operations on the same
/// numbers either way: the same bits.
///
/// # Safety
/// Every index of `tets` is below `x.len()` and `f.len()` (the parts of one
/// [`BlockBuffers`]), as `IO` requires; with `PLAIN`, every batch is whole, no lane
/// is removed and `weights` is `None`.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // the block's parts, kept apart for aliasing
unsafe fn block_body<K: BatchKernel, IO: LaneIo, const ENERGY: bool, const PLAIN: bool>(
    io: IO,
    k: &K,
    batch0: usize,
    n_tets: usize,
    dead: &[u8],
    weights: Option<&[[f64; LANES]]>,
    tets: &[LocalBatch],
    x: &[Node4],
    f: &mut [Node4],
    lanes: &mut [[f64; LANES]],
) -> f64 {
    // the caller's promise for the `PLAIN` instance (`run_block` decides it)
    debug_assert!(
        !PLAIN || (weights.is_none() && (batch0 + tets.len()) * LANES <= n_tets && dead.iter().all(|&m| m == 0)),
        "a plain block with weights, padding or removed tets"
    );
    let mut energy = 0.0;
    let mut p = [[[0.0; LANES]; 3]; 4];
    let mut fl = [[[0.0; LANES]; 3]; 4];
    let mut el = [0.0; LANES];
    if K::TWO_PHASE {
        for (bo, (idx, s)) in tets.iter().zip(lanes.iter_mut()).enumerate() {
            let b = batch0 + bo;
            // SAFETY: `idx` is a batch of `tets`, below `x.len()` (the precondition)
            unsafe { io.gather(idx, x, &mut p) };
            k.pre_batch(b, &p, s);
            if PLAIN {
                // whole batches, every lane kept, no weights: nothing to scale or zero
                continue;
            }
            if let Some(w) = weights {
                for l in 0..LANES {
                    s[l] *= w[bo][l];
                }
            }
            let count = (n_tets - b * LANES).min(LANES);
            for l in 0..LANES {
                if l >= count || dead[bo] & (1 << l) != 0 {
                    s[l] = 0.0;
                }
            }
        }
        let e = k.between(batch0, lanes);
        if ENERGY {
            energy += e;
        }
    }
    for (bo, idx) in tets.iter().enumerate() {
        let b = batch0 + bo;
        // SAFETY: `idx` is a batch of `tets`, below `x.len()` (the precondition)
        unsafe { gather_and_run(io, k, batch0, bo, idx, x, lanes, &mut p, &mut fl, &mut el) };
        if let Some(w) = weights.filter(|_| !PLAIN) {
            let w = &w[bo];
            for fa in fl.iter_mut() {
                for fc in fa.iter_mut() {
                    for l in 0..LANES {
                        fc[l] *= w[l];
                    }
                }
            }
            if ENERGY {
                for l in 0..LANES {
                    el[l] *= w[l];
                }
            }
        }
        // (a `PLAIN` block's batches are whole and keep every lane: the lane-by-lane
        // path below is compiled out of its instance)
        let (count, mask) = if PLAIN {
            (LANES, 0)
        } else {
            ((n_tets - b * LANES).min(LANES), dead[bo])
        };
        if count == LANES && mask == 0 {
            // SAFETY: as for the gather, below `f.len()`
            unsafe { io.scatter(idx, &fl, f) };
            if ENERGY {
                for l in 0..LANES {
                    energy += el[l];
                }
            }
        } else {
            for l in (0..count).filter(|l| mask & (1 << l) == 0) {
                if ENERGY {
                    energy += el[l];
                }
                scatter_lane(idx, &fl, f, l);
            }
        }
    }
    energy
}
