//! The shape parameters decoded from the optimizer's vector, and the Bouc-Wen kernel of a
//! shape.

use super::*;

/// Shape parameters decoded from a vector.
#[derive(Clone, Copy, Debug)]
pub(super) struct Shape {
    pub(super) s: f64,
    pub(super) w: f64,
    pub(super) n: f64,
    pub(super) g0: f64,
    /// Sub-sample timing of the input (samples; positive: the input acts later).
    pub(super) timing: f64,
    /// How the input curves between samples, for fractional shifts: 0 a straight line
    /// (a ramp or a staircase's average), 1 the cubic through four samples (a smooth,
    /// band-limited signal).
    pub(super) curvature: f64,
    /// Samples by which the linear blocks' inputs lag the samples (0: a value acts over
    /// the interval before its sample; 1: a D/A that updates at the sample and holds).
    pub(super) block_hold: f64,
    pub(super) delay: f64,
    pub(super) lag: f64,
    /// Second-order input lag: natural frequency (Hz; infinite: none) and damping.
    pub(super) lag2_hz: f64,
    pub(super) lag2_zeta: f64,
    pub(super) sat_c: f64,
    /// Smooth saturation `u_ref/κ tanh(κ x/u_ref)` (κ = 0: none).
    pub(super) sat_k: f64,
    /// Cubic compression coefficient.
    pub(super) sat_cubic: f64,
    pub(super) q: f64,
    /// Direction asymmetry: the hysteretic slope is `1 ± a` on rising / falling drive.
    pub(super) dir_a: f64,
    pub(super) rho: f64,
    pub(super) tau_r: f64,
    /// Rate acts on the linear gain instead of the loop width.
    pub(super) rate_gain: bool,
    pub(super) creep_g: f64,
    pub(super) creep_tau: f64,
    pub(super) creep_g2: f64,
    pub(super) creep_tau2: f64,
    /// Logarithmic creep: gain per decade (elements one per decade).
    pub(super) creep_log: f64,
    /// Settling drift's time constant (s).
    pub(super) drift_tau: f64,
    pub(super) mode_p: f64,
    pub(super) zeta: f64,
    /// Second mode (parallel): frequency (Hz), damping and share.
    pub(super) mode2_hz: f64,
    pub(super) mode2_zeta: f64,
    pub(super) mode2_share: f64,
    /// Feedback placement: oscillator frequency (Hz), damping, hysteretic share, shape.
    pub(super) fb_hz: f64,
    pub(super) fb_zeta: f64,
    pub(super) fb_r: f64,
    pub(super) fb_b: f64,
    pub(super) fb_c: f64,
}

impl Shape {
    /// Largest hysteretic state at the first sample (`g0_frac` = ±1): the saturation
    /// level `s u_ref`, but at most twice the drive's peak, what a past drive of the same
    /// range can leave in a state far from saturation. Without the cap a weakly saturating
    /// loop (large `s`) started at its far saturation level moves only by a creep-like
    /// relaxation, which a huge gain and an offset cancelling the state turn into a drift
    /// (seed 20261138 case 98: `h0` = 3.8e6 against an offset of 3.8e6 on a 0.6 mm
    /// stroke, and every drift candidate predicting the validation record 4-6x worse).
    pub(super) fn g0_scale(&self, u_ref: f64) -> f64 {
        self.s.min(2.0) * u_ref
    }

    /// Samples the input acts later by: the timing nuisance plus any transport delay (one
    /// shift, so both interpolate alike).
    pub(super) fn input_shift(&self, st: &Structure) -> f64 {
        let delay = if st.has(Effect::Delay) {
            self.delay.clamp(0.0, 1e4)
        } else {
            0.0
        };
        self.timing.clamp(-2.0, 2.0) + delay
    }

    /// Every parameter finite (unused ones hold finite defaults; `lag2_hz` is infinite
    /// when off).
    pub(super) fn is_finite(&self) -> bool {
        [
            self.s,
            self.w,
            self.n,
            self.g0,
            self.timing,
            self.curvature,
            self.block_hold,
            self.delay,
            self.lag,
            self.lag2_zeta,
            self.sat_c,
            self.sat_k,
            self.sat_cubic,
            self.q,
            self.dir_a,
            self.rho,
            self.tau_r,
            self.creep_g,
            self.creep_tau,
            self.creep_g2,
            self.creep_tau2,
            self.creep_log,
            self.drift_tau,
            self.mode_p,
            self.zeta,
            self.mode2_zeta,
            self.mode2_share,
            self.fb_hz,
            self.fb_zeta,
            self.fb_r,
            self.fb_b,
            self.fb_c,
        ]
        .iter()
        .all(|x| x.is_finite())
            && !self.lag2_hz.is_nan()
            && !self.mode2_hz.is_nan()
    }

