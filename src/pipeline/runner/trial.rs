//! One trial: an optimizer against an objective for a budget, from one seed. Above both
//! the optimizers and the harness contract they implement.

use crate::base::TrialSeed;
use crate::harness::{Evaluator, OptimizerConfig, Stall, Trace, TrialRecord};
use crate::objective::Objective;
use std::sync::Arc;
use std::time::Instant;

/// Everything a trial needs.
pub struct TrialSpec<'a> {
    pub objective_id: &'a str,
    pub optimizer_id: &'a str,
    pub trial: usize,
    pub objective: Arc<dyn Objective>,
    pub optimizer: &'a dyn OptimizerConfig,
    pub budget: u64,
    /// End the trial once a value <= this is seen.
    pub stop_value: Option<f64>,
    /// End the trial once the best value has stalled (a local polish that has converged).
    pub stall: Option<Stall>,
    pub seed: TrialSeed,
}

/// Runs one trial: the executor loop. The optimizer steps until the evaluator says done.
pub fn run_trial(spec: TrialSpec<'_>) -> TrialRecord {
    run_trial_observed(spec, &|_| {})
}

/// [`run_trial`], calling `step(evaluations used)` after every optimizer step (a
/// progress bar's hook).
pub fn run_trial_observed(spec: TrialSpec<'_>, step: &dyn Fn(u64)) -> TrialRecord {
    let start = Instant::now();
    let mut optimizer = spec
        .optimizer
        .start(spec.objective.bounds(), spec.budget, &spec.seed);
    let mut ev = Evaluator::new(Arc::clone(&spec.objective), spec.budget, spec.stop_value)
        .with_stall(spec.stall);
    while !ev.done() {
        let before = ev.used();
        optimizer.step(&mut ev);
        assert!(
            ev.used() > before || ev.done(),
            "optimizer {} spent no evaluation in a step",
            spec.optimizer_id
        );
        step(ev.used());
    }
    drop(optimizer);
    let trace = ev.finish();
    TrialIdentity::of(&spec).record(trace, start.elapsed().as_secs_f64())
}

/// What a trial record says about the trial besides its trace: the same for a trial of
/// the loop above and one an optimizer outside optbench drives
/// ([`crate::pipeline::external`]), so both leave identical records.
#[derive(Debug, Clone)]
pub struct TrialIdentity {
    pub objective_id: String,
    pub optimizer_id: String,
    pub trial: usize,
    pub seed: TrialSeed,
    pub budget: u64,
    /// Known optimum of the objective.
    pub optimum: Option<f64>,
}

impl TrialIdentity {
    pub fn of(spec: &TrialSpec<'_>) -> Self {
        TrialIdentity {
            objective_id: spec.objective_id.to_string(),
            optimizer_id: spec.optimizer_id.to_string(),
            trial: spec.trial,
            seed: spec.seed,
            budget: spec.budget,
            optimum: spec.objective.optimum(),
        }
    }

    /// The stored record of this trial, from its evaluator's final trace.
    pub fn record(self, trace: Trace, wall_s: f64) -> TrialRecord {
        TrialRecord {
            objective: self.objective_id,
            optimizer: self.optimizer_id,
            trial: self.trial,
            seed: self.seed.hex(),
            budget: self.budget,
            evaluations: trace.evaluations,
            best: trace.best,
            best_x: trace.best_x,
            optimum: self.optimum,
            stopped_at_target: trace.stopped_at_target,
            nonfinite: trace.nonfinite,
            penalised: trace.penalised,
            wall_s,
            improvements: trace.improvements,
            checkpoints: trace.checkpoints,
        }
    }
}

#[cfg(test)]
mod tests {
    //! The trial loop driving a real fit: here, above both the objective and the
    //! optimizer it joins.
    use super::*;
    use crate::objective::hysteresis::BoucWenFit;
    use crate::objective::hysteresis::tests::{TRUTH, TRUTH_X, bw_record, metric, named};

