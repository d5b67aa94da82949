//! Fixtures of the speed measurements (`optbench bench`, `benches/models.rs`) and of the
//! kernels' tests: a fitting-sized record and populations around its truth.

use super::bouc_wen::{self, BoucWenParams};
use super::rbf::{self, Narx, RbfNet, Regressors};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
/// The Bouc-Wen parameters of [`record`] (the twin's hysteresis on the command scale).
pub const TRUTH: BoucWenParams = BoucWenParams {
    d_e: 0.1545,
    alpha: 0.045,
    beta: 0.45,
    gamma: 0.225,
    n: 1.0,
    d0: 0.0,
};

/// `n` samples of a 10 Hz sine on the twin's command scale (1 ms) and the Bouc-Wen
/// output of [`TRUTH`].
pub fn record(n: usize) -> (Vec<f64>, Vec<f64>) {
    let u: Vec<f64> = (0..n)
        .map(|k| 2.35 + 2.3 * (2.0 * std::f64::consts::PI * 10.0 * k as f64 * 1e-3).sin())
        .collect();
    let mut y = vec![0.0; n];
    bouc_wen::simulate(&TRUTH, &u, &mut y);
    (u, y)
}

/// `k` parameter sets, each within ±50 % of [`TRUTH`] (as in mid-search).
pub fn bouc_wen_population(k: usize, seed: u64) -> Vec<BoucWenParams> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut f = |x: f64| x * rng.random_range(0.5..1.5);
    (0..k)
        .map(|_| BoucWenParams {
            d_e: f(TRUTH.d_e),
            alpha: f(TRUTH.alpha),
            beta: f(TRUTH.beta),
            gamma: f(TRUTH.gamma),
            n: f(TRUTH.n),
            d0: 0.0,
        })
        .collect()
}

/// `k` row-major parameter vectors of the dissertation's 3-7-1 network on `(u, y)`, each entry
/// within ±20 % of the usual initialisation.
pub fn rbf_population(u: &[f64], y: &[f64], k: usize, seed: u64) -> Vec<f64> {
    let (net, narx) = (RbfNet::SEED, Narx::SEED);
    let regs = Regressors::new(&narx, u, y);
    let (lo, hi) = regs.input_ranges();
    let base = rbf::init_params(&net, &lo, &hi);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let d = net.n_params();
    (0..k * d)
        .map(|q| base[q % d] * rng.random_range(0.8..1.2))
        .collect()
}
