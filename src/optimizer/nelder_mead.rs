//! Nelder-Mead simplex search, as a local polish after a global search (or alone).
//!
//! Adaptive coefficients of Gao and Han (2012) — reflection 1, expansion 1 + 2/d,
//! contraction 0.75 - 1/(2d), shrink 1 - 1/d — which keep the method effective beyond a few
//! dimensions. Points are clipped to the box. The initial simplex is the start point plus
//! steps of `step` times each interval's width; when the simplex collapses (spread of values
//! below 1e-12 relative) it restarts around its best point, so the method never stalls.

use crate::base::TrialSeed;
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;

/// Nelder-Mead settings.
#[derive(Debug, Clone)]
pub struct NelderMeadConfig {
    /// Initial simplex edge as a fraction of each interval's width.
    pub step: f64,
}

impl Default for NelderMeadConfig {
    fn default() -> Self {
        NelderMeadConfig { step: 0.05 }
    }
}

impl OptimizerConfig for NelderMeadConfig {
    fn batch_size(&self) -> usize {
        1
    }

    fn start(&self, bounds: &Bounds, _budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        let mut x = vec![0.0; bounds.dim()];
        bounds.sample(&mut seed.rng(0), &mut x);
        Box::new(NelderMead::new(bounds.clone(), self.step, Some(x)))
    }
}

/// The simplex state.
pub struct NelderMead {
    bounds: Bounds,
    step: f64,
    start: Option<Vec<f64>>,
    simplex: Vec<Vec<f64>>,
    values: Vec<f64>,
}

impl NelderMead {
    /// A search starting at `start`, or at the evaluator's best point when None.
    pub fn new(bounds: Bounds, step: f64, start: Option<Vec<f64>>) -> Self {
        NelderMead {
            bounds,
            step,
            start,
            simplex: Vec::new(),
            values: Vec::new(),
        }
    }

    fn eval(&self, ev: &mut Evaluator, x: &[f64]) -> f64 {
        ev.evaluate(x).unwrap_or(f64::INFINITY)
    }

    /// Builds (or rebuilds) the simplex around `x0`; false if the budget ran out.
    fn init(&mut self, ev: &mut Evaluator, x0: Vec<f64>) {
        let d = x0.len();
        self.simplex = vec![x0.clone()];
        for i in 0..d {
            let mut x = x0.clone();
            let h = self.step * self.bounds.width(i);
            // Step inward if the vertex would leave the box.
            x[i] = if x[i] + h <= self.bounds.upper()[i] {
                x[i] + h
            } else {
                x[i] - h
            };
            self.simplex.push(x);
        }
        self.values = Vec::with_capacity(d + 1);
        for k in 0..=d {
            let v = self.eval(ev, &self.simplex[k].clone());
            self.values.push(v);
        }
    }

    fn point(&self, centroid: &[f64], worst: &[f64], t: f64) -> Vec<f64> {
        let mut x: Vec<f64> = centroid
            .iter()
            .zip(worst)
            .map(|(c, w)| c + t * (c - w))
            .collect();
        self.bounds.clamp(&mut x);
        x
    }
}

