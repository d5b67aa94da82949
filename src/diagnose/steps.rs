//! Creep told from drift by what the drive does. After the drive moves and holds, a
//! piezo's creep carries the output on in the direction of the move, by an amount that
//! scales with the move and slows like a logarithm; a sensor drift does not care where the
//! drive went. So the residual's change over each hold, set against the move before it,
//! separates the two: proportional to the move (up holds against down holds of opposite
//! sign) is creep's signature, the same way after up and down moves is a drift's. The
//! significance is exact: the moves' signs flipped at random (all 2^k flips for up to 14
//! holds) give the statistic's distribution when the residual ignores the drive.

use crate::base::TrialSeed;
use rand::RngExt;
use serde::Serialize;

/// A hold of the drive after a move: where it starts, its samples, and the move (input
/// units: the level at the hold against the level before the move).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hold {
    pub at: usize,
    pub len: usize,
    pub step: f64,
}

/// Share of the drive's range the input may wander and still hold.
const HOLD_TOL: f64 = 0.01;
/// Share of the drive's range a move must cover to count.
const MOVE_MIN: f64 = 0.1;
/// Shortest hold (s) and fewest samples of one.
const HOLD_MIN_S: f64 = 0.5;
const HOLD_MIN_SAMPLES: usize = 10;

/// The holds of input `u` sampled every `dt`: stretches of at least half a second (and ten
/// samples) where the input stays within 1 % of its range, reached by a move of at least
/// 10 % of the range (a step, or a ramp that stops).
pub fn holds(u: &[f64], dt: f64) -> Vec<Hold> {
    let n = u.len();
    let (lo, hi) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let range = hi - lo;
    if n < 2 * HOLD_MIN_SAMPLES || range.is_nan() || range <= 0.0 {
        return Vec::new();
    }
    let tol = HOLD_TOL * range;
    let min_len = ((HOLD_MIN_S / dt).round() as usize).max(HOLD_MIN_SAMPLES);
    let mut out = Vec::new();
    let mut k = 1;
    while k + min_len <= n {
        let level = u[k];
        let len = u[k..]
            .iter()
            .take_while(|&&x| (x - level).abs() <= tol)
            .count();
        if len < min_len {
            k += 1;
            continue;
        }
        // The move: the level at the hold against the input a hold's shortest length
        // before it (a step's old level, a ramp's start or part of it).
        let before = u[k.saturating_sub(min_len)..k]
            .iter()
            .copied()
            .fold(level, |m, x| {
                if (x - level).abs() > (m - level).abs() {
                    x
                } else {
                    m
                }
            });
        let step = level - before;
        if step.abs() >= MOVE_MIN * range {
            out.push(Hold { at: k, len, step });
        }
        k += len;
    }
    out
}

/// What the residual did over the drive's holds.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StepEvidence {
    /// Holds after an upward and after a downward move.
    pub up: usize,
    pub down: usize,
    /// Mean change of the residual over an up hold and over a down hold, per unit of the
    /// (signed) move, output unit per input unit: creep gives the same sign both ways, a
    /// drift opposite signs.
    pub per_unit_up: f64,
    pub per_unit_down: f64,
    /// Correlation (through the origin) of the residual's change over each hold with the
    /// move before it: 1 is a change exactly proportional to the move.
    pub correlation: f64,
    /// Share of sign flips of the moves with a correlation at least as large in magnitude.
    pub p_value: f64,
    /// Student t of the mean change over all holds whatever the move's sign (a drift's).
    pub common_t: f64,
    /// `follows the steps`, `ignores the steps`, `nothing step-locked` or `too few holds`.
    pub verdict: String,
}

/// The verdict of a residual that follows the steps (creep's signature).
pub const FOLLOWS: &str = "follows the steps";

/// Level of the sign-flip test and of the common change's t.
const STEP_ALPHA: f64 = 0.05;
const COMMON_T: f64 = 3.0;

