//! Paper figures: convergence curves, box plots of final values and runtime ECDFs; for a
//! fitted hysteresis model, its output and error over time and its loops in the
//! input-output plane.
//!
//! Data in, files out: the caller passes the series (built with [`convergence_series`] and
//! [`runtimes`] from trial records, or from anything else) and a path stem; every figure is
//! written as `<stem>.svg` and `<stem>.png`, both 640 x 480 (the SVG in the same logical
//! pixels), each atomically (temporary file in the same folder, then a rename). The folder
//! must exist.
//!
//! Every figure has a title, axis labels, a legend (for box plots the optimizer names under
//! the boxes) and the Okabe-Ito colour-blind-safe palette ([`PALETTE`]), series `i` in
//! colour `i`, so one optimizer keeps its colour across figures when the caller keeps the
//! order. Text is DejaVu Sans compiled into the binary (the `font` module): no system font,
//! fontconfig or freetype is needed. The PNG is drawn at 3x and averaged down, so lines and
//! text are anti-aliased.
//!
//! # Values a logarithmic axis cannot show
//!
//! On a log axis, values <= 0 (an error of exactly 0, say) are drawn at a floor: the
//! largest power of ten at most a tenth of the smallest positive finite value drawn on that
//! axis (so at least a decade below all real data), or [`LOG_FLOOR_NO_POSITIVE`] when there
//! is none. When that happens the figure says so in a footnote at its lower
//! left ("y values <= 0 drawn at 10⁻⁹"). NaN is never drawn. What +inf means depends on the
//! figure and is documented on each function.

use super::font::{self, FAMILY};
use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use crate::stats::quantile_sorted;
use plotters::chart::SeriesAnno;
use plotters::coord::Shift;
use plotters::coord::cartesian::Cartesian2d;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::element::MultiLineText;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::{Path, PathBuf};

/// Width of every figure in pixels (PNG) and logical pixels (SVG).
pub const WIDTH: u32 = 640;
/// Height of every figure in pixels (PNG) and logical pixels (SVG).
pub const HEIGHT: u32 = 480;
/// The PNG is rendered this many times larger, then box-filtered down (anti-aliasing).
const SUPERSAMPLE: u32 = 3;

/// Okabe-Ito colours in the order series get them: black, orange, sky blue, bluish green,
/// blue, vermillion, reddish purple, and yellow last (hard to see on white). Series 9 and
/// later reuse the colours from the start.
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0x00, 0x00, 0x00),
    RGBColor(0xE6, 0x9F, 0x00),
    RGBColor(0x56, 0xB4, 0xE9),
    RGBColor(0x00, 0x9E, 0x73),
    RGBColor(0x00, 0x72, 0xB2),
    RGBColor(0xD5, 0x5E, 0x00),
    RGBColor(0xCC, 0x79, 0xA7),
    RGBColor(0xF0, 0xE4, 0x42),
];

/// Floor for values <= 0 on a log axis that has no positive finite value at all.
pub const LOG_FLOOR_NO_POSITIVE: f64 = 1e-16;

/// Colour of series `i`.
pub fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Axes, ticks and frames: dark grey, so pure black stays a series colour.
const INK: RGBColor = RGBColor(0x33, 0x33, 0x33);
const TITLE_PX: f64 = 20.0;
const LABEL_PX: f64 = 16.0;
const TICK_PX: f64 = 14.0;
const LEGEND_PX: f64 = 14.0;
const NOTE_PX: f64 = 11.0;
const LINE_W: u32 = 2;
const TICK_LEN: i32 = 4;

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

// ---------------------------------------------------------------------------------------
// Data helpers

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

// ---------------------------------------------------------------------------------------
// Axes

/// One axis in plot space: values go through `log10` on a log axis, so both kinds of axis
/// are plain linear ranges to plotters and ticks are chosen here.
#[derive(Debug, Clone)]
struct Axis {
    log: bool,
    /// Plot-space range.
    lo: f64,
    hi: f64,
    /// Data value that values <= 0 are drawn at (log axes).
    floor: f64,
    /// Whether some value <= 0 was moved to the floor.
    clamped: bool,
    ticks: Vec<f64>,
    minor: Vec<f64>,
    /// Category names instead of numbers (box plots); tick labels are drawn by the figure.
    categorical: bool,
}

impl Axis {
    /// An axis showing `values` (NaN and +inf ignored), widened by `pad` of its span each
    /// side, with at most about `max_ticks` labelled ticks.
    fn fit(log: bool, values: &[f64], pad: f64, max_ticks: usize) -> Axis {
        let min_pos = values
            .iter()
            .copied()
            .filter(|v| v.is_finite() && *v > 0.0)
            .fold(f64::INFINITY, f64::min);
        let floor = if min_pos.is_finite() {
            10f64.powf((min_pos.log10() - 1.0 + 1e-9).floor())
        } else {
            LOG_FLOOR_NO_POSITIVE
        };
        let mut a = Axis {
            log,
            lo: 0.0,
            hi: 1.0,
            floor,
            clamped: log && values.iter().any(|&v| v <= 0.0),
            ticks: vec![],
            minor: vec![],
            categorical: false,
        };
        let (lo, hi) = values
            .iter()
            .filter_map(|&v| a.to_plot(v))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), t| {
                (l.min(t), h.max(t))
            });
        let (mut lo, mut hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
        if hi - lo < 1e-12 * lo.abs().max(1.0) {
            let d = if log { 0.5 } else { (lo.abs() * 0.1).max(0.5) };
            (lo, hi) = (lo - d, hi + d);
        }
        let span = hi - lo;
        (a.lo, a.hi) = (lo - pad * span, hi + pad * span);
        a.retick(max_ticks);
        a
    }

    /// Ticks for the current range.
    fn retick(&mut self, max_ticks: usize) {
        (self.ticks, self.minor) = if self.log {
            log_ticks(self.lo, self.hi, max_ticks)
        } else {
            linear_ticks(self.lo, self.hi, max_ticks)
        };
    }

    /// The axis stretched upwards so its current range fills only the lower `1 - frac` of
    /// the plot (room for a legend above the data).
    fn with_headroom(&self, frac: f64, max_ticks: usize) -> Axis {
        let mut a = self.clone();
        a.hi = a.lo + (a.hi - a.lo) / (1.0 - frac);
        a.retick(max_ticks);
        a
    }

    /// A fixed linear axis with given ticks.
    fn fixed(lo: f64, hi: f64, ticks: Vec<f64>, minor: Vec<f64>) -> Axis {
        Axis {
            log: false,
            lo,
            hi,
            floor: LOG_FLOOR_NO_POSITIVE,
            clamped: false,
            ticks,
            minor,
            categorical: false,
        }
    }

    /// Categories 1..=n, one per unit.
    fn categories(n: usize) -> Axis {
        let mut a = Axis::fixed(
            0.5,
            n as f64 + 0.5,
            (1..=n).map(|i| i as f64).collect(),
            vec![],
        );
        a.categorical = true;
        a
    }

    /// Plot-space position of a data value; None for NaN and for +inf (and -inf on a
    /// linear axis). On a log axis values <= 0 go to the floor.
    fn to_plot(&self, v: f64) -> Option<f64> {
        if self.log {
            if v.is_nan() || v == f64::INFINITY {
                None
            } else {
                Some(v.max(self.floor).log10())
            }
        } else {
            v.is_finite().then_some(v)
        }
    }

    /// Tick label of a plot-space position.
    fn label(&self, t: f64) -> String {
        if self.categorical {
            String::new()
        } else if self.log {
            if (t - t.round()).abs() < 1e-9 {
                pow10(t.round() as i32)
            } else {
                fmt_num(10f64.powf(t))
            }
        } else {
            fmt_num(t)
        }
    }

    fn spec(&self) -> AxisCoord {
        AxisCoord {
            lo: self.lo,
            hi: self.hi,
            ticks: self.ticks.clone(),
            minor: self.minor.clone(),
        }
    }
}

/// An [`Axis`] as a plotters coordinate: linear in plot space, with our ticks as the bold
/// key points and minor ticks as the light ones.
struct AxisCoord {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
    minor: Vec<f64>,
}

