//! Differential evolution, the strong population baseline: the classic DE/rand/1/bin of
//! Storn and Price (1997) and SHADE, its success-history adaptive variant (Tanabe and
//! Fukunaga 2013).
//!
//! Both are ask/tell: a generation builds one trial vector per individual, evaluates the
//! whole batch through the [`Evaluator`], then keeps each trial that is at least as good as
//! its parent (`f(u) <= f(x)`). A mutant coordinate that leaves the box is put halfway
//! between the parent's coordinate and the violated bound (the repair used by JADE and
//! SHADE), so every point evaluated lies inside the box and the search can still approach a
//! bound. Every random number comes from the trial's stream 0, drawn in a fixed order.

use crate::base::{TrialSeed, standard_normal};
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// DE/rand/1/bin settings.
#[derive(Debug, Clone)]
pub struct DeConfig {
    /// Individuals (at least 4: a mutant needs three others).
    pub population: usize,
    /// Differential weight F.
    pub f: f64,
    /// Crossover rate CR.
    pub cr: f64,
}

impl Default for DeConfig {
    fn default() -> Self {
        DeConfig {
            population: 100,
            f: 0.5,
            cr: 0.9,
        }
    }
}

/// SHADE settings.
#[derive(Debug, Clone)]
pub struct ShadeConfig {
    /// Individuals (at least 4).
    pub population: usize,
    /// Entries of the success-history memory of (CR, F) means (paper: H = population).
    pub memory: usize,
    /// Largest greedy share p of current-to-pbest/1: p is drawn per individual in
    /// [2/population, p_max] (paper: 0.2).
    pub p_max: f64,
    /// Archive of replaced parents, as a multiple of the population (paper: 1).
    pub archive: f64,
}

impl Default for ShadeConfig {
    fn default() -> Self {
        ShadeConfig {
            population: 100,
            memory: 100,
            p_max: 0.2,
            archive: 1.0,
        }
    }
}

/// Puts coordinate `j` of a mutant back in the box: halfway between the parent's coordinate
/// and the bound it crossed.
#[inline]
fn repair(v: f64, parent: f64, lo: f64, hi: f64) -> f64 {
    if v < lo {
        0.5 * (lo + parent)
    } else if v > hi {
        0.5 * (hi + parent)
    } else {
        v
    }
}

/// Index in `0..n` distinct from every index in `avoid`.
fn pick_distinct(rng: &mut ChaCha8Rng, n: usize, avoid: &[usize]) -> usize {
    loop {
        let r = rng.random_range(0..n);
        if !avoid.contains(&r) {
            return r;
        }
    }
}

/// State shared by both variants: the population and its values.
struct Population {
    bounds: Bounds,
    rng: ChaCha8Rng,
    n: usize,
    x: Vec<f64>,
    f: Vec<f64>,
    trial: Vec<f64>,
    trial_f: Vec<f64>,
}

impl Population {
    fn new(bounds: &Bounds, n: usize, seed: &TrialSeed) -> Self {
        Population {
            bounds: bounds.clone(),
            rng: seed.rng(0),
            n,
            x: Vec::new(),
            f: Vec::new(),
            trial: vec![0.0; n * bounds.dim()],
            trial_f: vec![0.0; n],
        }
    }

    /// Draws and evaluates the initial population; false if it already existed.
    fn init(&mut self, ev: &mut Evaluator) -> bool {
        if !self.x.is_empty() {
            return false;
        }
        let d = self.bounds.dim();
        self.x = vec![0.0; self.n * d];
        for x in self.x.chunks_exact_mut(d) {
            self.bounds.sample(&mut self.rng, x);
        }
        self.f = vec![0.0; self.n];
        ev.evaluate_batch(&self.x, &mut self.f);
        true
    }
}

impl OptimizerConfig for DeConfig {
    fn batch_size(&self) -> usize {
        self.population
    }

