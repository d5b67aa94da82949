use super::evaluate::*;
use super::judge::*;
use super::propose::*;
use super::refit::{self, Fitted};
use super::residual;
use super::steps::tests::staircase;
use super::*;
use crate::base::{TrialSeed, standard_normal};
use crate::physics::bouc_wen::{BoucWenParams, BoucWenState};
use crate::physics::structure::tests::theta_with;
use crate::physics::structure::{Context, Effect, Form, Hold, Placement, Structure};
use rand::RngExt;

/// A triangle from 0.05 to 0.05 + `amp` whose frequency rises from `rate` Hz by 0.1 Hz
/// per second: the unipolar drive of the creep tests.
fn triangle_chirp(n: usize, dt: f64, rate: f64, amp: f64) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let t = k as f64 * dt;
            let phase = (t * (rate + 0.1 * t)).fract();
            0.05 + amp * (1.0 - (2.0 * phase - 1.0).abs())
        })
        .collect()
}

/// The Bouc-Wen loop (n = 1) of the records the tests write by hand.
const TEST_BOUC_WEN: BoucWenParams = BoucWenParams {
    d_e: 0.17,
    alpha: 0.05,
    beta: 0.45,
    gamma: 0.2,
    n: 1.0,
    d0: 0.0,
};

/// The plain model fitted to `data` (sampled every `dt`), then `(effect, form)` fitted
/// on top of it.
fn plain_plus(data: &Data, dt: f64, effect: Effect, form: Form, opts: &Options) -> Evaluated {
    let plain = Structure::new(&[], Some(1.0), Context::from_training(&data.ut, dt));
    let base = baseline_fit(&plain, data, opts);
    let p = Proposal {
        parts: vec![(effect, form)],
        placement: Placement::After,
    };
    fit_proposal(
        &base.structure,
        &base.theta,
        &p,
        Seeds::Hinted(&Memory::new(), &[]),
        data,
        opts,
        1,
    )
}

/// A record with a delay of `delay` samples before the hysteresis and modes `(hz,
/// damping, share)` in parallel after it, written without `Structure` (each mode by RK4
/// on 20 steps a sample, the input held), noise of RMS `sigma` from the stream `(salt,
/// label)`.
fn delayed_modes_record(
    u: &[f64],
    dt: f64,
    (delay, modes): (usize, &[(f64, f64, f64)]),
    sigma: f64,
    (salt, label): (u64, &str),
) -> Vec<f64> {
    let p = TEST_BOUC_WEN;
    let mut bw = BoucWenState::new(u[0]);
    let d0 = bw.step(&p, u[0]);
    let mut states: Vec<(f64, f64)> = modes.iter().map(|_| (d0, 0.0)).collect();
    let mut rng = TrialSeed::derive(salt, label, "noise", 0).rng(0);
    let h = dt / 20.0;
    (0..u.len())
        .map(|k| {
            let x: f64 = modes.iter().zip(&states).map(|(m, s)| m.2 * s.0).sum();
            let out = x + sigma * standard_normal(&mut rng);
            let d = bw.step(&p, u[k.saturating_sub(delay)]);
            for (&(hz, zeta, _), (x, v)) in modes.iter().zip(states.iter_mut()) {
                let w = std::f64::consts::TAU * hz;
                let f = |x: f64, v: f64| (v, w * w * (d - x) - 2.0 * zeta * w * v);
                for _ in 0..20 {
                    let k1 = f(*x, *v);
                    let k2 = f(*x + 0.5 * h * k1.0, *v + 0.5 * h * k1.1);
                    let k3 = f(*x + 0.5 * h * k2.0, *v + 0.5 * h * k2.1);
                    let k4 = f(*x + h * k3.0, *v + h * k3.1);
                    *x += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
                    *v += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
                }
            }
            out
        })
        .collect()
}

/// A delay beside a lightly damped mode: the mode fitted first takes some of the
/// delay's phase; the delay proposed next searches the mode again (started at the
/// residual's peaks) and both come back: the delay within a sample, the mode within 3 %,
/// the training residual at the noise.
#[test]
fn a_delay_beside_a_mode_searches_the_mode_again() {
    let (dt, n, sigma) = (1e-3, 6000, 1e-3);
    let probe = |k: usize, a: f64| a * (std::f64::consts::TAU * 70.0 * k as f64 * dt).sin();
    let tu: Vec<f64> = triangle_chirp(n, dt, 1.0, 4.6)
        .iter()
        .enumerate()
        .map(|(k, x)| x + probe(k, 0.08))
        .collect();
    let vu: Vec<f64> = triangle_chirp(n, dt, 0.6, 3.8)
        .iter()
        .enumerate()
        .map(|(k, x)| x + probe(k, 0.06))
        .collect();
    let truth = (3, 110.0, 0.04);
    let modes = [(truth.1, truth.2, 1.0)];
    let ty = delayed_modes_record(&tu, dt, (truth.0, &modes), sigma, (11, "delay-mode-train"));
    let vy = delayed_modes_record(
        &vu,
        dt,
        (truth.0, &modes),
        sigma,
        (11, "delay-mode-validate"),
    );
    let data = Data::new(tu, ty, vu, vy, false, dt);
    let opts = Options::default();
    let mode = plain_plus(&data, dt, Effect::Dynamics, Form::OneMode, &opts);
    let e = training_residual(&data.yt, &mode);
    let peaks = residual::peak_frequencies(&data.ut, &e, dt, sigma, 3);
    let p = Proposal {
        parts: vec![(Effect::Delay, Form::Transport)],
        placement: Placement::After,
    };
    let both = fit_proposal(
        &mode.fitted.structure,
        &mode.fitted.theta,
        &p,
        Seeds::Hinted(&Memory::new(), &peaks),
        &data,
        &opts,
        2,
    );
    let v = named(&both.fitted);
    let rmse = residual::rms(&training_residual(&data.yt, &both));
    let why = format!(
        "{v:?}, peaks {peaks:?}, mode alone {:?}",
        named(&mode.fitted)
    );
    let (delay, hz, _) = truth;
    assert!((v["delay_s"] / dt - delay as f64).abs() < 1.0, "{why}");
    assert!((v["mode_freq_hz"] / hz - 1.0).abs() < 0.03, "{why}");
    assert!(rmse < 1.3 * sigma, "{rmse} {why}");
}

