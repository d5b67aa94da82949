//! Fitting objectives of the operator models (Prandtl-Ishlinskii, Preisach): models whose
//! output is linear in their weights once their shape (PI thresholds, a Preisach grid) is
//! fixed ([`LinearInWeights`]).
//!
//! Same data handling as the Bouc-Wen and RBF fits ([`Datasets`]: normalised by the
//! training record's largest values, validation records scaled alike) and the same cost,
//! J = Σe²/2 of the free run on the training records: an operator model has no output
//! feedback, so its free run is its one-step output. Two searches:
//!
//! - **weights** (shape fixed, the coefficients searched): J is a convex quadratic whose
//!   exact minimum over the box is the non-negative least-squares solution ([`nnls`]), so
//!   the objective knows its [`Objective::optimum`] and suites report every optimizer's
//!   distance to it on a real hysteresis fit;
//! - **all** (PI: thresholds and coefficients): the full nonlinear problem; no known optimum.
//!
//! The coefficient box is chosen from the data, not from the optimum: coefficient `j` of
//! column `c_j` ranges over `|θ_j| · rms(c_j) ≤ B` (`coefficient_bound`, in units of the
//! normalised output, whose largest value is 1), non-negative weights from 0. The RMS, not
//! the largest value, so that a rate column's few spikes do not shut its weight in. A build whose
//! least-squares optimum lies outside that box fails with the coefficient named, so the
//! reported optimum is always one the optimizers can reach.

use super::hysteresis::{Datasets, FitView, hold_finite, units_of};
use super::{Bounds, Metric, Objective, Presentation};
use crate::base::error::{Error, Result};
use crate::base::lstsq::nnls;
use crate::data::recording::Recording;
use crate::physics::bouc_wen::cost_cap;
use crate::physics::model_file::{Integration, ModelFile, Normalisation, Param, Units};
use crate::physics::prandtl_ishlinskii::{LinearInWeights, PiBasis, PiForm, PiModel};
use crate::physics::preisach::PreisachGrid;

/// A shape an operator fit searches the weights of: its [`LinearInWeights`] columns, and
/// the model file of a set of weights. Implement it (and build the fit with
/// [`OperatorFit::weights`]) to fit another operator model.
pub trait OperatorBasis: LinearInWeights + Send + Sync {
    /// The objective's and the model file's kind (`pi`, `preisach`).
    fn kind(&self) -> &'static str;
    /// A short label for plots, e.g. `PI (asymmetric, 10 operators)`.
    fn label(&self) -> String;
    /// The model with coefficients `theta`, fitted on input / `scales.0` and output /
    /// `scales.1`, as a model file in physical units that runs again: one parameter per
    /// coefficient first, in [`LinearInWeights::names`] order, then any fixed shape
    /// parameters.
    fn model_file(&self, theta: &[f64], scales: (f64, f64), units: Units, dt: f64) -> ModelFile;
}

/// What a fit searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OperatorSearch {
    /// The coefficients, the shape fixed (exact optimum known).
    Weights,
    /// PI thresholds and coefficients.
    All,
}

/// Smallest threshold increment of the `all` search (the largest is 1): adjacent plays are
/// at least this share of the mean spacing apart, so thresholds stay strictly ordered.
pub const MIN_INCREMENT: f64 = 0.05;

/// PI thresholds searched (`search = all`) as `n` positive increments `s_k` in
/// [[`MIN_INCREMENT`], 1]: `r_0 = 0`, `r_i = r_max · Σ_{k≤i} s_k / Σ_{k≤n} s_k` for
/// `i < n`, `r_max` half the training input's range. Any increments give strictly
/// increasing thresholds inside `[0, r_max)` (the last increment is the gap to `r_max`);
/// equal increments give the uniform thresholds of the `weights` search.
#[derive(Debug, Clone)]
struct PiThresholds {
    form: PiForm,
    n: usize,
    r_max: f64,
}

impl PiThresholds {
    fn thresholds(&self, s: &[f64]) -> Vec<f64> {
        let total: f64 = s.iter().sum();
        let mut cum = 0.0;
        let mut r = vec![0.0];
        for &x in &s[..self.n - 1] {
            cum += x;
            r.push(self.r_max * cum / total);
        }
        r
    }
}

/// Row-major columns of one record: `rows[k * d + j]` is column `j` at sample `k`.
struct Rows {
    d: usize,
    rows: Vec<f64>,
}

