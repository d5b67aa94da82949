//! Black-box objectives. An objective knows its domain and how to evaluate points; it knows
//! nothing of optimizers, budgets or files.

pub mod bbob;
pub mod functions;
pub mod hysteresis;
pub mod operator;
pub mod source;

use crate::base::limits::{MAX_DIM, MAX_MAGNITUDE};
use rand::{Rng, RngExt};

/// A box-shaped search domain: `lower[i] <= x[i] <= upper[i]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Bounds {
    lower: Vec<f64>,
    upper: Vec<f64>,
}

impl Bounds {
    /// Checked constructor: same length, at least one dimension, finite, lower < upper.
    pub fn new(lower: Vec<f64>, upper: Vec<f64>) -> Result<Self, String> {
        if lower.len() != upper.len() {
            return Err(format!(
                "lower has {} entries but upper has {}",
                lower.len(),
                upper.len()
            ));
        }
        if lower.is_empty() {
            return Err("dimension must be at least 1".into());
        }
        if lower.len() > MAX_DIM {
            return Err(format!(
                "dimension {} is above the limit of {MAX_DIM} (derived from memory)",
                lower.len()
            ));
        }
        for (i, (&l, &u)) in lower.iter().zip(&upper).enumerate() {
            if !l.is_finite() || !u.is_finite() {
                return Err(format!("bound {i} is not finite ({l}, {u})"));
            }
            if l.abs().max(u.abs()) > MAX_MAGNITUDE {
                return Err(format!(
                    "bound {i} ({l}, {u}) is beyond ±{MAX_MAGNITUDE:e}, where costs would overflow"
                ));
            }
            if l >= u {
                return Err(format!(
                    "lower bound {l} is not below upper bound {u} (dimension {i})"
                ));
            }
        }
        Ok(Bounds { lower, upper })
    }

    /// The same interval `[lo, hi]` in every one of `dim` dimensions.
    pub fn uniform(dim: usize, lo: f64, hi: f64) -> Result<Self, String> {
        if dim > MAX_DIM {
            return Err(format!(
                "dimension {dim} is above the limit of {MAX_DIM} (derived from memory)"
            ));
        }
        Self::new(vec![lo; dim], vec![hi; dim])
    }

    pub fn dim(&self) -> usize {
        self.lower.len()
    }

    pub fn lower(&self) -> &[f64] {
        &self.lower
    }

    pub fn upper(&self) -> &[f64] {
        &self.upper
    }

    /// Width of the domain in dimension `i`.
    pub fn width(&self, i: usize) -> f64 {
        self.upper[i] - self.lower[i]
    }

    /// Whether every coordinate of `x` lies inside the box.
    pub fn contains(&self, x: &[f64]) -> bool {
        x.len() == self.dim()
            && x.iter()
                .zip(self.lower.iter().zip(&self.upper))
                .all(|(v, (l, u))| *l <= *v && *v <= *u)
    }

    /// Projects `x` onto the box coordinate by coordinate.
    pub fn clamp(&self, x: &mut [f64]) {
        for (v, (l, u)) in x.iter_mut().zip(self.lower.iter().zip(&self.upper)) {
            *v = v.clamp(*l, *u);
        }
    }

    /// Fills `x` with a point drawn uniformly from the box.
    pub fn sample(&self, rng: &mut impl Rng, x: &mut [f64]) {
        for (i, v) in x.iter_mut().enumerate() {
            *v = self.sample_coord(rng, i);
        }
    }

    /// A uniform draw of coordinate `i`.
    pub fn sample_coord(&self, rng: &mut impl Rng, i: usize) -> f64 {
        let u: f64 = rng.random();
        // lower + u*width can round up to exactly `upper` but never beyond it.
        (self.lower[i] + u * self.width(i)).min(self.upper[i])
    }

    /// Checks that row-major `points` are whole points of this box's dimension with finite
    /// coordinates (callers outside the harness, e.g. Python, hand in arbitrary arrays);
    /// returns how many. Points outside the box are allowed: every objective is defined
    /// there, as in COCO, and an optimizer that leaves the box pays what it finds.
    pub fn check_points(&self, points: &[f64]) -> Result<usize, String> {
        let d = self.dim();
        if !points.len().is_multiple_of(d) {
            return Err(format!(
                "{} coordinates are not a whole number of points of dimension {d}; expected {d} per point",
                points.len()
            ));
        }
        if let Some(i) = points.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "coordinate {} of point {} is {}: expected finite numbers",
                i % d,
                i / d,
                points[i]
            ));
        }
        Ok(points.len() / d)
    }
}

/// A black-box function to minimise over a box.
///
/// Points are slices of length [`Objective::dim`]. Batches are flat row-major matrices
/// (`n * dim` values) so that an objective can evaluate a whole population at once, for
/// example with SIMD over individuals.
pub trait Objective: Send + Sync {
    /// Short name of the function family, e.g. `griewank`.
    fn name(&self) -> &str;

    /// The search domain.
    fn bounds(&self) -> &Bounds;

    /// Number of decision variables.
    fn dim(&self) -> usize {
        self.bounds().dim()
    }

    /// Value at one point. May return NaN or infinity; the harness treats both as +inf.
    fn evaluate(&self, x: &[f64]) -> f64;

