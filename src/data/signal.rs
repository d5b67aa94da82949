//! Excitation signals: what drives the actuator (or the twin) in an experiment.
//!
//! A [`Signal`] is a function of time, evaluated with [`Signal::value`] or sampled with
//! [`Signal::sample`]. Signals compose (sums, scaling, amplitude modulation) and have a text
//! form for the CLI and suites, parsed by [`Signal::parse`] and printed by `Display`.
//!
//! # Spec grammar
//!
//! ```text
//! signal  := product ( '+' product )*           sum of terms
//! product := number '*' product | primary        scaling by a constant
//! primary := number                              constant, e.g. 2.35
//!          | '(' signal ')'
//!          | kind [ ':' key '=' value ( ',' key '=' value )* ]
//! value   := number | word | list | '(' ... ')'  list: numbers separated by ';'
//! ```
//!
//! Kinds and keys (times in s, frequencies in Hz, phases in rad). Keys without a value
//! shown are required; `key=v` shows an optional key's default; keys may come in any order.
//!
//! - `sine`: `freq`, `amp=1`, `phase=0`, `offset=0`: `offset + amp*sin(2π·freq·t + phase)`.
//! - `chirp`: `f0`, `f1`, `duration`, `law=lin` (`lin` or `log`), `amp=1`, `phase=0`,
//!   `offset=0`: a phase-continuous sweep from `f0` at t = 0 to `f1` at `duration` (up or
//!   down), holding `f1` afterwards.
//! - `multisine`: `fmin`, `fmax`, `period`, `rms=1`, `seed=0`, `offset=0`: the harmonics of
//!   1/`period` between `fmin` and `fmax` with equal amplitudes and random phases.
//! - `triangle`: `freq`, `amp=1`, `phase=0`, `offset=0`: peaks where the sine has them.
//! - `steps`: `levels` (e.g. `0;1;2;1`), `hold`, `repeat=false` (`true` or `false`).
//! - `am`: `carrier` = `(signal)`, `envelope` = `ramp`, `raised-cosine`,
//!   `(ramp:from=0,to=1,duration=1)`, `(raised-cosine:min=0,max=1,duration=1)` or
//!   `(signal)`: carrier times envelope (a bare `ramp`/`raised-cosine` takes the defaults).
//!
//! Examples: `2.5 + sine:freq=10,amp=2`, `sine:freq=10,amp=2,offset=2.5`,
//! `chirp:f0=10,f1=1,duration=8,amp=2,law=log,offset=2.5`,
//! `multisine:fmin=5,fmax=150,rms=50,period=10.92,seed=3`, `steps:levels=0;1;2;1,hold=0.5`,
//! `am:carrier=(sine:freq=10),envelope=(raised-cosine:min=0.3,max=1,duration=8)`,
//! `-1*(triangle:freq=1 + 0.5)`. Spaces around tokens are ignored. There is no binary `-`:
//! write `+ -2` or `-1*(...)`.

use crate::base::TrialSeed;
use crate::base::error::{Error, Result};
use crate::base::limits::MAX_NESTING;
use rand::RngExt;
use std::f64::consts::TAU;
use std::fmt;

/// How a chirp's instantaneous frequency moves from `f0` to `f1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChirpLaw {
    /// Frequency linear in time (`lin`).
    Linear,
    /// Frequency exponential in time, i.e. equal time per octave (`log`).
    Log,
}

/// The envelope of an amplitude-modulated signal: a gain that multiplies the carrier.
#[derive(Debug, Clone, PartialEq)]
pub enum AmEnvelope {
    /// Linear from `from` at t = 0 to `to` at `duration`, constant outside.
    Ramp { from: f64, to: f64, duration: f64 },
    /// `min` at t = 0, rising smoothly to `max` at `duration/2` and back to `min` at
    /// `duration` (one period of a raised cosine); `min` outside.
    RaisedCosine { min: f64, max: f64, duration: f64 },
    /// Any signal as the gain (e.g. a slow sine).
    Signal(Box<Signal>),
}

impl AmEnvelope {
    /// The gain at time `t`.
    pub fn value(&self, t: f64) -> f64 {
        match self {
            AmEnvelope::Ramp { from, to, duration } => {
                let x = (t / duration).clamp(0.0, 1.0);
                from + (to - from) * x
            }
            AmEnvelope::RaisedCosine { min, max, duration } => {
                if t <= 0.0 || t >= *duration {
                    *min
                } else {
                    min + (max - min) * 0.5 * (1.0 - (TAU * t / duration).cos())
                }
            }
            AmEnvelope::Signal(s) => s.value(t),
        }
    }
}

/// A random-phase multisine: equal-amplitude harmonics of `1/period` between `fmin` and
/// `fmax`, phases uniform in [0, 2π) drawn from `seed`, scaled so its RMS (over a period,
/// about `offset`) is `rms`. Built with [`Multisine::new`] so the phases always match the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct Multisine {
    fmin: f64,
    fmax: f64,
    rms: f64,
    period: f64,
    seed: u64,
    offset: f64,
    /// Harmonic numbers k (frequency k/period) and their phases.
    harmonics: Vec<(u64, f64)>,
    /// Amplitude of each harmonic: rms·sqrt(2/N).
    amp: f64,
}

/// Most harmonics a multisine may have (a typo in `period` should not allocate gigabytes).
const MAX_HARMONICS: u64 = 1_000_000;

impl Multisine {
    /// Draws the phases (stream 0 of [`TrialSeed::from_u64`]`(seed)`, one per harmonic in
    /// increasing frequency) and sets the amplitude. Refuses an empty band or bad numbers.
    pub fn new(
        fmin: f64,
        fmax: f64,
        rms: f64,
        period: f64,
        seed: u64,
        offset: f64,
    ) -> Result<Multisine> {
        let bad = |msg: String| Err(Error::Input(format!("multisine: {msg}")));
        if !(period.is_finite() && period > 0.0) {
            return bad(format!("period must be positive, got {period}"));
        }
        if !(fmin.is_finite() && fmax.is_finite() && 0.0 <= fmin && fmin <= fmax) {
            return bad(format!(
                "need 0 <= fmin <= fmax, got fmin {fmin}, fmax {fmax}"
            ));
        }
        if !(rms.is_finite() && rms >= 0.0 && offset.is_finite()) {
            return bad(format!(
                "rms must be >= 0 and offset finite, got {rms}, {offset}"
            ));
        }
        // Slack so a band edge that is a harmonic up to rounding is included.
        let kmin = ((fmin * period) * (1.0 - 1e-12)).ceil().max(1.0);
        let kmax = ((fmax * period) * (1.0 + 1e-12)).floor();
        if kmax < kmin {
            return bad(format!(
                "no harmonic of 1/period = {} Hz lies in [{fmin}, {fmax}] Hz",
                1.0 / period
            ));
        }
        if kmax - kmin + 1.0 > MAX_HARMONICS as f64 {
            return bad(format!(
                "{} harmonics in [{fmin}, {fmax}] Hz with period {period} s, at most \
                 {MAX_HARMONICS}",
                kmax - kmin + 1.0
            ));
        }
        let mut rng = TrialSeed::from_u64(seed).rng(0);
        let harmonics: Vec<(u64, f64)> = (kmin as u64..=kmax as u64)
            .map(|k| (k, rng.random::<f64>() * TAU))
            .collect();
        let amp = rms * (2.0 / harmonics.len() as f64).sqrt();
        Ok(Multisine {
            fmin,
            fmax,
            rms,
            period,
            seed,
            offset,
            harmonics,
            amp,
        })
    }