impl Optimizer for NelderMead {
    fn step(&mut self, ev: &mut Evaluator) {
        let d = self.bounds.dim();
        if self.simplex.is_empty() {
            let x0 = self.start.take().unwrap_or_else(|| ev.best_x().to_vec());
            let x0 = if x0.len() == d {
                x0
            } else {
                self.bounds.lower().to_vec()
            };
            self.init(ev, x0);
            return;
        }
        let df = d as f64;
        let (alpha, gamma, rho, sigma) = (1.0, 1.0 + 2.0 / df, 0.75 - 0.5 / df, 1.0 - 1.0 / df);
        // Order: best first.
        let mut idx: Vec<usize> = (0..=d).collect();
        idx.sort_by(|&a, &b| self.values[a].total_cmp(&self.values[b]).then(a.cmp(&b)));
        self.simplex = idx.iter().map(|&i| self.simplex[i].clone()).collect();
        self.values = idx.iter().map(|&i| self.values[i]).collect();
        let (fbest, fworst) = (self.values[0], self.values[d]);
        let spread = fworst - fbest;
        // Collapsed (or non-finite values): restart around the best point.
        if spread.is_nan() || spread <= 1e-12 * (1.0 + fbest.abs()) {
            let best = self.simplex[0].clone();
            self.init(ev, best);
            return;
        }
        let mut centroid = vec![0.0; d];
        for x in &self.simplex[..d] {
            for (c, v) in centroid.iter_mut().zip(x) {
                *c += v / df;
            }
        }
        let worst = self.simplex[d].clone();
        let xr = self.point(&centroid, &worst, alpha);
        let fr = self.eval(ev, &xr);
        if fr < self.values[0] {
            let xe = self.point(&centroid, &worst, gamma);
            let fe = self.eval(ev, &xe);
            (self.simplex[d], self.values[d]) = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < self.values[d - 1] {
            (self.simplex[d], self.values[d]) = (xr, fr);
        } else {
            // Contraction: outside if the reflection improved on the worst, else inside.
            let (xc, fc) = if fr < fworst {
                let x = self.point(&centroid, &worst, rho);
                let f = self.eval(ev, &x);
                (x, f)
            } else {
                let x = self.point(&centroid, &worst, -rho);
                let f = self.eval(ev, &x);
                (x, f)
            };
            if fc < fr.min(fworst) {
                (self.simplex[d], self.values[d]) = (xc, fc);
            } else {
                // Shrink towards the best.
                let best = self.simplex[0].clone();
                for k in 1..=d {
                    let mut x: Vec<f64> = best
                        .iter()
                        .zip(&self.simplex[k])
                        .map(|(b, v)| b + sigma * (v - b))
                        .collect();
                    self.bounds.clamp(&mut x);
                    self.values[k] = self.eval(ev, &x);
                    self.simplex[k] = x;
                }
            }
        }
    }
}

/// The local search of a polish.
#[derive(Debug, Clone)]
pub enum LocalSearch {
    NelderMead(NelderMeadConfig),
    Lbfgs(super::lbfgs::LbfgsConfig),
}

impl Default for LocalSearch {
    fn default() -> Self {
        LocalSearch::NelderMead(NelderMeadConfig::default())
    }
}

/// A global optimizer followed by a local polish (Nelder-Mead by default, or L-BFGS) of its
/// best point for the last `share` of the budget (the seed-reproduction suites leave it off).
#[derive(Debug, Clone)]
pub struct PolishedConfig {
    pub global: std::sync::Arc<dyn OptimizerConfig>,
    pub share: f64,
    pub local: LocalSearch,
}

impl OptimizerConfig for PolishedConfig {
    fn batch_size(&self) -> usize {
        self.global.batch_size()
    }

    fn needs_gradient(&self) -> bool {
        let local = match &self.local {
            LocalSearch::NelderMead(_) => false,
            LocalSearch::Lbfgs(c) => c.needs_gradient(),
        };
        self.global.needs_gradient() || local
    }

    fn start(&self, bounds: &Bounds, budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        let switch = ((1.0 - self.share) * budget as f64).floor() as u64;
        let local: Box<dyn Optimizer> = match &self.local {
            LocalSearch::NelderMead(c) => Box::new(NelderMead::new(bounds.clone(), c.step, None)),
            LocalSearch::Lbfgs(c) => Box::new(super::lbfgs::Lbfgs::new(
                bounds.clone(),
                c.clone(),
                seed.rng(super::lbfgs::POLISH_STREAM),
                None,
            )),
        };
        Box::new(Polished {
            global: self.global.start(bounds, switch, seed),
            local,
            switch,
        })
    }
}

struct Polished {
    global: Box<dyn Optimizer>,
    local: Box<dyn Optimizer>,
    switch: u64,
}

impl Optimizer for Polished {
    fn step(&mut self, ev: &mut Evaluator) {
        if ev.used() < self.switch {
            self.global.step(ev);
        } else {
            self.local.step(ev);
        }
    }
}