impl Rows {
    fn new(cols: &[Vec<f64>]) -> Rows {
        let (d, n) = (cols.len(), cols.first().map_or(0, Vec::len));
        let mut rows = vec![0.0; n * d];
        for (j, c) in cols.iter().enumerate() {
            for (k, v) in c.iter().enumerate() {
                rows[k * d + j] = *v;
            }
        }
        Rows { d, rows }
    }

    fn predict(&self, theta: &[f64]) -> Vec<f64> {
        self.rows
            .chunks_exact(self.d)
            .map(|r| r.iter().zip(theta).map(|(a, b)| a * b).sum())
            .collect()
    }
}

/// `Σ θ_j c_j`.
fn combine(cols: &[Vec<f64>], theta: &[f64], len: usize) -> Vec<f64> {
    let mut out = vec![0.0; len];
    for (c, t) in cols.iter().zip(theta) {
        out.iter_mut().zip(c).for_each(|(o, v)| *o += t * v);
    }
    out
}

/// Fit of an operator model to one or several recordings (see the module documentation).
pub struct OperatorFit {
    /// The fixed shape (`all`: the uniform thresholds the bounds come from).
    basis: Box<dyn OperatorBasis>,
    /// PI thresholds searched (`all`), or None.
    shape: Option<PiThresholds>,
    data: Datasets,
    /// The fixed basis's columns on every set (training first), normalised.
    rows: Vec<Rows>,
    /// Which coefficients are constrained to be non-negative.
    nonneg: Vec<bool>,
    bounds: Bounds,
    /// `(J*, θ*)` of the `weights` search.
    optimum: Option<(f64, Vec<f64>)>,
    /// The cost of unusable (non-finite) points, and the clip of finite ones.
    cap: f64,
}

impl OperatorFit {
    /// The weights of `basis` (built on `data`'s normalised inputs) searched, with the
    /// coefficient box of `bound` (see the module documentation). Errors if the exact
    /// optimum lies outside the box.
    pub fn weights(data: Datasets, basis: Box<dyn OperatorBasis>, bound: f64) -> Result<Self> {
        Self::build(data, basis, None, bound)
    }

    /// A PI model of `form` with `n` operators (uniform thresholds for `Weights`),
    /// normalised data.
    pub fn pi(
        train: &[Recording],
        validate: &[(String, Recording)],
        form: PiForm,
        n: usize,
        search: OperatorSearch,
        bound: f64,
    ) -> Result<Self> {
        let data = Datasets::new(train, validate, true)?;
        let u: Vec<f64> = data.trains().iter().flat_map(|d| d.u.clone()).collect();
        let thresholds = PiModel::uniform_thresholds(n, &u);
        // uniform_thresholds spaces r_max / n apart (r_max = half the range).
        let shape = (search == OperatorSearch::All).then(|| PiThresholds {
            form,
            n,
            r_max: n as f64 * thresholds.get(1).copied().unwrap_or(0.0),
        });
        if shape.is_some() && n < 2 {
            return Err(Error::Input(
                "search = \"all\" needs at least 2 operators (the first threshold is fixed at 0)"
                    .into(),
            ));
        }
        Self::build(data, Box::new(PiBasis { form, thresholds }), shape, bound)
    }

    /// A Preisach model on `levels` cells over the normalised training input's range.
    pub fn preisach(
        train: &[Recording],
        validate: &[(String, Recording)],
        levels: usize,
        bound: f64,
    ) -> Result<Self> {
        let data = Datasets::new(train, validate, true)?;
        let u: Vec<f64> = data.trains().iter().flat_map(|d| d.u.clone()).collect();
        let grid = PreisachGrid::for_input(levels, &u).map_err(Error::Input)?;
        Self::build(data, Box::new(grid), None, bound)
    }

