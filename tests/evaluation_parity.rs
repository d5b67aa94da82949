//! The objective is never called more often than the count says: every optimizer of the
//! registry (and the Levenberg-Marquardt polish, the single-thread MSGA and an L-BFGS with the
//! analytic gradient) runs real trials against an objective that counts its real calls, once
//! to the budget and once to a stop value hit inside a batch, and the trace's `evaluations`
//! must equal what the objective computed.
//!
//! The cost model checked: a value is one evaluation (alone, in a batch, or with its residual
//! vector); a value with its gradient is `1 + d` evaluations (the value and the `d`
//! forward differences a gradient is worth to a black-box method; `harness/evaluator.rs`).

mod common;

use common::Probe;
use optbench::base::TrialSeed;
use optbench::harness::{OptimizerConfig, TrialRecord};
use optbench::objective::functions::ExpDecay;
use optbench::objective::hysteresis::RbfFit;
use optbench::objective::source::{SimOptions, Source};
use optbench::objective::{Bounds, Objective};
use optbench::optimizer::lbfgs::{GradientSource, LbfgsConfig};
use optbench::optimizer::levenberg_marquardt::LevenbergMarquardtFrom;
use optbench::optimizer::msga::MsgaConfig;
use optbench::optimizer::nelder_mead::{LocalSearch, PolishedConfig};
use optbench::physics::rbf::{Mode, Narx, RbfNet};
use optbench::pipeline::runner::{TrialSpec, run_trial};
use optbench::registry::{default_optimizer, optimizer_kinds};
use std::path::Path;
use std::sync::Arc;

fn trial(
    obj: &Arc<Probe>,
    cfg: &dyn OptimizerConfig,
    budget: u64,
    stop_value: Option<f64>,
) -> TrialRecord {
    run_trial(TrialSpec {
        objective_id: "obj",
        optimizer_id: "opt",
        trial: 0,
        objective: Arc::clone(obj) as Arc<dyn Objective>,
        optimizer: cfg,
        budget,
        stop_value,
        stall: None,
        seed: TrialSeed::from_u64(21),
    })
}

/// Every optimizer of the registry with its defaults, and the variants with other counting
/// paths: MSGA in one thread, L-BFGS on the analytic gradient, MSGA polished by it, and the
/// Levenberg-Marquardt polish (residuals) from the box's centre.
fn configs(bounds: &Bounds) -> Vec<(String, Arc<dyn OptimizerConfig>)> {
    let mut v: Vec<(String, Arc<dyn OptimizerConfig>)> = optimizer_kinds()
        .iter()
        .map(|k| (k.name.to_string(), default_optimizer(k.name).unwrap()))
        .collect();
    let analytic = LbfgsConfig {
        gradient: GradientSource::Analytic,
        ..LbfgsConfig::default()
    };
    v.push((
        "msga-single-thread".into(),
        Arc::new(MsgaConfig {
            threads: false,
            ..MsgaConfig::default()
        }),
    ));
    v.push(("lbfgs-analytic".into(), Arc::new(analytic.clone())));
    v.push((
        "msga+lbfgs-analytic".into(),
        Arc::new(PolishedConfig {
            global: Arc::new(MsgaConfig::default()),
            share: 0.3,
            local: LocalSearch::Lbfgs(analytic),
        }),
    ));
    let centre: Vec<f64> = (0..bounds.dim())
        .map(|i| 0.5 * (bounds.lower()[i] + bounds.upper()[i]))
        .collect();
    v.push((
        "levenberg-marquardt".into(),
        Arc::new(LevenbergMarquardtFrom {
            start: centre,
            rel_tol: 1e-14,
        }),
    ));
    v
}

/// A small RBF fit (the dissertation's eq. 3.18 example, 0.5 s), the objective BP is for.
fn rbf() -> Arc<dyn Objective> {
    let rec = Source::parse(
        "eq318:sine:freq=20,amp=1",
        Path::new("."),
        "t,u,y",
        SimOptions {
            duration: Some(0.5),
            ..SimOptions::default()
        },
    )
    .unwrap()
    .load()
    .unwrap();
    Arc::new(RbfFit::new(&[rec], &[], RbfNet::SEED, Narx::SEED, Mode::OneStepAhead).unwrap())
}

