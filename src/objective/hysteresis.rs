//! Hysteresis-fit objectives: the cost of a model's parameters on a recording.
//!
//! Data are normalised before fitting (input and output divided by their largest absolute
//! value on the training record), so one set of parameter bounds serves an actuator in
//! volts and millimetres and a benchmark in newtons and metres alike; validation data use
//! the training scales. Costs are J = sum(e^2)/2 (dissertation eq. 3.8-3.9) in normalised units;
//! reports present them as RMSE in the recording's units.

use super::{Bounds, Metric, Objective, Presentation, PresentationKind};
use crate::base::error::{Error, Result};
use crate::data::recording::Recording;
use crate::physics::bouc_wen::{self, BoucWenParams, SimStatus};
use crate::physics::bouc_wen_fast::{self, FastInput};
use crate::physics::model_file::{
    Integration, ModelFile, Network, Normalisation, Param, RecordState, Units,
};
use crate::physics::rbf::{self, Mode, Narx, RbfNet, Regressors};
use crate::physics::rbf_fast::RbfBatch;

/// A recording scaled for fitting.
#[derive(Debug, Clone)]
pub struct FitData {
    pub u: Vec<f64>,
    pub y: Vec<f64>,
    /// Physical = normalised * scale.
    pub u_scale: f64,
    pub y_scale: f64,
    /// Unit of y, for labels.
    pub unit: String,
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

impl FitData {
    /// Scales `rec` by its own largest absolute values (or not at all).
    pub fn new(rec: &Recording, normalize: bool) -> Result<Self> {
        let (us, ys) = if normalize {
            (max_abs(&rec.u), max_abs(&rec.y))
        } else {
            (1.0, 1.0)
        };
        if us == 0.0 || ys == 0.0 {
            return Err(Error::Input(format!(
                "{}: the {} is zero everywhere; nothing to fit",
                rec.name,
                if us == 0.0 { "input" } else { "output" }
            )));
        }
        Ok(Self::with_scales(rec, us, ys))
    }

    /// `rec` scaled like `self` (for validation data).
    pub fn like(&self, rec: &Recording) -> Self {
        Self::with_scales(rec, self.u_scale, self.y_scale)
    }

    fn with_scales(rec: &Recording, u_scale: f64, y_scale: f64) -> Self {
        FitData {
            u: rec.u.iter().map(|v| v / u_scale).collect(),
            y: rec.y.iter().map(|v| v / y_scale).collect(),
            u_scale,
            y_scale,
            unit: rec.units[2].clone(),
        }
    }

    pub(super) fn unit_suffix(&self) -> String {
        if self.unit.is_empty() {
            String::new()
        } else {
            format!(" [{}]", self.unit)
        }
    }
}

/// What `optbench fit` shows of a fitting objective, in the recording's units.
pub trait FitView {
    /// The recordings with their labels: `train` first, then the validation ones.
    fn recordings(&self) -> Vec<(&str, &Recording)>;
    /// Model outputs at parameters `p` on recording `set` (an index into
    /// [`FitView::recordings`]), labelled.
    fn outputs(&self, p: &[f64], set: usize) -> Vec<(String, Vec<f64>)>;
    /// Parameters by name, in physical units where they have them.
    fn named_params(&self, p: &[f64]) -> Vec<(String, f64)>;
    /// The model at `p` as a file that runs again ([`ModelFile`]): de-normalised
    /// parameters with their search bounds, the scales, the scheme and each record's own
    /// state. The caller fills in how it was fitted.
    fn model(&self, p: &[f64]) -> ModelFile;
}

/// Units of the first training record, and a quotient `out/in` of them ("" if both are).
pub(super) fn units_of(rec: &Recording) -> (Units, String) {
    let [t, u, y] = rec.units.clone();
    let ratio = if u.is_empty() && y.is_empty() {
        String::new()
    } else {
        format!("{y}/{u}")
    };
    (
        Units {
            time: t,
            input: u,
            output: y,
        },
        ratio,
    )
}

/// The training recordings and any number of labelled validation recordings, scaled alike.
#[derive(Debug, Clone)]
pub struct Datasets {
    recordings: Vec<(String, Recording)>,
    scaled: Vec<FitData>,
    /// The first this many sets are the training ones.
    trains: usize,
}

impl Datasets {
    /// `train` (one or several records, labelled `train` or `train1`, `train2`, ...) scaled
    /// by their largest values (or not at all), `validate` like them.
    pub fn new(
        train: &[Recording],
        validate: &[(String, Recording)],
        normalize: bool,
    ) -> Result<Self> {
        let Some(first) = train.first() else {
            return Err(Error::Input("no training recording".into()));
        };
        let mut t = FitData::new(first, normalize)?;
        for r in &train[1..] {
            let own = FitData::new(r, normalize)?;
            t.u_scale = t.u_scale.max(own.u_scale);
            t.y_scale = t.y_scale.max(own.y_scale);
        }
        let mut scaled: Vec<FitData> = train.iter().map(|r| t.like(r)).collect();
        scaled.extend(validate.iter().map(|(_, r)| t.like(r)));
        let mut recordings: Vec<(String, Recording)> = train
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let label = if train.len() == 1 {
                    "train".to_string()
                } else {
                    format!("train{}", k + 1)
                };
                (label, r.clone())
            })
            .collect();
        recordings.extend(validate.iter().cloned());
        Ok(Datasets {
            recordings,
            scaled,
            trains: train.len(),
        })
    }

    /// The first training record's data (whose scales every set shares).
    pub fn train(&self) -> &FitData {
        &self.scaled[0]
    }

    /// Every training record's data.
    pub fn trains(&self) -> &[FitData] {
        &self.scaled[..self.trains]
    }

    /// Training samples in all.
    pub(super) fn train_samples(&self) -> usize {
        self.trains().iter().map(|d| d.u.len()).sum()
    }

    /// (label, scaled data) of every set, training first.
    pub fn sets(&self) -> impl Iterator<Item = (&str, &FitData)> {
        self.recordings
            .iter()
            .map(|(l, _)| l.as_str())
            .zip(&self.scaled)
    }

    pub(super) fn get(&self, set: usize) -> Option<&FitData> {
        self.scaled.get(set)
    }

    pub(super) fn recordings(&self) -> Vec<(&str, &Recording)> {
        self.recordings
            .iter()
            .map(|(l, r)| (l.as_str(), r))
            .collect()
    }

    /// Costs J = Σe²/2 over every training sample shown as RMSE in the training units:
    /// the presentation every free-run fit shares.
    pub(super) fn rmse_presentation(&self) -> Presentation {
        let t = self.train();
        Presentation {
            label: format!("train RMSE{}", t.unit_suffix()),
            kind: PresentationKind::RmseFromHalfSse {
                samples: self.train_samples(),
                scale: t.y_scale,
            },
        }
    }

    /// `<set> RMSE` and `<set> max error` of the normalised model output `output(k)` on
    /// every set `k`, in the recording's units.
    pub(super) fn free_run_metrics(&self, output: impl Fn(usize) -> Vec<f64>) -> Vec<Metric> {
        let unit = self.train().unit_suffix();
        let mut m = Vec::new();
        for (k, (set, d)) in self.sets().enumerate() {
            let (max, rms) = errors(&d.y, &output(k), 0, d.y_scale);
            m.push(Metric::new(format!("{set} RMSE{unit}"), rms));
            m.push(Metric::new(format!("{set} max error{unit}"), max));
        }
        m
    }

    /// Refuses sets sampled at another interval than the first training record's, for a
    /// discrete-time model (whose lags are samples).
    fn one_interval(&self, model: &str) -> Result<()> {
        let dt = self.recordings[0].1.dt();
        for (label, r) in &self.recordings[1..] {
            if !crate::physics::structure::same_interval(r.dt(), dt) {
                return Err(Error::Input(format!(
                    "{} ({label}) is sampled every {} s, the training record every {dt} s: the {model} is a discrete-time model (its lags are samples); resample the records to one interval, or fit a continuous-time model (bouc-wen, or optbench diagnose)",
                    r.name,
                    r.dt()
                )));
            }
        }
        Ok(())
    }
}

