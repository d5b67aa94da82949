//! Box plots of final values, one Tukey box per group, names under the boxes.

use super::axes::Axis;
use super::canvas::{DrawResult, Figure, Scale, TICK_LEN, TICK_PX, render};
use super::font;
use super::layout::{MARGIN_LEFT, TICK_LINE, clamp_note, frame, side_areas};
use super::style::color;
use crate::base::error::Result;
use crate::stats::quantile_sorted;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

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
/// ("GA (2 non-finite)"). Values <= 0 on a log axis: see [the kit](super).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::test_util::*;
    use crate::render::{HEIGHT, WIDTH};

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
}
