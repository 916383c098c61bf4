//! Warnings about facts that do not change while the process runs (a law given as
//! text that is stressed at rest, say), logged the first time only: a Python loop or
//! a parameter sweep that builds the same law a thousand times should say so once,
//! not bury the log under a thousand copies.

use std::collections::HashSet;
use std::sync::Mutex;

/// Distinct messages remembered: past it, messages are logged every time rather
/// than remembered, so that a long run with ever new messages (a sweep over
/// parameter values, each named in its warning) holds bounded memory.
const REMEMBERED: usize = 1024;

/// Logs `msg` with `log::warn!` unless this process logged the same text before
/// through this function; returns whether it was logged.
pub(crate) fn warn_once(msg: &str) -> bool {
    static SEEN: Mutex<Option<HashSet<String>>> = Mutex::new(None);
    let fresh = {
        // a poisoned lock only means another thread panicked while holding it: the
        // set is still a set
        let mut seen = SEEN.lock().unwrap_or_else(|e| e.into_inner());
        let seen = seen.get_or_insert_with(HashSet::new);
        if seen.contains(msg) {
            false
        } else {
            if seen.len() < REMEMBERED {
                seen.insert(msg.to_owned());
            }
            true
        }
    };
    if fresh {
        log::warn!("{msg}");
    }
    fresh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_text_is_logged_once_and_memory_stays_bounded() {
        let tag = "warn_once test";
        assert!(warn_once(&format!("{tag}: a")));
        assert!(!warn_once(&format!("{tag}: a")));
        assert!(warn_once(&format!("{tag}: b")), "another text is logged");
        // a new text is always logged; once the set is full (other tests of this
        // process may have filled part of it), it is logged every time
        for k in 0..REMEMBERED {
            assert!(warn_once(&format!("{tag}: sweep {k}")), "{k}");
        }
        let past = format!("{tag}: past the bound");
        assert!(warn_once(&past) && warn_once(&past), "not remembered past the bound");
        assert!(!warn_once(&format!("{tag}: a")), "remembered ones stay remembered");
    }
}