impl Ranged for AxisCoord {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let f = (v - self.lo) / (self.hi - self.lo);
        limit.0 + (f * f64::from(limit.1 - limit.0)).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minor.clone()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

/// "1.5", "20000", "0.002", "3·10⁻⁵": a short label for a tick value.
fn fmt_num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let a = v.abs();
    let mag = a.log10().floor() as i32;
    if (-3..5).contains(&mag) {
        let decimals = (3 - mag).max(0) as usize;
        let s = format!("{v:.decimals$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        if s == "-0" { "0".into() } else { s }
    } else {
        let m = v / 10f64.powi(mag);
        let ms = fmt_num(m);
        if ms == "1" {
            pow10(mag)
        } else if ms == "-1" {
            format!("-{}", pow10(mag))
        } else {
            format!("{ms}·{}", pow10(mag))
        }
    }
}

/// "10⁻⁵" with Unicode superscripts (DejaVu Sans has them).
fn pow10(e: i32) -> String {
    let sup: String = e
        .to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect();
    format!("10{sup}")
}

/// A "nice" step (1, 2, 2.5 or 5 times a power of ten) of at least `raw`.
fn nice_step(raw: f64) -> f64 {
    let mag = 10f64.powf(raw.log10().floor());
    let norm = raw / mag;
    let m = [1.0, 2.0, 2.5, 5.0, 10.0]
        .into_iter()
        .find(|&m| norm <= m + 1e-9)
        .unwrap_or(10.0);
    m * mag
}

/// Multiples of a nice step in [lo, hi] (at most about `max_ticks`), and half steps.
fn linear_ticks(lo: f64, hi: f64, max_ticks: usize) -> (Vec<f64>, Vec<f64>) {
    let step = nice_step((hi - lo) / max_ticks.max(2) as f64);
    let (k0, k1) = ((lo / step).ceil() as i64, (hi / step).floor() as i64);
    let ticks = (k0..=k1).map(|k| k as f64 * step).collect();
    let minor = ((2 * k0 - 1)..=(2 * k1 + 1))
        .filter(|k| k % 2 != 0)
        .map(|k| k as f64 * step / 2.0)
        .filter(|t| (lo..=hi).contains(t))
        .collect();
    (ticks, minor)
}

/// Ticks of a log axis given in decades (plot space): powers of ten, every `step`-th so
/// at most about `max_ticks`; minor lines at 2..9 x 10ⁿ or at skipped decades. A range
/// with fewer than two powers of ten gets nice linear ticks in value space instead.
fn log_ticks(lo: f64, hi: f64, max_ticks: usize) -> (Vec<f64>, Vec<f64>) {
    let (d0, d1) = (lo.ceil() as i64, hi.floor() as i64);
    let decades = d1 - d0 + 1;
    if decades >= 2 {
        let step = (decades + max_ticks as i64 - 1) / max_ticks as i64;
        let first = d0.div_euclid(step) * step + if d0.rem_euclid(step) == 0 { 0 } else { step };
        let ticks: Vec<f64> = (first..=d1)
            .step_by(step as usize)
            .map(|d| d as f64)
            .collect();
        let minor = if step == 1 && hi - lo <= 8.0 {
            (lo.floor() as i64..=d1)
                .flat_map(|d| (2..=9).map(move |k| d as f64 + (k as f64).log10()))
                .filter(|t| (lo..=hi).contains(t))
                .collect()
        } else {
            (d0..=d1)
                .filter(|d| d.rem_euclid(step) != 0)
                .map(|d| d as f64)
                .collect()
        };
        (ticks, minor)
    } else {
        let (a, b) = (10f64.powf(lo), 10f64.powf(hi));
        let (ticks, _) = linear_ticks(a, b, max_ticks.min(5));
        let ticks = ticks
            .into_iter()
            .filter(|&v| v > 0.0)
            .map(f64::log10)
            .filter(|t| (lo..=hi).contains(t))
            .collect();
        (ticks, vec![])
    }
}

// ---------------------------------------------------------------------------------------
// Rendering

type DrawResult<T = ()> = std::result::Result<T, Box<dyn std::error::Error + Send + Sync>>;
type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<AxisCoord, AxisCoord>>;

/// Pixel scale (1 for SVG, [`SUPERSAMPLE`] for the PNG's large canvas) and the kind of
/// canvas, for what plotters draws differently on a bitmap (see [`stroke`]).
#[derive(Debug, Clone, Copy)]
struct Scale(u32, Canvas);

#[derive(Debug, Clone, Copy, PartialEq)]
enum Canvas {
    Vector,
    Bitmap,
}

impl Scale {
    const SVG: Scale = Scale(1, Canvas::Vector);
    const PNG: Scale = Scale(SUPERSAMPLE, Canvas::Bitmap);

    fn u(self, v: u32) -> u32 {
        v * self.0
    }
    fn i(self, v: i32) -> i32 {
        v * self.0 as i32
    }
    fn font(self, px: f64) -> FontDesc<'static> {
        (FAMILY, px * f64::from(self.0)).into_font()
    }
}

/// A figure that can draw itself on any plotters backend.
trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: Scale) -> DrawResult
    where
        DB::ErrorType: 'static;
}

/// `<stem>.svg` and `<stem>.png`.
fn outputs(stem: &Path) -> Result<(PathBuf, PathBuf)> {
    let bad = stem.file_name().is_none()
        || stem
            .to_str()
            .is_some_and(|s| s.ends_with(std::path::MAIN_SEPARATOR) || s.ends_with('/'));
    if bad {
        return Err(Error::Input(format!(
            "{}: not a file path stem for a figure",
            stem.display()
        )));
    }
    let with = |ext: &str| {
        let mut s = stem.as_os_str().to_owned();
        s.push(".");
        s.push(ext);
        PathBuf::from(s)
    };
    Ok((with("svg"), with("png")))
}

fn draw_error(path: &Path, e: &(dyn std::error::Error + Send + Sync)) -> Error {
    Error::io(
        format!("drawing {}", path.display()),
        std::io::Error::other(e.to_string()),
    )
}

/// Draws `fig` into both files.
fn render(stem: &Path, fig: &impl Figure) -> Result<()> {
    let (svg_path, png_path) = outputs(stem)?;

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, HEIGHT)).into_drawing_area();
        fig.draw(&root, Scale::SVG)
            .and_then(|()| Ok(root.present()?))
            .map_err(|e| draw_error(&svg_path, &*e))?;
    }
    atomic_write(&svg_path, svg.as_bytes())?;

    let (bw, bh) = (WIDTH * SUPERSAMPLE, HEIGHT * SUPERSAMPLE);
    let mut big = vec![255u8; (bw * bh * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut big, (bw, bh)).into_drawing_area();
        fig.draw(&root, Scale::PNG)
            .and_then(|()| Ok(root.present()?))
            .map_err(|e| draw_error(&png_path, &*e))?;
    }
    write_png(&png_path, &downsample(&big, WIDTH, HEIGHT, SUPERSAMPLE))
}

/// Box filter: each output pixel is the mean of an `ss` x `ss` block.
fn downsample(big: &[u8], w: u32, h: u32, ss: u32) -> Vec<u8> {
    let (w, h, ss) = (w as usize, h as usize, ss as usize);
    let bw = w * ss;
    let n = (ss * ss) as u32;
    let mut out = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let mut sum = 0u32;
                for dy in 0..ss {
                    let row = ((y * ss + dy) * bw + x * ss) * 3 + c;
                    for dx in 0..ss {
                        sum += u32::from(big[row + dx * 3]);
                    }
                }
                out[(y * w + x) * 3 + c] = ((sum + n / 2) / n) as u8;
            }
        }
    }
    out
}

/// Encodes RGB pixels as PNG through plotters' encoder into `.<name>.tmp-<pid>.png` next
/// to `path`, then renames it into place.
fn write_png(path: &Path, rgb: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let tmp = dir.join(format!(".{name}.tmp-{}.png", std::process::id()));
    let encoded = (|| -> DrawResult {
        let mut backend = BitMapBackend::new(&tmp, (WIDTH, HEIGHT));
        backend.blit_bitmap((0, 0), (WIDTH, HEIGHT), rgb)?;
        backend.present()?;
        Ok(())
    })();
    let done = encoded.map_err(|e| draw_error(path, &*e)).and_then(|()| {
        std::fs::File::open(&tmp)
            .and_then(|f| f.sync_all())
            .and_then(|()| std::fs::rename(&tmp, path))
            .map_err(|e| Error::io(format!("writing {}", path.display()), e))
    });
    if done.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    done
}

/// Height of one line of tick labels, in logical pixels.
const TICK_LINE: f64 = TICK_PX * 1.3;
const MARGIN_LEFT: u32 = 6;

/// Width of the widest tick label of `axis`.
fn widest_tick<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    s: Scale,
    axis: &Axis,
) -> DrawResult<u32>
where
    DB::ErrorType: 'static,
{
    let font: TextStyle = s.font(TICK_PX).into();
    let mut m = 0;
    for &t in &axis.ticks {
        m = m.max(root.estimate_text_size(&axis.label(t), &font)?.0);
    }
    Ok(m)
}

