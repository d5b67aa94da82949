//! `model.json`: a fitted model written so that it runs again on any input (`optbench
//! simulate --model`), in the recording's own units.
//!
//! What a fit normalises stays inside the fit: the file holds the de-normalised physical
//! parameters (and, for the record, the scales the search ran on), the sampling interval,
//! the integration or discretisation, each fitted record's own initial state and offset,
//! and every parameter's search bounds with a flag where the fit ended at one. Three
//! kinds, one per model family that `fit` and `diagnose` write:
//!
//! - `bouc-wen`: `y = d_e u + d0 - h`, `dh = α du - β |du| |h|^(n-1) h - γ du |h|^n`,
//!   integrated by the fit's scheme with its sub-steps; run from the parameters list.
//! - `rbf`: the NARX network `y(k) = Σ_j w_j exp(-½ Σ_i ((x_i - c_ji)/b_ji)²)` on regressors
//!   `x = [u(k), …, y(k-1), …]`, centres and widths per regressor in that regressor's
//!   unit, free-run (the model's own past outputs).
//! - `structure`: `diagnose`'s Bouc-Wen with extensions, rebuilt from its effects, forms,
//!   placement and data context, run from its shape vector (unit-free, bounds given) and
//!   its linear coefficients (the physical parameters are listed for the reader).
//! - `pi`: a Prandtl-Ishlinskii model (plain, asymmetric or rate-dependent; see
//!   [`super::prandtl_ishlinskii`]), run from its `pi` field (thresholds, weights, rate
//!   weights, polynomial, offsets in physical units; the parameters list repeats them).
//! - `preisach`: a discretised Preisach model ([`super::preisach`]), run from its `preisach`
//!   field (the grid's levels and input range, the relay weights and offset, in physical
//!   units).
//!
//! Reading refuses what it cannot run: another format or version, an unknown kind, a
//! missing or non-finite value, each named with the file and the field.

use super::bouc_wen::{self, BoucWenParams, SimStatus};
use super::bouc_wen_fast;
use super::prandtl_ishlinskii::{PiForm, PiModel, check_thresholds};
use super::preisach::Preisach;
use super::rbf::Narx;
use super::structure::{self, Context, Effect, Hold, Placement, Structure};
use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The `format` field of every model file.
pub const FORMAT: &str = "optbench-model";
/// The version this build writes and reads.
pub const VERSION: u32 = 1;
/// A parameter within this share of its search range from a bound is flagged as at it.
pub const BOUND_TOLERANCE: f64 = 1e-2;

/// The model kinds a file may hold.
pub const KINDS: [&str; 5] = ["bouc-wen", "rbf", "structure", "pi", "preisach"];

/// A fitted model, as stored.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    pub format: String,
    pub version: u32,
    /// `bouc-wen`, `rbf`, `structure` or `pi`.
    pub kind: String,
    /// The model's equation in words, for the reader.
    pub model: String,
    /// How it was fitted (command, optimizer, budget, seed, records).
    pub fitted: Fitted,
    /// Units of time, input and output (from the recording).
    pub units: Units,
    /// The recording's column names of time, input and output (`simulate --model` reads
    /// and writes these unless told otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub columns: Option<Units>,
    /// Sampling interval of the (first) training record, s: a discrete-time model's step.
    pub sampling_interval_s: f64,
    /// What the search divided input and output by (1 where it ran on the raw data). The
    /// parameters below are already de-normalised; these are for reading the search bounds.
    pub normalisation: Normalisation,
    /// How the model is stepped (scheme, sub-steps, hold).
    pub integration: Integration,
    /// Where a run starts when no record of the fit is named.
    pub initial_state: String,
    /// The model's parameters in physical units, each with its search value and bounds.
    pub parameters: Vec<Param>,
    /// Each fitted record's own initial state and offset (training and validation).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub records: Vec<RecordState>,
    /// The RBF network in physical units (kind `rbf`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub network: Option<Network>,
    /// The structure model (kind `structure`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub structure: Option<StructureSpec>,
    /// The Prandtl-Ishlinskii model in physical units (kind `pi`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pi: Option<PiModel>,
    /// The Preisach model in physical units (kind `preisach`), checked against its grid
    /// when read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preisach: Option<Preisach>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fitted {
    pub command: String,
    pub optimizer: String,
    pub budget: u64,
    pub evaluations: u64,
    pub seed: u64,
    pub train: Vec<String>,
    pub validate: Vec<String>,
}

