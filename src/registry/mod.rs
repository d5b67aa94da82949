//! The objective and optimizer kinds a suite may name, with their parameter tables.

use crate::base::error::Error;
use crate::base::limits::{self, MAX_DIM, MAX_MAGNITUDE, MAX_POPULATION, MAX_SAMPLES};
use crate::base::params::{Default as D, Kind, Origin, Params, Spec, probability};
use crate::data::recording::{Delimiter, ReadOptions, Recording};
use crate::harness::OptimizerConfig;
use crate::objective::bbob::instance::MAX_BBOB_DIM;
use crate::objective::bbob::{Bbob, MAX_BBOB_INSTANCE};
use crate::objective::functions::{Function, Instance, MAX_ROTATED_DIM, TestFunction};
use crate::objective::hysteresis::{BoucWenFit, BoucWenScheme, RbfFit};
use crate::objective::operator::{OperatorFit, OperatorSearch};
use crate::objective::source::{SimOptions, Source};
use crate::objective::{Bounds, Objective};
use crate::optimizer::ga::GaConfig;
use crate::optimizer::gradient::GradientConfig;
use crate::optimizer::msga::MsgaConfig;
use crate::optimizer::nelder_mead::NelderMeadConfig;
use crate::optimizer::operators::Mutation;
use crate::optimizer::pso::PsoConfig;
use crate::optimizer::random_search::RandomSearchConfig;
use crate::physics::prandtl_ishlinskii::PiForm;
use crate::physics::rbf::{Mode, Narx, RbfNet};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

mod baselines;

/// An objective family a suite can name.
pub struct ObjectiveKind {
    pub name: &'static str,
    pub help: &'static str,
    pub params: &'static [Spec],
    pub build: fn(&Params) -> Result<Arc<dyn Objective>, Error>,
}

/// An optimizer a suite can name.
pub struct OptimizerKind {
    pub name: &'static str,
    pub help: &'static str,
    pub params: &'static [Spec],
    pub build: fn(&Params) -> Result<Arc<dyn OptimizerConfig>, Error>,
}

/// A size of at most `max` (limits in [`crate::base::limits`]).
const fn size(min: i64, max: usize) -> Kind {
    Kind::Int {
        min,
        max: max as i64,
    }
}

/// A bound or level: finite, of at most [`MAX_MAGNITUDE`] (so costs stay finite).
const MAGNITUDE: Kind = Kind::Float {
    min: -MAX_MAGNITUDE,
    max: MAX_MAGNITUDE,
};

const FUNCTION_PARAMS: &[Spec] = &[
    Spec {
        name: "dim",
        kind: size(1, MAX_DIM),
        default: D::Required,
        help: "number of variables",
    },
    Spec {
        name: "lower",
        kind: MAGNITUDE,
        default: D::Derived("the function's customary domain"),
        help: "lower bound of every variable",
    },
    Spec {
        name: "upper",
        kind: MAGNITUDE,
        default: D::Derived("the function's customary domain"),
        help: "upper bound of every variable",
    },
    Spec {
        name: "shift",
        kind: Kind::Choice(&["none", "random"]),
        default: D::Str("none"),
        help: "random: the minimiser moves to a point drawn for the instance in the central 80 % of the box (Schwefel's formula is wrapped into [-500, 500], so its minimum stays -418.98 d)",
    },
    Spec {
        name: "rotate",
        kind: Kind::Bool,
        default: D::Bool(false),
        help: "true: the function is rotated about its minimiser by a random orthogonal matrix drawn for the instance (dim <= 500)",
    },
    Spec {
        name: "instance",
        kind: Kind::Int {
            min: 1,
            max: i64::MAX,
        },
        default: D::Int(1),
        help: "which shift and rotation: drawn from (function, dim, instance) only, so instance N is the same problem in every suite with the same box",
    },
];

fn build_function(kind: TestFunction, p: &Params) -> Result<Arc<dyn Objective>, Error> {
    let (lo, hi) = kind.default_domain();
    let lower = p.opt_float("lower").unwrap_or(lo);
    let upper = p.opt_float("upper").unwrap_or(hi);
    let bounds = Bounds::uniform(p.usize("dim"), lower, upper).map_err(|e| p.error("lower", e))?;
    let inst = Instance {
        number: p.int("instance") as u64,
        shift: p.str("shift") == "random",
        rotate: p.bool("rotate"),
    };
    let f = Function::new(kind, bounds).map_err(|e| p.error("dim", e))?;
    let key = if inst.rotate && f.dim() > MAX_ROTATED_DIM {
        "rotate"
    } else {
        "instance"
    };
    Ok(Arc::new(
        f.with_instance(inst).map_err(|e| p.error(key, e))?,
    ))
}

