//! The piezo twin: a simulated bimorph actuator like the dissertation's PZBA-00030 (0.6 mm per
//! 70 V, first bending mode at 103 Hz, sampled every 1 ms by a 20 nm sensor), built from the
//! shared physics blocks, with every part switchable so that a test, a diagnosis or a
//! controller can ask for exactly the physics it needs.
//!
//! ```text
//!  u [V]   D/A command, zero-order hold over each sample dt (1 ms)
//!   │
//!   ▼
//!  amp ──────── ×gain (15 V/V); first-order low-pass (2 kHz)          [amp: low-pass on/off]
//!   │           drive clipped to ±limit (150 V)                       [saturation]
//!   ▼ v [V]     v + q v² (even-order term: unequal up/down gains)      [asymmetry, off]
//!  Bouc-Wen ─── D = d_e v + d0 - h(v)   (drive scale)                  [hysteresis: h on/off]
//!   │
//!   ▼ D [mm]    D + Σ gᵢ lagᵢ(D)  Kelvin-Voigt creep (0.5 s, 20 s)     [creep, off]
//!  mode ─────── ÿ + 2ζω ẏ + ω² y = ω² x   (103 Hz, ζ = 0.04)           [mode]
//!   │           pure delay                                           [delay, off]
//!   ▼
//!  sensor ───── + offset + rate·t                                    [drift, off]
//!               + N(0, σ²)   (σ = 0.3 µm)                            [noise]
//!               rounded to 20 nm                                     [quantization]
//!   │
//!   ▼ y [mm]
//! ```
//!
//! Hysteresis acts on the drive voltage (where it physically arises), so the Bouc-Wen
//! parameters are on the drive scale; [`TwinConfig::command_scale_bouc_wen`] quotes them
//! on the command scale, which is what a static fit of (u, y) such as the dissertation's recovers
//! (d_e = 0.154 mm/V there, against the dissertation's fitted 0.16).
//!
//! Defaults: `d_e = 0.0103 mm/V`, `α = 0.003 mm/V`, `β = 0.03 /V`, `γ = 0.015 /V`, `n = 1`,
//! chosen so that a 0-70 V drive (0-4.67 V command) at 1 Hz spans 0.6 mm with a loop 12 %
//! of the span wide (`h` saturates at `α/(β+γ)` = 67 µm).
//!
//! # Time stepping
//!
//! [`Twin::step`] takes the command for the coming sample interval and returns the sensor
//! reading at its end, so `y[k]` responds to `u[0..=k]` with no extra sample of latency.
//! A rig that reads `y` before it writes `u` records one sample later: enable `delay` with
//! 1 ms to reproduce it (it widens the loop with frequency: 12.5 % of the span at 1 Hz,
//! 17 % at 10 Hz, 29 % at 28 Hz, against 12 %, 10 %, 11 % without).
//!
//! Each sample is split into `substeps` sub-steps (default 20, 50 µs). The amplifier
//! low-pass and the linear blocks are discretised exactly (see [`super::linear`]), and
//! Bouc-Wen is rate-independent, integrated exactly along the drive path. Within a sample
//! the amplifier output relaxes exponentially towards the held command, so the creep and
//! mode blocks take their input as relaxing with the amplifier's time constant between
//! sub-step points ([`Mode::step_exp`]): exact when hysteresis is off, whatever
//! `substeps` is; with hysteresis the only error is the curvature of the Bouc-Wen map
//! within a sub-step. Measured on a 28 Hz, 0-60 V drive, noise-free, against 4000
//! sub-steps: 81 nm with 1 sub-step, 19 nm with 10, 5.5 nm with 20, 0.9 nm with 50
//! (second order). 20 keeps the model error at a quarter of the sensor's 20 nm resolution
//! for about 0.9 µs per sample. (Taking the input linear between sub-step points instead
//! would cost 150 nm at 20 sub-steps: the 80 µs amplifier lag is comparable to them.)
//! With the amplifier low-pass off the signal before the mode is constant within a sample
//! and the blocks use their zero-order-hold step, again exact.

use std::fmt::Write as _;

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::bouc_wen::{BoucWenKernel, BoucWenParams, BoucWenState};
use super::linear::{CreepChain, Delay, LowPass, Mode};
use crate::base::TrialSeed;
use crate::base::error::{Error, Result};
use crate::base::standard_normal;
use crate::data::recording::Recording;

/// Drive amplifier (seed: NF As-904). The gain always applies; `enabled` switches its
/// low-pass (an assumed 2 kHz effective bandwidth into the capacitive bimorph load).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AmpConfig {
    pub enabled: bool,
    /// Voltage gain (V/V), > 0.
    pub gain: f64,
    /// -3 dB frequency of the low-pass (Hz).
    pub cutoff_hz: f64,
}

impl Default for AmpConfig {
    fn default() -> Self {
        AmpConfig {
            enabled: true,
            gain: 15.0,
            cutoff_hz: 2000.0,
        }
    }
}

/// Clipping of the drive at the amplifier's rails.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SaturationConfig {
    pub enabled: bool,
    /// Largest |drive| (V).
    pub limit: f64,
}

impl Default for SaturationConfig {
    fn default() -> Self {
        SaturationConfig {
            enabled: true,
            limit: 150.0,
        }
    }
}

