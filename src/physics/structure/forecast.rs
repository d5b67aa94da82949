//! A record predicted rather than fitted. What belongs to one record alone (its sensor
//! offset, its drift, its creep states at the first sample) is not known before the record,
//! so it must be fitted there; but a sample it was fitted on cannot then judge the model.
//! Here it is fitted on the samples before each forecast origin only and the samples from
//! the origin on are predicted (a prequential forecast): a drift is extrapolated from what
//! came before, while what the actuator does after a step (creep) is predicted from the
//! drive by parameters fitted on another record.

use super::columns::spline_hats;
use super::*;
use crate::base::lstsq::{bounded_least_squares, dot};

/// A record forecast from its origins ([`Structure::forecast_on`]).
#[derive(Clone, Debug)]
pub struct Forecast {
    /// The output on every sample: before the first origin the fit of that lead (not a
    /// prediction), from each origin to the next what the samples before it predict.
    pub out: Vec<f64>,
    /// The coefficients of the last fit: the actuator's as given, the record's own fitted
    /// on the samples before the last origin (a spline drift's on knots over those samples).
    pub coef: Vec<f64>,
    /// How many coefficients are fitted on the record's own samples (its own ones).
    pub fitted: usize,
}

impl Structure {
    /// The output on one record `(u, y)` with the actuator's coefficients `coef` carried
    /// and the record's own ([`Self::record_coefs`]) fitted by least squares on `y[..o]`
    /// for each origin `o` of `origins` (ascending, inside the record), predicting the
    /// samples from `o` to the next origin (the last to the record's end). A spline drift is
    /// fitted on knots over `[0, o)` as dense as the record's and held at its last value
    /// (the forecast of a wandering sensor that knows nothing of the drive); a polynomial
    /// drift continues along its tangent at the origin (a curvature fitted on a short past
    /// extrapolates wildly); a settling drift and the creep states' decays continue as
    /// fitted. Samples before the
    /// first origin are the lead's own fit.
    pub fn forecast_on(
        &self,
        theta: &[f64],
        coef: &[f64],
        u: &[f64],
        y: &[f64],
        origins: &[usize],
    ) -> Forecast {
        assert!(self.records.is_none(), "a forecast is of one record");
        let n = u.len().min(y.len());
        let (cols, status) = self.columns(theta, &u[..n]);
        let own = self.record_coefs();
        let spline = self.coefs_where(|c| c.starts_with("drift_k"));
        let quadratic = self.coefs_where(|c| c == "drift_a2").first().copied();
        let actuator: Vec<f64> = (0..n)
            .map(|k| {
                cols.iter()
                    .zip(coef)
                    .enumerate()
                    .filter(|(j, _)| !own.contains(j))
                    .map(|(_, (col, b))| col[k] * b)
                    .sum()
            })
            .collect();
        let mut out = actuator.clone();
        let mut c = coef.to_vec();
        let first = origins.first().copied().unwrap_or(n).clamp(1, n);
        // (fitted on [0, fit_to), output over [from, to)): the lead in sample, then each
        // origin's forecast.
        let mut spans = vec![(first, 0, first)];
        for (i, &o) in origins.iter().enumerate() {
            let to = origins.get(i + 1).copied().unwrap_or(n).min(n);
            if o >= 1 && o < to {
                spans.push((o, o, to));
            }
        }
        for (fit_to, from, to) in spans {
            let m = spline.len();
            let m_here = if m == 0 {
                0
            } else {
                ((m * fit_to) as f64 / n as f64)
                    .round()
                    .clamp(1.0, m as f64) as usize
            };
            let hats = if m == 0 {
                Vec::new()
            } else {
                spline_hats(fit_to, m_here)
            };
            let mut idx = Vec::new();
            let mut sub: Vec<Vec<f64>> = Vec::new();
            for &j in &own {
                match spline.iter().position(|&k| k == j) {
                    Some(s) if s < m_here => {
                        idx.push(j);
                        sub.push(hats[s].clone());
                    }
                    Some(_) => {}
                    None => {
                        idx.push(j);
                        sub.push(cols[j][..fit_to].to_vec());
                    }
                }
            }
            // Only what these samples can tell apart: a column mostly the same as those
            // before it (a slow decay over a short lead is an offset) would get its
            // coefficient from the noise and carry it into the forecast.
            let keep = identifiable(&sub);
            let (idx, sub): (Vec<usize>, Vec<Vec<f64>>) = idx
                .into_iter()
                .zip(sub)
                .zip(&keep)
                .filter(|(_, k)| **k)
                .map(|(x, _)| x)
                .unzip();
            let rest: Vec<f64> = (0..fit_to).map(|k| y[k] - actuator[k]).collect();
            let bounds: Vec<(usize, f64)> = self
                .state_bounds(theta, self.state_range(&u[..fit_to], &y[..fit_to]))
                .into_iter()
                .filter_map(|(j, b)| idx.iter().position(|&k| k == j).map(|i| (i, b)))
                .collect();
            let b = if idx.is_empty() {
                Vec::new()
            } else {
                bounded_least_squares(&sub, &rest, &bounds)
            };
            for &j in &own {
                c[j] = 0.0;
            }
            for (&j, &v) in idx.iter().zip(&b) {
                c[j] = v;
            }
            let is_spline = |j: usize| spline.contains(&j);
            // The spline's value at the last fitted sample, held over the forecast.
            let hold: f64 = idx
                .iter()
                .zip(&b)
                .zip(&sub)
                .filter(|((j, _), _)| is_spline(**j))
                .map(|((_, v), col)| v * col[fit_to - 1])
                .sum();
            for (k, o) in out.iter_mut().enumerate().take(to).skip(from) {
                let mut own_part = 0.0;
                for ((&j, v), col) in idx.iter().zip(&b).zip(&sub) {
                    if quadratic == Some(j) && k >= fit_to && fit_to >= 2 {
                        // The quadratic drift term along its tangent at the last fitted
                        // sample: its curvature, from a short past, is not extrapolated.
                        let (a, slope) = (col[fit_to - 1], col[fit_to - 1] - col[fit_to - 2]);
                        own_part += v * (a + slope * (k + 1 - fit_to) as f64);
                    } else if !is_spline(j) {
                        own_part += v * cols[j][k];
                    } else if k < fit_to {
                        own_part += v * col[k];
                    }
                }
                if from >= fit_to {
                    own_part += hold;
                }
                *o = actuator[k] + own_part;
            }
        }
        if let Status::Unstable { at } = status {
            let last = if at > 0 { out[at - 1] } else { 0.0 };
            out[at..].fill(last);
        }
        Forecast {
            out,
            coef: c,
            fitted: own.len(),
        }
    }
}