/// Horizontal layout: (y label area, right margin), in backend pixels.
fn side_areas<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    s: Scale,
    x: &Axis,
    y: &Axis,
) -> DrawResult<(u32, u32)>
where
    DB::ErrorType: 'static,
{
    let label_dist = s.u(2 * TICK_LEN as u32);
    let y_area = label_dist + widest_tick(root, s, y)? + s.u(10) + s.u(LABEL_PX as u32) + s.u(4);
    let right = s.u(14).max(widest_tick(root, s, x)? / 2 + s.u(4));
    Ok((y_area, right))
}

/// Height under a plot for x tick labels (`x_tick_h` logical pixels high) and the x axis
/// label, in backend pixels.
fn x_label_area(s: Scale, x_tick_h: f64) -> u32 {
    s.u(2 * TICK_LEN as u32) + s.u(x_tick_h.ceil() as u32) + s.u(6) + s.u(LABEL_PX as u32) + s.u(6)
}

/// Fills the figure white and draws the title (shrunk until it fits the width); returns
/// the area under it, inside the figure margins (`right` from [`side_areas`]).
fn titled<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    s: Scale,
    title: &str,
    right: u32,
) -> DrawResult<DrawingArea<DB, Shift>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let (w, _) = root.dim_in_pixel();
    let mut title_px = TITLE_PX;
    let title_font = loop {
        let f = s.font(title_px);
        if root.estimate_text_size(title, &f.clone().into())?.0 + s.u(16) <= w || title_px <= 11.0 {
            break f;
        }
        title_px -= 1.0;
    };
    let body = root.margin(s.u(10), s.u(4), s.u(MARGIN_LEFT), right);
    Ok(body.titled(title, title_font)?)
}

/// A chart filling `area` with `x_area` under and `y_area` left of the plot for labels;
/// nothing drawn yet, so it can be rebuilt (see [`legend_headroom`]).
fn build<'a, DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    x: &Axis,
    y: &Axis,
    x_area: u32,
    y_area: u32,
) -> DrawResult<Chart<'a, DB>>
where
    DB::ErrorType: 'static,
{
    Ok(ChartBuilder::on(area)
        .x_label_area_size(x_area)
        .y_label_area_size(y_area)
        .build_cartesian_2d(x.spec(), y.spec())?)
}

/// Grid, axes, ticks, tick labels and axis labels. Without `x_desc` the x tick labels are
/// left out too (a panel sharing the x axis of the one below), the tick marks are not.
fn mesh<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    s: Scale,
    (x, x_desc): (&Axis, Option<&str>),
    (y, y_desc): (&Axis, &str),
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let tick_font: TextStyle = s.font(TICK_PX).color(&BLACK);
    let label_font: TextStyle = s.font(LABEL_PX).color(&BLACK);
    let x_fmt = |v: &f64| x.label(*v);
    let y_fmt = |v: &f64| y.label(*v);
    let mut mesh = chart.configure_mesh();
    mesh.y_desc(y_desc)
        .axis_desc_style(label_font)
        .label_style(tick_font.clone())
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .bold_line_style(BLACK.mix(0.13).stroke_width(s.u(1)))
        .light_line_style(BLACK.mix(0.05).stroke_width(s.u(1)))
        .axis_style(INK.stroke_width(s.u(1)))
        .set_all_tick_mark_size(s.i(TICK_LEN));
    match x_desc {
        Some(d) => mesh.x_desc(d),
        None => mesh.x_label_style(tick_font.color(&TRANSPARENT)),
    };
    if x.categorical {
        mesh.disable_x_mesh();
    }
    mesh.draw()?;
    Ok(())
}

/// Title, axes, grid, ticks and axis labels; returns the chart to draw series on. The x
/// tick labels get `x_tick_h` logical pixels of height.
fn frame<'a, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, Shift>,
    s: Scale,
    title: &str,
    (x, x_desc): (&Axis, &str),
    (y, y_desc): (&Axis, &str),
    x_tick_h: f64,
) -> DrawResult<Chart<'a, DB>>
where
    DB::ErrorType: 'static,
{
    let (y_area, right) = side_areas(root, s, x, y)?;
    let body = titled(root, s, title, right)?;
    let mut chart = build(&body, x, y, x_label_area(s, x_tick_h), y_area)?;
    mesh(&mut chart, s, (x, Some(x_desc)), (y, y_desc))?;
    Ok(chart)
}

/// Small grey note at the figure's lower left saying where values <= 0 went.
fn clamp_note<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    s: Scale,
    axes: &[(&str, &Axis)],
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let parts: Vec<String> = axes
        .iter()
        .filter(|(_, a)| a.clamped)
        .map(|(name, a)| format!("{name} values ≤ 0 drawn at {}", fmt_num(a.floor)))
        .collect();
    footnote(root, s, &parts)
}

/// Small grey note at the figure's lower left: what the figure does not show as given.
/// Nothing when `parts` is empty.
fn footnote<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    s: Scale,
    parts: &[String],
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    if parts.is_empty() {
        return Ok(());
    }
    let (_, h) = root.dim_in_pixel();
    let style = s
        .font(NOTE_PX)
        .color(&INK.mix(0.8))
        .pos(Pos::new(HPos::Left, VPos::Bottom));
    root.draw(&Text::new(
        parts.join("; "),
        (s.i(6), h as i32 - s.i(4)),
        style,
    ))?;
    Ok(())
}

/// Height of the footnote row, logical pixels.
const NOTE_ROW: u32 = 14;

/// `area` less a row at its bottom for the footnote, if there is one, so that a long note
/// cannot run into the x axis label.
fn above_footnote<DB: DrawingBackend>(
    area: DrawingArea<DB, Shift>,
    s: Scale,
    parts: &[String],
) -> DrawingArea<DB, Shift> {
    if parts.is_empty() {
        area
    } else {
        area.margin(0, s.u(NOTE_ROW), 0, 0)
    }
}

/// Plot-space polyline to backend pixels, sampled every few pixels (for legend placement).
fn ink<DB: DrawingBackend>(
    chart: &Chart<'_, DB>,
    s: Scale,
    pts: &[(f64, f64)],
    out: &mut Vec<(i32, i32)>,
) {
    let px: Vec<(i32, i32)> = pts.iter().map(|p| chart.backend_coord(p)).collect();
    let gap = s.i(3) as f64;
    for w in px.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = f64::from((b.0 - a.0).pow(2) + (b.1 - a.1).pow(2)).sqrt();
        let steps = (len / gap).ceil().max(1.0) as i32;
        for k in 0..steps {
            let f = f64::from(k) / f64::from(steps);
            out.push((
                a.0 + (f * f64::from(b.0 - a.0)) as i32,
                a.1 + (f * f64::from(b.1 - a.1)) as i32,
            ));
        }
    }
    out.extend(px.last());
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Corner {
    UpperRight,
    UpperLeft,
    LowerRight,
    LowerLeft,
}

/// Legend geometry in backend pixels: box size, label margin and swatch width.
struct LegendBox {
    w: i32,
    h: i32,
    margin: i32,
    swatch_area: i32,
}

/// The legend box of `labels`.
fn legend_box(s: Scale, labels: &[&str]) -> DrawResult<LegendBox> {
    let style: TextStyle = s.font(LEGEND_PX).color(&BLACK);
    let mut text = MultiLineText::<(i32, i32), &str>::new((0, 0), &style);
    for l in labels {
        text.push_line(*l);
    }
    let (tw, th) = text.estimate_dimension()?;
    let (margin, swatch_area) = (s.i(7), s.i(30));
    Ok(LegendBox {
        w: tw + swatch_area + 2 * margin,
        h: th + 2 * margin,
        margin,
        swatch_area,
    })
}

/// Distance of the legend box from the plot's edges.
fn legend_inset(s: Scale) -> i32 {
    s.i(6)
}

/// The corner of the plot (`prefer` order breaks ties) where a legend box `b` hides the
/// fewest `drawn` points: its position relative to the plot and how many it hides.
fn legend_spot<DB: DrawingBackend>(
    chart: &Chart<'_, DB>,
    s: Scale,
    b: &LegendBox,
    drawn: &[(i32, i32)],
    prefer: [Corner; 4],
) -> ((i32, i32), usize) {
    let (xr, yr) = chart.plotting_area().get_pixel_range();
    let (pw, ph) = (xr.end - xr.start, yr.end - yr.start);
    let inset = legend_inset(s);
    let at = |c: Corner| match c {
        Corner::UpperRight => (pw - b.w - inset, inset),
        Corner::UpperLeft => (inset, inset),
        Corner::LowerRight => (pw - b.w - inset, ph - b.h - inset),
        Corner::LowerLeft => (inset, ph - b.h - inset),
    };
    let hidden = |(x, y): (i32, i32)| {
        let pad = s.i(3);
        drawn
            .iter()
            .filter(|&&(px, py)| {
                let (px, py) = (px - xr.start, py - yr.start);
                px >= x - pad && px <= x + b.w + pad && py >= y - pad && py <= y + b.h + pad
            })
            .count()
    };
    prefer
        .into_iter()
        .map(|c| (at(c), hidden(at(c))))
        .min_by_key(|&(_, n)| n)
        .unwrap_or(((inset, inset), 0))
}

