//! Levenberg-Marquardt for least-squares objectives ([`Objective::residuals`]), as a local
//! polish: a forward-difference Jacobian (one evaluation per coordinate, as a batch), then
//! damped Gauss-Newton steps kept in the box. On a model fit it converges in a few
//! Jacobians where a simplex spends hundreds of evaluations and still creeps.
//!
//! Damping is Marquardt's (scaled by the normal matrix's diagonal) with Nielsen's update; a
//! coordinate at a bound that the step would push outside is held there and the step
//! solved again without it.
//!
//! [`Objective::residuals`]: crate::objective::Objective::residuals

use super::dot;
use crate::base::TrialSeed;
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;

/// Forward-difference step, as a fraction of each interval's width.
const FD_STEP: f64 = 1e-6;
/// Damping at the start, relative to the normal matrix's diagonal.
const LAMBDA0: f64 = 1e-3;

/// A polish from a given point with a given tolerance ([`LevenbergMarquardt::new`]).
#[derive(Debug)]
pub struct LevenbergMarquardtFrom {
    pub start: Vec<f64>,
    pub rel_tol: f64,
}

impl OptimizerConfig for LevenbergMarquardtFrom {
    fn batch_size(&self) -> usize {
        1
    }

    fn start(&self, bounds: &Bounds, _budget: u64, _seed: &TrialSeed) -> Box<dyn Optimizer> {
        Box::new(LevenbergMarquardt::new(
            bounds.clone(),
            self.start.clone(),
            self.rel_tol,
        ))
    }
}

/// The search state.
pub struct LevenbergMarquardt {
    bounds: Bounds,
    x: Vec<f64>,
    /// Converged once two steps in a row gain less than this fraction of the cost.
    rel_tol: f64,
    cost: f64,
    r: Vec<f64>,
    /// `JᵀJ` and `Jᵀr` at `x` (None: to be built).
    normal: Option<(Vec<Vec<f64>>, Vec<f64>)>,
    lambda: f64,
    nu: f64,
    /// A trial step from the current Jacobian failed.
    rejected: bool,
    /// Accepted steps in a row that gained less than the tolerance.
    small: usize,
    started: bool,
}

impl LevenbergMarquardt {
    /// A search from `start` that ends when two steps in a row lower the cost by less
    /// than `rel_tol` of it, or no step can (or the budget ends).
    pub fn new(bounds: Bounds, start: Vec<f64>, rel_tol: f64) -> Self {
        LevenbergMarquardt {
            bounds,
            x: start,
            rel_tol,
            cost: f64::INFINITY,
            r: Vec::new(),
            normal: None,
            lambda: LAMBDA0,
            nu: 2.0,
            rejected: false,
            small: 0,
            started: false,
        }
    }

    /// `JᵀJ` and `Jᵀr` from forward differences (a column whose point is penalised is
    /// zero: that coordinate does not move this iteration). `None` if the budget ended.
    fn normal_equations(&self, ev: &mut Evaluator) -> Option<(Vec<Vec<f64>>, Vec<f64>)> {
        let d = self.x.len();
        let (lo, hi) = (self.bounds.lower(), self.bounds.upper());
        let mut points = Vec::with_capacity(d * d);
        let mut steps = Vec::with_capacity(d);
        for i in 0..d {
            let h = FD_STEP * (hi[i] - lo[i]);
            let h = if self.x[i] + h > hi[i] { -h } else { h };
            let mut p = self.x.clone();
            p[i] += h;
            steps.push(p[i] - self.x[i]);
            points.extend(p);
        }
        let out = ev.evaluate_residuals_batch(&points)?;
        if out.len() < d {
            return None;
        }
        let cols: Vec<Option<Vec<f64>>> = out
            .into_iter()
            .zip(&steps)
            .map(|((_, ri), &h)| {
                (ri.len() == self.r.len() && h != 0.0).then(|| {
                    ri.iter()
                        .zip(&self.r)
                        .map(|(a, b)| (a - b) / h)
                        .collect::<Vec<f64>>()
                })
            })
            .collect();
        let mut a = vec![vec![0.0; d]; d];
        let mut g = vec![0.0; d];
        for i in 0..d {
            let Some(ci) = &cols[i] else { continue };
            g[i] = dot(ci, &self.r);
            for j in 0..=i {
                if let Some(cj) = &cols[j] {
                    a[i][j] = dot(ci, cj);
                    a[j][i] = a[i][j];
                }
            }
        }
        Some((a, g))
    }

