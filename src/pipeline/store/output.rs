//! Which files of a results folder are optbench's, so that a run never mixes its files with
//! another run's or a user's: `run` refuses a folder holding anything but results of the
//! same suite ([`claim`]), `--overwrite` removes only optbench's own files ([`clear_written`]),
//! and the report writes each generated subfolder afresh and swaps it in ([`FreshFolder`]),
//! so no plot or table of an objective no longer in the suite survives a regeneration.
//!
//! Nothing here follows a symbolic link: a link at one of optbench's names is removed as a
//! link, its target untouched; a link at any other name is left alone.

use super::lock::LOCK_FILE;
use super::progress::{PROGRESS_FILE, read_progress};
use crate::base::create_dir_within;
use crate::base::error::{Error, Result};
use std::path::{Path, PathBuf};

/// Files optbench writes at the top of a results folder (benchmark and control suites,
/// the report).
pub const WRITTEN_FILES: &[&str] = &[
    "suite.toml",
    "provenance.json",
    "traces.jsonl",
    "summary.json",
    PROGRESS_FILE,
    "report.md",
    "report.html",
    "analysis.json",
    "runs.jsonl",
    "models.jsonl",
];

/// Folders optbench writes whole: everything in them is generated, and replaced whole.
pub const WRITTEN_FOLDERS: &[&str] = &["tables", "plots", "ioh", "figures", "signals"];

/// Marks a generated folder being written (`.NAME.staged-SUFFIX`) or being removed after a
/// swap (`.NAME.retired-SUFFIX`); a killed process's leftovers are cleared by
/// [`remove_stale_staging`].
const STAGED_TAG: &str = ".staged-";
const RETIRED_TAG: &str = ".retired-";

fn is_ours(name: &str) -> bool {
    name == LOCK_FILE
        || WRITTEN_FILES.contains(&name)
        || WRITTEN_FOLDERS.contains(&name)
        || is_scratch(name)
}

/// A temporary of [`crate::base::atomic_write`] or a staged or retired folder.
fn is_scratch(name: &str) -> bool {
    name.starts_with('.')
        && (name.contains(".tmp-") || name.contains(STAGED_TAG) || name.contains(RETIRED_TAG))
}

/// The suite whose results `dir` holds, from its progress log, provenance or stored suite
/// (in that order); None when it holds none of them.
pub fn suite_of(dir: &Path) -> Result<Option<String>> {
    if let Some(p) = read_progress(dir)? {
        return Ok(Some(p.header.suite));
    }
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok();
    if let Some(name) = read("provenance.json")
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| v["suite_name"].as_str().map(String::from))
    {
        return Ok(Some(name));
    }
    Ok(read("suite.toml")
        .and_then(|t| t.parse::<toml::Table>().ok())
        .and_then(|t| t.get("name").and_then(|n| n.as_str()).map(String::from)))
}

/// The entries of `dir` (names), sorted; none if it does not exist.
fn entries(dir: &Path) -> Result<Vec<String>> {
    let rd = match std::fs::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(format!("reading {}", dir.display()), e)),
    };
    let mut names: Vec<String> = rd
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    Ok(names)
}

/// Checks that `run` of suite `suite` may write into `dir`: it is missing or empty, or holds
/// results of the same suite (with or without other files beside them). Any other folder
/// is refused with how to proceed, unless `overwrite`, which first removes optbench's own
/// files there ([`clear_written`]) and leaves every other file alone. Call while holding
/// the folder's lock.
pub fn claim(dir: &Path, suite: &str, overwrite: bool) -> Result<()> {
    let names = entries(dir)?;
    if names.iter().all(|n| is_scratch(n) || n == LOCK_FILE) {
        return Ok(());
    }
    if overwrite {
        clear_written(dir)?;
        return Ok(());
    }
    let holds_results = names
        .iter()
        .any(|n| is_ours(n) && !is_scratch(n) && n != LOCK_FILE);
    let stored = if holds_results { suite_of(dir)? } else { None };
    if stored.as_deref() == Some(suite) {
        return Ok(());
    }
    let how = "choose another --out, or pass --overwrite to remove optbench's files there \
               (results, report, tables, plots, ioh) and run; other files are left alone";
    Err(Error::Input(match stored {
        Some(other) => format!(
            "{}: holds the results of suite `{other}`, not `{suite}` (--resume continues only a run of the same suite); {how}",
            dir.display()
        ),
        None if holds_results => format!(
            "{}: holds results of an unknown suite (no progress.jsonl, provenance.json or suite.toml names it); {how}",
            dir.display()
        ),
        None => {
            let theirs: Vec<&str> = names
                .iter()
                .map(String::as_str)
                .filter(|n| !is_ours(n))
                .collect();
            format!(
                "{}: is not empty and holds no optbench results ({}{}); {how}",
                dir.display(),
                theirs[..theirs.len().min(5)].join(", "),
                if theirs.len() > 5 { ", ..." } else { "" }
            )
        }
    }))
}

