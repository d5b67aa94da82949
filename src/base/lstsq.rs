//! Small dense least squares for the diagnosis's variable projection: Gram-Schmidt QR with
//! reorthogonalisation (columns dependent on earlier ones get 0), and bounds on some
//! coefficients by an active set on the normal equations.

/// `v` minus its projections on `q` (twice: Gram-Schmidt with reorthogonalisation), the
/// coefficients added to `r`.
fn orthogonalise(v: &mut [f64], q: &[Option<Vec<f64>>], r: &mut [f64]) {
    for _ in 0..2 {
        for (i, qi) in q.iter().enumerate() {
            let Some(qi) = qi.as_ref() else { continue };
            let d = dot(qi, v);
            r[i] += d;
            v.iter_mut().zip(qi).for_each(|(x, a)| *x -= d * a);
        }
    }
}
/// `Σ aᵢ bᵢ` in eight interleaved partial sums: a single running sum waits on each add's
/// latency, and these dot products over whole records are most of a fit's linear algebra.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// Gram-Schmidt QR of `cols` (first `n` rows): orthonormal columns (None where a column
/// depends on the earlier ones) and `R`.
#[allow(clippy::type_complexity)]
pub fn qr(cols: &[Vec<f64>], n: usize) -> (Vec<Option<Vec<f64>>>, Vec<Vec<f64>>) {
    let m = cols.len();
    let mut q: Vec<Option<Vec<f64>>> = Vec::with_capacity(m);
    let mut r = vec![vec![0.0; m]; m];
    let mut rj = vec![0.0; m];
    for j in 0..m {
        let mut v = cols[j][..n].to_vec();
        let norm0 = dot(&v, &v).sqrt();
        rj.fill(0.0);
        orthogonalise(&mut v, &q, &mut rj);
        for (i, x) in rj.iter().enumerate().take(j) {
            r[i][j] = *x;
        }
        let norm = dot(&v, &v).sqrt();
        if norm > 1e-10 * norm0 && norm.is_finite() && norm > 0.0 {
            r[j][j] = norm;
            v.iter_mut().for_each(|x| *x /= norm);
            q.push(Some(v));
        } else {
            q.push(None);
        }
    }
    (q, r)
}

/// Solves `R b = rhs` for the kept columns of a [`qr`] (dropped ones get 0); all zeros if
/// anything is not finite.
fn back_substitute(q: &[Option<Vec<f64>>], r: &[Vec<f64>], rhs: &[f64]) -> Vec<f64> {
    let m = q.len();
    let mut b = vec![0.0; m];
    for j in (0..m).rev() {
        if q[j].is_none() {
            continue;
        }
        let s: f64 = (j + 1..m).map(|k| r[j][k] * b[k]).sum();
        b[j] = (rhs[j] - s) / r[j][j];
    }
    if b.iter().all(|x| x.is_finite()) {
        b
    } else {
        vec![0.0; m]
    }
}

/// Least squares `min |y - Σ b_j c_j|` by modified Gram-Schmidt with one
/// reorthogonalisation; columns that are (numerically) in the span of earlier ones get 0.
pub fn least_squares(cols: &[Vec<f64>], y: &[f64]) -> Vec<f64> {
    let (q, r) = qr(cols, y.len());
    let qty: Vec<f64> = q
        .iter()
        .map(|qi| qi.as_ref().map_or(0.0, |qi| dot(qi, y)))
        .collect();
    back_substitute(&q, &r, &qty)
}

/// [`least_squares`] with some coefficients bounded in magnitude (`(index, bound)`): a
/// coefficient beyond its bound is held there and the others refitted, until none is
/// beyond (at most once per bounded coefficient).
pub fn bounded_least_squares(cols: &[Vec<f64>], y: &[f64], bounds: &[(usize, f64)]) -> Vec<f64> {
    let solve = |held: &[(usize, f64)]| {
        if held.is_empty() {
            return Some(least_squares(cols, y));
        }
        let mut target = y.to_vec();
        for &(j, x) in held {
            target
                .iter_mut()
                .zip(&cols[j])
                .for_each(|(t, c)| *t -= x * c);
        }
        let free: Vec<Vec<f64>> = cols
            .iter()
            .enumerate()
            .map(|(j, c)| {
                if held.iter().any(|h| h.0 == j) {
                    vec![0.0; c.len()]
                } else {
                    c.clone()
                }
            })
            .collect();
        let mut b = least_squares(&free, &target);
        for &(j, x) in held {
            b[j] = x;
        }
        Some(b)
    };
    active_set(bounds, solve).expect("Gram-Schmidt always solves")
}