/// Even-order term `v + q v²` on the drive: loops that are not point-symmetric, which the
/// odd-symmetric Bouc-Wen model cannot produce.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AsymmetryConfig {
    pub enabled: bool,
    /// `q` (1/V); 1e-3 adds 7 % at 70 V.
    pub quadratic: f64,
}

impl Default for AsymmetryConfig {
    fn default() -> Self {
        AsymmetryConfig {
            enabled: false,
            quadratic: 1e-3,
        }
    }
}

/// The piezo element: `D = d_e v + d0 - h` on the drive scale. `enabled = false` keeps the
/// linear part and drops `h`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HysteresisConfig {
    pub enabled: bool,
    /// mm/V of drive.
    pub d_e: f64,
    /// mm/V.
    pub alpha: f64,
    /// 1/V (for n = 1).
    pub beta: f64,
    /// 1/V (for n = 1).
    pub gamma: f64,
    pub n: f64,
    /// mm.
    pub d0: f64,
}

impl Default for HysteresisConfig {
    fn default() -> Self {
        HysteresisConfig {
            enabled: true,
            d_e: 0.0103,
            alpha: 0.003,
            beta: 0.03,
            gamma: 0.015,
            n: 1.0,
            d0: 0.0,
        }
    }
}

impl HysteresisConfig {
    /// The Bouc-Wen parameters (drive scale).
    pub fn params(&self) -> BoucWenParams {
        BoucWenParams {
            d_e: self.d_e,
            alpha: self.alpha,
            beta: self.beta,
            gamma: self.gamma,
            n: self.n,
            d0: self.d0,
        }
    }
}

/// Kelvin-Voigt creep after the hysteresis: `D + g_f lag(τ_f) D + g_s lag(τ_s) D`, an
/// instantaneous response that creeps `g_f + g_s` (5 %) further over tens of seconds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CreepConfig {
    pub enabled: bool,
    pub gain_fast: f64,
    /// s.
    pub tau_fast: f64,
    pub gain_slow: f64,
    /// s.
    pub tau_slow: f64,
}

impl Default for CreepConfig {
    fn default() -> Self {
        CreepConfig {
            enabled: false,
            gain_fast: 0.02,
            tau_fast: 0.5,
            gain_slow: 0.03,
            tau_slow: 20.0,
        }
    }
}

/// First bending mode (unit static gain): the source of rate dependence.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModeConfig {
    pub enabled: bool,
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
}

impl Default for ModeConfig {
    fn default() -> Self {
        ModeConfig {
            enabled: true,
            freq_hz: 103.0,
            zeta: 0.04,
        }
    }
}

/// Pure transport delay (s), e.g. I/O latency; fractional sub-steps are interpolated.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DelayConfig {
    pub enabled: bool,
    /// s, at most 1.
    pub seconds: f64,
}

impl Default for DelayConfig {
    fn default() -> Self {
        DelayConfig {
            enabled: false,
            seconds: 1e-3,
        }
    }
}

/// Sensor offset and linear (thermal) drift.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriftConfig {
    pub enabled: bool,
    /// mm.
    pub offset: f64,
    /// mm/s.
    pub rate: f64,
}

impl Default for DriftConfig {
    fn default() -> Self {
        DriftConfig {
            enabled: false,
            offset: 0.0,
            rate: 2e-4,
        }
    }
}

/// Gaussian sensor noise, from ChaCha stream 1 of the twin's seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NoiseConfig {
    pub enabled: bool,
    /// Standard deviation (mm).
    pub sigma: f64,
}

impl Default for NoiseConfig {
    fn default() -> Self {
        NoiseConfig {
            enabled: true,
            sigma: 3e-4,
        }
    }
}

/// Rounding of the reading to the sensor's resolution.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct QuantizationConfig {
    pub enabled: bool,
    /// mm (seed: 20 nm).
    pub step: f64,
}

impl Default for QuantizationConfig {
    fn default() -> Self {
        QuantizationConfig {
            enabled: true,
            step: 2e-5,
        }
    }
}

/// Everything the twin simulates; see the module doc for the chain and the defaults. In
/// TOML every field is optional (`[mode]\nenabled = false`); unknown keys are errors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TwinConfig {
    /// Sample interval (s).
    pub dt: f64,
    /// Integration sub-steps per sample.
    pub substeps: usize,
    pub amp: AmpConfig,
    pub saturation: SaturationConfig,
    pub asymmetry: AsymmetryConfig,
    pub hysteresis: HysteresisConfig,
    pub creep: CreepConfig,
    pub mode: ModeConfig,
    pub delay: DelayConfig,
    pub drift: DriftConfig,
    pub noise: NoiseConfig,
    #[serde(alias = "quantisation")]
    pub quantization: QuantizationConfig,
}

impl Default for TwinConfig {
    fn default() -> Self {
        TwinConfig {
            dt: 1e-3,
            substeps: 20,
            amp: AmpConfig::default(),
            saturation: SaturationConfig::default(),
            asymmetry: AsymmetryConfig::default(),
            hysteresis: HysteresisConfig::default(),
            creep: CreepConfig::default(),
            mode: ModeConfig::default(),
            delay: DelayConfig::default(),
            drift: DriftConfig::default(),
            noise: NoiseConfig::default(),
            quantization: QuantizationConfig::default(),
        }
    }
}