    /// The frequencies present, in Hz, increasing.
    pub fn frequencies(&self) -> Vec<f64> {
        self.harmonics
            .iter()
            .map(|&(k, _)| k as f64 / self.period)
            .collect()
    }

    /// The period in s: the signal repeats exactly after it.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// The RMS about the offset over one period.
    pub fn rms(&self) -> f64 {
        self.rms
    }

    fn value(&self, t: f64) -> f64 {
        let x = t / self.period;
        let sum: f64 = self
            .harmonics
            .iter()
            .map(|&(k, phase)| (TAU * (k as f64 * x).rem_euclid(1.0) + phase).sin())
            .sum();
        self.offset + self.amp * sum
    }
}

/// An excitation signal: a function of time in s. See the [module docs](self) for the
/// text form.
#[derive(Debug, Clone, PartialEq)]
pub enum Signal {
    /// A constant level.
    Constant(f64),
    /// `offset + amp*sin(2π·freq·t + phase)`.
    Sine {
        amp: f64,
        freq: f64,
        phase: f64,
        offset: f64,
    },
    /// `offset + amp*sin(2π·cycles(t) + phase)`, the instantaneous frequency going from `f0`
    /// at t = 0 to `f1` at `duration` by `law`; `f0` before 0 and `f1` after `duration`,
    /// phase-continuous throughout.
    Chirp {
        f0: f64,
        f1: f64,
        duration: f64,
        law: ChirpLaw,
        amp: f64,
        phase: f64,
        offset: f64,
    },
    /// A random-phase multisine.
    Multisine(Multisine),
    /// A triangle wave with the sine's zeros and peaks: `offset` at phase 0 rising to
    /// `offset + amp` at a quarter period.
    Triangle {
        amp: f64,
        freq: f64,
        phase: f64,
        offset: f64,
    },
    /// A staircase: `levels[i]` on [i·hold, (i+1)·hold); after the last level either the
    /// last is held or (`repeat`) the sequence starts again. `levels[0]` before t = 0.
    Steps {
        levels: Vec<f64>,
        hold: f64,
        repeat: bool,
    },
    /// `carrier(t) * envelope(t)`.
    Am {
        carrier: Box<Signal>,
        envelope: AmEnvelope,
    },
    /// The sum of the terms.
    Sum(Vec<Signal>),
    /// `factor * signal`.
    Scale(f64, Box<Signal>),
}

/// Cycles completed by a chirp at time `t` (its phase over 2π).
fn chirp_cycles(f0: f64, f1: f64, duration: f64, law: ChirpLaw, t: f64) -> f64 {
    if t <= 0.0 {
        return f0 * t;
    }
    let tc = t.min(duration);
    let sweep = match law {
        ChirpLaw::Linear => f0 * tc + (f1 - f0) * tc * tc / (2.0 * duration),
        ChirpLaw::Log => {
            let r = (f1 / f0).ln();
            if r.abs() < 1e-12 {
                f0 * tc
            } else {
                // f0·T/ln(k)·(k^(t/T) − 1), written with exp_m1 for accuracy near t = 0.
                f0 * duration / r * (r * tc / duration).exp_m1()
            }
        }
    };
    sweep + f1 * (t - tc)
}

/// Triangle wave of period 1 in `x`, with sin(2πx)'s zeros and peaks.
fn triangle_unit(x: f64) -> f64 {
    let x = x.rem_euclid(1.0);
    if x < 0.25 {
        4.0 * x
    } else if x < 0.75 {
        2.0 - 4.0 * x
    } else {
        4.0 * x - 4.0
    }
}

impl Signal {
    /// The value at time `t` (s).
    pub fn value(&self, t: f64) -> f64 {
        match self {
            Signal::Constant(c) => *c,
            Signal::Sine {
                amp,
                freq,
                phase,
                offset,
            } => offset + amp * (TAU * (freq * t).rem_euclid(1.0) + phase).sin(),
            Signal::Chirp {
                f0,
                f1,
                duration,
                law,
                amp,
                phase,
                offset,
            } => {
                let c = chirp_cycles(*f0, *f1, *duration, *law, t);
                offset + amp * (TAU * c.rem_euclid(1.0) + phase).sin()
            }
            Signal::Multisine(m) => m.value(t),
            Signal::Triangle {
                amp,
                freq,
                phase,
                offset,
            } => offset + amp * triangle_unit(freq * t + phase / TAU),
            Signal::Steps {
                levels,
                hold,
                repeat,
            } => {
                // Slack so a sample taken at an exact multiple of `hold` (k·dt rounding just
                // below it) lands on the new level.
                let i = (t / hold + 1e-9).floor();
                let n = levels.len();
                let i = if i < 0.0 {
                    0
                } else if *repeat {
                    (i as u64 % n as u64) as usize
                } else {
                    (i.min(n as f64 - 1.0)) as usize
                };
                levels[i]
            }
            Signal::Am { carrier, envelope } => carrier.value(t) * envelope.value(t),
            Signal::Sum(terms) => terms.iter().map(|s| s.value(t)).sum(),
            Signal::Scale(k, s) => k * s.value(t),
        }
    }

    /// `round(duration/dt)` samples at t = 0, dt, 2dt, ...; empty if `dt` is not positive
    /// or `duration` is not a finite non-negative number.
    pub fn sample(&self, dt: f64, duration: f64) -> Vec<f64> {
        if !(dt > 0.0 && dt.is_finite() && duration >= 0.0 && duration.is_finite()) {
            return Vec::new();
        }
        let n = (duration / dt).round() as usize;
        (0..n).map(|k| self.value(k as f64 * dt)).collect()
    }