/// A delay beside two modes, where one mode was fitted first (its damping taking the
/// delay's phase): the pair stage offers the best timing with the mode made two,
/// searched from the residual's peaks, and it comes back (delay within a sample, modes
/// within 5 %, the training residual at the noise); without a timing among the best
/// singles it is not offered.
#[test]
fn a_timing_is_paired_with_the_one_mode_made_two() {
    let (dt, n, sigma) = (1e-3, 6000, 1e-3);
    let lines = |k: usize, a: f64| {
        let t = k as f64 * dt;
        (0..8)
            .map(|j| {
                let hz = 20.0 + 12.0 * j as f64;
                a * (std::f64::consts::TAU * hz * t + j as f64).sin()
            })
            .sum::<f64>()
    };
    let tu: Vec<f64> = triangle_chirp(n, dt, 1.0, 4.6)
        .iter()
        .enumerate()
        .map(|(k, x)| x + lines(k, 0.03))
        .collect();
    let vu: Vec<f64> = triangle_chirp(n, dt, 0.6, 3.8)
        .iter()
        .enumerate()
        .map(|(k, x)| x + lines(k, 0.025))
        .collect();
    let (delay, modes) = (4, [(35.0, 0.05, 0.7), (80.0, 0.05, 0.3)]);
    let ty = delayed_modes_record(&tu, dt, (delay, &modes), sigma, (12, "two-train"));
    let vy = delayed_modes_record(&vu, dt, (delay, &modes), sigma, (12, "two-validate"));
    let data = Data::new(tu, ty, vu, vy, false, dt);
    let opts = Options::default();
    let one = plain_plus(&data, dt, Effect::Dynamics, Form::OneMode, &opts);
    let parent = one.fitted.structure.clone();
    let pool = candidate_pool(&parent, &opts);
    let at = |part: (Effect, Form)| pool.iter().position(|p| p.parts == [part]).unwrap();
    let (delay_at, clip) = (
        at((Effect::Delay, Form::Transport)),
        at((Effect::Saturation, Form::Hard)),
    );
    let pairs = pair_proposals(&pool, &[delay_at, clip], parent.placement());
    let names: Vec<String> = pairs.iter().map(|p| p.0.form()).collect();
    assert_eq!(names, ["transport+hard", "transport+two-modes"]);
    assert_eq!(pairs[1].1, None, "the upgrade pair is searched");
    let slope = at((Effect::Asymmetry, Form::Even));
    assert!(
        pair_proposals(&pool, &[clip, slope], parent.placement())
            .iter()
            .all(|p| p.1.is_some())
    );
    let e = training_residual(&data.yt, &one);
    let peaks = residual::peak_frequencies(&data.ut, &e, dt, sigma, 3);
    let fit = |p: &Proposal| {
        let seeds = Seeds::Hinted(&Memory::new(), &peaks);
        fit_proposal(&parent, &one.fitted.theta, p, seeds, &data, &opts, 2)
    };
    let both = fit(&pairs[1].0);
    let v = named(&both.fitted);
    let rmse = |c: &Evaluated| residual::rms(&training_residual(&data.yt, c));
    let why = format!(
        "{v:?}, peaks {peaks:?}, one mode {:?} ({:.2} sigma)",
        named(&one.fitted),
        rmse(&one) / sigma
    );
    assert!((v["delay_s"] / dt - delay as f64).abs() < 1.0, "{why}");
    let mut hz = [v["mode_freq_hz"], v["mode2_freq_hz"]];
    hz.sort_by(f64::total_cmp);
    assert!(
        (hz[0] / modes[0].0 - 1.0).abs() < 0.05 && (hz[1] / modes[1].0 - 1.0).abs() < 0.05,
        "{why}"
    );
    assert!(rmse(&both) < 1.3 * sigma, "{} {why}", rmse(&both) / sigma);
    assert!(rmse(&one) > 2.0 * sigma, "{why}");
    // Neither alone: each single leaves several times the noise (measured 10.8 and 9.3).
    for part in [
        (Effect::Delay, Form::Transport),
        (Effect::Dynamics, Form::TwoModes),
    ] {
        let parts = vec![part];
        let alone = fit(&Proposal {
            parts,
            placement: Placement::After,
        });
        assert!(
            rmse(&alone) > 3.0 * sigma,
            "{part:?} alone {} {why}",
            rmse(&alone) / sigma
        );
    }
}

/// The exchanges open to `fitted` with nothing fitted in earlier rounds, in round 1.
fn offered(
    fitted: &Fitted,
    named: &[String],
    taken: &[(Effect, Effect)],
    data: &Data,
    opts: &Options,
) -> Vec<(Effect, Proposal, Evaluated)> {
    exchanges(fitted, named, taken, &Memory::new(), data, opts, 1)
}

/// Whether any exchange `tried` on `with` passes the gate (the band from `with`'s own
/// validation residual), and what the gates saw, for an assertion's message.
fn any_exchange_passes(
    tried: &[(Effect, Proposal, Evaluated)],
    with: &Evaluated,
    data: &Data,
    opts: &Options,
) -> (bool, String) {
    let band = rmse_band(validation_residual(with), 1, "exchange");
    let gates: Vec<([f64; 4], bool)> = tried
        .iter()
        .map(|(_, _, c)| exchange_gate(c, with, band, data.ut.len(), opts.bic_margin))
        .collect();
    let why = format!(
        "validation RMSE {} band {band:?}, exchanges [ΔBIC, Δfit, Δvalidation, sum] {:?} validation RMSE {:?}",
        with.validate_rmse,
        gates.iter().map(|g| g.0).collect::<Vec<_>>(),
        tried.iter().map(|t| t.2.validate_rmse).collect::<Vec<_>>()
    );
    (gates.iter().any(|g| g.1), why)
}

/// The exchange tests' drives: a triangle chirp for training, a slower, smaller one
/// for validation.
fn chirp_records(n: usize, dt: f64) -> (Vec<f64>, Vec<f64>) {
    (
        triangle_chirp(n, dt, 1.0, 4.6),
        triangle_chirp(n, dt, 0.6, 3.8),
    )
}

/// A slow drift of each record's own (training, validation).
const WANDER: [fn(f64) -> f64; 2] = [
    |t| 0.02 * (std::f64::consts::TAU * t / 4.0).sin(),
    |t| -0.015 * (std::f64::consts::TAU * t / 5.0).cos(),
];