    fn start(&self, bounds: &Bounds, _budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        Box::new(De {
            cfg: self.clone(),
            pop: Population::new(bounds, self.population, seed),
        })
    }
}

struct De {
    cfg: DeConfig,
    pop: Population,
}

impl Optimizer for De {
    fn step(&mut self, ev: &mut Evaluator) {
        let p = &mut self.pop;
        if p.init(ev) {
            return;
        }
        let d = p.bounds.dim();
        let (lo, hi) = (p.bounds.lower(), p.bounds.upper());
        for i in 0..p.n {
            let r1 = pick_distinct(&mut p.rng, p.n, &[i]);
            let r2 = pick_distinct(&mut p.rng, p.n, &[i, r1]);
            let r3 = pick_distinct(&mut p.rng, p.n, &[i, r1, r2]);
            let jrand = p.rng.random_range(0..d);
            for j in 0..d {
                let parent = p.x[i * d + j];
                let cross = j == jrand || p.rng.random::<f64>() < self.cfg.cr;
                p.trial[i * d + j] = if cross {
                    let v = p.x[r1 * d + j] + self.cfg.f * (p.x[r2 * d + j] - p.x[r3 * d + j]);
                    repair(v, parent, lo[j], hi[j])
                } else {
                    parent
                };
            }
        }
        let k = ev.evaluate_batch(&p.trial, &mut p.trial_f);
        for i in 0..k {
            if p.trial_f[i] <= p.f[i] {
                p.f[i] = p.trial_f[i];
                p.x[i * d..(i + 1) * d].copy_from_slice(&p.trial[i * d..(i + 1) * d]);
            }
        }
    }
}

impl OptimizerConfig for ShadeConfig {
    fn batch_size(&self) -> usize {
        self.population
    }

    fn start(&self, bounds: &Bounds, _budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        let archive_cap = (self.archive * self.population as f64).round() as usize;
        Box::new(Shade {
            cfg: self.clone(),
            pop: Population::new(bounds, self.population, seed),
            m_cr: vec![0.5; self.memory],
            m_f: vec![0.5; self.memory],
            k: 0,
            archive: Vec::new(),
            archive_cap,
            cr: vec![0.0; self.population],
            fs: vec![0.0; self.population],
            order: Vec::new(),
        })
    }
}

struct Shade {
    cfg: ShadeConfig,
    pop: Population,
    /// Success-history memory of CR and F means.
    m_cr: Vec<f64>,
    m_f: Vec<f64>,
    /// Next memory slot to overwrite.
    k: usize,
    /// Replaced parents (row-major, `archive.len() / dim` points).
    archive: Vec<f64>,
    archive_cap: usize,
    /// This generation's CR and F per individual.
    cr: Vec<f64>,
    fs: Vec<f64>,
    /// Population indices by value, best first.
    order: Vec<usize>,
}

impl Shade {
    /// Cauchy(loc, 0.1) redrawn until positive, truncated at 1 (SHADE's F rule).
    fn draw_f(rng: &mut ChaCha8Rng, loc: f64) -> f64 {
        loop {
            let u: f64 = rng.random();
            let f = loc + 0.1 * (std::f64::consts::PI * (u - 0.5)).tan();
            if f > 0.0 {
                return f.min(1.0);
            }
        }
    }
}

