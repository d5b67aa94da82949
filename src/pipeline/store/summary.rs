//! `summary.json`: per objective x optimizer, the final best value of every trial and their
//! statistics. Scripts read this file; its fields are a stable interface, and
//! `format_version` says which: a reader refuses a version newer than it knows, and takes a
//! file without one (written before the field) as version 1.

use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use crate::stats::describe;
use serde::{Deserialize, Serialize};

/// Summary of one objective x optimizer cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellSummary {
    pub objective: String,
    pub optimizer: String,
    /// Final best value of every trial, in trial order. These and the statistics may be
    /// infinite (a trial with no finite value): stored as "inf"/"-inf"/"nan", never null
    /// (see [`crate::base::json_float`]).
    #[serde(with = "crate::base::json_float::many")]
    pub finals: Vec<f64>,
    #[serde(with = "crate::base::json_float::one")]
    pub median: f64,
    #[serde(with = "crate::base::json_float::one")]
    pub mean: f64,
    /// Sample standard deviation.
    #[serde(with = "crate::base::json_float::one")]
    pub std: f64,
    #[serde(with = "crate::base::json_float::one")]
    pub min: f64,
    #[serde(with = "crate::base::json_float::one")]
    pub max: f64,
    /// First and third quartiles (type 7).
    #[serde(with = "crate::base::json_float::one")]
    pub q1: f64,
    #[serde(with = "crate::base::json_float::one")]
    pub q3: f64,
    /// Evaluations spent, summed over the trials (exact).
    pub evaluations: u64,
    /// Wall-clock seconds, summed over the trials.
    pub wall_s: f64,
    pub trials: usize,
    /// Budget per trial.
    pub budget: u64,
    /// Known optimum of the objective, if any (finals minus this are errors).
    pub optimum: Option<f64>,
    /// Evaluations that returned NaN or an infinity, summed over the trials.
    pub nonfinite: u64,
    /// Evaluations answered with a penalty, summed over the trials.
    #[serde(default)]
    pub penalised: u64,
}

/// The version of `summary.json` this build writes and the newest it reads. Raise it when a
/// field changes meaning or goes away (adding a field with a default does not).
pub const SUMMARY_FORMAT_VERSION: u32 = 1;

fn version_one() -> u32 {
    1
}

/// The whole `summary.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// See [`SUMMARY_FORMAT_VERSION`]; absent in files from before the field: 1.
    #[serde(default = "version_one")]
    pub format_version: u32,
    pub suite: String,
    pub seed: u64,
    pub results: Vec<CellSummary>,
}

/// Groups records (in plan order) into cells, keeping first-appearance order.
pub fn summarize(suite: &str, seed: u64, records: &[TrialRecord]) -> Summary {
    let mut cells: Vec<(String, String, Vec<&TrialRecord>)> = Vec::new();
    for r in records {
        match cells
            .iter_mut()
            .find(|(o, p, _)| *o == r.objective && *p == r.optimizer)
        {
            Some(c) => c.2.push(r),
            None => cells.push((r.objective.clone(), r.optimizer.clone(), vec![r])),
        }
    }
    let results = cells
        .into_iter()
        .map(|(objective, optimizer, mut rs)| {
            rs.sort_by_key(|r| r.trial);
            let finals: Vec<f64> = rs.iter().map(|r| r.best).collect();
            let d = describe(&finals);
            CellSummary {
                objective,
                optimizer,
                median: d.median,
                mean: d.mean,
                std: d.std,
                min: d.min,
                max: d.max,
                q1: d.q1,
                q3: d.q3,
                evaluations: rs.iter().map(|r| r.evaluations).sum(),
                wall_s: rs.iter().map(|r| r.wall_s).sum(),
                trials: rs.len(),
                budget: rs[0].budget,
                optimum: rs[0].optimum,
                nonfinite: rs.iter().map(|r| r.nonfinite).sum(),
                penalised: rs.iter().map(|r| r.penalised).sum(),
                finals,
            }
        })
        .collect();
    Summary {
        format_version: SUMMARY_FORMAT_VERSION,
        suite: suite.to_string(),
        seed,
        results,
    }
}

/// Reads `summary.json` of a results folder, refusing a format newer than this build's.
pub fn read_summary(dir: &std::path::Path) -> Result<Summary> {
    let path = dir.join("summary.json");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| Error::Input(format!("{}: cannot read: {e}", path.display())))?;
    #[derive(Deserialize)]
    struct Version {
        #[serde(default = "version_one")]
        format_version: u32,
    }
    let v: Version = serde_json::from_str(&text).map_err(|e| Error::at(&path, e.line(), e))?;
    if v.format_version > SUMMARY_FORMAT_VERSION {
        return Err(Error::Input(format!(
            "{}: format_version {} is newer than this optbench reads ({SUMMARY_FORMAT_VERSION}); \
             read it with a newer optbench, or rerun `optbench report`/`run` with this one",
            path.display(),
            v.format_version
        )));
    }
    serde_json::from_str(&text).map_err(|e| Error::at(&path, e.line(), e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_version_is_written_absent_means_one_and_newer_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let s = summarize("s", 1, &[]);
        let mut v = serde_json::to_value(&s).unwrap();
        assert_eq!(v["format_version"], SUMMARY_FORMAT_VERSION);
        let path = dir.path().join("summary.json");
        std::fs::write(&path, v.to_string()).unwrap();
        assert_eq!(read_summary(dir.path()).unwrap(), s);
        v.as_object_mut().unwrap().remove("format_version");
        std::fs::write(&path, v.to_string()).unwrap();
        assert_eq!(read_summary(dir.path()).unwrap().format_version, 1);
        v["format_version"] = (SUMMARY_FORMAT_VERSION + 1).into();
        std::fs::write(&path, v.to_string()).unwrap();
        let e = read_summary(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("format_version 2 is newer") && e.contains("summary.json"),
            "{e}"
        );
    }
}
