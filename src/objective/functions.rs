//! Standard test functions in any dimension, and [`ExpDecay`], a small least-squares fit.
//!
//! Griewank and Schwefel follow the dissertation (eq. 2.12, 2.13); the dissertation's Schwefel has no
//! `418.9829 * d` offset, so its minimum is [`SCHWEFEL_MIN_PER_DIM`] per dimension.

use super::{Bounds, Objective};
use std::f64::consts::{E, PI};

/// Location of the Schwefel minimum in each coordinate (root of sin(√x) + √x/2·cos(√x) = 0,
/// computed to 30 digits with mpmath).
pub const SCHWEFEL_ARGMIN: f64 = 420.968_746_359_982_03;
/// Schwefel minimum value per dimension, −x*·sin(√x*) at [`SCHWEFEL_ARGMIN`].
pub const SCHWEFEL_MIN_PER_DIM: f64 = -418.982_887_272_433_7;

/// The functions optbench knows, with their customary domains.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TestFunction {
    Sphere,
    Griewank,
    Schwefel,
    Rastrigin,
    Rosenbrock,
    Ackley,
}

impl TestFunction {
    pub const ALL: [TestFunction; 6] = [
        TestFunction::Sphere,
        TestFunction::Griewank,
        TestFunction::Schwefel,
        TestFunction::Rastrigin,
        TestFunction::Rosenbrock,
        TestFunction::Ackley,
    ];

