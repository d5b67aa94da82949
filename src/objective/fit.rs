//! Fitting objectives: the cost of a model's parameters on a recording.
//!
//! Data are normalised before fitting (input and output divided by their largest absolute
//! value on the training record), so one set of parameter bounds serves an actuator in
//! volts and millimetres and a benchmark in newtons and metres alike; validation data use
//! the training scales. Costs are J = sum(e^2)/2 (seed eq. 3.8-3.9) in normalised units;
//! reports present them as RMSE in the recording's units.

use super::{Bounds, Metric, Objective, Presentation, PresentationKind};
use crate::error::{Error, Result};
use crate::physics::bouc_wen_fast::{self, FastInput};
use crate::physics::rbf::{self, Mode, Narx, RbfNet, Regressors};
use crate::physics::rbf_fast::RbfBatch;
use crate::recording::Recording;

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

    fn unit_suffix(&self) -> String {
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
    fn train_samples(&self) -> usize {
        self.trains().iter().map(|d| d.u.len()).sum()
    }

    /// (label, scaled data) of every set, training first.
    pub fn sets(&self) -> impl Iterator<Item = (&str, &FitData)> {
        self.recordings
            .iter()
            .map(|(l, _)| l.as_str())
            .zip(&self.scaled)
    }

    fn get(&self, set: usize) -> Option<&FitData> {
        self.scaled.get(set)
    }

    fn recordings(&self) -> Vec<(&str, &Recording)> {
        self.recordings
            .iter()
            .map(|(l, r)| (l.as_str(), r))
            .collect()
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
fn hold_finite(out: &mut [f64]) {
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

/// Fit of a Gaussian RBF NARX network (seed section 3.2) to one or several recordings
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
}

impl Objective for RbfFit {
    fn name(&self) -> &str {
        "rbf"
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, p: &[f64]) -> f64 {
        let mut out = [0.0];
        self.evaluate_batch(p, &mut out);
        out[0]
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

/// Fit of the seed's Bouc-Wen model (eq. 3.1-3.3) to one or several recordings:
/// parameters (d_e, alpha, beta, gamma, n) and optionally an offset d0 per training record,
/// in normalised units, cost from a free-run simulation of each record (eq. 3.8-3.9),
/// summed. The model is rate-independent, so records at any sampling intervals fit
/// together. Unstable parameters cost a large finite penalty.
pub struct BoucWenFit {
    with_d0: bool,
    data: Datasets,
    bounds: Bounds,
    scheme: BoucWenScheme,
    /// Each training record prepared for the fast scheme.
    fast: Vec<FastInput>,
}

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
/// `n` when fitted).
pub const BOUC_WEN_PARAMS: [&str; 6] = ["d_e", "alpha", "beta", "gamma", "n", "d0"];

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
            data,
            bounds,
            scheme: BoucWenScheme::Fast { substeps: 0 },
            fast,
        })
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

    /// The parameters on set `set` (a training record's own offset; a validation record
    /// gets the first training record's).
    fn params(&self, p: &[f64], set: usize) -> crate::physics::bouc_wen::BoucWenParams {
        let own = if set < self.fast.len() { set } else { 0 };
        crate::physics::bouc_wen::BoucWenParams {
            d_e: p[0],
            alpha: p[1],
            beta: p[2],
            gamma: p[3],
            n: p[4],
            d0: if self.with_d0 { p[5 + own] } else { 0.0 },
        }
    }

    /// Normalised model output on set `set`; unstable runs keep the samples before the
    /// blow-up and hold the last finite value after it (for plots and metrics only).
    fn simulate(&self, p: &[f64], set: usize) -> Vec<f64> {
        let Some(d) = self.data.get(set) else {
            return Vec::new();
        };
        let mut out = vec![0.0; d.u.len()];
        let params = self.params(p, set);
        let status = match self.scheme() {
            // A training record at its own sub-steps, a validation record at the most any
            // training record uses.
            BoucWenScheme::Fast { substeps } => {
                let own = self.fast.get(set).map_or(substeps, FastInput::substeps);
                bouc_wen_fast::simulate(&params, &d.u, own, &mut out)
            }
            BoucWenScheme::Explicit => bouc_wen_fast::simulate_explicit(&params, &d.u, &mut out),
            BoucWenScheme::Accurate => crate::physics::bouc_wen::simulate(&params, &d.u, &mut out),
        };
        if let crate::physics::bouc_wen::SimStatus::Unstable { at } = status {
            out[at..].fill(f64::NAN);
        }
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
        let mut out = [0.0];
        self.evaluate_batch(p, &mut out);
        out[0]
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
                    bouc_wen_fast::costs(&params, &self.fast[r], &mut one);
                }
                BoucWenScheme::Accurate => {
                    for (p, o) in points.chunks_exact(d).zip(one.iter_mut()) {
                        *o = crate::physics::bouc_wen::cost(&self.params(p, r), &t.u, &t.y);
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
                .map(|t| crate::physics::bouc_wen::cost_cap(&t.y))
                .sum(),
        )
    }

    fn presentation(&self) -> Option<Presentation> {
        let t = self.data.train();
        Some(Presentation {
            label: format!("train RMSE{}", t.unit_suffix()),
            kind: PresentationKind::RmseFromHalfSse {
                samples: self.data.train_samples(),
                scale: t.y_scale,
            },
        })
    }

    fn metrics(&self, p: &[f64]) -> Vec<Metric> {
        let unit = self.data.train().unit_suffix();
        let mut m = Vec::new();
        for (k, (set, d)) in self.data.sets().enumerate() {
            let (max, rms) = errors(&d.y, &self.simulate(p, k), 0, d.y_scale);
            m.push(Metric::new(format!("{set} RMSE{unit}"), rms));
            m.push(Metric::new(format!("{set} max error{unit}"), max));
        }
        m
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
    /// and n as fitted (on normalised data they act on the normalised state).
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
                let at = if r == 0 {
                    String::new()
                } else {
                    format!("@{}", r + 1)
                };
                v.push((format!("d0{at} [{yu}]"), p[5 + r] * ys));
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eq318_recording(n: usize) -> Recording {
        let r: Vec<f64> = (0..n)
            .map(|k| (2.0 * std::f64::consts::PI * 20.0 * k as f64 * 1e-3).sin())
            .collect();
        let y = rbf::eq_3_18(&r);
        Recording::uniform("eq318", 1e-3, r, y).unwrap()
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
        let mut rng = crate::harness::TrialSeed::from_u64(9).rng(0);
        let mut p = vec![0.0; 35];
        fit.bounds().sample(&mut rng, &mut p);
        let mut g = vec![0.0; 35];
        let j = fit.value_and_gradient(&p, &mut g).unwrap();
        assert_eq!(j, fit.evaluate(&p));
        assert!(!net(Mode::FreeRun).has_gradient());
    }
}
