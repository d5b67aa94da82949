//! Samples per second of the physics models' fitting costs over a population, as a fitting
//! objective evaluates them: 200 individuals on a 10,000-sample record (a 10 Hz sine on the
//! twin's command scale). Each model runs its per-individual loop (the baseline) and its
//! batched path; after the run the ratios between them are printed (`cargo bench --bench
//! models`).
//!
//! Samples/s = individuals × samples / time (criterion's "elem/s").
//!
//! And one evaluation of a diagnosis candidate on a 40,000-sample record (the Bouc-Wen
//! chain plus its linear least squares), projected (as `diagnose` runs it) against the
//! direct Gram-Schmidt solve on all columns (the reference), per structure.

// As in the `optbench` binary.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use criterion::{BenchmarkId, Criterion, Throughput};
use optbench::physics::bouc_wen;
use optbench::physics::bouc_wen_fast::{self, FastInput};
use optbench::physics::fixtures;
use optbench::physics::rbf::{self, Mode, Narx, RbfNet, Regressors};
use optbench::physics::rbf_fast::RbfBatch;
use optbench::physics::structure::{Context, Effect, Form, Structure};
use rayon::prelude::*;
use std::hint::black_box;

const N: usize = 10_000;
const POP: usize = 200;

fn bouc_wen_costs(c: &mut Criterion) {
    let (u, y) = fixtures::record(N);
    let pop = fixtures::bouc_wen_population(POP, 7);
    let input = FastInput::new(&u, &y, 1);
    let mut out = vec![0.0; POP];
    let mut g = c.benchmark_group("bouc_wen_pop200_10k");
    g.throughput(Throughput::Elements((POP * N) as u64));
    g.sample_size(10);
    g.bench_function("accurate-per-individual", |b| {
        b.iter(|| {
            for (p, o) in pop.iter().zip(out.iter_mut()) {
                *o = bouc_wen::cost(p, &u, &y);
            }
            black_box(&out);
        })
    });
    g.bench_function("fast-scalar-reference", |b| {
        b.iter(|| {
            for (p, o) in pop.iter().zip(out.iter_mut()) {
                *o = bouc_wen_fast::cost_reference(p, &input);
            }
            black_box(&out);
        })
    });
    g.bench_function("fast-batched-portable", |b| {
        b.iter(|| bouc_wen_fast::costs_portable(black_box(&pop), &[], &input, &mut out))
    });
    g.bench_function("fast-batched", |b| {
        b.iter(|| bouc_wen_fast::costs(black_box(&pop), &input, &mut out))
    });
    g.bench_function("fast-batched-all-threads", |b| {
        b.iter(|| {
            pop.par_chunks(bouc_wen_fast::LANES)
                .zip(out.par_chunks_mut(bouc_wen_fast::LANES))
                .for_each(|(p, o)| bouc_wen_fast::costs(p, &input, o))
        })
    });
    // The dissertation's explicit recurrence (one `|h|^n` per sample).
    let explicit = FastInput::explicit(&u, &y);
    g.bench_function("explicit-scalar-reference", |b| {
        b.iter(|| {
            for (p, o) in pop.iter().zip(out.iter_mut()) {
                *o = bouc_wen_fast::cost_reference(p, &explicit);
            }
            black_box(&out);
        })
    });
    g.bench_function("explicit-batched-portable", |b| {
        b.iter(|| bouc_wen_fast::costs_portable(black_box(&pop), &[], &explicit, &mut out))
    });
    g.bench_function("explicit-batched", |b| {
        b.iter(|| bouc_wen_fast::costs(black_box(&pop), &explicit, &mut out))
    });
    g.finish();
}

fn rbf_costs(c: &mut Criterion) {
    let (u, y) = fixtures::record(N);
    let (net, narx) = (RbfNet::SEED, Narx::SEED);
    let regs = Regressors::new(&narx, &u, &y);
    let d = net.n_params();
    let pop = fixtures::rbf_population(&u, &y, POP, 8);
    let batch = RbfBatch::new(net, narx, &u, &y);
    let mut out = vec![0.0; POP];
    let mut g = c.benchmark_group("rbf_3_7_1_pop200_10k");
    g.throughput(Throughput::Elements((POP * N) as u64));
    g.sample_size(10);
    for (mode, tag) in [
        (Mode::OneStepAhead, "one-step"),
        (Mode::FreeRun, "free-run"),
    ] {
        g.bench_function(BenchmarkId::new("per-individual", tag), |b| {
            b.iter(|| {
                for (p, o) in pop.chunks_exact(d).zip(out.iter_mut()) {
                    *o = match mode {
                        Mode::OneStepAhead => regs.cost(&net, p),
                        Mode::FreeRun => rbf::cost(&net, &narx, p, &u, &y, mode),
                    };
                }
                black_box(&out);
            })
        });
        g.bench_function(BenchmarkId::new("batched", tag), |b| {
            b.iter(|| batch.costs(black_box(&pop), mode, &mut out))
        });
    }
    g.finish();
}

/// The diagnosis structures timed by [`diagnose_costs`]: name and (effect, form) parts.
fn diagnose_structures() -> Vec<(&'static str, Vec<(Effect, Form)>)> {
    vec![
        ("plain", vec![]),
        ("creep", vec![(Effect::Creep, Form::KelvinVoigt)]),
        (
            "creep+spline-drift",
            vec![
                (Effect::Creep, Form::KelvinVoigt),
                (Effect::OffsetDrift, Form::Spline),
            ],
        ),
        // The slowest blind cases' final models: every linear block at once.
        (
            "log-creep+two-modes",
            vec![
                (Effect::Creep, Form::Logarithmic),
                (Effect::Dynamics, Form::TwoModes),
            ],
        ),
    ]
}