macro_rules! function_kind {
    ($kind:expr, $help:expr) => {
        ObjectiveKind {
            name: $kind.name(),
            help: $help,
            params: FUNCTION_PARAMS,
            build: |p| build_function($kind, p),
        }
    };
}

const BBOB_PARAMS: &[Spec] = &[
    Spec {
        name: "function",
        kind: Kind::Int { min: 1, max: 24 },
        default: D::Required,
        help: "COCO's function number: 1-5 separable, 6-9 moderate, 10-14 ill-conditioned, 15-19 multi-modal, 20-24 weakly structured multi-modal",
    },
    Spec {
        name: "dim",
        kind: size(2, MAX_BBOB_DIM),
        default: D::Required,
        help: "number of variables (COCO's suite uses 2, 3, 5, 10, 20, 40)",
    },
    Spec {
        name: "instance",
        kind: size(1, MAX_BBOB_INSTANCE),
        default: D::Int(1),
        help: "COCO's instance number: it fixes the optimum's location and value and the rotations",
    },
];

fn build_bbob(p: &Params) -> Result<Arc<dyn Objective>, Error> {
    let f = Bbob::new(p.usize("function"), p.usize("dim"), p.usize("instance"))
        .map_err(|e| p.error("function", e))?;
    Ok(Arc::new(f))
}

/// Parameters shared by every fitting objective: where the data come from.
macro_rules! recording_params {
    ($($extra:expr),* $(,)?) => {
        &[
            Spec {
                name: "recording",
                kind: Kind::Text,
                default: D::Required,
                help: "CSV path ($OPTBENCH_DATA/..., or relative to the suite), twin:SIGNAL or eq318:SIGNAL; several separated by \" | \" are fitted together (parameters shared, costs summed)",
            },
            Spec {
                name: "validate",
                kind: Kind::Text,
                default: D::Derived("none"),
                help: "held-out recordings, same forms, separated by \" | \" (metrics only; the model is never fitted to them)",
            },
            Spec {
                name: "first",
                kind: size(0, MAX_SAMPLES),
                default: D::Int(0),
                help: "first training sample used",
            },
            Spec {
                name: "samples",
                kind: size(8, MAX_SAMPLES),
                default: D::Derived("all from `first` on"),
                help: "number of training samples used",
            },
            Spec {
                name: "columns",
                kind: Kind::Text,
                default: D::Str("t,u,y"),
                help: "time, input and output column names of CSV recordings",
            },
            Spec {
                name: "resample",
                kind: Kind::Bool,
                default: D::Derived("false"),
                help: "CSV recordings with gaps or irregular time stamps are linearly interpolated onto a uniform grid (jitter within 1 % of the step needs no resampling)",
            },
            Spec {
                name: "delimiter",
                kind: Kind::Text,
                default: D::Derived("detected"),
                help: "column separator of CSV recordings: \",\", \";\", tab or whitespace",
            },
            Spec {
                name: "trim_start",
                kind: Kind::Float { min: 0.0, max: f64::INFINITY },
                default: D::Derived("0"),
                help: "seconds left out at the start of every recording (training and validation), for records that start in motion; before first/samples",
            },
            Spec {
                name: "duration",
                kind: Kind::Float { min: f64::MIN_POSITIVE, max: f64::INFINITY },
                default: D::Derived("a chirp's own duration"),
                help: "seconds of simulated recording",
            },
            Spec {
                name: "validate_duration",
                kind: Kind::Float { min: f64::MIN_POSITIVE, max: f64::INFINITY },
                default: D::Derived("a chirp's own duration"),
                help: "seconds of simulated validation recording",
            },
            Spec {
                name: "dt",
                kind: Kind::Float { min: f64::MIN_POSITIVE, max: 1.0 },
                default: D::Float(1e-3),
                help: "sampling interval of simulated recordings [s]",
            },
            Spec {
                name: "twin",
                kind: Kind::Text,
                default: D::Str(""),
                help: "piezo-twin overrides, e.g. \"mode=off,creep=on\"",
            },
            Spec {
                name: "seed",
                kind: Kind::Int { min: 0, max: i64::MAX },
                default: D::Int(1),
                help: "noise seed of simulated recordings",
            },
            $($extra),*
        ]
    };
}