/// Replaces non-finite model outputs by the last finite one (0 before any), so metrics and
/// plots of absurd parameters stay finite; costs penalise such parameters on their own.
pub(super) fn hold_finite(out: &mut [f64]) {
    let mut last = 0.0;
    for v in out {
        if v.is_finite() {
            last = *v;
        } else {
            *v = last;
        }
    }
}

/// Max |e| and RMS of `model - measured` from `start`, in physical units.
fn errors(meas: &[f64], model: &[f64], start: usize, scale: f64) -> (f64, f64) {
    let e = rbf::fit_errors(meas, model, start);
    (e.max_abs * scale, e.rms * scale)
}

/// Fit of a Gaussian RBF NARX network (dissertation section 3.2) to one or several recordings
/// (the costs summed, the regressors restarting on each).
pub struct RbfFit {
    net: RbfNet,
    narx: Narx,
    mode: Mode,
    data: Datasets,
    /// Per training record.
    regressors: Vec<Regressors>,
    /// The training data prepared for batched costs, per training record.
    batch: Vec<RbfBatch>,
    bounds: Bounds,
}

impl RbfFit {
    /// The fit of `net` with regressors `narx` on `train`, optimised in `mode`; metrics also
    /// on every `validate` recording. Every record at one sampling interval.
    pub fn new(
        train: &[Recording],
        validate: &[(String, Recording)],
        net: RbfNet,
        narx: Narx,
        mode: Mode,
    ) -> Result<Self> {
        if net.inputs != narx.dim() {
            return Err(Error::Input(format!(
                "the network has {} inputs but the regressors give {}",
                net.inputs,
                narx.dim()
            )));
        }
        let data = Datasets::new(train, validate, true)?;
        data.one_interval("RBF NARX network")?;
        let regressors: Vec<Regressors> = data
            .trains()
            .iter()
            .map(|d| Regressors::new(&narx, &d.u, &d.y))
            .collect();
        let batch = data
            .trains()
            .iter()
            .map(|d| RbfBatch::new(net, narx, &d.u, &d.y))
            .collect();
        // Centres and widths over every training record's regressor ranges.
        let (mut lo, mut hi) = regressors[0].input_ranges();
        let (mut ylo, mut yhi) = regressors[0].output_range();
        for r in &regressors[1..] {
            let (l, h) = r.input_ranges();
            lo.iter_mut().zip(l).for_each(|(a, b)| *a = a.min(b));
            hi.iter_mut().zip(h).for_each(|(a, b)| *a = a.max(b));
            let (yl, yh) = r.output_range();
            (ylo, yhi) = (ylo.min(yl), yhi.max(yh));
        }
        let (lower, upper) = rbf::param_bounds(&net, &lo, &hi, ylo, yhi);
        let bounds = Bounds::new(lower, upper).map_err(Error::Input)?;
        Ok(RbfFit {
            net,
            narx,
            mode,
            data,
            regressors,
            batch,
            bounds,
        })
    }

    /// Model output on `d` in `mode`, normalised.
    fn predict(&self, p: &[f64], d: &FitData, mode: Mode) -> Vec<f64> {
        let mut out = vec![0.0; d.u.len()];
        rbf::predict(&self.net, &self.narx, p, &d.u, &d.y, mode, &mut out);
        hold_finite(&mut out);
        out
    }
}

impl FitView for RbfFit {
    fn recordings(&self) -> Vec<(&str, &Recording)> {
        self.data.recordings()
    }

    fn outputs(&self, p: &[f64], set: usize) -> Vec<(String, Vec<f64>)> {
        let Some(d) = self.data.get(set) else {
            return Vec::new();
        };
        [
            (Mode::OneStepAhead, "RBF one-step"),
            (Mode::FreeRun, "RBF free-run"),
        ]
        .into_iter()
        .map(|(mode, label)| {
            let y = self
                .predict(p, d, mode)
                .into_iter()
                .map(|v| v * d.y_scale)
                .collect();
            (label.to_string(), y)
        })
        .collect()
    }

    /// Centres, widths and weights in normalised units (inputs / u_scale, outputs / y_scale).
    fn named_params(&self, p: &[f64]) -> Vec<(String, f64)> {
        let (h, i) = (self.net.hidden, self.net.inputs);
        let mut v = Vec::with_capacity(p.len());
        for j in 0..h {
            for k in 0..i {
                v.push((format!("c{}_{}", j + 1, k + 1), p[j * i + k]));
            }
        }
        for j in 0..h {
            v.push((format!("b{}", j + 1), p[h * i + j]));
        }
        for j in 0..h {
            v.push((format!("w{}", j + 1), p[h * i + h + j]));
        }
        v
    }