/// The creep tests' record, written without `Structure`: `BoucWenState` (n = 1), then a
/// Kelvin-Voigt element of gain `creep` at 14 s from rest, plus `drift(t)` and noise of
/// RMS `sigma` from the stream `(salt, label)`.
fn creep_record(
    u: &[f64],
    dt: f64,
    creep: f64,
    drift: &dyn Fn(f64) -> f64,
    sigma: f64,
    (salt, label): (u64, &str),
) -> Vec<f64> {
    let p = TEST_BOUC_WEN;
    let mut bw = BoucWenState::new(u[0]);
    let a = 1.0 - (-dt / 14.0f64).exp();
    let mut x = 0.0;
    let mut rng = TrialSeed::derive(salt, label, "noise", 0).rng(0);
    u.iter()
        .enumerate()
        .map(|(k, &v)| {
            let d = bw.step(&p, v);
            let out = d + creep * x + drift(k as f64 * dt);
            x += a * (d - x);
            out + sigma * standard_normal(&mut rng)
        })
        .collect()
}

/// `st` fitted to the training record with the baseline's budget.
fn baseline_fit(st: &Structure, data: &Data, opts: &Options) -> Fitted {
    refit::fit(st, &data.ut, &data.yt, None, None, opts.baseline_budget, 1)
}

/// A fitted structure with one effect's parameters (the linear part is not looked at).
fn fitted_with(effect: Effect, form: Form, values: &[(&str, f64)], dt: f64) -> Fitted {
    let u: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
    let st = Structure::with_forms(
        &[(effect, form)],
        Some(1.0),
        Context::from_training(&u, dt),
        Placement::After,
    );
    Fitted::at(&st, theta_with(&st, values), &u, &u, 0)
}

fn fitted(form: Form, values: &[(&str, f64)], dt: f64) -> Fitted {
    fitted_with(Effect::Dynamics, form, values, dt)
}

/// `--hold auto`: a restoring-force record driven by a band-limited multisine (written
/// under the band-limited hold), fitted under the zero-order hold, is refitted under each
/// hold and the band-limited one kept: it predicts the validation record far better.
#[test]
fn the_hold_a_record_was_excited_with_is_chosen() {
    let dt = 1.0 / 750.0;
    // Random-phase multisines, 5-150 Hz, one training and one validation.
    let multisine = |n: usize, salt: u64| -> Vec<f64> {
        let mut rng = TrialSeed::derive(salt, "hold", "phases", 0).rng(0);
        let bins: Vec<(f64, f64)> = (1..n / 2)
            .map(|k| k as f64 / (n as f64 * dt))
            .filter(|f| (5.0..=150.0).contains(f))
            .map(|f| (f, std::f64::consts::TAU * rng.random::<f64>()))
            .collect();
        (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                bins.iter()
                    .map(|(f, p)| (std::f64::consts::TAU * f * t + p).sin())
                    .sum::<f64>()
                    * 0.2
            })
            .collect()
    };
    let (ut, uv) = (multisine(3000, 1), multisine(1500, 2));
    let ctx = Context::from_training(&ut, dt).with_hold(Hold::Bandlimited);
    let truth = Structure::with_forms(
        &[(Effect::Dynamics, Form::OneMode)],
        Some(1.0),
        ctx,
        Placement::Feedback,
    );
    let theta = theta_with(
        &truth,
        &[
            ("fb_log10_hz", 36f64.log10()),
            ("fb_log10_zeta", 0.02f64.log10()),
            ("fb_r", 0.5),
            ("fb_b", 0.5),
            ("fb_c", -1.0),
        ],
    );
    let coef: Vec<f64> = truth
        .linear_names()
        .iter()
        .map(|n| if n == "scale" { 1.0 } else { 0.0 })
        .collect();
    let noisy = |u: &[f64], salt: u64| -> Vec<f64> {
        let (y, _) = truth.simulate(&theta, &coef, u);
        let mut rng = TrialSeed::derive(salt, "hold", "noise", 0).rng(0);
        y.iter()
            .map(|v| v + 1e-4 * standard_normal(&mut rng))
            .collect()
    };
    let (yt, yv) = (noisy(&ut, 3), noisy(&uv, 4));
    let data = Data::new(ut.clone(), yt, uv, yv, false, dt);
    let opts = Options {
        model: "bouc-wen-n1".into(),
        ..Options::default()
    };
    let zoh = truth.with_hold(Hold::Zoh);
    let fit = refit::fit(
        &zoh,
        &data.ut,
        &data.yt,
        Some(&theta),
        None,
        repolish_budget(&opts),
        1,
    );
    let (kept, trials, used) = choose_hold(evaluate(fit, &data, &opts), &data, &opts);
    assert!(used > 0);
    let names: Vec<&str> = trials.iter().map(|t| t.hold.as_str()).collect();
    assert_eq!(names, ["zoh", "linear", "bandlimited"]);
    assert_eq!(
        kept.fitted.structure.hold(),
        Hold::Bandlimited,
        "{trials:?}"
    );
    assert!(trials[2].kept && !trials[0].kept && !trials[1].kept);
    assert!(
        trials[2].validate_rmse < 0.5 * trials[0].validate_rmse,
        "{trials:?}"
    );
    assert_eq!(kept.validate_rmse, trials[2].validate_rmse);
}

/// A slow creep (gain 0.75, 14 s) on a 6 s unipolar record, the hysteresis from a
/// virgin state and the creep from rest (written here, not by `Structure`): the plain fit
/// bends its loop to imitate the rise, and a creep searched from that bent loop alone
/// stays near it (the blind proof's case 37 of seed 20261128); searched with the loop
/// it reaches the noise.
#[test]
fn creep_is_searched_with_the_loop_shape_the_plain_fit_bent() {
    let (dt, n, sigma) = (1e-3, 6000, 1e-3);
    let u = triangle_chirp(n, dt, 1.0, 4.6);
    let y = creep_record(&u, dt, 0.75, &|_| 0.0, sigma, (7, "creep-shape"));
    let plain = Structure::new(&[], Some(1.0), Context::from_training(&u, dt));
    let (uv, yv) = (
        u.iter().rev().copied().collect(),
        y.iter().rev().copied().collect(),
    );
    let data = Data::new(u, y, uv, yv, false, dt);
    let opts = Options::default();
    let parent = baseline_fit(&plain, &data, &opts);
    assert!(
        parent.rmse(n) > 3.0 * sigma,
        "the plain fit leaves {}",
        parent.rmse(n)
    );
    let creep = Proposal {
        parts: vec![(Effect::Creep, Form::KelvinVoigt)],
        placement: Placement::After,
    };
    let c = fit_proposal(
        &parent.structure,
        &parent.theta,
        &creep,
        Seeds::Hinted(&Memory::new(), &[]),
        &data,
        &opts,
        1,
    );
    let rmse = c.fitted.rmse(n);
    assert!(rmse < 1.1 * sigma, "creep leaves {rmse} (noise {sigma})");
}

