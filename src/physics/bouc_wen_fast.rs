//! The Bouc-Wen fitting scheme: a fixed-cost discretisation of the model of [`super::bouc_wen`]
//! that vectorises over a population, for objectives that evaluate it millions of times.
//!
//! # Scheme
//!
//! As in the accurate kernel, a sample moves the input linearly by `Δu`, and in the
//! one-directional form (`s = sgn Δu`, `g = s h`, `v` from 0 to `|Δu|`) the model is
//! `dg/dv = α - c(g)|g|^n` with `c = β + γ` for `g ≥ 0` and `γ - β` below. Writing the
//! nonlinear term as `K(g) g`, `K = c(g) sgn(g) |g|^(n-1)`, each of `m` equal sub-steps of
//! length `ℓ = |Δu|/m` is a predictor-corrector exponential step:
//!
//! 1. predictor: half an explicit Euler step, `g½ = g + ℓ/2 · (α - c(g)|g|^n)`, clamped to the
//!    monotone path between `g` and the equilibrium it heads for (so stiff parameters cannot
//!    overshoot);
//! 2. corrector: the linear ODE `dg/dv = α - K(g½) g` solved exactly over `ℓ`:
//!    `g' = g e^z + α ℓ φ1(z)`, `z = -K(g½) ℓ`, `φ1(z) = (e^z - 1)/z`.
//!
//! For `n = 1` the corrector is the exact solution inside a sign region of `g`; for any `n`
//! the exponential form is unconditionally stable where the model itself is (`K ≥ 0`), and
//! the Euler predictor evaluates the rate (finite at `g = 0`) rather than `K` (infinite
//! there for `n < 1`), so states leave `g = 0` as they should. Cost: two `|g|^n` and one
//! `e^z` per sub-step, all branch-free.
//!
//! `m` defaults to `ceil(24 max|Δu| / range(u))` clamped to 1..=8 ([`auto_substeps`]): one
//! for slow sinusoids at 1 ms, three for 28 Hz. Error against the accurate kernel, relative
//! to max|h| over two periods of a full-range sine at 1 ms (measured in
//! `tests::error_against_the_accurate_kernel`): n = 1, 1 Hz: 6e-6; 28 Hz: 4e-4 (the sign
//! switch of `c` inside a sub-step); n = 0.6: 2e-4 at 1 Hz, 6e-3 at 28 Hz (the `|g|^n` cusp
//! at `g = 0`, where any fixed-step scheme converges slowly). Fits therefore use this scheme
//! (its errors are far below a fit's residual), while the twin uses the accurate kernel.
//!
//! # Paths
//!
//! - [`cost_reference`]: one individual with `std` `powf`/`exp` — the exact scalar path.
//! - [`costs`]: a population in structure-of-arrays lanes ([`LANES`] individuals each, the
//!   inner loops over lanes), with the polynomial functions of [`super::fastmath`]; on
//!   x86-64 with AVX2 and FMA it runs a copy compiled for them (detected at run time), else
//!   a portable copy. Both use explicit `mul_add`, so they give the same bits, and each
//!   lane's result depends on its own parameters only (not on the batch it was in). The
//!   batched cost is within 1e-9 relative of [`cost_reference`] on well-conditioned
//!   parameters (tested at 1e-6).
//! - The explicit recurrence ([`FastInput::explicit`]) has its own kernel: one `|h|^n` per
//!   sample, with the cheaper [`fastmath::pow_lo`] (2.5e-9 relative) in the batched path and
//!   `powf` in [`cost_reference`]; [`EXPLICIT_LANES`] individuals a block, each stage
//!   (`log2`, `exp2`, the clamped update, the cost) a loop over the lanes. Its batched cost
//!   is within 2e-9 relative of the reference on the benchmark population (tested at 1e-6),
//!   and it runs about 4 times faster than the default scheme (`optbench bench`).

// `!(x <= bound)` is deliberate (it is true for NaN), and index loops over lane arrays are
// the shape that vectorises.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
use super::bouc_wen::{BoucWenParams, SimStatus, cost_cap, instability_bound};
use super::fastmath;

/// Individuals per structure-of-arrays block: enough independent chains per vector unit
/// to hide the latency of each stage's dependency chain.
pub const LANES: usize = 32;
/// Block width of the explicit recurrence (measured best among 16..=64 on Zen; it also
/// divides the populations of 40 and 200 that MSGA and the benchmarks evaluate).
pub const EXPLICIT_LANES: usize = 40;
/// Block width for the rest of a population (at most `NARROW - 1` padded lanes).
const NARROW: usize = 8;

/// Floor on `|g|` before logarithms (keeps `|g|^(n-1)` finite at `g = 0`).
const TINY: f64 = 1e-300;
/// Clamp on the exponent `z` (beyond it `e^z` is 0 or the run is blowing up anyway).
const Z_MAX: f64 = 700.0;

/// Sub-steps per sample for `u`: `ceil(24 max|Δu| / range(u))`, within 1..=8.
pub fn auto_substeps(u: &[f64]) -> usize {
    let (lo, hi) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let range = hi - lo;
    let step = u.windows(2).fold(0.0f64, |m, w| m.max((w[1] - w[0]).abs()));
    if !(range > 0.0) || !step.is_finite() {
        return 1;
    }
    ((24.0 * step / range).ceil() as usize).clamp(1, 8)
}

/// A recording prepared for the scheme: per-sample direction and sub-step length.
#[derive(Clone, Debug)]
pub struct FastInput {
    u: Vec<f64>,
    y: Vec<f64>,
    /// `sgn Δu` (1 where `Δu = 0`).
    sign: Vec<f64>,
    /// `|Δu| / m` (0 on the first sample and where the input holds).
    ell: Vec<f64>,
    substeps: usize,
    /// The dissertation's explicit recurrence instead of the predictor-corrector scheme.
    explicit: bool,
    umax: f64,
    cap: f64,
}

