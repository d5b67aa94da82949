//! The evaluator: the one place where evaluations are counted.
//!
//! Optimizers never touch an objective directly. They pass points to the [`Evaluator`],
//! which spends budget, stops exactly at the budget or at the target, sanitises values
//! (NaN counts as +inf), and records the trace. An optimizer that evaluates on threads of
//! its own (MSGA) takes a [`Grant`] of a fixed number of evaluations, evaluates on any
//! thread, and hands the [`Evaluated`] result back through [`Evaluator::commit`]; the
//! coordinator commits in a fixed order, so counts and traces do not depend on scheduling.

use crate::objective::{Bounds, Objective};
use std::sync::Arc;

/// Anytime record of one trial: best-so-far at every improvement and at log-spaced
/// evaluation counts (10 per decade, plus the last evaluation).
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// (evaluation number, new best value) at every strict improvement.
    pub improvements: Vec<(u64, f64)>,
    /// (evaluation number, best-so-far) on the log-spaced grid.
    pub checkpoints: Vec<(u64, f64)>,
    /// Best value found (+inf if nothing finite was ever seen).
    pub best: f64,
    /// Where [`Trace::best`] was found.
    pub best_x: Vec<f64>,
    /// Evaluations spent.
    pub evaluations: u64,
    /// Evaluations that returned NaN or an infinity.
    pub nonfinite: u64,
    /// Evaluations the objective answered with a penalty (unusable parameters, e.g. an
    /// unstable model; see [`Objective::penalty_threshold`]).
    pub penalised: u64,
    /// Whether the run ended because the stop value was reached.
    pub stopped_at_target: bool,
}

/// Log-spaced evaluation counts up to `budget`: round(10^(k/10)), deduplicated, and `budget`.
pub fn checkpoint_grid(budget: u64) -> Vec<u64> {
    let mut grid = Vec::new();
    let mut k = 0u32;
    loop {
        let c = 10f64.powf(f64::from(k) / 10.0).round() as u64;
        if c >= budget {
            break;
        }
        if grid.last() != Some(&c) {
            grid.push(c);
        }
        k += 1;
    }
    if budget > 0 {
        grid.push(budget);
    }
    grid
}

/// Maps NaN and -inf to +inf: an undefined value must never look like a good one.
#[inline]
fn sanitize(f: f64) -> f64 {
    if f.is_nan() || f == f64::NEG_INFINITY {
        f64::INFINITY
    } else {
        f
    }
}

/// A convergence stop: the trial ends once `window` evaluations in a row have not improved
/// the best value by more than `rel` times its magnitude. For local polishes, where the
/// budget is an upper bound rather than the experiment's unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stall {
    pub window: u64,
    pub rel: f64,
}

/// Counts, limits and records the evaluations of one trial.
pub struct Evaluator {
    objective: Arc<dyn Objective>,
    budget: u64,
    used: u64,
    reserved: u64,
    stop_value: Option<f64>,
    stopped: bool,
    grid: Vec<u64>,
    next_checkpoint: usize,
    trace: Trace,
    /// Values at or above this are penalties ([`Objective::penalty_threshold`]).
    penalty: f64,
    stall: Option<Stall>,
    /// The best value when it last improved by more than the stall tolerance, and when.
    stall_ref: (f64, u64),
}

impl Evaluator {
    /// An evaluator spending at most `budget` evaluations, stopping early once a value
    /// `<= stop_value` has been seen.
    pub fn new(objective: Arc<dyn Objective>, budget: u64, stop_value: Option<f64>) -> Self {
        let dim = objective.dim();
        let penalty = objective.penalty_threshold().unwrap_or(f64::INFINITY);
        Evaluator {
            penalty,
            objective,
            budget,
            used: 0,
            reserved: 0,
            stop_value,
            stopped: false,
            grid: checkpoint_grid(budget),
            next_checkpoint: 0,
            trace: Trace {
                improvements: Vec::new(),
                checkpoints: Vec::new(),
                best: f64::INFINITY,
                best_x: Vec::with_capacity(dim),
                evaluations: 0,
                nonfinite: 0,
                penalised: 0,
                stopped_at_target: false,
            },
            stall: None,
            stall_ref: (f64::INFINITY, 0),
        }
    }

