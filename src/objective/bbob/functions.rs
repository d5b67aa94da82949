//! The raw BBOB functions (COCO's `f_*_raw`), before any shift, rotation or offset: each
//! in COCO's order of operations. `n` is the length of the point; every one needs `n >= 2`
//! (several divide by `n - 1`).

use std::f64::consts::PI;

/// f1: sum of squares.
pub fn sphere(x: &[f64]) -> f64 {
    let mut r = 0.0;
    for v in x {
        r += v * v;
    }
    r
}

/// f2, f10: `sum 10^(6 i/(n-1)) x_i^2`, with the coefficients precomputed by
/// [`ellipsoid_coefficients`].
pub fn ellipsoid(x: &[f64], coef: &[f64]) -> f64 {
    let mut r = x[0] * x[0];
    for i in 1..x.len() {
        r += coef[i] * x[i] * x[i];
    }
    r
}

/// `condition^(i/(n-1))` (the same `pow` COCO calls inside the sum).
pub fn ellipsoid_coefficients(condition: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| condition.powf(1.0 * i as f64 / (n as f64 - 1.0)))
        .collect()
}

/// f3, f15: `10 (n - sum cos 2 pi x_i) + sum x_i^2`.
pub fn rastrigin(x: &[f64]) -> f64 {
    let mut s1 = 0.0;
    let mut s2 = 0.0;
    for &v in x {
        s1 += (2.0 * PI * v).cos();
        s2 += v * v;
    }
    10.0 * (x.len() as f64 - s1) + s2
}

/// f5: `sum 5 |s_i| - s_i x_i`, `s_i = ±sqrt(100)^(i/(n-1))` signed like the optimum
/// corner `corner` (±5 per coordinate). Beyond the corner (`x_i corner_i >= 25`) the slope
/// stops: `x_i` counts as the corner, so the minimum stays there (COCO's boundary handling).
pub fn linear_slope(x: &[f64], corner: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mut r = 0.0;
    for (i, (&v, &c)) in x.iter().zip(corner).enumerate() {
        let base = 100f64.sqrt();
        let exponent = i as f64 / (n - 1.0);
        let s = if c > 0.0 {
            base.powf(exponent)
        } else {
            -base.powf(exponent)
        };
        if v * c < 25.0 {
            r += 5.0 * s.abs() - s * v;
        } else {
            r += 5.0 * s.abs() - s * c;
        }
    }
    r
}

/// f6 before its value transforms: squares, 10^4 times larger where `x_i` has the sign of
/// the optimum's coordinate.
pub fn attractive_sector(x: &[f64], xopt: &[f64]) -> f64 {
    let mut r = 0.0;
    for (&v, &o) in x.iter().zip(xopt) {
        if o * v > 0.0 {
            r += 100.0 * 100.0 * v * v;
        } else {
            r += v * v;
        }
    }
    r
}

/// f8, f9: `sum 100 (x_i^2 - x_{i+1})^2 + (x_i - 1)^2`.
pub fn rosenbrock(x: &[f64]) -> f64 {
    let mut s1 = 0.0;
    let mut s2 = 0.0;
    for i in 0..x.len() - 1 {
        let t = x[i] * x[i] - x[i + 1];
        s1 += t * t;
        let t = x[i] - 1.0;
        s2 += t * t;
    }
    100.0 * s1 + s2
}

/// f11: `10^6 x_1^2 + sum_{i>1} x_i^2`.
pub fn discus(x: &[f64]) -> f64 {
    let mut r = 1.0e6 * x[0] * x[0];
    for v in &x[1..] {
        r += v * v;
    }
    r
}

/// f12: `x_1^2 + 10^6 sum_{i>1} x_i^2`.
pub fn bent_cigar(x: &[f64]) -> f64 {
    let mut r = x[0] * x[0];
    for v in &x[1..] {
        r += 1.0e6 * v * v;
    }
    r
}

/// f13: `x_1^2 + 100 sqrt(sum_{i>1} x_i^2)`.
pub fn sharp_ridge(x: &[f64]) -> f64 {
    let mut r = 0.0;
    for v in &x[1..] {
        r += v * v;
    }
    100.0 * r.sqrt() + x[0] * x[0]
}

/// f14: `sqrt(sum |x_i|^(2 + 4 i/(n-1)))`.
pub fn different_powers(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mut sum = 0.0;
    for (i, v) in x.iter().enumerate() {
        let exponent = 2.0 + (4.0 * i as f64) / (n - 1.0);
        sum += v.abs().powf(exponent);
    }
    sum.sqrt()
}

/// The 12 amplitudes, frequencies and the value at 0 of Weierstrass (f16).
#[derive(Debug, Clone)]
pub struct WeierstrassTerms {
    pub a: [f64; 12],
    pub b: [f64; 12],
    pub f0: f64,
}