/// Locks `dir` ([`super::lock_folder`]) and [`claim`]s it for suite `suite`; a refused folder
/// is left as it was, without the lock file this call created.
pub fn lock_and_claim(dir: &Path, suite: &str, overwrite: bool) -> Result<super::FolderLock> {
    let lock_path = dir.join(LOCK_FILE);
    let had_lock = std::fs::symlink_metadata(&lock_path).is_ok();
    let lock = super::lock_folder(dir)?;
    match claim(dir, suite, overwrite) {
        Ok(()) => Ok(lock),
        Err(e) => {
            if !had_lock {
                let _ = std::fs::remove_file(&lock_path);
            }
            Err(e)
        }
    }
}

/// Removes optbench's own files and folders from `dir` (not its lock): a link at one of
/// those names is removed as a link. Returns the names removed.
pub fn clear_written(dir: &Path) -> Result<Vec<String>> {
    let mut removed = Vec::new();
    for name in entries(dir)? {
        if name == LOCK_FILE || !is_ours(&name) {
            continue;
        }
        let path = dir.join(&name);
        remove_entry(&path)?;
        removed.push(name);
    }
    Ok(removed)
}

/// Removes `path` without following it: a link or file with `remove_file`, a real folder
/// with `remove_dir_all` (which does not follow links inside it either).
fn remove_entry(path: &Path) -> Result<()> {
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(format!("reading {}", path.display()), e)),
    };
    let r = if meta.is_dir() {
        std::fs::remove_dir_all(path)
    } else {
        std::fs::remove_file(path)
    };
    r.map_err(|e| Error::io(format!("removing {}", path.display()), e))
}

/// Removes the staged and retired folders that killed processes left in `dir`. Call only
/// while holding the folder's lock.
pub fn remove_stale_staging(dir: &Path) {
    for name in entries(dir).unwrap_or_default() {
        if name.starts_with('.') && (name.contains(STAGED_TAG) || name.contains(RETIRED_TAG)) {
            let _ = remove_entry(&dir.join(name));
        }
    }
}

/// A generated subfolder written afresh beside the old one and swapped in by [`Self::commit`],
/// so a reader sees the old folder or the new one whole, and nothing of the old survives.
#[derive(Debug)]
pub struct FreshFolder {
    target: PathBuf,
    staged: PathBuf,
}

impl FreshFolder {
    /// Starts `root/name` afresh. An existing `root/name` that is a link or not a folder is
    /// refused (see [`create_dir_within`]).
    pub fn begin(root: &Path, name: &str) -> Result<FreshFolder> {
        let target = root.join(name);
        create_dir_within(root, &target)?;
        for attempt in 0u32.. {
            let staged = root.join(format!(".{name}{STAGED_TAG}{}", suffix(attempt)));
            match std::fs::create_dir(&staged) {
                Ok(()) => return Ok(FreshFolder { target, staged }),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && attempt < 16 => {}
                Err(e) => return Err(Error::io(format!("creating {}", staged.display()), e)),
            }
        }
        unreachable!("the loop returns")
    }

    /// Where to write the new content.
    pub fn path(&self) -> &Path {
        &self.staged
    }

    /// Puts the new folder in place of the old one and removes the old one.
    pub fn commit(mut self) -> Result<()> {
        let staged = std::mem::take(&mut self.staged);
        let parent = self.target.parent().unwrap_or(Path::new("."));
        let name = self
            .target
            .file_name()
            .unwrap_or_default()
            .to_string_lossy();
        let retired = parent.join(format!(".{name}{RETIRED_TAG}{}", suffix(0)));
        let err = |e| Error::io(format!("replacing {}", self.target.display()), e);
        if exchange(&staged, &self.target).is_ok() {
            // The staged name now holds the old folder.
            return remove_entry(&staged);
        } else {
            // No atomic exchange here: two renames, the folder briefly absent.
            match std::fs::rename(&self.target, &retired) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(err(e)),
            }
            std::fs::rename(&staged, &self.target).map_err(err)?;
        }
        remove_entry(&retired)
    }
}

impl Drop for FreshFolder {
    /// A folder never committed (its writing failed) is removed; the old one stays.
    fn drop(&mut self) {
        if !self.staged.as_os_str().is_empty() {
            let _ = remove_entry(&self.staged);
        }
    }
}

/// A fresh name part: the process and the time, so that two attempts rarely meet.
fn suffix(attempt: u32) -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
        .subsec_nanos();
    format!("{}-{nanos:09}-{attempt}", std::process::id())
}