/// Share of a column's size that must lie outside the span of the columns before it for
/// its coefficient to be fitted on these samples (a column 99.5 % the same as the others
/// leaves 10 %).
const IDENTIFIABLE: f64 = 0.03;

/// Which of `cols` (in order) the samples can identify ([`IDENTIFIABLE`]), by Gram-Schmidt
/// against the kept ones.
fn identifiable(cols: &[Vec<f64>]) -> Vec<bool> {
    let mut basis: Vec<Vec<f64>> = Vec::new();
    cols.iter()
        .map(|c| {
            let norm0 = dot(c, c).sqrt();
            let mut v = c.clone();
            for q in &basis {
                let a = dot(&v, q);
                v.iter_mut().zip(q).for_each(|(x, qi)| *x -= a * qi);
            }
            let norm = dot(&v, &v).sqrt();
            let keep = norm0 > 0.0 && norm.is_finite() && norm >= IDENTIFIABLE * norm0;
            if keep {
                v.iter_mut().for_each(|x| *x /= norm);
                basis.push(v);
            }
            keep
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::tests::slow_plain_record;
    use super::*;

    /// A model with a ramp drift and an offset, the record's truth.
    fn drifting(form: Form) -> (Structure, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let (u, ctx, plain, theta, _) = slow_plain_record();
        let st = Structure::with_forms(
            &[(Effect::OffsetDrift, form)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        let th = plain.embed(&theta, &st);
        let coef: Vec<f64> = st
            .linear_names()
            .iter()
            .map(|n| match n.as_str() {
                "d_e" => 0.15,
                "alpha" => 0.05,
                _ => 0.0,
            })
            .collect();
        let (y0, _) = st.simulate(&th, &coef, &u);
        (st, th, coef, u, y0)
    }

    #[test]
    fn a_forecast_uses_no_sample_at_or_after_its_origin() {
        let (st, th, coef, u, y0) = drifting(Form::Spline);
        let n = u.len();
        let y: Vec<f64> = y0
            .iter()
            .enumerate()
            .map(|(k, v)| v + 0.01 + 0.02 * (k as f64 / n as f64).sin())
            .collect();
        let origins = [n / 5, 2 * n / 5, 3 * n / 5, 4 * n / 5];
        let base = st.forecast_on(&th, &coef, &u, &y, &origins);
        for (i, &o) in origins.iter().enumerate() {
            // Anything from origin o on changed: every output before the next origin stays.
            let mut z = y.clone();
            z[o..].iter_mut().for_each(|v| *v += 5.0);
            let f = st.forecast_on(&th, &coef, &u, &z, &origins);
            let to = origins.get(i + 1).copied().unwrap_or(n);
            assert_eq!(&f.out[..to], &base.out[..to], "origin {o}");
            if to < n {
                // ... and what comes after was fitted on the change.
                assert_ne!(f.out[to..], base.out[to..]);
            }
        }
    }

    /// The largest |a - b| over the shorter of the two.
    fn largest_gap(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn an_offset_is_carried_and_a_ramp_extrapolated_but_a_spline_only_held() {
        let (u, ..) = slow_plain_record();
        let n = u.len();
        let origins = [n / 5, 2 * n / 5, 3 * n / 5, 4 * n / 5];
        let ramp = |k: usize| 0.03 * k as f64 / n as f64;
        // The record with an offset and the ramp, forecast by a drift of `form`.
        let ramped = |form: Form| {
            let (st, th, coef, u, y0) = drifting(form);
            let y: Vec<f64> = y0
                .iter()
                .enumerate()
                .map(|(k, v)| v + 0.01 + ramp(k))
                .collect();
            (st.forecast_on(&th, &coef, &u, &y, &origins), y)
        };
        // The polynomial drift continues the ramp: the forecast is exact.
        let (f, y) = ramped(Form::Polynomial);
        let worst = largest_gap(&f.out, &y);
        assert!(worst < 1e-9, "{worst}");
        assert_eq!(f.fitted, 3);
        // A spline fitted on the lead holds its last value: it misses the ramp's rise
        // over each block, by up to a block's rise.
        let (f, y) = ramped(Form::Spline);
        let lead = largest_gap(&f.out[..n / 5], &y);
        assert!(lead < 1e-9, "the lead is fitted: {lead}");
        let block = ramp(n / 5);
        for k in [n / 5 + 10, n - 1] {
            let miss = y[k] - f.out[k];
            assert!(
                miss > 0.0 && miss < block * 1.01,
                "{k}: {miss} against {block}"
            );
        }
        // Without drift the offset fitted on the lead is carried.
        let (u, _, plain, theta, y0) = slow_plain_record();
        let y: Vec<f64> = y0.iter().map(|v| v - 0.2).collect();
        let f = plain.forecast_on(&theta, &[0.15, 0.0, 0.05], &u, &y, &origins);
        let worst = largest_gap(&f.out, &y);
        assert!(worst < 1e-9, "{worst}");
    }
}
