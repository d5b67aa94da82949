//! Labelled (x, y) lines on linear or log axes: residuals, binned means, spectra; with a
//! shaded x range, vertical rules and series drawn as points where a figure needs them.

use super::axes::Axis;
use super::canvas::{DrawResult, Figure, Scale, render};
use super::font;
use super::layout::SWATCH;
use super::layout::{
    Pen, TICK_LINE, build, clamp_note, ink_all, line_series, mesh, point_series, side_areas,
    titled, x_label_area,
};
use super::legend::{Corner, legend, legend_headroom};
use super::loops::{MAX_LOOP_POINTS, stride};
use super::style::{Line, series_style};
use crate::base::error::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// What a [`lines_with`] figure draws besides its lines: a shaded x range (say, where a
/// record is fitted and not scored), vertical rules at given x (say, forecast origins),
/// each with its own legend entry, and series drawn as markers at their points only.
#[derive(Clone, Debug, Default)]
pub struct Decor {
    /// Shaded x ranges `(label, [(from, to), ...])`, the whole plot height, in light grey.
    pub band: Option<(String, Vec<(f64, f64)>)>,
    /// Vertical rules `(label, xs)` across the data's y range, in dark grey, dashed.
    pub rules: Option<(String, Vec<f64>)>,
    /// Indices of series drawn as markers at their points, without a line.
    pub points: Vec<usize>,
    /// Points the axes must show though nothing is drawn there (say, the origin).
    pub include: Vec<(f64, f64)>,
    /// The style of series `i` is [`series_style`]`(styles[i])` where given (a fit drawn
    /// in the colour of its points), else `i`'s.
    pub styles: Vec<usize>,
}

struct Lines<'a> {
    title: &'a str,
    series: &'a [(String, Vec<(f64, f64)>)],
    x_label: &'a str,
    y_label: &'a str,
    log: (bool, bool),
    decor: &'a Decor,
}

/// Grey of the shaded band and of the rules.
const BAND: RGBColor = RGBColor(0xDD, 0xDD, 0xDD);
const RULE: RGBColor = RGBColor(0x55, 0x55, 0x55);

