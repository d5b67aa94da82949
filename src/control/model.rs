//! The internal model of the IMC loop (dissertation Fig. 4.2): the RBF NARX network of dissertation §3.2,
//! fitted by PSO to a twin recording through the ordinary fitting objective
//! ([`RbfFit`]) and the harness ([`run_trial`]), then run in parallel with the plant.

use crate::base::TrialSeed;
use crate::base::error::{Error, Result};
use crate::data::recording::Recording;
use crate::harness::TrialRecord;
use crate::objective::Objective;
use crate::objective::hysteresis::{FitData, FitView, RbfFit};
use crate::objective::source::{SimOptions, Source};
use crate::optimizer::pso::PsoConfig;
use crate::physics::rbf::{Mode, Narx, RbfNet};
use crate::pipeline::runner::{TrialSpec, run_trial};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// A fitted RBF NARX model in physical units (V in, mm out), stepped one sample at a time
/// on its own past outputs (free run), as an internal model runs beside the plant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RbfModel {
    pub hidden: usize,
    pub input_lags: usize,
    pub output_lags: usize,
    /// Parameters in the fit's normalised units (see [`crate::physics::rbf`] for the layout).
    pub params: Vec<f64>,
    /// Physical = normalised × scale.
    pub u_scale: f64,
    pub y_scale: f64,
    /// Past commands (normalised), newest first, `input_lags - 1` of them.
    #[serde(skip)]
    u_past: Vec<f64>,
    /// Past outputs (normalised), newest first, `output_lags` of them.
    #[serde(skip)]
    y_past: Vec<f64>,
    /// Regressor scratch.
    #[serde(skip)]
    x: Vec<f64>,
    /// `∂y(k)/∂u(k)` of the last step, mm/V.
    #[serde(skip)]
    jacobian: f64,
    /// Which sensitivity [`Self::jacobian`] reports.
    #[serde(default)]
    pub sensitivity: Sensitivity,
}

/// The plant sensitivity the controller is trained through (the dissertation does not say which).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sensitivity {
    /// `∂y(k)/∂u(k)`: the literal partial derivative in the current command only. At 1 ms
    /// `u(k)` and `u(k-1)` are nearly collinear in the identification data, so a PSO fit
    /// splits their effect arbitrarily and this often has the wrong sign.
    Instant,
    /// `Σ_i ∂y(k)/∂u(k-i)` over the input lags: the response to a command change held over
    /// the model's input window (what a zero-order hold does), identified by the data.
    #[default]
    Held,
}

impl Sensitivity {
    /// Parses `instant` or `held`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "instant" => Ok(Sensitivity::Instant),
            "held" => Ok(Sensitivity::Held),
            _ => Err(Error::Input(format!(
                "sensitivity `{s}`: expected instant or held"
            ))),
        }
    }
}

impl RbfModel {
    /// A model at rest (zero command and output history). Refuses a parameter vector of the
    /// wrong length or scales that are not positive.
    pub fn new(
        net: RbfNet,
        narx: Narx,
        params: Vec<f64>,
        u_scale: f64,
        y_scale: f64,
    ) -> Result<Self> {
        if net.inputs != narx.dim() || params.len() != net.n_params() {
            return Err(Error::Input(format!(
                "internal model: {} parameters for a {}-{}-1 network on {} regressors",
                params.len(),
                net.inputs,
                net.hidden,
                narx.dim()
            )));
        }
        if !(u_scale > 0.0 && y_scale > 0.0 && u_scale.is_finite() && y_scale.is_finite()) {
            return Err(Error::Input(format!(
                "internal model: scales must be positive, got {u_scale}, {y_scale}"
            )));
        }
        let mut m = RbfModel {
            hidden: net.hidden,
            input_lags: narx.input_lags,
            output_lags: narx.output_lags,
            params,
            u_scale,
            y_scale,
            u_past: Vec::new(),
            y_past: Vec::new(),
            x: Vec::new(),
            jacobian: 0.0,
            sensitivity: Sensitivity::default(),
        };
        m.reset();
        Ok(m)
    }

    /// The network shape.
    pub fn net(&self) -> RbfNet {
        RbfNet::new(self.input_lags + self.output_lags, self.hidden)
    }

