//! The classical Preisach model on a discretised weight plane (dissertation §2.1.1, eq. 2.5-2.6):
//! a triangle of relay operators whose weighted sum is the output. For a fixed grid the
//! output is linear in the weights, so identification is a non-negative least-squares
//! problem with an exact optimum ([`Preisach::fit`], and [`LinearInWeights`] for the fitting
//! objectives).
//!
//! # Grid
//!
//! The input range `[u_min, u_max]` is cut into `N` equal cells of width `Δ`; the thresholds
//! are the cell centres `t_k = u_min + (k + ½)Δ`, `k = 0..N`. Relay `(i, j)`, `j ≤ i`, switches
//! up at `α = t_i` and down at `β = t_j`: its output becomes 1 when `u ≥ α`, 0 when `u < β`,
//! and otherwise keeps its value (the diagonal `i = j` is memoryless: `u ≥ t_i`). That is
//! `N(N+1)/2` relays, one per cell of the dissertation's discretised Preisach plane, and
//! `y = offset + Σ μ_ij R_ij[u]` with `μ_ij ≥ 0` (its eq. 2.6 with 0/1 cells: the `-Σμ'`
//! term is the offset). Centred thresholds put every relay inside the range, so `u_min`
//! switches all off and `u_max` all on: the training range is the model's saturation range.
//!
//! # State and initial state
//!
//! In row `i` (fixed `α`) the relays that are on are those with the smallest `β` (same
//! up-switch, and a lower down-switch is harder to reach), so the state is `k_i`, the number
//! of relays on in row `i`: the staircase interface of the Preisach plane, `N` integers. An
//! input step to level `L = #{k : t_k ≤ u}` fills rows `i < L` and cuts every row to at most
//! `L`; only rows whose count changes are touched (the rows above `L` are non-increasing,
//! so the cut stops at the first row already below it).
//!
//! The model starts **demagnetised at its first input sample** `u₀`: relay `(i, j)` is on iff
//! `t_i + t_j ≤ 2u₀`, the state a decaying alternating input ending at `u₀` leaves (the
//! interface along the anti-diagonal through `(u₀, u₀)`). A record that starts mid-range has
//! no preferred branch, and this state lies between the ascending and descending ones;
//! by wiping-out it is forgotten once the input has visited the record's maximum and minimum
//! (every relay's state is then set by the record alone). For a record starting at `u_min`
//! (the dissertation's experiments start at their bottom) it is negative saturation.
//!
//! # Memory
//!
//! Like every Preisach model it has the two properties Mayergoyz showed to characterise it:
//! **wiping-out** (when the input returns to a previous dominant extremum, the state is the
//! one it had there, so nested minor loops leave no trace) and **congruency** (minor loops
//! between the same two inputs are congruent whatever the history). The tests check both
//! on this implementation and show the Bouc-Wen model violates congruency.

use crate::base::lstsq::nnls;
use crate::physics::prandtl_ishlinskii::LinearInWeights;
use std::collections::HashMap;

/// Largest number of levels: `N(N+1)/2` relays, so 200 levels are 20,100 weights, already
/// more than any recording here identifies.
pub const MAX_LEVELS: usize = 200;

/// The relay grid: `levels` equal cells over `[u_min, u_max]`, thresholds at the cell centres.
/// The model's shape, fixed before a fit ([`LinearInWeights`]); stored as its three numbers.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "GridSpec", into = "GridSpec")]
pub struct PreisachGrid {
    u_min: f64,
    u_max: f64,
    /// `t_k`, increasing, `levels` of them.
    thresholds: Vec<f64>,
}

/// What a model file holds of a grid.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct GridSpec {
    levels: usize,
    u_min: f64,
    u_max: f64,
}

impl TryFrom<GridSpec> for PreisachGrid {
    type Error = String;
    fn try_from(g: GridSpec) -> Result<Self, String> {
        PreisachGrid::new(g.levels, g.u_min, g.u_max)
    }
}

