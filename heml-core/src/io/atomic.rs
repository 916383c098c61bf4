//! Atomic file output: write a sibling temporary file, then rename it over the
//! target. Readers (ParaView polling a `.pvd`, a user opening the last frame) see
//! either the old complete file or the new complete file, never a prefix, and a
//! failed or interrupted write leaves the previous file untouched.
//!
//! The temporary file lives in the same directory because a rename is only atomic
//! within one file system. A process killed between creating and renaming it
//! (`kill -9`) leaves the temporary behind — possibly empty; the next run writing to
//! the directory removes those of dead processes ([`remove_stale_temporaries`]). No `fsync` is issued: that protects against power loss,
//! not against the process crashes this module is about, and would cost
//! milliseconds per simulation frame.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{HemlError, Result};

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `path` atomically: `fill` writes the content into a buffered temporary
/// file, which is renamed to `path` only if `fill` and the flush succeed.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
{
    let tmp = temp_path(path)?;
    let result = (|| {
        let file = File::create(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 16, file);
        fill(&mut w)?;
        w.flush()?;
        drop(w);
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        // Best effort: the temporary may not exist if creation failed.
        let _ = std::fs::remove_file(&tmp);
        HemlError::io(path, e)
    })
}

/// `dir/.name.tmp-PID-N`: hidden, unique per process and call, same directory.
fn temp_path(path: &Path) -> Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| HemlError::Invalid(format!("cannot write '{}': the path has no file name", path.display())))?;
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}-{n}", std::process::id()));
    Ok(path.with_file_name(tmp_name))
}

/// Removes from `dir` the temporaries of [`write_atomic`] (`.NAME.tmp-PID-N`) whose
/// process is no longer running: the leftovers of writers killed mid-write. Returns
/// how many were removed. Temporaries of live processes (another run writing to the
/// same directory, or this one) are kept; where liveness cannot be checked (no
/// `/proc`), nothing is removed.
pub fn remove_stale_temporaries(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let proc_fs = Path::new("/proc/self").exists();
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temp_owner) else {
            continue;
        };
        let dead = proc_fs && pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists();
        if dead && std::fs::remove_file(entry.path()).is_ok() {
            log::info!("removed {} left by an interrupted run", entry.path().display());
            removed += 1;
        }
    }
    removed
}

/// The process id in a temporary's name `.NAME.tmp-PID-N`.
fn temp_owner(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?;
    let (_, tail) = rest.rsplit_once(".tmp-")?;
    let (pid, n) = tail.split_once('-')?;
    n.parse::<u64>().ok()?;
    pid.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stale_temporaries_of_dead_processes_are_removed() {
        let dir = std::env::temp_dir().join(format!("heml-atomic-stale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // pid 4194304 + 1 is above Linux's pid_max: never a live process
        let dead = dir.join(".frame_00003.vtu.tmp-4194305-7");
        let ours = dir.join(format!(".energy.csv.tmp-{}-0", std::process::id()));
        let other = dir.join("frame_00003.vtu");
        for f in [&dead, &ours, &other] {
            std::fs::write(f, b"").unwrap();
        }
        let expected = usize::from(Path::new("/proc/self").exists());
        assert_eq!(remove_stale_temporaries(&dir), expected);
        assert_eq!(dead.exists(), expected == 0);
        assert!(ours.exists() && other.exists());
        assert_eq!(temp_owner(".a.b.tmp-12-3"), Some(12));
        assert_eq!(temp_owner("a.tmp-12-3"), None);
        assert_eq!(temp_owner(".a.tmp-x-3"), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn failed_write_keeps_old_file_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("heml-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("out.txt");
        write_atomic(&path, |w| w.write_all(b"old")).unwrap();
        let e = write_atomic(&path, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(
            e.to_string().contains("out.txt") && e.to_string().contains("disk full"),
            "{e}"
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().filter_map(|e| e.ok()).collect();
        assert_eq!(leftovers.len(), 1, "temporary file left behind");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