    /// The regressor structure.
    pub fn narx(&self) -> Narx {
        Narx {
            input_lags: self.input_lags,
            output_lags: self.output_lags,
        }
    }

    /// Back to rest: zero past commands and outputs.
    pub fn reset(&mut self) {
        self.u_past = vec![0.0; self.input_lags.saturating_sub(1)];
        self.y_past = vec![0.0; self.output_lags];
        self.x = vec![0.0; self.input_lags + self.output_lags];
        self.jacobian = 0.0;
    }

    /// The model's output after holding the command `u` (V) for one sample, in mm, from
    /// its own past outputs; also sets [`Self::jacobian`].
    pub fn step(&mut self, u: f64) -> f64 {
        let un = u / self.u_scale;
        let il = self.input_lags;
        if il > 0 {
            self.x[0] = un;
            self.x[1..il].copy_from_slice(&self.u_past);
        }
        self.x[il..].copy_from_slice(&self.y_past);
        let net = self.net();
        let mut dx = vec![0.0; self.x.len()];
        let yn = net.input_grad(&self.params, &self.x, &mut dx);
        // In mm/V: the first regressor is the current command, the next ones the commands
        // before it (input_lags > 0 is checked when fitting).
        let du: f64 = match self.sensitivity {
            Sensitivity::Instant => dx.first().copied().unwrap_or(0.0),
            Sensitivity::Held => dx[..il].iter().sum(),
        };
        self.jacobian = du * self.y_scale / self.u_scale;
        if !self.u_past.is_empty() {
            self.u_past.rotate_right(1);
            self.u_past[0] = un;
        }
        if !self.y_past.is_empty() {
            self.y_past.rotate_right(1);
            self.y_past[0] = yn;
        }
        yn * self.y_scale
    }

    /// `∂y(k)/∂u(k)` (mm/V) at the last step: how the model says the next reading moves with
    /// the command just applied. The controller's back-propagation goes through it.
    pub fn jacobian(&self) -> f64 {
        self.jacobian
    }
}

/// How the internal model is identified: the dissertation's PSO fit of its 3-7-1 network on a
/// twin recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelFitConfig {
    /// Excitation signal (command, V) of the identification recording.
    pub signal: String,
    /// Seconds of it.
    pub duration: f64,
    /// Twin overrides during identification (the plant as the model was fitted to it).
    pub twin: String,
    pub hidden: usize,
    pub input_lags: usize,
    pub output_lags: usize,
    /// `free-run` (default: the internal model runs in parallel with the plant on its own
    /// outputs, so that is what it is fitted for) or `one-step` (the dissertation's Table 3.3 cost;
    /// such models drift in free run and the IMC loop tracks poorly with them).
    pub mode: String,
    /// PSO swarm size.
    pub swarm: usize,
    /// Function evaluations of the fit.
    pub budget: u64,
}

/// The identification signal: a 1 -> 10 Hz log chirp like suites/hysteresis.toml's Table 3.3
/// record, but over 0-4.7 V, down to the rest command the loop starts from. (With the
/// 0.05-4.65 V record the fitted sensitivity near 0 V is extrapolated and can be negative,
/// which sent 1 of 16 test loops away from the reference for good.)
pub const DEFAULT_MODEL_SIGNAL: &str =
    "chirp:f0=1,f1=10,duration=4,law=log,amp=2.35,offset=2.35,phase=-1.5707963267948966";

impl Default for ModelFitConfig {
    fn default() -> Self {
        ModelFitConfig {
            signal: DEFAULT_MODEL_SIGNAL.into(),
            duration: 4.0,
            twin: String::new(),
            hidden: 7,
            input_lags: 2,
            output_lags: 1,
            mode: "free-run".into(),
            swarm: 150,
            budget: 7500,
        }
    }
}

/// A fitted internal model with the record of its fit.
#[derive(Debug, Clone)]
pub struct FittedModel {
    pub model: RbfModel,
    pub record: TrialRecord,
    /// Free-run RMSE (mm) of the model on its identification recording.
    pub free_run_rmse: f64,
    /// One-step-ahead RMSE (mm) on the same recording.
    pub one_step_rmse: f64,
}