    /// Values of `out.len()` points stored row-major in `points`.
    fn evaluate_batch(&self, points: &[f64], out: &mut [f64]) {
        let d = self.dim();
        debug_assert_eq!(points.len(), out.len() * d);
        for (p, o) in points.chunks_exact(d).zip(out.iter_mut()) {
            *o = self.evaluate(p);
        }
    }

    /// Values at or above this are penalties for unusable parameters (an unstable model),
    /// not measurements of fit; the evaluator counts them so reports can say how many
    /// evaluations were penalised. `None`: the objective never penalises.
    fn penalty_threshold(&self) -> Option<f64> {
        None
    }

    /// The global minimum value inside [`Objective::bounds`], where it is known, so results
    /// can report the error to the optimum.
    fn optimum(&self) -> Option<f64> {
        None
    }

    /// Value and gradient at `x`, for objectives that have one (gradient-based baselines
    /// such as back-propagation); `None` where the objective is a pure black box. The harness
    /// charges a call `1 + d` evaluations (the value and the forward differences the gradient
    /// is worth), so an implementation may cost up to that many value passes; each says
    /// what it computes.
    fn value_and_gradient(&self, _x: &[f64], _grad: &mut [f64]) -> Option<f64> {
        None
    }

    /// Cost `½ Σ rᵢ²` with the residuals `r` behind it, for least-squares objectives (a
    /// model fitted to a recording), so a Gauss-Newton method can build a Jacobian. `None`
    /// where the objective is not a sum of squares; where it penalises `x` the cost is the
    /// penalty and `r` is left empty.
    fn residuals(&self, _x: &[f64], _r: &mut Vec<f64>) -> Option<f64> {
        None
    }

    /// [`Objective::residuals`] of row-major `points`, one `(cost, residuals)` per point.
    fn residuals_batch(&self, points: &[f64]) -> Option<Vec<(f64, Vec<f64>)>> {
        points
            .chunks_exact(self.dim())
            .map(|p| {
                let mut r = Vec::new();
                self.residuals(p, &mut r).map(|c| (c, r))
            })
            .collect()
    }

    /// Whether [`Objective::value_and_gradient`] is implemented.
    fn has_gradient(&self) -> bool {
        false
    }

    /// How reports should present a value of this objective (e.g. a fitting cost as an RMSE
    /// in the recording's units); `None` shows values as they are.
    fn presentation(&self) -> Option<Presentation> {
        None
    }

    /// Numbers a reader wants about a final point beyond its value (e.g. a fitted model's
    /// free-run RMSE on validation data); the report evaluates them once per trial.
    fn metrics(&self, _x: &[f64]) -> Vec<Metric> {
        Vec::new()
    }

    /// Its identity in a published benchmark suite (COCO's `bbob`), so that exports name it
    /// as that suite's tools (cocopp, IOHanalyzer) expect; `None` for objectives of our own.
    fn suite_id(&self) -> Option<SuiteId> {
        None
    }

    /// The fitting view of objectives that fit a model to a recording (for `optbench fit`
    /// plots and parameter tables); `None` for other objectives.
    fn as_fit(&self) -> Option<&dyn hysteresis::FitView> {
        None
    }
}

/// A member of a published benchmark suite: `function` and `instance` as the suite numbers
/// them (COCO's `bbob`: functions 1-24, instances from 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SuiteId {
    pub suite: &'static str,
    pub function: usize,
    pub instance: usize,
}

/// A named number about a point (see [`Objective::metrics`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Metric {
    pub name: String,
    pub value: f64,
}

impl Metric {
    pub fn new(name: impl Into<String>, value: f64) -> Self {
        Metric {
            name: name.into(),
            value,
        }
    }
}

/// A monotone map from objective values to the number a reader wants to see.
#[derive(Debug, Clone, PartialEq)]
pub struct Presentation {
    /// Column label, e.g. `RMSE [mm]`.
    pub label: String,
    pub kind: PresentationKind,
}

/// The supported maps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PresentationKind {
    /// The value is J = sum(e^2)/2 over `samples` residuals in units of `scale`: show
    /// `scale * sqrt(2 J / samples)`.
    RmseFromHalfSse { samples: usize, scale: f64 },
}

impl Presentation {
    /// The presented number for objective value `f`.
    pub fn apply(&self, f: f64) -> f64 {
        match self.kind {
            PresentationKind::RmseFromHalfSse { samples, scale } => {
                scale * (2.0 * f.max(0.0) / samples as f64).sqrt()
            }
        }
    }

    /// The objective value whose presentation is `shown` (the map is increasing).
    pub fn invert(&self, shown: f64) -> f64 {
        match self.kind {
            PresentationKind::RmseFromHalfSse { samples, scale } => {
                let r = shown / scale;
                0.5 * samples as f64 * r * r
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_are_checked_for_shape_and_finiteness_not_for_the_box() {
        let b = Bounds::uniform(2, -1.0, 1.0).unwrap();
        assert_eq!(b.check_points(&[0.0, 0.5, 7.0, -9.0]), Ok(2));
        assert_eq!(b.check_points(&[]), Ok(0));
        let e = b.check_points(&[0.0, 0.5, 1.0]).unwrap_err();
        assert!(
            e.contains("3 coordinates") && e.contains("dimension 2"),
            "{e}"
        );
        let e = b.check_points(&[0.0, 0.5, 1.0, f64::NAN]).unwrap_err();
        assert_eq!(e, "coordinate 1 of point 1 is NaN: expected finite numbers");
    }
}
