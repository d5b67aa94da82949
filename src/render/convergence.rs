//! Convergence curves: median and interquartile band of best-so-far over evaluations.

use super::axes::Axis;
use super::canvas::{DrawResult, Figure, Scale, render};
use super::font;
use super::layout::{Pen, SWATCH, TICK_LINE, clamp_note, draw_line, frame, ink};
use super::legend::{Corner, legend};
use super::style::color;
use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use crate::stats::quantile_sorted;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// One optimizer's convergence: median and quartiles across trials at each evaluation count.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvergenceSeries {
    pub label: String,
    /// Evaluation counts, increasing.
    pub evals: Vec<u64>,
    pub median: Vec<f64>,
    /// First quartile (type 7).
    pub q1: Vec<f64>,
    /// Third quartile (type 7).
    pub q3: Vec<f64>,
}

/// Quantile (type 7) that stays exact when both neighbouring order statistics are the same
/// infinity ([`quantile_sorted`] would give inf - inf = NaN there).
fn quantile7(sorted: &[f64], p: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * p.clamp(0.0, 1.0);
    let (lo, hi) = (sorted[h.floor() as usize], sorted[h.ceil() as usize]);
    if lo == hi {
        lo
    } else {
        quantile_sorted(sorted, p)
    }
}

/// Last value of an (evaluation, best-so-far) list with evaluation <= `count`.
fn last_at(points: &[(u64, f64)], count: u64) -> Option<f64> {
    let i = points.partition_point(|&(e, _)| e <= count);
    (i > 0).then(|| points[i - 1].1)
}

/// Best-so-far of `record` after `count` evaluations: the last improvement at or before
/// `count` (the last checkpoint at or before it too, whichever is lower, so a thinned
/// improvement list still gives the right value). +inf before the first finite value.
fn best_so_far(record: &TrialRecord, count: u64) -> f64 {
    let a = last_at(&record.improvements, count).unwrap_or(f64::INFINITY);
    let b = last_at(&record.checkpoints, count).unwrap_or(f64::INFINITY);
    a.min(b)
}

/// Convergence of a set of trials (one optimizer on one objective).
///
/// At every evaluation count in the union of the records' checkpoint grids, takes each
/// trial's exact best-so-far (its last improvement at or before that count; a trial that
/// stopped early keeps its final value), subtracts the optimum when the record knows it
/// (error to optimum), and takes the median and quartiles (type 7) across trials. Before a
/// trial's first finite value its best-so-far is +inf, so early quantiles can be +inf.
pub fn convergence_series(label: impl Into<String>, records: &[&TrialRecord]) -> ConvergenceSeries {
    let mut evals: Vec<u64> = records
        .iter()
        .flat_map(|r| r.checkpoints.iter().map(|&(e, _)| e))
        .collect();
    evals.sort_unstable();
    evals.dedup();
    let n = evals.len();
    let mut s = ConvergenceSeries {
        label: label.into(),
        evals: Vec::with_capacity(n),
        median: Vec::with_capacity(n),
        q1: Vec::with_capacity(n),
        q3: Vec::with_capacity(n),
    };
    let mut at = Vec::with_capacity(records.len());
    for e in evals {
        at.clear();
        at.extend(records.iter().map(|r| {
            let v = best_so_far(r, e);
            r.optimum.map_or(v, |o| v - o)
        }));
        at.sort_by(f64::total_cmp);
        s.evals.push(e);
        s.median.push(quantile7(&at, 0.5));
        s.q1.push(quantile7(&at, 0.25));
        s.q3.push(quantile7(&at, 0.75));
    }
    s
}

struct Convergence<'a> {
    title: &'a str,
    series: &'a [ConvergenceSeries],
    y_label: &'a str,
    log_y: bool,
}