    /// Centres and weights de-normalised (each regressor in its own unit); a node's width,
    /// one number on the normalised regressors, becomes one width per regressor.
    fn model(&self, p: &[f64]) -> ModelFile {
        let t = self.data.train();
        let (units, _) = units_of(&self.data.recordings[0].1);
        let (h, ni) = (self.net.hidden, self.net.inputs);
        let lags = self.narx.input_lags;
        let scale = |k: usize| if k < lags { t.u_scale } else { t.y_scale };
        let unit = |k: usize| {
            if k < lags {
                units.input.clone()
            } else {
                units.output.clone()
            }
        };
        let lag = |v: &str, l: usize| {
            if l == 0 {
                format!("{v}(k)")
            } else {
                format!("{v}(k-{l})")
            }
        };
        let regressors: Vec<String> = (0..ni)
            .map(|k| {
                if k < lags {
                    lag("u", k)
                } else {
                    lag("y", k - lags + 1)
                }
            })
            .collect();
        let (lo, hi) = (self.bounds.lower(), self.bounds.upper());
        let mut params = Vec::with_capacity(p.len());
        for j in 0..h {
            for k in 0..ni {
                let x = j * ni + k;
                params.push(
                    Param::new(format!("c{}_{}", j + 1, k + 1), p[x] * scale(k), unit(k))
                        .searched(p[x], lo[x], hi[x]),
                );
            }
        }
        // The width the network uses (`b²` floored, see `rbf::WIDTH_FLOOR`).
        let width = |b: f64| (b * b).max(rbf::WIDTH_FLOOR * rbf::WIDTH_FLOOR).sqrt();
        for j in 0..h {
            let x = h * ni + j;
            params.push(
                Param::new(format!("b{} (normalised)", j + 1), width(p[x]), "")
                    .searched(p[x], lo[x], hi[x]),
            );
        }
        for j in 0..h {
            let x = h * ni + h + j;
            params.push(
                Param::new(
                    format!("w{}", j + 1),
                    p[x] * t.y_scale,
                    units.output.clone(),
                )
                .searched(p[x], lo[x], hi[x]),
            );
        }
        let network = Network {
            input_lags: self.narx.input_lags,
            output_lags: self.narx.output_lags,
            regressors,
            centres: (0..h)
                .map(|j| (0..ni).map(|k| p[j * ni + k] * scale(k)).collect())
                .collect(),
            widths: (0..h)
                .map(|j| (0..ni).map(|k| width(p[h * ni + j]) * scale(k)).collect())
                .collect(),
            weights: (0..h).map(|j| p[h * ni + h + j] * t.y_scale).collect(),
        };
        let mode = match self.mode {
            Mode::OneStepAhead => "one-step-ahead predictions",
            Mode::FreeRun => "a free run",
        };
        let mut m = ModelFile::new(
            "rbf",
            &format!(
                "Gaussian RBF NARX network (dissertation section 3.2): y(k) = sum_j w_j exp(-1/2 sum_i ((x_i - c_ji)/b_ji)^2), x the regressors; fitted on {mode}, run free (its own past outputs)"
            ),
            units,
            self.data.recordings[0].1.dt(),
            Normalisation {
                input_scale: t.u_scale,
                output_scale: t.y_scale,
            },
            Integration {
                scheme: "narx".into(),
                substeps: None,
                hold: None,
            },
            "the first max(input_lags - 1, output_lags) outputs are the measured ones (0 without a measured output); from there the network feeds back its own outputs",
            params,
        );
        m.network = Some(network);
        m
    }
}

/// One point as a batch of one: the fits' batch path is their only evaluation path, so a
/// single evaluation cannot differ from the same point inside a population.
fn one_of_batch(o: &impl Objective, p: &[f64]) -> f64 {
    let mut out = [0.0];
    o.evaluate_batch(p, &mut out);
    out[0]
}

impl Objective for RbfFit {
    fn name(&self) -> &str {
        "rbf"
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, p: &[f64]) -> f64 {
        one_of_batch(self, p)
    }

    /// The sum over training records.
    fn evaluate_batch(&self, points: &[f64], out: &mut [f64]) {
        self.batch[0].costs(points, self.mode, out);
        let mut more = vec![0.0; out.len()];
        for b in &self.batch[1..] {
            b.costs(points, self.mode, &mut more);
            out.iter_mut().zip(&more).for_each(|(o, m)| *o += m);
        }
    }

    /// One-step mode only. A call is a back-propagation pass over every training sample
    /// (forward and backward; its own sum is discarded) and one batched value pass: about
    /// three value passes of work, charged `1 + d` evaluations (36 for the 3-7-1 network).
    fn value_and_gradient(&self, p: &[f64], grad: &mut [f64]) -> Option<f64> {
        match self.mode {
            // The value from the batched path, so that every optimizer records the same
            // value for the same point (the gradient pass's `exp` differs in the last bits).
            Mode::OneStepAhead => {
                self.regressors[0].cost_grad(&self.net, p, grad);
                let mut more = vec![0.0; grad.len()];
                for r in &self.regressors[1..] {
                    r.cost_grad(&self.net, p, &mut more);
                    grad.iter_mut().zip(&more).for_each(|(g, m)| *g += m);
                }
                Some(self.evaluate(p))
            }
            Mode::FreeRun => None,
        }
    }

    fn has_gradient(&self) -> bool {
        matches!(self.mode, Mode::OneStepAhead)
    }

    fn presentation(&self) -> Option<Presentation> {
        let mode = match self.mode {
            Mode::OneStepAhead => "one-step",
            Mode::FreeRun => "free-run",
        };
        let t = self.data.train();
        let start = self.narx.start() * self.data.trains().len();
        Some(Presentation {
            label: format!("train {mode} RMSE{}", t.unit_suffix()),
            kind: PresentationKind::RmseFromHalfSse {
                samples: self.data.train_samples() - start,
                scale: t.y_scale,
            },
        })
    }

    fn as_fit(&self) -> Option<&dyn FitView> {
        Some(self)
    }

    /// Both modes always: one-step-ahead (measured past outputs, flattering) and free-run
    /// (the model's own), on training and validation data.
    fn metrics(&self, p: &[f64]) -> Vec<Metric> {
        let unit = self.data.train().unit_suffix();
        let start = self.narx.start();
        let mut m = Vec::new();
        for (set, d) in self.data.sets() {
            for (mode, name) in [
                (Mode::OneStepAhead, "one-step"),
                (Mode::FreeRun, "free-run"),
            ] {
                let (max, rms) = errors(&d.y, &self.predict(p, d, mode), start, d.y_scale);
                m.push(Metric::new(format!("{set} {name} RMSE{unit}"), rms));
                m.push(Metric::new(format!("{set} {name} max error{unit}"), max));
            }
        }
        m
    }
}

/// Fit of the dissertation's Bouc-Wen model (eq. 3.1-3.3) to one or several recordings:
/// parameters (d_e, alpha, beta, gamma, n) and optionally an offset d0 per training record,
/// in normalised units, cost from a free-run simulation of each record (eq. 3.8-3.9),
/// summed. The model is rate-independent, so records at any sampling intervals fit
/// together. Unstable parameters cost a large finite penalty.
///
/// With several training records each also gets an initial hysteretic state of its own (a
/// record taken later in a session starts mid-loop): the search variable is the fraction
/// `q` in [-1, 1] of the loop's saturation level `(alpha/(beta+gamma))^(1/n)`, the range a
/// run from rest can reach, so `h0 = q · saturation` (0 where the parameters have no
/// saturation level). With one training record every run starts from rest, as the dissertation's.
///
/// Validation records: with one training and one validation record the validation record
/// is predicted from rest with the first training record's d0 (the dissertation's protocol). With
/// more records, each validation record's own nuisances are refitted on it with the
/// actuator's parameters held fixed: its offset d0 (when d0 is fitted) in closed form (the
/// mean residual) and its initial state by a bounded 1-D search over `q`.
pub struct BoucWenFit {
    with_d0: bool,
    /// Each training record's initial state is fitted (several training records).
    with_h0: bool,
    /// Validation records' nuisances refitted: always, never, or (None) with more than one
    /// training or validation record.
    refit: Option<bool>,
    data: Datasets,
    bounds: Bounds,
    scheme: BoucWenScheme,
    /// Each training record prepared for the fast scheme.
    fast: Vec<FastInput>,
    /// The validation records' refits ([`Self::refit`]) at the last point asked: metrics,
    /// figures and the parameter table ask for the same point in turn, and a refit is some
    /// 80 free runs of its record (a 153,000-sample record: seconds each time).
    refits: std::sync::Mutex<RefitCache>,
}