/// A direction asymmetry, written here by hand (Bouc-Wen n = 1,
/// `dh/dv = α (1 + a s) - β s h - γ |h|` with `s` the sign of the drive's step, 20
/// sub-steps per sample, a = +0.3), fitted on top of a model with a rate-dependent gain
/// (none in the data): the candidate finds a = +0.3, not the mirror optimum (a of the
/// other sign, γ negative), and leaves the noise.
#[test]
fn a_direction_asymmetry_is_searched_with_the_loop_shape() {
    let (dt, n, sigma) = (1e-3, 6000, 1e-3);
    let u: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 * dt;
            let phase = (t * (1.0 + 0.4 * t)).fract();
            2.3 * (2.0 * (1.0 - (2.0 * phase - 1.0).abs()) - 1.0)
        })
        .collect();
    let (a, alpha, beta, gamma, d_e, rho, tau) = (0.3, 0.05, 0.5, 0.25, 0.17, 0.0, 0.05);
    let simulate = |u: &[f64], salt: u64| -> Vec<f64> {
        let mut h = 0.0f64;
        let mut r = 0.0;
        let mut rng = TrialSeed::derive(salt, "asym-shape", "noise", 0).rng(0);
        let a_r = 1.0 - (-dt / tau).exp();
        let rms_rate = 4.0 * 2.3 * 1.5;
        (0..u.len())
            .map(|k| {
                if k > 0 {
                    let dv = u[k] - u[k - 1];
                    r += a_r * (dv.abs() / dt - r);
                    let s = dv.signum();
                    for _ in 0..20 {
                        let step = dv / 20.0;
                        h += step * (alpha * (1.0 + a * s) - beta * s * h - gamma * h.abs());
                    }
                }
                d_e * (1.0 + rho * r / rms_rate) * u[k] - h + sigma * standard_normal(&mut rng)
            })
            .collect()
    };
    let uv: Vec<f64> = u.iter().map(|x| 0.8 * x).collect();
    let data = Data::new(
        u.clone(),
        simulate(&u, 1),
        uv.clone(),
        simulate(&uv, 2),
        false,
        dt,
    );
    let opts = Options::default();
    let rate = Structure::with_forms(
        &[(Effect::RateDependence, Form::Gain)],
        Some(1.0),
        Context::from_training(&u, dt),
        Placement::After,
    );
    let parent = baseline_fit(&rate, &data, &opts);
    let asym = Proposal {
        parts: vec![(Effect::Asymmetry, Form::Direction)],
        placement: Placement::After,
    };
    let c = fit_proposal(
        &parent.structure,
        &parent.theta,
        &asym,
        Seeds::Hinted(&Memory::new(), &[]),
        &data,
        &opts,
        1,
    );
    let fitted_a = named(&c.fitted)["asymmetry_direction"];
    let rmse = c.fitted.rmse(n);
    assert!(
        (fitted_a - a).abs() < 0.05 && rmse < 1.05 * sigma,
        "a = {fitted_a} (true {a}), training RMSE {rmse} (noise {sigma}); parent RMSE {}",
        parent.rmse(n)
    );
}

/// The exchange of [`EXCHANGES`]: a drift of each record fitted where the data hold a
/// slow creep (written here with `BoucWenState` and a Kelvin-Voigt element from rest,
/// a different excitation on the validation record) is exchanged for creep; a true
/// drift (a wander, another on the validation record) is kept.
#[test]
fn a_drift_standing_in_for_creep_is_exchanged_and_a_true_drift_kept() {
    let (dt, n, sigma) = (1e-3, 6000, 1e-3);
    let (ut, uv) = chirp_records(n, dt);
    let record = |u: &[f64], creep: f64, drift: &dyn Fn(f64) -> f64, salt: u64| {
        creep_record(u, dt, creep, drift, sigma, (salt, "exchange"))
    };
    let opts = Options::default();
    let drift_only: [&dyn Fn(f64) -> f64; 2] = [&WANDER[0], &WANDER[1]];
    let none = |_: f64| 0.0;
    // A weak creep: the drift fits the training record as closely as creep with four
    // parameters fewer (training ΔBIC +13.7, the likelihood 21 better with creep);
    // creep predicts the validation record (43 better): taken, the training record
    // does not contradict it.
    for (creep, drift, exchanged) in [
        (0.75, [&none as &dyn Fn(f64) -> f64, &none], true),
        (0.14, [&none, &none], true),
        (0.0, drift_only, false),
    ] {
        let data = Data::new(
            ut.clone(),
            record(&ut, creep, drift[0], 1),
            uv.clone(),
            record(&uv, creep, drift[1], 2),
            false,
            dt,
        );
        let with_drift = plain_plus(&data, dt, Effect::OffsetDrift, Form::Spline, &opts);
        let named = vec!["offset-drift".to_string()];
        let tried = offered(&with_drift.fitted, &named, &[], &data, &opts);
        // A pair exchanged before, either way round, is not offered again.
        for taken in [
            (Effect::OffsetDrift, Effect::Creep),
            (Effect::Creep, Effect::OffsetDrift),
        ] {
            assert!(offered(&with_drift.fitted, &named, &[taken], &data, &opts).is_empty());
        }
        assert_eq!(tried.len(), Effect::Creep.forms().len());
        // `--effects` without creep: the drift is never exchanged for it.
        let no_creep = Options {
            effects: Effect::ALL
                .into_iter()
                .filter(|&e| e != Effect::Creep)
                .collect(),
            ..opts.clone()
        };
        assert!(offered(&with_drift.fitted, &named, &[], &data, &no_creep).is_empty());
        let (passes, why) = any_exchange_passes(&tried, &with_drift, &data, &opts);
        assert_eq!(passes, exchanged, "creep {creep}: drift model {why}");
    }
}