    /// Checks the parameters (finite numbers, positive durations and periods, non-empty
    /// lists, log chirps with positive frequencies); [`Signal::parse`] calls it.
    pub fn validate(&self) -> Result<()> {
        let bad = |kind: &str, msg: String| Err(Error::Input(format!("{kind}: {msg}")));
        let finite = |kind: &str, pairs: &[(&str, f64)]| -> Result<()> {
            for (k, v) in pairs {
                if !v.is_finite() {
                    return bad(kind, format!("{k} must be finite, got {v}"));
                }
            }
            Ok(())
        };
        match self {
            Signal::Constant(c) => finite("constant", &[("value", *c)]),
            Signal::Sine {
                amp,
                freq,
                phase,
                offset,
            }
            | Signal::Triangle {
                amp,
                freq,
                phase,
                offset,
            } => {
                let kind = if matches!(self, Signal::Sine { .. }) {
                    "sine"
                } else {
                    "triangle"
                };
                finite(
                    kind,
                    &[
                        ("amp", *amp),
                        ("freq", *freq),
                        ("phase", *phase),
                        ("offset", *offset),
                    ],
                )?;
                if *freq < 0.0 {
                    return bad(kind, format!("freq must be >= 0, got {freq}"));
                }
                Ok(())
            }
            Signal::Chirp {
                f0,
                f1,
                duration,
                law,
                amp,
                phase,
                offset,
            } => {
                finite(
                    "chirp",
                    &[
                        ("f0", *f0),
                        ("f1", *f1),
                        ("duration", *duration),
                        ("amp", *amp),
                        ("phase", *phase),
                        ("offset", *offset),
                    ],
                )?;
                if *duration <= 0.0 {
                    return bad("chirp", format!("duration must be > 0, got {duration}"));
                }
                let ok = match law {
                    ChirpLaw::Linear => *f0 >= 0.0 && *f1 >= 0.0,
                    ChirpLaw::Log => *f0 > 0.0 && *f1 > 0.0,
                };
                if !ok {
                    let need = if *law == ChirpLaw::Log {
                        "> 0 for law=log"
                    } else {
                        ">= 0"
                    };
                    return bad("chirp", format!("f0 and f1 must be {need}, got {f0}, {f1}"));
                }
                Ok(())
            }
            // Checked when built.
            Signal::Multisine(_) => Ok(()),
            Signal::Steps { levels, hold, .. } => {
                if levels.is_empty() {
                    return bad("steps", "levels is empty".into());
                }
                if levels.iter().any(|v| !v.is_finite()) {
                    return bad("steps", "levels must be finite".into());
                }
                if !(hold.is_finite() && *hold > 0.0) {
                    return bad("steps", format!("hold must be > 0, got {hold}"));
                }
                Ok(())
            }
            Signal::Am { carrier, envelope } => {
                carrier.validate()?;
                match envelope {
                    AmEnvelope::Ramp { from, to, duration } => {
                        finite("ramp", &[("from", *from), ("to", *to)])?;
                        if !(duration.is_finite() && *duration > 0.0) {
                            return bad("ramp", format!("duration must be > 0, got {duration}"));
                        }
                        Ok(())
                    }
                    AmEnvelope::RaisedCosine { min, max, duration } => {
                        finite("raised-cosine", &[("min", *min), ("max", *max)])?;
                        if !(duration.is_finite() && *duration > 0.0) {
                            return bad(
                                "raised-cosine",
                                format!("duration must be > 0, got {duration}"),
                            );
                        }
                        Ok(())
                    }
                    AmEnvelope::Signal(s) => s.validate(),
                }
            }
            Signal::Sum(terms) => {
                if terms.is_empty() {
                    return bad("sum", "no terms".into());
                }
                terms.iter().try_for_each(Signal::validate)
            }
            Signal::Scale(k, s) => {
                finite("scale", &[("factor", *k)])?;
                s.validate()
            }
        }
    }

    /// Parses a signal spec (grammar in the [module docs](self)) and validates it.
    /// Errors are [`Error::Input`] quoting the spec and the character position.
    pub fn parse(spec: &str) -> Result<Signal> {
        let mut p = Parser {
            src: spec,
            pos: 0,
            end: spec.len(),
            depth: 0,
        };
        let s = p.signal()?;
        p.skip_ws();
        if p.pos < p.end {
            return Err(p.err_at(p.pos, format!("unexpected '{}'", p.rest())));
        }
        s.validate()
            .map_err(|e| Error::Input(format!("signal '{spec}': {e}")))?;
        Ok(s)
    }
}

impl std::str::FromStr for Signal {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        Signal::parse(s)
    }
}

/// The dissertation's experiments on the piezo actuator, as D/A commands in V (0..4.7 V,
/// amplified ×15 to 0..70 V): `(name, signal, duration in s)`.
///
/// - `sine-1hz`, `sine-4hz`, `sine-10hz`, `sine-20hz`, `sine-28hz`: 2.35 ± 2.3 V, 2 s at
///   1 Hz and 1 s otherwise. Phase −π/2 so each starts (and, with whole cycles, ends) at
///   the bottom, 0.05 V, near the actuator's rest instead of jumping to mid-range.
/// - `validation-chirp-10-1hz` (Fig. 3.27(b)): an amplitude-varying sinusoid whose
///   frequency falls from 10 to 1 Hz: a log chirp 10 → 1 Hz over 8 s (same phase and
///   offset), its amplitude a raised cosine from 30 % up to 100 % of 2.3 V and back.
pub fn seed_experiments() -> Vec<(String, Signal, f64)> {
    const OFFSET: f64 = 2.35;
    const AMP: f64 = 2.3;
    const PHASE: f64 = -std::f64::consts::FRAC_PI_2;
    let mut out: Vec<(String, Signal, f64)> = [1.0, 4.0, 10.0, 20.0, 28.0]
        .into_iter()
        .map(|f: f64| {
            let sine = Signal::Sine {
                amp: AMP,
                freq: f,
                phase: PHASE,
                offset: OFFSET,
            };
            (
                format!("sine-{f}hz"),
                sine,
                if f == 1.0 { 2.0 } else { 1.0 },
            )
        })
        .collect();
    let chirp = Signal::Chirp {
        f0: 10.0,
        f1: 1.0,
        duration: 8.0,
        law: ChirpLaw::Log,
        amp: AMP,
        phase: PHASE,
        offset: 0.0,
    };
    let validation = Signal::Sum(vec![
        Signal::Constant(OFFSET),
        Signal::Am {
            carrier: Box::new(chirp),
            envelope: AmEnvelope::RaisedCosine {
                min: 0.3,
                max: 1.0,
                duration: 8.0,
            },
        },
    ]);
    out.push(("validation-chirp-10-1hz".into(), validation, 8.0));
    out
}

// ---------------------------------------------------------------------------------------
// Text form

/// A number in shortest round-trip form (exponent form for very large/small magnitudes).
fn num(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-5..1e16).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

impl fmt::Display for ChirpLaw {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ChirpLaw::Linear => "lin",
            ChirpLaw::Log => "log",
        })
    }
}

impl fmt::Display for AmEnvelope {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AmEnvelope::Ramp { from, to, duration } => write!(
                f,
                "(ramp:from={},to={},duration={})",
                num(*from),
                num(*to),
                num(*duration)
            ),
            AmEnvelope::RaisedCosine { min, max, duration } => write!(
                f,
                "(raised-cosine:min={},max={},duration={})",
                num(*min),
                num(*max),
                num(*duration)
            ),
            AmEnvelope::Signal(s) => write!(f, "({s})"),
        }
    }
}

