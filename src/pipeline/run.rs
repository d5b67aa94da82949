//! One run of a suite: load it with its overrides, open (or resume) its progress log, run
//! the trials still to do, write the results and hand the folder to the report.
//!
//! Every finished trial is appended to `progress.jsonl` in the results folder the moment it
//! ends (see [`crate::pipeline::store::progress`]), keyed by a hash of its full configuration
//! ([`trial_key`]). `--resume` reruns only the planned trials whose key is not in the log;
//! because every trial draws from its own seeded streams, the records, and so
//! `summary.json`, are the same as those of an uninterrupted run. A log written by another
//! suite text, other overrides, another build or another shard is refused unless
//! `--force-resume`, which keeps exactly the trials whose configuration is unchanged.
//!
//! `--shard K/N` runs plan positions `i` with `i mod N = K - 1` (round robin, so every
//! shard gets a similar mix of objectives and optimizers); `optbench merge` checks that the
//! shards come from the same suite and build, that every planned trial is there, and writes
//! one results folder in plan order, identical to a single run's.

use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use crate::base::hash::stable_hash;
use crate::harness::TrialRecord;
use crate::pipeline::runner::{RunOptions, run_trials};
use crate::pipeline::store::progress::{
    FORMAT, ProgressHeader, ProgressLine, ProgressLog, read_progress,
};
use crate::pipeline::store::{Provenance, write_run};
use crate::pipeline::suite::{PlannedTrial, Suite};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The build that runs: version and git commit.
pub fn build_id() -> String {
    format!(
        "{} {}",
        env!("CARGO_PKG_VERSION"),
        option_env!("OPTBENCH_GIT_COMMIT")
            .filter(|s| !s.is_empty())
            .unwrap_or("unknown-commit")
    )
}

/// Command-line overrides of a suite (`--trials`, `--seed`, `--budget`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Overrides {
    pub trials: Option<usize>,
    pub seed: Option<u64>,
    pub budget: Option<u64>,
}

impl Overrides {
    /// Applies the overrides to a loaded suite; refused if the plan outgrows its memory
    /// budget.
    pub fn apply(&self, suite: &mut Suite) -> Result<()> {
        if let Some(t) = self.trials {
            suite.trials = t;
            if let Some(m) = suite.plan_too_large() {
                return Err(Error::Input(format!("--trials {t}: {m}")));
            }
        }
        if let Some(s) = self.seed {
            suite.seed = s;
        }
        if let Some(b) = self.budget {
            for o in &mut suite.objectives {
                o.budget = b;
            }
        }
        Ok(())
    }
}

/// Hash of what decides a run's plan and results: the suite text and the effective seed,
/// trials and budget override.
pub fn fingerprint(suite: &Suite, budget: Option<u64>) -> String {
    let budget = budget.map(|b| b.to_string()).unwrap_or_default();
    stable_hash(&[
        b"optbench-suite-1",
        suite.text.as_bytes(),
        &suite.seed.to_le_bytes(),
        &(suite.trials as u64).to_le_bytes(),
        budget.as_bytes(),
    ])
}

/// Hash of everything one trial's result depends on: objective (id, kind, every validated
/// parameter, budget, stop value), optimizer (id, kind, full configuration including a
/// polish), its random key and index. Equal keys mean interchangeable records.
pub fn trial_key(suite: &Suite, t: &PlannedTrial) -> String {
    let obj = &suite.objectives[t.objective];
    let opt = &suite.optimizers[t.optimizer];
    let mut params: String = obj
        .params
        .values()
        .iter()
        .map(|(k, v)| format!("{k}={v};"))
        .collect();
    // `params` are the first instance's; the trial's own instance decides its result.
    if let Some(n) = obj.instance_of(t.trial) {
        params += &format!("trial instance={n};");
    }
    let stop = obj
        .stop_value(t.trial)
        .map(|s| s.to_bits().to_string())
        .unwrap_or_default();
    let config = format!("{:?}", opt.config);
    stable_hash(&[
        b"optbench-trial-1",
        obj.id.as_bytes(),
        obj.kind.as_bytes(),
        params.as_bytes(),
        &obj.budget.to_le_bytes(),
        stop.as_bytes(),
        opt.id.as_bytes(),
        opt.kind.as_bytes(),
        config.as_bytes(),
        suite.seed_of(t).hex().as_bytes(),
        &(t.trial as u64).to_le_bytes(),
    ])
}

