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

/// Diagnoses the files with `opts`, writes the report to `out`; returns the text to print.
pub fn diagnose_files(f: &Files, opts: &Options, out: &Path) -> Result<String> {
    if f.train.is_empty() || f.validate.is_empty() {
        return Err(Error::Input("--train and --validate are required".into()));
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
    let (train, validate) = (records(&f.train)?, records(&f.validate)?);
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
    // Columns every validation file holds, concatenated as the records are.
    let mut files = f
        .validate
        .iter()
        .map(|v| other_inputs(v, columns, ropts, f.trim_start));
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
    report::write(&d, out)?;
    Ok(format!(
        "{}\ndiagnosis.json and figures: {}\n",
        report::text(&d),
        out.display()
    ))
}
