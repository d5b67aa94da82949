//! Write-then-rename, so files are either the old or the new version, never half-written.
//!
//! The temporary file gets an unguessable name and is created exclusively without following
//! a symlink, so a link planted in the folder cannot redirect the write elsewhere. A killed
//! process leaves its temporary behind; [`remove_stale_temporaries`] clears them at the
//! next run in that folder (under the folder's lock, so never a live writer's file).

use super::error::{Error, Result};
use std::fs::{File, OpenOptions};
use std::hash::{BuildHasher, Hasher};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Marks a temporary: `.NAME.tmp-SUFFIX`.
const TMP_TAG: &str = ".tmp-";

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| Error::Input(format!("{}: not a file path", path.display())))?;
    let (tmp, mut f) = create_temporary(dir, &name.to_string_lossy())
        .map_err(|e| Error::io(format!("writing {}", path.display()), e))?;
    let mut write = || -> std::io::Result<()> {
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    };
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(format!("writing {}", path.display()), e)
    })
}

/// Creates `sub` (a path below `root`) folder by folder, refusing a part that is a symbolic
/// link or not a folder: a results folder received from someone else could point `tables/`
/// anywhere, and every write below it would follow.
pub fn create_dir_within(root: &Path, sub: &Path) -> Result<()> {
    let rel = sub
        .strip_prefix(root)
        .map_err(|_| Error::Input(format!("{}: not inside {}", sub.display(), root.display())))?;
    std::fs::create_dir_all(root)
        .map_err(|e| Error::io(format!("creating {}", root.display()), e))?;
    let mut at = root.to_path_buf();
    for part in rel.components() {
        at.push(part);
        match std::fs::symlink_metadata(&at) {
            Ok(m) if m.file_type().is_symlink() => {
                return Err(Error::Input(format!(
                    "{}: a symbolic link; a results folder's subfolders must be real folders \
                     (remove the link and run again)",
                    at.display()
                )));
            }
            Ok(m) if !m.is_dir() => {
                return Err(Error::Input(format!(
                    "{}: exists and is not a folder (remove it and run again)",
                    at.display()
                )));
            }
            Ok(_) => {}
            Err(_) => std::fs::create_dir(&at)
                .or_else(|e| if at.is_dir() { Ok(()) } else { Err(e) })
                .map_err(|e| Error::io(format!("creating {}", at.display()), e))?,
        }
    }
    Ok(())
}

/// A new, empty temporary for `name` in `dir`: a random suffix (the OS-seeded keys of
/// std's `RandomState`), `O_CREAT | O_EXCL` and, on Unix, `O_NOFOLLOW`.
fn create_temporary(dir: &Path, name: &str) -> std::io::Result<(PathBuf, File)> {
    let mut last = None;
    for attempt in 0u32..16 {
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u32(std::process::id());
        h.write_u32(attempt);
        h.write_u128(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap_or_default()
                .as_nanos(),
        );
        let tmp = dir.join(format!(".{name}{TMP_TAG}{:016x}", h.finish()));
        let mut o = OpenOptions::new();
        o.write(true).create_new(true);
        #[cfg(unix)]
        {
            use std::os::unix::fs::OpenOptionsExt;
            o.custom_flags(libc::O_NOFOLLOW).mode(0o644);
        }
        match o.open(&tmp) {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.expect("at least one attempt"))
}

/// Removes the temporaries (`.*.tmp-*`) that killed processes left in `dir` and its
/// direct subfolders; returns how many. Call only while holding the folder's lock. A
/// symlink with such a name is removed as a link; its target is never touched.
pub fn remove_stale_temporaries(dir: &Path) -> usize {
    let mut removed = 0;
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        let Ok(kind) = e.file_type() else { continue };
        if kind.is_dir() {
            removed += std::fs::read_dir(e.path())
                .into_iter()
                .flatten()
                .flatten()
                .filter(|s| is_temporary(&s.file_name().to_string_lossy()))
                .filter(|s| s.file_type().is_ok_and(|k| !k.is_dir()))
                .filter(|s| std::fs::remove_file(s.path()).is_ok())
                .count();
        } else if is_temporary(&name) && std::fs::remove_file(e.path()).is_ok() {
            removed += 1;
        }
    }
    removed
}

fn is_temporary(name: &str) -> bool {
    name.starts_with('.') && name.contains(TMP_TAG)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_content_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.json");
        atomic_write(&p, b"one").unwrap();
        atomic_write(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[cfg(unix)]
    #[test]
    fn a_planted_symlink_is_not_followed() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        std::fs::create_dir_all(dir.join("tables")).unwrap();
        let victim = root.path().join("victim.txt");
        std::fs::write(&victim, "keep").unwrap();
        // Links at the names the old code used (`.NAME.tmp-PID`), to a file outside.
        for name in ["a.json", "b.json"] {
            let link = dir.join(format!(".{name}.tmp-{}", std::process::id()));
            std::os::unix::fs::symlink(&victim, &link).unwrap();
        }
        atomic_write(&dir.join("a.json"), b"new").unwrap();
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
        assert_eq!(std::fs::read(dir.join("a.json")).unwrap(), b"new");
    }

    #[cfg(unix)]
    #[test]
    fn stale_temporaries_are_cleared_links_as_links() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        std::fs::create_dir_all(dir.join("tables")).unwrap();
        let victim = root.path().join("victim.txt");
        std::fs::write(&victim, "keep").unwrap();
        std::fs::write(dir.join("a.json"), "a").unwrap();
        std::os::unix::fs::symlink(&victim, dir.join(".b.json.tmp-77")).unwrap();
        std::os::unix::fs::symlink(&victim, dir.join(".b.json.tmp-78")).unwrap();
        // A killed run's leftovers, one in a subfolder; regular files are untouched.
        std::fs::write(dir.join(".c.json.tmp-123"), "x").unwrap();
        std::fs::write(dir.join("tables/.t.md.tmp-9"), "x").unwrap();
        assert_eq!(remove_stale_temporaries(&dir), 4);
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
        let mut left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["a.json", "tables"]);
        assert_eq!(std::fs::read_dir(dir.join("tables")).unwrap().count(), 0);
    }

    #[cfg(unix)]
    #[test]
    fn a_linked_subfolder_is_refused_and_nothing_written_through_it() {
        let tmp = tempfile::tempdir().unwrap();
        let (root, elsewhere) = (tmp.path().join("out"), tmp.path().join("elsewhere"));
        std::fs::create_dir_all(&root).unwrap();
        std::fs::create_dir_all(&elsewhere).unwrap();
        std::os::unix::fs::symlink(&elsewhere, root.join("tables")).unwrap();
        let err = create_dir_within(&root, &root.join("tables")).unwrap_err();
        assert!(err.to_string().contains("symbolic link"), "{err}");
        assert!(create_dir_within(&root, &root.join("tables/x")).is_err());
        assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
        create_dir_within(&root, &root.join("ioh/a/b")).unwrap();
        assert!(root.join("ioh/a/b").is_dir());
        assert!(create_dir_within(&root, &tmp.path().join("outside")).is_err());
    }
}