    /// The damped step from `x`, held in the box: `(A + λ diag A) δ = -g` over the
    /// coordinates not pinned at a bound they would cross.
    fn damped_step(&self, a: &[Vec<f64>], g: &[f64]) -> Vec<f64> {
        let d = g.len();
        let (lo, hi) = (self.bounds.lower(), self.bounds.upper());
        let scale = a.iter().enumerate().map(|(i, r)| r[i]).fold(0.0, f64::max);
        let mut free: Vec<usize> = (0..d).filter(|&i| a[i][i] > 0.0).collect();
        loop {
            let m = free.len();
            let mut s = vec![vec![0.0; m]; m];
            let mut b = vec![0.0; m];
            for (p, &i) in free.iter().enumerate() {
                for (q, &j) in free.iter().enumerate() {
                    s[p][q] = a[i][j];
                }
                s[p][p] += self.lambda * a[i][i].max(1e-12 * scale);
                b[p] = -g[i];
            }
            let Some(z) = cholesky_solve(&mut s, &b) else {
                return vec![0.0; d];
            };
            let mut delta = vec![0.0; d];
            for (p, &i) in free.iter().enumerate() {
                delta[i] = z[p];
            }
            let pinned: Vec<usize> = free
                .iter()
                .copied()
                .filter(|&i| {
                    (self.x[i] <= lo[i] && delta[i] < 0.0) || (self.x[i] >= hi[i] && delta[i] > 0.0)
                })
                .collect();
            if pinned.is_empty() {
                return (0..d)
                    .map(|i| (self.x[i] + delta[i]).clamp(lo[i], hi[i]) - self.x[i])
                    .collect();
            }
            free.retain(|i| !pinned.contains(i));
        }
    }
}

impl Optimizer for LevenbergMarquardt {
    fn step(&mut self, ev: &mut Evaluator) {
        if !self.started {
            self.started = true;
            let start = self.x.clone();
            match ev
                .evaluate_residuals_batch(&start)
                .and_then(|v| v.into_iter().next())
            {
                // A penalised start (or an objective without residuals): nothing to linearise.
                Some((c, r)) if !r.is_empty() => (self.cost, self.r) = (c, r),
                _ => ev.converged(),
            }
            return;
        }
        if self.normal.is_none() {
            match self.normal_equations(ev) {
                Some(n) => self.normal = Some(n),
                None => return,
            }
        }
        let (a, g) = self.normal.as_ref().expect("built above");
        let (delta, predicted) = loop {
            let delta = self.damped_step(a, g);
            // The decrease the linear model predicts for this step: -(gᵀδ + ½ δᵀAδ).
            let quad: f64 = (0..delta.len())
                .map(|i| delta[i] * (g[i] + 0.5 * dot(&a[i], &delta)))
                .sum();
            if -quad > self.rel_tol * self.cost {
                break (delta, -quad);
            }
            // No step this Jacobian allows gains enough: converged, unless the damping was
            // only carried over from earlier iterations (then once more, lightly damped).
            if self.rejected || self.lambda <= LAMBDA0 {
                ev.converged();
                return;
            }
            self.lambda = LAMBDA0;
            self.nu = 2.0;
        };
        let trial: Vec<f64> = self.x.iter().zip(&delta).map(|(x, s)| x + s).collect();
        let Some((c, r)) = ev
            .evaluate_residuals_batch(&trial)
            .and_then(|v| v.into_iter().next())
        else {
            return;
        };
        if !r.is_empty() && c < self.cost {
            let gain = self.cost - c;
            let rho = gain / predicted;
            // Two steps in a row that gain less than the tolerance: converged, or crawling
            // along a valley where the linear model is poor (nonsmooth residuals); either
            // way further gains are below what was asked for.
            self.small = if gain < self.rel_tol * self.cost {
                self.small + 1
            } else {
                0
            };
            (self.x, self.cost, self.r) = (trial, c, r);
            self.normal = None;
            self.rejected = false;
            self.lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
            self.nu = 2.0;
            if self.small >= 2 {
                ev.converged();
            }
        } else {
            self.rejected = true;
            self.lambda *= self.nu;
            self.nu *= 2.0;
            if self.lambda > 1e16 {
                ev.converged();
            }
        }
    }
}

