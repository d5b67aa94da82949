//! The linear coefficients of a shape by least squares (with the fixed columns projected
//! out once per fit), and the simulation of a fitted model.

use super::*;
use crate::base::lstsq::{bounded_least_squares, dot, gram_least_squares, qr};

impl Structure {
    /// Fits the linear coefficients of shape `theta` to `(u, y)` by least squares and
    /// returns them with the cost `Σ e²/2`. Always finite: an unstable shape costs
    /// `cost_cap(y) (2 - at/N)`, above every stable cost and higher the earlier it fails.
    pub fn fit_linear(&self, theta: &[f64], u: &[f64], y: &[f64]) -> LinearFit {
        let len = u.len().min(y.len());
        self.fit_linear_projected(theta, u, y, &self.projection(&u[..len], &y[..len]))
    }

    /// [`Self::fit_linear`] the direct way: every column, the fixed ones included, by
    /// Gram-Schmidt ([`bounded_least_squares`]). The reference the projected solve is
    /// tested and benchmarked against.
    pub fn fit_linear_reference(&self, theta: &[f64], u: &[f64], y: &[f64]) -> LinearFit {
        let len = u.len().min(y.len());
        let (u, y) = (&u[..len], &y[..len]);
        let cap = cost_cap(y);
        let (cols, status) = self.columns(theta, u);
        if let Status::Unstable { at } = status {
            return LinearFit::unstable(cols.len(), cap, at, len);
        }
        let coef =
            bounded_least_squares(&cols, y, &self.state_bounds(theta, self.state_range(u, y)));
        let cost: f64 = (0..len)
            .map(|k| {
                let m: f64 = cols.iter().zip(&coef).map(|(c, b)| c[k] * b).sum();
                0.5 * (y[k] - m).powi(2)
            })
            .sum();
        LinearFit {
            coef,
            cost: if cost.is_finite() { cost.min(cap) } else { cap },
            status,
        }
    }

    /// The shape-independent part of [`Self::fit_linear`] on record `y`, computed once per
    /// fit: each evaluation then orthogonalises only the few shape-dependent columns (a
    /// spline drift adds up to 16 fixed ones).
    pub fn projection(&self, u: &[f64], y: &[f64]) -> Projection {
        let mut p = Projection::new(self.fixed_indices(), &self.fixed_columns(y.len()), y);
        p.span = self.state_range(u, y);
        p
    }

    /// How far the output of a record `(u, y)` moved, for the creep states' bounds
    /// ([`Self::state_bounds`]): its span, or more for a record that starts far from 0 V
    /// (the actuator was brought there before recording began, so its creep states hold
    /// that excursion: the output's slope on the input times the first input's magnitude).
    /// The most any of a joint structure's records needs.
    pub fn state_range(&self, u: &[f64], y: &[f64]) -> f64 {
        match self.records() {
            Some(parts) if u.len() == parts.iter().map(|p| p.0).sum::<usize>() => {
                let mut from = 0;
                parts
                    .iter()
                    .map(|&(n, _)| {
                        from += n;
                        reach(&u[from - n..from], &y[from - n..from])
                    })
                    .fold(0.0, f64::max)
            }
            _ => reach(u, y),
        }
    }

    /// [`Self::fit_linear`] with the fixed columns' [`Projection`] of the same `y`.
    pub fn fit_linear_projected(
        &self,
        theta: &[f64],
        u: &[f64],
        y: &[f64],
        proj: &Projection,
    ) -> LinearFit {
        self.fit_linear_residuals(theta, u, y, proj).0
    }

    /// [`Self::fit_linear_projected`] and its residuals `y - model` (empty where the shape
    /// is unstable or the cost capped): the projected solve's own, at no extra cost.
    pub fn fit_linear_residuals(
        &self,
        theta: &[f64],
        u: &[f64],
        y: &[f64],
        proj: &Projection,
    ) -> (LinearFit, Vec<f64>) {
        let len = u.len().min(y.len());
        let (u, y) = (&u[..len], &y[..len]);
        debug_assert_eq!(proj.y_perp.len(), len);
        let cap = cost_cap(y);
        let (varying, status) = self.varying_columns(theta, u);
        let ncoef = varying.len() + proj.fixed_at.len();
        if let Status::Unstable { at } = status {
            return (LinearFit::unstable(ncoef, cap, at, len), Vec::new());
        }
        let fixed_at = &proj.fixed_at;
        let varying_at = |j: usize| j - fixed_at.iter().filter(|&&f| f < j).count();
        let bounds: Vec<(usize, f64)> = self
            .state_bounds(theta, proj.span)
            .into_iter()
            .map(|(j, b)| (varying_at(j), b))
            .collect();
        let (coef, j, mut e) = proj.solve(varying, &bounds);
        let cost = if j.is_finite() && j < cap {
            j
        } else {
            e.clear();
            cap
        };
        (LinearFit { coef, cost, status }, e)
    }

