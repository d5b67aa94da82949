//! The canvas every figure draws on: its size, palette and text sizes, and the two files
//! it becomes (an SVG sized in inches, and a 300 dpi PNG drawn at twice its size and averaged
//! down), each written atomically.

use super::font::FAMILY;
use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Width of every figure in logical pixels (the SVG's view box; see [`PX_PER_INCH`]).
pub const WIDTH: u32 = 640;
/// Height of every figure in logical pixels.
pub const HEIGHT: u32 = 480;
/// Logical pixels per inch: a figure is 6.4 x 4.8 in, the width of a two-column paper's
/// text (a figure* in IEEE or ACM), where the 14 px tick labels are 10 pt and the
/// smallest text (footnotes, 11 px) 8 pt.
pub const PX_PER_INCH: u32 = 100;
/// Resolution of the PNG, stated in its pHYs chunk.
pub const PNG_DPI: u32 = 300;
/// PNG pixels per logical pixel: the PNG is 1920 x 1440.
pub const PNG_SCALE: u32 = PNG_DPI / PX_PER_INCH;
/// The PNG is drawn this many times larger still, then box-filtered down (anti-aliasing).
const SUPERSAMPLE: u32 = 2;

/// Axes, ticks and frames: dark grey, so pure black stays a series colour.
pub(super) const INK: RGBColor = RGBColor(0x33, 0x33, 0x33);
pub(super) const TITLE_PX: f64 = 20.0;
pub(super) const LABEL_PX: f64 = 16.0;
pub(super) const TICK_PX: f64 = 14.0;
pub(super) const LEGEND_PX: f64 = 14.0;
pub(super) const NOTE_PX: f64 = 11.0;
pub(super) const LINE_W: u32 = 2;
pub(super) const TICK_LEN: i32 = 4;

pub(super) type DrawResult<T = ()> =
    std::result::Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// Pixel scale (1 for SVG, [`SUPERSAMPLE`] for the PNG's large canvas) and the kind of
/// canvas, for what plotters draws differently on a bitmap (see [`stroke`](super::layout::stroke)).
#[derive(Debug, Clone, Copy)]
pub(super) struct Scale(pub(super) u32, pub(super) Canvas);

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Canvas {
    Vector,
    Bitmap,
}

impl Scale {
    pub(super) const SVG: Scale = Scale(1, Canvas::Vector);
    const PNG: Scale = Scale(PNG_SCALE * SUPERSAMPLE, Canvas::Bitmap);

    pub(super) fn u(self, v: u32) -> u32 {
        v * self.0
    }
    pub(super) fn i(self, v: i32) -> i32 {
        v * self.0 as i32
    }
    pub(super) fn font(self, px: f64) -> FontDesc<'static> {
        (FAMILY, px * f64::from(self.0)).into_font()
    }
}

/// A figure that can draw itself on any plotters backend.
pub(super) trait Figure {
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
pub(super) fn render(stem: &Path, fig: &impl Figure) -> Result<()> {
    let (svg_path, png_path) = outputs(stem)?;

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, HEIGHT)).into_drawing_area();
        fig.draw(&root, Scale::SVG)
            .and_then(|()| Ok(root.present()?))
            .map_err(|e| draw_error(&svg_path, &*e))?;
    }
    atomic_write(&svg_path, physical_size(&svg).as_bytes())?;

    let (bw, bh) = (WIDTH * Scale::PNG.0, HEIGHT * Scale::PNG.0);
    let mut big = vec![255u8; (bw * bh * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut big, (bw, bh)).into_drawing_area();
        fig.draw(&root, Scale::PNG)
            .and_then(|()| Ok(root.present()?))
            .map_err(|e| draw_error(&png_path, &*e))?;
    }
    let (w, h) = (WIDTH * PNG_SCALE, HEIGHT * PNG_SCALE);
    write_png(&png_path, &downsample(&big, w, h, SUPERSAMPLE), (w, h))
}

/// The SVG with its printed size in inches (plotters writes it in pixels, which a viewer
/// or LaTeX reads at 96 per inch): the same size as the PNG.
fn physical_size(svg: &str) -> String {
    let px = format!("<svg width=\"{WIDTH}\" height=\"{HEIGHT}\" ");
    let inch = |v: u32| {
        let s = format!("{:.2}", f64::from(v) / f64::from(PX_PER_INCH));
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    };
    svg.replacen(
        &px,
        &format!(
            "<svg width=\"{}in\" height=\"{}in\" ",
            inch(WIDTH),
            inch(HEIGHT)
        ),
        1,
    )
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

/// Encodes RGB pixels as PNG in memory, with a pHYs chunk saying [`PNG_DPI`] (so a word
/// processor or LaTeX places it at its printed size), and writes it atomically, so no
/// temporary of a guessable name is opened.
fn write_png(path: &Path, rgb: &[u8], (w, h): (u32, u32)) -> Result<()> {
    let mut png = Vec::new();
    let mut enc = png::Encoder::new(&mut png, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let per_metre = (f64::from(PNG_DPI) / 0.0254).round() as u32;
    enc.set_pixel_dims(Some(png::PixelDimensions {
        xppu: per_metre,
        yppu: per_metre,
        unit: png::Unit::Meter,
    }));
    enc.write_header()
        .and_then(|mut wr| wr.write_image_data(rgb))
        .map_err(|e| draw_error(path, &e))?;
    atomic_write(path, &png)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_stem_is_an_input_error() {
        assert!(matches!(outputs(Path::new("")), Err(Error::Input(_))));
        assert!(matches!(outputs(Path::new("figs/")), Err(Error::Input(_))));
        let (s, p) = outputs(Path::new("figs/rastrigin_d2.5")).unwrap();
        assert_eq!(s, Path::new("figs/rastrigin_d2.5.svg"));
        assert_eq!(p, Path::new("figs/rastrigin_d2.5.png"));
    }
}
