//! Whether a fitted model's parameters are believable: a value pressed against the range the
//! model allows, or one the recording cannot support (a mode above every frequency the
//! drive excites, a time constant longer than the record, a piezo gain against the record's
//! own slope). A candidate whose own parameters are implausible or at a bound is not named
//! ([`refusal`]); the report says what it was and what was preferred; an unsupported value
//! is stated beside the evidence, so a name resting on it is never given without saying so.

use super::refit::Fitted;
use crate::physics::structure::{Effect, ParamSpec, Placement};
use crate::render::table::sig;
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;
use serde::Serialize;

/// What the training record can support.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scope {
    /// Sampling interval (s).
    pub dt: f64,
    /// Duration of the training record (s).
    pub span_s: f64,
    /// Top of the excited band (Hz): [`BAND_SHARE`] of the power of the input's rate lies
    /// below it. The rate, not the input, because dynamics answer to how fast the drive
    /// moves: a triangle's corners excite far above its fundamental, a sine's do not.
    pub band_hz: f64,
    /// Sign of the least-squares slope of output on input (1, -1, or 0 for none).
    pub slope_sign: f64,
}

/// Share of the input rate's power that defines the excited band.
pub const BAND_SHARE: f64 = 0.99;

/// A mode this many times above the excited band's top is not seen as a resonance, only
/// as the phase lag its low-frequency side adds.
pub const MODE_OVER_BAND: f64 = 2.0;

/// Creep over this share of the drive it low-passes is not a piezo's: a stack creeps a few
/// percent per decade of time (about 1-2 %), some ten percent over a record; more is a lag
/// or a drift standing in.
pub const CREEP_PLAUSIBLE: f64 = 0.25;

/// A first-order lag shorter than this share of the sampling interval is not resolved: its
/// fit rests on where the input acts within the interval (a nuisance), which shifts the
/// drive by up to a sample. Blind seed 20261162 case 72: a 0.86-sample delay named as a lag
/// of 0.02 samples held from the interval's start.
pub const LAG_RESOLVED: f64 = 0.1;

/// A parameter within this share of its range from a bound is at that bound.
pub const AT_BOUND_SHARE: f64 = 0.01;

impl Scope {
    /// The scope of a training record: input `u`, output `y`, sampled every `dt`.
    pub fn of(u: &[f64], y: &[f64], dt: f64) -> Scope {
        let n = u.len().min(y.len());
        Self::of_records(&[(&u[..n], dt)], &y[..n])
    }

    /// The scope of several training records `(input, interval)` fitted together (their
    /// outputs concatenated in `y`): the first record's interval, the longest record, the
    /// widest excited band, the slope over all of them.
    pub fn of_records(records: &[(&[f64], f64)], y: &[f64]) -> Scope {
        let u: Vec<f64> = records.iter().flat_map(|r| r.0.iter().copied()).collect();
        let r = super::residual::correlation(&u, y);
        Scope {
            dt: records.first().map_or(1.0, |r| r.1),
            span_s: records
                .iter()
                .fold(0.0, |m, &(u, dt)| f64::max(m, u.len() as f64 * dt)),
            band_hz: records
                .iter()
                .fold(0.0, |m, &(u, dt)| f64::max(m, excited_band(u, dt))),
            slope_sign: if r == 0.0 { 0.0 } else { r.signum() },
        }
    }
}

/// Frequency below which [`BAND_SHARE`] of the power of `u`'s first difference lies
/// (periodogram of the whole record; 0 for a constant input).
pub fn excited_band(u: &[f64], dt: f64) -> f64 {
    let du: Vec<f64> = u.windows(2).map(|w| w[1] - w[0]).collect();
    let n = du.len();
    if n < 4 {
        return 0.0;
    }
    let m = du.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<Complex<f64>> = du.iter().map(|v| Complex::new(v - m, 0.0)).collect();
    FftPlanner::<f64>::new()
        .plan_fft_forward(n)
        .process(&mut buf);
    let power: Vec<f64> = buf[..n / 2 + 1].iter().map(|c| c.norm_sqr()).collect();
    let total: f64 = power.iter().sum();
    if total <= 0.0 {
        return 0.0;
    }
    let mut acc = 0.0;
    for (k, p) in power.iter().enumerate() {
        acc += p;
        if acc >= BAND_SHARE * total {
            return k as f64 / (n as f64 * dt);
        }
    }
    0.5 / dt
}

