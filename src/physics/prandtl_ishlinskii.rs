//! The Prandtl-Ishlinskii (PI) model: a weighted sum of play (backlash) operators, the
//! operator model most of the piezo literature fits where the dissertation fits Bouc-Wen.
//!
//! ```text
//! v = u − u_off;   z_i(k) = play(r_i, z_i(k−1), v(k)),  z_i(−1) = 0
//! y(k) = d0 + Σ_i (w_i + ρ_i |u̇(k)|) z_i(k) + Σ_p a_p v(k)^(p+2)
//! ```
//!
//! `r_0 = 0` makes `z_0 = v`, the linear term. Three forms:
//! - **plain**: weights only (`ρ = 0`, no polynomial); odd-symmetric loops, and an exact
//!   analytic inverse that is again a PI model ([`PiModel::inverse`]);
//! - **asymmetric**: plus a memoryless polynomial `a_2 v² + a_3 v³` in the input (the
//!   "modified PI" of the literature), for loops whose ascending and descending branches
//!   differ in curvature, as a piezo stack's do;
//! - **rate-dependent**: each weight grows with the input rate, `w_i + ρ_i |u̇|` (the
//!   rate-dependent PI of Ang et al.), since rate dependence is the dissertation's subject.
//!
//! The operators start demagnetised at `v = 0` and load onto the first sample. For fixed
//! thresholds the output is linear in every other parameter ([`LinearInWeights`]), so
//! the best weights are a non-negative least-squares problem with an exact solution
//! ([`PiModel::fit`]).

use crate::base::lstsq::nnls;

/// Play operator with half-width `r`: the output `z` follows the input `u` once `u` has
/// pushed it to an edge of `[u − r, u + r]`.
#[inline]
pub fn play(r: f64, z: f64, u: f64) -> f64 {
    (u - r).max((u + r).min(z))
}

/// Which PI model (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PiForm {
    Plain,
    Asymmetric,
    RateDependent,
}

impl PiForm {
    pub const ALL: [PiForm; 3] = [PiForm::Plain, PiForm::Asymmetric, PiForm::RateDependent];

    pub fn name(self) -> &'static str {
        match self {
            PiForm::Plain => "plain",
            PiForm::Asymmetric => "asymmetric",
            PiForm::RateDependent => "rate-dependent",
        }
    }

    pub fn parse(s: &str) -> Option<PiForm> {
        PiForm::ALL.into_iter().find(|f| f.name() == s)
    }

    /// Degrees of the asymmetric form's polynomial terms.
    const POLY: [i32; 2] = [2, 3];
}

/// A fitted or given PI model (see the module documentation for the equation).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PiModel {
    pub form: PiForm,
    /// `r_0 = 0 < r_1 < ...`, in input units.
    pub thresholds: Vec<f64>,
    /// One per threshold, output per input units.
    pub weights: Vec<f64>,
    /// Rate-dependent form: each weight's growth per unit `|u̇|` (else empty).
    pub rate_weights: Vec<f64>,
    /// Asymmetric form: coefficients of `v²` and `v³` (else empty).
    pub poly: Vec<f64>,
    /// Output offset `d0`.
    pub offset: f64,
    /// The operators act on `v = u − input_offset` (an inverse's `d0`).
    pub input_offset: f64,
}

/// The columns of a PI model with fixed thresholds: the model's output is their weighted
/// sum, so its best weights are a least-squares problem.
///
/// A hysteresis model whose output is linear in its weights for a fixed shape (PI with
/// fixed thresholds, Preisach on a fixed grid) implements [`LinearInWeights`].
pub trait LinearInWeights {
    /// One column per weight, each as long as `u`.
    fn columns(&self, u: &[f64], dt: f64) -> Vec<Vec<f64>>;
    /// Which weights are constrained to be non-negative.
    fn nonnegative(&self) -> Vec<bool>;
    /// Weight names for tables and model files.
    fn names(&self) -> Vec<String>;
}

/// The PI model's shape: form and thresholds (the weights are what a fit finds).
#[derive(Debug, Clone, PartialEq)]
pub struct PiBasis {
    pub form: PiForm,
    pub thresholds: Vec<f64>,
}

/// `|u̇(k)|` by backward differences, 0 at the first sample.
fn rates(u: &[f64], dt: f64) -> Vec<f64> {
    let mut r = vec![0.0; u.len()];
    for k in 1..u.len() {
        r[k] = ((u[k] - u[k - 1]) / dt).abs();
    }
    r
}

