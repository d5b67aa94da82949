//! What a controller drives: one sample at a time, command in, reading out.

use super::model::RbfModel;
use crate::physics::linear::LowPass;
use crate::physics::prandtl_ishlinskii::PiStepper;
use crate::physics::twin::Twin;

/// A sampled plant. `step` holds the command `u` for one sample interval and returns the
/// reading at its end, so the reading after `u(k)` is the measurement at sample `k + 1`.
pub trait Plant {
    fn step(&mut self, u: f64) -> f64;
}

impl Plant for Twin {
    fn step(&mut self, u: f64) -> f64 {
        Twin::step(self, u)
    }
}

/// A linear first-order plant `gain · lowpass(τ)(u)` with zero-order hold, exactly
/// discretised ([`LowPass`]): the textbook loop for tests of settling.
#[derive(Debug, Clone)]
pub struct LinearPlant {
    gain: f64,
    lag: LowPass,
}

impl LinearPlant {
    /// Static gain `gain` (output per command), time constant `tau` s, sample `dt` s.
    pub fn new(gain: f64, tau: f64, dt: f64) -> Self {
        LinearPlant {
            gain,
            lag: LowPass::new(tau, dt),
        }
    }
}

impl Plant for LinearPlant {
    fn step(&mut self, u: f64) -> f64 {
        self.gain * self.lag.step(u)
    }
}

/// An RBF NARX model run as the plant (free run from rest): with the same model inside an
/// IMC loop the model is perfect, the case in which the dissertation says the feedback is zero.
#[derive(Debug, Clone)]
pub struct ModelPlant(pub RbfModel);

impl Plant for ModelPlant {
    fn step(&mut self, u: f64) -> f64 {
        self.0.step(u)
    }
}

/// A PI model as the plant (from its demagnetised state): with its own inverse as the
/// feedforward the loop must track exactly.
impl Plant for PiStepper {
    fn step(&mut self, u: f64) -> f64 {
        PiStepper::step(self, u)
    }
}