/// `--shard K/N`: the K-th (1-based) of N round-robin shares of the plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub k: usize,
    pub n: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let err = || format!("`{s}`: expected K/N with 1 <= K <= N, e.g. 2/8");
        let (k, n) = s.split_once('/').ok_or_else(err)?;
        let k: usize = k.trim().parse().map_err(|_| err())?;
        let n: usize = n.trim().parse().map_err(|_| err())?;
        if k == 0 || n == 0 || k > n {
            return Err(err());
        }
        Ok(Shard { k, n })
    }
}

impl Shard {
    /// The positions of `plan_len` planned trials that belong to this shard.
    pub fn positions(&self, plan_len: usize) -> Vec<usize> {
        (0..plan_len).filter(|i| i % self.n == self.k - 1).collect()
    }
}

/// What `optbench run` was asked to do.
#[derive(Debug, Clone, Default)]
pub struct RunRequest {
    pub suite: PathBuf,
    pub out: Option<PathBuf>,
    pub overrides: Overrides,
    pub threads: Option<usize>,
    pub progress: bool,
    pub quiet: bool,
    pub resume: bool,
    pub force_resume: bool,
    /// Run even into a folder holding other results or other files: optbench's own files
    /// there are removed first, the others left alone (see [`crate::pipeline::store::claim`]).
    pub overwrite: bool,
    pub shard: Option<Shard>,
    /// Writes the report of a finished results folder and returns its main table (the
    /// command passes `report::generate`; the pipeline sits below the report).
    pub report: Option<Report>,
}

/// See [`RunRequest::report`].
pub type Report = fn(&Path) -> Result<String>;

/// The suite with its overrides, where its results go, and its (share of the) plan.
pub struct Prepared {
    pub suite: Suite,
    pub out: PathBuf,
    pub plan: Vec<PlannedTrial>,
    pub keys: Vec<String>,
    pub header: ProgressHeader,
    /// See [`RunRequest::overwrite`].
    pub overwrite: bool,
}

/// Loads and validates the suite, applies overrides and the shard; writes nothing.
pub fn prepare(req: &RunRequest) -> Result<Prepared> {
    let mut suite = Suite::load(&req.suite)?;
    crate::pipeline::external::refuse_external(&suite)?;
    req.overrides.apply(&mut suite)?;
    // The suite file is refused with fewer trials than instances; a smaller --trials is a
    // quick look, allowed, but said, since part of each list then never runs.
    if let Some(o) = suite
        .objectives
        .iter()
        .find(|o| o.instances.len() > suite.trials)
    {
        eprintln!(
            "note: --trials {} runs only the first {} of the {} instances objectives such as `{}` list (trial t runs instance t mod n)",
            suite.trials,
            suite.trials,
            o.instances.len(),
            o.id
        );
    }
    let out = req.out.clone().unwrap_or_else(|| {
        let name = match req.shard {
            Some(s) => format!("{}-shard-{}-of-{}", suite.name, s.k, s.n),
            None => suite.name.to_string(),
        };
        PathBuf::from("results").join(name)
    });
    Prepared::new(
        suite,
        &req.suite,
        out,
        req.overrides.budget,
        req.shard,
        req.overwrite,
    )
}

impl Prepared {
    /// The plan of `suite` (overrides applied; `budget` is the `--budget` override) for
    /// results in `out`, read from `suite_file`; writes nothing.
    pub fn new(
        suite: Suite,
        suite_file: &Path,
        out: PathBuf,
        budget: Option<u64>,
        shard: Option<Shard>,
        overwrite: bool,
    ) -> Result<Prepared> {
        if out.is_file() {
            return Err(Error::Input(format!(
                "--out {}: is a file, expected a folder",
                out.display()
            )));
        }
        let all = suite.plan();
        let plan: Vec<PlannedTrial> = match shard {
            Some(s) => s.positions(all.len()).into_iter().map(|i| all[i]).collect(),
            None => all,
        };
        let keys: Vec<String> = plan.iter().map(|t| trial_key(&suite, t)).collect();
        let header = ProgressHeader {
            format: FORMAT.into(),
            suite: suite.name.to_string(),
            suite_file: std::path::absolute(suite_file)
                .unwrap_or_else(|_| suite_file.to_path_buf())
                .display()
                .to_string(),
            fingerprint: fingerprint(&suite, budget),
            build: build_id(),
            seed: suite.seed,
            trials: suite.trials,
            budget,
            shard: shard.map(|s| (s.k, s.n)),
            planned: plan.len(),
            started: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        };
        Ok(Prepared {
            suite,
            out,
            plan,
            keys,
            header,
            overwrite,
        })
    }
}