/// The residual `e`'s change over one hold: its last quarter against its first tenth, after
/// a settle of a tenth of the hold (at most 0.1 s).
fn change_over(h: &Hold, e: &[f64], dt: f64) -> f64 {
    let settle = (h.len / 10).min(((0.1 / dt).round() as usize).max(1));
    let w = &e[h.at + settle..h.at + h.len];
    let head = (w.len() / 10).max(1);
    let tail = (w.len() / 4).max(1);
    mean(&w[w.len() - tail..]) - mean(&w[..head])
}

/// Each hold of `u` ([`holds`]) and the residual `e`'s change over it: the points the step
/// evidence rests on (and its figure shows), whether or not there are enough for a verdict.
pub fn hold_changes(u: &[f64], e: &[f64], dt: f64) -> Vec<(Hold, f64)> {
    holds(&u[..u.len().min(e.len())], dt)
        .into_iter()
        .map(|h| (h, change_over(&h, e, dt)))
        .collect()
}

/// The residual `e`'s change over each hold of `u` ([`hold_changes`]) against the moves.
/// `None` without holds both ways (two up and two down at least, five in all).
pub fn step_evidence(u: &[f64], e: &[f64], dt: f64, seed: u64) -> Option<StepEvidence> {
    let points = hold_changes(u, e, dt);
    let up = points.iter().filter(|p| p.0.step > 0.0).count();
    let down = points.len() - up;
    if up < 2 || down < 2 || points.len() < 5 {
        return None;
    }
    let d: Vec<f64> = points.iter().map(|p| p.1).collect();
    let x: Vec<f64> = points.iter().map(|p| p.0.step).collect();
    let corr = |signs: &[f64]| {
        let sxd: f64 = x
            .iter()
            .zip(&d)
            .zip(signs)
            .map(|((x, d), s)| s * x * d)
            .sum();
        let sxx: f64 = x.iter().map(|x| x * x).sum();
        let sdd: f64 = d.iter().map(|d| d * d).sum();
        if sxx > 0.0 && sdd > 0.0 {
            sxd / (sxx * sdd).sqrt()
        } else {
            0.0
        }
    };
    let k = x.len();
    let r = corr(&vec![1.0; k]);
    let flips: Vec<Vec<f64>> = if k <= 14 {
        (0..1u32 << k)
            .map(|m| {
                (0..k)
                    .map(|i| if m >> i & 1 == 1 { -1.0 } else { 1.0 })
                    .collect()
            })
            .collect()
    } else {
        let mut rng = TrialSeed::derive(seed, "diagnose", "step-flips", 0).rng(0);
        (0..4000)
            .map(|_| {
                (0..k)
                    .map(|_| if rng.random::<bool>() { -1.0 } else { 1.0 })
                    .collect()
            })
            .collect()
    };
    let at_least = flips
        .iter()
        .filter(|s| corr(s).abs() >= r.abs() - 1e-12)
        .count();
    let p = at_least as f64 / flips.len() as f64;
    let per = |sign: f64| {
        let v: Vec<f64> = x
            .iter()
            .zip(&d)
            .filter(|(x, _)| x.signum() == sign)
            .map(|(x, d)| d / x)
            .collect();
        mean(&v)
    };
    let m = mean(&d);
    let sd = (d.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (k - 1) as f64).sqrt();
    let t = if sd > 0.0 {
        m / (sd / (k as f64).sqrt())
    } else {
        0.0
    };
    let verdict = if p <= STEP_ALPHA {
        FOLLOWS
    } else if t.abs() >= COMMON_T {
        "ignores the steps"
    } else {
        "nothing step-locked"
    };
    Some(StepEvidence {
        up,
        down,
        per_unit_up: per(1.0),
        per_unit_down: per(-1.0),
        correlation: r,
        p_value: p,
        common_t: t,
        verdict: verdict.to_string(),
    })
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::base::standard_normal;

    /// Steps between random levels every `hold` seconds, sampled every `dt`.
    pub(in crate::diagnose) fn staircase(levels: &[f64], hold: f64, dt: f64) -> Vec<f64> {
        let per = (hold / dt).round() as usize;
        levels
            .iter()
            .flat_map(|&l| std::iter::repeat_n(l, per))
            .collect()
    }

    /// Logarithmic creep after each step (gain `g` per decade from 10 ms), an independent
    /// sum over the steps so far.
    fn creep(u: &[f64], dt: f64, g: f64) -> Vec<f64> {
        let mut steps = Vec::new();
        (0..u.len())
            .map(|k| {
                if k > 0 && u[k] != u[k - 1] {
                    steps.push((k, u[k] - u[k - 1]));
                }
                steps
                    .iter()
                    .map(|&(at, du)| g * du * (1.0 + (k - at) as f64 * dt / 0.01).log10())
                    .sum()
            })
            .collect()
    }

    fn noisy(v: &[f64], sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = TrialSeed::derive(seed, "steps", "noise", 0).rng(0);
        v.iter()
            .map(|x| x + sigma * standard_normal(&mut rng))
            .collect()
    }

    const LEVELS: [f64; 9] = [0.0, 80.0, 20.0, 100.0, 40.0, 90.0, 10.0, 60.0, 30.0];

    #[test]
    fn holds_are_found_after_steps_and_ramps_and_not_on_a_sine() {
        let dt = 0.01;
        let u = staircase(&LEVELS, 5.0, dt);
        let h = holds(&u, dt);
        assert_eq!(h.len(), LEVELS.len() - 1);
        assert_eq!((h[0].at, h[0].step), (500, 80.0));
        assert_eq!(h[1].step, -60.0);
        // A ramp that stops is a move too.
        let mut r: Vec<f64> = (0..300).map(|k| k as f64 / 3.0).collect();
        r.extend(std::iter::repeat_n(100.0, 300));
        let h = holds(&r, dt);
        assert!(
            h.len() == 1 && (295..=301).contains(&h[0].at) && h[0].step > 10.0,
            "{h:?}"
        );
        let sine: Vec<f64> = (0..2000).map(|k| (k as f64 * dt).sin()).collect();
        assert!(holds(&sine, dt).is_empty());
    }

    #[test]
    fn creep_follows_the_steps_and_a_drift_does_not() {
        let dt = 0.01;
        let u = staircase(&LEVELS, 5.0, dt);
        let sigma = 0.05;
        // Creep: 0.5 % of the step per decade, the residual a plain model leaves.
        let e = noisy(&creep(&u, dt, 0.005), sigma, 1);
        let s = step_evidence(&u, &e, dt, 1).expect("holds both ways");
        assert_eq!(s.verdict, "follows the steps", "{s:?}");
        assert!(s.per_unit_up > 0.0 && s.per_unit_down > 0.0, "{s:?}");
        assert!(s.correlation > 0.9 && s.p_value <= 0.01, "{s:?}");
        // A sensor drift of the same size over each hold, rising whatever the drive does.
        let drift: Vec<f64> = (0..u.len()).map(|k| 0.12 * k as f64 * dt / 5.0).collect();
        let e = noisy(&drift, sigma, 2);
        let s = step_evidence(&u, &e, dt, 1).expect("holds both ways");
        assert_eq!(s.verdict, "ignores the steps", "{s:?}");
        assert!(s.p_value > 0.05, "{s:?}");
        // Noise alone: nothing step-locked (and the flips make p exact, not small).
        let e = noisy(&vec![0.0; u.len()], sigma, 3);
        let s = step_evidence(&u, &e, dt, 1).expect("holds both ways");
        assert_eq!(s.verdict, "nothing step-locked", "{s:?}");
        // Steps one way only cannot tell.
        let mono = staircase(&[0.0, 20.0, 40.0, 60.0, 80.0, 100.0], 5.0, dt);
        assert!(step_evidence(&mono, &noisy(&vec![0.0; mono.len()], sigma, 4), dt, 1).is_none());
    }
}
