//! The results folder's lock: one `run`, `report` or `merge` writes a folder at a time, so
//! two processes never mix their files. An advisory `flock` on `DIR/.optbench.lock`,
//! taken without waiting; the OS drops it when the holder ends, however it ends (SIGKILL
//! included), so a lock is never stale. The file names the holder (pid, start time,
//! command) for the message of the one refused. Taking the lock also clears the
//! temporaries and staged folders that killed runs left
//! ([`crate::base::remove_stale_temporaries`], [`super::output::remove_stale_staging`]).

use crate::base::error::{Error, Result};
use std::fs::File;
use std::path::Path;

/// The lock file's name inside a results folder.
pub const LOCK_FILE: &str = ".optbench.lock";

/// Held while alive; dropping it (or the process ending) releases the folder.
#[derive(Debug)]
pub struct FolderLock {
    _file: File,
}

/// Creates `dir` if needed and locks it, or refuses (exit 2) naming the holder.
pub fn lock_folder(dir: &Path) -> Result<FolderLock> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::io(format!("creating {}", dir.display()), e))?;
    let path = dir.join(LOCK_FILE);
    let mut o = std::fs::OpenOptions::new();
    o.read(true).write(true).create(true).truncate(false);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.custom_flags(libc::O_NOFOLLOW).mode(0o644);
    }
    let file = o
        .open(&path)
        .map_err(|e| Error::io(format!("opening {}", path.display()), e))?;
    #[cfg(unix)]
    {
        use std::io::Write;
        use std::os::fd::AsRawFd;
        // SAFETY: flock on a descriptor this function owns; no memory is passed.
        if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
            let e = std::io::Error::last_os_error();
            if e.raw_os_error() != Some(libc::EWOULDBLOCK) {
                return Err(Error::io(format!("locking {}", path.display()), e));
            }
            let holder = std::fs::read_to_string(&path).unwrap_or_default();
            let holder = holder.trim();
            return Err(Error::Input(format!(
                "{}: in use by another optbench process ({}); wait for it to end or choose another folder",
                dir.display(),
                if holder.is_empty() {
                    "it has just started"
                } else {
                    holder
                }
            )));
        }
        let command: Vec<String> = std::env::args().collect();
        let holder = format!(
            "pid {}, started {}, command `{}`\n",
            std::process::id(),
            humantime::format_rfc3339_seconds(std::time::SystemTime::now()),
            command.join(" ")
        );
        let mut f = &file;
        let _ = file.set_len(0);
        let _ = f.write_all(holder.as_bytes());
    }
    crate::base::remove_stale_temporaries(dir);
    super::output::remove_stale_staging(dir);
    Ok(FolderLock { _file: file })
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn a_second_holder_is_refused_with_the_first_named_until_it_lets_go() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let first = lock_folder(&out).unwrap();
        let e = lock_folder(&out).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let msg = e.to_string();
        assert!(
            msg.contains(&format!("pid {}", std::process::id())) && msg.contains("in use"),
            "{msg}"
        );
        drop(first);
        lock_folder(&out).unwrap();
    }
}