/// How a stored log differs from the run asked for (empty: it is the same run).
fn differences(old: &ProgressHeader, new: &ProgressHeader) -> Vec<String> {
    let mut d = Vec::new();
    if old.fingerprint != new.fingerprint {
        if (old.seed, old.trials, old.budget) != (new.seed, new.trials, new.budget) {
            d.push(format!(
                "seed/trials/budget were {}/{}/{:?}, now {}/{}/{:?}",
                old.seed, old.trials, old.budget, new.seed, new.trials, new.budget
            ));
        } else {
            d.push("the suite file has changed".into());
        }
    }
    if old.build != new.build {
        d.push(format!("built by `{}`, this is `{}`", old.build, new.build));
    }
    if old.shard != new.shard {
        let s = |s: Option<(usize, usize)>| match s {
            Some((k, n)) => format!("shard {k}/{n}"),
            None => "the whole plan".into(),
        };
        d.push(format!("ran {}, now {}", s(old.shard), s(new.shard)));
    }
    d
}

/// Locks the results folder, checks that it is this suite's to write (or clears it for
/// `--overwrite`), and opens the progress log for `p` (fresh, resumed or rewritten);
/// returns it, holding the lock, with the records already finished, by key. Damaged log
/// lines are reported on stderr and their trials left to run again.
pub fn open_log(
    p: &Prepared,
    resume: bool,
    force: bool,
) -> Result<(ProgressLog, HashMap<String, TrialRecord>)> {
    let lock = crate::pipeline::store::lock_and_claim(&p.out, &p.suite.name, p.overwrite)?;
    let existing = read_progress(&p.out)?;
    if let Some(old) = &existing {
        for w in &old.skipped {
            eprintln!("warning: {w}");
        }
    }
    let mut done = HashMap::new();
    let wanted: std::collections::HashSet<&str> = p.keys.iter().map(String::as_str).collect();
    let log = match existing {
        Some(old) if resume || force => {
            let mut diff = differences(&old.header, &p.header);
            if !old.header_intact {
                diff.push("its header fails its checksum (edited or damaged)".into());
            }
            if !diff.is_empty() && !force {
                return Err(Error::Input(format!(
                    "{}: cannot resume: {}; pass --force-resume to keep the {} stored trials whose configuration is unchanged and rerun the rest",
                    p.out.display(),
                    diff.join("; "),
                    old.lines.len()
                )));
            }
            for l in old.lines {
                if wanted.contains(l.key.as_str()) {
                    done.entry(l.key).or_insert(l.record);
                }
            }
            if diff.is_empty() && old.skipped.is_empty() {
                ProgressLog::resume(&p.out, old.valid_len)?
            } else {
                // A new header (or the same, without the damaged lines), and only the
                // trials this run can use, in plan order.
                let kept: Vec<ProgressLine> = p
                    .keys
                    .iter()
                    .filter_map(|k| {
                        done.get(k).map(|r| ProgressLine {
                            key: k.clone(),
                            record: r.clone(),
                        })
                    })
                    .collect();
                ProgressLog::create(&p.out, &p.header, &kept)?
            }
        }
        Some(old) if unique(&old.lines) < old.header.planned => {
            return Err(Error::Input(format!(
                "{}: holds an interrupted run ({} of {} trials finished); pass --resume to continue it, or delete {} to start over",
                p.out.display(),
                unique(&old.lines),
                old.header.planned,
                p.out
                    .join(crate::pipeline::store::progress::PROGRESS_FILE)
                    .display()
            )));
        }
        _ => ProgressLog::create(&p.out, &p.header, &[])?,
    };
    Ok((log.holding(lock), done))
}