impl From<PreisachGrid> for GridSpec {
    fn from(g: PreisachGrid) -> Self {
        GridSpec {
            levels: g.levels(),
            u_min: g.u_min,
            u_max: g.u_max,
        }
    }
}

impl PreisachGrid {
    /// `levels` cells over `[u_min, u_max]`.
    pub fn new(levels: usize, u_min: f64, u_max: f64) -> Result<Self, String> {
        if levels == 0 || levels > MAX_LEVELS {
            return Err(format!(
                "Preisach grid: {levels} levels; expected 1 to {MAX_LEVELS} (the model has \
                 levels·(levels+1)/2 relays)"
            ));
        }
        if !(u_min.is_finite() && u_max.is_finite() && u_max > u_min) {
            return Err(format!(
                "Preisach grid: input range [{u_min}, {u_max}]; expected finite bounds with \
                 u_max > u_min (a training input that varies)"
            ));
        }
        let cell = (u_max - u_min) / levels as f64;
        let thresholds = (0..levels)
            .map(|k| u_min + (k as f64 + 0.5) * cell)
            .collect();
        Ok(PreisachGrid {
            u_min,
            u_max,
            thresholds,
        })
    }

    /// `levels` cells over the range of the training input `u`.
    pub fn for_input(levels: usize, u: &[f64]) -> Result<Self, String> {
        if let Some(k) = u.iter().position(|x| !x.is_finite()) {
            return Err(format!(
                "Preisach grid: input sample {k} is {}; expected finite inputs",
                u[k]
            ));
        }
        let lo = u.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = u.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Self::new(levels, lo, hi)
    }

    pub fn levels(&self) -> usize {
        self.thresholds.len()
    }

    pub fn u_min(&self) -> f64 {
        self.u_min
    }

    pub fn u_max(&self) -> f64 {
        self.u_max
    }

    /// The switching thresholds `t_k` (cell centres), increasing.
    pub fn thresholds(&self) -> &[f64] {
        &self.thresholds
    }

    /// Number of relays, `N(N+1)/2`.
    pub fn relays(&self) -> usize {
        let n = self.levels();
        n * (n + 1) / 2
    }

    /// Index of relay `(i, j)` (`j ≤ i`) in the weight vector: row by row.
    pub fn index(i: usize, j: usize) -> usize {
        debug_assert!(j <= i);
        i * (i + 1) / 2 + j
    }

    /// `L = #{k : t_k ≤ u}`: the relays with `α ≤ u` are on, those with `β > u` off.
    fn level(&self, u: f64) -> usize {
        self.thresholds.partition_point(|&t| t <= u)
    }

    /// The model with coefficients `theta` (in [`LinearInWeights::columns`] order: the
    /// relays, then the offset).
    pub fn model(&self, theta: &[f64]) -> Result<Preisach, String> {
        let m = self.relays();
        if theta.len() != m + 1 {
            return Err(format!(
                "Preisach weights: {} values; expected {} ({} relays and the offset)",
                theta.len(),
                m + 1,
                m
            ));
        }
        Ok(Preisach {
            grid: self.clone(),
            weights: theta[..m].to_vec(),
            offset: theta[m],
        })
    }

    /// The demagnetised interface at `u0`: row `i` has the relays `t_i + t_j ≤ 2u0` on.
    fn demagnetised(&self, u0: f64) -> Vec<usize> {
        let t = &self.thresholds;
        (0..t.len())
            .map(|i| t[..=i].partition_point(|&tj| t[i] + tj <= 2.0 * u0))
            .collect()
    }
}

/// A discretised Preisach model: relay weights `μ_ij ≥ 0` on a [`PreisachGrid`] and an
/// output offset.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "PreisachFile")]
pub struct Preisach {
    pub grid: PreisachGrid,
    /// `μ_ij` at [`PreisachGrid::index`]`(i, j)`, output units per relay.
    pub weights: Vec<f64>,
    pub offset: f64,
}