/// Solves `S z = b` for symmetric positive definite `S` (overwritten by its Cholesky
/// factor); `None` if `S` is not numerically positive definite.
fn cholesky_solve(s: &mut [Vec<f64>], b: &[f64]) -> Option<Vec<f64>> {
    let m = b.len();
    for j in 0..m {
        let mut d = s[j][j];
        for x in &s[j][..j] {
            d -= x * x;
        }
        if d.is_nan() || d <= 0.0 || d.is_infinite() {
            return None;
        }
        let d = d.sqrt();
        s[j][j] = d;
        for i in j + 1..m {
            let mut v = s[i][j];
            for (a, c) in s[i][..j].iter().zip(&s[j][..j]) {
                v -= a * c;
            }
            s[i][j] = v / d;
        }
    }
    let mut z = b.to_vec();
    for i in 0..m {
        for k in 0..i {
            z[i] -= s[i][k] * z[k];
        }
        z[i] /= s[i][i];
    }
    for i in (0..m).rev() {
        for k in i + 1..m {
            z[i] -= s[k][i] * z[k];
        }
        z[i] /= s[i][i];
    }
    Some(z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::{Evaluator, OptimizerConfig, Trace};
    use crate::objective::Objective;
    use crate::objective::functions::ExpDecay as Decay;
    use std::sync::Arc;

    /// The polish from `start` driven through the contract alone (the trial loop is a
    /// floor above the optimizers): step until the evaluator is done.
    fn solve(obj: Arc<Decay>, start: &[f64], budget: u64) -> Trace {
        let config = LevenbergMarquardtFrom {
            start: start.to_vec(),
            rel_tol: 1e-12,
        };
        let mut opt = config.start(obj.bounds(), budget, &TrialSeed::from_u64(1));
        let mut ev = Evaluator::new(obj, budget, None);
        while !ev.done() {
            opt.step(&mut ev);
        }
        ev.finish()
    }

    #[test]
    fn it_finds_a_nonlinear_least_squares_optimum_in_few_evaluations() {
        let bounds = Bounds::new(vec![0.0, 0.01, -5.0], vec![10.0, 10.0, 5.0]).unwrap();
        let obj = Arc::new(Decay::new([2.0, 1.3, 0.4], bounds));
        let rec = solve(obj, &[5.0, 4.0, -1.0], 1000);
        for (x, t) in rec.best_x.iter().zip([2.0, 1.3, 0.4]) {
            assert!((x - t).abs() < 1e-6, "{:?}", rec.best_x);
        }
        assert!(rec.best < 1e-12, "cost {}", rec.best);
        // It stops by its own test, long before the budget: a Jacobian is 3 evaluations.
        // (That every residual vector it computes is counted: tests/evaluation_parity.rs.)
        assert!(rec.evaluations < 200, "{} evaluations", rec.evaluations);
    }

    #[test]
    fn an_optimum_outside_the_box_ends_on_the_bound_it_crosses() {
        // The true rate 1.3 lies above the box: the best in the box has b at its top.
        let bounds = Bounds::new(vec![0.0, 0.01, -5.0], vec![10.0, 1.0, 5.0]).unwrap();
        let obj = Arc::new(Decay::new([2.0, 1.3, 0.4], bounds));
        let rec = solve(obj, &[1.0, 0.5, 0.0], 1000);
        assert_eq!(rec.best_x[1], 1.0);
        assert!(
            rec.best_x
                .iter()
                .zip([0.0, 0.01, -5.0])
                .all(|(x, l)| *x >= l)
        );
        assert!(
            rec.best_x
                .iter()
                .zip([10.0, 1.0, 5.0])
                .all(|(x, u)| *x <= u)
        );
        // And it is the best there: the other two refitted with b held lose nothing.
        let held = Bounds::new(vec![0.0, 1.0, -5.0], vec![10.0, 1.0 + 1e-12, 5.0]).unwrap();
        let fixed = Arc::new(Decay::new([2.0, 1.3, 0.4], held));
        let alone = solve(fixed, &[1.0, 1.0, 0.0], 1000);
        assert!(
            rec.best <= alone.best * (1.0 + 1e-6),
            "{} vs {}",
            rec.best,
            alone.best
        );
    }

    #[test]
    fn the_budget_bounds_it_and_the_run_repeats_exactly() {
        let bounds = Bounds::new(vec![0.0, 0.01, -5.0], vec![10.0, 10.0, 5.0]).unwrap();
        let obj = Arc::new(Decay::new([2.0, 1.3, 0.4], bounds));
        let short = solve(obj.clone(), &[5.0, 4.0, -1.0], 9);
        assert_eq!(short.evaluations, 9);
        let again = solve(obj, &[5.0, 4.0, -1.0], 9);
        assert_eq!(short.best_x, again.best_x);
        assert_eq!(short.best.to_bits(), again.best.to_bits());
    }
}
