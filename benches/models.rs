//! Samples per second of the physics models on a fitting-sized record (1000 samples of a
//! 10 Hz sine on the twin's command scale): the Bouc-Wen cost for n = 1 (closed form) and
//! n = 1.3 (series + RK4), and the 3-7-1 RBF network's one-step and free-run costs. This is
//! the per-individual baseline that batched population paths are measured against.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use optbench::physics::bouc_wen::{self, BoucWenParams};
use optbench::physics::rbf::{self, Mode, Narx, RbfNet, Regressors};
use std::hint::black_box;

const N: usize = 1000;

fn record() -> (Vec<f64>, Vec<f64>) {
    let u: Vec<f64> = (0..N)
        .map(|k| 2.35 + 2.3 * (2.0 * std::f64::consts::PI * 10.0 * k as f64 * 1e-3).sin())
        .collect();
    let p = BoucWenParams {
        d_e: 0.1545,
        alpha: 0.045,
        beta: 0.45,
        gamma: 0.225,
        n: 1.0,
        d0: 0.0,
    };
    let mut y = vec![0.0; N];
    bouc_wen::simulate(&p, &u, &mut y);
    (u, y)
}

fn models(c: &mut Criterion) {
    let (u, y) = record();
    let mut g = c.benchmark_group("model_cost_1000_samples");
    g.throughput(Throughput::Elements(N as u64));
    for n in [1.0, 1.3] {
        let p = BoucWenParams {
            d_e: 0.15,
            alpha: 0.05,
            beta: 0.5,
            gamma: 0.2,
            n,
            d0: 0.0,
        };
        g.bench_with_input(BenchmarkId::new("bouc-wen", n), &p, |b, p| {
            b.iter(|| bouc_wen::cost(black_box(p), &u, &y))
        });
    }
    let net = RbfNet::SEED;
    let narx = Narx::SEED;
    let regs = Regressors::new(&narx, &u, &y);
    let (lo, hi) = regs.input_ranges();
    let p = rbf::init_params(&net, &lo, &hi);
    g.bench_function("rbf-3-7-1/one-step", |b| {
        b.iter(|| regs.cost(&net, black_box(&p)))
    });
    g.bench_function("rbf-3-7-1/free-run", |b| {
        b.iter(|| rbf::cost(&net, &narx, black_box(&p), &u, &y, Mode::FreeRun))
    });
    g.finish();
}

criterion_group!(benches, models);
criterion_main!(benches);
