//! The harness owns everything around an optimizer: the contract an optimizer implements
//! ([`Optimizer`], [`OptimizerConfig`]), evaluation counting and budgets ([`Evaluator`]),
//! and the record a trial leaves ([`TrialRecord`]). The trial loop that drives it all is
//! above, in the runner (`pipeline/runner/trial.rs`).

pub mod contract;
pub mod evaluator;
pub mod record;

pub use contract::{Optimizer, OptimizerConfig};
pub use evaluator::{Evaluated, Evaluator, Grant, Stall, Trace};
pub use record::TrialRecord;
