//! The strong baselines (DE, SHADE, CMA-ES, L-BFGS): known accuracies on sphere and
//! Rosenbrock within stated budgets for every seed tried, byte-identical repeats whatever
//! the thread count, the L-BFGS polish, and suite validation of their parameters.

mod common;

use common::{Probe, without_time};
use optbench::base::TrialSeed;
use optbench::harness::{OptimizerConfig, TrialRecord};
use optbench::objective::Objective;
use optbench::objective::functions::TestFunction;
use optbench::pipeline::runner::{RunOptions, TrialSpec, run_suite, run_trial};
use optbench::pipeline::suite::Suite;
use optbench::registry::default_optimizer;
use std::path::Path;
use std::sync::Arc;

fn trial(
    kind: TestFunction,
    dim: usize,
    cfg: &dyn OptimizerConfig,
    budget: u64,
    stop: f64,
    seed: u64,
) -> TrialRecord {
    run_trial(TrialSpec {
        objective_id: "obj",
        optimizer_id: "opt",
        trial: 0,
        objective: Arc::new(Probe::new(kind, dim)),
        optimizer: cfg,
        budget,
        stop_value: Some(stop),
        stall: None,
        seed: TrialSeed::from_u64(seed),
    })
}

/// Every one of seeds 1..=5 reaches `target` on `kind` in `dim` dimensions within `budget`.
fn reaches(name: &str, kind: TestFunction, dim: usize, budget: u64, target: f64) {
    let cfg = default_optimizer(name).unwrap();
    for seed in 1..=5 {
        let r = trial(kind, dim, cfg.as_ref(), budget, target, seed);
        assert!(
            r.best <= target,
            "{name} on {kind:?}-{dim}, seed {seed}: {:e} after {} evaluations (target {target:e})",
            r.best,
            r.evaluations
        );
    }
}

// Budgets are about 1.3 to 2 times the worst of ten seeds measured (release build), so a
// regression that slows convergence markedly fails.

#[test]
fn cmaes_reaches_known_accuracies() {
    // Hansen's CMA-ES needs about 2,000 evaluations on 10-D sphere to 1e-10 and 6,000-9,000
    // on 10-D Rosenbrock to 1e-8.
    reaches("cmaes", TestFunction::Sphere, 10, 5_000, 1e-10);
    reaches("cmaes", TestFunction::Rosenbrock, 10, 15_000, 1e-8);
}

#[test]
fn de_reaches_known_accuracies() {
    // DE/rand/1/bin, population 100, F 0.5, CR 0.9: about 30,000 evaluations on 10-D
    // sphere to 1e-10 and 70,000-90,000 on 10-D Rosenbrock to 1e-8.
    reaches("de", TestFunction::Sphere, 10, 40_000, 1e-10);
    reaches("de", TestFunction::Rosenbrock, 10, 120_000, 1e-8);
}

#[test]
fn shade_reaches_known_accuracies_faster_than_de() {
    // SHADE: about 17,000 on sphere and 55,000 on Rosenbrock, well under DE's.
    reaches("shade", TestFunction::Sphere, 10, 25_000, 1e-10);
    reaches("shade", TestFunction::Rosenbrock, 10, 75_000, 1e-8);
}

#[test]
fn lbfgs_reaches_known_accuracies_with_finite_differences() {
    // Forward-difference gradients (11 evaluations each in 10-D): sphere in a few
    // iterations, Rosenbrock in at most a few thousand evaluations.
    reaches("lbfgs", TestFunction::Sphere, 10, 200, 1e-10);
    reaches("lbfgs", TestFunction::Rosenbrock, 10, 6_000, 1e-8);
}

#[test]
fn lbfgs_with_the_analytic_gradient_reaches_the_same_accuracy_at_the_same_price() {
    use optbench::optimizer::lbfgs::{GradientSource, LbfgsConfig};
    let analytic = LbfgsConfig {
        gradient: GradientSource::Analytic,
        ..LbfgsConfig::default()
    };
    assert!(analytic.needs_gradient());
    // A gradient is charged 1 + d = 11 evaluations, what forward differences spend, and
    // every line-search point takes one: ten seeds need 900-4,400 evaluations to 1e-8
    // (forward differences 830-3,200), so the finite-difference budget holds.
    for seed in 1..=5 {
        let r = trial(TestFunction::Rosenbrock, 10, &analytic, 6_000, 1e-8, seed);
        assert!(r.best <= 1e-8, "seed {seed}: {:e}", r.best);
    }
}