    /// Model output for input `u` with shape `theta` and linear coefficients `coef` (from
    /// [`Self::fit_linear`] on training data); unstable samples hold the last finite value.
    pub fn simulate(&self, theta: &[f64], coef: &[f64], u: &[f64]) -> (Vec<f64>, Status) {
        let (cols, status) = self.columns(theta, u);
        let mut out: Vec<f64> = (0..u.len())
            .map(|k| cols.iter().zip(coef).map(|(c, b)| c[k] * b).sum())
            .collect();
        if let Status::Unstable { at } = status {
            let last = if at > 0 { out[at - 1] } else { 0.0 };
            out[at..].fill(last);
        }
        (out, status)
    }

    /// Model output on another record `(u, y)`: coefficients `coef` from training, except the
    /// record's own ones ([`Self::record_coefs`]: offset, drift, initial creep states),
    /// refitted by least squares to this record. Returns the output and the coefficients
    /// used.
    pub fn simulate_on(
        &self,
        theta: &[f64],
        coef: &[f64],
        u: &[f64],
        y: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (cols, status) = self.columns(theta, u);
        let nuisance = self.record_coefs();
        let mut c = coef.to_vec();
        let n = u.len().min(y.len());
        if !nuisance.is_empty() && status == Status::Ok {
            let rest: Vec<f64> = (0..n)
                .map(|k| {
                    y[k] - cols
                        .iter()
                        .zip(coef)
                        .enumerate()
                        .filter(|(j, _)| !nuisance.contains(j))
                        .map(|(_, (col, b))| col[k] * b)
                        .sum::<f64>()
                })
                .collect();
            let sub: Vec<Vec<f64>> = nuisance.iter().map(|&j| cols[j][..n].to_vec()).collect();
            let bounds: Vec<(usize, f64)> = self
                .state_bounds(theta, self.state_range(&u[..n], &y[..n]))
                .into_iter()
                .filter_map(|(j, b)| nuisance.iter().position(|&k| k == j).map(|i| (i, b)))
                .collect();
            for (&j, b) in nuisance
                .iter()
                .zip(bounded_least_squares(&sub, &rest, &bounds))
            {
                c[j] = b;
            }
        }
        let mut out: Vec<f64> = (0..u.len())
            .map(|k| cols.iter().zip(&c).map(|(col, b)| col[k] * b).sum())
            .collect();
        if let Status::Unstable { at } = status {
            let last = if at > 0 { out[at - 1] } else { 0.0 };
            out[at..].fill(last);
        }
        (out, c)
    }
}

/// Least squares with some columns fixed across evaluations (the constant, the drift):
/// the data with them projected out once, so an evaluation projects only its
/// shape-dependent columns off them (the same solution as [`crate::base::lstsq::least_squares`] on all
/// columns). The fixed columns are kept raw, each on its support, with the `R` of their QR
/// (`HᵀH = RᵀR`): projecting off a spline's hats then costs a few operations per sample
/// whatever their number, where an orthonormal basis is dense.
#[derive(Clone, Debug)]
pub struct Projection {
    /// Positions of the fixed columns among the coefficients.
    fixed_at: Vec<usize>,
    /// Each fixed column on its support: first sample and the values from there.
    fixed: Vec<(usize, Vec<f64>)>,
    /// Whether each fixed column is independent of the earlier ones (kept).
    kept: Vec<bool>,
    /// `R` of the fixed columns' QR (upper triangle).
    r: Vec<Vec<f64>>,
    /// `y` minus its projection on the fixed columns.
    y_perp: Vec<f64>,
    /// `Hᵀ y`.
    hty: Vec<f64>,
    /// How far the output moved ([`Structure::state_range`]), which bounds the creep
    /// states: once per fit, not per evaluation.
    span: f64,
}

impl Projection {
    /// The projection of `y` off `fixed` (columns of `y`'s length), which sit at
    /// `fixed_at` among the coefficients.
    pub fn new(fixed_at: Vec<usize>, fixed: &[Vec<f64>], y: &[f64]) -> Self {
        let n = y.len();
        let (q, r) = qr(fixed, n);
        let kept = q.iter().map(Option::is_some).collect();
        let fixed = fixed
            .iter()
            .map(|c| {
                let c = &c[..n];
                let lo = c.iter().position(|&x| x != 0.0).unwrap_or(0);
                let hi = c.iter().rposition(|&x| x != 0.0).map_or(lo, |i| i + 1);
                (lo, c[lo..hi].to_vec())
            })
            .collect();
        let mut p = Projection {
            fixed_at,
            fixed,
            kept,
            r,
            y_perp: y.to_vec(),
            hty: Vec::new(),
            span: span(y),
        };
        let mut y_perp = std::mem::take(&mut p.y_perp);
        p.hty = p.project(&mut y_perp);
        p.y_perp = y_perp;
        p
    }

    /// `Hᵀ v`, each fixed column over its support.
    pub(super) fn ht(&self, v: &[f64]) -> Vec<f64> {
        self.fixed.iter().map(|(lo, c)| dot(&v[*lo..], c)).collect()
    }

