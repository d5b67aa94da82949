//! Fitting a [`Structure`] with the harness's optimizers: the shape parameters are searched
//! (PSO, then a Nelder-Mead polish, each a trial of [`run_trial`] so every evaluation is
//! counted by the [`crate::harness::Evaluator`]); the linear coefficients are solved by
//! least squares inside each evaluation.

use crate::harness::{Stall, TrialRecord, TrialSeed, TrialSpec, run_trial};
use crate::objective::{Bounds, Objective};
use crate::optimizer::nelder_mead::NelderMead;
use crate::optimizer::pso::PsoConfig;
use crate::optimizer::{Optimizer, OptimizerConfig};
use crate::physics::structure::{LinearFit, Projection, Structure};
use rayon::prelude::*;
use std::sync::Arc;

/// The training cost of a structure's shape: `Σ e²/2` with the best linear coefficients.
pub struct StructureObjective {
    st: Structure,
    u: Arc<Vec<f64>>,
    y: Arc<Vec<f64>>,
    bounds: Bounds,
    projection: Projection,
}

impl StructureObjective {
    /// The objective of `st` on `(u, y)`.
    pub fn new(st: Structure, u: Arc<Vec<f64>>, y: Arc<Vec<f64>>) -> Self {
        let bounds = Bounds::new(
            st.specs().iter().map(|s| s.lower).collect(),
            st.specs().iter().map(|s| s.upper).collect(),
        )
        .expect("structure bounds are valid");
        let n = u.len().min(y.len());
        let projection = st.projection(&y[..n]);
        StructureObjective {
            st,
            u,
            y,
            bounds,
            projection,
        }
    }
}

impl Objective for StructureObjective {
    fn name(&self) -> &str {
        "structure"
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, x: &[f64]) -> f64 {
        self.st
            .fit_linear_projected(x, &self.u, &self.y, &self.projection)
            .cost
    }

    /// A swarm's simulations in parallel (each point on its own, so the values do not
    /// depend on the thread count).
    fn evaluate_batch(&self, points: &[f64], out: &mut [f64]) {
        par_batch(self, points, out);
    }
}

/// [`Objective::evaluate_batch`] over rayon's pool, point by point.
fn par_batch(obj: &impl Objective, points: &[f64], out: &mut [f64]) {
    let d = obj.dim();
    points
        .par_chunks_exact(d)
        .zip(out.par_iter_mut())
        .with_max_len(1)
        .for_each(|(p, o)| *o = obj.evaluate(p));
}

/// An objective restricted to some coordinates, the others held at `base`.
struct Restricted {
    inner: Arc<StructureObjective>,
    free: Vec<usize>,
    base: Vec<f64>,
    bounds: Bounds,
}

impl Objective for Restricted {
    fn name(&self) -> &str {
        "structure (restricted)"
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, x: &[f64]) -> f64 {
        let mut full = self.base.clone();
        for (&i, &v) in self.free.iter().zip(x) {
            full[i] = v;
        }
        self.inner.evaluate(&full)
    }

    fn evaluate_batch(&self, points: &[f64], out: &mut [f64]) {
        par_batch(self, points, out);
    }
}

/// A global optimizer whose first evaluations are given points (so a nested start is never
/// lost), then the optimizer itself.
#[derive(Debug)]
struct Seeded {
    points: Vec<Vec<f64>>,
    inner: PsoConfig,
}

struct SeededRun {
    points: Vec<Vec<f64>>,
    inner: Box<dyn Optimizer>,
}

impl OptimizerConfig for Seeded {
    fn batch_size(&self) -> usize {
        self.inner.batch_size()
    }

    fn start(&self, bounds: &Bounds, budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        let k = self.points.len() as u64;
        Box::new(SeededRun {
            points: self.points.clone(),
            inner: self.inner.start(bounds, budget.saturating_sub(k), seed),
        })
    }
}

impl Optimizer for SeededRun {
    fn step(&mut self, ev: &mut crate::harness::Evaluator) {
        if self.points.is_empty() {
            self.inner.step(ev);
        } else {
            let flat: Vec<f64> = self.points.drain(..).flatten().collect();
            let mut out = vec![0.0; flat.len() / ev.dim()];
            ev.evaluate_batch(&flat, &mut out);
        }
    }
}

/// Nelder-Mead from a given point.
#[derive(Debug)]
struct PolishFrom {
    x0: Vec<f64>,
    step: f64,
}

impl OptimizerConfig for PolishFrom {
    fn batch_size(&self) -> usize {
        1
    }

    fn start(&self, bounds: &Bounds, _budget: u64, _seed: &TrialSeed) -> Box<dyn Optimizer> {
        Box::new(NelderMead::new(
            bounds.clone(),
            self.step,
            Some(self.x0.clone()),
        ))
    }
}