    /// Best point of `budget` evaluations of CMA-ES on `fit`.
    fn fit_cmaes(fit: BoucWenFit, budget: u64) -> (Vec<f64>, f64, std::sync::Arc<dyn Objective>) {
        let obj: std::sync::Arc<dyn Objective> = std::sync::Arc::new(fit);
        let rec = run_trial(TrialSpec {
            objective_id: "fit",
            optimizer_id: "cmaes",
            trial: 0,
            objective: std::sync::Arc::clone(&obj),
            optimizer: &crate::optimizer::cmaes::CmaesConfig::default(),
            budget,
            stop_value: None,
            stall: None,
            seed: crate::base::TrialSeed::from_u64(5),
        });
        (rec.best_x, rec.best, obj)
    }

    /// Two noise-free records of one actuator, the second cut from the middle of a longer
    /// run so that it starts mid-loop: with an initial state per record the fit recovers the
    /// generating parameters and the second record's state, at a cost far below the best
    /// fit from rest (which must bend the shared parameters to explain the second start).
    #[test]
    fn each_training_record_gets_an_initial_state_of_its_own() {
        let (a, a0) = bw_record("a", 1.0, 0, 750, 0.0, 0.0, 1);
        let (b, b0) = bw_record("b", 0.7, 1071, 900, 0.0, 0.0, 2);
        let sat = TRUTH.saturation().unwrap();
        assert_eq!(a0, 0.0);
        assert!(b0.abs() > 0.2 * sat, "the cut starts mid-loop: {b0}");
        let recs = [a, b];
        let make = || BoucWenFit::new(&recs, &[], false, false, 0.0, 1.5).unwrap();
        let fit = make();
        assert!(fit.fits_initial_states());
        assert_eq!(fit.dim(), 7);
        assert_eq!(&fit.bounds().lower()[5..], &[-1.0, -1.0]);
        assert_eq!(&fit.bounds().upper()[..6], &[1.5, 1.5, 1.5, 1.5, 1.5, 1.0]);
        // At the truth (fractions 0 and b0/sat) the cost is the scheme's error only.
        let mut x: Vec<f64> = TRUTH_X.to_vec();
        x.extend([0.0, b0 / sat]);
        let at_truth = fit.evaluate(&x);
        let (best, cost, obj) = fit_cmaes(make(), 12_000);
        let rest = make().with_initial_states(false);
        assert_eq!(rest.dim(), 5);
        let (rest_best, rest_cost, rest_obj) = fit_cmaes(rest, 12_000);
        let h0 = named(obj.as_ref(), &best, "h0@2 []");
        eprintln!(
            "cost at truth {at_truth:.2e}, fitted {cost:.2e}, from rest {rest_cost:.2e} \
             (ratio {:.0}); h0@2 {h0:.5} vs {b0:.5} ({:.1e} of sat); h0 {:.2e}; x {best:?}; \
             from rest {rest_best:?}",
            rest_cost / cost,
            (h0 - b0).abs() / sat,
            named(obj.as_ref(), &best, "h0 []"),
        );
        assert!(at_truth < 1e-8, "{at_truth:e}");
        for (i, (got, want)) in best.iter().zip(TRUTH_X).enumerate() {
            assert!(
                (got - want).abs() < 0.01 * want,
                "parameter {i}: {got} vs {want}"
            );
        }
        assert!((h0 - b0).abs() < 0.01 * sat, "h0@2 {h0} vs {b0}");
        assert!(named(obj.as_ref(), &best, "h0 []").abs() < 0.01 * sat);
        assert!(
            cost < 1e-3 * rest_cost,
            "{cost:e} vs from rest {rest_cost:e}"
        );
        // The from-rest fit's second record is visibly off at its start.
        let train2 = |o: &dyn Objective, x: &[f64]| metric(o, x, "train2 RMSE");
        assert!(train2(rest_obj.as_ref(), &rest_best) > 10.0 * train2(obj.as_ref(), &best));
    }
}
