//! The per-node passes of a step outside the force evaluation — the kick, the drift,
//! the snapshot a step rolls back to, the end-of-step checks — on rayon for large
//! systems.
//!
//! A symplectic Euler step makes one such pass ([`kick_drift_into`]): it reads
//! x, v, f and 1/m and writes the new x and v into the snapshot's buffers (the old
//! ones stay there for a rollback, no copy), checking the free nodes on the way;
//! the end-of-step checks then read only the constrained nodes.
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

/// `out` = v + h·f·(1/m) per node: [`kick`] into another buffer (`out.len()` is
/// `v.len()`), the same bits.
pub(crate) fn kick_into(out: &mut [Vec3], v: &[Vec3], f: &[Vec3], inv_mass: &[f64], h: f64) {
    let op = |(o, (v, (f, im))): (&mut Vec3, (&Vec3, (&Vec3, &f64)))| *o = v + f * (h * im);
    if v.len() >= parallel_pass_threshold() {
        out.par_iter_mut()
            .zip(v.par_iter().zip(f.par_iter().zip(inv_mass)))
            .with_min_len(CHUNK)
            .for_each(op);
    } else {
        out.iter_mut().zip(v.iter().zip(f.iter().zip(inv_mass))).for_each(op);
    }
}

/// `out` = x + h·v per node: [`drift`] into another buffer, the same bits.
pub(crate) fn drift_into(out: &mut [Vec3], x: &[Vec3], v: &[Vec3], h: f64) {
    let op = |(o, (x, v)): (&mut Vec3, (&Vec3, &Vec3))| *o = x + v * h;
    if x.len() >= parallel_pass_threshold() {
        out.par_iter_mut()
            .zip(x.par_iter().zip(v))
            .with_min_len(CHUNK)
            .for_each(op);
    } else {
        out.iter_mut().zip(x.iter().zip(v)).for_each(op);
    }
}

/// The kick then the drift of a symplectic Euler step in one pass, into other
/// buffers: `v_out` = v + h·f·(1/m), `x_out` = x + h·`v_out` per node, the same bits
/// as [`kick_into`] then [`drift_into`] (each node reads and writes its own data
/// once instead of twice). Returns the [`Summary`] of the new state over the nodes
/// not `constrained` (the end-of-step checks then read only the constrained nodes
/// again, once the constraints have set them).
pub(crate) fn kick_drift_into(
    (x_out, v_out): (&mut [Vec3], &mut [Vec3]),
    (x, v): (&[Vec3], &[Vec3]),
    (f, inv_mass): (&[Vec3], &[f64]),
    constrained: &[bool],
    h: f64,
) -> Summary {
    debug_assert!(x_out.len() == x.len() && v_out.len() == x.len() && constrained.len() == x.len());
    // one chunk: a branch-free loop (the constraint flag selects, it does not
    // branch) with two accumulators, which the compiler keeps in registers
    let chunk = |((xo, vo), ((x, v), (f, (im, c)))): Chunk<'_>| {
        let mut s = Summary::NONE;
        let outs = xo.iter_mut().zip(vo.iter_mut());
        let ins = x.iter().zip(v).zip(f.iter().zip(im.iter().zip(c)));
        for ((xo, vo), ((x, v), (f, (im, c)))) in outs.zip(ins) {
            *vo = v + f * (h * im);
            *xo = x + *vo * h;
            s.add(xo, vo, !*c);
        }
        s
    };
    if x.len() >= parallel_pass_threshold() {
        x_out
            .par_chunks_mut(CHUNK)
            .zip(v_out.par_chunks_mut(CHUNK))
            .zip(
                x.par_chunks(CHUNK).zip(v.par_chunks(CHUNK)).zip(
                    f.par_chunks(CHUNK)
                        .zip(inv_mass.par_chunks(CHUNK).zip(constrained.par_chunks(CHUNK))),
                ),
            )
            .map(chunk)
            .reduce(|| Summary::NONE, Summary::merge)
    } else {
        chunk(((x_out, v_out), ((x, v), (f, (inv_mass, constrained)))))
    }
}

/// What [`kick_drift_into`] sees of a run of nodes: their new positions and
/// velocities (written), their positions, velocities, forces, inverse masses and
/// constraint flags.
type Chunk<'a> = (
    (&'a mut [Vec3], &'a mut [Vec3]),
    ((&'a [Vec3], &'a [Vec3]), (&'a [Vec3], (&'a [f64], &'a [bool]))),
);

/// What the end-of-step checks need to know of a set of nodes when nothing is
/// wrong — whether every coordinate of x and v is finite, and the largest squared
/// speed — in a form that vectorises: no index, no branch. Only when it reports a
/// problem does the step run the exact [`scan_state`] to name the node.
///
/// `bad` ORs the coordinates' "exponent all ones" tests (integer operations, which
/// vectorise, where `is_finite` on three coordinates would branch). The largest speed is the square root of the largest squared
/// speed, bit for bit (`norm` is `norm_squared().sqrt()`, and a correctly rounded
/// square root is monotone), so it is the speed [`scan_state`] reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Summary {
    bad: bool,
    speed2: f64,
}

