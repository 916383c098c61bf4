//! The lumped volumes of a layout's nodes, v_a = Σ_{t∋a} w_t·vol_t/4 (w_t the tet's
//! integration weight), for the anti-locking volumetric term
//! ([`crate::force::NodalVolume`]).
//!
//! One scalar per node instead of a force vector: the blocks accumulate vol_t/4 in
//! one `f64` per local node (a quarter of the block driver's 32-byte force slots)
//! and the merge sums the blocks' copies of each node in block order, with the
//! driver's merge lists. So it costs about a quarter of a force pass' scatter and
//! merge, and gives the same bits for any thread count (the blocks' order and
//! contents do not depend on it).

// The lanes are indexed in lock-step on purpose (it is what vectorises).
#![allow(clippy::needless_range_loop)]

use super::driver::{Scratch, MERGE_CHUNK};
#[cfg(target_arch = "x86_64")]
use super::lane_io::Avx2;
use super::lane_io::{LaneIo, Node4, Portable};
use super::layout::{Layout, LocalBatch, LANES};
use super::simd::Isa;
use crate::force::lanes::lane_crosses;
use crate::Vec3;

impl Layout {
    /// Writes the lumped current volume v_a of every node at `x` to `v` (0 for nodes
    /// no live tet touches); the blocks on rayon when `parallel`. `x` and `v` hold
    /// one entry per node of the layout (the callers check `x`; `v` is theirs).
    pub(crate) fn lumped_volumes(&self, x: &[Vec3], parallel: bool, v: &mut [f64]) {
        let mut guard = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        self.lumped_in(&mut guard, x, parallel, v);
    }

    /// [`Self::lumped_volumes`] in the scratch `s` (locked by the caller), whose
    /// blocks' position buffers keep `x` afterwards (with zero padding slots).
    pub(super) fn lumped_in(&self, s: &mut Scratch, x: &[Vec3], parallel: bool, v: &mut [f64]) {
        debug_assert!(x.len() == self.n_nodes && v.len() == self.n_nodes);
        let parallel = self.runs_parallel(parallel);
        let blocks = self.blocks.list();
        s.ensure(self.n_slots, blocks.len(), true);
        // each block's own part of the slots (blocks lie one after the other): its
        // local positions (the driver's buffers) and one accumulator per node
        type Task<'a> = (usize, super::layout::BlockBuffers<'a>, &'a mut [f64]);
        let mut tasks: Vec<Task> = Vec::with_capacity(blocks.len());
        let (mut xs, mut fs, mut rest) = (&mut s.x[..], &mut s.f[..], &mut s.lumped[..]);
        for (b, blk) in blocks.iter().enumerate() {
            let (mine, tail) = std::mem::take(&mut rest).split_at_mut(blk.nodes.len());
            tasks.push((b, self.blocks.buffers(b, &mut xs, &mut fs), mine));
            rest = tail;
        }
        let isa = Isa::current();
        let one = |(b, mut bufs, a): Task| {
            let blk = &blocks[b];
            for (xi, &g) in bufs.x_mut().iter_mut().zip(&blk.nodes) {
                *xi = Node4::from_vec(&x[g as usize]);
            }
            a.fill(0.0);
            let (batches, xl, _) = bufs.into_parts();
            assert_eq!(a.len(), xl.len(), "lumped volumes: one accumulator per local node");
            match isa {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: the token proves the CPU has avx2 and fma, the features
                // `block_avx2` enables; `batches` and `xl` are the parts of one
                // `BlockBuffers` and `a` is as long as `xl` (asserted), so every
                // index is below both lengths.
                Isa::Avx512(t) => unsafe { block_avx2(Avx2(t.avx2()), self, blk.batch_start, batches, xl, a) },
                #[cfg(target_arch = "x86_64")]
                // SAFETY: as above.
                Isa::Avx2(t) => unsafe { block_avx2(Avx2(t), self, blk.batch_start, batches, xl, a) },
                // SAFETY: as above (and the portable gather checks them anyway).
                _ => unsafe { block_body(Portable, self, blk.batch_start, batches, xl, a) },
            }
        };
        crate::parallel::for_each_task(tasks, parallel, &one);
        let acc: &[f64] = &s.lumped;
        crate::parallel::for_each_chunk_mut(v, MERGE_CHUNK, parallel, &|c, chunk| {
            for (o, vi) in chunk.iter_mut().enumerate() {
                let i = c * MERGE_CHUNK + o;
                let (lo, hi) = (self.merge_off[i] as usize, self.merge_off[i + 1] as usize);
                *vi = self.merge[lo..hi].iter().map(|&s| acc[s as usize]).sum();
            }
        });
    }
}

/// The lumped volumes of one block's tets (batches from `batch0`, local indices
/// `batches`, local positions `xl`) added to its accumulators `a`, with the driver
/// compiled for AVX2 and FMA (its SIMD gather; the lane loops 4 wide).
///
/// # Safety
/// The CPU has avx2 and fma, and the preconditions of [`block_body`] hold.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn block_avx2(io: Avx2, layout: &Layout, batch0: usize, batches: &[LocalBatch], xl: &[Node4], a: &mut [f64]) {
    // SAFETY: the caller's preconditions.
    unsafe { block_body(io, layout, batch0, batches, xl, a) }
}

/// The lumped volumes of one block's tets: per batch, the gather, the
/// determinants det(v1, v2, v3) = 6 vol (as the kernels'), and w_t·vol_t/4 added
/// to each corner's accumulator, lane by lane (dead and padding lanes skipped).
///
/// # Safety
/// Every index of `batches` is below `xl.len()` and `a.len()`.
#[inline(always)]
unsafe fn block_body<IO: LaneIo>(
    io: IO,
    layout: &Layout,
    batch0: usize,
    batches: &[LocalBatch],
    xl: &[Node4],
    a: &mut [f64],
) {
    let n_tets = layout.n_tets();
    let mut p = [[[0.0; LANES]; 3]; 4];
    for (bo, idx) in batches.iter().enumerate() {
        let bt = batch0 + bo;
        // SAFETY: `idx` is a batch of the block, every index below `xl.len()`
        unsafe { io.gather(idx, xl, &mut p) };
        let (_, det) = lane_crosses(&p);
        let mut q = [0.0; LANES];
        for l in 0..LANES {
            q[l] = det[l] * (1.0 / 24.0);
        }
        let count = n_tets.saturating_sub(bt * LANES).min(LANES);
        let mask = layout.dead[bt];
        if count == LANES && mask == 0 && layout.weights.is_none() {
            for l in 0..LANES {
                for &c in &idx[l] {
                    // SAFETY: every index of the batch is below `a.len()`
                    unsafe { *a.get_unchecked_mut(c as usize) += q[l] };
                }
            }
        } else {
            for l in (0..count).filter(|l| mask & (1 << l) == 0) {
                let ql = layout.weight(bt * LANES + l) * q[l];
                for &c in &idx[l] {
                    a[c as usize] += ql;
                }
            }
        }
    }
}
