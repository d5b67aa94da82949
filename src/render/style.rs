//! How series are told apart: series `i` gets colour `i`, dash pattern `i` and marker `i`,
//! so a figure stays readable printed in greyscale or seen with a colour-vision deficiency.
//!
//! The colours are Okabe-Ito's without its yellow (faint on white), then three of Paul Tol's
//! "muted" set. Series sharing a dash pattern (`i` and `i + 5`) differ in grey level by at
//! least [`MIN_GREY_STEP`] and always in marker; the unit tests check both for ten series.
//! Dashes and markers are drawn as plain paths and polygons, the same on the SVG and the
//! PNG canvas (plotters' SVG backend has no dash attribute).

use super::canvas::Canvas;
use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters_backend::{BackendCoord, DrawingErrorKind};

/// Colour of series `i % 10`.
pub const PALETTE: [RGBColor; 10] = [
    RGBColor(0x00, 0x00, 0x00), // black
    RGBColor(0xE6, 0x9F, 0x00), // orange
    RGBColor(0x56, 0xB4, 0xE9), // sky blue
    RGBColor(0x00, 0x9E, 0x73), // bluish green
    RGBColor(0x00, 0x72, 0xB2), // blue
    RGBColor(0xCC, 0x79, 0xA7), // reddish purple
    RGBColor(0xD5, 0x5E, 0x00), // vermillion
    RGBColor(0x88, 0x22, 0x55), // Tol wine
    RGBColor(0x33, 0x22, 0x88), // Tol indigo
    RGBColor(0xCC, 0x66, 0x77), // Tol rose
];

/// Dash patterns (on, off, ... in logical pixels; empty: solid) of series `i % 5`: solid,
/// dashed, dotted, dash-dot, long dash.
pub(super) const DASHES: [&[f64]; 5] = [
    &[],
    &[7.0, 4.0],
    &[2.0, 3.0],
    &[9.0, 3.0, 2.0, 3.0],
    &[16.0, 5.0],
];

/// Least difference in grey level (0-255, Rec. 601 luma) between two of ten series that
/// share a dash pattern.
pub const MIN_GREY_STEP: f64 = 40.0;

/// Marker shapes, series `i % 10` gets `MARKERS[i % 10]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    TriangleUp,
    Diamond,
    TriangleDown,
    OpenCircle,
    OpenSquare,
    Cross,
    Plus,
    OpenTriangle,
}

pub(super) const MARKERS: [Marker; 10] = [
    Marker::Circle,
    Marker::Square,
    Marker::TriangleUp,
    Marker::Diamond,
    Marker::TriangleDown,
    Marker::OpenCircle,
    Marker::OpenSquare,
    Marker::Cross,
    Marker::Plus,
    Marker::OpenTriangle,
];

/// Colour, dash pattern (index into the dash list) and marker of one series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesStyle {
    pub color: RGBColor,
    pub dash: usize,
    pub marker: Marker,
}

/// The style of series `i`.
pub fn series_style(i: usize) -> SeriesStyle {
    SeriesStyle {
        color: PALETTE[i % PALETTE.len()],
        dash: i % DASHES.len(),
        marker: MARKERS[i % MARKERS.len()],
    }
}

/// Colour of series `i`.
pub fn color(i: usize) -> RGBColor {
    series_style(i).color
}

/// Grey level (Rec. 601 luma, 0-255) of a colour printed in greyscale.
pub fn grey(c: RGBColor) -> f64 {
    0.299 * f64::from(c.0) + 0.587 * f64::from(c.1) + 0.114 * f64::from(c.2)
}

/// The runs of `pts` (backend pixels) that `pattern` (on, off, ... in backend pixels) draws,
/// measured along the path; the whole path when the pattern is empty.
pub(super) fn dash_runs(pts: &[(f64, f64)], pattern: &[f64]) -> Vec<Vec<(f64, f64)>> {
    if pattern.is_empty() || pattern.iter().any(|&d| d <= 0.0) {
        return vec![pts.to_vec()];
    }
    let mut out = Vec::new();
    let (mut k, mut left) = (0, pattern[0]);
    let mut run: Vec<(f64, f64)> = pts.first().copied().into_iter().collect();
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
        let mut at = 0.0;
        while len - at > left {
            at += left;
            let f = at / len;
            let p = (a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1));
            if k % 2 == 0 {
                run.push(p);
                out.push(std::mem::take(&mut run));
            } else {
                run = vec![p];
            }
            k = (k + 1) % pattern.len();
            left = pattern[k];
        }
        left -= len - at;
        if k % 2 == 0 {
            run.push(b);
        }
    }
    out.push(run);
    out.retain(|r| r.len() >= 2);
    out
}

