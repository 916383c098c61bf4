//! Moving one batch's corner positions in and corner forces out: between the
//! per-node AoS buffers of a block and the SoA lanes of the kernels. Plain indexed
//! loads and stores, or AVX2 4×4 transposes once the CPU is proven to have AVX2.

// The lanes are indexed in lock-step on purpose (it is what vectorises).
#![allow(clippy::needless_range_loop)]

use super::driver::{LaneForces, LanePoints};
use super::layout::{LocalBatch, LANES};
use crate::Vec3;

/// One scalar per corner of each lane, `[corner][lane]`.
pub(crate) type LaneScalars = [[f64; LANES]; 4];

/// A node position or force padded to four `f64` (32-byte aligned), so that one
/// aligned vector load or store moves a whole node in the SIMD gather and scatter.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(32))]
pub(crate) struct Node4([f64; 4]);

impl Node4 {
    /// The node `v`, padded with a zero.
    pub(crate) fn from_vec(v: &Vec3) -> Node4 {
        Node4([v.x, v.y, v.z, 0.0])
    }
    /// Puts `w` in the padding slot, the position unchanged: one scalar per node
    /// that the gather hands to the kernel with the positions ([`LaneIo::gather_w`]).
    pub(crate) fn set_w(&mut self, w: f64) {
        self.0[3] = w;
    }
    /// The node without its padding.
    pub(crate) fn to_vec(self) -> Vec3 {
        Vec3::new(self.0[0], self.0[1], self.0[2])
    }
}

/// Moves one batch between a block's buffers and the kernels' lanes.
///
/// # Safety
/// Both methods require every index of `idx` to be below the buffer's length: true
/// of the parts of one [`super::layout::BlockBuffers`] (checked once, when the
/// layout was built). The AVX2 implementation can only exist once the CPU is proven
/// to have AVX2 (it holds an [`super::simd::Avx2Token`]).
pub(crate) trait LaneIo: Copy {
    /// `p[a][c][l] = x[idx[l][a]][c]`.
    ///
    /// # Safety
    /// Every index of `idx` is below `x.len()`.
    unsafe fn gather(self, idx: &LocalBatch, x: &[Node4], p: &mut LanePoints);
    /// As [`Self::gather`], and `w[a][l] = x[idx[l][a]]`'s padding slot (see
    /// [`Node4::with_w`]): the AVX2 transpose has it in a register already.
    ///
    /// # Safety
    /// Every index of `idx` is below `x.len()`.
    unsafe fn gather_w(self, idx: &LocalBatch, x: &[Node4], p: &mut LanePoints, w: &mut LaneScalars);
    /// `f[idx[l][a]][c] += fl[a][c][l]` for every lane, corner by corner then lane
    /// by lane.
    ///
    /// # Safety
    /// Every index of `idx` is below `f.len()`.
    unsafe fn scatter(self, idx: &LocalBatch, fl: &LaneForces, f: &mut [Node4]);
}

/// Plain indexed loads and stores (the baseline target; bounds-checked, so sound
/// whatever the indices).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Portable;