/// Evaluation budgets of one fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// PSO evaluations (0: no global stage).
    pub global: u64,
    /// PSO swarm size.
    pub swarm: usize,
    /// Nelder-Mead evaluations per polish round.
    pub polish: u64,
    /// Polish rounds (each restarts the simplex at a smaller step).
    pub rounds: usize,
    /// The global stage fits only the first this many samples (0: all); the polish always
    /// fits the whole record. Cheap exploration for an expensive model.
    pub global_window: usize,
    /// A screen (0: none): the polish runs only if the global stage gained at least this
    /// much over the start, in BIC units (`N ln(start cost / best)`). A nested candidate
    /// that cannot gain 2 units by its own parameters will not gain the 20-30 it needs to
    /// pass; most candidates of later rounds are such, and the polish is most of a fit.
    pub screen: f64,
}

/// A fitted structure.
#[derive(Clone, Debug)]
pub struct Fitted {
    pub structure: Structure,
    pub theta: Vec<f64>,
    pub linear: LinearFit,
    /// Evaluations spent.
    pub evaluations: u64,
}

impl Fitted {
    /// `st` at shape `theta` with its best linear coefficients on `(u, y)`, after
    /// `evaluations` (the least-squares solve repeats one the optimizer has counted).
    pub fn at(st: &Structure, theta: Vec<f64>, u: &[f64], y: &[f64], evaluations: u64) -> Self {
        Fitted {
            linear: st.fit_linear(&theta, u, y),
            structure: st.clone(),
            theta,
            evaluations,
        }
    }

    /// Training RMSE (same units as y).
    pub fn rmse(&self, samples: usize) -> f64 {
        (2.0 * self.linear.cost / samples.max(1) as f64).sqrt()
    }
}

/// Fits `st` on `(u, y)`: a PSO over the coordinates `free` (all when `None`) with the
/// others at `start` (or neutral), seeded with `start`, then Nelder-Mead over all
/// coordinates from the best point. Seeds derive from `(seed, label, stage)`.
pub fn fit(
    st: &Structure,
    u: &Arc<Vec<f64>>,
    y: &Arc<Vec<f64>>,
    start: Option<&[f64]>,
    free: Option<&[usize]>,
    budget: Budget,
    seed: u64,
) -> Fitted {
    fit_until(st, u, y, start, free, budget, seed, &mut |_| false)
}

