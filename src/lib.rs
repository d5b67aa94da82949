//! optbench: a reproducible benchmark harness for black-box optimizers, built around the
//! identification and compensation of hysteresis in piezoelectric actuators.
//!
//! Two flows share one house. Benchmarks: suite TOML -> plan -> trials (objective x optimizer
//! x seed) -> traces -> result store -> statistics -> report. Physics: recording -> model ->
//! fit -> diagnose or compensate. The modules, from the ground floor up (a module imports
//! only the floors below it; `scripts/import_graph.py --layers` and a test check it):
//!
//! - [`base`]: seeds and random streams, the stable hash, atomic writes, errors, parameter
//!   tables. Imports nothing of the project.
//! - [`data`]: recordings read as labs write them, and the drive signals of experiments.
//! - [`physics`]: the hysteresis models (Bouc-Wen, RBF network, the restoring-force and
//!   structure extensions), the piezo twin; shared by fitting, diagnosis and control.
//! - [`objective`]: the black-box [`objective::Objective`] trait, the test functions (COCO's
//!   BBOB among them) and the hysteresis-fit objectives.
//! - [`harness`]: the optimizer contract beside the evaluator (the one place evaluations are
//!   counted), and the record of a trial.
//! - [`optimizer`]: GA, PSO, MSGA (one thread per membrane), CMA-ES, DE, L-BFGS, Nelder-Mead,
//!   Levenberg-Marquardt, BP and random search; they only see an evaluator.
//! - [`stats`]: descriptive statistics, intervals, rank tests, ERT.
//! - [`registry`]: the names suites and commands use for objective and optimizer kinds.
//! - [`render`]: the figure and table kit (six figure kinds as SVG and PNG, Markdown and
//!   LaTeX writers, the bundled font); draws data, not runs.
//! - [`pipeline`]: suite and plan, the trial runner, the result store, a run (resumable,
//!   sharded), merge and MPI; the one-trial jobs of `fit` and `simulate`.
//! - [`speed`]: what `optbench bench` measures (evaluation paths, harness overhead).
//! - [`report`]: tables, figures and the IOHprofiler export of a stored run.
//! - [`diagnose`]: where a model misses a recording and which physics it left out.
//! - [`control`]: hysteresis compensation in closed loop (IMC with RBF networks, PID).
//! - [`cmd`]: the command line, one file per subcommand.

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
pub mod render;
pub mod report;
pub mod speed;
pub mod stats;

pub use base::error::{Error, Result};