/// When the legend would hide some of `drawn` in every corner, `y` with room above the data
/// for it (see [`Axis::with_headroom`]); the chart must then be rebuilt on the new axis.
fn legend_headroom<DB: DrawingBackend>(
    chart: &Chart<'_, DB>,
    s: Scale,
    labels: &[&str],
    drawn: &[(i32, i32)],
    y: &Axis,
    max_ticks: usize,
) -> DrawResult<Option<Axis>> {
    if labels.is_empty() {
        return Ok(None);
    }
    let b = legend_box(s, labels)?;
    use Corner::*;
    let (_, hidden) = legend_spot(
        chart,
        s,
        &b,
        drawn,
        [UpperRight, UpperLeft, LowerRight, LowerLeft],
    );
    if hidden == 0 {
        return Ok(None);
    }
    let (_, yr) = chart.plotting_area().get_pixel_range();
    let need = b.h + 2 * legend_inset(s) + s.i(3);
    // Never squeeze the data into less than a third of the plot.
    let frac = (f64::from(need) / f64::from((yr.end - yr.start).max(1))).min(2.0 / 3.0);
    Ok(Some(y.with_headroom(frac, max_ticks)))
}

/// Draws the legend in the corner of the plot where it hides the fewest drawn points
/// (`prefer` order breaks ties).
fn legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    s: Scale,
    labels: &[&str],
    drawn: &[(i32, i32)],
    prefer: [Corner; 4],
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    if labels.is_empty() {
        return Ok(());
    }
    let b = legend_box(s, labels)?;
    let ((x, y), _) = legend_spot(chart, s, &b, drawn, prefer);
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::Coordinate(x, y))
        .label_font(s.font(LEGEND_PX).color(&BLACK))
        .legend_area_size(b.swatch_area as u32)
        .margin(b.margin as u32)
        .background_style(WHITE.mix(0.9).filled())
        .border_style(INK.mix(0.45).stroke_width(s.u(1)))
        .draw()?;
    Ok(())
}

/// Draws the polyline `pts` (plot space) in `style`; returns its series handle, for a
/// legend entry. The SVG gets one polyline. On a bitmap plotters fills a wide line's whole
/// outline as one even-odd polygon with mitred corners: holes where the line overlaps
/// itself (a retraced loop, a min/max envelope's zigzag) and spikes at sharp turns. So
/// there each segment is its own quad, with round joins.
fn stroke<'a, 'b, DB: DrawingBackend + 'a>(
    chart: &'b mut Chart<'a, DB>,
    s: Scale,
    pts: Vec<(f64, f64)>,
    style: ShapeStyle,
) -> DrawResult<&'b mut SeriesAnno<'a, DB>>
where
    DB::ErrorType: 'static,
{
    if s.1 == Canvas::Vector || style.stroke_width <= 1 {
        return Ok(chart.draw_series(LineSeries::new(pts, style))?);
    }
    // Points on the same pixel as the one before add nothing.
    let mut kept: Vec<(f64, f64)> = Vec::with_capacity(pts.len());
    let mut last = None;
    for p in pts {
        let b = chart.backend_coord(&p);
        if last != Some(b) {
            kept.push(p);
            last = Some(b);
        }
    }
    let inner = kept
        .get(1..kept.len().saturating_sub(1))
        .unwrap_or_default();
    let r = style.stroke_width / 2;
    chart.draw_series(inner.iter().map(|&p| Circle::new(p, r, style.filled())))?;
    Ok(chart.draw_series(
        kept.windows(2)
            .map(|w| PathElement::new(vec![w[0], w[1]], style)),
    )?)
}

/// Draws `pts` (plot space) as a line in `col`, `width` logical pixels wide; with a label,
/// also its legend entry (a short line of the same colour and width).
fn line_series<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    s: Scale,
    pts: Vec<(f64, f64)>,
    (col, width): (RGBColor, u32),
    label: Option<&str>,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let (lw, sw) = (s.u(width), s.i(22));
    let anno = stroke(chart, s, pts, col.stroke_width(lw))?;
    if let Some(l) = label {
        anno.label(l).legend(move |p| {
            EmptyElement::at(p) + PathElement::new(vec![(0, 0), (sw, 0)], col.stroke_width(lw))
        });
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Convergence

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
        let (sw, sh, lw) = (s.i(22), s.i(5), s.u(LINE_W));
        for (i, (c, line)) in self.series.iter().zip(lines).enumerate() {
            let col = color(i);
            stroke(&mut chart, s, line, col.stroke_width(lw))?
                .label(c.label.as_str())
                .legend(move |p| {
                    EmptyElement::at(p)
                        + Rectangle::new([(0, -sh), (sw, sh)], col.mix(0.2).filled())
                        + PathElement::new(vec![(0, 0), (sw, 0)], col.stroke_width(lw))
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

/// Convergence figure: per series, the median as a line and the interquartile range as a
/// translucent band of the same colour, against function evaluations on a log axis; `y`
/// on a log axis when `log_y`.
///
/// Points where the median is +inf or NaN (fewer than half the trials have a finite value
/// yet) are left out of the line; where q3 is +inf the band reaches the top of the plot;
/// where q1 is not finite the band is left out. Values <= 0 on a log axis: see the module
/// documentation. `evals`, `median`, `q1`, `q3` of a series must have the same length.
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

// ---------------------------------------------------------------------------------------
// Box plot

/// Tukey box: quartiles (type 7), whiskers to the most extreme values within 1.5 IQR of
/// the box, everything beyond as outliers.
#[derive(Debug, Clone, PartialEq)]
struct BoxStats {
    q1: f64,
    median: f64,
    q3: f64,
    low: f64,
    high: f64,
    outliers: Vec<f64>,
}

fn box_stats(values: &[f64]) -> Option<BoxStats> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let (q1, median, q3) = (
        quantile_sorted(&v, 0.25),
        quantile_sorted(&v, 0.5),
        quantile_sorted(&v, 0.75),
    );
    let iqr = q3 - q1;
    let (fence_lo, fence_hi) = (q1 - 1.5 * iqr, q3 + 1.5 * iqr);
    let inside = || {
        v.iter()
            .copied()
            .filter(|&x| x >= fence_lo && x <= fence_hi)
    };
    Some(BoxStats {
        q1,
        median,
        q3,
        low: inside().fold(q1, f64::min),
        high: inside().fold(q3, f64::max),
        outliers: v
            .iter()
            .copied()
            .filter(|&x| x < fence_lo || x > fence_hi)
            .collect(),
    })
}

struct BoxPlot<'a> {
    title: &'a str,
    groups: &'a [(String, Vec<f64>)],
    y_label: &'a str,
    log_y: bool,
}

impl BoxPlot<'_> {
    /// Category label: the name, plus how many values could not be drawn.
    fn names(&self) -> Vec<String> {
        self.groups
            .iter()
            .map(|(name, v)| {
                let bad = v.iter().filter(|x| !x.is_finite()).count();
                match bad {
                    0 => name.clone(),
                    b if b == v.len() => format!("{name}\n(no finite value)"),
                    b => format!("{name}\n({b} non-finite)"),
                }
            })
            .collect()
    }
}

impl Figure for BoxPlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, s: Scale) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let n = self.groups.len();
        let all: Vec<f64> = self
            .groups
            .iter()
            .flat_map(|(_, v)| v.iter().copied())
            .collect();
        let x = Axis::categories(n);
        let y = Axis::fit(self.log_y, &all, 0.05, 7);

        // Names under the boxes, as large as fits in a box's slot, wrapped if need be.
        let names = self.names();
        let (w, _) = root.dim_in_pixel();
        let (y_area, right) = side_areas(root, s, &x, &y)?;
        let plot_w = w.saturating_sub(s.u(MARGIN_LEFT) + y_area + right);
        let slot = (plot_w / n.max(1) as u32)
            .saturating_sub(s.u(8))
            .max(s.u(20));
        let paragraphs = |name: &String| name.lines().count();
        let mut px = TICK_PX;
        let mut fallback = None;
        let (font, wrapped) = loop {
            let f: TextStyle = s.font(px).color(&BLACK);
            let mut wrapped = Vec::with_capacity(n);
            for name in &names {
                wrapped.push(wrap(root, &f, name, slot)?);
            }
            if names
                .iter()
                .zip(&wrapped)
                .all(|(n, w)| w.len() == paragraphs(n))
            {
                break (f, wrapped);
            }
            if fallback.is_none()
                && names
                    .iter()
                    .zip(&wrapped)
                    .all(|(n, w)| w.len() <= paragraphs(n) + 1)
            {
                fallback = Some((f.clone(), wrapped.clone()));
            }
            if px <= 10.0 {
                break fallback.unwrap_or((f, wrapped));
            }
            px -= 1.0;
        };
        let line_h = (font.font.get_size() / f64::from(s.0) * 1.25).ceil();
        let lines = wrapped.iter().map(Vec::len).max().unwrap_or(1) as f64;
        let mut chart = frame(
            root,
            s,
            self.title,
            (&x, "optimizer"),
            (&y, self.y_label),
            (lines * line_h).max(TICK_LINE),
        )?;

        let (hw, cap) = (0.3, 0.15);
        let thin = s.u(1);
        for (i, (_, values)) in self.groups.iter().enumerate() {
            let Some(b) = box_stats(values) else {
                continue;
            };
            let c = color(i);
            let xc = (i + 1) as f64;
            let p = |v: f64| y.to_plot(v).unwrap_or(y.lo);
            let (q1, med, q3) = (p(b.q1), p(b.median), p(b.q3));
            let (lo, hi) = (p(b.low), p(b.high));
            chart.draw_series([
                Rectangle::new([(xc - hw, q3), (xc + hw, q1)], c.mix(0.25).filled()),
                Rectangle::new([(xc - hw, q3), (xc + hw, q1)], c.stroke_width(thin)),
            ])?;
            chart.draw_series([
                PathElement::new(vec![(xc, q3), (xc, hi)], c.stroke_width(thin)),
                PathElement::new(vec![(xc, q1), (xc, lo)], c.stroke_width(thin)),
                PathElement::new(vec![(xc - cap, hi), (xc + cap, hi)], c.stroke_width(thin)),
                PathElement::new(vec![(xc - cap, lo), (xc + cap, lo)], c.stroke_width(thin)),
                PathElement::new(vec![(xc - hw, med), (xc + hw, med)], c.stroke_width(s.u(3))),
            ])?;
            chart.draw_series(
                b.outliers
                    .iter()
                    .map(|&v| Circle::new((xc, p(v)), s.u(3), c.stroke_width(thin))),
            )?;
        }

        let line_h = s.i(line_h as i32);
        for (i, lines) in wrapped.iter().enumerate() {
            let (cx, cy) = chart.backend_coord(&((i + 1) as f64, y.lo));
            for (j, line) in lines.iter().enumerate() {
                root.draw(&Text::new(
                    line.as_str(),
                    (cx, cy + s.i(2 * TICK_LEN) + j as i32 * line_h),
                    font.pos(Pos::new(HPos::Center, VPos::Top)),
                ))?;
            }
        }
        clamp_note(root, s, &[("y", &y)])
    }
}

