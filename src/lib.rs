//! optbench: a reproducible benchmark harness for black-box optimizers, built around the
//! identification and compensation of hysteresis in piezoelectric actuators.
//!
//! The flow is suite TOML -> plan -> trials (objective x optimizer x seed) -> traces ->
//! result store -> statistics -> report. Each stage lives in its own module:
//!
//! - [`objective`]: the black-box [`objective::Objective`] trait and the test functions.
//! - [`optimizer`]: optimizers (GA, PSO, MSGA, random search) that only see an evaluator.
//! - [`base`]: the ground floor: seeds and random streams, the stable hash, atomic writes,
//!   errors, parameter tables. It imports nothing of the project.
//! - [`harness`]: the optimizer contract beside the evaluator (the one place evaluations are
//!   counted), and the record of a trial.
//! - [`runner`]: the trial loop, above optimizers and harness, and a plan's trials in parallel.
//! - [`suite`]: TOML suites, parameter validation, the plan of trials.
//! - [`results`]: the result store (traces, summary, provenance), written atomically.
//! - [`scale`]: resume after a crash, shards and their merge, MPI ranks (feature `mpi`).
//! - [`report`]: what is printed and rendered from stored results.
//! - [`control`]: hysteresis compensation in closed loop (IMC with RBF networks, PID).

pub mod base;
pub mod cmd;
pub mod control;
pub mod data;
pub mod diagnose;
pub mod harness;
pub mod objective;
pub mod optimizer;
pub mod physics;
pub mod pipeline;
pub mod registry;
pub mod report;
pub mod speed;
pub mod stats;

pub use base::error::{Error, Result};
