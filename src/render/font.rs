//! The font of every figure: DejaVu Sans, compiled into the binary (from the `dejavu` crate)
//! and handed to plotters' pure-Rust `ab_glyph` text renderer.
//!
//! plotters with its default `ttf` feature asks fontconfig/freetype for system fonts, so on a
//! machine without fonts both SVG (text is measured for layout) and PNG fail. The `ab_glyph`
//! feature never looks at the system: it only knows the fonts registered here, by family
//! name, before anything is drawn. [`register`] does that once per process; every public
//! plotting function calls it first.

use crate::base::error::{Error, Result};
use plotters::style::{FontStyle, register_font};
use std::sync::OnceLock;

/// Family name the bundled font is registered under and every figure uses. The generic
/// CSS name, so an SVG viewer without DejaVu substitutes a similar sans-serif font.
pub const FAMILY: &str = "sans-serif";

static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();

/// Registers DejaVu Sans (regular and bold; other styles fall back to regular) as
/// [`FAMILY`]. Cheap after the first call; safe to call from many threads.
pub fn register() -> Result<()> {
    REGISTERED
        .get_or_init(|| {
            for (style, bytes) in [
                (FontStyle::Normal, dejavu::sans::regular()),
                (FontStyle::Bold, dejavu::sans::bold()),
            ] {
                register_font(FAMILY, style, bytes).map_err(|_| {
                    format!(
                        "bundled DejaVu Sans ({}) is not a usable font",
                        style.as_str()
                    )
                })?;
            }
            Ok(())
        })
        .clone()
        .map_err(|msg| Error::io("registering the plot font", std::io::Error::other(msg)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use plotters::style::{FontDesc, IntoFont};

    #[test]
    fn registered_font_measures_text() {
        register().unwrap();
        register().unwrap();
        let font: FontDesc = (FAMILY, 20.0).into_font();
        let (w, h) = font.box_size("function evaluations").unwrap();
        assert!(w > 100 && h > 10, "{w}x{h}");
        let bold = font.style(FontStyle::Bold);
        assert!(bold.box_size("x").unwrap().0 > 0);
    }
}
