//! Worker-thread pools for the parallel force assembly, optionally pinned to CPUs.
//!
//! The force fields run on whatever rayon pool they are called from
//! (`pool.install(..)`), else on rayon's global pool. For steady, repeatable step
//! times — a haptic loop, a benchmark — pin the workers: when a pool's threads are
//! woken after idling, the OS may first put two of them on the same CPU and take
//! milliseconds to spread them. On the 2-core test machine, `heml bench` measured
//! the 2-thread force evaluation 10–15 % faster with pinned workers (medians of
//! interleaved runs, see docs/guide/performance.md), and steadier.
//!
//! ```text
//! use crate::threads::{thread_pool, Placement};
//!
//! let (pool, placement) = thread_pool(2, Placement::Pinned)?;
//! // `placement` says what was done: pinning needs a CPU per worker
//! let sum: u64 = pool.install(|| (1..=100u64).sum());
//! assert_eq!(sum, 5050);
//! assert!(placement == Placement::Pinned || placement == Placement::Os);
//! # Ok::<(), heml::HemlError>(())
//! ```

use heml::{HemlError, Result};

/// Where a pool's worker threads run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placement {
    /// Wherever the OS schedules them.
    Os,
    /// The k-th worker on the k-th CPU this process may use, for good.
    Pinned,
}

/// A rayon pool of `threads` workers placed as asked, and the placement it got:
/// [`Placement::Pinned`] falls back to [`Placement::Os`] when the process may use
/// fewer CPUs than `threads`, or the platform cannot pin.
pub fn thread_pool(threads: usize, placement: Placement) -> Result<(rayon::ThreadPool, Placement)> {
    if threads == 0 {
        return Err(HemlError::Invalid("a thread pool needs at least 1 thread".into()));
    }
    let cores = match placement {
        Placement::Pinned => cpus_for(threads),
        Placement::Os => None,
    };
    let mut builder = rayon::ThreadPoolBuilder::new().num_threads(threads);
    let got = if let Some(cores) = cores {
        builder = builder.start_handler(move |k| {
            // a failed pin leaves the worker where the OS put it: slower, not wrong
            core_affinity::set_for_current(cores[k]);
        });
        Placement::Pinned
    } else {
        Placement::Os
    };
    let pool = builder
        .build()
        .map_err(|e| HemlError::Invalid(format!("cannot start {threads} threads: {e}")))?;
    Ok((pool, got))
}

/// The placement [`thread_pool`] gives `threads` workers when asked for `placement`.
pub fn placement_for(threads: usize, placement: Placement) -> Placement {
    match placement {
        Placement::Pinned if cpus_for(threads).is_some() => Placement::Pinned,
        _ => Placement::Os,
    }
}

/// Most worker threads a pool may have: 4 × the CPUs this process may use, at
/// most 1024 (at least 8).
pub fn max_threads() -> usize {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    cpus.saturating_mul(4).clamp(8, 1024)
}

/// A `--threads` value (clap parser): 1 to [`max_threads`].
pub fn thread_count(s: &str) -> std::result::Result<usize, String> {
    thread_count_or_zero(s).and_then(|n| match n {
        0 => Err("a thread pool needs at least 1 thread".into()),
        n => Ok(n),
    })
}

/// A thread count where 0 means a default (clap parser): 0 to [`max_threads`].
pub fn thread_count_or_zero(s: &str) -> std::result::Result<usize, String> {
    let n: usize = s.parse().map_err(|_| format!("{s:?} is not a number of threads"))?;
    let max = max_threads();
    if n > max {
        return Err(format!(
            "{n} threads is more than the {max} allowed (4 × the CPUs this process may use, at most 1024)"
        ));
    }
    Ok(n)
}

/// The CPUs this process may use, when there are at least `threads` of them.
fn cpus_for(threads: usize) -> Option<Vec<core_affinity::CoreId>> {
    core_affinity::get_core_ids().filter(|c| c.len() >= threads)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thread_counts_are_bounded() {
        assert_eq!(thread_count("1"), Ok(1));
        assert_eq!(thread_count(&max_threads().to_string()), Ok(max_threads()));
        assert!(max_threads() <= 1024);
        for bad in ["0", "100000", "18446744073709551616", "-1", "x"] {
            assert!(thread_count(bad).is_err(), "{bad}");
        }
        assert_eq!(thread_count_or_zero("0"), Ok(0));
    }

    #[test]
    fn zero_threads_is_an_error() {
        let err = thread_pool(0, Placement::Os).unwrap_err();
        assert!(err.to_string().contains("at least 1 thread"), "{err}");
    }

    #[test]
    fn pinning_falls_back_when_there_are_too_few_cpus() {
        let cpus = core_affinity::get_core_ids().map_or(0, |c| c.len());
        let (pool, got) = thread_pool(cpus + 1, Placement::Pinned).unwrap();
        assert_eq!(got, Placement::Os);
        assert_eq!(placement_for(cpus + 1, Placement::Pinned), Placement::Os);
        assert_eq!(pool.current_num_threads(), cpus + 1);
    }

    #[test]
    fn pinned_workers_run_on_distinct_cpus() {
        let Some(cores) = core_affinity::get_core_ids() else {
            return; // the platform cannot pin: nothing to check
        };
        let n = cores.len().min(2);
        let (pool, got) = thread_pool(n, Placement::Pinned).unwrap();
        assert_eq!(got, Placement::Pinned);
        // each worker's affinity is now its one CPU
        let seen: Vec<usize> = pool.broadcast(|_| {
            let ids = core_affinity::get_core_ids().unwrap();
            assert_eq!(ids.len(), 1, "a pinned worker may run on {} CPUs", ids.len());
            ids[0].id
        });
        let mut distinct = seen.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), n, "workers on CPUs {seen:?}");
    }
}
