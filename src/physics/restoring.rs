//! Hysteresis inside the mechanical feedback: a single-degree-of-freedom oscillator whose
//! restoring force is partly hysteretic,
//!
//! ```text
//!  m ÿ + c ẏ + k y + α g(y) = F(t),   dg/dy = 1 - (β sgn(ẏ g) + γ)|g|^n
//! ```
//!
//! (the Bouc-Wen benchmark of Noël & Schoukens is this with `z = α g`). The hysteresis is
//! driven by the displacement, not by the command, so it cannot be written as a Bouc-Wen
//! block followed by a mode; `optbench diagnose` offers it as the second placement of
//! `dynamics`.
//!
//! Written in unit-free form for fitting: with `ω² = (k+α)/m`, `r = α/(k+α)`, the drive
//! scaled to `x = F/F_ref` and the displacement to small-amplitude static gain 1,
//!
//! ```text
//!  ÿ + 2ζω ẏ + ω² ((1-r) y + r g) = ω² x,   dg/dy = 1 - (b sgn(ẏ g) + c)|g|^n
//! ```
//!
//! and the physical displacement is `a y` (`a` fitted by least squares): an output scale is
//! exactly redundant with the shape (`b a^-n`, `c a^-n`), so nothing is lost. `b + c < 0`
//! (a loop that hardens on loading, as in the benchmark) is allowed.
//!
//! Integration: classical RK4 with `m` sub-steps per sample, the drive known at every
//! half sub-step from [`upsample`] (zero-order hold, linear, or band-limited interpolation
//! of the samples: which one is a property of how the data were excited).

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;
use std::sync::{Arc, Mutex};

/// The fewest RK4 sub-steps per sample by default: the hysteresis is not smooth where `ẏ`
/// changes sign, which the `ω h` rule of [`Oscillator::substeps`] does not see. Chosen on
/// the Bouc-Wen benchmark (its 36 Hz mode at 750 Hz gets 2 by the rule; 4 bring its true
/// parameters to 3.5e-7 m of the official data), so prior knowledge of that data set.
pub const MIN_SUBSTEPS: usize = 4;

/// How the input moves between its samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Hold {
    /// Held from just after one sample to the next (a D/A converter's staircase): the
    /// value of sample `k` acts over `(t_{k-1}, t_k]`.
    #[default]
    Zoh,
    /// Straight lines between samples.
    Linear,
    /// The band-limited signal through the samples (FFT interpolation): right for a
    /// continuous excitation sampled without aliasing, such as a multisine or a sweep.
    Bandlimited,
}

impl Hold {
    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Hold::Zoh => "zoh",
            Hold::Linear => "linear",
            Hold::Bandlimited => "bandlimited",
        }
    }

    /// The hold named `s`, if any.
    pub fn parse(s: &str) -> Option<Hold> {
        [Hold::Zoh, Hold::Linear, Hold::Bandlimited]
            .into_iter()
            .find(|h| h.name() == s)
    }
}

/// The input between samples, stored per interval: interval `k` (from sample `k-1` to
/// sample `k`, `k = 1..N`) owns `per = 2m + 1` values at `t_{k-1} + j dt / 2m`, both ends
/// included, so a hold may jump at the samples.
#[derive(Clone, Debug)]
pub struct Fine {
    pub values: Vec<f64>,
    /// Sub-steps per sample.
    pub substeps: usize,
    /// Samples.
    pub len: usize,
}

impl Fine {
    /// Values per interval.
    pub fn per(&self) -> usize {
        2 * self.substeps + 1
    }

    /// The `per` values of interval `k` (`1 ≤ k < len`).
    pub fn interval(&self, k: usize) -> &[f64] {
        let p = self.per();
        &self.values[(k - 1) * p..k * p]
    }

    /// Applies `f` to every value (a memoryless drive nonlinearity).
    pub fn map(&mut self, f: impl Fn(f64) -> f64) {
        for v in &mut self.values {
            *v = f(*v);
        }
    }
}

/// Input samples `x` at the half sub-steps of `substeps` RK4 steps per sample, by `hold`.
pub fn upsample(x: &[f64], hold: Hold, substeps: usize) -> Fine {
    let m = substeps.max(1);
    let per = 2 * m + 1;
    let n = x.len();
    let mut values = Vec::with_capacity(n.saturating_sub(1) * per);
    match hold {
        Hold::Zoh => {
            for &v in x.iter().skip(1) {
                values.extend(std::iter::repeat_n(v, per));
            }
        }
        Hold::Linear => {
            for w in x.windows(2) {
                for j in 0..per {
                    let s = j as f64 / (per - 1) as f64;
                    values.push(w[0] + (w[1] - w[0]) * s);
                }
            }
        }
        Hold::Bandlimited => {
            let f = 2 * m;
            let dense = dense_cached(x, f);
            for k in 1..n {
                values.extend_from_slice(&dense[(k - 1) * f..=(k - 1) * f + 2 * m]);
            }
        }
    }
    Fine {
        values,
        substeps: m,
        len: n,
    }
}