/// A field reached by an override key.
enum Field<'a> {
    Num(&'a mut f64),
    Flag(&'a mut bool),
    Count(&'a mut usize),
}

/// Override keys: each part, its fields, and the field a bare `part=<number>` sets.
const PARTS: &[(&str, &[&str], Option<&str>)] = &[
    ("amp", &["enabled", "gain", "cutoff_hz"], Some("cutoff_hz")),
    ("saturation", &["enabled", "limit"], Some("limit")),
    ("asymmetry", &["enabled", "quadratic"], Some("quadratic")),
    (
        "hysteresis",
        &["enabled", "d_e", "alpha", "beta", "gamma", "n", "d0"],
        None,
    ),
    (
        "creep",
        &["enabled", "gain_fast", "tau_fast", "gain_slow", "tau_slow"],
        None,
    ),
    ("mode", &["enabled", "freq_hz", "zeta"], Some("freq_hz")),
    ("delay", &["enabled", "seconds"], Some("seconds")),
    ("drift", &["enabled", "offset", "rate"], Some("rate")),
    ("noise", &["enabled", "sigma"], Some("sigma")),
    ("quantization", &["enabled", "step"], Some("step")),
];

fn parse_switch(v: &str) -> Option<bool> {
    match v {
        "on" | "true" => Some(true),
        "off" | "false" => Some(false),
        _ => None,
    }
}

impl TwinConfig {
    /// The defaults with `overrides` applied; see [`Self::apply_overrides`].
    pub fn parse_overrides(overrides: &str) -> Result<Self> {
        let mut cfg = Self::default();
        cfg.apply_overrides(overrides)?;
        Ok(cfg)
    }

    /// A TOML document (every field optional), validated.
    pub fn from_toml(text: &str) -> Result<Self> {
        let cfg: Self =
            toml::from_str(text).map_err(|e| Error::Input(format!("twin config: {e}")))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Applies CLI-style overrides, then validates. Grammar (whitespace ignored):
    ///
    /// ```text
    /// overrides := [item {"," item}]
    /// item      := "dt=" number | "substeps=" integer
    ///            | part "=" ("on" | "off" | "true" | "false")    switch the part
    ///            | part "=" number        set the part's main value and switch it on
    ///            | part "." field "=" value     number; on/off for `enabled`
    /// part      := amp | saturation | asymmetry | hysteresis | creep | mode | delay
    ///            | drift | noise | quantization
    /// ```
    ///
    /// Main values: amp → cutoff_hz, saturation → limit, asymmetry → quadratic, mode →
    /// freq_hz, delay → seconds, drift → rate, noise → sigma, quantization → step
    /// (hysteresis and creep have none). Example: `mode=off,creep=on,noise=0.001`.
    /// Unknown keys or bad values give [`Error::Input`] naming the valid keys, and leave
    /// `self` unchanged.
    pub fn apply_overrides(&mut self, overrides: &str) -> Result<()> {
        let mut next = self.clone();
        next.apply_unchecked(overrides)?;
        next.validate()?;
        *self = next;
        Ok(())
    }

    fn apply_unchecked(&mut self, overrides: &str) -> Result<()> {
        for item in overrides
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
        {
            let Some((key, value)) = item.split_once('=') else {
                return Err(Error::Input(format!(
                    "twin override `{item}`: expected key=value"
                )));
            };
            let (key, value) = (key.trim(), value.trim());
            let bad_value = |what: &str| {
                Error::Input(format!("twin override `{item}`: `{value}` is not {what}"))
            };
            let (part, field) = match key.split_once('.') {
                Some((p, f)) => (p, Some(f)),
                None => (key, None),
            };
            let part = if part == "quantisation" {
                "quantization"
            } else {
                part
            };
            let target = match field {
                Some(f) => self.field(part, f),
                None if PARTS.iter().any(|p| p.0 == part) => {
                    if let Some(on) = parse_switch(value) {
                        if let Some(Field::Flag(b)) = self.field(part, "enabled") {
                            *b = on;
                        }
                        continue;
                    }
                    let Some(main) = PARTS.iter().find(|p| p.0 == part).and_then(|p| p.2) else {
                        return Err(bad_value("on/off (this part has no main value)"));
                    };
                    if let Some(Field::Flag(b)) = self.field(part, "enabled") {
                        *b = true;
                    }
                    self.field(part, main)
                }
                None => self.field("", part),
            };
            match target {
                Some(Field::Num(x)) => {
                    *x = value.parse().map_err(|_| bad_value("a number"))?;
                }
                Some(Field::Flag(b)) => {
                    *b = parse_switch(value).ok_or_else(|| bad_value("on/off"))?;
                }
                Some(Field::Count(n)) => {
                    *n = value.parse().map_err(|_| bad_value("a whole number"))?;
                }
                None => {
                    return Err(Error::Input(format!(
                        "twin override: unknown key `{key}`; valid keys: {}",
                        Self::valid_keys()
                    )));
                }
            }
        }
        Ok(())
    }

    /// The override keys, for messages.
    pub fn valid_keys() -> String {
        let mut s = String::from("dt, substeps");
        for (part, fields, _) in PARTS {
            let _ = write!(s, ", {part}[.{}]", fields.join("|."));
        }
        s
    }

    fn field(&mut self, part: &str, name: &str) -> Option<Field<'_>> {
        use Field::{Count, Flag, Num};
        Some(match (part, name) {
            ("", "dt") => Num(&mut self.dt),
            ("", "substeps") => Count(&mut self.substeps),
            ("amp", "enabled") => Flag(&mut self.amp.enabled),
            ("amp", "gain") => Num(&mut self.amp.gain),
            ("amp", "cutoff_hz") => Num(&mut self.amp.cutoff_hz),
            ("saturation", "enabled") => Flag(&mut self.saturation.enabled),
            ("saturation", "limit") => Num(&mut self.saturation.limit),
            ("asymmetry", "enabled") => Flag(&mut self.asymmetry.enabled),
            ("asymmetry", "quadratic") => Num(&mut self.asymmetry.quadratic),
            ("hysteresis", "enabled") => Flag(&mut self.hysteresis.enabled),
            ("hysteresis", "d_e") => Num(&mut self.hysteresis.d_e),
            ("hysteresis", "alpha") => Num(&mut self.hysteresis.alpha),
            ("hysteresis", "beta") => Num(&mut self.hysteresis.beta),
            ("hysteresis", "gamma") => Num(&mut self.hysteresis.gamma),
            ("hysteresis", "n") => Num(&mut self.hysteresis.n),
            ("hysteresis", "d0") => Num(&mut self.hysteresis.d0),
            ("creep", "enabled") => Flag(&mut self.creep.enabled),
            ("creep", "gain_fast") => Num(&mut self.creep.gain_fast),
            ("creep", "tau_fast") => Num(&mut self.creep.tau_fast),
            ("creep", "gain_slow") => Num(&mut self.creep.gain_slow),
            ("creep", "tau_slow") => Num(&mut self.creep.tau_slow),
            ("mode", "enabled") => Flag(&mut self.mode.enabled),
            ("mode", "freq_hz") => Num(&mut self.mode.freq_hz),
            ("mode", "zeta") => Num(&mut self.mode.zeta),
            ("delay", "enabled") => Flag(&mut self.delay.enabled),
            ("delay", "seconds") => Num(&mut self.delay.seconds),
            ("drift", "enabled") => Flag(&mut self.drift.enabled),
            ("drift", "offset") => Num(&mut self.drift.offset),
            ("drift", "rate") => Num(&mut self.drift.rate),
            ("noise", "enabled") => Flag(&mut self.noise.enabled),
            ("noise", "sigma") => Num(&mut self.noise.sigma),
            ("quantization", "enabled") => Flag(&mut self.quantization.enabled),
            ("quantization", "step") => Num(&mut self.quantization.step),
            _ => return None,
        })
    }

    /// Checks every value (also of parts that are off, so a config stays valid when a part
    /// is switched on later).
    pub fn validate(&self) -> Result<()> {
        let checks: [(&str, f64, bool); 22] = [
            ("dt", self.dt, self.dt > 0.0),
            ("amp.gain", self.amp.gain, self.amp.gain > 0.0),
            (
                "amp.cutoff_hz",
                self.amp.cutoff_hz,
                self.amp.cutoff_hz > 0.0,
            ),
            (
                "saturation.limit",
                self.saturation.limit,
                self.saturation.limit > 0.0,
            ),
            ("asymmetry.quadratic", self.asymmetry.quadratic, true),
            ("hysteresis.d_e", self.hysteresis.d_e, true),
            ("hysteresis.alpha", self.hysteresis.alpha, true),
            ("hysteresis.beta", self.hysteresis.beta, true),
            ("hysteresis.gamma", self.hysteresis.gamma, true),
            ("hysteresis.n", self.hysteresis.n, self.hysteresis.n > 0.0),
            ("hysteresis.d0", self.hysteresis.d0, true),
            ("creep.gain_fast", self.creep.gain_fast, true),
            (
                "creep.tau_fast",
                self.creep.tau_fast,
                self.creep.tau_fast >= 0.0,
            ),
            ("creep.gain_slow", self.creep.gain_slow, true),
            (
                "creep.tau_slow",
                self.creep.tau_slow,
                self.creep.tau_slow >= 0.0,
            ),
            ("mode.freq_hz", self.mode.freq_hz, self.mode.freq_hz > 0.0),
            ("mode.zeta", self.mode.zeta, self.mode.zeta >= 0.0),
            (
                "delay.seconds",
                self.delay.seconds,
                (0.0..=1.0).contains(&self.delay.seconds),
            ),
            ("drift.offset", self.drift.offset, true),
            ("drift.rate", self.drift.rate, true),
            ("noise.sigma", self.noise.sigma, self.noise.sigma >= 0.0),
            (
                "quantization.step",
                self.quantization.step,
                self.quantization.step > 0.0,
            ),
        ];
        for (name, value, ok) in checks {
            if !(ok && value.is_finite()) {
                return Err(Error::Input(format!(
                    "twin config: {name} = {value} is out of range"
                )));
            }
        }
        if !(1..=10_000).contains(&self.substeps) {
            return Err(Error::Input(format!(
                "twin config: substeps = {} is out of range 1..=10000",
                self.substeps
            )));
        }
        Ok(())
    }

    /// Integration step (s).
    fn substeps_dt(&self) -> f64 {
        self.dt / self.substeps as f64
    }

    /// Static command-to-displacement gain without hysteresis (mm/V): `gain · d_e`.
    pub fn static_gain(&self) -> f64 {
        self.amp.gain * self.hysteresis.d_e
    }

    /// The hysteresis parameters on the command scale (drive = gain × command): what a
    /// static Bouc-Wen fit of (u, y) should find when the other parts are negligible.
    pub fn command_scale_bouc_wen(&self) -> BoucWenParams {
        self.hysteresis.params().rescale_input(self.amp.gain)
    }
}

/// ChaCha stream of the sensor noise.
const NOISE_STREAM: u64 = 1;

/// The simulated actuator, one sample at a time (for closed-loop control) or over a whole
/// input ([`simulate`]).
#[derive(Clone, Debug)]
pub struct Twin {
    cfg: TwinConfig,
    seed: u64,
    amp: Option<LowPass>,
    limit: f64,
    quadratic: f64,
    linear: (f64, f64),
    hysteresis: Option<BoucWenKernel>,
    bw: BoucWenState,
    creep: Option<CreepChain>,
    mode: Option<Mode>,
    delay: Option<Delay>,
    /// Amplifier low-pass on: the signal relaxes exponentially within a sample.
    smooth: bool,
    rng: ChaCha8Rng,
    k: u64,
}

impl Twin {
    /// A twin at rest (zero command) with noise from `seed`.
    ///
    /// # Panics
    /// If `cfg` is invalid ([`TwinConfig::validate`]); use [`Self::try_new`] otherwise.
    pub fn new(cfg: &TwinConfig, seed: u64) -> Self {
        Self::try_new(cfg, seed).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Self::new`], reporting an invalid configuration as [`Error::Input`].
    pub fn try_new(cfg: &TwinConfig, seed: u64) -> Result<Self> {
        cfg.validate()?;
        let h = cfg.substeps_dt();
        let tau_amp = 1.0 / (2.0 * std::f64::consts::PI * cfg.amp.cutoff_hz);
        let c = &cfg.creep;
        let mut twin = Twin {
            cfg: cfg.clone(),
            seed,
            amp: cfg
                .amp
                .enabled
                .then(|| LowPass::from_cutoff(cfg.amp.cutoff_hz, h)),
            limit: if cfg.saturation.enabled {
                cfg.saturation.limit
            } else {
                f64::INFINITY
            },
            quadratic: if cfg.asymmetry.enabled {
                cfg.asymmetry.quadratic
            } else {
                0.0
            },
            linear: (cfg.hysteresis.d_e, cfg.hysteresis.d0),
            hysteresis: cfg
                .hysteresis
                .enabled
                .then(|| BoucWenKernel::new(&cfg.hysteresis.params())),
            bw: BoucWenState::new(0.0),
            creep: c.enabled.then(|| {
                CreepChain::new(
                    &[
                        (1.0, 0.0),
                        (c.gain_fast, c.tau_fast),
                        (c.gain_slow, c.tau_slow),
                    ],
                    h,
                )
                .with_exp_hold(tau_amp)
            }),
            mode: cfg
                .mode
                .enabled
                .then(|| Mode::new(cfg.mode.freq_hz, cfg.mode.zeta, h).with_exp_hold(tau_amp)),
            delay: cfg.delay.enabled.then(|| Delay::new(cfg.delay.seconds, h)),
            smooth: cfg.amp.enabled,
            rng: TrialSeed::from_u64(seed).rng(NOISE_STREAM),
            k: 0,
        };
        twin.settle();
        Ok(twin)
    }

    /// Puts every block at rest at zero command.
    fn settle(&mut self) {
        self.bw = BoucWenState::new(0.0);
        if let Some(a) = &mut self.amp {
            a.settle(0.0);
        }
        let mut x = self.linear.1; // D at v = 0 is d0
        if let Some(c) = &mut self.creep {
            c.settle(x);
            x *= c.dc_gain();
        }
        if let Some(m) = &mut self.mode {
            m.settle(x);
        }
        if let Some(d) = &mut self.delay {
            d.settle(x);
        }
    }

    /// Back to the state of [`Self::new`]: at rest, time 0, noise stream restarted.
    pub fn reset(&mut self) {
        self.settle();
        self.rng = TrialSeed::from_u64(self.seed).rng(NOISE_STREAM);
        self.k = 0;
    }

    /// The configuration.
    pub fn config(&self) -> &TwinConfig {
        &self.cfg
    }

    /// Samples stepped since the start.
    pub fn samples(&self) -> u64 {
        self.k
    }

    /// Holds the command `u_cmd` (V) for one sample interval and returns the sensor reading
    /// (mm) at its end.
    pub fn step(&mut self, u_cmd: f64) -> f64 {
        let target = self.cfg.amp.gain * u_cmd;
        let mut x = 0.0;
        for _ in 0..self.cfg.substeps {
            let mut v = match &mut self.amp {
                Some(a) => a.step(target),
                None => target,
            };
            v = v.clamp(-self.limit, self.limit);
            v += self.quadratic * v * v;
            x = match &self.hysteresis {
                Some(k) => self.bw.step_with(k, v),
                None => self.linear.0 * v + self.linear.1,
            };
            if let Some(c) = &mut self.creep {
                x = if self.smooth {
                    c.step_exp(x)
                } else {
                    c.step(x)
                };
            }
            if let Some(m) = &mut self.mode {
                x = if self.smooth {
                    m.step_exp(x)
                } else {
                    m.step(x)
                };
            }
            if let Some(d) = &mut self.delay {
                x = d.step(x);
            }
        }
        let mut y = x;
        if self.cfg.drift.enabled {
            // At the sample's time k·dt.
            y += self.cfg.drift.offset + self.cfg.drift.rate * self.k as f64 * self.cfg.dt;
        }
        if self.cfg.noise.enabled && self.cfg.noise.sigma > 0.0 {
            y += self.cfg.noise.sigma * standard_normal(&mut self.rng);
        }
        if self.cfg.quantization.enabled {
            let q = self.cfg.quantization.step;
            y = (y / q).round() * q;
        }
        self.k += 1;
        y
    }
}

/// The twin's readings for the command sequence `u` sampled every `dt` (overrides
/// `cfg.dt`), from rest; `y[k]` is read at the end of `u[k]`'s hold interval.
///
/// # Panics
/// If the configuration is invalid; [`recording`] reports it instead.
pub fn simulate(cfg: &TwinConfig, u: &[f64], dt: f64, seed: u64) -> Vec<f64> {
    let cfg = TwinConfig { dt, ..cfg.clone() };
    let mut twin = Twin::new(&cfg, seed);
    u.iter().map(|&x| twin.step(x)).collect()
}

/// Seconds the twin holds the first command before a [`recording`] starts.
pub const PRE_ROLL_S: f64 = 0.5;

/// A [`Recording`] of the twin driven by `u` (units s, V, mm) after a pre-roll of
/// [`PRE_ROLL_S`] at `u[0]`; see [`simulate`] for a run from rest.
pub fn recording(
    cfg: &TwinConfig,
    name: impl Into<String>,
    u: Vec<f64>,
    dt: f64,
    seed: u64,
) -> Result<Recording> {
    let cfg = TwinConfig { dt, ..cfg.clone() };
    cfg.validate()?;
    let mut twin = Twin::try_new(&cfg, seed)?;
    // Pre-roll: the actuator sits at the first command before recording starts, as on a rig,
    // so a signal that does not start at 0 V does not begin with a step through the mode.
    if let Some(&u0) = u.first() {
        for _ in 0..(PRE_ROLL_S / dt).round() as usize {
            twin.step(u0);
        }
    }
    let y: Vec<f64> = u.iter().map(|&x| twin.step(x)).collect();
    let mut r = Recording::uniform(name, dt, u, y)?;
    r.units = ["s".into(), "V".into(), "mm".into()];
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Everything off: amplifier gain and the linear piezo gain only.
    fn bare() -> TwinConfig {
        TwinConfig::parse_overrides(
            "amp=off,saturation=off,hysteresis=off,mode=off,noise=off,quantization=off",
        )
        .unwrap()
    }

    /// `1 - cos` command spanning 0..amp V at `f` Hz for `periods` periods.
    fn raised_cosine(f: f64, amp: f64, periods: f64, dt: f64) -> Vec<f64> {
        let len = (periods / f / dt).round() as usize;
        (0..len)
            .map(|k| 0.5 * amp * (1.0 - (2.0 * PI * f * k as f64 * dt).cos()))
            .collect()
    }

    /// The loop traced over the last period: its span, and the rising and falling
    /// branches at 95 command levels (3-97 % of `amp`, reached by both branches even when
    /// the samples miss the turning points), by linear interpolation.
    fn branches(u: &[f64], y: &[f64], f: f64, dt: f64, amp: f64) -> (f64, Vec<f64>, Vec<f64>) {
        let per = (1.0 / f / dt).round() as usize;
        let (u, y) = (&u[u.len() - per..], &y[y.len() - per..]);
        let span =
            y.iter().cloned().fold(f64::MIN, f64::max) - y.iter().cloned().fold(f64::MAX, f64::min);
        let at = |c: f64, rising: bool| -> f64 {
            (1..per)
                .find_map(|k| {
                    let (a, b) = (u[k - 1], u[k]);
                    let ok = if rising {
                        a <= c && c < b
                    } else {
                        b <= c && c < a
                    };
                    ok.then(|| y[k - 1] + (c - a) / (b - a) * (y[k] - y[k - 1]))
                })
                .unwrap()
        };
        let levels = (3..98).map(|i| amp * i as f64 / 100.0);
        let rise = levels.clone().map(|c| at(c, true)).collect();
        let fall = levels.map(|c| at(c, false)).collect();
        (span, rise, fall)
    }

    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
    }

    #[test]
    fn bare_twin_is_a_static_gain() {
        let cfg = bare();
        let u: Vec<f64> = (0..300).map(|k| (k as f64 * 0.37).sin() * 3.0).collect();
        let y = simulate(&cfg, &u, 1e-3, 1);
        let g = cfg.static_gain();
        assert!((g - 0.1545).abs() < 1e-12);
        for (yk, uk) in y.iter().zip(&u) {
            assert!(
                (yk - g * uk).abs() <= 1e-15 * yk.abs().max(1e-300),
                "{yk} vs {uk}"
            );
        }
    }

    #[test]
    fn mode_alone_gives_the_analytic_step_response() {
        let mut cfg = bare();
        cfg.apply_overrides("mode=on").unwrap();
        let y = simulate(&cfg, &[1.0; 60], 1e-3, 1);
        let g = cfg.static_gain();
        let (w, z) = (2.0 * PI * 103.0, 0.04);
        let (s, wd) = (z * w, w * (1.0f64 - z * z).sqrt());
        for (k, yk) in y.iter().enumerate() {
            let t = (k + 1) as f64 * 1e-3;
            let want = g * (1.0 - (-s * t).exp() * ((wd * t).cos() + s / wd * (wd * t).sin()));
            assert!((yk - want).abs() < 1e-12 * g, "k={k}: {yk} vs {want}");
        }
    }

    #[test]
    fn delay_alone_shifts_the_input() {
        let mut cfg = bare();
        let u: Vec<f64> = (0..50).map(|k| (k as f64 * 0.3).cos() + 1.0).collect();
        let y0 = simulate(&cfg, &u, 1e-3, 1);
        // The staircase delayed by 2.5 ms, read at the end of each interval, shows u[k-2].
        for (seconds, shift) in [(0.003, 3), (0.0025, 2), (0.0, 0)] {
            cfg.delay = DelayConfig {
                enabled: true,
                seconds,
            };
            let y = simulate(&cfg, &u, 1e-3, 1);
            assert_eq!(y[shift..], y0[..u.len() - shift], "{seconds} s");
            assert!(y[..shift].iter().all(|&v| v == 0.0));
        }
    }

    #[test]
    fn readings_lie_on_the_sensor_grid() {
        let cfg = TwinConfig::default();
        let u = raised_cosine(5.0, 4.0, 1.0, 1e-3);
        for y in simulate(&cfg, &u, 1e-3, 3) {
            let q = y / 2e-5;
            assert!((q - q.round()).abs() < 1e-6, "{y}");
        }
    }

    #[test]
    fn default_loop_at_1_hz_and_28_hz() {
        let amp = 70.0 / 15.0; // 0-70 V drive
        let dt = 1e-3;
        let loop_at = |overrides: &str, f: f64, periods: f64| {
            let cfg = TwinConfig::parse_overrides(overrides).unwrap();
            let u = raised_cosine(f, amp, periods, dt);
            let y = simulate(&cfg, &u, dt, 7);
            branches(&u, &y, f, dt, amp)
        };
        let (span1, rise1, fall1) = loop_at("", 1.0, 2.0);
        let width1 = max_diff(&rise1, &fall1);
        assert!((span1 - 0.6).abs() < 0.01, "span {span1}");
        assert!((0.10..=0.15).contains(&(width1 / span1)), "width {width1}");

        // The mode amplifies (|H| = 1.08 at 28 Hz): a taller loop, on both branches.
        let (span28, rise28, fall28) = loop_at("", 28.0, 20.0);
        assert!(span28 > 1.05 * span1, "span {span28} vs {span1}");
        let moved = max_diff(&rise28, &rise1).min(max_diff(&fall28, &fall1));
        assert!(
            moved > 0.02,
            "28 Hz loop within {moved} mm of the 1 Hz loop"
        );
        let width28 = max_diff(&rise28, &fall28);
        assert!(width28 > 0.09 * span28, "width {width28}");

        // Without the mode the chain is rate-independent: the same loop at 28 Hz (up to
        // noise, the 2 kHz amplifier and sampling of the turning points).
        let (s1, r1, f1) = loop_at("mode=off", 1.0, 2.0);
        let (s28, r28, f28) = loop_at("mode=off", 28.0, 20.0);
        assert!((s28 / s1 - 1.0).abs() < 0.01, "{s28} vs {s1}");
        let moved = max_diff(&r28, &r1).max(max_diff(&f28, &f1));
        assert!(moved < 0.004, "{moved}");
    }

    #[test]
    fn substeps_are_converged() {
        // The default 20 sub-steps against 1000, noise-free, at 28 Hz: within 10 nm.
        let mut cfg = TwinConfig::parse_overrides("noise=off,quantization=off").unwrap();
        let u = raised_cosine(28.0, 4.0, 5.0, 1e-3);
        let y = simulate(&cfg, &u, 1e-3, 0);
        cfg.substeps = 1000;
        let fine = simulate(&cfg, &u, 1e-3, 0);
        let err = y
            .iter()
            .zip(&fine)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(err < 1e-5, "max deviation {err} mm");
        // Exact for any sub-step count without hysteresis (exponential hold).
        cfg.apply_overrides("hysteresis=off").unwrap();
        let fine = simulate(&cfg, &u, 1e-3, 0);
        cfg.substeps = 3;
        let coarse = simulate(&cfg, &u, 1e-3, 0);
        assert!(max_diff(&fine, &coarse) < 1e-12);
    }

    #[test]
    fn seeds_fix_the_noise() {
        let cfg = TwinConfig::default();
        let u = raised_cosine(2.0, 4.0, 1.0, 1e-3);
        let a = simulate(&cfg, &u, 1e-3, 11);
        let b = simulate(&cfg, &u, 1e-3, 11);
        let c = simulate(&cfg, &u, 1e-3, 12);
        assert_eq!(a, b);
        assert_ne!(a, c);
        // Only the noise differs: σ = 0.3 µm.
        let rms =
            (a.iter().zip(&c).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt();
        assert!((rms / (2.0f64.sqrt() * 3e-4) - 1.0).abs() < 0.15, "{rms}");
        // reset() replays the same bytes; stepping matches simulate().
        let mut twin = Twin::new(&cfg, 11);
        let first: Vec<f64> = u.iter().map(|&x| twin.step(x)).collect();
        twin.reset();
        let again: Vec<f64> = u.iter().map(|&x| twin.step(x)).collect();
        assert_eq!(first, a);
        assert_eq!(again, a);
    }

    #[test]
    fn recording_has_units_and_time() {
        let u = raised_cosine(1.0, 4.0, 0.05, 1e-3);
        let r = recording(&TwinConfig::default(), "twin 1 Hz", u.clone(), 1e-3, 5).unwrap();
        assert_eq!(r.units, ["s", "V", "mm"]);
        assert_eq!(r.u, u);
        assert!((r.dt() - 1e-3).abs() < 1e-15);
        assert!(recording(&TwinConfig::default(), "bad", u, -1.0, 5).is_err());
    }

    #[test]
    fn overrides_grammar() {
        let cfg = TwinConfig::parse_overrides(" mode=off, creep=on ,noise=0.001,").unwrap();
        assert!(!cfg.mode.enabled && cfg.creep.enabled);
        assert!(cfg.noise.enabled && cfg.noise.sigma == 0.001);
        let cfg = TwinConfig::parse_overrides(
            "noise=off,mode.zeta=0.05,delay=0.002,substeps=40,dt=0.0005",
        )
        .unwrap();
        assert!(!cfg.noise.enabled && cfg.mode.zeta == 0.05);
        assert!(cfg.delay.enabled && cfg.delay.seconds == 0.002);
        assert_eq!((cfg.substeps, cfg.dt), (40, 0.0005));
        let cfg = TwinConfig::parse_overrides("quantisation.enabled=false,amp.gain=10").unwrap();
        assert!(!cfg.quantization.enabled && cfg.amp.gain == 10.0);
        for (bad, needle) in [
            (
                "modes=off",
                "valid keys: dt, substeps, amp[.enabled|.gain|.cutoff_hz]",
            ),
            ("mode.q=1", "unknown key `mode.q`"),
            ("mode=maybe", "not a number"),
            ("creep=0.1", "no main value"),
            ("noise", "expected key=value"),
            ("noise=-1", "noise.sigma"),
            ("substeps=0", "substeps"),
            ("mode.enabled=2", "on/off"),
        ] {
            let e = TwinConfig::parse_overrides(bad).unwrap_err();
            assert!(matches!(e, Error::Input(_)));
            assert!(e.to_string().contains(needle), "{bad}: {e}");
        }
        // Failed overrides change nothing.
        let mut cfg = TwinConfig::default();
        assert!(cfg.apply_overrides("mode=off,bogus=1").is_err());
        assert_eq!(cfg, TwinConfig::default());
        // Every listed key resolves.
        let mut cfg = TwinConfig::default();
        for (part, fields, _) in PARTS {
            for f in *fields {
                assert!(cfg.field(part, f).is_some(), "{part}.{f}");
            }
        }
    }

    #[test]
    fn toml_config() {
        let cfg = TwinConfig::from_toml("substeps = 30\n[mode]\nenabled = false\n").unwrap();
        assert_eq!(cfg.substeps, 30);
        assert!(!cfg.mode.enabled && cfg.mode.freq_hz == 103.0);
        assert!(TwinConfig::from_toml("[mode]\nfreq = 3\n").is_err());
        assert!(TwinConfig::from_toml("[mode]\nzeta = -1\n").is_err());
        // Round trip.
        let text = toml::to_string(&TwinConfig::default()).unwrap();
        assert_eq!(TwinConfig::from_toml(&text).unwrap(), TwinConfig::default());
    }

    #[test]
    fn parts_switch_on() {
        // Each optional part changes the noise-free output; the twin stays finite.
        let base = TwinConfig::parse_overrides("noise=off,quantization=off").unwrap();
        let u = raised_cosine(2.0, 4.6, 2.0, 1e-3);
        let y0 = simulate(&base, &u, 1e-3, 0);
        for ov in [
            "asymmetry=on",
            "creep=on",
            "delay=on",
            "drift=on",
            "saturation.limit=40",
            "amp=off",
            "hysteresis=off",
            "hysteresis.n=0.6",
        ] {
            let mut cfg = base.clone();
            cfg.apply_overrides(ov).unwrap();
            let y = simulate(&cfg, &u, 1e-3, 0);
            assert!(y.iter().all(|v| v.is_finite()));
            let diff = y
                .iter()
                .zip(&y0)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(diff > 1e-4, "{ov}: {diff}");
        }
    }
}
