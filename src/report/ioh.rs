//! Export of traces in the format IOHexperimenter's `Analyzer` logger writes (v0.3), so the
//! IOH project's tools (IOHanalyzer, `iohinspector`) load optbench results as their own.
//!
//! ```text
//! ioh/instances.csv                                         which objective is which instance
//! ioh/<optimizer>/IOHprofiler_f<fid>_<kind>.json            meta data: one per objective kind
//! ioh/<optimizer>/data_f<fid>_<kind>/IOHprofiler_f<fid>_DIM<d>.dat   the runs of one dimension
//! ```
//!
//! - **Function id** `fid`: fixed per objective kind ([`FUNCTION_IDS`]), the same in every
//!   suite, so 2-D and 30-D Griewank are one function in two dimensions (`DIM`). The meta
//!   file's `suite` is `optbench`, the name of this numbering. A member of COCO's `bbob`
//!   suite (`Objective::suite_id`) keeps BBOB's numbers instead, as IOH numbers them:
//!   function 1-24 and COCO's instance, in meta files of suite `BBOB`, one per function
//!   (`IOHprofiler_f<fid>_bbob.json`). Two objectives of the same BBOB problem share their
//!   instance: they are runs on one problem.
//! - **Instance**: a test function is the untransformed function on a box; instance 1 is
//!   its customary domain, any other box a number derived from the box. A fitting objective
//!   (`bouc-wen`, `rbf`) is a model fitted to recordings; its instance is derived from every
//!   parameter (recordings, samples, model settings). Derived numbers are a stable hash
//!   in 2..=65535, so the same configuration has the same instance in every suite. Within
//!   a suite every objective has an instance of its own: a second objective with the same
//!   configuration (the same fit at another budget) or a hash clash takes the next free
//!   number. `instances.csv` names the objective behind each instance.
//! - **Values** (`raw_y`, and `best.y` in the meta file): f − f* where the optimum is known
//!   (clipped at 0 as in the report), else the objective's value (a fit's cost).
//! - **Runs**: one per trial, in suite order then trial order, the meta file's `runs` in the
//!   same order as the `.dat` blocks (that is how the loaders pair them). Each block is a
//!   header line `evaluations raw_y`, then one line per improvement of the best-so-far,
//!   and the last evaluation with the final best. Every block has a line at evaluation 1
//!   (the loaders start a run there): where the first value came later (a gradient charged
//!   with its value), that line says `inf`, nothing known yet. The trial number is a run
//!   attribute (`trial`).
//!
//! IOHexperimenter's own last line holds the last evaluation's value; optbench keeps only
//! the best-so-far, so its last line holds that, which every loader takes the running
//! minimum of anyway.

use crate::base::error::{Error, Result};
use crate::base::hash::stable_hash;
use crate::base::{SafeName, atomic_write, create_dir_within};
use crate::harness::TrialRecord;
use crate::objective::functions::TestFunction;
use crate::pipeline::suite::Suite;
use serde_json::json;
use std::collections::BTreeSet;
use std::fmt::Write;
use std::path::Path;

/// The IOH format version the export follows (IOHexperimenter's meta file `version`).
pub const IOH_FORMAT: &str = "0.3.22";

/// Function id of every objective kind, fixed forever: results of different suites and
/// versions are compared by it. New kinds get new numbers; numbers are never reused. Ids 1 to
/// 24 are left to COCO's BBOB functions (IOH numbers them so), so BBOB runs exported beside
/// these never share an id with an untransformed test function.
pub const FUNCTION_IDS: &[(&str, u16)] = &[
    ("sphere", 25),
    ("griewank", 26),
    ("schwefel", 27),
    ("rastrigin", 28),
    ("rosenbrock", 29),
    ("ackley", 30),
    ("bouc-wen", 101),
    ("rbf", 102),
    ("pi", 103),
    // Reserved for the Preisach fit of issue 19.
    ("preisach", 104),
];

/// The function id of objective kind `kind`.
pub fn function_id(kind: &str) -> Result<u16> {
    FUNCTION_IDS
        .iter()
        .find(|(k, _)| *k == kind)
        .map(|(_, id)| *id)
        .ok_or_else(|| {
            Error::Input(format!(
                "objective kind `{kind}` has no IOH function id (add it to report::ioh::FUNCTION_IDS)"
            ))
        })
}

