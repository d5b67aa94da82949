//! COCO's legacy BBOB 2009 random generators (`suite_bbob_legacy_code.c`), which fix every
//! instance: the optimum's location and value, the rotations. They are not random streams of
//! ours (those are ChaCha, in `base::seed`) but part of the functions' definition: the same
//! seed must give COCO's numbers bit for bit, so the arithmetic below keeps COCO's order.

use std::f64::consts::PI;

/// The largest dimension the legacy generators serve: COCO builds a rotation from
/// `dim * dim` Gaussian numbers in a buffer of 2000 (`dim <= 44`); 40 is the largest
/// dimension of COCO's `bbob` suite and the largest the reference table checks.
pub const MAX_BBOB_DIM: usize = 40;

/// `n` uniform numbers in (0, 1] from `seed`: a Park-Miller minimal-standard generator
/// shuffled through a table of 32 (Bays-Durham), as `bbob2009_unif`.
pub fn bbob2009_unif(n: usize, seed: i64) -> Vec<f64> {
    let mut seed = seed.abs().max(1);
    let step = |s: i64| -> i64 {
        // C: tmp = (int) floor((double) s / 127773); the quotient fits an int.
        let tmp = ((s as f64) / 127773.0).floor() as i32 as i64;
        let next = 16807 * (s - tmp * 127773) - 2836 * tmp;
        if next < 0 { next + 2147483647 } else { next }
    };
    let mut table = [0i64; 32];
    for i in (0..40).rev() {
        seed = step(seed);
        if i < 32 {
            table[i] = seed;
        }
    }
    let mut current = table[0];
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        seed = step(seed);
        let k = ((current as f64) / 67108865.0).floor() as i32 as usize;
        current = table[k];
        table[k] = seed;
        let r = current as f64 / 2.147483647e9;
        out.push(if r == 0.0 { 1e-99 } else { r });
    }
    out
}

/// `n` standard normal numbers from `seed` (Box-Muller over `2n` uniforms), as
/// `bbob2009_gauss`.
pub fn bbob2009_gauss(n: usize, seed: i64) -> Vec<f64> {
    let u = bbob2009_unif(2 * n, seed);
    (0..n)
        .map(|i| {
            let g = (-2.0 * u[i].ln()).sqrt() * (2.0 * PI * u[n + i]).cos();
            if g == 0.0 { 1e-99 } else { g }
        })
        .collect()
}

/// A `dim x dim` orthogonal matrix, `b[row][column]`: Gaussian entries (column-major from
/// the stream), then Gram-Schmidt over the columns, as `bbob2009_compute_rotation`.
pub fn compute_rotation(seed: i64, dim: usize) -> Vec<Vec<f64>> {
    let g = bbob2009_gauss(dim * dim, seed);
    let mut b: Vec<Vec<f64>> = (0..dim)
        .map(|i| (0..dim).map(|j| g[j * dim + i]).collect())
        .collect();
    for i in 0..dim {
        for j in 0..i {
            let mut prod = 0.0;
            for row in b.iter() {
                prod += row[i] * row[j];
            }
            for row in b.iter_mut() {
                row[i] -= prod * row[j];
            }
        }
        let mut prod = 0.0;
        for row in b.iter() {
            prod += row[i] * row[i];
        }
        for row in b.iter_mut() {
            row[i] /= prod.sqrt();
        }
    }
    b
}

/// The optimum's location, on a grid of 8e-4 in [-4, 4) (0 moved to -1e-5), as
/// `bbob2009_compute_xopt`.
pub fn compute_xopt(seed: i64, dim: usize) -> Vec<f64> {
    bbob2009_unif(dim, seed)
        .into_iter()
        .map(|u| {
            let x = 8.0 * (1e4 * u).floor() / 1e4 - 4.0;
            if x == 0.0 { -1e-5 } else { x }
        })
        .collect()
}

/// The optimal value of `function` (1-24) on `instance`: a ratio of two Gaussians, scaled
/// by 100, rounded to 2 decimals and clamped to [-1000, 1000], as `bbob2009_compute_fopt`.
/// Functions 4 and 18 draw it with the seeds of 3 and 17, as in COCO.
pub fn compute_fopt(function: usize, instance: usize) -> f64 {
    let base = match function {
        4 => 3,
        18 => 17,
        f => f as i64,
    };
    let seed = base + 10000 * instance as i64;
    let a = bbob2009_gauss(1, seed)[0];
    let b = bbob2009_gauss(1, seed + 1)[0];
    let rounded = (100.0 * 100.0 * a / b + 0.5).floor() / 100.0;
    rounded.clamp(-1000.0, 1000.0)
}

/// The seed of `function`'s instance: `function + 10000 instance`, except that f4 and f18
/// share the seeds of f3 and f17 (`rseed_3`, `rseed_17` in `suite_bbob.c`).
pub fn instance_seed(function: usize, instance: usize) -> i64 {
    let base = match function {
        4 => 3,
        18 => 17,
        f => f as i64,
    };
    base + 10000 * instance as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniforms_lie_in_the_unit_interval_and_follow_the_seed() {
        let a = bbob2009_unif(100, 10001);
        assert!(a.iter().all(|&u| u > 0.0 && u <= 1.0));
        assert_eq!(a, bbob2009_unif(100, 10001));
        assert_ne!(a, bbob2009_unif(100, 10002));
        // A negative seed is its absolute value, 0 is 1 (as in COCO).
        assert_eq!(bbob2009_unif(5, -7), bbob2009_unif(5, 7));
        assert_eq!(bbob2009_unif(5, 0), bbob2009_unif(5, 1));
    }

    #[test]
    fn rotations_are_orthogonal() {
        for dim in [2, 5, 40] {
            let b = compute_rotation(1_010_001, dim);
            for i in 0..dim {
                for j in 0..dim {
                    let dot: f64 = (0..dim).map(|k| b[k][i] * b[k][j]).sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((dot - want).abs() < 1e-12, "dim {dim} ({i},{j}): {dot}");
                }
            }
        }
    }

    #[test]
    fn fopt_is_rounded_to_hundredths_and_clamped() {
        for f in 1..=24 {
            for i in [1, 2, 15, 101] {
                let v = compute_fopt(f, i);
                assert!((-1000.0..=1000.0).contains(&v));
                assert!(((v * 100.0).round() - v * 100.0).abs() < 1e-6, "{v}");
            }
        }
    }
}
