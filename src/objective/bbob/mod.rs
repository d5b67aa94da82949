//! The 24 noiseless BBOB functions of COCO's `bbob` suite, computed as COCO 2.x computes
//! them (`suite_bbob.c`, `f_*.c`, the transformation wrappers), so that values, optima and
//! instances are the ones cocoex and cocopp know: a result on `bbob-f03-i02-d10` here is a
//! result on COCO's f3, instance 2, in 10-D.
//!
//! COCO composes each function from wrappers (shift by x_opt, rotations, T_osz, T_asy,
//! conditioning, the boundary penalty f_pen, the offset f_opt); [`Bbob::evaluate`] applies
//! them in COCO's order, from the outermost wrapper in. `tests/bbob.rs` compares every
//! function with a table written by cocoex (`scripts/bbob_reference.py`).

pub mod functions;
pub mod instance;
pub mod transform;

use super::{Bounds, Objective, SuiteId};
use functions as raw;
use instance::{MAX_BBOB_DIM, compute_fopt, compute_rotation, compute_xopt, instance_seed};
use transform as t;

/// The largest instance number accepted: the IOH export numbers instances in 16 bits
/// (COCO's own suites use instances up to 110). The seeds, 10^4 per instance, stay far
/// inside the range where COCO's legacy generator is exact (its C `int` quotient).
pub const MAX_BBOB_INSTANCE: usize = u16::MAX as usize;

/// One BBOB problem: function 1-24, dimension, instance, on [-5, 5]^dim.
#[derive(Debug, Clone)]
pub struct Bbob {
    function: usize,
    instance: usize,
    name: String,
    bounds: Bounds,
    fopt: f64,
    /// The optimum's location as COCO reports it (`best_parameter`).
    best: Vec<f64>,
    data: Data,
}

/// What an instance precomputes: the shift, the matrices and the per-coordinate
/// coefficients its chain of wrappers uses (unused fields stay empty).
#[derive(Debug, Clone, Default)]
struct Data {
    xopt: Vec<f64>,
    /// The first affine map applied after the shift (row-major), and a second.
    m1: Vec<f64>,
    m2: Vec<f64>,
    /// The offset `b` of the affine maps (zero except f9's 0.5).
    b: Vec<f64>,
    coef: Vec<f64>,
    /// f8's scaling of the shifted point, `max(1, sqrt(n)/8)`.
    factor: f64,
    rot1: Vec<Vec<f64>>,
    rot2: Vec<Vec<f64>>,
    /// f20: which coordinates the x-hat step negates.
    negate: Vec<bool>,
    gallagher: Option<Gallagher>,
    weierstrass: Option<raw::WeierstrassTerms>,
}

/// Gallagher's peaks (f21: 101, f22: 21).
#[derive(Debug, Clone)]
struct Gallagher {
    rotation: Vec<Vec<f64>>,
    /// `x_local[i][peak]`: the peaks' centres in rotated coordinates.
    x_local: Vec<Vec<f64>>,
    /// `scales[peak][i]`: each peak's diagonal conditioning.
    scales: Vec<Vec<f64>>,
    heights: Vec<f64>,
}

impl Bbob {
    /// COCO's f`function` (1-24), instance `instance` (>= 1), in `dim` (2..=40) variables.
    pub fn new(function: usize, dim: usize, instance: usize) -> Result<Bbob, String> {
        if !(1..=24).contains(&function) {
            return Err(format!(
                "bbob function {function} does not exist: the suite numbers its functions 1 to 24"
            ));
        }
        if !(2..=MAX_BBOB_DIM).contains(&dim) {
            return Err(format!(
                "bbob dimension {dim} is outside 2..={MAX_BBOB_DIM}: several functions need 2 variables, and COCO's instance generator (and the reference table) stop at {MAX_BBOB_DIM}"
            ));
        }
        if !(1..=MAX_BBOB_INSTANCE).contains(&instance) {
            return Err(format!(
                "bbob instance {instance} is outside 1..={MAX_BBOB_INSTANCE}: COCO numbers instances from 1"
            ));
        }
        let (data, best) = build(function, dim, instance);
        Ok(Bbob {
            function,
            instance,
            name: format!("bbob-f{function:02}-i{instance:02}-d{dim:02}"),
            bounds: Bounds::uniform(dim, -5.0, 5.0)?,
            fopt: compute_fopt(function, instance),
            best,
            data,
        })
    }

