//! The sampled closed loop: reference in, plant reading back, a controller in between, with
//! a divergence guard that ends a run as failed (with its time) instead of panicking.
//!
//! Timing, at sample `k` (time `k·dt`): the reading `y(k)` (the plant's output after the
//! previous command) and the reference `y_d(k)` give the error `e(k) = y_d(k) - y(k)` (eq.
//! 4.1); the controller returns `u(k)`, held over the next interval; the plant returns
//! `y(k+1)`. The first reading is taken after one interval at zero command from rest.

use super::feedforward::Feedforward;
use super::model::RbfModel;
use super::network::{NetConfig, RbfController};
use super::pid::{IncrementalPid, PidGains};
use super::plant::Plant;
use serde::{Deserialize, Serialize};

/// Internal model control as in dissertation Fig. 4.2: the internal model runs beside the plant on
/// the same commands; the feedback signal is `d̂ = y - y_m`, the controller network acts on
/// `e = (y_d - d̂) - y_m` (which equals `y_d - y`, eq. 4.1) and is trained through the
/// model's sensitivity `∂y_m/∂u`.
#[derive(Debug, Clone)]
pub struct Imc {
    model: RbfModel,
    net: RbfController,
    /// Model output for the coming reading.
    ym: f64,
    /// Model sensitivity of that reading to the last command.
    jacobian: f64,
    feedback: f64,
}

impl Imc {
    /// A loop around `model` (reset to rest) with a fresh controller network.
    pub fn new(mut model: RbfModel, cfg: &NetConfig) -> Self {
        model.reset();
        Imc {
            model,
            net: RbfController::new(cfg),
            ym: 0.0,
            jacobian: 0.0,
            feedback: 0.0,
        }
    }

    /// The controller network (for inspection).
    pub fn network(&self) -> &RbfController {
        &self.net
    }
}

/// A controller of the loop.
#[derive(Debug, Clone)]
pub enum Controller {
    /// Incremental PID on `e = y_d - y` (eq. 4.9). Inside the IMC structure of Fig. 4.2 the
    /// internal model cancels out of a PID's input, so this is also the dissertation's "PID instead
    /// of the RBFNN controller for IMC".
    Pid(IncrementalPid),
    /// The dissertation's IMC with two RBF networks.
    Imc(Box<Imc>),
    /// The inverse of a hysteresis model on the reference, optionally plus a PID.
    Feedforward(Box<Feedforward>),
}

impl Controller {
    /// Incremental PID at rest at command 0.
    pub fn pid(gains: PidGains) -> Self {
        Controller::Pid(IncrementalPid::new(gains, 0.0))
    }

    /// IMC around `model`.
    pub fn imc(model: RbfModel, cfg: &NetConfig) -> Self {
        Controller::Imc(Box::new(Imc::new(model, cfg)))
    }

    /// Called once with the command applied before the loop starts (the plant saw it too).
    fn start(&mut self, u0: f64) {
        match self {
            Controller::Imc(c) => {
                c.ym = c.model.step(u0);
                c.jacobian = c.net.training_sensitivity(c.model.jacobian());
            }
            Controller::Feedforward(f) => f.start(u0),
            Controller::Pid(_) => {}
        }
    }

    /// The command `u(k)` from the reference and the reading at sample `k`, and the next
    /// reference sample `y_d(k+1)` (the one `u(k)` sets; only a feedforward looks at it).
    fn command(&mut self, yd: f64, yd_next: f64, y: f64) -> f64 {
        match self {
            Controller::Pid(p) => p.step(yd - y),
            Controller::Feedforward(f) => f.command(yd_next, yd - y),
            Controller::Imc(c) => {
                c.feedback = y - c.ym;
                let e = (yd - c.feedback) - c.ym;
                let u = c.net.step(e, c.jacobian);
                // A non-finite command ends the run; keep the model finite meanwhile.
                if u.is_finite() {
                    c.ym = c.model.step(u);
                    c.jacobian = c.net.training_sensitivity(c.model.jacobian());
                }
                u
            }
        }
    }

    /// The feedback signal `d̂(k) = y(k) - y_m(k)` of the last command (0 for PID).
    fn feedback(&self) -> f64 {
        match self {
            Controller::Pid(_) | Controller::Feedforward(_) => 0.0,
            Controller::Imc(c) => c.feedback,
        }
    }
}

/// Limits of the divergence guard.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Guard {
    /// Largest |command| (V): the twin's amplifier rails (±150 V drive = ±10 V command).
    pub u_limit: f64,
    /// Largest |reading| (mm): beyond what the actuator can reach (about ±1.6 mm at the
    /// rails on the twin) something diverged.
    pub y_limit: f64,
}

