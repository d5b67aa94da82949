//! Diagnosing recorded files: read and trim the training, validation and test records, run
//! the diagnosis, look for coupled inputs among the validation files' other columns, and
//! write the report.

use super::{Options, TestSet, coupling, diagnose_with_tests, report};
use crate::base::error::{Error, Result};
use crate::data::recording::{Columns, ReadOptions, Recording, header_names, unit_from_name};
use crate::objective::source::{read_noting, resolve_path};
use std::path::{Path, PathBuf};

/// The files of one diagnosis and how to read them.
pub struct Files {
    pub train: Vec<PathBuf>,
    pub validate: Vec<PathBuf>,
    pub test: Vec<PathBuf>,
    pub test_periodic: Vec<PathBuf>,
    pub columns: Columns,
    pub read: ReadOptions,
    pub trim_start: f64,
    /// Instead of validation files: this share of every training record's tail, held out
    /// (never fitted) as its validation record.
    pub holdout: Option<f64>,
}

/// Where `n` samples split for a held-out tail of `fraction` (0 < fraction < 1): the
/// first index of the tail.
pub fn holdout_split(n: usize, fraction: f64) -> Result<usize> {
    if !(fraction > 0.0 && fraction < 1.0) {
        return Err(Error::Input(format!(
            "--holdout {fraction}: expected the share of each training record held out for validation, between 0 and 1 (e.g. 0.2)"
        )));
    }
    Ok(n - ((n as f64 * fraction).round() as usize).clamp(1, n - 1))
}

fn read(path: &Path, columns: &Columns, read: &ReadOptions) -> Result<Recording> {
    let p = resolve_path(&path.to_string_lossy(), Path::new("."));
    read_noting(&p, columns, read)
}

/// The other numeric columns of a file in the input column's unit (`u2_V` beside `u1_V`):
/// inputs driven at the same time, read like the input (an output or a column that does
/// not read as numbers is left out).
fn other_inputs(
    path: &Path,
    columns: &Columns,
    read_opts: &ReadOptions,
    trim: f64,
) -> Vec<(String, Vec<f64>)> {
    let p = resolve_path(&path.to_string_lossy(), Path::new("."));
    let unit = unit_from_name(&columns.input);
    let Ok(names) = header_names(&p, read_opts) else {
        return Vec::new();
    };
    names
        .into_iter()
        .filter(|n| {
            ![&columns.time, &columns.input, &columns.output].contains(&n)
                && !unit.is_empty()
                && unit_from_name(n) == unit
        })
        .filter_map(|n| {
            let c = Columns {
                input: n.clone(),
                ..columns.clone()
            };
            let r = Recording::read_csv(&p, &c, read_opts)
                .ok()?
                .trim_start(trim)
                .ok()?;
            Some((n, r.u))
        })
        .collect()
}

/// `x` (0..1) as a percentage with at most one decimal.
fn percent(x: f64) -> String {
    let p = (1000.0 * x).round() / 10.0;
    format!("{p} %")
}

/// Diagnoses the files with `opts`, writes the report to `out`; returns the text to print.
pub fn diagnose_files(f: &Files, opts: &Options, out: &Path) -> Result<String> {
    if f.train.is_empty() || (f.validate.is_empty() == f.holdout.is_none()) {
        return Err(Error::Input(
            "--train and one of --validate or --holdout are required".into(),
        ));
    }
    if !(f.trim_start.is_finite() && f.trim_start >= 0.0) {
        return Err(Error::Input(format!(
            "--trim-start {}: expected the seconds (>= 0) to leave out at the start of every record",
            f.trim_start
        )));
    }
    let (columns, ropts) = (&f.columns, &f.read);
    let records = |paths: &[PathBuf]| -> Result<Vec<Recording>> {
        paths
            .iter()
            .map(|p| read(p, columns, ropts)?.trim_start(f.trim_start))
            .collect()
    };
    let (mut train, mut validate) = (records(&f.train)?, records(&f.validate)?);
    // The held-out tails, and where each training file splits.
    let mut splits = Vec::new();
    if let Some(fraction) = f.holdout {
        for r in &mut train {
            let k = holdout_split(r.len(), fraction)?;
            let (mut head, mut tail) = (r.slice(0..k)?, r.slice(k..r.len())?);
            head.name = format!("{} (first {})", r.name, percent(1.0 - fraction));
            tail.name = format!("{} (last {}, held out)", r.name, percent(fraction));
            *r = head;
            splits.push(k);
            validate.push(tail);
        }
    }
    let mut tests = Vec::new();
    for (paths, periodic) in [(&f.test, false), (&f.test_periodic, true)] {
        for p in paths {
            tests.push(TestSet {
                recording: read(p, columns, ropts)?.trim_start(f.trim_start)?,
                periodic,
            });
        }
    }
    let mut d = diagnose_with_tests(&train, &validate, &tests, opts)?;
    // Columns every validation file (or held-out tail) holds, concatenated as the records
    // are.
    let tails = f.train.iter().zip(&splits).map(|(p, &k)| {
        let mut o = other_inputs(p, columns, ropts, f.trim_start);
        for (_, x) in &mut o {
            x.drain(..k.min(x.len()));
        }
        o
    });
    let mut files: Box<dyn Iterator<Item = _>> = if f.holdout.is_some() {
        Box::new(tails)
    } else {
        Box::new(
            f.validate
                .iter()
                .map(|v| other_inputs(v, columns, ropts, f.trim_start)),
        )
    };
    let mut others = files.next().unwrap_or_default();
    for here in files {
        others.retain_mut(|(n, x)| match here.iter().find(|h| &h.0 == n) {
            Some(more) => {
                x.extend(&more.1);
                true
            }
            None => false,
        });
    }
    d.couplings = coupling::couplings(&d, &others);
    d.columns = Some(columns.clone());
    d.model_file.columns = Some(crate::physics::model_file::Units {
        time: columns.time.clone(),
        input: columns.input.clone(),
        output: columns.output.clone(),
    });
    report::write(&d, out)?;
    Ok(format!(
        "{}\ndiagnosis.json and figures: {}\n",
        report::text(&d),
        out.display()
    ))
}
