//! `progress.jsonl`: the append-only log of finished trials that makes a run resumable.
//!
//! The first line is a [`ProgressHeader`] naming the run (suite fingerprint, build, the
//! overrides of the command line, the shard); every further line is one finished trial,
//! `{"key": ..., "record": ...}`, written with a single `write` the moment the trial ends.
//! A process killed at any point (SIGKILL included) leaves every finished trial on disk and
//! at most one torn last line, which [`read_progress`] ignores and [`ProgressLog::resume`]
//! cuts off before appending. Lines are not fsynced one by one: the log survives a killed
//! process, not a power cut in the last seconds.

use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use serde::{Deserialize, Serialize};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The log's file name inside a results folder.
pub const PROGRESS_FILE: &str = "progress.jsonl";

/// Format tag of the first line.
pub const FORMAT: &str = "optbench-progress-1";

/// What a run was: two runs may share trials only if their headers agree.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProgressHeader {
    pub format: String,
    pub suite: String,
    /// Path of the suite file as given (to resolve its relative paths when merging).
    pub suite_file: String,
    /// Hash of the suite text and the command-line overrides below.
    pub fingerprint: String,
    /// Tool version and git commit of the build that ran it.
    pub build: String,
    /// Effective seed, trials and budget override (`--seed`, `--trials`, `--budget`).
    pub seed: u64,
    pub trials: usize,
    pub budget: Option<u64>,
    /// `(k, n)` for `--shard k/n`; None for the whole plan.
    pub shard: Option<(usize, usize)>,
    /// Trials this run (or shard) has to finish.
    pub planned: usize,
    /// RFC 3339 UTC time the log was started.
    pub started: String,
}

/// One finished trial.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ProgressLine {
    /// Hash of the trial's full configuration (see `scale::trial_key`).
    pub key: String,
    pub record: TrialRecord,
}

/// A log read back.
#[derive(Debug)]
pub struct Progress {
    pub header: ProgressHeader,
    /// Finished trials in the order they were written.
    pub lines: Vec<ProgressLine>,
    /// Bytes up to the end of the last complete line.
    pub valid_len: u64,
    /// Whether a torn (incomplete or unreadable) last line was dropped.
    pub torn: bool,
}

/// Reads `dir/progress.jsonl`; `Ok(None)` if there is none.
pub fn read_progress(dir: &Path) -> Result<Option<Progress>> {
    let path = dir.join(PROGRESS_FILE);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(format!("reading {}", path.display()), e)),
    };
    let mut header: Option<ProgressHeader> = None;
    let mut lines = Vec::new();
    let mut valid_len = 0u64;
    let mut torn = false;
    let mut start = 0usize;
    let mut number = 0usize;
    while start < bytes.len() {
        number += 1;
        let Some(end) = bytes[start..].iter().position(|&b| b == b'\n') else {
            // No newline: a write cut short by a kill.
            torn = true;
            break;
        };
        let line = &bytes[start..start + end];
        let next = start + end + 1;
        if header.is_none() {
            let h: ProgressHeader = serde_json::from_slice(line).map_err(|e| {
                Error::at(
                    &path,
                    number,
                    format!("not an optbench progress header: {e}"),
                )
            })?;
            if h.format != FORMAT {
                return Err(Error::at(
                    &path,
                    number,
                    format!("format `{}`, expected `{FORMAT}`", h.format),
                ));
            }
            header = Some(h);
        } else {
            match serde_json::from_slice::<ProgressLine>(line) {
                Ok(l) => lines.push(l),
                Err(e) if next >= bytes.len() => {
                    // Only the very last line may be damaged (a kill mid-write).
                    let _ = e;
                    torn = true;
                    break;
                }
                Err(e) => {
                    return Err(Error::at(&path, number, format!("not a trial line: {e}")));
                }
            }
        }
        valid_len = next as u64;
        start = next;
    }
    let Some(header) = header else {
        // Killed before the header was complete: nothing was finished.
        return Ok(None);
    };
    Ok(Some(Progress {
        header,
        lines,
        valid_len,
        torn,
    }))
}

/// An open log that trials are appended to, from any thread.
pub struct ProgressLog {
    path: PathBuf,
    file: Mutex<File>,
}

impl ProgressLog {
    /// Starts a new log in `dir` with `header` and the already finished `lines` (written to
    /// a temporary file and renamed, so an old log is replaced whole or not at all).
    pub fn create(dir: &Path, header: &ProgressHeader, lines: &[ProgressLine]) -> Result<Self> {
        let path = dir.join(PROGRESS_FILE);
        let mut bytes = serde_json::to_vec(header).expect("serialisable");
        bytes.push(b'\n');
        for l in lines {
            serde_json::to_writer(&mut bytes, l).expect("serialisable");
            bytes.push(b'\n');
        }
        crate::base::atomic_write(&path, &bytes)?;
        Self::open(path)
    }

