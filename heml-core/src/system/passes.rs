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

/// The fastest node and its speed (the lowest id among equals; (0, 0) when empty).
pub(crate) fn fastest(v: &[Vec3]) -> (usize, f64) {
    // a total order on (speed, −id): the reduction is associative and commutative
    let pick = |a: (usize, f64), b: (usize, f64)| match b.1.total_cmp(&a.1) {
        Ordering::Greater => b,
        Ordering::Equal if b.0 < a.0 => b,
        _ => a,
    };
    let none = (usize::MAX, 0.0);
    let (i, s) = if v.len() >= parallel_pass_threshold() {
        v.par_iter()
            .enumerate()
            .with_min_len(CHUNK)
            .map(|(i, v)| (i, v.norm()))
            .reduce(|| none, pick)
    } else {
        v.iter().enumerate().map(|(i, v)| (i, v.norm())).fold(none, pick)
    };
    (if i == usize::MAX { 0 } else { i }, s)
}
