//! Gaussian radial-basis-function (RBF) networks and the NARX hysteresis model built on them
//! (dissertation §3.2, eq. 3.10-3.19), with the dissertation's back-propagation (BP) baseline.
//!
//! The network is deliberately generic (`inputs`-`hidden`-1, gradients with respect to both
//! parameters and inputs) because the same code is the 2-7-1 controller of dissertation §4.1
//! (eq. 4.3-4.8), trained online through the plant model.
//!
//! # Parameter vector layout
//!
//! For a net with `I` inputs and `H` hidden nodes, a parameter vector `p` has
//! `H * (I + 2)` entries:
//!
//! | range                     | meaning                                            |
//! |---------------------------|----------------------------------------------------|
//! | `p[0 .. H*I]`             | centres `c_j`, row-major: `c_j = p[j*I .. (j+1)*I]` |
//! | `p[H*I .. H*I + H]`       | widths `b_j`                                       |
//! | `p[H*I + H .. H*(I + 2)]` | output weights `w_j`                               |
//!
//! The dissertation's 3-7-1 net therefore has 21 + 7 + 7 = 35 parameters (its "individual length 35").
//!
//! # Model modes
//!
//! [`Mode::OneStepAhead`] feeds the *measured* past outputs into the regressors, as the dissertation
//! did; it is easy to fit and flatters the model, since each prediction is corrected by the
//! measurement. [`Mode::FreeRun`] feeds back the model's *own* past outputs: a simulation from
//! the input alone, which is what a model used for control must do.

/// Smallest width magnitude the network uses: `b²` is floored at `WIDTH_FLOOR²` so that a
/// zero (or NaN) width gives a finite, extremely narrow Gaussian instead of `0/0`. In the
/// units of the regressors (e.g. V, mm), 1e-9 is far below any meaningful width. Below the
/// floor the output no longer depends on the width, and its gradient is zero.
pub const WIDTH_FLOOR: f64 = 1e-9;
const B2_MIN: f64 = WIDTH_FLOOR * WIDTH_FLOOR;

/// Errors are saturated at `CAP_FACTOR` times the output scale of the measured data (see
/// [`output_scale`]); far beyond anything a sane model produces, it only keeps costs finite.
pub const CAP_FACTOR: f64 = 1e3;

/// Optimizer bounds for output weights: `±WEIGHT_BOUND_FACTOR` times the output scale. With
/// overlapping Gaussians, weights a few times the output magnitude are needed to shape the
/// output (neighbouring nodes partly cancel); BP fits of the dissertation's eq. 3.18 data stay well
/// inside this.
pub const WEIGHT_BOUND_FACTOR: f64 = 10.0;

/// Lower optimizer bound for widths, as a fraction of the regressor box diagonal: narrower
/// Gaussians fall between neighbouring samples of typical records and only overfit.
pub const WIDTH_BOUND_LO_FRAC: f64 = 1e-2;

/// An `inputs`-`hidden`-1 Gaussian RBF network (dissertation eq. 3.12, 3.14):
/// `h_j = exp(-‖x - c_j‖² / (2 b_j²))`, `y = Σ_j w_j h_j`. No bias term, as in the dissertation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RbfNet {
    pub inputs: usize,
    pub hidden: usize,
}

impl RbfNet {
    /// The dissertation's 3-7-1 hysteresis model (§3.2).
    pub const SEED: RbfNet = RbfNet {
        inputs: 3,
        hidden: 7,
    };

    /// The dissertation's 2-7-1 controller (§4.1).
    pub const CONTROLLER: RbfNet = RbfNet {
        inputs: 2,
        hidden: 7,
    };

    pub const fn new(inputs: usize, hidden: usize) -> Self {
        RbfNet { inputs, hidden }
    }

    /// Length of a parameter vector: `hidden * (inputs + 2)`.
    pub const fn n_params(&self) -> usize {
        self.hidden * (self.inputs + 2)
    }

    /// Index of the first width `b_0` in a parameter vector.
    pub const fn width_offset(&self) -> usize {
        self.hidden * self.inputs
    }

    /// Index of the first output weight `w_0` in a parameter vector.
    pub const fn weight_offset(&self) -> usize {
        self.hidden * (self.inputs + 1)
    }

    /// Splits `p` into (centres, widths, weights).
    fn split<'a>(&self, p: &'a [f64]) -> (&'a [f64], &'a [f64], &'a [f64]) {
        assert!(self.inputs > 0, "an RBF net needs at least one input");
        assert_eq!(p.len(), self.n_params(), "parameter vector length");
        let (c, rest) = p.split_at(self.width_offset());
        let (b, w) = rest.split_at(self.hidden);
        (c, b, w)
    }

    /// Network output `y(x)`.
    ///
    /// Finite for finite `p` and `x` (zero widths included), unless the weights are so large
    /// that their sum overflows.
    pub fn eval(&self, p: &[f64], x: &[f64]) -> f64 {
        let (c, b, w) = self.split(p);
        assert_eq!(x.len(), self.inputs, "input length");
        let mut y = 0.0;
        for ((cj, &bj), &wj) in c.chunks_exact(self.inputs).zip(b).zip(w) {
            y += wj * (exponent_factor(bj) * dist2(x, cj)).exp();
        }
        y
    }

    /// Output `y(x)`; overwrites `grad` (length [`Self::n_params`]) with `∂y/∂p` in the
    /// parameter layout. This is the per-sample building block of BP (dissertation eq. 4.6-4.8) and of
    /// [`Regressors::cost_grad`].
    pub fn eval_grad(&self, p: &[f64], x: &[f64], grad: &mut [f64]) -> f64 {
        let (c, b, w) = self.split(p);
        assert_eq!(x.len(), self.inputs, "input length");
        assert_eq!(grad.len(), p.len(), "gradient length");
        let (ni, nh) = (self.inputs, self.hidden);
        let (gc, rest) = grad.split_at_mut(nh * ni);
        let (gb, gw) = rest.split_at_mut(nh);
        let mut y = 0.0;
        for j in 0..nh {
            let cj = &c[j * ni..(j + 1) * ni];
            let (d2, b2) = (dist2(x, cj), width2(b[j]));
            let h = (exponent_factor(b[j]) * d2).exp();
            y += w[j] * h;
            gw[j] = h;
            // ∂(w h)/∂c = w h (x - c) / b², ∂(w h)/∂b = w h ‖x - c‖² / b³.
            let a = w[j] * h / b2;
            for ((g, xi), ci) in gc[j * ni..(j + 1) * ni].iter_mut().zip(x).zip(cj) {
                *g = a * (xi - ci);
            }
            // Outside the clamp of `width2` the output does not depend on b.
            gb[j] = if (B2_MIN..=f64::MAX).contains(&(b[j] * b[j])) {
                a * d2 / b[j]
            } else {
                0.0
            };
        }
        y
    }

    /// Output `y(x)`; overwrites `dx` (length [`Self::inputs`]) with `∂y/∂x`. The controller of
    /// dissertation §4.1 back-propagates the tracking error through the plant model with this.
    pub fn input_grad(&self, p: &[f64], x: &[f64], dx: &mut [f64]) -> f64 {
        let (c, b, w) = self.split(p);
        assert_eq!(x.len(), self.inputs, "input length");
        assert_eq!(dx.len(), self.inputs, "input gradient length");
        dx.fill(0.0);
        let mut y = 0.0;
        for ((cj, &bj), &wj) in c.chunks_exact(self.inputs).zip(b).zip(w) {
            let (d2, b2) = (dist2(x, cj), width2(bj));
            let h = (exponent_factor(bj) * d2).exp();
            y += wj * h;
            let a = wj * h / b2;
            for ((g, xi), ci) in dx.iter_mut().zip(x).zip(cj) {
                *g -= a * (xi - ci);
            }
        }
        y
    }
}

