//! Measured and modelled output over time, with the models' errors in a panel under it.

use super::axes::Axis;
use super::canvas::{DrawResult, Figure, Scale, render};
use super::font;
use super::layout::{
    Chart, Pen, TICK_LINE, above_footnote, build, footnote, ink_all, line_series, mesh, side_areas,
    titled, x_label_area,
};
use super::legend::{Corner, legend, legend_headroom};
use super::measured::{check_lengths, nonfinite_note, output_series};
use crate::base::error::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Space between the two panels of [`timeseries_with_error`], logical pixels: the upper
/// panel's tick marks and room for y tick labels at both panels' facing edges.
const PANEL_GAP: u32 = 18;

/// Min/max envelope of a time series, for drawing: `x` is cut into `columns` equal slices
/// of `[lo, hi]` (one per pixel column), and of each run of consecutive samples in one slice
/// only the lowest and the highest are kept, in time order (once if they are the same
/// sample). A line through them covers, to within a pixel, what a line through every
/// sample would, so a one-sample spike still shows; yet it has at most 2 points a column
/// however long the record. `x` should increase (otherwise it only thins less). Samples
/// with a non-finite `x` or `y` are skipped.
fn envelope(x: &[f64], y: &[f64], (lo, hi): (f64, f64), columns: usize) -> Vec<(f64, f64)> {
    type Sample = (usize, f64, f64);
    let cols = columns.max(1);
    let width = (hi - lo) / cols as f64;
    let column = |v: f64| {
        if width > 0.0 {
            ((v - lo) / width).floor().clamp(0.0, (cols - 1) as f64) as usize
        } else {
            0
        }
    };
    let flush = |out: &mut Vec<(f64, f64)>, (min, max): (Sample, Sample)| {
        let (a, b) = if min.0 <= max.0 {
            (min, max)
        } else {
            (max, min)
        };
        out.push((a.1, a.2));
        if b.0 != a.0 {
            out.push((b.1, b.2));
        }
    };
    let mut out = Vec::with_capacity((2 * cols).min(x.len()));
    // The current run: its column, its lowest and its highest sample.
    let mut run: Option<(usize, Sample, Sample)> = None;
    for (k, (&xv, &yv)) in x.iter().zip(y).enumerate() {
        if !(xv.is_finite() && yv.is_finite()) {
            continue;
        }
        let c = column(xv);
        match &mut run {
            Some((rc, min, max)) if *rc == c => {
                if yv < min.2 {
                    *min = (k, xv, yv);
                }
                if yv > max.2 {
                    *max = (k, xv, yv);
                }
            }
            _ => {
                if let Some((_, min, max)) = run {
                    flush(&mut out, (min, max));
                }
                run = Some((c, (k, xv, yv), (k, xv, yv)));
            }
        }
    }
    if let Some((_, min, max)) = run {
        flush(&mut out, (min, max));
    }
    out
}

/// "error [mm]" for "displacement [mm]": "error" and the unit in trailing brackets, if any.
fn error_label(y_label: &str) -> String {
    let l = y_label.trim_end();
    match l.strip_suffix(']').and_then(|r| r.rfind('[')) {
        Some(i) => format!("error {}", &l[i..]),
        None => "error".into(),
    }
}

/// Width of the plot in logical pixels: the number of envelope columns.
fn plot_columns<DB: DrawingBackend>(chart: &Chart<'_, DB>, s: Scale) -> usize {
    let (xr, _) = chart.plotting_area().get_pixel_range();
    ((xr.end - xr.start).max(1) as u32).div_ceil(s.0) as usize
}

struct TimeSeries<'a> {
    title: &'a str,
    t: &'a [f64],
    measured: (&'a str, &'a [f64]),
    models: &'a [(String, Vec<f64>)],
    t_label: &'a str,
    y_label: &'a str,
}