/// Canonical spec text: `Signal::parse(&s.to_string()) == Ok(s)` for every parsed signal.
impl fmt::Display for Signal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Optional keys are printed only when they differ from their default.
        let opt = |key: &str, v: f64, default: f64| {
            if v == default {
                String::new()
            } else {
                format!(",{key}={}", num(v))
            }
        };
        match self {
            Signal::Constant(c) => f.write_str(&num(*c)),
            Signal::Sine {
                amp,
                freq,
                phase,
                offset,
            } => write!(
                f,
                "sine:freq={},amp={}{}{}",
                num(*freq),
                num(*amp),
                opt("phase", *phase, 0.0),
                opt("offset", *offset, 0.0)
            ),
            Signal::Triangle {
                amp,
                freq,
                phase,
                offset,
            } => write!(
                f,
                "triangle:freq={},amp={}{}{}",
                num(*freq),
                num(*amp),
                opt("phase", *phase, 0.0),
                opt("offset", *offset, 0.0)
            ),
            Signal::Chirp {
                f0,
                f1,
                duration,
                law,
                amp,
                phase,
                offset,
            } => write!(
                f,
                "chirp:f0={},f1={},duration={},law={law},amp={}{}{}",
                num(*f0),
                num(*f1),
                num(*duration),
                num(*amp),
                opt("phase", *phase, 0.0),
                opt("offset", *offset, 0.0)
            ),
            Signal::Multisine(m) => write!(
                f,
                "multisine:fmin={},fmax={},rms={},period={},seed={}{}",
                num(m.fmin),
                num(m.fmax),
                num(m.rms),
                num(m.period),
                m.seed,
                opt("offset", m.offset, 0.0)
            ),
            Signal::Steps {
                levels,
                hold,
                repeat,
            } => {
                let levels: Vec<String> = levels.iter().map(|v| num(*v)).collect();
                write!(f, "steps:levels={},hold={}", levels.join(";"), num(*hold))?;
                if *repeat {
                    f.write_str(",repeat=true")?;
                }
                Ok(())
            }
            Signal::Am { carrier, envelope } => {
                write!(f, "am:carrier=({carrier}),envelope={envelope}")
            }
            Signal::Sum(terms) => {
                for (i, s) in terms.iter().enumerate() {
                    if i > 0 {
                        f.write_str(" + ")?;
                    }
                    match s {
                        Signal::Sum(_) => write!(f, "({s})")?,
                        _ => write!(f, "{s}")?,
                    }
                }
                Ok(())
            }
            Signal::Scale(k, s) => match **s {
                Signal::Sum(_) => write!(f, "{}*({s})", num(*k)),
                _ => write!(f, "{}*{s}", num(*k)),
            },
        }
    }
}

/// The signal kinds [`Signal::parse`] knows.
const KINDS: &str = "sine, chirp, multisine, triangle, steps, am (or a number; combine with \
                     '+', 'number*' and parentheses)";

/// Recursive-descent parser over `src[pos..end]` (positions are into the whole spec, so
/// errors inside nested signals point at the right character).
struct Parser<'a> {
    src: &'a str,
    pos: usize,
    end: usize,
    /// Nesting level at `pos`: refused past [`MAX_NESTING`] before the recursion can
    /// exhaust the stack.
    depth: usize,
}

/// One `key=value` of a kind, with where it was written.
struct Param {
    key: String,
    key_pos: usize,
    /// The value text: for a parenthesised value, what is inside the parentheses.
    value: String,
    value_pos: usize,
    parens: bool,
}

impl<'a> Parser<'a> {
    fn err_at(&self, pos: usize, msg: impl fmt::Display) -> Error {
        Error::Input(format!(
            "signal '{}': {msg} (at character {})",
            self.src,
            pos + 1
        ))
    }