/// Interpolations recently computed, newest first: a fit evaluates thousands of parameter
/// sets on the same input, and each sub-step count needs its own (an FFT plan, two
/// transforms and a large allocation that otherwise dominate an evaluation).
type DenseEntries = Vec<(Arc<Vec<f64>>, usize, Arc<Vec<f64>>)>;
static DENSE: Mutex<DenseEntries> = Mutex::new(Vec::new());
const DENSE_ENTRIES: usize = 8;
/// Values kept in all (128 MB); the newest entry stays whatever its size.
const DENSE_VALUES: usize = 1 << 24;

/// [`fft_interpolate`] through a small process-wide cache keyed by the input's values and
/// the factor (the same bits as computing it: the cache only skips the work).
fn dense_cached(x: &[f64], factor: usize) -> Arc<Vec<f64>> {
    let lookup = |cache: &mut DenseEntries| {
        let i = cache
            .iter()
            .position(|(k, f, _)| *f == factor && same_bits(k, x))?;
        let hit = cache.remove(i);
        let dense = Arc::clone(&hit.2);
        cache.insert(0, hit);
        Some(dense)
    };
    if let Some(d) = lookup(&mut DENSE.lock().unwrap_or_else(|e| e.into_inner())) {
        return d;
    }
    // Computed outside the lock: threads may race to the same entry, with the same values.
    let dense = Arc::new(fft_interpolate(x, factor));
    let mut cache = DENSE.lock().unwrap_or_else(|e| e.into_inner());
    if lookup(&mut cache).is_none() {
        cache.insert(0, (Arc::new(x.to_vec()), factor, Arc::clone(&dense)));
        cache.truncate(DENSE_ENTRIES);
        while cache.len() > 1
            && cache.iter().map(|e| e.0.len() + e.2.len()).sum::<usize>() > DENSE_VALUES
        {
            cache.pop();
        }
    }
    dense
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// `x` interpolated `factor` times more densely as the periodic band-limited signal through
/// its samples (`factor · N + 1` values: the last repeats the first period's start, which
/// for a non-periodic record is the wrap-around, an edge effect of a few samples).
pub fn fft_interpolate(x: &[f64], factor: usize) -> Vec<f64> {
    let n = x.len();
    if n < 2 || factor <= 1 {
        let mut v = x.to_vec();
        v.push(x.first().copied().unwrap_or(0.0));
        return v;
    }
    let big = n * factor;
    let mut planner = FftPlanner::<f64>::new();
    let mut spec: Vec<Complex<f64>> = x.iter().map(|&v| Complex::new(v, 0.0)).collect();
    planner.plan_fft_forward(n).process(&mut spec);
    let mut wide = vec![Complex::new(0.0, 0.0); big];
    let half = n / 2;
    for (j, &c) in spec.iter().enumerate().take(half + 1) {
        wide[j] = c;
    }
    for j in half + 1..n {
        wide[big - (n - j)] = spec[j];
    }
    if n.is_multiple_of(2) {
        // The Nyquist bin is shared between +N/2 and -N/2 so the result stays real.
        let c = spec[half] * 0.5;
        wide[half] = c;
        wide[big - half] = c;
    }
    planner.plan_fft_inverse(big).process(&mut wide);
    let scale = 1.0 / n as f64;
    let mut out: Vec<f64> = wide.iter().map(|c| c.re * scale).collect();
    out.push(out[0]);
    out
}

/// The oscillator's unit-free parameters (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Oscillator {
    /// Small-amplitude natural frequency (rad/s).
    pub omega: f64,
    pub zeta: f64,
    /// Hysteretic share of the small-amplitude stiffness, `α/(k+α)`.
    pub r: f64,
    pub b: f64,
    pub c: f64,
    pub n: f64,
}

impl Oscillator {
    /// RK4 sub-steps per sample of `dt` s that keep `ω h` at most 0.2 (RK4's phase error
    /// per step about `(ω h)^5/120`), and at least `min` (at most 64).
    pub fn substeps(&self, dt: f64, min: usize) -> usize {
        let s = (self.omega * dt / 0.2).ceil();
        if s.is_finite() {
            (s as usize).clamp(min.clamp(1, 64), 64)
        } else {
            64
        }
    }

    #[inline(always)]
    fn rate(&self, power: impl Fn(f64) -> f64, x: f64, y: f64, v: f64, g: f64) -> (f64, f64, f64) {
        let w2 = self.omega * self.omega;
        let acc = w2 * (x - (1.0 - self.r) * y - self.r * g) - 2.0 * self.zeta * self.omega * v;
        let p = power(g.abs());
        let s = if v * g >= 0.0 { self.b } else { -self.b };
        (v, acc, v * (1.0 - (s + self.c) * p))
    }

