//! Every optimizer stays in bounds, spends exactly its budget, and MSGA really runs one OS
//! thread per membrane with results independent of the threading.

mod common;

use common::{Probe, without_time};
use optbench::base::TrialSeed;
use optbench::harness::OptimizerConfig;
use optbench::objective::Objective;
use optbench::objective::functions::TestFunction;
use optbench::optimizer::msga::MsgaConfig;
use optbench::pipeline::runner::{TrialSpec, run_trial};
use optbench::registry::{default_optimizer, optimizer_kinds};
use std::sync::Arc;
use std::sync::atomic::Ordering;

fn trial(
    objective: Arc<dyn Objective>,
    optimizer: &dyn OptimizerConfig,
    budget: u64,
    stop_value: Option<f64>,
    seed: u64,
) -> optbench::harness::TrialRecord {
    run_trial(TrialSpec {
        objective_id: "obj",
        optimizer_id: "opt",
        trial: 0,
        objective,
        optimizer,
        budget,
        stop_value,
        stall: None,
        seed: TrialSeed::from_u64(seed),
    })
}

fn all_configs() -> Vec<(String, Arc<dyn OptimizerConfig>)> {
    let mut v: Vec<(String, Arc<dyn OptimizerConfig>)> = optimizer_kinds()
        .iter()
        .map(|k| (k.name.to_string(), default_optimizer(k.name).unwrap()))
        .collect();
    v.push((
        "msga-single-thread".into(),
        Arc::new(MsgaConfig {
            threads: false,
            ..MsgaConfig::default()
        }),
    ));
    v.push((
        "msga-migration-lag-1".into(),
        Arc::new(MsgaConfig {
            migration_lag: 1,
            ..MsgaConfig::default()
        }),
    ));
    v
}

#[test]
fn every_optimizer_spends_exactly_its_budget_inside_the_bounds() {
    // Budgets below, at and between population multiples, including a partial first
    // generation.
    for (name, cfg) in all_configs() {
        for budget in [1u64, 37, 200, 1037, 3000] {
            for kind in [TestFunction::Schwefel, TestFunction::Rosenbrock] {
                let probe = Arc::new(Probe::new(kind, 3));
                let r = trial(probe.clone(), cfg.as_ref(), budget, None, budget);
                assert_eq!(r.evaluations, budget, "{name} budget {budget}");
                assert_eq!(
                    probe.cost(),
                    budget,
                    "{name}: real calls must equal the count"
                );
                assert_eq!(
                    probe.out_of_bounds.load(Ordering::SeqCst),
                    0,
                    "{name} left the box"
                );
                assert!(probe.bounds().contains(&r.best_x), "{name}");
                assert_eq!(r.checkpoints.last().unwrap().0, budget);
                // The reported best is the value at best_x.
                assert_eq!(r.best, probe.evaluate(&r.best_x), "{name}");
            }
        }
    }
}

#[test]
fn a_target_ends_the_trial_at_the_hitting_evaluation() {
    for (name, cfg) in all_configs() {
        let probe = Arc::new(Probe::new(TestFunction::Sphere, 2));
        // Sphere in [-5.12, 5.12]^2: every method reaches 1.0 within a few hundred points.
        let r = trial(probe.clone(), cfg.as_ref(), 100_000, Some(1.0), 3);
        assert!(r.stopped_at_target, "{name}");
        assert!(r.best <= 1.0, "{name}");
        let hit = r.improvements.last().unwrap();
        // MSGA's membranes evaluate a round at once: the rest of the hit's round was
        // computed, and is counted.
        let end = if name.starts_with("msga") {
            hit.0.div_ceil(200) * 200
        } else {
            hit.0
        };
        assert_eq!(
            r.evaluations, end,
            "{name}: stops at the evaluation that hit (hit at {})",
            hit.0
        );
        assert!(
            r.improvements[..r.improvements.len() - 1]
                .iter()
                .all(|i| i.1 > 1.0)
        );
    }
}

