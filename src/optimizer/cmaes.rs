//! CMA-ES, the (mu/mu_w, lambda) covariance matrix adaptation evolution strategy with the
//! default parameters of Hansen's tutorial (arXiv:1604.00772, 2016), and IPOP restarts
//! (Auger and Hansen 2005: each restart doubles lambda).
//!
//! Written here rather than taken from a crate: the `cmaes` crate owns the objective and
//! its own random generator, which would bypass the [`Evaluator`] and the trial's ChaCha
//! streams. Ask/tell: a generation samples lambda points, evaluates them as one batch through
//! the evaluator and updates mean, step size and covariance from their ranks.
//!
//! The search runs in coordinates normalised to the unit box; a sample is mapped into the
//! box by reflection (folding `u` with period 2 onto [0, 1]), so every evaluated point is
//! inside the bounds while the strategy itself is unconstrained. The start mean is uniform
//! in the box and the start step size `sigma` is a fraction of each interval's width.
//!
//! A run restarts (fresh uniform mean, lambda doubled if `ipop`) when it has converged or
//! stalled: step size below 1e-12 of the box, best values of the last 10 + 30 d / lambda
//! generations and of the current generation within 1e-12 (relative), covariance condition
//! number above 1e14, or non-finite state. The symmetric eigendecomposition of C comes from
//! nalgebra and is refreshed lazily (every lambda / (c1 + c_mu) / d / 10 generations).

use crate::base::limits::MAX_POPULATION;
use crate::base::{TrialSeed, standard_normal};
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand_chacha::ChaCha8Rng;
use std::collections::VecDeque;

/// CMA-ES settings.
#[derive(Debug, Clone)]
pub struct CmaesConfig {
    /// Offspring per generation of the first run (None: 4 + floor(3 ln d)).
    pub lambda: Option<usize>,
    /// Initial step size as a fraction of each interval's width.
    pub sigma: f64,
    /// Double lambda at every restart (IPOP-CMA-ES); false restarts with the same lambda.
    pub ipop: bool,
}

impl Default for CmaesConfig {
    fn default() -> Self {
        CmaesConfig {
            lambda: None,
            sigma: 0.3,
            ipop: true,
        }
    }
}

/// The default offspring count for dimension `d`.
pub fn default_lambda(d: usize) -> usize {
    4 + (3.0 * (d as f64).ln()).floor() as usize
}

impl OptimizerConfig for CmaesConfig {
    fn batch_size(&self) -> usize {
        // The first run's lambda depends on the dimension; this is the 10-D value.
        self.lambda.unwrap_or(10)
    }

    fn start(&self, bounds: &Bounds, _budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        let d = bounds.dim();
        Box::new(Cmaes {
            bounds: bounds.clone(),
            rng: seed.rng(0),
            sigma0: self.sigma,
            ipop: self.ipop,
            lambda: self.lambda.unwrap_or_else(|| default_lambda(d)).max(2),
            run: None,
            restarts: 0,
        })
    }
}

struct Cmaes {
    bounds: Bounds,
    rng: ChaCha8Rng,
    sigma0: f64,
    ipop: bool,
    /// Offspring of the current (or next) run.
    lambda: usize,
    run: Option<Run>,
    restarts: u32,
}

/// Strategy parameters and state of one run (between restarts).
struct Run {
    n: usize,
    lambda: usize,
    weights: Vec<f64>,
    mueff: f64,
    cc: f64,
    cs: f64,
    c1: f64,
    cmu: f64,
    damps: f64,
    chi_n: f64,
    mean: DVector<f64>,
    sigma: f64,
    c: DMatrix<f64>,
    b: DMatrix<f64>,
    /// Square roots of C's eigenvalues.
    diag: DVector<f64>,
    /// C^{-1/2} = B diag^{-1} B^T.
    inv_sqrt: DMatrix<f64>,
    pc: DVector<f64>,
    ps: DVector<f64>,
    generation: u64,
    eigen_generation: u64,
    /// Best value of each recent generation, for the flat-fitness test.
    history: VecDeque<f64>,
    /// Normalised samples (unbounded) and the box points evaluated, row-major.
    samples: Vec<DVector<f64>>,
    points: Vec<f64>,
    values: Vec<f64>,
}

