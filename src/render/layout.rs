//! What every figure shares around its data: title, plot area, mesh, footnotes, and lines
//! drawn alike on both canvases.

use super::axes::{Axis, AxisCoord, fmt_num};
use super::canvas::{
    DrawResult, INK, LABEL_PX, LINE_W, NOTE_PX, Scale, TICK_LEN, TICK_PX, TITLE_PX,
};
use super::style::{DASHES, Line, MarkerAt, SeriesStyle, along, series_style};
use plotters::chart::SeriesAnno;
use plotters::coord::Shift;
use plotters::coord::cartesian::Cartesian2d;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters_backend::BackendCoord;

pub(super) type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<AxisCoord, AxisCoord>>;

/// Height of one line of tick labels, in logical pixels.
pub(super) const TICK_LINE: f64 = TICK_PX * 1.3;
pub(super) const MARGIN_LEFT: u32 = 6;

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
pub(super) fn side_areas<DB: DrawingBackend>(
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
pub(super) fn x_label_area(s: Scale, x_tick_h: f64) -> u32 {
    s.u(2 * TICK_LEN as u32) + s.u(x_tick_h.ceil() as u32) + s.u(6) + s.u(LABEL_PX as u32) + s.u(6)
}

/// Fills the figure white and draws the title (shrunk until it fits the width); returns
/// the area under it, inside the figure margins (`right` from [`side_areas`]).
pub(super) fn titled<DB: DrawingBackend>(
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
/// nothing drawn yet, so it can be rebuilt (see [`legend_headroom`](super::legend::legend_headroom)).
pub(super) fn build<'a, DB: DrawingBackend>(
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
pub(super) fn mesh<DB: DrawingBackend>(
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
pub(super) fn frame<'a, DB: DrawingBackend>(
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
pub(super) fn clamp_note<DB: DrawingBackend>(
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
pub(super) fn footnote<DB: DrawingBackend>(
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
pub(super) fn above_footnote<DB: DrawingBackend>(
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
pub(super) fn ink<DB: DrawingBackend>(
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

/// How a series' line is drawn: its style, width (logical pixels) and, when markers are
/// on, where along the line the first one sits (a fraction of [`MARK_EVERY`]; series
/// get different phases so that their markers do not pile up where their lines meet).
#[derive(Debug, Clone, Copy)]
pub(super) struct Pen {
    pub(super) style: SeriesStyle,
    pub(super) width: u32,
    pub(super) markers: Option<f64>,
}

/// Horizontal distance between two markers on a line, logical pixels.
pub(super) const MARK_EVERY: f64 = 90.0;
/// Marker radius, logical pixels.
const MARK_R: f64 = 3.5;
/// Length of a legend swatch's line, logical pixels.
pub(super) const SWATCH: i32 = 28;

impl Pen {
    /// Series `i` of `n`, with markers.
    pub(super) fn marked(i: usize, n: usize) -> Pen {
        Pen {
            style: series_style(i),
            width: LINE_W,
            markers: Some((i as f64 + 0.5) / n.max(1) as f64),
        }
    }

    /// Output series `i` (0 the measured one), without markers: the measured line is drawn
    /// first and wider, so it shows on both sides of a model that fits it.
    pub(super) fn output(i: usize) -> Pen {
        Pen {
            style: series_style(i),
            width: if i == 0 { LINE_W + 2 } else { LINE_W },
            markers: None,
        }
    }

    fn line<C>(&self, s: Scale, points: Vec<C>, marks: Vec<C>) -> Line<C> {
        Line {
            points,
            color: self.style.color,
            width: s.u(self.width),
            dash: DASHES[self.style.dash]
                .iter()
                .map(|d| d * f64::from(s.0))
                .collect(),
            canvas: s.1,
            marks: marks
                .into_iter()
                .map(|at| MarkerAt {
                    at,
                    marker: self.style.marker,
                    color: self.style.color,
                    radius: MARK_R * f64::from(s.0),
                })
                .collect(),
        }
    }

    /// The legend swatch at `p`: a short line in this pen, with its marker in the middle.
    pub(super) fn swatch(&self, s: Scale, (x, y): BackendCoord) -> Line<BackendCoord> {
        let sw = s.i(SWATCH);
        let mark = self.markers.map(|_| (x + sw / 2, y)).into_iter().collect();
        self.line(s, vec![(x, y), (x + sw, y)], mark)
    }
}

/// Draws `pts` (plot space) in `pen`: the line, then its markers every [`MARK_EVERY`]
/// of x along it (if the pen has them); returns the series handle, for a legend entry.
pub(super) fn draw_line<'a, 'b, DB: DrawingBackend + 'a>(
    chart: &'b mut Chart<'a, DB>,
    s: Scale,
    pts: Vec<(f64, f64)>,
    pen: &Pen,
) -> DrawResult<&'b mut SeriesAnno<'a, DB>>
where
    DB::ErrorType: 'static,
{
    let marks = match pen.markers {
        Some(phase) => {
            let px = |p: (f64, f64)| {
                let (x, y) = chart.backend_coord(&p);
                (f64::from(x), f64::from(y))
            };
            // Spaced along x, not along the path: a noisy line (a residual) is long.
            let len = |a, b| (px(b).0 - px(a).0).abs();
            let lerp = |a: (f64, f64), b: (f64, f64), f: f64| {
                (a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1))
            };
            along(&pts, len, lerp, MARK_EVERY * f64::from(s.0), phase)
        }
        None => Vec::new(),
    };
    Ok(chart.draw_series(std::iter::once(pen.line(s, pts, marks)))?)
}

/// Draws `pts` (plot space) in `pen`; with a label, also its legend entry.
pub(super) fn line_series<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    s: Scale,
    pts: Vec<(f64, f64)>,
    pen: Pen,
    label: Option<&str>,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let anno = draw_line(chart, s, pts, &pen)?;
    if let Some(l) = label {
        anno.label(l).legend(move |p| pen.swatch(s, p));
    }
    Ok(())
}

/// Draws `pts` (plot space) as markers of `style` at each point, no line; with a label,
/// also its legend entry (the marker alone).
pub(super) fn point_series<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    s: Scale,
    pts: Vec<(f64, f64)>,
    style: SeriesStyle,
    label: Option<&str>,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let pen = Pen {
        style,
        width: LINE_W,
        markers: Some(0.0),
    };
    let radius = 1.5 * MARK_R * f64::from(s.0);
    let big = move |at| MarkerAt {
        at,
        marker: style.marker,
        color: style.color,
        radius,
    };
    let anno = chart.draw_series(std::iter::once(Line {
        points: Vec::new(),
        color: style.color,
        width: s.u(pen.width),
        dash: Vec::new(),
        canvas: s.1,
        marks: pts.into_iter().map(big).collect(),
    }))?;
    if let Some(l) = label {
        let sw = s.i(SWATCH);
        anno.label(l).legend(move |(x, y)| Line {
            points: Vec::new(),
            color: style.color,
            width: 1,
            dash: Vec::new(),
            canvas: s.1,
            marks: vec![MarkerAt {
                at: (x + sw / 2, y),
                marker: style.marker,
                color: style.color,
                radius,
            }],
        });
    }
    Ok(())
}

/// Where `lines` pass, for legend placement.
pub(super) fn ink_all<DB: DrawingBackend>(
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
