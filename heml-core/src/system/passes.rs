//! The per-node passes of a step outside the force evaluation — the kick, the drift,
//! the snapshot a step rolls back to, the end-of-step checks — on rayon for large
//! systems.
//!
//! Each pass computes every node from that node's data alone (no sums across nodes),
//! and the reductions (the first bad node, the fastest node) break ties by the lowest
//! node id, so the result is the same, bit for bit, at any thread count and chunking.
//! Below [`PAR_MIN`] nodes the passes run serially: a parallel call costs a few
//! microseconds of scheduling, more than a pass over a small mesh (a haptic-rate
//! step of a 2k-node mesh must not pay it ten times).

use crate::Vec3;
use rayon::prelude::*;
use std::cmp::Ordering;

/// Node count from which the passes run in parallel.
pub(crate) const PAR_MIN: usize = 8192;

/// Nodes per rayon task (a few tens of kilobytes of each array: large enough to
/// amortise the task, small enough to balance two to sixteen threads).
const CHUNK: usize = 2048;

/// v += h·f·(1/m) per node.
pub(crate) fn kick(v: &mut [Vec3], f: &[Vec3], inv_mass: &[f64], h: f64) {
    let op = |(v, (f, im)): (&mut Vec3, (&Vec3, &f64))| *v += f * (h * im);
    if v.len() >= PAR_MIN {
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
    if x.len() >= PAR_MIN {
        x.par_iter_mut().zip(v).with_min_len(CHUNK).for_each(op);
    } else {
        x.iter_mut().zip(v).for_each(op);
    }
}

/// `dst` becomes a copy of `src`.
pub(crate) fn copy(dst: &mut Vec<Vec3>, src: &[Vec3]) {
    if src.len() >= PAR_MIN && dst.len() == src.len() {
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
    if a.len() >= PAR_MIN {
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
    let (i, s) = if v.len() >= PAR_MIN {
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
