//! Export of BBOB runs in the format COCO's `bbob` logger writes (`data_format =
//! 'bbob-new2'`), so `cocopp` post-processes optbench results as it does COCO's own and
//! sets them beside the published BBOB data:
//!
//! ```text
//! coco/<optimizer>/bbobexp_f<F>.info                     one block of three lines per dimension
//! coco/<optimizer>/data_f<F>/bbobexp_f<F>_DIM<D>.dat     target-triggered: one run after another
//! coco/<optimizer>/data_f<F>/bbobexp_f<F>_DIM<D>.tdat    evaluation-triggered, the same runs
//! ```
//!
//! Only objectives of COCO's suite are exported ([`Objective::suite_id`] `bbob`); each trial
//! is one run of the instance it ran (see `instances` in the suite), with that instance's
//! f_opt. The traces keep every improvement of the best-so-far, so the lines COCO's logger
//! writes can be rebuilt exactly where they depend on the best-so-far:
//!
//! - `.dat`: a line where the best-so-far error f − f_opt first falls to a new level of
//!   COCO's grid 10^(k/5) (the 51 targets 10^2..10^-8 are on it, so every first hitting
//!   time cocopp reads is the exact one), the first evaluation, and the last evaluation;
//! - `.tdat`: the best-so-far at COCO's evaluation triggers, ⌊10^(k/20)⌋ and
//!   dim·{1, 2, 5}·10^j, and at the last evaluation.
//!
//! Columns are COCO's first five: evaluations, constraint evaluations (0), best f − f_opt,
//! the value measured at that evaluation and the best measured value. The traces hold no
//! value of an evaluation that did not improve and no point but the final best, so
//! "measured" is `nan` on such lines and the x columns are left out (cocopp reads columns
//! 0 and 2 only and checks no column count for these files).
//!
//! [`Objective::suite_id`]: crate::objective::Objective::suite_id

use crate::base::error::Result;
use crate::base::{atomic_write, create_dir_within};
use crate::harness::TrialRecord;
use crate::pipeline::suite::Suite;
use crate::report::analysis::{best_at, error_of};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::Path;

/// The suite name COCO gives the functions this exports.
pub const SUITE: &str = "bbob";
/// COCO's final target, written as the `.info` files' `Precision`.
pub const PRECISION: f64 = 1e-8;

/// COCO's 51 targets of f − f_opt, 10^2 down to 10^-8 in steps of 10^0.2: those cocopp
/// aggregates its runtime ECDFs over.
pub fn targets() -> Vec<f64> {
    (0..=50).map(|k| 10f64.powf(2.0 - 0.2 * k as f64)).collect()
}

/// One trial on one instance of a BBOB function.
#[derive(Debug, Clone, Copy)]
pub struct BbobRun<'a> {
    pub function: usize,
    pub instance: usize,
    pub dim: usize,
    /// f_opt of the instance.
    pub fopt: f64,
    pub record: &'a TrialRecord,
}

/// The trials in `records` that ran a BBOB function with a known optimum, in record order.
/// Records of objectives the suite does not have are skipped (loading refuses them).
pub fn bbob_runs<'a>(suite: &Suite, records: &'a [TrialRecord]) -> Vec<BbobRun<'a>> {
    records
        .iter()
        .filter_map(|r| {
            let entry = suite.objectives.iter().find(|o| o.id == r.objective)?;
            let objective = entry.objective_of(r.trial);
            let id = objective.suite_id().filter(|s| s.suite == SUITE)?;
            Some(BbobRun {
                function: id.function,
                instance: id.instance,
                dim: objective.dim(),
                fopt: r.optimum?,
                record: r,
            })
        })
        .collect()
}