impl FastInput {
    /// Input `u` and measured output `y` (common length), `substeps` per sample (0 = auto).
    pub fn new(u: &[f64], y: &[f64], substeps: usize) -> Self {
        let len = u.len().min(y.len());
        let (u, y) = (&u[..len], &y[..len]);
        let m = if substeps == 0 {
            auto_substeps(u)
        } else {
            substeps
        };
        let mut sign = vec![1.0; len];
        let mut ell = vec![0.0; len];
        for k in 1..len {
            let du = u[k] - u[k - 1];
            sign[k] = if du < 0.0 { -1.0 } else { 1.0 };
            ell[k] = du.abs() / m as f64;
        }
        FastInput {
            u: u.to_vec(),
            y: y.to_vec(),
            sign,
            ell,
            substeps: m,
            explicit: false,
            umax: u.iter().fold(0.0f64, |a, x| a.max(x.abs())),
            cap: cost_cap(y),
        }
    }

    /// The seed-style explicit recurrence on `u`, `y`: one Euler step per sample,
    /// `h(k+1) = h(k) + α Δu - β|Δu||h|^(n-1) h - γ Δu |h|^n`, clamped to the monotone path
    /// towards the equilibrium (so stiff parameters cannot overshoot into chaos). One `|h|^n`
    /// per sample: the fastest scheme and the least accurate (first order in `Δu`).
    pub fn explicit(u: &[f64], y: &[f64]) -> Self {
        FastInput {
            explicit: true,
            ..FastInput::new(u, y, 1)
        }
    }

    /// Whether this input runs the explicit recurrence.
    pub fn is_explicit(&self) -> bool {
        self.explicit
    }

    /// Sub-steps per sample in use.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// Samples.
    pub fn len(&self) -> usize {
        self.u.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.u.is_empty()
    }

    /// The cost of a run that blew up at sample `at` (see [`super::bouc_wen::cost`]).
    fn penalty(&self, at: usize) -> f64 {
        self.cap * (2.0 - at as f64 / self.len() as f64)
    }

    /// A stable run's `Σe²/2`, clipped like [`super::bouc_wen::cost`].
    fn clip(&self, j: f64) -> f64 {
        if j <= 1e12 { j } else { j.min(self.cap) }
    }
}

/// Per-individual constants, computed once with `std` functions (shared by every path).
#[derive(Clone, Copy, Debug, Default)]
struct Lane {
    shape: Shape,
    d_e: f64,
    d0: f64,
    bound: f64,
}

/// The constants of the hysteretic state's update (what every stage reads).
#[derive(Clone, Copy, Debug, Default)]
struct Shape {
    alpha: f64,
    c_pos: f64,
    c_neg: f64,
    n: f64,
    /// Equilibria of `dg/dv` below and above 0 (±1e300 where there is none).
    eq_lo: f64,
    eq_hi: f64,
}

impl Lane {
    fn new(p: &BoucWenParams, umax: f64) -> Self {
        let (alpha, n) = (p.alpha, p.n);
        let c_pos = p.beta + p.gamma;
        let c_neg = p.gamma - p.beta;
        let eq = |c: f64| {
            let r = alpha / c;
            let e = r.powf(1.0 / n);
            if r > 0.0 && e.is_finite() { e } else { 1e300 }
        };
        Lane {
            shape: Shape {
                alpha,
                c_pos,
                c_neg,
                n,
                eq_lo: -eq(c_neg),
                eq_hi: eq(c_pos),
            },
            d_e: p.d_e,
            d0: p.d0,
            bound: 1e6 * (1.0 + alpha.abs()) * umax,
        }
    }
}

/// The transcendental functions a path uses.
trait Math {
    fn log2(x: f64) -> f64;
    fn exp2(x: f64) -> f64;
    /// `(e^x, e^x - 1)`.
    fn exp_expm1(x: f64) -> (f64, f64);
    /// `x^y` in two stages, `pow_finish(pow_start(x), y)`, so that a batched loop can run
    /// each stage over all lanes (the explicit recurrence's `|h|^n`).
    fn pow_start(x: f64) -> f64;
    fn pow_finish(a: f64, y: f64) -> f64;
}

/// Polynomial, vectorisable functions (batched paths).
struct Poly;
impl Math for Poly {
    #[inline(always)]
    fn log2(x: f64) -> f64 {
        fastmath::log2(x)
    }
    #[inline(always)]
    fn exp2(x: f64) -> f64 {
        fastmath::exp2(x)
    }
    #[inline(always)]
    fn exp_expm1(x: f64) -> (f64, f64) {
        fastmath::exp_expm1(x)
    }
    #[inline(always)]
    fn pow_start(x: f64) -> f64 {
        fastmath::log2_lo(x)
    }
    #[inline(always)]
    fn pow_finish(a: f64, y: f64) -> f64 {
        fastmath::exp2_lo(y * a)
    }
}

/// The standard library's functions (the scalar reference).
struct Libm;
impl Math for Libm {
    #[inline(always)]
    fn log2(x: f64) -> f64 {
        x.log2()
    }
    #[inline(always)]
    fn exp2(x: f64) -> f64 {
        x.exp2()
    }
    #[inline(always)]
    fn exp_expm1(x: f64) -> (f64, f64) {
        (x.exp(), x.exp_m1())
    }
    #[inline(always)]
    fn pow_start(x: f64) -> f64 {
        x
    }
    #[inline(always)]
    fn pow_finish(a: f64, y: f64) -> f64 {
        a.powf(y)
    }
}