    /// This evaluator with a convergence stop ([`Stall`]).
    pub fn with_stall(mut self, stall: Option<Stall>) -> Self {
        self.stall = stall;
        self
    }

    pub fn bounds(&self) -> &Bounds {
        self.objective.bounds()
    }

    pub fn dim(&self) -> usize {
        self.objective.dim()
    }

    pub fn budget(&self) -> u64 {
        self.budget
    }

    /// Evaluations spent so far.
    pub fn used(&self) -> u64 {
        self.used
    }

    /// Evaluations that may still be spent or granted.
    pub fn remaining(&self) -> u64 {
        if self.stopped {
            0
        } else {
            self.budget - self.used - self.reserved
        }
    }

    /// True once the budget is spent or the stop value reached.
    pub fn done(&self) -> bool {
        self.stopped || self.used >= self.budget
    }

    /// Best value so far.
    pub fn best(&self) -> f64 {
        self.trace.best
    }

    /// Point of the best value so far (empty before the first evaluation).
    pub fn best_x(&self) -> &[f64] {
        &self.trace.best_x
    }

    #[inline]
    fn record(&mut self, x: &[f64], f: f64) {
        self.used += 1;
        if !f.is_finite() {
            self.trace.nonfinite += 1;
        } else if f >= self.penalty {
            self.trace.penalised += 1;
        }
        if f < self.trace.best || self.trace.best_x.is_empty() {
            if f < self.trace.best {
                self.trace.best = f;
                self.trace.improvements.push((self.used, f));
            }
            self.trace.best_x.clear();
            self.trace.best_x.extend_from_slice(x);
        }
        if self.grid.get(self.next_checkpoint) == Some(&self.used) {
            self.trace.checkpoints.push((self.used, self.trace.best));
            self.next_checkpoint += 1;
        }
        if let Some(s) = self.stop_value
            && self.trace.best <= s
        {
            self.stopped = true;
            self.trace.stopped_at_target = true;
        }
        if let Some(st) = self.stall {
            let (r, at) = self.stall_ref;
            let best = self.trace.best;
            if !r.is_finite() || best < r - st.rel * r.abs() {
                self.stall_ref = (best, self.used);
            } else if self.used - at >= st.window {
                self.stopped = true;
            }
        }
    }

    /// Records values computed for `points` in order, until the stop value is reached.
    /// Returns how many were counted; `values` past that are set to +inf.
    fn record_all(&mut self, points: &[f64], values: &mut [f64]) -> usize {
        let d = self.dim();
        let mut counted = 0;
        for (x, f) in points.chunks_exact(d).zip(values.iter_mut()) {
            if self.stopped {
                break;
            }
            self.record(x, *f);
            counted += 1;
        }
        values[counted..].fill(f64::INFINITY);
        counted
    }

    /// Evaluates the row-major `points` into `out` (one value per point) as far as the
    /// budget allows. Points that were not counted (budget spent or stop value reached)
    /// get +inf. Returns the number counted.
    pub fn evaluate_batch(&mut self, points: &[f64], out: &mut [f64]) -> usize {
        let d = self.dim();
        assert_eq!(points.len(), out.len() * d, "batch shape");
        let k = (self.remaining() as usize).min(out.len());
        self.objective
            .evaluate_batch(&points[..k * d], &mut out[..k]);
        for v in &mut out[..k] {
            *v = sanitize(*v);
        }
        out[k..].fill(f64::INFINITY);
        self.record_all(&points[..k * d], &mut out[..k])
    }

    /// Evaluates one point; `None` once the budget is spent or the stop value reached.
    pub fn evaluate(&mut self, x: &[f64]) -> Option<f64> {
        let mut out = [0.0];
        (self.evaluate_batch(x, &mut out) == 1).then_some(out[0])
    }

    /// Value and gradient at `x`, counted as one evaluation (a gradient costs a few function
    /// evaluations; budgets stay comparable in order of magnitude, and reports say so).
    /// `None` once the budget is spent, or if the objective has no gradient.
    pub fn evaluate_with_gradient(&mut self, x: &[f64], grad: &mut [f64]) -> Option<f64> {
        if self.remaining() == 0 {
            return None;
        }
        let f = sanitize(self.objective.value_and_gradient(x, grad)?);
        if !f.is_finite() || grad.iter().any(|g| !g.is_finite()) {
            grad.fill(0.0);
        }
        self.record(x, f);
        Some(f)
    }