/// `v` as C's `printf("%+.{prec}e")` or `"%.{prec}e"` writes it (`+1.2e+01`): the form
/// COCO's files have. Non-finite values as `inf`, `-inf`, `nan`, which cocopp reads.
pub fn c_exp(v: f64, prec: usize, plus: bool) -> String {
    if !v.is_finite() {
        return if v.is_nan() {
            "nan".into()
        } else if v > 0.0 {
            if plus { "+inf" } else { "inf" }.into()
        } else {
            "-inf".into()
        };
    }
    let s = format!("{v:.prec$e}");
    let (mantissa, exp) = s.split_once('e').expect("Rust's {:e} has an exponent");
    let exp: i32 = exp.parse().expect("an integer exponent");
    let sign = if plus && !mantissa.starts_with('-') {
        "+"
    } else {
        ""
    };
    let esign = if exp < 0 { '-' } else { '+' };
    format!("{sign}{mantissa}e{esign}{:02}", exp.abs())
}

/// The level of error `e` on COCO's target grid: the smallest k with e <= 10^(k/5) (a
/// hair of slack, so an error equal to a grid value up to rounding counts as reaching it);
/// `i64::MIN` for 0.
fn level(e: f64) -> i64 {
    if e <= 0.0 {
        return i64::MIN;
    }
    if !e.is_finite() {
        return i64::MAX;
    }
    (5.0 * e.log10() - 1e-9).ceil() as i64
}

/// The header line starting each run, COCO's with the instance added as a `key = value`
/// pair (cocopp reads `instance` from it).
fn run_header(fopt: f64, instance: usize) -> String {
    format!(
        "% f evaluations | g evaluations | best noise-free fitness - Fopt ({}) + sum g_i+ | measured fitness | best measured fitness or single-digit g-values (x not recorded), instance = {instance}\n",
        c_exp(fopt, 12, false)
    )
}

fn line(out: &mut String, evals: u64, best: f64, measured: f64, fopt: f64) {
    writeln!(
        out,
        "{evals} 0 {} {} {}",
        c_exp(error_of(best, Some(fopt)), 9, true),
        c_exp(measured, 9, true),
        c_exp(best, 9, true)
    )
    .expect("write to string");
}

/// One run's target-triggered lines (`.dat`).
pub fn dat_block(out: &mut String, run: &BbobRun<'_>) {
    let r = run.record;
    out.push_str(&run_header(run.fopt, run.instance));
    let mut last_level = i64::MAX;
    let mut last_eval = 0;
    for (i, &(e, v)) in r.improvements.iter().enumerate() {
        let l = level(error_of(v, Some(run.fopt)));
        if i == 0 || l < last_level {
            line(out, e, v, v, run.fopt);
            last_level = l;
            last_eval = e;
        }
    }
    if r.evaluations > last_eval {
        let measured = match r.improvements.last() {
            Some(&(e, v)) if e == r.evaluations => v,
            _ => f64::NAN,
        };
        line(out, r.evaluations, r.best, measured, run.fopt);
    }
}

/// COCO's evaluation triggers up to `evals`: ⌊10^(k/20)⌋, dim·{1, 2, 5}·10^j, and `evals`.
pub fn evaluation_triggers(dim: usize, evals: u64) -> Vec<u64> {
    let mut out = std::collections::BTreeSet::new();
    for k in 0.. {
        let e = 10f64.powf(k as f64 / 20.0).floor() as u64;
        if e > evals {
            break;
        }
        out.insert(e);
    }
    let mut decade = dim as u64;
    while decade <= evals {
        for m in [1, 2, 5] {
            if decade * m <= evals {
                out.insert(decade * m);
            }
        }
        decade = decade.saturating_mul(10);
    }
    if evals > 0 {
        out.insert(evals);
    }
    out.into_iter().collect()
}