impl Figure for TimeSeries<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: Scale) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let series = output_series(self.measured, self.models);
        let errors: Vec<Vec<f64>> = self
            .models
            .iter()
            .map(|(_, m)| m.iter().zip(self.measured.1).map(|(a, b)| a - b).collect())
            .collect();
        let all: Vec<f64> = series.iter().flat_map(|(_, v)| v.iter().copied()).collect();
        let all_e: Vec<f64> = errors.iter().flatten().copied().chain([0.0]).collect();
        let x = Axis::fit(false, self.t, 0.0, 8);
        let mut y = Axis::fit(false, &all, 0.04, 6);
        let e = Axis::fit(false, &all_e, 0.08, 4);
        let labels: Vec<&str> = series.iter().map(|(l, _)| *l).collect();
        let note: Vec<String> = nonfinite_note(self.t, &series).into_iter().collect();

        // Upper panel about 2/3, lower 1/3 of the plot height; both with the same y label
        // area, so the plots line up.
        let (x_area, gap) = (x_label_area(s, TICK_LINE), s.u(PANEL_GAP));
        let (y_area, right) = side_areas(root, s, &x, &y)?;
        let mut y_area = y_area.max(side_areas(root, s, &x, &e)?.0);
        let body = above_footnote(titled(root, s, self.title, right)?, s, &note);
        let (_, h) = body.dim_in_pixel();
        let lower_plot = h.saturating_sub(gap + x_area) / 3;
        let (top, bottom) = body.split_vertically(h - lower_plot - x_area);

        let envelopes = |chart: &Chart<'_, DB>| -> Vec<Vec<(f64, f64)>> {
            let columns = plot_columns(chart, s);
            series
                .iter()
                .map(|(_, v)| envelope(self.t, v, (x.lo, x.hi), columns))
                .collect()
        };
        let mut upper = build(&top, &x, &y, gap, y_area)?;
        let mut lines = envelopes(&upper);
        if let Some(roomy) =
            legend_headroom(&upper, s, &labels, &ink_all(&upper, s, &lines), &y, 6)?
        {
            y = roomy;
            y_area = y_area.max(side_areas(root, s, &x, &y)?.0);
            upper = build(&top, &x, &y, gap, y_area)?;
            lines = envelopes(&upper);
        }
        let drawn = ink_all(&upper, s, &lines);
        mesh(&mut upper, s, (&x, None), (&y, self.y_label))?;
        for (i, (line, label)) in lines.into_iter().zip(&labels).enumerate() {
            line_series(&mut upper, s, line, Pen::output(i), Some(label))?;
        }
        use Corner::*;
        legend(
            &mut upper,
            s,
            &labels,
            &drawn,
            [UpperRight, UpperLeft, LowerRight, LowerLeft],
        )?;

        let mut lower = build(&bottom, &x, &e, x_area, y_area)?;
        mesh(
            &mut lower,
            s,
            (&x, Some(self.t_label)),
            (&e, &error_label(self.y_label)),
        )?;
        let columns = plot_columns(&lower, s);
        for (i, err) in errors.iter().enumerate() {
            let line = envelope(self.t, err, (x.lo, x.hi), columns);
            line_series(&mut lower, s, line, Pen::output(i + 1), None)?;
        }
        footnote(root, s, &note)
    }
}