/// Splits `text` into lines no wider than `max_w` with `font`: at its newlines, then after
/// `_`, `-` or `/` and at spaces, and inside a word only if the word alone is too wide.
fn wrap<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    font: &TextStyle,
    text: &str,
    max_w: u32,
) -> DrawResult<Vec<String>>
where
    DB::ErrorType: 'static,
{
    let width = |t: &str| -> DrawResult<u32> { Ok(root.estimate_text_size(t, font)?.0) };
    let mut out = Vec::new();
    for para in text.lines() {
        // Pieces each ending at a break opportunity; a space starts a new piece.
        let mut pieces: Vec<String> = vec![String::new()];
        for c in para.chars() {
            if c == ' ' && !pieces.last().is_some_and(String::is_empty) {
                pieces.push(String::new());
            }
            if let Some(p) = pieces.last_mut() {
                p.push(c);
            }
            if matches!(c, '_' | '-' | '/') {
                pieces.push(String::new());
            }
        }
        let mut line = String::new();
        for piece in pieces.iter().filter(|p| !p.is_empty()) {
            let candidate = format!("{line}{piece}");
            if line.is_empty() || width(&candidate)? <= max_w {
                line = candidate;
                if width(&line)? <= max_w {
                    continue;
                }
            } else {
                out.push(std::mem::take(&mut line));
                line = piece.trim_start().to_string();
                if width(&line)? <= max_w {
                    continue;
                }
            }
            // `line` is one word too wide on its own: cut it by characters.
            let mut cut = String::new();
            for c in std::mem::take(&mut line).chars() {
                if !cut.is_empty() && width(&format!("{cut}{c}"))? > max_w {
                    out.push(std::mem::take(&mut cut));
                }
                cut.push(c);
            }
            line = cut;
        }
        out.push(line);
    }
    if out.is_empty() {
        out.push(String::new());
    }
    Ok(out)
}

/// Box plot: one Tukey box per group (quartiles type 7, whiskers to the most extreme values
/// within 1.5 IQR of the box, outliers as circles), in colour `i` for group `i`, names
/// under the boxes. Non-finite values (NaN, +-inf) are left out and counted in the name
/// ("GA (2 non-finite)"). Values <= 0 on a log axis: see the module documentation.
pub fn boxplot(
    path_stem: &Path,
    title: &str,
    groups: &[(String, Vec<f64>)],
    y_label: &str,
    log_y: bool,
) -> Result<()> {
    font::register()?;
    render(
        path_stem,
        &BoxPlot {
            title,
            groups,
            y_label,
            log_y,
        },
    )
}

// ---------------------------------------------------------------------------------------
// ECDF

struct Ecdf<'a> {
    title: &'a str,
    series: &'a [(String, Vec<f64>)],
    x_label: &'a str,
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
            (&y, "fraction of (trial, target) pairs reached"),
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
            line_series(&mut chart, s, steps, (color(i), LINE_W), Some(label))?;
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
/// curve up, so a series that missed some pairs ends below 1. Values <= 0: see the module
/// documentation. The x axis spans at least `x_span` (typically 1 to the budget), so a
/// curve that stays flat is shown over the whole run.
pub fn ecdf(
    path_stem: &Path,
    title: &str,
    series: &[(String, Vec<f64>)],
    x_label: &str,
    x_span: (f64, f64),
) -> Result<()> {
    font::register()?;
    render(
        path_stem,
        &Ecdf {
            title,
            series,
            x_label,
            x_span,
        },
    )
}

// ---------------------------------------------------------------------------------------
// Time series and input-output loops

/// Most points drawn per series in the input-output plane (see [`loops`]).
const MAX_LOOP_POINTS: usize = 5000;
/// Space between the two panels of [`timeseries_with_error`], logical pixels: the upper
/// panel's tick marks and room for y tick labels at both panels' facing edges.
const PANEL_GAP: u32 = 18;
/// Legend label of the measured output.
const MEASURED: &str = "measured";

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

/// Every `step`-th sample pair from the first, `step` the smallest that keeps at most
/// `cap`, plus the last so the path ends where the record does; pairs with a non-finite
/// value are skipped. Returns the points and `step`.
fn stride(x: &[f64], y: &[f64], cap: usize) -> (Vec<(f64, f64)>, usize) {
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

/// "error [mm]" for "displacement [mm]": "error" and the unit in trailing brackets, if any.
fn error_label(y_label: &str) -> String {
    let l = y_label.trim_end();
    match l.strip_suffix(']').and_then(|r| r.rfind('[')) {
        Some(i) => format!("error {}", &l[i..]),
        None => "error".into(),
    }
}

/// The measured output first, then the models: (label, values), series `i` in colour `i`
/// (so the measured output is black).
fn output_series<'a>(
    measured: &'a [f64],
    models: &'a [(String, Vec<f64>)],
) -> Vec<(&'a str, &'a [f64])> {
    std::iter::once((MEASURED, measured))
        .chain(models.iter().map(|(l, v)| (l.as_str(), v.as_slice())))
        .collect()
}

/// Colour and width of output series `i` (0 the measured one): the measured line is
/// drawn first and wider, so it shows on both sides of a model that fits it.
fn series_pen(i: usize) -> (RGBColor, u32) {
    (color(i), if i == 0 { LINE_W + 2 } else { LINE_W })
}