/// The parameters of fitting objectives that name recordings (`A | B`), whose file paths
/// a suite anchors to its own folder (see [`anchor_recordings`]).
pub const RECORDING_KEYS: [&str; 2] = ["recording", "validate"];

/// A `recording` or `validate` value with its relative file paths made absolute against
/// `base`; None when no spec changes.
pub fn anchor_recordings(value: &str, base: &Path) -> Option<String> {
    let mut changed = false;
    let specs: Vec<String> = value
        .split(" | ")
        .map(
            |s| match crate::objective::source::anchored(s.trim(), base) {
                Some(a) => {
                    changed = true;
                    a
                }
                None => s.to_string(),
            },
        )
        .collect();
    changed.then(|| specs.join(" | "))
}

/// The training recordings (`recording = "A | B"`; one may be sliced by `first`/`samples`)
/// and the labelled validation recordings (`validate = "A | B"`) named by a fitting
/// objective.
fn recordings(p: &Params) -> Result<(Vec<Recording>, Labelled), Error> {
    let base = p.file().parent().unwrap_or(Path::new(".")).to_path_buf();
    let sim = |duration: Option<f64>| SimOptions {
        duration,
        dt: p.float("dt"),
        twin: p.str("twin").to_string(),
        seed: p.int("seed") as u64,
    };
    let read = ReadOptions {
        resample: p.opt_bool("resample").unwrap_or(false),
        delimiter: match p.opt_str("delimiter") {
            Some(d) => Delimiter::parse(d).map_err(|e| p.error("delimiter", e))?,
            None => Delimiter::Auto,
        },
    };
    let trim = p.opt_float("trim_start").unwrap_or(0.0);
    for key in ["duration", "validate_duration"] {
        if let Some(d) = p.opt_float(key) {
            limits::samples(d, p.float("dt")).map_err(|e| p.error(key, e))?;
        }
    }
    let load = |key: &str, spec: &str, duration: Option<f64>| -> Result<Recording, Error> {
        Source::parse(spec, &base, p.str("columns"), sim(duration))
            .and_then(|s| s.read_with(read).load())
            .and_then(|r| r.trim_start(trim))
            .map_err(|e| p.error(key, e))
    };
    let specs: Vec<&str> = p.str("recording").split(" | ").map(str::trim).collect();
    if specs.len() > 1 {
        if p.opt_int("samples").is_some() || p.usize("first") > 0 {
            return Err(p.error(
                "first",
                "first/samples slice one training recording; with several, trim the files or use trim_start",
            ));
        }
        let train = specs
            .iter()
            .map(|s| load("recording", s, p.opt_float("duration")))
            .collect::<Result<Vec<_>, _>>()?;
        return Ok((train, validation(p, &load)?));
    }
    let mut train = load("recording", specs[0], p.opt_float("duration"))?;
    let first = p.usize("first");
    let end = match p.opt_int("samples") {
        Some(n) => first.saturating_add(n as usize),
        None => train.len(),
    };
    if first >= train.len() {
        return Err(p.error(
            "first",
            format!(
                "first sample {first} requested but the recording has {}",
                train.len()
            ),
        ));
    }
    if first > 0 || end < train.len() {
        if end > train.len() {
            return Err(p.error(
                "samples",
                format!(
                    "samples {first}..{end} requested but the recording has {}",
                    train.len()
                ),
            ));
        }
        train = train.slice(first..end).map_err(|e| p.error("samples", e))?;
    }
    Ok((vec![train], validation(p, &load)?))
}

/// Recordings with their labels.
type Labelled = Vec<(String, Recording)>;

/// Loads a recording for a key from a spec, with a duration for simulated ones.
type Loader<'a> = dyn Fn(&str, &str, Option<f64>) -> Result<Recording, Error> + 'a;

/// The labelled validation recordings of [`recordings`].
fn validation(p: &Params, load: &Loader) -> Result<Labelled, Error> {
    let mut validate = Vec::new();
    if let Some(specs) = p.opt_str("validate") {
        let specs: Vec<&str> = specs.split(" | ").map(str::trim).collect();
        for (i, spec) in specs.iter().enumerate() {
            let label = if specs.len() == 1 {
                "validate".to_string()
            } else if spec.contains(':') && !spec.starts_with('$') && !spec.contains('/') {
                format!("validate{}", i + 1)
            } else {
                Path::new(spec)
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| format!("validate{}", i + 1))
            };
            validate.push((
                label,
                load("validate", spec, p.opt_float("validate_duration"))?,
            ));
        }
    }
    Ok(validate)
}

