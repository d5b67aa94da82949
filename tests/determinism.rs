//! Same seed, same results, whatever the thread count; and the seed optimizers beat random
//! search.

mod common;

use common::without_time;
use optbench::pipeline::runner::{RunOptions, run_suite};
use optbench::pipeline::suite::Suite;
use std::path::Path;

const SUITE: &str = r#"
name = "determinism"
seed = 7
trials = 4
budget = 3000

[[objective]]
kind = "griewank"
dim = 2

[[objective]]
kind = "rastrigin"
dim = 5
stop_at = 1e-3

[[optimizer]]
kind = "ga"

[[optimizer]]
kind = "pso"

[[optimizer]]
kind = "msga"

[[optimizer]]
kind = "random"
"#;

fn run(text: &str, threads: usize) -> Vec<optbench::harness::TrialRecord> {
    let suite = Suite::parse(text, Path::new("determinism.toml")).unwrap();
    let opts = RunOptions {
        threads: Some(threads),
        progress: false,
    };
    run_suite(&suite, &opts)
        .unwrap()
        .0
        .into_iter()
        .map(without_time)
        .collect()
}

#[test]
fn results_do_not_depend_on_thread_count_or_repetition() {
    let one = run(SUITE, 1);
    assert_eq!(one.len(), 2 * 4 * 4);
    assert_eq!(one, run(SUITE, 3), "1 thread vs 3 threads");
    assert_eq!(one, run(SUITE, 1), "repeat");
    let summary = |r: &[optbench::harness::TrialRecord]| {
        let mut s = optbench::pipeline::store::summarize("determinism", 7, r);
        for c in &mut s.results {
            c.wall_s = 0.0;
        }
        serde_json::to_string(&s).unwrap()
    };
    assert_eq!(summary(&one), summary(&run(SUITE, 2)), "summary bytes");
}

#[test]
fn another_seed_changes_every_cell() {
    let a = run(SUITE, 2);
    let b = run(&SUITE.replace("seed = 7", "seed = 8"), 2);
    for (x, y) in a.iter().zip(&b) {
        assert_ne!(x.best_x, y.best_x, "{} {}", x.objective, x.optimizer);
    }
}

#[test]
fn each_seed_optimizer_beats_random_search_on_2d_griewank() {
    // The dissertation's Table 2.3 setting at a tenth of the budget (200 x 20), 15 fixed seeds.
    let text = r#"
name = "beat-random"
seed = 2013
trials = 15
budget = 4000
[[objective]]
kind = "griewank"
dim = 2
lower = -600
upper = 600
[[optimizer]]
kind = "ga"
[[optimizer]]
kind = "pso"
[[optimizer]]
kind = "msga"
[[optimizer]]
kind = "random"
"#;
    let records = run(text, 2);
    let summary = optbench::pipeline::store::summarize("beat-random", 2013, &records);
    let rs = summary
        .results
        .iter()
        .find(|c| c.optimizer == "random")
        .unwrap();
    for c in summary.results.iter().filter(|c| c.optimizer != "random") {
        // Median below random search's best quartile, and most trials below its median.
        assert!(
            c.median < rs.q1,
            "{}: median {} vs random q1 {}",
            c.optimizer,
            c.median,
            rs.q1
        );
        let wins = c.finals.iter().filter(|&&f| f < rs.median).count();
        assert!(
            wins >= 12,
            "{}: only {wins}/15 trials beat random's median",
            c.optimizer
        );
    }
}