/// A point and the refitted `(d0, h0)` of each validation set there (`None`: not asked yet).
type RefitCache = Option<(Vec<f64>, Vec<Option<(f64, f64)>>)>;

/// How the Bouc-Wen fit integrates the model (see [`crate::physics::bouc_wen_fast`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoucWenScheme {
    /// Fixed-cost predictor-corrector exponential steps, batched over the population;
    /// `substeps` per sample (0: chosen from the training input).
    Fast { substeps: usize },
    /// The adaptive, cusp-aware kernel the twin uses, one individual at a time (about 20x
    /// slower than `Fast`).
    Accurate,
    /// The seed-style explicit recurrence, one clamped Euler step per sample, batched:
    /// fastest, first order in the input step (2e-3 of the loop at 1 Hz, 1 ms).
    Explicit,
}

/// Names of the Bouc-Wen parameters in vector order (one `d0` per training record follows
/// `n` when fitted, then, with several training records, one initial-state fraction each).
pub const BOUC_WEN_PARAMS: [&str; 6] = ["d_e", "alpha", "beta", "gamma", "n", "d0"];

/// Initial hysteretic state `q · saturation` of parameters `p` (`q` clamped to [-1, 1]; 0
/// where `p` has no saturation level).
pub fn initial_state(p: &BoucWenParams, q: f64) -> f64 {
    p.saturation().map_or(0.0, |s| q.clamp(-1.0, 1.0) * s)
}

/// Grid points of the validation records' initial-state search over [-1, 1].
const STATE_GRID: usize = 41;
/// Golden-section iterations after the grid (the bracket shrinks by 0.618 each).
const STATE_GOLDEN: usize = 40;

impl BoucWenFit {
    /// The fit on `train` with every parameter in `[lower, upper]` (the seed: [0, 1.5]),
    /// on normalised data or in the recording's own units.
    pub fn new(
        train: &[Recording],
        validate: &[(String, Recording)],
        with_d0: bool,
        normalize: bool,
        lower: f64,
        upper: f64,
    ) -> Result<Self> {
        let data = Datasets::new(train, validate, normalize)?;
        let dim = 5 + if with_d0 { train.len() } else { 0 };
        let bounds = Bounds::uniform(dim, lower, upper).map_err(Error::Input)?;
        let fast = data
            .trains()
            .iter()
            .map(|t| FastInput::new(&t.u, &t.y, 0))
            .collect();
        Ok(BoucWenFit {
            with_d0,
            with_h0: false,
            refit: None,
            refits: std::sync::Mutex::new(None),
            data,
            bounds,
            scheme: BoucWenScheme::Fast { substeps: 0 },
            fast,
        }
        .with_initial_states(true))
    }

    /// With several training records, fit each one's initial state (`on`, the default) or
    /// start every record from rest. One training record always starts from rest.
    pub fn with_initial_states(mut self, on: bool) -> Self {
        let keep = 5 + if self.with_d0 { self.fast.len() } else { 0 };
        self.with_h0 = on && self.fast.len() > 1;
        let states = if self.with_h0 { self.fast.len() } else { 0 };
        let (mut lower, mut upper) = (
            self.bounds.lower()[..keep].to_vec(),
            self.bounds.upper()[..keep].to_vec(),
        );
        lower.extend(std::iter::repeat_n(-1.0, states));
        upper.extend(std::iter::repeat_n(1.0, states));
        self.bounds = Bounds::new(lower, upper).expect("valid bounds stay valid");
        self
    }

    /// Sub-steps of the fast scheme on validation records (the most any training record
    /// uses; 0 for the other schemes).
    #[cfg(test)]
    fn scheme_substeps(&self) -> usize {
        match self.scheme() {
            BoucWenScheme::Fast { substeps } => substeps,
            _ => 0,
        }
    }

    /// Whether every training record gets an initial state of its own.
    pub fn fits_initial_states(&self) -> bool {
        self.with_h0
    }

    /// Whether validation records get their offset and initial state refitted on them:
    /// `Some(true)` always, `Some(false)` never (the dissertation's protocol: from rest with the
    /// first training record's offset), `None` (the default) with more than one training or
    /// more than one validation record.
    pub fn with_validation_refit(mut self, refit: Option<bool>) -> Self {
        self.refit = refit;
        self
    }

    /// Whether validation records get their offset and initial state refitted.
    pub fn refits_validation(&self) -> bool {
        let held = self.data.recordings.len() - self.fast.len();
        held > 0 && self.refit.unwrap_or(held > 1 || self.fast.len() > 1)
    }

    /// Position of training record `r`'s initial-state fraction in a parameter vector.
    fn state_at(&self, r: usize) -> Option<usize> {
        self.with_h0
            .then(|| 5 + if self.with_d0 { self.fast.len() } else { 0 } + r)
    }

    /// The same fit integrated by `scheme` (default: fast, automatic sub-steps).
    pub fn with_scheme(mut self, scheme: BoucWenScheme) -> Self {
        for (f, t) in self.fast.iter_mut().zip(self.data.trains()) {
            match scheme {
                BoucWenScheme::Fast { substeps } => *f = FastInput::new(&t.u, &t.y, substeps),
                BoucWenScheme::Explicit => *f = FastInput::explicit(&t.u, &t.y),
                BoucWenScheme::Accurate => {}
            }
        }
        self.scheme = scheme;
        self
    }

    /// The scheme in use, with the sub-step count resolved (the most any record uses).
    pub fn scheme(&self) -> BoucWenScheme {
        match self.scheme {
            BoucWenScheme::Fast { .. } => BoucWenScheme::Fast {
                substeps: self.fast.iter().map(FastInput::substeps).max().unwrap_or(1),
            },
            other => other,
        }
    }

    /// The parameters on training record `r` (its own offset).
    fn params(&self, p: &[f64], r: usize) -> BoucWenParams {
        BoucWenParams {
            d_e: p[0],
            alpha: p[1],
            beta: p[2],
            gamma: p[3],
            n: p[4],
            d0: if self.with_d0 { p[5 + r] } else { 0.0 },
        }
    }

    /// Training record `r`'s initial state (normalised; 0: from rest).
    fn train_state(&self, p: &[f64], params: &BoucWenParams, r: usize) -> f64 {
        self.state_at(r)
            .map_or(0.0, |i| initial_state(params, p[i]))
    }

    /// The parameters and initial state on set `set`: a training record's own; a validation
    /// record's refitted on it ([`Self::refit`]) with several records, else the first
    /// training record's d0 and the state of rest.
    fn params_and_state(&self, p: &[f64], set: usize) -> (BoucWenParams, f64) {
        if set < self.fast.len() {
            let params = self.params(p, set);
            return (params, self.train_state(p, &params, set));
        }
        let params = self.params(p, 0);
        if !self.refits_validation() {
            return (params, 0.0);
        }
        let (d0, h0) = self.refit_at(p, &params, set);
        (BoucWenParams { d0, ..params }, h0)
    }

