//! Batched fitting costs of the RBF NARX network (the costs of [`super::rbf::cost`]) for a
//! population, with the vectorisable `exp` of [`super::fastmath`].
//!
//! - One-step-ahead is not a recurrence: each individual runs vectorised over time, [`TLANES`]
//!   samples per block (regressors stored column by column), each block's squared errors
//!   summed in lanes and the lanes added in a fixed order at the end.
//! - Free run is a recurrence in time, so the population runs in lanes instead ([`LANES`]
//!   individuals per block, one fed-back output history per lane).
//!
//! As for the Bouc-Wen kernel, an AVX2+FMA copy is chosen at run time and a portable copy
//! serves other CPUs; both use explicit `mul_add` and give the same bits, and each cost
//! depends on its own individual only. The saturation and divergence rules are those of
//! [`super::rbf::cost`]; the costs agree with it within 1e-12 relative (the `exp`
//! polynomial and the summation order differ), tested at 1e-9. The `exp` is
//! [`fastmath::exp2_fast`] (relative error 8e-13 + 2.2e-16 |x|, tested) with `log2 e` folded
//! into each node's width factor.

// `!(x <= bound)` is deliberate (it is true for NaN), and index loops over lane arrays are
// the shape that vectorises.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
use super::fastmath::{self, select};
use super::rbf::{Mode, Narx, RbfNet, error_cap, exponent_factor};
use std::f64::consts::LOG2_E;

/// Individuals per free-run block.
pub const LANES: usize = 16;
/// Samples per one-step block.
pub const TLANES: usize = 32;

/// A recording prepared for batched RBF costs.
#[derive(Clone, Debug)]
pub struct RbfBatch {
    net: RbfNet,
    narx: Narx,
    r: Vec<f64>,
    y: Vec<f64>,
    /// One-step regressors, column-major: `cols[i][k]` is input `i` of sample `start + k`.
    cols: Vec<Vec<f64>>,
    cap: f64,
}

impl RbfBatch {
    /// `net` with regressors `narx` on input `r` and measured output `y` (same length).
    pub fn new(net: RbfNet, narx: Narx, r: &[f64], y: &[f64]) -> Self {
        assert_eq!(net.inputs, narx.dim(), "net inputs vs NARX regressors");
        assert_eq!(r.len(), y.len(), "input and output lengths");
        let n = r.len();
        let s = narx.start().min(n);
        let mut cols = vec![vec![0.0; n - s]; narx.dim()];
        let mut x = vec![0.0; narx.dim()];
        for k in s..n {
            narx.regressor(r, y, k, &mut x);
            for (c, v) in cols.iter_mut().zip(&x) {
                c[k - s] = *v;
            }
        }
        RbfBatch {
            net,
            narx,
            r: r.to_vec(),
            y: y.to_vec(),
            cols,
            cap: error_cap(y),
        }
    }