impl Default for Guard {
    fn default() -> Self {
        Guard {
            u_limit: 10.0,
            y_limit: 2.0,
        }
    }
}

/// Why and when a run stopped early.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Failure {
    /// Sample index at which the guard tripped.
    pub sample: usize,
    /// Its time (s).
    pub time_s: f64,
    pub reason: String,
}

/// One closed-loop run: every signal per sample, up to the end or the failure.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LoopRun {
    pub dt: f64,
    /// Reference `y_d(k)` (mm).
    pub reference: Vec<f64>,
    /// Reading `y(k)` (mm).
    pub output: Vec<f64>,
    /// Command `u(k)` (V).
    pub command: Vec<f64>,
    /// IMC feedback signal `d̂(k) = y(k) - y_m(k)` (mm; 0 for PID and feedforward).
    pub feedback: Vec<f64>,
    pub failure: Option<Failure>,
}

impl LoopRun {
    /// Samples completed.
    pub fn len(&self) -> usize {
        self.output.len()
    }

    pub fn is_empty(&self) -> bool {
        self.output.is_empty()
    }

    /// Sample times (s).
    pub fn time(&self) -> Vec<f64> {
        (0..self.len()).map(|k| k as f64 * self.dt).collect()
    }

    /// Tracking error `e(k) = y_d(k) - y(k)`.
    pub fn error(&self) -> Vec<f64> {
        self.reference
            .iter()
            .zip(&self.output)
            .map(|(r, y)| r - y)
            .collect()
    }

    /// RMS tracking error over samples at or after `from_s` seconds; `None` for a failed run
    /// or when no sample is left.
    pub fn rmse(&self, from_s: f64) -> Option<f64> {
        if self.failure.is_some() {
            return None;
        }
        let k0 = ((from_s / self.dt) - 1e-9).ceil().max(0.0) as usize;
        let e = self.error();
        let tail = e.get(k0..).filter(|t| !t.is_empty())?;
        Some((tail.iter().map(|v| v * v).sum::<f64>() / tail.len() as f64).sqrt())
    }

    /// Largest |e| at or after `from_s` (None as for [`Self::rmse`]).
    pub fn max_error(&self, from_s: f64) -> Option<f64> {
        if self.failure.is_some() {
            return None;
        }
        let k0 = ((from_s / self.dt) - 1e-9).ceil().max(0.0) as usize;
        let e = self.error();
        let tail = e.get(k0..).filter(|t| !t.is_empty())?;
        Some(tail.iter().fold(0.0f64, |m, v| m.max(v.abs())))
    }
}

/// Runs the loop for every sample of `reference` (mm), sampled every `dt` s. Never
/// panics on divergence: a non-finite or out-of-range reading or command ends the run with
/// a [`Failure`] at that sample.
pub fn run_loop(
    plant: &mut dyn Plant,
    controller: &mut Controller,
    reference: &[f64],
    dt: f64,
    guard: &Guard,
) -> LoopRun {
    let n = reference.len();
    let mut run = LoopRun {
        dt,
        reference: Vec::with_capacity(n),
        output: Vec::with_capacity(n),
        command: Vec::with_capacity(n),
        feedback: Vec::with_capacity(n),
        failure: None,
    };
    let fail = |k: usize, reason: String| {
        Some(Failure {
            sample: k,
            time_s: k as f64 * dt,
            reason,
        })
    };
    let mut y = plant.step(0.0);
    controller.start(0.0);
    for (k, &yd) in reference.iter().enumerate() {
        if !(y.is_finite() && y.abs() <= guard.y_limit) {
            run.failure = fail(
                k,
                format!(
                    "reading y = {y} mm outside ±{} mm (diverged)",
                    guard.y_limit
                ),
            );
            break;
        }
        // The reference is known ahead; past its end the last sample is held.
        let yd_next = reference.get(k + 1).copied().unwrap_or(yd);
        let u = controller.command(yd, yd_next, y);
        if !(u.is_finite() && u.abs() <= guard.u_limit) {
            run.failure = fail(
                k,
                format!(
                    "command u = {u} V outside the actuator's ±{} V (diverged)",
                    guard.u_limit
                ),
            );
            break;
        }
        run.reference.push(yd);
        run.output.push(y);
        run.command.push(u);
        run.feedback.push(controller.feedback());
        y = plant.step(u);
    }
    run
}