/// One objective of the export.
#[derive(Debug, Clone, PartialEq)]
pub struct IohObjective<'a> {
    pub id: &'a SafeName,
    pub kind: &'a str,
    pub fid: u16,
    pub dim: usize,
    pub instance: u16,
    /// Subtracted from every value where known (each run's own: see [`Self::optimum_of`]).
    pub optimum: Option<f64>,
    /// A BBOB objective over an `instances` list: trial t ran `instances[t mod n]`; empty:
    /// every trial ran `instance`.
    pub instances: Vec<u16>,
}

impl IohObjective<'_> {
    /// The optimum subtracted from `r`'s values: its own where the objective's is known
    /// (each instance has its own f_opt).
    pub fn optimum_of(&self, r: &TrialRecord) -> Option<f64> {
        self.optimum.map(|f| r.optimum.unwrap_or(f))
    }

    /// The instance trial `trial` ran.
    pub fn instance_of(&self, trial: usize) -> u16 {
        match self.instances.len() {
            0 => self.instance,
            n => self.instances[trial % n],
        }
    }
}

/// What identifies an objective's instance: None for a test function as its formula
/// defines it on its customary domain (instance 1), else the text its number is derived
/// from: the box and, for a shifted or rotated function, its `shift`, `rotate` and
/// `instance`, so a moved function never shares a number with the plain one.
fn instance_key(kind: &str, params: &[(String, String)], bounds: (f64, f64)) -> Option<String> {
    match TestFunction::ALL.iter().find(|f| f.name() == kind) {
        Some(f) => {
            let get = |k: &str| params.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
            let moved =
                get("shift").is_some_and(|v| v != "\"none\"") || get("rotate") == Some("true");
            let mut key = (f.default_domain() != bounds)
                .then(|| format!("{kind};box={:e},{:e}", bounds.0, bounds.1));
            if moved {
                let k = key.get_or_insert_with(|| kind.to_string());
                for p in ["shift", "rotate", "instance"] {
                    k.push_str(&format!(";{p}={}", get(p).unwrap_or("")));
                }
            }
            key
        }
        None => Some(
            std::iter::once(kind.to_string())
                .chain(params.iter().map(|(k, v)| format!("{k}={v}")))
                .collect::<Vec<_>>()
                .join(";"),
        ),
    }
}

/// The instance number of `key`: 1 for None, else a stable hash in 2..=65535.
fn instance_of(key: Option<&str>) -> u16 {
    match key {
        None => 1,
        Some(k) => {
            let h = u64::from_str_radix(&stable_hash(&[k.as_bytes()])[..16], 16)
                .expect("hex from stable_hash");
            2 + (h % 65534) as u16
        }
    }
}

/// The suite's objectives with their function ids and instances, in suite order.
pub fn objectives(suite: &Suite) -> Result<Vec<IohObjective<'_>>> {
    let mut out: Vec<IohObjective<'_>> = Vec::new();
    // Every objective gets an instance of its own, so `instances.csv` maps one to one.
    let mut taken: BTreeSet<(u16, usize, u16)> = BTreeSet::new();
    for o in &suite.objectives {
        let dim = o.objective.dim();
        if let Some(s) = o.objective.suite_id().filter(|s| s.suite == "bbob") {
            // BBOB's own numbers (the kind refuses instances beyond 16 bits).
            out.push(IohObjective {
                id: &o.id,
                kind: o.kind,
                fid: s.function as u16,
                dim,
                instance: u16::try_from(s.instance).unwrap_or(u16::MAX),
                optimum: o.objective.optimum(),
                instances: o
                    .instances
                    .iter()
                    .map(|(i, _)| u16::try_from(*i).unwrap_or(u16::MAX))
                    .collect(),
            });
            continue;
        }
        let fid = function_id(o.kind)?;
        let b = o.objective.bounds();
        let params: Vec<(String, String)> = o
            .params
            .values()
            .iter()
            .filter(|(k, _)| **k != "dim")
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        let key = instance_key(o.kind, &params, (b.lower()[0], b.upper()[0]));
        let mut instance = instance_of(key.as_deref());
        while !taken.insert((fid, dim, instance)) {
            instance = if instance == u16::MAX {
                2
            } else {
                instance + 1
            };
        }
        out.push(IohObjective {
            id: &o.id,
            kind: o.kind,
            fid,
            dim,
            instance,
            optimum: o.objective.optimum(),
            instances: Vec::new(),
        });
    }
    Ok(out)
}