/// A model file's fields, checked against each other before they make a model.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct PreisachFile {
    grid: PreisachGrid,
    weights: Vec<f64>,
    offset: f64,
}

impl TryFrom<PreisachFile> for Preisach {
    type Error = String;
    fn try_from(f: PreisachFile) -> Result<Self, String> {
        if let Some(k) = f.weights.iter().position(|w| !w.is_finite()) {
            return Err(format!(
                "Preisach weights: weight {k} is {}; expected finite weights",
                f.weights[k]
            ));
        }
        let mut theta = f.weights;
        theta.push(f.offset);
        f.grid.model(&theta)
    }
}

impl Preisach {
    /// The weights in [`LinearInWeights`] column order: the relays, then the offset.
    pub fn theta(&self) -> Vec<f64> {
        let mut t = self.weights.clone();
        t.push(self.offset);
        t
    }

    /// The least-squares optimum on `(u, y)`: `levels` cells over the range of `u`, weights
    /// `≥ 0`, offset free. `dt` is unused (the model is rate-independent); it is there so every
    /// operator model fits alike.
    ///
    /// Samples in the same relay state give the same model output, so they are merged into
    /// one row (their mean, weighted by the square root of their count) before the NNLS: the
    /// same minimiser, on as many rows as the record has distinct states (a periodic input
    /// has about `2N` per period) instead of samples.
    pub fn fit(levels: usize, u: &[f64], y: &[f64], dt: f64) -> Result<Preisach, String> {
        let _ = dt;
        if u.len() != y.len() || u.is_empty() {
            return Err(format!(
                "Preisach fit: {} inputs and {} outputs; expected as many of each, at least one",
                u.len(),
                y.len()
            ));
        }
        if let Some(k) = y.iter().position(|x| !x.is_finite()) {
            return Err(format!(
                "Preisach fit: output sample {k} is {}; expected finite outputs",
                y[k]
            ));
        }
        let grid = PreisachGrid::for_input(levels, u)?;
        // Distinct interfaces, each with its sample count and output sum.
        let mut groups: HashMap<Vec<usize>, usize> = HashMap::new();
        let mut states: Vec<(Vec<usize>, f64, f64)> = Vec::new();
        let mut st = PreisachStepper::new(grid.clone(), &vec![0.0; grid.relays()], 0.0);
        for (&x, &yk) in u.iter().zip(y) {
            st.step(x);
            let g = *groups.entry(st.up.clone()).or_insert_with(|| {
                states.push((st.up.clone(), 0.0, 0.0));
                states.len() - 1
            });
            states[g].1 += 1.0;
            states[g].2 += yk;
        }
        let m = grid.relays();
        let mut cols = vec![vec![0.0; states.len()]; m + 1];
        let mut target = Vec::with_capacity(states.len());
        for (g, (up, count, sum)) in states.iter().enumerate() {
            let w = count.sqrt();
            for (i, &k) in up.iter().enumerate() {
                for j in 0..k {
                    cols[PreisachGrid::index(i, j)][g] = w;
                }
            }
            cols[m][g] = w;
            target.push(sum / w);
        }
        grid.model(&nnls(&cols, &target, &grid.nonnegative()))
    }

    /// A stepper from the initial state (demagnetised at its first input).
    pub fn stepper(&self) -> PreisachStepper {
        PreisachStepper::new(self.grid.clone(), &self.weights, self.offset)
    }

    /// Free run over `u` from the initial state. `dt` is unused (rate-independent).
    pub fn simulate(&self, u: &[f64], dt: f64) -> Vec<f64> {
        let _ = dt;
        let mut st = self.stepper();
        u.iter().map(|&x| st.step(x)).collect()
    }
}