impl WeierstrassTerms {
    pub fn new() -> Self {
        let mut t = WeierstrassTerms {
            a: [0.0; 12],
            b: [0.0; 12],
            f0: 0.0,
        };
        for k in 0..12 {
            t.a[k] = 0.5f64.powf(k as f64);
            t.b[k] = 3f64.powf(k as f64);
            t.f0 += t.a[k] * (2.0 * PI * t.b[k] * 0.5).cos();
        }
        t
    }
}

impl Default for WeierstrassTerms {
    fn default() -> Self {
        Self::new()
    }
}

/// f16: `10 (1/n sum_i sum_k a_k cos(2 pi b_k (x_i + 1/2)) - f0)^3`.
pub fn weierstrass(x: &[f64], t: &WeierstrassTerms) -> f64 {
    let mut r = 0.0;
    for &v in x {
        for k in 0..12 {
            r += (2.0 * PI * (v + 0.5) * t.b[k]).cos() * t.a[k];
        }
    }
    10.0 * (r / x.len() as f64 - t.f0).powf(3.0)
}

/// f17, f18: `(1/(n-1) sum s_i^(1/4) (1 + sin^2(50 s_i^(1/10))))^2`, `s_i = x_i^2 +
/// x_{i+1}^2`.
pub fn schaffers(x: &[f64]) -> f64 {
    let mut r = 0.0;
    for i in 0..x.len() - 1 {
        let t = x[i] * x[i] + x[i + 1] * x[i + 1];
        r += t.powf(0.25) * (1.0 + (50.0 * t.powf(0.1)).sin().powf(2.0));
    }
    (r / (x.len() as f64 - 1.0)).powf(2.0)
}

/// f19: `10 + 10/(n-1) sum (s_i/4000 - cos s_i)`, `s_i` the Rosenbrock terms.
pub fn griewank_rosenbrock(x: &[f64]) -> f64 {
    let mut r = 0.0;
    for i in 0..x.len() - 1 {
        let c1 = x[i] * x[i] - x[i + 1];
        let c2 = 1.0 - x[i];
        let t = 100.0 * c1 * c1 + c2 * c2;
        r += t / 4000. - t.cos();
    }
    10.0 + 10.0 * r / (x.len() - 1) as f64
}

/// f20 on its scaled variables: `0.01 (418.98... - 1/n sum x_i sin sqrt|x_i| + penalty)`,
/// the penalty counting squared excess beyond ±500.
pub fn schwefel(x: &[f64]) -> f64 {
    let mut penalty = 0.0;
    for &v in x {
        let t = v.abs() - 500.0;
        if t > 0.0 {
            penalty += t * t;
        }
    }
    let mut sum = 0.0;
    for &v in x {
        sum += v * v.abs().sqrt().sin();
    }
    0.01 * (penalty + 418.9828872724339 - sum / x.len() as f64)
}

/// f23: `10/n^2 (prod (1 + i sum_j |2^j x_i - round(2^j x_i)| / 2^j)^(10/n^1.2) - 1)`.
pub fn katsuura(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mut r = 1.0;
    for (i, &v) in x.iter().enumerate() {
        let mut t = 0.0;
        for j in 1..33 {
            let p = 2f64.powf(j as f64);
            t += (p * v - round(p * v)).abs() / p;
        }
        let t = 1.0 + (i as f64 + 1.0) * t;
        r *= t;
    }
    10. / n / n * (-1. + r.powf(10. / n.powf(1.2)))
}

/// COCO's rounding (`coco_double_round`): halves round up, `floor(x + 0.5)`.
pub fn round(x: f64) -> f64 {
    (x + 0.5).floor()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raw_minima_are_zero_where_the_definitions_put_them() {
        let zero = [0.0; 5];
        let ones = [1.0; 5];
        assert_eq!(sphere(&zero), 0.0);
        assert_eq!(ellipsoid(&zero, &ellipsoid_coefficients(1e6, 5)), 0.0);
        assert_eq!(rastrigin(&zero), 0.0);
        assert_eq!(rosenbrock(&ones), 0.0);
        assert_eq!(discus(&zero), 0.0);
        assert_eq!(bent_cigar(&zero), 0.0);
        assert_eq!(sharp_ridge(&zero), 0.0);
        assert_eq!(different_powers(&zero), 0.0);
        assert_eq!(schaffers(&zero), 0.0);
        assert_eq!(katsuura(&zero), 0.0);
        assert!(weierstrass(&zero, &WeierstrassTerms::new()).abs() < 1e-12);
        assert!(griewank_rosenbrock(&ones).abs() < 1e-12);
    }
}
