//! The evaluator: the one place where evaluations are counted.
//!
//! Optimizers never touch an objective directly. They pass points to the [`Evaluator`],
//! which spends budget, stops exactly at the budget or at the target, sanitises values
//! (NaN counts as +inf to the optimizer; the trace records every non-finite value, and any
//! above [`NONFINITE_COST`], as that finite penalty, so no result is ever NaN or infinite),
//! and records the trace. An optimizer that evaluates on threads of
//! its own (MSGA) takes a [`Grant`] of a fixed number of evaluations, evaluates on any
//! thread, and hands the [`Evaluated`] result back through [`Evaluator::commit`]; the
//! coordinator commits in a fixed order, so counts and traces do not depend on scheduling.
//!
//! # What an evaluation is
//! The rule: the objective never computes more than the count says. One value is one
//! evaluation, alone, in a batch, or with its residual vector. One value with its gradient
//! is `1 + d` evaluations ([`Evaluator::gradient_cost`]): a gradient is `d` numbers, which
//! a black-box method buys with `d` forward differences (what `lbfgs` pays on finite
//! differences, and the unit of Moré and Wild's data profiles), so methods that use a
//! gradient get no information cheaper than the others and budgets mean the same for all.
//! The currency is information, not arithmetic: a back-propagation pass costs a few value
//! passes of work, not `d` (the trial's wall time says that), and is still charged `d`.
//!
//! Under a stop value (or a stall rule) a trial can end inside a batch, so the evaluator
//! evaluates such batches point by point and computes nothing after the hit (a batched
//! objective loses its lanes only in trials that can stop early). Grants are computed on
//! other threads before anyone knows where the trial ends: whatever a grant computed is
//! counted, also past a stop (then as spent, not searched: the best and its improvement
//! entry stay at the hit, which remains the runtime-to-target of ERTs and ECDFs, while
//! `evaluations` is everything spent). Which grants exist depends on counts only, so this is
//! deterministic.