    pub fn name(self) -> &'static str {
        match self {
            TestFunction::Sphere => "sphere",
            TestFunction::Griewank => "griewank",
            TestFunction::Schwefel => "schwefel",
            TestFunction::Rastrigin => "rastrigin",
            TestFunction::Rosenbrock => "rosenbrock",
            TestFunction::Ackley => "ackley",
        }
    }

    /// One line of documentation for `optbench list`.
    pub fn describe(self) -> &'static str {
        match self {
            TestFunction::Sphere => "sum x_i^2; unimodal, minimum 0 at 0",
            TestFunction::Griewank => {
                "1 + sum x_i^2/4000 - prod cos(x_i/sqrt(i)) (dissertation eq. 2.12); minimum 0 at 0"
            }
            TestFunction::Schwefel => {
                "-sum x_i sin(sqrt|x_i|) (dissertation eq. 2.13, no offset); minimum -418.9829*dim at x_i = 420.9687"
            }
            TestFunction::Rastrigin => "10 d + sum (x_i^2 - 10 cos 2 pi x_i); minimum 0 at 0",
            TestFunction::Rosenbrock => {
                "sum 100 (x_{i+1} - x_i^2)^2 + (1 - x_i)^2; minimum 0 at (1, ..., 1); dim >= 2"
            }
            TestFunction::Ackley => {
                "-20 exp(-0.2 sqrt(mean x^2)) - exp(mean cos 2 pi x) + 20 + e; minimum 0 at 0"
            }
        }
    }

    /// The customary search interval, used in every dimension unless the suite overrides it.
    pub fn default_domain(self) -> (f64, f64) {
        match self {
            TestFunction::Sphere | TestFunction::Rastrigin => (-5.12, 5.12),
            TestFunction::Griewank => (-600.0, 600.0),
            TestFunction::Schwefel => (-500.0, 500.0),
            TestFunction::Rosenbrock => (-5.0, 10.0),
            TestFunction::Ackley => (-32.768, 32.768),
        }
    }

    /// Smallest dimension for which the function is defined.
    pub fn min_dim(self) -> usize {
        match self {
            TestFunction::Rosenbrock => 2,
            _ => 1,
        }
    }

    /// Coordinate of the global minimiser (the same in every dimension) and the minimum value.
    fn argmin_and_min(self, dim: usize) -> (f64, f64) {
        match self {
            TestFunction::Schwefel => (SCHWEFEL_ARGMIN, SCHWEFEL_MIN_PER_DIM * dim as f64),
            TestFunction::Rosenbrock => (1.0, 0.0),
            _ => (0.0, 0.0),
        }
    }

    /// Value at `x` and its gradient into `g` (same length as `x`).
    pub fn value_and_gradient(self, x: &[f64], g: &mut [f64]) -> f64 {
        let n = x.len();
        match self {
            TestFunction::Sphere => {
                for (gi, xi) in g.iter_mut().zip(x) {
                    *gi = 2.0 * xi;
                }
            }
            TestFunction::Griewank => {
                // Product of the cosines without factor j, from prefix and suffix products.
                let c: Vec<f64> = (0..n)
                    .map(|i| (x[i] / ((i + 1) as f64).sqrt()).cos())
                    .collect();
                let mut prefix = 1.0;
                let mut suffix = vec![1.0; n + 1];
                for i in (0..n).rev() {
                    suffix[i] = suffix[i + 1] * c[i];
                }
                for j in 0..n {
                    let sj = ((j + 1) as f64).sqrt();
                    g[j] = x[j] / 2000.0 + (x[j] / sj).sin() / sj * prefix * suffix[j + 1];
                    prefix *= c[j];
                }
            }
            TestFunction::Schwefel => {
                for (gi, &xi) in g.iter_mut().zip(x) {
                    let r = xi.abs().sqrt();
                    *gi = -(r.sin() + 0.5 * r * r.cos());
                }
            }
            TestFunction::Rastrigin => {
                for (gi, &xi) in g.iter_mut().zip(x) {
                    *gi = 2.0 * xi + 20.0 * PI * (2.0 * PI * xi).sin();
                }
            }
            TestFunction::Rosenbrock => {
                g.fill(0.0);
                for i in 0..n - 1 {
                    let a = x[i + 1] - x[i] * x[i];
                    g[i] += -400.0 * x[i] * a - 2.0 * (1.0 - x[i]);
                    g[i + 1] += 200.0 * a;
                }
            }
            TestFunction::Ackley => {
                let nf = n as f64;
                let r = (x.iter().map(|v| v * v).sum::<f64>() / nf).sqrt();
                let ec = (x.iter().map(|v| (2.0 * PI * v).cos()).sum::<f64>() / nf).exp();
                let er = (-0.2 * r).exp();
                for (gi, &xi) in g.iter_mut().zip(x) {
                    let radial = if r > 0.0 {
                        4.0 * er * xi / (nf * r)
                    } else {
                        0.0
                    };
                    *gi = radial + 2.0 * PI / nf * ec * (2.0 * PI * xi).sin();
                }
            }
        }
        self.value(x)
    }

    /// Value at `x` (any length >= [`TestFunction::min_dim`]).
    pub fn value(self, x: &[f64]) -> f64 {
        match self {
            TestFunction::Sphere => x.iter().map(|v| v * v).sum(),
            TestFunction::Griewank => {
                let mut sum = 0.0;
                let mut prod = 1.0;
                for (i, &v) in x.iter().enumerate() {
                    sum += v * v;
                    prod *= (v / ((i + 1) as f64).sqrt()).cos();
                }
                1.0 + sum / 4000.0 - prod
            }
            TestFunction::Schwefel => -x.iter().map(|&v| v * v.abs().sqrt().sin()).sum::<f64>(),
            TestFunction::Rastrigin => {
                10.0 * x.len() as f64
                    + x.iter()
                        .map(|&v| v * v - 10.0 * (2.0 * PI * v).cos())
                        .sum::<f64>()
            }
            TestFunction::Rosenbrock => x
                .windows(2)
                .map(|w| {
                    let a = w[1] - w[0] * w[0];
                    let b = 1.0 - w[0];
                    100.0 * a * a + b * b
                })
                .sum(),
            TestFunction::Ackley => {
                let n = x.len() as f64;
                let sq = x.iter().map(|v| v * v).sum::<f64>() / n;
                let cs = x.iter().map(|v| (2.0 * PI * v).cos()).sum::<f64>() / n;
                -20.0 * (-0.2 * sq.sqrt()).exp() - cs.exp() + 20.0 + E
            }
        }
    }
}

/// A [`TestFunction`] over a box.
#[derive(Debug, Clone)]
pub struct Function {
    kind: TestFunction,
    bounds: Bounds,
    optimum: Option<f64>,
}

impl Function {
    /// The function over `bounds`; fails when the dimension is too small for it.
    pub fn new(kind: TestFunction, bounds: Bounds) -> Result<Self, String> {
        if bounds.dim() < kind.min_dim() {
            return Err(format!(
                "{} needs dimension >= {}, got {}",
                kind.name(),
                kind.min_dim(),
                bounds.dim()
            ));
        }
        let (a, fmin) = kind.argmin_and_min(bounds.dim());
        // The known minimum only counts when the minimiser lies inside the box.
        let optimum = bounds.contains(&vec![a; bounds.dim()]).then_some(fmin);
        Ok(Function {
            kind,
            bounds,
            optimum,
        })
    }

