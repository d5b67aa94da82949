//! `progress.jsonl`: the append-only log of finished trials that makes a run resumable.
//!
//! The first line is a [`ProgressHeader`] naming the run (suite fingerprint, build, the
//! overrides of the command line, the shard); every further line is one finished trial,
//! `{"crc": ..., "key": ..., "record": ...}`, written with a single `write` the moment the
//! trial ends. `crc` is the CRC-32 (hex) of the line's bytes after the `"crc":"...",`
//! prefix, so the line stays plain JSON and is checked byte for byte.
//!
//! What the reader ([`read_progress`]) does with damage, anywhere in the file: a torn last
//! line (a kill mid-write) is dropped and cut off before the next append; a line that fails
//! its checksum or does not parse (a disk that filled up mid-write, an edited value) is
//! skipped with a warning naming file and line, and its trial runs again; a line that a
//! failed write left without its newline is separated from the complete line appended
//! after it, which is kept. Logs written before the checksum (no `crc`) are read as they
//! are. A finished trial is never lost to damage elsewhere in the log.
//!
//! Lines are not fsynced one by one: the log survives a killed process (SIGKILL included)
//! and a full disk, but a power cut may lose the trials of the last seconds, which then run
//! again; the result files are fsynced before their rename ([`crate::base::atomic_write`]).

use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use serde::{Deserialize, Serialize};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// How every checksummed line starts: `{"crc":"` then 8 hex digits and `",`.
const CRC_PREFIX: &[u8] = b"{\"crc\":\"";

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
    /// Whether the header passed its checksum (or has none: an older log).
    pub header_intact: bool,
    /// One warning per damaged line skipped before the last (`file:line: why`); their
    /// trials run again.
    pub skipped: Vec<String>,
}

/// `json` (an object) as one checksummed line: `{"crc":"XXXXXXXX",` + the rest + newline.
fn checksummed(json: &[u8]) -> Vec<u8> {
    let rest = &json[1..];
    let mut line = Vec::with_capacity(json.len() + 20);
    line.extend_from_slice(CRC_PREFIX);
    line.extend_from_slice(format!("{:08x}\",", crc32fast::hash(rest)).as_bytes());
    line.extend_from_slice(rest);
    line.push(b'\n');
    line
}

/// Whether a line (without newline) carries a checksum, and if so whether it holds.
#[derive(Debug, PartialEq)]
enum Check {
    Holds,
    Fails,
    Absent,
}

fn check(line: &[u8]) -> Check {
    let Some(tail) = line.strip_prefix(CRC_PREFIX) else {
        return Check::Absent;
    };
    let stored = tail
        .get(..8)
        .and_then(|h| std::str::from_utf8(h).ok())
        .and_then(|h| u32::from_str_radix(h, 16).ok());
    match (stored, tail.get(8..10), tail.get(10..)) {
        (Some(crc), Some(b"\","), Some(rest)) if crc32fast::hash(rest) == crc => Check::Holds,
        _ => Check::Fails,
    }
}

/// A trial line read back, or why not.
fn trial_line(line: &[u8]) -> std::result::Result<ProgressLine, String> {
    match check(line) {
        Check::Fails => Err("fails its checksum (edited or damaged)".into()),
        Check::Holds | Check::Absent => {
            serde_json::from_slice(line).map_err(|e| format!("not a trial line: {e}"))
        }
    }
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
    let mut header_intact = true;
    let mut lines = Vec::new();
    let mut skipped = Vec::new();
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
            header_intact = check(line) != Check::Fails;
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
        } else if !line.iter().all(u8::is_ascii_whitespace) {
            match trial_line(line) {
                Ok(l) => lines.push(l),
                Err(why) => {
                    // A write cut short and followed by a complete line: keep that line.
                    let salvaged = (1..line.len())
                        .rev()
                        .filter(|&i| line[i..].starts_with(CRC_PREFIX))
                        .find_map(|i| {
                            (check(&line[i..]) == Check::Holds)
                                .then(|| trial_line(&line[i..]).ok())
                                .flatten()
                        });
                    let kept = if salvaged.is_some() {
                        "; the complete trial line after it is kept"
                    } else {
                        ""
                    };
                    skipped.push(format!(
                        "{}:{number}: {why}: line skipped, its trial runs again{kept}",
                        path.display()
                    ));
                    lines.extend(salvaged);
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
        header_intact,
        skipped,
    }))
}

/// An open log that trials are appended to, from any thread.
pub struct ProgressLog {
    path: PathBuf,
    file: Mutex<Appender>,
    /// The folder's lock, held as long as the log is open for this run.
    lock: Option<super::lock::FolderLock>,
}

struct Appender {
    file: File,
    /// A write failed (or was cut short) and may have left part of a line: the next line
    /// starts with a newline, so that part stays a line of its own.
    torn: bool,
}