    pub fn function(&self) -> usize {
        self.function
    }

    pub fn instance(&self) -> usize {
        self.instance
    }

    /// The optimum's location as COCO reports it (`best_parameter`); the value there is
    /// f_opt up to the rounding of the transformations (`tests/bbob.rs` checks both).
    pub fn x_opt(&self) -> &[f64] {
        &self.best
    }

    /// The value at `x`, with COCO's arithmetic (see the module's documentation).
    pub fn value(&self, x: &[f64]) -> f64 {
        let d = &self.data;
        let fopt = self.fopt;
        match self.function {
            1 => raw::sphere(&t::shift(x, &d.xopt)) + fopt,
            2 => raw::ellipsoid(&t::oscillate(&t::shift(x, &d.xopt)), &d.coef) + fopt,
            3 => {
                let z = t::asymmetric(&t::oscillate(&t::shift(x, &d.xopt)), 0.2);
                let z: Vec<f64> = z.iter().zip(&d.coef).map(|(v, c)| c * v).collect();
                raw::rastrigin(&z) + fopt
            }
            4 => {
                let z = t::brs(&t::oscillate(&t::shift(x, &d.xopt)));
                (raw::rastrigin(&z) + fopt) + 100.0 * t::boundary_excess(x)
            }
            5 => raw::linear_slope(x, &self.best) + fopt,
            6 => {
                let z = t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt));
                let v = t::oscillate_value(raw::attractive_sector(&z, &d.xopt));
                v.powf(0.9) + fopt
            }
            7 => self.step_ellipsoid(x),
            8 => {
                let z: Vec<f64> = t::shift(x, &d.xopt)
                    .iter()
                    .map(|v| d.factor * v - (-1.0))
                    .collect();
                raw::rosenbrock(&z) + fopt
            }
            9 => raw::rosenbrock(&t::affine(&d.m1, &d.b, x)) + fopt,
            10 => {
                let z = t::oscillate(&t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt)));
                raw::ellipsoid(&z, &d.coef) + fopt
            }
            11 => {
                let z = t::oscillate(&t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt)));
                raw::discus(&z) + fopt
            }
            12 => {
                let z = t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt));
                let z = t::affine(&d.m1, &d.b, &t::asymmetric(&z, 0.5));
                raw::bent_cigar(&z) + fopt
            }
            13 => raw::sharp_ridge(&t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt))) + fopt,
            14 => raw::different_powers(&t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt))) + fopt,
            15 => {
                let z = t::oscillate(&t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt)));
                let z = t::affine(&d.m2, &d.b, &t::asymmetric(&z, 0.2));
                raw::rastrigin(&z) + fopt
            }
            16 => {
                let z = t::oscillate(&t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt)));
                let z = t::affine(&d.m2, &d.b, &z);
                let terms = d.weierstrass.as_ref().expect("f16 has its terms");
                let penalty_factor = 10.0 / self.dim() as f64;
                (raw::weierstrass(&z, terms) + fopt) + penalty_factor * t::boundary_excess(x)
            }
            17 | 18 => {
                let z = t::asymmetric(&t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt)), 0.5);
                let z = t::affine(&d.m2, &d.b, &z);
                (raw::schaffers(&z) + fopt) + 10.0 * t::boundary_excess(x)
            }
            19 => {
                let z: Vec<f64> = t::affine(&d.m1, &d.b, x)
                    .iter()
                    .map(|v| v - (-0.5))
                    .collect();
                raw::griewank_rosenbrock(&z) + fopt
            }
            20 => self.schwefel(x),
            21 | 22 => self.gallagher(x),
            23 => {
                let z = t::affine(&d.m1, &d.b, &t::shift(x, &d.xopt));
                (raw::katsuura(&z) + fopt) + 1.0 * t::boundary_excess(x)
            }
            24 => self.lunacek(x),
            _ => unreachable!("checked in Bbob::new"),
        }
    }

    /// f7, monolithic in COCO (`f_step_ellipsoid_raw`): its rounding sits between the two
    /// rotations.
    fn step_ellipsoid(&self, x: &[f64]) -> f64 {
        let d = &self.data;
        let n = x.len();
        let penalty = t::abs_excess(x);
        let mut z = vec![0.0; n];
        for (i, zi) in z.iter_mut().enumerate() {
            let c1 = 10f64.powf(i as f64 / (n - 1) as f64).sqrt();
            for ((r, xj), oj) in d.rot2[i].iter().zip(x).zip(&d.xopt) {
                *zi += c1 * r * (xj - oj);
            }
        }
        let x1 = z[0];
        for v in z.iter_mut() {
            *v = if v.abs() > 0.5 {
                raw::round(*v)
            } else {
                raw::round(10.0 * *v) / 10.0
            };
        }
        let zz = t::rotate(&d.rot1, &z);
        let mut r = 0.0;
        for (c, v) in d.coef.iter().zip(&zz) {
            r += c * v * v;
        }
        let m = (x1.abs() * 1.0e-4).max_like_coco(r);
        0.1 * m + penalty + self.fopt
    }

    /// f20: x-hat (sign flips), scale 2, z-hat, the conditioning around 2|x_opt|, scale
    /// 100, then the raw Schwefel function.
    fn schwefel(&self, x: &[f64]) -> f64 {
        let d = &self.data;
        let n = x.len();
        let a: Vec<f64> = x
            .iter()
            .zip(&d.negate)
            .map(|(&v, &neg)| if neg { -v } else { v })
            .collect();
        let b: Vec<f64> = a.iter().map(|v| 2.0 * v).collect();
        let mut c = vec![0.0; n];
        c[0] = b[0];
        for i in 1..n {
            c[i] = b[i] + 0.25 * (b[i - 1] - 2.0 * d.xopt[i - 1].abs());
        }
        let tmp2: Vec<f64> = d.xopt.iter().map(|v| 2.0 * v.abs()).collect();
        let tmp1: Vec<f64> = d.xopt.iter().map(|v| -2.0 * v.abs()).collect();
        let e = t::affine(&d.m1, &d.b, &t::shift(&c, &tmp2));
        let g: Vec<f64> = t::shift(&e, &tmp1).iter().map(|v| 100.0 * v).collect();
        raw::schwefel(&g) + self.fopt
    }

    /// f21, f22 (`f_gallagher_raw`), then the offset.
    fn gallagher(&self, x: &[f64]) -> f64 {
        let g = self
            .data
            .gallagher
            .as_ref()
            .expect("f21/f22 have their peaks");
        let n = x.len();
        let fac = -0.5 / n as f64;
        let f_add = t::abs_excess(x);
        let tmx = t::rotate(&g.rotation, x);
        let mut f: f64 = 0.0;
        for (peak, (scales, height)) in g.scales.iter().zip(&g.heights).enumerate() {
            let mut s = 0.0;
            for j in 0..n {
                let d = tmx[j] - g.x_local[j][peak];
                s += scales[j] * d * d;
            }
            let v = height * (fac * s).exp();
            f = f.max_like_coco(v);
        }
        let f = 10.0 - f;
        let a = 0.1;
        let mut f_true = if f > 0.0 {
            let v = f.ln() / a;
            (v + 0.49 * (v.sin() + (0.79 * v).sin())).exp().powf(a)
        } else if f < 0.0 {
            let v = (-f).ln() / a;
            -(v + 0.49 * ((0.55 * v).sin() + (0.31 * v).sin()))
                .exp()
                .powf(a)
        } else {
            f
        };
        f_true *= f_true;
        f_true += f_add;
        f_true + self.fopt
    }

    /// f24 (`f_lunacek_bi_rastrigin_raw`), then the offset.
    fn lunacek(&self, x: &[f64]) -> f64 {
        let d = &self.data;
        let n = x.len();
        let nf = n as f64;
        let mu0 = 2.5;
        let dd = 1.0;
        let s = 1.0 - 0.5 / ((nf + 20.0).sqrt() - 4.1);
        let mu1 = -((mu0 * mu0 - dd) / s).sqrt();
        let penalty = t::abs_excess(x);
        let x_hat: Vec<f64> = x
            .iter()
            .zip(&d.xopt)
            .map(|(&v, &o)| {
                let h = 2.0 * v;
                if o < 0.0 { -h } else { h }
            })
            .collect();
        let mut tmp = vec![0.0; n];
        for (i, ti) in tmp.iter_mut().enumerate() {
            let c1 = d.coef[i];
            for (r, h) in d.rot2[i].iter().zip(&x_hat) {
                *ti += c1 * r * (h - mu0);
            }
        }
        let z = t::rotate(&d.rot1, &tmp);
        let (mut s1, mut s2, mut s3) = (0.0, 0.0, 0.0);
        for i in 0..n {
            s1 += (x_hat[i] - mu0) * (x_hat[i] - mu0);
            s2 += (x_hat[i] - mu1) * (x_hat[i] - mu1);
            s3 += (2.0 * std::f64::consts::PI * z[i]).cos();
        }
        let second = dd * nf + s * s2;
        let m = if s1 < second { s1 } else { second };
        (m + 10.0 * (nf - s3) + 1e4 * penalty) + self.fopt
    }
}

