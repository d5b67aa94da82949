//! The canvas every figure draws on: its size, palette and text sizes, and the two files
//! it becomes (an SVG, and a PNG drawn at 3x and averaged down), each written atomically.

use super::font::FAMILY;
use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
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

/// Colour of series `i`.
pub fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

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
    const PNG: Scale = Scale(SUPERSAMPLE, Canvas::Bitmap);

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

/// Encodes RGB pixels as PNG in memory (the encoder plotters' bitmap backend uses, with
/// its defaults: the same bytes) and writes them atomically, so no temporary of a
/// guessable name is opened.
fn write_png(path: &Path, rgb: &[u8]) -> Result<()> {
    use image::ImageEncoder;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(rgb, WIDTH, HEIGHT, image::ColorType::Rgb8)
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
