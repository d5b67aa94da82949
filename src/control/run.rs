//! One closed-loop experiment as the CLI and suites describe it: a controller with its
//! settings, a reference, the plant (twin overrides), the twin the internal model was
//! identified on, and the numbers that come out.

use super::closed_loop::{Controller, Guard, LoopRun, run_loop};
use super::feedforward::{
    DEFAULT_BW_BUDGET, DEFAULT_PI_OPERATORS, FF_PID, Feedforward, FittedInverse, InverseFitConfig,
    InverseModelSpec,
};
use super::model::{FittedModel, ModelFitConfig, Sensitivity};
use super::network::NetConfig;
use super::pid::PidGains;
use super::reference::Reference;
use crate::base::TrialSeed;
use crate::base::error::{Error, Result};
use crate::base::limits::{self, MAX_DIM, MAX_POPULATION};
use crate::physics::twin::{Twin, TwinConfig};
use serde::{Deserialize, Serialize};

/// Sample interval of the loop (s): the dissertation's 1 ms.
pub const DT: f64 = 1e-3;

/// Seconds at the start treated as the transient (the dissertation removed it from its
/// hysteresis-compensation figures and says errors fall "within a single second").
pub const DEFAULT_TRANSIENT_S: f64 = 1.0;

/// The controller kinds, as named on the command line and in suites.
pub const CONTROLLER_KINDS: [&str; 6] =
    ["imc-rbf", "pid", "ff-pi", "ff-bw", "ff-pi+pid", "ff-bw+pid"];

/// Parameters of each kind: (name, meaning).
pub const PID_KEYS: &[(&str, &str)] = &[
    (
        "kp",
        "proportional gain of eq. 4.9, V/mm (dissertation 1.0)",
    ),
    ("ki", "integral gain, V/mm per sample (dissertation 0.8)"),
    ("kd", "derivative gain, V/mm (dissertation 0.6)"),
];

/// Parameters of `imc-rbf`: (name, meaning).
pub const IMC_KEYS: &[(&str, &str)] = &[
    ("learning_rate", "η of eq. 4.6-4.8 (default 0.1)"),
    ("momentum", "β of eq. 4.6-4.8, in [0, 1) (default 0.9)"),
    ("hidden", "controller hidden nodes (seed 7)"),
    (
        "error_scale",
        "mm; the network sees [e, Δe]/error_scale (default 0.5)",
    ),
    (
        "centre_spread",
        "initial centres on [-s, s]² diagonal (default 1)",
    ),
    ("width", "initial widths (default 1)"),
    ("u0", "initial command at zero error, V (default 0)"),
    (
        "sensitivity",
        "held (Σ ∂y/∂u over the input lags, default) or instant (∂y(k)/∂u(k))",
    ),
    (
        "sensitivity_floor",
        "mm/V; train through max(model sensitivity, floor) (default: none)",
    ),
    (
        "sensitivity_ceiling",
        "mm/V; train through min(model sensitivity, ceiling) (default: none)",
    ),
    (
        "model_mode",
        "internal model fitted on free-run (default) or one-step (seed) cost",
    ),
    (
        "model_budget",
        "PSO evaluations of the model fit (default 7500)",
    ),
    ("model_swarm", "PSO particles (default 150)"),
    ("model_hidden", "model hidden nodes (seed 7)"),
    ("model_signal", "identification command signal (V)"),
    ("model_duration", "seconds of it (default 4)"),
];

/// Parameters of the identification experiment, shared by every model-based kind.
const IDENT_KEYS: &[(&str, &str)] = &[
    ("model_signal", "identification command signal (V)"),
    ("model_duration", "seconds of it (default 4)"),
];

/// Parameters of `ff-pi` besides the identification's: (name, meaning).
pub const FF_PI_KEYS: &[(&str, &str)] = &[(
    "operators",
    "play operators of the PI model, the linear term included (default 10)",
)];

/// Parameters of `ff-bw` besides the identification's: (name, meaning).
pub const FF_BW_KEYS: &[(&str, &str)] = &[(
    "model_budget",
    "CMA-ES evaluations of the Bouc-Wen fit (default 6000)",
)];

/// A controller with its settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ControllerSpec {
    Pid(PidGains),
    ImcRbf(ImcSpec),
    Feedforward(FeedforwardSpec),
}

/// Settings of a feedforward controller: the model inverted, how it is identified, and the
/// PID added on the error (None: feedforward alone).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FeedforwardSpec {
    pub fit: InverseFitConfig,
    pub pid: Option<PidGains>,
}

/// Settings of the IMC loop: its controller network and how its model is identified.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImcSpec {
    pub net: NetConfig,
    pub model: ModelFitConfig,
    pub sensitivity: Sensitivity,
}