/// `b²` kept in `[WIDTH_FLOOR², f64::MAX]` (a NaN width counts as the floor, an overflowing
/// one as `f64::MAX`), so that `-d²/(2b²)` is never `0/0` or `0·∞`.
#[inline(always)]
#[allow(clippy::manual_clamp)] // `clamp` would keep a NaN; `max` maps it to the floor.
fn width2(b: f64) -> f64 {
    (b * b).max(B2_MIN).min(f64::MAX)
}

/// `-1 / (2 b²)`: `h = exp(exponent_factor(b) · d²)`. Every evaluation path uses this same
/// expression, so they agree to the last bit.
#[inline(always)]
pub(crate) fn exponent_factor(b: f64) -> f64 {
    -0.5 / width2(b)
}

#[inline(always)]
fn dist2(x: &[f64], c: &[f64]) -> f64 {
    x.iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum()
}

/// NARX regressor structure: `x(k) = [r(k), r(k-1), …, r(k-input_lags+1), y(k-1), …,
/// y(k-output_lags)]`, with `r` the drive input and `y` the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Narx {
    pub input_lags: usize,
    pub output_lags: usize,
}

impl Narx {
    /// The dissertation's 3-input model (eq. 3.10): `x = [r(k), r(k-1), y(k-1)]`.
    pub const SEED: Narx = Narx {
        input_lags: 2,
        output_lags: 1,
    };

    /// Our reading of the dissertation's 7-input variant (§3.2.3, Fig. 3.23), whose inputs the dissertation
    /// does not list: `x = [r(k), …, r(k-3), y(k-1), …, y(k-3)]`.
    pub const SEED_7: Narx = Narx {
        input_lags: 4,
        output_lags: 3,
    };

    /// Number of regressors (network inputs).
    pub const fn dim(&self) -> usize {
        self.input_lags + self.output_lags
    }

    /// First sample that can be predicted: every lag is inside the record from here on.
    /// Samples before it are initial conditions, taken from the measurement.
    pub const fn start(&self) -> usize {
        let a = self.input_lags.saturating_sub(1);
        if a > self.output_lags {
            a
        } else {
            self.output_lags
        }
    }

    /// Fills `x` with the regressors of sample `k` (`k >= start()`), reading past outputs
    /// from `y` (measured or simulated, as the caller chooses).
    pub fn regressor(&self, r: &[f64], y: &[f64], k: usize, x: &mut [f64]) {
        debug_assert!(k >= self.start() && x.len() == self.dim());
        let (xr, xy) = x.split_at_mut(self.input_lags);
        for (i, v) in xr.iter_mut().enumerate() {
            *v = r[k - i];
        }
        for (i, v) in xy.iter_mut().enumerate() {
            *v = y[k - 1 - i];
        }
    }

    fn check(&self, net: &RbfNet, r: &[f64], y: &[f64]) {
        assert!(self.dim() > 0, "NARX model without regressors");
        assert_eq!(net.inputs, self.dim(), "net inputs vs NARX regressors");
        assert_eq!(r.len(), y.len(), "input and output lengths");
    }
}

/// How past outputs enter the regressors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Measured past outputs (the dissertation's choice; a prediction one step ahead).
    OneStepAhead,
    /// The model's own past outputs (a simulation from the input only).
    FreeRun,
}

/// Output scale used for error caps and weight bounds:
/// `max(y_hi - y_lo, |y_lo|, |y_hi|)` (range and offset both count, as the net has no bias),
/// 1 if that is zero or not finite.
pub fn output_scale(y_lo: f64, y_hi: f64) -> f64 {
    let s = (y_hi - y_lo).max(y_lo.abs()).max(y_hi.abs());
    if s > 0.0 && s.is_finite() { s } else { 1.0 }
}

/// Min and max of the finite values of `v` (NaN are skipped; (0, 0) if there are none).
fn min_max(v: &[f64]) -> (f64, f64) {
    let (lo, hi) = v
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
    if lo <= hi { (lo, hi) } else { (0.0, 0.0) }
}

/// The error cap for measured outputs `y`: [`CAP_FACTOR`] × [`output_scale`], at most 1e100
/// so that sums of squared caps stay finite.
pub(crate) fn error_cap(y: &[f64]) -> f64 {
    let (lo, hi) = min_max(y);
    (CAP_FACTOR * output_scale(lo, hi)).min(1e100)
}

