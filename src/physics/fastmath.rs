//! Branch-free `exp2`, `log2`, `exp`, `pow` and `expm1(z)/z` for the batched model kernels.
//!
//! `f64::powf` and `f64::exp` are library calls that no compiler can vectorise, and the
//! Bouc-Wen and RBF kernels spend most of their time in them. These versions are plain
//! arithmetic (polynomials, bit manipulation and selects) that vectorise over lanes, with
//! every fused multiply-add written as an explicit [`f64::mul_add`]: the AVX2+FMA build
//! lowers it to `vfmadd`, the portable build to the correctly rounded `fma` call, so both give
//! the same bits (never rely on the compiler contracting `a * b + c`).
//!
//! Accuracy (tested against `std` over wide ranges): `exp2`, `exp`: relative error below
//! 1e-14 on [-1000, 1000] (`exp` on [-700, 700]); `e^x - 1` and `phi1`: below 3e-14;
//! `log2(x)`: absolute error below 1e-15 · max(1, |log2 x|) for normal positive `x`. Inputs
//! outside the ranges are clamped (documented per function): the kernels clamp their states
//! are never left for finite states. `exp2_lo`, `log2_lo` and `pow_lo` trade accuracy for
//! speed (1.9e-9 relative, 1.8e-10 absolute, 2.5e-9 relative; tested): the explicit Bouc-Wen
//! recurrence's `|h|^n`, whose cost stays within 1e-6 of the exact path.

/// `1.5 · 2^52`: adding it rounds a float of magnitude below 2^51 to an integer held in the
/// low mantissa bits.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;
const LN2: f64 = std::f64::consts::LN_2;
const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// `log2(e) - LOG2_E`: the constant's rounding error, which would otherwise cost `e^x` a
/// relative error of `|x|` · 1e-16.
const LOG2_E_LO: f64 = 2.035_527_374_093_103_3e-17;
/// Taylor coefficients of `2^f = e^(f ln 2)`, `(ln 2)^k / k!`, k = 0..=11 (truncation error
/// below 7e-15 relative for |f| ≤ 0.5).
const EXP2_C: [f64; 12] = {
    let mut c = [1.0; 12];
    let mut k = 1;
    while k < 12 {
        c[k] = c[k - 1] * LN2 / k as f64;
        k += 1;
    }
    c
};

/// Select without a branch the compiler might keep (`c ? a : b`).
#[inline(always)]
pub fn select(c: bool, a: f64, b: f64) -> f64 {
    if c { a } else { b }
}

/// `2^r` for an integer-valued `r` in [-1022, 1023] held as `ROUND_MAGIC + r`.
#[inline(always)]
fn pow2i(t: f64) -> f64 {
    let ri = t.to_bits().wrapping_sub(ROUND_MAGIC.to_bits());
    f64::from_bits(ri.wrapping_add(1023) << 52)
}

/// `2^f - 1` for |f| ≤ 0.5 + ε, without cancellation near 0.
#[inline(always)]
fn exp2m1_reduced(f: f64) -> f64 {
    let mut p = EXP2_C[11];
    let mut k = 11;
    while k > 1 {
        k -= 1;
        p = p.mul_add(f, EXP2_C[k]);
    }
    p * f
}

/// `2^x` for x clamped to [-1020, 1020] (NaN stays NaN).
#[inline(always)]
pub fn exp2(x: f64) -> f64 {
    let x = select(x < -1020.0, -1020.0, select(x > 1020.0, 1020.0, x));
    let t = x + ROUND_MAGIC;
    let f = x - (t - ROUND_MAGIC);
    let q = exp2m1_reduced(f);
    pow2i(t).mul_add(q, pow2i(t))
}

/// `(e^x, e^x - 1)` for x clamped to about [-707, 707]; the second without cancellation
/// near 0 (what `(e^z - 1)/z` needs).
#[inline(always)]
pub fn exp_expm1(x: f64) -> (f64, f64) {
    let x = select(x < -707.0, -707.0, select(x > 707.0, 707.0, x));
    // x·log2(e) = hi + lo, the product's rounding error and the constant's kept.
    let hi = x * LOG2_E;
    let lo = x.mul_add(LOG2_E, -hi) + x * LOG2_E_LO;
    let t = hi + ROUND_MAGIC;
    let f = (hi - (t - ROUND_MAGIC)) + lo;
    let q = exp2m1_reduced(f);
    let s = pow2i(t);
    (s.mul_add(q, s), s.mul_add(q, s - 1.0))
}