impl LaneIo for Portable {
    #[inline(always)]
    unsafe fn gather(self, idx: &LocalBatch, x: &[Node4], p: &mut LanePoints) {
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
    unsafe fn gather_w(self, idx: &LocalBatch, x: &[Node4], p: &mut LanePoints, w: &mut LaneScalars) {
        for l in 0..LANES {
            for a in 0..4 {
                let q = &x[idx[l][a] as usize].0;
                for c in 0..3 {
                    p[a][c][l] = q[c];
                }
                w[a][l] = q[3];
            }
        }
    }
    #[inline(always)]
    unsafe fn scatter(self, idx: &LocalBatch, fl: &LaneForces, f: &mut [Node4]) {
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

/// Adds the four corner forces of lane `l` to `f` (the padded last batch, lane by
/// lane; bounds-checked).
#[inline(always)]
pub(crate) fn scatter_lane(idx: &LocalBatch, fl: &LaneForces, f: &mut [Node4], l: usize) {
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
mod avx2 {
    use super::super::driver::{LaneForces, LanePoints};
    use super::super::layout::{LocalBatch, LANES};
    use super::super::simd::Avx2Token;
    use super::{LaneIo, LaneScalars, Node4};
    use std::arch::x86_64::*;

    /// The AVX2 lane I/O; holding the token proves the CPU has AVX2.
    #[derive(Debug, Clone, Copy)]
    pub(crate) struct Avx2(pub(crate) Avx2Token);

    impl LaneIo for Avx2 {
        #[inline(always)]
        unsafe fn gather(self, idx: &LocalBatch, x: &[Node4], p: &mut LanePoints) {
            // SAFETY: `self.0` is an `Avx2Token`, made only when run-time detection
            // saw AVX2 on this CPU; the indices are below `x.len()` (the caller's
            // contract, met by the parts of a `BlockBuffers`).
            unsafe { gather::<false>(idx, x, p, &mut [[0.0; LANES]; 4]) }
        }
        #[inline(always)]
        unsafe fn gather_w(self, idx: &LocalBatch, x: &[Node4], p: &mut LanePoints, w: &mut LaneScalars) {
            // SAFETY: as for `gather`.
            unsafe { gather::<true>(idx, x, p, w) }
        }
        #[inline(always)]
        unsafe fn scatter(self, idx: &LocalBatch, fl: &LaneForces, f: &mut [Node4]) {
            // SAFETY: as for `gather`, with the indices below `f.len()`.
            unsafe { scatter(idx, fl, f) }
        }
    }

    /// The positions, and the padding slots into `w` when `W`.
    ///
    /// # Safety
    /// The CPU has AVX2 and every index of `idx` is below `x.len()`.
    #[inline(always)]
    unsafe fn gather<const W: bool>(idx: &LocalBatch, x: &[Node4], p: &mut LanePoints, w: &mut LaneScalars) {
        let base = x.as_ptr() as *const f64;
        for a in 0..4 {
            for h in 0..LANES / 4 {
                let i = &idx[4 * h..4 * h + 4];
                let r0 = _mm256_load_pd(base.add(4 * i[0][a] as usize));
                let r1 = _mm256_load_pd(base.add(4 * i[1][a] as usize));
                let r2 = _mm256_load_pd(base.add(4 * i[2][a] as usize));
                let r3 = _mm256_load_pd(base.add(4 * i[3][a] as usize));
                let t0 = _mm256_unpacklo_pd(r0, r1); // x0 x1 z0 z1
                let t1 = _mm256_unpackhi_pd(r0, r1); // y0 y1 w0 w1
                let t2 = _mm256_unpacklo_pd(r2, r3); // x2 x3 z2 z3
                let t3 = _mm256_unpackhi_pd(r2, r3); // y2 y3 w2 w3
                if W {
                    _mm256_storeu_pd(w[a][4 * h..].as_mut_ptr(), _mm256_permute2f128_pd(t1, t3, 0x31));
                }
                let out = &mut p[a];
                _mm256_storeu_pd(out[0][4 * h..].as_mut_ptr(), _mm256_permute2f128_pd(t0, t2, 0x20));
                _mm256_storeu_pd(out[1][4 * h..].as_mut_ptr(), _mm256_permute2f128_pd(t1, t3, 0x20));
                _mm256_storeu_pd(out[2][4 * h..].as_mut_ptr(), _mm256_permute2f128_pd(t0, t2, 0x31));
            }
        }
    }

    /// # Safety
    /// The CPU has AVX2 and every index of `idx` is below `f.len()`.
    #[inline(always)]
    unsafe fn scatter(idx: &LocalBatch, fl: &LaneForces, f: &mut [Node4]) {
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
#[cfg(target_arch = "x86_64")]
pub(crate) use avx2::Avx2;
