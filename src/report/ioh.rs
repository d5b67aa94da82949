//! Export of traces in the IOHprofiler format, so IOHanalyzer can load optbench results.
//!
//! Layout (IOHanalyzer detects the format from it), one folder per optimizer as
//! IOHexperimenter writes it:
//!
//! ```text
//! ioh/<optimizer>/IOHprofiler_f<k>_<objective>.info
//! ioh/<optimizer>/data_f<k>_<objective>/IOHprofiler_f<k>_DIM<d>.dat
//! ```
//!
//! `k` is the objective's 1-based position in the suite. The `.info` file holds one
//! three-line block: `suite = '...', funcId = k, funcName = '...', DIM = d, maximization = F,
//! algId = '...'`, a `%` comment line, and the data file path followed by
//! `instance:evaluations|final best` for each trial (every trial is instance 1: the
//! objectives are not randomised instances, the trials are independent runs). The `.dat`
//! file is the two-column format: per trial a header line
//! `"function evaluation" "best-so-far f(x)"`, then one line per improvement, ending with
//! the trial's last evaluation as IOHanalyzer requires. Values are raw objective values;
//! the comment line gives the known optimum where there is one.

use crate::base::error::Result;
use crate::base::{SafeName, atomic_write};
use crate::harness::TrialRecord;
use std::fmt::Write;
use std::path::Path;

/// One objective of the export: its suite position, id and dimension.
pub struct IohObjective<'a> {
    pub id: &'a SafeName,
    pub dim: usize,
}

/// Writes the IOHprofiler export of `records` under `dir` (typically `results/<suite>/ioh`).
/// `objectives` lists the suite's objectives in suite order (their position is the funcId),
/// `optimizers` the suite's optimizers: only their names become folders, whatever a record
/// says.
pub fn export(
    dir: &Path,
    suite: &str,
    objectives: &[IohObjective<'_>],
    optimizers: &[&SafeName],
    records: &[TrialRecord],
) -> Result<()> {
    for &opt in optimizers {
        for (k, obj) in objectives.iter().enumerate() {
            let fid = k + 1;
            let mut runs: Vec<&TrialRecord> = records
                .iter()
                .filter(|r| *opt == r.optimizer && *obj.id == r.objective)
                .collect();
            if runs.is_empty() {
                continue;
            }
            runs.sort_by_key(|r| r.trial);
            let data_dir = format!("data_f{fid}_{}", obj.id);
            let dat_name = format!("IOHprofiler_f{fid}_DIM{}.dat", obj.dim);
            let base = dir.join(opt);
            crate::base::create_dir_within(dir, &base.join(&data_dir))?;

            let mut dat = String::new();
            for r in &runs {
                dat.push_str("\"function evaluation\" \"best-so-far f(x)\"\n");
                for &(e, v) in &r.improvements {
                    writeln!(dat, "{e} {v:e}").expect("write to string");
                }
                let last = r.improvements.last().copied();
                if last.map(|l| l.0) != Some(r.evaluations) {
                    writeln!(dat, "{} {:e}", r.evaluations, r.best).expect("write to string");
                }
            }
            atomic_write(&base.join(&data_dir).join(&dat_name), dat.as_bytes())?;

            let optimum = runs[0]
                .optimum
                .map(|o| format!("known optimum {o:e}"))
                .unwrap_or_else(|| "optimum unknown".into());
            let mut info = format!(
                "suite = 'optbench:{suite}', funcId = {fid}, funcName = '{}', DIM = {}, maximization = F, algId = '{opt}'\n",
                obj.id, obj.dim
            );
            writeln!(
                info,
                "% optbench {} export; {} runs, budget {} evaluations; {optimum}",
                env!("CARGO_PKG_VERSION"),
                runs.len(),
                runs[0].budget
            )
            .expect("write to string");
            info.push_str(&format!("{data_dir}/{dat_name}"));
            for r in &runs {
                write!(info, ", 1:{}|{:e}", r.evaluations, r.best).expect("write to string");
            }
            info.push('\n');
            atomic_write(
                &base.join(format!("IOHprofiler_f{fid}_{}.info", obj.id)),
                info.as_bytes(),
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(opt: &str, trial: usize, imp: Vec<(u64, f64)>, evals: u64) -> TrialRecord {
        TrialRecord {
            objective: "griewank-2d".into(),
            optimizer: opt.into(),
            trial,
            seed: "00".into(),
            budget: 100,
            evaluations: evals,
            best: imp.last().unwrap().1,
            best_x: vec![0.0, 0.0],
            optimum: Some(0.0),
            stopped_at_target: false,
            nonfinite: 0,
            penalised: 0,
            wall_s: 0.1,
            improvements: imp,
            checkpoints: vec![],
        }
    }

    #[test]
    fn writes_info_and_two_column_dat() {
        let dir = tempfile::tempdir().unwrap();
        let recs = vec![
            record("GA", 1, vec![(1, 5.0), (7, 0.5)], 100),
            record("GA", 0, vec![(1, 3.0), (100, 0.25)], 100),
            record("PSO", 0, vec![(2, 1.0)], 100),
        ];
        let name = |s: &str| SafeName::new(s).unwrap();
        let (obj, ga, pso) = (name("griewank-2d"), name("GA"), name("PSO"));
        export(
            dir.path(),
            "tiny",
            &[IohObjective { id: &obj, dim: 2 }],
            &[&ga, &pso],
            &recs,
        )
        .unwrap();
        let info =
            std::fs::read_to_string(dir.path().join("GA/IOHprofiler_f1_griewank-2d.info")).unwrap();
        let lines: Vec<&str> = info.lines().collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(
            lines[0],
            "suite = 'optbench:tiny', funcId = 1, funcName = 'griewank-2d', DIM = 2, maximization = F, algId = 'GA'"
        );
        assert!(lines[1].starts_with("% optbench"));
        assert_eq!(
            lines[2],
            "data_f1_griewank-2d/IOHprofiler_f1_DIM2.dat, 1:100|2.5e-1, 1:100|5e-1"
        );
        let dat = std::fs::read_to_string(
            dir.path()
                .join("GA/data_f1_griewank-2d/IOHprofiler_f1_DIM2.dat"),
        )
        .unwrap();
        // Trial 0 first; each run ends at its last evaluation.
        assert_eq!(
            dat,
            "\"function evaluation\" \"best-so-far f(x)\"\n1 3e0\n100 2.5e-1\n\
             \"function evaluation\" \"best-so-far f(x)\"\n1 5e0\n7 5e-1\n100 5e-1\n"
        );
        assert!(
            dir.path()
                .join("PSO/IOHprofiler_f1_griewank-2d.info")
                .exists()
        );
    }
}