    /// Free run on set `set` (normalised; NaN from a blow-up on).
    fn run(&self, params: &BoucWenParams, h0: f64, set: usize) -> Vec<f64> {
        let Some(d) = self.data.get(set) else {
            return Vec::new();
        };
        let mut out = vec![0.0; d.u.len()];
        let status = match self.scheme() {
            // A training record at its own sub-steps, a validation record at the most any
            // training record uses.
            BoucWenScheme::Fast { substeps } => {
                let own = self.fast.get(set).map_or(substeps, FastInput::substeps);
                bouc_wen_fast::simulate_from(params, h0, &d.u, own, &mut out)
            }
            BoucWenScheme::Explicit => {
                bouc_wen_fast::simulate_explicit_from(params, h0, &d.u, &mut out)
            }
            BoucWenScheme::Accurate => bouc_wen::simulate_from(params, h0, &d.u, &mut out),
        };
        if let SimStatus::Unstable { at } = status {
            out[at..].fill(f64::NAN);
        }
        out
    }

    /// [`Self::refit`] of validation set `set` at point `p`, computed once per point.
    /// Trials running in parallel may ask for other points: the lock is not held while a
    /// refit runs, and the last point asked wins the cache.
    fn refit_at(&self, p: &[f64], params: &BoucWenParams, set: usize) -> (f64, f64) {
        let cached = |c: &RefitCache| {
            c.as_ref()
                .filter(|(at, _)| at.as_slice() == p)
                .and_then(|(_, v)| v[set])
        };
        if let Some(v) = cached(&self.refits.lock().expect("not poisoned")) {
            return v;
        }
        let v = self.refit(params, set);
        let mut cache = self.refits.lock().expect("not poisoned");
        if cache.as_ref().is_none_or(|(at, _)| at.as_slice() != p) {
            *cache = Some((p.to_vec(), vec![None; self.data.recordings.len()]));
        }
        if let Some((_, slots)) = cache.as_mut() {
            slots[set] = Some(v);
        }
        v
    }

    /// Validation set `set`'s own offset and initial state `(d0, h0)` (normalised) for the
    /// actuator parameters of `params`: for each initial state the offset minimising the
    /// squared error is the mean residual (0 when d0 is not fitted); the state's fraction of
    /// the saturation level is searched over [-1, 1] on a grid of [`STATE_GRID`] points,
    /// then by golden section between the best point's neighbours. Runs that blow up
    /// count as infinitely bad; if all do, the state of rest and the offset at it.
    fn refit(&self, params: &BoucWenParams, set: usize) -> (f64, f64) {
        let Some(d) = self.data.get(set) else {
            return (params.d0, 0.0);
        };
        let shape = BoucWenParams { d0: 0.0, ..*params };
        // (sse, d0) at fraction q.
        let at = |q: f64| -> (f64, f64) {
            let out = self.run(&shape, initial_state(&shape, q), set);
            let len = out.len().min(d.y.len()) as f64;
            let r = || d.y.iter().zip(&out).map(|(y, m)| y - m);
            let d0 = if self.with_d0 {
                r().sum::<f64>() / len
            } else {
                0.0
            };
            let sse: f64 = r().map(|e| (e - d0) * (e - d0)).sum();
            (if sse.is_finite() { sse } else { f64::INFINITY }, d0)
        };
        if shape.saturation().is_none() {
            let (_, d0) = at(0.0);
            return (if d0.is_finite() { d0 } else { 0.0 }, 0.0);
        }
        let step = 2.0 / (STATE_GRID - 1) as f64;
        let grid = |i: usize| -1.0 + step * i as f64;
        let (mut best_q, mut best) = (0.0, at(0.0));
        for i in 0..STATE_GRID {
            let q = grid(i);
            let v = at(q);
            if v.0 < best.0 {
                (best_q, best) = (q, v);
            }
        }
        if best.0.is_finite() {
            let (mut a, mut b) = ((best_q - step).max(-1.0), (best_q + step).min(1.0));
            let ratio = 0.5 * (5f64.sqrt() - 1.0);
            let (mut x1, mut x2) = (b - ratio * (b - a), a + ratio * (b - a));
            let (mut f1, mut f2) = (at(x1), at(x2));
            for _ in 0..STATE_GOLDEN {
                if f1.0 <= f2.0 {
                    (b, x2, f2) = (x2, x1, f1);
                    x1 = b - ratio * (b - a);
                    f1 = at(x1);
                } else {
                    (a, x1, f1) = (x1, x2, f2);
                    x2 = a + ratio * (b - a);
                    f2 = at(x2);
                }
            }
            for (q, v) in [(x1, f1), (x2, f2)] {
                if v.0 < best.0 {
                    (best_q, best) = (q, v);
                }
            }
        } else {
            best = at(0.0);
            best_q = 0.0;
        }
        let d0 = if best.1.is_finite() { best.1 } else { 0.0 };
        (d0, initial_state(&shape, best_q))
    }

    /// Normalised model output on set `set`; unstable runs keep the samples before the
    /// blow-up and hold the last finite value after it (for plots and metrics only).
    fn simulate(&self, p: &[f64], set: usize) -> Vec<f64> {
        let (params, h0) = self.params_and_state(p, set);
        let mut out = self.run(&params, h0, set);
        hold_finite(&mut out);
        out
    }
}

impl Objective for BoucWenFit {
    fn name(&self) -> &str {
        "bouc-wen"
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, p: &[f64]) -> f64 {
        one_of_batch(self, p)
    }

    /// The sum over training records.
    fn evaluate_batch(&self, points: &[f64], out: &mut [f64]) {
        let d = self.dim();
        out.fill(0.0);
        let mut one = vec![0.0; out.len()];
        for (r, t) in self.data.trains().iter().enumerate() {
            match self.scheme {
                BoucWenScheme::Fast { .. } | BoucWenScheme::Explicit => {
                    let params: Vec<_> =
                        points.chunks_exact(d).map(|p| self.params(p, r)).collect();
                    // From rest (no states: the same bits as before states existed).
                    let states: Vec<f64> = match self.state_at(r) {
                        Some(i) => points
                            .chunks_exact(d)
                            .zip(&params)
                            .map(|(p, q)| initial_state(q, p[i]))
                            .collect(),
                        None => Vec::new(),
                    };
                    bouc_wen_fast::costs_from(&params, &states, &self.fast[r], &mut one);
                }
                BoucWenScheme::Accurate => {
                    for (p, o) in points.chunks_exact(d).zip(one.iter_mut()) {
                        let params = self.params(p, r);
                        let h0 = self.train_state(p, &params, r);
                        *o = bouc_wen::cost_from(&params, h0, &t.u, &t.y);
                    }
                }
            }
            out.iter_mut().zip(&one).for_each(|(o, c)| *o += c);
        }
    }

    /// Unstable runs cost at least the cap (and stable runs beyond it are clipped to it),
    /// on every training record.
    fn penalty_threshold(&self) -> Option<f64> {
        Some(
            self.data
                .trains()
                .iter()
                .map(|t| bouc_wen::cost_cap(&t.y))
                .sum(),
        )
    }

    fn presentation(&self) -> Option<Presentation> {
        Some(self.data.rmse_presentation())
    }

    fn metrics(&self, p: &[f64]) -> Vec<Metric> {
        self.data.free_run_metrics(|k| self.simulate(p, k))
    }

