//! Axes in plot space (a log axis is linear in log10), their ticks and tick labels.

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};

/// Floor for values <= 0 on a log axis that has no positive finite value at all.
pub const LOG_FLOOR_NO_POSITIVE: f64 = 1e-16;

/// One axis in plot space: values go through `log10` on a log axis, so both kinds of axis
/// are plain linear ranges to plotters and ticks are chosen here.
#[derive(Debug, Clone)]
pub(super) struct Axis {
    log: bool,
    /// Plot-space range.
    pub(super) lo: f64,
    pub(super) hi: f64,
    /// Data value that values <= 0 are drawn at (log axes).
    pub(super) floor: f64,
    /// Whether some value <= 0 was moved to the floor.
    pub(super) clamped: bool,
    pub(super) ticks: Vec<f64>,
    minor: Vec<f64>,
    /// Category names instead of numbers (box plots); tick labels are drawn by the figure.
    pub(super) categorical: bool,
}

impl Axis {
    /// An axis showing `values` (NaN and +inf ignored), widened by `pad` of its span each
    /// side, with at most about `max_ticks` labelled ticks.
    pub(super) fn fit(log: bool, values: &[f64], pad: f64, max_ticks: usize) -> Axis {
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
    pub(super) fn with_headroom(&self, frac: f64, max_ticks: usize) -> Axis {
        let mut a = self.clone();
        a.hi = a.lo + (a.hi - a.lo) / (1.0 - frac);
        a.retick(max_ticks);
        a
    }

    /// A fixed linear axis with given ticks.
    pub(super) fn fixed(lo: f64, hi: f64, ticks: Vec<f64>, minor: Vec<f64>) -> Axis {
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
    pub(super) fn categories(n: usize) -> Axis {
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
    pub(super) fn to_plot(&self, v: f64) -> Option<f64> {
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
    pub(super) fn label(&self, t: f64) -> String {
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

    pub(super) fn spec(&self) -> AxisCoord {
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
pub(super) struct AxisCoord {
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
pub(super) fn fmt_num(v: f64) -> String {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