const RBF_PARAMS: &[Spec] = recording_params![
    Spec {
        name: "hidden",
        kind: size(1, MAX_DIM),
        default: D::Int(7),
        help: "hidden Gaussian nodes (seed: 7; also tried 9)",
    },
    Spec {
        name: "input_lags",
        kind: size(1, MAX_DIM),
        default: D::Int(2),
        help: "regressors r(k)..r(k-input_lags+1) (seed: 2; its 7-input variant: 4)",
    },
    Spec {
        name: "output_lags",
        kind: size(0, MAX_DIM),
        default: D::Int(1),
        help: "regressors y(k-1)..y(k-output_lags) (seed: 1; its 7-input variant: 3)",
    },
    Spec {
        name: "mode",
        kind: Kind::Choice(&["one-step", "free-run"]),
        default: D::Str("one-step"),
        help: "cost on one-step-ahead predictions (measured past outputs, as the seed) or on a free-run simulation",
    },
];

fn build_rbf(p: &Params) -> Result<Arc<dyn Objective>, Error> {
    let narx = Narx {
        input_lags: p.usize("input_lags"),
        output_lags: p.usize("output_lags"),
    };
    let net = RbfNet::new(narx.dim(), p.usize("hidden"));
    if net.n_params() > MAX_DIM {
        return Err(p.error(
            "hidden",
            format!(
                "{} hidden x ({} regressors + 2) = {} parameters, above the limit of {MAX_DIM} variables",
                net.hidden,
                narx.dim(),
                net.n_params()
            ),
        ));
    }
    let (train, validate) = recordings(p)?;
    // The regressor matrix of a record: samples x regressors values.
    let most = train.iter().chain(validate.iter().map(|(_, r)| r));
    if let Some(r) = most.max_by_key(|r| r.len())
        && (r.len() as u64).saturating_mul(narx.dim() as u64) > limits::BUDGET_F64
    {
        return Err(p.error(
            "input_lags",
            format!(
                "{} samples x {} regressors is above the limit of {} regressor values (a memory budget of {} B)",
                r.len(),
                narx.dim(),
                limits::BUDGET_F64,
                limits::BUDGET_BYTES
            ),
        ));
    }
    let mode = match p.str("mode") {
        "free-run" => Mode::FreeRun,
        _ => Mode::OneStepAhead,
    };
    let fit = RbfFit::new(&train, &validate, net, narx, mode).map_err(|e| p.entry_error(e))?;
    Ok(Arc::new(fit))
}

const BOUC_WEN_PARAMS: &[Spec] = recording_params![
    Spec {
        name: "d0",
        kind: Kind::Bool,
        default: D::Bool(false),
        help: "also fit the offset d0 (the seed fitted d_e, alpha, beta, gamma, n)",
    },
    Spec {
        name: "h0",
        kind: Kind::Bool,
        default: D::Bool(true),
        help: "with several training records, fit each one's initial hysteretic state (h0, h0@2, ...: a fraction in [-1, 1] of the saturation level (alpha/(beta+gamma))^(1/n)); false: every record from rest. One record always starts from rest",
    },
    Spec {
        name: "refit_validation",
        kind: Kind::Choice(&["auto", "always", "never"]),
        default: D::Str("auto"),
        help: "refit each validation record's own offset (with d0) and initial state on it, the actuator's parameters held fixed: auto = with more than one training or validation record; never = the dissertation's protocol (from rest with the first training record's d0), as a benchmark's official free-run test",
    },
    Spec {
        name: "normalize",
        kind: Kind::Bool,
        default: D::Bool(true),
        help: "fit on input and output divided by their largest |value| (false: the recording's units, as the dissertation's bounds suggest for V and mm)",
    },
    Spec {
        name: "lower",
        kind: MAGNITUDE,
        default: D::Float(0.0),
        help: "lower bound of every (normalised) parameter (seed: 0)",
    },
    Spec {
        name: "upper",
        kind: MAGNITUDE,
        default: D::Float(1.5),
        help: "upper bound of every (normalised) parameter (seed: 1.5)",
    },
    Spec {
        name: "scheme",
        kind: Kind::Choice(&["fast", "accurate", "explicit"]),
        default: D::Str("fast"),
        help: "integration: fast = fixed-cost exponential steps batched over the population (errors far below a fit's residual); accurate = the twin's adaptive kernel, one individual at a time; explicit = the seed-style one-step Euler recurrence, batched (fastest, first order)",
    },
    Spec {
        name: "substeps",
        kind: Kind::Int { min: 0, max: 64 },
        default: D::Int(0),
        help: "fast scheme's sub-steps per sample (0: ceil(24 max|du|/range(u)), 1 to 8)",
    },
];

