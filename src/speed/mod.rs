//! `optbench bench`: evaluation speed measured in one process, as ratios against baselines
//! run alongside, so that a user sees what this machine gives before planning a suite.
//!
//! Every figure is the median of several timed repetitions (wall clock, after one warm-up).
//! The all-thread figures run the whole population on every thread at once (per core: each
//! thread's rate). Its fixtures ([`crate::physics::fixtures`]) are shared with the criterion
//! benches (`benches/models.rs`), which give the detailed view.

use crate::base::TrialSeed;
use crate::data::recording::Recording;
use crate::harness::Evaluator;
use crate::objective::functions::{Function, TestFunction};
use crate::objective::hysteresis::BoucWenFit;
use crate::objective::{Bounds, Objective};
use crate::optimizer::msga::MsgaConfig;
use crate::physics::bouc_wen;
use crate::physics::bouc_wen_fast::{self, FastInput};
use crate::physics::fixtures;
use crate::physics::rbf::{self, Mode, Narx, RbfNet, Regressors};
use crate::physics::rbf_fast::RbfBatch;
use crate::pipeline::runner::{TrialSpec, run_trial};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use std::time::Instant;

/// Sizes of a run.
#[derive(Clone, Copy, Debug)]
pub struct BenchConfig {
    /// Samples per record.
    pub samples: usize,
    /// Individuals per population.
    pub population: usize,
    /// Timed repetitions per figure (median reported).
    pub repeats: usize,
    /// Evaluations of the harness-overhead and MSGA measurements.
    pub evaluations: u64,
}

impl BenchConfig {
    /// The full run (about a minute on 2 cores): 10,000 samples x 200 individuals.
    pub fn full() -> Self {
        BenchConfig {
            samples: 10_000,
            population: 200,
            repeats: 5,
            evaluations: 200_000,
        }
    }

    /// A few seconds: 2,000 samples x 64 individuals.
    pub fn quick() -> Self {
        BenchConfig {
            samples: 2_000,
            population: 64,
            repeats: 3,
            evaluations: 40_000,
        }
    }
}

