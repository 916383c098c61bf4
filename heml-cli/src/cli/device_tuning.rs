//! OS settings for a haptic device thread that `heml bench --haptic` tries, each
//! reporting what it got (an OS that refuses one leaves the thread as it was).
//!
//! - **Timer slack** (`prctl(PR_SET_TIMERSLACK)`): Linux lets a normal-priority
//!   thread's sleeps end up to 50 µs late by default, to batch wake-ups; 1 ns asks
//!   for wake-ups on time.
//! - **Short scheduler slice** (`sched_setattr` with `sched_runtime`, Linux ≥ 6.12,
//!   EEVDF): a normal-priority thread that asks for a slice shorter than the running
//!   thread's may preempt it when it wakes, instead of waiting for the running
//!   thread's slice (≈ 3 ms) to end — a device thread sharing its CPU with the
//!   simulation's worker gets on it in time without a real-time priority.
//! - **Locked memory** (`mlockall`): no page of the process is ever paged out or
//!   faulted in lazily again; process-wide and kept until exit.
//!
//! Everything here is Linux-only; elsewhere each call reports "not available".

/// Sets the calling thread's timer slack to 1 ns.
pub fn timer_slack_1ns() -> String {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: PR_SET_TIMERSLACK takes one unsigned long by value and touches no
        // memory of ours.
        let r = unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong, 0, 0, 0) };
        if r == 0 {
            "timer slack 1 ns".into()
        } else {
            format!("timer slack kept (prctl: {})", std::io::Error::last_os_error())
        }
    }
    #[cfg(not(target_os = "linux"))]
    {
        "timer slack: not available".into()
    }
}

/// The `struct sched_attr` of `sched_setattr(2)` (the libc crate does not declare
/// it), in its first published size.
#[cfg(target_os = "linux")]
#[repr(C)]
#[derive(Default)]
struct SchedAttr {
    size: u32,
    sched_policy: u32,
    sched_flags: u64,
    sched_nice: i32,
    sched_priority: u32,
    sched_runtime: u64,
    sched_deadline: u64,
    sched_period: u64,
}

/// Asks the scheduler for slices of `slice_ns` (clamped by the kernel to
/// 0.1–100 ms) for the calling thread at normal priority (SCHED_OTHER, nice 0).
pub fn short_slice(slice_ns: u64) -> String {
    #[cfg(target_os = "linux")]
    {
        let attr = SchedAttr {
            size: std::mem::size_of::<SchedAttr>() as u32,
            sched_policy: libc::SCHED_OTHER as u32,
            sched_runtime: slice_ns,
            ..SchedAttr::default()
        };
        // SAFETY: `attr` is a valid, initialised sched_attr of the size it declares,
        // alive for the call; pid 0 is the calling thread; flags 0.
        let r = unsafe { libc::syscall(libc::SYS_sched_setattr, 0, &attr as *const SchedAttr, 0) };
        if r == 0 {
            format!("slice {:.0} µs", slice_ns as f64 * 1e-3)
        } else {
            format!("slice kept (sched_setattr: {})", std::io::Error::last_os_error())
        }
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = slice_ns;
        "short slice: not available".into()
    }
}

/// Locks every page of the process, present and future, in memory.
pub fn lock_memory() -> String {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: mlockall takes flags only.
        let r = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
        if r == 0 {
            "memory locked".into()
        } else {
            format!("memory not locked (mlockall: {})", std::io::Error::last_os_error())
        }
    }
    #[cfg(not(target_os = "linux"))]
    {
        "mlockall: not available".into()
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// The timer slack set is the one the kernel reports back (PR_GET_TIMERSLACK),
    /// on a thread of its own so that no other test inherits it.
    #[test]
    fn timer_slack_is_set_on_the_calling_thread() {
        std::thread::spawn(|| {
            assert_eq!(timer_slack_1ns(), "timer slack 1 ns");
            // SAFETY: PR_GET_TIMERSLACK takes no argument and returns the slack.
            let got = unsafe { libc::prctl(libc::PR_GET_TIMERSLACK, 0, 0, 0, 0) };
            assert_eq!(got, 1);
        })
        .join()
        .unwrap();
    }

    /// A refused or accepted slice request says which; an accepted one keeps the
    /// thread at SCHED_OTHER.
    #[test]
    fn short_slice_keeps_normal_policy() {
        std::thread::spawn(|| {
            let got = short_slice(100_000);
            assert!(got == "slice 100 µs" || got.starts_with("slice kept"), "{got}");
            // SAFETY: sched_getscheduler takes a pid (0: this thread).
            assert_eq!(unsafe { libc::sched_getscheduler(0) }, libc::SCHED_OTHER);
        })
        .join()
        .unwrap();
    }
}