    fn build(
        data: Datasets,
        basis: Box<dyn OperatorBasis>,
        shape: Option<PiThresholds>,
        bound: f64,
    ) -> Result<Self> {
        if !(bound.is_finite() && bound > 0.0) {
            return Err(Error::Input(format!(
                "coefficient_bound = {bound}: expected a positive number"
            )));
        }
        let dts: Vec<f64> = data.recordings().iter().map(|(_, r)| r.dt()).collect();
        let cols: Vec<Vec<Vec<f64>>> = data
            .sets()
            .zip(&dts)
            .map(|((_, d), &dt)| basis.columns(&d.u, dt))
            .collect();
        let trains = data.trains().len();
        let d = cols[0].len();
        let names = basis.names();
        let nonneg = basis.nonnegative();
        let samples = data.train_samples() as f64;
        let rms = (0..d).map(|j| {
            let ss: f64 = cols[..trains]
                .iter()
                .flat_map(|c| c[j].iter())
                .map(|v| v * v)
                .sum();
            (ss / samples).sqrt()
        });
        let (mut lower, mut upper) = (Vec::new(), Vec::new());
        if let Some(s) = &shape {
            lower.extend(std::iter::repeat_n(MIN_INCREMENT, s.n));
            upper.extend(std::iter::repeat_n(1.0, s.n));
        }
        for (m, &pos) in rms.zip(&nonneg) {
            let b = if m > 0.0 && m.is_finite() {
                bound / m
            } else {
                bound
            };
            lower.push(if pos { 0.0 } else { -b });
            upper.push(b);
        }
        let bounds = Bounds::new(lower, upper).map_err(Error::Input)?;
        let cap = cost_cap(
            &data
                .trains()
                .iter()
                .flat_map(|t| t.y.clone())
                .collect::<Vec<_>>(),
        );
        let mut fit = OperatorFit {
            basis,
            shape,
            data,
            rows: cols.iter().map(|c| Rows::new(c)).collect(),
            nonneg: nonneg.clone(),
            bounds,
            optimum: None,
            cap,
        };
        if fit.shape.is_none() {
            let stacked: Vec<Vec<f64>> = (0..d)
                .map(|j| cols[..trains].iter().flat_map(|c| c[j].clone()).collect())
                .collect();
            let y: Vec<f64> = fit.data.trains().iter().flat_map(|t| t.y.clone()).collect();
            let theta = nnls(&stacked, &y, &nonneg);
            let (lo, hi) = (fit.bounds.lower(), fit.bounds.upper());
            for j in 0..d {
                if !(lo[j] <= theta[j] && theta[j] <= hi[j]) {
                    return Err(Error::Input(format!(
                        "the least-squares optimum's coefficient {} = {:e} (on normalised data) lies outside its search range [{:e}, {:e}] (coefficient_bound = {bound}: |coefficient| x RMS of its column <= {bound}); raise coefficient_bound so that the box holds the optimum",
                        names[j], theta[j], lo[j], hi[j]
                    )));
                }
            }
            let j = fit.evaluate(&theta);
            fit.optimum = Some((j, theta));
        }
        Ok(fit)
    }

    /// The exact optimum's coefficients (normalised), `weights` search only.
    pub fn optimum_point(&self) -> Option<&[f64]> {
        self.optimum.as_ref().map(|o| o.1.as_slice())
    }

    /// Shape variables and coefficients of `p`.
    fn split<'a>(&self, p: &'a [f64]) -> (&'a [f64], &'a [f64]) {
        p.split_at(self.shape.as_ref().map_or(0, |s| s.n))
    }

    /// The PI basis at the shape variables `s` (`all` search).
    fn pi_at(&self, s: &PiThresholds, x: &[f64]) -> PiBasis {
        PiBasis {
            form: s.form,
            thresholds: s.thresholds(x),
        }
    }

    /// Normalised model output on set `set` (non-finite values held, for plots and metrics
    /// use [`Self::output`]).
    fn raw_output(&self, p: &[f64], set: usize) -> Vec<f64> {
        let (x, theta) = self.split(p);
        match &self.shape {
            None => self.rows[set].predict(theta),
            Some(s) => {
                let Some(d) = self.data.get(set) else {
                    return Vec::new();
                };
                let dt = self.data.recordings()[set].1.dt();
                combine(&self.pi_at(s, x).columns(&d.u, dt), theta, d.u.len())
            }
        }
    }

    fn output(&self, p: &[f64], set: usize) -> Vec<f64> {
        let mut out = self.raw_output(p, set);
        hold_finite(&mut out);
        out
    }

    /// Residuals `y - model` over the training records, in order.
    fn train_residuals(&self, p: &[f64]) -> Vec<f64> {
        let mut r = Vec::with_capacity(self.data.train_samples());
        for (set, t) in self.data.trains().iter().enumerate() {
            let out = self.raw_output(p, set);
            r.extend(t.y.iter().zip(&out).map(|(y, m)| y - m));
        }
        r
    }

    /// The cost of residuals `r`, the cap for non-finite or larger ones.
    fn capped(&self, r: &[f64]) -> f64 {
        let j = 0.5 * r.iter().map(|e| e * e).sum::<f64>();
        if j.is_finite() && j < self.cap {
            j
        } else {
            self.cap
        }
    }
}

impl Objective for OperatorFit {
    fn name(&self) -> &str {
        self.basis.kind()
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, p: &[f64]) -> f64 {
        self.capped(&self.train_residuals(p))
    }