fn build_bouc_wen(p: &Params) -> Result<Arc<dyn Objective>, Error> {
    let (train, validate) = recordings(p)?;
    let fit = BoucWenFit::new(
        &train,
        &validate,
        p.bool("d0"),
        p.bool("normalize"),
        p.float("lower"),
        p.float("upper"),
    )
    .map_err(|e| p.error("lower", e))?
    .with_initial_states(p.bool("h0"))
    .with_validation_refit(match p.str("refit_validation") {
        "always" => Some(true),
        "never" => Some(false),
        _ => None,
    })
    .with_scheme(match p.str("scheme") {
        "accurate" => BoucWenScheme::Accurate,
        "explicit" => BoucWenScheme::Explicit,
        _ => BoucWenScheme::Fast {
            substeps: p.int("substeps") as usize,
        },
    });
    Ok(Arc::new(fit))
}

/// The search box of an operator fit's coefficients (PI, Preisach).
const COEFFICIENT_BOUND: Spec = Spec {
    name: "coefficient_bound",
    kind: Kind::Float {
        min: f64::MIN_POSITIVE,
        max: MAX_MAGNITUDE,
    },
    default: D::Float(4.0),
    help: "search box of each coefficient: |coefficient| x its column's RMS <= this, in units of the normalised output (non-negative weights from 0); a search of the weights refuses a box that misses the exact optimum",
};

const PI_PARAMS: &[Spec] = recording_params![
    Spec {
        name: "form",
        kind: Kind::Choice(&["plain", "asymmetric", "rate-dependent"]),
        default: D::Str("plain"),
        help: "plain = weighted plays; asymmetric = plus a2 u^2 + a3 u^3; rate-dependent = each weight grows with |du/dt| (w_i + rho_i |du/dt|)",
    },
    Spec {
        name: "operators",
        kind: size(1, 200),
        default: D::Int(10),
        help: "play operators, the first (threshold 0) the linear term; thresholds r_i = i/n x half the training input's range",
    },
    Spec {
        name: "search",
        kind: Kind::Choice(&["weights", "all"]),
        default: D::Str("weights"),
        help: "weights = thresholds fixed uniform, coefficients searched (a convex problem: its exact least-squares optimum is known and reported); all = thresholds too (n increments in [0.05, 1], r_i = r_max x cumulative share: ordered by construction; no known optimum)",
    },
    COEFFICIENT_BOUND,
];

fn build_pi(p: &Params) -> Result<Arc<dyn Objective>, Error> {
    let (train, validate) = recordings(p)?;
    let form = PiForm::parse(p.str("form")).expect("a choice of the spec");
    let search = match p.str("search") {
        "all" => OperatorSearch::All,
        _ => OperatorSearch::Weights,
    };
    let fit = OperatorFit::pi(
        &train,
        &validate,
        form,
        p.usize("operators"),
        search,
        p.float("coefficient_bound"),
    )
    .map_err(|e| p.entry_error(e))?;
    Ok(Arc::new(fit))
}

const PREISACH_PARAMS: &[Spec] = recording_params![
    Spec {
        name: "levels",
        kind: size(1, 60),
        default: D::Int(10),
        help: "cells of the relay grid over the training input's range: levels (levels+1)/2 relay weights and an offset",
    },
    COEFFICIENT_BOUND,
];

fn build_preisach(p: &Params) -> Result<Arc<dyn Objective>, Error> {
    let (train, validate) = recordings(p)?;
    let fit = OperatorFit::preisach(
        &train,
        &validate,
        p.usize("levels"),
        p.float("coefficient_bound"),
    )
    .map_err(|e| p.entry_error(e))?;
    Ok(Arc::new(fit))
}

/// The objective kinds that fit a model to recordings (those with a `recording`), the
/// models `optbench fit --model` accepts.
pub fn fitting_kind_names() -> Vec<&'static str> {
    objective_kinds()
        .iter()
        .filter(|k| k.params.iter().any(|p| p.name == "recording"))
        .map(|k| k.name)
        .collect()
}

