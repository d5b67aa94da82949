use super::*;
use crate::base::TrialSeed;
use crate::physics::bouc_wen::{BoucWenKernel, BoucWenState};
use crate::physics::twin::TwinConfig;
use rand::RngExt;

/// A model on `levels` cells over `[lo, hi]` with weights uniform in `[0.5, 1.5]` and offset
/// `-0.3` (all weights positive, so the unconstrained optimum is the NNLS one).
fn random_model(levels: usize, lo: f64, hi: f64, seed: u64) -> Preisach {
    let mut rng = TrialSeed::from_u64(seed).rng(0);
    let grid = PreisachGrid::new(levels, lo, hi).unwrap();
    let mut theta: Vec<f64> = (0..grid.relays())
        .map(|_| 0.5 + rng.random::<f64>())
        .collect();
    theta.push(-0.3);
    grid.model(&theta).unwrap()
}

/// Samples through `points` by straight segments of steps at most `h`, each point hit exactly.
fn ramp(points: &[f64], h: f64) -> Vec<f64> {
    let mut u = vec![points[0]];
    for w in points.windows(2) {
        let n = ((w[1] - w[0]).abs() / h).ceil().max(1.0) as usize;
        u.extend((1..n).map(|k| w[0] + (w[1] - w[0]) * k as f64 / n as f64));
        u.push(w[1]);
    }
    u
}

/// The independent code path: every relay kept and switched by its own rule, each step.
struct BruteForce<'a> {
    m: &'a Preisach,
    on: Vec<bool>,
}

impl<'a> BruteForce<'a> {
    fn new(m: &'a Preisach) -> Self {
        BruteForce { m, on: Vec::new() }
    }

    fn step(&mut self, u: f64) -> f64 {
        let t = self.m.grid.thresholds();
        let n = t.len();
        if self.on.is_empty() {
            // Demagnetised at the first input.
            self.on = (0..n)
                .flat_map(|i| (0..=i).map(move |j| (i, j)))
                .map(|(i, j)| t[i] + t[j] <= 2.0 * u)
                .collect();
        }
        let mut y = self.m.offset;
        for i in 0..n {
            for j in 0..=i {
                let r = &mut self.on[PreisachGrid::index(i, j)];
                if u >= t[i] {
                    *r = true;
                } else if u < t[j] {
                    *r = false;
                }
                if *r {
                    y += self.m.weights[PreisachGrid::index(i, j)];
                }
            }
        }
        y
    }

    /// The interface read off the relays: the count of relays on per row.
    fn interface(&self) -> Vec<usize> {
        let n = self.m.grid.levels();
        (0..n)
            .map(|i| {
                (0..=i)
                    .filter(|&j| self.on[PreisachGrid::index(i, j)])
                    .count()
            })
            .collect()
    }
}

/// A random input over and beyond `[lo, hi]`: jumps, small moves, repeats, and the exact
/// thresholds (where the relay rule's ties are).
fn random_input(m: &Preisach, len: usize, seed: u64) -> Vec<f64> {
    let mut rng = TrialSeed::from_u64(seed).rng(1);
    let (lo, hi) = (m.grid.u_min(), m.grid.u_max());
    let t = m.grid.thresholds().to_vec();
    let mut u = vec![lo + (hi - lo) * rng.random::<f64>()];
    for _ in 1..len {
        let prev = *u.last().unwrap();
        let x = match rng.random_range(0..5) {
            0 => lo - 0.2 * (hi - lo) + 1.4 * (hi - lo) * rng.random::<f64>(),
            1 => t[rng.random_range(0..t.len())],
            2 => prev,
            _ => prev + 0.1 * (hi - lo) * (rng.random::<f64>() - 0.5),
        };
        u.push(x);
    }
    u
}

#[test]
fn interface_matches_every_relay() {
    for (levels, seed) in [(1, 1), (2, 2), (7, 3), (25, 4)] {
        let m = random_model(levels, -1.0, 2.5, seed);
        for start in 0..3 {
            let u = random_input(&m, 3000, seed * 10 + start);
            let mut fast = m.stepper();
            let mut brute = BruteForce::new(&m);
            for (k, &x) in u.iter().enumerate() {
                let (a, b) = (fast.step(x), brute.step(x));
                assert_eq!(
                    fast.interface(),
                    brute.interface(),
                    "levels {levels}, sample {k}"
                );
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
            }
        }
    }
}