fn number(kind: &str, key: &str, v: &str) -> Result<f64> {
    v.trim()
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
        .ok_or_else(|| {
            Error::Input(format!(
                "controller `{kind}`: `{key}` = `{v}` is not a finite number"
            ))
        })
}

/// A count in `[1, max]` (limits in [`crate::base::limits`]).
fn count(kind: &str, key: &str, v: &str, max: usize) -> Result<usize> {
    v.trim()
        .parse::<usize>()
        .ok()
        .filter(|&n| (1..=max).contains(&n))
        .ok_or_else(|| {
            Error::Input(format!(
                "controller `{kind}`: `{key}` = `{v}` is not an integer in [1, {max}]"
            ))
        })
}

fn unknown(kind: &str, key: &str, keys: &[(&str, &str)]) -> Error {
    Error::Input(format!(
        "controller `{kind}`: unknown parameter `{key}`; valid: {}",
        keys.iter().map(|k| k.0).collect::<Vec<_>>().join(", ")
    ))
}

impl ControllerSpec {
    /// `kind` (`pid` or `imc-rbf`) with `key=value` settings over the defaults.
    pub fn parse(kind: &str, params: &[(String, String)]) -> Result<ControllerSpec> {
        match kind {
            "pid" => {
                let mut g = PidGains::default();
                for (k, v) in params {
                    let x = number(kind, k, v)?;
                    match k.as_str() {
                        "kp" => g.kp = x,
                        "ki" => g.ki = x,
                        "kd" => g.kd = x,
                        _ => return Err(unknown(kind, k, PID_KEYS)),
                    }
                }
                Ok(ControllerSpec::Pid(g))
            }
            "imc-rbf" => {
                let mut net = NetConfig::default();
                let mut model = ModelFitConfig::default();
                let mut sensitivity = Sensitivity::default();
                for (k, v) in params {
                    match k.as_str() {
                        "learning_rate" => net.learning_rate = number(kind, k, v)?,
                        "momentum" => net.momentum = number(kind, k, v)?,
                        "hidden" => net.hidden = count(kind, k, v, MAX_DIM)?,
                        "error_scale" => net.error_scale = number(kind, k, v)?,
                        "centre_spread" => net.centre_spread = number(kind, k, v)?,
                        "width" => net.width = number(kind, k, v)?,
                        "u0" => net.u0 = number(kind, k, v)?,
                        "sensitivity_floor" => net.sensitivity_floor = Some(number(kind, k, v)?),
                        "sensitivity_ceiling" => {
                            net.sensitivity_ceiling = Some(number(kind, k, v)?)
                        }
                        "sensitivity" => sensitivity = Sensitivity::parse(v.trim())?,
                        "model_mode" => match v.trim() {
                            m @ ("one-step" | "free-run") => model.mode = m.into(),
                            m => {
                                return Err(Error::Input(format!(
                                    "controller `{kind}`: `model_mode` = `{m}`: expected one-step or free-run"
                                )));
                            }
                        },
                        "model_budget" => model.budget = count(kind, k, v, usize::MAX)? as u64,
                        "model_swarm" => model.swarm = count(kind, k, v, MAX_POPULATION)?,
                        "model_hidden" => model.hidden = count(kind, k, v, MAX_DIM)?,
                        _ => {
                            if !ident_key(kind, k, v, &mut model.signal, &mut model.duration)? {
                                return Err(unknown(kind, k, IMC_KEYS));
                            }
                        }
                    }
                }
                net.validate()
                    .map_err(|m| Error::Input(format!("controller `{kind}`: {m}")))?;
                Ok(ControllerSpec::ImcRbf(ImcSpec {
                    net,
                    model,
                    sensitivity,
                }))
            }
            "ff-pi" | "ff-bw" | "ff-pi+pid" | "ff-bw+pid" => {
                let with_pid = kind.ends_with("+pid");
                let (model, model_keys) = if kind.starts_with("ff-pi") {
                    let operators = DEFAULT_PI_OPERATORS;
                    (InverseModelSpec::Pi { operators }, FF_PI_KEYS)
                } else {
                    let budget = DEFAULT_BW_BUDGET;
                    (InverseModelSpec::BoucWen { budget }, FF_BW_KEYS)
                };
                let mut fit = InverseFitConfig::new(model);
                let mut pid = with_pid.then_some(FF_PID);
                for (k, v) in params {
                    match (k.as_str(), &mut fit.model, &mut pid) {
                        ("model_budget", InverseModelSpec::BoucWen { budget }, _) => {
                            *budget = count(kind, k, v, usize::MAX)? as u64
                        }
                        ("operators", InverseModelSpec::Pi { operators }, _) => {
                            *operators = count(kind, k, v, MAX_DIM)?
                        }
                        ("kp", _, Some(g)) => g.kp = number(kind, k, v)?,
                        ("ki", _, Some(g)) => g.ki = number(kind, k, v)?,
                        ("kd", _, Some(g)) => g.kd = number(kind, k, v)?,
                        _ => {
                            if !ident_key(kind, k, v, &mut fit.signal, &mut fit.duration)? {
                                let pid_keys = if with_pid { PID_KEYS } else { &[] };
                                let keys: Vec<_> = [model_keys, IDENT_KEYS, pid_keys].concat();
                                return Err(unknown(kind, k, &keys));
                            }
                        }
                    }
                }
                Ok(ControllerSpec::Feedforward(FeedforwardSpec { fit, pid }))
            }
            _ => Err(Error::Input(format!(
                "unknown controller `{kind}`; valid: {}",
                CONTROLLER_KINDS.join(", ")
            ))),
        }
    }