impl ProgressLog {
    /// Starts a new log in `dir` with `header` and the already finished `lines` (written to
    /// a temporary file and renamed, so an old log is replaced whole or not at all).
    pub fn create(dir: &Path, header: &ProgressHeader, lines: &[ProgressLine]) -> Result<Self> {
        let path = dir.join(PROGRESS_FILE);
        let mut bytes = checksummed(&serde_json::to_vec(header).expect("serialisable"));
        for l in lines {
            bytes.extend(checksummed(&serde_json::to_vec(l).expect("serialisable")));
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
            file: Mutex::new(Appender { file, torn: false }),
            lock: None,
        })
    }

    /// This log, keeping the folder locked until it is dropped.
    pub fn holding(mut self, lock: super::lock::FolderLock) -> Self {
        self.lock = Some(lock);
        self
    }

    /// Appends one finished trial as one checksummed line, in one `write`.
    pub fn append(&self, key: &str, record: &TrialRecord) -> Result<()> {
        #[derive(Serialize)]
        struct Line<'a> {
            key: &'a str,
            record: &'a TrialRecord,
        }
        let line = checksummed(&serde_json::to_vec(&Line { key, record }).expect("serialisable"));
        let mut a = self.file.lock().unwrap_or_else(|p| p.into_inner());
        let bytes = if a.torn {
            [&b"\n"[..], &line].concat()
        } else {
            line
        };
        let written = a.file.write(&bytes);
        a.torn = !matches!(written, Ok(n) if n == bytes.len());
        match written {
            Ok(n) if n == bytes.len() => Ok(()),
            Ok(n) => Err(Error::io(
                format!("appending to {}", self.path.display()),
                std::io::Error::new(
                    std::io::ErrorKind::WriteZero,
                    format!("{n} of {} bytes written (disk full?)", bytes.len()),
                ),
            )),
            Err(e) => Err(Error::io(
                format!("appending to {}", self.path.display()),
                e,
            )),
        }
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
    fn damage_anywhere_skips_that_line_only_with_a_warning_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let log = ProgressLog::create(dir.path(), &header(), &[]).unwrap();
        for k in 0..4 {
            log.append(&format!("k{k}"), &record(k)).unwrap();
        }
        drop(log);
        let path = dir.path().join(PROGRESS_FILE);
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        // Line 2 (k0): garbage; line 3 (k1): a value edited, still valid JSON; line 4
        // (k2): cut short without its newline by a full disk, so k3 follows on its line.
        lines[1] = "garbage".into();
        lines[2] = lines[2].replace("\"budget\":10", "\"budget\":11");
        let half = lines[3].len() / 2;
        let k3 = lines.remove(4);
        lines[3] = format!("{}{k3}", &lines[3][..half]);
        std::fs::write(&path, lines.join("\n") + "\n").unwrap();
        let p = read_progress(dir.path()).unwrap().unwrap();
        assert!(p.header_intact && !p.torn);
        assert_eq!(
            p.lines.iter().map(|l| l.key.as_str()).collect::<Vec<_>>(),
            ["k3"]
        );
        assert_eq!(p.skipped.len(), 3, "{:?}", p.skipped);
        assert!(p.skipped[0].contains("progress.jsonl:2: not a trial line"));
        assert!(p.skipped[1].contains("progress.jsonl:3: fails its checksum"));
        assert!(p.skipped[2].contains("progress.jsonl:4:"));
        assert!(p.skipped[2].contains("after it is kept"));
        // An edited header is noticed, not trusted.
        lines[0] = lines[0].replace("\"seed\":1", "\"seed\":2");
        std::fs::write(&path, lines.join("\n") + "\n").unwrap();
        assert!(!read_progress(dir.path()).unwrap().unwrap().header_intact);
        // No log, or a header cut short, means nothing finished.
        assert!(read_progress(&dir.path().join("none")).unwrap().is_none());
        std::fs::write(&path, "{\"format\":").unwrap();
        assert!(read_progress(dir.path()).unwrap().is_none());
    }

    #[test]
    fn logs_from_before_the_checksum_still_read() {
        let dir = tempfile::tempdir().unwrap();
        let mut text = serde_json::to_string(&header()).unwrap() + "\n";
        text += r#"{"key":"k0","record":{"objective":"o","optimizer":"p","trial":0,"seed":"00","budget":10,"evaluations":10,"best":null,"best_x":[0.5],"optimum":0.0,"stopped_at_target":false,"nonfinite":10,"wall_s":0.0,"improvements":[],"checkpoints":[[10,null]]}}"#;
        std::fs::write(dir.path().join(PROGRESS_FILE), text + "\n").unwrap();
        let p = read_progress(dir.path()).unwrap().unwrap();
        assert!(p.header_intact && p.skipped.is_empty());
        assert_eq!(p.lines[0].record.best, f64::INFINITY);
        assert_eq!(p.lines[0].record.checkpoints, [(10, f64::INFINITY)]);
    }

    #[test]
    fn a_failed_write_leaves_the_next_line_on_a_line_of_its_own() {
        let dir = tempfile::tempdir().unwrap();
        let log = ProgressLog::create(dir.path(), &header(), &[]).unwrap();
        log.append("k0", &record(0)).unwrap();
        // What a full disk leaves: part of a line, and a writer that knows it failed.
        let path = dir.path().join(PROGRESS_FILE);
        let mut f = OpenOptions::new().append(true).open(&path).unwrap();
        f.write_all(b"{\"crc\":\"0000").unwrap();
        log.file.lock().unwrap().torn = true;
        log.append("k2", &record(2)).unwrap();
        let p = read_progress(dir.path()).unwrap().unwrap();
        assert_eq!(
            p.lines.iter().map(|l| l.key.as_str()).collect::<Vec<_>>(),
            ["k0", "k2"]
        );
        assert_eq!(p.skipped.len(), 1, "{:?}", p.skipped);
    }
}