    /// The function over its customary domain in `dim` dimensions.
    pub fn standard(kind: TestFunction, dim: usize) -> Result<Self, String> {
        let (lo, hi) = kind.default_domain();
        Self::new(kind, Bounds::uniform(dim, lo, hi)?)
    }

    pub fn kind(&self) -> TestFunction {
        self.kind
    }
}

impl Objective for Function {
    fn name(&self) -> &str {
        self.kind.name()
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, x: &[f64]) -> f64 {
        self.kind.value(x)
    }

    fn optimum(&self) -> Option<f64> {
        self.optimum
    }

    /// The closed-form gradient, then the value: about two value passes of work, charged
    /// `1 + d` all the same.
    fn value_and_gradient(&self, x: &[f64], grad: &mut [f64]) -> Option<f64> {
        Some(self.kind.value_and_gradient(x, grad))
    }

    fn has_gradient(&self) -> bool {
        true
    }
}

/// `y = a e^(-b t) + c` sampled at 200 points on `[0, 4]`, fitted in `(a, b, c)`: a small
/// nonlinear least-squares problem with residuals and an analytic gradient, so that tests
/// can drive every kind of evaluation (values, gradients, residual vectors) through one
/// objective.
pub struct ExpDecay {
    t: Vec<f64>,
    y: Vec<f64>,
    bounds: Bounds,
}

impl ExpDecay {
    /// The curve of parameters `truth`, fitted over `bounds` (three dimensions).
    pub fn new(truth: [f64; 3], bounds: Bounds) -> Self {
        assert_eq!(bounds.dim(), 3, "a, b and c");
        let t: Vec<f64> = (0..200).map(|k| f64::from(k) * 0.02).collect();
        let y = t
            .iter()
            .map(|t| truth[0] * (-truth[1] * t).exp() + truth[2])
            .collect();
        ExpDecay { t, y, bounds }
    }

    fn residual_vector(&self, x: &[f64]) -> Vec<f64> {
        self.t
            .iter()
            .zip(&self.y)
            .map(|(t, y)| y - (x[0] * (-x[1] * t).exp() + x[2]))
            .collect()
    }
}

/// `J = ½ Σ r²`, the cost of a residual vector.
fn half_square(r: &[f64]) -> f64 {
    0.5 * r.iter().map(|v| v * v).sum::<f64>()
}

impl Objective for ExpDecay {
    fn name(&self) -> &str {
        "exp-decay"
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, x: &[f64]) -> f64 {
        half_square(&self.residual_vector(x))
    }

    /// One pass over the samples (charged `1 + d` all the same).
    fn value_and_gradient(&self, x: &[f64], g: &mut [f64]) -> Option<f64> {
        let r = self.residual_vector(x);
        g.fill(0.0);
        for (ri, t) in r.iter().zip(&self.t) {
            let e = (-x[1] * t).exp();
            g[0] -= ri * e;
            g[1] += ri * x[0] * t * e;
            g[2] -= ri;
        }
        Some(half_square(&r))
    }

    fn has_gradient(&self) -> bool {
        true
    }