use fastmath::select;

// One sub-step, in stages. The batched loops run each stage over every lane before the next
// (short independent chains the CPU overlaps); [`substep`] composes them for one lane. The
// operations per lane are the same either way, so both give the same bits.

/// Stage 1: the state in the step's direction and `log2 |g|`.
#[inline(always)]
fn stage_log_g<M: Math>(h: f64, s: f64) -> (f64, f64) {
    let g = s * h;
    (g, M::log2(select(g.abs() > TINY, g.abs(), TINY)))
}

/// Stage 2: the half-Euler predictor `g½` (clamped), returned as `(|g½| floored, c(g½)·sgn)`.
#[inline(always)]
fn stage_predict<M: Math>(g: f64, log_g: f64, half_l: f64, sh: Shape) -> (f64, f64) {
    let gh = stage_euler::<M>(g, log_g, half_l, sh);
    let agh = select(gh.abs() > TINY, gh.abs(), TINY);
    (agh, select(gh >= 0.0, sh.c_pos, -sh.c_neg))
}

/// An explicit Euler step of length `step` in the one-directional form, clamped to the
/// monotone path between `g` and the equilibrium it heads for (the predictor of the
/// predictor-corrector scheme, with half a step; [`explicit_update`] is the explicit
/// recurrence's version, with a fused rate).
#[inline(always)]
fn stage_euler<M: Math>(g: f64, log_g: f64, step: f64, sh: Shape) -> f64 {
    let pn = M::exp2(sh.n * log_g);
    let c0 = select(g >= 0.0, sh.c_pos, sh.c_neg);
    let rate = sh.alpha - c0 * pn;
    let gh = step.mul_add(rate, g);
    let lo = select(g < sh.eq_lo, g, sh.eq_lo);
    let hi = select(g > sh.eq_hi, g, sh.eq_hi);
    select(gh < lo, lo, select(gh > hi, hi, gh))
}

/// Stage 3: the corrector's exponent `z = -K(g½) ℓ`, clamped, from `log2 |g½|`.
#[inline(always)]
fn stage_exponent<M: Math>(log_gh: f64, ch: f64, n: f64, l: f64) -> f64 {
    let k = ch * M::exp2((n - 1.0) * log_gh);
    let z = -k * l;
    select(z < -Z_MAX, -Z_MAX, select(z > Z_MAX, Z_MAX, z))
}

/// Stage 4: the exact solution of the frozen linear ODE, back in `h`.
#[inline(always)]
fn stage_correct<M: Math>(g: f64, z: f64, alpha: f64, l: f64, s: f64) -> f64 {
    let (ez, em1) = M::exp_expm1(z);
    s * g.mul_add(ez, alpha * l * fastmath::phi1(z, em1))
}

/// One sub-step of length `l` in direction `s` from hysteretic state `h`.
#[inline(always)]
fn substep<M: Math>(h: f64, s: f64, l: f64, sh: Shape) -> f64 {
    let (g, log_g) = stage_log_g::<M>(h, s);
    let (agh, ch) = stage_predict::<M>(g, log_g, 0.5 * l, sh);
    let z = stage_exponent::<M>(M::log2(agh), ch, sh.n, l);
    stage_correct::<M>(g, z, sh.alpha, l, s)
}

/// `|g|` floored at [`TINY`] (the argument of `|g|^n`).
#[inline(always)]
fn floor_abs(g: f64) -> f64 {
    select(g.abs() > TINY, g.abs(), TINY)
}

/// The explicit recurrence's Euler step in the one-directional form, from `g` and
/// `pn = |g|^n`: `g + ℓ(α - c(g)|g|^n)`, clamped to the monotone path between `g` and the
/// equilibrium it heads for.
#[inline(always)]
fn explicit_update(g: f64, pn: f64, l: f64, sh: Shape) -> f64 {
    let c0 = select(g >= 0.0, sh.c_pos, sh.c_neg);
    let gh = l.mul_add((-c0).mul_add(pn, sh.alpha), g);
    let lo = select(g < sh.eq_lo, g, sh.eq_lo);
    let hi = select(g > sh.eq_hi, g, sh.eq_hi);
    select(gh < lo, lo, select(gh > hi, hi, gh))
}

/// One sample of either scheme for one lane.
#[inline(always)]
fn step_one<M: Math>(h: f64, s: f64, l: f64, sh: Shape, input: &FastInput) -> f64 {
    if input.explicit {
        let g = s * h;
        let pn = M::pow_finish(M::pow_start(floor_abs(g)), sh.n);
        return s * explicit_update(g, pn, l, sh);
    }
    let mut h = h;
    for _ in 0..input.substeps {
        h = substep::<M>(h, s, l, sh);
    }
    h
}

/// Fitting cost `J = Σe²/2` of `p` on `input` with the `std` functions, one individual.
pub fn cost_reference(p: &BoucWenParams, input: &FastInput) -> f64 {
    cost_reference_from(p, 0.0, input)
}

/// [`cost_reference`] of a run from hysteretic state `h0` at the first sample.
pub fn cost_reference_from(p: &BoucWenParams, h0: f64, input: &FastInput) -> f64 {
    let mut out = [0.0];
    let (p, h0) = (std::slice::from_ref(p), [h0]);
    if input.explicit {
        run_explicit::<Libm, 1>(p, &h0, input, &mut out);
    } else {
        run_block::<Libm, 1>(p, &h0, input, &mut out);
    }
    out[0]
}

/// Free run of the scheme from the virgin state at `u[0]` into `out` (`std` functions);
/// like [`super::bouc_wen::simulate`], stops at the first unstable sample.
pub fn simulate(p: &BoucWenParams, u: &[f64], substeps: usize, out: &mut [f64]) -> SimStatus {
    simulate_from(p, 0.0, u, substeps, out)
}