/// The other exchanges of [`EXCHANGES`], on records written here with `BoucWenState`
/// (n = 1) after a map of the drive and before one of the output: an even-order term
/// (`v + 0.05 v²`) fitted with a saturation is exchanged for asymmetry, a soft
/// saturation (`1.3 tanh(v / 1.3)`) is kept; a first-order lag of the drive (8 ms)
/// fitted with a delay is exchanged for the input lag, a transport delay (8 samples) is
/// kept; the same lag fitted with a mode is exchanged for input timing, a resonant mode
/// of the output (60 Hz, damping 0.05) is kept.
#[test]
fn a_stand_in_for_its_partner_is_exchanged_and_a_true_one_kept() {
    let (dt, n, sigma) = (1e-3, 6000, 1e-3);
    let bipolar = |rate: f64, amp: f64| -> Vec<f64> {
        triangle_chirp(n, dt, rate, 2.0)
            .iter()
            .map(|x| amp * (x - 1.05))
            .collect()
    };
    let (ut, uv) = (bipolar(1.0, 2.3), bipolar(0.6, 1.9));
    type Map<'a> = &'a dyn Fn(&[f64]) -> Vec<f64>;
    let record = |u: &[f64], (map, out): (Map, Map), salt: u64| -> Vec<f64> {
        let p = TEST_BOUC_WEN;
        let v = map(u);
        let mut bw = BoucWenState::new(v[0]);
        let y: Vec<f64> = v.iter().map(|&x| bw.step(&p, x)).collect();
        let mut rng = TrialSeed::derive(salt, "exchange-map", "noise", 0).rng(0);
        out(&y)
            .iter()
            .map(|&x| x + sigma * standard_normal(&mut rng))
            .collect()
    };
    let same = |u: &[f64]| u.to_vec();
    // Semi-implicit Euler of x'' = w²(y - x) - 2ζw x', fine for w dt = 0.38.
    let mode = |y: &[f64]| {
        let (w, z) = (2.0 * std::f64::consts::PI * 60.0, 0.05);
        let (mut x, mut v) = (y[0], 0.0);
        y.iter()
            .map(|&f| {
                v += dt * (w * w * (f - x) - 2.0 * z * w * v);
                x += dt * v;
                x
            })
            .collect::<Vec<f64>>()
    };
    let even = |u: &[f64]| u.iter().map(|v| v + 0.05 * v * v).collect::<Vec<f64>>();
    let soft = |u: &[f64]| {
        u.iter()
            .map(|v| 1.3 * (v / 1.3).tanh())
            .collect::<Vec<f64>>()
    };
    let lag = |u: &[f64]| {
        let a = 1.0 - (-dt / 8e-3f64).exp();
        let mut x = u[0];
        u.iter()
            .map(|&v| {
                x += a * (v - x);
                x
            })
            .collect::<Vec<f64>>()
    };
    let delay = |u: &[f64]| {
        (0..u.len())
            .map(|k| u[k.saturating_sub(8)])
            .collect::<Vec<f64>>()
    };
    let cases: [((Map, Map), Effect, Form, bool); 6] = [
        ((&even, &same), Effect::Saturation, Form::Smooth, true),
        ((&soft, &same), Effect::Saturation, Form::Smooth, false),
        ((&lag, &same), Effect::Delay, Form::Transport, true),
        ((&delay, &same), Effect::Delay, Form::Transport, false),
        ((&lag, &same), Effect::Dynamics, Form::OneMode, true),
        ((&same, &mode), Effect::Dynamics, Form::OneMode, false),
    ];
    let opts = Options::default();
    for (maps, named_effect, form, exchanged) in cases {
        let data = Data::new(
            ut.clone(),
            record(&ut, maps, 1),
            uv.clone(),
            record(&uv, maps, 2),
            false,
            dt,
        );
        let with_named = plain_plus(&data, dt, named_effect, form, &opts);
        let named = vec![named_effect.name().to_string()];
        let tried = offered(&with_named.fitted, &named, &[], &data, &opts);
        let partners: Vec<Effect> = EXCHANGES
            .iter()
            .filter(|(e, _)| *e == named_effect)
            .map(|p| p.1)
            .collect();
        let forms: usize = partners.iter().map(|p| p.forms().len()).sum();
        assert_eq!(tried.len(), forms);
        assert!(tried.iter().all(|(out, p, _)| *out == named_effect
            && p.parts.len() == 1
            && partners.contains(&p.parts[0].0)));
        let (passes, why) = any_exchange_passes(&tried, &with_named, &data, &opts);
        assert_eq!(
            passes,
            exchanged,
            "{} for {partners:?}: {why}",
            named_effect.name(),
        );
    }
}

/// One effect standing in for two: creep named on a record that holds a drift of its
/// own and an even-order asymmetry (the drive mapped to `v + 0.05 v²`) is exchanged for
/// the drift with the asymmetry fitted on an earlier parent; on the same record
/// without the asymmetry the pair is offered too, but its asymmetry does not earn a
/// place beside the drift alone.
#[test]
fn a_creep_standing_in_for_two_effects_is_exchanged_for_both() {
    let (dt, n, sigma) = (1e-3, 6000, 1e-3);
    let (ut, uv) = chirp_records(n, dt);
    let drift: [&dyn Fn(f64) -> f64; 2] = [&WANDER[0], &WANDER[1]];
    let opts = Options::default();
    for (q, both) in [(0.05, true), (0.0, false)] {
        let skew = |u: &[f64]| u.iter().map(|v| v + q * v * v).collect::<Vec<f64>>();
        let record = |u: &[f64], k: usize| {
            creep_record(&skew(u), dt, 0.0, drift[k], sigma, (k as u64 + 1, "two"))
        };
        let data = Data::new(
            ut.clone(),
            record(&ut, 0),
            uv.clone(),
            record(&uv, 1),
            false,
            dt,
        );
        let with_creep = plain_plus(&data, dt, Effect::Creep, Form::KelvinVoigt, &opts);
        let asym = plain_plus(&data, dt, Effect::Asymmetry, Form::Even, &opts);
        let memory = Memory::from([((Effect::Asymmetry, Form::Even), vec![asym.fitted])]);
        let named = vec!["creep".to_string()];
        let tried = exchanges(&with_creep.fitted, &named, &[], &memory, &data, &opts, 1);
        assert_eq!(tried.len(), Effect::OffsetDrift.forms().len() + 1);
        let (_, pair, c) = tried.iter().find(|t| t.1.parts.len() == 2).unwrap();
        assert_eq!(pair.parts[0].0, Effect::OffsetDrift);
        assert_eq!(pair.parts[1], (Effect::Asymmetry, Form::Even));
        let alone = tried
            .iter()
            .find(|t| t.1.parts == pair.parts[..1])
            .map(|t| &t.2)
            .unwrap();
        let noise = sigma;
        let band = rmse_band(validation_residual(&with_creep), 1, "two");
        let (gain, exchange) = exchange_gate(c, &with_creep, band, n, opts.bic_margin);
        let beside = beside_alone(c, alone, &data, noise, "mm", &opts);
        assert_eq!(
            exchange && beside.passed,
            both,
            "q {q}: exchange {gain:?} {exchange}; beside the drift: {}",
            beside.evidence
        );
    }
}