    fn residuals(&self, x: &[f64], r: &mut Vec<f64>) -> Option<f64> {
        *r = self.residual_vector(x);
        Some(half_square(r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f(kind: TestFunction, x: &[f64]) -> f64 {
        Function::standard(kind, x.len()).unwrap().evaluate(x)
    }

    #[test]
    fn minima_are_where_documented() {
        for kind in TestFunction::ALL {
            for dim in [2, 5, 30] {
                let obj = Function::standard(kind, dim).unwrap();
                let (a, fmin) = kind.argmin_and_min(dim);
                let v = obj.evaluate(&vec![a; dim]);
                assert!(
                    (v - fmin).abs() < 1e-9 * (1.0 + fmin.abs()),
                    "{kind:?} d={dim}: {v}"
                );
                assert_eq!(obj.optimum(), Some(fmin));
            }
        }
    }

    #[test]
    fn known_values_off_the_optimum() {
        // Hand-computed: Griewank(pi, 0) = 1 + pi^2/4000 - cos(pi) = 2 + pi^2/4000.
        let g = f(TestFunction::Griewank, &[PI, 0.0]);
        assert!((g - (2.0 + PI * PI / 4000.0)).abs() < 1e-15);
        // Griewank's second coordinate is scaled by 1/sqrt(2) (dissertation eq. 2.12).
        let y = 2f64.sqrt() * PI;
        let g2 = f(TestFunction::Griewank, &[0.0, y]);
        assert!((g2 - (2.0 + y * y / 4000.0)).abs() < 1e-15);
        // Rastrigin at 0.5 in each of 2 dims: 20 + 2 * (0.25 + 10) = 40.5.
        assert!((f(TestFunction::Rastrigin, &[0.5, 0.5]) - 40.5).abs() < 1e-12);
        // Rosenbrock(0, 0) = 1; (-1, 1) = 4.
        assert_eq!(f(TestFunction::Rosenbrock, &[0.0, 0.0]), 1.0);
        assert_eq!(f(TestFunction::Rosenbrock, &[-1.0, 1.0]), 4.0);
        // Schwefel(1, 1) = -2 sin(1).
        assert!((f(TestFunction::Schwefel, &[1.0, 1.0]) + 2.0 * 1f64.sin()).abs() < 1e-15);
        // Schwefel is defined for negative coordinates through |x|.
        let s = f(TestFunction::Schwefel, &[-4.0, 0.0]);
        assert!((s - 4.0 * 2f64.sin()).abs() < 1e-14);
        // Ackley at 1 in every dimension: 20 + e - 20 exp(-0.2) - e^1.
        let a = f(TestFunction::Ackley, &[1.0; 3]);
        assert!((a - (20.0 - 20.0 * (-0.2f64).exp())).abs() < 1e-12);
        assert_eq!(f(TestFunction::Sphere, &[3.0, 4.0]), 25.0);
    }

    #[test]
    fn schwefel_seed_table_value() {
        // The dissertation's Table 2.4 MSGA row: (420.9711, 420.9487) -> -837.9657.
        let v = f(TestFunction::Schwefel, &[420.9711, 420.9487]);
        assert!((v - -837.9657).abs() < 1e-4, "{v}");
    }

    #[test]
    fn optimum_outside_the_box_is_unknown() {
        let b = Bounds::uniform(2, -100.0, 100.0).unwrap();
        let s = Function::new(TestFunction::Schwefel, b).unwrap();
        assert_eq!(s.optimum(), None);
    }

    #[test]
    fn batch_matches_single_points() {
        let obj = Function::standard(TestFunction::Ackley, 3).unwrap();
        let pts = [0.1, -2.0, 3.0, 4.5, 0.0, -1.0];
        let mut out = [0.0; 2];
        obj.evaluate_batch(&pts, &mut out);
        assert_eq!(out[0], obj.evaluate(&pts[..3]));
        assert_eq!(out[1], obj.evaluate(&pts[3..]));
    }

    #[test]
    fn gradients_match_finite_differences() {
        let mut rng = crate::base::TrialSeed::from_u64(4).rng(0);
        let mut objectives: Vec<Box<dyn Objective>> = TestFunction::ALL
            .iter()
            .map(|&k| Box::new(Function::standard(k, 5).unwrap()) as Box<dyn Objective>)
            .collect();
        let box3 = Bounds::new(vec![0.0, 0.01, -5.0], vec![10.0, 10.0, 5.0]).unwrap();
        objectives.push(Box::new(ExpDecay::new([2.0, 1.3, 0.4], box3)));
        for f in &objectives {
            let (kind, d) = (f.name(), f.dim());
            for _ in 0..20 {
                let mut x = vec![0.0; d];
                f.bounds().sample(&mut rng, &mut x);
                let mut g = vec![0.0; d];
                let v = f.value_and_gradient(&x, &mut g).unwrap();
                assert_eq!(v, f.evaluate(&x));
                let mut r = Vec::new();
                assert_eq!(f.residuals(&x, &mut r).unwrap_or(v), v);
                for j in 0..d {
                    let h = 1e-6 * (1.0 + x[j].abs());
                    let (mut a, mut b) = (x.clone(), x.clone());
                    a[j] += h;
                    b[j] -= h;
                    let fd = (f.evaluate(&a) - f.evaluate(&b)) / (2.0 * h);
                    let tol = 1e-5 * (1.0 + fd.abs().max(g[j].abs()));
                    assert!((fd - g[j]).abs() < tol, "{kind} d{j}: fd {fd} vs {}", g[j]);
                }
            }
        }
    }

    #[test]
    fn rosenbrock_needs_two_dimensions() {
        assert!(Function::standard(TestFunction::Rosenbrock, 1).is_err());
    }
}