    /// The memoryless part of the chain: saturation (hard, smooth or cubic), then
    /// asymmetry (`u_ref` the training peak).
    pub(super) fn drive(&self, u_ref: f64) -> impl Fn(f64) -> f64 {
        let limit = if self.sat_c > 0.0 {
            u_ref / self.sat_c
        } else {
            f64::INFINITY
        };
        let (k, cubic, q) = (self.sat_k, self.sat_cubic, self.q);
        move |x: f64| {
            let mut x = x.clamp(-limit, limit);
            if k > 0.0 {
                x = u_ref / k * (k * x / u_ref).tanh();
            }
            if cubic != 0.0 {
                x -= cubic * x * x * x / (u_ref * u_ref);
            }
            x + q * x * x / u_ref
        }
    }

    /// The creep elements `(gain, τ)`: the Kelvin-Voigt pair, or for logarithmic creep one
    /// element per decade from 10 samples to ten training records, equal gains.
    pub(super) fn creep_elements(&self, form: Form, ctx: &Context) -> Vec<(f64, f64)> {
        match form {
            Form::Logarithmic => log_creep_taus(ctx)
                .into_iter()
                .map(|tau| (self.creep_log, tau))
                .collect(),
            _ => vec![
                (self.creep_g, self.creep_tau),
                (self.creep_g2, self.creep_tau2),
            ],
        }
    }
}

/// Time constants of logarithmic creep: one per decade from 10 samples to ten training
/// records.
pub(super) fn log_creep_taus(ctx: &Context) -> Vec<f64> {
    let lo = (10.0 * ctx.dt).log10();
    let hi = (10.0 * ctx.t_ref).max(100.0 * ctx.dt).log10();
    let m = ((hi - lo).ceil() as usize).clamp(2, 8);
    (0..m)
        .map(|i| 10f64.powf(lo + (hi - lo) * (i as f64 + 0.5) / m as f64))
        .collect()
}

/// The two time constants whose decays stand for a logarithmic creep chain's initial state
/// (the band's lower and upper thirds).
pub(super) fn log_creep_state_taus(ctx: &Context) -> [f64; 2] {
    let t = log_creep_taus(ctx);
    [t[t.len() / 3], t[(2 * t.len()) / 3]]
}

/// Knots of the spline drift: one every 2.5 s of the training record, 3 to 16 segments.
pub(super) fn spline_segments(ctx: &Context) -> usize {
    ((ctx.t_ref / 2.5).round() as usize).clamp(3, 16)
}

/// `u` shifted by `s` samples (positive: later), interpolated between samples: straight
/// (`curvature` 0) or by the cubic through the four nearest samples (1), or between.
/// Beyond the ends the end values hold.
pub(super) fn shift(u: &[f64], s: f64, curvature: f64) -> Vec<f64> {
    let n = u.len();
    if s == 0.0 || n < 2 {
        return u.to_vec();
    }
    let whole = s.floor();
    let frac = s - whole;
    let w = whole as i64;
    let at = |i: i64| u[i.clamp(0, n as i64 - 1) as usize];
    // Position t in [0, 1] between p1 = u[k-w-1] and p2 = u[k-w]; the cubic is the line
    // minus t(1-t)/2 times a blend of the two second differences around the interval.
    let t = 1.0 - frac;
    let (c0, c1) = (
        curvature * t * (1.0 - t) / 2.0 * (2.0 - t) / 3.0,
        curvature * t * (1.0 - t) / 2.0 * (1.0 + t) / 3.0,
    );
    let value = |p0: f64, p1: f64, p2: f64, p3: f64| {
        let line = p1 + t * (p2 - p1);
        if curvature == 0.0 || frac == 0.0 {
            line
        } else {
            line - c0 * (p0 - 2.0 * p1 + p2) - c1 * (p1 - 2.0 * p2 + p3)
        }
    };
    let clamped = |k: i64| value(at(k - w - 2), at(k - w - 1), at(k - w), at(k - w + 1));
    // Samples `[lo, hi)` read four inputs inside the record: no clamping (every
    // evaluation shifts the whole input).
    let lo = (w + 2).clamp(0, n as i64);
    let hi = (n as i64 - 1 + w).clamp(lo, n as i64);
    let mut out = Vec::with_capacity(n);
    out.extend((0..lo).map(clamped));
    out.extend(
        u[((lo - w - 2).max(0) as usize).min(n)..]
            .windows(4)
            .take((hi - lo) as usize)
            .map(|p| value(p[0], p[1], p[2], p[3])),
    );
    out.extend((hi..n as i64).map(clamped));
    out
}