/// `e^x` for x clamped to about [-707, 707].
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    exp_expm1(x).0
}

/// `log2(x)` for positive normal `x` (callers floor their arguments, e.g. at 1e-300).
#[inline(always)]
pub fn log2(x: f64) -> f64 {
    let bits = x.to_bits();
    let e_biased = (bits >> 52) & 0x7ff;
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    // Mantissa in [sqrt(1/2), sqrt(2)).
    let big = m > std::f64::consts::SQRT_2;
    let m = select(big, m * 0.5, m);
    // Exponent as float without an i64 → f64 conversion (AVX2 has none).
    let e = f64::from_bits(0x4330_0000_0000_0000 | e_biased) - 4_503_599_627_371_519.0;
    let e = select(big, e + 1.0, e);
    // ln m = 2 atanh(s), s = (m-1)/(m+1), |s| ≤ 0.1716.
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let mut p: f64 = 1.0 / 17.0;
    p = p.mul_add(s2, 1.0 / 15.0);
    p = p.mul_add(s2, 1.0 / 13.0);
    p = p.mul_add(s2, 1.0 / 11.0);
    p = p.mul_add(s2, 1.0 / 9.0);
    p = p.mul_add(s2, 1.0 / 7.0);
    p = p.mul_add(s2, 1.0 / 5.0);
    p = p.mul_add(s2, 1.0 / 3.0);
    let ln_m = (2.0 * s).mul_add(p * s2, 2.0 * s);
    ln_m.mul_add(LOG2_E, e)
}

/// Bits of `sqrt(1/2)`: [`log2_lo`] reduces to a mantissa in `[sqrt(1/2), sqrt(2))`.
const SQRT_HALF_BITS: u64 = 0x3fe6_a09e_667f_3bcd;
/// Minimax coefficients of `log2(m) / s` in `s²`, `s = (m-1)/(m+1)`, `|s| ≤ 0.1716`
/// (absolute error of `log2` below 1.8e-10).
const LOG2_LO: [f64; 4] = [
    2.885_390_072_752_01,
    0.961_800_759_261_877_5,
    0.576_584_537_251_868_3,
    0.434_256_035_117_044_5,
];
/// Minimax coefficients of `2^f` on `[-0.5, 0.5]` (relative error below 1.9e-9).
const EXP2_LO: [f64; 7] = [
    1.000_000_000_554_179,
    0.693_147_205_737_789_4,
    0.240_226_468_905_915_87,
    0.055_503_287_758_236_694,
    0.009_618_488_957_257_934,
    0.001_339_993_168_204_396_9,
    0.000_153_458_131_485_810_72,
];

/// `log2(x)` to 1.8e-10 absolute, for `x` in `[1e-300, ∞)` (callers floor their arguments):
/// the cheap half of [`pow_lo`]. The mantissa reduction is integer arithmetic on the bits
/// (no compare, no select), the series three fused multiply-adds.
#[inline(always)]
pub fn log2_lo(x: f64) -> f64 {
    // Adding 1.0's bits minus sqrt(1/2)'s carries into the exponent exactly when the
    // mantissa is at least sqrt(2)/2·2, so `kb` is the biased exponent of the reduced form.
    let ix = x
        .to_bits()
        .wrapping_add(0x3ff0_0000_0000_0000 - SQRT_HALF_BITS);
    let kb = ix >> 52;
    let m = f64::from_bits((ix & 0x000f_ffff_ffff_ffff).wrapping_add(SQRT_HALF_BITS));
    let e = f64::from_bits(0x4330_0000_0000_0000 | kb) - 4_503_599_627_371_519.0;
    let s = (m - 1.0) / (m + 1.0);
    let z = s * s;
    let q = z
        .mul_add(LOG2_LO[3], LOG2_LO[2])
        .mul_add(z, LOG2_LO[1])
        .mul_add(z, LOG2_LO[0]);
    s.mul_add(q, e)
}