/// Median wall time in seconds of `repeats` runs of `f` (after one warm-up run).
fn time(repeats: usize, mut f: impl FnMut()) -> f64 {
    f();
    median(
        (0..repeats.max(1))
            .map(|_| {
                let s = Instant::now();
                f();
                s.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

/// The middle value (the upper one of an even count).
fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Runs `f` once on every thread of the pool at the same time, each with its own output of
/// `n` values: all cores busy with the whole population each, as when a suite runs trials
/// in parallel (splitting one population would measure load balance, not the cores: five
/// 40-lane blocks on two threads can gain at most 5/3).
fn everywhere(n: usize, f: impl Fn(&mut [f64]) + Sync) {
    rayon::broadcast(|_| {
        let mut out = vec![0.0; n];
        f(&mut out);
        std::hint::black_box(&out);
    });
}

/// One line of the table: a rate for the baseline, the batched path and the batched path on
/// every thread.
#[derive(Clone, Debug)]
pub struct Row {
    pub name: String,
    pub unit: &'static str,
    /// Work items (samples or evaluations) per timed run.
    pub work: f64,
    pub scalar_s: f64,
    pub batched_s: f64,
    /// Time for every thread to run the batched path once, concurrently ([`everywhere`]).
    pub threads_s: f64,
    pub threads: usize,
}

impl Row {
    fn rate(&self, s: f64, threads: usize) -> f64 {
        self.work / s / 1e6 / threads as f64
    }

    /// Batched over scalar.
    pub fn speedup(&self) -> f64 {
        self.scalar_s / self.batched_s
    }

    /// The batched path's rate per core with every core busy.
    pub fn threads_rate(&self) -> f64 {
        self.rate(self.threads_s, 1)
    }

    /// Whole machine with every thread against one thread.
    pub fn threads_speedup(&self) -> f64 {
        self.threads as f64 * self.batched_s / self.threads_s
    }
}

/// The whole measurement.
#[derive(Clone, Debug)]
pub struct BenchReport {
    pub rows: Vec<Row>,
    /// Evaluator over a bare loop on Griewank-30, minus one (0.03 = 3 % overhead).
    pub harness_overhead: f64,
    /// MSGA on its 5 membrane threads against the same MSGA in one thread (Bouc-Wen fit),
    /// with the dissertation's communication rule (`migration_lag = 0`).
    pub msga_threads_speedup: f64,
    /// The same with migrants taken one step late (`migration_lag = 1`).
    pub msga_threads_speedup_lagged: f64,
    pub accelerated: bool,
    pub threads: usize,
    /// Samples per record and individuals per population of the run.
    pub samples: usize,
    pub population: usize,
    /// The explicit recurrence's record and a few costs on it, so that a port elsewhere
    /// (`scripts/compare_peers.py`) can check it computes the same recurrence.
    pub explicit_check: ExplicitCheck,
}

/// A record and the explicit recurrence's costs of a few parameter sets on it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ExplicitCheck {
    pub u: Vec<f64>,
    pub y: Vec<f64>,
    /// `[d_e, alpha, beta, gamma, n, d0]` per parameter set.
    pub params: Vec<[f64; 6]>,
    /// [`bouc_wen_fast::cost_reference`] (`powf`) and the batched path.
    pub reference: Vec<f64>,
    pub batched: Vec<f64>,
}

/// The measurements [`run_with_progress`] announces, for a progress bar's length.
pub const STAGES: usize = 10;

/// Runs every measurement.
pub fn run(cfg: &BenchConfig) -> BenchReport {
    run_with_progress(cfg, &mut |_| {})
}

/// [`run`], calling `stage` with the name of each of the [`STAGES`] measurements as it starts.
pub fn run_with_progress(cfg: &BenchConfig, stage: &mut dyn FnMut(&str)) -> BenchReport {
    let threads = rayon::current_num_threads();
    let mut rows = Vec::new();
    let (u, y) = fixtures::record(cfg.samples);
    let samples = (cfg.samples * cfg.population) as f64;

    // Bouc-Wen fitting cost.
    let pop = fixtures::bouc_wen_population(cfg.population, 7);
    let input = FastInput::new(&u, &y, 1);
    let mut out = vec![0.0; pop.len()];
    stage("bouc-wen");
    rows.push(Row {
        name: "bouc-wen".into(),
        unit: "M samples/s",
        work: samples,
        scalar_s: time(cfg.repeats, || {
            for (p, o) in pop.iter().zip(out.iter_mut()) {
                *o = bouc_wen_fast::cost_reference(p, &input);
            }
        }),
        batched_s: time(cfg.repeats, || bouc_wen_fast::costs(&pop, &input, &mut out)),
        threads_s: time(cfg.repeats, || {
            everywhere(pop.len(), |o| bouc_wen_fast::costs(&pop, &input, o))
        }),
        threads,
    });
    let explicit = FastInput::explicit(&u, &y);
    let explicit_check = {
        let ps = &pop[..pop.len().min(4)];
        let mut batched = vec![0.0; ps.len()];
        bouc_wen_fast::costs(ps, &explicit, &mut batched);
        ExplicitCheck {
            u: u.clone(),
            y: y.clone(),
            params: ps
                .iter()
                .map(|p| [p.d_e, p.alpha, p.beta, p.gamma, p.n, p.d0])
                .collect(),
            reference: ps
                .iter()
                .map(|p| bouc_wen_fast::cost_reference(p, &explicit))
                .collect(),
            batched,
        }
    };
    stage("bouc-wen (explicit recurrence)");
    rows.push(Row {
        name: "bouc-wen (explicit recurrence)".into(),
        unit: "M samples/s",
        work: samples,
        scalar_s: time(cfg.repeats, || {
            for (p, o) in pop.iter().zip(out.iter_mut()) {
                *o = bouc_wen_fast::cost_reference(p, &explicit);
            }
        }),
        batched_s: time(cfg.repeats, || {
            bouc_wen_fast::costs(&pop, &explicit, &mut out)
        }),
        threads_s: time(cfg.repeats, || {
            everywhere(pop.len(), |o| bouc_wen_fast::costs(&pop, &explicit, o))
        }),
        threads,
    });
    stage("bouc-wen (accurate kernel)");
    let accurate_s = time(cfg.repeats.min(3), || {
        for (p, o) in pop.iter().zip(out.iter_mut()) {
            *o = bouc_wen::cost(p, &u, &y);
        }
    });
    rows.push(Row {
        name: "bouc-wen (accurate kernel)".into(),
        unit: "M samples/s",
        work: samples,
        scalar_s: accurate_s,
        batched_s: accurate_s,
        threads_s: time(cfg.repeats.min(3), || {
            everywhere(pop.len(), |o| {
                for (p, o) in pop.iter().zip(o.iter_mut()) {
                    *o = bouc_wen::cost(p, &u, &y);
                }
            })
        }),
        threads,
    });

    // RBF network, both modes.
    let (net, narx) = (RbfNet::SEED, Narx::SEED);
    let d = net.n_params();
    let rpop = fixtures::rbf_population(&u, &y, cfg.population, 8);
    let regs = Regressors::new(&narx, &u, &y);
    let batch = RbfBatch::new(net, narx, &u, &y);
    for (mode, tag) in [
        (Mode::OneStepAhead, "one-step"),
        (Mode::FreeRun, "free-run"),
    ] {
        stage(&format!("rbf 3-7-1 {tag}"));
        rows.push(Row {
            name: format!("rbf 3-7-1 {tag}"),
            unit: "M samples/s",
            work: samples,
            scalar_s: time(cfg.repeats, || {
                for (p, o) in rpop.chunks_exact(d).zip(out.iter_mut()) {
                    *o = match mode {
                        Mode::OneStepAhead => regs.cost(&net, p),
                        Mode::FreeRun => rbf::cost(&net, &narx, p, &u, &y, mode),
                    };
                }
            }),
            batched_s: time(cfg.repeats, || batch.costs(&rpop, mode, &mut out)),
            threads_s: time(cfg.repeats, || {
                everywhere(cfg.population, |o| batch.costs(&rpop, mode, o))
            }),
            threads,
        });
    }

    // Test functions: evaluations/s.
    let points = cfg.population * 50;
    for kind in [TestFunction::Griewank, TestFunction::Schwefel] {
        let dim = 30;
        let f = function(kind, dim);
        let xs = sample_points(f.bounds(), points, 9);
        let mut vals = vec![0.0; points];
        stage(&format!("{}-30", kind.name()));
        rows.push(Row {
            name: format!("{}-30", kind.name()),
            unit: "M evals/s",
            work: points as f64,
            scalar_s: time(cfg.repeats, || {
                for (x, v) in xs.chunks_exact(dim).zip(vals.iter_mut()) {
                    *v = f.evaluate(x);
                }
            }),
            batched_s: time(cfg.repeats, || f.evaluate_batch(&xs, &mut vals)),
            threads_s: time(cfg.repeats, || {
                everywhere(points, |v| f.evaluate_batch(&xs, v))
            }),
            threads,
        });
    }

    stage("harness overhead");
    let harness_overhead = harness_overhead(cfg);
    stage("msga threads");
    let msga_threads_speedup = msga_threads(cfg, 0);
    stage("msga threads, lagged migration");
    let msga_threads_speedup_lagged = msga_threads(cfg, 1);
    BenchReport {
        rows,
        harness_overhead,
        msga_threads_speedup,
        msga_threads_speedup_lagged,
        accelerated: bouc_wen_fast::accelerated(),
        threads,
        samples: cfg.samples,
        population: cfg.population,
        explicit_check,
    }
}

fn function(kind: TestFunction, dim: usize) -> Function {
    let (lo, hi) = kind.default_domain();
    Function::new(kind, Bounds::uniform(dim, lo, hi).expect("valid domain")).expect("valid")
}

fn sample_points(b: &Bounds, k: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut xs = vec![0.0; k * b.dim()];
    for x in xs.chunks_exact_mut(b.dim()) {
        b.sample(&mut rng, x);
    }
    xs
}

/// Evaluator (counting, budget, trace) against a bare loop over the same batches.
fn harness_overhead(cfg: &BenchConfig) -> f64 {
    let kind = TestFunction::Griewank;
    let f: Arc<dyn Objective> = Arc::new(function(kind, 30));
    let batch = 200;
    let xs = sample_points(f.bounds(), batch, 10);
    let rounds = (cfg.evaluations as usize).div_ceil(batch);
    let mut vals = vec![0.0; batch];
    let bare = time(cfg.repeats, || {
        for _ in 0..rounds {
            f.evaluate_batch(&xs, &mut vals);
        }
    });
    let harness = time(cfg.repeats, || {
        let mut ev = Evaluator::new(Arc::clone(&f), (rounds * batch) as u64, None);
        while !ev.done() {
            ev.evaluate_batch(&xs, &mut vals);
        }
    });
    harness / bare - 1.0
}

/// MSGA on 5 membrane threads against one thread, on a Bouc-Wen fit. The two are timed
/// in alternation (median of each), so that a change in the machine's load between them
/// does not land on one side only.
fn msga_threads(cfg: &BenchConfig, migration_lag: usize) -> f64 {
    let (u, y) = fixtures::record(cfg.samples);
    let rec = Recording::uniform("bench", 1e-3, u, y).expect("valid record");
    let fit: Arc<dyn Objective> = Arc::new(
        BoucWenFit::new(std::slice::from_ref(&rec), &[], false, true, 0.0, 1.5).expect("valid fit"),
    );
    let budget = (cfg.evaluations / 20).max(2000);
    let run = |threads: bool| {
        let opt = MsgaConfig {
            threads,
            migration_lag,
            ..MsgaConfig::default()
        };
        let start = Instant::now();
        run_trial(TrialSpec {
            objective_id: "bouc-wen",
            optimizer_id: "msga",
            trial: 0,
            objective: Arc::clone(&fit),
            optimizer: &opt,
            budget,
            stop_value: None,
            stall: None,
            seed: TrialSeed::from_u64(1),
        });
        start.elapsed().as_secs_f64()
    };
    run(false);
    run(true);
    let (one, five): (Vec<f64>, Vec<f64>) = (0..cfg.repeats.clamp(3, 5))
        .map(|_| (run(false), run(true)))
        .unzip();
    median(one) / median(five)
}

impl BenchReport {
    /// The measurement as JSON (`optbench bench --json FILE`): rates per core in each row's
    /// unit, the ratios, and the explicit recurrence's check data.
    pub fn to_json(&self) -> serde_json::Value {
        let rows: Vec<serde_json::Value> = self
            .rows
            .iter()
            .map(|r| {
                serde_json::json!({
                    "name": r.name,
                    "unit": r.unit,
                    "scalar": r.rate(r.scalar_s, 1),
                    "batched": r.rate(r.batched_s, 1),
                    "threads": r.threads_rate(),
                    "batched_over_scalar": r.speedup(),
                    "threads_over_batched": r.threads_speedup(),
                })
            })
            .collect();
        serde_json::json!({
            "threads": self.threads,
            "accelerated": self.accelerated,
            "samples": self.samples,
            "population": self.population,
            "rows": rows,
            "harness_overhead": self.harness_overhead,
            "msga_threads_speedup": self.msga_threads_speedup,
            "msga_threads_speedup_lagged": self.msga_threads_speedup_lagged,
            "explicit_check": self.explicit_check,
        })
    }

    /// The table as printed by `optbench bench`.
    pub fn render(&self) -> String {
        let mut s = String::new();
        let path = if self.accelerated {
            "AVX2+FMA"
        } else {
            "portable"
        };
        s.push_str(&format!(
            "evaluation speed, per core ({} threads, batched kernels: {path})\n\n",
            self.threads
        ));
        s.push_str(&format!(
            "{:<31} {:>12} {:>10} {:>10} {:>10} {:>9} {:>9}\n",
            "objective", "unit", "scalar", "batched", "threads", "b/s", "t/b"
        ));
        for r in &self.rows {
            s.push_str(&format!(
                "{:<31} {:>12} {:>10.1} {:>10.1} {:>10.1} {:>8.1}x {:>8.2}x\n",
                r.name,
                r.unit,
                r.rate(r.scalar_s, 1),
                r.rate(r.batched_s, 1),
                r.threads_rate(),
                r.speedup(),
                r.threads_speedup(),
            ));
        }
        s.push_str(
            "\nscalar: one individual at a time (std exp/powf); batched: the objective's population path;\nthreads: every thread running the batched path at once, per core; b/s = batched/scalar;\nt/b = all threads/one thread (whole machine)\n\n",
        );
        s.push_str(&format!(
            "harness overhead on griewank-30 (Evaluator vs bare loop): {:+.1} % (goal <= 5 %)\n",
            100.0 * self.harness_overhead
        ));
        s.push_str(&format!(
            "msga on the bouc-wen fit, 5 membrane threads / 1 thread: {:.2}x (seed's rule), \
             {:.2}x (migration_lag = 1)\n",
            self.msga_threads_speedup, self.msga_threads_speedup_lagged
        ));
        if let Some(bw) = self.rows.iter().find(|r| r.name == "bouc-wen") {
            s.push_str(&format!("bouc-wen batched/scalar = {:.1}x\n", bw.speedup()));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tiny_run_measures_every_row_and_ends_with_the_bouc_wen_ratio() {
        let cfg = BenchConfig {
            samples: 200,
            population: 20,
            repeats: 1,
            evaluations: 2000,
        };
        let mut stages = Vec::new();
        let r = run_with_progress(&cfg, &mut |s| stages.push(s.to_string()));
        assert_eq!(r.rows.len(), 7);
        // Every row announced by its own name, then the three whole-run figures.
        assert_eq!(stages.len(), STAGES);
        for (row, stage) in r.rows.iter().zip(&stages) {
            assert_eq!(&row.name, stage);
        }
        for row in &r.rows {
            assert!(row.scalar_s > 0.0 && row.batched_s > 0.0 && row.threads_s > 0.0);
        }
        assert!(r.harness_overhead.is_finite() && r.msga_threads_speedup > 0.0);
        assert!(r.msga_threads_speedup_lagged > 0.0);
        let text = r.render();
        let last = text.lines().last().unwrap();
        assert!(last.starts_with("bouc-wen batched/scalar = "), "{last}");
        assert!(last.ends_with('x'));
        let json = r.to_json();
        assert_eq!(json["rows"].as_array().unwrap().len(), 7);
        let check = &r.explicit_check;
        assert_eq!(check.u.len(), 200);
        for (a, b) in check.reference.iter().zip(&check.batched) {
            assert!(((a - b) / a).abs() < 1e-6, "{a} vs {b}");
        }
    }
}