/// A polyline in a series' colour, width and dash pattern, with its markers on top, drawn
/// the same on both canvases.
/// The SVG gets one polyline per dash. On a bitmap plotters fills a wide line's whole
/// outline as one even-odd polygon with mitred corners: holes where the line overlaps
/// itself (a retraced loop, a min/max envelope's zigzag) and spikes at sharp turns. So
/// there each segment is its own quad, with round joins.
pub(super) struct Line<C> {
    pub(super) points: Vec<C>,
    pub(super) color: RGBColor,
    /// Width in backend pixels.
    pub(super) width: u32,
    /// On, off, ... in backend pixels; empty: solid.
    pub(super) dash: Vec<f64>,
    pub(super) canvas: Canvas,
    pub(super) marks: Vec<MarkerAt<C>>,
}

impl<'a, C: 'a> PointCollection<'a, C> for &'a Line<C> {
    type Point = &'a C;
    type IntoIter = Vec<&'a C>;
    fn point_iter(self) -> Vec<&'a C> {
        self.points
            .iter()
            .chain(self.marks.iter().map(|m| &m.at))
            .collect()
    }
}

impl<C, DB: DrawingBackend> Drawable<DB> for Line<C> {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut points: I,
        backend: &mut DB,
        dim: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        let style = self.color.stroke_width(self.width);
        // Points on the same pixel as the one before add nothing.
        let mut px: Vec<BackendCoord> = Vec::new();
        for p in points.by_ref().take(self.points.len()) {
            if px.last() != Some(&p) {
                px.push(p);
            }
        }
        let runs = if self.dash.is_empty() {
            vec![px]
        } else {
            let f: Vec<(f64, f64)> = px
                .iter()
                .map(|&(x, y)| (f64::from(x), f64::from(y)))
                .collect();
            dash_runs(&f, &self.dash)
                .into_iter()
                .map(|r| {
                    let mut v: Vec<BackendCoord> = Vec::with_capacity(r.len());
                    for (x, y) in r {
                        let p = (x.round() as i32, y.round() as i32);
                        if v.last() != Some(&p) {
                            v.push(p);
                        }
                    }
                    v
                })
                .collect()
        };
        for run in runs {
            if run.len() < 2 {
                continue;
            }
            if self.canvas == Canvas::Vector || self.width <= 1 {
                backend.draw_path(run, &style)?;
                continue;
            }
            for w in run.windows(2) {
                backend.draw_path([w[0], w[1]], &style)?;
            }
            let r = self.width / 2;
            for &p in &run[1..run.len() - 1] {
                backend.draw_circle(p, r, &self.color.filled(), true)?;
            }
        }
        for (m, p) in self.marks.iter().zip(points) {
            m.draw(std::iter::once(p), backend, dim)?;
        }
        Ok(())
    }
}

/// A marker of `radius` backend pixels at one point.
pub(super) struct MarkerAt<C> {
    pub(super) at: C,
    pub(super) marker: Marker,
    pub(super) color: RGBColor,
    pub(super) radius: f64,
}

impl<'a, C: 'a> PointCollection<'a, C> for &'a MarkerAt<C> {
    type Point = &'a C;
    type IntoIter = std::iter::Once<&'a C>;
    fn point_iter(self) -> Self::IntoIter {
        std::iter::once(&self.at)
    }
}

/// Regular polygon of `n` corners, radius `r`, the first at angle `start` (radians,
/// counter-clockwise from +x; y grows downwards on screen).
fn regular(n: usize, r: f64, start: f64) -> Vec<(f64, f64)> {
    (0..n)
        .map(|k| {
            let a = start + std::f64::consts::TAU * k as f64 / n as f64;
            (r * a.cos(), -r * a.sin())
        })
        .collect()
}

/// A bar from `-half` to `half` along angle `a`, `t` thick, as a polygon.
fn bar(half: f64, t: f64, a: f64) -> Vec<(f64, f64)> {
    let (c, s) = (a.cos(), -a.sin());
    let (nx, ny) = (-s * t / 2.0, c * t / 2.0);
    vec![
        (-half * c + nx, -half * s + ny),
        (half * c + nx, half * s + ny),
        (half * c - nx, half * s - ny),
        (-half * c - nx, -half * s - ny),
    ]
}