/// One run's evaluation-triggered lines (`.tdat`); triggers before the first value are
/// left out (nothing known yet).
pub fn tdat_block(out: &mut String, run: &BbobRun<'_>) {
    let r = run.record;
    out.push_str(&run_header(run.fopt, run.instance));
    for e in evaluation_triggers(run.dim, r.evaluations) {
        let best = best_at(&r.improvements, e);
        if best == f64::INFINITY {
            continue;
        }
        let i = r.improvements.partition_point(|&(x, _)| x < e);
        let measured = match r.improvements.get(i) {
            Some(&(x, v)) if x == e => v,
            _ => f64::NAN,
        };
        line(out, e, best, measured, run.fopt);
    }
}

/// The `.info` entry of one run: `instance:evaluations|final f − f_opt`.
fn info_entry(run: &BbobRun<'_>) -> String {
    format!(
        "{}:{}|{}",
        run.instance,
        run.record.evaluations,
        c_exp(error_of(run.record.best, Some(run.fopt)), 1, false)
    )
}

/// Writes the export of the BBOB runs among `records` under `dir` (typically
/// `results/<suite>/coco`), one folder per optimizer of the suite; returns the number of
/// runs written (0: the suite has no BBOB objective, and nothing is written).
pub fn export(dir: &Path, suite: &Suite, records: &[TrialRecord]) -> Result<usize> {
    let runs = bbob_runs(suite, records);
    if runs.is_empty() {
        return Ok(0);
    }
    let version = env!("CARGO_PKG_VERSION");
    for opt in &suite.optimizers {
        // (function, dim) -> runs, in suite order of objectives, then trial order.
        let mut cells: BTreeMap<(usize, usize), Vec<&BbobRun<'_>>> = BTreeMap::new();
        for run in runs.iter().filter(|r| r.record.optimizer == *opt.id) {
            cells.entry((run.function, run.dim)).or_default().push(run);
        }
        let position = |id: &str| suite.objectives.iter().position(|o| o.id == id);
        let mut infos: BTreeMap<usize, String> = BTreeMap::new();
        for ((f, dim), cell) in &mut cells {
            cell.sort_by_key(|r| (position(&r.record.objective), r.record.trial));
            let base = dir.join(opt.id.as_str());
            let data_dir = format!("data_f{f}");
            create_dir_within(dir, &base.join(&data_dir))?;
            let stem = format!("bbobexp_f{f}_DIM{dim}");
            let (mut dat, mut tdat) = (String::new(), String::new());
            for run in cell.iter() {
                dat_block(&mut dat, run);
                tdat_block(&mut tdat, run);
            }
            atomic_write(
                &base.join(&data_dir).join(format!("{stem}.dat")),
                dat.as_bytes(),
            )?;
            atomic_write(
                &base.join(&data_dir).join(format!("{stem}.tdat")),
                tdat.as_bytes(),
            )?;
            let info = infos.entry(*f).or_default();
            // cocopp splits the header at ", " and " = ": no value may hold either.
            writeln!(
                info,
                "suite = '{SUITE}', funcId = {f}, DIM = {dim}, Precision = {}, algId = '{}', coco_version = 'optbench-{version}', logger = 'bbob', data_format = 'bbob-new2', settings = '{}; suite {}'",
                c_exp(PRECISION, 3, false),
                opt.id,
                opt.kind,
                suite.name
            )
            .expect("write to string");
            info.push_str(
                "% written by optbench from its traces: .dat lines at COCO's target levels, .tdat at its evaluation triggers, no x columns\n",
            );
            let entries: Vec<String> = cell.iter().map(|r| info_entry(r)).collect();
            writeln!(info, "{data_dir}/{stem}.dat, {}", entries.join(", "))
                .expect("write to string");
        }
        for (f, info) in infos {
            atomic_write(
                &dir.join(opt.id.as_str()).join(format!("bbobexp_f{f}.info")),
                info.as_bytes(),
            )?;
        }
    }
    Ok(runs.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(improvements: Vec<(u64, f64)>, evaluations: u64) -> TrialRecord {
        TrialRecord {
            objective: "o".into(),
            optimizer: "p".into(),
            trial: 0,
            seed: String::new(),
            budget: evaluations,
            evaluations,
            best: improvements.last().map_or(f64::INFINITY, |i| i.1),
            best_x: vec![],
            optimum: Some(79.48),
            stopped_at_target: false,
            nonfinite: 0,
            penalised: 0,
            wall_s: 0.0,
            improvements,
            checkpoints: vec![],
        }
    }

    #[test]
    fn numbers_are_written_as_c_writes_them() {
        assert_eq!(c_exp(79.48, 12, false), "7.948000000000e+01");
        assert_eq!(c_exp(32.06998128, 9, true), "+3.206998128e+01");
        assert_eq!(c_exp(-247.11, 9, true), "-2.471100000e+02");
        assert_eq!(c_exp(1e-8, 3, false), "1.000e-08");
        assert_eq!(c_exp(0.0, 1, false), "0.0e+00");
        assert_eq!(c_exp(1e150, 1, false), "1.0e+150");
        assert_eq!(c_exp(f64::NAN, 9, true), "nan");
        assert_eq!(c_exp(f64::INFINITY, 9, true), "+inf");
    }

    #[test]
    fn the_targets_are_cocos_51() {
        let t = targets();
        assert_eq!(t.len(), 51);
        assert!((t[0] - 100.0).abs() < 1e-12 && (t[50] - 1e-8).abs() < 1e-20);
        assert!((t[10] - 1.0).abs() < 1e-14);
    }

    /// The evaluation triggers of the `.tdat` COCO 2.8.2 wrote for a 2-D run of 60
    /// evaluations (exdata of its own random search).
    #[test]
    fn evaluation_triggers_are_cocos() {
        assert_eq!(
            evaluation_triggers(2, 60),
            [
                1, 2, 3, 4, 5, 6, 7, 8, 10, 11, 12, 14, 15, 17, 19, 20, 22, 25, 28, 31, 35, 39, 40,
                44, 50, 56, 60
            ]
        );
    }

    /// Lines where the error enters a new level of 10^(k/5), the first and last
    /// evaluation; the error equal to a grid value counts as reaching it.
    #[test]
    fn dat_lines_fall_on_cocos_target_levels() {
        let f = 79.48;
        let imp = vec![
            (1, f + 32.0),
            (3, f + 4.7),
            (5, f + 4.5), // same level as 4.7 (10^0.6 = 3.98 < e <= 10^0.8 = 6.31)
            (9, f + 1.0),
            (14, f + 1e-3),
        ];
        let r = record(imp, 60);
        let run = BbobRun {
            function: 1,
            instance: 2,
            dim: 2,
            fopt: f,
            record: &r,
        };
        let mut s = String::new();
        dat_block(&mut s, &run);
        let evals: Vec<&str> = s
            .lines()
            .skip(1)
            .map(|l| l.split(' ').next().unwrap())
            .collect();
        assert_eq!(evals, ["1", "3", "9", "14", "60"]);
        assert!(
            s.starts_with("% f evaluations") && s.lines().next().unwrap().ends_with("instance = 2")
        );
        assert!(s.lines().last().unwrap().starts_with("60 0 +1.0000"), "{s}");
        assert!(s.lines().last().unwrap().contains(" nan "), "{s}");
        assert_eq!(level(1.0), 0);
        assert_eq!(level(10f64.powf(-0.2 * 37.0)), -37);
        let mut t = String::new();
        tdat_block(&mut t, &run);
        let line4 = t.lines().find(|l| l.starts_with("4 ")).unwrap();
        assert!(
            line4.starts_with("4 0 +4.70") && line4.contains(" nan "),
            "{line4}"
        );
        let line5 = t.lines().find(|l| l.starts_with("5 ")).unwrap();
        assert!(!line5.contains("nan"), "{line5}");
        assert_eq!(info_entry(&run), "2:60|1.0e-03");
    }
}