impl Figure for Convergence<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: Scale) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let xs: Vec<f64> = self
            .series
            .iter()
            .flat_map(|c| c.evals.iter().map(|&e| e as f64))
            .collect();
        let ys: Vec<f64> = self
            .series
            .iter()
            .flat_map(|c| c.median.iter().chain(&c.q1).chain(&c.q3).copied())
            .collect();
        let x = Axis::fit(true, &xs, 0.0, 8);
        let y = Axis::fit(self.log_y, &ys, 0.04, 7);
        let mut chart = frame(
            root,
            s,
            self.title,
            (&x, "function evaluations"),
            (&y, self.y_label),
            TICK_LINE,
        )?;

        let mut lines = Vec::new();
        let mut drawn = Vec::new();
        for (i, c) in self.series.iter().enumerate() {
            let (mut line, mut lower, mut upper) = (vec![], vec![], vec![]);
            for k in 0..c.evals.len() {
                let Some(px) = x.to_plot(c.evals[k] as f64) else {
                    continue;
                };
                if let Some(py) = y.to_plot(c.median[k]) {
                    line.push((px, py));
                }
                let top = if c.q3[k] == f64::INFINITY {
                    Some(y.hi)
                } else {
                    y.to_plot(c.q3[k])
                };
                if let (Some(l), Some(u)) = (y.to_plot(c.q1[k]), top) {
                    lower.push((px, l));
                    upper.push((px, u));
                }
            }
            ink(&chart, s, &line, &mut drawn);
            ink(&chart, s, &lower, &mut drawn);
            ink(&chart, s, &upper, &mut drawn);
            if lower.len() >= 2 {
                let band: Vec<(f64, f64)> = lower
                    .iter()
                    .copied()
                    .chain(upper.iter().rev().copied())
                    .collect();
                chart.draw_series(std::iter::once(Polygon::new(
                    band,
                    color(i).mix(0.2).filled(),
                )))?;
            }
            lines.push(line);
        }
        // Lines after all bands, so no band covers another series' line.
        let (sw, sh, n) = (s.i(SWATCH), s.i(5), self.series.len());
        for (i, (c, line)) in self.series.iter().zip(lines).enumerate() {
            let pen = Pen::marked(i, n);
            let col = pen.style.color;
            draw_line(&mut chart, s, line, &pen)?
                .label(c.label.as_str())
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + Rectangle::new([(0, -sh), (sw, sh)], col.mix(0.2).filled())
                        + pen.swatch(s, (0, 0))
                });
        }
        let labels: Vec<&str> = self.series.iter().map(|c| c.label.as_str()).collect();
        use Corner::*;
        legend(
            &mut chart,
            s,
            &labels,
            &drawn,
            [UpperRight, LowerLeft, UpperLeft, LowerRight],
        )?;
        clamp_note(root, s, &[("x", &x), ("y", &y)])
    }
}

