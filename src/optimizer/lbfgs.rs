//! L-BFGS local search for box-constrained problems, alone (multistart) or as the polish
//! of a global optimizer (`polish_with = "lbfgs"`).
//!
//! A projected L-BFGS: variables on a bound whose gradient pushes outward are held fixed,
//! the two-loop recursion (Nocedal 1980) gives the direction on the others, and a
//! backtracking line search with quadratic interpolation accepts the first step on the
//! projected path `P(x + a d)` that satisfies Armijo's condition (c1 = 1e-4). Pairs (s, y)
//! with too little curvature are skipped, so the inverse-Hessian model stays positive.
//!
//! Written here rather than taken from argmin: argmin's executor calls the cost function
//! itself, while here only the [`Evaluator`] evaluates and counts. Gradients are forward
//! differences by default (d evaluations each, counted like any other; step
//! sqrt(machine epsilon) x max(|x_i|, 1e-3 x width_i), taken inward at an upper bound), or
//! the objective's analytic gradient, charged the same d beside its value (as for `bp`): the
//! analytic gradient buys precision, not evaluations, and every line-search point then costs
//! `1 + d`.
//!
//! When a search converges (projected gradient zero, or no decrease along the steepest
//! descent direction) it restarts from a uniform random point of the box, so a standalone
//! run spends its whole budget as multistart L-BFGS; the evaluator keeps the best point.

use super::dot;
use crate::base::TrialSeed;
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;
use rand_chacha::ChaCha8Rng;
use std::collections::VecDeque;

/// Random stream of a polishing L-BFGS's restarts (0 is the global optimizer's, 1-5 MSGA's
/// membranes).
pub const POLISH_STREAM: u64 = 7;

/// Where gradients come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GradientSource {
    /// Forward differences, d evaluations per gradient: works on any black box.
    FiniteDifference,
    /// The objective's own gradient (objectives that have one), charged `1 + d` with its
    /// value like forward differences.
    Analytic,
}

/// L-BFGS settings.
#[derive(Debug, Clone)]
pub struct LbfgsConfig {
    /// (s, y) pairs kept for the inverse-Hessian model.
    pub memory: usize,
    pub gradient: GradientSource,
}

impl Default for LbfgsConfig {
    fn default() -> Self {
        LbfgsConfig {
            memory: 10,
            gradient: GradientSource::FiniteDifference,
        }
    }
}

impl OptimizerConfig for LbfgsConfig {
    fn batch_size(&self) -> usize {
        1
    }

    fn needs_gradient(&self) -> bool {
        self.gradient == GradientSource::Analytic
    }

    fn start(&self, bounds: &Bounds, _budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        let mut rng = seed.rng(0);
        let mut x = vec![0.0; bounds.dim()];
        bounds.sample(&mut rng, &mut x);
        Box::new(Lbfgs::new(bounds.clone(), self.clone(), rng, Some(x)))
    }
}

/// The search state.
pub struct Lbfgs {
    bounds: Bounds,
    cfg: LbfgsConfig,
    rng: ChaCha8Rng,
    /// First start point; None starts at the evaluator's best point (a polish).
    start: Option<Vec<f64>>,
    started: bool,
    x: Vec<f64>,
    fx: f64,
    /// Gradient at x (None until computed for the current point).
    g: Option<Vec<f64>>,
    memory: VecDeque<(Vec<f64>, Vec<f64>, f64)>,
}

impl Lbfgs {
    /// A search from `start`, or from the evaluator's best point when None; `rng` draws the
    /// restart points.
    pub fn new(bounds: Bounds, cfg: LbfgsConfig, rng: ChaCha8Rng, start: Option<Vec<f64>>) -> Self {
        Lbfgs {
            bounds,
            cfg,
            rng,
            start,
            started: false,
            x: Vec::new(),
            fx: f64::INFINITY,
            g: None,
            memory: VecDeque::new(),
        }
    }

