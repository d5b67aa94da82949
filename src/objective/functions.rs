//! Standard test functions in any dimension, and [`ExpDecay`], a small least-squares fit.
//!
//! Griewank and Schwefel follow the dissertation (eq. 2.12, 2.13); the dissertation's Schwefel has no
//! `418.9829 * d` offset, so its minimum is [`SCHWEFEL_MIN_PER_DIM`] per dimension.
//!
//! [`Instance`] moves a function's minimiser away from where its formula puts it (Griewank's
//! at the centre of the box, where arithmetic crossover pulls) and rotates it, as BBOB's
//! instances do, so a comparison cannot be won by a bias toward the centre or the axes.

use super::{Bounds, Objective};
use crate::base::seed::{TrialSeed, standard_normal};
use rand::RngExt;
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

/// Which problem of a function's family to build: instance `number` (from 1) moved and/or
/// rotated. The draws depend on (function, dimension, number) only, so instance N is the same
/// problem in every suite that uses the same box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Instance {
    pub number: u64,
    /// Moves the minimiser to a point drawn uniformly from the central [`SHIFT_SPAN`] of the
    /// box in every coordinate (at least a tenth of the width from each face).
    pub shift: bool,
    /// Rotates the function about its minimiser by a random orthogonal matrix (Haar).
    pub rotate: bool,
}

impl Instance {
    /// The function as its formula defines it.
    pub const PLAIN: Instance = Instance {
        number: 1,
        shift: false,
        rotate: false,
    };
}

/// Fraction of each interval, about its middle, in which a shifted minimiser is drawn.
pub const SHIFT_SPAN: f64 = 0.8;

/// Largest dimension a rotation is built for: its matrix has `d²` entries and Gram-Schmidt
/// costs `d³` (500: 2 MB, well under a second).
pub const MAX_ROTATED_DIM: usize = 500;

/// `z = R (x − c) + a`: the point of the formula's domain a point `x` of the box stands for;
/// `c` is the instance's minimiser and `a` the formula's.
#[derive(Debug, Clone)]
struct Transform {
    centre: Vec<f64>,
    /// Row-major `d × d` orthogonal matrix, or none (identity).
    rotation: Option<Vec<f64>>,
    anchor: f64,
    /// Schwefel only: `z` is wrapped into the customary domain `[lo, lo + period)`, so the
    /// formula is never read outside it, where it has lower values than its minimum inside.
    wrap: Option<(f64, f64)>,
}

impl Transform {
    fn apply(&self, x: &[f64]) -> Vec<f64> {
        let d: Vec<f64> = x.iter().zip(&self.centre).map(|(x, c)| x - c).collect();
        let mut z = match &self.rotation {
            None => d,
            Some(r) => r.chunks_exact(x.len()).map(|row| dot(row, &d)).collect(),
        };
        for v in &mut z {
            *v += self.anchor;
            if let Some((lo, period)) = self.wrap {
                *v -= period * ((*v - lo) / period).floor();
            }
        }
        z
    }