/// Builds the objective of kind `name` from suite-style keys (`given`: key -> (value,
/// line)), for callers outside a suite file (the Python package): the same validation and
/// messages as a suite's `[[objective]]`.
pub fn build_objective(
    name: &str,
    given: &BTreeMap<String, (toml::Value, usize)>,
    origin: Origin,
) -> Result<Arc<dyn Objective>, Error> {
    let kinds = objective_kinds();
    let Some(kind) = kinds.iter().find(|k| k.name == name) else {
        let valid: Vec<_> = kinds.iter().map(|k| k.name).collect();
        return Err(Error::at(
            &origin.file,
            origin.line,
            format!(
                "unknown objective kind `{name}`; valid kinds: {}",
                valid.join(", ")
            ),
        ));
    };
    let params = Params::validate(kind.params, given, origin)?;
    (kind.build)(&params)
}

/// Every optimizer kind's name.
pub fn optimizer_names() -> Vec<&'static str> {
    optimizer_kinds().iter().map(|k| k.name).collect()
}

/// Every objective kind.
pub fn objective_kinds() -> Vec<ObjectiveKind> {
    use TestFunction::*;
    vec![
        function_kind!(Sphere, Sphere.describe()),
        function_kind!(Griewank, Griewank.describe()),
        function_kind!(Schwefel, Schwefel.describe()),
        function_kind!(Rastrigin, Rastrigin.describe()),
        function_kind!(Rosenbrock, Rosenbrock.describe()),
        function_kind!(Ackley, Ackley.describe()),
        ObjectiveKind {
            name: "bbob",
            help: "COCO's noiseless BBOB function `function` (1-24), instance `instance`, on [-5, 5]^dim, with COCO's values, optimum and instance generator (named bbob-fFF-iII-dDD)",
            params: BBOB_PARAMS,
            build: build_bbob,
        },
        ObjectiveKind {
            name: "bouc-wen",
            help: "fit the dissertation's Bouc-Wen model (eq. 3.1-3.3: d_e, alpha, beta, gamma, n [, d0]) to a recording by free-run simulation",
            params: BOUC_WEN_PARAMS,
            build: build_bouc_wen,
        },
        ObjectiveKind {
            name: "rbf",
            help: "fit a Gaussian RBF NARX network (seed 3.2, 3-7-1 = 35 parameters) to a recording; reports one-step and free-run errors",
            params: RBF_PARAMS,
            build: build_rbf,
        },
        ObjectiveKind {
            name: "pi",
            help: "fit a Prandtl-Ishlinskii model (plain, asymmetric or rate-dependent; weighted play operators) to a recording; search = weights has a known exact optimum",
            params: PI_PARAMS,
            build: build_pi,
        },
        ObjectiveKind {
            name: "preisach",
            help: "fit a discretised Preisach model (a triangle of relays over the input's range, weights >= 0) to a recording; the weights' exact least-squares optimum is the known optimum",
            params: PREISACH_PARAMS,
            build: build_preisach,
        },
    ]
}

const POPULATION: Spec = Spec {
    name: "population",
    kind: size(2, MAX_POPULATION),
    default: D::Int(200),
    help: "individuals evaluated per generation",
};

const GA_PARAMS: &[Spec] = &[
    POPULATION,
    probability("pc", 0.9, "crossover probability per pair"),
    probability("pm", 0.1, "mutation probability per gene"),
    Spec {
        name: "elite",
        kind: size(0, MAX_POPULATION),
        default: D::Int(1),
        help: "best individuals copied unchanged into the next generation",
    },
    Spec {
        name: "mutation",
        kind: Kind::Choice(&["uniform", "gaussian"]),
        default: D::Str("uniform"),
        help: "uniform: redraw the gene in its interval (dissertation eq. 3.5); gaussian: add noise",
    },
    Spec {
        name: "sigma",
        kind: Kind::Float {
            min: f64::MIN_POSITIVE,
            max: f64::INFINITY,
        },
        default: D::Float(0.1),
        help: "gaussian mutation step as a fraction of the interval width",
    },
];