#[test]
fn lbfgs_polish_refines_a_global_optimizers_best_point() {
    use optbench::optimizer::nelder_mead::{LocalSearch, PolishedConfig};
    let pso: Arc<dyn OptimizerConfig> = default_optimizer("pso").unwrap();
    let polished = PolishedConfig {
        global: Arc::clone(&pso),
        share: 0.2,
        local: LocalSearch::Lbfgs(Default::default()),
    };
    for seed in 1..=3 {
        let run = |cfg: &dyn OptimizerConfig| {
            let obj: Arc<dyn Objective> = Arc::new(Probe::new(TestFunction::Rosenbrock, 10));
            run_trial(TrialSpec {
                objective_id: "obj",
                optimizer_id: "opt",
                trial: 0,
                objective: obj,
                optimizer: cfg,
                budget: 20_000,
                stop_value: None,
                stall: None,
                seed: TrialSeed::from_u64(seed),
            })
        };
        let plain = run(pso.as_ref());
        let refined = run(&polished);
        assert_eq!(refined.evaluations, 20_000);
        // The polish starts from the global phase's best point (after 16,000 evaluations)
        // and on smooth Rosenbrock gets to the optimum in its 4,000.
        assert!(
            refined.best < 1e-6 && refined.best < 1e-3 * plain.best,
            "seed {seed}: {:e} vs {:e}",
            refined.best,
            plain.best
        );
    }
}

const SUITE: &str = r#"
name = "baselines-determinism"
seed = 11
trials = 3
budget = 4000

[[objective]]
kind = "rastrigin"
dim = 5

[[objective]]
kind = "rosenbrock"
dim = 4
stop_at = 1e-6

[[optimizer]]
kind = "de"
population = 20

[[optimizer]]
kind = "shade"
population = 20

[[optimizer]]
kind = "cmaes"

[[optimizer]]
kind = "lbfgs"

[[optimizer]]
kind = "pso"
id = "PSO-LBFGS"
population = 40
polish = 0.2
polish_with = "lbfgs"
"#;

fn run(threads: usize) -> String {
    let suite = Suite::parse(SUITE, Path::new("baselines.toml")).unwrap();
    let (records, _) = run_suite(
        &suite,
        &RunOptions {
            threads: Some(threads),
            progress: false,
        },
    )
    .unwrap();
    let records: Vec<TrialRecord> = records.into_iter().map(without_time).collect();
    assert_eq!(records.len(), 2 * 5 * 3);
    records
        .iter()
        .map(|r| serde_json::to_string(r).unwrap() + "\n")
        .collect()
}

#[test]
fn same_seed_same_bytes_whatever_the_thread_count() {
    let one = run(1);
    assert_eq!(one, run(2), "1 thread vs 2 threads");
    assert_eq!(one, run(1), "repeat");
    let other = SUITE.replace("seed = 11", "seed = 12");
    let suite = Suite::parse(&other, Path::new("baselines.toml")).unwrap();
    let (b, _) = run_suite(&suite, &RunOptions::default()).unwrap();
    let b: String = b
        .into_iter()
        .map(|r| serde_json::to_string(&without_time(r)).unwrap() + "\n")
        .collect();
    assert_ne!(one, b, "another seed changes the runs");
}

fn parse_error(extra: &str) -> String {
    let text = format!(
        "name = \"bad\"\nseed = 1\ntrials = 1\nbudget = 100\n[[objective]]\nkind = \"sphere\"\ndim = 2\n{extra}"
    );
    match Suite::parse(&text, Path::new("bad.toml")) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_baseline_parameters_are_refused_with_file_and_line() {
    let e = parse_error("[[optimizer]]\nkind = \"de\"\npopulation = 3\n");
    assert!(
        e.contains("bad.toml:10:") && e.contains("`population`") && e.contains("[4, 10000]"),
        "{e}"
    );
    let e = parse_error("[[optimizer]]\nkind = \"shade\"\npopulation = 8\np_max = 0.1\n");
    assert!(
        e.contains("bad.toml:") && e.contains("p_max >= 2/population"),
        "{e}"
    );
    let e = parse_error("[[optimizer]]\nkind = \"cmaes\"\nsigma = 0\n");
    assert!(e.contains("bad.toml:10:") && e.contains("`sigma`"), "{e}");
    let e = parse_error("[[optimizer]]\nkind = \"lbfgs\"\ngradient = \"numeric\"\n");
    assert!(e.contains("finite-difference | analytic"), "{e}");
    let e = parse_error("[[optimizer]]\nkind = \"pso\"\npolish_with = \"lbfgs\"\n");
    assert!(
        e.contains("bad.toml:10:") && e.contains("`polish_with` needs `polish`"),
        "{e}"
    );
    let e = parse_error("[[optimizer]]\nkind = \"pso\"\npolish = 0.1\npolish_with = \"bfgs\"\n");
    assert!(
        e.contains("bad.toml:11:") && e.contains("expected \"nelder-mead\" or \"lbfgs\""),
        "{e}"
    );
}
