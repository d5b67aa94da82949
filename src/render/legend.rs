//! Legends: placed in the corner of the plot where they hide the least, or above the data.

use super::axes::Axis;
use super::canvas::{DrawResult, INK, LEGEND_PX, Scale};
use super::layout::{Chart, SWATCH};
use plotters::element::MultiLineText;
use plotters::prelude::*;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Corner {
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
    let (margin, swatch_area) = (s.i(7), s.i(SWATCH + 10));
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
pub(super) fn legend_headroom<DB: DrawingBackend>(
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
pub(super) fn legend<'a, DB: DrawingBackend + 'a>(
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