/// Checks that the measured output and every model are as long as the independent variable.
fn check_lengths(
    what: &str,
    n: usize,
    measured: &[f64],
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
fn nonfinite_note(x: &[f64], series: &[(&str, &[f64])]) -> Option<String> {
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

/// Width of the plot in logical pixels: the number of envelope columns.
fn plot_columns<DB: DrawingBackend>(chart: &Chart<'_, DB>, s: Scale) -> usize {
    let (xr, _) = chart.plotting_area().get_pixel_range();
    ((xr.end - xr.start).max(1) as u32).div_ceil(s.0) as usize
}

/// Where `lines` pass, for legend placement.
fn ink_all<DB: DrawingBackend>(
    chart: &Chart<'_, DB>,
    s: Scale,
    lines: &[Vec<(f64, f64)>],
) -> Vec<(i32, i32)> {
    let mut drawn = Vec::new();
    for l in lines {
        ink(chart, s, l, &mut drawn);
    }
    drawn
}

struct TimeSeries<'a> {
    title: &'a str,
    t: &'a [f64],
    measured: &'a [f64],
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
            .map(|(_, m)| m.iter().zip(self.measured).map(|(a, b)| a - b).collect())
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
            line_series(&mut upper, s, line, series_pen(i), Some(label))?;
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
            line_series(&mut lower, s, line, (color(i + 1), LINE_W), None)?;
        }
        footnote(root, s, &note)
    }
}

/// Measured and modelled output over time with the models' errors under it (the layout
/// of the dissertation's Fig. 3.5): an upper panel, about 2/3 of the height, with the
/// measured output in black and model `i` in colour `i + 1` ([`color`]) and a legend; a
/// lower panel with each model's error e = model - measured in its colour, on the same x
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
    measured: &[f64],
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