/// COCO's `coco_double_max(a, b)`: `a > b ? a : b` (NaN handling as in C).
trait MaxLikeCoco {
    fn max_like_coco(self, other: f64) -> f64;
}

impl MaxLikeCoco for f64 {
    fn max_like_coco(self, other: f64) -> f64 {
        if self > other { self } else { other }
    }
}

/// The instance data of f`function` in `dim` variables, and the optimum's location.
fn build(function: usize, dim: usize, instance: usize) -> (Data, Vec<f64>) {
    let rseed = instance_seed(function, instance);
    let n = dim;
    let mut d = Data {
        b: vec![0.0; n],
        ..Data::default()
    };
    let sqrt10 = 10f64.sqrt();
    // The usual pair: R from rseed + 10^6, Q from rseed.
    let two_rotations = || {
        (
            compute_rotation(rseed + 1_000_000, n),
            compute_rotation(rseed, n),
        )
    };
    let best = match function {
        1 => {
            d.xopt = compute_xopt(rseed, n);
            d.xopt.clone()
        }
        2 => {
            d.xopt = compute_xopt(rseed, n);
            d.coef = raw::ellipsoid_coefficients(1.0e6, n);
            d.xopt.clone()
        }
        3 => {
            d.xopt = compute_xopt(rseed, n);
            d.coef = t::conditioning_diagonal(10.0, n);
            d.xopt.clone()
        }
        4 => {
            d.xopt = compute_xopt(rseed, n);
            // In COCO's legacy code though not in the function's definition.
            for v in d.xopt.iter_mut().step_by(2) {
                *v = v.abs();
            }
            d.xopt.clone()
        }
        5 => compute_xopt(rseed, n)
            .iter()
            .map(|&v| if v < 0.0 { -5.0 } else { 5.0 })
            .collect(),
        6 | 13 => {
            d.xopt = compute_xopt(rseed, n);
            let (r, q) = two_rotations();
            d.m1 = t::rot_scale_rot(&r, sqrt10, &q);
            d.xopt.clone()
        }
        7 => {
            d.xopt = compute_xopt(rseed, n);
            (d.rot1, d.rot2) = two_rotations();
            d.coef = raw::ellipsoid_coefficients(100.0, n);
            d.xopt.clone()
        }
        8 => {
            d.xopt = compute_xopt(rseed, n).iter().map(|v| v * 0.75).collect();
            d.factor = 1f64.max((n as f64).sqrt() / 8.0);
            d.xopt.clone()
        }
        9 => {
            let r = compute_rotation(rseed, n);
            let factor = 1f64.max((n as f64).sqrt() / 8.0);
            d.m1 = r.iter().flatten().map(|v| factor * v).collect();
            d.b = vec![0.5; n];
            column_sums_over(&r, 2.0 * factor)
        }
        10 | 11 | 14 => {
            d.xopt = compute_xopt(rseed, n);
            d.m1 = t::flatten(&compute_rotation(rseed + 1_000_000, n));
            if function == 10 {
                d.coef = raw::ellipsoid_coefficients(1.0e6, n);
            }
            d.xopt.clone()
        }
        12 => {
            d.xopt = compute_xopt(rseed + 1_000_000, n);
            d.m1 = t::flatten(&compute_rotation(rseed + 1_000_000, n));
            d.xopt.clone()
        }
        15 | 16 | 23 => {
            d.xopt = compute_xopt(rseed, n);
            let (r, q) = two_rotations();
            let base = match function {
                15 => sqrt10,
                16 => 1.0 / 100f64.sqrt(),
                _ => 100f64.sqrt(),
            };
            let lambda_mix = t::rot_scale_rot(&r, base, &q);
            if function == 23 {
                d.m1 = lambda_mix;
            } else {
                // Shift, then R, T_osz (and T_asy for f15), then R Λ Q.
                d.m1 = t::flatten(&r);
                d.m2 = lambda_mix;
            }
            if function == 16 {
                d.weierstrass = Some(raw::WeierstrassTerms::new());
            }
            d.xopt.clone()
        }
        17 | 18 => {
            let conditioning: f64 = if function == 17 { 10.0 } else { 1000.0 };
            d.xopt = compute_xopt(rseed, n);
            let (r, q) = two_rotations();
            d.m1 = t::flatten(&r);
            d.m2 = vec![0.0; n * n];
            for (i, row) in q.iter().enumerate() {
                let exponent = 1.0 * i as f64 / (n as f64 - 1.0);
                let scale = conditioning.sqrt().powf(exponent);
                for (j, v) in row.iter().enumerate() {
                    d.m2[i * n + j] = v * scale;
                }
            }
            d.xopt.clone()
        }
        19 => {
            let scales = 1f64.max((n as f64).sqrt() / 8.0);
            let r: Vec<Vec<f64>> = compute_rotation(rseed, n)
                .into_iter()
                .map(|row| row.into_iter().map(|v| v * scales).collect())
                .collect();
            d.m1 = t::flatten(&r);
            column_sums_over(&r, 2.0 * scales)
        }
        20 => {
            let u = instance::bbob2009_unif(n, rseed);
            d.negate = u.iter().map(|v| v - 0.5 < 0.0).collect();
            d.xopt = d
                .negate
                .iter()
                .map(|&neg| {
                    if neg {
                        -(0.5 * 4.2096874637)
                    } else {
                        0.5 * 4.2096874637
                    }
                })
                .collect();
            d.m1 = vec![0.0; n * n];
            for i in 0..n {
                let exponent = 1.0 * i as f64 / (n as f64 - 1.0);
                d.m1[i * n + i] = 10f64.sqrt().powf(exponent);
            }
            d.negate
                .iter()
                .map(|&neg| {
                    if neg {
                        -0.5 * 4.2096874633
                    } else {
                        0.5 * 4.2096874633
                    }
                })
                .collect()
        }
        21 | 22 => {
            let (g, best) = build_gallagher(function, n, rseed);
            d.gallagher = Some(g);
            best
        }
        24 => {
            (d.rot1, d.rot2) = two_rotations();
            let signs = instance::bbob2009_gauss(n, rseed);
            d.xopt = signs
                .iter()
                .map(|&g| if g < 0.0 { -(0.5 * 2.5) } else { 0.5 * 2.5 })
                .collect();
            d.coef = (0..n)
                .map(|i| 100f64.sqrt().powf(i as f64 / (n - 1) as f64))
                .collect();
            d.xopt.clone()
        }
        _ => unreachable!("checked in Bbob::new"),
    };
    (d, best)
}