impl Summary {
    /// The summary of no node.
    pub(crate) const NONE: Summary = Summary {
        bad: false,
        speed2: 0.0,
    };

    /// Adds node (x, v) when `counted`.
    #[inline(always)]
    fn add(&mut self, x: &Vec3, v: &Vec3, counted: bool) {
        self.bad |= counted & (non_finite(x) | non_finite(v));
        // a NaN speed (a NaN velocity) leaves the maximum alone: `bad` reports it
        self.speed2 = self.speed2.max(if counted { v.norm_squared() } else { 0.0 });
    }

    /// The summary of the nodes of `a` and of `b` (the same in any grouping).
    pub(crate) fn merge(a: Summary, b: Summary) -> Summary {
        Summary {
            bad: a.bad | b.bad,
            speed2: a.speed2.max(b.speed2),
        }
    }

    /// Whether every coordinate summarised is finite.
    pub(crate) fn finite(&self) -> bool {
        !self.bad
    }

    /// The largest speed (0 for no node): the speed of [`scan_state`]'s fastest node.
    pub(crate) fn max_speed(&self) -> f64 {
        self.speed2.sqrt()
    }
}

/// Whether a coordinate of `p` is infinite or NaN (its exponent bits all ones),
/// without a branch.
#[inline(always)]
fn non_finite(p: &Vec3) -> bool {
    const EXP: u64 = 0x7ff0_0000_0000_0000;
    p.iter().fold(false, |b, c| b | (c.to_bits() & EXP == EXP))
}

/// The [`Summary`] of the whole state (x, v).
pub(crate) fn summarize(x: &[Vec3], v: &[Vec3]) -> Summary {
    let chunk = |(x, v): (&[Vec3], &[Vec3])| {
        let mut s = Summary::NONE;
        x.iter().zip(v).for_each(|(x, v)| s.add(x, v, true));
        s
    };
    if x.len() >= parallel_pass_threshold() {
        x.par_chunks(CHUNK)
            .zip(v.par_chunks(CHUNK))
            .map(chunk)
            .reduce(|| Summary::NONE, Summary::merge)
    } else {
        chunk((x, v))
    }
}