const DIAG_N: usize = 40_000;

fn diagnose_costs(c: &mut Criterion) {
    let (u, y) = fixtures::record(DIAG_N);
    let ctx = Context::from_training(&u, 1e-3);
    let mut g = c.benchmark_group("diagnose_eval_40k");
    g.throughput(Throughput::Elements(DIAG_N as u64));
    g.sample_size(20);
    for (name, parts) in diagnose_structures() {
        let mut st = Structure::new(&[], Some(1.0), ctx);
        for (e, f) in parts {
            st = st.extended_with(e, f);
        }
        // Neutral shape with both creep elements active (their states inside the bounds).
        let theta: Vec<f64> = st
            .specs()
            .iter()
            .map(|s| match s.name {
                "creep_g" => 0.05,
                "creep_g2" => 0.03,
                "creep_log_gain" => 0.02,
                "mode_log10_hz" => 150f64.log10(),
                "mode2_log10_hz" => 40f64.log10(),
                "mode2_share" => 0.3,
                _ => s.neutral,
            })
            .collect();
        let proj = st.projection(&u, &y);
        g.bench_function(BenchmarkId::new("projected", name), |b| {
            b.iter(|| black_box(st.fit_linear_projected(&theta, &u, &y, &proj).cost))
        });
        g.bench_function(BenchmarkId::new("reference", name), |b| {
            b.iter(|| black_box(st.fit_linear_reference(&theta, &u, &y).cost))
        });
    }
    g.finish();
}

fn print_diagnose_ratios() {
    let group = "diagnose_eval_40k";
    println!("\nOne diagnosis evaluation, {DIAG_N} samples (this run):");
    let plain = mean_ns(group, "projected/plain");
    for (name, _) in diagnose_structures() {
        let p = mean_ns(group, &format!("projected/{name}"));
        let r = mean_ns(group, &format!("reference/{name}"));
        if let (Some(p), Some(r), Some(plain)) = (p, r, plain) {
            println!(
                "  {name:<19} projected {:>6.2} ms, reference {:>6.2} ms: reference / projected = {:.2}x, projected / plain = {:.2}x",
                p * 1e-6,
                r * 1e-6,
                r / p,
                p / plain
            );
        }
    }
}

/// Mean time of a finished benchmark from criterion's estimates, in nanoseconds.
fn mean_ns(group: &str, id: &str) -> Option<f64> {
    let target = std::env::var("CARGO_TARGET_DIR").unwrap_or_else(|_| "target".into());
    let path = format!("{target}/criterion/{group}/{id}/new/estimates.json");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
    v["mean"]["point_estimate"].as_f64()
}

fn print_ratios() {
    let group = "bouc_wen_pop200_10k";
    let samples = (POP * N) as f64;
    let ids = [
        "accurate-per-individual",
        "fast-scalar-reference",
        "fast-batched-portable",
        "fast-batched",
        "fast-batched-all-threads",
        "explicit-scalar-reference",
        "explicit-batched-portable",
        "explicit-batched",
    ];
    let t: Vec<Option<f64>> = ids.iter().map(|id| mean_ns(group, id)).collect();
    println!("\nBouc-Wen cost, {POP} individuals x {N} samples (this run):");
    for (id, t) in ids.iter().zip(&t) {
        if let Some(t) = t {
            println!("  {id:<26} {:>8.1} M samples/s", samples / t * 1e3);
        }
    }
    let threads = rayon::current_num_threads() as f64;
    if let (Some(acc), Some(reference), Some(port), Some(fast), Some(all)) =
        (t[0], t[1], t[2], t[3], t[4])
    {
        println!("  batched / accurate per-individual = {:.1}x", acc / fast);
        println!(
            "  batched / fast scalar reference   = {:.1}x",
            reference / fast
        );
        println!("  batched / batched portable        = {:.1}x", port / fast);
        println!(
            "  all {threads} threads / one thread       = {:.2}x ({:.1} M samples/s per core)",
            fast / all,
            samples / all * 1e3 / threads
        );
    }
    if let (Some(reference), Some(port), Some(fast)) = (t[5], t[6], t[7]) {
        println!(
            "  explicit batched / its scalar reference = {:.1}x, / its portable copy = {:.1}x",
            reference / fast,
            port / fast
        );
    }
}

fn print_rbf_ratios() {
    let group = "rbf_3_7_1_pop200_10k";
    let samples = (POP * N) as f64;
    println!("\nRBF 3-7-1 cost, {POP} individuals x {N} samples (this run):");
    for tag in ["one-step", "free-run"] {
        let one = mean_ns(group, &format!("per-individual/{tag}"));
        let all = mean_ns(group, &format!("batched/{tag}"));
        if let (Some(one), Some(all)) = (one, all) {
            println!(
                "  {tag:<9} per-individual {:>6.1} M samples/s, batched {:>6.1} M samples/s: batched / per-individual = {:.1}x",
                samples / one * 1e3,
                samples / all * 1e3,
                one / all
            );
        }
    }
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bouc_wen_costs(&mut c);
    rbf_costs(&mut c);
    diagnose_costs(&mut c);
    c.final_summary();
    print_ratios();
    print_rbf_ratios();
    print_diagnose_ratios();
}