impl Run {
    fn new(n: usize, lambda: usize, mean: DVector<f64>, sigma: f64) -> Run {
        let mu = lambda / 2;
        let raw: Vec<f64> = (1..=mu)
            .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
            .collect();
        let total: f64 = raw.iter().sum();
        let weights: Vec<f64> = raw.iter().map(|w| w / total).collect();
        let mueff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
        let nf = n as f64;
        let cc = (4.0 + mueff / nf) / (nf + 4.0 + 2.0 * mueff / nf);
        let cs = (mueff + 2.0) / (nf + mueff + 5.0);
        let c1 = 2.0 / ((nf + 1.3).powi(2) + mueff);
        let cmu = (1.0 - c1).min(2.0 * (mueff - 2.0 + 1.0 / mueff) / ((nf + 2.0).powi(2) + mueff));
        let damps = 1.0 + 2.0 * (((mueff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + cs;
        let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
        Run {
            n,
            lambda,
            weights,
            mueff,
            cc,
            cs,
            c1,
            cmu,
            damps,
            chi_n,
            mean,
            sigma,
            c: DMatrix::identity(n, n),
            b: DMatrix::identity(n, n),
            diag: DVector::from_element(n, 1.0),
            inv_sqrt: DMatrix::identity(n, n),
            pc: DVector::zeros(n),
            ps: DVector::zeros(n),
            generation: 0,
            eigen_generation: 0,
            history: VecDeque::new(),
            samples: Vec::new(),
            points: vec![0.0; lambda * n],
            values: vec![0.0; lambda],
        }
    }

    /// Refreshes B, diag and C^{-1/2} from C; false if C is no longer positive definite.
    fn decompose(&mut self) -> bool {
        let sym = (&self.c + self.c.transpose()) * 0.5;
        if sym.iter().any(|v| !v.is_finite()) {
            return false;
        }
        self.c = sym;
        let eig = SymmetricEigen::new(self.c.clone());
        if eig.eigenvalues.iter().any(|&l| l.is_nan() || l <= 0.0) {
            return false;
        }
        self.b = eig.eigenvectors;
        self.diag = eig.eigenvalues.map(f64::sqrt);
        let inv = DMatrix::from_diagonal(&self.diag.map(|s| 1.0 / s));
        self.inv_sqrt = &self.b * inv * self.b.transpose();
        self.eigen_generation = self.generation;
        true
    }

    /// Whether the run has converged or broken down and should restart.
    fn should_restart(&self) -> bool {
        if !self.sigma.is_finite() || self.mean.iter().any(|v| !v.is_finite()) {
            return true;
        }
        let max_sd = self
            .c
            .diagonal()
            .iter()
            .fold(0.0f64, |a, &v| a.max(v.sqrt()));
        if self.sigma * max_sd < 1e-12 {
            return true;
        }
        let (dmin, dmax) = self
            .diag
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        if dmax * dmax > 1e14 * dmin * dmin {
            return true;
        }
        let span = 10 + (30.0 * self.n as f64 / self.lambda as f64).ceil() as usize;
        if self.history.len() >= span {
            let (lo, hi) = self
                .history
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
            let (glo, ghi) = self
                .values
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
            let tol = 1e-12 * (1.0 + lo.abs());
            if lo.is_finite() && hi - lo <= tol && ghi - glo <= tol {
                return true;
            }
        }
        false
    }
}

/// Folds an unbounded normalised coordinate onto [0, 1] (reflection at 0 and 1).
#[inline]
fn fold(u: f64) -> f64 {
    let t = u.rem_euclid(2.0);
    if t > 1.0 { 2.0 - t } else { t }
}

impl Cmaes {
    fn new_run(&mut self) -> Run {
        let n = self.bounds.dim();
        let mean = DVector::from_fn(n, |_, _| {
            let u: f64 = rand::RngExt::random(&mut self.rng);
            u
        });
        Run::new(n, self.lambda, mean, self.sigma0)
    }
}

impl Optimizer for Cmaes {
    fn step(&mut self, ev: &mut Evaluator) {
        if self.run.is_none() {
            let run = self.new_run();
            self.run = Some(run);
        }
        let run = self.run.as_mut().expect("run started");
        let n = run.n;
        let (lo, hi) = (self.bounds.lower(), self.bounds.upper());

        // Ask: lambda samples m + sigma B D z, mapped into the box.
        if run.samples.len() != run.lambda {
            run.samples = vec![DVector::zeros(n); run.lambda];
        }
        let mut z = DVector::zeros(n);
        for k in 0..run.lambda {
            for j in 0..n {
                z[j] = standard_normal(&mut self.rng) * run.diag[j];
            }
            let u = &mut run.samples[k];
            u.copy_from(&run.mean);
            u.gemv(run.sigma, &run.b, &z, 1.0);
            for j in 0..n {
                let w = hi[j] - lo[j];
                run.points[k * n + j] = (lo[j] + w * fold(u[j])).clamp(lo[j], hi[j]);
            }
        }
        let evaluated = ev.evaluate_batch(&run.points, &mut run.values);
        if evaluated < run.lambda {
            // The budget (or the stop value) ended the trial inside this generation.
            return;
        }

        // Tell: rank, then update mean, evolution paths, covariance and step size.
        let mut order: Vec<usize> = (0..run.lambda).collect();
        let values = &run.values;
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]).then(a.cmp(&b)));
        let old_mean = run.mean.clone();
        let mut mean = DVector::zeros(n);
        for (w, &i) in run.weights.iter().zip(&order) {
            mean += &run.samples[i] * *w;
        }
        let y_w = (&mean - &old_mean) / run.sigma;
        run.mean = mean;
        run.generation += 1;
        let g = run.generation as f64;

        run.ps = &run.ps * (1.0 - run.cs)
            + (&run.inv_sqrt * &y_w) * (run.cs * (2.0 - run.cs) * run.mueff).sqrt();
        let ps_norm = run.ps.norm();
        let hsig = ps_norm / (1.0 - (1.0 - run.cs).powf(2.0 * g)).sqrt() / run.chi_n
            < 1.4 + 2.0 / (n as f64 + 1.0);
        let hs = if hsig { 1.0 } else { 0.0 };
        run.pc =
            &run.pc * (1.0 - run.cc) + &y_w * (hs * (run.cc * (2.0 - run.cc) * run.mueff).sqrt());

        // C <- decay C + c1 pc pc^T + c_mu sum w_i y_i y_i^T, in place.
        let decay = 1.0 - run.c1 - run.cmu + (1.0 - hs) * run.c1 * run.cc * (2.0 - run.cc);
        run.c *= decay;
        let pc = run.pc.clone();
        run.c.ger(run.c1, &pc, &pc, 1.0);
        let mut y = DVector::zeros(n);
        for (w, &i) in run.weights.iter().zip(&order) {
            y.copy_from(&run.samples[i]);
            y -= &old_mean;
            y /= run.sigma;
            run.c.ger(run.cmu * w, &y, &y, 1.0);
        }
        run.sigma *= ((run.cs / run.damps) * (ps_norm / run.chi_n - 1.0)).exp();
        // The folded search space has period 2: larger steps mean nothing.
        run.sigma = run.sigma.min(2.0);

        run.history.push_back(run.values[order[0]]);
        let span = 10 + (30.0 * n as f64 / run.lambda as f64).ceil() as usize;
        while run.history.len() > span {
            run.history.pop_front();
        }

        let lag = run.lambda as f64 / (run.c1 + run.cmu) / n as f64 / 10.0;
        let mut healthy = true;
        if (run.generation - run.eigen_generation) as f64 >= lag {
            healthy = run.decompose();
        }
        if !healthy || run.should_restart() {
            self.restarts += 1;
            if self.ipop {
                // Capped like a population set by the user (a limit derived from memory).
                self.lambda = self.lambda.saturating_mul(2).min(MAX_POPULATION);
            }
            self.run = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fold_reflects_into_the_unit_interval() {
        for (u, t) in [
            (0.25, 0.25),
            (1.25, 0.75),
            (-0.25, 0.25),
            (2.5, 0.5),
            (-1.5, 0.5),
        ] {
            assert!((fold(u) - t).abs() < 1e-15, "{u}");
        }
    }

    #[test]
    fn default_parameters_match_the_tutorial() {
        // d = 10: lambda 10, mu 5, mueff about 3.17 (Hansen 2016, Table 1).
        assert_eq!(default_lambda(10), 10);
        let r = Run::new(10, 10, DVector::zeros(10), 0.3);
        assert_eq!(r.weights.len(), 5);
        assert!((r.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!((r.mueff - 3.1672).abs() < 1e-3, "{}", r.mueff);
        assert!(r.c1 + r.cmu <= 1.0);
    }
}