    /// Reopens an existing log for appending, cutting off a torn last line first.
    pub fn resume(dir: &Path, valid_len: u64) -> Result<Self> {
        let path = dir.join(PROGRESS_FILE);
        let f = OpenOptions::new()
            .write(true)
            .open(&path)
            .map_err(|e| Error::io(format!("opening {}", path.display()), e))?;
        f.set_len(valid_len)
            .map_err(|e| Error::io(format!("truncating {}", path.display()), e))?;
        drop(f);
        Self::open(path)
    }

    fn open(path: PathBuf) -> Result<Self> {
        let file = OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| Error::io(format!("opening {}", path.display()), e))?;
        Ok(ProgressLog {
            path,
            file: Mutex::new(file),
        })
    }

    /// Appends one finished trial as one line, in one write.
    pub fn append(&self, key: &str, record: &TrialRecord) -> Result<()> {
        #[derive(Serialize)]
        struct Line<'a> {
            key: &'a str,
            record: &'a TrialRecord,
        }
        let mut bytes = serde_json::to_vec(&Line { key, record }).expect("serialisable");
        bytes.push(b'\n');
        let mut f = self.file.lock().unwrap_or_else(|p| p.into_inner());
        f.write_all(&bytes)
            .map_err(|e| Error::io(format!("appending to {}", self.path.display()), e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> ProgressHeader {
        ProgressHeader {
            format: FORMAT.into(),
            suite: "s".into(),
            suite_file: "s.toml".into(),
            fingerprint: "f".into(),
            build: "b".into(),
            seed: 1,
            trials: 2,
            budget: None,
            shard: None,
            planned: 3,
            started: "now".into(),
        }
    }

    fn record(trial: usize) -> TrialRecord {
        TrialRecord {
            objective: "o".into(),
            optimizer: "p".into(),
            trial,
            seed: "00".into(),
            budget: 10,
            evaluations: 10,
            best: f64::INFINITY,
            best_x: vec![0.5],
            optimum: Some(0.0),
            stopped_at_target: false,
            nonfinite: 10,
            penalised: 0,
            wall_s: 0.0,
            improvements: vec![],
            checkpoints: vec![(10, 1.5)],
        }
    }

    #[test]
    fn appended_lines_read_back_and_a_torn_tail_is_cut() {
        let dir = tempfile::tempdir().unwrap();
        let log = ProgressLog::create(dir.path(), &header(), &[]).unwrap();
        log.append("k0", &record(0)).unwrap();
        log.append("k1", &record(1)).unwrap();
        drop(log);
        // A kill mid-write: half of a third line.
        let path = dir.path().join(PROGRESS_FILE);
        let mut f = OpenOptions::new().append(true).open(&path).unwrap();
        f.write_all(b"{\"key\":\"k2\",\"rec").unwrap();
        drop(f);
        let p = read_progress(dir.path()).unwrap().unwrap();
        assert_eq!(p.header, header());
        assert!(p.torn);
        assert_eq!(p.lines.len(), 2);
        assert_eq!(p.lines[1].record, record(1));
        assert_eq!(p.lines[0].record.best, f64::INFINITY);
        // Resuming cuts the torn line, so the next append starts on a fresh line.
        let log = ProgressLog::resume(dir.path(), p.valid_len).unwrap();
        log.append("k2", &record(2)).unwrap();
        let p = read_progress(dir.path()).unwrap().unwrap();
        assert!(!p.torn);
        assert_eq!(
            p.lines.iter().map(|l| l.key.as_str()).collect::<Vec<_>>(),
            ["k0", "k1", "k2"]
        );
    }

    #[test]
    fn damage_before_the_last_line_is_an_error_with_its_line() {
        let dir = tempfile::tempdir().unwrap();
        let log = ProgressLog::create(dir.path(), &header(), &[]).unwrap();
        log.append("k0", &record(0)).unwrap();
        drop(log);
        let path = dir.path().join(PROGRESS_FILE);
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines: Vec<&str> = text.lines().collect();
        let good = lines[1].to_string();
        lines.insert(1, "garbage");
        std::fs::write(&path, lines.join("\n") + "\n").unwrap();
        let e = read_progress(dir.path()).unwrap_err().to_string();
        assert!(e.contains("progress.jsonl:2:"), "{e}");
        assert!(good.contains("k0"));
        // No log, or a header cut short, means nothing finished.
        assert!(read_progress(&dir.path().join("none")).unwrap().is_none());
        std::fs::write(&path, "{\"format\":").unwrap();
        assert!(read_progress(dir.path()).unwrap().is_none());
    }
}