/// Time, input and output: units, or column names.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Units {
    pub time: String,
    pub input: String,
    pub output: String,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    pub input_scale: f64,
    pub output_scale: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Integration {
    /// `fast`, `accurate`, `explicit` (Bouc-Wen), `narx` (RBF) or `structure`.
    pub scheme: String,
    /// Sub-steps per sample of the fast Bouc-Wen scheme (validation records' count).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub substeps: Option<usize>,
    /// How the input moves between samples (structure).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hold: Option<String>,
}

/// One parameter: physical value and unit, and where the search left it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Param {
    pub name: String,
    /// Physical value (`"inf"` where a parameter's meaning is "none", e.g. no clipping).
    #[serde(with = "crate::base::json_float::one")]
    pub value: f64,
    pub unit: String,
    /// The searched coordinate, its bounds, and which bound it sits at (if any).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub search: Option<Search>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Search {
    pub value: f64,
    pub lower: f64,
    pub upper: f64,
    /// `lower` or `upper` when within [`BOUND_TOLERANCE`] of the range of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at_bound: Option<String>,
}

impl Search {
    /// `value` searched in `[lower, upper]`, flagged where it sits at a bound.
    pub fn new(value: f64, lower: f64, upper: f64) -> Search {
        let tol = BOUND_TOLERANCE * (upper - lower).abs();
        let at_bound = if value <= lower + tol {
            Some("lower".to_string())
        } else if value >= upper - tol {
            Some("upper".to_string())
        } else {
            None
        };
        Search {
            value,
            lower,
            upper,
            at_bound,
        }
    }
}

impl Param {
    pub fn new(name: impl Into<String>, value: f64, unit: impl Into<String>) -> Param {
        Param {
            name: name.into(),
            value,
            unit: unit.into(),
            search: None,
        }
    }

    /// With the searched coordinate `x` in `[lower, upper]`.
    pub fn searched(mut self, x: f64, lower: f64, upper: f64) -> Param {
        self.search = Some(Search::new(x, lower, upper));
        self
    }
}

/// A fitted record's own state: offset and initial hysteretic state (Bouc-Wen), or shape and
/// linear coefficients with its offset, drift and creep states refitted (structure).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordState {
    /// `train`, `train2`, `validate`, ... (`--record` names it).
    pub label: String,
    pub name: String,
    pub sampling_interval_s: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d0: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub h0: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub substeps: Option<usize>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shape: Vec<Named>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub linear: Vec<Named>,
}

/// A named number.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Named {
    pub name: String,
    pub value: f64,
}

/// An RBF NARX network in the recording's units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Network {
    pub input_lags: usize,
    pub output_lags: usize,
    /// The regressors in order, e.g. `u(k)`, `u(k-1)`, `y(k-1)`.
    pub regressors: Vec<String>,
    /// Per hidden node, per regressor (that regressor's unit).
    pub centres: Vec<Vec<f64>>,
    /// Per hidden node, per regressor (that regressor's unit).
    pub widths: Vec<Vec<f64>>,
    /// Per hidden node (output unit).
    pub weights: Vec<f64>,
}

/// `diagnose`'s structure model: enough to rebuild it exactly.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StructureSpec {
    /// `[effect, form]` pairs.
    pub effects: Vec<[String; 2]>,
    /// The pinned Bouc-Wen exponent, if any.
    pub fixed_n: Option<f64>,
    /// `after-hysteresis` or `feedback`.
    pub placement: String,
    /// The training data's scales that make the shape unit-free.
    pub context: StructureContext,
    /// Shape parameters (training record), by name, unit-free, with their search bounds.
    pub shape: Vec<Param>,
    /// Linear coefficients (training record), by name.
    pub linear: Vec<Named>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StructureContext {
    pub dt: f64,
    pub u_ref: f64,
    pub rate_ref: f64,
    pub t_ref: f64,
    pub hold: String,
    pub min_substeps: usize,
    /// A Prandtl-Ishlinskii or Preisach core (`diagnose --model pi`, `preisach`); absent:
    /// Bouc-Wen.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pi: Option<crate::physics::structure::PiCore>,
}

/// An input to run a model on: samples every `dt`, with the measured output if there is one
/// (an RBF free run starts from its first samples).
pub struct Input<'a> {
    pub u: &'a [f64],
    pub y: Option<&'a [f64]>,
    pub dt: f64,
}