    /// `(HᵀH)⁻¹ c` over the kept columns (`Rᵀ z = c`, then `R w = z`); dropped ones get 0.
    pub(super) fn gram_solve(&self, c: &[f64]) -> Vec<f64> {
        let m = c.len();
        let mut z = vec![0.0; m];
        for j in 0..m {
            if !self.kept[j] {
                continue;
            }
            let s: f64 = (0..j)
                .filter(|&i| self.kept[i])
                .map(|i| self.r[i][j] * z[i])
                .sum();
            z[j] = (c[j] - s) / self.r[j][j];
        }
        let mut w = vec![0.0; m];
        for j in (0..m).rev() {
            if !self.kept[j] {
                continue;
            }
            let s: f64 = (j + 1..m)
                .filter(|&k| self.kept[k])
                .map(|k| self.r[j][k] * w[k])
                .sum();
            w[j] = (z[j] - s) / self.r[j][j];
        }
        w
    }

    /// `v` minus its projection on the fixed columns (twice: the second pass removes what
    /// round-off left of the first); returns `Hᵀ v` of the `v` given.
    pub(super) fn project(&self, v: &mut [f64]) -> Vec<f64> {
        let first = self.ht(v);
        self.subtract(v, &first);
        let again = self.ht(v);
        self.subtract(v, &again);
        first
    }

    /// `v -= H (HᵀH)⁻¹ c`, each fixed column over its support.
    pub(super) fn subtract(&self, v: &mut [f64], c: &[f64]) {
        let w = self.gram_solve(c);
        for ((lo, col), wi) in self.fixed.iter().zip(&w) {
            if *wi != 0.0 {
                v[*lo..].iter_mut().zip(col).for_each(|(x, a)| *x -= wi * a);
            }
        }
    }

    /// Coefficients (in coefficient order) and `Σ e²/2` for the shape-dependent columns
    /// `varying` (in their order, without the fixed ones).
    /// `bounds`: (index in `varying`, largest magnitude) of bounded coefficients. Also the
    /// residuals: off the fixed columns' span, which the fixed coefficients absorb exactly.
    pub(super) fn solve(
        &self,
        mut varying: Vec<Vec<f64>>,
        bounds: &[(usize, f64)],
    ) -> (Vec<f64>, f64, Vec<f64>) {
        let m = self.fixed.len();
        let n = self.y_perp.len();
        // Hᵀ V, and V with the fixed columns projected out.
        let htv: Vec<Vec<f64>> = varying
            .iter_mut()
            .map(|v| {
                let norm0 = dot(&v[..n], &v[..n]).sqrt();
                let c = self.project(&mut v[..n]);
                // A column inside the fixed span is dependent: drop it, as least squares
                // on all columns would.
                let norm = dot(&v[..n], &v[..n]).sqrt();
                if norm.is_nan() || norm <= 1e-10 * norm0 {
                    v.fill(0.0);
                }
                c
            })
            .collect();
        let bv = gram_least_squares(&varying, &self.y_perp, bounds);
        let mut e = self.y_perp.clone();
        for (v, b) in varying.iter().zip(&bv) {
            if *b != 0.0 {
                e.iter_mut().zip(v).for_each(|(x, c)| *x -= b * c);
            }
        }
        let cost = 0.5 * dot(&e, &e);
        // HᵀH b_f = Hᵀ y - Hᵀ V b_v.
        let rhs: Vec<f64> = (0..m)
            .map(|i| self.hty[i] - htv.iter().zip(&bv).map(|(c, b)| c[i] * b).sum::<f64>())
            .collect();
        let bf = self.gram_solve(&rhs);
        let bf = if bf.iter().all(|x| x.is_finite()) {
            bf
        } else {
            vec![0.0; m]
        };
        let total = bv.len() + m;
        let mut coef = Vec::with_capacity(total);
        let (mut fi, mut vi) = (bf.into_iter(), bv.into_iter());
        for i in 0..total {
            coef.push(if self.fixed_at.contains(&i) {
                fi.next().unwrap_or(0.0)
            } else {
                vi.next().unwrap_or(0.0)
            });
        }
        (coef, cost, e)
    }
}

/// [`span`] of `y`, or the output's least-squares slope on the input times `|u[0]|` where
/// that is more: how far a record's output moved since the actuator rested at 0 V.
pub(super) fn reach(u: &[f64], y: &[f64]) -> f64 {
    let n = u.len().min(y.len());
    let (u, y) = (&u[..n], &y[..n]);
    let here = span(y);
    if n < 2 {
        return here;
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
    let (mu, my) = (mean(u), mean(y));
    let (mut suy, mut suu) = (0.0, 0.0);
    for (a, b) in u.iter().zip(y) {
        suy += (a - mu) * (b - my);
        suu += (a - mu) * (a - mu);
    }
    let before = if suu > 0.0 {
        (suy / suu).abs() * u[0].abs()
    } else {
        0.0
    };
    if before.is_finite() {
        here.max(before)
    } else {
        here
    }
}

/// Max minus min of a record (0 if empty or not finite).
pub(super) fn span(y: &[f64]) -> f64 {
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
    if hi >= lo && (hi - lo).is_finite() {
        hi - lo
    } else {
        0.0
    }
}