fn build_ga(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    let cfg = GaConfig {
        population: p.usize("population"),
        pc: p.float("pc"),
        pm: p.float("pm"),
        elite: p.usize("elite"),
        mutation: match p.str("mutation") {
            "gaussian" => Mutation::Gaussian {
                sigma: p.float("sigma"),
            },
            _ => Mutation::Uniform,
        },
    };
    if cfg.elite >= cfg.population {
        return Err(p.error(
            "elite",
            format!(
                "{} must be smaller than the population ({})",
                cfg.elite, cfg.population
            ),
        ));
    }
    Ok(Arc::new(cfg))
}

const COEFF: Kind = Kind::Float {
    min: 0.0,
    max: 10.0,
};

const PSO_PARAMS: &[Spec] = &[
    Spec {
        name: "population",
        kind: size(1, MAX_POPULATION),
        default: D::Int(200),
        help: "particles in the swarm",
    },
    Spec {
        name: "w_start",
        kind: Kind::Float { min: 0.0, max: 2.0 },
        default: D::Float(0.9),
        help: "inertia weight at the first iteration",
    },
    Spec {
        name: "w_end",
        kind: Kind::Float { min: 0.0, max: 2.0 },
        default: D::Float(0.4),
        help: "inertia weight at the last iteration (equal to w_start for constant)",
    },
    Spec {
        name: "c1",
        kind: COEFF,
        default: D::Float(2.0),
        help: "cognitive acceleration constant (seed: 2)",
    },
    Spec {
        name: "c2",
        kind: COEFF,
        default: D::Float(2.0),
        help: "social acceleration constant (seed: 2)",
    },
    Spec {
        name: "vmax",
        kind: Kind::Float {
            min: f64::MIN_POSITIVE,
            max: 1.0,
        },
        default: D::Float(0.2),
        help: "velocity clamp as a fraction of each interval's width",
    },
];

fn build_pso(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    Ok(Arc::new(PsoConfig {
        swarm: p.usize("population"),
        w_start: p.float("w_start"),
        w_end: p.float("w_end"),
        c1: p.float("c1"),
        c2: p.float("c2"),
        vmax: p.float("vmax"),
    }))
}

const MSGA_PARAMS: &[Spec] = &[
    Spec {
        name: "objects",
        kind: size(2, MAX_POPULATION / 5),
        default: D::Int(40),
        help: "objects per membrane (5 membranes, dissertation Fig. 3.3)",
    },
    probability(
        "pm",
        0.1,
        "mutation probability per gene (dissertation Table 3.1)",
    ),
    probability(
        "pc",
        0.9,
        "crossover probability per pair (dissertation Table 3.1)",
    ),
    probability(
        "ps",
        0.05,
        "shift probability per object (dissertation Table 3.1)",
    ),
    probability(
        "exchange",
        0.3,
        "share of best objects sent to each neighbour membrane (dissertation Table 3.1)",
    ),
    Spec {
        name: "threads",
        kind: Kind::Bool,
        default: D::Bool(true),
        help: "one OS thread per membrane; false runs them in turn (same results)",
    },
    Spec {
        name: "migration_lag",
        kind: Kind::Int { min: 0, max: 1 },
        default: D::Int(0),
        help: "steps late that migrants are taken in: 0 = the dissertation's rule (neighbours wait \
               for each other every step), 1 = the previous step's (membranes drift; faster \
               on fewer cores than membranes, a different algorithm)",
    },
];

fn build_msga(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    Ok(Arc::new(MsgaConfig {
        objects: p.usize("objects"),
        pm: p.float("pm"),
        pc: p.float("pc"),
        ps: p.float("ps"),
        exchange: p.float("exchange"),
        threads: p.bool("threads"),
        migration_lag: p.usize("migration_lag"),
        ..MsgaConfig::default()
    }))
}

const NM_PARAMS: &[Spec] = &[Spec {
    name: "step",
    kind: Kind::Float {
        min: f64::MIN_POSITIVE,
        max: 1.0,
    },
    default: D::Float(0.05),
    help: "initial simplex edge as a fraction of each interval's width",
}];

fn build_nm(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    Ok(Arc::new(NelderMeadConfig {
        step: p.float("step"),
    }))
}

const RANDOM_PARAMS: &[Spec] = &[Spec {
    name: "batch",
    kind: size(1, MAX_POPULATION),
    default: D::Int(200),
    help: "points drawn per iteration",
}];

fn build_random(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    Ok(Arc::new(RandomSearchConfig {
        batch: p.usize("batch"),
    }))
}