/// Gallagher's peaks as `f_gallagher_bbob_problem_allocate` draws them.
fn build_gallagher(function: usize, n: usize, rseed: i64) -> (Gallagher, Vec<f64>) {
    let peaks = if function == 21 { 101 } else { 21 };
    let max_condition: f64 = 1000.0;
    let (first_condition, b, c) = if peaks == 101 {
        (1000f64.sqrt(), 10.0, 5.0)
    } else {
        (1000.0, 9.8, 4.9)
    };
    let rotation = compute_rotation(rseed, n);
    // The peaks' condition numbers: a random permutation of 1000^(k/(peaks-2)).
    let u = instance::bbob2009_unif(peaks - 1, rseed);
    let order = sorted_indices(&u);
    let fit = [1.1, 9.1];
    let mut conditions = vec![first_condition];
    let mut heights = vec![10.0];
    for i in 1..peaks {
        conditions.push(max_condition.powf(order[i - 1] as f64 / (peaks - 2) as f64));
        heights.push((i - 1) as f64 / (peaks - 2) as f64 * (fit[1] - fit[0]) + fit[0]);
    }
    let scales: Vec<Vec<f64>> = (0..peaks)
        .map(|i| {
            let u = instance::bbob2009_unif(n, rseed + 1000 * i as i64);
            let order = sorted_indices(&u);
            (0..n)
                .map(|j| conditions[i].powf(order[j] as f64 / (n - 1) as f64 - 0.5))
                .collect()
        })
        .collect();
    let u = instance::bbob2009_unif(n * peaks, rseed);
    let best: Vec<f64> = (0..n).map(|i| 0.8 * (b * u[i] - c)).collect();
    let x_local: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            (0..peaks)
                .map(|j| {
                    let mut s = 0.0;
                    for k in 0..n {
                        s += rotation[i][k] * (b * u[j * n + k] - c);
                    }
                    if j == 0 { s * 0.8 } else { s }
                })
                .collect()
        })
        .collect();
    (
        Gallagher {
            rotation,
            x_local,
            scales,
            heights,
        },
        best,
    )
}

