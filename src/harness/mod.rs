//! The harness owns everything around an optimizer: evaluation counting and budgets
//! ([`Evaluator`]), random streams ([`TrialSeed`]), and the trial loop ([`run_trial`]).

pub mod evaluator;
pub mod trial;

pub use evaluator::{Evaluated, Evaluator, Grant, Stall, Trace};
pub use trial::{TrialRecord, TrialSpec, run_trial};