/// One questionable parameter.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Flag {
    /// The reported parameter (as in `params`), or the model's internal one when it moves
    /// several reported ones (`w` moves `beta` and `gamma`).
    pub parameter: String,
    pub value: f64,
    /// The reported parameters an internal one moves.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub shows_as: Vec<String>,
    /// `at-bound` (the fit wanted to go further than the model allows), `unsupported` (the
    /// record cannot show this value) or `implausible` (against the record itself).
    pub kind: &'static str,
    pub why: String,
    /// The effect the parameter belongs to (`None`: the Bouc-Wen loop or a nuisance).
    #[serde(skip)]
    pub effect: Option<Effect>,
}

impl Flag {
    /// One line for the text report.
    pub fn line(&self) -> String {
        let moves = if self.shows_as.is_empty() {
            String::new()
        } else {
            format!(" (moves {})", self.shows_as.join(", "))
        };
        format!(
            "[{}] {}{moves} = {}: {}",
            self.kind,
            self.parameter,
            sig(self.value, 4),
            self.why
        )
    }
}

/// Every flag of a fitted model.
pub fn check(f: &Fitted, scope: &Scope) -> Vec<Flag> {
    let named = f.structure.named_params(&f.theta, &f.linear.coef);
    let specs = f.structure.specs();
    let mut flags: Vec<Flag> = Vec::new();
    for (i, s) in specs.iter().enumerate() {
        let Some(mut flag) = at_bound(s, f.theta[i]) else {
            continue;
        };
        // The reported parameters that move with it, found by nudging it inwards.
        let mut theta = f.theta.clone();
        let inward = if theta[i] > 0.5 * (s.lower + s.upper) {
            -1.0
        } else {
            1.0
        };
        theta[i] += inward * 0.1 * (s.upper - s.lower);
        let moved = f.structure.named_params(&theta, &f.linear.coef);
        flag.shows_as = named
            .iter()
            .zip(&moved)
            .filter(|(a, b)| a.1 != b.1 && a.1.is_finite())
            .map(|(a, _)| a.0.clone())
            .collect();
        if let [one] = flag.shows_as.as_slice() {
            flag.parameter = one.clone();
            flag.value = named
                .iter()
                .find(|p| &p.0 == one)
                .map_or(flag.value, |p| p.1);
            flag.shows_as.clear();
        }
        flags.push(flag);
    }
    let value_of = |n: &str| named.iter().find(|(m, _)| m == n).map_or(0.0, |p| p.1);
    for (name, value) in &named {
        // A time constant matters only where its element acts.
        let gain = match name.as_str() {
            "creep_tau_s" => value_of("creep_gain"),
            "creep_tau_slow_s" => value_of("creep_gain_slow"),
            "rate_tau_s" => value_of("rate_rho"),
            _ => 1.0,
        };
        if gain == 0.0 {
            continue;
        }
        if let Some(flag) = unsupported(name, *value, scope) {
            flags.push(flag);
        }
    }
    if let Some(&(_, tau)) = named.iter().find(|(n, _)| n == "lag_tau_s")
        && tau > 0.0
        && tau < LAG_RESOLVED * scope.dt
    {
        flags.push(Flag {
            parameter: "lag_tau_s".into(),
            value: tau,
            shows_as: Vec::new(),
            kind: "implausible",
            why: format!(
                "{} of a sample: a record sampled every {} s cannot show a lag this short; \
                 fed a held input it only shifts the held sample, a delay",
                sig(tau / scope.dt, 2),
                sig(scope.dt, 3)
            ),
            effect: Some(Effect::InputLag),
        });
    }
    if let Some(total) = f.structure.creep_total(&f.theta)
        && total > CREEP_PLAUSIBLE
    {
        flags.push(Flag {
            parameter: "creep_total".into(),
            value: total,
            shows_as: Vec::new(),
            kind: "implausible",
            why: format!(
                "creep of {} % of the drive in all: a piezo creeps a few percent per decade of time, some ten percent over a record; a lag or a drift is standing in",
                sig(100.0 * total, 3)
            ),
            effect: Some(Effect::Creep),
        });
    }
    if f.structure.placement() == Placement::After
        && let Some(&(_, de)) = named.iter().find(|(n, _)| n == "d_e")
        && scope.slope_sign != 0.0
        && de * scope.slope_sign < 0.0
    {
        flags.push(Flag {
            parameter: "d_e".into(),
            value: de,
            shows_as: Vec::new(),
            kind: "implausible",
            why: format!(
                "the piezo gain runs against the record's own slope (output {} with input): \
                 the hysteretic term carries more than the whole response",
                if scope.slope_sign > 0.0 {
                    "rises"
                } else {
                    "falls"
                }
            ),
            effect: None,
        });
    }
    flags
}