/// What one pair of trials measured: (name, case, counted evaluations, real cost).
type Row = (String, &'static str, u64, u64);

/// Runs `cfg` to the budget and then to a stop value hit inside a batch, and returns the
/// counts; asserts the stop was hit where the budget run hit that value.
fn measure(
    name: &str,
    cfg: &dyn OptimizerConfig,
    inner: &Arc<dyn Objective>,
    budget: u64,
) -> Vec<Row> {
    let full_obj = Arc::new(Probe::of(Arc::clone(inner)));
    let full = trial(&full_obj, cfg, budget, None);
    let mut rows = vec![(
        name.to_string(),
        "budget",
        full.evaluations,
        full_obj.cost(),
    )];
    // A value the run reached mid-way, at an evaluation with more of its batch after it
    // where there is one (there the evaluator must not compute the rest, or count it).
    let half = |e: &u64| e.abs_diff(full.evaluations / 2);
    let inside: Vec<(u64, f64)> = full
        .improvements
        .iter()
        .filter(|(e, _)| full_obj.inside_a_call(*e))
        .copied()
        .collect();
    let from = if inside.is_empty() {
        &full.improvements
    } else {
        &inside
    };
    let Some(&(hit, value)) = from.iter().min_by_key(|(e, _)| half(e)) else {
        return rows;
    };
    if cfg.batch_size() > 1 {
        assert!(
            full_obj.inside_a_call(hit),
            "{name}: no improvement inside a batch to stop at"
        );
    }
    let stop_obj = Arc::new(Probe::of(Arc::clone(inner)));
    let stopped = trial(&stop_obj, cfg, budget, Some(value));
    assert!(stopped.stopped_at_target, "{name}: the stop value was hit");
    assert_eq!(
        stopped
            .improvements
            .iter()
            .find(|i| i.1 <= value)
            .unwrap()
            .0,
        hit,
        "{name}: the stop value is reached where the budget run reached it"
    );
    // Nothing after the hit is computed, except the rest of MSGA's round (its membranes
    // evaluate at once), which is counted.
    let round = hit.div_ceil(200) * 200;
    assert!(
        stopped.evaluations == hit || (name.starts_with("msga") && stopped.evaluations == round),
        "{name}: hit at {hit}, {} evaluations",
        stopped.evaluations
    );
    rows.push((
        name.to_string(),
        "stop",
        stopped.evaluations,
        stop_obj.cost(),
    ));
    rows
}

#[test]
fn every_optimizer_is_charged_exactly_what_the_objective_computed() {
    let box3 = Bounds::new(vec![0.0, 0.01, -5.0], vec![10.0, 10.0, 5.0]).unwrap();
    let decay: Arc<dyn Objective> = Arc::new(ExpDecay::new([2.0, 1.3, 0.4], box3));
    let mut rows = Vec::new();
    for (name, cfg) in configs(decay.bounds()) {
        rows.extend(measure(&name, cfg.as_ref(), &decay, 2000));
    }
    // The gradient optimizers and MSGA on a real fit (35 parameters: a gradient is 36).
    let net = rbf();
    for name in ["bp", "lbfgs-analytic", "msga"] {
        let cfg = configs(net.bounds())
            .into_iter()
            .find(|c| c.0 == name)
            .unwrap()
            .1;
        rows.extend(measure(&format!("{name} (rbf)"), cfg.as_ref(), &net, 3000));
    }
    let mut wrong = Vec::new();
    for (name, case, counted, real) in &rows {
        eprintln!("{name:24} {case:6} counted {counted:6} real {real:6}");
        if counted != real {
            wrong.push(format!(
                "{name} ({case}): counted {counted}, computed {real}"
            ));
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}