    /// Costs and residuals ([`Objective::residuals`]) of the row-major `points`, each
    /// counted as one evaluation, as many as the budget allows (in order, until the stop
    /// value is reached); `None` if the objective has no residuals.
    pub fn evaluate_residuals_batch(&mut self, points: &[f64]) -> Option<Vec<(f64, Vec<f64>)>> {
        let d = self.dim();
        let k = (self.remaining() as usize).min(points.len() / d.max(1));
        let mut out = self.objective.residuals_batch(&points[..k * d])?;
        let mut values: Vec<f64> = out.iter().map(|(c, _)| sanitize(*c)).collect();
        let counted = self.record_all(&points[..k * d], &mut values);
        out.truncate(counted);
        for ((c, r), v) in out.iter_mut().zip(values) {
            *c = v;
            if !v.is_finite() {
                r.clear();
            }
        }
        Some(out)
    }

    /// Ends the trial early: a local search has converged (its budget was an upper bound).
    pub fn converged(&mut self) {
        self.stopped = true;
    }

    /// Reserves up to `n` evaluations for evaluation elsewhere (another thread). The result
    /// must come back through [`Evaluator::commit`]; grants are counted at commit, in the
    /// order the caller commits them.
    pub fn grant(&mut self, n: usize) -> Grant {
        let quota = (self.remaining() as usize).min(n);
        self.reserved += quota as u64;
        Grant {
            objective: Arc::clone(&self.objective),
            quota,
        }
    }

    /// Counts the evaluations of a grant, in order, until the stop value is reached.
    /// Returns how many were counted.
    pub fn commit(&mut self, mut e: Evaluated) -> usize {
        self.reserved -= e.quota as u64;
        let k = e.evaluated;
        let d = self.dim();
        self.record_all(&e.points[..k * d], &mut e.values[..k])
    }

    /// Ends the trial and returns its trace.
    pub fn finish(mut self) -> Trace {
        debug_assert_eq!(self.reserved, 0, "grants left uncommitted");
        if self.trace.checkpoints.last().map(|c| c.0) != Some(self.used) && self.used > 0 {
            self.trace.checkpoints.push((self.used, self.trace.best));
        }
        self.trace.evaluations = self.used;
        self.trace
    }
}

/// A reservation of evaluations that can be spent on any thread.
pub struct Grant {
    objective: Arc<dyn Objective>,
    quota: usize,
}

impl Grant {
    /// How many points this grant may evaluate.
    pub fn quota(&self) -> usize {
        self.quota
    }

    /// Evaluates the first `quota` of the row-major `points`; the rest get +inf.
    pub fn evaluate(self, points: &[f64]) -> Evaluated {
        let d = self.objective.dim();
        let n = points.len() / d;
        let k = self.quota.min(n);
        let mut values = vec![f64::INFINITY; n];
        self.objective
            .evaluate_batch(&points[..k * d], &mut values[..k]);
        for v in &mut values[..k] {
            *v = sanitize(*v);
        }
        Evaluated {
            points: points.to_vec(),
            values,
            evaluated: k,
            quota: self.quota,
        }
    }
}

/// Values computed under a [`Grant`], waiting to be counted.
#[derive(Debug)]
pub struct Evaluated {
    points: Vec<f64>,
    values: Vec<f64>,
    evaluated: usize,
    quota: usize,
}