const BP_PARAMS: &[Spec] = &[
    Spec {
        name: "learning_rate",
        kind: Kind::Float {
            min: f64::MIN_POSITIVE,
            max: f64::INFINITY,
        },
        default: D::Float(0.01),
        help: "initial step size eta (halved after a step that increases the cost)",
    },
    Spec {
        name: "momentum",
        kind: Kind::Float {
            min: 0.0,
            max: 0.999,
        },
        default: D::Float(0.9),
        help: "momentum term mu of dp(k) = -eta grad + mu dp(k-1) (dissertation eq. 4.6-4.8)",
    },
];

fn build_bp(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    Ok(Arc::new(GradientConfig {
        learning_rate: p.float("learning_rate"),
        momentum: p.float("momentum"),
    }))
}

/// Every optimizer kind.
pub fn optimizer_kinds() -> Vec<OptimizerKind> {
    let mut kinds = vec![
        OptimizerKind {
            name: "ga",
            help: "real-coded GA: roulette selection, arithmetic crossover, mutation, elitism",
            params: GA_PARAMS,
            build: build_ga,
        },
        OptimizerKind {
            name: "pso",
            help: "particle swarm (dissertation eq. 3.15/3.16), linearly decreasing inertia",
            params: PSO_PARAMS,
            build: build_pso,
        },
        OptimizerKind {
            name: "msga",
            help: "membrane-structure GA (seed 3.1.1): 5 membranes, one OS thread each",
            params: MSGA_PARAMS,
            build: build_msga,
        },
        OptimizerKind {
            name: "bp",
            help: "back-propagation baseline: gradient descent with momentum (needs a gradient; one gradient step = 1 + dim evaluations)",
            params: BP_PARAMS,
            build: build_bp,
        },
        OptimizerKind {
            name: "nelder-mead",
            help: "Nelder-Mead simplex (adaptive coefficients), from a random start; also the local polish of `polish = share`",
            params: NM_PARAMS,
            build: build_nm,
        },
        OptimizerKind {
            name: "random",
            help: "uniform random search, the floor every method must beat",
            params: RANDOM_PARAMS,
            build: build_random,
        },
    ];
    kinds.extend(baselines::kinds());
    kinds
}

/// Builds the named optimizer with all defaults (for code outside suites).
pub fn default_optimizer(name: &str) -> Option<Arc<dyn OptimizerConfig>> {
    let kinds = optimizer_kinds();
    let k = kinds.iter().find(|k| k.name == name)?;
    let p = Params::defaults(k.params, name).ok()?;
    (k.build)(&p).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn given(pairs: &[(&str, toml::Value)]) -> BTreeMap<String, (toml::Value, usize)> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), (v.clone(), 0)))
            .collect()
    }

    fn origin() -> Origin {
        Origin {
            file: "optbench.problem".into(),
            line: 0,
            what: "objective `x`".into(),
        }
    }

    #[test]
    fn objectives_build_by_kind_name_with_the_suites_messages() {
        let f = build_objective(
            "griewank",
            &given(&[("dim", toml::Value::Integer(3))]),
            origin(),
        )
        .unwrap();
        assert_eq!((f.name(), f.dim(), f.optimum()), ("griewank", 3, Some(0.0)));
        let err = |kind, keys| build_objective(kind, &given(keys), origin()).err().unwrap();
        let e = err("nope", &[]).to_string();
        assert!(
            e.starts_with("optbench.problem: unknown objective kind `nope`"),
            "{e}"
        );
        assert!(e.contains("griewank") && e.contains("bouc-wen"), "{e}");
        let e = err("griewank", &[]);
        assert!(e.to_string().contains("missing parameter `dim`"), "{e}");
        let two = toml::Value::Integer(2);
        let e = err("griewank", &[("dim", two.clone()), ("dims", two)]);
        assert!(e.to_string().contains("unknown parameter `dims`"), "{e}");
    }

    #[test]
    fn only_relative_csv_paths_are_anchored() {
        let base = Path::new("/s");
        assert_eq!(
            anchor_recordings(
                "a.csv | twin:sine:freq=1 | $OPTBENCH_DATA/x.csv | /d/b.csv",
                base
            )
            .as_deref(),
            Some("/s/a.csv | twin:sine:freq=1 | $OPTBENCH_DATA/x.csv | /d/b.csv")
        );
        for kept in [
            "twin:chirp",
            "eq318:sine:freq=2",
            "$OPTBENCH_DATA/b/c.csv",
            "/abs.csv",
        ] {
            assert_eq!(anchor_recordings(kept, base), None, "{kept}");
        }
    }
}