/// Swaps two paths in one step (Linux `renameat2(RENAME_EXCHANGE)`); an error where the
/// system cannot.
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        use std::ffi::CString;
        use std::os::unix::ffi::OsStrExt;
        let c = |p: &Path| {
            CString::new(p.as_os_str().as_bytes())
                .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))
        };
        let (ca, cb) = (c(a)?, c(b)?);
        // SAFETY: two NUL-terminated paths that live across the call.
        let r = unsafe {
            libc::renameat2(
                libc::AT_FDCWD,
                ca.as_ptr(),
                libc::AT_FDCWD,
                cb.as_ptr(),
                libc::RENAME_EXCHANGE,
            )
        };
        if r == 0 {
            Ok(())
        } else {
            Err(std::io::Error::last_os_error())
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        let _ = (a, b);
        Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        entries(dir).unwrap()
    }

    #[test]
    fn a_fresh_folder_replaces_the_old_whole_and_leaves_no_scratch() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        std::fs::create_dir_all(root.join("plots")).unwrap();
        std::fs::write(root.join("plots/old.svg"), "old").unwrap();
        let f = FreshFolder::begin(root, "plots").unwrap();
        std::fs::write(f.path().join("new.svg"), "new").unwrap();
        // Until the commit a reader sees the old folder.
        assert_eq!(names(&root.join("plots")), ["old.svg"]);
        f.commit().unwrap();
        assert_eq!(names(&root.join("plots")), ["new.svg"]);
        assert_eq!(names(root), ["plots"]);
        // A folder that did not exist yet.
        let f = FreshFolder::begin(root, "ioh").unwrap();
        f.commit().unwrap();
        assert_eq!(names(root), ["ioh", "plots"]);
        // One abandoned (its writing failed): the old folder stays, the new one goes.
        let f = FreshFolder::begin(root, "plots").unwrap();
        std::fs::write(f.path().join("half.svg"), "half").unwrap();
        drop(f);
        assert_eq!(names(root), ["ioh", "plots"]);
        assert_eq!(names(&root.join("plots")), ["new.svg"]);
    }

    #[cfg(unix)]
    #[test]
    fn overwrite_clears_only_optbenchs_names_and_never_follows_a_link() {
        let tmp = tempfile::tempdir().unwrap();
        let (dir, elsewhere) = (tmp.path().join("out"), tmp.path().join("elsewhere"));
        std::fs::create_dir_all(dir.join("plots")).unwrap();
        std::fs::create_dir_all(elsewhere.join("keep")).unwrap();
        std::fs::write(elsewhere.join("keep/x.png"), "x").unwrap();
        std::fs::write(dir.join("plots/a.png"), "a").unwrap();
        std::fs::write(dir.join("summary.json"), "{}").unwrap();
        std::fs::write(dir.join("notes.txt"), "mine").unwrap();
        std::fs::write(dir.join(LOCK_FILE), "").unwrap();
        std::os::unix::fs::symlink(&elsewhere, dir.join("ioh")).unwrap();
        std::os::unix::fs::symlink(&elsewhere, dir.join("mine")).unwrap();
        std::fs::create_dir(dir.join(".tables.staged-1")).unwrap();
        let mut removed = clear_written(&dir).unwrap();
        removed.sort();
        assert_eq!(
            removed,
            [".tables.staged-1", "ioh", "plots", "summary.json"]
        );
        assert_eq!(names(&dir), [LOCK_FILE, "mine", "notes.txt"]);
        assert_eq!(names(&elsewhere.join("keep")), ["x.png"]);
    }

    #[test]
    fn claim_takes_empty_and_same_suite_folders_and_refuses_the_rest() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        claim(&dir, "a", false).unwrap();
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(LOCK_FILE), "").unwrap();
        std::fs::write(dir.join(".x.json.tmp-1"), "").unwrap();
        claim(&dir, "a", false).unwrap();
        std::fs::write(dir.join("notes.txt"), "mine").unwrap();
        let e = claim(&dir, "a", false).unwrap_err().to_string();
        assert!(
            e.contains("not empty and holds no optbench results (") && e.contains("notes.txt"),
            "{e}"
        );
        assert!(e.contains("--out") && e.contains("--overwrite"), "{e}");
        std::fs::write(dir.join("suite.toml"), "name = \"b\"\nseed = 1\n").unwrap();
        let e = claim(&dir, "a", false).unwrap_err().to_string();
        assert!(
            e.contains("results of suite `b`, not `a`") && e.contains("--resume"),
            "{e}"
        );
        std::fs::write(dir.join("provenance.json"), r#"{"suite_name": "a"}"#).unwrap();
        claim(&dir, "a", false).unwrap();
        std::fs::write(dir.join("provenance.json"), "not json").unwrap();
        std::fs::write(dir.join("suite.toml"), "not toml [").unwrap();
        let e = claim(&dir, "a", false).unwrap_err().to_string();
        assert!(e.contains("unknown suite"), "{e}");
        claim(&dir, "a", true).unwrap();
        assert_eq!(names(&dir), [LOCK_FILE, "notes.txt"]);
    }
}