struct Loops<'a> {
    title: &'a str,
    u: &'a [f64],
    measured: &'a [f64],
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
            line_series(&mut chart, s, line, series_pen(i), Some(label))?;
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
/// output against the input `u` as a black line and model `i`'s output against `u` in
/// colour `i + 1` ([`color`]), with a legend.
///
/// Long records are thinned to every k-th sample, k the smallest that leaves at most 5000
/// points per line (noted in a footnote when k > 1); the axes fit what is drawn. Not a
/// min/max envelope as in [`timeseries_with_error`]: along `u` the path goes back and
/// forth, so per-column extremes would join points of different branches; a stride keeps
/// the path's order and, for the smooth, densely sampled records loops come from, its
/// shape (the time-series figure is the one that shows every spike). Samples with a
/// non-finite input or output are skipped and counted in a footnote. `measured` and every
/// model must have the length of `u`.
pub fn loops(
    path_stem: &Path,
    title: &str,
    u: &[f64],
    measured: &[f64],
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

// ---------------------------------------------------------------------------------------
// Generic lines

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
            line_series(&mut chart, s, line, series_pen(i), Some(label))?;
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

/// Labelled (x, y) lines, series `i` in colour `i` (series 0 drawn wider), with a legend;
/// either axis logarithmic. More than 5000 points per line are thinned by a stride (see
/// [`loops`]); non-finite points are skipped. For residuals over time, binned means and
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

#[cfg(test)]
mod tests {
    use super::*;

    fn record(
        optimum: Option<f64>,
        improvements: &[(u64, f64)],
        checkpoints: &[(u64, f64)],
    ) -> TrialRecord {
        let best = improvements.last().map_or(f64::INFINITY, |p| p.1);
        TrialRecord {
            objective: "f".into(),
            optimizer: "o".into(),
            trial: 0,
            seed: "0".into(),
            budget: 100,
            evaluations: checkpoints.last().map_or(0, |c| c.0),
            best,
            best_x: vec![],
            optimum,
            stopped_at_target: false,
            nonfinite: 0,
            penalised: 0,
            wall_s: 0.0,
            improvements: improvements.to_vec(),
            checkpoints: checkpoints.to_vec(),
        }
    }

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
    fn runtimes_are_first_hits_or_inf() {
        let r = record(Some(1.0), &[(1, 11.0), (5, 6.0), (20, 2.0)], &[(100, 2.0)]);
        assert_eq!(
            runtimes(&[&r], &[10.0, 1.0, 0.1]),
            vec![1.0, 20.0, f64::INFINITY]
        );
    }

    #[test]
    fn box_stats_are_tukey() {
        // numpy type 7 on 1..=9 and 30: q1 = 3.25, median 5.5, q3 = 7.75, IQR 4.5,
        // upper fence 14.5 -> whisker at 9, 30 an outlier.
        let mut v: Vec<f64> = (1..=9).map(f64::from).collect();
        v.push(30.0);
        v.push(f64::NAN);
        let b = box_stats(&v).unwrap();
        assert_eq!((b.q1, b.median, b.q3), (3.25, 5.5, 7.75));
        assert_eq!((b.low, b.high), (1.0, 9.0));
        assert_eq!(b.outliers, vec![30.0]);
        assert!(box_stats(&[f64::INFINITY]).is_none());
    }

    #[test]
    fn wrap_breaks_at_separators_then_inside_words() {
        font::register().unwrap();
        let mut buf = String::new();
        let root = SVGBackend::with_string(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        let f: TextStyle = Scale::SVG.font(TICK_PX).into();
        let w = |t: &str| root.estimate_text_size(t, &f).unwrap().0;
        let wrap = |t: &str, max: u32| wrap(&root, &f, t, max).unwrap();
        assert_eq!(wrap("GA", 100), vec!["GA"]);
        assert_eq!(
            wrap("GA\n(2 non-finite)", 500),
            vec!["GA", "(2 non-finite)"]
        );
        let max = w("optimizer_variant_") + 1;
        assert_eq!(
            wrap("optimizer_variant_0", max),
            vec!["optimizer_variant_", "0"]
        );
        assert_eq!(wrap("random search", w("random")), vec!["random", "search"]);
        let cut = wrap("abcdefghijklmnop", w("abcdef"));
        assert!(
            cut.len() >= 3 && cut.concat() == "abcdefghijklmnop",
            "{cut:?}"
        );
        assert!(cut.iter().all(|l| w(l) <= w("abcdef")));
    }

    #[test]
    fn tick_labels_and_log_floor() {
        assert_eq!(pow10(-12), "10⁻¹²");
        assert_eq!(fmt_num(0.30000000000000004), "0.3");
        assert_eq!(fmt_num(20000.0), "20000");
        assert_eq!(fmt_num(2.5e-7), "2.5·10⁻⁷");
        assert_eq!(fmt_num(1e9), "10⁹");
        let a = Axis::fit(true, &[0.0, 1e-3, 10.0, f64::INFINITY, f64::NAN], 0.0, 8);
        assert!(a.clamped);
        assert_eq!(a.floor, 1e-4);
        assert_eq!((a.lo, a.hi), (-4.0, 1.0));
        assert_eq!(a.ticks, vec![-4.0, -3.0, -2.0, -1.0, 0.0, 1.0]);
        let a = Axis::fit(true, &[-1.0], 0.0, 8);
        assert_eq!(a.floor, LOG_FLOOR_NO_POSITIVE);
        assert!(!a.ticks.is_empty());
        // Less than a decade still gets ticks.
        let a = Axis::fit(true, &[200.0, 500.0], 0.0, 8);
        assert!(a.ticks.len() >= 2, "{:?}", a.ticks);
        // Many decades are thinned.
        let a = Axis::fit(true, &[1e-300, 1.0], 0.0, 7);
        assert!(a.ticks.len() <= 8 && a.ticks.len() >= 2, "{:?}", a.ticks);
    }

    // ---- files

    struct Files {
        svg: String,
        png: Vec<u8>,
    }

    fn files(dir: &Path, stem: &str) -> Files {
        let svg = std::fs::read_to_string(dir.join(format!("{stem}.svg"))).unwrap();
        let png = std::fs::read(dir.join(format!("{stem}.png"))).unwrap();
        Files { svg, png }
    }

    /// Number of <text> elements whose content is exactly `s`.
    fn texts(svg: &str, s: &str) -> usize {
        svg.matches(&format!(">\n{s}\n</text>")).count()
    }

    /// Elements named `tag` with attribute `attr` = `value`.
    fn count(svg: &str, tag: &str, attr: &str, value: &str) -> usize {
        svg.split('<')
            .filter(|e| e.starts_with(tag) && e.contains(&format!("{attr}=\"{value}\"")))
            .count()
    }

    fn hex(c: RGBColor) -> String {
        format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
    }

    fn check_common(f: &Files, title: &str, labels: &[&str]) {
        let svg = f.svg.trim();
        assert!(svg.starts_with("<svg"), "{}", &svg[..50]);
        assert!(svg.ends_with("</svg>"));
        assert!(
            svg.contains(&format!("width=\"{WIDTH}\""))
                && svg.contains(&format!("height=\"{HEIGHT}\""))
        );
        assert_eq!(texts(svg, title), 1, "title");
        for l in labels {
            assert_eq!(texts(svg, l), 1, "label {l}");
        }

        assert_eq!(&f.png[..8], b"\x89PNG\r\n\x1a\n");
        assert_eq!(&f.png[12..16], b"IHDR");
        let w = u32::from_be_bytes(f.png[16..20].try_into().unwrap());
        let h = u32::from_be_bytes(f.png[20..24].try_into().unwrap());
        assert_eq!((w, h), (WIDTH, HEIGHT));
        // The title (text rendered with the bundled font) darkens the top strip.
        let decoder = png::Decoder::new(std::io::Cursor::new(&f.png));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        let ch = info.color_type.samples();
        let dark = (0..30)
            .flat_map(|y| (WIDTH / 4..3 * WIDTH / 4).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let i = (y * WIDTH + x) as usize * ch;
                buf[i..i + 3].iter().all(|&v| v < 100)
            })
            .count();
        assert!(dark > 50, "only {dark} dark pixels in the title strip");
    }

    fn only_outputs(dir: &Path, stem: &str) {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, vec![format!("{stem}.png"), format!("{stem}.svg")]);
    }

    fn demo_series() -> Vec<ConvergenceSeries> {
        let evals: Vec<u64> = (0..=20)
            .map(|k| 10f64.powf(k as f64 * 0.2).round() as u64)
            .collect();
        let mk = |label: &str, rate: f64, zero_from: usize| {
            let median: Vec<f64> = (0..evals.len())
                .map(|k| {
                    if k >= zero_from {
                        0.0
                    } else {
                        100.0 * (-rate * k as f64).exp()
                    }
                })
                .collect();
            ConvergenceSeries {
                label: label.into(),
                evals: evals.clone(),
                q1: median.iter().map(|m| m * 0.4).collect(),
                q3: median.iter().map(|m| m * 2.5).collect(),
                median,
            }
        };
        let mut s = vec![
            mk("GA", 0.5, 99),
            mk("PSO", 0.9, 18),
            mk("random search", 0.15, 99),
        ];
        s[0].q3[0] = f64::INFINITY;
        s
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
            // One median line and one legend swatch per series; one band and its swatch.
            assert_eq!(count(&f.svg, "polyline", "stroke", &c), 2, "lines of {c}");
            assert_eq!(count(&f.svg, "polygon", "fill", &c), 1, "band of {c}");
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

    #[test]
    fn boxplot_writes_svg_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let groups = vec![
            ("GA".to_string(), vec![1e-3, 2e-3, 3e-3, 5e-3, 4e-3, 0.2]),
            ("PSO".to_string(), vec![1e-5, 3e-5, 2e-5, 8e-6, 1e-5]),
            ("MSGA".to_string(), vec![0.01, 0.02, 0.015, 0.03, 0.012]),
        ];
        boxplot(
            &dir.path().join("box"),
            "Final error, Rastrigin d=5",
            &groups,
            "final error to optimum",
            true,
        )
        .unwrap();
        only_outputs(dir.path(), "box");
        let f = files(dir.path(), "box");
        check_common(&f, "Final error, Rastrigin d=5", &["GA", "PSO", "MSGA"]);
        for i in 0..groups.len() {
            // One filled box per group.
            assert_eq!(count(&f.svg, "rect", "fill", &hex(color(i))), 1);
        }
        // GA's 0.2 is an outlier: the only circle of its colour.
        assert_eq!(count(&f.svg, "circle", "stroke", &hex(color(0))), 1);
        boxplot(&dir.path().join("lin"), "linear", &groups, "error", false).unwrap();
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
            assert_eq!(count(&f.svg, "polyline", "stroke", &hex(color(i))), 2);
        }
    }

    #[test]
    fn degenerate_inputs_still_give_figures() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let inf = ConvergenceSeries {
            label: "never finite".into(),
            evals: vec![0, 1, 10],
            median: vec![f64::INFINITY; 3],
            q1: vec![f64::INFINITY; 3],
            q3: vec![f64::NAN; 3],
        };
        let zeros = ConvergenceSeries {
            label: "all zero".into(),
            evals: vec![5, 5],
            median: vec![0.0; 2],
            q1: vec![-1.0; 2],
            q3: vec![0.0; 2],
        };
        convergence(&d.join("c0"), "no series", &[], "error", true).unwrap();
        convergence(
            &d.join("c1"),
            "odd series",
            &[inf, zeros.clone()],
            "error",
            true,
        )
        .unwrap();
        convergence(
            &d.join("c2"),
            "odd series, linear",
            &[zeros],
            "error",
            false,
        )
        .unwrap();
        boxplot(&d.join("b0"), "no groups", &[], "error", true).unwrap();
        let groups = vec![
            ("empty".to_string(), vec![]),
            ("inf".to_string(), vec![f64::INFINITY, f64::NAN]),
            ("one".to_string(), vec![0.0]),
        ];
        boxplot(&d.join("b1"), "odd groups", &groups, "error", true).unwrap();
        let f = files(d, "b1");
        assert_eq!(texts(&f.svg, "(no finite value)"), 1);
        ecdf(&d.join("e0"), "no series", &[], "evaluations", (1.0, 1.0)).unwrap();
        let series = vec![
            ("none".to_string(), vec![]),
            ("zero".to_string(), vec![0.0, 1.0]),
        ];
        ecdf(
            &d.join("e1"),
            "odd series",
            &series,
            "evaluations",
            (1.0, 100.0),
        )
        .unwrap();
        let f = files(d, "e1");
        assert_eq!(texts(&f.svg, "x values ≤ 0 drawn at 0.1"), 1);
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 14);
    }

    /// Points of each polyline drawn in colour `c`.
    fn polylines(svg: &str, c: RGBColor) -> Vec<Vec<(f64, f64)>> {
        let stroke = format!("stroke=\"{}\"", hex(c));
        svg.split('<')
            .filter(|e| e.starts_with("polyline") && e.contains(&stroke))
            .map(|e| {
                let pts = e.split("points=\"").nth(1).unwrap().split('"').next();
                pts.unwrap()
                    .split_whitespace()
                    .map(|p| {
                        let (x, y) = p.split_once(',').unwrap();
                        (x.parse().unwrap(), y.parse().unwrap())
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn timeseries_with_error_writes_svg_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let r = piezo(2000, 0.02);
        let title = "Piezo actuator: output and model error";
        timeseries_with_error(
            &dir.path().join("ts"),
            title,
            &r.t,
            &r.measured,
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
            assert_eq!(polylines(&f.svg, color(i)).len(), 3, "lines of model {i}");
        }
        let error_series: usize = (0..PALETTE.len()).map(in_lower).sum();
        assert_eq!(error_series, r.models.len());
        assert_eq!(in_lower(0), 0);
    }

    #[test]
    fn loops_writes_svg_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let r = piezo(2000, 0.02);
        let title = "Piezo actuator: hysteresis loops";
        loops(
            &dir.path().join("loops"),
            title,
            &r.u,
            &r.measured,
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
        // One line and one legend swatch per output; nothing thinned, so no footnote.
        for i in 0..=r.models.len() {
            assert_eq!(polylines(&f.svg, color(i)).len(), 2, "lines of series {i}");
        }
        assert!(!f.svg.contains("samples drawn"));
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

    #[test]
    fn error_label_takes_the_unit() {
        assert_eq!(error_label("displacement y [µm]"), "error [µm]");
        assert_eq!(error_label("y [mm] "), "error [mm]");
        assert_eq!(error_label("normalised output"), "error");
        assert_eq!(error_label("y [mm] at the tip"), "error");
    }

    #[test]
    fn long_records_render() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut r = piezo(150_000, 0.05);
        r.measured[777] = f64::NAN;
        timeseries_with_error(
            &d.join("ts"),
            "150 000 samples",
            &r.t,
            &r.measured,
            &r.models,
            "time [s]",
            "y [µm]",
        )
        .unwrap();
        loops(
            &d.join("loops"),
            "150 000 samples",
            &r.u,
            &r.measured,
            &r.models,
            "u [V]",
            "y [µm]",
        )
        .unwrap();
        let f = files(d, "ts");
        check_common(&f, "150 000 samples", &[MEASURED, "Bouc-Wen"]);
        assert_eq!(texts(&f.svg, "1 non-finite sample not drawn"), 1);
        for i in 0..=r.models.len() {
            // At most two points per pixel column.
            let lines = polylines(&f.svg, color(i));
            assert!(lines.iter().all(|l| l.len() <= 2 * WIDTH as usize));
        }
        let f = files(d, "loops");
        check_common(&f, "150 000 samples", &[MEASURED, "Bouc-Wen"]);
        assert_eq!(
            texts(
                &f.svg,
                "1 in 30 samples drawn; 1 non-finite sample not drawn"
            ),
            1
        );
    }

    #[test]
    fn odd_records_still_give_figures_or_input_errors() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let nan = vec![("all NaN".to_string(), vec![f64::NAN; 3])];
        timeseries_with_error(&d.join("t0"), "empty", &[], &[], &[], "t", "y").unwrap();
        loops(&d.join("l0"), "empty", &[], &[], &[], "u", "y").unwrap();
        let (t, y) = ([0.0, 1.0, 2.0], [1.0, 1.0, 1.0]);
        timeseries_with_error(&d.join("t1"), "flat", &t, &y, &nan, "t", "y").unwrap();
        loops(&d.join("l1"), "flat", &t, &y, &nan, "u", "y").unwrap();
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 8);
        let short = vec![("short".to_string(), vec![1.0])];
        assert!(matches!(
            timeseries_with_error(&d.join("x"), "x", &t, &y, &short, "t", "y"),
            Err(Error::Input(_))
        ));
        assert!(matches!(
            loops(&d.join("x"), "x", &t, &y[..2], &[], "u", "y"),
            Err(Error::Input(_))
        ));
    }

    /// Writes the demo figures to `$OPTBENCH_PLOT_DIR` to look at:
    /// `OPTBENCH_PLOT_DIR=/tmp/figs cargo test --release --lib demo_figures -- --ignored`.
    #[test]
    #[ignore]
    fn demo_figures() {
        let dir = PathBuf::from(std::env::var("OPTBENCH_PLOT_DIR").expect("OPTBENCH_PLOT_DIR"));
        std::fs::create_dir_all(&dir).unwrap();
        let mut series = demo_series();
        convergence(
            &dir.join("convergence"),
            "Sphere d=10: convergence",
            &series,
            "best-so-far error to optimum",
            true,
        )
        .unwrap();
        for (i, name) in ["MSGA", "PSO (ring)", "GA (tournament)", "CMA-ES", "DE"]
            .iter()
            .enumerate()
        {
            let mut c = series[i % 3].clone();
            c.label = name.to_string();
            for m in c.median.iter_mut().chain(&mut c.q1).chain(&mut c.q3) {
                *m *= 1.5f64.powi(i as i32 + 1);
            }
            series.push(c);
        }
        convergence(
            &dir.join("convergence8"),
            "Eight optimizers, linear y",
            &series,
            "best-so-far value",
            false,
        )
        .unwrap();
        let groups: Vec<(String, Vec<f64>)> = ["GA", "PSO", "MSGA", "random search"]
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let v = (0..30)
                    .map(|k| {
                        10f64.powf(-(i as f64) - 0.05 * k as f64 + if k == 7 { 2.0 } else { 0.0 })
                    })
                    .collect();
                (n.to_string(), v)
            })
            .collect();
        boxplot(
            &dir.join("box"),
            "Final error, Rastrigin d=5 (30 trials)",
            &groups,
            "final error to optimum",
            true,
        )
        .unwrap();
        let long: Vec<(String, Vec<f64>)> = (0..8)
            .map(|i| {
                (
                    format!("optimizer_variant_{i}"),
                    vec![1.0 + i as f64, 2.0, 3.0, 2.5 + i as f64 * 0.3],
                )
            })
            .collect();
        boxplot(
            &dir.join("box_long"),
            "Long names, linear y",
            &long,
            "final value",
            false,
        )
        .unwrap();
        let ecdf_series = vec![
            (
                "GA".to_string(),
                (0..60)
                    .map(|k| {
                        if k % 4 == 0 {
                            f64::INFINITY
                        } else {
                            10f64.powf(1.0 + k as f64 * 0.06)
                        }
                    })
                    .collect(),
            ),
            (
                "PSO".to_string(),
                (0..60).map(|k| 10f64.powf(0.5 + k as f64 * 0.05)).collect(),
            ),
            (
                "random search".to_string(),
                (0..60)
                    .map(|k| {
                        if k % 3 == 0 {
                            10f64.powf(2.0 + k as f64 * 0.04)
                        } else {
                            f64::INFINITY
                        }
                    })
                    .collect(),
            ),
        ];
        ecdf(
            &dir.join("ecdf"),
            "Runtime ECDF, 20 targets in [10⁻⁸, 10²]",
            &ecdf_series,
            "function evaluations",
            (1.0, 40_000.0),
        )
        .unwrap();
        let r = piezo(40_000, 0.02);
        timeseries_with_error(
            &dir.join("timeseries"),
            "Piezo actuator, 1 Hz sine: output and model error",
            &r.t,
            &r.measured,
            &r.models,
            "time [s]",
            "displacement y [µm]",
        )
        .unwrap();
        loops(
            &dir.join("loops"),
            "Piezo actuator, 1 Hz sine: hysteresis loops",
            &r.u,
            &r.measured,
            &r.models,
            "input voltage u [V]",
            "displacement y [µm]",
        )
        .unwrap();
        // Long record with spikes and gaps: the envelope keeps the spikes.
        let mut r = piezo(150_000, 0.05);
        r.measured[40_000] += 3.0;
        r.measured[100_000] -= 4.0;
        for k in (1000..1100).step_by(7) {
            r.measured[k] = f64::NAN;
        }
        timeseries_with_error(
            &dir.join("timeseries_long"),
            "150 000 samples, two spikes, a gap",
            &r.t,
            &r.measured,
            &r.models[..1],
            "time [s]",
            "displacement y [µm]",
        )
        .unwrap();
        // Many models with long names, one exact; no unit; a short record.
        let r = piezo(300, 0.0);
        let mut many = r.models.clone();
        many.push(("exact copy of the measurement".into(), r.measured.clone()));
        for k in 1..=3 {
            let v = r
                .measured
                .iter()
                .map(|m| m * (1.0 + 0.01 * k as f64))
                .collect();
            many.push((format!("rate-dependent PI, {} operators", 5 * k), v));
        }
        timeseries_with_error(
            &dir.join("timeseries_many"),
            "Six models, 300 samples, a y label without a unit",
            &r.t,
            &r.measured,
            &many,
            "t",
            "normalised output",
        )
        .unwrap();
        loops(
            &dir.join("loops_many"),
            "Six models",
            &r.u,
            &r.measured,
            &many,
            "u",
            "normalised output",
        )
        .unwrap();
        loops(
            &dir.join("loops_long"),
            "150 000 samples",
            &r.u,
            &r.measured,
            &r.models,
            "input voltage u [V]",
            "displacement y [µm]",
        )
        .unwrap();
    }

    /// A piezo-like record: `n` samples over 2 s of a 1 Hz sine 0..100 V; measured output
    /// 0.13 u minus a tanh of a play operator's lag (hysteresis), plus deterministic noise
    /// of amplitude `noise`; two models slightly off.
    struct Record {
        t: Vec<f64>,
        u: Vec<f64>,
        measured: Vec<f64>,
        models: Vec<(String, Vec<f64>)>,
    }

    fn piezo(n: usize, noise: f64) -> Record {
        let t: Vec<f64> = (0..n).map(|k| 2.0 * k as f64 / (n - 1) as f64).collect();
        let u: Vec<f64> = t
            .iter()
            .map(|&t| 50.0 - 50.0 * (2.0 * std::f64::consts::PI * t).cos())
            .collect();
        let output = |gain: f64, r: f64, depth: f64| -> Vec<f64> {
            let mut z = 0.0f64;
            u.iter()
                .map(|&u| {
                    z = z.clamp(u - r, u + r);
                    gain * u - depth * r * ((u - z) / 10.0).tanh()
                })
                .collect()
        };
        let mut measured = output(0.13, 25.0, 0.03);
        for (k, m) in measured.iter_mut().enumerate() {
            *m += noise * (((k as f64 * 12.9898).sin() * 43758.5453).fract() - 0.5) * 2.0;
        }
        Record {
            models: vec![
                ("Prandtl-Ishlinskii".into(), output(0.128, 20.0, 0.03)),
                ("Bouc-Wen".into(), output(0.131, 25.0, 0.022)),
            ],
            t,
            u,
            measured,
        }
    }

    #[test]
    fn bad_stem_is_an_input_error() {
        assert!(matches!(outputs(Path::new("")), Err(Error::Input(_))));
        assert!(matches!(outputs(Path::new("figs/")), Err(Error::Input(_))));
        let (s, p) = outputs(Path::new("figs/rastrigin_d2.5")).unwrap();
        assert_eq!(s, Path::new("figs/rastrigin_d2.5.svg"));
        assert_eq!(p, Path::new("figs/rastrigin_d2.5.png"));
    }
}
