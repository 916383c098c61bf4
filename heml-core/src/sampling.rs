//! Deterministic pseudo-random numbers (xorshift64), for what must be the same on
//! every run: the power iteration's start vector of the stability estimate, and the
//! unit tests' random matrices and tets. Not for statistics.

/// Numbers uniform in [−½, ½) from `seed` (non-zero), the same sequence on every run
/// and machine: xorshift64's state, its top 53 bits as a fraction, minus ½.
pub(crate) fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}