#[test]
fn traces_are_monotone_and_consistent() {
    for (name, cfg) in all_configs() {
        let probe = Arc::new(Probe::new(TestFunction::Griewank, 5));
        let r = trial(probe, cfg.as_ref(), 5000, None, 11);
        assert!(
            r.improvements
                .windows(2)
                .all(|w| w[0].0 < w[1].0 && w[0].1 > w[1].1),
            "{name}"
        );
        assert!(
            r.checkpoints
                .windows(2)
                .all(|w| w[0].0 < w[1].0 && w[0].1 >= w[1].1),
            "{name}"
        );
        assert_eq!(r.improvements.last().unwrap().1, r.best);
        // Each checkpoint equals the last improvement at or before it (+inf before the
        // first value: BP's first value comes with a gradient, after 1 + d evaluations).
        for &(e, v) in &r.checkpoints {
            let last = r.improvements.iter().rev().find(|i| i.0 <= e);
            assert_eq!(last.map_or(f64::INFINITY, |i| i.1), v, "{name} at {e}");
        }
    }
}

#[test]
fn msga_runs_one_os_thread_per_membrane() {
    let probe = Arc::new(Probe::new(TestFunction::Griewank, 2));
    trial(probe.clone(), &MsgaConfig::default(), 2000, None, 5);
    let threads = probe.threads.lock().unwrap().clone();
    let expected: std::collections::BTreeSet<String> =
        (0..5).map(|i| format!("msga-membrane-{i}")).collect();
    assert_eq!(threads, expected);
}

/// MSGA with `migration_lag` on its membrane threads and in one thread.
fn msga_threaded_and_single(migration_lag: usize) -> (MsgaConfig, MsgaConfig) {
    let threaded = MsgaConfig {
        migration_lag,
        ..MsgaConfig::default()
    };
    let single = MsgaConfig {
        threads: false,
        ..threaded.clone()
    };
    (threaded, single)
}

#[test]
fn msga_is_identical_on_threads_and_in_one_thread_and_across_repeats() {
    let mut lagged = Vec::new();
    for migration_lag in [0, 1] {
        let (threaded, single) = msga_threaded_and_single(migration_lag);
        for (kind, dim, stop) in [
            (TestFunction::Griewank, 2, None),
            (TestFunction::Schwefel, 10, None),
            (TestFunction::Sphere, 4, Some(1e-3)),
        ] {
            let run = |cfg: &MsgaConfig| {
                let obj: Arc<dyn Objective> = Arc::new(Probe::new(kind, dim));
                without_time(trial(obj, cfg, 8000, stop, 99))
            };
            let a = run(&threaded);
            assert_eq!(a, run(&single), "{kind:?} lag {migration_lag}");
            for _ in 0..3 {
                assert_eq!(a, run(&threaded), "{kind:?} lag {migration_lag}: repeat");
            }
            lagged.push(a);
        }
    }
    // The lag is a different algorithm: the migrants change the later steps.
    assert_ne!(lagged[0].improvements, lagged[3].improvements);
}

/// [`Probe`] with random pauses (from the clock) that shuffle which membrane thread runs
/// ahead of which: MSGA's membranes drift up to a step apart, and their results must not.
struct Jitter(Probe, std::sync::atomic::AtomicU64);

impl Objective for Jitter {
    fn name(&self) -> &str {
        "jitter"
    }
    fn bounds(&self) -> &optbench::objective::Bounds {
        self.0.bounds()
    }
    fn evaluate(&self, x: &[f64]) -> f64 {
        if self.1.fetch_add(1, Ordering::SeqCst).is_multiple_of(16) {
            let nanos = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .subsec_nanos();
            std::thread::sleep(std::time::Duration::from_micros(u64::from(nanos % 400)));
        }
        self.0.evaluate(x)
    }
}

#[test]
fn msga_results_do_not_depend_on_scheduling() {
    for migration_lag in [0, 1] {
        let (threaded, single) = msga_threaded_and_single(migration_lag);
        for (kind, dim, stop) in [
            (TestFunction::Griewank, 3, None),
            (TestFunction::Sphere, 4, Some(1e-2)),
        ] {
            let plain: Arc<dyn Objective> = Arc::new(Probe::new(kind, dim));
            let want = without_time(trial(plain, &single, 3037, stop, 5));
            for _ in 0..3 {
                let jitter: Arc<dyn Objective> = Arc::new(Jitter(
                    Probe::new(kind, dim),
                    std::sync::atomic::AtomicU64::new(0),
                ));
                let got = without_time(trial(jitter, &threaded, 3037, stop, 5));
                let what = format!("{kind:?} lag {migration_lag}");
                assert_eq!(got.best, want.best, "{what}");
                assert_eq!(got.improvements, want.improvements, "{what}");
                assert_eq!(got.evaluations, want.evaluations, "{what}");
            }
        }
    }
}