/// Creep whose larger element sits at ten samples is a lag; a slow element that does
/// most of the work, or a fast one just off the bound, is creep.
#[test]
fn creep_is_a_lag_when_its_main_element_is_pinned_at_ten_samples() {
    let dt = 1e-3;
    let pinned = |tau: f64, g: f64, g2: f64| {
        let f = fitted_with(
            Effect::Creep,
            Form::KelvinVoigt,
            &[
                ("creep_g", g),
                ("creep_log10_tau_s", tau.log10()),
                ("creep_g2", g2),
                ("creep_log10_tau2_s", 2f64.log10()),
            ],
            dt,
        );
        creep_pinned_fast(&f)
    };
    assert!(pinned(10.0 * dt, 0.3, 0.05));
    assert!(pinned(11.0 * dt, 0.3, 0.05), "within 12 % of the bound");
    assert!(
        !pinned(10.0 * dt, 0.05, 0.3),
        "the slow element does the work"
    );
    assert!(!pinned(20.0 * dt, 0.3, 0.05), "off the bound");
    let log = fitted_with(
        Effect::Creep,
        Form::Logarithmic,
        &[("creep_log_gain", 0.1)],
        dt,
    );
    assert!(
        !creep_pinned_fast(&log),
        "logarithmic creep has no free time constant"
    );
}

/// Creep yields to a drift of each record only when the drift also predicts the
/// validation record about as well.
#[test]
fn a_drift_is_taken_before_creep_only_if_it_predicts_as_well() {
    // Case 61 of seed 20261128: equal training ΔBIC, creep ahead on validation by 2,650.
    assert!(!drift_first(
        [-15047.9, -513701.4],
        [-15048.1, -511050.7],
        10.0
    ));
    // The same training ΔBIC and the same validation: the drift goes first.
    assert!(drift_first(
        [-15047.9, -513701.4],
        [-15048.1, -513695.0],
        10.0
    ));
    // Creep far ahead on training: creep, whatever the validation says.
    assert!(!drift_first([-20000.0, -5e5], [-15000.0, -6e5], 10.0));
}

/// A named effect's other forms are offered in later rounds (not dynamics, which has
/// its own upgrade from one mode to two).
#[test]
fn the_pool_offers_a_named_effects_other_forms() {
    let u: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
    let parent = Structure::with_forms(
        &[
            (Effect::Creep, Form::KelvinVoigt),
            (Effect::Dynamics, Form::OneMode),
        ],
        Some(1.0),
        Context::from_training(&u, 1e-3),
        Placement::After,
    );
    let pool = candidate_pool(&parent, &Options::default());
    let has = |e: Effect, f: Form| pool.iter().any(|p| p.parts == [(e, f)]);
    assert!(has(Effect::Creep, Form::Logarithmic));
    assert!(
        !has(Effect::Creep, Form::KelvinVoigt),
        "not the form it has"
    );
    assert!(has(Effect::Dynamics, Form::TwoModes));
    assert!(
        has(Effect::OffsetDrift, Form::Spline),
        "new effects as before"
    );
}

/// Pairs are drawn from the three best singles by training ΔBIC, one form per effect
/// and one timing at most, and the best timing joins them when none is among them
/// (seed 20261153 case 92's first-order lag ranked fifth behind creep's forms and
/// three drifts); effects the parent has and a single that does not lower BIC never.
#[test]
fn the_best_timing_joins_the_pair_members() {
    let u: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
    let parent = Structure::with_forms(
        &[(Effect::Saturation, Form::Hard)],
        Some(1.0),
        Context::from_training(&u, 1e-3),
        Placement::After,
    );
    let pool = candidate_pool(&parent, &Options::default());
    let at = |e: Effect, f: Form| pool.iter().position(|p| p.parts == [(e, f)]).unwrap();
    // The members (name and form) drawn from singles ranked by training ΔBIC, `same`
    // telling which explain one residual.
    let drawn = |ranked: &[(Effect, Form, f64)], same: &dyn Fn(usize, usize) -> bool| {
        let singles: Vec<(usize, f64)> = ranked.iter().map(|&(e, f, d)| (at(e, f), d)).collect();
        pair_members(&pool, &singles, &parent, 3, same)
            .iter()
            .map(|&i| format!("{} {}", pool[i].name(), pool[i].form()))
            .collect::<Vec<String>>()
    };
    let members = |ranked: &[(Effect, Form, f64)]| drawn(ranked, &|_, _| false);
    // Singles ranked by training ΔBIC, and the members expected from them.
    type Case<'a> = (&'a [(Effect, Form, f64)], &'a [&'a str]);
    let cases: [Case; 3] = [
        (
            &[
                (Effect::Creep, Form::KelvinVoigt, -133_445.0),
                (Effect::Creep, Form::Logarithmic, -129_427.0),
                (Effect::OffsetDrift, Form::Spline, -86_761.0),
                (Effect::Saturation, Form::Smooth, -50_000.0),
                (Effect::RateDependence, Form::Gain, -40_012.0),
                (Effect::InputLag, Form::SecondOrder, -2_406.0),
                (Effect::Delay, Form::Transport, -2_402.0),
            ],
            &[
                "creep kelvin-voigt",
                "offset-drift spline",
                "rate-dependence gain",
                "input-lag second-order",
            ],
        ),
        // A timing among the three: no extra, and no second timing.
        (
            &[
                (Effect::Delay, Form::Transport, -9_000.0),
                (Effect::InputLag, Form::FirstOrder, -8_000.0),
                (Effect::Creep, Form::KelvinVoigt, -7_000.0),
                (Effect::Asymmetry, Form::Even, -6_000.0),
            ],
            &[
                "delay transport",
                "creep kelvin-voigt",
                "asymmetry even-order",
            ],
        ),
        // A timing that does not lower BIC does not join.
        (
            &[
                (Effect::Creep, Form::KelvinVoigt, -7_000.0),
                (Effect::Delay, Form::Transport, 4.0),
            ],
            &["creep kelvin-voigt"],
        ),
    ];
    for (ranked, expected) in cases {
        assert_eq!(members(ranked), expected);
    }
    // A single explaining a member's residual gives its place to the next (seed
    // 20261155 case 98: delay, mode and creep held the places, the asymmetry beside
    // the delay was never tried).
    let ranked = [
        (Effect::Delay, Form::Transport, -6_767.0),
        (Effect::Dynamics, Form::OneMode, -6_747.0),
        (Effect::Creep, Form::KelvinVoigt, -2_731.0),
        (Effect::Asymmetry, Form::Even, -1_853.0),
    ];
    let (delay, mode) = (
        at(Effect::Delay, Form::Transport),
        at(Effect::Dynamics, Form::OneMode),
    );
    let same = |a: usize, b: usize| [a, b] == [mode, delay] || [a, b] == [delay, mode];
    assert_eq!(
        drawn(&ranked, &same),
        [
            "delay transport",
            "creep kelvin-voigt",
            "asymmetry even-order"
        ]
    );
    assert_eq!(
        members(&ranked),
        ["delay transport", "dynamics one-mode", "creep kelvin-voigt"]
    );
}