    /// The cap: non-finite points (the cost of a finite point in the box is a finite
    /// quadratic far below it).
    fn penalty_threshold(&self) -> Option<f64> {
        Some(self.cap)
    }

    fn optimum(&self) -> Option<f64> {
        self.optimum.as_ref().map(|o| o.0)
    }

    fn residuals(&self, p: &[f64], r: &mut Vec<f64>) -> Option<f64> {
        let res = self.train_residuals(p);
        let j = self.capped(&res);
        r.clear();
        if j < self.cap {
            *r = res;
        }
        Some(j)
    }

    fn presentation(&self) -> Option<Presentation> {
        Some(self.data.rmse_presentation())
    }

    /// RMSE and max error of the free run on every set; with a known optimum also the
    /// training RMSE above the optimum's (0 at it).
    fn metrics(&self, p: &[f64]) -> Vec<Metric> {
        let unit = self.data.train().unit_suffix();
        let mut m = self.data.free_run_metrics(|k| self.output(p, k));
        if let Some((j, _)) = &self.optimum {
            let pr = self.data.rmse_presentation();
            m.push(Metric::new(
                format!("train RMSE above the optimum{unit}"),
                pr.apply(self.evaluate(p)) - pr.apply(*j),
            ));
        }
        m
    }

    fn as_fit(&self) -> Option<&dyn FitView> {
        Some(self)
    }
}

impl FitView for OperatorFit {
    fn recordings(&self) -> Vec<(&str, &Recording)> {
        self.data.recordings()
    }

    fn outputs(&self, p: &[f64], set: usize) -> Vec<(String, Vec<f64>)> {
        let Some(d) = self.data.get(set) else {
            return Vec::new();
        };
        let y = self
            .output(p, set)
            .into_iter()
            .map(|v| v * d.y_scale)
            .collect();
        vec![(self.basis.label(), y)]
    }

    /// The model file's parameters: coefficients and thresholds in physical units.
    fn named_params(&self, p: &[f64]) -> Vec<(String, f64)> {
        let mut params = self.model(p).parameters;
        // Not the threshold increments model() appends: the thresholds they give are listed.
        params.truncate(params.len() - self.split(p).0.len());
        params
            .into_iter()
            .map(|q| {
                let name = if q.unit.is_empty() {
                    q.name
                } else {
                    format!("{} [{}]", q.name, q.unit)
                };
                (name, q.value)
            })
            .collect()
    }

    /// The model in physical units; the coefficients (and, `all`, the threshold
    /// increments `s1`, ...) with their searched values and bounds.
    fn model(&self, p: &[f64]) -> ModelFile {
        let t = self.data.train();
        let (units, _) = units_of(self.data.recordings()[0].1);
        let dt = self.data.recordings()[0].1.dt();
        let (x, theta) = self.split(p);
        let scales = (t.u_scale, t.y_scale);
        let mut m = match &self.shape {
            None => self.basis.model_file(theta, scales, units, dt),
            Some(s) => self.pi_at(s, x).model_file(theta, scales, units, dt),
        };
        let (lo, hi) = (self.bounds.lower(), self.bounds.upper());
        let off = x.len();
        for (j, q) in m.parameters.iter_mut().take(theta.len()).enumerate() {
            let i = off + j;
            *q = q.clone().searched(p[i], lo[i], hi[i]);
            // A weight at 0 is at the model's constraint, not at a search limit to widen.
            if let Some(s) = q.search.as_mut().filter(|_| self.nonneg[j]) {
                s.at_bound = s.at_bound.take().filter(|b| b != "lower");
            }
        }
        for (k, v) in x.iter().enumerate() {
            m.parameters
                .push(Param::new(format!("s{}", k + 1), *v, "").searched(*v, lo[k], hi[k]));
        }
        m
    }
}

/// `a/b^k` as a unit ("" when both are unitless).
fn per(a: &str, b: &str, k: i32) -> String {
    match (a.is_empty() && b.is_empty(), k) {
        (true, _) => String::new(),
        (_, 1) => format!("{a}/{b}"),
        _ => format!("{a}/{b}^{k}"),
    }
}

/// `model` (fitted on input / `us`, output / `us`) in physical units: with `u = us u'`
/// and `y = ys y'` a play scales with the input, so thresholds scale by `us`, weights by
/// `ys/us`, rate weights by `ys/us²` (the rate scales by `us`), `v^p` coefficients by
/// `ys/us^p`, offsets by their side's scale.
pub fn denormalised(model: &PiModel, us: f64, ys: f64) -> PiModel {
    PiModel {
        form: model.form,
        thresholds: model.thresholds.iter().map(|r| r * us).collect(),
        weights: model.weights.iter().map(|w| w * ys / us).collect(),
        rate_weights: model
            .rate_weights
            .iter()
            .map(|w| w * ys / (us * us))
            .collect(),
        poly: model
            .poly
            .iter()
            .zip(2..)
            .map(|(a, p)| a * ys / us.powi(p))
            .collect(),
        offset: model.offset * ys,
        input_offset: model.input_offset * us,
    }
}