/// A value as exported: f − f* (at least 0) where the optimum is known.
fn exported(value: f64, optimum: Option<f64>) -> f64 {
    crate::report::analysis::error_of(value, optimum)
}

/// A finite number for JSON, None (null) otherwise.
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// One run's `.dat` block.
fn dat_block(out: &mut String, r: &TrialRecord, optimum: Option<f64>) {
    out.push_str("evaluations raw_y\n");
    if r.improvements.first().map(|i| i.0) != Some(1) {
        out.push_str("1 inf\n");
    }
    for &(e, v) in &r.improvements {
        writeln!(out, "{e} {:e}", exported(v, optimum)).expect("write to string");
    }
    let last = r.improvements.last().map(|l| l.0).unwrap_or(1);
    if r.evaluations > last {
        writeln!(out, "{} {:e}", r.evaluations, exported(r.best, optimum))
            .expect("write to string");
    }
}

/// One run's entry in the meta file.
fn run_json(r: &TrialRecord, o: &IohObjective<'_>) -> serde_json::Value {
    json!({
        "instance": o.instance_of(r.trial),
        "evals": r.evaluations,
        "best": {
            "evals": r.improvements.last().map(|l| l.0).unwrap_or(0),
            "y": finite(exported(r.best, o.optimum_of(r))),
            "x": r.best_x,
        },
        "trial": r.trial,
    })
}

