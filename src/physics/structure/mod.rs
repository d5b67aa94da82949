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
//! - Bouc-Wen (dissertation eq. 3.1-3.3) written as `D = d_e v + d0 - α g`, `dg/dv = 1 - (β'
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
pub use super::restoring::MIN_SUBSTEPS;
use super::restoring::{Oscillator, upsample};
use std::sync::Arc;

mod columns;
mod context;
mod effect;
mod forecast;
mod records;
mod shape;
mod solve;
pub use records::{MAX_RECORDS, same_interval};

pub use context::{Context, CoreKind, MAX_PI_OPERATORS, MAX_PREISACH_LEVELS, PiCore, Placement};
pub use effect::{Effect, Form, ParamSpec};
pub use forecast::Forecast;
use shape::{Shape, log_creep_state_taus, log_creep_taus, shift, spline_segments};
pub use solve::Projection;

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

/// Names of a PI core's play weights (`w0` the linear term's).
const PI_WEIGHTS: [&str; MAX_PI_OPERATORS] = [
    "w0", "w1", "w2", "w3", "w4", "w5", "w6", "w7", "w8", "w9", "w10", "w11", "w12", "w13", "w14",
    "w15", "w16", "w17", "w18", "w19", "w20", "w21", "w22", "w23", "w24", "w25", "w26", "w27",
    "w28", "w29", "w30", "w31",
];