/// Model outputs for the whole record into `out` (same length as `r` and `y_meas`).
///
/// The first [`Narx::start`] samples are initial conditions: `out[k] = y_meas[k]` there, in
/// both modes. Outputs are not sanitised: a diverging free run shows up as huge or NaN values.
pub fn predict(
    net: &RbfNet,
    narx: &Narx,
    p: &[f64],
    r: &[f64],
    y_meas: &[f64],
    mode: Mode,
    out: &mut [f64],
) {
    narx.check(net, r, y_meas);
    assert_eq!(out.len(), r.len(), "output length");
    let n = r.len();
    let s = narx.start().min(n);
    out[..s].copy_from_slice(&y_meas[..s]);
    let mut x = vec![0.0; narx.dim()];
    for k in s..n {
        match mode {
            Mode::OneStepAhead => narx.regressor(r, y_meas, k, &mut x),
            Mode::FreeRun => narx.regressor(r, out, k, &mut x),
        }
        out[k] = net.eval(p, &x);
    }
}

/// Fitting cost `L = Σ_k e(k)²/2` over the samples after the initial conditions (dissertation eq.
/// 3.17, 3.19), `e = y_model - y_meas`. Always finite, for any `p`:
///
/// - one-step-ahead: each `|e|` is saturated at the cap ([`CAP_FACTOR`] × output scale of
///   `y_meas`; NaN counts as the cap);
/// - free run: at the first sample `k` where `|e|` exceeds the cap (or is NaN) the simulation
///   is declared diverged and stops; the cost is the sum so far plus `cap²` for each of the
///   remaining samples (twice the most any non-diverged sample can add), so the penalty
///   exceeds any non-diverged continuation and grows the earlier divergence happens.
pub fn cost(net: &RbfNet, narx: &Narx, p: &[f64], r: &[f64], y_meas: &[f64], mode: Mode) -> f64 {
    match mode {
        Mode::OneStepAhead => Regressors::new(narx, r, y_meas).cost(net, p),
        Mode::FreeRun => free_run_cost(net, narx, p, r, y_meas),
    }
}

/// One-step-ahead cost (as [`cost`]) and its gradient `∂L/∂p` written into `grad`. Builds the
/// regressors on each call; reuse a [`Regressors`] to fit the same data repeatedly.
pub fn cost_grad(
    net: &RbfNet,
    narx: &Narx,
    p: &[f64],
    r: &[f64],
    y_meas: &[f64],
    grad: &mut [f64],
) -> f64 {
    Regressors::new(narx, r, y_meas).cost_grad(net, p, grad)
}

fn free_run_cost(net: &RbfNet, narx: &Narx, p: &[f64], r: &[f64], y: &[f64]) -> f64 {
    narx.check(net, r, y);
    let n = r.len();
    let s = narx.start().min(n);
    let cap = error_cap(y);
    let mut out = y.to_vec();
    let mut x = vec![0.0; narx.dim()];
    let mut sum = 0.0;
    for k in s..n {
        narx.regressor(r, &out, k, &mut x);
        let ym = net.eval(p, &x);
        let e = ym - y[k];
        if e.is_nan() || e.abs() > cap {
            return sum + (n - k) as f64 * cap * cap;
        }
        sum += 0.5 * e * e;
        out[k] = ym;
    }
    sum
}

/// One-step-ahead training data: every regressor row computed once from the measured record,
/// so that repeated cost evaluations (an optimizer, BP epochs) are a tight loop over samples
/// with no recurrence.
#[derive(Debug, Clone, PartialEq)]
pub struct Regressors {
    dim: usize,
    /// Row-major, `len() * dim` values.
    x: Vec<f64>,
    target: Vec<f64>,
    cap: f64,
}

impl Regressors {
    /// Regressors of samples `narx.start()..` of the record `(r, y)` (measured outputs).
    pub fn new(narx: &Narx, r: &[f64], y: &[f64]) -> Self {
        assert!(narx.dim() > 0, "NARX model without regressors");
        assert_eq!(r.len(), y.len(), "input and output lengths");
        let (n, d) = (r.len(), narx.dim());
        let s = narx.start().min(n);
        let mut x = vec![0.0; (n - s) * d];
        for (k, row) in (s..n).zip(x.chunks_exact_mut(d)) {
            narx.regressor(r, y, k, row);
        }
        Regressors {
            dim: d,
            x,
            target: y[s..].to_vec(),
            cap: error_cap(y),
        }
    }

    /// Number of samples in the cost.
    pub fn len(&self) -> usize {
        self.target.len()
    }

    pub fn is_empty(&self) -> bool {
        self.target.is_empty()
    }

    /// Number of regressors per sample.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Regressor row `i` (sample `start + i`).
    pub fn row(&self, i: usize) -> &[f64] {
        &self.x[i * self.dim..(i + 1) * self.dim]
    }

    /// The measured outputs being fitted.
    pub fn targets(&self) -> &[f64] {
        &self.target
    }

    /// Per-regressor (min, max) over the record: input ranges for [`init_params`] and
    /// [`param_bounds`].
    pub fn input_ranges(&self) -> (Vec<f64>, Vec<f64>) {
        let mut lo = vec![f64::INFINITY; self.dim];
        let mut hi = vec![f64::NEG_INFINITY; self.dim];
        for row in self.x.chunks_exact(self.dim) {
            for ((l, h), &v) in lo.iter_mut().zip(hi.iter_mut()).zip(row) {
                *l = l.min(v);
                *h = h.max(v);
            }
        }
        for (l, h) in lo.iter_mut().zip(hi.iter_mut()) {
            if *l > *h {
                (*l, *h) = (0.0, 0.0);
            }
        }
        (lo, hi)
    }

    /// (min, max) of the fitted outputs.
    pub fn output_range(&self) -> (f64, f64) {
        min_max(&self.target)
    }

