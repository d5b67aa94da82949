//! The scales of the training data, and where the hysteresis sits in the model.

use super::*;
use crate::physics::preisach::PreisachGrid;

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
    /// The fewest RK4 sub-steps per sample of that integrator ([`MIN_SUBSTEPS`]).
    pub min_substeps: usize,
    /// The hysteresis at the chain's core: `None` Bouc-Wen, else a Prandtl-Ishlinskii or
    /// Preisach model with fixed thresholds ([`PiCore`]).
    pub pi: Option<PiCore>,
}

/// A core whose output is linear in its weights: a Prandtl-Ishlinskii model (`operators`
/// plays with thresholds `r_i = i/operators · half_range`, the training input's half-range)
/// or a discretised Preisach model ([`CoreKind::Relays`]: `operators` levels over the
/// training input's range, [`PreisachGrid`]). The weights are linear coefficients like
/// Bouc-Wen's `d_e` and `α`, so the chain's variable projection fits them exactly.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PiCore {
    pub operators: usize,
    pub half_range: f64,
    /// Plays or relays; absent in files written before the Preisach core: plays.
    #[serde(default)]
    pub kind: CoreKind,
    /// The training input's minimum (the Preisach grid's lower end; unused by plays).
    #[serde(default)]
    pub u_min: f64,
}

/// What a [`PiCore`]'s columns are.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CoreKind {
    /// Play operators: a Prandtl-Ishlinskii model.
    #[default]
    Plays,
    /// The relays of a Preisach model on `operators` levels.
    Relays,
}

/// Most operators of a PI core (each one a column simulated through the chain).
pub const MAX_PI_OPERATORS: usize = 32;

/// Most levels of a Preisach core: `7·8/2 = 28` relays, within [`MAX_PI_OPERATORS`] columns.
pub const MAX_PREISACH_LEVELS: usize = 7;

impl PiCore {
    /// `operators` plays over the half-range of the training inputs.
    pub fn new(operators: usize, inputs: &[&[f64]]) -> PiCore {
        let (lo, hi) = inputs
            .iter()
            .flat_map(|u| u.iter())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let varies = hi > lo;
        PiCore {
            operators: operators.clamp(1, MAX_PI_OPERATORS),
            half_range: if varies { 0.5 * (hi - lo) } else { 1.0 },
            kind: CoreKind::Plays,
            u_min: if varies { lo } else { 0.0 },
        }
    }

    /// A Preisach core of `levels` levels over the range of the training inputs.
    pub fn preisach(levels: usize, inputs: &[&[f64]]) -> PiCore {
        PiCore {
            operators: levels.clamp(1, MAX_PREISACH_LEVELS),
            kind: CoreKind::Relays,
            ..PiCore::new(levels, inputs)
        }
    }

    /// The thresholds, `r_0 = 0` (the linear term) first.
    pub fn thresholds(&self) -> Vec<f64> {
        (0..self.operators)
            .map(|i| self.half_range * i as f64 / self.operators as f64)
            .collect()
    }

    /// The Preisach grid of a relay core: `operators` levels over the training range.
    pub fn grid(&self) -> PreisachGrid {
        let levels = self.operators.clamp(1, MAX_PREISACH_LEVELS);
        PreisachGrid::new(levels, self.u_min, self.u_min + 2.0 * self.half_range)
            .or_else(|_| PreisachGrid::new(levels, 0.0, 1.0))
            .expect("a unit range makes a grid")
    }

    /// The number of linear columns: one per play, or one per relay.
    pub fn columns(&self) -> usize {
        match self.kind {
            CoreKind::Plays => self.operators.clamp(1, MAX_PI_OPERATORS),
            CoreKind::Relays => self.grid().relays(),
        }
    }

    /// The name in labels and reports.
    pub fn name(&self) -> &'static str {
        match self.kind {
            CoreKind::Plays => "pi",
            CoreKind::Relays => "preisach",
        }
    }
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
            min_substeps: MIN_SUBSTEPS,
            pi: None,
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

    /// The same scales with a Prandtl-Ishlinskii core.
    pub fn with_pi(mut self, pi: Option<PiCore>) -> Context {
        self.pi = pi;
        self
    }

    /// The same with at least `min` RK4 sub-steps per sample.
    pub fn with_min_substeps(mut self, min: usize) -> Context {
        self.min_substeps = min;
        self
    }
}