    /// Costs of the row-major `points` (one parameter vector per row) in `mode`.
    pub fn costs(&self, points: &[f64], mode: Mode, out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if super::bouc_wen_fast::accelerated() {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above).
            unsafe { self.costs_avx2(points, mode, out) };
            return;
        }
        self.costs_portable(points, mode, out);
    }

    /// [`Self::costs`] compiled for any CPU (public for tests and benches).
    pub fn costs_portable(&self, points: &[f64], mode: Mode, out: &mut [f64]) {
        self.costs_impl(points, mode, out);
    }

    /// [`Self::costs`] compiled for AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn costs_avx2(&self, points: &[f64], mode: Mode, out: &mut [f64]) {
        self.costs_impl(points, mode, out);
    }

    #[inline(always)]
    fn costs_impl(&self, points: &[f64], mode: Mode, out: &mut [f64]) {
        let d = self.net.n_params();
        assert_eq!(points.len(), out.len() * d, "one cost per parameter vector");
        match mode {
            Mode::OneStepAhead => {
                for (p, o) in points.chunks_exact(d).zip(out.iter_mut()) {
                    *o = self.one_step(p);
                }
            }
            Mode::FreeRun => {
                for (ps, os) in points.chunks(LANES * d).zip(out.chunks_mut(LANES)) {
                    let mut block = [0.0; LANES];
                    self.free_run_block(ps, &mut block);
                    os.copy_from_slice(&block[..os.len()]);
                }
            }
        }
    }

    /// One-step cost of one individual, vectorised over time.
    #[inline(always)]
    fn one_step(&self, p: &[f64]) -> f64 {
        let (h, m) = (self.net.hidden, self.net.inputs);
        let (c, rest) = p.split_at(h * m);
        let (b, w) = rest.split_at(h);
        // `exp(k d²) = 2^(k log2(e) d²)`: the factor carries `log2 e`.
        let kf: Vec<f64> = b.iter().map(|&b| exponent_factor(b) * LOG2_E).collect();
        let t = &self.y[self.y.len() - self.cols[0].len()..];
        let len = t.len();
        let cap = self.cap;
        let mut acc = [0.0; TLANES];
        // Exponents of every node and lane, then every `exp` in one flat loop (independent
        // chains for the CPU to overlap), then the weighted sums in node order.
        let mut z = vec![[0.0; TLANES]; h];
        let mut k0 = 0;
        while k0 + TLANES <= len {
            for (j, zj) in z.iter_mut().enumerate() {
                let mut d2 = [0.0; TLANES];
                for i in 0..m {
                    let col = &self.cols[i][k0..k0 + TLANES];
                    let cj = c[j * m + i];
                    for l in 0..TLANES {
                        let dx = col[l] - cj;
                        d2[l] = dx.mul_add(dx, d2[l]);
                    }
                }
                for l in 0..TLANES {
                    zj[l] = kf[j] * d2[l];
                }
            }
            for zj in z.iter_mut() {
                for v in zj.iter_mut() {
                    *v = fastmath::exp2_fast(*v);
                }
            }
            let mut ym = [0.0; TLANES];
            for (j, zj) in z.iter().enumerate() {
                for l in 0..TLANES {
                    ym[l] = w[j].mul_add(zj[l], ym[l]);
                }
            }
            for l in 0..TLANES {
                let e = (ym[l] - t[k0 + l]).abs();
                let e = select(e <= cap, e, cap);
                acc[l] = (0.5 * e).mul_add(e, acc[l]);
            }
            k0 += TLANES;
        }
        let mut tail = 0.0;
        for k in k0..len {
            let mut ym = 0.0;
            for j in 0..h {
                let mut d2 = 0.0;
                for i in 0..m {
                    let dx = self.cols[i][k] - c[j * m + i];
                    d2 = dx.mul_add(dx, d2);
                }
                ym = w[j].mul_add(fastmath::exp2_fast(kf[j] * d2), ym);
            }
            let e = (ym - t[k]).abs();
            let e = select(e <= cap, e, cap);
            tail = (0.5 * e).mul_add(e, tail);
        }
        acc.iter().sum::<f64>() + tail
    }

    /// Free-run costs of up to [`LANES`] individuals (row-major `ps`), population in lanes.
    #[inline(always)]
    fn free_run_block(&self, ps: &[f64], out: &mut [f64; LANES]) {
        let (h, m) = (self.net.hidden, self.net.inputs);
        let d = self.net.n_params();
        let rows = ps.len() / d;
        // Structure of arrays; missing lanes repeat the last individual (discarded).
        let lane = |l: usize| &ps[l.min(rows - 1) * d..][..d];
        let c: Vec<[f64; LANES]> = (0..h * m)
            .map(|q| std::array::from_fn(|l| lane(l)[q]))
            .collect();
        let kf: Vec<[f64; LANES]> = (0..h)
            .map(|j| std::array::from_fn(|l| exponent_factor(lane(l)[h * m + j]) * LOG2_E))
            .collect();
        let w: Vec<[f64; LANES]> = (0..h)
            .map(|j| std::array::from_fn(|l| lane(l)[h * (m + 1) + j]))
            .collect();
        let (il, ol) = (self.narx.input_lags, self.narx.output_lags);
        let n = self.r.len();
        let s = self.narx.start().min(n);
        let cap = self.cap;
        // Fed-back outputs, newest first; initial conditions from the measurement.
        let mut hist: Vec<[f64; LANES]> = (0..ol)
            .map(|o| [if s > o { self.y[s - 1 - o] } else { 0.0 }; LANES])
            .collect();
        let mut sum = [0.0; LANES];
        let never = f64::INFINITY;
        let mut at = [never; LANES];
        let mut z = vec![[0.0; LANES]; h];
        for k in s..n {
            for (j, zj) in z.iter_mut().enumerate() {
                let mut d2 = [0.0; LANES];
                for i in 0..il {
                    let x = self.r[k - i];
                    let cj = &c[j * m + i];
                    for l in 0..LANES {
                        let dx = x - cj[l];
                        d2[l] = dx.mul_add(dx, d2[l]);
                    }
                }
                for (o, hv) in hist.iter().enumerate() {
                    let cj = &c[j * m + il + o];
                    for l in 0..LANES {
                        let dx = hv[l] - cj[l];
                        d2[l] = dx.mul_add(dx, d2[l]);
                    }
                }
                let kj = &kf[j];
                for l in 0..LANES {
                    zj[l] = kj[l] * d2[l];
                }
            }
            for zj in z.iter_mut() {
                for v in zj.iter_mut() {
                    *v = fastmath::exp2_fast(*v);
                }
            }
            let mut ym = [0.0; LANES];
            for (zj, wj) in z.iter().zip(&w) {
                for l in 0..LANES {
                    ym[l] = wj[l].mul_add(zj[l], ym[l]);
                }
            }
            let (yk, kfl) = (self.y[k], k as f64);
            for l in 0..LANES {
                let e = ym[l] - yk;
                let bad = !(e.abs() <= cap);
                let first = bad & (at[l] == never);
                at[l] = select(first, kfl, at[l]);
                let live = at[l] == never;
                sum[l] = select(live, (0.5 * e).mul_add(e, sum[l]), sum[l]);
            }
            if ol > 0 {
                hist.rotate_right(1);
                hist[0] = ym;
            }
        }
        for l in 0..LANES {
            out[l] = if at[l] == never {
                sum[l]
            } else {
                sum[l] + (n as f64 - at[l]) * cap * cap
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::rbf::{self, Regressors};

    fn record() -> (Vec<f64>, Vec<f64>) {
        let r: Vec<f64> = (0..403)
            .map(|k| (2.0 * std::f64::consts::PI * 3.0 * k as f64 * 1e-3).sin())
            .collect();
        let y = rbf::eq_3_18(&r);
        (r, y)
    }

    /// Individuals around the record's ranges plus hostile ones (tiny widths, huge weights).
    fn population(net: &RbfNet, narx: &Narx, r: &[f64], y: &[f64], k: usize) -> Vec<f64> {
        let regs = Regressors::new(narx, r, y);
        let (lo, hi) = regs.input_ranges();
        let base = rbf::init_params(net, &lo, &hi);
        let mut v = Vec::new();
        for i in 0..k {
            for (q, &b) in base.iter().enumerate() {
                let t = ((i * 31 + q * 17) % 23) as f64 / 22.0 - 0.5;
                v.push(b * (1.0 + t) + 0.1 * t);
            }
        }
        let d = net.n_params();
        v[d * 3..d * 4].iter_mut().for_each(|x| *x *= 1e6); // huge: diverges at once
        v[d * 5 + net.width_offset()] = 0.0; // zero width
        v
    }

    #[test]
    fn batched_costs_match_the_reference_in_both_modes() {
        let (r, y) = record();
        for (net, narx) in [
            (RbfNet::SEED, Narx::SEED),
            (RbfNet::new(7, 9), Narx::SEED_7),
        ] {
            let batch = RbfBatch::new(net, narx, &r, &y);
            let pts = population(&net, &narx, &r, &y, 13);
            let d = net.n_params();
            for mode in [Mode::OneStepAhead, Mode::FreeRun] {
                let mut out = vec![0.0; 13];
                batch.costs(&pts, mode, &mut out);
                for (p, &c) in pts.chunks_exact(d).zip(&out) {
                    let want = rbf::cost(&net, &narx, p, &r, &y, mode);
                    assert!(c.is_finite(), "{mode:?}: {c}");
                    assert!(
                        (c - want).abs() <= 1e-9 * want.abs().max(1e-300),
                        "{mode:?} {net:?}: {c} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn costs_depend_on_the_individual_only_and_paths_agree_bitwise() {
        let (r, y) = record();
        let (net, narx) = (RbfNet::SEED, Narx::SEED);
        let batch = RbfBatch::new(net, narx, &r, &y);
        let d = net.n_params();
        let pts = population(&net, &narx, &r, &y, 11);
        for mode in [Mode::OneStepAhead, Mode::FreeRun] {
            let mut all = vec![0.0; 11];
            batch.costs_portable(&pts, mode, &mut all);
            let mut tail = vec![0.0; 9];
            batch.costs_portable(&pts[2 * d..], mode, &mut tail);
            assert!(
                all[2..]
                    .iter()
                    .zip(&tail)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
            #[cfg(target_arch = "x86_64")]
            if crate::physics::bouc_wen_fast::accelerated() {
                let mut fast = vec![0.0; 11];
                // SAFETY: checked by `accelerated`.
                unsafe { batch.costs_avx2(&pts, mode, &mut fast) };
                assert!(
                    all.iter()
                        .zip(&fast)
                        .all(|(a, b)| a.to_bits() == b.to_bits())
                );
            }
        }
    }
}