    fn rest(&self) -> &'a str {
        &self.src[self.pos..self.end]
    }

    fn peek(&self) -> Option<char> {
        self.rest().chars().next()
    }

    fn skip_ws(&mut self) {
        while let Some(c) = self.peek() {
            if !c.is_whitespace() {
                break;
            }
            self.pos += c.len_utf8();
        }
    }

    fn eat(&mut self, c: char) -> bool {
        self.skip_ws();
        if self.peek() == Some(c) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    /// signal := product ('+' product)*
    fn signal(&mut self) -> Result<Signal> {
        let mut terms = vec![self.product()?];
        while self.eat('+') {
            terms.push(self.product()?);
        }
        Ok(if terms.len() == 1 {
            terms.pop().unwrap()
        } else {
            Signal::Sum(terms)
        })
    }

    /// product := number '*' product | primary
    fn product(&mut self) -> Result<Signal> {
        self.skip_ws();
        let start = self.pos;
        if self.depth > MAX_NESTING {
            return Err(self.err_at(
                start,
                format!("nested more than {MAX_NESTING} levels deep (each '(' and 'k*' is one)"),
            ));
        }
        if self
            .peek()
            .is_some_and(|c| c.is_ascii_digit() || matches!(c, '.' | '-' | '+'))
        {
            let text = self.number_text();
            let v = parse_number(text).map_err(|m| self.err_at(start, m))?;
            if self.eat('*') {
                self.depth += 1;
                let inner = self.product()?;
                self.depth -= 1;
                return Ok(Signal::Scale(v, Box::new(inner)));
            }
            return Ok(Signal::Constant(v));
        }
        self.primary()
    }

    /// The longest number-like text at `pos`: digits, '.', and signs at the start or after
    /// an exponent 'e'.
    fn number_text(&mut self) -> &'a str {
        let start = self.pos;
        let bytes = self.src.as_bytes();
        let mut i = self.pos;
        while i < self.end {
            let c = bytes[i];
            let sign_ok = i == start || matches!(bytes[i - 1], b'e' | b'E');
            if c.is_ascii_alphanumeric() || c == b'.' || (matches!(c, b'+' | b'-') && sign_ok) {
                i += 1;
            } else {
                break;
            }
        }
        self.pos = i;
        &self.src[start..i]
    }

    /// primary := '(' signal ')' | kind [':' params]
    fn primary(&mut self) -> Result<Signal> {
        self.skip_ws();
        let start = self.pos;
        if self.eat('(') {
            self.depth += 1;
            let s = self.signal()?;
            self.depth -= 1;
            if !self.eat(')') {
                return Err(self.err_at(self.pos, format!("expected ')' for '(' at {}", start + 1)));
            }
            return Ok(s);
        }
        let kind = self.word();
        if kind.is_empty() {
            let what = match self.peek() {
                Some(c) => format!("unexpected '{c}'"),
                None => "missing signal".into(),
            };
            return Err(self.err_at(start, format!("{what}; expected one of {KINDS}")));
        }
        let params = if self.eat(':') {
            self.params()?
        } else {
            Vec::new()
        };
        self.build(kind, start, params)
    }

    /// A kind or key name: letters, digits, '_' and '-'.
    fn word(&mut self) -> &'a str {
        self.skip_ws();
        let start = self.pos;
        while let Some(c) = self.peek() {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                self.pos += 1;
            } else {
                break;
            }
        }
        &self.src[start..self.pos]
    }

    /// params := key '=' value (',' key '=' value)*
    fn params(&mut self) -> Result<Vec<Param>> {
        let mut out = Vec::new();
        loop {
            self.skip_ws();
            let key_pos = self.pos;
            let key = self.word().to_string();
            if key.is_empty() {
                return Err(self.err_at(key_pos, "expected key=value"));
            }
            if !self.eat('=') {
                return Err(self.err_at(self.pos, format!("expected '=' after '{key}'")));
            }
            self.skip_ws();
            let value_pos = self.pos;
            let (value, parens) = if self.peek() == Some('(') {
                let close = self.matching_paren()?;
                let inner = self.src[self.pos + 1..close].to_string();
                self.pos = close + 1;
                (inner, true)
            } else {
                let start = self.pos;
                let bytes = self.src.as_bytes();
                while self.pos < self.end {
                    let c = bytes[self.pos];
                    let exp_sign = matches!(c, b'+' | b'-')
                        && self.pos > start
                        && matches!(bytes[self.pos - 1], b'e' | b'E');
                    let ok = c.is_ascii_alphanumeric()
                        || matches!(c, b'.' | b';' | b'_' | b'-')
                        || exp_sign;
                    if !ok {
                        break;
                    }
                    self.pos += 1;
                }
                (self.src[start..self.pos].to_string(), false)
            };
            if value.trim().is_empty() {
                return Err(self.err_at(value_pos, format!("empty value for '{key}'")));
            }
            out.push(Param {
                key,
                key_pos,
                value,
                value_pos,
                parens,
            });
            if !self.eat(',') {
                return Ok(out);
            }
        }
    }

    /// Index of the ')' matching the '(' at `pos`.
    fn matching_paren(&self) -> Result<usize> {
        let mut depth = 0usize;
        for (i, c) in self.src[self.pos..self.end].char_indices() {
            match c {
                '(' => depth += 1,
                ')' => {
                    depth -= 1;
                    if depth == 0 {
                        return Ok(self.pos + i);
                    }
                }
                _ => {}
            }
        }
        Err(self.err_at(self.pos, "unclosed '('"))
    }

    /// A sub-parser for a parenthesised value.
    fn sub(&self, p: &Param) -> Parser<'a> {
        Parser {
            src: self.src,
            pos: p.value_pos + 1,
            end: p.value_pos + 1 + p.value.len(),
            depth: self.depth + 1,
        }
    }

    /// A whole nested signal.
    fn nested_signal(&self, p: &Param) -> Result<Signal> {
        if !p.parens {
            return Err(self.err_at(
                p.value_pos,
                format!(
                    "'{}' takes a signal in parentheses, e.g. {}=(sine:freq=1)",
                    p.key, p.key
                ),
            ));
        }
        let mut sub = self.sub(p);
        let s = sub.signal()?;
        sub.skip_ws();
        if sub.pos < sub.end {
            return Err(sub.err_at(sub.pos, format!("unexpected '{}'", sub.rest())));
        }
        Ok(s)
    }

    fn envelope(&self, p: &Param) -> Result<AmEnvelope> {
        const ENVELOPES: &str = "ramp, raised-cosine, (ramp:from=..,to=..,duration=..), \
             (raised-cosine:min=..,max=..,duration=..) or a signal in parentheses";
        let (kind, params, kind_pos) = if p.parens {
            let mut sub = self.sub(p);
            sub.skip_ws();
            let kind_pos = sub.pos;
            let kind = sub.word();
            if !matches!(kind, "ramp" | "raised-cosine") {
                return Ok(AmEnvelope::Signal(Box::new(self.nested_signal(p)?)));
            }
            let params = if sub.eat(':') {
                sub.params()?
            } else {
                Vec::new()
            };
            sub.skip_ws();
            if sub.pos < sub.end {
                return Err(sub.err_at(sub.pos, format!("unexpected '{}'", sub.rest())));
            }
            (kind.to_string(), params, kind_pos)
        } else {
            (p.value.clone(), Vec::new(), p.value_pos)
        };
        let mut ps = Params::new(self, &kind, kind_pos, params);
        match kind.as_str() {
            "ramp" => {
                ps.allow(&["from", "to", "duration"])?;
                Ok(AmEnvelope::Ramp {
                    from: ps.num("from", 0.0)?,
                    to: ps.num("to", 1.0)?,
                    duration: ps.num("duration", 1.0)?,
                })
            }
            "raised-cosine" => {
                ps.allow(&["min", "max", "duration"])?;
                Ok(AmEnvelope::RaisedCosine {
                    min: ps.num("min", 0.0)?,
                    max: ps.num("max", 1.0)?,
                    duration: ps.num("duration", 1.0)?,
                })
            }
            other => Err(self.err_at(
                kind_pos,
                format!("unknown envelope '{other}'; valid: {ENVELOPES}"),
            )),
        }
    }

    fn build(&self, kind: &str, kind_pos: usize, params: Vec<Param>) -> Result<Signal> {
        let mut ps = Params::new(self, kind, kind_pos, params);
        let s = match kind {
            "sine" | "triangle" => {
                ps.allow(&["freq", "amp", "phase", "offset"])?;
                let (amp, freq) = (ps.num("amp", 1.0)?, ps.req("freq")?);
                let (phase, offset) = (ps.num("phase", 0.0)?, ps.num("offset", 0.0)?);
                if kind == "sine" {
                    Signal::Sine {
                        amp,
                        freq,
                        phase,
                        offset,
                    }
                } else {
                    Signal::Triangle {
                        amp,
                        freq,
                        phase,
                        offset,
                    }
                }
            }
            "chirp" => {
                ps.allow(&["f0", "f1", "duration", "law", "amp", "phase", "offset"])?;
                let law = match ps.word("law")? {
                    None => ChirpLaw::Linear,
                    Some((w, _)) if matches!(w.as_str(), "lin" | "linear") => ChirpLaw::Linear,
                    Some((w, _)) if matches!(w.as_str(), "log" | "exp" | "exponential") => {
                        ChirpLaw::Log
                    }
                    Some((w, pos)) => {
                        return Err(self.err_at(pos, format!("law '{w}': valid laws are lin, log")));
                    }
                };
                Signal::Chirp {
                    f0: ps.req("f0")?,
                    f1: ps.req("f1")?,
                    duration: ps.req("duration")?,
                    law,
                    amp: ps.num("amp", 1.0)?,
                    phase: ps.num("phase", 0.0)?,
                    offset: ps.num("offset", 0.0)?,
                }
            }
            "multisine" => {
                ps.allow(&["fmin", "fmax", "period", "rms", "seed", "offset"])?;
                let seed = match ps.word("seed")? {
                    None => 0,
                    Some((w, pos)) => w.parse::<u64>().map_err(|_| {
                        self.err_at(pos, format!("seed '{w}' is not a non-negative integer"))
                    })?,
                };
                let m = Multisine::new(
                    ps.req("fmin")?,
                    ps.req("fmax")?,
                    ps.num("rms", 1.0)?,
                    ps.req("period")?,
                    seed,
                    ps.num("offset", 0.0)?,
                )
                .map_err(|e| self.err_at(kind_pos, e))?;
                Signal::Multisine(m)
            }
            "steps" => {
                ps.allow(&["levels", "hold", "repeat"])?;
                let (text, pos) = ps.word("levels")?.ok_or_else(|| ps.missing("levels"))?;
                let levels = text
                    .split(';')
                    .map(|v| {
                        parse_number(v.trim()).map_err(|m| self.err_at(pos, format!("levels: {m}")))
                    })
                    .collect::<Result<Vec<f64>>>()?;
                let repeat = match ps.word("repeat")? {
                    None => false,
                    Some((w, _)) if matches!(w.as_str(), "true" | "yes" | "1") => true,
                    Some((w, _)) if matches!(w.as_str(), "false" | "no" | "0") => false,
                    Some((w, pos)) => {
                        return Err(self.err_at(pos, format!("repeat '{w}': use true or false")));
                    }
                };
                Signal::Steps {
                    levels,
                    hold: ps.req("hold")?,
                    repeat,
                }
            }
            "am" => {
                ps.allow(&["carrier", "envelope"])?;
                let carrier = ps.take("carrier").ok_or_else(|| ps.missing("carrier"))?;
                let envelope = ps.take("envelope").ok_or_else(|| ps.missing("envelope"))?;
                Signal::Am {
                    carrier: Box::new(self.nested_signal(&carrier)?),
                    envelope: self.envelope(&envelope)?,
                }
            }
            other => {
                return Err(self.err_at(
                    kind_pos,
                    format!("unknown signal kind '{other}'; valid kinds: {KINDS}"),
                ));
            }
        };
        s.validate().map_err(|e| self.err_at(kind_pos, e))?;
        Ok(s)
    }
}