    /// Displacement at every sample (interval `dt` s) for the drive `fine` (unit-free),
    /// starting at rest with
    /// hysteretic state `g0` at the equilibrium of the first drive value `x0`. `Err(k)`:
    /// the state left every plausible bound at sample `k`.
    pub fn respond(&self, fine: &Fine, dt: f64, x0: f64, g0: f64) -> Result<Vec<f64>, usize> {
        // Two copies: with `n = 1` no power at all (a select would still evaluate `powf`).
        if self.n == 1.0 {
            self.respond_with(|a| a, fine, dt, x0, g0)
        } else {
            let n = self.n;
            // Branch-free 2^(n log2 a) (relative error < 1e-14), far cheaper than `powf`.
            self.respond_with(
                |a: f64| super::fastmath::pow(a.max(1e-300), n),
                fine,
                dt,
                x0,
                g0,
            )
        }
    }

    fn respond_with(
        &self,
        power: impl Fn(f64) -> f64 + Copy,
        fine: &Fine,
        dt: f64,
        x0: f64,
        g0: f64,
    ) -> Result<Vec<f64>, usize> {
        let n = fine.len;
        let mut out = Vec::with_capacity(n);
        if n == 0 {
            return Ok(out);
        }
        let r = self.r.min(0.999);
        let mut y = (x0 - r * g0) / (1.0 - r);
        let mut v = 0.0;
        let mut g = g0;
        out.push(y);
        let m = fine.substeps;
        let h = dt / m as f64;
        let half_h = 0.5 * h;
        let bound = 1e6;
        for k in 1..n {
            let xs = fine.interval(k);
            for j in 0..m {
                let (x_a, x_m, x_b) = (xs[2 * j], xs[2 * j + 1], xs[2 * j + 2]);
                // The rate at the state advanced by `c` times the slopes `k`.
                let ahead = |x: f64, c: f64, k: (f64, f64, f64)| {
                    self.rate(power, x, y + c * k.0, v + c * k.1, g + c * k.2)
                };
                let k1 = self.rate(power, x_a, y, v, g);
                let k2 = ahead(x_m, half_h, k1);
                let k3 = ahead(x_m, half_h, k2);
                let (k4y, k4v, k4g) = ahead(x_b, h, k3);
                let ((k1y, k1v, k1g), (k2y, k2v, k2g), (k3y, k3v, k3g)) = (k1, k2, k3);
                y += h / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y);
                v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
                g += h / 6.0 * (k1g + 2.0 * k2g + 2.0 * k3g + k4g);
            }
            if !(y.abs() <= bound && g.abs() <= bound && v.is_finite()) {
                return Err(k);
            }
            out.push(y);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::recording::{Columns, ReadOptions, Recording, data_dir};
    use crate::physics::linear::Mode;
    use std::f64::consts::PI;

    #[test]
    fn fft_interpolation_is_exact_for_a_band_limited_periodic_signal() {
        let n = 64;
        let f = |t: f64| (2.0 * PI * 3.0 * t).sin() + 0.4 * (2.0 * PI * 11.0 * t + 0.3).cos();
        let x: Vec<f64> = (0..n).map(|k| f(k as f64 / n as f64)).collect();
        let d = fft_interpolate(&x, 6);
        assert_eq!(d.len(), 6 * n + 1);
        for (i, v) in d.iter().enumerate() {
            assert!((v - f(i as f64 / (6 * n) as f64)).abs() < 1e-12, "{i}");
        }
        // Odd length too.
        let x: Vec<f64> = (0..63).map(|k| f(k as f64 / 63.0)).collect();
        let d = fft_interpolate(&x, 4);
        assert!((d[5] - f(5.0 / 252.0)).abs() < 1e-12);
    }

    #[test]
    fn cached_interpolation_is_the_computed_one_through_hits_and_evictions() {
        // More distinct (input, factor) pairs than the cache holds, so the second round
        // recomputes what was evicted; every pair is asked for twice in a row (a hit).
        let inputs: Vec<Vec<f64>> = (0..6)
            .map(|s| {
                (0..97)
                    .map(|k| ((k * (s + 3)) as f64 * 0.37).sin())
                    .collect()
            })
            .collect();
        for round in 0..2 {
            for (i, x) in inputs.iter().enumerate() {
                for factor in [4, 6] {
                    let want = fft_interpolate(x, factor);
                    // The first call computes (or hits), the second hits.
                    for call in 0..2 {
                        let got = dense_cached(x, factor);
                        assert_eq!(got.len(), want.len());
                        assert!(
                            got.iter()
                                .zip(&want)
                                .all(|(a, b)| a.to_bits() == b.to_bits()),
                            "round {round} input {i} factor {factor} call {call}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn holds_place_the_samples_as_documented() {
        let x = [1.0, 3.0, -1.0];
        let z = upsample(&x, Hold::Zoh, 2);
        assert_eq!(z.per(), 5);
        assert_eq!(z.interval(1), &[3.0; 5]);
        assert_eq!(z.interval(2), &[-1.0; 5]);
        let l = upsample(&x, Hold::Linear, 2);
        assert_eq!(l.interval(1), &[1.0, 1.5, 2.0, 2.5, 3.0]);
        let b = upsample(&x, Hold::Bandlimited, 2);
        // Band-limited passes through the samples.
        assert!((b.interval(1)[0] - 1.0).abs() < 1e-12 && (b.interval(2)[4] + 1.0).abs() < 1e-12);
    }

    #[test]
    fn without_hysteresis_it_is_the_exact_linear_mode() {
        // b = c = 0: g follows y, so the oscillator is ÿ + 2ζω ẏ + ω² y = ω² x, which
        // `Mode` discretises exactly under a zero-order hold.
        let dt = 1e-3;
        let (f, zeta) = (40.0, 0.05);
        let osc = Oscillator {
            omega: 2.0 * PI * f,
            zeta,
            r: 0.6,
            b: 0.0,
            c: 0.0,
            n: 1.0,
        };
        let x: Vec<f64> = (0..600)
            .map(|k| (2.0 * PI * 7.0 * k as f64 * dt).sin() + if k > 300 { 0.5 } else { 0.0 })
            .collect();
        let fine = upsample(&x, Hold::Zoh, osc.substeps(dt, MIN_SUBSTEPS));
        let y = osc.respond(&fine, dt, x[0], x[0]).unwrap();
        let mut mode = Mode::new(f, zeta, dt);
        mode.settle(x[0]);
        let mut worst = 0.0f64;
        for k in 1..x.len() {
            worst = worst.max((mode.step(x[k]) - y[k]).abs());
        }
        // RK4 at ω h ≤ 0.2 (here 0.06): a few 1e-7 of a unit-size response.
        assert!(worst < 2e-6, "{worst}");
    }

    #[test]
    fn hostile_parameters_fail_cleanly() {
        let x: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
        let fine = upsample(&x, Hold::Linear, 4);
        for (b, c, n) in [(-50.0, -50.0, 1.0), (0.0, -30.0, 0.5), (5.0, 5.0, 3.0)] {
            let osc = Oscillator {
                omega: 2.0 * PI * 100.0,
                zeta: 0.01,
                r: 0.9,
                b,
                c,
                n,
            };
            match osc.respond(&fine, 1e-3, 0.0, 0.0) {
                Ok(y) => assert!(y.iter().all(|v| v.is_finite())),
                Err(k) => assert!(k < x.len()),
            }
        }
    }

    /// The benchmark's own parameters in this form reproduce its noiseless multisine test
    /// set: the structure and the band-limited hold are those of the official simulator.
    #[test]
    fn reproduces_the_bouc_wen_benchmark_from_its_true_parameters() {
        let p = data_dir().join("boucwen-benchmark/test_multisine.csv");
        if !p.is_file() {
            eprintln!("skipping: data not found at {}", p.display());
            return;
        }
        let rec = Recording::read_csv(
            &p,
            &Columns::parse("t_s,u_N,y_m").unwrap(),
            &ReadOptions::default(),
        )
        .unwrap();
        let (m, c, k, alpha, beta, gamma, delta): (f64, f64, f64, f64, f64, f64, f64) =
            (2.0, 10.0, 5e4, 5e4, 1e3, 0.8, -1.1);
        let f_ref = 100.0;
        let a = f_ref / (k + alpha);
        let osc = Oscillator {
            omega: ((k + alpha) / m).sqrt(),
            zeta: c / (2.0 * ((k + alpha) * m).sqrt()),
            r: alpha / (k + alpha),
            b: beta * gamma * a,
            c: beta * delta * a,
            n: 1.0,
        };
        // One steady-state period: simulate two and keep the second.
        let n = rec.len();
        let x: Vec<f64> = rec.u.iter().chain(&rec.u).map(|u| u / f_ref).collect();
        let fine = upsample(&x, Hold::Bandlimited, osc.substeps(rec.dt(), MIN_SUBSTEPS));
        let y = osc.respond(&fine, rec.dt(), 0.0, 0.0).unwrap();
        let e: f64 = (0..n)
            .map(|i| (a * y[n + i] - rec.y[i]).powi(2))
            .sum::<f64>()
            / n as f64;
        let rmse = e.sqrt();
        // Published best black-box model: 7.53e-6 m.
        eprintln!("benchmark multisine test, true parameters: RMSE {rmse:.3e} m");
        assert!(rmse < 1e-6, "{rmse}");
    }
}
