//! Particle swarm optimisation, dissertation eq. 3.15/3.16:
//! `v <- w v + c1 r1 (p - x) + c2 r2 (g - x)`, `x <- x + v`, with r1, r2 drawn per particle
//! and per dimension. The global best `g` is updated synchronously after each swarm
//! evaluation. Velocities are clamped to `vmax` times the domain width; a particle that
//! leaves the box is put back on the violated bound and that velocity component is zeroed
//! ("absorbing walls").

use crate::base::TrialSeed;
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// PSO settings. The inertia falls linearly from `w_start` to `w_end` over the run (Shi and
/// Eberhart's schedule); set them equal for a constant inertia.
#[derive(Debug, Clone)]
pub struct PsoConfig {
    pub swarm: usize,
    pub w_start: f64,
    pub w_end: f64,
    pub c1: f64,
    pub c2: f64,
    pub vmax: f64,
}

impl Default for PsoConfig {
    fn default() -> Self {
        PsoConfig {
            swarm: 200,
            w_start: 0.9,
            w_end: 0.4,
            c1: 2.0,
            c2: 2.0,
            vmax: 0.2,
        }
    }
}

impl OptimizerConfig for PsoConfig {
    fn batch_size(&self) -> usize {
        self.swarm
    }

    fn start(&self, bounds: &Bounds, budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        // Iterations after the initial evaluation, for the inertia schedule.
        let iterations = (budget.saturating_sub(self.swarm as u64)).div_ceil(self.swarm as u64);
        let vmax = (0..bounds.dim())
            .map(|j| self.vmax * bounds.width(j))
            .collect();
        Box::new(Pso {
            vmax,
            cfg: self.clone(),
            bounds: bounds.clone(),
            rng: seed.rng(0),
            iterations: iterations.max(1),
            iter: 0,
            x: Vec::new(),
            v: Vec::new(),
            f: Vec::new(),
            pbest: Vec::new(),
            pbest_f: Vec::new(),
            gbest: Vec::new(),
            gbest_f: f64::INFINITY,
        })
    }
}

struct Pso {
    cfg: PsoConfig,
    bounds: Bounds,
    rng: ChaCha8Rng,
    iterations: u64,
    iter: u64,
    x: Vec<f64>,
    v: Vec<f64>,
    f: Vec<f64>,
    pbest: Vec<f64>,
    pbest_f: Vec<f64>,
    gbest: Vec<f64>,
    gbest_f: f64,
    /// Velocity clamp per dimension (`vmax` times the interval width).
    vmax: Vec<f64>,
}

impl Pso {
    fn update_bests(&mut self) {
        let d = self.bounds.dim();
        for i in 0..self.cfg.swarm {
            if self.f[i] < self.pbest_f[i] {
                self.pbest_f[i] = self.f[i];
                self.pbest[i * d..(i + 1) * d].copy_from_slice(&self.x[i * d..(i + 1) * d]);
            }
            if self.f[i] < self.gbest_f {
                self.gbest_f = self.f[i];
                self.gbest.copy_from_slice(&self.x[i * d..(i + 1) * d]);
            }
        }
    }
}

impl Optimizer for Pso {
    fn step(&mut self, ev: &mut Evaluator) {
        let d = self.bounds.dim();
        let n = self.cfg.swarm;
        let vmax = &self.vmax;
        if self.x.is_empty() {
            self.x = vec![0.0; n * d];
            self.v = vec![0.0; n * d];
            for i in 0..n {
                self.bounds
                    .sample(&mut self.rng, &mut self.x[i * d..(i + 1) * d]);
                for (v, vm) in self.v[i * d..(i + 1) * d].iter_mut().zip(vmax) {
                    *v = (2.0 * self.rng.random::<f64>() - 1.0) * vm;
                }
            }
            self.f = vec![0.0; n];
            ev.evaluate_batch(&self.x, &mut self.f);
            self.pbest = self.x.clone();
            self.pbest_f = vec![f64::INFINITY; n];
            self.gbest = vec![0.0; d];
            self.update_bests();
            return;
        }

        let frac = (self.iter as f64 / (self.iterations.max(2) - 1) as f64).min(1.0);
        let w = self.cfg.w_start + (self.cfg.w_end - self.cfg.w_start) * frac;
        self.iter += 1;
        let (lo, hi) = (self.bounds.lower(), self.bounds.upper());
        for i in 0..n {
            for j in 0..d {
                let k = i * d + j;
                let r1: f64 = self.rng.random();
                let r2: f64 = self.rng.random();
                let v = w * self.v[k]
                    + self.cfg.c1 * r1 * (self.pbest[k] - self.x[k])
                    + self.cfg.c2 * r2 * (self.gbest[j] - self.x[k]);
                let mut v = v.clamp(-vmax[j], vmax[j]);
                let mut x = self.x[k] + v;
                if x < lo[j] {
                    x = lo[j];
                    v = 0.0;
                } else if x > hi[j] {
                    x = hi[j];
                    v = 0.0;
                }
                self.x[k] = x;
                self.v[k] = v;
            }
        }
        ev.evaluate_batch(&self.x, &mut self.f);
        self.update_bests();
    }
}
