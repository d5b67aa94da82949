//! Running beyond one process: merging the shards of `run --shard K/N` (or of resumable
//! runs) into one results folder, and (feature `mpi`) the ranks of one MPI job. Resume and
//! sharding themselves live with the run ([`crate::pipeline::run`]).

#[cfg(feature = "mpi")]
pub mod mpi;

use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use crate::pipeline::run::{Overrides, Prepared, Report, fingerprint, finish, trial_key};
use crate::pipeline::store::Provenance;
use crate::pipeline::store::progress::{
    Progress, ProgressHeader, ProgressLine, ProgressLog, read_progress,
};
use crate::pipeline::suite::{PlannedTrial, Suite};
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// One run among the folders given to [`merge`]: the folders that share its suite text and
/// overrides (its shards), and its suite as run.
struct Run<'a> {
    dirs: Vec<&'a Path>,
    header: ProgressHeader,
    suite: Suite,
}

/// Combines results folders into `out`: the shards of one run (`run --shard K/N`, or any
/// runs of the same suite and build), exactly as one run of the whole plan would have
/// written it; and runs of different optimizers on the same objectives, seed, trials and
/// budgets (a built-in run and an external optimizer's,
/// [`crate::pipeline::external`]), into one folder whose suite has every optimizer.
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
        logs.push((d.as_path(), p));
    }
    if logs.is_empty() {
        return Err(Error::Input(
            "merge: name at least one results folder".into(),
        ));
    }
    let runs = group_runs(&logs)?;
    let combined = runs.len() > 1;
    let (suite, header) = if combined {
        combine(&runs)?
    } else {
        let r = runs.into_iter().next().expect("one run");
        (r.suite, r.header)
    };
    let plan = suite.plan();
    let keys: Vec<String> = plan.iter().map(|t| trial_key(&suite, t)).collect();
    let mut found: HashMap<String, TrialRecord> = HashMap::new();
    let mut threads = 0;
    let mut earliest: Option<std::time::SystemTime> = None;
    let mut shards = Vec::new();
    let mut parts = Vec::new();
    for (d, p) in logs {
        // Threads of each folder, from its provenance (absent: counted as 0).
        let provenance = std::fs::read_to_string(d.join("provenance.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<Provenance>(&t).ok());
        threads += provenance.as_ref().map_or(0, |p| p.threads);
        if combined && let Some(p) = provenance {
            parts.push(p);
        }
        if let Ok(t) = humantime::parse_rfc3339(&p.header.started) {
            earliest = Some(earliest.map_or(t, |e| e.min(t)));
        }
        shards.push(match p.header.shard {
            Some((k, n)) if combined => format!("{} {k}/{n}", d.display()),
            Some((k, n)) => format!("{k}/{n}"),
            None if combined => d.display().to_string(),
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
            "merge: {} of {} planned trials are missing ({} given: {}), e.g. objective `{}`, optimizer `{}`, trial {}; run the missing shards (or `--resume` the unfinished ones) first",
            missing.len(),
            plan.len(),
            if combined { "folders" } else { "shards" },
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
            .unwrap_or(header.started.clone()),
        ..header
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
    if combined {
        // The merged suite, before the results that name its optimizers.
        atomic_write(&out.join("suite.toml"), suite.text.as_bytes())?;
    }
    let p = Prepared {
        suite,
        out: out.to_path_buf(),
        plan,
        keys,
        header,
        overwrite: false,
    };
    let started = earliest.unwrap_or_else(std::time::SystemTime::now);
    let mut provenance = Provenance::new(&p.suite, threads, started);
    provenance.parts = parts;
    let text = finish(&p, &records, provenance, 0, quiet, report)?;
    Ok(if quiet {
        text
    } else if combined {
        let ids: Vec<&str> = p.suite.optimizers.iter().map(|o| o.id.as_str()).collect();
        format!(
            "merged {} folders ({}) of optimizers {}\n{text}",
            shards.len(),
            shards.join(", "),
            ids.join(", ")
        )
    } else {
        format!(
            "merged {} shards ({})\n{text}",
            shards.len(),
            shards.join(", ")
        )
    })
}

/// The folders' runs: folders with the same suite text and overrides are shards of one run
/// (from one build), in the order first named.
fn group_runs<'a>(logs: &[(&'a Path, Progress)]) -> Result<Vec<Run<'a>>> {
    let mut runs: Vec<Run<'a>> = Vec::new();
    for (d, p) in logs {
        let h = &p.header;
        if let Some(r) = runs
            .iter_mut()
            .find(|r| r.header.fingerprint == h.fingerprint)
        {
            if h.build != r.header.build {
                return Err(Error::Input(format!(
                    "{}: built by `{}`, but {} by `{}`; shards must come from the same build",
                    d.display(),
                    h.build,
                    r.dirs[0].display(),
                    r.header.build
                )));
            }
            r.dirs.push(d);
            continue;
        }
        let suite = run_suite(d, h)?;
        if let Some(r) = runs.iter().find(|r| {
            r.suite
                .optimizers
                .iter()
                .any(|o| suite.optimizers.iter().any(|s| s.id == o.id))
        }) {
            // The same optimizer in another run: shards that do not belong together.
            let h0 = &r.header;
            return Err(Error::Input(format!(
                "{}: suite `{}` (seed {}, {} trials, budget {:?}) is not the run of {} (suite `{}`, seed {}, {} trials, budget {:?}); only shards of the same suite and overrides merge (or runs of optimizers with different ids on the same objectives, seed, trials and budgets)",
                d.display(),
                h.suite,
                h.seed,
                h.trials,
                h.budget,
                r.dirs[0].display(),
                h0.suite,
                h0.seed,
                h0.trials,
                h0.budget
            )));
        }
        runs.push(Run {
            dirs: vec![d],
            header: h.clone(),
            suite,
        });
    }
    Ok(runs)
}