/// [`fit`], asking `decided` after each polish round (with the best shape so far) whether
/// the question the fit answers is settled; the rounds up to then are those of [`fit`].
#[allow(clippy::too_many_arguments)]
pub fn fit_until(
    st: &Structure,
    u: &Arc<Vec<f64>>,
    y: &Arc<Vec<f64>>,
    start: Option<&[f64]>,
    free: Option<&[usize]>,
    budget: Budget,
    seed: u64,
    decided: &mut dyn FnMut(&[f64]) -> bool,
) -> Fitted {
    let obj = Arc::new(StructureObjective::new(st.clone(), u.clone(), y.clone()));
    let w = budget.global_window;
    let n = u.len().min(y.len());
    // Samples the global stage fits.
    let explored = if w > 0 && w < n { w } else { n };
    let explore = if explored < n {
        Arc::new(StructureObjective::new(
            st.clone(),
            Arc::new(u[..w].to_vec()),
            Arc::new(y[..w].to_vec()),
        ))
    } else {
        obj.clone()
    };
    let neutral: Vec<f64> = st.specs().iter().map(|s| s.neutral).collect();
    let mut best = start.map_or(neutral, <[f64]>::to_vec);
    let label = st.label();
    let mut evaluations = 0;
    let all: Vec<usize> = (0..best.len()).collect();
    let free = free.unwrap_or(&all).to_vec();
    let mut screened_out = false;
    if budget.global > 0 && !free.is_empty() {
        let bounds = Bounds::new(
            free.iter().map(|&i| obj.bounds().lower()[i]).collect(),
            free.iter().map(|&i| obj.bounds().upper()[i]).collect(),
        )
        .expect("valid bounds");
        let restricted: Arc<dyn Objective> = Arc::new(Restricted {
            inner: explore,
            free: free.clone(),
            base: best.clone(),
            bounds,
        });
        // The start, and a grid over the first one or two free coordinates (the others at
        // the start): narrow basins (a lightly damped mode) are then not left to chance.
        let start: Vec<f64> = free.iter().map(|&i| best[i]).collect();
        let mut points = vec![start.clone()];
        let cell = |j: usize, k: usize, m: usize| {
            let (lo, hi) = (obj.bounds().lower()[free[j]], obj.bounds().upper()[free[j]]);
            lo + (hi - lo) * (k as f64 + 0.5) / m as f64
        };
        let (m0, m1) = if free.len() >= 2 { (12, 5) } else { (16, 1) };
        for k0 in 0..m0 {
            for k1 in 0..m1 {
                let mut p = start.clone();
                p[0] = cell(0, k0, m0);
                if m1 > 1 {
                    p[1] = cell(1, k1, m1);
                }
                points.push(p);
            }
        }
        // And each free coordinate a little off its start, on a log scale: a concealed
        // effect is small, far below the grid's first cell.
        for (j, &i) in free.iter().enumerate() {
            let (lo, hi) = (obj.bounds().lower()[i], obj.bounds().upper()[i]);
            for f in [1e-3, 3e-3, 1e-2, 3e-2] {
                for sign in [1.0, -1.0] {
                    let x = start[j] + sign * f * (hi - lo);
                    if x >= lo && x <= hi {
                        let mut p = start.clone();
                        p[j] = x;
                        points.push(p);
                    }
                }
            }
        }
        let seeded = Seeded {
            points,
            inner: PsoConfig {
                swarm: budget.swarm,
                ..PsoConfig::default()
            },
        };
        let rec = run_trial(TrialSpec {
            objective_id: &label,
            optimizer_id: "pso",
            trial: 0,
            objective: restricted,
            optimizer: &seeded,
            budget: budget.global,
            stop_value: None,
            stall: None,
            seed: TrialSeed::derive(seed, &label, "pso", 0),
        });
        evaluations += rec.evaluations;
        for (&i, &v) in free.iter().zip(&rec.best_x) {
            best[i] = v;
        }
        let gain = bic_gain(&rec, explored);
        screened_out = budget.screen > 0.0 && (gain.is_nan() || gain < budget.screen);
    }
    if !best.is_empty() && !screened_out {
        let mut step = 0.05;
        for round in 0..budget.rounds {
            let rec = run_trial(TrialSpec {
                objective_id: &label,
                optimizer_id: "nelder-mead",
                trial: round,
                objective: obj.clone(),
                optimizer: &PolishFrom {
                    x0: best.clone(),
                    step,
                },
                budget: budget.polish,
                stop_value: None,
                // Converged: the last window of evaluations moved BIC (N ln SSE) by less
                // than 0.01, far below any decision margin.
                stall: Some(Stall {
                    window: 60 + 15 * best.len() as u64,
                    rel: 0.01 / n.max(1) as f64,
                }),
                seed: TrialSeed::derive(seed, &label, "nelder-mead", round as u64),
            });
            evaluations += rec.evaluations;
            // A round that gained nothing (below 0.05 BIC units) converged where it
            // started: a smaller simplex from there converges there too.
            let converged = bic_gain(&rec, n) < 0.05;
            // The simplex starts at `best`, so its best is never worse.
            best = rec.best_x;
            step *= 0.3;
            if converged || decided(&best) {
                break;
            }
        }
    }
    Fitted::at(st, best, u, y, evaluations)
}

/// What a run gained over its first evaluation (its start: seeded or the simplex's first
/// vertex), in BIC units on `samples` samples: `N ln(start cost / best)`.
fn bic_gain(rec: &TrialRecord, samples: usize) -> f64 {
    let start_cost = rec.improvements.first().map_or(rec.best, |x| x.1);
    samples as f64 * (start_cost / rec.best).ln()
}

/// Validation SSE/2 of a fitted model as a function of its initial hysteretic state only
/// (the validation recording starts with a history of its own; everything else is held).
struct InitialState {
    st: Structure,
    theta: Vec<f64>,
    coef: Vec<f64>,
    index: usize,
    u: Vec<f64>,
    y: Vec<f64>,
    bounds: Bounds,
}