#[test]
fn msga_hands_over_to_a_polish_with_nothing_reserved() {
    use optbench::optimizer::nelder_mead::PolishedConfig;
    // MSGA's threads are granted rounds ahead; when a polish takes over at MSGA's own budget
    // no round may still hold evaluations (the polish would starve), and the threaded run
    // must give the same trial as the single-threaded one. Switch points fall inside a round.
    for (local, migration_lag) in [("nelder-mead", 0), ("lbfgs", 1)] {
        let polished = |threads: bool| PolishedConfig {
            global: Arc::new(MsgaConfig {
                threads,
                migration_lag,
                ..MsgaConfig::default()
            }),
            share: 0.1,
            local: optbench::optimizer::polish_method(Some(local)).unwrap(),
        };
        for budget in [1037u64, 3000, 4444] {
            let obj = || -> Arc<dyn Objective> { Arc::new(Probe::new(TestFunction::Griewank, 5)) };
            let want = without_time(trial(obj(), &polished(false), budget, None, 3));
            let got = without_time(trial(obj(), &polished(true), budget, None, 3));
            assert_eq!(got.evaluations, budget, "{local} {budget}");
            assert_eq!(got.best, want.best, "{local} {budget}");
            assert_eq!(got.improvements, want.improvements, "{local} {budget}");
        }
    }
}

#[test]
fn different_seeds_give_different_runs() {
    for (name, cfg) in all_configs() {
        let obj = || -> Arc<dyn Objective> { Arc::new(Probe::new(TestFunction::Griewank, 2)) };
        let a = trial(obj(), cfg.as_ref(), 2000, None, 1);
        let b = trial(obj(), cfg.as_ref(), 2000, None, 2);
        assert_ne!(a.best_x, b.best_x, "{name}");
    }
}

#[test]
fn bp_converges_on_smooth_functions_with_its_gradient() {
    use optbench::optimizer::gradient::GradientConfig;
    let cfg = GradientConfig::default();
    // Sphere: 300 gradient steps (each charged 1 + 10 evaluations) from a random start
    // reach 1e-8.
    let probe = Arc::new(Probe::new(TestFunction::Sphere, 10));
    let r = trial(probe, &cfg, 300 * 11, None, 1);
    assert!(r.best < 1e-8, "sphere: {}", r.best);
    // Rosenbrock-2, the curved valley that gradient descent crawls along: the bold-driver
    // rate keeps it stable and 20,000 gradients (60,000 evaluations) get within 1e-3.
    let probe = Arc::new(Probe::new(TestFunction::Rosenbrock, 2));
    let r = trial(
        probe,
        &GradientConfig {
            learning_rate: 1e-3,
            momentum: 0.9,
        },
        20_000 * 3,
        None,
        1,
    );
    assert!(r.best < 1e-3, "rosenbrock: {}", r.best);
}

#[test]
fn nelder_mead_reaches_known_accuracies() {
    use optbench::optimizer::nelder_mead::NelderMeadConfig;
    let cfg = NelderMeadConfig::default();
    // Sphere-5: 1e-8 within 3000 evaluations; Rosenbrock-2: 1e-6 within 3000.
    let r = trial(
        Arc::new(Probe::new(TestFunction::Sphere, 5)),
        &cfg,
        3000,
        None,
        1,
    );
    assert!(r.best < 1e-8, "sphere: {}", r.best);
    let r = trial(
        Arc::new(Probe::new(TestFunction::Rosenbrock, 2)),
        &cfg,
        3000,
        None,
        1,
    );
    assert!(r.best < 1e-6, "rosenbrock: {}", r.best);
}

#[test]
fn polish_refines_the_global_optimizers_best_point() {
    use optbench::optimizer::nelder_mead::PolishedConfig;
    // On 10-D sphere, PSO plus a 10 % Nelder-Mead polish ends far below PSO alone at the
    // same budget, for every seed tried.
    let pso: Arc<dyn OptimizerConfig> = default_optimizer("pso").unwrap();
    let polished = PolishedConfig {
        global: Arc::clone(&pso),
        share: 0.1,
        local: Default::default(),
    };
    for seed in 1..=3 {
        let obj = || -> Arc<dyn Objective> { Arc::new(Probe::new(TestFunction::Sphere, 10)) };
        let plain = trial(obj(), pso.as_ref(), 6000, None, seed);
        let refined = trial(obj(), &polished, 6000, None, seed);
        assert_eq!(refined.evaluations, 6000);
        assert!(
            refined.best < 0.01 * plain.best,
            "seed {seed}: {} vs {}",
            refined.best,
            plain.best
        );
    }
}