/// Play outputs of every threshold over `v`, from the demagnetised state.
fn plays(thresholds: &[f64], v: &[f64]) -> Vec<Vec<f64>> {
    thresholds
        .iter()
        .map(|&r| {
            let mut z = 0.0;
            v.iter()
                .map(|&x| {
                    z = play(r, z, x);
                    z
                })
                .collect()
        })
        .collect()
}

impl LinearInWeights for PiBasis {
    /// The plays, then (rate-dependent) each play times `|u̇|`, then (asymmetric) `v²` and
    /// `v³`, then the constant of the offset.
    fn columns(&self, u: &[f64], dt: f64) -> Vec<Vec<f64>> {
        let mut cols = plays(&self.thresholds, u);
        if self.form == PiForm::RateDependent {
            let rate = rates(u, dt);
            let scaled: Vec<Vec<f64>> = cols
                .iter()
                .map(|z| z.iter().zip(&rate).map(|(a, b)| a * b).collect())
                .collect();
            cols.extend(scaled);
        }
        if self.form == PiForm::Asymmetric {
            for p in PiForm::POLY {
                cols.push(u.iter().map(|x| x.powi(p)).collect());
            }
        }
        cols.push(vec![1.0; u.len()]);
        cols
    }

    /// Play weights are non-negative (the model is then invertible, and a negative weight
    /// would make a loop turn the wrong way); rate weights, polynomial and offset are free.
    fn nonnegative(&self) -> Vec<bool> {
        let n = self.thresholds.len();
        let mut c = vec![true; n];
        let extra = match self.form {
            PiForm::Plain => 0,
            PiForm::RateDependent => n,
            PiForm::Asymmetric => PiForm::POLY.len(),
        };
        c.extend(std::iter::repeat_n(false, extra + 1));
        c
    }

    fn names(&self) -> Vec<String> {
        let n = self.thresholds.len();
        let mut v: Vec<String> = (0..n).map(|i| format!("w{i}")).collect();
        match self.form {
            PiForm::Plain => {}
            PiForm::RateDependent => v.extend((0..n).map(|i| format!("rho{i}"))),
            PiForm::Asymmetric => v.extend(PiForm::POLY.iter().map(|p| format!("a{p}"))),
        }
        v.push("d0".into());
        v
    }
}

impl PiBasis {
    /// The model with coefficients `theta` (in [`LinearInWeights::columns`] order).
    pub fn model(&self, theta: &[f64]) -> PiModel {
        let n = self.thresholds.len();
        let (rate_weights, poly) = match self.form {
            PiForm::Plain => (Vec::new(), Vec::new()),
            PiForm::RateDependent => (theta[n..2 * n].to_vec(), Vec::new()),
            PiForm::Asymmetric => (Vec::new(), theta[n..n + PiForm::POLY.len()].to_vec()),
        };
        PiModel {
            form: self.form,
            thresholds: self.thresholds.clone(),
            weights: theta[..n].to_vec(),
            rate_weights,
            poly,
            offset: *theta.last().expect("the offset is always a coefficient"),
            input_offset: 0.0,
        }
    }
}

/// Checks thresholds: at least one, finite, `r_0 = 0`, strictly increasing.
pub fn check_thresholds(r: &[f64]) -> Result<(), String> {
    if r.is_empty() {
        return Err("a PI model needs at least one threshold".into());
    }
    if r[0] != 0.0 {
        return Err(format!(
            "the first threshold is the linear term and must be 0 (got {})",
            r[0]
        ));
    }
    for w in r.windows(2) {
        if !(w[1].is_finite() && w[1] > w[0]) {
            return Err(format!(
                "thresholds must increase strictly and be finite ({} then {})",
                w[0], w[1]
            ));
        }
    }
    Ok(())
}

impl PiModel {
    /// `n` thresholds `r_i = i/n · (max u − min u)/2`: a play of half-width `r` turns only
    /// on loops wider than `2r`, so wider ones would be constants after the first loading.
    pub fn uniform_thresholds(n: usize, u: &[f64]) -> Vec<f64> {
        let (lo, hi) = u
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let range = if hi > lo { hi - lo } else { 1.0 };
        (0..n).map(|i| 0.5 * range * i as f64 / n as f64).collect()
    }