    /// The kind as named on the command line (`pid`, `imc-rbf`, `ff-bw+pid`, ...).
    pub fn kind(&self) -> String {
        match self {
            ControllerSpec::Pid(_) => "pid".into(),
            ControllerSpec::ImcRbf(_) => "imc-rbf".into(),
            ControllerSpec::Feedforward(f) => format!(
                "ff-{}{}",
                f.fit.model.short(),
                if f.pid.is_some() { "+pid" } else { "" }
            ),
        }
    }
}

/// Sets `model_signal` or `model_duration` (true), or says the key is neither (false).
fn ident_key(
    kind: &str,
    key: &str,
    v: &str,
    signal: &mut String,
    duration: &mut f64,
) -> Result<bool> {
    match key {
        "model_signal" => {
            crate::data::signal::Signal::parse(v)
                .map_err(|e| Error::Input(format!("controller `{kind}`: `model_signal`: {e}")))?;
            *signal = v.trim().into();
        }
        "model_duration" => {
            let d = number(kind, key, v)?;
            if d <= 0.0 {
                return Err(Error::Input(format!(
                    "controller `{kind}`: `model_duration` = {d}: must be > 0"
                )));
            }
            limits::samples(d, DT)
                .map_err(|e| Error::Input(format!("controller `{kind}`: `model_duration`: {e}")))?;
            *duration = d;
        }
        _ => return Ok(false),
    }
    Ok(true)
}

/// How a run's model is identified: the IMC's RBF internal model or a feedforward's
/// inverted model. Untagged: an IMC setting serialises as before.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Identification {
    Rbf(ModelFitConfig),
    Inverse(InverseFitConfig),
}

/// A model identified for a run.
#[derive(Debug, Clone)]
pub enum Identified {
    Rbf(FittedModel),
    Inverse(FittedInverse),
}

impl Identification {
    /// Fits the model, every random number from `seed`.
    pub fn fit(&self, seed: &TrialSeed) -> Result<Identified> {
        Ok(match self {
            Identification::Rbf(m) => Identified::Rbf(m.fit(seed)?),
            Identification::Inverse(m) => Identified::Inverse(m.fit(seed)?),
        })
    }

    /// The twin the model is identified on.
    pub fn twin(&self) -> &str {
        match self {
            Identification::Rbf(m) => &m.twin,
            Identification::Inverse(m) => &m.twin,
        }
    }
}

impl Identified {
    /// Free-run RMSE (mm) of the model on its identification record.
    pub fn free_run_rmse(&self) -> f64 {
        match self {
            Identified::Rbf(m) => m.free_run_rmse,
            Identified::Inverse(m) => m.free_run_rmse,
        }
    }

    /// Objective evaluations of the fit.
    pub fn evaluations(&self) -> u64 {
        match self {
            Identified::Rbf(m) => m.record.evaluations,
            Identified::Inverse(m) => m.evaluations,
        }
    }
}

/// Splits `key=value` items (CLI `--controller-param`), refusing items without `=`.
pub fn key_values(items: &[String]) -> Result<Vec<(String, String)>> {
    items
        .iter()
        .map(|s| {
            s.split_once('=')
                .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
                .ok_or_else(|| {
                    Error::Input(format!("--controller-param `{s}`: expected KEY=VALUE"))
                })
        })
        .collect()
}

/// One experiment, fully specified.
#[derive(Debug, Clone)]
pub struct RunSpec {
    pub controller: ControllerSpec,
    pub reference: Reference,
    /// Twin overrides of the plant in the loop.
    pub plant: String,
    /// Twin overrides the internal model was identified on (None: the plant's).
    pub model_twin: Option<String>,
    pub guard: Guard,
    /// Seconds treated as the transient.
    pub transient: f64,
}