/// The flags of `f` on parameters of `effects` only: what a candidate's own evidence rests
/// on.
pub fn check_effects(f: &Fitted, scope: &Scope, effects: &[Effect]) -> Vec<Flag> {
    check(f, scope)
        .into_iter()
        .filter(|g| g.effect.is_some_and(|e| effects.contains(&e)))
        .collect()
}

/// Why a candidate's own flags ([`check_effects`]) keep it from being named: a value the
/// record itself contradicts (`implausible`) or one pressed against the model's range
/// (`at-bound`: the fit wanted more than the form allows, so the form is standing in for
/// something else). `unsupported` values are not refused: the effect is seen, only its
/// parameter is an extrapolation (a mode above the excited band still adds its lag).
/// `None`: nothing refuses it.
pub fn refusal(flags: &[Flag]) -> Option<String> {
    let bad: Vec<String> = flags
        .iter()
        .filter(|f| f.kind == "implausible" || f.kind == "at-bound")
        .map(Flag::line)
        .collect();
    (!bad.is_empty()).then(|| bad.join("; "))
}

/// Mixing fractions whose ends are both proper models (a straight or a smooth drive
/// between samples, a block acting at the interval's end or held from its start, all of a
/// two-mode response in the second mode): at an end they press against nothing.
const FRACTIONS: [&str; 3] = ["intersample_curvature", "block_hold_samples", "mode2_share"];

/// A shape parameter at a bound other than the one where its effect vanishes.
fn at_bound(s: &ParamSpec, x: f64) -> Option<Flag> {
    if FRACTIONS.contains(&s.name) {
        return None;
    }
    // Where the fast creep element's range meets the slow one's: both elements want the
    // same time scale, a partition of the model's own, not a limit of the physics.
    let room = AT_BOUND_SHARE * (s.upper - s.lower);
    // The rate's memory at its shortest is the rate without memory, the rate-dependent PI
    // of the literature (weights growing with |du/dt|): a limit of the form, not a misfit.
    match s.name {
        "creep_log10_tau_s" if s.upper - x <= room => return None,
        "creep_log10_tau2_s" if x - s.lower <= room => return None,
        "rate_log10_tau_s" if x - s.lower <= room => return None,
        _ => {}
    }
    let room = AT_BOUND_SHARE * (s.upper - s.lower);
    let lower = x - s.lower <= room && s.neutral != s.lower;
    let upper = s.upper - x <= room && s.neutral != s.upper;
    if !(lower || upper) {
        return None;
    }
    let (end, bound) = if lower {
        ("lower", s.lower)
    } else {
        ("upper", s.upper)
    };
    let meaning = match (s.name, lower) {
        ("creep_log10_tau_s", true) => {
            "the fastest creep allowed (ten samples): the data want a faster lag, which input timing or a mode holds"
        }
        ("creep_g" | "creep_g2" | "creep_log_gain", false) => {
            "creep carries as much of the response as the model allows: a drift or another lag may be standing in"
        }
        ("creep_log10_tau2_s" | "drift_log10_tau_s" | "rate_log10_tau_s", false) => {
            "a time constant this long is a trend over the record, not identified"
        }
        ("mode_log10_zeta" | "mode2_log10_zeta" | "fb_log10_zeta", false) => {
            "an overdamped mode is a lag, not a resonance"
        }
        ("timing_samples", _) => {
            "the recording set-up's sub-sample timing cannot explain the lag; a delay may"
        }
        ("delay_samples", false) => {
            "the longest delay allowed: align the records before diagnosing"
        }
        ("g0_frac", _) => "the record starts with the hysteresis saturated",
        ("n", _) => "the Bouc-Wen exponent wants to leave its range",
        _ => "the fit presses against the model's range",
    };
    Some(Flag {
        parameter: s.name.to_string(),
        value: x,
        shows_as: Vec::new(),
        kind: "at-bound",
        why: format!("{} at its {end} bound {}: {meaning}", s.name, sig(bound, 4)),
        effect: s.effect,
    })
}