    /// Value (and, with an analytic gradient, the gradient) at `x`; None once the trial is
    /// over, or once fewer evaluations remain than a gradient costs (then one is spent on a
    /// plain value, so that the trial still ends on its budget).
    fn value(&self, ev: &mut Evaluator, x: &[f64], grad: &mut Vec<f64>) -> Option<f64> {
        match self.cfg.gradient {
            GradientSource::FiniteDifference => ev.evaluate(x),
            GradientSource::Analytic => {
                grad.resize(x.len(), 0.0);
                let f = ev.evaluate_with_gradient(x, grad);
                if f.is_none() {
                    ev.evaluate(x);
                }
                f
            }
        }
    }

    /// Forward-difference gradient at (x, fx); None if the budget ran out.
    fn fd_gradient(&self, ev: &mut Evaluator) -> Option<Vec<f64>> {
        let d = self.x.len();
        let eps = f64::EPSILON.sqrt();
        let mut steps = vec![0.0; d];
        let mut pts = Vec::with_capacity(d * d);
        for j in 0..d {
            let mut h = eps * self.x[j].abs().max(1e-3 * self.bounds.width(j));
            if self.x[j] + h > self.bounds.upper()[j] {
                h = -h;
            }
            let mut p = self.x.clone();
            p[j] += h;
            // The rounded step actually taken.
            steps[j] = p[j] - self.x[j];
            pts.extend_from_slice(&p);
        }
        let mut vals = vec![0.0; d];
        if ev.evaluate_batch(&pts, &mut vals) < d {
            return None;
        }
        Some(
            vals.iter()
                .zip(&steps)
                .map(|(f, h)| {
                    let g = (f - self.fx) / h;
                    if g.is_finite() { g } else { 0.0 }
                })
                .collect(),
        )
    }

    /// Sets the current point and its gradient; false if the trial ended meanwhile.
    fn arrive(&mut self, ev: &mut Evaluator, x: Vec<f64>, fx: f64, grad: Vec<f64>) -> bool {
        self.x = x;
        self.fx = fx;
        self.g = match self.cfg.gradient {
            GradientSource::Analytic => Some(grad),
            GradientSource::FiniteDifference => self.fd_gradient(ev),
        };
        self.g.is_some()
    }

    /// Starts a fresh search at `x` (its value unknown).
    fn restart_at(&mut self, ev: &mut Evaluator, mut x: Vec<f64>) {
        self.bounds.clamp(&mut x);
        self.memory.clear();
        let mut grad = Vec::new();
        let Some(fx) = self.value(ev, &x, &mut grad) else {
            return;
        };
        self.arrive(ev, x, fx, grad);
    }

    fn restart_random(&mut self, ev: &mut Evaluator) {
        let mut x = vec![0.0; self.bounds.dim()];
        self.bounds.sample(&mut self.rng, &mut x);
        self.restart_at(ev, x);
    }

    /// Coordinates held on their bound: at the bound with the gradient pushing outward.
    fn active(&self, g: &[f64]) -> Vec<bool> {
        let (lo, hi) = (self.bounds.lower(), self.bounds.upper());
        (0..g.len())
            .map(|j| (self.x[j] <= lo[j] && g[j] > 0.0) || (self.x[j] >= hi[j] && g[j] < 0.0))
            .collect()
    }

    /// The L-BFGS direction on the free coordinates (two-loop recursion).
    fn direction(&self, pg: &[f64], active: &[bool]) -> Vec<f64> {
        let mut q = pg.to_vec();
        let mut alphas = Vec::with_capacity(self.memory.len());
        for (s, y, rho) in self.memory.iter().rev() {
            let a = rho * dot(s, &q);
            for (qj, (yj, act)) in q.iter_mut().zip(y.iter().zip(active)) {
                if !act {
                    *qj -= a * yj;
                }
            }
            alphas.push(a);
        }
        if let Some((s, y, _)) = self.memory.back() {
            let gamma = dot(s, y) / dot(y, y);
            q.iter_mut().for_each(|v| *v *= gamma);
        }
        for ((s, y, rho), a) in self.memory.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &q);
            for (qj, (sj, act)) in q.iter_mut().zip(s.iter().zip(active)) {
                if !act {
                    *qj += sj * (a - b);
                }
            }
        }
        q.iter()
            .zip(active)
            .map(|(v, &act)| if act { 0.0 } else { -v })
            .collect()
    }
}