impl<C, DB: DrawingBackend> Drawable<DB> for MarkerAt<C> {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut points: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
        let Some((x, y)) = points.next() else {
            return Ok(());
        };
        let r = self.radius;
        let t = (r / 2.5).max(1.0);
        let at = |poly: Vec<(f64, f64)>| -> Vec<BackendCoord> {
            poly.into_iter()
                .map(|(dx, dy)| (x + dx.round() as i32, y + dy.round() as i32))
                .collect()
        };
        let fill = self.color.filled();
        let white = WHITE.filled();
        let (shape, open) = match self.marker {
            Marker::Circle | Marker::OpenCircle => {
                backend.draw_circle((x, y), r.round() as u32, &fill, true)?;
                if self.marker == Marker::OpenCircle {
                    backend.draw_circle((x, y), (r - t).round().max(1.0) as u32, &white, true)?;
                }
                return Ok(());
            }
            Marker::Cross | Marker::Plus => {
                let a = if self.marker == Marker::Cross {
                    FRAC_PI_4
                } else {
                    0.0
                };
                let half = r * 1.15;
                backend.fill_polygon(at(bar(half, t, a)), &fill)?;
                backend.fill_polygon(at(bar(half, t, a + FRAC_PI_2)), &fill)?;
                return Ok(());
            }
            Marker::Square => ((4, r * 1.25, FRAC_PI_4), false),
            Marker::OpenSquare => ((4, r * 1.25, FRAC_PI_4), true),
            Marker::Diamond => ((4, r * 1.3, 0.0), false),
            Marker::TriangleUp => ((3, r * 1.3, FRAC_PI_2), false),
            Marker::OpenTriangle => ((3, r * 1.35, FRAC_PI_2), true),
            Marker::TriangleDown => ((3, r * 1.3, -FRAC_PI_2), false),
        };
        let (n, outer, start) = shape;
        backend.fill_polygon(at(regular(n, outer, start)), &fill)?;
        if open {
            // The inner outline sits `t` inside the outer one: its inradius is `t` less.
            let inradius = outer * (std::f64::consts::PI / n as f64).cos();
            let k = ((inradius - t) / inradius).max(0.0);
            backend.fill_polygon(at(regular(n, outer * k, start)), &white)?;
        }
        Ok(())
    }
}

/// Points every `spacing` along `pts` (arc length in the metric `len`), the first
/// `phase * spacing` from the start.
pub(super) fn along<P: Copy>(
    pts: &[P],
    len: impl Fn(P, P) -> f64,
    lerp: impl Fn(P, P, f64) -> P,
    spacing: f64,
    phase: f64,
) -> Vec<P> {
    let mut out = Vec::new();
    if spacing <= 0.0 {
        return out;
    }
    let mut next = phase.rem_euclid(1.0) * spacing;
    let mut done = 0.0;
    for w in pts.windows(2) {
        let l = len(w[0], w[1]);
        while l > 0.0 && next <= done + l {
            out.push(lerp(w[0], w[1], (next - done) / l));
            next += spacing;
        }
        done += l;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ten_series_stay_apart_in_colour_dash_marker_and_grey() {
        let n = 10;
        for i in 0..n {
            for j in i + 1..n {
                let (a, b) = (series_style(i), series_style(j));
                assert_ne!(a.color, b.color, "colours of {i} and {j}");
                assert_ne!(a.marker, b.marker, "markers of {i} and {j}");
                let grey_apart = (grey(a.color) - grey(b.color)).abs() >= MIN_GREY_STEP;
                assert!(
                    a.dash != b.dash || grey_apart,
                    "series {i} and {j}: same dash, greys {} and {}",
                    grey(a.color),
                    grey(b.color)
                );
            }
        }
        // No faint colour: every series darker than Okabe-Ito's yellow (grey 219).
        assert!(PALETTE.iter().all(|&c| grey(c) < 175.0));
        assert_eq!(series_style(n), series_style(0));
    }

    #[test]
    fn dashes_follow_the_pattern_along_the_path() {
        // 0..30 along x then 30 down: dashes of 7 on, 4 off.
        let pts = [(0.0, 0.0), (30.0, 0.0), (30.0, 30.0)];
        let runs = dash_runs(&pts, &[7.0, 4.0]);
        let length = |r: &Vec<(f64, f64)>| -> f64 {
            r.windows(2)
                .map(|w| ((w[1].0 - w[0].0).powi(2) + (w[1].1 - w[0].1).powi(2)).sqrt())
                .sum()
        };
        // 60 px: dashes start at 0, 11, 22, 33, 44, 55 (the last cut at 60).
        assert_eq!(runs.len(), 6);
        for r in &runs[..5] {
            assert!((length(r) - 7.0).abs() < 1e-9, "{r:?}");
        }
        assert!((length(&runs[5]) - 5.0).abs() < 1e-9);
        // The dash across the corner keeps the corner.
        assert_eq!(runs[2], vec![(22.0, 0.0), (29.0, 0.0)]);
        assert_eq!(runs[3], vec![(30.0, 3.0), (30.0, 10.0)]);
        let corner = dash_runs(&[(0.0, 0.0), (5.0, 0.0), (5.0, 5.0)], &[8.0, 1.0]);
        assert_eq!(corner[0], vec![(0.0, 0.0), (5.0, 0.0), (5.0, 3.0)]);
        // Solid: the path as it is.
        assert_eq!(dash_runs(&pts, &[]), vec![pts.to_vec()]);
    }

    #[test]
    fn marks_are_evenly_spaced_along_the_path() {
        let pts = [0.0, 10.0, 10.0, 25.0];
        let m = along(
            &pts,
            |a: f64, b| (b - a).abs(),
            |a, b, f| a + f * (b - a),
            4.0,
            0.5,
        );
        assert_eq!(m, vec![2.0, 6.0, 10.0, 14.0, 18.0, 22.0]);
        assert!(along(&pts, |a: f64, b| (b - a).abs(), |a, _, _| a, 0.0, 0.0).is_empty());
    }
}
