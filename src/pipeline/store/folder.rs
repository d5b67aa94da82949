//! Writing and reading a results folder.

use super::summary::{Summary, summarize};
use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use crate::pipeline::suite::Suite;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Where a run came from, so any number can be traced to the code and settings behind it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    pub tool: String,
    pub version: String,
    /// `git describe`-style commit of the build, with `-dirty` for uncommitted changes.
    pub git_commit: Option<String>,
    /// Whether the build had uncommitted changes (the commit alone does not name its code);
    /// null where the commit is unknown or the file predates the field.
    #[serde(default)]
    pub git_dirty: Option<bool>,
    /// `rustc --version` of the build (floating-point results may differ between compilers).
    #[serde(default)]
    pub rustc: Option<String>,
    /// The processor, from `/proc/cpuinfo` where there is one (for wall times).
    #[serde(default)]
    pub cpu_model: Option<String>,
    pub suite_name: String,
    pub suite_file: String,
    pub seed: u64,
    pub trials: usize,
    pub threads: usize,
    /// RFC 3339 UTC times.
    pub started: String,
    pub finished: String,
    pub wall_s: f64,
    /// The command line as given.
    pub command: Vec<String>,
    pub os: String,
    pub arch: String,
    /// What the caller adds about a run optbench did not drive itself: an external
    /// optimizer's language and package versions, a partial run ([`crate::pipeline::external`]).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub extra: std::collections::BTreeMap<String, String>,
    /// The provenance of each folder `optbench merge` combined from runs of different
    /// optimizers (empty for a single run or a merge of shards).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub parts: Vec<Provenance>,
}

impl Provenance {
    /// Provenance fields known from the build and the environment.
    pub fn new(suite: &Suite, threads: usize, started: std::time::SystemTime) -> Self {
        Self::of_run(
            &suite.name,
            &suite.path,
            suite.seed,
            suite.trials,
            threads,
            started,
        )
    }

    /// The same for any kind of suite (objective or control), from its name, file, seed and
    /// trials; finished now.
    pub fn of_run(
        suite_name: &str,
        suite_file: &std::path::Path,
        seed: u64,
        trials: usize,
        threads: usize,
        started: std::time::SystemTime,
    ) -> Self {
        let finished = std::time::SystemTime::now();
        let git_commit = option_env!("OPTBENCH_GIT_COMMIT")
            .filter(|s| !s.is_empty())
            .map(String::from);
        Provenance {
            tool: env!("CARGO_PKG_NAME").into(),
            version: env!("CARGO_PKG_VERSION").into(),
            git_dirty: git_commit.as_deref().map(|c| c.ends_with("-dirty")),
            git_commit,
            rustc: option_env!("OPTBENCH_RUSTC_VERSION")
                .filter(|s| !s.is_empty())
                .map(String::from),
            cpu_model: std::fs::read_to_string("/proc/cpuinfo")
                .ok()
                .and_then(|t| cpu_model(&t)),
            suite_name: suite_name.to_string(),
            suite_file: suite_file.display().to_string(),
            seed,
            trials,
            threads,
            started: humantime::format_rfc3339_seconds(started).to_string(),
            finished: humantime::format_rfc3339_seconds(finished).to_string(),
            wall_s: finished
                .duration_since(started)
                .unwrap_or_default()
                .as_secs_f64(),
            command: std::env::args().collect(),
            os: std::env::consts::OS.into(),
            arch: std::env::consts::ARCH.into(),
            extra: Default::default(),
            parts: Vec::new(),
        }
    }
}

/// The processor's name in a `/proc/cpuinfo` text: `model name` (x86), else the keys other
/// architectures use.
pub fn cpu_model(cpuinfo: &str) -> Option<String> {
    [
        "model name",
        "cpu model",
        "Model",
        "Hardware",
        "Processor",
        "cpu",
    ]
    .iter()
    .find_map(|key| {
        cpuinfo.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            (k.trim() == *key && !v.trim().is_empty()).then(|| v.trim().to_string())
        })
    })
}

fn json<T: Serialize>(v: &T) -> Vec<u8> {
    let mut s = serde_json::to_vec_pretty(v).expect("serialisable");
    s.push(b'\n');
    s
}

/// Writes a complete results folder and returns the summary.
pub fn write_run(
    dir: &Path,
    suite: &Suite,
    records: &[TrialRecord],
    provenance: &Provenance,
) -> Result<Summary> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::io(format!("creating {}", dir.display()), e))?;
    let summary = summarize(&suite.name, suite.seed, records);
    atomic_write(&dir.join("suite.toml"), suite.text.as_bytes())?;
    let mut lines = Vec::new();
    for r in records {
        serde_json::to_writer(&mut lines, r).expect("serialisable");
        lines.push(b'\n');
    }
    atomic_write(&dir.join("traces.jsonl"), &lines)?;
    atomic_write(&dir.join("summary.json"), &json(&summary))?;
    atomic_write(&dir.join("provenance.json"), &json(provenance))?;
    Ok(summary)
}

/// Reads `traces.jsonl` from a results folder.
pub fn read_traces(dir: &Path) -> Result<Vec<TrialRecord>> {
    let path = dir.join("traces.jsonl");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| Error::Input(format!("{}: cannot read: {e}", path.display())))?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l)
                .map_err(|e| Error::at(&path, i + 1, format!("not a trial record: {e}")))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_model_is_read_from_the_first_key_that_names_it() {
        let x86 = "processor\t: 0\nvendor_id\t: GenuineIntel\nmodel\t\t: 85\nmodel name\t: Intel(R) Xeon(R) Gold 6148 CPU @ 2.40GHz\n\nprocessor\t: 1\nmodel name\t: Intel(R) Xeon(R) Gold 6148 CPU @ 2.40GHz\n";
        assert_eq!(
            cpu_model(x86).as_deref(),
            Some("Intel(R) Xeon(R) Gold 6148 CPU @ 2.40GHz")
        );
        let arm = "processor\t: 0\nBogoMIPS\t: 108.00\nCPU part\t: 0xd0c\n\nModel\t\t: Raspberry Pi 4 Model B Rev 1.4\n";
        assert_eq!(
            cpu_model(arm).as_deref(),
            Some("Raspberry Pi 4 Model B Rev 1.4")
        );
        assert_eq!(cpu_model("processor\t: 0\nmodel name\t:\n"), None);
    }

    #[test]
    fn provenance_names_the_build_and_reads_files_from_before_the_new_fields() {
        let p = Provenance::of_run(
            "s",
            Path::new("s.toml"),
            1,
            2,
            3,
            std::time::SystemTime::now(),
        );
        assert!(
            p.rustc.as_deref().is_some_and(|r| r.starts_with("rustc ")),
            "{:?}",
            p.rustc
        );
        assert_eq!(
            p.git_dirty,
            p.git_commit.as_deref().map(|c| c.ends_with("-dirty"))
        );
        if std::path::Path::new("/proc/cpuinfo").exists() {
            assert!(p.cpu_model.is_some());
        }
        let mut v = serde_json::to_value(&p).unwrap();
        for k in ["git_dirty", "rustc", "cpu_model"] {
            v.as_object_mut().unwrap().remove(k);
        }
        let old: Provenance = serde_json::from_value(v).unwrap();
        assert_eq!(
            (old.git_dirty, old.rustc, old.cpu_model),
            (None, None, None)
        );
    }
}
