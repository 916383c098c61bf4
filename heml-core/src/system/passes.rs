//! The per-node passes of a step outside the force evaluation — the kick, the drift,
//! the snapshot a step rolls back to, the end-of-step checks — on rayon for large
//! systems.
//!
//! Each pass computes every node from that node's data alone (no sums across nodes),
//! and the reductions (the first bad node, the fastest node) break ties by the lowest
//! node id, so the result is the same, bit for bit, at any thread count and chunking.
//! Below [`parallel_pass_threshold`] nodes the passes run serially. The default is
//! high because parallel passes did not pay on the 2-core machine this was measured
//! on (`heml bench`, symplectic Euler, 2 pinned threads, 2026-11-23, quiet machine):
//! with a threshold of 8192 nodes a step of gen_kidney_100k (18 167 nodes) took
//! 1.99–2.06 ms against 1.21–1.40 ms serial, and a 1M-tet box (≈ 180k nodes)
//! 18.0–19.9 ms against 14.3–16.1 ms — memory-bound passes of a few tens of
//! microseconds lose more to scheduling than they gain. Machines with many cores may
//! gain: [`set_parallel_pass_threshold`] lowers it.

use crate::Vec3;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::sync::atomic::{AtomicUsize, Ordering as AtomicOrdering};

/// Default node count from which the passes run in parallel (see the module doc).
pub const DEFAULT_PARALLEL_PASS_THRESHOLD: usize = 1 << 20;

static PAR_MIN: AtomicUsize = AtomicUsize::new(DEFAULT_PARALLEL_PASS_THRESHOLD);

/// The node count from which a step's per-node passes (kick, drift, snapshot,
/// end-of-step checks) run on rayon.
pub fn parallel_pass_threshold() -> usize {
    PAR_MIN.load(AtomicOrdering::Relaxed)
}

/// Sets [`parallel_pass_threshold`] for the whole process. Results do not depend on
/// it (the passes give the same bits serial or parallel, at any thread count): only
/// speed does, so it is a tuning knob, safe to change while systems run.
///
/// ```
/// use heml_core::system::{parallel_pass_threshold, set_parallel_pass_threshold};
/// let old = parallel_pass_threshold();
/// set_parallel_pass_threshold(50_000); // a 16-core machine, say
/// assert_eq!(parallel_pass_threshold(), 50_000);
/// set_parallel_pass_threshold(old);
/// ```
pub fn set_parallel_pass_threshold(nodes: usize) {
    PAR_MIN.store(nodes, AtomicOrdering::Relaxed);
}

/// Nodes per rayon task (a few tens of kilobytes of each array: large enough to
/// amortise the task, small enough to balance two to sixteen threads).
const CHUNK: usize = 2048;

/// v += h·f·(1/m) per node.
pub(crate) fn kick(v: &mut [Vec3], f: &[Vec3], inv_mass: &[f64], h: f64) {
    let op = |(v, (f, im)): (&mut Vec3, (&Vec3, &f64))| *v += f * (h * im);
    if v.len() >= parallel_pass_threshold() {
        v.par_iter_mut()
            .zip(f.par_iter().zip(inv_mass))
            .with_min_len(CHUNK)
            .for_each(op);
    } else {
        v.iter_mut().zip(f.iter().zip(inv_mass)).for_each(op);
    }
}

/// x += h·v per node.
pub(crate) fn drift(x: &mut [Vec3], v: &[Vec3], h: f64) {
    let op = |(x, v): (&mut Vec3, &Vec3)| *x += v * h;
    if x.len() >= parallel_pass_threshold() {
        x.par_iter_mut().zip(v).with_min_len(CHUNK).for_each(op);
    } else {
        x.iter_mut().zip(v).for_each(op);
    }
}

/// `dst` becomes a copy of `src`.
pub(crate) fn copy(dst: &mut Vec<Vec3>, src: &[Vec3]) {
    if src.len() >= parallel_pass_threshold() && dst.len() == src.len() {
        dst.par_chunks_mut(CHUNK)
            .zip(src.par_chunks(CHUNK))
            .for_each(|(d, s)| d.copy_from_slice(s));
    } else {
        dst.clear();
        dst.extend_from_slice(src);
    }
}

