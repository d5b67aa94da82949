//! The figure and table kit: six figure kinds, Markdown and LaTeX table writers and the
//! bundled font. It draws data, not runs, so the report, fits, diagnosis and control all
//! use it from above; it imports only `base`, `harness` (trial records into convergence
//! series) and `stats`.
//!
//! Data in, files out: the caller passes the series (built with [`convergence_series`] and
//! [`runtimes`] from trial records, or from anything else) and a path stem; every figure is
//! written as `<stem>.svg` and `<stem>.png`, each atomically (temporary file in the same
//! folder, then a rename). The folder must exist. Both are 6.4 x 4.8 in, a figure the width
//! of a two-column paper's text with 10 pt tick labels: the SVG says so in inches (640 x 480
//! logical pixels in its view box), the PNG is 1920 x 1440 at 300 dpi (its pHYs chunk says
//! so), drawn at twice that and averaged down, so lines and text are anti-aliased. No PDF:
//! plotters has no PDF backend; the SVG converts losslessly (`rsvg-convert -f pdf`,
//! Inkscape).
//!
//! Every figure has a title, axis labels, a legend (for box plots the optimizer names under
//! the boxes). Series `i` gets colour, dash pattern and marker `i` ([`series_style`]:
//! Okabe-Ito without its yellow, then Paul Tol's muted colours), so series stay apart in
//! greyscale print and for colour-blind readers, and one optimizer keeps its style across
//! figures when the caller keeps the order. Text is DejaVu Sans compiled into the binary
//! (the `font` module): no system font, fontconfig or freetype is needed.
//!
//! # Values a logarithmic axis cannot show
//!
//! On a log axis, values <= 0 (an error of exactly 0, say) are drawn at a floor: the
//! largest power of ten at most a tenth of the smallest positive finite value drawn on that
//! axis (so at least a decade below all real data), or [`LOG_FLOOR_NO_POSITIVE`] when there
//! is none. When that happens the figure says so in a footnote at its lower
//! left ("y values <= 0 drawn at 10⁻⁹"). NaN is never drawn. What +inf means depends on the
//! figure and is documented on each function.

pub mod latex;
pub mod table;

mod axes;
mod boxplot;
mod canvas;
mod convergence;
mod ecdf;
mod font;
mod layout;
mod legend;
mod lines;
mod loops;
mod measured;
mod style;
mod timeseries;

#[cfg(test)]
mod test_util;
#[cfg(test)]
mod tests;

pub use axes::LOG_FLOOR_NO_POSITIVE;
pub use boxplot::boxplot;
pub use canvas::{HEIGHT, PNG_DPI, PNG_SCALE, PX_PER_INCH, WIDTH};
pub use convergence::{ConvergenceSeries, convergence, convergence_series};
pub use ecdf::{ecdf, ecdf_of, runtimes};
pub use lines::{Decor, lines, lines_with};
pub use loops::loops;
pub use measured::MEASURED;
pub use style::{MIN_GREY_STEP, Marker, PALETTE, SeriesStyle, color, grey, series_style};
pub use timeseries::timeseries_with_error;