impl ModelFitConfig {
    /// The identification recording from noise seed `noise_seed`.
    pub fn recording(&self, noise_seed: u64) -> Result<Recording> {
        let src = Source::parse(
            &format!("twin:{}", self.signal),
            Path::new("."),
            "t,u,y",
            SimOptions {
                duration: Some(self.duration),
                dt: 1e-3,
                twin: self.twin.clone(),
                seed: noise_seed,
            },
        )?;
        src.load()
    }

    fn mode(&self) -> Result<Mode> {
        match self.mode.as_str() {
            "one-step" => Ok(Mode::OneStepAhead),
            "free-run" => Ok(Mode::FreeRun),
            m => Err(Error::Input(format!(
                "internal model: mode `{m}`: expected one-step or free-run"
            ))),
        }
    }

    /// Fits the model by PSO, every random number from `seed` (stream 0 drives PSO; the
    /// recording's noise seed is drawn from stream 1).
    pub fn fit(&self, seed: &TrialSeed) -> Result<FittedModel> {
        use rand::RngExt;
        let noise_seed: u64 = seed.rng(1).random();
        let rec = self.recording(noise_seed)?;
        let narx = Narx {
            input_lags: self.input_lags,
            output_lags: self.output_lags,
        };
        if narx.input_lags == 0 {
            return Err(Error::Input(
                "internal model: input_lags must be >= 1 (the command must enter the model)".into(),
            ));
        }
        let net = RbfNet::new(narx.dim(), self.hidden);
        let fit = Arc::new(RbfFit::new(
            std::slice::from_ref(&rec),
            &[],
            net,
            narx,
            self.mode()?,
        )?);
        let pso = PsoConfig {
            swarm: self.swarm,
            ..PsoConfig::default()
        };
        let objective: Arc<dyn Objective> = fit.clone();
        let record = run_trial(TrialSpec {
            objective_id: "internal-model",
            optimizer_id: "PSO",
            trial: 0,
            objective,
            optimizer: &pso,
            budget: self.budget,
            stop_value: None,
            stall: None,
            seed: *seed,
        });
        // The fit normalises by the record's largest |u| and |y|; take the same scales and
        // check them against the fit's own output, so a change of its internals is caught
        // here rather than silently mis-scaling the model.
        let scales = FitData::new(&rec, true)?;
        let model = RbfModel::new(
            net,
            narx,
            record.best_x.clone(),
            scales.u_scale,
            scales.y_scale,
        )?;
        let outputs = fit.outputs(&record.best_x, 0);
        let free = outputs
            .iter()
            .find(|(l, _)| l.contains("free"))
            .map(|(_, y)| y.clone())
            .ok_or_else(|| Error::Input("internal model: the fit shows no free run".into()))?;
        let one = outputs
            .iter()
            .find(|(l, _)| l.contains("one-step"))
            .map(|(_, y)| y.clone())
            .unwrap_or_else(|| free.clone());
        check_scales(&model, &rec, &free)?;
        let start = narx.start();
        Ok(FittedModel {
            free_run_rmse: rms_diff(&rec.y[start..], &free[start..]),
            one_step_rmse: rms_diff(&rec.y[start..], &one[start..]),
            model,
            record,
        })
    }
}

/// RMS of `a − b` over the length of `a` (records of equal length here).
pub(super) fn rms_diff(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().max(1) as f64;
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / n).sqrt()
}

/// The model's free run from the recording's first samples must reproduce the fit's.
fn check_scales(model: &RbfModel, rec: &Recording, free: &[f64]) -> Result<()> {
    let narx = model.narx();
    let net = model.net();
    let un: Vec<f64> = rec.u.iter().map(|v| v / model.u_scale).collect();
    let yn: Vec<f64> = rec.y.iter().map(|v| v / model.y_scale).collect();
    let mut out = vec![0.0; un.len()];
    crate::physics::rbf::predict(
        &net,
        &narx,
        &model.params,
        &un,
        &yn,
        Mode::FreeRun,
        &mut out,
    );
    let worst = out
        .iter()
        .zip(free)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .fold(0.0f64, |m, (a, b)| m.max((a * model.y_scale - b).abs()));
    if worst > 1e-9 * model.y_scale.max(1.0) {
        return Err(Error::Input(format!(
            "internal model: the fit's scaling changed (model output differs by {worst:.3e} mm); \
             control::model must follow objective::hysteresis"
        )));
    }
    Ok(())
}