impl Optimizer for Shade {
    fn step(&mut self, ev: &mut Evaluator) {
        let p = &mut self.pop;
        if p.init(ev) {
            return;
        }
        let d = p.bounds.dim();
        let n = p.n;
        let (lo, hi) = (p.bounds.lower(), p.bounds.upper());
        self.order.clear();
        self.order.extend(0..n);
        let f = &p.f;
        self.order
            .sort_by(|&a, &b| f[a].total_cmp(&f[b]).then(a.cmp(&b)));
        let archived = self.archive.len() / d;
        let p_min = 2.0 / n as f64;
        for i in 0..n {
            let r = p.rng.random_range(0..self.cfg.memory);
            let cr = (self.m_cr[r] + 0.1 * standard_normal(&mut p.rng)).clamp(0.0, 1.0);
            let fi = Self::draw_f(&mut p.rng, self.m_f[r]);
            self.cr[i] = cr;
            self.fs[i] = fi;
            let share = p_min + p.rng.random::<f64>() * (self.cfg.p_max - p_min).max(0.0);
            let top = ((share * n as f64).round() as usize).clamp(1, n);
            let pbest = self.order[p.rng.random_range(0..top)];
            let r1 = pick_distinct(&mut p.rng, n, &[i]);
            // r2 from the population and the archive, distinct from i and r1.
            let r2 = pick_distinct(&mut p.rng, n + archived, &[i, r1]);
            let x2 = |j: usize| {
                if r2 < n {
                    p.x[r2 * d + j]
                } else {
                    self.archive[(r2 - n) * d + j]
                }
            };
            let jrand = p.rng.random_range(0..d);
            for j in 0..d {
                let parent = p.x[i * d + j];
                let cross = j == jrand || p.rng.random::<f64>() < cr;
                p.trial[i * d + j] = if cross {
                    let v = parent
                        + fi * (p.x[pbest * d + j] - parent)
                        + fi * (p.x[r1 * d + j] - x2(j));
                    repair(v, parent, lo[j], hi[j])
                } else {
                    parent
                };
            }
        }
        let k = ev.evaluate_batch(&p.trial, &mut p.trial_f);

        let (mut s_cr, mut s_f, mut w) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..k {
            if p.trial_f[i] <= p.f[i] {
                if p.trial_f[i] < p.f[i] {
                    let gain = p.f[i] - p.trial_f[i];
                    // An infinite gain (from a penalised parent) would swamp the weights.
                    s_cr.push(self.cr[i]);
                    s_f.push(self.fs[i]);
                    w.push(if gain.is_finite() { gain } else { 1e300 });
                    // The replaced parent goes to the archive; a full archive replaces a
                    // random entry.
                    let parent = &p.x[i * d..(i + 1) * d];
                    if self.archive_cap > 0 {
                        if self.archive.len() / d < self.archive_cap {
                            self.archive.extend_from_slice(parent);
                        } else {
                            let slot = p.rng.random_range(0..self.archive_cap);
                            self.archive[slot * d..(slot + 1) * d].copy_from_slice(parent);
                        }
                    }
                }
                p.f[i] = p.trial_f[i];
                p.x[i * d..(i + 1) * d].copy_from_slice(&p.trial[i * d..(i + 1) * d]);
            }
        }
        if !s_cr.is_empty() {
            let total: f64 = w.iter().sum();
            let w: Vec<f64> = w.iter().map(|v| v / total).collect();
            let mean_cr: f64 = w.iter().zip(&s_cr).map(|(w, c)| w * c).sum();
            let num: f64 = w.iter().zip(&s_f).map(|(w, f)| w * f * f).sum();
            let den: f64 = w.iter().zip(&s_f).map(|(w, f)| w * f).sum();
            self.m_cr[self.k] = mean_cr;
            self.m_f[self.k] = num / den;
            self.k = (self.k + 1) % self.cfg.memory;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repair_lands_between_parent_and_bound() {
        assert_eq!(repair(-3.0, 0.5, -1.0, 1.0), -0.25);
        assert_eq!(repair(5.0, 0.5, -1.0, 1.0), 0.75);
        assert_eq!(repair(0.2, 0.5, -1.0, 1.0), 0.2);
    }

    #[test]
    fn shade_f_is_in_0_1() {
        let mut rng = TrialSeed::from_u64(3).rng(0);
        for loc in [0.0, 0.5, 1.0] {
            for _ in 0..1000 {
                let f = Shade::draw_f(&mut rng, loc);
                assert!(f > 0.0 && f <= 1.0);
            }
        }
    }
}