/// The first node (lowest id) with a non-finite component.
pub(crate) fn first_non_finite(a: &[Vec3]) -> Option<usize> {
    let bad = |p: &Vec3| !p.iter().all(|c| c.is_finite());
    if a.len() >= parallel_pass_threshold() {
        a.par_iter().with_min_len(CHUNK).position_first(bad)
    } else {
        a.iter().position(bad)
    }
}

/// What [`scan_state`] found: the first non-finite position and velocity (lowest
/// ids) and the fastest node with its speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StateScan {
    pub bad_x: Option<usize>,
    pub bad_v: Option<usize>,
    pub fastest: (usize, f64),
}

/// [`first_non_finite`] of `x` and of `v` and the fastest node of `v` (the lowest
/// id among equal speeds; (0, 0) when empty) in one pass over
/// the two arrays (the end-of-step checks read each array once instead of x once
/// and v twice). Same results, bit for bit, as the three separate passes, at any
/// thread count: each field reduces with a total order broken by the lowest id.
pub(crate) fn scan_state(x: &[Vec3], v: &[Vec3]) -> StateScan {
    let finite = |p: &Vec3| p.iter().all(|c| c.is_finite());
    let first = |a: Option<usize>, b: Option<usize>| match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    let pick = |a: (usize, f64), b: (usize, f64)| match b.1.total_cmp(&a.1) {
        Ordering::Greater => b,
        Ordering::Equal if b.0 < a.0 => b,
        _ => a,
    };
    let none = StateScan {
        bad_x: None,
        bad_v: None,
        fastest: (usize::MAX, 0.0),
    };
    let merge = |a: StateScan, b: StateScan| StateScan {
        bad_x: first(a.bad_x, b.bad_x),
        bad_v: first(a.bad_v, b.bad_v),
        fastest: pick(a.fastest, b.fastest),
    };
    let one = |(i, (x, v)): (usize, (&Vec3, &Vec3))| StateScan {
        bad_x: (!finite(x)).then_some(i),
        bad_v: (!finite(v)).then_some(i),
        fastest: (i, v.norm()),
    };
    let mut s = if x.len() >= parallel_pass_threshold() {
        x.par_iter()
            .zip(v)
            .enumerate()
            .with_min_len(CHUNK)
            .map(one)
            .reduce(|| none, merge)
    } else {
        x.iter().zip(v).enumerate().map(one).fold(none, merge)
    };
    if s.fastest.0 == usize::MAX {
        s.fastest.0 = 0;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fused scan finds the lowest bad ids and the fastest node (lowest id
    /// among ties), the same serial and parallel (results never depend on the
    /// threshold, so changing it here cannot disturb other tests).
    #[test]
    fn scan_state_serial_and_parallel_agree() {
        let n = 5 * CHUNK + 17;
        let mut x: Vec<Vec3> = (0..n).map(|i| Vec3::repeat(i as f64)).collect();
        let mut v: Vec<Vec3> = (0..n).map(|i| Vec3::new((i % 7) as f64, 0.0, 0.0)).collect();
        x[3 * CHUNK + 5].y = f64::NAN;
        x[4 * CHUNK].z = f64::INFINITY;
        v[CHUNK + 1].x = f64::NEG_INFINITY;
        let run = |x: &[Vec3], v: &[Vec3], threshold: usize| {
            let old = parallel_pass_threshold();
            set_parallel_pass_threshold(threshold);
            let s = rayon::ThreadPoolBuilder::new()
                .num_threads(3)
                .build()
                .unwrap()
                .install(|| scan_state(x, v));
            set_parallel_pass_threshold(old);
            s
        };
        let serial = run(&x, &v, usize::MAX);
        assert_eq!(serial.bad_x, Some(3 * CHUNK + 5));
        assert_eq!(serial.bad_v, Some(CHUNK + 1));
        // −∞ has norm +∞: the fastest
        assert_eq!(serial.fastest, (CHUNK + 1, f64::INFINITY));
        assert_eq!(run(&x, &v, 0), serial);
        v[CHUNK + 1].x = 0.0;
        // speed 6 first reached at node 6: ties go to the lowest id
        let s = run(&x, &v, 0);
        assert_eq!((s.bad_v, s.fastest), (None, (6, 6.0)));
        assert_eq!(s, run(&x, &v, usize::MAX));
        let empty = scan_state(&[], &[]);
        assert_eq!((empty.bad_x, empty.bad_v, empty.fastest), (None, None, (0, 0.0)));
    }
}