#[test]
fn columns_sum_to_the_output() {
    let m = random_model(9, 0.0, 4.7, 5);
    let u = random_input(&m, 800, 6);
    let cols = m.grid.columns(&u, 1e-3);
    assert_eq!(cols.len(), m.grid.relays() + 1);
    assert_eq!(m.grid.names().len(), cols.len());
    assert_eq!(m.grid.nonnegative().iter().filter(|&&b| !b).count(), 1);
    let theta = m.theta();
    let y = m.simulate(&u, 1e-3);
    for (t, &yt) in y.iter().enumerate() {
        let s: f64 = cols.iter().zip(&theta).map(|(c, w)| c[t] * w).sum();
        assert!((s - yt).abs() < 1e-12 * (1.0 + yt.abs()));
        assert!(cols.iter().all(|c| c[t] == 0.0 || c[t] == 1.0));
    }
}

#[test]
fn initial_state_is_demagnetised_at_the_first_input() {
    let m = random_model(10, 0.0, 4.7, 7);
    // From the bottom of the range: negative saturation, every relay off.
    assert_eq!(m.simulate(&[0.0], 1e-3)[0], m.offset);
    // From the top: every relay on.
    let all: f64 = m.weights.iter().sum();
    assert!((m.simulate(&[4.7], 1e-3)[0] - m.offset - all).abs() < 1e-12);
    // Mid-range: the relays below the anti-diagonal through (u0, u0).
    let t = m.grid.thresholds();
    let u0 = 2.0;
    let mut want = m.offset;
    for i in 0..t.len() {
        for j in 0..=i {
            if t[i] + t[j] <= 2.0 * u0 {
                want += m.weights[PreisachGrid::index(i, j)];
            }
        }
    }
    assert!((m.simulate(&[u0], 1e-3)[0] - want).abs() < 1e-12);
    // Forgotten once the input has visited the range's top and bottom: two records
    // starting mid-range at different inputs agree from then on, bit for bit.
    let tail = ramp(&[4.7, 0.0, 3.1, 1.2, 4.0], 0.05);
    let a = m.simulate(&[&[1.3][..], &tail].concat(), 1e-3);
    let b = m.simulate(&[&[3.8, 2.2][..], &tail].concat(), 1e-3);
    assert_ne!(a[0], b[1]);
    assert_eq!(a[1..], b[2..]);
}

/// A stepper of some hysteresis model from its initial state at the first input.
type Stepper = Box<dyn FnMut(f64) -> f64>;

fn preisach_stepper(m: &Preisach) -> impl Fn() -> Stepper + '_ {
    move || {
        let mut st = m.stepper();
        Box::new(move |u| st.step(u))
    }
}

/// The twin's Bouc-Wen on the command scale (0..4.7 V), from `h = 0` at the first input.
fn bouc_wen_stepper() -> Stepper {
    let k = BoucWenKernel::new(&TwinConfig::default().command_scale_bouc_wen());
    let mut st: Option<BoucWenState> = None;
    Box::new(move |u| st.get_or_insert(BoucWenState::new(u)).step_with(&k, u))
}

/// The most the minor loop `u1 → u2 → u1` (steps of 0.01), reached by each of `histories`
/// (each ending with a reversal from `u2` to `u1`, so the loop is closed), differs between
/// histories in its output measured from the loop's start, over the loop's output span: 0
/// for congruent loops.
fn congruency_gap(new: &dyn Fn() -> Stepper, histories: &[Vec<f64>], u1: f64, u2: f64) -> f64 {
    let lp = ramp(&[u1, u2, u1], 0.01);
    let loops: Vec<Vec<f64>> = histories
        .iter()
        .map(|h| {
            let mut s = new();
            h.iter().for_each(|&x| {
                s(x);
            });
            let y: Vec<f64> = lp.iter().map(|&x| s(x)).collect();
            y.iter().map(|v| v - y[0]).collect()
        })
        .collect();
    let span = loops[0].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let gap = loops[1..]
        .iter()
        .flat_map(|l| l.iter().zip(&loops[0]).map(|(a, b)| (a - b).abs()))
        .fold(0.0f64, f64::max);
    gap / span
}

/// Outputs of the suffix after `prefix` with and without `nested` minor loops inserted
/// (both end at the prefix's last input, a dominant maximum): the largest difference over
/// the output span. 0 when the nested loops are wiped out.
fn wiping_gap(new: &dyn Fn() -> Stepper, prefix: &[f64], nested: &[f64], suffix: &[f64]) -> f64 {
    let run = |seq: Vec<f64>| -> Vec<f64> {
        let mut s = new();
        let y: Vec<f64> = seq.iter().map(|&x| s(x)).collect();
        y[y.len() - suffix.len()..].to_vec()
    };
    let a = run([prefix, nested, suffix].concat());
    let b = run([prefix, suffix].concat());
    let span =
        b.iter().fold(f64::MIN, |m, &v| m.max(v)) - b.iter().fold(f64::MAX, |m, &v| m.min(v));
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        / span
}

