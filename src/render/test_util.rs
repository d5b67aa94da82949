//! Test helpers shared by the figure tests: trial records, demo data, and reading back
//! the SVG and PNG a figure wrote.

use super::ConvergenceSeries;
use super::canvas::{HEIGHT, PNG_DPI, PNG_SCALE, WIDTH};
use super::style::{DASHES, series_style};
use crate::harness::TrialRecord;
use plotters::prelude::*;
use std::path::Path;

pub(super) fn record(
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

pub(super) struct Files {
    pub(super) svg: String,
    pub(super) png: Vec<u8>,
}

pub(super) fn files(dir: &Path, stem: &str) -> Files {
    let svg = std::fs::read_to_string(dir.join(format!("{stem}.svg"))).unwrap();
    let png = std::fs::read(dir.join(format!("{stem}.png"))).unwrap();
    Files { svg, png }
}

/// Number of <text> elements whose content is exactly `s`.
pub(super) fn texts(svg: &str, s: &str) -> usize {
    svg.matches(&format!(">\n{s}\n</text>")).count()
}

/// Elements named `tag` with attribute `attr` = `value`.
pub(super) fn count(svg: &str, tag: &str, attr: &str, value: &str) -> usize {
    svg.split('<')
        .filter(|e| e.starts_with(tag) && e.contains(&format!("{attr}=\"{value}\"")))
        .count()
}

pub(super) fn hex(c: RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

pub(super) fn check_common(f: &Files, title: &str, labels: &[&str]) {
    let svg = f.svg.trim();
    assert!(svg.starts_with("<svg"), "{}", &svg[..50]);
    assert!(svg.ends_with("</svg>"));
    // Printed size in inches, the view box in logical pixels.
    assert!(
        svg.starts_with(&format!(
            "<svg width=\"6.4in\" height=\"4.8in\" viewBox=\"0 0 {WIDTH} {HEIGHT}\""
        )),
        "{}",
        &svg[..80]
    );
    assert_eq!(texts(svg, title), 1, "title");
    for l in labels {
        assert_eq!(texts(svg, l), 1, "label {l}");
    }

    assert_eq!(&f.png[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(&f.png[12..16], b"IHDR");
    let w = u32::from_be_bytes(f.png[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(f.png[20..24].try_into().unwrap());
    let (w_px, h_px) = (WIDTH * PNG_SCALE, HEIGHT * PNG_SCALE);
    assert_eq!((w, h), (w_px, h_px));
    // The title (text rendered with the bundled font) darkens the top strip.
    let decoder = png::Decoder::new(std::io::Cursor::new(&f.png));
    let mut reader = decoder.read_info().unwrap();
    // 300 dpi in the pHYs chunk: 11811 pixels per metre.
    let dims = reader.info().pixel_dims.expect("a pHYs chunk");
    assert_eq!(dims.unit, png::Unit::Meter);
    assert_eq!((dims.xppu, dims.yppu), (11811, 11811));
    assert_eq!((f64::from(dims.xppu) * 0.0254).round() as u32, PNG_DPI);
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let ch = info.color_type.samples();
    let dark = (0..30 * PNG_SCALE)
        .flat_map(|y| (w_px / 4..3 * w_px / 4).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let i = (y * w_px + x) as usize * ch;
            buf[i..i + 3].iter().all(|&v| v < 100)
        })
        .count();
    assert!(
        dark > 50 * (PNG_SCALE * PNG_SCALE) as usize,
        "only {dark} dark pixels in the title strip"
    );
}

pub(super) fn only_outputs(dir: &Path, stem: &str) {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, vec![format!("{stem}.png"), format!("{stem}.svg")]);
}

pub(super) fn demo_series() -> Vec<ConvergenceSeries> {
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

/// Points of each polyline drawn in colour `c`.
pub(super) fn polylines(svg: &str, c: RGBColor) -> Vec<Vec<(f64, f64)>> {
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

/// A piezo-like record: `n` samples over 2 s of a 1 Hz sine 0..100 V; measured output
/// 0.13 u minus a tanh of a play operator's lag (hysteresis), plus deterministic noise
/// of amplitude `noise`; two models slightly off.
pub(super) struct Record {
    pub(super) t: Vec<f64>,
    pub(super) u: Vec<f64>,
    pub(super) measured: Vec<f64>,
    pub(super) models: Vec<(String, Vec<f64>)>,
}

pub(super) fn piezo(n: usize, noise: f64) -> Record {
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

/// Length of a polyline.
fn length(line: &[(f64, f64)]) -> f64 {
    line.windows(2)
        .map(|w| ((w[1].0 - w[0].0).powi(2) + (w[1].1 - w[0].1).powi(2)).sqrt())
        .sum()
}

/// Checks that series `i` of `n` is drawn in its style ([`series_style`]): lines in its
/// colour, dashed (every polyline no longer than the pattern's longest dash, give or take
/// the rounding to whole pixels) or solid (one line longer than that); with `markers`, at
/// least one marker on the line besides the legend's (a filled polygon or circle).
pub(super) fn check_styled(svg: &str, i: usize, markers: bool) {
    let st = series_style(i);
    let lines = polylines(svg, st.color);
    assert!(!lines.is_empty(), "series {i}: no line");
    let longest = lines.iter().map(|l| length(l)).fold(0.0, f64::max);
    let dash = DASHES[st.dash];
    let on = dash.iter().step_by(2).copied().fold(0.0, f64::max);
    if dash.is_empty() {
        assert!(longest > 20.0, "series {i}: solid, longest line {longest}");
    } else {
        assert!(lines.len() > 2, "series {i}: {} dashes", lines.len());
        assert!(longest <= on + 2.0, "series {i}: a dash of {longest} px");
    }
    if markers {
        let c = hex(st.color);
        let marks =
            count(svg, "polygon opacity=\"1\"", "fill", &c) + count(svg, "circle", "fill", &c);
        assert!(marks >= 2, "series {i}: {marks} markers");
    }
}