impl Optimizer for Lbfgs {
    fn step(&mut self, ev: &mut Evaluator) {
        if !self.started {
            self.started = true;
            match self.start.take() {
                Some(x) => self.restart_at(ev, x),
                None if ev.best_x().len() == self.bounds.dim() && ev.best().is_finite() => {
                    // Polish: the evaluator's best point, whose value is known already.
                    let x = ev.best_x().to_vec();
                    let fx = ev.best();
                    let grad = if self.cfg.gradient == GradientSource::Analytic {
                        let mut g = vec![0.0; x.len()];
                        if ev.evaluate_with_gradient(&x, &mut g).is_none() {
                            // Too few evaluations left for a gradient: spend them.
                            ev.evaluate(&x);
                            return;
                        }
                        g
                    } else {
                        Vec::new()
                    };
                    self.arrive(ev, x, fx, grad);
                }
                None => self.restart_random(ev),
            }
            return;
        }
        let Some(g) = self.g.clone() else {
            // The gradient could not be completed (a previous step hit the end).
            self.restart_random(ev);
            return;
        };
        if !self.fx.is_finite() {
            self.restart_random(ev);
            return;
        }
        let active = self.active(&g);
        let pg: Vec<f64> = g
            .iter()
            .zip(&active)
            .map(|(v, &a)| if a { 0.0 } else { *v })
            .collect();
        if pg.iter().all(|v| *v == 0.0) {
            self.restart_random(ev);
            return;
        }
        let mut d = self.direction(&pg, &active);
        let descent = dot(&d, &pg);
        if descent.is_nan() || descent >= 0.0 {
            self.memory.clear();
            d = pg.iter().map(|v| -v).collect();
        }
        let dmax = d.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let min_width = (0..d.len())
            .map(|j| self.bounds.width(j))
            .fold(f64::INFINITY, f64::min);
        let mut alpha = if self.memory.is_empty() {
            (0.1 * min_width / dmax).min(1.0)
        } else {
            1.0
        };

        // Backtracking on the projected path.
        for _ in 0..60 {
            let mut xt: Vec<f64> = self.x.iter().zip(&d).map(|(x, v)| x + alpha * v).collect();
            self.bounds.clamp(&mut xt);
            let s: Vec<f64> = xt.iter().zip(&self.x).map(|(a, b)| a - b).collect();
            if s.iter().all(|v| *v == 0.0) {
                break;
            }
            let slope = dot(&g, &s);
            let mut grad_t = Vec::new();
            let Some(ft) = self.value(ev, &xt, &mut grad_t) else {
                return;
            };
            if ft <= self.fx + 1e-4 * slope {
                let old_g = g;
                if !self.arrive(ev, xt, ft, grad_t) {
                    return;
                }
                let gt = self.g.as_ref().expect("gradient");
                let y: Vec<f64> = gt.iter().zip(&old_g).map(|(a, b)| a - b).collect();
                let sy = dot(&s, &y);
                if sy > 1e-10 * dot(&y, &y).sqrt() * dot(&s, &s).sqrt() && sy > 0.0 {
                    if self.memory.len() == self.cfg.memory {
                        self.memory.pop_front();
                    }
                    self.memory.push_back((s, y, 1.0 / sy));
                }
                return;
            }
            // Minimiser of the quadratic through f(0), f'(0) and f(alpha), kept in
            // [0.1, 0.5] x alpha.
            let dphi = slope / alpha;
            let q = if ft.is_finite() {
                -dphi * alpha * alpha / (2.0 * (ft - self.fx - dphi * alpha))
            } else {
                0.1 * alpha
            };
            alpha = if q.is_finite() {
                q.clamp(0.1 * alpha, 0.5 * alpha)
            } else {
                0.5 * alpha
            };
        }
        // No decrease along this direction: retry along the steepest descent, and restart
        // where even that fails (this also guarantees the step spends an evaluation).
        if self.memory.is_empty() {
            self.restart_random(ev);
        } else {
            self.memory.clear();
            self.step(ev);
        }
    }
}