fn bad(path: &Path, field: &str, what: impl std::fmt::Display) -> Error {
    Error::Input(format!("{}: {field}: {what}", path.display()))
}

fn finite(path: &Path, field: &str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(bad(path, field, format!("{v} is not a finite number")))
    }
}

/// `v` finite and above zero (an interval, a scale).
fn positive(path: &Path, field: &str, v: f64) -> Result<f64> {
    if finite(path, field, v)? <= 0.0 {
        return Err(bad(path, field, format!("{v}: must be > 0")));
    }
    Ok(v)
}

impl ModelFile {
    /// A new file of `kind` with the fields every kind has.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        kind: &str,
        model: &str,
        units: Units,
        dt: f64,
        normalisation: Normalisation,
        integration: Integration,
        initial_state: &str,
        parameters: Vec<Param>,
    ) -> ModelFile {
        ModelFile {
            format: FORMAT.into(),
            version: VERSION,
            kind: kind.into(),
            model: model.into(),
            fitted: Fitted {
                command: String::new(),
                optimizer: String::new(),
                budget: 0,
                evaluations: 0,
                seed: 0,
                train: Vec::new(),
                validate: Vec::new(),
            },
            units,
            columns: None,
            sampling_interval_s: dt,
            normalisation,
            integration,
            initial_state: initial_state.into(),
            parameters,
            records: Vec::new(),
            network: None,
            structure: None,
            pi: None,
            preisach: None,
        }
    }

    /// The parameters that ended at a search bound: `(name, "lower" | "upper")`.
    pub fn at_bounds(&self) -> Vec<(&str, &str)> {
        let shape = self.structure.iter().flat_map(|s| &s.shape);
        self.parameters
            .iter()
            .chain(shape)
            .filter_map(|p| {
                let b = p.search.as_ref()?.at_bound.as_deref()?;
                Some((p.name.as_str(), b))
            })
            .collect()
    }

    /// The first sample the model predicts: an RBF network's earlier samples are its
    /// initial conditions (the measured outputs), left out of errors as the fit does.
    pub fn first_predicted(&self) -> usize {
        self.network.as_ref().map_or(0, |n| {
            Narx {
                input_lags: n.input_lags,
                output_lags: n.output_lags,
            }
            .start()
        })
    }

    /// RMS of `measured - predicted` from [`Self::first_predicted`] on.
    pub fn rmse(&self, measured: &[f64], predicted: &[f64]) -> f64 {
        super::rbf::fit_errors(measured, predicted, self.first_predicted()).rms
    }

    /// Writes the file (atomically); refuses a model that would not read back (a
    /// non-finite value where a run needs a number).
    pub fn write(&self, path: &Path) -> Result<()> {
        self.check(path)?;
        let mut json = serde_json::to_vec_pretty(self).expect("serialisable");
        json.push(b'\n');
        atomic_write(path, &json)
    }

    /// The column names of time, input and output the model was fitted on, if known.
    pub fn column_names(&self) -> Option<[&str; 3]> {
        self.columns
            .as_ref()
            .map(|c| [c.time.as_str(), c.input.as_str(), c.output.as_str()])
    }

    /// Reads and checks `path`.
    pub fn read(path: &Path) -> Result<ModelFile> {
        // A path the user typed: a missing or unreadable file is their input (exit 2).
        let text = std::fs::read_to_string(path).map_err(|e| {
            Error::Input(format!(
                "--model {}: cannot read ({e}); expected the model.json of an `optbench fit` or `diagnose` folder",
                path.display()
            ))
        })?;
        let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            bad(
                path,
                "JSON",
                format!("{e}; expected a model.json written by `optbench fit` or `diagnose`"),
            )
        })?;
        let format = value.get("format").and_then(|v| v.as_str());
        if format != Some(FORMAT) {
            return Err(bad(
                path,
                "format",
                format!(
                    "{}; expected \"{FORMAT}\" (a model.json written by `optbench fit` or `diagnose`)",
                    format.map_or("missing".to_string(), |f| format!("\"{f}\""))
                ),
            ));
        }
        match value.get("version").and_then(|v| v.as_u64()) {
            Some(v) if v == VERSION as u64 => {}
            v => {
                return Err(bad(
                    path,
                    "version",
                    format!(
                        "{}; this optbench reads version {VERSION}: refit with this version, or run the optbench that wrote it",
                        v.map_or("missing".to_string(), |v| v.to_string())
                    ),
                ));
            }
        }
        let kind = value.get("kind").and_then(|v| v.as_str()).unwrap_or("");
        if !KINDS.contains(&kind) {
            return Err(bad(
                path,
                "kind",
                format!(
                    "\"{kind}\" is not a model kind; valid: {}",
                    KINDS.join(", ")
                ),
            ));
        }
        let m: ModelFile = serde_json::from_value(value).map_err(|e| bad(path, "field", e))?;
        m.check(path)?;
        Ok(m)
    }

    /// Checks that the model can run: every value it needs is present and finite.
    fn check(&self, path: &Path) -> Result<()> {
        positive(path, "sampling_interval_s", self.sampling_interval_s)?;
        for r in &self.records {
            let f = |n: &str| format!("records[{}].{n}", r.label);
            for (n, v) in [("d0", r.d0), ("h0", r.h0)] {
                if let Some(v) = v {
                    finite(path, &f(n), v)?;
                }
            }
            for x in r.shape.iter().chain(&r.linear) {
                finite(path, &f(&x.name), x.value)?;
            }
        }
        match self.kind.as_str() {
            "bouc-wen" => {
                self.bouc_wen(path, None)?;
                for r in &self.records {
                    self.bouc_wen(path, Some(&r.label))?;
                }
            }
            "rbf" => {
                self.network_checked(path)?;
            }
            "pi" => {
                self.pi_checked(path)?;
            }
            "preisach" => {
                self.preisach_checked(path)?;
            }
            "structure" => {
                self.structure_checked(path, None)?;
                for r in &self.records {
                    self.structure_checked(path, Some(&r.label))?;
                }
            }
            k => {
                return Err(bad(
                    path,
                    "kind",
                    format!("\"{k}\" is not a model kind; valid: {}", KINDS.join(", ")),
                ));
            }
        }
        Ok(())
    }

    fn param(&self, path: &Path, name: &str) -> Result<f64> {
        let p = self
            .parameters
            .iter()
            .find(|p| p.name == name)
            .ok_or_else(|| bad(path, &format!("parameters.{name}"), "missing"))?;
        finite(path, &format!("parameters.{name}"), p.value)
    }

    fn record(&self, path: &Path, label: &str) -> Result<&RecordState> {
        self.records
            .iter()
            .find(|r| r.label == label)
            .ok_or_else(|| {
                let have: Vec<&str> = self.records.iter().map(|r| r.label.as_str()).collect();
                bad(
                    path,
                    "records",
                    format!(
                        "no record `{label}`; this model has {}",
                        if have.is_empty() {
                            "none".to_string()
                        } else {
                            have.join(", ")
                        }
                    ),
                )
            })
    }

    /// The Bouc-Wen parameters, initial state and sub-steps (a record's own, if named).
    fn bouc_wen(&self, path: &Path, record: Option<&str>) -> Result<(BoucWenParams, f64, usize)> {
        let d0 = match self.parameters.iter().any(|p| p.name == "d0") {
            true => self.param(path, "d0")?,
            false => 0.0,
        };
        let mut p = BoucWenParams {
            d_e: self.param(path, "d_e")?,
            alpha: self.param(path, "alpha")?,
            beta: self.param(path, "beta")?,
            gamma: self.param(path, "gamma")?,
            n: self.param(path, "n")?,
            d0,
        };
        let mut h0 = 0.0;
        let mut substeps = self.integration.substeps.unwrap_or(0);
        if let Some(label) = record {
            let r = self.record(path, label)?;
            p.d0 = r.d0.unwrap_or(p.d0);
            h0 = r.h0.unwrap_or(0.0);
            substeps = r.substeps.unwrap_or(substeps);
        }
        match self.integration.scheme.as_str() {
            "fast" if substeps == 0 => Err(bad(
                path,
                "integration.substeps",
                "missing (the fast scheme needs its sub-steps per sample, 1 to 64)",
            )),
            "fast" | "accurate" | "explicit" => Ok((p, h0, substeps)),
            s => Err(bad(
                path,
                "integration.scheme",
                format!("\"{s}\"; valid for bouc-wen: fast, accurate, explicit"),
            )),
        }
    }

    /// The PI model, checked: thresholds valid, one weight per threshold, rate weights and
    /// polynomial as its form has them, every number finite.
    /// The Preisach model of a `preisach` file (its grid and weights were checked against
    /// each other when the file was read).
    fn preisach_checked(&self, path: &Path) -> Result<&Preisach> {
        self.preisach.as_ref().ok_or_else(|| {
            bad(
                path,
                "preisach",
                "missing (a preisach model needs its grid and weights)",
            )
        })
    }

    fn pi_checked(&self, path: &Path) -> Result<&PiModel> {
        let m = self
            .pi
            .as_ref()
            .ok_or_else(|| bad(path, "pi", "missing (a pi model needs its operators)"))?;
        check_thresholds(&m.thresholds).map_err(|e| bad(path, "pi.thresholds", e))?;
        let n = m.thresholds.len();
        let (rates, poly) = match m.form {
            PiForm::Plain => (0, 0),
            PiForm::Asymmetric => (0, 2),
            PiForm::RateDependent => (n, 0),
        };
        for (field, got, want) in [
            ("weights", m.weights.len(), n),
            ("rate_weights", m.rate_weights.len(), rates),
            ("poly", m.poly.len(), poly),
        ] {
            if got != want {
                return Err(bad(
                    path,
                    &format!("pi.{field}"),
                    format!(
                        "{got} values; expected {want} for the {} form with {n} thresholds",
                        m.form.name()
                    ),
                ));
            }
        }
        let values = m.weights.iter().chain(&m.rate_weights).chain(&m.poly);
        for (i, v) in values.enumerate() {
            finite(path, &format!("pi coefficient {i}"), *v)?;
        }
        finite(path, "pi.offset", m.offset)?;
        finite(path, "pi.input_offset", m.input_offset)?;
        Ok(m)
    }

    fn network_checked(&self, path: &Path) -> Result<&Network> {
        let net = self
            .network
            .as_ref()
            .ok_or_else(|| bad(path, "network", "missing (an rbf model needs its network)"))?;
        let inputs = net.input_lags + net.output_lags;
        if net.input_lags == 0 || net.regressors.len() != inputs {
            return Err(bad(
                path,
                "network",
                format!(
                    "{} input lags, {} output lags and {} regressors; expected at least one input lag and one regressor per lag",
                    net.input_lags,
                    net.output_lags,
                    net.regressors.len()
                ),
            ));
        }
        let h = net.weights.len();
        if h == 0 || net.centres.len() != h || net.widths.len() != h {
            return Err(bad(
                path,
                "network",
                format!(
                    "{} weights, {} centre rows, {} width rows; expected one of each per hidden node",
                    h,
                    net.centres.len(),
                    net.widths.len()
                ),
            ));
        }
        for (j, (c, b)) in net.centres.iter().zip(&net.widths).enumerate() {
            if c.len() != inputs || b.len() != inputs {
                return Err(bad(
                    path,
                    &format!("network node {}", j + 1),
                    format!(
                        "{} centres and {} widths; expected {inputs} (one per regressor)",
                        c.len(),
                        b.len()
                    ),
                ));
            }
            for (i, (&ci, &bi)) in c.iter().zip(b).enumerate() {
                finite(path, &format!("network.centres[{j}][{i}]"), ci)?;
                finite(path, &format!("network.widths[{j}][{i}]"), bi)?;
                if bi == 0.0 {
                    return Err(bad(path, &format!("network.widths[{j}][{i}]"), "is zero"));
                }
            }
            finite(path, &format!("network.weights[{j}]"), net.weights[j])?;
        }
        Ok(net)
    }

    /// The structure at its training interval with shape and linear coefficients (a
    /// record's own, if named).
    fn structure_checked(
        &self,
        path: &Path,
        record: Option<&str>,
    ) -> Result<(Structure, Vec<f64>, Vec<f64>)> {
        let s = self.structure.as_ref().ok_or_else(|| {
            bad(
                path,
                "structure",
                "missing (a structure model needs its effects, context, shape and coefficients)",
            )
        })?;
        let mut parts = Vec::new();
        for [e, f] in &s.effects {
            let effect = Effect::parse(e).ok_or_else(|| {
                bad(
                    path,
                    "structure.effects",
                    format!(
                        "unknown effect `{e}`; valid: {}",
                        Effect::ALL.map(Effect::name).join(", ")
                    ),
                )
            })?;
            let form = effect
                .forms()
                .iter()
                .copied()
                .find(|x| x.name() == f)
                .ok_or_else(|| {
                    bad(
                        path,
                        "structure.effects",
                        format!(
                            "`{f}` is not a form of {e}; valid: {}",
                            effect
                                .forms()
                                .iter()
                                .map(|x| x.name())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    )
                })?;
            parts.push((effect, form));
        }
        let placement = [Placement::After, Placement::Feedback]
            .into_iter()
            .find(|p| p.name() == s.placement)
            .ok_or_else(|| {
                bad(
                    path,
                    "structure.placement",
                    format!("\"{}\"; valid: after-hysteresis, feedback", s.placement),
                )
            })?;
        let c = &s.context;
        let hold = Hold::parse(&c.hold).ok_or_else(|| {
            bad(
                path,
                "structure.context.hold",
                format!("\"{}\"; valid: zoh, linear, bandlimited", c.hold),
            )
        })?;
        for (n, v) in [
            ("dt", c.dt),
            ("u_ref", c.u_ref),
            ("rate_ref", c.rate_ref),
            ("t_ref", c.t_ref),
        ] {
            positive(path, &format!("structure.context.{n}"), v)?;
        }
        if !(1..=64).contains(&c.min_substeps) {
            return Err(bad(
                path,
                "structure.context.min_substeps",
                format!("{}: expected 1 to 64", c.min_substeps),
            ));
        }
        if let Some(n) = s.fixed_n {
            finite(path, "structure.fixed_n", n)?;
        }
        let ctx = Context {
            dt: c.dt,
            u_ref: c.u_ref,
            rate_ref: c.rate_ref,
            t_ref: c.t_ref,
            hold,
            min_substeps: c.min_substeps,
            pi: c.pi,
        };
        let mut st = Structure::with_forms(&parts, s.fixed_n, ctx, placement);
        let pairs = |v: &[Named]| -> Vec<(String, f64)> {
            v.iter().map(|x| (x.name.clone(), x.value)).collect()
        };
        let (shape, linear, field) = match record {
            Some(label) => {
                let r = self.record(path, label)?;
                let f = format!("records[{label}].sampling_interval_s");
                positive(path, &f, r.sampling_interval_s)?;
                // The record's state is that of the model at its own interval.
                if !structure::same_interval(r.sampling_interval_s, c.dt) {
                    st = st.at_interval(r.sampling_interval_s);
                }
                (
                    pairs(&r.shape),
                    pairs(&r.linear),
                    format!("records[{label}]"),
                )
            }
            None => (
                s.shape.iter().map(|x| (x.name.clone(), x.value)).collect(),
                pairs(&s.linear),
                "structure".to_string(),
            ),
        };
        let by_name =
            |list: &[(String, f64)], names: Vec<String>, what: &str| -> Result<Vec<f64>> {
                names
                    .iter()
                    .map(|n| {
                        let f = format!("{field}.{what}.{n}");
                        let v = list
                            .iter()
                            .find(|x| &x.0 == n)
                            .ok_or_else(|| bad(path, &f, "missing"))?;
                        finite(path, &f, v.1)
                    })
                    .collect()
            };
        let theta = by_name(
            &shape,
            st.specs().iter().map(|s| s.name.to_string()).collect(),
            "shape",
        )?;
        let coef = by_name(&linear, st.linear_names(), "linear")?;
        Ok((st, theta, coef))
    }

    /// The model's output on `input` (physical units), from the model's initial-state
    /// convention or from fitted record `record`'s own state.
    pub fn run(&self, path: &Path, input: &Input, record: Option<&str>) -> Result<Vec<f64>> {
        let u = input.u;
        let mut out = vec![0.0; u.len()];
        match self.kind.as_str() {
            "bouc-wen" => {
                let (p, h0, substeps) = self.bouc_wen(path, record)?;
                let status = match self.integration.scheme.as_str() {
                    "accurate" => bouc_wen::simulate_from(&p, h0, u, &mut out),
                    "explicit" => bouc_wen_fast::simulate_explicit_from(&p, h0, u, &mut out),
                    _ => bouc_wen_fast::simulate_from(&p, h0, u, substeps, &mut out),
                };
                if let SimStatus::Unstable { at } = status {
                    return Err(Error::Input(format!(
                        "{}: the model is unstable on this input from sample {at} on",
                        path.display()
                    )));
                }
            }
            "rbf" => {
                if record.is_some() {
                    return Err(bad(
                        path,
                        "records",
                        "an rbf model has no per-record state (leave out --record)",
                    ));
                }
                let net = self.network_checked(path)?;
                if !structure::same_interval(input.dt, self.sampling_interval_s) {
                    return Err(Error::Input(format!(
                        "{}: the input is sampled every {} s, the model every {} s: an RBF NARX model is discrete-time (its lags are samples); resample the input",
                        path.display(),
                        input.dt,
                        self.sampling_interval_s
                    )));
                }
                network_free_run(net, u, input.y, &mut out);
            }
            "pi" => {
                if record.is_some() {
                    return Err(bad(
                        path,
                        "records",
                        "a pi model has no per-record state (leave out --record)",
                    ));
                }
                out = self.pi_checked(path)?.simulate(u, input.dt);
            }
            "preisach" => {
                if record.is_some() {
                    return Err(bad(
                        path,
                        "records",
                        "a preisach model has no per-record state (leave out --record)",
                    ));
                }
                out = self.preisach_checked(path)?.simulate(u, input.dt);
            }
            _ => {
                let (st, theta, coef) = self.structure_checked(path, record)?;
                let (st, theta) = if structure::same_interval(input.dt, st.context().dt) {
                    (st, theta)
                } else {
                    let to = st.at_interval(input.dt);
                    let theta = st.carry(&theta, &to);
                    (to, theta)
                };
                let coef = &coef[..st.linear_names().len().min(coef.len())];
                let (y, status) = st.simulate(&theta, coef, u);
                if let structure::Status::Unstable { at } = status {
                    return Err(Error::Input(format!(
                        "{}: the model is unstable on this input from sample {at} on",
                        path.display()
                    )));
                }
                out = y;
            }
        }
        if let Some(k) = out.iter().position(|v| !v.is_finite()) {
            return Err(Error::Input(format!(
                "{}: the model's output is not finite from sample {k} on (it diverges on this input)",
                path.display()
            )));
        }
        Ok(out)
    }
}