/// [`simulate`] from hysteretic state `h0` at `u[0]` (as [`super::bouc_wen::simulate_from`]).
pub fn simulate_from(
    p: &BoucWenParams,
    h0: f64,
    u: &[f64],
    substeps: usize,
    out: &mut [f64],
) -> SimStatus {
    simulate_with(p, h0, &FastInput::new(u, u, substeps), out)
}

/// [`simulate`] with the explicit recurrence ([`FastInput::explicit`]).
pub fn simulate_explicit(p: &BoucWenParams, u: &[f64], out: &mut [f64]) -> SimStatus {
    simulate_explicit_from(p, 0.0, u, out)
}

/// [`simulate_explicit`] from hysteretic state `h0` at `u[0]`.
pub fn simulate_explicit_from(p: &BoucWenParams, h0: f64, u: &[f64], out: &mut [f64]) -> SimStatus {
    simulate_with(p, h0, &FastInput::explicit(u, u), out)
}

fn simulate_with(p: &BoucWenParams, h0: f64, input: &FastInput, out: &mut [f64]) -> SimStatus {
    let u = &input.u;
    let ln = Lane::new(p, input.umax);
    let bound = instability_bound(p, u);
    let mut h = h0;
    for k in 0..input.len() {
        let (s, l) = (input.sign[k], input.ell[k]);
        if l > 0.0 {
            h = step_one::<Libm>(h, s, l, ln.shape, input);
        }
        if !(h.abs() <= bound) {
            return SimStatus::Unstable { at: k };
        }
        out[k] = ln.d_e.mul_add(u[k], ln.d0) - h;
    }
    SimStatus::Ok
}

/// Costs of a population (`out[i]` for `params[i]`), batched, on the fastest path this
/// machine supports. Each cost is identical whatever the batch or the path.
pub fn costs(params: &[BoucWenParams], input: &FastInput, out: &mut [f64]) {
    costs_from(params, &[], input, out);
}

/// [`costs`] of runs that start from hysteretic states `h0` (`h0[i]` for `params[i]`; an
/// empty slice: every run from rest, the same bits as [`costs`]).
pub fn costs_from(params: &[BoucWenParams], h0: &[f64], input: &FastInput, out: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if avx2_fma() {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above).
        unsafe { costs_avx2(params, h0, input, out) };
        return;
    }
    costs_portable(params, h0, input, out);
}

/// Whether this CPU runs the AVX2+FMA copy.
pub fn accelerated() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        avx2_fma()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[cfg(target_arch = "x86_64")]
fn avx2_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// [`costs_from`] compiled for any CPU (the fallback; public for tests and benches).
pub fn costs_portable(params: &[BoucWenParams], h0: &[f64], input: &FastInput, out: &mut [f64]) {
    costs_blocks(params, h0, input, out);
}