    fn as_fit(&self) -> Option<&dyn FitView> {
        Some(self)
    }
}

impl FitView for BoucWenFit {
    fn recordings(&self) -> Vec<(&str, &Recording)> {
        self.data.recordings()
    }

    fn outputs(&self, p: &[f64], set: usize) -> Vec<(String, Vec<f64>)> {
        let Some(d) = self.data.get(set) else {
            return Vec::new();
        };
        let y = self
            .simulate(p, set)
            .into_iter()
            .map(|v| v * d.y_scale)
            .collect();
        vec![("Bouc-Wen".to_string(), y)]
    }

    /// d_e, alpha and d0 in the recording's units (output per input, output); beta, gamma
    /// and n as fitted (on normalised data they act on the normalised state); with several
    /// training records each one's initial state `h0` (output units), and with several
    /// records each validation record's refitted `validate <name> d0` and `h0`.
    fn named_params(&self, p: &[f64]) -> Vec<(String, f64)> {
        let t = self.data.train();
        let scaled = t.u_scale != 1.0 || t.y_scale != 1.0;
        let tag = if scaled { " (normalised)" } else { "" };
        let (us, ys) = (t.u_scale, t.y_scale);
        let train = &self.data.recordings[0].1;
        let (uu, yu) = (&train.units[1], &train.units[2]);
        let ratio = if uu.is_empty() && yu.is_empty() {
            String::new()
        } else {
            format!(" [{yu}/{uu}]")
        };
        let mut v = vec![
            (format!("d_e{ratio}"), p[0] * ys / us),
            (format!("alpha{ratio}"), p[1] * ys / us),
            (format!("beta{tag}"), p[2]),
            (format!("gamma{tag}"), p[3]),
            ("n".into(), p[4]),
        ];
        if self.with_d0 {
            for r in 0..self.fast.len() {
                v.push((format!("d0{} [{yu}]", record_tag(r)), p[5 + r] * ys));
            }
        }
        if self.with_h0 {
            for r in 0..self.fast.len() {
                let h0 = self.train_state(p, &self.params(p, r), r);
                v.push((format!("h0{} [{yu}]", record_tag(r)), h0 * ys));
            }
        }
        if self.refits_validation() {
            let sets = self.data.recordings.len();
            for set in self.fast.len()..sets {
                let (params, h0) = self.params_and_state(p, set);
                let label = &self.data.recordings[set].0;
                if self.with_d0 {
                    v.push((format!("validate {label} d0 [{yu}]"), params.d0 * ys));
                }
                v.push((format!("validate {label} h0 [{yu}]"), h0 * ys));
            }
        }
        v
    }

    /// The parameters de-normalised: with `u = u_s u'` and `y = y_s y'` (the scales the
    /// search ran on), `d_e` and `α` scale by `y_s/u_s`, `β` and `γ` by
    /// `1/(u_s y_s^(n-1))`, offsets and states by `y_s`; each record's own offset and
    /// initial state (refitted ones for validation records where the fit refits them).
    fn model(&self, p: &[f64]) -> ModelFile {
        let t = self.data.train();
        let (us, ys) = (t.u_scale, t.y_scale);
        let (units, ratio) = units_of(&self.data.recordings[0].1);
        let shape_unit = if ratio.is_empty() {
            String::new()
        } else {
            format!("{}^(1-n)/{}", units.output, units.input)
        };
        let (lo, hi) = (self.bounds.lower(), self.bounds.upper());
        let n = p[4];
        let shape = 1.0 / (us * ys.powf(n - 1.0));
        let mut params: Vec<Param> = [
            ("d_e", ys / us, ratio.as_str()),
            ("alpha", ys / us, ratio.as_str()),
            ("beta", shape, shape_unit.as_str()),
            ("gamma", shape, shape_unit.as_str()),
            ("n", 1.0, ""),
        ]
        .into_iter()
        .enumerate()
        .map(|(i, (name, k, unit))| Param::new(name, p[i] * k, unit).searched(p[i], lo[i], hi[i]))
        .collect();
        if self.with_d0 {
            for r in 0..self.fast.len() {
                let x = 5 + r;
                params.push(
                    Param::new(
                        format!("d0{}", record_tag(r)),
                        p[x] * ys,
                        units.output.clone(),
                    )
                    .searched(p[x], lo[x], hi[x]),
                );
            }
        }
        for r in 0..self.fast.len() {
            if let Some(x) = self.state_at(r) {
                let h0 = self.train_state(p, &self.params(p, r), r);
                params.push(
                    Param::new(
                        format!("h0{}", record_tag(r)),
                        h0 * ys,
                        units.output.clone(),
                    )
                    .searched(p[x], lo[x], hi[x]),
                );
            }
        }
        let (scheme, substeps) = match self.scheme() {
            BoucWenScheme::Fast { substeps } => ("fast", Some(substeps)),
            BoucWenScheme::Accurate => ("accurate", None),
            BoucWenScheme::Explicit => ("explicit", None),
        };
        let records = self
            .data
            .recordings
            .iter()
            .enumerate()
            .map(|(set, (label, rec))| {
                let (params, h0) = self.params_and_state(p, set);
                RecordState {
                    label: label.clone(),
                    name: rec.name.clone(),
                    sampling_interval_s: rec.dt(),
                    d0: Some(params.d0 * ys),
                    h0: Some(h0 * ys),
                    substeps: substeps.map(|m| self.fast.get(set).map_or(m, FastInput::substeps)),
                    shape: Vec::new(),
                    linear: Vec::new(),
                }
            })
            .collect();
        let mut m = ModelFile::new(
            "bouc-wen",
            "Bouc-Wen (dissertation eq. 3.1-3.3): y = d_e u + d0 - h, dh = alpha du - beta |du| |h|^(n-1) h - gamma du |h|^n, integrated in the input",
            units,
            self.data.recordings[0].1.dt(),
            Normalisation {
                input_scale: us,
                output_scale: ys,
            },
            Integration {
                scheme: scheme.into(),
                substeps,
                hold: None,
            },
            "from rest (h0 = 0) at the first sample, offset d0 (the first training record's; 0 when not fitted); with --record LABEL from that record's own d0 and h0 (records)",
            params,
        );
        m.records = records;
        m
    }
}