use crate::base::limits::NONFINITE_COST;
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
    /// Best value found (+inf only before the first evaluation; at most [`NONFINITE_COST`]
    /// after it).
    pub best: f64,
    /// Where [`Trace::best`] was found.
    pub best_x: Vec<f64>,
    /// Evaluations spent.
    pub evaluations: u64,
    /// Evaluations that returned NaN or an infinity (also counted as penalised).
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

    /// Evaluations charged for one value with its gradient: the value and the `d` forward
    /// differences the gradient is worth (see the module documentation).
    pub fn gradient_cost(&self) -> u64 {
        1 + self.dim() as u64
    }

    /// Whether the trial can end inside a batch (a stop value or a stall rule), so batches
    /// are evaluated point by point.
    pub fn can_stop_early(&self) -> bool {
        self.stop_value.is_some() || self.stall.is_some()
    }

    /// Counts one evaluation and the checkpoint it may complete.
    #[inline]
    fn tick(&mut self) {
        self.used += 1;
        if self.grid.get(self.next_checkpoint) == Some(&self.used) {
            self.trace.checkpoints.push((self.used, self.trace.best));
            self.next_checkpoint += 1;
        }
    }

    /// Counts the kind of value `f` is (non-finite, penalised).
    #[inline]
    fn tally(&mut self, f: f64) {
        if !f.is_finite() {
            self.trace.nonfinite += 1;
            self.trace.penalised += 1;
        } else if f >= self.penalty || f >= NONFINITE_COST {
            self.trace.penalised += 1;
        }
    }

    #[inline]
    fn record(&mut self, x: &[f64], f: f64) {
        self.tally(f);
        // The finite penalty: ranks below every legitimate cost, keeps results finite.
        let f = if f < NONFINITE_COST {
            f
        } else {
            NONFINITE_COST
        };
        if f < self.trace.best || self.trace.best_x.is_empty() {
            if f < self.trace.best {
                self.trace.best = f;
                self.trace.improvements.push((self.used + 1, f));
            }
            self.trace.best_x.clear();
            self.trace.best_x.extend_from_slice(x);
        }
        self.tick();
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

    /// Counts values computed for `points`: in order into the search until the trial
    /// stops, the rest as spent only (they were computed). Returns how many entered the
    /// search; `values` past that are set to +inf.
    fn count_computed(&mut self, points: &[f64], values: &mut [f64]) -> usize {
        let d = self.dim();
        let mut searched = 0;
        for (x, f) in points.chunks_exact(d).zip(values.iter_mut()) {
            if self.stopped {
                self.tally(*f);
                self.tick();
                *f = f64::INFINITY;
            } else {
                self.record(x, *f);
                searched += 1;
            }
        }
        searched
    }

    /// Evaluates the row-major `points` into `out` (one value per point) as far as the
    /// budget allows. Points that were not evaluated (budget spent or stop value reached)
    /// get +inf. Returns the number evaluated.
    pub fn evaluate_batch(&mut self, points: &[f64], out: &mut [f64]) -> usize {
        let d = self.dim();
        assert_eq!(points.len(), out.len() * d, "batch shape");
        let k = (self.remaining() as usize).min(out.len());
        out[k..].fill(f64::INFINITY);
        if self.can_stop_early() {
            // Nothing after the hit is computed.
            for i in 0..k {
                if self.stopped {
                    out[i..k].fill(f64::INFINITY);
                    return i;
                }
                let x = &points[i * d..(i + 1) * d];
                self.objective.evaluate_batch(x, &mut out[i..=i]);
                out[i] = sanitize(out[i]);
                self.record(x, out[i]);
            }
            return k;
        }
        self.objective
            .evaluate_batch(&points[..k * d], &mut out[..k]);
        for v in &mut out[..k] {
            *v = sanitize(*v);
        }
        self.count_computed(&points[..k * d], &mut out[..k])
    }

    /// Evaluates one point; `None` once the budget is spent or the stop value reached.
    pub fn evaluate(&mut self, x: &[f64]) -> Option<f64> {
        let mut out = [0.0];
        (self.evaluate_batch(x, &mut out) == 1).then_some(out[0])
    }

    /// Value and gradient at `x`, charged [`Evaluator::gradient_cost`] evaluations (the
    /// value is the last of them, where an improvement or a hit is recorded). `None`, and
    /// nothing computed, when fewer evaluations remain than that, or if the objective has no
    /// gradient.
    pub fn evaluate_with_gradient(&mut self, x: &[f64], grad: &mut [f64]) -> Option<f64> {
        if self.remaining() < self.gradient_cost() {
            return None;
        }
        let f = sanitize(self.objective.value_and_gradient(x, grad)?);
        if !f.is_finite() || grad.iter().any(|g| !g.is_finite()) {
            grad.fill(0.0);
        }
        for _ in 1..self.gradient_cost() {
            self.tick();
        }
        self.record(x, f);
        Some(f)
    }

    /// Costs and residuals ([`Objective::residuals`]) of the row-major `points`, each
    /// counted as one evaluation, as many as the budget allows (in order, until the stop
    /// value is reached, after which nothing is computed); `None` if the objective has no
    /// residuals.
    pub fn evaluate_residuals_batch(&mut self, points: &[f64]) -> Option<Vec<(f64, Vec<f64>)>> {
        let d = self.dim();
        let k = (self.remaining() as usize).min(points.len() / d.max(1));
        let mut out = if self.can_stop_early() {
            let mut out = Vec::with_capacity(k);
            for x in points[..k * d].chunks_exact(d) {
                if self.stopped {
                    break;
                }
                let mut one = self.objective.residuals_batch(x)?;
                let c = sanitize(one[0].0);
                self.record(x, c);
                out.append(&mut one);
            }
            out
        } else {
            let mut out = self.objective.residuals_batch(&points[..k * d])?;
            let mut values: Vec<f64> = out.iter().map(|(c, _)| sanitize(*c)).collect();
            let searched = self.count_computed(&points[..k * d], &mut values);
            out.truncate(searched);
            out
        };
        for (c, r) in &mut out {
            *c = sanitize(*c);
            if !c.is_finite() {
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

    /// Counts the evaluations of a grant, in order: into the search until the trial stops,
    /// after that as spent (they were computed). Returns how many entered the search.
    pub fn commit(&mut self, mut e: Evaluated) -> usize {
        self.reserved -= e.quota as u64;
        let k = e.evaluated;
        let d = self.dim();
        self.count_computed(&e.points[..k * d], &mut e.values[..k])
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

    /// Sphere that counts the values it computes.
    struct Counting(Function, std::sync::atomic::AtomicU64);

    impl Objective for Counting {
        fn name(&self) -> &str {
            "counting"
        }
        fn bounds(&self) -> &Bounds {
            self.0.bounds()
        }
        fn evaluate(&self, x: &[f64]) -> f64 {
            self.1.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            self.0.evaluate(x)
        }
        fn value_and_gradient(&self, x: &[f64], grad: &mut [f64]) -> Option<f64> {
            self.evaluate(x);
            self.0.value_and_gradient(x, grad)
        }
    }

    fn counting(d: usize) -> Arc<Counting> {
        Arc::new(Counting(
            Function::standard(TestFunction::Sphere, d).unwrap(),
            Default::default(),
        ))
    }

    #[test]
    fn stops_at_target_mid_batch() {
        let obj = counting(1);
        let mut ev = Evaluator::new(obj.clone(), 100, Some(0.5));
        let mut out = vec![0.0; 4];
        let n = ev.evaluate_batch(&[3.0, 2.0, 0.1, 0.0], &mut out);
        assert_eq!(n, 3);
        // The point after the hit was never computed.
        assert_eq!(obj.1.load(std::sync::atomic::Ordering::SeqCst), 3);
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
    fn non_finite_values_are_recorded_as_the_finite_penalty() {
        struct Bad(Bounds);
        impl Objective for Bad {
            fn name(&self) -> &str {
                "bad"
            }
            fn bounds(&self) -> &Bounds {
                &self.0
            }
            fn evaluate(&self, x: &[f64]) -> f64 {
                if x[0] > 0.0 { f64::NAN } else { f64::INFINITY }
            }
        }
        let obj = Arc::new(Bad(Bounds::uniform(1, -1.0, 1.0).unwrap()));
        let mut ev = Evaluator::new(obj, 4, None);
        let mut out = [0.0; 4];
        ev.evaluate_batch(&[0.5, -0.5, 0.2, -0.2], &mut out);
        let t = ev.finish();
        assert_eq!(t.best, NONFINITE_COST);
        assert_eq!((t.nonfinite, t.penalised), (4, 4));
        assert!(t.checkpoints.iter().all(|c| c.1 == NONFINITE_COST));
        assert_eq!(t.improvements, vec![(1, NONFINITE_COST)]);
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

    #[test]
    fn grants_computed_past_a_stop_are_counted_as_spent() {
        let mut ev = Evaluator::new(sphere(1), 100, Some(0.5));
        let (g1, g2) = (ev.grant(3), ev.grant(3));
        let e1 = g1.evaluate(&[2.0, 0.5, 0.0]);
        let e2 = g2.evaluate(&[0.1, 0.2, 3.0]);
        // The second point of the first grant reaches the value: the rest is spent, not
        // searched (0.0 and 0.01 never become the best).
        assert_eq!(ev.commit(e1), 2);
        assert_eq!(ev.commit(e2), 0);
        let t = ev.finish();
        assert!(t.stopped_at_target);
        assert_eq!(t.evaluations, 6);
        assert_eq!(t.improvements, vec![(1, 4.0), (2, 0.25)]);
        assert_eq!((t.best, t.best_x), (0.25, vec![0.5]));
        assert_eq!(t.checkpoints.last(), Some(&(6, 0.25)));
    }

    #[test]
    fn a_gradient_costs_its_value_and_d_forward_differences() {
        let obj = counting(3);
        let mut ev = Evaluator::new(obj.clone(), 10, None);
        assert_eq!(ev.gradient_cost(), 4);
        let mut g = vec![0.0; 3];
        assert_eq!(
            ev.evaluate_with_gradient(&[1.0, 0.0, 0.0], &mut g),
            Some(1.0)
        );
        assert_eq!(g, vec![2.0, 0.0, 0.0]);
        assert_eq!(ev.used(), 4);
        assert!(
            ev.evaluate_with_gradient(&[0.5, 0.0, 0.0], &mut g)
                .is_some()
        );
        // Two evaluations left: not enough for a gradient, and nothing is computed.
        assert_eq!(ev.evaluate_with_gradient(&[0.0; 3], &mut g), None);
        assert_eq!(obj.1.load(std::sync::atomic::Ordering::SeqCst), 2);
        let t = ev.finish();
        assert_eq!(t.evaluations, 8);
        // Each value is recorded as the last evaluation of its call.
        assert_eq!(t.improvements, vec![(4, 1.0), (8, 0.25)]);
    }
}
