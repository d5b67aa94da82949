//! Runtime ECDFs (as in COCO): the fraction of (trial, target) pairs reached over time.

use super::axes::Axis;
use super::canvas::{DrawResult, Figure, Scale, render};
use super::font;
use super::layout::{Pen, TICK_LINE, clamp_note, frame, ink, line_series};
use super::legend::{Corner, legend};
use crate::base::error::Result;
use crate::harness::TrialRecord;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Runtimes for an ECDF: for every record and every target (in that order), the evaluation
/// at which the record's error to optimum (its value when the optimum is unknown) first got
/// to <= target, or +inf if it never did.
pub fn runtimes(records: &[&TrialRecord], targets: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(records.len() * targets.len());
    for r in records {
        let off = r.optimum.unwrap_or(0.0);
        for &t in targets {
            let hit = r.improvements.iter().find(|&&(_, v)| v - off <= t);
            out.push(hit.map_or(f64::INFINITY, |&(e, _)| e as f64));
        }
    }
    out
}

struct Ecdf<'a> {
    title: &'a str,
    series: &'a [(String, Vec<f64>)],
    x_label: &'a str,
    y_label: &'a str,
    x_span: (f64, f64),
}

impl Figure for Ecdf<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: Scale) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let reached = |v: &f64| !v.is_nan() && *v != f64::INFINITY;
        let xs: Vec<f64> = self
            .series
            .iter()
            .flat_map(|(_, v)| v.iter().copied().filter(reached))
            .chain([self.x_span.0, self.x_span.1])
            .collect();
        let x = Axis::fit(true, &xs, 0.04, 8);
        let y = Axis::fixed(
            -0.03,
            1.03,
            (0..=5).map(|k| f64::from(k) * 0.2).collect(),
            (0..5).map(|k| f64::from(k) * 0.2 + 0.1).collect(),
        );
        let mut chart = frame(
            root,
            s,
            self.title,
            (&x, self.x_label),
            (&y, self.y_label),
            TICK_LINE,
        )?;
        let mut drawn = Vec::new();
        for (i, (label, values)) in self.series.iter().enumerate() {
            let mut hits: Vec<f64> = values
                .iter()
                .copied()
                .filter(reached)
                .filter_map(|v| x.to_plot(v))
                .collect();
            hits.sort_by(f64::total_cmp);
            let n = values.len().max(1) as f64;
            let mut steps = vec![(x.lo, 0.0)];
            for (k, &t) in hits.iter().enumerate() {
                steps.push((t, k as f64 / n));
                steps.push((t, (k + 1) as f64 / n));
            }
            steps.push((x.hi, hits.len() as f64 / n));
            ink(&chart, s, &steps, &mut drawn);
            let pen = Pen::marked(i, self.series.len());
            line_series(&mut chart, s, steps, pen, Some(label))?;
        }
        let labels: Vec<&str> = self.series.iter().map(|(l, _)| l.as_str()).collect();
        use Corner::*;
        legend(
            &mut chart,
            s,
            &labels,
            &drawn,
            [UpperLeft, LowerRight, UpperRight, LowerLeft],
        )?;
        clamp_note(root, s, &[("x", &x)])
    }
}

/// Runtime ECDF (as in COCO): per series, the fraction of its values (one per (trial,
/// target) pair, e.g. from [`runtimes`]) that are <= x, as a step curve over a log x axis.
/// +inf and NaN mean "never reached": they count in the denominator but never step the
/// curve up, so a series that missed some pairs ends below 1. Values <= 0: see [the kit](super).
/// The x axis spans at least `x_span` (typically 1 to the budget), so a
/// curve that stays flat is shown over the whole run.
pub fn ecdf(
    path_stem: &Path,
    title: &str,
    series: &[(String, Vec<f64>)],
    x_label: &str,
    x_span: (f64, f64),
) -> Result<()> {
    ecdf_of(
        path_stem,
        title,
        series,
        (x_label, "fraction of (trial, target) pairs reached"),
        x_span,
    )
}

/// [`ecdf`] with its own y label, for values that count other things than (trial, target)
/// pairs (COCO's aggregate over functions counts (function, instance, target) triples).
pub fn ecdf_of(
    path_stem: &Path,
    title: &str,
    series: &[(String, Vec<f64>)],
    (x_label, y_label): (&str, &str),
    x_span: (f64, f64),
) -> Result<()> {
    font::register()?;
    render(
        path_stem,
        &Ecdf {
            title,
            series,
            x_label,
            y_label,
            x_span,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::test_util::*;

    #[test]
    fn runtimes_are_first_hits_or_inf() {
        let r = record(Some(1.0), &[(1, 11.0), (5, 6.0), (20, 2.0)], &[(100, 2.0)]);
        assert_eq!(
            runtimes(&[&r], &[10.0, 1.0, 0.1]),
            vec![1.0, 20.0, f64::INFINITY]
        );
    }

    #[test]
    fn ecdf_writes_svg_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let series = vec![
            (
                "GA".to_string(),
                vec![12.0, 150.0, 900.0, 4000.0, f64::INFINITY, f64::INFINITY],
            ),
            (
                "PSO".to_string(),
                vec![5.0, 40.0, 300.0, 2500.0, 9000.0, 20000.0],
            ),
            ("random search".to_string(), vec![f64::INFINITY; 6]),
        ];
        ecdf(
            &dir.path().join("ecdf"),
            "Runtime ECDF, 3 targets",
            &series,
            "function evaluations",
            (1.0, 40_000.0),
        )
        .unwrap();
        only_outputs(dir.path(), "ecdf");
        let f = files(dir.path(), "ecdf");
        check_common(
            &f,
            "Runtime ECDF, 3 targets",
            &["GA", "PSO", "random search"],
        );
        for i in 0..series.len() {
            check_styled(&f.svg, i, true);
        }
    }
}
