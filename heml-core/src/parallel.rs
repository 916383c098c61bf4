//! The library's parallel loops over per-kernel work, behind closures passed as
//! `&dyn Fn`.
//!
//! Why: a rayon loop written inside a generic function (a force field's pass, a
//! tangent's product) is compiled again for every kernel it is instantiated with,
//! and with it rayon's whole machinery (bridges, joins, stack jobs: ~1 500 lines of
//! LLVM IR per loop). Every law has a dozen such loops (element, nodal and patch
//! fields, their tangents, each per instruction set), so before this module those
//! copies were ~35 % of the IR `heml-materials` compiled (`cargo llvm-lines`: 346
//! copies of rayon's bridge for its ten laws), and every law a user declares paid
//! them again. Here each loop is compiled once per item type; a kernel's loop body
//! is reached through one dynamic call per task or per chunk (a block of tets, a
//! chunk of hundreds of nodes), whose cost is lost in the work it calls.
//!
//! Each helper runs the same calls on the same items whether `parallel` or not, and
//! every item or chunk is written by exactly one call, so the results are the same
//! bits on any thread count.

use rayon::prelude::*;

/// Calls `f` on each task, one task per rayon job when `parallel` (tasks are
/// coarse: a block of tets each), else in order on this thread.
pub(crate) fn for_each_task<T: Send>(tasks: Vec<T>, parallel: bool, f: &(dyn Fn(T) + Sync)) {
    if parallel {
        tasks.into_par_iter().with_max_len(1).for_each(f);
    } else {
        tasks.into_iter().for_each(f);
    }
}

/// Calls `f(c, chunk)` on the consecutive chunks of `items` (`len` items each, the
/// last one shorter), `c` the chunk's number, on rayon when `parallel`, and returns
/// what each call returned, in chunk order.
pub(crate) fn map_chunks_mut<T: Send, R: Send>(
    items: &mut [T],
    len: usize,
    parallel: bool,
    f: &(dyn Fn(usize, &mut [T]) -> R + Sync),
) -> Vec<R> {
    let call = |(c, chunk): (usize, &mut [T])| f(c, chunk);
    if parallel {
        items.par_chunks_mut(len).enumerate().map(call).collect()
    } else {
        items.chunks_mut(len).enumerate().map(call).collect()
    }
}

/// Calls `f(c, chunk)` on the consecutive chunks of `items` (`len` items each, the
/// last one shorter), `c` the chunk's number, on rayon when `parallel`.
pub(crate) fn for_each_chunk_mut<T: Send>(
    items: &mut [T],
    len: usize,
    parallel: bool,
    f: &(dyn Fn(usize, &mut [T]) + Sync),
) {
    if parallel {
        items.par_chunks_mut(len).enumerate().for_each(|(c, chunk)| f(c, chunk));
    } else {
        items.chunks_mut(len).enumerate().for_each(|(c, chunk)| f(c, chunk));
    }
}

/// `(0..n).map(f)` into a vector, computed in chunks of `len` on rayon: each
/// chunk's values by one call of `fill(start, out)`, which writes `out[i]` for item
/// `start + i`.
pub(crate) fn fill_chunks<T: Send + Default + Clone>(
    n: usize,
    len: usize,
    fill: &(dyn Fn(usize, &mut [T]) + Sync),
) -> Vec<T> {
    let mut out = vec![T::default(); n];
    for_each_chunk_mut(&mut out, len, true, &|c, chunk| fill(c * len, chunk));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_once_in_order_on_any_thread_count() {
        for parallel in [false, true] {
            let mut v: Vec<usize> = vec![0; 1000];
            for_each_chunk_mut(&mut v, 64, parallel, &|c, chunk| {
                for (o, x) in chunk.iter_mut().enumerate() {
                    *x += c * 64 + o;
                }
            });
            assert!(v.iter().enumerate().all(|(i, &x)| x == i), "parallel {parallel}");
            let sums = map_chunks_mut(&mut v, 100, parallel, &|c, chunk| (c, chunk.len()));
            let expect: Vec<_> = (0..10).map(|c| (c, 100)).collect();
            assert_eq!(sums, expect);
            let mut hits = vec![0u8; 7];
            let tasks: Vec<(usize, &mut u8)> = hits.iter_mut().enumerate().collect();
            for_each_task(tasks, parallel, &|(_, h)| *h += 1);
            assert_eq!(hits, [1; 7]);
        }
        let squares = fill_chunks(1001, 256, &|start, out: &mut [usize]| {
            for (o, x) in out.iter_mut().enumerate() {
                *x = (start + o) * (start + o);
            }
        });
        assert!(squares.iter().enumerate().all(|(i, &x)| x == i * i));
        assert_eq!(squares.len(), 1001);
    }
}