/// The active-set loop of a bounded least squares: `solve(held)` (coefficients with
/// `held` fixed, None if it cannot) from none held; a coefficient beyond its bound is
/// then held there and the rest solved again, until none is beyond (at most once per
/// bounded coefficient). None as soon as a solve is None.
fn active_set(
    bounds: &[(usize, f64)],
    solve: impl Fn(&[(usize, f64)]) -> Option<Vec<f64>>,
) -> Option<Vec<f64>> {
    let mut b = solve(&[])?;
    let mut held: Vec<(usize, f64)> = Vec::new();
    for _ in 0..bounds.len() {
        let beyond: Vec<(usize, f64)> = bounds
            .iter()
            .filter(|(j, _)| !held.iter().any(|h| h.0 == *j))
            .filter_map(|&(j, lim)| {
                let x = *b.get(j)?;
                (x.abs() > lim).then(|| (j, lim.copysign(x)))
            })
            .collect();
        if beyond.is_empty() {
            break;
        }
        held.extend(beyond);
        b = solve(&held)?;
    }
    Some(b)
}

/// [`bounded_least_squares`] by the normal equations of the columns scaled to unit norm:
/// one pass per inner product and no column copied, where Gram-Schmidt's passes were most
/// of an evaluation's linear algebra. Only when every column keeps at least `1e-4` of its
/// norm outside the earlier ones (the squared condition number then costs at most eight
/// digits of the coefficients, and only to second order the cost, which the caller takes
/// from the residual); otherwise, dependent columns included, Gram-Schmidt decides.
pub(crate) fn gram_least_squares(
    cols: &[Vec<f64>],
    y: &[f64],
    bounds: &[(usize, f64)],
) -> Vec<f64> {
    let m = cols.len();
    let scale: Vec<f64> = cols
        .iter()
        .map(|c| {
            let d = dot(c, c).sqrt();
            if d > 0.0 && d.is_finite() {
                1.0 / d
            } else {
                0.0
            }
        })
        .collect();
    let mut g = vec![vec![0.0; m]; m];
    for i in 0..m {
        for j in i..m {
            let x = if scale[i] == 0.0 || scale[j] == 0.0 {
                0.0
            } else if i == j {
                1.0
            } else {
                dot(&cols[i], &cols[j]) * scale[i] * scale[j]
            };
            g[i][j] = x;
            g[j][i] = x;
        }
    }
    let gy: Vec<f64> = (0..m)
        .map(|j| {
            if scale[j] == 0.0 {
                0.0
            } else {
                dot(&cols[j], y) * scale[j]
            }
        })
        .collect();
    // Coefficients with `held` (index, value in the columns' own units) fixed; None if the
    // free columns are near dependent.
    let solve = |held: &[(usize, f64)]| -> Option<Vec<f64>> {
        let free: Vec<usize> = (0..m)
            .filter(|&j| scale[j] != 0.0 && !held.iter().any(|h| h.0 == j))
            .collect();
        let rhs: Vec<f64> = free
            .iter()
            .map(|&i| {
                gy[i]
                    - held
                        .iter()
                        .filter(|h| scale[h.0] != 0.0)
                        .map(|&(j, x)| g[i][j] * x / scale[j])
                        .sum::<f64>()
            })
            .collect();
        // Cholesky L Lᵀ of the free block.
        let k = free.len();
        let mut l = vec![vec![0.0; k]; k];
        for a in 0..k {
            let d = g[free[a]][free[a]] - (0..a).map(|c| l[a][c] * l[a][c]).sum::<f64>();
            if d.is_nan() || d < 1e-8 {
                return None;
            }
            let da = d.sqrt();
            l[a][a] = da;
            for b in a + 1..k {
                let x = g[free[b]][free[a]] - (0..a).map(|c| l[b][c] * l[a][c]).sum::<f64>();
                l[b][a] = x / da;
            }
        }
        let mut z = vec![0.0; k];
        for a in 0..k {
            let s: f64 = (0..a).map(|c| l[a][c] * z[c]).sum();
            z[a] = (rhs[a] - s) / l[a][a];
        }
        let mut w = vec![0.0; k];
        for a in (0..k).rev() {
            let s: f64 = (a + 1..k).map(|c| l[c][a] * w[c]).sum();
            w[a] = (z[a] - s) / l[a][a];
        }
        let mut b = vec![0.0; m];
        for (a, &j) in free.iter().enumerate() {
            b[j] = w[a] * scale[j];
        }
        for &(j, x) in held {
            b[j] = x;
        }
        b.iter().all(|x| x.is_finite()).then_some(b)
    };
    active_set(bounds, solve).unwrap_or_else(|| bounded_least_squares(cols, y, bounds))
}

