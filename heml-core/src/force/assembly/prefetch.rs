//! A cache hint for the rest batches: the driver runs a field's batches in order
//! over one array, and asks for the batch [`AHEAD`] batches on while it computes
//! this one.
//!
//! Why: profiles showed the kernels waiting on the first load of each batch's rest
//! data — HGO a fifth of its time (13 numbers per tet), the nodal element pass
//! (whose lumped sweep and nodal pass push the rest data out of cache between two
//! element passes) 233 samples on that load against 33 for the same loop run alone.
//! The hardware prefetcher does not keep up with a stream interleaved with the
//! gathers of the block's node buffer.

/// How many batches ahead [`prefetch`] asks for: a batch's kernel takes about as
/// long as a cache miss, so two batches give the lines time to arrive (measured on
/// HGO: 0 → 2.5×, 1 → 1.9×, 2 → 1.9×, 4 → 1.8× neo-Hookean's cost).
pub(crate) const AHEAD: usize = 2;

/// Asks the cache for the item `AHEAD` places after `rest[b]` (all its lines). A
/// hint only: an index past the end is never read, and off x86-64 it does nothing.
#[inline(always)]
pub(crate) fn prefetch<T>(rest: &[T], b: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let next = rest.as_ptr().wrapping_add(b.wrapping_add(AHEAD)) as *const i8;
        for line in 0..std::mem::size_of::<T>().div_ceil(64) {
            // SAFETY: a prefetch reads no memory the program can observe and never
            // faults, whatever the address (`wrapping_add` forms it without UB)
            unsafe { _mm_prefetch::<_MM_HINT_T0>(next.wrapping_add(64 * line)) }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (rest, b);
}