/// The parameters of one kind, consumed key by key.
struct Params<'p, 'a> {
    parser: &'p Parser<'a>,
    kind: String,
    kind_pos: usize,
    list: Vec<Param>,
}

impl<'p, 'a> Params<'p, 'a> {
    fn new(parser: &'p Parser<'a>, kind: &str, kind_pos: usize, list: Vec<Param>) -> Self {
        Params {
            parser,
            kind: kind.to_string(),
            kind_pos,
            list,
        }
    }

    /// Refuses keys outside `valid` and repeated keys.
    fn allow(&self, valid: &[&str]) -> Result<()> {
        for (i, p) in self.list.iter().enumerate() {
            if !valid.contains(&p.key.as_str()) {
                return Err(self.parser.err_at(
                    p.key_pos,
                    format!(
                        "unknown key '{}' for {}; valid keys: {}",
                        p.key,
                        self.kind,
                        valid.join(", ")
                    ),
                ));
            }
            if self.list[..i].iter().any(|q| q.key == p.key) {
                return Err(self
                    .parser
                    .err_at(p.key_pos, format!("key '{}' given twice", p.key)));
            }
        }
        Ok(())
    }

    fn missing(&self, key: &str) -> Error {
        self.parser
            .err_at(self.kind_pos, format!("{} needs '{key}='", self.kind))
    }

    fn take(&mut self, key: &str) -> Option<Param> {
        let i = self.list.iter().position(|p| p.key == key)?;
        Some(self.list.remove(i))
    }

    /// The plain (unparenthesised) text of `key`, with its position.
    fn word(&mut self, key: &str) -> Result<Option<(String, usize)>> {
        match self.take(key) {
            None => Ok(None),
            Some(p) if p.parens => Err(self.parser.err_at(
                p.value_pos,
                format!("'{key}' takes a plain value, not '(...)'"),
            )),
            Some(p) => Ok(Some((p.value, p.value_pos))),
        }
    }

    fn num(&mut self, key: &str, default: f64) -> Result<f64> {
        Ok(self.opt_num(key)?.unwrap_or(default))
    }

    fn req(&mut self, key: &str) -> Result<f64> {
        self.opt_num(key)?.ok_or_else(|| self.missing(key))
    }

    fn opt_num(&mut self, key: &str) -> Result<Option<f64>> {
        match self.word(key)? {
            None => Ok(None),
            Some((text, pos)) => parse_number(&text)
                .map(Some)
                .map_err(|m| self.parser.err_at(pos, format!("{key}: {m}"))),
        }
    }
}