/// Names of a Preisach core's relay weights, `mu[i,j]` switching up at threshold `i` and
/// down at `j`, in [`crate::physics::preisach::PreisachGrid::index`] order (as its
/// `names`), for up to [`MAX_PREISACH_LEVELS`] levels.
const PREISACH_WEIGHTS: [&str; MAX_PREISACH_LEVELS * (MAX_PREISACH_LEVELS + 1) / 2] = [
    "mu[0,0]", "mu[1,0]", "mu[1,1]", "mu[2,0]", "mu[2,1]", "mu[2,2]", "mu[3,0]", "mu[3,1]",
    "mu[3,2]", "mu[3,3]", "mu[4,0]", "mu[4,1]", "mu[4,2]", "mu[4,3]", "mu[4,4]", "mu[5,0]",
    "mu[5,1]", "mu[5,2]", "mu[5,3]", "mu[5,4]", "mu[5,5]", "mu[6,0]", "mu[6,1]", "mu[6,2]",
    "mu[6,3]", "mu[6,4]", "mu[6,5]", "mu[6,6]",
];

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
        let kind = ctx.pi.map(|p| p.kind);
        let mut parts: Vec<(Effect, Form)> = parts
            .iter()
            .map(|&(e, f)| {
                let forms = e.forms_on(kind);
                if forms.contains(&f) {
                    (e, f)
                } else {
                    (e, forms[0])
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
        // A Preisach core shapes any asymmetric loop itself ([`Effect::not_for_core`]); an
        // operator core has no restoring-force form.
        let placement = if let Some(p) = ctx.pi {
            parts.retain(|(e, _)| e.not_for_core(p.kind).is_none());
            Placement::After
        } else {
            placement
        };
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
            // The PI core's thresholds are fixed and its weights linear: no shape.
            Placement::After if ctx.pi.is_some() => Vec::new(),
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
        if ctx.pi.is_none() {
            if fixed_n.is_none() {
                specs.push(spec("n", 0.5, 3.0, 1.0, None));
            }
            // The hysteretic state at the first sample, as a fraction of its saturation
            // level: a recording starts with a history the data do not show. (The PI
            // operators start demagnetised, as the PI model defines them.)
            specs.push(spec("g0_frac", -1.0, 1.0, 0.0, None));
        }
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
                // The asymmetric PI's quadratic is a linear column: no shape parameter.
                (Effect::Asymmetry, _) if ctx.pi.is_some() => {}
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
        let mut s = String::from(self.ctx.pi.map_or("bouc-wen", |p| p.name()));
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
            Placement::After if self.ctx.pi.is_some() => {
                let m = self.pi_operators();
                let names: &[&'static str] = match self.ctx.pi.map(|p| p.kind) {
                    Some(CoreKind::Relays) => &PREISACH_WEIGHTS,
                    _ => &PI_WEIGHTS,
                };
                let ops = m - usize::from(self.pi_quadratic());
                let mut v = vec![names[0], "d0"];
                v.extend(&names[1..ops]);
                if self.pi_quadratic() {
                    v.push("asymmetry_a2");
                }
                v
            }
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

    /// The kind of the operator core (`None`: Bouc-Wen).
    pub fn core_kind(&self) -> Option<CoreKind> {
        self.ctx.pi.map(|p| p.kind)
    }

    /// The linear columns of a PI or Preisach core (0 for Bouc-Wen): one per operator,
    /// and the asymmetric PI's quadratic ([`Self::pi_quadratic`]).
    pub fn pi_operators(&self) -> usize {
        self.ctx.pi.map_or(0, |p| p.columns()) + usize::from(self.pi_quadratic())
    }

    /// A PI core's asymmetry: the asymmetric ("modified") PI's memoryless `a₂ v²/u_ref`
    /// beside the plays, linear in its weight like them.
    pub fn pi_quadratic(&self) -> bool {
        self.core_kind() == Some(CoreKind::Plays) && self.has(Effect::Asymmetry)
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

    /// The same model (same parameters) with inputs moving between samples by `hold`, on
    /// every record.
    pub fn with_hold(&self, hold: Hold) -> Structure {
        let one = Structure::with_forms(
            &self.parts(),
            self.fixed_n,
            self.ctx.with_hold(hold),
            self.placement,
        );
        match self.records() {
            Some(parts) => one.on_records(parts),
            None => one,
        }
    }

    /// How the input moves between samples.
    pub fn hold(&self) -> Hold {
        self.ctx.hold
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

    /// Parameters by name in the dissertation's form where it applies (`d_e`, `alpha`, `beta`,
    /// `gamma`, `n`, `d0` of eq. 3.1-3.3 on the data's own units), then each extension's in
    /// physical units (seconds, Hz, fractions).
    pub fn named_params(&self, theta: &[f64], coef: &[f64]) -> Vec<(String, f64)> {
        if let Some(r) = &self.records {
            return r.named_params(theta, coef);
        }
        let sh = self.shape(theta);
        // The mode's frequency from its period parameter `p = 1/ω` (0: no mode).
        let mode_hz = |p: f64| {
            if p > 0.0 {
                1.0 / (2.0 * std::f64::consts::PI * p)
            } else {
                f64::INFINITY
            }
        };
        let mut v: Vec<(String, f64)> = match self.placement {
            Placement::After if self.ctx.pi.is_some() => {
                // Weights with the threshold(s) each operator turns at, then the offset.
                let w = |i: usize| coef.get(if i == 0 { 0 } else { i + 1 }).copied();
                let mut v = Vec::new();
                match self.ctx.pi {
                    Some(p) if p.kind == CoreKind::Relays => {
                        let grid = p.grid();
                        let t = grid.thresholds();
                        for i in 0..t.len() {
                            for j in 0..=i {
                                let k = crate::physics::preisach::PreisachGrid::index(i, j);
                                v.push((format!("mu[{i},{j}]"), w(k).unwrap_or(0.0)));
                                v.push((format!("up[{i},{j}]"), t[i]));
                                v.push((format!("down[{i},{j}]"), t[j]));
                            }
                        }
                    }
                    p => {
                        let r = p.map(|p| p.thresholds()).unwrap_or_default();
                        for (i, ri) in r.iter().enumerate() {
                            v.push((format!("w{i}"), w(i).unwrap_or(0.0)));
                            v.push((format!("r{i}"), *ri));
                        }
                        if self.pi_quadratic() {
                            v.push(("asymmetry_a2".into(), w(r.len()).unwrap_or(0.0)));
                        }
                    }
                }
                v.push(("d0".into(), coef.get(1).copied().unwrap_or(0.0)));
                v
            }
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
                    v.push(("mode_freq_hz".into(), mode_hz(sh.mode_p)));
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
                    v.push(("mode_freq_hz".into(), mode_hz(sh.mode_p)));
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

#[cfg(test)]
pub(crate) mod tests;