/// Writes the export of `records` under `dir` (typically `results/<suite>/ioh`).
/// `optimizers` are the suite's optimizers (id, kind): only their ids become folders,
/// whatever a record says.
pub fn export(
    dir: &Path,
    suite: &str,
    objectives: &[IohObjective<'_>],
    optimizers: &[(&SafeName, &str)],
    records: &[TrialRecord],
) -> Result<()> {
    let mut csv = String::from("function_id,function_name,dimension,instance,objective,values\n");
    for o in objectives {
        writeln!(
            csv,
            "{},{},{},{},{},{}",
            o.fid,
            o.kind,
            o.dim,
            o.instance,
            o.id,
            match o.optimum {
                Some(f) => format!("f - f* (f* = {f:e})"),
                None => "f (optimum unknown)".into(),
            }
        )
        .expect("write to string");
    }
    create_dir_within(dir, dir)?;
    atomic_write(&dir.join("instances.csv"), csv.as_bytes())?;

    // (Kind, function id) in order of first appearance (one id per kind except BBOB's),
    // dimensions in order of first appearance.
    let mut kinds: Vec<(&str, u16)> = Vec::new();
    for o in objectives {
        if !kinds.contains(&(o.kind, o.fid)) {
            kinds.push((o.kind, o.fid));
        }
    }
    for &(opt, opt_kind) in optimizers {
        for &(kind, fid) in &kinds {
            let base = dir.join(opt);
            let data_dir = format!("data_f{fid}_{kind}");
            let mut scenarios = Vec::new();
            let mut dims: Vec<usize> = Vec::new();
            for o in objectives.iter().filter(|o| o.kind == kind && o.fid == fid) {
                if !dims.contains(&o.dim) {
                    dims.push(o.dim);
                }
            }
            for dim in dims {
                let mut dat = String::new();
                let mut runs = Vec::new();
                for o in objectives
                    .iter()
                    .filter(|o| o.kind == kind && o.fid == fid && o.dim == dim)
                {
                    let mut of_obj: Vec<&TrialRecord> = records
                        .iter()
                        .filter(|r| *opt == r.optimizer && *o.id == r.objective)
                        .collect();
                    of_obj.sort_by_key(|r| r.trial);
                    for r in of_obj {
                        dat_block(&mut dat, r, o.optimum_of(r));
                        runs.push(run_json(r, o));
                    }
                }
                if runs.is_empty() {
                    continue;
                }
                let dat_name = format!("IOHprofiler_f{fid}_DIM{dim}.dat");
                create_dir_within(dir, &base.join(&data_dir))?;
                atomic_write(&base.join(&data_dir).join(&dat_name), dat.as_bytes())?;
                scenarios.push(json!({
                    "dimension": dim,
                    "path": format!("{data_dir}/{dat_name}"),
                    "runs": runs,
                }));
            }
            if scenarios.is_empty() {
                continue;
            }
            let meta = json!({
                "version": IOH_FORMAT,
                "suite": if kind == "bbob" { "BBOB" } else { "optbench" },
                "function_id": fid,
                "function_name": kind,
                "maximization": false,
                "algorithm": {
                    "name": opt.as_str(),
                    "info": format!(
                        "optbench {} {opt_kind}, suite {suite}",
                        env!("CARGO_PKG_VERSION")
                    ),
                },
                "run_attributes": ["trial"],
                "attributes": ["evaluations", "raw_y"],
                "scenarios": scenarios,
            });
            let mut bytes = serde_json::to_vec_pretty(&meta).expect("serialisable");
            bytes.push(b'\n');
            atomic_write(
                &base.join(format!("IOHprofiler_f{fid}_{kind}.json")),
                &bytes,
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(obj: &str, opt: &str, trial: usize, imp: Vec<(u64, f64)>, evals: u64) -> TrialRecord {
        TrialRecord {
            objective: obj.into(),
            optimizer: opt.into(),
            trial,
            seed: "00".into(),
            budget: 100,
            evaluations: evals,
            best: imp.last().map(|l| l.1).unwrap_or(f64::INFINITY),
            best_x: vec![0.0, 0.0],
            optimum: None,
            stopped_at_target: false,
            nonfinite: 0,
            penalised: 0,
            wall_s: 0.1,
            improvements: imp,
            checkpoints: vec![],
        }
    }

    #[test]
    fn one_meta_file_per_kind_with_a_scenario_per_dimension_and_runs_in_dat_order() {
        let dir = tempfile::tempdir().unwrap();
        let name = |s: &str| SafeName::new(s).unwrap();
        let (s2, s5, w2, ga) = (
            name("schwefel-2d"),
            name("schwefel-5d"),
            name("schwefel-wide"),
            name("GA"),
        );
        fn obj(id: &SafeName, dim: usize, instance: u16, optimum: Option<f64>) -> IohObjective<'_> {
            IohObjective {
                id,
                kind: "schwefel",
                fid: 27,
                dim,
                instance,
                optimum,
                instances: Vec::new(),
            }
        }
        let opt = Some(-837.9657745448674);
        let objectives = [
            obj(&s2, 2, 1, opt),
            obj(&s5, 5, 1, opt),
            obj(&w2, 2, 777, None),
        ];
        let recs = vec![
            record("schwefel-2d", "GA", 1, vec![(1, -800.0), (7, -837.0)], 100),
            record(
                "schwefel-2d",
                "GA",
                0,
                vec![(1, -700.0), (100, -837.9657745448674)],
                100,
            ),
            record("schwefel-wide", "GA", 0, vec![(4, 10.0)], 5),
            record("schwefel-5d", "GA", 0, vec![], 0),
        ];
        export(dir.path(), "tiny", &objectives, &[(&ga, "ga")], &recs).unwrap();
        let meta: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("GA/IOHprofiler_f27_schwefel.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(meta["function_id"], 27);
        assert_eq!(meta["suite"], "optbench");
        assert_eq!(meta["maximization"], false);
        let sc = meta["scenarios"].as_array().unwrap();
        assert_eq!(sc.len(), 2);
        assert_eq!(sc[0]["dimension"], 2);
        assert_eq!(sc[0]["path"], "data_f27_schwefel/IOHprofiler_f27_DIM2.dat");
        let runs = sc[0]["runs"].as_array().unwrap();
        // Trial order within an objective, objectives in suite order.
        let ids: Vec<(u64, u64)> = runs
            .iter()
            .map(|r| {
                (
                    r["instance"].as_u64().unwrap(),
                    r["trial"].as_u64().unwrap(),
                )
            })
            .collect();
        assert_eq!(ids, [(1, 0), (1, 1), (777, 0)]);
        // f - f*: the optimum reached is 0, not the raw negative value.
        assert_eq!(runs[0]["best"]["y"], 0.0);
        assert_eq!(runs[0]["best"]["evals"], 100);
        assert_eq!(runs[1]["best"]["y"], -837.0 + 837.9657745448674);
        // No evaluation: no finite best, null rather than an invalid number.
        assert!(sc[1]["runs"][0]["best"]["y"].is_null());
        let dat = std::fs::read_to_string(
            dir.path()
                .join("GA/data_f27_schwefel/IOHprofiler_f27_DIM2.dat"),
        )
        .unwrap();
        let e1 = -700.0 + 837.9657745448674;
        let e2 = -800.0 + 837.9657745448674;
        let e3 = -837.0 + 837.9657745448674;
        assert_eq!(
            dat,
            format!(
                "evaluations raw_y\n1 {e1:e}\n100 0e0\n\
                 evaluations raw_y\n1 {e2:e}\n7 {e3:e}\n100 {e3:e}\n\
                 evaluations raw_y\n1 inf\n4 1e1\n5 1e1\n"
            )
        );
        let csv = std::fs::read_to_string(dir.path().join("instances.csv")).unwrap();
        assert!(
            csv.contains("\n27,schwefel,2,777,schwefel-wide,f (optimum unknown)\n"),
            "{csv}"
        );
        assert!(
            csv.contains("\n27,schwefel,2,1,schwefel-2d,f - f* (f* = -8.379657745448674e2)\n"),
            "{csv}"
        );
    }

    #[test]
    fn every_objective_kind_has_one_fixed_function_id() {
        // `bbob` objectives take BBOB's numbers 1-24 from their suite identity.
        for k in crate::registry::objective_kinds() {
            if k.name != "bbob" {
                function_id(k.name).unwrap();
            }
        }
        let mut ids: Vec<u16> = FUNCTION_IDS.iter().map(|k| k.1).collect();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), FUNCTION_IDS.len());
        assert!(ids.iter().all(|&id| id > 24), "1..=24 are BBOB's: {ids:?}");
        assert!(function_id("no-such-kind").is_err());
    }

    #[test]
    fn instances_are_one_on_the_customary_domain_and_stable_elsewhere() {
        let p = |v: &[(&str, &str)]| -> Vec<(String, String)> {
            v.iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect()
        };
        assert_eq!(instance_key("griewank", &[], (-600.0, 600.0)), None);
        let narrow = instance_key("griewank", &[], (-1.0, 1.0));
        assert_eq!(narrow.as_deref(), Some("griewank;box=-1e0,1e0"));
        assert!(instance_of(narrow.as_deref()) >= 2);
        // Frozen: the same box has this number in every suite and version.
        let sphere = instance_key("sphere", &[], (-1.0, 1.0));
        assert_eq!(instance_of(sphere.as_deref()), 29145);
        let a = instance_key("bouc-wen", &p(&[("recording", "twin:chirp")]), (0.0, 1.0));
        let b = instance_key("bouc-wen", &p(&[("recording", "twin:sine")]), (0.0, 1.0));
        assert_ne!(instance_of(a.as_deref()), instance_of(b.as_deref()));
    }

    #[test]
    fn moved_functions_never_share_the_plain_instance() {
        let p = |shift: &str, rotate: &str, inst: &str| -> Vec<(String, String)> {
            [("shift", shift), ("rotate", rotate), ("instance", inst)]
                .iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect()
        };
        let dom = (-600.0, 600.0);
        // The defaults are the plain function: instance 1, as before these keys existed.
        assert_eq!(
            instance_key("griewank", &p("\"none\"", "false", "1"), dom),
            None
        );
        let keys = [
            p("\"random\"", "false", "1"),
            p("\"random\"", "false", "2"),
            p("\"random\"", "true", "1"),
            p("\"none\"", "true", "1"),
        ];
        let numbers: BTreeSet<u16> = keys
            .iter()
            .map(|k| instance_of(instance_key("griewank", k, dom).as_deref()))
            .collect();
        assert_eq!(numbers.len(), keys.len());
        assert!(!numbers.contains(&1));
        assert_eq!(
            instance_key("griewank", &keys[2], (-1.0, 1.0)).as_deref(),
            Some("griewank;box=-1e0,1e0;shift=\"random\";rotate=true;instance=1")
        );
    }
}