impl Objective for InitialState {
    fn name(&self) -> &str {
        "initial state"
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn evaluate(&self, x: &[f64]) -> f64 {
        let mut th = self.theta.clone();
        th[self.index] = x[0];
        let (out, _) = self.st.simulate_on(&th, &self.coef, &self.u, &self.y);
        let j: f64 = out
            .iter()
            .zip(&self.y)
            .map(|(m, t)| 0.5 * (t - m) * (t - m))
            .sum();
        if j.is_finite() { j } else { f64::MAX / 4.0 }
    }
}

/// The shape vector of `f` with the initial state (`g0_frac`) fitted to another recording
/// `(u, y)`, by Nelder-Mead through the harness (`budget` evaluations), and the evaluations.
pub fn initial_state_for(
    f: &Fitted,
    u: &[f64],
    y: &[f64],
    budget: u64,
    seed: u64,
) -> (Vec<f64>, u64) {
    let Some(index) = f.structure.specs().iter().position(|s| s.name == "g0_frac") else {
        return (f.theta.clone(), 0);
    };
    let spec = &f.structure.specs()[index];
    let obj: Arc<dyn Objective> = Arc::new(InitialState {
        st: f.structure.clone(),
        theta: f.theta.clone(),
        coef: f.linear.coef.clone(),
        index,
        u: u.to_vec(),
        y: y.to_vec(),
        bounds: Bounds::new(vec![spec.lower], vec![spec.upper]).expect("valid bounds"),
    });
    let label = format!("{} initial state", f.structure.label());
    let rec = run_trial(TrialSpec {
        objective_id: &label,
        optimizer_id: "nelder-mead",
        trial: 0,
        objective: obj,
        optimizer: &PolishFrom {
            x0: vec![0.0],
            step: 0.1,
        },
        budget,
        stop_value: None,
        stall: None,
        seed: TrialSeed::derive(seed, &label, "nelder-mead", 0),
    });
    let mut th = f.theta.clone();
    th[index] = rec.best_x[0];
    (th, rec.evaluations)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::structure::tests::theta_with;
    use crate::physics::structure::{Context, Effect};

    /// `n` samples at 1 kHz of a `hz` sine drive, the plain n = 1 Bouc-Wen structure on it,
    /// the shape that made the record and the record (noiseless).
    fn plain_sine_record(n: usize, hz: f64) -> (Vec<f64>, Structure, Vec<f64>, Vec<f64>) {
        let dt = 1e-3;
        let u: Vec<f64> = (0..n)
            .map(|k| 2.0 + 1.8 * (2.0 * std::f64::consts::PI * hz * k as f64 * dt).sin())
            .collect();
        let plain = Structure::new(&[], Some(1.0), Context::from_training(&u, dt));
        let theta = theta_with(&plain, &[("log10_s", -0.4), ("w", 0.6)]);
        let (y, _) = plain.simulate(&theta, &[0.15, 0.01, 0.05], &u);
        (u, plain, theta, y)
    }

    /// A plain Bouc-Wen record (no asymmetry), and the nested asymmetry candidate started at
    /// the plain optimum: its own parameter cannot gain, so the screen skips the polish; on
    /// a record with asymmetry it gains and the polish runs.
    #[test]
    fn the_screen_skips_the_polish_only_when_the_search_gains_nothing() {
        let (u, plain, theta, clean) = plain_sine_record(3000, 2.0);
        let asym = plain.extended(Effect::Asymmetry);
        let mut th_a = plain.embed(&theta, &asym);
        let q = asym
            .specs()
            .iter()
            .position(|s| s.name == "asym_q")
            .unwrap();
        th_a[q] = 0.1;
        let (skewed, _) = asym.simulate(&th_a, &[0.15, 0.01, 0.05], &u);
        let budget = Budget {
            global: 120,
            swarm: 10,
            polish: 300,
            rounds: 1,
            global_window: 0,
            screen: 2.0,
        };
        let free = [q];
        let start = plain.embed(&theta, &asym);
        let run = |y: Vec<f64>, b: Budget| {
            fit(
                &asym,
                &Arc::new(u.clone()),
                &Arc::new(y),
                Some(&start),
                Some(&free),
                b,
                7,
            )
        };
        let skipped = run(clean.clone(), budget);
        assert_eq!(skipped.evaluations, 120, "only the global stage");
        let unscreened = run(
            clean,
            Budget {
                screen: 0.0,
                ..budget
            },
        );
        assert!(unscreened.evaluations > 120);
        let polished = run(skewed, budget);
        assert!(
            polished.evaluations > 120,
            "a gaining candidate is polished"
        );
        assert!(
            (polished.theta[q] - 0.1).abs() < 0.02,
            "{}",
            polished.theta[q]
        );
    }

    /// A fit that is decided after its first polish round is exactly that round of the
    /// full fit (same shape, same evaluations): stopping early changes nothing before it.
    #[test]
    fn a_fit_decided_after_one_round_is_the_full_fits_first_round() {
        let (u, plain, _, y) = plain_sine_record(2000, 3.0);
        let start = theta_with(&plain, &[("log10_s", -0.2), ("w", 0.4)]);
        let budget = |rounds| Budget {
            global: 0,
            swarm: 1,
            polish: 150,
            rounds,
            global_window: 0,
            screen: 0.0,
        };
        let (u, y) = (Arc::new(u), Arc::new(y));
        let run = |rounds, decided: &mut dyn FnMut(&[f64]) -> bool| {
            fit_until(
                &plain,
                &u,
                &y,
                Some(&start),
                None,
                budget(rounds),
                3,
                decided,
            )
        };
        let mut asked = 0;
        let stopped = run(3, &mut |_| {
            asked += 1;
            true
        });
        let one = run(1, &mut |_| false);
        let full = run(3, &mut |_| false);
        assert_eq!(asked, 1);
        assert_eq!(stopped.theta, one.theta);
        assert_eq!(stopped.evaluations, one.evaluations);
        assert!(
            full.evaluations > one.evaluations,
            "the full fit polishes on"
        );
        assert!(full.linear.cost <= one.linear.cost);
    }
}