/// The suite a folder's log was run from: its `suite.toml` with the log's overrides, checked
/// against the log's fingerprint.
fn run_suite(dir: &Path, h: &ProgressHeader) -> Result<Suite> {
    let text_path = dir.join("suite.toml");
    let text = std::fs::read_to_string(&text_path)
        .map_err(|e| Error::Input(format!("{}: cannot read: {e}", text_path.display())))?;
    // Parse as the original file, so its relative paths resolve as they did in the run.
    let origin = PathBuf::from(&h.suite_file);
    let origin = if origin.exists() { origin } else { text_path };
    let mut suite = Suite::parse(&text, &origin)?;
    Overrides {
        trials: Some(h.trials),
        seed: Some(h.seed),
        budget: h.budget,
    }
    .apply(&mut suite)?;
    if fingerprint(&suite, h.budget) != h.fingerprint {
        return Err(Error::Input(format!(
            "{}: suite.toml does not match its progress log (edited after the run?)",
            dir.display()
        )));
    }
    Ok(suite)
}

/// Checks that runs of different optimizers ran the same trials of the same objectives
/// (seed, trials, and per objective its kind, parameters, budget, targets and stop value),
/// and returns the suite of all their optimizers with its progress header. The suite is
/// the first run's, every optimizer of the others added, the effective seed, trials and
/// budgets written into it (so it needs no overrides), and each objective run by the
/// optimizers that ran it in their own run; its trial keys are the runs' own.
fn combine(runs: &[Run<'_>]) -> Result<(Suite, ProgressHeader)> {
    let first = &runs[0];
    let s0 = &first.suite;
    let d0 = first.dirs[0].display();
    for r in &runs[1..] {
        let s = &r.suite;
        let d = r.dirs[0].display();
        let differs = |field: &str, a: &dyn fmt::Display, b: &dyn fmt::Display| {
            Error::Input(format!(
                "merge: {field} differs between the folders: {a} in {d0}, {b} in {d}; only runs of the same objectives, seed, trials and budgets merge (run them again with the same suite and `--seed`/`--trials`/`--budget`)"
            ))
        };
        if s.seed != s0.seed {
            return Err(differs("seed", &s0.seed, &s.seed));
        }
        if s.trials != s0.trials {
            return Err(differs("trials", &s0.trials, &s.trials));
        }
        let ids = |s: &Suite| {
            s.objectives
                .iter()
                .map(|o| o.id.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        if ids(s) != ids(s0) {
            return Err(differs(
                "the list of objectives",
                &format!("[{}]", ids(s0)),
                &format!("[{}]", ids(s)),
            ));
        }
        for (a, b) in s0.objectives.iter().zip(&s.objectives) {
            let id = &a.id;
            if a.kind != b.kind {
                return Err(differs(
                    &format!("objective `{id}`: kind"),
                    &a.kind,
                    &b.kind,
                ));
            }
            let (pa, pb) = (params_text(a), params_text(b));
            if pa != pb {
                return Err(differs(&format!("objective `{id}`: parameters"), &pa, &pb));
            }
            if a.budget != b.budget {
                return Err(differs(
                    &format!("objective `{id}`: budget"),
                    &a.budget,
                    &b.budget,
                ));
            }
            if a.targets != b.targets {
                return Err(differs(
                    &format!("objective `{id}`: targets"),
                    &format!("{:?}", a.targets),
                    &format!("{:?}", b.targets),
                ));
            }
            if a.stop_at.map(f64::to_bits) != b.stop_at.map(f64::to_bits) {
                return Err(differs(
                    &format!("objective `{id}`: stop_at"),
                    &format!("{:?}", a.stop_at),
                    &format!("{:?}", b.stop_at),
                ));
            }
        }
        if r.header.build != first.header.build {
            eprintln!(
                "note: {d} was built by `{}`, {d0} by `{}`; their objectives are compared by configuration, not by code",
                r.header.build, first.header.build
            );
        }
    }
    let text = combined_text(runs)?;
    let suite = Suite::parse(&text, Path::new(&first.header.suite_file)).map_err(|e| {
        Error::Input(format!(
            "merge: the suite combining {} is invalid ({e}); give the runs' optimizers and tables distinct ids",
            runs.iter()
                .map(|r| r.dirs[0].display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ))
    })?;
    let header = ProgressHeader {
        suite: suite.name.to_string(),
        fingerprint: fingerprint(&suite, None),
        seed: suite.seed,
        trials: suite.trials,
        budget: None,
        ..first.header.clone()
    };
    Ok((suite, header))
}

/// An objective's validated parameters, as its trial keys see them.
fn params_text(o: &crate::pipeline::suite::ObjectiveEntry) -> String {
    o.params
        .values()
        .iter()
        .map(|(k, v)| format!("{k} = {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The text of the combined suite ([`combine`]).
fn combined_text(runs: &[Run<'_>]) -> Result<String> {
    let table_of = |s: &Suite| -> Result<toml::Table> {
        s.text
            .parse()
            .map_err(|e| Error::Input(format!("{}: {e}", s.path.display())))
    };
    let s0 = &runs[0].suite;
    let mut table = table_of(s0)?;
    table.insert("seed".into(), toml::Value::Integer(s0.seed as i64));
    table.insert("trials".into(), toml::Value::Integer(s0.trials as i64));
    table.remove("targets");
    table.remove("stop_at");
    let mut optimizers = Vec::new();
    let mut tables = Vec::new();
    for r in runs {
        let t = table_of(&r.suite)?;
        if let Some(toml::Value::Array(o)) = t.get("optimizer") {
            optimizers.extend(o.iter().cloned());
        }
        if let Some(toml::Value::Array(o)) = t.get("table") {
            tables.extend(o.iter().cloned());
        }
    }
    let all = optimizers.len();
    if let Some(toml::Value::Array(objectives)) = table.get_mut("objective") {
        for (i, o) in objectives.iter_mut().enumerate() {
            let toml::Value::Table(t) = o else { continue };
            let entry = &s0.objectives[i];
            t.insert("budget".into(), toml::Value::Integer(entry.budget as i64));
            t.remove("targets");
            if !entry.targets.is_empty() {
                t.insert(
                    "targets".into(),
                    toml::Value::Array(entry.targets.iter().map(|&x| x.into()).collect()),
                );
            }
            t.remove("stop_at");
            if let Some(s) = entry.stop_at {
                t.insert("stop_at".into(), toml::Value::Float(s));
            }
            // The optimizers that ran this objective in their own runs.
            let ran: Vec<toml::Value> = runs
                .iter()
                .flat_map(|r| {
                    let s = &r.suite;
                    s.objectives[i]
                        .optimizers
                        .iter()
                        .map(|&k| toml::Value::String(s.optimizers[k].id.to_string()))
                })
                .collect();
            t.remove("optimizers");
            if ran.len() < all {
                t.insert("optimizers".into(), toml::Value::Array(ran));
            }
        }
    }
    table.insert("optimizer".into(), toml::Value::Array(optimizers));
    table.remove("table");
    if !tables.is_empty() {
        table.insert("table".into(), toml::Value::Array(tables));
    }
    let names: Vec<String> = runs
        .iter()
        .map(|r| format!("`{}` ({})", r.suite.name, r.dirs[0].display()))
        .collect();
    Ok(format!(
        "# runs of {} merged by optbench\n{}",
        names.join(", "),
        toml::to_string(&table).expect("a TOML table serialises")
    ))
}