/// The minor-loop experiments: histories reaching `u2 = 3.0` by the major ascending branch,
/// from the top, after a reversal below `u1 = 1.5`, and after a first-order reversal curve,
/// each then down to `u1`.
fn histories() -> Vec<Vec<f64>> {
    [
        vec![0.0, 3.0, 1.5],
        vec![0.0, 4.7, 3.0, 1.5],
        vec![0.0, 4.7, 0.6, 3.0, 1.5],
        vec![0.0, 4.7, 0.0, 2.0, 0.8, 3.0, 1.5],
    ]
    .iter()
    .map(|p| ramp(p, 0.01))
    .collect()
}

fn nested() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    // After the dominant minimum 0.4 and maximum 4.0: loops nested inside (0.4, 4.0),
    // back to 4.0, then a suffix that goes below the minimum and above the maximum.
    let prefix = ramp(&[0.0, 4.7, 0.4, 4.0], 0.01);
    let nested = ramp(&[4.0, 1.0, 3.5, 1.5, 3.0, 2.0, 2.5, 4.0], 0.01);
    let suffix = ramp(&[4.0, 1.2, 3.3, 0.2, 4.5, 1.0], 0.01);
    (prefix, nested[1..].to_vec(), suffix[1..].to_vec())
}

#[test]
fn nested_minor_loops_are_wiped_out() {
    let m = random_model(12, 0.0, 4.7, 8);
    let (prefix, nested, suffix) = nested();
    // The state back at the dominant maximum is the one before the loops, relay for relay.
    let mut a = m.stepper();
    prefix.iter().for_each(|&x| {
        a.step(x);
    });
    let before = a.interface().to_vec();
    let y_before = a.step(4.0);
    let mut changed = false;
    for &x in &nested {
        let y = a.step(x);
        changed |= a.interface() != before.as_slice();
        if x == 4.0 {
            assert_eq!(y, y_before);
        }
    }
    assert!(changed, "the nested loops must move the state");
    assert_eq!(a.interface(), before.as_slice());
    // And the loops leave no trace on what follows.
    assert_eq!(
        wiping_gap(&preisach_stepper(&m), &prefix, &nested, &suffix),
        0.0
    );
}

#[test]
fn minor_loops_are_congruent() {
    let m = random_model(12, 0.0, 4.7, 9);
    let gap = congruency_gap(&preisach_stepper(&m), &histories(), 1.5, 3.0);
    assert!(gap < 1e-12, "Preisach congruency gap {gap:e}");
    // The histories do put the model in different states at the loop's start.
    let ends: Vec<f64> = histories()
        .iter()
        .map(|h| *m.simulate(h, 1e-3).last().unwrap())
        .collect();
    assert!(ends.windows(2).all(|w| (w[0] - w[1]).abs() > 1e-3));
}

/// The same checks find the Bouc-Wen model (the twin's parameters) not congruent, by far
/// more than the tolerance above, and not wiping out its nested loops either: the tests
/// tell a Preisach memory from another.
#[test]
fn bouc_wen_fails_the_memory_checks() {
    let gap = congruency_gap(&bouc_wen_stepper, &histories(), 1.5, 3.0);
    eprintln!(
        "Bouc-Wen congruency gap: {:.3} % of the minor loop's span",
        100.0 * gap
    );
    assert!(gap > 1e-2, "Bouc-Wen congruency gap {gap:e}");
    let (prefix, nested, suffix) = nested();
    let wipe = wiping_gap(&bouc_wen_stepper, &prefix, &nested, &suffix);
    eprintln!(
        "Bouc-Wen wiping-out gap: {:.3} % of the output span",
        100.0 * wipe
    );
    assert!(wipe > 1e-3, "Bouc-Wen wiping-out gap {wipe:e}");
}

/// First-order reversal states: from negative saturation up to `t_i`, down to `t_j`, for
/// every relay, so every weight is identifiable; ends at `hi` so the range is `[lo, hi]`.
fn reversal_input(grid: &PreisachGrid) -> Vec<f64> {
    let t = grid.thresholds();
    let mut u = vec![grid.u_min()];
    for i in 0..t.len() {
        for j in 0..=i {
            u.extend([t[i], t[j], grid.u_min()]);
        }
    }
    u.push(grid.u_max());
    u
}