/// A physical value the training record cannot show.
fn unsupported(name: &str, value: f64, scope: &Scope) -> Option<Flag> {
    if !value.is_finite() {
        return None;
    }
    let flag = |why: String, effect| {
        Some(Flag {
            parameter: name.to_string(),
            value,
            shows_as: Vec::new(),
            kind: "unsupported",
            why,
            effect: Some(effect),
        })
    };
    match name {
        "mode_freq_hz" | "mode2_freq_hz" | "natural_freq_hz"
            if value > MODE_OVER_BAND * scope.band_hz =>
        {
            flag(
                format!(
                    "above the excited band ({} % of the drive's rate power below {} Hz): the \
                     record shows only the lag this mode adds, not its resonance; its frequency \
                     and damping are extrapolations",
                    100.0 * BAND_SHARE,
                    sig(scope.band_hz, 3)
                ),
                Effect::Dynamics,
            )
        }
        "creep_tau_s"
        | "creep_tau_slow_s"
        | "rate_tau_s"
        | "drift_settling_tau_s"
        | "lag_tau_s"
            if value > scope.span_s =>
        {
            flag(
                format!(
                    "longer than the training record ({} s): a trend, its time constant not identified",
                    sig(scope.span_s, 3)
                ),
                effect_of(name),
            )
        }
        _ => None,
    }
}