impl Figure for Lines<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: Scale) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let d = self.decor;
        let band_x = d
            .band
            .iter()
            .flat_map(|b| b.1.iter().flat_map(|r| [r.0, r.1]));
        let rule_x = d.rules.iter().flat_map(|r| r.1.iter().copied());
        let xs: Vec<f64> = self
            .series
            .iter()
            .flat_map(|(_, p)| p.iter().map(|q| q.0))
            .chain(band_x)
            .chain(rule_x)
            .chain(d.include.iter().map(|p| p.0))
            .collect();
        let ys: Vec<f64> = self
            .series
            .iter()
            .flat_map(|(_, p)| p.iter().map(|q| q.1))
            .collect();
        let y_fit: Vec<f64> = ys
            .iter()
            .copied()
            .chain(d.include.iter().map(|p| p.1))
            .collect();
        let x = Axis::fit(self.log.0, &xs, 0.0, 8);
        let mut y = Axis::fit(self.log.1, &y_fit, 0.04, 7);
        // The data's y range (plot space), where the rules are drawn.
        let (y_lo, y_hi) = ys
            .iter()
            .filter_map(|&v| y.to_plot(v))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        // A long label is wrapped (at a `+`, a space or a comma) into legend rows of its
        // own, the rows after the first without a swatch.
        let wrapped: Vec<Vec<String>> = self.series.iter().map(|(l, _)| wrap(l)).collect();
        let mut labels: Vec<&str> = wrapped.iter().flatten().map(String::as_str).collect();
        labels.extend(d.band.iter().map(|b| b.0.as_str()));
        labels.extend(d.rules.iter().map(|r| r.0.as_str()));
        let to_plot = |pts: &[(f64, f64)], y: &Axis| -> Vec<(f64, f64)> {
            let (px, py): (Vec<f64>, Vec<f64>) = pts.iter().copied().unzip();
            stride(&px, &py, MAX_LOOP_POINTS)
                .0
                .into_iter()
                .filter_map(|(a, b)| Some((x.to_plot(a)?, y.to_plot(b)?)))
                .collect()
        };
        let plotted = |y: &Axis| -> Vec<Vec<(f64, f64)>> {
            self.series.iter().map(|(_, p)| to_plot(p, y)).collect()
        };
        // The legend goes where it hides no data: in a corner, or above the data.
        let (mut y_area, right) = side_areas(root, s, &x, &y)?;
        let body = titled(root, s, self.title, right)?;
        let x_area = x_label_area(s, TICK_LINE);
        let mut chart = build(&body, &x, &y, x_area, y_area)?;
        let mut lines = plotted(&y);
        if let Some(roomy) =
            legend_headroom(&chart, s, &labels, &ink_all(&chart, s, &lines), &y, 7)?
        {
            y = roomy;
            y_area = y_area.max(side_areas(root, s, &x, &y)?.0);
            chart = build(&body, &x, &y, x_area, y_area)?;
            lines = plotted(&y);
        }
        let drawn = ink_all(&chart, s, &lines);
        if let Some((_, ranges)) = &d.band {
            let shaded: Vec<Rectangle<(f64, f64)>> = ranges
                .iter()
                .filter_map(|&(a, b)| Some((x.to_plot(a)?, x.to_plot(b)?)))
                .map(|(a, b)| Rectangle::new([(a, y.lo), (b, y.hi)], BAND.filled()))
                .collect();
            chart.draw_series(shaded)?;
        }
        mesh(&mut chart, s, (&x, Some(self.x_label)), (&y, self.y_label))?;
        let n = self.series.len();
        for (i, (line, rows)) in lines.into_iter().zip(&wrapped).enumerate() {
            let label = rows.first().map(String::as_str);
            let st = d.styles.get(i).copied().unwrap_or(i);
            if d.points.contains(&i) {
                point_series(&mut chart, s, line, series_style(st), label)?;
            } else if d.points.is_empty() {
                line_series(&mut chart, s, line, Pen::marked(st, n), label)?;
            } else {
                // Beside points, a line without markers (which would read as points).
                let pen = Pen {
                    markers: None,
                    ..Pen::marked(st, n)
                };
                line_series(&mut chart, s, line, pen, label)?;
            }
            for row in rows.iter().skip(1) {
                chart
                    .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())?
                    .label(row.as_str())
                    .legend(|(px, py)| Rectangle::new([(px, py), (px, py)], WHITE.filled()));
            }
        }
        let sw = s.i(SWATCH);
        if let Some((label, _)) = &d.band {
            // An empty series for the band's legend entry: a filled swatch.
            chart
                .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())?
                .label(label.as_str())
                .legend(move |(px, py)| {
                    Rectangle::new([(px, py - s.i(6)), (px + sw, py + s.i(6))], BAND.filled())
                });
        }
        if let Some((label, at)) = &d.rules
            && y_lo.is_finite()
        {
            let dash = vec![6.0 * f64::from(s.0), 4.0 * f64::from(s.0)];
            let xs: Vec<f64> = at.iter().filter_map(|&v| x.to_plot(v)).collect();
            chart
                .draw_series(
                    xs.iter()
                        .map(|&px| rule(s, vec![(px, y_lo), (px, y_hi)], dash.clone())),
                )?
                .label(label.as_str())
                .legend(move |(px, py)| {
                    rule(
                        s,
                        vec![(px + sw / 2, py - s.i(8)), (px + sw / 2, py + s.i(8))],
                        vec![3.0 * f64::from(s.0), 2.0 * f64::from(s.0)],
                    )
                });
        }
        use Corner::*;
        legend(
            &mut chart,
            s,
            &labels,
            &drawn,
            [UpperRight, UpperLeft, LowerRight, LowerLeft],
        )?;
        clamp_note(root, s, &[("x", &x), ("y", &y)])
    }
}

/// Longest legend row, in characters: a row of the 14 px legend font this long fits the
/// plot's width with its swatch.
const LEGEND_ROW: usize = 52;