    /// The least-squares optimum of `form` with `thresholds` on `(u, y)`: play weights
    /// non-negative, the rest free ([`nnls`]). Errors on bad thresholds or data.
    pub fn fit(
        form: PiForm,
        thresholds: Vec<f64>,
        u: &[f64],
        y: &[f64],
        dt: f64,
    ) -> Result<PiModel, String> {
        check_thresholds(&thresholds)?;
        if u.len() != y.len() || u.is_empty() {
            return Err(format!(
                "input and output must be equally long and non-empty ({} and {} samples)",
                u.len(),
                y.len()
            ));
        }
        if !u.iter().chain(y).all(|x| x.is_finite()) {
            return Err("the data hold a non-finite value".into());
        }
        let basis = PiBasis { form, thresholds };
        let theta = nnls(&basis.columns(u, dt), y, &basis.nonnegative());
        Ok(basis.model(&theta))
    }

    /// The model's output on `u` (sampled every `dt`), from the demagnetised state.
    pub fn simulate(&self, u: &[f64], dt: f64) -> Vec<f64> {
        let mut s = self.stepper(dt);
        u.iter().map(|&x| s.step(x)).collect()
    }

    /// A sample-by-sample runner from the demagnetised state (for control loops).
    pub fn stepper(&self, dt: f64) -> PiStepper {
        PiStepper {
            model: self.clone(),
            z: vec![0.0; self.thresholds.len()],
            last: None,
            dt,
        }
    }

    /// The analytic inverse of the plain form: a plain PI model `Γ⁻¹` with
    /// `Γ[Γ⁻¹[y]] = y` for every output sequence from the demagnetised state. With
    /// `W_j = Σ_{i≤j} w_i`: thresholds `r'_j = Σ_{i≤j} w_i (r_j − r_i)`, weights
    /// `w'_0 = 1/w_0`, `w'_j = −w_j / (W_j W_{j−1})`; it acts on `y − d0` and adds the
    /// forward model's input offset. Needs `w_0 > 0` and `w_j ≥ 0`.
    pub fn inverse(&self) -> Result<PiModel, String> {
        if self.form != PiForm::Plain {
            return Err(format!(
                "only the plain PI model has an analytic inverse (this one is {})",
                self.form.name()
            ));
        }
        check_thresholds(&self.thresholds)?;
        let w = &self.weights;
        if !(w[0] > 0.0 && w.iter().all(|x| *x >= 0.0 && x.is_finite())) {
            return Err(format!(
                "the inverse needs a positive linear weight and non-negative play weights (w0 = {})",
                w[0]
            ));
        }
        let n = w.len();
        let mut thresholds = Vec::with_capacity(n);
        let mut weights = Vec::with_capacity(n);
        let mut cum = 0.0;
        for j in 0..n {
            let prev = cum;
            cum += w[j];
            let r: f64 = (0..=j)
                .map(|i| w[i] * (self.thresholds[j] - self.thresholds[i]))
                .sum();
            thresholds.push(r);
            weights.push(if j == 0 {
                1.0 / w[0]
            } else {
                -w[j] / (cum * prev)
            });
        }
        // Plays of zero weight add nothing but would repeat a threshold.
        let keep: Vec<usize> = (0..n).filter(|&j| j == 0 || w[j] > 0.0).collect();
        Ok(PiModel {
            form: PiForm::Plain,
            thresholds: keep.iter().map(|&j| thresholds[j]).collect(),
            weights: keep.iter().map(|&j| weights[j]).collect(),
            rate_weights: Vec::new(),
            poly: Vec::new(),
            offset: self.input_offset,
            input_offset: self.offset,
        })
    }
}

/// A [`PiModel`] run one sample at a time.
#[derive(Debug, Clone)]
pub struct PiStepper {
    model: PiModel,
    z: Vec<f64>,
    last: Option<f64>,
    dt: f64,
}

impl PiStepper {
    /// The output at the next sample, whose input is `u`.
    pub fn step(&mut self, u: f64) -> f64 {
        let m = &self.model;
        let v = u - m.input_offset;
        let rate = self.last.map_or(0.0, |p| ((u - p) / self.dt).abs());
        self.last = Some(u);
        let mut y = m.offset;
        for (i, z) in self.z.iter_mut().enumerate() {
            *z = play(m.thresholds[i], *z, v);
            let w = m.weights[i] + m.rate_weights.get(i).map_or(0.0, |r| r * rate);
            y += w * *z;
        }
        for (a, p) in m.poly.iter().zip(PiForm::POLY) {
            y += a * v.powi(p);
        }
        y
    }
}

#[cfg(test)]
mod tests;