/// A round is skipped only when a pass would need a validation RMSE below the noise: the
/// room over the floor (the smaller of the validation record's and the pooled noise) is
/// measured against 15 % of the pooled noise variance.
#[test]
fn the_search_stops_at_the_noise_floor_only_when_a_pass_would_beat_the_noise() {
    let room = |r: f64| (1.0 + r).sqrt();
    let single = |rmse: f64, v: f64, n: f64| at_noise_floor(rmse, v, n, MIN_EXPLAINED);
    assert!(single(1.0, 1.0, 1.0), "at the floor");
    assert!(single(room(0.14), 1.0, 1.0));
    assert!(!single(room(0.16), 1.0, 1.0));
    // A validation record cleaner than the pooled noise leaves more room.
    assert!(!single(room(0.14), 0.9, 1.0));
    // A noisier one does not shrink the room below the pooled floor's.
    assert!(!single(room(0.16), 1.3, 1.0));
    // 15 % of the pooled variance, whatever the unit.
    assert!(single(2e-3 * room(0.14), 2e-3, 2e-3));
    assert!(!single(2e-3 * room(0.16), 2e-3, 2e-3));
    // A pair needs twice a single's share: room for a single may be none for a pair.
    assert!(at_noise_floor(room(0.25), 1.0, 1.0, 2.0 * MIN_EXPLAINED));
    assert!(!at_noise_floor(room(0.31), 1.0, 1.0, 2.0 * MIN_EXPLAINED));
}

/// The paired gain band sees what the parent's own band hides: on a record whose
/// noise is three times larger in its second half, a candidate removing a slow error of
/// 0.4 sigma RMS (16 % of the noise variance) lands inside the parent's RMSE band but its
/// gain band lies above zero; a candidate equal to the parent gives [0, 0], one that adds
/// the error lies below.
#[test]
fn the_paired_gain_band_finds_a_gain_inside_the_parents_band() {
    let n = 8000;
    let mut rng = TrialSeed::derive(5, "gain-band", "test", 0).rng(0);
    let noise: Vec<f64> = (0..n)
        .map(|k| (if k < n / 2 { 1.0 } else { 3.0 }) * standard_normal(&mut rng))
        .collect();
    let sigma = residual::rms(&noise);
    let slow: Vec<f64> = (0..n)
        .map(|k| 0.4 * sigma * 2f64.sqrt() * (k as f64 / 700.0).sin())
        .collect();
    let parent: Vec<f64> = noise.iter().zip(&slow).map(|(e, s)| e + s).collect();
    let worse: Vec<f64> = parent.iter().zip(&slow).map(|(e, s)| e + s).collect();
    let band = rmse_band(&parent, 1, "parent");
    assert!(
        residual::rms(&noise) > band[0],
        "the unpaired band already separates: {} vs {band:?}",
        residual::rms(&noise)
    );
    let better = gain_band(&parent, &noise, 1);
    assert!(better[0] > 0.0, "{better:?}");
    let same = gain_band(&parent, &parent, 1);
    assert_eq!(same, [0.0, 0.0]);
    let adds = gain_band(&parent, &worse, 1);
    assert!(adds[1] < 0.0, "{adds:?}");
}

