//! The BBOB transformations of variables and values (COCO's `transform_vars_*.c`,
//! `transform_obj_*.c`). Each keeps COCO's order of floating-point operations, since the
//! functions must agree with COCO's to about 1e-12 and several are steep or oscillating.

/// `x - offset` (`transform_vars_shift`).
pub fn shift(x: &[f64], offset: &[f64]) -> Vec<f64> {
    x.iter().zip(offset).map(|(a, o)| a - o).collect()
}

/// `M x + b` with `M` row-major `n x n` (`transform_vars_affine`): each row starts at `b`
/// and adds the products left to right.
pub fn affine(m: &[f64], b: &[f64], x: &[f64]) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|i| {
            let row = &m[i * n..(i + 1) * n];
            let mut acc = b[i];
            for (xj, mij) in x.iter().zip(row) {
                acc += xj * mij;
            }
            acc
        })
        .collect()
}

/// `M x` for `M` given as rows (`m[i][j]`), each sum starting at 0: the in-function
/// rotations of f7, f21/f22 and f24 (`tmx[i] += rot[i][j] * x[j]`).
pub fn rotate(m: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
    m.iter()
        .map(|row| {
            let mut acc = 0.0;
            for (mij, xj) in row.iter().zip(x) {
                acc += mij * xj;
            }
            acc
        })
        .collect()
}

/// T_osz of one number: a smooth, monotone, oscillating distortion keeping sign and 0.
pub fn t_osz(x: f64) -> f64 {
    const ALPHA: f64 = 0.1;
    if x > 0.0 {
        let t = x.ln() / ALPHA;
        let base = (t + 0.49 * (t.sin() + (0.79 * t).sin())).exp();
        base.powf(ALPHA)
    } else if x < 0.0 {
        let t = (-x).ln() / ALPHA;
        let base = (t + 0.49 * ((0.55 * t).sin() + (0.31 * t).sin())).exp();
        -base.powf(ALPHA)
    } else {
        0.0
    }
}

/// T_osz of every coordinate (`transform_vars_oscillate`).
pub fn oscillate(x: &[f64]) -> Vec<f64> {
    x.iter().map(|&v| t_osz(v)).collect()
}

/// T_osz of an objective value (`transform_obj_oscillate`): as [`t_osz`] except that it
/// divides `ln|y|` once for both signs, which is the same number.
pub fn oscillate_value(y: f64) -> f64 {
    if y == 0.0 { y } else { t_osz(y) }
}

/// T_asy^beta (`transform_vars_asymmetric`): positive coordinates raised to
/// `1 + beta i/(n-1) sqrt(x_i)`, the others kept.
pub fn asymmetric(x: &[f64], beta: f64) -> Vec<f64> {
    let n = x.len() as f64;
    x.iter()
        .enumerate()
        .map(|(i, &v)| {
            if v > 0.0 {
                let exponent = 1.0 + (beta * i as f64) / (n - 1.0) * v.sqrt();
                v.powf(exponent)
            } else {
                v
            }
        })
        .collect()
}

/// The diagonal of Λ^alpha (`transform_vars_conditioning`): `alpha^(0.5 i/(n-1))`.
pub fn conditioning_diagonal(alpha: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| alpha.powf(0.5 * i as f64 / (n as f64 - 1.0)))
        .collect()
}

/// `sqrt(10)^(i/(n-1))`, times 10 at even (0-based) indices where the coordinate is
/// positive: the s_i scaling of Bueche-Rastrigin (`transform_vars_brs`).
pub fn brs(x: &[f64]) -> Vec<f64> {
    let n = x.len() as f64;
    x.iter()
        .enumerate()
        .map(|(i, &v)| {
            let mut factor = 10f64.sqrt().powf(i as f64 / (n - 1.0));
            if v > 0.0 && i % 2 == 0 {
                factor *= 10.0;
            }
            factor * v
        })
        .collect()
}

/// f_pen's sum of squared excesses outside [-5, 5]^n (`transform_obj_penalize` and the
/// in-function penalties of f7, f21/f22, f24).
pub fn boundary_excess(x: &[f64]) -> f64 {
    let mut penalty = 0.0;
    for &v in x {
        let c1 = v - 5.0;
        let c2 = -5.0 - v;
        if c1 > 0.0 {
            penalty += c1 * c1;
        } else if c2 > 0.0 {
            penalty += c2 * c2;
        }
    }
    penalty
}

/// The same excess as written inside f7, f21/f22 and f24 (`|x| - 5`, squared): equal to
/// [`boundary_excess`] but kept in COCO's form so the sums round alike.
pub fn abs_excess(x: &[f64]) -> f64 {
    let mut penalty = 0.0;
    for &v in x {
        let t = v.abs() - 5.0;
        if t > 0.0 {
            penalty += t * t;
        }
    }
    penalty
}

/// The row-major matrix `R diag(base^(k/(n-1))) Q` as COCO builds it for f6, f13, f15,
/// f16, f23: each entry sums `R[i][k] * base^(k/(n-1)) * Q[k][j]` over k.
pub fn rot_scale_rot(r: &[Vec<f64>], base: f64, q: &[Vec<f64>]) -> Vec<f64> {
    let n = r.len();
    let mut m = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            let mut acc = 0.0;
            for k in 0..n {
                let exponent = 1.0 * k as f64 / (n as f64 - 1.0);
                acc += r[i][k] * base.powf(exponent) * q[k][j];
            }
            m[i * n + j] = acc;
        }
    }
    m
}

/// A rotation as a row-major matrix (`bbob2009_copy_rotation_matrix`).
pub fn flatten(r: &[Vec<f64>]) -> Vec<f64> {
    r.iter().flatten().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_osz_keeps_sign_zero_and_order() {
        assert_eq!(t_osz(0.0), 0.0);
        assert!(t_osz(1.0) > 0.0 && t_osz(-1.0) < 0.0);
        // ln 1 = 0, so T_osz(1) = exp(0)^0.1 = 1.
        assert_eq!(t_osz(1.0), 1.0);
        let xs: Vec<f64> = (-50..=50).map(|k| k as f64 * 0.1).collect();
        let ys = oscillate(&xs);
        assert!(ys.windows(2).all(|w| w[0] <= w[1]));
    }

    #[test]
    fn asymmetric_leaves_negatives_and_the_first_coordinate() {
        let y = asymmetric(&[2.0, -3.0, 4.0], 0.5);
        assert_eq!(y[0], 2.0);
        assert_eq!(y[1], -3.0);
        assert!((y[2] - 4f64.powf(1.0 + 0.5 * 2.0)).abs() < 1e-12);
    }

    #[test]
    fn penalties_count_only_the_excess() {
        assert_eq!(boundary_excess(&[5.0, -5.0, 0.0]), 0.0);
        assert_eq!(boundary_excess(&[6.0, -7.0]), 1.0 + 4.0);
        assert_eq!(abs_excess(&[6.0, -7.0]), 1.0 + 4.0);
    }
}