impl Structure {
    pub(super) fn shape(&self, theta: &[f64]) -> Shape {
        let mut sh = Shape {
            s: 10f64.powf(-0.5),
            w: 0.5,
            n: self.fixed_n.unwrap_or(1.0),
            g0: 0.0,
            timing: 0.0,
            curvature: 0.0,
            block_hold: 0.0,
            delay: 0.0,
            lag: 0.0,
            lag2_hz: f64::INFINITY,
            lag2_zeta: 0.7,
            sat_c: 0.0,
            sat_k: 0.0,
            sat_cubic: 0.0,
            q: 0.0,
            dir_a: 0.0,
            rho: 0.0,
            tau_r: 1.0,
            rate_gain: self.form(Effect::RateDependence) == Some(Form::Gain),
            creep_g: 0.0,
            creep_tau: 1.0,
            creep_g2: 0.0,
            creep_tau2: 1.0,
            creep_log: 0.0,
            drift_tau: 1.0,
            mode_p: 0.0,
            zeta: 0.3,
            mode2_hz: 1.0,
            mode2_zeta: 0.3,
            mode2_share: 0.0,
            fb_hz: 1.0,
            fb_zeta: 0.05,
            fb_r: 0.5,
            fb_b: 0.0,
            fb_c: 0.0,
        };
        for (spec, &x) in self.specs.iter().zip(theta) {
            match spec.name {
                "log10_s" => sh.s = 10f64.powf(x),
                "w" => sh.w = x,
                "n" => sh.n = x,
                "g0_frac" => sh.g0 = x,
                "timing_samples" => sh.timing = x,
                "intersample_curvature" => sh.curvature = x,
                "block_hold_samples" => sh.block_hold = x,
                "delay_samples" => sh.delay = x,
                "lag2_log10_hz" => sh.lag2_hz = spec.hz_unless_top(x).unwrap_or(f64::INFINITY),
                "lag2_log10_zeta" => sh.lag2_zeta = 10f64.powf(x),
                "sat_smooth_k" => sh.sat_k = x,
                "sat_cubic" => sh.sat_cubic = x,
                "asym_dir" => sh.dir_a = x,
                "creep_log_gain" => sh.creep_log = x,
                "drift_log10_tau_s" => sh.drift_tau = 10f64.powf(x),
                "mode2_log10_hz" => sh.mode2_hz = spec.hz_unless_top(x).unwrap_or(f64::INFINITY),
                "mode2_log10_zeta" => sh.mode2_zeta = 10f64.powf(x),
                "mode2_share" => sh.mode2_share = x,
                "lag_log10_tau_s" => {
                    // The bottom of the range is no lag at all.
                    sh.lag = if x <= spec.lower + 1e-9 {
                        0.0
                    } else {
                        10f64.powf(x)
                    }
                }
                "sat_level" => sh.sat_c = if x >= spec.upper - 1e-9 { 0.0 } else { 1.0 / x },
                "asym_q" => sh.q = x,
                "rate_rho" => sh.rho = x,
                "rate_log10_tau_s" => sh.tau_r = 10f64.powf(x),
                "creep_g" => sh.creep_g = x,
                "creep_log10_tau_s" => sh.creep_tau = 10f64.powf(x),
                "creep_g2" => sh.creep_g2 = x,
                "creep_log10_tau2_s" => sh.creep_tau2 = 10f64.powf(x),
                "mode_log10_hz" => {
                    sh.mode_p = spec
                        .hz_unless_top(x)
                        .map_or(0.0, |f| 1.0 / (2.0 * std::f64::consts::PI * f))
                }
                "mode_log10_zeta" => sh.zeta = 10f64.powf(x),
                "fb_log10_hz" => sh.fb_hz = 10f64.powf(x),
                "fb_log10_zeta" => sh.fb_zeta = 10f64.powf(x),
                "fb_r" => sh.fb_r = x,
                "fb_b" => sh.fb_b = x,
                "fb_c" => sh.fb_c = x,
                _ => {}
            }
        }
        sh
    }

    /// The `g`-form Bouc-Wen shape (`α = slope`, 1 but for direction asymmetry,
    /// `d_e = d0 = 0`).
    pub(super) fn kernel(&self, sh: &Shape, slope: f64) -> BoucWenKernel {
        let sigma = (sh.s * self.ctx.u_ref).powf(-sh.n);
        BoucWenKernel::new(&BoucWenParams {
            d_e: 0.0,
            alpha: slope,
            beta: sh.w * sigma,
            gamma: (1.0 - sh.w) * sigma,
            n: sh.n,
            d0: 0.0,
        })
    }
}
