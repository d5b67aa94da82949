//! A measured output beside the models' outputs: the series of the time-series and loop
//! figures.

use crate::base::error::{Error, Result};

/// Legend label of a measured output.
pub const MEASURED: &str = "measured";

/// The measured output (or whatever the models are held against, e.g. a controlled
/// plant's output) first, then the models: (label, values), series `i` in style `i` (so
/// the first is black).
pub(super) fn output_series<'a>(
    (label, measured): (&'a str, &'a [f64]),
    models: &'a [(String, Vec<f64>)],
) -> Vec<(&'a str, &'a [f64])> {
    std::iter::once((label, measured))
        .chain(models.iter().map(|(l, v)| (l.as_str(), v.as_slice())))
        .collect()
}

/// Checks that the measured output and every model are as long as the independent variable.
pub(super) fn check_lengths(
    what: &str,
    n: usize,
    measured: (&str, &[f64]),
    models: &[(String, Vec<f64>)],
) -> Result<()> {
    for (label, v) in output_series(measured, models) {
        if v.len() != n {
            return Err(Error::Input(format!(
                "{what} has {n} samples but `{label}` has {}",
                v.len()
            )));
        }
    }
    Ok(())
}

/// Footnote part counting the (x, output) samples that cannot be drawn.
pub(super) fn nonfinite_note(x: &[f64], series: &[(&str, &[f64])]) -> Option<String> {
    let n: usize = series
        .iter()
        .map(|(_, v)| {
            x.iter()
                .zip(*v)
                .filter(|(a, b)| !(a.is_finite() && b.is_finite()))
                .count()
        })
        .sum();
    match n {
        0 => None,
        1 => Some("1 non-finite sample not drawn".into()),
        n => Some(format!("{n} non-finite samples not drawn")),
    }
}