/// `2^x` to 1.9e-9 relative, x clamped to [-1020, 1020]: the cheap half of [`pow_lo`].
/// The scale `2^round(x)` is added to the polynomial's exponent bits directly.
#[inline(always)]
pub fn exp2_lo(x: f64) -> f64 {
    let x = select(x < -1020.0, -1020.0, select(x > 1020.0, 1020.0, x));
    let t = x + ROUND_MAGIC;
    let f = x - (t - ROUND_MAGIC);
    let mut p = EXP2_LO[6];
    let mut k = 6;
    while k > 0 {
        k -= 1;
        p = p.mul_add(f, EXP2_LO[k]);
    }
    // `t`'s low bits hold round(x); shifted by 52 they are round(x) in the exponent field.
    f64::from_bits(p.to_bits().wrapping_add(t.to_bits() << 52))
}

/// `x^y` to about 2e-9 relative (|y| ≤ 2) for `x` in `[1e-300, ∞)`: the `|h|^n` of the
/// explicit Bouc-Wen recurrence, where a fit needs far less than full precision and every
/// operation saved is throughput.
#[inline(always)]
pub fn pow_lo(x: f64, y: f64) -> f64 {
    exp2_lo(y * log2_lo(x))
}

/// Minimax coefficients of `2^f` on `[-0.5, 0.5]`, degree 8 (relative error 7.8e-13).
const EXP2_FAST: [f64; 9] = [
    0.999_999_999_999_762_3,
    0.693_147_180_546_515_7,
    0.240_226_506_988_771_9,
    0.055_504_109_393_366_23,
    0.009_618_128_543_548_165,
    0.001_333_345_206_674_454_6,
    0.000_154_038_512_630_179_06,
    1.530_973_623_547_198e-5,
    1.317_596_518_611_301_5e-6,
];

/// `2^x` to 8e-13 relative, x clamped to [-1020, 1020]: [`exp2`] with a minimax polynomial
/// three degrees shorter and the scale added to the exponent bits (the RBF kernels' `exp`,
/// where it is most of the work).
#[inline(always)]
pub fn exp2_fast(x: f64) -> f64 {
    let x = select(x < -1020.0, -1020.0, select(x > 1020.0, 1020.0, x));
    let t = x + ROUND_MAGIC;
    let f = x - (t - ROUND_MAGIC);
    let mut p = EXP2_FAST[8];
    let mut k = 8;
    while k > 0 {
        k -= 1;
        p = p.mul_add(f, EXP2_FAST[k]);
    }
    f64::from_bits(p.to_bits().wrapping_add(t.to_bits() << 52))
}

/// `e^x` as `2^(x log2 e)` with [`exp2_fast`]: relative error below 8e-13 + 2.2e-16 |x|
/// (the rounding of `x log2 e`, which [`exp`] avoids at a cost), x clamped to about
/// [-707, 707]. Callers that scale `x` anyway fold `log2 e` into their factor and call
/// [`exp2_fast`].
#[inline(always)]
pub fn exp_fast(x: f64) -> f64 {
    exp2_fast(x * LOG2_E)
}

/// `x^y` for positive normal `x` (with the clamping of [`exp2`]).
#[inline(always)]
pub fn pow(x: f64, y: f64) -> f64 {
    exp2(y * log2(x))
}