fn effect_of(name: &str) -> Effect {
    match name.split('_').next() {
        Some("creep") => Effect::Creep,
        Some("rate") => Effect::RateDependence,
        Some("drift") => Effect::OffsetDrift,
        _ => Effect::InputLag,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::refit::Fitted;
    use crate::physics::structure::{Context, Form, Structure};

    fn sine(hz: f64, dt: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * hz * i as f64 * dt).sin())
            .collect()
    }

    #[test]
    fn the_band_of_a_sine_is_its_frequency_and_a_triangle_reaches_far_higher() {
        let dt = 1e-3;
        let b = excited_band(&sine(2.0, dt, 5000), dt);
        assert!((b - 2.0).abs() < 0.3, "sine band {b}");
        // A 2 Hz triangle: its rate is a square wave, whose power falls as 1/k^2 over odd
        // harmonics, so 99 % is reached only near the 40th.
        let tri: Vec<f64> = (0..5000)
            .map(|i| {
                let p = (2.0 * i as f64 * dt).fract();
                1.0 - 4.0 * (p - 0.5).abs()
            })
            .collect();
        let bt = excited_band(&tri, dt);
        assert!(bt > 40.0 && bt < 200.0, "triangle band {bt}");
        assert_eq!(excited_band(&[1.0; 100], dt), 0.0);
    }

    fn fitted(effects: &[(Effect, Form)], set: &[(&str, f64)], dt: f64) -> (Fitted, Scope) {
        let u: Vec<f64> = sine(1.0, dt, 4000).iter().map(|v| 1.0 + v).collect();
        let ctx = Context::from_training(&u, dt);
        let st = Structure::with_forms(effects, Some(1.0), ctx, Placement::After);
        let mut theta: Vec<f64> = st.specs().iter().map(|s| s.neutral).collect();
        for (name, v) in set {
            theta[st.specs().iter().position(|s| s.name == *name).unwrap()] = *v;
        }
        // A record whose output rises with the input.
        let y: Vec<f64> = u.iter().map(|v| 2.0 * v).collect();
        let f = Fitted::at(&st, theta, &u, &y, 0);
        let scope = Scope::of(&u, &y, dt);
        (f, scope)
    }

    /// A lag of a fiftieth of a sample is refused (it stands for a shift of the held
    /// input); one of half a sample, the shortest the blind generator draws is 0.8, is not.
    #[test]
    fn a_lag_far_below_a_sample_is_not_a_lag() {
        let dt = 1e-3;
        let lag = [(Effect::InputLag, Form::FirstOrder)];
        let at = |samples: f64| {
            let (f, scope) = fitted(&lag, &[("lag_log10_tau_s", (samples * dt).log10())], dt);
            check_effects(&f, &scope, &[Effect::InputLag])
        };
        let short = at(0.02);
        assert_eq!(short.len(), 1, "{short:?}");
        assert_eq!(short[0].kind, "implausible");
        assert!(refusal(&short).is_some_and(|r| r.contains("a delay")));
        assert!(at(0.5).is_empty(), "{:?}", at(0.5));
        // At the bottom of its range the lag is a wire: nothing to flag.
        let (f, scope) = fitted(&lag, &[], dt);
        assert!(check(&f, &scope).is_empty());
    }

    #[test]
    fn neutral_model_has_no_flag_and_pressed_values_are_named() {
        let dt = 5e-3;
        let creep = [(Effect::Creep, Form::KelvinVoigt)];
        let (f, scope) = fitted(&creep, &[], dt);
        assert!((scope.band_hz - 1.0).abs() < 0.2);
        assert_eq!(scope.slope_sign, 1.0);
        assert!(check(&f, &scope).is_empty(), "{:?}", check(&f, &scope));

        let lo = f.structure.specs()[f
            .structure
            .specs()
            .iter()
            .position(|s| s.name == "creep_log10_tau_s")
            .unwrap()]
        .lower;
        let (f, scope) = fitted(&creep, &[("creep_g", 0.5), ("creep_log10_tau_s", lo)], dt);
        let flags = check_effects(&f, &scope, &[Effect::Creep]);
        let names: Vec<&str> = flags.iter().map(|g| g.parameter.as_str()).collect();
        assert_eq!(
            names,
            ["creep_gain", "creep_tau_s", "creep_total"],
            "{flags:?}"
        );
        assert!((flags[0].value - 0.5).abs() < 1e-12);
        assert!((flags[1].value - 10f64.powf(lo)).abs() < 1e-12);
        assert!(flags[..2].iter().all(|g| g.kind == "at-bound"));
        assert_eq!(flags[2].kind, "implausible");
        // A creep of 5 % is a piezo's: no flag.
        let slow = [
            ("creep_g", 0.03),
            ("creep_g2", 0.02),
            ("creep_log10_tau2_s", 0.7),
        ];
        let (f, scope) = fitted(&creep, &slow, dt);
        assert!(check(&f, &scope).is_empty(), "{:?}", check(&f, &scope));
        assert!(flags[1].why.contains("fastest creep"));
        // The loop's own parameters are not the creep's.
        assert!(check_effects(&f, &scope, &[Effect::Dynamics]).is_empty());
    }

    #[test]
    fn a_mode_above_the_band_and_a_slow_creep_are_unsupported() {
        let dt = 5e-3;
        // 7 Hz under a 1 Hz sine (the minor-loop case), damping 0.21.
        let (f, scope) = fitted(
            &[(Effect::Dynamics, Form::OneMode)],
            &[
                ("mode_log10_hz", 7f64.log10()),
                ("mode_log10_zeta", 0.21f64.log10()),
            ],
            dt,
        );
        let flags = check(&f, &scope);
        assert_eq!(flags.len(), 1, "{flags:?}");
        assert_eq!(flags[0].parameter, "mode_freq_hz");
        assert_eq!(flags[0].kind, "unsupported");
        assert!((flags[0].value - 7.0).abs() < 1e-9);
        // At 1.5 Hz the mode is inside twice the band: no flag.
        let (f, scope) = fitted(
            &[(Effect::Dynamics, Form::OneMode)],
            &[("mode_log10_hz", 1.5f64.log10())],
            dt,
        );
        let dynamics = check_effects(&f, &scope, &[Effect::Dynamics]);
        assert!(dynamics.is_empty(), "{dynamics:?}");
        // A slow creep element of 100 s on a 20 s record.
        let (f, scope) = fitted(
            &[(Effect::Creep, Form::KelvinVoigt)],
            &[("creep_g2", 0.2), ("creep_log10_tau2_s", 2.0)],
            dt,
        );
        let flags = check(&f, &scope);
        assert!(
            flags
                .iter()
                .any(|g| g.parameter == "creep_tau_slow_s" && g.kind == "unsupported"),
            "{flags:?}"
        );
    }

    #[test]
    fn a_piezo_gain_against_the_records_slope_is_implausible() {
        let dt = 5e-3;
        let u: Vec<f64> = sine(1.0, dt, 2000).iter().map(|v| 1.0 + v).collect();
        let ctx = Context::from_training(&u, dt);
        let st = Structure::new(&[], Some(1.0), ctx);
        let theta = st.specs().iter().map(|s| s.neutral).collect();
        let mut f = Fitted::at(&st, theta, &u, &u, 0);
        // The output rises with the input but the fit put the gain negative.
        f.linear.coef[0] = -1.0;
        let flags = check(&f, &Scope::of(&u, &u, dt));
        assert!(
            flags
                .iter()
                .any(|g| g.parameter == "d_e" && g.kind == "implausible"),
            "{flags:?}"
        );
        f.linear.coef[0] = 1.0;
        assert!(check(&f, &Scope::of(&u, &u, dt)).is_empty());
    }
}