    /// One-step-ahead cost `Σ e²/2` (see [`cost`] for the saturation that keeps it finite).
    pub fn cost(&self, net: &RbfNet, p: &[f64]) -> f64 {
        let (c, b, w) = net.split(p);
        assert_eq!(net.inputs, self.dim, "net inputs vs regressors");
        // -1/(2 b²) once per node instead of a division per node and sample.
        let k: Vec<f64> = b.iter().map(|&b| exponent_factor(b)).collect();
        let cap = self.cap;
        let mut sum = 0.0;
        for (x, &t) in self.x.chunks_exact(self.dim).zip(&self.target) {
            let mut ym = 0.0;
            for ((cj, &kj), &wj) in c.chunks_exact(self.dim).zip(&k).zip(w) {
                ym += wj * (kj * dist2(x, cj)).exp();
            }
            // NaN.min(cap) is cap: a NaN output costs as much as a saturated one.
            let e = (ym - t).abs().min(cap);
            sum += 0.5 * e * e;
        }
        sum
    }

    /// One-step-ahead cost and its gradient `∂L/∂p` (overwriting `grad`). Saturated samples
    /// (`|e|` at the cap) contribute no gradient, consistently with the saturated cost;
    /// non-finite gradient entries (possible only for absurd parameters) are set to 0 so a
    /// gradient step never injects NaN.
    pub fn cost_grad(&self, net: &RbfNet, p: &[f64], grad: &mut [f64]) -> f64 {
        assert_eq!(net.inputs, self.dim, "net inputs vs regressors");
        assert_eq!(grad.len(), p.len(), "gradient length");
        grad.fill(0.0);
        let mut g = vec![0.0; p.len()];
        let mut sum = 0.0;
        for (x, &t) in self.x.chunks_exact(self.dim).zip(&self.target) {
            let e = net.eval_grad(p, x, &mut g) - t;
            if e.abs() < self.cap {
                sum += 0.5 * e * e;
                for (gi, &di) in grad.iter_mut().zip(&g) {
                    *gi += e * di;
                }
            } else {
                sum += 0.5 * self.cap * self.cap;
            }
        }
        for gi in grad.iter_mut() {
            if !gi.is_finite() {
                *gi = 0.0;
            }
        }
        sum
    }
}

/// Max absolute and RMS error of a fit (the metrics of dissertation Table 3.3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitErrors {
    pub max_abs: f64,
    pub rms: f64,
}

/// Errors of `y_model` against `y_meas` over samples `start..` (skip the initial conditions).
pub fn fit_errors(y_meas: &[f64], y_model: &[f64], start: usize) -> FitErrors {
    assert_eq!(y_meas.len(), y_model.len(), "lengths");
    let s = start.min(y_meas.len());
    let (mut max_abs, mut ss) = (0.0f64, 0.0);
    for (a, b) in y_meas[s..].iter().zip(&y_model[s..]) {
        let e = (a - b).abs();
        max_abs = max_abs.max(e);
        ss += e * e;
    }
    let n = (y_meas.len() - s).max(1) as f64;
    FitErrors {
        max_abs: if ss.is_nan() { f64::NAN } else { max_abs },
        rms: (ss / n).sqrt(),
    }
}

/// The dissertation's numerical identification plant (eq. 3.18):
/// `y[k] = 0.9802 y[k-1] - 0.3406 r[k] + 0.3306 r[k-1]`, at rest before the record
/// (`y[-1] = r[-1] = 0`, so `y[0] = -0.3406 r[0]`). The dissertation drives it with a 20 Hz sine
/// sampled at 1 ms.
pub fn eq_3_18(r: &[f64]) -> Vec<f64> {
    let mut y = Vec::with_capacity(r.len());
    let (mut y1, mut r1) = (0.0, 0.0);
    for &rk in r {
        let yk = 0.9802 * y1 - 0.3406 * rk + 0.3306 * r1;
        y.push(yk);
        (y1, r1) = (yk, rk);
    }
    y
}

/// Widens degenerate input intervals so that `lo < hi` (bounds must be proper intervals).
fn proper_box(x_lo: &[f64], x_hi: &[f64]) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(x_lo.len(), x_hi.len(), "input range lengths");
    x_lo.iter()
        .zip(x_hi)
        .map(|(&l, &h)| {
            if h > l {
                (l, h)
            } else {
                let m = 0.5 * (l + h);
                let d = 1e-6 * m.abs().max(1.0);
                (m - d, m + d)
            }
        })
        .unzip()
}

fn diagonal(lo: &[f64], hi: &[f64]) -> f64 {
    dist2(lo, hi).sqrt()
}

/// Starting parameters from the regressor ranges `[x_lo, x_hi]`: centres evenly spaced along
/// the box diagonal (at fractions (j + ½)/H, which is where the regressors of a slowly varying
/// input with a positively responding output lie: r(k) ≈ r(k-1), y rising with r), widths
/// diagonal / H (neighbouring Gaussians overlap at h ≈ 0.6), weights 0 (the net starts at
/// y = 0 and BP first moves the weights, as ∂y/∂c and ∂y/∂b are proportional to w). Within
/// [`param_bounds`].
pub fn init_params(net: &RbfNet, x_lo: &[f64], x_hi: &[f64]) -> Vec<f64> {
    assert_eq!(x_lo.len(), net.inputs, "input range length");
    let (lo, hi) = proper_box(x_lo, x_hi);
    let diag = diagonal(&lo, &hi);
    let nh = net.hidden;
    let mut p = vec![0.0; net.n_params()];
    for j in 0..nh {
        let f = (j as f64 + 0.5) / nh as f64;
        for i in 0..net.inputs {
            p[j * net.inputs + i] = lo[i] + f * (hi[i] - lo[i]);
        }
        p[net.width_offset() + j] = (diag / nh as f64).max(WIDTH_BOUND_LO_FRAC * diag);
    }
    p
}