/// `φ1(z) = (e^z - 1)/z` (1 at 0), given `em1 = e^z - 1` from [`exp_expm1`].
#[inline(always)]
pub fn phi1(z: f64, em1: f64) -> f64 {
    // Keep the division finite at 0 (its value is discarded there).
    let q = em1 / select(z == 0.0, 1.0, z);
    select(z == 0.0, 1.0, q)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        ((a - b) / b).abs()
    }

    #[test]
    fn exp2_and_exp_match_std() {
        let mut worst = (0.0f64, 0.0f64);
        for i in 0..=200_000 {
            let x = -1000.0 + 2000.0 * i as f64 / 200_000.0 + 1e-7 * (i % 7) as f64;
            worst.0 = worst.0.max(rel(exp2(x), x.exp2()));
            let y = x * 0.7;
            worst.1 = worst.1.max(rel(exp(y), y.exp()));
        }
        assert!(worst.0 < 1e-14, "exp2 {:e}", worst.0);
        assert!(worst.1 < 1e-14, "exp {:e}", worst.1);
        assert_eq!(exp2(0.0), 1.0);
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp2(3.0), 8.0);
        assert!(exp2(-5000.0) < 1e-300 && exp2(-5000.0) >= 0.0);
        assert!(exp2(f64::NAN).is_nan());
    }

    #[test]
    fn log2_and_pow_match_std() {
        let mut worst = (0.0f64, 0.0f64);
        let mut x = 1e-300;
        while x < 1e300 {
            for k in 0..5 {
                let v = x * (1.0 + 0.37 * k as f64);
                worst.0 = worst.0.max((log2(v) - v.log2()).abs());
                if (1e-30..1e30).contains(&v) {
                    for y in [-1.3, -0.5, 0.2, 0.7, 1.0, 1.5, 2.9] {
                        worst.1 = worst.1.max(rel(pow(v, y), v.powf(y)));
                    }
                }
            }
            x *= 1.37;
        }
        assert!(worst.0 < 1e-15 * 1000.0, "log2 abs {:e}", worst.0);
        // pow's relative error is |y ln x| times log2's absolute error, plus exp2's.
        assert!(worst.1 < 1e-13, "pow {:e}", worst.1);
        assert_eq!(log2(1.0), 0.0);
        assert_eq!(log2(1024.0), 10.0);
    }

    #[test]
    fn low_precision_functions_meet_their_stated_bounds() {
        let mut worst = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..=400_000 {
            let x = -1019.0 + 2038.0 * i as f64 / 400_000.0 + 1e-7 * (i % 7) as f64;
            worst.0 = worst.0.max(rel(exp2_lo(x), x.exp2()));
        }
        let mut x = 1e-300;
        while x < 1e300 {
            for k in 0..7 {
                let v = x * (1.0 + 0.29 * k as f64);
                worst.1 = worst.1.max((log2_lo(v) - v.log2()).abs());
                if (1e-30..1e30).contains(&v) {
                    for y in [0.3, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0] {
                        worst.2 = worst.2.max(rel(pow_lo(v, y), v.powf(y)));
                    }
                }
            }
            x *= 1.0137;
        }
        assert!(worst.0 < 1.9e-9, "exp2_lo {:e}", worst.0);
        assert!(worst.1 < 1.8e-10, "log2_lo abs {:e}", worst.1);
        // |y ln 2| times log2's error plus exp2's, and the rounding of y·log2(x).
        assert!(worst.2 < 2.5e-9, "pow_lo {:e}", worst.2);
        assert!(exp2_lo(-5000.0) > 0.0 && exp2_lo(-5000.0) < 1e-300);
        assert!(exp2_lo(5000.0).is_finite());
        assert_eq!(log2_lo(1.0), 0.0);
        assert!(log2_lo(1e-300).is_finite() && log2_lo(f64::MAX).is_finite());
    }

    #[test]
    fn fast_exp_meets_its_stated_bound() {
        let mut worst = (0.0f64, 0.0f64);
        for i in 0..=400_000 {
            let x = -1019.0 + 2038.0 * i as f64 / 400_000.0 + 1e-7 * (i % 7) as f64;
            worst.0 = worst.0.max(rel(exp2_fast(x), x.exp2()));
            let y = x * 0.69;
            worst.1 = worst
                .1
                .max(rel(exp_fast(y), y.exp()) / (8e-13 + 2.2e-16 * y.abs()));
        }
        assert!(worst.0 < 8e-13, "exp2_fast {:e}", worst.0);
        assert!(worst.1 < 1.0, "exp_fast {:e} of its bound", worst.1);
        assert!(exp_fast(-800.0) > 0.0 && exp_fast(-800.0) < 1e-300);
        assert!(exp2_fast(f64::NAN).is_nan());
    }

    #[test]
    fn phi1_matches_its_definition_including_near_zero() {
        for i in -4000..=4000 {
            let z = i as f64 * 0.01 + 1e-9 * (i % 3) as f64;
            let want = if z == 0.0 { 1.0 } else { z.exp_m1() / z };
            let got = phi1(z, exp_expm1(z).1);
            assert!(rel(got, want) < 3e-14, "z {z}: {got} vs {want}");
        }
        assert_eq!(phi1(0.0, 1.0), 1.0);
        assert!(rel(phi1(1e-12, exp_expm1(1e-12).1), 1.0 + 5e-13) < 1e-15);
        for x in [-700.0, -3.0, -1e-9, 1e-9, 0.3, 5.0, 700.0] {
            let (e, m1) = exp_expm1(x);
            assert!(
                rel(e, f64::exp(x)) < 1e-14 && rel(m1, f64::exp_m1(x)) < 3e-14,
                "{x}"
            );
        }
    }
}