/// Non-negative least squares `min ½|y − Σ θ_j c_j|²` with `θ_j ≥ 0` where `nonneg[j]`,
/// the others free (Lawson and Hanson's active set, free coefficients always in the
/// passive set). A hysteresis model linear in its weights (Prandtl-Ishlinskii, Preisach)
/// fits by this exactly, which gives its fitting objective a known optimum. Each inner
/// solve is Gram-Schmidt on the passive columns, so dependent columns get 0 rather than
/// an ill-conditioned value.
pub fn nnls(cols: &[Vec<f64>], y: &[f64], nonneg: &[bool]) -> Vec<f64> {
    let m = cols.len();
    assert_eq!(nonneg.len(), m, "one constraint flag per column");
    let solve = |passive: &[bool]| -> Vec<f64> {
        let idx: Vec<usize> = (0..m).filter(|&j| passive[j]).collect();
        let sub: Vec<Vec<f64>> = idx.iter().map(|&j| cols[j].clone()).collect();
        let b = if sub.is_empty() {
            Vec::new()
        } else {
            least_squares(&sub, y)
        };
        let mut x = vec![0.0; m];
        for (k, &j) in idx.iter().enumerate() {
            x[j] = b[k];
        }
        x
    };
    let norms: Vec<f64> = cols.iter().map(|c| dot(c, c).sqrt()).collect();
    let y_norm = dot(y, y).sqrt();
    let mut passive: Vec<bool> = nonneg.iter().map(|&c| !c).collect();
    let mut x = solve(&passive);
    // Coefficients whose solve came back <= 0 right after entering (rounding, at the
    // optimum's edge): kept out until the point moves, so the loop cannot cycle.
    let mut barred = vec![false; m];
    for _ in 0..3 * m.max(1) {
        let mut r = y.to_vec();
        for (j, c) in cols.iter().enumerate() {
            if x[j] != 0.0 {
                r.iter_mut().zip(c).for_each(|(ri, ci)| *ri -= x[j] * ci);
            }
        }
        let entering = (0..m)
            .filter(|&j| nonneg[j] && !passive[j] && !barred[j])
            .map(|j| (j, dot(&cols[j], &r)))
            .filter(|&(j, w)| w > 1e-12 * norms[j] * y_norm.max(f64::MIN_POSITIVE))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((t, _)) = entering else { break };
        passive[t] = true;
        let mut first = true;
        loop {
            let s = solve(&passive);
            let bad: Vec<usize> = (0..m)
                .filter(|&j| nonneg[j] && passive[j] && s[j] <= 0.0)
                .collect();
            if bad.is_empty() {
                x = s;
                break;
            }
            if first && bad == [t] {
                passive[t] = false;
                barred[t] = true;
                break;
            }
            first = false;
            let alpha = bad
                .iter()
                .map(|&j| x[j] / (x[j] - s[j]))
                .fold(f64::INFINITY, f64::min)
                .clamp(0.0, 1.0);
            for j in 0..m {
                x[j] += alpha * (s[j] - x[j]);
                if nonneg[j] && passive[j] && x[j] <= 0.0 {
                    x[j] = 0.0;
                    passive[j] = false;
                }
            }
        }
        // The point moved: a coefficient barred at the old one may be of use now.
        if !barred[t] {
            barred.fill(false);
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounded_least_squares_holds_a_coefficient_at_its_bound_and_refits_the_rest() {
        let a: Vec<f64> = (0..50).map(|k| 1.0 + 0.1 * k as f64).collect();
        let b: Vec<f64> = (0..50).map(|k| ((k as f64) * 0.3).sin()).collect();
        let y: Vec<f64> = a.iter().zip(&b).map(|(x, z)| 2.0 * x - 5.0 * z).collect();
        let free = bounded_least_squares(&[a.clone(), b.clone()], &y, &[]);
        assert!((free[0] - 2.0).abs() < 1e-9 && (free[1] + 5.0).abs() < 1e-9);
        let held = bounded_least_squares(&[a.clone(), b.clone()], &y, &[(1, 1.5)]);
        assert_eq!(held[1], -1.5);
        // The other coefficient is the least-squares one given the held value.
        let rest: Vec<f64> = y.iter().zip(&b).map(|(v, z)| v + 1.5 * z).collect();
        assert!((held[0] - least_squares(&[a], &rest)[0]).abs() < 1e-12);
    }

    #[test]
    fn normal_equations_agree_with_gram_schmidt_and_yield_to_it_on_near_dependent_columns() {
        let n = 4000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 / n as f64).collect();
        let decay = |tau: f64| t.iter().map(|x| (-x / tau).exp()).collect::<Vec<f64>>();
        let y: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, x)| (7.0 * x).sin() + 0.3 * (-x / 0.2).exp() + 0.01 * ((k * 37) % 11) as f64)
            .collect();
        let sine: Vec<f64> = t.iter().map(|x| (7.0 * x).sin()).collect();
        let a = decay(0.2);
        let cost = |cols: &[Vec<f64>], b: &[f64]| -> f64 {
            (0..n)
                .map(|k| {
                    let m: f64 = cols.iter().zip(b).map(|(c, x)| c[k] * x).sum();
                    0.5 * (y[k] - m).powi(2)
                })
                .sum()
        };
        // Well conditioned: the normal equations, the same fit.
        let good = vec![sine.clone(), a.clone(), decay(0.02), vec![0.0; n]];
        for bounds in [vec![], vec![(1, 0.1)]] {
            let gs = bounded_least_squares(&good, &y, &bounds);
            let ne = gram_least_squares(&good, &y, &bounds);
            let (c_gs, c_ne) = (cost(&good, &gs), cost(&good, &ne));
            assert!((c_ne / c_gs - 1.0).abs() < 1e-12, "{c_ne} vs {c_gs}");
            for (x, z) in ne.iter().zip(&gs) {
                assert!((x - z).abs() <= 1e-9 * (1.0 + z.abs()), "{x} vs {z}");
            }
            assert!(bounds.iter().all(|&(j, lim)| ne[j].abs() <= lim));
            assert_eq!(ne[3], 0.0);
        }
        // A column near another (and one exactly dependent): Gram-Schmidt decides, which
        // gives the dependent one 0 rather than a pair of large opposite coefficients.
        let bad = vec![
            sine,
            a.clone(),
            decay(0.2001),
            a.iter().map(|x| 2.0 * x).collect(),
        ];
        for bounds in [vec![], vec![(1, 0.1)]] {
            assert_eq!(
                gram_least_squares(&bad, &y, &bounds),
                bounded_least_squares(&bad, &y, &bounds)
            );
        }
        assert_eq!(gram_least_squares(&bad, &y, &[])[3], 0.0);
    }

    #[test]
    fn least_squares_handles_collinear_columns() {
        let a: Vec<f64> = (0..50).map(|k| k as f64).collect();
        let b = vec![1.0; 50];
        let c: Vec<f64> = a.iter().map(|x| 2.0 * x + 1.0).collect();
        let y: Vec<f64> = a.iter().map(|x| 3.0 * x - 2.0).collect();
        let coef = least_squares(&[a.clone(), b, c], &y);
        let fit: Vec<f64> = (0..50)
            .map(|k| coef[0] * a[k] + coef[1] + coef[2] * (2.0 * a[k] + 1.0))
            .collect();
        for (f, t) in fit.iter().zip(&y) {
            assert!((f - t).abs() < 1e-9);
        }
        assert_eq!(coef[2], 0.0);
    }

    #[test]
    fn nnls_keeps_constrained_coefficients_non_negative_at_the_optimum() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        for case in 0..20 {
            let (n, m) = (60, 8);
            let cols: Vec<Vec<f64>> = (0..m)
                .map(|_| (0..n).map(|_| rng.random::<f64>() - 0.3).collect())
                .collect();
            let y: Vec<f64> = (0..n).map(|_| rng.random::<f64>() * 2.0 - 1.0).collect();
            let nonneg: Vec<bool> = (0..m).map(|j| j % 3 != 2).collect();
            let x = nnls(&cols, &y, &nonneg);
            let mut r = y.clone();
            for (j, c) in cols.iter().enumerate() {
                r.iter_mut().zip(c).for_each(|(ri, ci)| *ri -= x[j] * ci);
            }
            let mut at_bound = 0;
            for j in 0..m {
                let g = dot(&cols[j], &r);
                if nonneg[j] && x[j] == 0.0 {
                    at_bound += 1;
                    assert!(
                        g <= 1e-10,
                        "case {case}: coefficient {j} would improve ({g:e})"
                    );
                } else {
                    assert!(g.abs() < 1e-10, "case {case}: gradient {g:e} at {j}");
                    assert!(!nonneg[j] || x[j] > 0.0);
                }
            }
            // Unconstrained, some of these would be negative: the bound is exercised.
            if case == 0 {
                let free = least_squares(&cols, &y);
                assert!(free.iter().zip(&nonneg).any(|(b, c)| *c && *b < 0.0));
                assert!(at_bound > 0);
            }
        }
    }
}