/// Free run of `net` on input `u`: the first [`Narx::start`] outputs are the measured ones
/// (`y`) or 0 without a measurement, as the fit's.
fn network_free_run(net: &Network, u: &[f64], y: Option<&[f64]>, out: &mut [f64]) {
    let narx = Narx {
        input_lags: net.input_lags,
        output_lags: net.output_lags,
    };
    let s = narx.start().min(u.len());
    if let Some(y) = y {
        out[..s].copy_from_slice(&y[..s]);
    }
    let mut x = vec![0.0; narx.dim()];
    for k in s..u.len() {
        narx.regressor(u, out, k, &mut x);
        let mut v = 0.0;
        for ((c, b), w) in net.centres.iter().zip(&net.widths).zip(&net.weights) {
            let d2: f64 = x
                .iter()
                .zip(c)
                .zip(b)
                .map(|((xi, ci), bi)| {
                    let z = (xi - ci) / bi;
                    z * z
                })
                .sum();
            v += w * (-0.5 * d2).exp();
        }
        out[k] = v;
    }
}

/// Writes the predicted output beside the measured one as CSV: time, input, measured output
/// (if any), `predicted_<output>` and `residual_<output>` (measured minus predicted), under
/// the recording's column names, every number in shortest round-trip form.
pub fn write_prediction(
    path: &Path,
    names: [&str; 3],
    t: &[f64],
    u: &[f64],
    y: Option<&[f64]>,
    predicted: &[f64],
) -> Result<()> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let fail = |e: csv::Error| Error::Input(format!("writing {}: {e}", path.display()));
    let (pred, res) = (
        format!("predicted_{}", names[2]),
        format!("residual_{}", names[2]),
    );
    let header: Vec<&str> = match y {
        Some(_) => vec![names[0], names[1], names[2], &pred, &res],
        None => vec![names[0], names[1], &pred],
    };
    w.write_record(header).map_err(fail)?;
    for k in 0..predicted.len() {
        let mut row = vec![t[k].to_string(), u[k].to_string()];
        if let Some(y) = y {
            row.push(y[k].to_string());
            row.push(predicted[k].to_string());
            row.push((y[k] - predicted[k]).to_string());
        } else {
            row.push(predicted[k].to_string());
        }
        w.write_record(row).map_err(fail)?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| Error::Input(format!("writing {}: {e}", path.display())))?;
    atomic_write(path, &bytes)
}

#[cfg(test)]
mod tests;