/// Measured and modelled output over time with the models' errors under it (the layout
/// of the dissertation's Fig. 3.5): an upper panel, about 2/3 of the height, with the
/// measured output as a wide black line and model `i` in the colour and dash pattern of
/// series `i + 1` ([`series_style`](super::series_style)) and a legend; a
/// lower panel with each model's error e = model - measured in its style, on the same x
/// range, its y label "error" and the unit in brackets at the end of `y_label`, if any.
/// Only the lower panel has x tick labels.
///
/// Long records draw fast and keep their peaks: each line is reduced to the lowest and
/// highest sample of every pixel column (a min/max envelope), so at most two points per
/// column however long the record, and a one-sample spike still shows. Samples with a non-finite time or value are skipped and counted in
/// a footnote. `t` should increase; `measured` and every model must have its length.
pub fn timeseries_with_error(
    path_stem: &Path,
    title: &str,
    t: &[f64],
    measured: (&str, &[f64]),
    models: &[(String, Vec<f64>)],
    t_label: &str,
    y_label: &str,
) -> Result<()> {
    font::register()?;
    check_lengths("t", t.len(), measured, models)?;
    render(
        path_stem,
        &TimeSeries {
            title,
            t,
            measured,
            models,
            t_label,
            y_label,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::measured::MEASURED;
    use crate::render::test_util::*;
    use crate::render::{PALETTE, color};

    #[test]
    fn timeseries_with_error_writes_svg_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let r = piezo(2000, 0.02);
        let title = "Piezo actuator: output and model error";
        timeseries_with_error(
            &dir.path().join("ts"),
            title,
            &r.t,
            (MEASURED, &r.measured),
            &r.models,
            "time [s]",
            "displacement y [µm]",
        )
        .unwrap();
        only_outputs(dir.path(), "ts");
        let f = files(dir.path(), "ts");
        check_common(
            &f,
            title,
            &[
                MEASURED,
                "Prandtl-Ishlinskii",
                "Bouc-Wen",
                "time [s]",
                "displacement y [µm]",
                "error [µm]",
            ],
        );
        // x tick labels on the lower panel only; the upper panel's leave no empty texts.
        assert_eq!(texts(&f.svg, "1.75"), 1);
        assert_eq!(texts(&f.svg, ""), 0);
        // The measured output: its line and legend swatch. Every model: the same, plus its
        // error line in the lower panel, below everything drawn in black.
        let measured = polylines(&f.svg, color(0));
        assert_eq!(measured.len(), 2);
        let upper_bottom = measured.iter().flatten().map(|p| p.1).fold(0.0, f64::max);
        let in_lower = |i: usize| {
            polylines(&f.svg, color(i))
                .iter()
                .filter(|l| l.iter().all(|p| p.1 > upper_bottom))
                .count()
        };
        for i in 1..=r.models.len() {
            check_styled(&f.svg, i, false);
        }
        let error_series = (0..PALETTE.len()).filter(|&i| in_lower(i) > 0).count();
        assert_eq!(error_series, r.models.len());
        assert_eq!(in_lower(0), 0);
    }

    #[test]
    fn envelope_keeps_every_columns_extremes() {
        let n = 150_000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-4).collect();
        let mut y: Vec<f64> = (0..n)
            .map(|k| (k as f64 * 1e-3).sin() + 0.1 * (((k * 7919) % 101) as f64 / 50.0 - 1.0))
            .collect();
        y[12_345] = 7.0;
        y[98_765] = -9.0;
        y[500] = f64::NAN;
        let cols = 580;
        let span = (0.0, t[n - 1]);
        let env = envelope(&t, &y, span, cols);
        assert!(env.len() <= 2 * cols, "{}", env.len());
        assert!(env.contains(&(t[12_345], 7.0)) && env.contains(&(t[98_765], -9.0)));
        assert!(env.iter().all(|p| p.1.is_finite()));
        assert!(env.windows(2).all(|w| w[0].0 <= w[1].0), "time order");
        // Brute force: every column's lowest and highest sample are kept.
        let width = span.1 / cols as f64;
        let mut ext = vec![(f64::INFINITY, f64::NEG_INFINITY); cols];
        for (&tk, &yk) in t.iter().zip(&y).filter(|(_, y)| y.is_finite()) {
            let c = ((tk / width) as usize).min(cols - 1);
            ext[c] = (ext[c].0.min(yk), ext[c].1.max(yk));
        }
        for (c, &(lo, hi)) in ext.iter().enumerate() {
            let of_c = |p: &&(f64, f64)| ((p.0 / width) as usize).min(cols - 1) == c;
            let ys: Vec<f64> = env.iter().filter(of_c).map(|p| p.1).collect();
            assert!(ys.contains(&lo) && ys.contains(&hi), "column {c}");
        }
        // Short records stay whole, minus non-finite samples; within a column the
        // extremes keep their time order.
        assert_eq!(
            envelope(&[0.0, 1.0, 2.0], &[1.0, f64::NAN, 3.0], (0.0, 2.0), 100),
            vec![(0.0, 1.0), (2.0, 3.0)]
        );
        assert_eq!(
            envelope(&[0.0, 0.1, 0.2, 0.3], &[0.0, 5.0, -5.0, 1.0], (0.0, 1.0), 1),
            vec![(0.1, 5.0), (0.2, -5.0)]
        );
        assert!(envelope(&[], &[], (0.0, 1.0), 10).is_empty());
    }

    #[test]
    fn error_label_takes_the_unit() {
        assert_eq!(error_label("displacement y [µm]"), "error [µm]");
        assert_eq!(error_label("y [mm] "), "error [mm]");
        assert_eq!(error_label("normalised output"), "error");
        assert_eq!(error_label("y [mm] at the tip"), "error");
    }
}