impl RunSpec {
    /// The identification settings of a model-based run (with the twin it is identified on).
    pub fn model_config(&self) -> Option<Identification> {
        let twin = self
            .model_twin
            .clone()
            .unwrap_or_else(|| self.plant.clone());
        match &self.controller {
            ControllerSpec::Pid(_) => None,
            ControllerSpec::ImcRbf(s) => Some(Identification::Rbf(ModelFitConfig {
                twin,
                ..s.model.clone()
            })),
            ControllerSpec::Feedforward(f) => Some(Identification::Inverse(InverseFitConfig {
                twin,
                ..f.fit.clone()
            })),
        }
    }

    /// Checks the twin overrides and the transient before anything runs.
    pub fn validate(&self) -> Result<()> {
        TwinConfig::parse_overrides(&self.plant)
            .map_err(|e| Error::Input(format!("plant: {e}")))?;
        if let Some(m) = &self.model_twin {
            TwinConfig::parse_overrides(m).map_err(|e| Error::Input(format!("model twin: {e}")))?;
        }
        if !(self.transient >= 0.0 && self.transient < self.reference.duration) {
            return Err(Error::Input(format!(
                "transient {} s must be in [0, {}) (the reference's duration)",
                self.transient, self.reference.duration
            )));
        }
        Ok(())
    }

    /// Runs the loop on the twin with sensor noise from `noise_seed`; `model` is the fitted
    /// model of a model-based run (fit it with [`Self::model_config`]).
    pub fn execute(&self, model: Option<&Identified>, noise_seed: u64) -> Result<Outcome> {
        let cfg = TwinConfig::parse_overrides(&self.plant)
            .map_err(|e| Error::Input(format!("plant: {e}")))?;
        let mut twin = Twin::try_new(&cfg, noise_seed)?;
        let mut controller = match (&self.controller, model) {
            (ControllerSpec::Pid(g), _) => Controller::pid(*g),
            (ControllerSpec::ImcRbf(s), Some(Identified::Rbf(m))) => {
                let mut model = m.model.clone();
                model.sensitivity = s.sensitivity;
                Controller::imc(model, &s.net)
            }
            (ControllerSpec::Feedforward(f), Some(Identified::Inverse(m))) => {
                Controller::Feedforward(Box::new(Feedforward::new(
                    &m.model,
                    f.pid,
                    self.guard.u_limit,
                )))
            }
            (c, _) => {
                return Err(Error::Input(format!(
                    "a {} run needs its fitted model",
                    c.kind()
                )));
            }
        };
        let reference = self.reference.sample(DT);
        let run = run_loop(&mut twin, &mut controller, &reference, DT, &self.guard);
        Ok(Outcome::new(run, self.transient, model))
    }

    /// Fits the model (if any) from `model_seed`, then runs with `noise_seed`.
    pub fn fit_and_execute(&self, model_seed: &TrialSeed, noise_seed: u64) -> Result<Outcome> {
        let fitted = match self.model_config() {
            Some(m) => Some(m.fit(model_seed)?),
            None => None,
        };
        self.execute(fitted.as_ref(), noise_seed)
    }
}

/// The numbers of one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// RMS of `e = y_d - y` over the whole run, mm (None: the run failed).
    pub rmse_mm: Option<f64>,
    /// Over the samples after the transient.
    pub rmse_steady_mm: Option<f64>,
    /// Largest |e| after the transient.
    pub max_error_steady_mm: Option<f64>,
    /// RMS of the IMC feedback signal `d̂ = y - y_m`, mm (0 for PID and feedforward).
    pub feedback_rms_mm: f64,
    pub transient_s: f64,
    pub failure: Option<super::closed_loop::Failure>,
    /// Free-run RMSE (mm) of the internal or inverted model on its identification record.
    pub model_free_run_rmse_mm: Option<f64>,
}

/// A run and its metrics.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub run: LoopRun,
    pub metrics: Metrics,
}

impl Outcome {
    fn new(run: LoopRun, transient: f64, model: Option<&Identified>) -> Outcome {
        let n = run.feedback.len().max(1) as f64;
        let metrics = Metrics {
            rmse_mm: run.rmse(0.0),
            rmse_steady_mm: run.rmse(transient),
            max_error_steady_mm: run.max_error(transient),
            feedback_rms_mm: (run.feedback.iter().map(|v| v * v).sum::<f64>() / n).sqrt(),
            transient_s: transient,
            failure: run.failure.clone(),
            model_free_run_rmse_mm: model.map(Identified::free_run_rmse),
        };
        Outcome { run, metrics }
    }
}
