//! Bouc-Wen with switchable structural extensions: the model family that `optbench
//! diagnose` searches. Each extension is one piece of physics the plain model leaves out,
//! with its own parameters, physical bounds and a *neutral* value at which the extended
//! model equals the plain one exactly (so every candidate is nested in its parent).
//!
//! ```text
//!  u ─ delay ─ input-lag ─ saturation ─ asymmetry ─► v ─ Bouc-Wen ─► D ─ creep ─ dynamics ─ + drift ─► y
//!                                                       (rate-dependence scales h)
//! ```
//!
//! - `delay`: transport delay of `d` samples, one shift with the timing nuisance (fractional:
//!   interpolated straight or, with the `intersample_curvature` nuisance, by a cubic).
//! - `input-lag`: first-order low-pass `τ` on the command (zero-order hold, as a D/A drives
//!   an amplifier; exact for a staircase command).
//! - `saturation`: the drive clipped at `±u_ref / c` (`c = 0`: no clipping).
//! - `asymmetry`: even-order term `v = x + q x²/u_ref` (unequal up/down gains).
//! - Bouc-Wen (seed eq. 3.1-3.3) written as `D = d_e v + d0 - α g`, `dg/dv = 1 - (β'
//!   sgn(v̇ g) + γ')|g|^n`: `h = α g` exactly when `β = β' α^(1-n)`, `γ = γ' α^(1-n)`
//!   (α > 0), so `d_e`, `d0` and `α` enter linearly and are solved by least squares for
//!   every shape (variable projection). The optimizer sees only the shape: `log10 s` (`g`
//!   saturates at `s u_ref`, i.e. `β'+γ' = (s u_ref)^-n`), `w = β'/(β'+γ')` and `n`.
//! - `rate-dependence`: `h` scaled by `1 + ρ r`, `r` the drive rate `|v̇|` low-passed
//!   with `τ_r` over its RMS on the training data: loops widen with rate.
//! - `creep`: a two-element Kelvin-Voigt chain `D + g₁ lag(τ₁) D + g₂ lag(τ₂) D`, one fast
//!   element (τ₁ from 10 samples to a quarter of the record) and one slow (τ₂ from a
//!   quarter of the record to ten records), as a piezo creeps on both scales. Each
//!   element's state at a record's start is the record's own, within the element's gain
//!   times how far the output moved ([`Structure::state_bounds`]).
//! - `dynamics`: second-order mode `ÿ + 2ζω ẏ + ω² y = ω² x` after the hysteresis,
//!   parametrised by `p = 1/ω` (s; `p = 0` passes `x` through) and `ζ`.
//! - `offset-drift`: `y += a1 t/T + a2 (t/T)²` (T the training duration), two more
//!   linear coefficients.
//!
//! Linear blocks are the exact discretisations of [`super::linear`]: zero-order hold after
//! the command, exponential hold (the drive relaxes with `τ`) when `input-lag` is on, as
//! in the twin. Unstable or absurd parameters give a finite penalty ([`cost_cap`]),
//! never NaN.

use super::bouc_wen::{BoucWenKernel, BoucWenParams, cost_cap};
use super::linear::{LowPass, Mode};
pub use super::restoring::Hold;
use super::restoring::{Oscillator, upsample};
use std::sync::Arc;

mod records;
pub use records::{MAX_RECORDS, same_interval};

/// A piece of physics the plain Bouc-Wen model leaves out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Effect {
    Delay,
    InputLag,
    Saturation,
    Asymmetry,
    RateDependence,
    Creep,
    Dynamics,
    OffsetDrift,
}

impl Effect {
    /// Every effect, in chain order.
    pub const ALL: [Effect; 8] = [
        Effect::Delay,
        Effect::InputLag,
        Effect::Saturation,
        Effect::Asymmetry,
        Effect::RateDependence,
        Effect::Creep,
        Effect::Dynamics,
        Effect::OffsetDrift,
    ];

    /// The name used in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Delay => "delay",
            Effect::InputLag => "input-lag",
            Effect::Saturation => "saturation",
            Effect::Asymmetry => "asymmetry",
            Effect::RateDependence => "rate-dependence",
            Effect::Creep => "creep",
            Effect::Dynamics => "dynamics",
            Effect::OffsetDrift => "offset-drift",
        }
    }

    /// The effect named `name`, if any.
    pub fn parse(name: &str) -> Option<Effect> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }

    /// One line on what the effect is, for reports.
    pub fn meaning(self) -> &'static str {
        match self {
            Effect::Delay => "transport delay between command and displacement",
            Effect::InputLag => "first-order low-pass on the drive (amplifier bandwidth)",
            Effect::Saturation => "drive clipped at large |u|",
            Effect::Asymmetry => "even-order term: unequal gains up and down",
            Effect::RateDependence => {
                "hysteretic slope (loop width) or gain growing with the input rate"
            }
            Effect::Creep => "slow visco-elastic (Kelvin-Voigt) lag after the hysteresis",
            Effect::Dynamics => "second-order structural mode after the hysteresis",
            Effect::OffsetDrift => "sensor offset drifting slowly, uncorrelated with the input",
        }
    }

    /// The functional forms the effect is searched in, the first the default. One name
    /// covers several forms because physics offers several (a soft saturation is not a
    /// clip; thermal settling is not a polynomial in time).
    pub fn forms(self) -> &'static [Form] {
        match self {
            Effect::Delay => &[Form::Transport],
            Effect::InputLag => &[Form::FirstOrder, Form::SecondOrder],
            Effect::Saturation => &[Form::Hard, Form::Smooth, Form::Cubic],
            Effect::Asymmetry => &[Form::Even, Form::Direction],
            Effect::RateDependence => &[Form::Width, Form::Gain],
            Effect::Creep => &[Form::KelvinVoigt, Form::Logarithmic],
            Effect::Dynamics => &[Form::OneMode, Form::TwoModes],
            Effect::OffsetDrift => &[Form::Polynomial, Form::Spline, Form::Settling],
        }
    }

    /// Whether the effect belongs to one recording (a sensor's offset drift), refitted on
    /// every record, rather than to the actuator (carried over with the same parameters).
    pub fn per_record(self) -> bool {
        self == Effect::OffsetDrift
    }
}

/// One functional form of an [`Effect`] ([`Effect::forms`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Form {
    /// Delay: a fractional transport delay.
    Transport,
    /// Input lag: first-order low-pass.
    FirstOrder,
    /// Input lag: second-order low-pass (an amplifier with a damped pole pair).
    SecondOrder,
    /// Saturation: the drive clipped.
    Hard,
    /// Saturation: `L tanh(x/L)`.
    Smooth,
    /// Saturation: `x - c x³/u_ref²`.
    Cubic,
    /// Asymmetry: `x + q x²/u_ref`.
    Even,
    /// Asymmetry: the hysteretic slope differs on rising and falling drive.
    Direction,
    /// Rate-dependence: the hysteretic slope inside the Bouc-Wen equation grows with the
    /// rate (the loop widens and keeps that width until the drive moves on).
    Width,
    /// Rate-dependence: the linear gain grows with the rate.
    Gain,
    /// Creep: two Kelvin-Voigt elements, one fast and one slow.
    KelvinVoigt,
    /// Creep: equal weight per decade of time constants (logarithmic creep).
    Logarithmic,
    /// Dynamics: one mode.
    OneMode,
    /// Dynamics: two modes in parallel (modal superposition).
    TwoModes,
    /// Drift: quadratic in time.
    Polynomial,
    /// Drift: a piecewise-linear function of time (knots every few seconds): settling,
    /// wander, anything smooth.
    Spline,
    /// Drift: exponential settling `e^(-t/τ)`, τ shared by the records, the amplitude each
    /// record's own (a sensor warming up). Two parameters where creep needs five: creep
    /// must earn its name by what the input drives, not by its initial-state decays.
    Settling,
}

impl Form {
    /// The name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Form::Transport => "transport",
            Form::FirstOrder => "first-order",
            Form::SecondOrder => "second-order",
            Form::Hard => "hard",
            Form::Smooth => "smooth",
            Form::Cubic => "cubic",
            Form::Even => "even-order",
            Form::Direction => "direction",
            Form::Width => "width",
            Form::Gain => "gain",
            Form::KelvinVoigt => "kelvin-voigt",
            Form::Logarithmic => "logarithmic",
            Form::OneMode => "one-mode",
            Form::TwoModes => "two-modes",
            Form::Polynomial => "polynomial",
            Form::Spline => "spline",
            Form::Settling => "settling",
        }
    }
}

/// One shape parameter: its name, physical bounds and neutral value.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub lower: f64,
    pub upper: f64,
    /// Value at which the parameter's effect vanishes (or a typical start).
    pub neutral: f64,
    /// Which effect it belongs to (`None`: the Bouc-Wen shape).
    pub effect: Option<Effect>,
}

impl ParamSpec {
    /// `10^x` for a log-frequency whose top of range means "off" (no mode, no lag).
    fn hz_unless_top(&self, x: f64) -> Option<f64> {
        (x < self.upper - 1e-9).then(|| 10f64.powf(x))
    }
}

/// Scales of the training data that make the shape parameters unit-free.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Context {
    /// Sample interval (s).
    pub dt: f64,
    /// Largest |u| of the training input.
    pub u_ref: f64,
    /// RMS of |du/dt| of the training input (input units per second).
    pub rate_ref: f64,
    /// Duration of the training record (s): the time scale of the drift polynomial.
    pub t_ref: f64,
    /// How the input moves between samples, for the feedback placement's integrator (the
    /// blocks of the chain are discretised for a zero-order hold).
    pub hold: Hold,
}

/// Where the `dynamics` mode sits relative to the hysteresis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Placement {
    /// A mode after the hysteresis: `y = G(s) h(u)` (a piezo stack driving a structure).
    #[default]
    After,
    /// The hysteresis inside the mechanical feedback, a restoring force:
    /// `m ÿ + c ẏ + k y + z(y) = u` ([`super::restoring`]).
    Feedback,
}

impl Placement {
    /// The name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Placement::After => "after-hysteresis",
            Placement::Feedback => "feedback",
        }
    }

    /// One line for humans.
    pub fn meaning(self) -> &'static str {
        match self {
            Placement::After => "a structural mode after the hysteresis",
            Placement::Feedback => {
                "the hysteresis inside the mechanical feedback (a hysteretic restoring force)"
            }
        }
    }
}

impl Context {
    /// The scales of training input `u` sampled every `dt`.
    pub fn from_training(u: &[f64], dt: f64) -> Context {
        let u_ref = u.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300);
        let n = u.len().max(2);
        let ms: f64 = u
            .windows(2)
            .map(|w| ((w[1] - w[0]) / dt).powi(2))
            .sum::<f64>()
            / (n - 1) as f64;
        Context {
            dt,
            u_ref,
            rate_ref: ms.sqrt().max(1e-300),
            t_ref: (n as f64 * dt).max(dt),
            hold: Hold::Zoh,
        }
    }

    /// The scales of several training records `(input, interval)` fitted together: the
    /// largest |u|, the RMS rate over every sample, the longest record's duration (the time
    /// scale one record can show); sampled at the first record's interval.
    pub fn from_records(records: &[(&[f64], f64)]) -> Context {
        let one: Vec<Context> = records
            .iter()
            .map(|&(u, dt)| Context::from_training(u, dt))
            .collect();
        let Some(first) = one.first() else {
            return Context::from_training(&[], 1.0);
        };
        let weight = |k: usize| records[k].0.len().max(2) as f64 - 1.0;
        let total: f64 = (0..one.len()).map(weight).sum();
        let ms: f64 = one
            .iter()
            .enumerate()
            .map(|(k, c)| weight(k) * c.rate_ref * c.rate_ref)
            .sum::<f64>()
            / total;
        Context {
            u_ref: one.iter().fold(0.0f64, |m, c| m.max(c.u_ref)),
            rate_ref: ms.sqrt().max(1e-300),
            t_ref: one.iter().fold(0.0f64, |m, c| m.max(c.t_ref)),
            ..*first
        }
    }

    /// The same scales with inputs moving between samples by `hold`.
    pub fn with_hold(mut self, hold: Hold) -> Context {
        self.hold = hold;
        self
    }
}

/// The Bouc-Wen model with a set of extensions, on data with context `ctx`.
#[derive(Clone, Debug, PartialEq)]
pub struct Structure {
    effects: Vec<Effect>,
    /// The form of each effect (same order as `effects`).
    forms: Vec<Form>,
    fixed_n: Option<f64>,
    ctx: Context,
    placement: Placement,
    specs: Vec<ParamSpec>,
    /// Several records fitted jointly ([`Self::on_records`]); `None`: one record.
    records: Option<Arc<records::Records>>,
}

/// Outcome of a simulation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    Ok,
    /// Non-finite or unbounded state from sample `at` on.
    Unstable {
        at: usize,
    },
}

/// The fitted linear coefficients and the training cost of one shape.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearFit {
    /// [`Structure::linear_names`]: `d_e, d0, α` (feedback: `scale, d0`), then the drift's
    /// and the creep states'.
    pub coef: Vec<f64>,
    /// `Σ e²/2` (penalty when unstable).
    pub cost: f64,
    pub status: Status,
}

impl LinearFit {
    /// A shape unstable from sample `at` of `len`: the finite penalty `cap (2 - at/len)`,
    /// above every stable cost and higher the earlier it fails.
    fn unstable(ncoef: usize, cap: f64, at: usize, len: usize) -> LinearFit {
        LinearFit {
            coef: vec![0.0; ncoef],
            cost: cap * (2.0 - at as f64 / len.max(1) as f64),
            status: Status::Unstable { at },
        }
    }
}

/// Shape parameters decoded from a vector.
#[derive(Clone, Copy, Debug)]
struct Shape {
    s: f64,
    w: f64,
    n: f64,
    g0: f64,
    /// Sub-sample timing of the input (samples; positive: the input acts later).
    timing: f64,
    /// How the input curves between samples, for fractional shifts: 0 a straight line
    /// (a ramp or a staircase's average), 1 the cubic through four samples (a smooth,
    /// band-limited signal).
    curvature: f64,
    /// Samples by which the linear blocks' inputs lag the samples (0: a value acts over
    /// the interval before its sample; 1: a D/A that updates at the sample and holds).
    block_hold: f64,
    delay: f64,
    lag: f64,
    /// Second-order input lag: natural frequency (Hz; infinite: none) and damping.
    lag2_hz: f64,
    lag2_zeta: f64,
    sat_c: f64,
    /// Smooth saturation `u_ref/κ tanh(κ x/u_ref)` (κ = 0: none).
    sat_k: f64,
    /// Cubic compression coefficient.
    sat_cubic: f64,
    q: f64,
    /// Direction asymmetry: the hysteretic slope is `1 ± a` on rising / falling drive.
    dir_a: f64,
    rho: f64,
    tau_r: f64,
    /// Rate acts on the linear gain instead of the loop width.
    rate_gain: bool,
    creep_g: f64,
    creep_tau: f64,
    creep_g2: f64,
    creep_tau2: f64,
    /// Logarithmic creep: gain per decade (elements one per decade).
    creep_log: f64,
    /// Settling drift's time constant (s).
    drift_tau: f64,
    mode_p: f64,
    zeta: f64,
    /// Second mode (parallel): frequency (Hz), damping and share.
    mode2_hz: f64,
    mode2_zeta: f64,
    mode2_share: f64,
    /// Feedback placement: oscillator frequency (Hz), damping, hysteretic share, shape.
    fb_hz: f64,
    fb_zeta: f64,
    fb_r: f64,
    fb_b: f64,
    fb_c: f64,
}

impl Shape {
    /// Largest hysteretic state at the first sample (`g0_frac` = ±1): the saturation
    /// level `s u_ref`, but at most twice the drive's peak, what a past drive of the same
    /// range can leave in a state far from saturation. Without the cap a weakly saturating
    /// loop (large `s`) started at its far saturation level moves only by a creep-like
    /// relaxation, which a huge gain and an offset cancelling the state turn into a drift
    /// (seed 20261138 case 98: `h0` = 3.8e6 against an offset of 3.8e6 on a 0.6 mm
    /// stroke, and every drift candidate predicting the validation record 4-6x worse).
    fn g0_scale(&self, u_ref: f64) -> f64 {
        self.s.min(2.0) * u_ref
    }