/// Box bounds `(lower, upper)` for optimizing a parameter vector, from the regressor ranges
/// `[x_lo, x_hi]` and the output range `[y_lo, y_hi]` of the data:
///
/// - centres inside the input ranges (degenerate ranges are widened slightly);
/// - widths in `[WIDTH_BOUND_LO_FRAC · D, D]`, `D` the box diagonal: from narrow bumps to a
///   Gaussian nearly flat over the data (negative widths are redundant, as only `b²` counts);
/// - weights in `±WEIGHT_BOUND_FACTOR` × [`output_scale`]`(y_lo, y_hi)`.
pub fn param_bounds(
    net: &RbfNet,
    x_lo: &[f64],
    x_hi: &[f64],
    y_lo: f64,
    y_hi: f64,
) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(x_lo.len(), net.inputs, "input range length");
    let (lo, hi) = proper_box(x_lo, x_hi);
    let diag = diagonal(&lo, &hi);
    let wmax = WEIGHT_BOUND_FACTOR * output_scale(y_lo, y_hi);
    let mut lower = Vec::with_capacity(net.n_params());
    let mut upper = Vec::with_capacity(net.n_params());
    for _ in 0..net.hidden {
        lower.extend_from_slice(&lo);
        upper.extend_from_slice(&hi);
    }
    lower.extend(std::iter::repeat_n(WIDTH_BOUND_LO_FRAC * diag, net.hidden));
    upper.extend(std::iter::repeat_n(diag, net.hidden));
    lower.extend(std::iter::repeat_n(-wmax, net.hidden));
    upper.extend(std::iter::repeat_n(wmax, net.hidden));
    (lower, upper)
}

/// How BP applies the momentum update `Δp = -η ∂J/∂p + β Δp_prev`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BpUpdate {
    /// One update per sample with the instantaneous cost `e(k)²/2`, samples in time order, the
    /// momentum carried across samples and epochs: dissertation eq. 4.6-4.8 literally.
    Online,
    /// One update per epoch along the *mean* per-sample gradient (∂L/∂p divided by the number
    /// of samples), so `η` has the same scale as in `Online`.
    Batch,
}

/// Back-propagation settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BpConfig {
    /// η > 0.
    pub learning_rate: f64,
    /// β in [0, 1).
    pub momentum: f64,
    /// Passes over the data.
    pub epochs: usize,
    /// Per-sample (seed) or per-epoch updates.
    pub mode: BpUpdate,
}

impl Default for BpConfig {
    /// Settings that fit the dissertation's eq. 3.18 data well (see the tests).
    fn default() -> Self {
        BpConfig {
            learning_rate: 0.1,
            momentum: 0.5,
            epochs: 300,
            mode: BpUpdate::Online,
        }
    }
}

/// Outcome of [`bp_train`].
#[derive(Debug, Clone, PartialEq)]
pub struct BpResult {
    /// The parameters with the lowest cost seen at an epoch boundary (p0 included).
    pub params: Vec<f64>,
    /// One-step-ahead cost of the initial parameters.
    pub initial_cost: f64,
    /// One-step-ahead cost `L` of the parameters held after each epoch.
    pub cost_per_epoch: Vec<f64>,
    /// Learning rate at the end (halved at each divergence guard trip).
    pub learning_rate: f64,
    /// How many times the divergence guard restored the best parameters.
    pub reverts: usize,
}

/// Divergence guard: an epoch ending with non-finite parameters or a cost above this multiple
/// of the best so far restores the best parameters, clears the momentum and halves η.
const BP_GUARD: f64 = 10.0;

/// Trains by back-propagation with momentum (the dissertation's BP baseline, update law of eq.
/// 4.6-4.8) on the one-step-ahead cost, from `p0`. Results are finite for any finite `p0`.
pub fn bp_train(
    net: &RbfNet,
    narx: &Narx,
    p0: &[f64],
    r: &[f64],
    y: &[f64],
    cfg: &BpConfig,
) -> BpResult {
    narx.check(net, r, y);
    bp_train_on(net, &Regressors::new(narx, r, y), p0, cfg)
}

