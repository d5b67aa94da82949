//! Labelled (x, y) lines on linear or log axes: residuals, binned means, spectra.

use super::axes::Axis;
use super::canvas::{DrawResult, Figure, Scale, render};
use super::font;
use super::layout::{Pen, TICK_LINE, clamp_note, frame, ink_all, line_series};
use super::legend::{Corner, legend};
use super::loops::{MAX_LOOP_POINTS, stride};
use crate::base::error::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

struct Lines<'a> {
    title: &'a str,
    series: &'a [(String, Vec<(f64, f64)>)],
    x_label: &'a str,
    y_label: &'a str,
    log: (bool, bool),
}

impl Figure for Lines<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: Scale) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let xs: Vec<f64> = self
            .series
            .iter()
            .flat_map(|(_, p)| p.iter().map(|q| q.0))
            .collect();
        let ys: Vec<f64> = self
            .series
            .iter()
            .flat_map(|(_, p)| p.iter().map(|q| q.1))
            .collect();
        let x = Axis::fit(self.log.0, &xs, 0.0, 8);
        let y = Axis::fit(self.log.1, &ys, 0.04, 7);
        let mut chart = frame(
            root,
            s,
            self.title,
            (&x, self.x_label),
            (&y, self.y_label),
            TICK_LINE,
        )?;
        let lines: Vec<Vec<(f64, f64)>> = self
            .series
            .iter()
            .map(|(_, pts)| {
                let (px, py): (Vec<f64>, Vec<f64>) = pts.iter().copied().unzip();
                stride(&px, &py, MAX_LOOP_POINTS)
                    .0
                    .into_iter()
                    .filter_map(|(a, b)| Some((x.to_plot(a)?, y.to_plot(b)?)))
                    .collect()
            })
            .collect();
        let drawn = ink_all(&chart, s, &lines);
        let labels: Vec<&str> = self.series.iter().map(|(l, _)| l.as_str()).collect();
        for (i, (line, label)) in lines.into_iter().zip(&labels).enumerate() {
            let pen = Pen::marked(i, labels.len());
            line_series(&mut chart, s, line, pen, Some(label))?;
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

/// Labelled (x, y) lines, series `i` in the colour, dash pattern and marker of
/// [`series_style`](super::series_style)`(i)`, with a legend;
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
    font::register()?;
    render(
        path_stem,
        &Lines {
            title,
            series,
            x_label,
            y_label,
            log,
        },
    )
}
