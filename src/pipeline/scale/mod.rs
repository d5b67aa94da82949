//! Running beyond one process: merging the shards of `run --shard K/N` (or of resumable
//! runs) into one results folder, and (feature `mpi`) the ranks of one MPI job. Resume and
//! sharding themselves live with the run ([`crate::pipeline::run`]).

#[cfg(feature = "mpi")]
pub mod mpi;

use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use crate::pipeline::run::{Overrides, Prepared, Report, fingerprint, finish, trial_key};
use crate::pipeline::store::Provenance;
use crate::pipeline::store::progress::{ProgressHeader, ProgressLine, ProgressLog, read_progress};
use crate::pipeline::suite::{PlannedTrial, Suite};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Combines the results folders of shards (or of any runs of the same suite and build)
/// into `out`, exactly as one run of the whole plan would have written it.
pub fn merge(dirs: &[PathBuf], out: &Path, quiet: bool, report: Option<Report>) -> Result<String> {
    let mut logs = Vec::new();
    for d in dirs {
        let p = read_progress(d)?.ok_or_else(|| {
            Error::Input(format!(
                "{}: no {} (not a results folder of `optbench run`, or a run from before resumable logs)",
                d.display(),
                crate::pipeline::store::progress::PROGRESS_FILE
            ))
        })?;
        for w in &p.skipped {
            eprintln!("warning: {w}");
        }
        if !p.header_intact {
            return Err(Error::Input(format!(
                "{}: the header of its {} fails its checksum (edited or damaged); `optbench run --force-resume` in that folder rewrites it, keeping the stored trials",
                d.display(),
                crate::pipeline::store::progress::PROGRESS_FILE
            )));
        }
        logs.push((d, p));
    }
    let Some((first_dir, first)) = logs.first() else {
        return Err(Error::Input(
            "merge: name at least one results folder".into(),
        ));
    };
    let h0 = first.header.clone();
    for (d, p) in &logs[1..] {
        let h = &p.header;
        if h.fingerprint != h0.fingerprint {
            return Err(Error::Input(format!(
                "{}: suite `{}` (seed {}, {} trials, budget {:?}) is not the run of {} (suite `{}`, seed {}, {} trials, budget {:?}); only shards of the same suite and overrides merge",
                d.display(),
                h.suite,
                h.seed,
                h.trials,
                h.budget,
                first_dir.display(),
                h0.suite,
                h0.seed,
                h0.trials,
                h0.budget
            )));
        }
        if h.build != h0.build {
            return Err(Error::Input(format!(
                "{}: built by `{}`, but {} by `{}`; shards must come from the same build",
                d.display(),
                h.build,
                first_dir.display(),
                h0.build
            )));
        }
    }
    let text_path = first_dir.join("suite.toml");
    let text = std::fs::read_to_string(&text_path)
        .map_err(|e| Error::Input(format!("{}: cannot read: {e}", text_path.display())))?;
    // Parse as the original file, so its relative paths resolve as they did in the run.
    let origin = PathBuf::from(&h0.suite_file);
    let origin = if origin.exists() { origin } else { text_path };
    let mut suite = Suite::parse(&text, &origin)?;
    Overrides {
        trials: Some(h0.trials),
        seed: Some(h0.seed),
        budget: h0.budget,
    }
    .apply(&mut suite)?;
    if fingerprint(&suite, h0.budget) != h0.fingerprint {
        return Err(Error::Input(format!(
            "{}: suite.toml does not match its progress log (edited after the run?)",
            first_dir.display()
        )));
    }
    let plan = suite.plan();
    let keys: Vec<String> = plan.iter().map(|t| trial_key(&suite, t)).collect();
    let mut found: HashMap<String, TrialRecord> = HashMap::new();
    let mut threads = 0;
    let mut earliest: Option<std::time::SystemTime> = None;
    let mut shards = Vec::new();
    for (d, p) in logs {
        // Threads of each shard, from its provenance (absent: counted as 0).
        threads += std::fs::read_to_string(d.join("provenance.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<Provenance>(&t).ok())
            .map_or(0, |p| p.threads);
        if let Ok(t) = humantime::parse_rfc3339(&p.header.started) {
            earliest = Some(earliest.map_or(t, |e| e.min(t)));
        }
        shards.push(match p.header.shard {
            Some((k, n)) => format!("{k}/{n}"),
            None => "all".into(),
        });
        for l in p.lines {
            found.entry(l.key).or_insert(l.record);
        }
    }
    let missing: Vec<&PlannedTrial> = plan
        .iter()
        .zip(&keys)
        .filter(|(_, k)| !found.contains_key(*k))
        .map(|(t, _)| t)
        .collect();
    if let Some(t) = missing.first() {
        return Err(Error::Input(format!(
            "merge: {} of {} planned trials are missing (shards given: {}), e.g. objective `{}`, optimizer `{}`, trial {}; run the missing shards (or `--resume` the unfinished ones) first",
            missing.len(),
            plan.len(),
            shards.join(", "),
            suite.objectives[t.objective].id,
            suite.optimizers[t.optimizer].id,
            t.trial
        )));
    }
    let records: Vec<TrialRecord> = keys
        .iter()
        .map(|k| found.remove(k).expect("checked"))
        .collect();
    let _lock = crate::pipeline::store::lock_and_claim(out, &suite.name, false)?;
    let header = ProgressHeader {
        shard: None,
        planned: plan.len(),
        started: earliest
            .map(|t| humantime::format_rfc3339_seconds(t).to_string())
            .unwrap_or(h0.started.clone()),
        ..h0
    };
    let lines: Vec<ProgressLine> = keys
        .iter()
        .zip(&records)
        .map(|(k, r)| ProgressLine {
            key: k.clone(),
            record: r.clone(),
        })
        .collect();
    ProgressLog::create(out, &header, &lines)?;
    let p = Prepared {
        suite,
        out: out.to_path_buf(),
        plan,
        keys,
        header,
        overwrite: false,
    };
    let started = earliest.unwrap_or_else(std::time::SystemTime::now);
    let provenance = Provenance::new(&p.suite, threads, started);
    let text = finish(&p, &records, provenance, 0, quiet, report)?;
    Ok(if quiet {
        text
    } else {
        format!(
            "merged {} shards ({})\n{text}",
            shards.len(),
            shards.join(", ")
        )
    })
}