/// One-sample stepping of a [`Preisach`] model (for control loops), by its interface.
#[derive(Clone, Debug)]
pub struct PreisachStepper {
    grid: PreisachGrid,
    /// Row `i`'s prefix sums of weights start at `i(i+3)/2`.
    prefix: Vec<f64>,
    /// `full[L]`: the weights of rows `< L`, all on at level `L`.
    full: Vec<f64>,
    offset: f64,
    /// `k_i`, relays on in row `i`; empty before the first step.
    up: Vec<usize>,
    /// The input's level at the last step.
    level: usize,
}

impl PreisachStepper {
    fn new(grid: PreisachGrid, weights: &[f64], offset: f64) -> Self {
        let n = grid.levels();
        // Row i's prefix sums Σ_{j<k} μ_ij, k = 0..=i+1, rows concatenated.
        let mut prefix = Vec::with_capacity(grid.relays() + n);
        let mut full = Vec::with_capacity(n + 1);
        full.push(0.0);
        for i in 0..n {
            let mut s = 0.0;
            prefix.push(0.0);
            for j in 0..=i {
                s += weights[PreisachGrid::index(i, j)];
                prefix.push(s);
            }
            full.push(full[i] + s);
        }
        PreisachStepper {
            grid,
            prefix,
            full,
            offset,
            up: Vec::new(),
            level: 0,
        }
    }

    /// Applies input `u` and returns the output. The first call sets the initial state
    /// (demagnetised at `u`).
    pub fn step(&mut self, u: f64) -> f64 {
        let l = self.grid.level(u);
        if self.up.is_empty() {
            self.up = self.grid.demagnetised(u);
        } else if l > self.level {
            // Rising: rows with α in (previous input, u] switch fully on.
            for i in self.level..l {
                self.up[i] = i + 1;
            }
        } else if l < self.level {
            // Falling: relays with β > u switch off; rows above the old level are
            // non-increasing, so the first one already at most `l` ends the cut.
            for i in l..self.level {
                self.up[i] = l;
            }
            for k in &mut self.up[self.level..] {
                if *k <= l {
                    break;
                }
                *k = l;
            }
        }
        self.level = l;
        self.output()
    }

    /// The output of the current state, summed afresh (a function of the state alone, so
    /// a state revisited gives the same output bit for bit): the full rows below the level,
    /// then the partial rows up to the first empty one.
    fn output(&self) -> f64 {
        let mut s = self.full[self.level];
        for (i, &k) in self.up.iter().enumerate().skip(self.level) {
            if k == 0 {
                break;
            }
            s += self.prefix[i * (i + 3) / 2 + k];
        }
        self.offset + s
    }

    /// The interface: relays on per row (`k_i`), empty before the first step.
    pub fn interface(&self) -> &[usize] {
        &self.up
    }
}

impl LinearInWeights for PreisachGrid {
    /// Each relay's output (0 or 1) over `u` from the initial state, then the offset's
    /// column of ones.
    fn columns(&self, u: &[f64], _dt: f64) -> Vec<Vec<f64>> {
        let m = self.relays();
        let mut cols = vec![vec![0.0; u.len()]; m + 1];
        let mut st = PreisachStepper::new(self.clone(), &vec![0.0; m], 0.0);
        for (t, &x) in u.iter().enumerate() {
            st.step(x);
            for (i, &k) in st.up.iter().enumerate() {
                for j in 0..k {
                    cols[PreisachGrid::index(i, j)][t] = 1.0;
                }
            }
        }
        cols[m].fill(1.0);
        cols
    }

    /// Relay weights are non-negative (a negative one would turn its loop the wrong way);
    /// the offset is free.
    fn nonnegative(&self) -> Vec<bool> {
        let mut v = vec![true; self.relays()];
        v.push(false);
        v
    }

    /// `mu[i,j]` for the relay switching up at `t_i` and down at `t_j`, then `d0`.
    fn names(&self) -> Vec<String> {
        let n = self.levels();
        let mut v: Vec<String> = (0..n)
            .flat_map(|i| (0..=i).map(move |j| format!("mu[{i},{j}]")))
            .collect();
        v.push("d0".into());
        v
    }
}

#[cfg(test)]
mod tests;