impl Evaluated {
    /// One value per point (+inf for points beyond the quota).
    pub fn values(&self) -> &[f64] {
        &self.values
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objective::functions::{Function, TestFunction};

    fn sphere(d: usize) -> Arc<dyn Objective> {
        Arc::new(Function::standard(TestFunction::Sphere, d).unwrap())
    }

    #[test]
    fn grid_is_log_spaced_and_ends_at_budget() {
        let g = checkpoint_grid(1000);
        assert_eq!(&g[..8], &[1, 2, 3, 4, 5, 6, 8, 10]);
        assert_eq!(*g.last().unwrap(), 1000);
        assert!(g.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(checkpoint_grid(1), vec![1]);
    }

    #[test]
    fn stall_ends_a_trial_only_after_a_window_without_real_gain() {
        let mut ev = Evaluator::new(sphere(1), 1000, None).with_stall(Some(Stall {
            window: 10,
            rel: 1e-3,
        }));
        // Improving by 10 % per evaluation: never stalls.
        let mut x = 1.0;
        for _ in 0..50 {
            x *= 0.95;
            assert!(ev.evaluate(&[x]).is_some());
        }
        assert!(!ev.done());
        // Gains below the tolerance (1e-5 relative) do not reset the window: the tenth
        // evaluation after the last real gain ends the trial, not a budget.
        for k in 1..=10 {
            x *= 1.0 - 1e-5;
            assert!(ev.evaluate(&[x]).is_some());
            assert_eq!(ev.done(), k == 10, "after {k}");
        }
        assert_eq!(ev.evaluate(&[0.0]), None);
        let t = ev.finish();
        assert_eq!(t.evaluations, 60);
        assert!(!t.stopped_at_target);
    }

    #[test]
    fn stops_exactly_at_budget() {
        let mut ev = Evaluator::new(sphere(2), 5, None);
        let pts = vec![1.0; 2 * 4];
        let mut out = vec![0.0; 4];
        assert_eq!(ev.evaluate_batch(&pts, &mut out), 4);
        assert_eq!(ev.evaluate_batch(&pts, &mut out), 1);
        assert_eq!(out, vec![2.0, f64::INFINITY, f64::INFINITY, f64::INFINITY]);
        assert!(ev.done());
        assert_eq!(ev.evaluate(&[0.0, 0.0]), None);
        let t = ev.finish();
        assert_eq!(t.evaluations, 5);
        assert_eq!(t.checkpoints.last(), Some(&(5, 2.0)));
    }

    #[test]
    fn stops_at_target_mid_batch() {
        let mut ev = Evaluator::new(sphere(1), 100, Some(0.5));
        let mut out = vec![0.0; 4];
        let n = ev.evaluate_batch(&[3.0, 2.0, 0.1, 0.0], &mut out);
        assert_eq!(n, 3);
        assert_eq!(out[3], f64::INFINITY);
        assert!(ev.done());
        let t = ev.finish();
        assert!(t.stopped_at_target);
        assert_eq!(t.evaluations, 3);
        assert_eq!(
            t.improvements,
            vec![(1, 9.0), (2, 4.0), (3, 0.010000000000000002)]
        );
        assert_eq!(t.checkpoints.last().unwrap().0, 3);
    }

    #[test]
    fn nan_never_becomes_best() {
        struct Nan(Bounds);
        impl Objective for Nan {
            fn name(&self) -> &str {
                "nan"
            }
            fn bounds(&self) -> &Bounds {
                &self.0
            }
            fn evaluate(&self, x: &[f64]) -> f64 {
                if x[0] > 0.0 { f64::NAN } else { 1.0 }
            }
        }
        let obj = Arc::new(Nan(Bounds::uniform(1, -1.0, 1.0).unwrap()));
        let mut ev = Evaluator::new(obj, 10, None);
        assert_eq!(ev.evaluate(&[0.5]), Some(f64::INFINITY));
        assert_eq!(ev.best_x(), &[0.5]);
        assert_eq!(ev.evaluate(&[-0.5]), Some(1.0));
        let t = ev.finish();
        assert_eq!(t.best, 1.0);
        assert_eq!(t.best_x, vec![-0.5]);
        assert_eq!(t.nonfinite, 1);
    }

    #[test]
    fn grants_count_at_commit_in_commit_order() {
        let mut ev = Evaluator::new(sphere(1), 5, None);
        let g1 = ev.grant(3);
        let g2 = ev.grant(3);
        assert_eq!((g1.quota(), g2.quota()), (3, 2));
        assert_eq!(ev.remaining(), 0);
        let e2 = g2.evaluate(&[1.0, 2.0, 3.0]);
        let e1 = g1.evaluate(&[4.0, 5.0, 6.0]);
        assert_eq!(e2.values(), &[1.0, 4.0, f64::INFINITY]);
        assert_eq!(ev.commit(e1), 3);
        assert_eq!(ev.commit(e2), 2);
        let t = ev.finish();
        assert_eq!(t.evaluations, 5);
        assert_eq!(t.improvements, vec![(1, 16.0), (4, 1.0)]);
    }
}