/// `label` in rows of at most [`LEGEND_ROW`] characters, broken after a `+`, a space or a
/// comma where possible (continuation rows indented).
fn wrap(label: &str) -> Vec<String> {
    let mut rows = Vec::new();
    let mut rest = label;
    while rest.chars().count() > LEGEND_ROW {
        let cut = rest
            .char_indices()
            .take_while(|&(i, _)| rest[..i].chars().count() < LEGEND_ROW)
            .filter(|&(_, c)| matches!(c, '+' | ' ' | ','))
            .map(|(i, c)| i + c.len_utf8())
            .last()
            .filter(|&i| i > LEGEND_ROW / 3)
            .unwrap_or_else(|| {
                rest.char_indices()
                    .nth(LEGEND_ROW)
                    .map_or(rest.len(), |(i, _)| i)
            });
        rows.push(rest[..cut].trim_end().to_string());
        rest = rest[cut..].trim_start();
    }
    rows.push(rest.to_string());
    for r in rows.iter_mut().skip(1) {
        r.insert_str(0, "   ");
    }
    rows
}

/// A vertical rule (or its legend swatch) in dark grey, `dash` in backend pixels.
fn rule<C>(s: Scale, points: Vec<C>, dash: Vec<f64>) -> Line<C> {
    Line {
        points,
        color: RULE,
        width: s.u(2),
        dash,
        canvas: s.1,
        marks: Vec::new(),
    }
}

/// Labelled (x, y) lines, series `i` in the colour, dash pattern and marker of
/// [`series_style`](super::series_style)`(i)`, with a legend in the corner where it hides
/// no data, or above the data (the y axis stretched) where every corner would;
/// either axis logarithmic. More than 5000 points per line are thinned by a stride (see
/// [`loops`](fn@super::loops)); non-finite points are skipped. For residuals over time, binned means and
/// spectra.
pub fn lines(
    path_stem: &Path,
    title: &str,
    series: &[(String, Vec<(f64, f64)>)],
    x_label: &str,
    y_label: &str,
    log: (bool, bool),
) -> Result<()> {
    lines_with(
        path_stem,
        title,
        series,
        x_label,
        y_label,
        log,
        &Decor::default(),
    )
}

/// [`lines`] with a shaded x range, vertical rules and series drawn as points
/// ([`Decor`]), each with its legend entry (the band's and the rules' after the series').
pub fn lines_with(
    path_stem: &Path,
    title: &str,
    series: &[(String, Vec<(f64, f64)>)],
    x_label: &str,
    y_label: &str,
    log: (bool, bool),
    decor: &Decor,
) -> Result<()> {
    font::register()?;
    render(
        path_stem,
        &Lines {
            title,
            series,
            x_label,
            y_label,
            log,
            decor,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_legend_labels_wrap_at_a_plus_and_short_ones_do_not() {
        assert_eq!(wrap("baseline (pi)"), vec!["baseline (pi)".to_string()]);
        let l = "bouc-wen+input-lag+asymmetry[direction]+rate-dependence[gain]+offset-drift[spline]: validation RMSE 0.484 um";
        let rows = wrap(l);
        assert!(rows.len() >= 2, "{rows:?}");
        assert!(
            rows.iter().all(|r| r.chars().count() <= LEGEND_ROW + 3),
            "{rows:?}"
        );
        assert!(rows[0].ends_with('+'), "{rows:?}");
        // Nothing is lost but the breaks' spaces and the continuation indent.
        let joined: String = rows.iter().map(|r| r.trim()).collect::<Vec<_>>().join(" ");
        assert_eq!(
            joined.replace("+ ", "+").replace(' ', ""),
            l.replace(' ', "")
        );
    }

    #[test]
    fn a_decorated_figure_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let pts: Vec<(f64, f64)> = (0..200)
            .map(|k| (k as f64, (k as f64 / 9.0).sin()))
            .collect();
        let decor = Decor {
            band: Some(("lead".into(), vec![(0.0, 40.0)])),
            rules: Some(("origins".into(), vec![40.0, 80.0, 120.0])),
            points: vec![1],
            include: vec![(0.0, -2.0)],
            styles: vec![0, 0],
        };
        let few: Vec<(f64, f64)> = pts.iter().step_by(20).copied().collect();
        lines_with(
            &dir.path().join("d"),
            "decorated",
            &[("line".into(), pts), ("points".into(), few)],
            "x",
            "y",
            (false, false),
            &decor,
        )
        .unwrap();
        let svg = std::fs::read_to_string(dir.path().join("d.svg")).unwrap();
        // Each legend entry is a text of its own (the band's and the rules' too).
        for label in ["lead", "origins", "points", "line"] {
            assert!(svg.lines().any(|l| l.trim() == label), "{label}");
        }
    }
}