fn unique(lines: &[ProgressLine]) -> usize {
    lines
        .iter()
        .map(|l| l.key.as_str())
        .collect::<std::collections::HashSet<_>>()
        .len()
}

/// Runs (or resumes) a suite, or one shard of it, in this process on its thread pool; returns
/// the text to print (`cmd::run` hands MPI-launched runs to [`crate::pipeline::scale::mpi`]).
pub fn run(req: &RunRequest) -> Result<String> {
    let started = std::time::SystemTime::now();
    let p = prepare(req)?;
    let (log, mut done) = open_log(&p, req.resume, req.force_resume)?;
    let todo: Vec<usize> = (0..p.plan.len())
        .filter(|&i| !done.contains_key(&p.keys[i]))
        .collect();
    let todo_plan: Vec<PlannedTrial> = todo.iter().map(|&i| p.plan[i]).collect();
    let failure: Mutex<Option<Error>> = Mutex::new(None);
    let opts = RunOptions {
        threads: req.threads,
        progress: req.progress,
    };
    let (fresh, threads) = run_trials(&p.suite, &todo_plan, &opts, &|j, r| {
        if let Err(e) = log.append(&p.keys[todo[j]], r) {
            failure
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .get_or_insert(e);
        }
    })?;
    if let Some(e) = failure.into_inner().unwrap_or_else(|e| e.into_inner()) {
        return Err(e);
    }
    let reused = p.plan.len() - todo.len();
    let mut fresh = fresh.into_iter();
    let records: Vec<TrialRecord> = p
        .keys
        .iter()
        .map(|k| {
            done.remove(k)
                .unwrap_or_else(|| fresh.next().expect("one fresh record per trial run"))
        })
        .collect();
    let provenance = Provenance::new(&p.suite, threads, started);
    finish(&p, &records, provenance, reused, req.quiet, req.report)
}

/// Writes the results of a finished run (or shard) with its `provenance` and returns the
/// text to print.
pub fn finish(
    p: &Prepared,
    records: &[TrialRecord],
    provenance: Provenance,
    reused: usize,
    quiet: bool,
    report: Option<Report>,
) -> Result<String> {
    let threads = provenance.threads;
    let resumed = if reused > 0 {
        format!(", {reused} trials resumed from {}", p.out.display())
    } else {
        String::new()
    };
    if let Some((k, n)) = p.header.shard {
        atomic_write(&p.out.join("suite.toml"), p.suite.text.as_bytes())?;
        let mut json = serde_json::to_vec_pretty(&provenance).expect("serialisable");
        json.push(b'\n');
        atomic_write(&p.out.join("provenance.json"), &json)?;
        return Ok(if quiet {
            String::new()
        } else {
            format!(
                "suite {} shard {k}/{n}: {} of {} trials ({} threads, {:.1} s{resumed}) in {}\ncombine the shards with `optbench merge DIR... --out DIR`\n",
                p.suite.name,
                records.len(),
                p.suite.plan().len(),
                threads,
                provenance.wall_s,
                p.out.display()
            )
        });
    }
    write_run(&p.out, &p.suite, records, &provenance)?;
    let table = match report {
        Some(generate) => generate(&p.out)?,
        None => String::new(),
    };
    Ok(if quiet {
        String::new()
    } else {
        format!(
            "suite {} (seed {}, {} trials, {} threads, {:.1} s{resumed})\n\n{table}\nresults and report: {}\n",
            p.suite.name,
            p.suite.seed,
            p.suite.trials,
            threads,
            provenance.wall_s,
            p.out.display()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_plan() {
        for n in 1..=7 {
            let mut all: Vec<usize> = (1..=n).flat_map(|k| Shard { k, n }.positions(20)).collect();
            all.sort();
            assert_eq!(all, (0..20).collect::<Vec<_>>(), "n = {n}");
        }
        assert_eq!("2/8".parse::<Shard>(), Ok(Shard { k: 2, n: 8 }));
        for bad in ["0/3", "4/3", "3", "a/b", "1/0"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
