//! Physics models of piezo actuators, shared by the twin (simulation), the fitting
//! objectives, diagnosis and control: one implementation of each model.
//!
//! - [`bouc_wen`]: the dissertation's Bouc-Wen hysteresis model, stepped exactly (`n = 1`) or by RK4
//!   in the input, with a free-run simulation and the fitting cost.
//! - [`linear`]: linear blocks (structural mode, low-pass, creep chain, delay), exactly
//!   discretised, each with a one-step API.
//! - [`prandtl_ishlinskii`]: the Prandtl-Ishlinskii operator model (plain, asymmetric,
//!   rate-dependent), linear in its weights, with the analytic inverse used for feedforward.
//! - [`rbf`]: the Gaussian RBF network, its NARX model (one-step and free-run) and the
//!   back-propagation baseline.
//! - [`restoring`]: an oscillator whose restoring force is hysteretic (the hysteresis
//!   inside the mechanical feedback, as in the Bouc-Wen benchmark).
//! - [`structure`]: Bouc-Wen with switchable extensions (delay, lags, saturation, asymmetry,
//!   rate dependence, creep, a mode, drift): the model family of `optbench diagnose`.
//! - [`twin`]: the simulated PZBA-00030-like actuator, a switchable chain of the above plus a
//!   drive amplifier and a sensor.

pub mod bouc_wen;
pub mod bouc_wen_fast;
pub mod fastmath;
pub mod fixtures;
pub mod linear;
pub mod model_file;
pub mod prandtl_ishlinskii;
pub mod rbf;
pub mod rbf_fast;
pub mod restoring;
pub mod structure;
pub mod twin;