/// The rule that recasts a mode as input timing: a resonance needs a 2x peak (ζ below
/// 0.26) below 0.4 of the sampling rate; two modes need one such.
#[test]
fn a_mode_is_a_resonance_only_with_a_resolved_peak() {
    let dt = 1e-3; // 1 kHz: modes resolved below 400 Hz
    let one = |hz: f64, zeta: f64| {
        let f = fitted(
            Form::OneMode,
            &[
                ("mode_log10_hz", hz.log10()),
                ("mode_log10_zeta", zeta.log10()),
            ],
            dt,
        );
        resonant(&f, dt)
    };
    assert_eq!(one(150.0, 0.05), Some(true));
    assert_eq!(one(150.0, 0.25), Some(true));
    assert_eq!(one(150.0, 0.3), Some(false), "no 2x peak");
    assert_eq!(one(150.0, 1.2), Some(false), "overdamped: a low-pass");
    assert_eq!(one(450.0, 0.02), Some(false), "too near Nyquist to resolve");
    let two = |z1: f64, z2: f64| {
        let f = fitted(
            Form::TwoModes,
            &[
                ("mode_log10_hz", 100f64.log10()),
                ("mode_log10_zeta", z1.log10()),
                ("mode2_log10_hz", 250f64.log10()),
                ("mode2_log10_zeta", z2.log10()),
                ("mode2_share", 0.4),
            ],
            dt,
        );
        resonant(&f, dt)
    };
    assert_eq!(two(1.0, 0.05), Some(true), "one resonant mode suffices");
    assert_eq!(two(1.0, 0.6), Some(false));
    // A sharp mode with a share of 0.5 % beside an overdamped one: the sum is a lag.
    let tiny = |share: f64| {
        let f = fitted(
            Form::TwoModes,
            &[
                ("mode_log10_hz", 150f64.log10()),
                ("mode_log10_zeta", 0.05f64.log10()),
                ("mode2_log10_hz", 347f64.log10()),
                ("mode2_log10_zeta", 0.85f64.log10()),
                ("mode2_share", share),
            ],
            dt,
        );
        resonant(&f, dt)
    };
    assert_eq!(tiny(0.995), Some(false), "0.5 % of a sharp mode");
    assert_eq!(tiny(0.5), Some(true), "half of it peaks 5x");
    let plain = Structure::new(&[], Some(1.0), Context::from_training(&[0.0, 1.0], dt));
    let f = Fitted::at(&plain, theta_with(&plain, &[]), &[0.0, 1.0], &[0.0, 1.0], 0);
    assert_eq!(resonant(&f, dt), None);
}

/// An exchange may not put modes with no resonance in place of input timing: blind seed
/// 20261160 case 0 (a 2-sample fractional delay at 1,040 Hz) was exchanged for a lag and a
/// mode at 497 Hz with ζ 1.2 beside one at 172 Hz with ζ 0.037 and a share of 7 %.
#[test]
fn an_exchange_cannot_put_a_low_pass_in_place_of_input_timing() {
    let dt = 1.0 / 1039.7;
    let modes = |hz: [f64; 2], zeta: [f64; 2], share: f64| {
        fitted(
            Form::TwoModes,
            &[
                ("mode_log10_hz", hz[0].log10()),
                ("mode_log10_zeta", zeta[0].log10()),
                ("mode2_log10_hz", hz[1].log10()),
                ("mode2_log10_zeta", zeta[1].log10()),
                ("mode2_share", share),
            ],
            dt,
        )
    };
    let lag = modes([496.75, 171.54], [1.199, 0.037], 0.068);
    let resonance = modes([33.1, 91.1], [0.065, 0.083], 0.4);
    let with = [Effect::InputLag, Effect::Dynamics];
    assert!(low_pass_for_timing(Effect::Delay, &with, &lag, dt));
    assert!(low_pass_for_timing(
        Effect::InputLag,
        &[Effect::Dynamics],
        &lag,
        dt
    ));
    assert!(
        !low_pass_for_timing(Effect::Delay, &with, &resonance, dt),
        "a resonance is not timing"
    );
    assert!(
        !low_pass_for_timing(Effect::Saturation, &with, &lag, dt),
        "only input timing"
    );
    assert!(
        !low_pass_for_timing(Effect::Delay, &[Effect::InputLag], &lag, dt),
        "no modes brought in"
    );
}

/// The judging rule (issue 50): a spline drift refitted on the whole validation record
/// fits it, so under the old rule it beat creep that only predicted it; judged by
/// prediction alone (the drift fitted on the samples before each forecast origin, the rest
/// forecast) creep wins. The record: steps and holds through `BoucWenState` and a
/// Kelvin-Voigt creep element written here (not `Structure`), whose gain is a third lower on
/// the validation record (a colder day): creep transfers, imperfectly, as real creep does
/// (old rule: drift 0.0040 against creep 0.0051; predicted: creep 0.010, drift 0.019).
#[test]
fn a_drift_refitted_on_the_judging_record_no_longer_beats_creep_that_predicts() {
    let dt = 0.02;
    let sigma = 2e-3;
    let ut = staircase(
        &[0.3, 4.2, 1.0, 3.6, 0.6, 2.8, 4.4, 1.8, 0.2, 3.2, 1.2, 4.0],
        3.0,
        dt,
    );
    let uv = staircase(
        &[0.4, 3.8, 0.8, 4.4, 2.0, 0.3, 3.4, 1.4, 4.1, 0.9, 2.6, 0.5],
        3.0,
        dt,
    );
    let none = |_: f64| 0.0;
    let data = Data::new(
        ut.clone(),
        creep_record(&ut, dt, 0.75, &none, sigma, (1, "judge")),
        uv.clone(),
        creep_record(&uv, dt, 0.5, &none, sigma, (2, "judge")),
        false,
        dt,
    );
    let opts = Options::default();
    let creep = plain_plus(&data, dt, Effect::Creep, Form::KelvinVoigt, &opts);
    let drift = plain_plus(&data, dt, Effect::OffsetDrift, Form::Spline, &opts);
    // The old rule: the record's own parts refitted on the whole validation record, and
    // the same samples scored.
    let refitted = |e: &Evaluated| {
        let (_, _, _, out, _) = data.validation_fit(&e.fitted, &data.uv, &data.yv, opts.seed);
        let r: Vec<f64> = data.yv.iter().zip(&out).map(|(y, m)| y - m).collect();
        residual::rms(&data.scored(&r))
    };
    let (old_creep, old_drift) = (refitted(&creep), refitted(&drift));
    assert!(
        old_drift < old_creep,
        "the old rule preferred the drift: {old_drift} against creep {old_creep}"
    );
    assert!(
        creep.validate_rmse < drift.validate_rmse,
        "predicted, creep wins: {} against the drift's {}",
        creep.validate_rmse,
        drift.validate_rmse
    );
    // Each says what it fitted on the validation record's own samples: the drift its
    // offset and knots, creep its offset and two initial creep states; the initial
    // hysteretic state for both.
    assert!(
        drift.fitted_v > creep.fitted_v,
        "{} {}",
        drift.fitted_v,
        creep.fitted_v
    );
    // The record's judging as diagnosis.json states it.
    let j = data.judging(&creep.fitted);
    assert_eq!(j.len(), 1);
    assert_eq!((j[0].samples, j[0].fitted_on_scored), (uv.len(), 0));
    assert_eq!(j[0].scored, uv.len() - uv.len() / 5);
}