/// [`costs_from`] compiled for AVX2 and FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub unsafe fn costs_avx2(params: &[BoucWenParams], h0: &[f64], input: &FastInput, out: &mut [f64]) {
    // One function per scheme: each kernel gets the registers and layout to itself.
    if input.explicit {
        // SAFETY: as for this function.
        unsafe { explicit_avx2(params, h0, input, out) }
    } else {
        // SAFETY: as for this function.
        unsafe { fast_avx2(params, h0, input, out) }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
unsafe fn explicit_avx2(params: &[BoucWenParams], h0: &[f64], input: &FastInput, out: &mut [f64]) {
    explicit_blocks(params, h0, input, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
unsafe fn fast_avx2(params: &[BoucWenParams], h0: &[f64], input: &FastInput, out: &mut [f64]) {
    fast_blocks(params, h0, input, out);
}

#[inline(always)]
fn costs_blocks(params: &[BoucWenParams], h0: &[f64], input: &FastInput, out: &mut [f64]) {
    if input.explicit {
        explicit_blocks(params, h0, input, out);
    } else {
        fast_blocks(params, h0, input, out);
    }
}

// Whole blocks of `$w` individuals, then `NARROW` ones, the last padded with copies of its
// last individual (results discarded); a lane's result does not depend on the block width.
// `$h0` is empty (every run from rest) or one initial state per individual, chunked alike.
// A macro, not a function taking the kernel: the kernel must be inlined into the caller to
// be compiled with its target features.
macro_rules! in_blocks {
    ($params:ident, $h0:ident, $input:ident, $out:ident, $w:expr, $kernel:ident) => {{
        assert_eq!($params.len(), $out.len(), "one cost per parameter set");
        assert!(
            $h0.is_empty() || $h0.len() == $params.len(),
            "no initial state, or one per parameter set"
        );
        let split = $params.len() / $w * $w;
        let h0_of = |r: std::ops::Range<usize>| if $h0.is_empty() { &[][..] } else { &$h0[r] };
        for (b, (ps, os)) in $params[..split]
            .chunks($w)
            .zip($out[..split].chunks_mut($w))
            .enumerate()
        {
            $kernel::<Poly, { $w }>(ps, h0_of(b * $w..(b + 1) * $w), $input, os);
        }
        for (b, (ps, os)) in $params[split..]
            .chunks(NARROW)
            .zip($out[split..].chunks_mut(NARROW))
            .enumerate()
        {
            let at = split + b * NARROW;
            let mut pad = [ps[ps.len() - 1]; NARROW];
            pad[..ps.len()].copy_from_slice(ps);
            let hs = h0_of(at..at + ps.len());
            let mut hpad = [hs.last().copied().unwrap_or(0.0); NARROW];
            hpad[..hs.len()].copy_from_slice(hs);
            let mut o = [0.0; NARROW];
            $kernel::<Poly, NARROW>(&pad, &hpad, $input, &mut o);
            os.copy_from_slice(&o[..ps.len()]);
        }
    }};
}

#[inline(always)]
fn explicit_blocks(params: &[BoucWenParams], h0: &[f64], input: &FastInput, out: &mut [f64]) {
    in_blocks!(params, h0, input, out, EXPLICIT_LANES, run_explicit);
}

#[inline(always)]
fn fast_blocks(params: &[BoucWenParams], h0: &[f64], input: &FastInput, out: &mut [f64]) {
    in_blocks!(params, h0, input, out, LANES, run_block);
}

/// The explicit recurrence for `W` individuals through the whole recording, structure of
/// arrays, each stage (`log2 |g|`, `2^(n·)`, the clamped update, the cost) a loop over the
/// lanes so that their independent chains overlap. `J = Σe²/2` is summed as `Σe²` and
/// halved at the end (exact: a power of two).
#[inline(always)]
fn run_explicit<M: Math, const W: usize>(
    ps: &[BoucWenParams],
    h0: &[f64],
    input: &FastInput,
    out: &mut [f64],
) {
    let lanes = Lanes::<W>::new(ps, h0, input.umax);
    let Lanes {
        n, d_e, d0, bound, ..
    } = lanes;
    let never = f64::INFINITY;
    let (mut h, mut j, mut at) = (lanes.h0, [0.0; W], [never; W]);
    let len = input.len();
    let (us, ys, signs, ells) = (
        &input.u[..len],
        &input.y[..len],
        &input.sign[..len],
        &input.ell[..len],
    );
    for k in 0..len {
        let (s, l) = (signs[k], ells[k]);
        if l > 0.0 {
            let (mut g, mut pn) = ([0.0; W], [0.0; W]);
            for i in 0..W {
                g[i] = s * h[i];
                pn[i] = M::pow_start(floor_abs(g[i]));
            }
            for i in 0..W {
                pn[i] = M::pow_finish(pn[i], n[i]);
            }
            for i in 0..W {
                h[i] = s * explicit_update(g[i], pn[i], l, lanes.shape(i));
            }
        }
        let (u, y, kf) = (us[k], ys[k], k as f64);
        for i in 0..W {
            let e = (y - d_e[i].mul_add(u, d0[i])) + h[i];
            j[i] = e.mul_add(e, j[i]);
            let c = select(!(h[i].abs() <= bound[i]), kf, never);
            at[i] = select(c < at[i], c, at[i]);
        }
    }
    j.iter_mut().for_each(|j| *j *= 0.5);
    write_costs(&j, &at, input, out);
}

/// `W` individuals through the whole recording, structure of arrays, lanes innermost.
#[inline(always)]
fn run_block<M: Math, const W: usize>(
    ps: &[BoucWenParams],
    h0: &[f64],
    input: &FastInput,
    out: &mut [f64],
) {
    let lanes = Lanes::<W>::new(ps, h0, input.umax);
    let Lanes {
        alpha,
        n,
        d_e,
        d0,
        bound,
        ..
    } = lanes;
    let never = f64::INFINITY;
    let (mut h, mut j, mut at) = (lanes.h0, [0.0; W], [never; W]);
    for k in 0..input.len() {
        let (s, l) = (input.sign[k], input.ell[k]);
        if l > 0.0 {
            let half_l = 0.5 * l;
            for _ in 0..input.substeps {
                let (mut g, mut a, mut b) = ([0.0; W], [0.0; W], [0.0; W]);
                for i in 0..W {
                    (g[i], a[i]) = stage_log_g::<M>(h[i], s);
                }
                for i in 0..W {
                    (a[i], b[i]) = stage_predict::<M>(g[i], a[i], half_l, lanes.shape(i));
                }
                for i in 0..W {
                    a[i] = M::log2(a[i]);
                }
                for i in 0..W {
                    a[i] = stage_exponent::<M>(a[i], b[i], n[i], l);
                }
                for i in 0..W {
                    h[i] = stage_correct::<M>(g[i], a[i], alpha[i], l, s);
                }
            }
        }
        let (u, y) = (input.u[k], input.y[k]);
        let kf = k as f64;
        for i in 0..W {
            let e = y - (d_e[i].mul_add(u, d0[i]) - h[i]);
            j[i] = (0.5 * e).mul_add(e, j[i]);
            let bad = !(h[i].abs() <= bound[i]);
            at[i] = select(bad & (at[i] == never), kf, at[i]);
        }
    }
    write_costs(&j, &at, input, out);
}

/// A block's lanes as structure of arrays (an array of `Shape`s would need gathers).
#[derive(Clone, Copy)]
struct Lanes<const W: usize> {
    alpha: [f64; W],
    c_pos: [f64; W],
    c_neg: [f64; W],
    n: [f64; W],
    eq_lo: [f64; W],
    eq_hi: [f64; W],
    d_e: [f64; W],
    d0: [f64; W],
    bound: [f64; W],
    /// Initial hysteretic states.
    h0: [f64; W],
}

impl<const W: usize> Lanes<W> {
    /// The first `W` of `ps` (lanes beyond them keep `Lane::default()`), starting from the
    /// states `h0` (0 where `h0` has none).
    #[inline(always)]
    fn new(ps: &[BoucWenParams], h0: &[f64], umax: f64) -> Self {
        let mut ln = [Lane::default(); W];
        for (l, p) in ln.iter_mut().zip(ps) {
            *l = Lane::new(p, umax);
        }
        let soa = |f: fn(&Lane) -> f64| -> [f64; W] { std::array::from_fn(|i| f(&ln[i])) };
        Lanes {
            alpha: soa(|l| l.shape.alpha),
            c_pos: soa(|l| l.shape.c_pos),
            c_neg: soa(|l| l.shape.c_neg),
            n: soa(|l| l.shape.n),
            eq_lo: soa(|l| l.shape.eq_lo),
            eq_hi: soa(|l| l.shape.eq_hi),
            d_e: soa(|l| l.d_e),
            d0: soa(|l| l.d0),
            bound: soa(|l| l.bound),
            h0: std::array::from_fn(|i| h0.get(i).copied().unwrap_or(0.0)),
        }
    }

    #[inline(always)]
    fn shape(&self, i: usize) -> Shape {
        Shape {
            alpha: self.alpha[i],
            c_pos: self.c_pos[i],
            c_neg: self.c_neg[i],
            n: self.n[i],
            eq_lo: self.eq_lo[i],
            eq_hi: self.eq_hi[i],
        }
    }
}

/// Each lane's cost `j`, or the penalty for the sample `at` where it blew up (`inf`: never).
#[inline(always)]
fn write_costs<const W: usize>(j: &[f64; W], at: &[f64; W], input: &FastInput, out: &mut [f64]) {
    for i in 0..out.len().min(W) {
        out[i] = if at[i] == f64::INFINITY {
            input.clip(j[i])
        } else {
            input.penalty(at[i] as usize)
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::bouc_wen;

    fn sine(f: f64, periods: f64) -> Vec<f64> {
        let n = (periods / f / 1e-3).round() as usize;
        (0..n)
            .map(|k| 30.0 + 30.0 * (2.0 * std::f64::consts::PI * f * k as f64 * 1e-3).sin())
            .collect()
    }

    fn params(alpha: f64, beta: f64, gamma: f64, n: f64) -> BoucWenParams {
        BoucWenParams {
            d_e: 0.0103,
            alpha,
            beta,
            gamma,
            n,
            d0: 0.01,
        }
    }

    /// The scheme's hysteretic part `h` (from its output) against the accurate kernel's,
    /// relative to max|h|.
    fn scheme_error(p: &BoucWenParams, u: &[f64]) -> f64 {
        let (mut a, mut b) = (vec![0.0; u.len()], vec![0.0; u.len()]);
        assert_eq!(bouc_wen::simulate(p, u, &mut a), SimStatus::Ok);
        assert_eq!(simulate(p, u, 0, &mut b), SimStatus::Ok);
        let hmax = u
            .iter()
            .zip(&a)
            .map(|(x, d)| (p.d_e * x + p.d0 - d).abs())
            .fold(0.0, f64::max);
        a.iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
            / hmax
    }

    #[test]
    fn error_against_the_accurate_kernel() {
        let cases = [
            (1.0, 1.0, 2e-5),
            (28.0, 1.0, 1e-3),
            (1.0, 0.6, 5e-4),
            (28.0, 0.6, 1.5e-2),
            (10.0, 1.4, 1e-3),
        ];
        for (f, n, tol) in cases {
            let u = sine(f, 2.0);
            let p = params(0.003, 0.03, 0.015, n);
            let e = scheme_error(&p, &u);
            eprintln!("f {f} Hz, n {n}: {e:.1e} of max|h|");
            assert!(e < tol, "f {f} n {n}: {e:e} ≥ {tol:e}");
        }
    }

    fn population(k: usize) -> Vec<BoucWenParams> {
        // Deterministic spread over the dissertation's [0, 1.5] box, hostile corners included.
        (0..k)
            .map(|i| {
                let t = |a: usize| ((i * a + 7) % 97) as f64 / 96.0 * 1.5;
                BoucWenParams {
                    d_e: t(13),
                    alpha: t(29),
                    beta: t(31),
                    gamma: t(37),
                    n: t(41),
                    d0: t(43) - 0.75,
                }
            })
            .collect()
    }

    fn normalised_sine(f: f64) -> (Vec<f64>, Vec<f64>) {
        let u: Vec<f64> = sine(f, 2.0).iter().map(|x| x / 60.0).collect();
        let truth = params(1.0, 0.6, 0.3, 1.0);
        let mut y = vec![0.0; u.len()];
        bouc_wen::simulate(&truth, &u, &mut y);
        (u, y)
    }

    #[test]
    fn batched_costs_match_the_scalar_reference_and_never_nan() {
        let (u, y) = normalised_sine(10.0);
        let input = FastInput::new(&u, &y, 0);
        let pop = population(53);
        let mut out = vec![0.0; pop.len()];
        costs(&pop, &input, &mut out);
        let mut compared = 0;
        for (p, &c) in pop.iter().zip(&out) {
            assert!(c.is_finite() && c >= 0.0, "{p:?}: {c}");
            let r = cost_reference(p, &input);
            if r < 1e6 && p.n > 0.2 {
                compared += 1;
                assert!(((c - r) / r).abs() < 1e-6, "{p:?}: {c} vs {r}");
            }
        }
        assert!(compared > 20, "only {compared} well-conditioned cases");
    }

    #[test]
    fn cost_depends_on_the_individual_only_and_paths_agree_bitwise() {
        let (u, y) = normalised_sine(4.0);
        let input = FastInput::new(&u, &y, 2);
        let pop = population(37);
        let mut a = vec![0.0; pop.len()];
        costs_portable(&pop, &[], &input, &mut a);
        // Alone, and in a shifted batch: the same bits.
        for i in [0, 5, 16, 36] {
            let mut one = [0.0];
            costs_portable(&pop[i..=i], &[], &input, &mut one);
            assert_eq!(one[0].to_bits(), a[i].to_bits());
        }
        let mut b = vec![0.0; pop.len() - 3];
        costs_portable(&pop[3..], &[], &input, &mut b);
        assert!(
            a[3..]
                .iter()
                .zip(&b)
                .all(|(x, y)| x.to_bits() == y.to_bits())
        );
        #[cfg(target_arch = "x86_64")]
        if accelerated() {
            let mut c = vec![0.0; pop.len()];
            // SAFETY: checked by `accelerated`.
            unsafe { costs_avx2(&pop, &[], &input, &mut c) };
            assert!(a.iter().zip(&c).all(|(x, y)| x.to_bits() == y.to_bits()));
        } else {
            eprintln!("no AVX2+FMA here: accelerated path not compared");
        }
    }

    /// A run from a state mid-loop (`h0 ≠ 0`): the scheme follows the accurate kernel from
    /// the same state as closely as from rest; the batched costs equal the scalar reference,
    /// do not depend on the batch, and the AVX2 and portable paths give the same bits (both
    /// schemes); `h0 = 0` is the run from rest, bit for bit; absurd states cost the penalty.
    #[test]
    fn runs_from_a_mid_loop_state_match_the_reference_and_paths_agree_bitwise() {
        let u = sine(1.0, 2.0);
        for n in [1.0, 0.6] {
            let p = params(0.003, 0.03, 0.015, n);
            let sat = p.saturation().unwrap();
            for frac in [0.7, -0.9] {
                let h0 = frac * sat;
                let (mut a, mut b) = (vec![0.0; u.len()], vec![0.0; u.len()]);
                let ok = SimStatus::Ok;
                assert_eq!(bouc_wen::simulate_from(&p, h0, &u, &mut a), ok);
                assert_eq!(simulate_from(&p, h0, &u, 0, &mut b), ok);
                let first = p.d_e.mul_add(u[0], p.d0) - h0;
                assert_eq!(b[0].to_bits(), first.to_bits());
                assert!((a[0] - first).abs() < 1e-15);
                let err = a
                    .iter()
                    .zip(&b)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max)
                    / sat;
                // As from rest (`error_against_the_accurate_kernel`): the |g|^n cusp costs
                // n = 0.6 more.
                let tol = if n == 1.0 { 2e-5 } else { 2e-3 };
                eprintln!("n {n}, h0 {frac} sat: {err:.1e} of sat");
                assert!(err < tol, "n {n} h0 {frac} sat: {err:e}");
                // The state matters: from rest the run is another one.
                let mut rest = vec![0.0; u.len()];
                simulate(&p, &u, 0, &mut rest);
                assert!((rest[0] - b[0]).abs() > 0.5 * sat);
            }
        }
        let (u, y) = normalised_sine(4.0);
        for input in [FastInput::new(&u, &y, 2), FastInput::explicit(&u, &y)] {
            let pop = population(45);
            let h0: Vec<f64> = pop
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let frac = ((i * 17) % 21) as f64 / 10.0 - 1.0;
                    frac * p.saturation().filter(|s| s.is_finite()).unwrap_or(0.0)
                })
                .collect();
            assert!(h0.iter().filter(|h| **h != 0.0).count() > 20);
            let mut a = vec![0.0; pop.len()];
            costs_from(&pop, &h0, &input, &mut a);
            let mut compared = 0;
            for ((p, &h), &c) in pop.iter().zip(&h0).zip(&a) {
                assert!(c.is_finite() && c >= 0.0, "{p:?} {h}: {c}");
                let r = cost_reference_from(p, h, &input);
                if r < 1e6 && p.n > 0.2 {
                    compared += 1;
                    assert!(((c - r) / r).abs() < 1e-6, "{p:?} {h}: {c} vs {r}");
                }
            }
            assert!(compared > 15, "only {compared} well-conditioned cases");
            let mut b = vec![0.0; pop.len()];
            costs_portable(&pop, &h0, &input, &mut b);
            assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
            #[cfg(target_arch = "x86_64")]
            if accelerated() {
                let mut c = vec![0.0; pop.len()];
                // SAFETY: checked by `accelerated`.
                unsafe { costs_avx2(&pop, &h0, &input, &mut c) };
                assert!(a.iter().zip(&c).all(|(x, y)| x.to_bits() == y.to_bits()));
            }
            for i in [0, 7, 33, 44] {
                let mut one = [0.0];
                costs_from(&pop[i..=i], &h0[i..=i], &input, &mut one);
                assert_eq!(one[0].to_bits(), a[i].to_bits());
            }
            let mut shifted = vec![0.0; pop.len() - 5];
            costs_from(&pop[5..], &h0[5..], &input, &mut shifted);
            assert!(
                a[5..]
                    .iter()
                    .zip(&shifted)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            );
            // Zero states: the run from rest.
            let (mut zero, mut rest) = (vec![0.0; pop.len()], vec![0.0; pop.len()]);
            costs_from(&pop, &vec![0.0; pop.len()], &input, &mut zero);
            costs(&pop, &input, &mut rest);
            assert!(
                zero.iter()
                    .zip(&rest)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            );
            // Absurd states: the finite penalty of a blow-up at the first sample.
            let truth = params(1.0, 0.6, 0.3, 1.0);
            let mut out = [0.0; 3];
            costs_from(
                &[truth; 3],
                &[f64::NAN, 1e300, -f64::INFINITY],
                &input,
                &mut out,
            );
            for c in out {
                assert!(c.is_finite() && c >= cost_cap(&y), "{c}");
            }
        }
    }

    #[test]
    fn fitting_the_true_parameters_costs_almost_nothing() {
        let (u, y) = normalised_sine(1.0);
        let input = FastInput::new(&u, &y, 0);
        let truth = params(1.0, 0.6, 0.3, 1.0);
        let mut off = truth;
        off.alpha *= 1.05;
        let mut out = [0.0; 2];
        costs(&[truth, off], &input, &mut out);
        // Scheme error at the truth is far below the cost of a 5 % parameter error.
        assert!(out[0] < 1e-3 * out[1], "{out:?}");
    }

    #[test]
    fn explicit_recurrence_is_batched_exactly_and_stays_bounded() {
        let (u, y) = normalised_sine(4.0);
        let input = FastInput::explicit(&u, &y);
        assert!(input.is_explicit());
        let pop = population(41);
        let mut a = vec![0.0; pop.len()];
        costs(&pop, &input, &mut a);
        let mut b = vec![0.0; pop.len()];
        costs_portable(&pop, &[], &input, &mut b);
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
        for (p, &c) in pop.iter().zip(&a) {
            assert!(c.is_finite() && c >= 0.0);
            let r = cost_reference(p, &input);
            if r < 1e6 && p.n > 0.2 {
                assert!(((c - r) / r).abs() < 1e-6, "{p:?}: {c} vs {r}");
            }
        }
        // Stiff, small n with γ > β at 28 Hz: plain explicit Euler overshoots the saturation
        // level by orders of magnitude; the clamped recurrence stays within it.
        let p = params(1.0, 0.1, 3.0, 0.2);
        let u: Vec<f64> = sine(28.0, 2.0).iter().map(|x| x / 60.0).collect();
        let mut out = vec![0.0; u.len()];
        assert_eq!(simulate_explicit(&p, &u, &mut out), SimStatus::Ok);
        let sat = p.saturation().unwrap();
        let hmax = u
            .iter()
            .zip(&out)
            .map(|(x, d)| (p.d_e * x + p.d0 - d).abs())
            .fold(0.0, f64::max);
        assert!(hmax <= sat * (1.0 + 1e-12), "{hmax} vs saturation {sat}");
        // Less accurate than the default scheme, as documented: first order in Δu.
        let u = sine(1.0, 2.0);
        let p = params(0.003, 0.03, 0.015, 1.0);
        let (mut acc, mut exp) = (vec![0.0; u.len()], vec![0.0; u.len()]);
        bouc_wen::simulate(&p, &u, &mut acc);
        simulate_explicit(&p, &u, &mut exp);
        let hmax = u
            .iter()
            .zip(&acc)
            .map(|(x, d)| (p.d_e * x + p.d0 - d).abs())
            .fold(0.0, f64::max);
        let err = acc
            .iter()
            .zip(&exp)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
            / hmax;
        eprintln!("explicit recurrence, 1 Hz, n 1: {err:.1e} of max|h|");
        assert!(err > 10.0 * scheme_error(&p, &u) && err < 5e-3, "{err:e}");
    }

    #[test]
    fn explicit_kernel_is_accurate_and_batch_independent_on_a_fit_population() {
        // The benchmark's mid-search population (every parameter within ±50 % of the truth,
        // n from 0.5 to 1.5) on its 10 Hz record: the cheap power costs J about 2e-9.
        use crate::physics::fixtures;
        let (u, y) = fixtures::record(3000);
        let input = FastInput::explicit(&u, &y);
        let pop = fixtures::bouc_wen_population(2 * EXPLICIT_LANES + 5, 3);
        let mut a = vec![0.0; pop.len()];
        costs(&pop, &input, &mut a);
        let mut worst = 0.0f64;
        for (p, &c) in pop.iter().zip(&a) {
            let r = cost_reference(p, &input);
            worst = worst.max(((c - r) / r).abs());
        }
        eprintln!("explicit kernel vs powf reference: {worst:.1e} relative");
        assert!(worst < 1e-6, "{worst:e}");
        // Alone, in a shifted batch, and on the portable path: the same bits.
        let mut b = vec![0.0; pop.len() - 7];
        costs(&pop[7..], &input, &mut b);
        assert!(
            a[7..]
                .iter()
                .zip(&b)
                .all(|(x, y)| x.to_bits() == y.to_bits())
        );
        for i in [0, 39, 40, 84] {
            let mut one = [0.0];
            costs(&pop[i..=i], &input, &mut one);
            assert_eq!(one[0].to_bits(), a[i].to_bits());
        }
        let mut c = vec![0.0; pop.len()];
        costs_portable(&pop, &[], &input, &mut c);
        assert!(a.iter().zip(&c).all(|(x, y)| x.to_bits() == y.to_bits()));
        // Blow-ups: the penalty of the first unstable sample, as on the reference path.
        let wild = params(1.0, -1e3, 0.0, 3.0);
        let nan = params(f64::NAN, 0.5, 0.5, 1.0);
        let mut out = [0.0; 2];
        costs(&[wild, nan], &input, &mut out);
        for (p, c) in [wild, nan].iter().zip(out) {
            assert!(c.is_finite() && c >= cost_cap(&y), "{c}");
            assert_eq!(c.to_bits(), cost_reference(p, &input).to_bits());
        }
    }

    #[test]
    fn blow_ups_get_the_ordered_finite_penalty() {
        let (u, y) = normalised_sine(10.0);
        let input = FastInput::new(&u, &y, 0);
        // β + γ < 0: dh/du grows with h, a finite-time blow-up; and a NaN parameter.
        let wild = params(1.0, -1e3, 0.0, 3.0);
        let nan = params(f64::NAN, 0.5, 0.5, 1.0);
        let mut out = [0.0; 2];
        costs(&[wild, nan], &input, &mut out);
        let cap = cost_cap(&y);
        for c in out {
            assert!(c.is_finite() && c >= cap, "{c} vs cap {cap}");
        }
        let plain = bouc_wen::cost(&params(1.0, 0.6, 0.3, 1.0), &u, &y);
        assert!(plain < cap);
    }
}