/// The suffix naming record `r`'s own parameter (`d0`, `d0@2`, ...): none for the first.
fn record_tag(r: usize) -> String {
    if r == 0 {
        String::new()
    } else {
        format!("@{}", r + 1)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn eq318_recording(n: usize) -> Recording {
        let r: Vec<f64> = (0..n)
            .map(|k| (2.0 * std::f64::consts::PI * 20.0 * k as f64 * 1e-3).sin())
            .collect();
        let y = rbf::eq_3_18(&r);
        Recording::uniform("eq318", 1e-3, r, y).unwrap()
    }

    use rand::RngExt;

    /// The generating Bouc-Wen model of the initial-state tests (saturation 1/0.9).
    pub(crate) const TRUTH: BoucWenParams = BoucWenParams {
        d_e: 0.8,
        alpha: 1.0,
        beta: 0.6,
        gamma: 0.3,
        n: 1.0,
        d0: 0.0,
    };
    pub(crate) const TRUTH_X: [f64; 5] = [TRUTH.d_e, TRUTH.alpha, TRUTH.beta, TRUTH.gamma, TRUTH.n];

    /// A record of [`TRUTH`] (accurate kernel) at 2 ms: a two-tone drive of base frequency
    /// `f` in [0.05, 0.95], simulated from rest for `skip + samples` samples of which the
    /// first `skip` are dropped (`skip > 0`: the record starts mid-loop), plus offset `d0`
    /// and uniform noise of amplitude `noise` (seeded). Returns the record and the true
    /// hysteretic state at its first sample.
    pub(crate) fn bw_record(
        name: &str,
        f: f64,
        skip: usize,
        samples: usize,
        d0: f64,
        noise: f64,
        seed: u64,
    ) -> (Recording, f64) {
        let tau = 2.0 * std::f64::consts::PI;
        let u: Vec<f64> = (0..skip + samples)
            .map(|k| {
                let t = k as f64 * 2e-3;
                0.5 - 0.4 * (tau * f * t).cos() + 0.05 * (tau * 3.1 * f * t).sin()
            })
            .collect();
        let mut y = vec![0.0; u.len()];
        assert_eq!(bouc_wen::simulate(&TRUTH, &u, &mut y), SimStatus::Ok);
        let h0 = TRUTH.d_e * u[skip] - y[skip];
        let mut rng = crate::base::TrialSeed::from_u64(seed).rng(0);
        let y: Vec<f64> = y[skip..]
            .iter()
            .map(|v| v + d0 + noise * (2.0 * rng.random::<f64>() - 1.0))
            .collect();
        let rec = Recording::uniform(name, 2e-3, u[skip..].to_vec(), y).unwrap();
        (rec, h0)
    }

    pub(crate) fn named(obj: &dyn Objective, x: &[f64], name: &str) -> f64 {
        let v = obj.as_fit().unwrap().named_params(x);
        v.iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no {name} in {v:?}"))
            .1
    }

    pub(crate) fn metric(obj: &dyn Objective, x: &[f64], name: &str) -> f64 {
        let m = obj.metrics(x);
        m.iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("no {name} in {m:?}"))
            .value
    }

    /// A validation record with an offset and a mid-loop start of its own, beside two
    /// training records: at the actuator's true parameters its refitted offset and initial
    /// state are the truth's and its RMSE is the noise's, where the dissertation's protocol (the
    /// first training record's offset, from rest) is far off.
    #[test]
    fn validation_records_get_their_offset_and_initial_state_refitted() {
        let (a, _) = bw_record("a", 1.0, 0, 750, 0.02, 0.0, 1);
        let (b, b0) = bw_record("b", 0.7, 1071, 900, 0.07, 0.0, 2);
        let noise = 0.004; // uniform: sigma = noise / sqrt(3)
        let sigma = noise / 3f64.sqrt();
        let (v, v0) = bw_record("v", 0.9, 1300, 1000, -0.03, noise, 3);
        let sat = TRUTH.saturation().unwrap();
        assert!(v0.abs() > 0.1 * sat, "mid-loop: {v0}");
        let fit = BoucWenFit::new(
            &[a.clone(), b],
            &[("v".into(), v.clone())],
            true,
            false,
            0.0,
            1.5,
        )
        .unwrap();
        assert_eq!(fit.dim(), 9);
        let mut x: Vec<f64> = TRUTH_X.to_vec();
        x.extend([0.02, 0.07, 0.0, b0 / sat]);
        let rmse = metric(&fit, &x, "v RMSE");
        let d0 = named(&fit, &x, "validate v d0 []");
        let h0 = named(&fit, &x, "validate v h0 []");
        // The dissertation's protocol: from rest with the first record's offset.
        let old = {
            let mut out = vec![0.0; v.len()];
            let p = BoucWenParams { d0: 0.02, ..TRUTH };
            bouc_wen_fast::simulate(&p, &v.u, fit.scheme_substeps(), &mut out);
            errors(&v.y, &out, 0, 1.0).1
        };
        eprintln!(
            "validation RMSE {rmse:.5} (noise sigma {sigma:.5}; seed's protocol {old:.4}); \
             d0 {d0:.5} vs -0.03, h0 {h0:.5} vs {v0:.5}"
        );
        assert!(
            rmse < 1.05 * sigma && rmse > 0.95 * sigma,
            "{rmse} vs {sigma}"
        );
        assert!((d0 + 0.03).abs() < 5e-4, "d0 {d0}");
        assert!((h0 - v0).abs() < 0.01 * sat, "h0 {h0} vs {v0}");
        assert!(old > 10.0 * rmse, "{old}");
        // Training records keep their own: the first from (almost) rest, the second mid-loop.
        assert!((named(&fit, &x, "h0@2 []") - b0).abs() < 1e-12);
        // One training and two validation records: refitted too (the same record twice).
        let two = BoucWenFit::new(
            std::slice::from_ref(&a),
            &[("v".into(), v.clone()), ("w".into(), v)],
            true,
            false,
            0.0,
            1.5,
        )
        .unwrap();
        assert_eq!(two.dim(), 6);
        let x1: Vec<f64> = TRUTH_X.iter().copied().chain([0.02]).collect();
        assert_eq!(named(&two, &x1, "validate w h0 []"), h0);
        assert_eq!(metric(&two, &x1, "w RMSE"), rmse);
    }

    /// One training and one validation record: the dissertation's protocol, bit for bit (training
    /// from rest; validation from rest with the training record's offset), on every scheme.
    #[test]
    fn one_training_and_one_validation_record_keep_the_seed_protocol() {
        let (a, _) = bw_record("a", 1.0, 0, 750, 0.02, 0.001, 1);
        let (v, _) = bw_record("v", 0.9, 1300, 1000, -0.03, 0.001, 3);
        let x: Vec<f64> = vec![0.79, 1.02, 0.58, 0.33, 0.97, 0.015];
        let p = BoucWenParams {
            d_e: x[0],
            alpha: x[1],
            beta: x[2],
            gamma: x[3],
            n: x[4],
            d0: x[5],
        };
        for scheme in [
            BoucWenScheme::Fast { substeps: 0 },
            BoucWenScheme::Accurate,
            BoucWenScheme::Explicit,
        ] {
            let fit = BoucWenFit::new(
                std::slice::from_ref(&a),
                &[("v".into(), v.clone())],
                true,
                false,
                0.0,
                1.5,
            )
            .unwrap()
            .with_scheme(scheme);
            assert!(!fit.fits_initial_states() && !fit.refits_validation());
            assert_eq!(fit.dim(), 6);
            let names: Vec<String> = fit.named_params(&x).into_iter().map(|n| n.0).collect();
            assert!(names.iter().all(|n| !n.contains("h0")), "{names:?}");
            // The old way: free runs from rest.
            let run = |u: &[f64], out: &mut [f64]| match scheme {
                BoucWenScheme::Fast { .. } => {
                    bouc_wen_fast::simulate(&p, u, fit.scheme_substeps(), out)
                }
                BoucWenScheme::Accurate => bouc_wen::simulate(&p, u, out),
                BoucWenScheme::Explicit => bouc_wen_fast::simulate_explicit(&p, u, out),
            };
            let (mut ta, mut tv) = (vec![0.0; a.len()], vec![0.0; v.len()]);
            assert_eq!(run(&a.u, &mut ta), SimStatus::Ok);
            assert_eq!(run(&v.u, &mut tv), SimStatus::Ok);
            let (max, rms) = errors(&v.y, &tv, 0, 1.0);
            assert_eq!(metric(&fit, &x, "v RMSE").to_bits(), rms.to_bits());
            assert_eq!(metric(&fit, &x, "v max error").to_bits(), max.to_bits());
            let (_, train) = errors(&a.y, &ta, 0, 1.0);
            assert_eq!(metric(&fit, &x, "train RMSE").to_bits(), train.to_bits());
            let batched = |input: FastInput| {
                let mut c = [0.0];
                bouc_wen_fast::costs(&[p], &input, &mut c);
                c[0]
            };
            let cost = match scheme {
                BoucWenScheme::Accurate => bouc_wen::cost(&p, &a.u, &a.y),
                BoucWenScheme::Explicit => batched(FastInput::explicit(&a.u, &a.y)),
                BoucWenScheme::Fast { .. } => batched(FastInput::new(&a.u, &a.y, 0)),
            };
            assert_eq!(fit.evaluate(&x).to_bits(), cost.to_bits());
            // `refit_validation = "never"` keeps this protocol with several validation
            // records (a benchmark's official test); "always" refits a single one.
            let make = |vs: &[(String, Recording)], refit| {
                BoucWenFit::new(std::slice::from_ref(&a), vs, true, false, 0.0, 1.5)
                    .unwrap()
                    .with_scheme(scheme)
                    .with_validation_refit(refit)
            };
            let twice = [("v".into(), v.clone()), ("w".into(), v.clone())];
            let never = make(&twice, Some(false));
            assert!(!never.refits_validation());
            assert_eq!(metric(&never, &x, "w RMSE").to_bits(), rms.to_bits());
            assert!(make(&twice, None).refits_validation());
            let always = make(&twice[..1], Some(true));
            assert!(always.refits_validation());
            assert!(metric(&always, &x, "v RMSE") < rms);
            assert!(make(&[], Some(true)).named_params(&x).len() == 6);
        }
    }

    /// The written model (de-normalised, run in the recording's units) predicts what the
    /// fit scored, on normalised data, for every record: Bouc-Wen with several records
    /// (each its own offset and state, the validation one refitted) and the RBF network.
    #[test]
    fn the_model_file_reproduces_the_fits_errors() {
        use crate::physics::model_file::Input;
        let scaled = |r: Recording, k: f64| {
            let u = r.u.iter().map(|v| 3.0 * v).collect();
            let y = r.y.iter().map(|v| k * v).collect();
            Recording::uniform(r.name.clone(), r.dt(), u, y).unwrap()
        };
        let (a, _) = bw_record("a", 1.0, 0, 750, 0.02, 0.001, 1);
        let (b, _) = bw_record("b", 0.7, 1071, 900, 0.07, 0.001, 2);
        let (v, _) = bw_record("v", 0.9, 1300, 1000, -0.03, 0.001, 3);
        let (a, b, v) = (scaled(a, 0.2), scaled(b, 0.2), scaled(v, 0.2));
        let fit = BoucWenFit::new(&[a, b], &[("v".into(), v)], true, true, 0.0, 1.5).unwrap();
        let x = [0.9, 1.1, 0.55, 0.35, 0.9, 0.1, 0.3, 0.2, -0.4];
        let path = std::path::Path::new("model.json");
        let check = |obj: &dyn Objective, x: &[f64], metric_of: &dyn Fn(&str) -> String| {
            let m = obj.as_fit().unwrap().model(x);
            for (label, rec) in obj.as_fit().unwrap().recordings() {
                let own = m.records.iter().any(|r| r.label == label);
                let input = Input {
                    u: &rec.u,
                    y: Some(&rec.y),
                    dt: rec.dt(),
                };
                let out = m.run(path, &input, own.then_some(label)).unwrap();
                let got = m.rmse(&rec.y, &out);
                let want = metric(obj, x, &metric_of(label));
                assert!(
                    (got - want).abs() <= 1e-9 * want,
                    "{label}: {got} vs {want}"
                );
            }
        };
        check(&fit, &x, &|l| format!("{l} RMSE"));
        let rec = eq318_recording(400);
        let rbf = RbfFit::new(
            std::slice::from_ref(&rec),
            &[("validate".into(), scaled(eq318_recording(300), 2.0))],
            RbfNet::new(3, 7),
            Narx::SEED,
            Mode::OneStepAhead,
        )
        .unwrap();
        let mut rng = crate::base::TrialSeed::from_u64(4).rng(0);
        let mut p = vec![0.0; 35];
        rbf.bounds().sample(&mut rng, &mut p);
        check(&rbf, &p, &|l| format!("{l} free-run RMSE"));
    }

    #[test]
    fn costs_are_finite_and_presented_as_rmse() {
        let rec = eq318_recording(500);
        let fit = RbfFit::new(
            std::slice::from_ref(&rec),
            &[("validate".into(), rec.clone())],
            RbfNet::new(3, 7),
            Narx::SEED,
            Mode::FreeRun,
        )
        .unwrap();
        assert_eq!(fit.dim(), 35);
        let p: Vec<f64> = fit
            .bounds()
            .lower()
            .iter()
            .zip(fit.bounds().upper())
            .map(|(l, u)| 0.5 * (l + u))
            .collect();
        let j = fit.evaluate(&p);
        assert!(j.is_finite() && j > 0.0);
        // The presented RMSE equals the free-run RMSE metric on the training data.
        let rmse = fit.presentation().unwrap().apply(j);
        let m = fit.metrics(&p);
        let free = m
            .iter()
            .find(|m| m.name == "train free-run RMSE")
            .unwrap()
            .value;
        assert!(
            (rmse - free).abs() < 1e-12 * (1.0 + free),
            "{rmse} vs {free}"
        );
        assert_eq!(
            m.len(),
            8,
            "train and validate x one-step and free-run x RMSE and max"
        );
        // Hostile parameters: finite.
        let hostile = vec![f64::MAX; 35];
        assert!(fit.evaluate(&hostile).is_finite());
    }

    #[test]
    fn one_step_mode_has_the_gradient_of_its_cost() {
        let rec = eq318_recording(300);
        let net = |mode| {
            RbfFit::new(
                std::slice::from_ref(&rec),
                &[],
                RbfNet::new(3, 7),
                Narx::SEED,
                mode,
            )
            .unwrap()
        };
        let fit = net(Mode::OneStepAhead);
        assert!(fit.has_gradient());
        let mut rng = crate::base::TrialSeed::from_u64(9).rng(0);
        let mut p = vec![0.0; 35];
        fit.bounds().sample(&mut rng, &mut p);
        let mut g = vec![0.0; 35];
        let j = fit.value_and_gradient(&p, &mut g).unwrap();
        assert_eq!(j, fit.evaluate(&p));
        assert!(!net(Mode::FreeRun).has_gradient());
    }
}
