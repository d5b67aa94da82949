//! Hysteresis loops: measured and modelled output against the input.

use super::axes::Axis;
use super::canvas::{DrawResult, Figure, Scale, render};
use super::font;
use super::layout::{
    Pen, TICK_LINE, above_footnote, build, footnote, ink_all, line_series, mesh, side_areas,
    titled, x_label_area,
};
use super::legend::{Corner, legend, legend_headroom};
use super::measured::{check_lengths, nonfinite_note, output_series};
use crate::base::error::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Most points drawn per series in the input-output plane (see [`loops`]).
pub(super) const MAX_LOOP_POINTS: usize = 5000;

/// Every `step`-th sample pair from the first, `step` the smallest that keeps at most
/// `cap`, plus the last so the path ends where the record does; pairs with a non-finite
/// value are skipped. Returns the points and `step`.
pub(super) fn stride(x: &[f64], y: &[f64], cap: usize) -> (Vec<(f64, f64)>, usize) {
    let n = x.len().min(y.len());
    let step = n.div_ceil(cap.max(1)).max(1);
    let last = (n > 0 && !(n - 1).is_multiple_of(step)).then(|| n - 1);
    let pts = (0..n)
        .step_by(step)
        .chain(last)
        .map(|k| (x[k], y[k]))
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .collect();
    (pts, step)
}

struct Loops<'a> {
    title: &'a str,
    u: &'a [f64],
    measured: (&'a str, &'a [f64]),
    models: &'a [(String, Vec<f64>)],
    u_label: &'a str,
    y_label: &'a str,
}

impl Figure for Loops<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: Scale) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let series = output_series(self.measured, self.models);
        let labels: Vec<&str> = series.iter().map(|(l, _)| *l).collect();
        let mut step = 1;
        let lines: Vec<Vec<(f64, f64)>> = series
            .iter()
            .map(|(_, v)| {
                let (pts, k) = stride(self.u, v, MAX_LOOP_POINTS);
                step = k;
                pts
            })
            .collect();
        let note: Vec<String> = (step > 1)
            .then(|| format!("1 in {step} samples drawn"))
            .into_iter()
            .chain(nonfinite_note(self.u, &series))
            .collect();
        // Axes fit what is drawn: a sample the stride skips would only leave empty space.
        let drawn_values =
            |f: fn(&(f64, f64)) -> f64| -> Vec<f64> { lines.iter().flatten().map(f).collect() };
        let x = Axis::fit(false, &drawn_values(|p| p.0), 0.04, 8);
        let mut y = Axis::fit(false, &drawn_values(|p| p.1), 0.04, 7);

        let (y_area, right) = side_areas(root, s, &x, &y)?;
        let body = above_footnote(titled(root, s, self.title, right)?, s, &note);
        let x_area = x_label_area(s, TICK_LINE);
        let mut chart = build(&body, &x, &y, x_area, y_area)?;
        if let Some(roomy) =
            legend_headroom(&chart, s, &labels, &ink_all(&chart, s, &lines), &y, 7)?
        {
            y = roomy;
            let y_area = y_area.max(side_areas(root, s, &x, &y)?.0);
            chart = build(&body, &x, &y, x_area, y_area)?;
        }
        let drawn = ink_all(&chart, s, &lines);
        mesh(&mut chart, s, (&x, Some(self.u_label)), (&y, self.y_label))?;
        for (i, (line, label)) in lines.into_iter().zip(&labels).enumerate() {
            line_series(&mut chart, s, line, Pen::output(i), Some(label))?;
        }
        use Corner::*;
        legend(
            &mut chart,
            s,
            &labels,
            &drawn,
            [UpperLeft, LowerRight, UpperRight, LowerLeft],
        )?;
        footnote(root, s, &note)
    }
}

/// Hysteresis loops in the input-output plane (the dissertation's Fig. 3.6): the measured
/// output against the input `u` as a wide black line and model `i`'s output against `u` in
/// the colour and dash pattern of series `i + 1` ([`series_style`](super::series_style)),
/// with a legend: a model that fits lets the measured line show between its dashes.
///
/// Long records are thinned to every k-th sample, k the smallest that leaves at most 5000
/// points per line (noted in a footnote when k > 1); the axes fit what is drawn. Not a
/// min/max envelope as in [`timeseries_with_error`](super::timeseries_with_error): along `u` the path goes back and
/// forth, so per-column extremes would join points of different branches; a stride keeps
/// the path's order and, for the smooth, densely sampled records loops come from, its
/// shape (the time-series figure is the one that shows every spike). Samples with a
/// non-finite input or output are skipped and counted in a footnote. `measured` and every
/// model must have the length of `u`.
pub fn loops(
    path_stem: &Path,
    title: &str,
    u: &[f64],
    measured: (&str, &[f64]),
    models: &[(String, Vec<f64>)],
    u_label: &str,
    y_label: &str,
) -> Result<()> {
    font::register()?;
    check_lengths("u", u.len(), measured, models)?;
    render(
        path_stem,
        &Loops {
            title,
            u,
            measured,
            models,
            u_label,
            y_label,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::color;
    use crate::render::measured::MEASURED;
    use crate::render::test_util::*;

    #[test]
    fn loops_writes_svg_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let r = piezo(2000, 0.02);
        let title = "Piezo actuator: hysteresis loops";
        loops(
            &dir.path().join("loops"),
            title,
            &r.u,
            (MEASURED, &r.measured),
            &r.models,
            "input voltage u [V]",
            "displacement y [µm]",
        )
        .unwrap();
        only_outputs(dir.path(), "loops");
        let f = files(dir.path(), "loops");
        check_common(
            &f,
            title,
            &[
                MEASURED,
                "Prandtl-Ishlinskii",
                "Bouc-Wen",
                "input voltage u [V]",
                "displacement y [µm]",
            ],
        );
        // Every output in its style: the measured one solid, the models dashed; nothing
        // thinned, so no footnote.
        for i in 0..=r.models.len() {
            check_styled(&f.svg, i, false);
        }
        assert_eq!(
            polylines(&f.svg, color(0)).len(),
            2,
            "measured: line and swatch"
        );
        assert!(!f.svg.contains("samples drawn"));
    }

    #[test]
    fn stride_caps_points_and_keeps_the_ends() {
        let x: Vec<f64> = (0..150_000).map(f64::from).collect();
        let (pts, step) = stride(&x, &x, MAX_LOOP_POINTS);
        assert_eq!(step, 30);
        assert!(pts.len() <= MAX_LOOP_POINTS + 1);
        assert_eq!(pts[0], (0.0, 0.0));
        assert_eq!(pts.last(), Some(&(149_999.0, 149_999.0)));
        let (pts, step) = stride(&[1.0, f64::NAN, 3.0], &[1.0, 2.0, 3.0], 10);
        assert_eq!((pts, step), (vec![(1.0, 1.0), (3.0, 3.0)], 1));
        assert_eq!(stride(&[], &[], 10), (vec![], 1));
    }
}