/// A finite decimal number.
fn parse_number(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("'{text}' is not finite")),
        Err(_) => Err(format!("'{text}' is not a number")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    fn parse(spec: &str) -> Signal {
        Signal::parse(spec).unwrap_or_else(|e| panic!("{spec}: {e}"))
    }

    #[test]
    fn sine_values_at_known_times() {
        let s = parse("sine:freq=10,amp=2,offset=2.5");
        assert!(close(s.value(0.0), 2.5, 1e-12));
        assert!(close(s.value(0.025), 4.5, 1e-12)); // quarter period: peak
        assert!(close(s.value(0.05), 2.5, 1e-12));
        assert!(close(s.value(0.075), 0.5, 1e-12));
        assert!(close(s.value(1000.025), 4.5, 1e-9)); // accurate far from 0
        let c = parse("sine:freq=1,phase=1.5707963267948966");
        assert!(close(c.value(0.0), 1.0, 1e-15)); // a cosine
        let x = s.sample(0.001, 0.1);
        assert_eq!(x.len(), 100);
        assert_eq!(x[25], s.value(0.025));
        assert!(s.sample(0.0, 1.0).is_empty());
        assert!(s.sample(0.1, f64::NAN).is_empty());
    }

    /// Local frequencies from consecutive upward zero crossings of `s - offset`: (cycle
    /// middle, 1/cycle length = mean frequency over the cycle, first and second crossing).
    fn crossing_frequencies(
        s: &Signal,
        offset: f64,
        dt: f64,
        duration: f64,
    ) -> Vec<(f64, f64, f64, f64)> {
        let x = s.sample(dt, duration);
        let mut ups = Vec::new();
        for k in 1..x.len() {
            let (a, b) = (x[k - 1] - offset, x[k] - offset);
            if a < 0.0 && b >= 0.0 {
                ups.push((k as f64 - 1.0 + a / (a - b)) * dt);
            }
        }
        ups.windows(2)
            .map(|w| (0.5 * (w[0] + w[1]), 1.0 / (w[1] - w[0]), w[0], w[1]))
            .collect()
    }

    #[test]
    fn chirp_frequency_goes_from_f0_to_f1_both_laws_both_ways() {
        let duration = 8.0;
        for (law, name) in [(ChirpLaw::Linear, "lin"), (ChirpLaw::Log, "log")] {
            for (f0, f1) in [(10.0, 1.0), (1.0, 10.0), (2.0, 40.0)] {
                let spec = format!(
                    "chirp:f0={f0},f1={f1},duration={duration},amp=2,offset=2.5,law={name}"
                );
                let s = parse(&spec);
                let expected = |t: f64| match law {
                    ChirpLaw::Linear => f0 + (f1 - f0) * t / duration,
                    ChirpLaw::Log => f0 * (f1 / f0).powf(t / duration),
                };
                // Measured past the end too, where the chirp holds f1.
                let freqs = crossing_frequencies(&s, 2.5, 1e-5, duration + 3.0 / f1);
                let (mut during, mut after) = (0, 0);
                for &(t, f, t_first, t_second) in &freqs {
                    if t_second <= duration {
                        // Between two upward crossings the expected frequency law must
                        // integrate to exactly one cycle (Simpson's rule).
                        let m = 200;
                        let h = (t_second - t_first) / m as f64;
                        let cycles = (0..=m)
                            .map(|i| {
                                let w = if i == 0 || i == m {
                                    1.0
                                } else {
                                    (2 + 2 * (i % 2)) as f64
                                };
                                w * expected(t_first + i as f64 * h)
                            })
                            .sum::<f64>()
                            * h
                            / 3.0;
                        assert!(
                            (cycles - 1.0).abs() < 1e-4,
                            "{spec}: cycle at {t} s ({f} Hz) holds {cycles} cycles of the law"
                        );
                        during += 1;
                    } else if t_first >= duration {
                        assert!(close(f, f1, 1e-6 * f1), "{spec}: after the end {f} Hz");
                        after += 1;
                    }
                }
                assert!(
                    during >= 5 && after >= 2,
                    "{spec}: {during}, {after} cycles"
                );
                // The checked cycles start at the beginning of the sweep.
                assert!(
                    freqs[0].0 < 2.5 / f0,
                    "{spec}: first cycle at {} s",
                    freqs[0].0
                );
                // Numerical phase derivative at the ends is exactly f0 and f1.
                let h = 1e-7;
                let inst = |t: f64| {
                    (chirp_cycles(f0, f1, duration, law, t + h)
                        - chirp_cycles(f0, f1, duration, law, t - h))
                        / (2.0 * h)
                };
                assert!(close(inst(h), f0, 1e-5 * f0.max(f1)), "{spec}");
                assert!(close(inst(duration - h), f1, 1e-5 * f0.max(f1)), "{spec}");
                // Phase-continuous past the end, continuing at f1.
                // (slope at most 2π·f·amp ≈ 500 /s, so 2e-9 s moves it by < 1e-6).
                let jump = s.value(duration + 1e-9) - s.value(duration - 1e-9);
                assert!(jump.abs() < 2e-6, "{spec}: jump {jump}");
                assert!(close(inst(duration + 1.0), f1, 1e-5 * f0.max(f1)), "{spec}");
            }
        }
    }

    #[test]
    fn multisine_has_the_target_rms_and_is_periodic() {
        let s = parse("multisine:fmin=5,fmax=150,rms=50,period=10.92,seed=3");
        let Signal::Multisine(m) = &s else {
            panic!("not a multisine")
        };
        let f = m.frequencies();
        assert!(f[0] >= 5.0 && f[0] - 1.0 / 10.92 < 5.0, "{}", f[0]);
        assert!(*f.last().unwrap() <= 150.0 + 1e-9);
        assert_eq!(f.len(), 1638 - 55 + 1);
        // One period sampled at 750 Hz-ish: RMS exact by discrete orthogonality.
        let n = 8192;
        let x = s.sample(10.92 / n as f64, 10.92);
        assert_eq!(x.len(), n);
        let rms = (x.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        assert!(close(rms, 50.0, 1e-9), "rms {rms}");
        let mean = x.iter().sum::<f64>() / n as f64;
        assert!(mean.abs() < 1e-9, "mean {mean}");
        for t in [0.0, 0.123, 3.3, 7.77] {
            assert!(close(s.value(t), s.value(t + 10.92), 1e-9));
            assert!(close(s.value(t), s.value(t + 5.0 * 10.92), 1e-8));
        }
        // The seed decides the phases; an offset shifts it.
        let other = parse("multisine:fmin=5,fmax=150,rms=50,period=10.92,seed=4");
        assert!((s.value(0.1) - other.value(0.1)).abs() > 1e-6);
        assert_eq!(
            s,
            parse("multisine:seed=3,period=10.92,rms=50,fmax=150,fmin=5")
        );
        let shifted = parse("multisine:fmin=5,fmax=150,rms=50,period=10.92,seed=3,offset=2");
        assert!(close(shifted.value(0.7), s.value(0.7) + 2.0, 1e-12));
        // Band edges that are harmonics are included; a band with none is refused.
        let one = parse("multisine:fmin=1,fmax=1,period=2");
        assert_eq!(
            match &one {
                Signal::Multisine(m) => m.frequencies(),
                _ => unreachable!(),
            },
            vec![1.0]
        );
        let e = Signal::parse("multisine:fmin=1.1,fmax=1.2,period=2").unwrap_err();
        assert!(e.to_string().contains("no harmonic"), "{e}");
    }

    #[test]
    fn triangle_peaks_and_slopes() {
        let s = parse("triangle:freq=2,amp=1.5,offset=1");
        assert!(close(s.value(0.0), 1.0, 1e-12));
        assert!(close(s.value(0.125), 2.5, 1e-12));
        assert!(close(s.value(0.375), -0.5, 1e-12));
        assert!(close(s.value(0.5), 1.0, 1e-12));
        assert!(close(s.value(0.0625), 1.75, 1e-12)); // linear rise
        let x = s.sample(1e-3, 2.0);
        let (lo, hi) = x
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        assert!(close(lo, -0.5, 1e-9) && close(hi, 2.5, 1e-9), "{lo} {hi}");
    }

    #[test]
    fn staircase_holds_each_level() {
        let s = parse("steps:levels=0;1;2;1,hold=0.5");
        let x = s.sample(0.01, 3.0);
        for (k, v) in x.iter().enumerate() {
            let expected = match k {
                0..50 => 0.0,
                50..100 => 1.0,
                100..150 => 2.0,
                _ => 1.0, // last level held
            };
            assert_eq!(*v, expected, "sample {k}");
        }
        assert_eq!(s.value(-1.0), 0.0);
        let r = parse("steps:levels=0;1;2;1,hold=0.5,repeat=true");
        assert_eq!(r.value(2.0), 0.0);
        assert_eq!(r.value(2.7), 1.0);
        assert_eq!(r.value(3.2), 2.0);
        assert_eq!(r.value(0.1 * 7.0), 1.0); // 0.7 = 0.6999999999999999...
    }

    #[test]
    fn am_multiplies_carrier_by_envelope() {
        let s = parse("am:carrier=(sine:freq=10,amp=1),envelope=ramp");
        assert!(close(s.value(0.025), 0.025, 1e-12)); // ramp 0 -> 1 over 1 s
        assert!(close(s.value(2.025), 1.0, 1e-12)); // held at 1
        let r = parse("am:carrier=(2),envelope=(raised-cosine:min=0.3,max=1,duration=8)");
        assert!(close(r.value(0.0), 0.6, 1e-12));
        assert!(close(r.value(4.0), 2.0, 1e-12));
        assert!(close(r.value(8.0), 0.6, 1e-12));
        let g = parse("am:carrier=(sine:freq=10),envelope=(1 + 0.5*sine:freq=0.5)");
        for t in [0.0, 0.3, 0.525, 1.7] {
            let e = (1.0 + 0.5 * (TAU * 0.5 * t).sin()) * (TAU * 10.0 * t).sin();
            assert!(close(g.value(t), e, 1e-12), "{t}");
        }
        let sum = parse("2.5 + sine:freq=10,amp=2");
        assert_eq!(
            sum.value(0.3),
            parse("sine:freq=10,amp=2,offset=2.5").value(0.3)
        );
        assert!(close(
            parse("-1*(triangle:freq=1 + 0.5)").value(0.25),
            -1.5,
            1e-12
        ));
    }

    #[test]
    fn parse_round_trips_through_display() {
        let specs = [
            "sine:freq=10,amp=2,offset=2.5",
            "chirp:f0=10,f1=1,amp=2,offset=2.5,law=log,duration=8",
            "chirp:f0=0,f1=100,duration=1e-3,phase=-1.5707963267948966",
            "multisine:fmin=5,fmax=150,rms=50,period=10.92,seed=3",
            "triangle:freq=1,amp=1",
            "steps:levels=0;1;2;1,hold=0.5",
            "steps:levels=-1e-7;3e20,hold=0.25,repeat=true",
            "am:carrier=(sine:freq=10,amp=1),envelope=ramp",
            "am:carrier=(chirp:f0=1,f1=2,duration=3),envelope=(raised-cosine:min=0.3,max=1,duration=8)",
            "am:carrier=(sine:freq=1),envelope=(0.5 + 2*sine:freq=0.1)",
            " 2.35 + ( sine:freq=1 + -3 ) + 0.5*2*triangle:freq=3 ",
            "-1*(triangle:freq=1 + 0.5)",
            "0.1",
        ];
        for spec in specs {
            let s = parse(spec);
            let text = s.to_string();
            assert_eq!(parse(&text), s, "{spec} -> {text}");
            assert_eq!(parse(&text).to_string(), text);
        }
        assert_eq!(
            parse("sine:freq=10,amp=2,offset=2.5").to_string(),
            "sine:freq=10,amp=2,offset=2.5"
        );
    }

    fn refused(spec: &str, needles: &[&str]) {
        let e = Signal::parse(spec).expect_err(spec).to_string();
        assert!(e.contains(&format!("signal '{spec}'")), "{e}");
        for n in needles {
            assert!(e.contains(n), "{spec}: '{n}' not in: {e}");
        }
    }

    #[test]
    fn nesting_is_bounded_before_the_stack_is() {
        let parens = |n: usize| format!("{}sine:freq=1{}", "(".repeat(n), ")".repeat(n));
        assert!(Signal::parse(&parens(MAX_NESTING)).is_ok());
        refused(&parens(MAX_NESTING + 1), &["nested more than 64 levels"]);
        assert!(Signal::parse(&format!("{}sine:freq=1", "2*".repeat(MAX_NESTING))).is_ok());
        refused(
            &format!("{}sine:freq=1", "2*".repeat(MAX_NESTING + 1)),
            &["nested more than 64 levels"],
        );
        // Parameters in parentheses count too.
        let mut am = "sine:freq=1".to_string();
        for _ in 0..MAX_NESTING + 1 {
            am = format!("am:carrier=({am}),envelope=ramp");
        }
        refused(&am, &["nested more than 64 levels"]);
    }

    #[test]
    fn parse_rejects_bad_specs_with_useful_messages() {
        refused(
            "sawtooth:freq=1",
            &[
                "unknown signal kind 'sawtooth'",
                "sine, chirp, multisine, triangle, steps, am",
                "character 1",
            ],
        );
        refused(
            "sine:frq=1",
            &[
                "unknown key 'frq' for sine",
                "valid keys: freq, amp, phase, offset",
                "character 6",
            ],
        );
        refused("sine:amp=1", &["sine needs 'freq='"]);
        refused(
            "sine:freq=abc",
            &["freq: 'abc' is not a number", "character 11"],
        );
        refused("sine:freq=inf", &["'inf' is not finite"]);
        refused("sine:freq=1,freq=2", &["key 'freq' given twice"]);
        refused("sine:freq=-1", &["freq must be >= 0"]);
        refused("sine:freq=", &["empty value for 'freq'"]);
        refused("sine:freq=1 sine:freq=2", &["unexpected 'sine:freq=2'"]);
        refused("chirp:f0=10,f1=1", &["chirp needs 'duration='"]);
        refused("chirp:f0=0,f1=1,duration=1,law=log", &["> 0 for law=log"]);
        refused(
            "chirp:f0=1,f1=2,duration=1,law=cubic",
            &["law 'cubic'", "lin, log"],
        );
        refused("multisine:fmin=5,fmax=1,period=1", &["fmin <= fmax"]);
        refused("multisine:fmin=5,fmax=6,period=1,seed=-2", &["seed '-2'"]);
        refused(
            "steps:levels=0;x;2,hold=1",
            &["levels: 'x' is not a number"],
        );
        refused("steps:levels=0;1,hold=0", &["hold must be > 0"]);
        refused("steps:levels=0;1,hold=1,repeat=maybe", &["repeat 'maybe'"]);
        refused(
            "am:carrier=sine,envelope=ramp",
            &["'carrier' takes a signal in parentheses"],
        );
        refused(
            "am:carrier=(sine:freq=1),envelope=square",
            &["unknown envelope 'square'", "raised-cosine"],
        );
        refused(
            "am:carrier=(sine:fq=1),envelope=ramp",
            &["unknown key 'fq' for sine", "character 18"],
        );
        refused(
            "am:carrier=(sine:freq=1),envelope=(ramp:duration=0)",
            &["duration must be > 0"],
        );
        refused("am:carrier=(sine:freq=1", &["unclosed '('"]);
        refused("(sine:freq=1", &["expected ')'"]);
        refused("", &["missing signal", "expected one of sine"]);
        refused("sine:freq=1 +", &["missing signal"]);
    }

    #[test]
    fn seed_experiments_match_the_dissertation() {
        let ex = seed_experiments();
        let names: Vec<&str> = ex.iter().map(|(n, _, _)| n.as_str()).collect();
        assert_eq!(
            names,
            [
                "sine-1hz",
                "sine-4hz",
                "sine-10hz",
                "sine-20hz",
                "sine-28hz",
                "validation-chirp-10-1hz"
            ]
        );
        for (name, s, duration) in &ex {
            let dt = 1e-4;
            let x = s.sample(dt, *duration);
            let (lo, hi) = x
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            // The D/A command range: 0..4.7 V (70 V after the x15 amplifier).
            assert!(lo >= 0.0 && hi <= 4.7, "{name}: {lo}..{hi} V");
            assert_eq!(parse(&s.to_string()), *s, "{name}");
            if name.starts_with("sine") {
                assert!(close(lo, 0.05, 1e-6) && close(hi, 4.65, 1e-6), "{name}");
                assert!(
                    close(s.value(0.0), 0.05, 1e-12),
                    "{name} starts at the bottom"
                );
            }
        }
        assert_eq!(ex[0].2, 2.0);
        assert!(ex[1..5].iter().all(|e| e.2 == 1.0));
        let (_, v, d) = &ex[5];
        assert_eq!(*d, 8.0);
        // Amplitude 30 % at the ends, 100 % mid-way; frequency 10 Hz falling to 1 Hz.
        let f = crossing_frequencies(v, 2.35, 1e-5, 8.0);
        assert!((f[0].1 / 10.0 - 1.0).abs() < 0.05, "{:?}", f[0]);
        assert!((f[f.len() - 1].1 - 1.0).abs() < 0.2, "{:?}", f[f.len() - 1]);
        let x = v.sample(1e-4, 8.0);
        let peak = |a: usize, b: usize| x[a..b].iter().fold(0.0f64, |m, v| m.max((v - 2.35).abs()));
        assert!(close(peak(0, 1000), 0.3 * 2.3, 0.05), "{}", peak(0, 1000));
        assert!(
            close(peak(38_000, 42_000), 2.3, 0.01),
            "{}",
            peak(38_000, 42_000)
        );
    }
}