#[test]
fn fit_recovers_the_weights_of_a_preisach_model() {
    for (levels, seed) in [(1, 11), (8, 12), (16, 13)] {
        let m = random_model(levels, 0.2, 4.5, seed);
        let u = reversal_input(&m.grid);
        let y = m.simulate(&u, 1e-3);
        let f = Preisach::fit(levels, &u, &y, 1e-3).unwrap();
        assert_eq!(f.grid, m.grid);
        let err = f
            .theta()
            .iter()
            .zip(m.theta())
            .fold(0.0f64, |e, (a, b)| e.max((a - b).abs()));
        assert!(err < 1e-8, "levels {levels}: weight error {err:e}");
    }
}

/// Merging samples of one state is exact: the fit's residual equals the NNLS optimum on
/// every sample's row, and no nonnegative perturbation of it does better.
#[test]
fn merged_rows_give_the_full_least_squares_optimum() {
    let truth = random_model(6, 0.0, 4.7, 14);
    let u = random_input(&truth, 1500, 15);
    let mut rng = TrialSeed::from_u64(16).rng(2);
    // Not a Preisach output: a curve and noise, so some weights end on their bound.
    let y: Vec<f64> = u
        .iter()
        .zip(truth.simulate(&u, 1e-3))
        .map(|(x, v)| v + 0.3 * x * x - 2.0 * x + 0.2 * (rng.random::<f64>() - 0.5))
        .collect();
    let f = Preisach::fit(6, &u, &y, 1e-3).unwrap();
    let cols = f.grid.columns(&u, 1e-3);
    let full = nnls(&cols, &y, &f.grid.nonnegative());
    let sse = |theta: &[f64]| -> f64 {
        (0..u.len())
            .map(|t| {
                let p: f64 = cols.iter().zip(theta).map(|(c, w)| c[t] * w).sum();
                (y[t] - p).powi(2)
            })
            .sum()
    };
    let (a, b) = (sse(&f.theta()), sse(&full));
    assert!((a - b).abs() <= 1e-9 * b, "{a} vs {b}");
    assert!(f.weights.iter().all(|&w| w >= 0.0));
    assert!(f.weights.contains(&0.0), "expected an active bound");
    let yf = f.simulate(&u, 1e-3);
    let direct: f64 = y.iter().zip(&yf).map(|(a, b)| (a - b).powi(2)).sum();
    assert!((direct - a).abs() <= 1e-9 * a);
}

#[test]
fn a_model_file_round_trips_and_checks_its_grid() {
    let m = random_model(4, -1.0, 3.0, 17);
    let text = serde_json::to_string(&m).unwrap();
    assert!(
        text.contains(r#""grid":{"levels":4,"u_min":-1.0,"u_max":3.0}"#),
        "{text}"
    );
    let back: Preisach = serde_json::from_str(&text).unwrap();
    assert_eq!(back, m);
    let bad = text.replace(r#""u_max":3.0"#, r#""u_max":-2.0"#);
    let e = serde_json::from_str::<Preisach>(&bad)
        .unwrap_err()
        .to_string();
    assert!(e.contains("u_max > u_min"), "{e}");
    let short = text.replace(r#""weights":["#, r#""weights":[1.0,"#);
    let e = serde_json::from_str::<Preisach>(&short)
        .unwrap_err()
        .to_string();
    assert!(e.contains("expected 11 (10 relays and the offset)"), "{e}");
}

#[test]
fn bad_input_is_reported() {
    let e = Preisach::fit(0, &[0.0, 1.0], &[0.0, 1.0], 1e-3).unwrap_err();
    assert!(e.contains("0 levels"), "{e}");
    let e = Preisach::fit(5, &[1.0, 1.0], &[0.0, 1.0], 1e-3).unwrap_err();
    assert!(e.contains("u_max > u_min"), "{e}");
    let e = Preisach::fit(5, &[0.0, 1.0], &[0.0], 1e-3).unwrap_err();
    assert!(e.contains("2 inputs and 1 outputs"), "{e}");
    let e = Preisach::fit(5, &[0.0, f64::NAN], &[0.0, 1.0], 1e-3).unwrap_err();
    assert!(e.contains("input sample 1"), "{e}");
    let e = Preisach::fit(5, &[0.0, 1.0], &[0.0, f64::INFINITY], 1e-3).unwrap_err();
    assert!(e.contains("output sample 1"), "{e}");
    let grid = PreisachGrid::for_input(3, &[0.0, 1.0]).unwrap();
    let e = grid.model(&[1.0; 3]).unwrap_err();
    assert!(e.contains("expected 7 (6 relays and the offset)"), "{e}");
}