    /// `Rᵀ g`: the gradient in `x` from the gradient in `z` (the wrap's slope is 1).
    fn pull_back(&self, gz: &[f64], g: &mut [f64]) {
        match &self.rotation {
            None => g.copy_from_slice(gz),
            Some(r) => {
                g.fill(0.0);
                for (row, gzi) in r.chunks_exact(gz.len()).zip(gz) {
                    for (gj, rij) in g.iter_mut().zip(row) {
                        *gj += rij * gzi;
                    }
                }
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// The random stream of instance `number` of `kind` in `dim` dimensions: stream 1 draws the
/// shift, stream 2 the rotation, so an instance's shift is the same with or without rotation.
fn instance_seed(kind: TestFunction, dim: usize, number: u64) -> TrialSeed {
    TrialSeed::derive(number, kind.name(), "instance", dim as u64)
}

/// A `d × d` orthogonal matrix drawn uniformly (Haar): Gaussian rows orthonormalised by
/// Gram-Schmidt, twice, so that `R Rᵀ = I` to rounding.
fn random_rotation(rng: &mut impl rand::Rng, d: usize) -> Vec<f64> {
    let mut r: Vec<f64> = (0..d * d).map(|_| standard_normal(rng)).collect();
    for i in 0..d {
        for _pass in 0..2 {
            for j in 0..i {
                let (done, rest) = r.split_at_mut(i * d);
                let (bj, bi) = (&done[j * d..(j + 1) * d], &mut rest[..d]);
                let p = dot(bi, bj);
                for (v, w) in bi.iter_mut().zip(bj) {
                    *v -= p * w;
                }
            }
        }
        let row = &mut r[i * d..(i + 1) * d];
        let n = dot(row, row).sqrt();
        row.iter_mut().for_each(|v| *v /= n);
    }
    r
}

/// A [`TestFunction`] over a box, as its formula defines it or as an [`Instance`].
#[derive(Debug, Clone)]
pub struct Function {
    kind: TestFunction,
    bounds: Bounds,
    optimum: Option<f64>,
    argmin: Option<Vec<f64>>,
    transform: Option<Transform>,
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
        // The known minimum only counts when the minimiser lies inside the box, and for
        // Schwefel when the box lies inside [-500, 500]: beyond, its formula goes lower.
        let (lo, hi) = kind.default_domain();
        let within = (0..bounds.dim()).all(|i| bounds.lower()[i] >= lo && bounds.upper()[i] <= hi);
        let argmin = Some(vec![a; bounds.dim()])
            .filter(|x| bounds.contains(x) && (kind != TestFunction::Schwefel || within));
        Ok(Function {
            kind,
            optimum: argmin.as_ref().map(|_| fmin),
            argmin,
            bounds,
            transform: None,
        })
    }

    /// The function as instance `inst`.
    ///
    /// The formula is read at `z = R (x − c) + a` (`c` the instance's minimiser, `a` the
    /// formula's), so the minimum value stays the formula's and sits at `c`. Every kind but
    /// Schwefel has its minimum only at `a` on the whole real space, so that is exact.
    /// Schwefel's formula has lower values outside [-500, 500]: there `z` is wrapped into
    /// that interval (period 1000), so the minimum over the box is still `−418.98·d`, at `c`
    /// (and wherever else `z` wraps onto `a`). On the customary box a shift then translates
    /// the landscape cyclically, leaving one seam per coordinate where the formula's two
    /// ends (`±180.8`) meet.
    pub fn with_instance(mut self, inst: Instance) -> Result<Self, String> {
        let kind = self.kind;
        if inst.number == 0 {
            return Err("instance numbers start at 1".into());
        }
        if !inst.shift && !inst.rotate {
            if inst.number != 1 {
                return Err(format!(
                    "instance {} of {} without shift or rotate is the same problem as instance 1; \
                     set shift = \"random\" or rotate = true to draw instances",
                    inst.number,
                    kind.name()
                ));
            }
            return Ok(self);
        }
        let d = self.bounds.dim();
        if inst.rotate && d > MAX_ROTATED_DIM {
            return Err(format!(
                "rotate = true needs dimension <= {MAX_ROTATED_DIM} (a d x d matrix), got {d}"
            ));
        }
        let seed = instance_seed(kind, d, inst.number);
        let (a, fmin) = kind.argmin_and_min(d);
        let centre = if inst.shift {
            let mut rng = seed.rng(1);
            let b = &self.bounds;
            (0..d)
                .map(|i| {
                    let u: f64 = rng.random();
                    b.lower()[i] + b.width(i) * (0.5 * (1.0 - SHIFT_SPAN) + SHIFT_SPAN * u)
                })
                .collect()
        } else {
            vec![a; d]
        };
        let rotation = inst.rotate.then(|| random_rotation(&mut seed.rng(2), d));
        let wrap = (kind == TestFunction::Schwefel).then(|| {
            let (lo, hi) = kind.default_domain();
            (lo, hi - lo)
        });
        self.argmin = Some(centre.clone()).filter(|c| self.bounds.contains(c));
        self.optimum = self.argmin.as_ref().map(|_| fmin);
        self.transform = Some(Transform {
            centre,
            rotation,
            anchor: a,
            wrap,
        });
        Ok(self)
    }

    /// The function over its customary domain in `dim` dimensions.
    pub fn standard(kind: TestFunction, dim: usize) -> Result<Self, String> {
        let (lo, hi) = kind.default_domain();
        Self::new(kind, Bounds::uniform(dim, lo, hi)?)
    }

    pub fn kind(&self) -> TestFunction {
        self.kind
    }

    /// A point of the box where [`Objective::optimum`] is attained, where that is known.
    pub fn argmin(&self) -> Option<&[f64]> {
        self.argmin.as_deref()
    }

    /// The instance's rotation, row-major `d × d`; `None` when it is not rotated.
    pub fn rotation(&self) -> Option<&[f64]> {
        self.transform.as_ref()?.rotation.as_deref()
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
        match &self.transform {
            None => self.kind.value(x),
            Some(t) => self.kind.value(&t.apply(x)),
        }
    }

    fn optimum(&self) -> Option<f64> {
        self.optimum
    }

    /// The closed-form gradient, then the value: about two value passes of work (plus two
    /// matrix products when rotated), charged `1 + d` all the same.
    fn value_and_gradient(&self, x: &[f64], grad: &mut [f64]) -> Option<f64> {
        match &self.transform {
            None => Some(self.kind.value_and_gradient(x, grad)),
            Some(t) => {
                let mut gz = vec![0.0; x.len()];
                let v = self.kind.value_and_gradient(&t.apply(x), &mut gz);
                t.pull_back(&gz, grad);
                Some(v)
            }
        }
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

    /// The central difference of `f` along coordinate `j` at `x`, the tolerance it is held
    /// to against the analytic derivative `g`, and the step.
    fn central_difference(f: &dyn Objective, x: &[f64], j: usize, g: f64) -> (f64, f64, f64) {
        let h = 1e-6 * (1.0 + x[j].abs());
        let (mut a, mut b) = (x.to_vec(), x.to_vec());
        a[j] += h;
        b[j] -= h;
        let fd = (f.evaluate(&a) - f.evaluate(&b)) / (2.0 * h);
        (fd, 1e-5 * (1.0 + fd.abs().max(g.abs())), h)
    }

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
                for (j, &gj) in g.iter().enumerate() {
                    let (fd, tol, _) = central_difference(f.as_ref(), &x, j, gj);
                    assert!((fd - gj).abs() < tol, "{kind} d{j}: fd {fd} vs {}", gj);
                }
            }
        }
    }

    const MOVED: [(bool, bool); 3] = [(true, false), (false, true), (true, true)];

    fn inst(kind: TestFunction, dim: usize, number: u64, shift: bool, rotate: bool) -> Function {
        let inst = Instance {
            number,
            shift,
            rotate,
        };
        Function::standard(kind, dim)
            .unwrap()
            .with_instance(inst)
            .unwrap()
    }

    /// Compass search from `x` with steps from `step` down to 1e-9 of it: a local minimum
    /// inside the box.
    fn refine(f: &Function, mut x: Vec<f64>, step: f64) -> (Vec<f64>, f64) {
        let mut fx = f.evaluate(&x);
        let mut h = step;
        while h > step * 1e-9 {
            let mut moved = false;
            for i in 0..x.len() {
                for s in [h, -h] {
                    let mut y = x.clone();
                    y[i] += s;
                    f.bounds().clamp(&mut y);
                    let fy = f.evaluate(&y);
                    if fy < fx {
                        (x, fx, moved) = (y, fy, true);
                    }
                }
            }
            if !moved {
                h *= 0.5;
            }
        }
        (x, fx)
    }

    /// Asserts that `f`'s optimum is attained at its argmin and that no point found by a
    /// search from `starts` is lower.
    fn check_optimum(f: &Function, starts: Vec<Vec<f64>>, what: &str) {
        let opt = f
            .optimum()
            .unwrap_or_else(|| panic!("{what}: optimum unknown"));
        let at = f.evaluate(f.argmin().unwrap());
        assert!(
            (at - opt).abs() <= 1e-9 * (1.0 + opt.abs()),
            "{what}: f(argmin) {at} vs {opt}"
        );
        let step = f.bounds().width(0) / 400.0;
        for x in starts {
            let (y, fy) = refine(f, x, step);
            assert!(
                fy >= opt - 1e-9 * (1.0 + opt.abs()),
                "{what}: {fy} < {opt} at {y:?}"
            );
        }
    }

    #[test]
    fn moved_optima_are_right_on_a_dense_grid_in_two_dimensions() {
        for kind in TestFunction::ALL {
            for (shift, rotate) in MOVED {
                for number in [1, 2, 3] {
                    let f = inst(kind, 2, number, shift, rotate);
                    let what = format!("{kind:?} shift {shift} rotate {rotate} #{number}");
                    // 301 x 301 grid; refine the 30 lowest grid points.
                    let b = f.bounds().clone();
                    let mut grid: Vec<(f64, Vec<f64>)> = (0..301 * 301)
                        .map(|k| {
                            let x: Vec<f64> = [k % 301, k / 301]
                                .iter()
                                .enumerate()
                                .map(|(i, &j)| b.lower()[i] + b.width(i) * j as f64 / 300.0)
                                .collect();
                            (f.evaluate(&x), x)
                        })
                        .collect();
                    grid.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let opt = f.optimum().unwrap();
                    assert!(grid[0].0 >= opt - 1e-9 * (1.0 + opt.abs()), "{what}: grid");
                    check_optimum(&f, grid.into_iter().take(30).map(|g| g.1).collect(), &what);
                }
            }
        }
    }

    #[test]
    fn moved_optima_are_right_under_random_probes_in_ten_dimensions() {
        let mut rng = crate::base::TrialSeed::from_u64(11).rng(0);
        for kind in TestFunction::ALL {
            for (shift, rotate) in MOVED {
                let f = inst(kind, 10, 4, shift, rotate);
                let opt = f.optimum().unwrap();
                let mut probes: Vec<(f64, Vec<f64>)> = (0..20_000)
                    .map(|_| {
                        let mut x = vec![0.0; 10];
                        f.bounds().sample(&mut rng, &mut x);
                        (f.evaluate(&x), x)
                    })
                    .collect();
                assert!(probes.iter().all(|p| p.0 >= opt), "{kind:?}");
                probes.sort_by(|a, b| a.0.total_cmp(&b.0));
                let what = format!("{kind:?} d10 shift {shift} rotate {rotate}");
                check_optimum(&f, probes.into_iter().take(5).map(|p| p.1).collect(), &what);
            }
        }
    }

    #[test]
    fn shifted_minimiser_is_drawn_well_inside_the_box() {
        for kind in TestFunction::ALL {
            let (a, _) = kind.argmin_and_min(3);
            for number in 1..=30 {
                let f = inst(kind, 3, number, true, false);
                let b = f.bounds();
                for (i, &c) in f.argmin().unwrap().iter().enumerate() {
                    let margin = (c - b.lower()[i]).min(b.upper()[i] - c) / b.width(i);
                    assert!(margin >= 0.1 - 1e-12, "{kind:?} #{number}: {c}");
                    assert_ne!(c, a);
                }
            }
        }
    }

    #[test]
    fn schwefel_is_only_read_inside_its_domain() {
        // Shifted and rotated, a point at the box corner still reads the formula inside
        // [-500, 500): the wrap keeps it from the lower values beyond.
        let f = inst(TestFunction::Schwefel, 2, 7, true, true);
        let t = f.transform.as_ref().unwrap();
        for x in [
            [-500.0, -500.0],
            [500.0, 500.0],
            [-500.0, 500.0],
            [123.0, -456.0],
        ] {
            assert!(t.apply(&x).iter().all(|z| (-500.0..500.0).contains(z)));
        }
        // Without the wrap a shifted Schwefel would go below its minimum in the box.
        let plain = Function::standard(TestFunction::Schwefel, 1).unwrap();
        assert!(plain.kind.value(&[-555.0]) < SCHWEFEL_MIN_PER_DIM);
        // So the formula on a wider box has no known optimum, and on a narrower one that
        // holds the minimiser it keeps it.
        let wide = Function::new(
            TestFunction::Schwefel,
            Bounds::uniform(1, -600.0, 600.0).unwrap(),
        );
        assert_eq!(wide.unwrap().optimum(), None);
        let narrow = Function::new(
            TestFunction::Schwefel,
            Bounds::uniform(1, 0.0, 500.0).unwrap(),
        );
        assert_eq!(narrow.unwrap().optimum(), Some(SCHWEFEL_MIN_PER_DIM));
    }

    #[test]
    fn an_instance_is_the_same_bytes_every_time_and_instances_differ() {
        let probe = [[1.5, -250.0], [399.0, 7.25], [-599.0, 600.0]];
        let bits =
            |f: &Function| -> Vec<u64> { probe.iter().map(|x| f.evaluate(x).to_bits()).collect() };
        for (shift, rotate) in MOVED {
            let a = inst(TestFunction::Griewank, 2, 5, shift, rotate);
            let b = inst(TestFunction::Griewank, 2, 5, shift, rotate);
            assert_eq!(bits(&a), bits(&b));
            assert_eq!(a.argmin(), b.argmin());
            assert_eq!(a.rotation(), b.rotation());
            let c = inst(TestFunction::Griewank, 2, 6, shift, rotate);
            assert_ne!(bits(&a), bits(&c));
            assert_ne!((a.argmin(), a.rotation()), (c.argmin(), c.rotation()));
        }
        // The shift does not depend on whether the instance is also rotated, and the draw
        // depends on the function and dimension.
        let s = inst(TestFunction::Griewank, 2, 5, true, false);
        let sr = inst(TestFunction::Griewank, 2, 5, true, true);
        assert_eq!(s.argmin(), sr.argmin());
        let other = inst(TestFunction::Sphere, 2, 5, true, false);
        assert_ne!(
            s.argmin().unwrap()[0] / 600.0,
            other.argmin().unwrap()[0] / 5.12
        );
        // Frozen: a change here silently changes every published shifted result.
        let g1 = inst(TestFunction::Griewank, 2, 1, true, true);
        let frozen = (g1.argmin().unwrap()[0], g1.rotation().unwrap()[0]);
        assert_eq!(frozen, GOLDEN_INSTANCE_1, "{frozen:?}");
    }

    const GOLDEN_INSTANCE_1: (f64, f64) = (278.343_829_356_395_4, 0.435_635_000_106_868_95);

    #[test]
    fn rotations_are_orthogonal_to_rounding() {
        for d in [2, 10, 50] {
            let f = inst(TestFunction::Griewank, d, 3, false, true);
            let r = f.rotation().unwrap();
            let mut worst = 0f64;
            for i in 0..d {
                for j in 0..d {
                    let p = dot(&r[i * d..(i + 1) * d], &r[j * d..(j + 1) * d]);
                    worst = worst.max((p - f64::from(u8::from(i == j))).abs());
                }
            }
            assert!(worst < 1e-12, "d={d}: {worst}");
        }
        // Rotated Griewank is no longer separable: f(x1, x2) - f(x1, 0) depends on x1.
        let f = inst(TestFunction::Griewank, 2, 3, false, true);
        let diff = |x1: f64| f.evaluate(&[x1, 9.0]) - f.evaluate(&[x1, 0.0]);
        assert!((diff(1.0) - diff(40.0)).abs() > 1e-3);
    }

    #[test]
    fn moved_gradients_match_finite_differences() {
        let mut rng = crate::base::TrialSeed::from_u64(8).rng(0);
        for kind in TestFunction::ALL {
            let f = inst(kind, 4, 2, true, true);
            for _ in 0..10 {
                let mut x = vec![0.0; 4];
                f.bounds().sample(&mut rng, &mut x);
                let mut g = vec![0.0; 4];
                assert_eq!(f.value_and_gradient(&x, &mut g), Some(f.evaluate(&x)));
                for (j, &gj) in g.iter().enumerate() {
                    let (fd, tol, h) = central_difference(&f, &x, j, gj);
                    // A Schwefel seam between a and b makes the difference meaningless.
                    if (fd - gj).abs() > tol && kind == TestFunction::Schwefel {
                        assert!((fd * 2.0 * h).abs() > 100.0, "{kind:?}: {fd} vs {}", gj);
                        continue;
                    }
                    assert!((fd - gj).abs() < tol, "{kind:?} d{j}: fd {fd} vs {}", gj);
                }
            }
        }
    }

    #[test]
    fn instances_without_a_transform_are_refused() {
        let f = || Function::standard(TestFunction::Griewank, 2).unwrap();
        let two = Instance {
            number: 2,
            ..Instance::PLAIN
        };
        let e = f().with_instance(two).unwrap_err();
        assert!(e.contains("same problem as instance 1"), "{e}");
        let big = Function::standard(TestFunction::Griewank, MAX_ROTATED_DIM + 1).unwrap();
        let rot = Instance {
            rotate: true,
            ..Instance::PLAIN
        };
        assert!(
            big.with_instance(rot)
                .unwrap_err()
                .contains("rotate = true needs")
        );
        // The plain instance is the formula itself, bit for bit.
        let p = f().with_instance(Instance::PLAIN).unwrap();
        assert_eq!(
            p.evaluate(&[3.0, 4.0]).to_bits(),
            f().evaluate(&[3.0, 4.0]).to_bits()
        );
    }

    #[test]
    fn rosenbrock_needs_two_dimensions() {
        assert!(Function::standard(TestFunction::Rosenbrock, 1).is_err());
    }
}