/// The indices of `u` in increasing order of value (COCO sorts (value, index) pairs with
/// qsort; the values are distinct, so a stable sort gives the same order).
fn sorted_indices(u: &[f64]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..u.len()).collect();
    idx.sort_by(|&a, &b| u[a].total_cmp(&u[b]));
    idx
}

impl Objective for Bbob {
    fn name(&self) -> &str {
        &self.name
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    /// COCO's value; a point with a non-finite coordinate, or one so far out that the
    /// arithmetic overflows into NaN, is worth +inf (the harness's penalty), never NaN.
    fn evaluate(&self, x: &[f64]) -> f64 {
        if x.iter().any(|v| !v.is_finite()) {
            return f64::INFINITY;
        }
        let v = self.value(x);
        if v.is_nan() { f64::INFINITY } else { v }
    }

    fn optimum(&self) -> Option<f64> {
        Some(self.fopt)
    }

    fn suite_id(&self) -> Option<SuiteId> {
        Some(SuiteId {
            suite: "bbob",
            function: self.function,
            instance: self.instance,
        })
    }
}

/// x_opt of f8/f9-style rotated functions: each column of `r` summed in row order (COCO's
/// order, so the sums agree bit for bit), divided by `divisor`.
fn column_sums_over(r: &[Vec<f64>], divisor: f64) -> Vec<f64> {
    (0..r.len())
        .map(|col| r.iter().fold(0.0, |s, row| s + row[col]) / divisor)
        .collect()
}
