//! Speed of the harness: objective evaluation, one generation of each optimizer, and MSGA
//! on 5 membrane threads against the same MSGA in one thread. After the run, the ratios
//! between variants measured in this same process are printed.

use criterion::{BenchmarkId, Criterion, Throughput};
use optbench::base::TrialSeed;
use optbench::harness::{Evaluator, OptimizerConfig};
use optbench::objective::Objective;
use optbench::objective::functions::{Function, TestFunction};
use optbench::optimizer::msga::MsgaConfig;
use optbench::pipeline::runner::{TrialSpec, run_trial};
use optbench::registry::default_optimizer;
use std::hint::black_box;
use std::sync::Arc;

fn objectives(c: &mut Criterion) {
    let mut g = c.benchmark_group("objective_batch200");
    g.throughput(Throughput::Elements(200));
    for kind in TestFunction::ALL {
        for dim in [2usize, 30] {
            let f = Function::standard(kind, dim).unwrap();
            let mut rng = TrialSeed::from_u64(1).rng(0);
            let mut pts = vec![0.0; 200 * dim];
            for x in pts.chunks_exact_mut(dim) {
                f.bounds().sample(&mut rng, x);
            }
            let mut out = vec![0.0; 200];
            g.bench_with_input(BenchmarkId::new(kind.name(), dim), &pts, |b, pts| {
                b.iter(|| f.evaluate_batch(black_box(pts), &mut out))
            });
        }
    }
    g.finish();
}

fn generations(c: &mut Criterion) {
    let mut g = c.benchmark_group("generation_griewank30");
    let obj: Arc<dyn Objective> = Arc::new(Function::standard(TestFunction::Griewank, 30).unwrap());
    let mut configs: Vec<(&str, Arc<dyn OptimizerConfig>)> = ["ga", "pso", "msga", "random"]
        .into_iter()
        .map(|n| (n, default_optimizer(n).unwrap()))
        .collect();
    configs.push((
        "msga-1thread",
        Arc::new(MsgaConfig {
            threads: false,
            ..MsgaConfig::default()
        }),
    ));
    for (name, cfg) in configs {
        g.throughput(Throughput::Elements(cfg.batch_size() as u64));
        let mut opt = cfg.start(obj.bounds(), u64::MAX / 2, &TrialSeed::from_u64(2));
        let mut ev = Evaluator::new(Arc::clone(&obj), u64::MAX / 2, None);
        opt.step(&mut ev); // initial population
        g.bench_function(name, |b| b.iter(|| opt.step(&mut ev)));
    }
    g.finish();
}

/// MSGA trial time on 5 membrane threads and on 1 thread, on a cheap objective (where
/// synchronisation dominates) and a costly one (where evaluation does), with the dissertation's
/// communication rule and with migrants one step late (`migration_lag = 1`).
fn msga_threads(c: &mut Criterion) {
    let mut g = c.benchmark_group("msga_threads");
    g.sample_size(10);
    for dim in [30usize, 2000] {
        let obj: Arc<dyn Objective> =
            Arc::new(Function::standard(TestFunction::Griewank, dim).unwrap());
        for (name, threads, migration_lag) in [
            ("5threads", true, 0),
            ("1thread", false, 0),
            ("5threads-lag1", true, 1),
            ("1thread-lag1", false, 1),
        ] {
            let cfg = MsgaConfig {
                threads,
                migration_lag,
                ..MsgaConfig::default()
            };
            let id = BenchmarkId::new(name, dim);
            g.bench_function(id, |b| {
                b.iter(|| {
                    run_trial(TrialSpec {
                        objective_id: "griewank",
                        optimizer_id: "msga",
                        trial: 0,
                        objective: Arc::clone(&obj),
                        optimizer: &cfg,
                        budget: 4000,
                        stop_value: None,
                        stall: None,
                        seed: TrialSeed::from_u64(3),
                    })
                })
            });
        }
    }
    g.finish();
}

/// Mean time of a finished benchmark from criterion's estimates, in nanoseconds.
fn mean_ns(group: &str, id: &str) -> Option<f64> {
    let target = std::env::var("CARGO_TARGET_DIR").unwrap_or_else(|_| "target".into());
    let path = format!("{target}/criterion/{group}/{id}/new/estimates.json");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
    v["mean"]["point_estimate"].as_f64()
}

fn print_ratios() {
    let mut lines = Vec::new();
    for dim in [30, 2000] {
        for (lag, what) in [("", "seed's rule"), ("-lag1", "migration_lag = 1")] {
            if let (Some(t5), Some(t1)) = (
                mean_ns("msga_threads", &format!("5threads{lag}/{dim}")),
                mean_ns("msga_threads", &format!("1thread{lag}/{dim}")),
            ) {
                lines.push(format!(
                    "msga griewank-{dim}d ({what}): 1 thread / 5 threads = {:.2}x ({:.1} ms vs {:.1} ms per 4000-evaluation trial)",
                    t1 / t5,
                    t1 / 1e6,
                    t5 / 1e6
                ));
            }
        }
    }
    if let (Some(s), Some(t)) = (
        mean_ns("generation_griewank30", "msga-1thread"),
        mean_ns("generation_griewank30", "msga"),
    ) {
        lines.push(format!(
            "msga generation griewank-30d: 1 thread / 5 threads = {:.2}x",
            s / t
        ));
    }
    if !lines.is_empty() {
        println!("\nratios measured in this run (> 1 means the threaded MSGA is faster):");
        for l in lines {
            println!("  {l}");
        }
    }
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    objectives(&mut c);
    generations(&mut c);
    msga_threads(&mut c);
    c.final_summary();
    print_ratios();
}