/// The [`Summary`] of the nodes `ids` alone.
pub(crate) fn summarize_nodes(ids: &[usize], x: &[Vec3], v: &[Vec3]) -> Summary {
    let mut s = Summary::NONE;
    ids.iter().for_each(|&i| s.add(&x[i], &v[i], true));
    s
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

/// The first node (lowest id) with a non-finite component: a branch-free pass
/// that vectorises (see [`Summary`]), then, only when it finds one, a search.
pub(crate) fn first_non_finite(a: &[Vec3]) -> Option<usize> {
    let any = |a: &[Vec3]| a.iter().fold(false, |b, p| b | non_finite(p));
    let found = if a.len() >= parallel_pass_threshold() {
        a.par_chunks(CHUNK).map(any).reduce(|| false, |a, b| a | b)
    } else {
        any(a)
    };
    if !found {
        return None;
    }
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

impl StateScan {
    /// The scan of no node (its fastest node is `usize::MAX` until [`Self::done`]).
    pub(crate) const NONE: StateScan = StateScan {
        bad_x: None,
        bad_v: None,
        fastest: (usize::MAX, 0.0),
    };

    /// The scan of node `i` alone.
    pub(crate) fn of(i: usize, x: &Vec3, v: &Vec3) -> StateScan {
        let finite = |p: &Vec3| p.iter().all(|c| c.is_finite());
        StateScan {
            bad_x: (!finite(x)).then_some(i),
            bad_v: (!finite(v)).then_some(i),
            fastest: (i, v.norm()),
        }
    }

    /// The scan of the nodes of `a` and of `b`: each field reduces with a total
    /// order broken by the lowest id, so merging in any grouping and order gives
    /// the same bits.
    pub(crate) fn merge(a: StateScan, b: StateScan) -> StateScan {
        let first = |a: Option<usize>, b: Option<usize>| match (a, b) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let pick = |a: (usize, f64), b: (usize, f64)| match b.1.total_cmp(&a.1) {
            Ordering::Greater => b,
            Ordering::Equal if b.0 < a.0 => b,
            _ => a,
        };
        StateScan {
            bad_x: first(a.bad_x, b.bad_x),
            bad_v: first(a.bad_v, b.bad_v),
            fastest: pick(a.fastest, b.fastest),
        }
    }

    /// The final scan: fastest node 0 (speed 0) when no node was scanned.
    pub(crate) fn done(mut self) -> StateScan {
        if self.fastest.0 == usize::MAX {
            self.fastest.0 = 0;
        }
        self
    }
}

/// [`first_non_finite`] of `x` and of `v` and the fastest node of `v` (the lowest
/// id among equal speeds; (0, 0) when empty) in one pass over
/// the two arrays (the end-of-step checks read each array once instead of x once
/// and v twice). Same results, bit for bit, as the three separate passes, at any
/// thread count: each field reduces with a total order broken by the lowest id.
pub(crate) fn scan_state(x: &[Vec3], v: &[Vec3]) -> StateScan {
    let one = |(i, (x, v)): (usize, (&Vec3, &Vec3))| StateScan::of(i, x, v);
    let s = if x.len() >= parallel_pass_threshold() {
        x.par_iter()
            .zip(v)
            .enumerate()
            .with_min_len(CHUNK)
            .map(one)
            .reduce(|| StateScan::NONE, StateScan::merge)
    } else {
        x.iter()
            .zip(v)
            .enumerate()
            .map(one)
            .fold(StateScan::NONE, StateScan::merge)
    };
    s.done()
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
        // the fused update's summary of the free nodes, merged with the constrained
        // nodes' summary, is the summary of the whole new state, serial and
        // parallel, and agrees with the exact scan
        let f: Vec<Vec3> = (0..n).map(|i| Vec3::new(1.0, -(i as f64), 0.5)).collect();
        let inv_mass: Vec<f64> = (0..n)
            .map(|i| if i % 5 == 0 { 0.0 } else { 1.0 / (1 + i % 3) as f64 })
            .collect();
        let constrained: Vec<bool> = inv_mass.iter().map(|&m| m == 0.0).collect();
        let ids: Vec<usize> = (0..n).filter(|&i| constrained[i]).collect();
        for threshold in [0, usize::MAX] {
            let (mut xo, mut vo) = (vec![Vec3::zeros(); n], vec![Vec3::zeros(); n]);
            let old = parallel_pass_threshold();
            set_parallel_pass_threshold(threshold);
            let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
            let free =
                pool.install(|| kick_drift_into((&mut xo, &mut vo), (&x, &v), (&f, &inv_mass), &constrained, 0.1));
            let (mut xk, mut vk) = (x.clone(), v.clone());
            kick(&mut vk, &f, &inv_mass, 0.1);
            drift(&mut xk, &vk, 0.1);
            // bit for bit (x holds a NaN and an ∞, which == would not match)
            let bits = |a: &[Vec3]| a.iter().map(|p| p.map(f64::to_bits)).collect::<Vec<_>>();
            assert_eq!((bits(&xo), bits(&vo)), (bits(&xk), bits(&vk)));
            // the NaN and the ∞ of x are on free nodes
            assert!(!free.finite());
            // constrained nodes set elsewhere (a fast one among them), as the constraints do
            for &i in &ids {
                vo[i] = Vec3::new(0.0, 0.0, 1e3 + i as f64);
            }
            let merged = Summary::merge(free, summarize_nodes(&ids, &xo, &vo));
            let whole = pool.install(|| summarize(&xo, &vo));
            set_parallel_pass_threshold(old);
            assert_eq!(merged, whole);
            let exact = scan_state(&xo, &vo);
            assert_eq!(merged.max_speed(), exact.fastest.1);
            assert_eq!(exact.fastest.0, *ids.last().unwrap());
            assert_eq!(exact.bad_x, Some(3 * CHUNK + 5));
            // finite positions: the summary says so, and still finds the fastest speed
            let xf: Vec<Vec3> = xo
                .iter()
                .map(|p| p.map(|c| if c.is_finite() { c } else { 0.0 }))
                .collect();
            let s = summarize(&xf, &vo);
            assert!(s.finite());
            assert_eq!(s.max_speed(), exact.fastest.1);
            // a constrained node's NaN is not the free nodes' business
            let mut vn = vo.clone();
            vn[ids[1]].y = f64::NAN;
            let (mut xo2, mut vo2) = (xo.clone(), vo.clone());
            let free = kick_drift_into((&mut xo2, &mut vo2), (&xf, &vn), (&f, &inv_mass), &constrained, 0.1);
            assert!(free.finite());
            assert!(!summarize_nodes(&ids, &xo2, &vo2).finite());
        }
        assert_eq!(first_non_finite(&x), Some(3 * CHUNK + 5));
        assert_eq!(first_non_finite(&v), None);
        let empty = scan_state(&[], &[]);
        assert_eq!((empty.bad_x, empty.bad_v, empty.fastest), (None, None, (0, 0.0)));
    }
}