/// [`bp_train`] on prepared regressors.
pub fn bp_train_on(net: &RbfNet, data: &Regressors, p0: &[f64], cfg: &BpConfig) -> BpResult {
    assert_eq!(p0.len(), net.n_params(), "parameter vector length");
    let np = p0.len();
    let beta = cfg.momentum;
    let mut eta = cfg.learning_rate;
    let mut p = p0.to_vec();
    let mut dp = vec![0.0; np];
    let mut g = vec![0.0; np];
    let mut grad = vec![0.0; np];
    let initial_cost = data.cost_grad(net, &p, &mut grad);
    let (mut best, mut best_cost) = (p.clone(), initial_cost);
    let mut cost_per_epoch = Vec::with_capacity(cfg.epochs);
    let mut reverts = 0;
    let inv_n = 1.0 / data.len().max(1) as f64;
    for _ in 0..cfg.epochs {
        let mut cost = match cfg.mode {
            BpUpdate::Online => {
                for (i, &t) in data.targets().iter().enumerate() {
                    let e = net.eval_grad(&p, data.row(i), &mut g) - t;
                    // Saturated errors give no gradient, as in the cost.
                    let e = if e.abs() < data.cap { e } else { 0.0 };
                    for ((pi, di), gi) in p.iter_mut().zip(dp.iter_mut()).zip(&g) {
                        *di = -eta * e * gi + beta * *di;
                        *pi += *di;
                    }
                }
                data.cost(net, &p)
            }
            BpUpdate::Batch => {
                for ((pi, di), gi) in p.iter_mut().zip(dp.iter_mut()).zip(&grad) {
                    *di = -eta * inv_n * gi + beta * *di;
                    *pi += *di;
                }
                data.cost_grad(net, &p, &mut grad)
            }
        };
        if !p.iter().all(|v| v.is_finite()) || cost > BP_GUARD * best_cost {
            p.copy_from_slice(&best);
            dp.fill(0.0);
            eta *= 0.5;
            reverts += 1;
            cost = match cfg.mode {
                BpUpdate::Online => best_cost,
                BpUpdate::Batch => data.cost_grad(net, &p, &mut grad),
            };
        } else if cost < best_cost {
            best.copy_from_slice(&p);
            best_cost = cost;
        }
        cost_per_epoch.push(cost);
    }
    BpResult {
        params: best,
        initial_cost,
        cost_per_epoch,
        learning_rate: eta,
        reverts,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The dissertation's numerical example: a unit 20 Hz sine sampled at 1 ms (the dissertation gives no
    /// amplitude) driving eq. 3.18.
    fn eq_3_18_data(n: usize) -> (Vec<f64>, Vec<f64>) {
        let r: Vec<f64> = (0..n)
            .map(|k| (2.0 * std::f64::consts::PI * 20.0 * k as f64 * 1e-3).sin())
            .collect();
        let y = eq_3_18(&r);
        (r, y)
    }

    /// Centres in [-1, 1], widths of either sign with magnitude in [0.3, 1.5], weights in
    /// [-2, 2]: every node active somewhere on unit-scale data.
    fn random_params(net: &RbfNet, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let mut p = vec![0.0; net.n_params()];
        for (i, v) in p.iter_mut().enumerate() {
            *v = if i < net.width_offset() {
                rng.random_range(-1.0..1.0)
            } else if i < net.weight_offset() {
                let s = if rng.random::<bool>() { 1.0 } else { -1.0 };
                s * rng.random_range(0.3..1.5)
            } else {
                rng.random_range(-2.0..2.0)
            };
        }
        p
    }

    /// Central differences of `f` at `at`, one coordinate at a time.
    fn finite_diff(f: impl Fn(&[f64]) -> f64, at: &[f64]) -> Vec<f64> {
        let mut q = at.to_vec();
        (0..at.len())
            .map(|i| {
                let h = 1e-5 * at[i].abs().max(1.0);
                q[i] = at[i] + h;
                let fp = f(&q);
                q[i] = at[i] - h;
                let fm = f(&q);
                q[i] = at[i];
                (fp - fm) / (2.0 * h)
            })
            .collect()
    }

    /// Component-wise relative error, each component measured against
    /// max(|fd_i|, 1e-3 ‖fd‖∞) so that near-zero components do not demand absolute zero.
    fn max_rel_err(analytic: &[f64], fd: &[f64]) -> f64 {
        let scale = fd.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0, "degenerate test: zero gradient");
        analytic
            .iter()
            .zip(fd)
            .map(|(a, f)| (a - f).abs() / f.abs().max(1e-3 * scale))
            .fold(0.0, f64::max)
    }

    const NETS: [RbfNet; 3] = [RbfNet::SEED, RbfNet::CONTROLLER, RbfNet::new(7, 9)];

    #[test]
    fn seed_net_has_35_params_in_documented_layout() {
        let net = RbfNet::SEED;
        assert_eq!(net.n_params(), 35);
        assert_eq!((net.width_offset(), net.weight_offset()), (21, 28));
        // Only node 4 contributes: its centre is p[12..15], width p[25], weight p[32].
        let mut p = vec![0.0; 35];
        p[12..15].copy_from_slice(&[0.1, -0.2, 0.3]);
        p[21..28].fill(1.0);
        p[25] = 0.7;
        p[32] = 1.5;
        let x = [0.4, 0.2, -0.1];
        let d2 = 0.3f64.powi(2) + 0.4f64.powi(2) + 0.4f64.powi(2);
        let expect = 1.5 * (-d2 / (2.0 * 0.49)).exp();
        assert!((net.eval(&p, &x) - expect).abs() < 1e-15);
        // A negative width is the same Gaussian.
        p[25] = -0.7;
        assert!((net.eval(&p, &x) - expect).abs() < 1e-15);
    }

    #[test]
    fn eval_grad_matches_finite_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for net in NETS {
            for _ in 0..5 {
                let p = random_params(&net, &mut rng);
                let x: Vec<f64> = (0..net.inputs)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                let mut g = vec![f64::NAN; p.len()];
                let y = net.eval_grad(&p, &x, &mut g);
                assert_eq!(y, net.eval(&p, &x));
                let fd = finite_diff(|q| net.eval(q, &x), &p);
                let err = max_rel_err(&g, &fd);
                assert!(err < 1e-6, "{net:?}: relative error {err:e}");
            }
        }
    }

    #[test]
    fn input_grad_matches_finite_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for net in NETS {
            for _ in 0..5 {
                let p = random_params(&net, &mut rng);
                let x: Vec<f64> = (0..net.inputs)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                let mut dx = vec![f64::NAN; net.inputs];
                let y = net.input_grad(&p, &x, &mut dx);
                assert_eq!(y, net.eval(&p, &x));
                let fd = finite_diff(|q| net.eval(&p, q), &x);
                let err = max_rel_err(&dx, &fd);
                assert!(err < 1e-6, "{net:?}: relative error {err:e}");
            }
        }
    }

    #[test]
    fn cost_grad_matches_finite_differences() {
        let (r, y) = eq_3_18_data(200);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for narx in [Narx::SEED, Narx::SEED_7] {
            let net = RbfNet::new(narx.dim(), 7);
            let data = Regressors::new(&narx, &r, &y);
            for _ in 0..3 {
                let p = random_params(&net, &mut rng);
                let mut g = vec![f64::NAN; p.len()];
                let j = cost_grad(&net, &narx, &p, &r, &y, &mut g);
                assert_eq!(j, data.cost(&net, &p));
                assert_eq!(j, cost(&net, &narx, &p, &r, &y, Mode::OneStepAhead));
                let fd = finite_diff(|q| data.cost(&net, q), &p);
                let err = max_rel_err(&g, &fd);
                assert!(err < 1e-6, "{narx:?}: relative error {err:e}");
            }
        }
    }

    #[test]
    fn width_below_floor_is_finite_and_has_zero_width_gradient() {
        let net = RbfNet::SEED;
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut p = random_params(&net, &mut rng);
        p[21..28].fill(0.0);
        p[0..3].copy_from_slice(&[0.5, 0.5, 0.5]);
        let mut g = vec![0.0; 35];
        // Exactly at a centre: h = exp(-0/…) = 1, elsewhere h underflows to 0.
        let y = net.eval_grad(&p, &[0.5, 0.5, 0.5], &mut g);
        assert_eq!(y, p[28]);
        assert!(g.iter().all(|v| v.is_finite()));
        assert!(g[21..28].iter().all(|&v| v == 0.0));
        // A NaN width is the floor too; an overflowing one a flat Gaussian.
        p[21] = f64::NAN;
        p[22] = 1e200;
        assert_eq!(net.eval_grad(&p, &[0.5, 0.5, 0.5], &mut g), p[28] + p[29]);
        assert!(g.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn narx_regressors_follow_documented_order() {
        assert_eq!((Narx::SEED.dim(), Narx::SEED.start()), (3, 1));
        assert_eq!((Narx::SEED_7.dim(), Narx::SEED_7.start()), (7, 3));
        let long_input = Narx {
            input_lags: 5,
            output_lags: 1,
        };
        assert_eq!(long_input.start(), 4);
        let r: Vec<f64> = (0..10).map(|k| k as f64).collect();
        let y: Vec<f64> = (0..10).map(|k| 100.0 + k as f64).collect();
        let mut x = [0.0; 7];
        Narx::SEED_7.regressor(&r, &y, 5, &mut x);
        assert_eq!(x, [5.0, 4.0, 3.0, 2.0, 104.0, 103.0, 102.0]);
        let data = Regressors::new(&Narx::SEED, &r, &y);
        assert_eq!(data.len(), 9);
        assert_eq!(data.row(0), &[1.0, 0.0, 100.0]);
        assert_eq!(data.targets()[0], 101.0);
    }

    #[test]
    fn one_step_predict_is_the_net_on_measured_regressors() {
        let (r, y) = eq_3_18_data(50);
        let net = RbfNet::SEED;
        let p = random_params(&net, &mut ChaCha8Rng::seed_from_u64(5));
        let mut out = vec![f64::NAN; 50];
        predict(&net, &Narx::SEED, &p, &r, &y, Mode::OneStepAhead, &mut out);
        assert_eq!(out[0], y[0], "initial condition is the measurement");
        for k in 1..50 {
            assert_eq!(out[k], net.eval(&p, &[r[k], r[k - 1], y[k - 1]]));
        }
        let manual: f64 = (1..50).map(|k| 0.5 * (out[k] - y[k]).powi(2)).sum();
        let j = cost(&net, &Narx::SEED, &p, &r, &y, Mode::OneStepAhead);
        assert!((j - manual).abs() <= 1e-12 * manual);
    }

    #[test]
    fn free_run_feeds_back_own_outputs() {
        let (r, y) = eq_3_18_data(300);
        let narx = Narx::SEED_7;
        let net = RbfNet::new(7, 7);
        let p = random_params(&net, &mut ChaCha8Rng::seed_from_u64(6));
        let mut free = vec![0.0; 300];
        let mut one = vec![0.0; 300];
        predict(&net, &narx, &p, &r, &y, Mode::FreeRun, &mut free);
        predict(&net, &narx, &p, &r, &y, Mode::OneStepAhead, &mut one);
        // An imperfect model: the two modes part ways once the feedback differs.
        assert_eq!(free[..3], y[..3]);
        assert_eq!(free[3], one[3], "first prediction only sees measured lags");
        let diff = free
            .iter()
            .zip(&one)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff > 1e-2, "free run and one-step coincide ({diff:e})");
        // A perfect model: the record generated by the net itself. One-step on it
        // reproduces it exactly and both costs vanish.
        let mut again = vec![0.0; 300];
        predict(&net, &narx, &p, &r, &free, Mode::OneStepAhead, &mut again);
        assert_eq!(again, free);
        predict(&net, &narx, &p, &r, &free, Mode::FreeRun, &mut again);
        assert_eq!(again, free);
        assert_eq!(cost(&net, &narx, &p, &r, &free, Mode::FreeRun), 0.0);
        assert_eq!(cost(&net, &narx, &p, &r, &free, Mode::OneStepAhead), 0.0);
    }

    #[test]
    fn hostile_parameters_give_finite_costs() {
        let (r, y) = eq_3_18_data(200);
        let (net, narx) = (RbfNet::SEED, Narx::SEED);
        let base = random_params(&net, &mut ChaCha8Rng::seed_from_u64(7));
        type Spoil = fn(&mut [f64]);
        let hostile: [(&str, Spoil); 8] = [
            ("zero widths", |p| p[21..28].fill(0.0)),
            ("tiny widths", |p| p[21..28].fill(1e-300)),
            ("huge weights", |p| p[28..].fill(1e300)),
            ("max weights", |p| p[28..].fill(f64::MAX)),
            ("inf weights", |p| p[28..].fill(f64::INFINITY)),
            ("NaN everywhere", |p| p.fill(f64::NAN)),
            ("inf centres", |p| p[..21].fill(f64::INFINITY)),
            ("inf widths, -inf weights", |p| {
                p[21..28].fill(f64::INFINITY);
                p[28..].fill(f64::NEG_INFINITY)
            }),
        ];
        let n = (200 - 1) as f64;
        let cap = CAP_FACTOR * output_scale(-0.37, 0.35);
        for (what, f) in hostile {
            let mut p = base.clone();
            f(&mut p);
            for mode in [Mode::OneStepAhead, Mode::FreeRun] {
                let j = cost(&net, &narx, &p, &r, &y, mode);
                assert!(j.is_finite() && j >= 0.0, "{what} {mode:?}: {j}");
                assert!(j <= n * cap * cap, "{what} {mode:?}: {j}");
            }
            let mut g = vec![0.0; 35];
            let j = cost_grad(&net, &narx, &p, &r, &y, &mut g);
            assert!(j.is_finite(), "{what}: {j}");
            assert!(g.iter().all(|v| v.is_finite()), "{what}: {g:?}");
        }
        // Zero widths alone keep the net's output finite.
        let mut p = base.clone();
        p[21..28].fill(0.0);
        assert!(net.eval(&p, &[0.1, 0.2, 0.3]).is_finite());
    }

    #[test]
    fn free_run_penalty_grows_the_earlier_it_diverges() {
        // One node fires only for r ≈ 5 with an enormous weight: the model is fine (y_m ≈ 0)
        // until the input spike at sample `at`, where the error exceeds the cap.
        let net = RbfNet::SEED;
        let mut p = vec![0.0; 35];
        p[0..3].copy_from_slice(&[5.0, 0.0, 0.0]);
        p[21..28].fill(0.1);
        p[28] = 1e12;
        let j_at = |at: usize| {
            let mut r = vec![0.0; 400];
            r[at] = 5.0;
            let y = vec![0.01; 400];
            cost(&net, &Narx::SEED, &p, &r, &y, Mode::FreeRun)
        };
        let (early, late) = (j_at(50), j_at(300));
        assert!(early.is_finite() && late.is_finite());
        assert!(early > late, "early {early:e} vs late {late:e}");
        // Diverged samples cost cap² each, twice the most a non-diverged one can.
        let cap = CAP_FACTOR * 0.01;
        assert!(late >= 100.0 * cap * cap && early >= 350.0 * cap * cap);
    }

    #[test]
    fn eq_3_18_matches_hand_recurrence() {
        // Impulse response, by hand.
        let y = eq_3_18(&[1.0, 0.0, 0.0, 0.0]);
        let y0 = -0.3406;
        let y1 = 0.9802 * y0 + 0.3306;
        let y2 = 0.9802 * y1;
        let y3 = 0.9802 * y2;
        assert_eq!(y, vec![y0, y1, y2, y3]);
        // Step response tends to the DC gain (-0.3406 + 0.3306) / (1 - 0.9802).
        let y = eq_3_18(&[1.0; 2000]);
        let dc = (-0.3406 + 0.3306) / (1.0 - 0.9802);
        assert!((y[1999] - dc).abs() < 1e-12);
        assert!(eq_3_18(&[]).is_empty());
    }

    #[test]
    fn init_params_lie_within_param_bounds() {
        let (r, y) = eq_3_18_data(1000);
        let data = Regressors::new(&Narx::SEED, &r, &y);
        let (lo, hi) = data.input_ranges();
        let (ylo, yhi) = data.output_range();
        let net = RbfNet::SEED;
        let p = init_params(&net, &lo, &hi);
        let (pl, pu) = param_bounds(&net, &lo, &hi, ylo, yhi);
        assert_eq!((p.len(), pl.len(), pu.len()), (35, 35, 35));
        for i in 0..35 {
            assert!(pl[i] < pu[i] && pl[i] <= p[i] && p[i] <= pu[i], "param {i}");
        }
        // Centre bounds are the input ranges; weights ±10 × output scale.
        assert_eq!(
            (pl[3..6].to_vec(), pu[3..6].to_vec()),
            (lo.clone(), hi.clone())
        );
        assert_eq!(pu[34], WEIGHT_BOUND_FACTOR * output_scale(ylo, yhi));
        // A constant input still gives proper intervals.
        let (pl, pu) = param_bounds(&RbfNet::new(1, 2), &[3.0], &[3.0], 0.0, 0.0);
        assert!(pl.iter().zip(&pu).all(|(l, u)| l < u), "{pl:?} {pu:?}");
    }

    /// BP with the default settings on the dissertation's numerical example (eq. 3.18, 20 Hz sine,
    /// 1 ms, 1 s) from [`init_params`]. Run with `--nocapture` for the numbers.
    #[test]
    fn bp_fits_eq_3_18_data() {
        let (r, y) = eq_3_18_data(1000);
        let (net, narx) = (RbfNet::SEED, Narx::SEED);
        let data = Regressors::new(&narx, &r, &y);
        let (lo, hi) = data.input_ranges();
        let p0 = init_params(&net, &lo, &hi);
        let mut out = vec![0.0; 1000];
        for mode in [BpUpdate::Online, BpUpdate::Batch] {
            let cfg = BpConfig {
                mode,
                ..BpConfig::default()
            };
            let cfg = if mode == BpUpdate::Batch {
                BpConfig {
                    learning_rate: 1.0,
                    momentum: 0.9,
                    ..cfg
                }
            } else {
                cfg
            };
            let res = bp_train(&net, &narx, &p0, &r, &y, &cfg);
            let c = &res.cost_per_epoch;
            assert_eq!(c.len(), 300);
            let best = c.iter().copied().fold(f64::INFINITY, f64::min);
            assert_eq!(best, data.cost(&net, &res.params));
            predict(
                &net,
                &narx,
                &res.params,
                &r,
                &y,
                Mode::OneStepAhead,
                &mut out,
            );
            let (one, one_ss) = (fit_errors(&y, &out, 1), fit_errors(&y, &out, 200));
            predict(&net, &narx, &res.params, &r, &y, Mode::FreeRun, &mut out);
            let free = fit_errors(&y, &out, 1);
            println!(
                "BP {mode:?} (eta {}, beta {}): L {:.4e} -> {:.4e} (epoch 100) -> {:.4e} \
                 (epoch 300), factor {:.0}; one-step RMS {:.3e} max {:.3e} (from 200 ms: \
                 RMS {:.3e} max {:.3e}); free-run RMS {:.3e} max {:.3e}",
                cfg.learning_rate,
                cfg.momentum,
                res.initial_cost,
                c[99],
                best,
                res.initial_cost / best,
                one.rms,
                one.max_abs,
                one_ss.rms,
                one_ss.max_abs,
                free.rms,
                free.max_abs
            );
            assert!(res.initial_cost / best > 1e3, "{mode:?}: {best:e}");
            assert_eq!(res.reverts, 0);
            // The output spans ±0.36: RMS under 2% of it.
            assert!(one.rms < 7e-3 && free.rms < 7e-3, "{mode:?}");
        }
    }

    #[test]
    fn bp_guard_keeps_results_finite() {
        let (r, y) = eq_3_18_data(200);
        let (net, narx) = (RbfNet::SEED, Narx::SEED);
        let p0 = random_params(&net, &mut ChaCha8Rng::seed_from_u64(8));
        for mode in [BpUpdate::Online, BpUpdate::Batch] {
            let cfg = BpConfig {
                learning_rate: 1e8,
                momentum: 0.99,
                epochs: 20,
                mode,
            };
            let res = bp_train(&net, &narx, &p0, &r, &y, &cfg);
            assert!(res.params.iter().all(|v| v.is_finite()));
            assert!(res.cost_per_epoch.iter().all(|v| v.is_finite()));
            assert!(res.reverts > 0 && res.learning_rate < 1e8, "{mode:?}");
            let j = cost(&net, &narx, &res.params, &r, &y, Mode::OneStepAhead);
            assert!(j <= res.initial_cost);
        }
    }
}