    /// Samples the input acts later by: the timing nuisance plus any transport delay (one
    /// shift, so both interpolate alike).
    fn input_shift(&self, st: &Structure) -> f64 {
        let delay = if st.has(Effect::Delay) {
            self.delay.clamp(0.0, 1e4)
        } else {
            0.0
        };
        self.timing.clamp(-2.0, 2.0) + delay
    }

    /// Every parameter finite (unused ones hold finite defaults; `lag2_hz` is infinite
    /// when off).
    fn is_finite(&self) -> bool {
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
    fn drive(&self, u_ref: f64) -> impl Fn(f64) -> f64 {
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
    fn creep_elements(&self, form: Form, ctx: &Context) -> Vec<(f64, f64)> {
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
fn log_creep_taus(ctx: &Context) -> Vec<f64> {
    let lo = (10.0 * ctx.dt).log10();
    let hi = (10.0 * ctx.t_ref).max(100.0 * ctx.dt).log10();
    let m = ((hi - lo).ceil() as usize).clamp(2, 8);
    (0..m)
        .map(|i| 10f64.powf(lo + (hi - lo) * (i as f64 + 0.5) / m as f64))
        .collect()
}

/// The two time constants whose decays stand for a logarithmic creep chain's initial state
/// (the band's lower and upper thirds).
fn log_creep_state_taus(ctx: &Context) -> [f64; 2] {
    let t = log_creep_taus(ctx);
    [t[t.len() / 3], t[(2 * t.len()) / 3]]
}

/// Knots of the spline drift: one every 2.5 s of the training record, 3 to 16 segments.
fn spline_segments(ctx: &Context) -> usize {
    ((ctx.t_ref / 2.5).round() as usize).clamp(3, 16)
}

/// `u` shifted by `s` samples (positive: later), interpolated between samples: straight
/// (`curvature` 0) or by the cubic through the four nearest samples (1), or between.
/// Beyond the ends the end values hold.
fn shift(u: &[f64], s: f64, curvature: f64) -> Vec<f64> {
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
    /// The plain model plus `effects` (any order, duplicates ignored) in their default
    /// forms; `fixed_n` pins the Bouc-Wen exponent (e.g. 1) instead of fitting it.
    pub fn new(effects: &[Effect], fixed_n: Option<f64>, ctx: Context) -> Structure {
        Self::placed(effects, fixed_n, ctx, Placement::After)
    }

    /// The model with `dynamics` at `placement`, effects in their default forms. With
    /// [`Placement::Feedback`] `dynamics` is always on (it is the oscillator the hysteresis
    /// sits in) and `rate-dependence` is not available (its rate would be the
    /// displacement's, not the drive's).
    pub fn placed(
        effects: &[Effect],
        fixed_n: Option<f64>,
        ctx: Context,
        placement: Placement,
    ) -> Structure {
        let parts: Vec<(Effect, Form)> = effects.iter().map(|&e| (e, e.forms()[0])).collect();
        Self::with_forms(&parts, fixed_n, ctx, placement)
    }

    /// The model with effects in given forms (the first form of a duplicated effect wins;
    /// a form that is not the effect's falls back to its default).
    pub fn with_forms(
        parts: &[(Effect, Form)],
        fixed_n: Option<f64>,
        ctx: Context,
        placement: Placement,
    ) -> Structure {
        let mut parts: Vec<(Effect, Form)> = parts
            .iter()
            .map(|&(e, f)| {
                if e.forms().contains(&f) {
                    (e, f)
                } else {
                    (e, e.forms()[0])
                }
            })
            .collect();
        if placement == Placement::Feedback {
            // The oscillator is the one mode; the direction form acts on the hysteretic
            // slope of the after-placement kernel only.
            parts.retain(|(e, _)| !matches!(e, Effect::RateDependence | Effect::Dynamics));
            parts.push((Effect::Dynamics, Form::OneMode));
            for p in &mut parts {
                if *p == (Effect::Asymmetry, Form::Direction) {
                    p.1 = Form::Even;
                }
            }
        }
        parts.sort_by_key(|p| p.0);
        parts.dedup_by_key(|p| p.0);
        let dt = ctx.dt;
        let t = ctx.t_ref;
        let spec = |name, lower, upper, neutral, effect| ParamSpec {
            name,
            lower,
            upper,
            neutral,
            effect,
        };
        let hi = (0.5 / dt).log10();
        let lo_hz = (0.005 / dt).log10();
        let mut specs = match placement {
            Placement::After => vec![
                spec("log10_s", -2.0, 1.0, -0.5, None),
                spec("w", 0.0, 1.5, 0.5, None),
            ],
            // Frequency and damping first: the fit's grid covers them (narrow basins).
            // `b = c = 0` is the linear oscillator; `b + c < 0` a hardening loop.
            Placement::Feedback => vec![
                spec(
                    "fb_log10_hz",
                    lo_hz,
                    hi,
                    0.5 * (lo_hz + hi),
                    Some(Effect::Dynamics),
                ),
                spec(
                    "fb_log10_zeta",
                    0.002f64.log10(),
                    1.5f64.log10(),
                    0.05f64.log10(),
                    Some(Effect::Dynamics),
                ),
                spec("fb_r", 0.0, 0.95, 0.5, Some(Effect::Dynamics)),
                spec("fb_b", -4.0, 4.0, 0.0, None),
                spec("fb_c", -4.0, 4.0, 0.0, None),
            ],
        };
        if fixed_n.is_none() {
            specs.push(spec("n", 0.5, 3.0, 1.0, None));
        }
        // The hysteretic state at the first sample, as a fraction of its saturation level:
        // a recording starts with a history the data do not show.
        specs.push(spec("g0_frac", -1.0, 1.0, 0.0, None));
        // A nuisance of the recording set-up, not of the actuator: where the input acts
        // within a sample. A drive linear between samples acts half a sample earlier than
        // the zero-order hold the blocks assume; the sensor may sample anywhere in the
        // interval. So -1 to +0.5 samples belong to the baseline; a longer delay is physics.
        specs.push(spec("timing_samples", -1.0, 0.5, 0.0, None));
        // Likewise how the input moves between samples, which a fractional shift (timing,
        // delay) must interpolate: straight (0) or smooth (1).
        specs.push(spec("intersample_curvature", 0.0, 1.0, 0.0, None));
        let z = (0.005f64.log10(), 1.5f64.log10());
        for &(e, form) in &parts {
            let x = Some(e);
            match (e, form) {
                // Up to 16 samples (3 ms at 5 kHz, 32 ms at 500 Hz): longer is a wiring or
                // protocol delay to align before diagnosing, not physics.
                (Effect::Delay, _) => specs.push(spec("delay_samples", 0.0, 16.0, 0.0, x)),
                (Effect::InputLag, Form::SecondOrder) => {
                    // The top (Nyquist) is no filter at all.
                    specs.push(spec("lag2_log10_hz", lo_hz, hi, hi, x));
                    let zl = (0.4f64.log10(), 1.5f64.log10());
                    specs.push(spec("lag2_log10_zeta", zl.0, zl.1, 0.7f64.log10(), x));
                }
                (Effect::InputLag, _) => {
                    // Log scale; the lower end (τ = dt/100) is a wire; the upper a cut-off
                    // of 0.25 Hz (a slow drive filter) or 20 samples, whichever is longer.
                    let lo = (0.01 * dt).log10();
                    let hi = (20.0 * dt).max(0.64).log10();
                    specs.push(spec("lag_log10_tau_s", lo, hi, lo, x))
                }
                (Effect::Saturation, Form::Smooth) => {
                    specs.push(spec("sat_smooth_k", 0.0, 2.0, 0.0, x))
                }
                (Effect::Saturation, Form::Cubic) => {
                    specs.push(spec("sat_cubic", 0.0, 0.3, 0.0, x))
                }
                // Clip level over the training peak; the top (1) is no clipping at all.
                (Effect::Saturation, _) => specs.push(spec("sat_level", 0.5, 1.0, 1.0, x)),
                (Effect::Asymmetry, Form::Direction) => {
                    specs.push(spec("asym_dir", -0.9, 0.9, 0.0, x))
                }
                (Effect::Asymmetry, _) => specs.push(spec("asym_q", -0.3, 0.3, 0.0, x)),
                (Effect::RateDependence, _) => {
                    specs.push(spec("rate_rho", 0.0, 2.0, 0.0, x));
                    let (lo, hi) = ((2.0 * dt).log10(), (0.5 * t).max(4.0 * dt).log10());
                    specs.push(spec("rate_log10_tau_s", lo, hi, 0.5 * (lo + hi), x));
                }
                (Effect::Creep, Form::Logarithmic) => {
                    specs.push(spec("creep_log_gain", 0.0, 0.3, 0.0, x))
                }
                (Effect::Creep, _) => {
                    // Overlapping ranges (the fast element up to half the record, the slow
                    // from a twentieth): two elements may sit close together.
                    let mid = (0.25 * t).max(20.0 * dt).log10();
                    let (lo, hi) = ((10.0 * dt).log10(), (10.0 * t).max(40.0 * dt).log10());
                    let fast_hi = (0.5 * t).max(20.0 * dt).log10();
                    let slow_lo = (0.05 * t).max(10.0 * dt).log10();
                    specs.push(spec("creep_g", 0.0, 0.5, 0.0, x));
                    specs.push(spec("creep_log10_tau_s", lo, fast_hi, 0.5 * (lo + mid), x));
                    specs.push(spec("creep_g2", 0.0, 0.5, 0.0, x));
                    specs.push(spec("creep_log10_tau2_s", slow_lo, hi, 0.5 * (mid + hi), x));
                }
                (Effect::Dynamics, _) if placement == Placement::Feedback => {}
                (Effect::Dynamics, f) => {
                    // Modes from fs/200 to Nyquist on a log scale (above it a mode aliases);
                    // the upper end itself is a wire (no mode).
                    specs.push(spec("mode_log10_hz", lo_hz, hi, hi, x));
                    specs.push(spec("mode_log10_zeta", z.0, z.1, 0.3f64.log10(), x));
                    if f == Form::TwoModes {
                        specs.push(spec("mode2_log10_hz", lo_hz, hi, hi, x));
                        specs.push(spec("mode2_log10_zeta", z.0, z.1, 0.3f64.log10(), x));
                        specs.push(spec("mode2_share", 0.0, 1.0, 0.0, x));
                    }
                }
                (Effect::OffsetDrift, Form::Settling) => {
                    let (lo, hi) = ((0.02 * t).max(50.0 * dt).log10(), (10.0 * t).log10());
                    specs.push(spec("drift_log10_tau_s", lo, hi, 0.5 * (lo + hi), x))
                }
                (Effect::OffsetDrift, _) => {}
            }
        }
        // Where within its interval a sample acts on the linear blocks (lag, creep, modes):
        // at the interval's end, or held from its start (a D/A). A nuisance, offered only
        // with such a block (the hysteresis, rate-independent, does not see it), last so a
        // new effect's own parameters lead its search.
        let linear_block = parts
            .iter()
            .any(|(e, _)| matches!(e, Effect::InputLag | Effect::Creep | Effect::Dynamics));
        if placement == Placement::After && linear_block {
            specs.push(spec("block_hold_samples", 0.0, 1.0, 0.0, None));
        }
        let (effects, forms) = parts.into_iter().unzip();
        Structure {
            effects,
            forms,
            fixed_n,
            ctx,
            placement,
            specs,
            records: None,
        }
    }

    /// Where `dynamics` sits.
    pub fn placement(&self) -> Placement {
        self.placement
    }

    /// The extensions, in chain order.
    pub fn effects(&self) -> &[Effect] {
        &self.effects
    }

    /// Whether `e` is on.
    pub fn has(&self, e: Effect) -> bool {
        self.effects.contains(&e)
    }

    /// The form of `e`, if on.
    pub fn form(&self, e: Effect) -> Option<Form> {
        let i = self.effects.iter().position(|x| *x == e)?;
        Some(self.forms[i])
    }

    /// The effects with their forms.
    pub fn parts(&self) -> Vec<(Effect, Form)> {
        self.effects
            .iter()
            .copied()
            .zip(self.forms.iter().copied())
            .collect()
    }

    /// `bouc-wen+creep+dynamics`; the feedback placement reads `dynamics(feedback)`, a form
    /// other than the effect's default `creep[logarithmic]`.
    pub fn label(&self) -> String {
        let mut s = String::from("bouc-wen");
        for (e, f) in self.effects.iter().zip(&self.forms) {
            s.push('+');
            s.push_str(e.name());
            if *e == Effect::Dynamics && self.placement == Placement::Feedback {
                s.push_str("(feedback)");
            }
            if *f != e.forms()[0] {
                s.push('[');
                s.push_str(f.name());
                s.push(']');
            }
        }
        s
    }

    /// The data scales.
    pub fn context(&self) -> &Context {
        &self.ctx
    }

    /// The pinned exponent, if any.
    pub fn fixed_n(&self) -> Option<f64> {
        self.fixed_n
    }

    /// The shape parameters the optimizer searches, in vector order.
    pub fn specs(&self) -> &[ParamSpec] {
        &self.specs
    }

    /// Names of the linear coefficients, in [`LinearFit::coef`] order.
    pub fn linear_names(&self) -> Vec<String> {
        if let Some(r) = &self.records {
            return r.names().to_vec();
        }
        self.own_linear_names()
            .into_iter()
            .map(str::to_string)
            .collect()
    }

    /// [`Self::linear_names`] of one record.
    fn own_linear_names(&self) -> Vec<&'static str> {
        let mut v = match self.placement {
            Placement::After => vec!["d_e", "d0", "alpha"],
            Placement::Feedback => vec!["scale", "d0"],
        };
        match self.form(Effect::OffsetDrift) {
            Some(Form::Spline) => {
                const KNOTS: [&str; 16] = [
                    "drift_k1",
                    "drift_k2",
                    "drift_k3",
                    "drift_k4",
                    "drift_k5",
                    "drift_k6",
                    "drift_k7",
                    "drift_k8",
                    "drift_k9",
                    "drift_k10",
                    "drift_k11",
                    "drift_k12",
                    "drift_k13",
                    "drift_k14",
                    "drift_k15",
                    "drift_k16",
                ];
                v.extend(&KNOTS[..spline_segments(&self.ctx)]);
            }
            Some(Form::Settling) | None => {}
            Some(_) => v.extend(["drift_a1", "drift_a2"]),
        }
        if self.has(Effect::Creep) {
            v.extend(["creep_x0_fast", "creep_x0_slow"]);
        }
        if self.form(Effect::OffsetDrift) == Some(Form::Settling) {
            v.push("drift_settling");
        }
        v
    }

    /// Indices (in [`LinearFit::coef`]) of coefficients that belong to a record's own
    /// initial state (the creep elements' states at its first sample, which decay as
    /// `e^(-t/τ)`).
    pub fn initial_state_coefs(&self) -> Vec<usize> {
        self.coefs_where(|n| n.starts_with("creep_x0"))
    }

    /// Indices of the coefficients that belong to one record, refitted on every record by
    /// [`Self::simulate_on`]: its sensor offset, its drift and its initial creep states.
    /// The rest (gains, the hysteresis) are the actuator's and carry over.
    pub fn record_coefs(&self) -> Vec<usize> {
        self.coefs_where(|n| n == "d0" || n.starts_with("drift_") || n.starts_with("creep_x0"))
    }

    /// The total gain of creep (a fraction of the drive it low-passes): both Kelvin-Voigt
    /// elements, or the logarithmic form's gain per decade times its decades; `None`
    /// without creep.
    pub fn creep_total(&self, theta: &[f64]) -> Option<f64> {
        let form = self.form(Effect::Creep)?;
        let sh = self.shape(theta);
        Some(match form {
            Form::Logarithmic => sh.creep_log.abs() * log_creep_taus(&self.ctx).len() as f64,
            _ => sh.creep_g.abs() + sh.creep_g2.abs(),
        })
    }

    /// Largest magnitude of each creep initial state (coefficient index, bound) on a record
    /// whose output moved by `range` ([`Self::state_range`]): an element of gain `g`
    /// low-passes `g D`, so its state departs from its equilibrium by at most `g` times how
    /// far `D` moved. Without the bound a slow element of no gain is a free decay per
    /// record: a drift named creep.
    pub fn state_bounds(&self, theta: &[f64], range: f64) -> Vec<(usize, f64)> {
        if let Some(r) = &self.records {
            return r.state_bounds(theta, range);
        }
        let Some(form) = self.form(Effect::Creep) else {
            return Vec::new();
        };
        let sh = self.shape(theta);
        let gains: Vec<f64> = match form {
            Form::Logarithmic => {
                let total = self.creep_total(theta).unwrap_or(0.0);
                vec![total, total]
            }
            _ => vec![sh.creep_g.abs(), sh.creep_g2.abs()],
        };
        self.initial_state_coefs()
            .into_iter()
            .zip(gains)
            .map(|(j, g)| {
                (
                    j,
                    if (g * range).is_finite() {
                        g * range
                    } else {
                        0.0
                    },
                )
            })
            .collect()
    }

    /// Coefficients whose name (a further record's without its `@k`) passes `keep`.
    fn coefs_where(&self, keep: impl Fn(&str) -> bool) -> Vec<usize> {
        // Without allocating names: the creep states' bounds ask on every evaluation.
        let pick = |names: &mut dyn Iterator<Item = &str>| -> Vec<usize> {
            names
                .enumerate()
                .filter(|(_, n)| keep(records::base_name(n)))
                .map(|(i, _)| i)
                .collect()
        };
        match &self.records {
            Some(r) => pick(&mut r.names().iter().map(String::as_str)),
            None => pick(&mut self.own_linear_names().into_iter()),
        }
    }

    /// Parameters counted by information criteria: shape plus linear.
    pub fn n_params(&self) -> usize {
        self.specs.len() + self.linear_names().len()
    }

    /// The same structure with `e` added in its default form (use [`Self::embed`] for the
    /// nested start).
    pub fn extended(&self, e: Effect) -> Structure {
        self.extended_with(e, e.forms()[0])
    }

    /// The same structure with `e` added (or its form replaced) in form `form`.
    pub fn extended_with(&self, e: Effect, form: Form) -> Structure {
        let mut parts: Vec<(Effect, Form)> =
            self.parts().into_iter().filter(|p| p.0 != e).collect();
        parts.push((e, form));
        self.same_records(Structure::with_forms(
            &parts,
            self.fixed_n,
            self.ctx,
            self.placement,
        ))
    }

    /// The same structure without `e`.
    pub fn without(&self, e: Effect) -> Structure {
        let parts: Vec<(Effect, Form)> = self.parts().into_iter().filter(|p| p.0 != e).collect();
        self.same_records(Structure::with_forms(
            &parts,
            self.fixed_n,
            self.ctx,
            self.placement,
        ))
    }

    /// The same effects with `dynamics` at `placement` (not nested across placements:
    /// [`Self::embed`] carries the shared parameters, the rest start neutral).
    pub fn with_placement(&self, placement: Placement) -> Structure {
        self.same_records(Structure::with_forms(
            &self.parts(),
            self.fixed_n,
            self.ctx,
            placement,
        ))
    }

    /// `theta` (a shape vector of this structure) carried into `other`, which must contain
    /// every effect of this one: shared parameters copied, new ones at their neutral values.
    pub fn embed(&self, theta: &[f64], other: &Structure) -> Vec<f64> {
        other
            .specs
            .iter()
            .map(|s| {
                self.specs
                    .iter()
                    .position(|m| m.name == s.name)
                    .and_then(|i| theta.get(i).copied())
                    .unwrap_or(s.neutral)
            })
            .collect()
    }

    /// The same model for a record sampled every `dt`: the data scales of the training
    /// record kept (so every parameter means the same), its linear blocks and integrators
    /// discretised for `dt` (the models are continuous-time). One record: a structure on
    /// several records gives its first record's model.
    pub fn at_interval(&self, dt: f64) -> Structure {
        Structure::with_forms(
            &self.parts(),
            self.fixed_n,
            Context { dt, ..self.ctx },
            self.placement,
        )
    }

    /// `theta` of this structure as the parameters of `to`, the same model at another
    /// sampling interval ([`Structure::at_interval`]): times counted in samples (a delay,
    /// the sub-sample timing) are rescaled to `to`'s samples; a mode or drive filter at or
    /// above `to`'s Nyquist frequency is off there (a frequency its samples cannot hold,
    /// whose response over the band they hold is that of a wire up to a small phase); the
    /// rest is in physical units and carried unchanged.
    pub fn carry(&self, theta: &[f64], to: &Structure) -> Vec<f64> {
        let ratio = self.ctx.dt / to.ctx.dt;
        to.specs
            .iter()
            .map(|s| {
                let Some(i) = self.specs.iter().position(|m| m.name == s.name) else {
                    return s.neutral;
                };
                let x = theta[i];
                let from = &self.specs[i];
                match s.name {
                    "delay_samples" | "timing_samples" => x * ratio,
                    "mode_log10_hz" | "mode2_log10_hz" | "lag2_log10_hz" => {
                        if x >= from.upper - 1e-9 || x >= s.upper {
                            s.upper
                        } else {
                            x
                        }
                    }
                    _ => x,
                }
            })
            .collect()
    }

    fn shape(&self, theta: &[f64]) -> Shape {
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
    fn kernel(&self, sh: &Shape, slope: f64) -> BoucWenKernel {
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

    /// Simulates the regressor columns on input `u`: `[v, 1, -(1+ρr) α-free g]` after the
    /// post-hysteresis filters, plus the drift columns; column-major, `cols[j][k]`.
    fn columns(&self, theta: &[f64], u: &[f64]) -> (Vec<Vec<f64>>, Status) {
        if let Some(r) = &self.records {
            return r.columns(theta, u);
        }
        let (varying, status) = self.varying_columns(theta, u);
        (self.assemble(varying, u.len()), status)
    }

    /// The columns that depend on the shape, in coefficient order without
    /// [`Self::fixed_columns`]: `[v, g, creep states]` (or `[y, creep states]` in the
    /// feedback placement).
    fn varying_columns(&self, theta: &[f64], u: &[f64]) -> (Vec<Vec<f64>>, Status) {
        if let Some(r) = &self.records {
            return r.varying_columns(theta, u);
        }
        let n = u.len();
        let sh = self.shape(theta);
        if self.placement == Placement::Feedback {
            return self.columns_feedback(&sh, u);
        }
        let ctx = &self.ctx;
        let dt = ctx.dt;
        let mut cv = vec![0.0; n];
        let mut cg = vec![0.0; n];
        let mut status = Status::Ok;
        if n == 0 {
            return (vec![cv, cg], status);
        }
        let finite_shape = sh.is_finite();
        let u = &if finite_shape {
            shift(u, sh.input_shift(self), sh.curvature.clamp(0.0, 1.0))
        } else {
            u.to_vec()
        };
        // Direction asymmetry: the hysteretic slope is 1 + a on rising drive, 1 - a falling.
        let up = self.kernel(&sh, 1.0 + sh.dir_a);
        let down = if sh.dir_a != 0.0 {
            self.kernel(&sh, 1.0 - sh.dir_a)
        } else {
            up
        };
        let drive = sh.drive(ctx.u_ref);
        let mut lag =
            (self.has(Effect::InputLag) && sh.lag > 0.0).then(|| LowPass::new(sh.lag, dt));
        let mut lag2 = (self.has(Effect::InputLag) && sh.lag2_hz.is_finite())
            .then(|| Mode::new(sh.lag2_hz, sh.lag2_zeta.max(0.0), dt));
        let mut rate =
            (self.has(Effect::RateDependence) && sh.rho != 0.0).then(|| LowPass::new(sh.tau_r, dt));
        let exp_tau = lag.as_ref().map(|_| sh.lag);
        let with_hold_lp = |l: LowPass| match exp_tau {
            Some(t) => l.with_exp_hold(t),
            None => l,
        };
        let mut creep: Vec<(f64, LowPass, LowPass)> = match self.form(Effect::Creep) {
            Some(form) => sh
                .creep_elements(form, ctx)
                .into_iter()
                .filter(|(g, _)| *g != 0.0)
                .map(|(g, tau)| {
                    (
                        g,
                        with_hold_lp(LowPass::new(tau, dt)),
                        with_hold_lp(LowPass::new(tau, dt)),
                    )
                })
                .collect(),
            None => Vec::new(),
        };
        let mk_mode = |f: f64, zeta: f64| {
            let m = Mode::new(f, zeta.max(0.0), dt);
            match exp_tau {
                Some(t) => m.with_exp_hold(t),
                None => m,
            }
        };
        let mut mode = (self.has(Effect::Dynamics) && sh.mode_p > 0.0).then(|| {
            let f = 1.0 / (2.0 * std::f64::consts::PI * sh.mode_p);
            (mk_mode(f, sh.zeta), mk_mode(f, sh.zeta))
        });
        let share = sh.mode2_share.clamp(0.0, 1.0);
        let mut mode2 = (self.has(Effect::Dynamics) && sh.mode2_hz.is_finite() && share > 0.0)
            .then(|| {
                (
                    mk_mode(sh.mode2_hz, sh.mode2_zeta),
                    mk_mode(sh.mode2_hz, sh.mode2_zeta),
                )
            });

        // Initial state: every block at rest at the first sample.
        let u0 = u[0];
        if let Some(l) = &mut lag {
            l.settle(u0);
        }
        if let Some(l) = &mut lag2 {
            l.settle(u0);
        }
        let v0 = drive(u0);
        // The rate's memory starts at the rate the record starts with: a record cut from a
        // running excitation starts in motion, and memory at rest would add a start-up
        // transient of the rate time constant that a drift or creep then soaks up.
        let rate0 = (u.get(1).map_or(v0, |&x| drive(x)) - v0).abs() / dt;
        if let Some(r) = &mut rate {
            r.settle(rate0);
        }
        // The hysteretic state at the first sample; the linear blocks after it at rest there.
        let mut g = sh.g0.clamp(-1.0, 1.0) * sh.g0_scale(ctx.u_ref);
        let g_init = if g.is_finite() { g } else { 0.0 };
        for (_, a, b) in &mut creep {
            a.settle(v0);
            b.settle(-g_init);
        }
        let k_dc = 1.0 + creep.iter().map(|c| c.0).sum::<f64>();
        for (a, b) in mode.iter_mut().chain(mode2.iter_mut()) {
            a.settle(k_dc * v0);
            b.settle(-k_dc * g_init);
        }
        let bound = 1e6 * (1.0 + ctx.u_ref) * (1.0 + u.iter().fold(0.0f64, |m, x| m.max(x.abs())));
        let mut v_prev = v0;
        // Previous inputs of the linear blocks, for the hold (`block_hold`): the drive
        // into the lag; without a lag, the hysteresis output into creep and modes (with a
        // lag, their inputs are continuous and the exponential hold is exact).
        let hold = sh.block_hold.clamp(0.0, 1.0);
        let held = |x: f64, prev: &mut f64| {
            let r = x - hold * (x - *prev);
            *prev = x;
            r
        };
        let hold_after = lag.is_none() && hold > 0.0;
        let mut prev_u = u0;
        let (mut prev_a0, mut prev_b0) = (v0, -g_init);
        let (mut prev_am, mut prev_bm) = (k_dc * v0, -k_dc * g_init);
        let step_mode = |m: &mut Mode, x: f64| {
            if exp_tau.is_some() {
                m.step_exp(x)
            } else {
                m.step(x)
            }
        };
        for k in 0..n {
            let mut x = u[k];
            if let Some(l) = &mut lag {
                x = l.step(held(x, &mut prev_u));
            }
            if let Some(l) = &mut lag2 {
                x = l.step(x);
            }
            let v = drive(x);
            let dv = v - v_prev;
            let rr = rate.as_mut().map_or(0.0, |r| {
                r.step(if k == 0 { rate0 } else { dv.abs() / dt }) / ctx.rate_ref
            });
            let advance = |g: f64, dv: f64| {
                if dv >= 0.0 {
                    up.advance(g, dv)
                } else {
                    down.advance(g, dv)
                }
            };
            let mut vv = v;
            if sh.rate_gain {
                vv *= 1.0 + sh.rho * rr;
                g = advance(g, dv);
            } else if rr != 0.0 {
                // The slope inside the equation scales with the rate: dg = dv (kα - c|g|^n).
                // With g = k^(1/n) g' that is the plain equation in g' over k^(1-1/n) dv, so
                // the state keeps the memory of earlier rates (the width is not rescaled at
                // once when the rate falls).
                let k = (1.0 + sh.rho * rr).max(1e-6);
                let kn = if sh.n == 1.0 { k } else { k.powf(1.0 / sh.n) };
                g = kn * advance(g / kn, dv * k / kn);
            } else {
                g = advance(g, dv);
            }
            v_prev = v;
            let (mut a, mut b) = (vv, -g);
            let (a0, b0) = if hold_after && !creep.is_empty() {
                (held(a, &mut prev_a0), held(b, &mut prev_b0))
            } else {
                (a, b)
            };
            for (gain, ca, cb) in &mut creep {
                let (la, lb) = if exp_tau.is_some() {
                    (ca.step_exp(a0), cb.step_exp(b0))
                } else {
                    (ca.step(a0), cb.step(b0))
                };
                a += *gain * la;
                b += *gain * lb;
            }
            if hold_after && (mode.is_some() || mode2.is_some()) {
                a = held(a, &mut prev_am);
                b = held(b, &mut prev_bm);
            }
            match (&mut mode, &mut mode2) {
                (Some((ma, mb)), Some((na, nb))) => {
                    let (a1, b1) = (step_mode(ma, a), step_mode(mb, b));
                    let (a2, b2) = (step_mode(na, a), step_mode(nb, b));
                    a = (1.0 - share) * a1 + share * a2;
                    b = (1.0 - share) * b1 + share * b2;
                }
                (Some((ma, mb)), None) | (None, Some((ma, mb))) => {
                    a = step_mode(ma, a);
                    b = step_mode(mb, b);
                }
                (None, None) => {}
            }
            if !(finite_shape && a.is_finite() && b.is_finite() && g.abs() <= bound) {
                status = Status::Unstable { at: k };
                cv[k..].fill(0.0);
                cg[k..].fill(0.0);
                break;
            }
            cv[k] = a;
            cg[k] = b;
        }
        let mut cols = vec![cv, cg];
        cols.extend(self.state_columns(&sh, n));
        (cols, status)
    }

    /// The columns that do not depend on the shape: the constant and the drift (`t/T,
    /// (t/T)²`, or the spline's hat functions over the record's own length).
    fn fixed_columns(&self, n: usize) -> Vec<Vec<f64>> {
        if let Some(r) = &self.records {
            return r.fixed_columns();
        }
        let dt = self.ctx.dt;
        let mut cols = vec![vec![1.0; n]];
        match self.form(Effect::OffsetDrift) {
            Some(Form::Spline) => {
                // Hats at knots 1..=m over [0, n-1]; the constant column spans knot 0.
                let m = spline_segments(&self.ctx);
                let width = (n.max(2) - 1) as f64 / m as f64;
                for j in 1..=m {
                    let c = j as f64 * width;
                    cols.push(
                        (0..n)
                            .map(|k| (1.0 - (k as f64 - c).abs() / width).max(0.0))
                            .collect(),
                    );
                }
            }
            Some(Form::Settling) | None => {}
            Some(_) => {
                let t: Vec<f64> = (0..n).map(|k| k as f64 * dt / self.ctx.t_ref).collect();
                let t2 = t.iter().map(|x| x * x).collect();
                cols.push(t);
                cols.push(t2);
            }
        }
        cols
    }

    /// Indices of [`Self::fixed_columns`] among the coefficients (the constant is always 1;
    /// the drift follows the hysteretic column after the hysteresis, the constant in the
    /// feedback placement).
    fn fixed_indices(&self) -> Vec<usize> {
        if let Some(r) = &self.records {
            return r.fixed_indices();
        }
        let drift = self.fixed_columns(0).len() - 1;
        let first = match self.placement {
            Placement::After => 3,
            Placement::Feedback => 2,
        };
        std::iter::once(1).chain(first..first + drift).collect()
    }

    /// All columns in coefficient order from the shape-dependent ones `varying`.
    fn assemble(&self, varying: Vec<Vec<f64>>, n: usize) -> Vec<Vec<f64>> {
        let fixed_at = self.fixed_indices();
        let total = varying.len() + fixed_at.len();
        let mut fixed = self.fixed_columns(n).into_iter();
        let mut var = varying.into_iter();
        (0..total)
            .map(|i| {
                if fixed_at.contains(&i) {
                    fixed.next().expect("fixed column")
                } else {
                    var.next().expect("varying column")
                }
            })
            .collect()
    }

    /// Decays `e^(-t/τ)` from each record's start, shape-dependent columns after the drift:
    /// the creep elements' initial states, then a settling drift.
    fn state_columns(&self, sh: &Shape, n: usize) -> Vec<Vec<f64>> {
        let dt = self.ctx.dt;
        let mut taus = match self.form(Effect::Creep) {
            Some(Form::Logarithmic) => log_creep_state_taus(&self.ctx).to_vec(),
            Some(_) => vec![sh.creep_tau, sh.creep_tau2],
            None => Vec::new(),
        };
        if self.form(Effect::OffsetDrift) == Some(Form::Settling) {
            taus.push(sh.drift_tau);
        }
        taus.into_iter()
            .map(|tau| {
                let r = (-dt / tau).exp();
                let col: Vec<f64> = std::iter::successors(Some(1.0), |p| Some(p * r))
                    .take(n)
                    .collect();
                if col.iter().all(|x| x.is_finite()) {
                    col
                } else {
                    vec![0.0; n]
                }
            })
            .collect()
    }

    /// [`Self::varying_columns`] for the feedback placement: `[creep(y), creep states]`, `y` the unit-free
    /// oscillator's displacement driven by the chain's output over `u_ref`.
    fn columns_feedback(&self, sh: &Shape, u: &[f64]) -> (Vec<Vec<f64>>, Status) {
        let n = u.len();
        let ctx = &self.ctx;
        let dt = ctx.dt;
        let osc = Oscillator {
            omega: 2.0 * std::f64::consts::PI * sh.fb_hz,
            zeta: sh.fb_zeta,
            r: sh.fb_r,
            b: sh.fb_b,
            c: sh.fb_c,
            n: sh.n,
        };
        let finite = sh.is_finite();
        let tail = self.state_columns(sh, n);
        let failed = |at: usize| {
            let mut cols = vec![vec![0.0; n]];
            cols.extend(tail.iter().cloned());
            (cols, Status::Unstable { at })
        };
        if n == 0 || !finite {
            return failed(0);
        }
        // The command at the samples (timing, delay, a second-order lag), between them
        // (hold), a first-order lag on the fine grid.
        let mut x = shift(u, sh.input_shift(self), sh.curvature.clamp(0.0, 1.0));
        if self.has(Effect::InputLag) && sh.lag2_hz.is_finite() {
            let mut l = Mode::new(sh.lag2_hz, sh.lag2_zeta.max(0.0), dt);
            l.settle(x[0]);
            for v in &mut x {
                *v = l.step(*v);
            }
        }
        let m = osc.substeps(dt);
        let mut fine = upsample(&x, ctx.hold, m);
        if self.has(Effect::InputLag) && sh.lag > 0.0 {
            let mut lp = LowPass::new(sh.lag, dt / (2 * m) as f64);
            lp.settle(u[0]);
            let per = fine.per();
            for (i, v) in fine.values.iter_mut().enumerate() {
                // Each interval's first value is the previous one's last instant.
                *v = if i % per == 0 {
                    lp.output()
                } else {
                    lp.step(*v)
                };
            }
        }
        let clip = sh.drive(ctx.u_ref);
        let drive = |x: f64| clip(x) / ctx.u_ref;
        fine.map(drive);
        let y = match osc.respond(&fine, dt, drive(u[0]), sh.g0.clamp(-1.0, 1.0)) {
            Ok(y) => y,
            Err(at) => return failed(at),
        };
        let mut out = y;
        if let Some(form) = self.form(Effect::Creep) {
            let y = out.clone();
            for (g, tau) in sh.creep_elements(form, ctx) {
                if g != 0.0 {
                    let mut lp = LowPass::new(tau, dt);
                    lp.settle(y[0]);
                    for (o, &v) in out.iter_mut().zip(&y).skip(1) {
                        *o += g * lp.step(v);
                    }
                    out[0] += g * y[0];
                }
            }
        }
        if out.iter().any(|v| !v.is_finite()) {
            return failed(0);
        }
        let mut cols = vec![out];
        cols.extend(tail);
        (cols, Status::Ok)
    }

    /// Fits the linear coefficients of shape `theta` to `(u, y)` by least squares and
    /// returns them with the cost `Σ e²/2`. Always finite: an unstable shape costs
    /// `cost_cap(y) (2 - at/N)`, above every stable cost and higher the earlier it fails.
    pub fn fit_linear(&self, theta: &[f64], u: &[f64], y: &[f64]) -> LinearFit {
        let len = u.len().min(y.len());
        self.fit_linear_projected(theta, u, y, &self.projection(&u[..len], &y[..len]))
    }

    /// [`Self::fit_linear`] the direct way: every column, the fixed ones included, by
    /// Gram-Schmidt ([`bounded_least_squares`]). The reference the projected solve is
    /// tested and benchmarked against.
    pub fn fit_linear_reference(&self, theta: &[f64], u: &[f64], y: &[f64]) -> LinearFit {
        let len = u.len().min(y.len());
        let (u, y) = (&u[..len], &y[..len]);
        let cap = cost_cap(y);
        let (cols, status) = self.columns(theta, u);
        if let Status::Unstable { at } = status {
            return LinearFit::unstable(cols.len(), cap, at, len);
        }
        let coef =
            bounded_least_squares(&cols, y, &self.state_bounds(theta, self.state_range(u, y)));
        let cost: f64 = (0..len)
            .map(|k| {
                let m: f64 = cols.iter().zip(&coef).map(|(c, b)| c[k] * b).sum();
                0.5 * (y[k] - m).powi(2)
            })
            .sum();
        LinearFit {
            coef,
            cost: if cost.is_finite() { cost.min(cap) } else { cap },
            status,
        }
    }

    /// The shape-independent part of [`Self::fit_linear`] on record `y`, computed once per
    /// fit: each evaluation then orthogonalises only the few shape-dependent columns (a
    /// spline drift adds up to 16 fixed ones).
    pub fn projection(&self, u: &[f64], y: &[f64]) -> Projection {
        let mut p = Projection::new(self.fixed_indices(), &self.fixed_columns(y.len()), y);
        p.span = self.state_range(u, y);
        p
    }

    /// How far the output of a record `(u, y)` moved, for the creep states' bounds
    /// ([`Self::state_bounds`]): its span, or more for a record that starts far from 0 V
    /// (the actuator was brought there before recording began, so its creep states hold
    /// that excursion: the output's slope on the input times the first input's magnitude).
    /// The most any of a joint structure's records needs.
    pub fn state_range(&self, u: &[f64], y: &[f64]) -> f64 {
        match self.records() {
            Some(parts) if u.len() == parts.iter().map(|p| p.0).sum::<usize>() => {
                let mut from = 0;
                parts
                    .iter()
                    .map(|&(n, _)| {
                        from += n;
                        reach(&u[from - n..from], &y[from - n..from])
                    })
                    .fold(0.0, f64::max)
            }
            _ => reach(u, y),
        }
    }

    /// [`Self::fit_linear`] with the fixed columns' [`Projection`] of the same `y`.
    pub fn fit_linear_projected(
        &self,
        theta: &[f64],
        u: &[f64],
        y: &[f64],
        proj: &Projection,
    ) -> LinearFit {
        self.fit_linear_residuals(theta, u, y, proj).0
    }

    /// [`Self::fit_linear_projected`] and its residuals `y - model` (empty where the shape
    /// is unstable or the cost capped): the projected solve's own, at no extra cost.
    pub fn fit_linear_residuals(
        &self,
        theta: &[f64],
        u: &[f64],
        y: &[f64],
        proj: &Projection,
    ) -> (LinearFit, Vec<f64>) {
        let len = u.len().min(y.len());
        let (u, y) = (&u[..len], &y[..len]);
        debug_assert_eq!(proj.y_perp.len(), len);
        let cap = cost_cap(y);
        let (varying, status) = self.varying_columns(theta, u);
        let ncoef = varying.len() + proj.fixed_at.len();
        if let Status::Unstable { at } = status {
            return (LinearFit::unstable(ncoef, cap, at, len), Vec::new());
        }
        let fixed_at = &proj.fixed_at;
        let varying_at = |j: usize| j - fixed_at.iter().filter(|&&f| f < j).count();
        let bounds: Vec<(usize, f64)> = self
            .state_bounds(theta, proj.span)
            .into_iter()
            .map(|(j, b)| (varying_at(j), b))
            .collect();
        let (coef, j, mut e) = proj.solve(varying, &bounds);
        let cost = if j.is_finite() && j < cap {
            j
        } else {
            e.clear();
            cap
        };
        (LinearFit { coef, cost, status }, e)
    }

    /// Model output for input `u` with shape `theta` and linear coefficients `coef` (from
    /// [`Self::fit_linear`] on training data); unstable samples hold the last finite value.
    pub fn simulate(&self, theta: &[f64], coef: &[f64], u: &[f64]) -> (Vec<f64>, Status) {
        let (cols, status) = self.columns(theta, u);
        let mut out: Vec<f64> = (0..u.len())
            .map(|k| cols.iter().zip(coef).map(|(c, b)| c[k] * b).sum())
            .collect();
        if let Status::Unstable { at } = status {
            let last = if at > 0 { out[at - 1] } else { 0.0 };
            out[at..].fill(last);
        }
        (out, status)
    }

    /// Model output on another record `(u, y)`: coefficients `coef` from training, except the
    /// record's own ones ([`Self::record_coefs`]: offset, drift, initial creep states),
    /// refitted by least squares to this record. Returns the output and the coefficients
    /// used.
    pub fn simulate_on(
        &self,
        theta: &[f64],
        coef: &[f64],
        u: &[f64],
        y: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (cols, status) = self.columns(theta, u);
        let nuisance = self.record_coefs();
        let mut c = coef.to_vec();
        let n = u.len().min(y.len());
        if !nuisance.is_empty() && status == Status::Ok {
            let rest: Vec<f64> = (0..n)
                .map(|k| {
                    y[k] - cols
                        .iter()
                        .zip(coef)
                        .enumerate()
                        .filter(|(j, _)| !nuisance.contains(j))
                        .map(|(_, (col, b))| col[k] * b)
                        .sum::<f64>()
                })
                .collect();
            let sub: Vec<Vec<f64>> = nuisance.iter().map(|&j| cols[j][..n].to_vec()).collect();
            let bounds: Vec<(usize, f64)> = self
                .state_bounds(theta, self.state_range(&u[..n], &y[..n]))
                .into_iter()
                .filter_map(|(j, b)| nuisance.iter().position(|&k| k == j).map(|i| (i, b)))
                .collect();
            for (&j, b) in nuisance
                .iter()
                .zip(bounded_least_squares(&sub, &rest, &bounds))
            {
                c[j] = b;
            }
        }
        let mut out: Vec<f64> = (0..u.len())
            .map(|k| cols.iter().zip(&c).map(|(col, b)| col[k] * b).sum())
            .collect();
        if let Status::Unstable { at } = status {
            let last = if at > 0 { out[at - 1] } else { 0.0 };
            out[at..].fill(last);
        }
        (out, c)
    }

    /// Parameters by name in the seed's form where it applies (`d_e`, `alpha`, `beta`,
    /// `gamma`, `n`, `d0` of eq. 3.1-3.3 on the data's own units), then each extension's in
    /// physical units (seconds, Hz, fractions).
    pub fn named_params(&self, theta: &[f64], coef: &[f64]) -> Vec<(String, f64)> {
        if let Some(r) = &self.records {
            return r.named_params(theta, coef);
        }
        let sh = self.shape(theta);
        let mut v: Vec<(String, f64)> = match self.placement {
            Placement::After => {
                let sigma = (sh.s * self.ctx.u_ref).powf(-sh.n);
                let alpha = coef.get(2).copied().unwrap_or(0.0);
                let scale = alpha.abs().powf(1.0 - sh.n);
                vec![
                    ("d_e".into(), coef[0]),
                    ("alpha".into(), alpha),
                    ("beta".into(), sh.w * sigma * scale),
                    ("gamma".into(), (1.0 - sh.w) * sigma * scale),
                    ("n".into(), sh.n),
                    ("d0".into(), coef[1]),
                    ("h0".into(), alpha * sh.g0 * sh.g0_scale(self.ctx.u_ref)),
                ]
            }
            Placement::Feedback => {
                // m ÿ + c ẏ + k y + z = u, ż = α ẏ - β|ẏ||z|^(n-1) z - γ ẏ|z|^n, in the
                // data's units (input per output for stiffnesses).
                let a = coef.first().copied().unwrap_or(0.0);
                let stiff = self.ctx.u_ref / a;
                let w = 2.0 * std::f64::consts::PI * sh.fb_hz;
                let mass = stiff / (w * w);
                let alpha = sh.fb_r * stiff;
                let pa = a.abs().powf(-sh.n) * alpha.abs().powf(1.0 - sh.n);
                vec![
                    ("mass".into(), mass),
                    ("damping".into(), 2.0 * sh.fb_zeta * w * mass),
                    ("stiffness".into(), (1.0 - sh.fb_r) * stiff),
                    ("alpha".into(), alpha),
                    ("beta".into(), sh.fb_b * pa),
                    ("gamma".into(), sh.fb_c * pa),
                    ("n".into(), sh.n),
                    ("d0".into(), coef.get(1).copied().unwrap_or(0.0)),
                    ("z0".into(), alpha * a * sh.g0),
                    ("natural_freq_hz".into(), sh.fb_hz),
                    ("zeta".into(), sh.fb_zeta),
                ]
            }
        };
        let lin = self.own_linear_names();
        let at = |name: &str| lin.iter().position(|n| *n == name).map_or(0.0, |i| coef[i]);
        let dt = self.ctx.dt;
        v.push(("timing_offset_s".into(), sh.timing * dt));
        v.push(("intersample_curvature".into(), sh.curvature));
        if self.specs.iter().any(|s| s.name == "block_hold_samples") {
            v.push(("block_hold_samples".into(), sh.block_hold));
        }
        let hz = |x: f64| if x.is_finite() { x } else { f64::INFINITY };
        for (&e, &form) in self.effects.iter().zip(&self.forms) {
            match (e, form) {
                (Effect::Delay, _) => v.push(("delay_s".into(), sh.delay * dt)),
                (Effect::InputLag, Form::SecondOrder) => {
                    v.push(("lag_cutoff_hz".into(), hz(sh.lag2_hz)));
                    v.push(("lag_zeta".into(), sh.lag2_zeta));
                }
                (Effect::InputLag, _) => v.push(("lag_tau_s".into(), sh.lag)),
                (Effect::Saturation, Form::Smooth) => v.push((
                    "saturation_scale_input".into(),
                    if sh.sat_k > 0.0 {
                        self.ctx.u_ref / sh.sat_k
                    } else {
                        f64::INFINITY
                    },
                )),
                (Effect::Saturation, Form::Cubic) => {
                    v.push(("saturation_cubic".into(), sh.sat_cubic))
                }
                (Effect::Asymmetry, Form::Direction) => {
                    v.push(("asymmetry_direction".into(), sh.dir_a))
                }
                (Effect::Creep, Form::Logarithmic) => {
                    v.push(("creep_gain_per_decade".into(), sh.creep_log))
                }
                (Effect::Dynamics, Form::TwoModes) if self.placement == Placement::After => {
                    let f = if sh.mode_p > 0.0 {
                        1.0 / (2.0 * std::f64::consts::PI * sh.mode_p)
                    } else {
                        f64::INFINITY
                    };
                    v.push(("mode_freq_hz".into(), f));
                    v.push(("mode_zeta".into(), sh.zeta));
                    v.push(("mode2_freq_hz".into(), hz(sh.mode2_hz)));
                    v.push(("mode2_zeta".into(), sh.mode2_zeta));
                    v.push(("mode2_share".into(), sh.mode2_share));
                }
                (Effect::OffsetDrift, Form::Spline) => v.push((
                    "drift_knot_spacing_s".into(),
                    self.ctx.t_ref / spline_segments(&self.ctx) as f64,
                )),
                (Effect::Saturation, _) => v.push((
                    "saturation_limit_input".into(),
                    if sh.sat_c > 0.0 {
                        self.ctx.u_ref / sh.sat_c
                    } else {
                        f64::INFINITY
                    },
                )),
                (Effect::Asymmetry, _) => {
                    v.push(("asymmetry_q_per_input".into(), sh.q / self.ctx.u_ref))
                }
                (Effect::RateDependence, _) => {
                    v.push(("rate_rho".into(), sh.rho));
                    v.push(("rate_tau_s".into(), sh.tau_r));
                }
                (Effect::Creep, _) => {
                    v.push(("creep_gain".into(), sh.creep_g));
                    v.push(("creep_tau_s".into(), sh.creep_tau));
                    v.push(("creep_gain_slow".into(), sh.creep_g2));
                    v.push(("creep_tau_slow_s".into(), sh.creep_tau2));
                }
                (Effect::Dynamics, _) if self.placement == Placement::Feedback => {}
                (Effect::Dynamics, _) => {
                    let f = if sh.mode_p > 0.0 {
                        1.0 / (2.0 * std::f64::consts::PI * sh.mode_p)
                    } else {
                        f64::INFINITY
                    };
                    v.push(("mode_freq_hz".into(), f));
                    v.push(("mode_zeta".into(), sh.zeta));
                }
                (Effect::OffsetDrift, Form::Settling) => {
                    v.push(("drift_settling_tau_s".into(), sh.drift_tau))
                }
                (Effect::OffsetDrift, _) => {
                    let t = self.ctx.t_ref;
                    v.push(("drift_per_s".into(), at("drift_a1") / t));
                    v.push(("drift_per_s2".into(), at("drift_a2") / (t * t)));
                }
            }
        }
        v
    }
}

/// Least squares with some columns fixed across evaluations (the constant, the drift):
/// the data with them projected out once, so an evaluation projects only its
/// shape-dependent columns off them (the same solution as [`least_squares`] on all
/// columns). The fixed columns are kept raw, each on its support, with the `R` of their QR
/// (`HᵀH = RᵀR`): projecting off a spline's hats then costs a few operations per sample
/// whatever their number, where an orthonormal basis is dense.
#[derive(Clone, Debug)]
pub struct Projection {
    /// Positions of the fixed columns among the coefficients.
    fixed_at: Vec<usize>,
    /// Each fixed column on its support: first sample and the values from there.
    fixed: Vec<(usize, Vec<f64>)>,
    /// Whether each fixed column is independent of the earlier ones (kept).
    kept: Vec<bool>,
    /// `R` of the fixed columns' QR (upper triangle).
    r: Vec<Vec<f64>>,
    /// `y` minus its projection on the fixed columns.
    y_perp: Vec<f64>,
    /// `Hᵀ y`.
    hty: Vec<f64>,
    /// How far the output moved ([`Structure::state_range`]), which bounds the creep
    /// states: once per fit, not per evaluation.
    span: f64,
}

/// `v` minus its projections on `q` (twice: Gram-Schmidt with reorthogonalisation), the
/// coefficients added to `r`.
fn orthogonalise(v: &mut [f64], q: &[Option<Vec<f64>>], r: &mut [f64]) {
    for _ in 0..2 {
        for (i, qi) in q.iter().enumerate() {
            let Some(qi) = qi.as_ref() else { continue };
            let d = dot(qi, v);
            r[i] += d;
            v.iter_mut().zip(qi).for_each(|(x, a)| *x -= d * a);
        }
    }
}
/// `Σ aᵢ bᵢ` in eight interleaved partial sums: a single running sum waits on each add's
/// latency, and these dot products over whole records are most of a fit's linear algebra.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// Gram-Schmidt QR of `cols` (first `n` rows): orthonormal columns (None where a column
/// depends on the earlier ones) and `R`.
#[allow(clippy::type_complexity)]
fn qr(cols: &[Vec<f64>], n: usize) -> (Vec<Option<Vec<f64>>>, Vec<Vec<f64>>) {
    let m = cols.len();
    let mut q: Vec<Option<Vec<f64>>> = Vec::with_capacity(m);
    let mut r = vec![vec![0.0; m]; m];
    let mut rj = vec![0.0; m];
    for j in 0..m {
        let mut v = cols[j][..n].to_vec();
        let norm0 = dot(&v, &v).sqrt();
        rj.fill(0.0);
        orthogonalise(&mut v, &q, &mut rj);
        for (i, x) in rj.iter().enumerate().take(j) {
            r[i][j] = *x;
        }
        let norm = dot(&v, &v).sqrt();
        if norm > 1e-10 * norm0 && norm.is_finite() && norm > 0.0 {
            r[j][j] = norm;
            v.iter_mut().for_each(|x| *x /= norm);
            q.push(Some(v));
        } else {
            q.push(None);
        }
    }
    (q, r)
}

/// Solves `R b = rhs` for the kept columns of a [`qr`] (dropped ones get 0); all zeros if
/// anything is not finite.
fn back_substitute(q: &[Option<Vec<f64>>], r: &[Vec<f64>], rhs: &[f64]) -> Vec<f64> {
    let m = q.len();
    let mut b = vec![0.0; m];
    for j in (0..m).rev() {
        if q[j].is_none() {
            continue;
        }
        let s: f64 = (j + 1..m).map(|k| r[j][k] * b[k]).sum();
        b[j] = (rhs[j] - s) / r[j][j];
    }
    if b.iter().all(|x| x.is_finite()) {
        b
    } else {
        vec![0.0; m]
    }
}

impl Projection {
    /// The projection of `y` off `fixed` (columns of `y`'s length), which sit at
    /// `fixed_at` among the coefficients.
    pub fn new(fixed_at: Vec<usize>, fixed: &[Vec<f64>], y: &[f64]) -> Self {
        let n = y.len();
        let (q, r) = qr(fixed, n);
        let kept = q.iter().map(Option::is_some).collect();
        let fixed = fixed
            .iter()
            .map(|c| {
                let c = &c[..n];
                let lo = c.iter().position(|&x| x != 0.0).unwrap_or(0);
                let hi = c.iter().rposition(|&x| x != 0.0).map_or(lo, |i| i + 1);
                (lo, c[lo..hi].to_vec())
            })
            .collect();
        let mut p = Projection {
            fixed_at,
            fixed,
            kept,
            r,
            y_perp: y.to_vec(),
            hty: Vec::new(),
            span: span(y),
        };
        let mut y_perp = std::mem::take(&mut p.y_perp);
        p.hty = p.project(&mut y_perp);
        p.y_perp = y_perp;
        p
    }

    /// `Hᵀ v`, each fixed column over its support.
    fn ht(&self, v: &[f64]) -> Vec<f64> {
        self.fixed.iter().map(|(lo, c)| dot(&v[*lo..], c)).collect()
    }

    /// `(HᵀH)⁻¹ c` over the kept columns (`Rᵀ z = c`, then `R w = z`); dropped ones get 0.
    fn gram_solve(&self, c: &[f64]) -> Vec<f64> {
        let m = c.len();
        let mut z = vec![0.0; m];
        for j in 0..m {
            if !self.kept[j] {
                continue;
            }
            let s: f64 = (0..j)
                .filter(|&i| self.kept[i])
                .map(|i| self.r[i][j] * z[i])
                .sum();
            z[j] = (c[j] - s) / self.r[j][j];
        }
        let mut w = vec![0.0; m];
        for j in (0..m).rev() {
            if !self.kept[j] {
                continue;
            }
            let s: f64 = (j + 1..m)
                .filter(|&k| self.kept[k])
                .map(|k| self.r[j][k] * w[k])
                .sum();
            w[j] = (z[j] - s) / self.r[j][j];
        }
        w
    }

    /// `v` minus its projection on the fixed columns (twice: the second pass removes what
    /// round-off left of the first); returns `Hᵀ v` of the `v` given.
    fn project(&self, v: &mut [f64]) -> Vec<f64> {
        let first = self.ht(v);
        self.subtract(v, &first);
        let again = self.ht(v);
        self.subtract(v, &again);
        first
    }

    /// `v -= H (HᵀH)⁻¹ c`, each fixed column over its support.
    fn subtract(&self, v: &mut [f64], c: &[f64]) {
        let w = self.gram_solve(c);
        for ((lo, col), wi) in self.fixed.iter().zip(&w) {
            if *wi != 0.0 {
                v[*lo..].iter_mut().zip(col).for_each(|(x, a)| *x -= wi * a);
            }
        }
    }

    /// Coefficients (in coefficient order) and `Σ e²/2` for the shape-dependent columns
    /// `varying` (in their order, without the fixed ones).
    /// `bounds`: (index in `varying`, largest magnitude) of bounded coefficients. Also the
    /// residuals: off the fixed columns' span, which the fixed coefficients absorb exactly.
    fn solve(
        &self,
        mut varying: Vec<Vec<f64>>,
        bounds: &[(usize, f64)],
    ) -> (Vec<f64>, f64, Vec<f64>) {
        let m = self.fixed.len();
        let n = self.y_perp.len();
        // Hᵀ V, and V with the fixed columns projected out.
        let htv: Vec<Vec<f64>> = varying
            .iter_mut()
            .map(|v| {
                let norm0 = dot(&v[..n], &v[..n]).sqrt();
                let c = self.project(&mut v[..n]);
                // A column inside the fixed span is dependent: drop it, as least squares
                // on all columns would.
                let norm = dot(&v[..n], &v[..n]).sqrt();
                if norm.is_nan() || norm <= 1e-10 * norm0 {
                    v.fill(0.0);
                }
                c
            })
            .collect();
        let bv = gram_least_squares(&varying, &self.y_perp, bounds);
        let mut e = self.y_perp.clone();
        for (v, b) in varying.iter().zip(&bv) {
            if *b != 0.0 {
                e.iter_mut().zip(v).for_each(|(x, c)| *x -= b * c);
            }
        }
        let cost = 0.5 * dot(&e, &e);
        // HᵀH b_f = Hᵀ y - Hᵀ V b_v.
        let rhs: Vec<f64> = (0..m)
            .map(|i| self.hty[i] - htv.iter().zip(&bv).map(|(c, b)| c[i] * b).sum::<f64>())
            .collect();
        let bf = self.gram_solve(&rhs);
        let bf = if bf.iter().all(|x| x.is_finite()) {
            bf
        } else {
            vec![0.0; m]
        };
        let total = bv.len() + m;
        let mut coef = Vec::with_capacity(total);
        let (mut fi, mut vi) = (bf.into_iter(), bv.into_iter());
        for i in 0..total {
            coef.push(if self.fixed_at.contains(&i) {
                fi.next().unwrap_or(0.0)
            } else {
                vi.next().unwrap_or(0.0)
            });
        }
        (coef, cost, e)
    }
}

/// Least squares `min |y - Σ b_j c_j|` by modified Gram-Schmidt with one
/// reorthogonalisation; columns that are (numerically) in the span of earlier ones get 0.
pub fn least_squares(cols: &[Vec<f64>], y: &[f64]) -> Vec<f64> {
    let (q, r) = qr(cols, y.len());
    let qty: Vec<f64> = q
        .iter()
        .map(|qi| qi.as_ref().map_or(0.0, |qi| dot(qi, y)))
        .collect();
    back_substitute(&q, &r, &qty)
}

/// [`least_squares`] with some coefficients bounded in magnitude (`(index, bound)`): a
/// coefficient beyond its bound is held there and the others refitted, until none is
/// beyond (at most once per bounded coefficient).
pub fn bounded_least_squares(cols: &[Vec<f64>], y: &[f64], bounds: &[(usize, f64)]) -> Vec<f64> {
    let solve = |held: &[(usize, f64)]| {
        if held.is_empty() {
            return Some(least_squares(cols, y));
        }
        let mut target = y.to_vec();
        for &(j, x) in held {
            target
                .iter_mut()
                .zip(&cols[j])
                .for_each(|(t, c)| *t -= x * c);
        }
        let free: Vec<Vec<f64>> = cols
            .iter()
            .enumerate()
            .map(|(j, c)| {
                if held.iter().any(|h| h.0 == j) {
                    vec![0.0; c.len()]
                } else {
                    c.clone()
                }
            })
            .collect();
        let mut b = least_squares(&free, &target);
        for &(j, x) in held {
            b[j] = x;
        }
        Some(b)
    };
    active_set(bounds, solve).expect("Gram-Schmidt always solves")
}

/// The active-set loop of a bounded least squares: `solve(held)` (coefficients with
/// `held` fixed, None if it cannot) from none held; a coefficient beyond its bound is
/// then held there and the rest solved again, until none is beyond (at most once per
/// bounded coefficient). None as soon as a solve is None.
fn active_set(
    bounds: &[(usize, f64)],
    solve: impl Fn(&[(usize, f64)]) -> Option<Vec<f64>>,
) -> Option<Vec<f64>> {
    let mut b = solve(&[])?;
    let mut held: Vec<(usize, f64)> = Vec::new();
    for _ in 0..bounds.len() {
        let beyond: Vec<(usize, f64)> = bounds
            .iter()
            .filter(|(j, _)| !held.iter().any(|h| h.0 == *j))
            .filter_map(|&(j, lim)| {
                let x = *b.get(j)?;
                (x.abs() > lim).then(|| (j, lim.copysign(x)))
            })
            .collect();
        if beyond.is_empty() {
            break;
        }
        held.extend(beyond);
        b = solve(&held)?;
    }
    Some(b)
}

/// [`bounded_least_squares`] by the normal equations of the columns scaled to unit norm:
/// one pass per inner product and no column copied, where Gram-Schmidt's passes were most
/// of an evaluation's linear algebra. Only when every column keeps at least `1e-4` of its
/// norm outside the earlier ones (the squared condition number then costs at most eight
/// digits of the coefficients, and only to second order the cost, which the caller takes
/// from the residual); otherwise, dependent columns included, Gram-Schmidt decides.
fn gram_least_squares(cols: &[Vec<f64>], y: &[f64], bounds: &[(usize, f64)]) -> Vec<f64> {
    let m = cols.len();
    let scale: Vec<f64> = cols
        .iter()
        .map(|c| {
            let d = dot(c, c).sqrt();
            if d > 0.0 && d.is_finite() {
                1.0 / d
            } else {
                0.0
            }
        })
        .collect();
    let mut g = vec![vec![0.0; m]; m];
    for i in 0..m {
        for j in i..m {
            let x = if scale[i] == 0.0 || scale[j] == 0.0 {
                0.0
            } else if i == j {
                1.0
            } else {
                dot(&cols[i], &cols[j]) * scale[i] * scale[j]
            };
            g[i][j] = x;
            g[j][i] = x;
        }
    }
    let gy: Vec<f64> = (0..m)
        .map(|j| {
            if scale[j] == 0.0 {
                0.0
            } else {
                dot(&cols[j], y) * scale[j]
            }
        })
        .collect();
    // Coefficients with `held` (index, value in the columns' own units) fixed; None if the
    // free columns are near dependent.
    let solve = |held: &[(usize, f64)]| -> Option<Vec<f64>> {
        let free: Vec<usize> = (0..m)
            .filter(|&j| scale[j] != 0.0 && !held.iter().any(|h| h.0 == j))
            .collect();
        let rhs: Vec<f64> = free
            .iter()
            .map(|&i| {
                gy[i]
                    - held
                        .iter()
                        .filter(|h| scale[h.0] != 0.0)
                        .map(|&(j, x)| g[i][j] * x / scale[j])
                        .sum::<f64>()
            })
            .collect();
        // Cholesky L Lᵀ of the free block.
        let k = free.len();
        let mut l = vec![vec![0.0; k]; k];
        for a in 0..k {
            let d = g[free[a]][free[a]] - (0..a).map(|c| l[a][c] * l[a][c]).sum::<f64>();
            if d.is_nan() || d < 1e-8 {
                return None;
            }
            let da = d.sqrt();
            l[a][a] = da;
            for b in a + 1..k {
                let x = g[free[b]][free[a]] - (0..a).map(|c| l[b][c] * l[a][c]).sum::<f64>();
                l[b][a] = x / da;
            }
        }
        let mut z = vec![0.0; k];
        for a in 0..k {
            let s: f64 = (0..a).map(|c| l[a][c] * z[c]).sum();
            z[a] = (rhs[a] - s) / l[a][a];
        }
        let mut w = vec![0.0; k];
        for a in (0..k).rev() {
            let s: f64 = (a + 1..k).map(|c| l[c][a] * w[c]).sum();
            w[a] = (z[a] - s) / l[a][a];
        }
        let mut b = vec![0.0; m];
        for (a, &j) in free.iter().enumerate() {
            b[j] = w[a] * scale[j];
        }
        for &(j, x) in held {
            b[j] = x;
        }
        b.iter().all(|x| x.is_finite()).then_some(b)
    };
    active_set(bounds, solve).unwrap_or_else(|| bounded_least_squares(cols, y, bounds))
}

/// [`span`] of `y`, or the output's least-squares slope on the input times `|u[0]|` where
/// that is more: how far a record's output moved since the actuator rested at 0 V.
fn reach(u: &[f64], y: &[f64]) -> f64 {
    let n = u.len().min(y.len());
    let (u, y) = (&u[..n], &y[..n]);
    let here = span(y);
    if n < 2 {
        return here;
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
    let (mu, my) = (mean(u), mean(y));
    let (mut suy, mut suu) = (0.0, 0.0);
    for (a, b) in u.iter().zip(y) {
        suy += (a - mu) * (b - my);
        suu += (a - mu) * (a - mu);
    }
    let before = if suu > 0.0 {
        (suy / suu).abs() * u[0].abs()
    } else {
        0.0
    };
    if before.is_finite() {
        here.max(before)
    } else {
        here
    }
}

/// Max minus min of a record (0 if empty or not finite).
fn span(y: &[f64]) -> f64 {
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
    if hi >= lo && (hi - lo).is_finite() {
        hi - lo
    } else {
        0.0
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::physics::bouc_wen;
    use crate::physics::twin::{self, TwinConfig};

    /// A record that starts far from 0 V bounds its creep states by the excursion that
    /// brought it there (slope times its first input), one near 0 V by its span; a joint
    /// structure takes the most any of its records needs.
    #[test]
    fn creep_states_are_bounded_by_how_far_the_output_moved_since_rest() {
        let dt = 1e-3;
        let high: Vec<f64> = (0..1000).map(|k| 4.0 - 0.5 * k as f64 / 1000.0).collect();
        let low: Vec<f64> = high.iter().map(|x| x - 3.9).collect();
        let out = |u: &[f64]| -> Vec<f64> { u.iter().map(|x| 0.15 * x - 0.2).collect() };
        let st = Structure::new(
            &[Effect::Creep],
            Some(1.0),
            Context::from_training(&high, dt),
        );
        let (yh, yl) = (out(&high), out(&low));
        assert!((st.state_range(&high, &yh) - 0.6).abs() < 1e-9);
        assert!((st.state_range(&low, &yl) - span(&yl)).abs() < 1e-12);
        let joint = st.on_records(&[(1000, dt), (1000, 2.0 * dt)]);
        let u: Vec<f64> = low.iter().chain(&high).copied().collect();
        let y: Vec<f64> = yl.iter().chain(&yh).copied().collect();
        assert!((joint.state_range(&u, &y) - 0.6).abs() < 1e-9);
    }

    /// A model carried to half the sampling interval is the same continuous-time model: a
    /// mode, a delay counted in samples and a drive filter give the same output at the
    /// shared instants, up to the discretisation of the smooth drive.
    #[test]
    fn a_model_carried_to_another_interval_is_the_same_model() {
        let dt = 1e-3;
        let u = sine(2000, 3.0, dt);
        let parts = [
            (Effect::Delay, Form::Transport),
            (Effect::InputLag, Form::SecondOrder),
            (Effect::Dynamics, Form::OneMode),
        ];
        let ctx = Context::from_training(&u, dt);
        let st = Structure::with_forms(&parts, Some(1.0), ctx, Placement::After);
        let theta = theta_with(
            &st,
            &[
                ("delay_samples", 3.0),
                ("lag2_log10_hz", 80f64.log10()),
                ("mode_log10_hz", 40f64.log10()),
                ("mode_log10_zeta", 0.1f64.log10()),
            ],
        );
        let mut coef = vec![0.0; st.linear_names().len()];
        coef[0] = 1.0;
        coef[2] = 0.5;
        let fine = st.at_interval(dt / 2.0);
        let carried = st.carry(&theta, &fine);
        let at = |name: &str| fine.specs().iter().position(|s| s.name == name).unwrap();
        assert_eq!(carried[at("delay_samples")], 6.0);
        assert_eq!(carried[at("mode_log10_hz")], 40f64.log10());
        let (coarse_out, _) = st.simulate(&theta, &coef, &u);
        let (fine_out, _) = fine.simulate(&carried, &coef, &sine(4000, 3.0, dt / 2.0));
        // After the start-up transient, at the shared instants.
        let worst = (200..2000)
            .map(|k| (coarse_out[k] - fine_out[2 * k]).abs())
            .fold(0.0, f64::max);
        let span = coarse_out.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(worst < 0.006 * span, "worst {worst} of {span}");
        // Back to the training interval: the same parameters.
        let back = fine.carry(&carried, &st);
        for (a, b) in back.iter().zip(&theta) {
            assert!((a - b).abs() < 1e-12);
        }
        // A mode above a coarser record's Nyquist frequency is off there.
        let slow = st.at_interval(0.02);
        let off = st.carry(&theta, &slow);
        let m = slow
            .specs()
            .iter()
            .position(|s| s.name == "mode_log10_hz")
            .unwrap();
        assert_eq!(off[m], slow.specs()[m].upper);
    }

    fn sine(n: usize, f: f64, dt: f64) -> Vec<f64> {
        (0..n)
            .map(|k| 2.35 - 2.3 * (2.0 * std::f64::consts::PI * f * k as f64 * dt).cos())
            .collect()
    }

    #[test]
    fn plain_model_equals_the_seed_bouc_wen() {
        // α-scaled g-form with n ≠ 1 reproduces bouc_wen::simulate of the seed's form.
        let dt = 1e-3;
        let u = sine(1500, 3.0, dt);
        let ctx = Context::from_training(&u, dt);
        for n in [1.0, 0.7, 1.6] {
            let p = BoucWenParams {
                d_e: 0.15,
                alpha: 0.05,
                beta: 0.4,
                gamma: 0.25,
                n,
                d0: 0.01,
            };
            let mut y = vec![0.0; u.len()];
            bouc_wen::simulate(&p, &u, &mut y);
            let st = Structure::new(&[], None, ctx);
            // Shape of p: σ = (β'+γ') = (β+γ) α^(n-1) = (s u_ref)^-n.
            let sigma = (p.beta + p.gamma) * p.alpha.powf(n - 1.0);
            let s = sigma.powf(-1.0 / n) / ctx.u_ref;
            let theta = [s.log10(), p.beta / (p.beta + p.gamma), n, 0.0];
            let fit = st.fit_linear(&theta, &u, &y);
            assert!(fit.cost < 1e-20, "n={n}: {}", fit.cost);
            let named = st.named_params(&theta, &fit.coef);
            let get = |k: &str| named.iter().find(|x| x.0 == k).unwrap().1;
            for (k, want) in [
                ("d_e", p.d_e),
                ("alpha", p.alpha),
                ("beta", p.beta),
                ("gamma", p.gamma),
                ("d0", p.d0),
            ] {
                assert!((get(k) - want).abs() < 1e-8 * (1.0 + want.abs()), "{k}");
            }
        }
    }

    #[test]
    fn extensions_at_neutral_values_are_the_plain_model() {
        let dt = 1e-3;
        let u = sine(800, 5.0, dt);
        let y: Vec<f64> = u.iter().map(|x| 0.15 * x + 0.001 * x * x).collect();
        let ctx = Context::from_training(&u, dt);
        let plain = Structure::new(&[], Some(1.0), ctx);
        let theta = [-0.4, 0.6, 0.1];
        let base = plain.fit_linear(&theta, &u, &y);
        let all = Structure::new(&Effect::ALL, Some(1.0), ctx);
        let nested = plain.embed(&theta, &all);
        let ext = all.fit_linear(&nested, &u, &y);
        // Offset-drift and creep add free columns (drift, initial creep states), so their
        // cost can only be lower; the others equal the plain model's, in every form.
        assert!(ext.cost <= base.cost * (1.0 + 1e-12));
        for e in Effect::ALL {
            for &form in e.forms() {
                let one = Structure::with_forms(&[(e, form)], Some(1.0), ctx, Placement::After);
                assert_eq!(one.form(e), Some(form));
                let f = one.fit_linear(&plain.embed(&theta, &one), &u, &y);
                if matches!(e, Effect::OffsetDrift | Effect::Creep) {
                    assert!(f.cost <= base.cost * (1.0 + 1e-12), "{}", one.label());
                    continue;
                }
                assert!(
                    (f.cost - base.cost).abs() <= 1e-10 * base.cost,
                    "{}: {} vs {}",
                    one.label(),
                    f.cost,
                    base.cost
                );
            }
        }
    }

    /// Each twin part is reproduced by the matching extension at the twin's values.
    #[test]
    fn extensions_reproduce_the_twin() {
        let dt = 1e-3;
        // From 0 V, where the twin rests (the model starts virgin at u[0]).
        let u: Vec<f64> = sine(1500, 4.0, dt).iter().map(|x| x - 0.05).collect();
        let ctx = Context::from_training(&u, dt);
        let base = "amp=off,mode=off,noise=off,quantization=off";
        let p = TwinConfig::default().command_scale_bouc_wen();
        let sigma = p.beta + p.gamma; // n = 1
        let s = (1.0 / sigma / ctx.u_ref).log10();
        let w = p.beta / (p.beta + p.gamma);
        let gain = 15.0;
        type Case<'a> = (&'a str, Vec<Effect>, Vec<(&'a str, f64)>);
        let cases: Vec<Case> = vec![
            ("", vec![], vec![]),
            (
                "amp=on,amp.cutoff_hz=500",
                vec![Effect::InputLag],
                vec![(
                    "lag_log10_tau_s",
                    (1.0 / (2.0 * std::f64::consts::PI * 500.0)).log10(),
                )],
            ),
            (
                "delay=0.002",
                vec![Effect::Delay],
                vec![("delay_samples", 2.0)],
            ),
            (
                "saturation.limit=60",
                vec![Effect::Saturation],
                vec![("sat_level", 60.0 / gain / ctx.u_ref)],
            ),
            (
                "asymmetry=0.001",
                vec![Effect::Asymmetry],
                vec![("asym_q", 0.001 * gain * ctx.u_ref)],
            ),
            (
                "mode=on,mode.freq_hz=150",
                vec![Effect::Dynamics],
                vec![
                    ("mode_log10_hz", 150f64.log10()),
                    ("mode_log10_zeta", 0.04f64.log10()),
                ],
            ),
            (
                "creep=on,creep.gain_slow=0.03,creep.tau_fast=0.3,creep.gain_fast=0.05",
                vec![Effect::Creep],
                vec![
                    ("creep_g", 0.05),
                    ("creep_log10_tau_s", 0.3f64.log10()),
                    ("creep_g2", 0.03),
                    ("creep_log10_tau2_s", 20f64.log10()),
                ],
            ),
        ];
        for (ov, effects, values) in cases {
            let cfg = TwinConfig::parse_overrides(&format!("{base},{ov}")).unwrap();
            let y = twin::simulate(&cfg, &u, dt, 0);
            let st = Structure::new(&effects, Some(1.0), ctx);
            let mut theta: Vec<f64> = st.specs().iter().map(|s| s.neutral).collect();
            theta[0] = s;
            theta[1] = w;
            for (name, v) in values {
                let i = st.specs().iter().position(|s| s.name == name).unwrap();
                theta[i] = v;
            }
            let fit = st.fit_linear(&theta, &u, &y);
            let rms = (2.0 * fit.cost / u.len() as f64).sqrt();
            assert!(rms < 2e-6, "{ov}: rms {rms}");
            assert!((fit.coef[0] - gain * 0.0103).abs() < 1e-3, "{ov}");
        }
    }

    /// The shape of `st` with the named values set, every other parameter neutral.
    pub(crate) fn theta_with(st: &Structure, values: &[(&str, f64)]) -> Vec<f64> {
        st.specs()
            .iter()
            .map(|s| {
                values
                    .iter()
                    .find(|v| v.0 == s.name)
                    .map_or(s.neutral, |v| v.1)
            })
            .collect()
    }

    #[test]
    fn shift_reads_inside_the_record_as_at_its_ends() {
        // The direct formula with every index clamped, which `shift` applies at the ends.
        let reference = |u: &[f64], s: f64, curvature: f64| -> Vec<f64> {
            let n = u.len() as i64;
            if s == 0.0 || n < 2 {
                return u.to_vec();
            }
            let (w, t) = (s.floor() as i64, 1.0 - (s - s.floor()));
            let at = |i: i64| u[i.clamp(0, n - 1) as usize];
            let c0 = curvature * t * (1.0 - t) / 2.0 * (2.0 - t) / 3.0;
            let c1 = curvature * t * (1.0 - t) / 2.0 * (1.0 + t) / 3.0;
            (0..n)
                .map(|k| {
                    let (p0, p1, p2, p3) = (at(k - w - 2), at(k - w - 1), at(k - w), at(k - w + 1));
                    let line = p1 + t * (p2 - p1);
                    if curvature == 0.0 || t == 1.0 {
                        line
                    } else {
                        line - c0 * (p0 - 2.0 * p1 + p2) - c1 * (p1 - 2.0 * p2 + p3)
                    }
                })
                .collect()
        };
        for n in [1usize, 2, 3, 4, 5, 9, 40] {
            let u: Vec<f64> = (0..n).map(|k| ((k * k) as f64 * 0.37).sin()).collect();
            let nf = n as f64;
            for s in [
                -nf - 7.3,
                -nf,
                -nf + 1.5,
                -3.25,
                -1.0,
                -0.5,
                0.0,
                0.4,
                1.0,
                2.75,
                nf - 1.5,
                nf,
                nf + 4.6,
            ] {
                for c in [0.0, 0.7, 1.0] {
                    assert_eq!(shift(&u, s, c), reference(&u, s, c), "n {n} s {s} c {c}");
                }
            }
        }
    }

    #[test]
    fn timing_moves_the_input_by_whole_and_fractional_samples() {
        let dt = 1e-3;
        let u = sine(900, 3.0, dt);
        let ctx = Context::from_training(&u, dt);
        let st = Structure::new(&[], Some(1.0), ctx);
        let shape = [("log10_s", -0.4), ("w", 0.6)];
        let coef = [0.15, 0.01, 0.05];
        // One sample earlier is the next sample (the last one held).
        let (early, _) = st.simulate(
            &theta_with(&st, &[shape[0], shape[1], ("timing_samples", -1.0)]),
            &coef,
            &u,
        );
        let mut next = u[1..].to_vec();
        next.push(u[u.len() - 1]);
        let (want, _) = st.simulate(&theta_with(&st, &shape), &coef, &next);
        for (a, b) in early.iter().zip(&want).skip(1) {
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
        // Half a sample later is the mean of neighbours, before the hysteresis.
        let half: Vec<f64> = (0..u.len())
            .map(|k| 0.5 * (u[k] + u[k.saturating_sub(1)]))
            .collect();
        let (late, _) = st.simulate(
            &theta_with(&st, &[shape[0], shape[1], ("timing_samples", 0.5)]),
            &coef,
            &u,
        );
        let (want, _) = st.simulate(&theta_with(&st, &shape), &coef, &half);
        for (a, b) in late.iter().zip(&want) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn a_held_input_reaches_the_linear_blocks_one_sample_later() {
        let dt = 1e-3;
        let u = sine(800, 7.0, dt);
        let ctx = Context::from_training(&u, dt);
        let coef = [0.15, 0.01, 0.05];
        let shape = [("log10_s", -0.4), ("w", 0.6)];
        // Through an input lag: a D/A hold is the whole chain one sample later.
        let lag = Structure::with_forms(
            &[(Effect::InputLag, Form::FirstOrder)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        let tau = ("lag_log10_tau_s", (2e-3f64).log10());
        assert!(lag.specs().iter().any(|s| s.name == tau.0));
        let (held, _) = lag.simulate(
            &theta_with(
                &lag,
                &[shape[0], shape[1], tau, ("block_hold_samples", 1.0)],
            ),
            &coef,
            &u,
        );
        let mut later = vec![u[0]];
        later.extend(&u[..u.len() - 1]);
        let (want, _) = lag.simulate(&theta_with(&lag, &[shape[0], shape[1], tau]), &coef, &later);
        for (a, b) in held.iter().zip(&want) {
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
        // Without a linear block there is nothing to hold (the hysteresis is
        // rate-independent): the nuisance is not offered.
        let plain = Structure::new(&[], Some(1.0), ctx);
        assert!(!plain.specs().iter().any(|s| s.name == "block_hold_samples"));
        // Through a mode after the hysteresis it moves the output.
        let mode = Structure::with_forms(
            &[(Effect::Dynamics, Form::OneMode)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        let p = ("mode_log10_hz", 150f64.log10());
        assert!(mode.specs().iter().any(|s| s.name == p.0));
        let (c, _) = mode.simulate(&theta_with(&mode, &[shape[0], shape[1], p]), &coef, &u);
        let (d, _) = mode.simulate(
            &theta_with(&mode, &[shape[0], shape[1], p, ("block_hold_samples", 1.0)]),
            &coef,
            &u,
        );
        assert!(c.iter().zip(&d).any(|(x, y)| (x - y).abs() > 1e-6));
    }

    #[test]
    fn a_curved_shift_is_exact_for_cubics_and_a_straight_one_for_lines() {
        let cubic: Vec<f64> = (0..40)
            .map(|k| {
                let x = k as f64 * 0.1;
                1.0 - 0.5 * x + 0.3 * x * x - 0.07 * x * x * x
            })
            .collect();
        let line: Vec<f64> = (0..40).map(|k| 2.0 - 0.3 * k as f64).collect();
        for s in [0.3, -0.6, 1.45, -1.0] {
            let c = shift(&cubic, s, 1.0);
            let l = shift(&line, s, 0.0);
            // Away from the held ends.
            for k in 4..36 {
                let x = (k as f64 - s) * 0.1;
                let want = 1.0 - 0.5 * x + 0.3 * x * x - 0.07 * x * x * x;
                assert!(
                    (c[k] - want).abs() < 1e-12,
                    "s {s} k {k}: {} vs {want}",
                    c[k]
                );
                assert!((l[k] - (2.0 - 0.3 * (k as f64 - s))).abs() < 1e-12);
            }
            // A straight shift of a cubic is not exact (curvature matters).
            let straight = shift(&cubic, s, 0.0);
            if s.fract() != 0.0 {
                assert!((4..36).any(|k| (straight[k] - c[k]).abs() > 1e-4));
            }
        }
    }

    #[test]
    fn saturation_forms_are_their_formulas() {
        // The memoryless forms equal the plain model driven by the transformed input.
        let dt = 1e-3;
        let u = sine(900, 3.0, dt);
        let ctx = Context::from_training(&u, dt);
        let plain = Structure::new(&[], Some(1.0), ctx);
        let shape = [("log10_s", -0.4), ("w", 0.6)];
        let coef = [0.15, 0.01, 0.05];
        let r = ctx.u_ref;
        type Formula = Box<dyn Fn(f64) -> f64>;
        let cases: [(Form, &str, f64, Formula); 3] = [
            (
                Form::Hard,
                "sat_level",
                0.8,
                Box::new(move |x: f64| x.clamp(-0.8 * r, 0.8 * r)),
            ),
            (
                Form::Smooth,
                "sat_smooth_k",
                1.3,
                Box::new(move |x: f64| r / 1.3 * (1.3 * x / r).tanh()),
            ),
            (
                Form::Cubic,
                "sat_cubic",
                0.2,
                Box::new(move |x: f64| x - 0.2 * x.powi(3) / (r * r)),
            ),
        ];
        for (form, name, value, formula) in cases {
            let st = Structure::with_forms(
                &[(Effect::Saturation, form)],
                Some(1.0),
                ctx,
                Placement::After,
            );
            let (got, _) = st.simulate(
                &theta_with(&st, &[shape[0], shape[1], (name, value)]),
                &coef,
                &u,
            );
            let x: Vec<f64> = u.iter().map(|&v| formula(v)).collect();
            let (want, _) = plain.simulate(&theta_with(&plain, &shape), &coef, &x);
            let worst = got
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-12, "{}: {worst}", form.name());
            // And the form does change the output.
            let (neutral, _) = st.simulate(&theta_with(&st, &shape), &coef, &u);
            assert!(
                got.iter().zip(&neutral).any(|(a, b)| (a - b).abs() > 1e-4),
                "{}",
                form.name()
            );
        }
    }

    #[test]
    fn rich_forms_nest_their_simple_ones_and_act() {
        let dt = 1e-3;
        let u = sine(3000, 2.0, dt);
        let ctx = Context::from_training(&u, dt);
        let shape = [("log10_s", -0.4), ("w", 0.6)];
        let coef = [0.15, 0.01, 0.05];
        // Two modes with no share of the second are the one mode.
        let one = Structure::new(&[Effect::Dynamics], Some(1.0), ctx);
        let two = one.extended_with(Effect::Dynamics, Form::TwoModes);
        assert_eq!(two.label(), "bouc-wen+dynamics[two-modes]");
        let m = [
            ("mode_log10_hz", 80f64.log10()),
            ("mode_log10_zeta", 0.05f64.log10()),
        ];
        let (a, _) = one.simulate(
            &theta_with(&one, &[shape[0], shape[1], m[0], m[1]]),
            &coef,
            &u,
        );
        let th2 = one.embed(&theta_with(&one, &[shape[0], shape[1], m[0], m[1]]), &two);
        let (b, _) = two.simulate(&th2, &coef, &u);
        assert_eq!(a, b);
        // Every non-default form moves the output away from the plain model.
        let plain = Structure::new(&[], Some(1.0), ctx);
        let (base, _) = plain.simulate(&theta_with(&plain, &shape), &coef, &u);
        type Act<'a> = (Effect, Form, Vec<(&'a str, f64)>);
        let acts: [Act; 5] = [
            (
                Effect::InputLag,
                Form::SecondOrder,
                vec![("lag2_log10_hz", 30f64.log10())],
            ),
            (Effect::Asymmetry, Form::Direction, vec![("asym_dir", 0.2)]),
            (Effect::RateDependence, Form::Gain, vec![("rate_rho", 0.5)]),
            (
                Effect::Creep,
                Form::Logarithmic,
                vec![("creep_log_gain", 0.05)],
            ),
            (
                Effect::Dynamics,
                Form::TwoModes,
                vec![
                    m[0],
                    m[1],
                    ("mode2_log10_hz", 150f64.log10()),
                    ("mode2_share", 0.5),
                ],
            ),
        ];
        for (e, form, values) in acts {
            let st = Structure::with_forms(&[(e, form)], Some(1.0), ctx, Placement::After);
            let mut v = values.clone();
            v.extend(shape);
            let (out, status) = st.simulate(&theta_with(&st, &v), &coef, &u);
            assert_eq!(status, Status::Ok, "{}", st.label());
            let diff = out
                .iter()
                .zip(&base)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(diff > 1e-4, "{}: {diff}", st.label());
        }
    }

    /// The hysteretic state at the first sample is at most the saturation level and at
    /// most twice the drive's peak: a weakly saturating loop cannot start far out at its
    /// saturation level (where only a slow relaxation moves it), and `h0` reports the
    /// state the simulation starts from.
    #[test]
    fn the_initial_hysteretic_state_is_capped_at_twice_the_drive_peak() {
        let dt = 1e-3;
        let u: Vec<f64> = (0..2000).map(|k| 1.5 * (k as f64 * 0.01).sin()).collect();
        let ctx = Context::from_training(&u, dt);
        let plain = Structure::new(&[], Some(1.0), ctx);
        let coef = [0.0, 0.0, 1.0];
        for (log10_s, start) in [(1.0, 2.0 * 1.5), (-0.4, 10f64.powf(-0.4) * 1.5)] {
            for frac in [-1.0, 1.0] {
                let theta = theta_with(
                    &plain,
                    &[("log10_s", log10_s), ("w", 0.6), ("g0_frac", frac)],
                );
                let (out, status) = plain.simulate(&theta, &coef, &u);
                assert_eq!(status, Status::Ok);
                let h0 = plain
                    .named_params(&theta, &coef)
                    .into_iter()
                    .find(|p| p.0 == "h0")
                    .unwrap()
                    .1;
                // The third column is the state with its sign turned: `-g`.
                assert!(
                    (out[0] + frac * start).abs() < 1e-6 * start
                        && (h0 - frac * start).abs() < 1e-6 * start,
                    "log10 s {log10_s}, g0_frac {frac}: output {} h0 {h0}, expected state {}",
                    out[0],
                    frac * start
                );
            }
        }
    }

    #[test]
    fn logarithmic_creep_grows_evenly_per_decade_after_a_step() {
        let dt = 1e-3;
        let n = 40_000;
        let u: Vec<f64> = (0..n).map(|k| if k < 10 { 0.0 } else { 1.0 }).collect();
        let ctx = Context::from_training(&u, dt);
        let st = Structure::with_forms(
            &[(Effect::Creep, Form::Logarithmic)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        // A purely elastic actuator (no hysteresis: α = 0), creep 2 % per decade.
        let th = theta_with(&st, &[("creep_log_gain", 0.02)]);
        let mut coef = vec![0.0; st.linear_names().len()];
        coef[0] = 1.0;
        let (y, _) = st.simulate(&th, &coef, &u);
        // Growth over each decade inside the band (0.1-1 s, 1-10 s) is about the same.
        let at = |t: f64| y[10 + (t / dt) as usize];
        let (d1, d2) = (at(1.0) - at(0.1), at(10.0) - at(1.0));
        assert!(d1 > 0.01 && d2 > 0.01, "{d1} {d2}");
        assert!((d1 / d2 - 1.0).abs() < 0.35, "{d1} {d2}");
    }

    /// A 20 s, 0.5 Hz sine at 100 Hz and the plain model's output on it: the record the
    /// drift forms are added to.
    fn slow_plain_record() -> (Vec<f64>, Context, Structure, Vec<f64>, Vec<f64>) {
        let dt = 1e-2;
        let u = sine(2000, 0.5, dt);
        let ctx = Context::from_training(&u, dt);
        let plain = Structure::new(&[], Some(1.0), ctx);
        let theta = theta_with(&plain, &[("log10_s", -0.4), ("w", 0.6)]);
        let (y0, _) = plain.simulate(&theta, &[0.15, 0.0, 0.05], &u);
        (u, ctx, plain, theta, y0)
    }

    #[test]
    fn spline_drift_recovers_a_piecewise_linear_drift_and_belongs_to_the_record() {
        let (u, ctx, plain, theta, y0) = slow_plain_record();
        // A wander through the spline's own knots (8 segments over samples 0..=1999).
        let knots = [0.0, 0.3, -0.2, 0.1, 0.4, 0.0, -0.3, 0.2, 0.1];
        let drift = |k: usize| {
            let x = k as f64 / (1999.0 / 8.0);
            let j = (x.floor() as usize).min(7);
            knots[j] + (x - j as f64) * (knots[j + 1] - knots[j])
        };
        let y: Vec<f64> = y0
            .iter()
            .enumerate()
            .map(|(k, v)| v + 1e-2 * drift(k))
            .collect();
        let st = Structure::with_forms(
            &[(Effect::OffsetDrift, Form::Spline)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        assert_eq!(spline_segments(&ctx), 8);
        let fit = st.fit_linear(&plain.embed(&theta, &st), &u, &y);
        assert!(fit.cost < 1e-20, "{}", fit.cost);
        let names = st.linear_names();
        let rec: Vec<&str> = st
            .record_coefs()
            .iter()
            .map(|&i| names[i].as_str())
            .collect();
        assert!(rec.contains(&"d0") && rec.contains(&"drift_k8") && !rec.contains(&"d_e"));
    }

    #[test]
    fn settling_drift_recovers_an_exponential_and_belongs_to_the_record() {
        let (u, ctx, plain, theta, y0) = slow_plain_record();
        let (dt, tau) = (ctx.dt, 4.0);
        let y: Vec<f64> = y0
            .iter()
            .enumerate()
            .map(|(k, v)| v + 0.02 * (1.0 - (-(k as f64) * dt / tau).exp()))
            .collect();
        let st = Structure::with_forms(
            &[(Effect::OffsetDrift, Form::Settling)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        let mut th = plain.embed(&theta, &st);
        let i = st
            .specs()
            .iter()
            .position(|s| s.name == "drift_log10_tau_s");
        th[i.expect("settling has a time constant")] = tau.log10();
        let fit = st.fit_linear(&th, &u, &y);
        assert!(fit.cost < 1e-20, "{}", fit.cost);
        let names = st.linear_names();
        let at = names.iter().position(|n| *n == "drift_settling").unwrap();
        assert!((fit.coef[at] + 0.02).abs() < 1e-9, "{}", fit.coef[at]);
        assert!(st.record_coefs().contains(&at));
        // A wrong time constant leaves a remainder: the form is not a free offset.
        th[i.unwrap()] = (0.1 * tau).log10();
        assert!(st.fit_linear(&th, &u, &y).cost > 1e-6);
    }

    #[test]
    fn bounded_least_squares_holds_a_coefficient_at_its_bound_and_refits_the_rest() {
        let a: Vec<f64> = (0..50).map(|k| 1.0 + 0.1 * k as f64).collect();
        let b: Vec<f64> = (0..50).map(|k| ((k as f64) * 0.3).sin()).collect();
        let y: Vec<f64> = a.iter().zip(&b).map(|(x, z)| 2.0 * x - 5.0 * z).collect();
        let free = bounded_least_squares(&[a.clone(), b.clone()], &y, &[]);
        assert!((free[0] - 2.0).abs() < 1e-9 && (free[1] + 5.0).abs() < 1e-9);
        let held = bounded_least_squares(&[a.clone(), b.clone()], &y, &[(1, 1.5)]);
        assert_eq!(held[1], -1.5);
        // The other coefficient is the least-squares one given the held value.
        let rest: Vec<f64> = y.iter().zip(&b).map(|(v, z)| v + 1.5 * z).collect();
        assert!((held[0] - least_squares(&[a], &rest)[0]).abs() < 1e-12);
    }

    #[test]
    fn a_creep_element_without_gain_cannot_stand_for_a_drift() {
        let (u, ctx, plain, theta, y0) = slow_plain_record();
        let dt = ctx.dt;
        // A slow decay of the record's own (a drift), not driven by the input.
        let y: Vec<f64> = y0
            .iter()
            .enumerate()
            .map(|(k, v)| v + 0.02 * (-(k as f64) * dt / 8.0).exp())
            .collect();
        let st = Structure::with_forms(
            &[(Effect::Creep, Form::KelvinVoigt)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        // The plain record's shape, a slow element of 8 s.
        let shape = [
            ("log10_s", -0.4),
            ("w", 0.6),
            ("creep_log10_tau2_s", 8f64.log10()),
        ];
        let th = theta_with(&st, &shape);
        // No gain: the initial states are held at zero, the decay stays in the residual.
        let none = st.fit_linear(&th, &u, &y);
        let x0 = st.initial_state_coefs();
        assert!(x0.iter().all(|&j| none.coef[j] == 0.0), "{:?}", none.coef);
        // Creep of no gain is the plain model exactly, on the plain model's cost.
        let plain_cost = plain.fit_linear(&theta, &u, &y).cost;
        assert!(
            plain_cost > 1e-3,
            "the decay is not in the plain model: {plain_cost}"
        );
        assert!(
            (none.cost / plain_cost - 1.0).abs() < 1e-9,
            "{} vs {plain_cost}",
            none.cost
        );
        // With gain, the state may depart from rest up to the gain times the output's span.
        let th = theta_with(&st, &[shape.as_slice(), &[("creep_g2", 0.2)]].concat());
        let some = st.fit_linear(&th, &u, &y);
        let bound = st.state_bounds(&th, span(&y));
        assert!(bound.iter().any(|b| b.1 > 0.0));
        for (j, lim) in bound {
            assert!(
                some.coef[j].abs() <= lim + 1e-12,
                "{} > {lim}",
                some.coef[j]
            );
        }
        assert!(some.cost < none.cost);
    }

    /// A record cut from a running ramp starts in motion: the rate's memory starts at that
    /// rate, so a rate-dependent gain is the same from the first sample (no start-up
    /// transient of the rate time constant for a drift or creep to soak up).
    #[test]
    fn the_rate_memory_starts_at_the_rate_the_record_starts_with() {
        let dt = 1e-3;
        let u: Vec<f64> = (0..600).map(|k| 0.5 + 2e-3 * k as f64).collect();
        let ctx = Context::from_training(&u, dt);
        let st = Structure::with_forms(
            &[(Effect::RateDependence, Form::Gain)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        let th = theta_with(
            &st,
            &[("rate_rho", 0.8), ("rate_log10_tau_s", (0.05f64).log10())],
        );
        // Only the drive term (d_e = 1): v (1 + ρ r), r the rate over its reference.
        let (out, _) = st.simulate(&th, &[1.0, 0.0, 0.0], &u);
        let gain: Vec<f64> = out.iter().zip(&u).map(|(y, x)| y / x).collect();
        let settled = gain[599];
        assert!(settled > 1.1, "the rate acts: gain {settled}");
        for (k, g) in gain.iter().enumerate() {
            assert!(
                (g - settled).abs() < 1e-9,
                "sample {k}: gain {g} vs {settled}"
            );
        }
    }

    #[test]
    fn rate_dependent_width_acts_inside_the_bouc_wen_equation() {
        // A triangle (constant |du/dt|, so the rate's low-pass settles to 1) then a hold.
        let dt = 1e-3;
        let tri: Vec<f64> = (0..1600)
            .map(|k| {
                let p = (k % 400) as f64 / 200.0;
                2.0 * if p <= 1.0 { p } else { 2.0 - p }
            })
            .collect();
        let rho = 0.7;
        for n in [1.0, 1.6] {
            let mut u = tri.clone();
            u.extend(std::iter::repeat_n(tri[1599], 300));
            let ctx = Context::from_training(&tri, dt);
            let st = Structure::with_forms(
                &[(Effect::RateDependence, Form::Width)],
                Some(n),
                ctx,
                Placement::After,
            );
            let th = theta_with(
                &st,
                &[
                    ("log10_s", -0.4),
                    ("w", 0.6),
                    ("rate_rho", rho),
                    ("rate_log10_tau_s", (2.0 * dt).log10()),
                ],
            );
            let (out, _) = st.simulate(&th, &[0.0, 0.0, -1.0], &u);
            // Reference: dg/du = k - (β sgn(du g) + γ)|g|^n with k = 1 + ρ, by fine Euler
            // steps from the model's own state at sample 800.
            let sigma = (10f64.powf(-0.4) * ctx.u_ref).powf(-n);
            let (beta, gamma) = (0.6 * sigma, 0.4 * sigma);
            let mut g = out[800];
            for k in 801..1600 {
                let du = (u[k] - u[k - 1]) / 2000.0;
                for _ in 0..2000 {
                    g += du * ((1.0 + rho) - (beta * (du * g).signum() + gamma) * g.abs().powf(n));
                }
                assert!((out[k] - g).abs() < 1e-4 * (1.0 + g.abs()), "n={n} k={k}");
            }
            // For n = 1 the loop is 1+ρ times the rate-free one (g = k h solves it)...
            if n == 1.0 {
                let plain = Structure::new(&[], Some(n), ctx);
                let pth = theta_with(&plain, &[("log10_s", -0.4), ("w", 0.6)]);
                let (p, _) = plain.simulate(&pth, &[0.0, 0.0, -1.0], &u);
                for k in [1000, 1200, 1400] {
                    assert!((out[k] / p[k] - (1.0 + rho)).abs() < 1e-3, "{k}");
                }
            }
            // ...and keeps its state while the drive holds, however the rate decays.
            assert!(out[1600..].iter().all(|x| *x == out[1600]));
        }
    }

    #[test]
    fn drift_columns_recover_a_linear_drift() {
        let dt = 1e-3;
        let u = sine(2000, 2.0, dt);
        let ctx = Context::from_training(&u, dt);
        let plain = Structure::new(&[], Some(1.0), ctx);
        let theta = [-0.4, 0.6, 0.0];
        let (y0, _) = plain.simulate(&theta, &[0.15, 0.0, 0.05], &u);
        let y: Vec<f64> = y0
            .iter()
            .enumerate()
            .map(|(k, v)| v + 3e-3 * k as f64 * dt)
            .collect();
        let st = Structure::new(&[Effect::OffsetDrift], Some(1.0), ctx);
        let fit = st.fit_linear(&theta, &u, &y);
        assert!(fit.cost < 1e-20);
        let named = st.named_params(&theta, &fit.coef);
        let rate = named.iter().find(|x| x.0 == "drift_per_s").unwrap().1;
        assert!((rate - 3e-3).abs() < 1e-9, "{rate}");
    }

    #[test]
    fn hostile_shapes_give_finite_costs() {
        let dt = 1e-3;
        let u = sine(300, 8.0, dt);
        let y: Vec<f64> = u.iter().map(|x| 0.15 * x).collect();
        let ctx = Context::from_training(&u, dt);
        let st = Structure::new(&Effect::ALL, None, ctx);
        let cap = cost_cap(&y);
        let d = st.specs().len();
        for v in [f64::NAN, f64::INFINITY, -1e300, 1e300, 0.0, -5.0] {
            for i in 0..d {
                let mut theta: Vec<f64> = st.specs().iter().map(|s| s.neutral).collect();
                theta[i] = v;
                let f = st.fit_linear(&theta, &u, &y);
                assert!(f.cost.is_finite() && f.cost >= 0.0, "{i}={v}: {}", f.cost);
                assert!(f.cost <= 2.0 * cap);
                let (out, _) = st.simulate(&theta, &f.coef, &u);
                assert!(out.iter().all(|x| x.is_finite()));
            }
        }
        // Bounds: every corner is finite too.
        for corner in 0..(1u32 << d.min(10)) {
            let theta: Vec<f64> = st
                .specs()
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    if corner >> (i % 10) & 1 == 1 {
                        s.upper
                    } else {
                        s.lower
                    }
                })
                .collect();
            assert!(st.fit_linear(&theta, &u, &y).cost.is_finite());
        }
    }

    /// The theta of physical restoring-force parameters `(m, c, k, α, β, γ, n)` on `ctx`,
    /// and the output scale `a` (the structure's first linear coefficient).
    fn feedback_theta(st: &Structure, p: [f64; 7]) -> (Vec<f64>, f64) {
        let [m, c, k, alpha, beta, gamma, n] = p;
        let stiff = k + alpha;
        let a = st.context().u_ref / stiff;
        let w = (stiff / m).sqrt();
        let pa = a.powf(n) * alpha.powf(n - 1.0);
        let theta = st
            .specs()
            .iter()
            .map(|s| match s.name {
                "fb_log10_hz" => (w / (2.0 * std::f64::consts::PI)).log10(),
                "fb_log10_zeta" => (c / (2.0 * (stiff * m).sqrt())).log10(),
                "fb_r" => alpha / stiff,
                "fb_b" => beta * pa,
                "fb_c" => gamma * pa,
                "n" => n,
                _ => s.neutral,
            })
            .collect();
        (theta, a)
    }

    #[test]
    fn feedback_placement_is_the_physical_restoring_force_model() {
        // Data from the oscillator in physical form; the structure's fit reproduces them
        // and its named parameters are the physical ones.
        let dt = 1.0 / 750.0;
        let u: Vec<f64> = (0..3000)
            .map(|k| {
                let t = k as f64 * dt;
                60.0 * (2.0 * std::f64::consts::PI * 13.0 * t).sin()
                    + 35.0 * (2.0 * std::f64::consts::PI * 41.0 * t + 1.0).sin()
            })
            .collect();
        let ctx = Context::from_training(&u, dt).with_hold(Hold::Linear);
        let st = Structure::placed(&[], None, ctx, Placement::Feedback);
        assert!(st.has(Effect::Dynamics));
        assert_eq!(st.label(), "bouc-wen+dynamics(feedback)");
        let phys = [2.0, 10.0, 5e4, 5e4, 800.0, -1100.0, 1.3];
        let (theta, a) = feedback_theta(&st, phys);
        let osc = Oscillator {
            omega: 2.0 * std::f64::consts::PI * 10f64.powf(theta[0]),
            zeta: 10f64.powf(theta[1]),
            r: theta[2],
            b: theta[3],
            c: theta[4],
            n: 1.3,
        };
        let x: Vec<f64> = u.iter().map(|v| v / ctx.u_ref).collect();
        let fine = upsample(&x, Hold::Linear, osc.substeps(dt));
        let yi = osc.respond(&fine, dt, x[0], 0.0).unwrap();
        let y: Vec<f64> = yi.iter().map(|v| a * v + 3e-5).collect();
        let lf = st.fit_linear(&theta, &u, &y);
        assert_eq!(lf.status, Status::Ok);
        assert!((lf.coef[0] / a - 1.0).abs() < 1e-9, "{:?}", lf.coef);
        assert!((lf.coef[1] - 3e-5).abs() < 1e-12);
        assert!(lf.cost < 1e-20, "{}", lf.cost);
        let named: std::collections::BTreeMap<String, f64> =
            st.named_params(&theta, &lf.coef).into_iter().collect();
        for (name, want) in [
            ("mass", 2.0),
            ("damping", 10.0),
            ("stiffness", 5e4),
            ("alpha", 5e4),
            ("beta", 800.0),
            ("gamma", -1100.0),
            ("n", 1.3),
        ] {
            assert!(
                (named[name] / want - 1.0).abs() < 1e-6,
                "{name}: {}",
                named[name]
            );
        }
    }

    #[test]
    fn feedback_placement_embeds_shared_parameters_and_stays_finite() {
        let dt = 1e-3;
        let u = sine(800, 5.0, dt);
        let ctx = Context::from_training(&u, dt);
        let after = Structure::new(&[Effect::Delay], None, ctx);
        let fb = after.with_placement(Placement::Feedback);
        assert_eq!(fb.effects(), &[Effect::Delay, Effect::Dynamics]);
        assert_eq!(fb.linear_names(), vec!["scale", "d0"]);
        let mut theta: Vec<f64> = after.specs().iter().map(|s| s.neutral).collect();
        let i = after
            .specs()
            .iter()
            .position(|s| s.name == "delay_samples")
            .unwrap();
        theta[i] = 2.5;
        let moved = after.embed(&theta, &fb);
        let j = fb
            .specs()
            .iter()
            .position(|s| s.name == "delay_samples")
            .unwrap();
        assert_eq!(moved[j], 2.5);
        // Rate-dependence is not offered around a feedback loop.
        assert!(
            !fb.extended(Effect::RateDependence)
                .has(Effect::RateDependence)
        );
        // Every corner of the box: a finite cost, never NaN.
        let y: Vec<f64> = u.iter().map(|v| 0.3 * v).collect();
        let specs = fb.specs().to_vec();
        for corner in 0..(1usize << specs.len()) {
            let th: Vec<f64> = specs
                .iter()
                .enumerate()
                .map(|(b, s)| {
                    if corner >> b & 1 == 1 {
                        s.upper
                    } else {
                        s.lower
                    }
                })
                .collect();
            let lf = fb.fit_linear(&th, &u, &y);
            assert!(
                lf.cost.is_finite() && lf.cost <= 2.0 * cost_cap(&y),
                "{th:?}"
            );
        }
    }

    #[test]
    fn projected_fit_equals_least_squares_on_all_columns() {
        let dt = 1e-3;
        let u = sine(3000, 2.0, dt);
        let ctx = Context::from_training(&u, dt);
        for (parts, placement) in [
            (vec![(Effect::OffsetDrift, Form::Spline)], Placement::After),
            (
                vec![
                    (Effect::OffsetDrift, Form::Spline),
                    (Effect::Creep, Form::KelvinVoigt),
                ],
                Placement::After,
            ),
            (
                vec![
                    (Effect::OffsetDrift, Form::Polynomial),
                    (Effect::Creep, Form::KelvinVoigt),
                ],
                Placement::After,
            ),
            (vec![], Placement::After),
            (
                vec![(Effect::OffsetDrift, Form::Polynomial)],
                Placement::Feedback,
            ),
        ] {
            let st = Structure::with_forms(&parts, Some(1.0), ctx, placement);
            // Creep with gain (its states free inside their bounds), two time constants a
            // decade apart on a spline drift: near-collinear decays and hats.
            let theta = theta_with(
                &st,
                &[
                    ("creep_g", 0.05),
                    ("creep_log10_tau_s", 0.3f64.log10()),
                    ("creep_g2", 0.03),
                    ("creep_log10_tau2_s", 3f64.log10()),
                ],
            );
            let y: Vec<f64> = u
                .iter()
                .enumerate()
                .map(|(k, x)| 0.3 * x + 0.1 * (k as f64 * 0.01).sin() + 0.02 * (k % 7) as f64)
                .collect();
            let (cols, _) = st.columns(&theta, &u);
            assert_eq!(cols.len(), st.linear_names().len(), "{}", st.label());
            let reference = st.fit_linear_reference(&theta, &u, &y);
            let (direct, e) = (reference.coef, reference.cost);
            let fit = st.fit_linear(&theta, &u, &y);
            assert!(
                (fit.cost / e - 1.0).abs() < 1e-9,
                "{} {} {e}",
                st.label(),
                fit.cost
            );
            for (a, b) in fit.coef.iter().zip(&direct) {
                assert!(
                    (a - b).abs() <= 1e-7 * (1.0 + b.abs()),
                    "{}: {a} vs {b}",
                    st.label()
                );
            }
            // The residuals a Gauss-Newton polish linearises are the fit's own: y minus
            // every column (the fixed ones included) times its coefficient.
            let (with_r, r) = st.fit_linear_residuals(&theta, &u, &y, &st.projection(&u, &y));
            assert_eq!(with_r.cost.to_bits(), fit.cost.to_bits());
            assert_eq!(r.len(), y.len());
            let scale = y.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            for (k, rk) in r.iter().enumerate() {
                let m: f64 = cols.iter().zip(&fit.coef).map(|(c, b)| c[k] * b).sum();
                assert!(
                    (rk - (y[k] - m)).abs() < 1e-9 * scale,
                    "{}: sample {k}",
                    st.label()
                );
            }
            assert!((0.5 * dot(&r, &r) / fit.cost - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn normal_equations_agree_with_gram_schmidt_and_yield_to_it_on_near_dependent_columns() {
        let n = 4000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 / n as f64).collect();
        let decay = |tau: f64| t.iter().map(|x| (-x / tau).exp()).collect::<Vec<f64>>();
        let y: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, x)| (7.0 * x).sin() + 0.3 * (-x / 0.2).exp() + 0.01 * ((k * 37) % 11) as f64)
            .collect();
        let sine: Vec<f64> = t.iter().map(|x| (7.0 * x).sin()).collect();
        let a = decay(0.2);
        let cost = |cols: &[Vec<f64>], b: &[f64]| -> f64 {
            (0..n)
                .map(|k| {
                    let m: f64 = cols.iter().zip(b).map(|(c, x)| c[k] * x).sum();
                    0.5 * (y[k] - m).powi(2)
                })
                .sum()
        };
        // Well conditioned: the normal equations, the same fit.
        let good = vec![sine.clone(), a.clone(), decay(0.02), vec![0.0; n]];
        for bounds in [vec![], vec![(1, 0.1)]] {
            let gs = bounded_least_squares(&good, &y, &bounds);
            let ne = gram_least_squares(&good, &y, &bounds);
            let (c_gs, c_ne) = (cost(&good, &gs), cost(&good, &ne));
            assert!((c_ne / c_gs - 1.0).abs() < 1e-12, "{c_ne} vs {c_gs}");
            for (x, z) in ne.iter().zip(&gs) {
                assert!((x - z).abs() <= 1e-9 * (1.0 + z.abs()), "{x} vs {z}");
            }
            assert!(bounds.iter().all(|&(j, lim)| ne[j].abs() <= lim));
            assert_eq!(ne[3], 0.0);
        }
        // A column near another (and one exactly dependent): Gram-Schmidt decides, which
        // gives the dependent one 0 rather than a pair of large opposite coefficients.
        let bad = vec![
            sine,
            a.clone(),
            decay(0.2001),
            a.iter().map(|x| 2.0 * x).collect(),
        ];
        for bounds in [vec![], vec![(1, 0.1)]] {
            assert_eq!(
                gram_least_squares(&bad, &y, &bounds),
                bounded_least_squares(&bad, &y, &bounds)
            );
        }
        assert_eq!(gram_least_squares(&bad, &y, &[])[3], 0.0);
    }

    #[test]
    fn least_squares_handles_collinear_columns() {
        let a: Vec<f64> = (0..50).map(|k| k as f64).collect();
        let b = vec![1.0; 50];
        let c: Vec<f64> = a.iter().map(|x| 2.0 * x + 1.0).collect();
        let y: Vec<f64> = a.iter().map(|x| 3.0 * x - 2.0).collect();
        let coef = least_squares(&[a.clone(), b, c], &y);
        let fit: Vec<f64> = (0..50)
            .map(|k| coef[0] * a[k] + coef[1] + coef[2] * (2.0 * a[k] + 1.0))
            .collect();
        for (f, t) in fit.iter().zip(&y) {
            assert!((f - t).abs() < 1e-9);
        }
        assert_eq!(coef[2], 0.0);
    }
}
