//! Hysteresis compensation by feedback (dissertation chapter 4): internal model control (IMC) with
//! two RBF networks against the incremental PID baseline, in closed loop at 1 ms on the
//! piezo twin.
//!
//! - [`plant`]: what is driven (the twin, a linear plant, an RBF model as a plant).
//! - [`pid`]: the incremental PID of eq. 4.9.
//! - [`network`]: the 2-7-1 controller network of eq. 4.1-4.8, trained online.
//! - [`model`]: the internal model, the RBF NARX network fitted by PSO to twin data.
//! - [`closed_loop`]: the sampled loop, the IMC structure of Fig. 4.2, the divergence guard.
//! - [`reference`]: the dissertation's rising-frequency sinusoids and any signal as a reference.
//! - [`feedforward`]: the alternative the dissertation names: an inverted hysteresis model
//!   (Prandtl-Ishlinskii, Bouc-Wen) on the reference, alone or plus the PID.

pub mod closed_loop;
pub mod feedforward;
pub mod figures;
pub mod invert;
pub mod model;
pub mod network;
pub mod pid;
pub mod plant;
pub mod reference;
pub mod run;
pub mod single;
pub mod suite;

pub use closed_loop::{Controller, Failure, Guard, Imc, LoopRun, run_loop};
pub use model::{FittedModel, ModelFitConfig, RbfModel};
pub use network::{NetConfig, RbfController};
pub use pid::{IncrementalPid, PidGains};
pub use plant::{LinearPlant, ModelPlant, Plant};
pub use reference::Reference;

#[cfg(test)]
mod tests;