/// Convergence figure: per series, the median as a line (series `i` in the colour, dash
/// pattern and marker of [`series_style`](super::series_style)`(i)`) and the interquartile
/// range as a translucent band of the same colour, against function evaluations on a log
/// axis; `y` on a log axis when `log_y`. `y_label` says what the values are, in their unit.
///
/// Points where the median is +inf or NaN (fewer than half the trials have a finite value
/// yet) are left out of the line; where q3 is +inf the band reaches the top of the plot;
/// where q1 is not finite the band is left out. Values <= 0 on a log axis: see [the
/// kit](super). `evals`, `median`, `q1`, `q3` of a series must have the same length.
pub fn convergence(
    path_stem: &Path,
    title: &str,
    series: &[ConvergenceSeries],
    y_label: &str,
    log_y: bool,
) -> Result<()> {
    font::register()?;
    for c in series {
        let n = c.evals.len();
        if c.median.len() != n || c.q1.len() != n || c.q3.len() != n {
            return Err(Error::Input(format!(
                "convergence series {:?}: evals, median, q1 and q3 differ in length",
                c.label
            )));
        }
    }
    render(
        path_stem,
        &Convergence {
            title,
            series,
            y_label,
            log_y,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::test_util::*;

    #[test]
    fn convergence_series_takes_exact_quantiles_of_best_so_far() {
        // Errors to the optimum 1.0 at the grid {1, 10, 50, 100}:
        //   r1: improvements 11@1, 6@5, 2@20      -> 10, 5, 1, 1
        //   r2: 21@1, 5@3, stopped after 50       -> 20, 4, 4, 4 (keeps its final value)
        //   r3: first value only at 2: 9@2, 1.5@60 -> inf, 8, 8, 0.5
        let r1 = record(
            Some(1.0),
            &[(1, 11.0), (5, 6.0), (20, 2.0)],
            &[(1, 11.0), (10, 6.0), (100, 2.0)],
        );
        let r2 = record(
            Some(1.0),
            &[(1, 21.0), (3, 5.0)],
            &[(1, 21.0), (10, 5.0), (50, 5.0)],
        );
        let r3 = record(Some(1.0), &[(2, 9.0), (60, 1.5)], &[(10, 9.0), (100, 1.5)]);
        let s = convergence_series("GA", &[&r1, &r2, &r3]);
        assert_eq!(s.label, "GA");
        assert_eq!(s.evals, vec![1, 10, 50, 100]);
        // numpy: np.percentile([10, 20, inf], [25, 50, 75]) = [15, 20, inf]
        //        [4, 5, 8] -> [4.5, 5, 6.5]; [1, 4, 8] -> [2.5, 4, 6]; [.5, 1, 4] -> [.75, 1, 2.5]
        assert_eq!(s.median, vec![20.0, 5.0, 4.0, 1.0]);
        assert_eq!(s.q1, vec![15.0, 4.5, 2.5, 0.75]);
        assert_eq!(s.q3, vec![f64::INFINITY, 6.5, 6.0, 2.5]);

        // Without an optimum, raw values; two infinite neighbours give inf, not NaN.
        let r4 = record(None, &[(5, 3.0)], &[(1, f64::INFINITY), (10, 3.0)]);
        let s = convergence_series("x", &[&r4, &r4, &r3]);
        assert_eq!(s.evals, vec![1, 10, 100]);
        assert_eq!(s.median, vec![f64::INFINITY, 3.0, 3.0]);
        // r3 keeps its optimum: at 100 the values are [0.5, 3, 3].
        assert_eq!(s.q1, vec![f64::INFINITY, 3.0, 1.75]);
        assert!(convergence_series("e", &[]).evals.is_empty());
    }

    #[test]
    fn convergence_writes_svg_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let series = demo_series();
        convergence(
            &dir.path().join("conv"),
            "Sphere d=10: convergence",
            &series,
            "best-so-far error to optimum",
            true,
        )
        .unwrap();
        only_outputs(dir.path(), "conv");
        let f = files(dir.path(), "conv");
        check_common(
            &f,
            "Sphere d=10: convergence",
            &["GA", "PSO", "random search"],
        );
        for i in 0..series.len() {
            let c = hex(color(i));
            // The median line in the series' style; one band.
            check_styled(&f.svg, i, true);
            assert_eq!(
                count(&f.svg, "polygon opacity=\"0.2\"", "fill", &c),
                1,
                "band of {c}"
            );
        }
        // PSO reaches an error of exactly 0: drawn at the floor, and the figure says so.
        assert_eq!(texts(&f.svg, "y values ≤ 0 drawn at 10⁻⁷"), 1, "{}", f.svg);
        assert!(f.svg.contains("10⁻⁷") || f.svg.contains("10⁻⁶"));

        let bad = ConvergenceSeries {
            q1: vec![],
            ..series[0].clone()
        };
        assert!(matches!(
            convergence(&dir.path().join("bad"), "t", &[bad], "y", false),
            Err(Error::Input(_))
        ));
        // Linear y works too.
        convergence(
            &dir.path().join("lin"),
            "linear",
            &series[..1],
            "error",
            false,
        )
        .unwrap();
    }
}