impl OperatorBasis for PiBasis {
    fn kind(&self) -> &'static str {
        "pi"
    }

    fn label(&self) -> String {
        format!(
            "PI ({}, {} operators)",
            self.form.name(),
            self.thresholds.len()
        )
    }

    fn model_file(&self, theta: &[f64], scales: (f64, f64), units: Units, dt: f64) -> ModelFile {
        let phys = denormalised(&self.model(theta), scales.0, scales.1);
        let (yu, uu) = (units.output.clone(), units.input.clone());
        let mut params: Vec<Param> = Vec::new();
        for (i, w) in phys.weights.iter().enumerate() {
            params.push(Param::new(format!("w{i}"), *w, per(&yu, &uu, 1)));
        }
        for (i, w) in phys.rate_weights.iter().enumerate() {
            let unit = if yu.is_empty() && uu.is_empty() {
                String::new()
            } else {
                format!("{yu} s/{uu}^2")
            };
            params.push(Param::new(format!("rho{i}"), *w, unit));
        }
        for (a, p) in phys.poly.iter().zip(2..) {
            params.push(Param::new(format!("a{p}"), *a, per(&yu, &uu, p)));
        }
        params.push(Param::new("d0", phys.offset, yu.clone()));
        for (i, r) in phys.thresholds.iter().enumerate().skip(1) {
            params.push(Param::new(format!("r{i}"), *r, uu.clone()));
        }
        let mut m = ModelFile::new(
            "pi",
            &format!(
                "Prandtl-Ishlinskii ({}): y(k) = d0 + sum_i (w_i + rho_i |du/dt|) z_i(k) + a2 u^2 + a3 u^3, z_i(k) = max(u(k) - r_i, min(u(k) + r_i, z_i(k-1))), r_0 = 0",
                self.form.name()
            ),
            units,
            dt,
            Normalisation {
                input_scale: scales.0,
                output_scale: scales.1,
            },
            Integration {
                scheme: "operator".into(),
                substeps: None,
                hold: None,
            },
            "every play operator at rest (z_i = 0) before the first sample, |du/dt| = 0 at it",
            params,
        );
        m.pi = Some(phys);
        m
    }
}

impl OperatorBasis for PreisachGrid {
    fn kind(&self) -> &'static str {
        "preisach"
    }

    fn label(&self) -> String {
        format!("Preisach ({} levels)", self.levels())
    }

    /// With `u = us u'` and `y = ys y'` the grid's range scales by `us` (the relays switch
    /// at the same physical inputs), weights and offset by `ys`.
    fn model_file(&self, theta: &[f64], scales: (f64, f64), units: Units, dt: f64) -> ModelFile {
        let (us, ys) = scales;
        let grid = PreisachGrid::new(self.levels(), self.u_min() * us, self.u_max() * us)
            .expect("a valid grid scaled by a positive number stays valid");
        let phys: Vec<f64> = theta.iter().map(|v| v * ys).collect();
        let model = grid
            .model(&phys)
            .expect("one coefficient per relay and the offset");
        let yu = units.output.clone();
        let n = self.levels();
        let mut params: Vec<Param> = Vec::new();
        for i in 0..n {
            for j in 0..=i {
                let w = model.weights[PreisachGrid::index(i, j)];
                params.push(Param::new(format!("mu[{i},{j}]"), w, yu.clone()));
            }
        }
        params.push(Param::new("d0", model.offset, yu.clone()));
        let mut m = ModelFile::new(
            "preisach",
            &format!(
                "Preisach, {n} levels over [{}, {}] (relay (i, j) on once u >= t_i, off once u < t_j, t_k at the cell centres): y = d0 + sum mu_ij R_ij[u]",
                grid.u_min(),
                grid.u_max()
            ),
            units,
            dt,
            Normalisation {
                input_scale: us,
                output_scale: ys,
            },
            Integration {
                scheme: "operator".into(),
                substeps: None,
                hold: None,
            },
            "demagnetised at the first input sample: relay (i, j) on iff t_i + t_j <= 2 u(0)",
            params,
        );
        m.preisach = Some(model);
        m
    }
}

#[cfg(test)]
mod tests;
