//! The model family against its formulas, the plain model, the twin and itself.

use super::solve::span;
use super::*;
use crate::base::lstsq::dot;
use crate::physics::bouc_wen;
use crate::physics::twin::{self, TwinConfig};

/// A record that starts far from 0 V bounds its creep states by the excursion that
/// brought it there (slope times its first input), one near 0 V by its span; a joint
/// structure takes the most any of its records needs.
#[test]
fn creep_states_are_bounded_by_how_far_the_output_moved_since_rest() {
    let dt = 1e-3;
    let high: Vec<f64> = (0..1000).map(|k| 4.0 - 0.5 * k as f64 / 1000.0).collect();
    let low: Vec<f64> = high.iter().map(|x| x - 3.9).collect();
    let out = |u: &[f64]| -> Vec<f64> { u.iter().map(|x| 0.15 * x - 0.2).collect() };
    let st = Structure::new(
        &[Effect::Creep],
        Some(1.0),
        Context::from_training(&high, dt),
    );
    let (yh, yl) = (out(&high), out(&low));
    assert!((st.state_range(&high, &yh) - 0.6).abs() < 1e-9);
    assert!((st.state_range(&low, &yl) - span(&yl)).abs() < 1e-12);
    let joint = st.on_records(&[(1000, dt), (1000, 2.0 * dt)]);
    let u: Vec<f64> = low.iter().chain(&high).copied().collect();
    let y: Vec<f64> = yl.iter().chain(&yh).copied().collect();
    assert!((joint.state_range(&u, &y) - 0.6).abs() < 1e-9);
}

/// A model carried to half the sampling interval is the same continuous-time model: a
/// mode, a delay counted in samples and a drive filter give the same output at the
/// shared instants, up to the discretisation of the smooth drive.
#[test]
fn a_model_carried_to_another_interval_is_the_same_model() {
    let dt = 1e-3;
    let u = sine(2000, 3.0, dt);
    let parts = [
        (Effect::Delay, Form::Transport),
        (Effect::InputLag, Form::SecondOrder),
        (Effect::Dynamics, Form::OneMode),
    ];
    let ctx = Context::from_training(&u, dt);
    let st = Structure::with_forms(&parts, Some(1.0), ctx, Placement::After);
    let theta = theta_with(
        &st,
        &[
            ("delay_samples", 3.0),
            ("lag2_log10_hz", 80f64.log10()),
            ("mode_log10_hz", 40f64.log10()),
            ("mode_log10_zeta", 0.1f64.log10()),
        ],
    );
    let mut coef = vec![0.0; st.linear_names().len()];
    coef[0] = 1.0;
    coef[2] = 0.5;
    let fine = st.at_interval(dt / 2.0);
    let carried = st.carry(&theta, &fine);
    let at = |name: &str| fine.specs().iter().position(|s| s.name == name).unwrap();
    assert_eq!(carried[at("delay_samples")], 6.0);
    assert_eq!(carried[at("mode_log10_hz")], 40f64.log10());
    let (coarse_out, _) = st.simulate(&theta, &coef, &u);
    let (fine_out, _) = fine.simulate(&carried, &coef, &sine(4000, 3.0, dt / 2.0));
    // After the start-up transient, at the shared instants.
    let worst = (200..2000)
        .map(|k| (coarse_out[k] - fine_out[2 * k]).abs())
        .fold(0.0, f64::max);
    let span = coarse_out.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(worst < 0.006 * span, "worst {worst} of {span}");
    // Back to the training interval: the same parameters.
    let back = fine.carry(&carried, &st);
    for (a, b) in back.iter().zip(&theta) {
        assert!((a - b).abs() < 1e-12);
    }
    // A mode above a coarser record's Nyquist frequency is off there.
    let slow = st.at_interval(0.02);
    let off = st.carry(&theta, &slow);
    let m = slow
        .specs()
        .iter()
        .position(|s| s.name == "mode_log10_hz")
        .unwrap();
    assert_eq!(off[m], slow.specs()[m].upper);
}

fn sine(n: usize, f: f64, dt: f64) -> Vec<f64> {
    (0..n)
        .map(|k| 2.35 - 2.3 * (2.0 * std::f64::consts::PI * f * k as f64 * dt).cos())
        .collect()
}

#[test]
fn plain_model_equals_the_seed_bouc_wen() {
    // α-scaled g-form with n ≠ 1 reproduces bouc_wen::simulate of the dissertation's form.
    let dt = 1e-3;
    let u = sine(1500, 3.0, dt);
    let ctx = Context::from_training(&u, dt);
    for n in [1.0, 0.7, 1.6] {
        let p = BoucWenParams {
            d_e: 0.15,
            alpha: 0.05,
            beta: 0.4,
            gamma: 0.25,
            n,
            d0: 0.01,
        };
        let mut y = vec![0.0; u.len()];
        bouc_wen::simulate(&p, &u, &mut y);
        let st = Structure::new(&[], None, ctx);
        // Shape of p: σ = (β'+γ') = (β+γ) α^(n-1) = (s u_ref)^-n.
        let sigma = (p.beta + p.gamma) * p.alpha.powf(n - 1.0);
        let s = sigma.powf(-1.0 / n) / ctx.u_ref;
        let theta = [s.log10(), p.beta / (p.beta + p.gamma), n, 0.0];
        let fit = st.fit_linear(&theta, &u, &y);
        assert!(fit.cost < 1e-20, "n={n}: {}", fit.cost);
        let named = st.named_params(&theta, &fit.coef);
        let get = |k: &str| named.iter().find(|x| x.0 == k).unwrap().1;
        for (k, want) in [
            ("d_e", p.d_e),
            ("alpha", p.alpha),
            ("beta", p.beta),
            ("gamma", p.gamma),
            ("d0", p.d0),
        ] {
            assert!((get(k) - want).abs() < 1e-8 * (1.0 + want.abs()), "{k}");
        }
    }
}

#[test]
fn extensions_at_neutral_values_are_the_plain_model() {
    let dt = 1e-3;
    let u = sine(800, 5.0, dt);
    let y: Vec<f64> = u.iter().map(|x| 0.15 * x + 0.001 * x * x).collect();
    let ctx = Context::from_training(&u, dt);
    let plain = Structure::new(&[], Some(1.0), ctx);
    let theta = [-0.4, 0.6, 0.1];
    let base = plain.fit_linear(&theta, &u, &y);
    let all = Structure::new(&Effect::ALL, Some(1.0), ctx);
    let nested = plain.embed(&theta, &all);
    let ext = all.fit_linear(&nested, &u, &y);
    // Offset-drift and creep add free columns (drift, initial creep states), so their
    // cost can only be lower; the others equal the plain model's, in every form.
    assert!(ext.cost <= base.cost * (1.0 + 1e-12));
    for e in Effect::ALL {
        for &form in e.forms() {
            let one = Structure::with_forms(&[(e, form)], Some(1.0), ctx, Placement::After);
            assert_eq!(one.form(e), Some(form));
            let f = one.fit_linear(&plain.embed(&theta, &one), &u, &y);
            if matches!(e, Effect::OffsetDrift | Effect::Creep) {
                assert!(f.cost <= base.cost * (1.0 + 1e-12), "{}", one.label());
                continue;
            }
            assert!(
                (f.cost - base.cost).abs() <= 1e-10 * base.cost,
                "{}: {} vs {}",
                one.label(),
                f.cost,
                base.cost
            );
        }
    }
}

/// Each twin part is reproduced by the matching extension at the twin's values.
#[test]
fn extensions_reproduce_the_twin() {
    let dt = 1e-3;
    // From 0 V, where the twin rests (the model starts virgin at u[0]).
    let u: Vec<f64> = sine(1500, 4.0, dt).iter().map(|x| x - 0.05).collect();
    let ctx = Context::from_training(&u, dt);
    let base = "amp=off,mode=off,noise=off,quantization=off";
    let p = TwinConfig::default().command_scale_bouc_wen();
    let sigma = p.beta + p.gamma; // n = 1
    let s = (1.0 / sigma / ctx.u_ref).log10();
    let w = p.beta / (p.beta + p.gamma);
    let gain = 15.0;
    type Case<'a> = (&'a str, Vec<Effect>, Vec<(&'a str, f64)>);
    let cases: Vec<Case> = vec![
        ("", vec![], vec![]),
        (
            "amp=on,amp.cutoff_hz=500",
            vec![Effect::InputLag],
            vec![(
                "lag_log10_tau_s",
                (1.0 / (2.0 * std::f64::consts::PI * 500.0)).log10(),
            )],
        ),
        (
            "delay=0.002",
            vec![Effect::Delay],
            vec![("delay_samples", 2.0)],
        ),
        (
            "saturation.limit=60",
            vec![Effect::Saturation],
            vec![("sat_level", 60.0 / gain / ctx.u_ref)],
        ),
        (
            "asymmetry=0.001",
            vec![Effect::Asymmetry],
            vec![("asym_q", 0.001 * gain * ctx.u_ref)],
        ),
        (
            "mode=on,mode.freq_hz=150",
            vec![Effect::Dynamics],
            vec![
                ("mode_log10_hz", 150f64.log10()),
                ("mode_log10_zeta", 0.04f64.log10()),
            ],
        ),
        (
            "creep=on,creep.gain_slow=0.03,creep.tau_fast=0.3,creep.gain_fast=0.05",
            vec![Effect::Creep],
            vec![
                ("creep_g", 0.05),
                ("creep_log10_tau_s", 0.3f64.log10()),
                ("creep_g2", 0.03),
                ("creep_log10_tau2_s", 20f64.log10()),
            ],
        ),
    ];
    for (ov, effects, values) in cases {
        let cfg = TwinConfig::parse_overrides(&format!("{base},{ov}")).unwrap();
        let y = twin::simulate(&cfg, &u, dt, 0);
        let st = Structure::new(&effects, Some(1.0), ctx);
        let mut theta: Vec<f64> = st.specs().iter().map(|s| s.neutral).collect();
        theta[0] = s;
        theta[1] = w;
        for (name, v) in values {
            let i = st.specs().iter().position(|s| s.name == name).unwrap();
            theta[i] = v;
        }
        let fit = st.fit_linear(&theta, &u, &y);
        let rms = (2.0 * fit.cost / u.len() as f64).sqrt();
        assert!(rms < 2e-6, "{ov}: rms {rms}");
        assert!((fit.coef[0] - gain * 0.0103).abs() < 1e-3, "{ov}");
    }
}

/// The shape of `st` with the named values set, every other parameter neutral.
pub(crate) fn theta_with(st: &Structure, values: &[(&str, f64)]) -> Vec<f64> {
    st.specs()
        .iter()
        .map(|s| {
            values
                .iter()
                .find(|v| v.0 == s.name)
                .map_or(s.neutral, |v| v.1)
        })
        .collect()
}

#[test]
fn shift_reads_inside_the_record_as_at_its_ends() {
    // The direct formula with every index clamped, which `shift` applies at the ends.
    let reference = |u: &[f64], s: f64, curvature: f64| -> Vec<f64> {
        let n = u.len() as i64;
        if s == 0.0 || n < 2 {
            return u.to_vec();
        }
        let (w, t) = (s.floor() as i64, 1.0 - (s - s.floor()));
        let at = |i: i64| u[i.clamp(0, n - 1) as usize];
        let c0 = curvature * t * (1.0 - t) / 2.0 * (2.0 - t) / 3.0;
        let c1 = curvature * t * (1.0 - t) / 2.0 * (1.0 + t) / 3.0;
        (0..n)
            .map(|k| {
                let (p0, p1, p2, p3) = (at(k - w - 2), at(k - w - 1), at(k - w), at(k - w + 1));
                let line = p1 + t * (p2 - p1);
                if curvature == 0.0 || t == 1.0 {
                    line
                } else {
                    line - c0 * (p0 - 2.0 * p1 + p2) - c1 * (p1 - 2.0 * p2 + p3)
                }
            })
            .collect()
    };
    for n in [1usize, 2, 3, 4, 5, 9, 40] {
        let u: Vec<f64> = (0..n).map(|k| ((k * k) as f64 * 0.37).sin()).collect();
        let nf = n as f64;
        for s in [
            -nf - 7.3,
            -nf,
            -nf + 1.5,
            -3.25,
            -1.0,
            -0.5,
            0.0,
            0.4,
            1.0,
            2.75,
            nf - 1.5,
            nf,
            nf + 4.6,
        ] {
            for c in [0.0, 0.7, 1.0] {
                assert_eq!(shift(&u, s, c), reference(&u, s, c), "n {n} s {s} c {c}");
            }
        }
    }
}

#[test]
fn timing_moves_the_input_by_whole_and_fractional_samples() {
    let dt = 1e-3;
    let u = sine(900, 3.0, dt);
    let ctx = Context::from_training(&u, dt);
    let st = Structure::new(&[], Some(1.0), ctx);
    let shape = [("log10_s", -0.4), ("w", 0.6)];
    let coef = [0.15, 0.01, 0.05];
    // One sample earlier is the next sample (the last one held).
    let (early, _) = st.simulate(
        &theta_with(&st, &[shape[0], shape[1], ("timing_samples", -1.0)]),
        &coef,
        &u,
    );
    let mut next = u[1..].to_vec();
    next.push(u[u.len() - 1]);
    let (want, _) = st.simulate(&theta_with(&st, &shape), &coef, &next);
    for (a, b) in early.iter().zip(&want).skip(1) {
        assert!((a - b).abs() < 1e-12, "{a} {b}");
    }
    // Half a sample later is the mean of neighbours, before the hysteresis.
    let half: Vec<f64> = (0..u.len())
        .map(|k| 0.5 * (u[k] + u[k.saturating_sub(1)]))
        .collect();
    let (late, _) = st.simulate(
        &theta_with(&st, &[shape[0], shape[1], ("timing_samples", 0.5)]),
        &coef,
        &u,
    );
    let (want, _) = st.simulate(&theta_with(&st, &shape), &coef, &half);
    for (a, b) in late.iter().zip(&want) {
        assert!((a - b).abs() < 1e-12);
    }
}

#[test]
fn a_held_input_reaches_the_linear_blocks_one_sample_later() {
    let dt = 1e-3;
    let u = sine(800, 7.0, dt);
    let ctx = Context::from_training(&u, dt);
    let coef = [0.15, 0.01, 0.05];
    let shape = [("log10_s", -0.4), ("w", 0.6)];
    // Through an input lag of either form: a D/A hold is the whole chain one sample later
    // (the second-order lag ignored the hold once, and ran a sample ahead of a D/A).
    for (form, p) in [
        (Form::FirstOrder, ("lag_log10_tau_s", (2e-3f64).log10())),
        (Form::SecondOrder, ("lag2_log10_hz", 60f64.log10())),
    ] {
        let lag = Structure::with_forms(
            &[(Effect::InputLag, form)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        assert!(lag.specs().iter().any(|s| s.name == p.0));
        let (held, _) = lag.simulate(
            &theta_with(&lag, &[shape[0], shape[1], p, ("block_hold_samples", 1.0)]),
            &coef,
            &u,
        );
        let mut later = vec![u[0]];
        later.extend(&u[..u.len() - 1]);
        let (want, _) = lag.simulate(&theta_with(&lag, &[shape[0], shape[1], p]), &coef, &later);
        for (a, b) in held.iter().zip(&want) {
            assert!((a - b).abs() < 1e-12, "{form:?}: {a} {b}");
        }
    }
    // Without a linear block there is nothing to hold (the hysteresis is
    // rate-independent): the nuisance is not offered.
    let plain = Structure::new(&[], Some(1.0), ctx);
    assert!(!plain.specs().iter().any(|s| s.name == "block_hold_samples"));
    // Through a mode after the hysteresis it moves the output.
    let mode = Structure::with_forms(
        &[(Effect::Dynamics, Form::OneMode)],
        Some(1.0),
        ctx,
        Placement::After,
    );
    let p = ("mode_log10_hz", 150f64.log10());
    assert!(mode.specs().iter().any(|s| s.name == p.0));
    let (c, _) = mode.simulate(&theta_with(&mode, &[shape[0], shape[1], p]), &coef, &u);
    let (d, _) = mode.simulate(
        &theta_with(&mode, &[shape[0], shape[1], p, ("block_hold_samples", 1.0)]),
        &coef,
        &u,
    );
    assert!(c.iter().zip(&d).any(|(x, y)| (x - y).abs() > 1e-6));
}

#[test]
fn a_curved_shift_is_exact_for_cubics_and_a_straight_one_for_lines() {
    let cubic: Vec<f64> = (0..40)
        .map(|k| {
            let x = k as f64 * 0.1;
            1.0 - 0.5 * x + 0.3 * x * x - 0.07 * x * x * x
        })
        .collect();
    let line: Vec<f64> = (0..40).map(|k| 2.0 - 0.3 * k as f64).collect();
    for s in [0.3, -0.6, 1.45, -1.0] {
        let c = shift(&cubic, s, 1.0);
        let l = shift(&line, s, 0.0);
        // Away from the held ends.
        for k in 4..36 {
            let x = (k as f64 - s) * 0.1;
            let want = 1.0 - 0.5 * x + 0.3 * x * x - 0.07 * x * x * x;
            assert!(
                (c[k] - want).abs() < 1e-12,
                "s {s} k {k}: {} vs {want}",
                c[k]
            );
            assert!((l[k] - (2.0 - 0.3 * (k as f64 - s))).abs() < 1e-12);
        }
        // A straight shift of a cubic is not exact (curvature matters).
        let straight = shift(&cubic, s, 0.0);
        if s.fract() != 0.0 {
            assert!((4..36).any(|k| (straight[k] - c[k]).abs() > 1e-4));
        }
    }
}

#[test]
fn saturation_forms_are_their_formulas() {
    // The memoryless forms equal the plain model driven by the transformed input.
    let dt = 1e-3;
    let u = sine(900, 3.0, dt);
    let ctx = Context::from_training(&u, dt);
    let plain = Structure::new(&[], Some(1.0), ctx);
    let shape = [("log10_s", -0.4), ("w", 0.6)];
    let coef = [0.15, 0.01, 0.05];
    let r = ctx.u_ref;
    type Formula = Box<dyn Fn(f64) -> f64>;
    let cases: [(Form, &str, f64, Formula); 3] = [
        (
            Form::Hard,
            "sat_level",
            0.8,
            Box::new(move |x: f64| x.clamp(-0.8 * r, 0.8 * r)),
        ),
        (
            Form::Smooth,
            "sat_smooth_k",
            1.3,
            Box::new(move |x: f64| r / 1.3 * (1.3 * x / r).tanh()),
        ),
        (
            Form::Cubic,
            "sat_cubic",
            0.2,
            Box::new(move |x: f64| x - 0.2 * x.powi(3) / (r * r)),
        ),
    ];
    for (form, name, value, formula) in cases {
        let st = Structure::with_forms(
            &[(Effect::Saturation, form)],
            Some(1.0),
            ctx,
            Placement::After,
        );
        let (got, _) = st.simulate(
            &theta_with(&st, &[shape[0], shape[1], (name, value)]),
            &coef,
            &u,
        );
        let x: Vec<f64> = u.iter().map(|&v| formula(v)).collect();
        let (want, _) = plain.simulate(&theta_with(&plain, &shape), &coef, &x);
        let worst = got
            .iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "{}: {worst}", form.name());
        // And the form does change the output.
        let (neutral, _) = st.simulate(&theta_with(&st, &shape), &coef, &u);
        assert!(
            got.iter().zip(&neutral).any(|(a, b)| (a - b).abs() > 1e-4),
            "{}",
            form.name()
        );
    }
}

#[test]
fn rich_forms_nest_their_simple_ones_and_act() {
    let dt = 1e-3;
    let u = sine(3000, 2.0, dt);
    let ctx = Context::from_training(&u, dt);
    let shape = [("log10_s", -0.4), ("w", 0.6)];
    let coef = [0.15, 0.01, 0.05];
    // Two modes with no share of the second are the one mode.
    let one = Structure::new(&[Effect::Dynamics], Some(1.0), ctx);
    let two = one.extended_with(Effect::Dynamics, Form::TwoModes);
    assert_eq!(two.label(), "bouc-wen+dynamics[two-modes]");
    let m = [
        ("mode_log10_hz", 80f64.log10()),
        ("mode_log10_zeta", 0.05f64.log10()),
    ];
    let (a, _) = one.simulate(
        &theta_with(&one, &[shape[0], shape[1], m[0], m[1]]),
        &coef,
        &u,
    );
    let th2 = one.embed(&theta_with(&one, &[shape[0], shape[1], m[0], m[1]]), &two);
    let (b, _) = two.simulate(&th2, &coef, &u);
    assert_eq!(a, b);
    // Every non-default form moves the output away from the plain model.
    let plain = Structure::new(&[], Some(1.0), ctx);
    let (base, _) = plain.simulate(&theta_with(&plain, &shape), &coef, &u);
    type Act<'a> = (Effect, Form, Vec<(&'a str, f64)>);
    let acts: [Act; 5] = [
        (
            Effect::InputLag,
            Form::SecondOrder,
            vec![("lag2_log10_hz", 30f64.log10())],
        ),
        (Effect::Asymmetry, Form::Direction, vec![("asym_dir", 0.2)]),
        (Effect::RateDependence, Form::Gain, vec![("rate_rho", 0.5)]),
        (
            Effect::Creep,
            Form::Logarithmic,
            vec![("creep_log_gain", 0.05)],
        ),
        (
            Effect::Dynamics,
            Form::TwoModes,
            vec![
                m[0],
                m[1],
                ("mode2_log10_hz", 150f64.log10()),
                ("mode2_share", 0.5),
            ],
        ),
    ];
    for (e, form, values) in acts {
        let st = Structure::with_forms(&[(e, form)], Some(1.0), ctx, Placement::After);
        let mut v = values.clone();
        v.extend(shape);
        let (out, status) = st.simulate(&theta_with(&st, &v), &coef, &u);
        assert_eq!(status, Status::Ok, "{}", st.label());
        let diff = out
            .iter()
            .zip(&base)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff > 1e-4, "{}: {diff}", st.label());
    }
}

/// The hysteretic state at the first sample is at most the saturation level and at
/// most twice the drive's peak: a weakly saturating loop cannot start far out at its
/// saturation level (where only a slow relaxation moves it), and `h0` reports the
/// state the simulation starts from.
#[test]
fn the_initial_hysteretic_state_is_capped_at_twice_the_drive_peak() {
    let dt = 1e-3;
    let u: Vec<f64> = (0..2000).map(|k| 1.5 * (k as f64 * 0.01).sin()).collect();
    let ctx = Context::from_training(&u, dt);
    let plain = Structure::new(&[], Some(1.0), ctx);
    let coef = [0.0, 0.0, 1.0];
    for (log10_s, start) in [(1.0, 2.0 * 1.5), (-0.4, 10f64.powf(-0.4) * 1.5)] {
        for frac in [-1.0, 1.0] {
            let theta = theta_with(
                &plain,
                &[("log10_s", log10_s), ("w", 0.6), ("g0_frac", frac)],
            );
            let (out, status) = plain.simulate(&theta, &coef, &u);
            assert_eq!(status, Status::Ok);
            let h0 = plain
                .named_params(&theta, &coef)
                .into_iter()
                .find(|p| p.0 == "h0")
                .unwrap()
                .1;
            // The third column is the state with its sign turned: `-g`.
            assert!(
                (out[0] + frac * start).abs() < 1e-6 * start
                    && (h0 - frac * start).abs() < 1e-6 * start,
                "log10 s {log10_s}, g0_frac {frac}: output {} h0 {h0}, expected state {}",
                out[0],
                frac * start
            );
        }
    }
}

#[test]
fn logarithmic_creep_grows_evenly_per_decade_after_a_step() {
    let dt = 1e-3;
    let n = 40_000;
    let u: Vec<f64> = (0..n).map(|k| if k < 10 { 0.0 } else { 1.0 }).collect();
    let ctx = Context::from_training(&u, dt);
    let st = Structure::with_forms(
        &[(Effect::Creep, Form::Logarithmic)],
        Some(1.0),
        ctx,
        Placement::After,
    );
    // A purely elastic actuator (no hysteresis: α = 0), creep 2 % per decade.
    let th = theta_with(&st, &[("creep_log_gain", 0.02)]);
    let mut coef = vec![0.0; st.linear_names().len()];
    coef[0] = 1.0;
    let (y, _) = st.simulate(&th, &coef, &u);
    // Growth over each decade inside the band (0.1-1 s, 1-10 s) is about the same.
    let at = |t: f64| y[10 + (t / dt) as usize];
    let (d1, d2) = (at(1.0) - at(0.1), at(10.0) - at(1.0));
    assert!(d1 > 0.01 && d2 > 0.01, "{d1} {d2}");
    assert!((d1 / d2 - 1.0).abs() < 0.35, "{d1} {d2}");
}

/// A 20 s, 0.5 Hz sine at 100 Hz and the plain model's output on it: the record the
/// drift forms are added to.
pub(super) fn slow_plain_record() -> (Vec<f64>, Context, Structure, Vec<f64>, Vec<f64>) {
    let dt = 1e-2;
    let u = sine(2000, 0.5, dt);
    let ctx = Context::from_training(&u, dt);
    let plain = Structure::new(&[], Some(1.0), ctx);
    let theta = theta_with(&plain, &[("log10_s", -0.4), ("w", 0.6)]);
    let (y0, _) = plain.simulate(&theta, &[0.15, 0.0, 0.05], &u);
    (u, ctx, plain, theta, y0)
}

#[test]
fn spline_drift_recovers_a_piecewise_linear_drift_and_belongs_to_the_record() {
    let (u, ctx, plain, theta, y0) = slow_plain_record();
    // A wander through the spline's own knots (8 segments over samples 0..=1999).
    let knots = [0.0, 0.3, -0.2, 0.1, 0.4, 0.0, -0.3, 0.2, 0.1];
    let drift = |k: usize| {
        let x = k as f64 / (1999.0 / 8.0);
        let j = (x.floor() as usize).min(7);
        knots[j] + (x - j as f64) * (knots[j + 1] - knots[j])
    };
    let y: Vec<f64> = y0
        .iter()
        .enumerate()
        .map(|(k, v)| v + 1e-2 * drift(k))
        .collect();
    let st = Structure::with_forms(
        &[(Effect::OffsetDrift, Form::Spline)],
        Some(1.0),
        ctx,
        Placement::After,
    );
    assert_eq!(spline_segments(&ctx), 8);
    let fit = st.fit_linear(&plain.embed(&theta, &st), &u, &y);
    assert!(fit.cost < 1e-20, "{}", fit.cost);
    let names = st.linear_names();
    let rec: Vec<&str> = st
        .record_coefs()
        .iter()
        .map(|&i| names[i].as_str())
        .collect();
    assert!(rec.contains(&"d0") && rec.contains(&"drift_k8") && !rec.contains(&"d_e"));
}

#[test]
fn settling_drift_recovers_an_exponential_and_belongs_to_the_record() {
    let (u, ctx, plain, theta, y0) = slow_plain_record();
    let (dt, tau) = (ctx.dt, 4.0);
    let y: Vec<f64> = y0
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.02 * (1.0 - (-(k as f64) * dt / tau).exp()))
        .collect();
    let st = Structure::with_forms(
        &[(Effect::OffsetDrift, Form::Settling)],
        Some(1.0),
        ctx,
        Placement::After,
    );
    let mut th = plain.embed(&theta, &st);
    let i = st
        .specs()
        .iter()
        .position(|s| s.name == "drift_log10_tau_s");
    th[i.expect("settling has a time constant")] = tau.log10();
    let fit = st.fit_linear(&th, &u, &y);
    assert!(fit.cost < 1e-20, "{}", fit.cost);
    let names = st.linear_names();
    let at = names.iter().position(|n| *n == "drift_settling").unwrap();
    assert!((fit.coef[at] + 0.02).abs() < 1e-9, "{}", fit.coef[at]);
    assert!(st.record_coefs().contains(&at));
    // A wrong time constant leaves a remainder: the form is not a free offset.
    th[i.unwrap()] = (0.1 * tau).log10();
    assert!(st.fit_linear(&th, &u, &y).cost > 1e-6);
}

#[test]
fn a_creep_element_without_gain_cannot_stand_for_a_drift() {
    let (u, ctx, plain, theta, y0) = slow_plain_record();
    let dt = ctx.dt;
    // A slow decay of the record's own (a drift), not driven by the input.
    let y: Vec<f64> = y0
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.02 * (-(k as f64) * dt / 8.0).exp())
        .collect();
    let st = Structure::with_forms(
        &[(Effect::Creep, Form::KelvinVoigt)],
        Some(1.0),
        ctx,
        Placement::After,
    );
    // The plain record's shape, a slow element of 8 s.
    let shape = [
        ("log10_s", -0.4),
        ("w", 0.6),
        ("creep_log10_tau2_s", 8f64.log10()),
    ];
    let th = theta_with(&st, &shape);
    // No gain: the initial states are held at zero, the decay stays in the residual.
    let none = st.fit_linear(&th, &u, &y);
    let x0 = st.initial_state_coefs();
    assert!(x0.iter().all(|&j| none.coef[j] == 0.0), "{:?}", none.coef);
    // Creep of no gain is the plain model exactly, on the plain model's cost.
    let plain_cost = plain.fit_linear(&theta, &u, &y).cost;
    assert!(
        plain_cost > 1e-3,
        "the decay is not in the plain model: {plain_cost}"
    );
    assert!(
        (none.cost / plain_cost - 1.0).abs() < 1e-9,
        "{} vs {plain_cost}",
        none.cost
    );
    // With gain, the state may depart from rest up to the gain times the output's span.
    let th = theta_with(&st, &[shape.as_slice(), &[("creep_g2", 0.2)]].concat());
    let some = st.fit_linear(&th, &u, &y);
    let bound = st.state_bounds(&th, span(&y));
    assert!(bound.iter().any(|b| b.1 > 0.0));
    for (j, lim) in bound {
        assert!(
            some.coef[j].abs() <= lim + 1e-12,
            "{} > {lim}",
            some.coef[j]
        );
    }
    assert!(some.cost < none.cost);
}

/// A record cut from a running ramp starts in motion: the rate's memory starts at that
/// rate, so a rate-dependent gain is the same from the first sample (no start-up
/// transient of the rate time constant for a drift or creep to soak up).
#[test]
fn the_rate_memory_starts_at_the_rate_the_record_starts_with() {
    let dt = 1e-3;
    let u: Vec<f64> = (0..600).map(|k| 0.5 + 2e-3 * k as f64).collect();
    let ctx = Context::from_training(&u, dt);
    let st = Structure::with_forms(
        &[(Effect::RateDependence, Form::Gain)],
        Some(1.0),
        ctx,
        Placement::After,
    );
    let th = theta_with(
        &st,
        &[("rate_rho", 0.8), ("rate_log10_tau_s", (0.05f64).log10())],
    );
    // Only the drive term (d_e = 1): v (1 + ρ r), r the rate over its reference.
    let (out, _) = st.simulate(&th, &[1.0, 0.0, 0.0], &u);
    let gain: Vec<f64> = out.iter().zip(&u).map(|(y, x)| y / x).collect();
    let settled = gain[599];
    assert!(settled > 1.1, "the rate acts: gain {settled}");
    for (k, g) in gain.iter().enumerate() {
        assert!(
            (g - settled).abs() < 1e-9,
            "sample {k}: gain {g} vs {settled}"
        );
    }
}

#[test]
fn rate_dependent_width_acts_inside_the_bouc_wen_equation() {
    // A triangle (constant |du/dt|, so the rate's low-pass settles to 1) then a hold.
    let dt = 1e-3;
    let tri: Vec<f64> = (0..1600)
        .map(|k| {
            let p = (k % 400) as f64 / 200.0;
            2.0 * if p <= 1.0 { p } else { 2.0 - p }
        })
        .collect();
    let rho = 0.7;
    for n in [1.0, 1.6] {
        let mut u = tri.clone();
        u.extend(std::iter::repeat_n(tri[1599], 300));
        let ctx = Context::from_training(&tri, dt);
        let st = Structure::with_forms(
            &[(Effect::RateDependence, Form::Width)],
            Some(n),
            ctx,
            Placement::After,
        );
        let th = theta_with(
            &st,
            &[
                ("log10_s", -0.4),
                ("w", 0.6),
                ("rate_rho", rho),
                ("rate_log10_tau_s", (2.0 * dt).log10()),
            ],
        );
        let (out, _) = st.simulate(&th, &[0.0, 0.0, -1.0], &u);
        // Reference: dg/du = k - (β sgn(du g) + γ)|g|^n with k = 1 + ρ, by fine Euler
        // steps from the model's own state at sample 800.
        let sigma = (10f64.powf(-0.4) * ctx.u_ref).powf(-n);
        let (beta, gamma) = (0.6 * sigma, 0.4 * sigma);
        let mut g = out[800];
        for k in 801..1600 {
            let du = (u[k] - u[k - 1]) / 2000.0;
            for _ in 0..2000 {
                g += du * ((1.0 + rho) - (beta * (du * g).signum() + gamma) * g.abs().powf(n));
            }
            assert!((out[k] - g).abs() < 1e-4 * (1.0 + g.abs()), "n={n} k={k}");
        }
        // For n = 1 the loop is 1+ρ times the rate-free one (g = k h solves it)...
        if n == 1.0 {
            let plain = Structure::new(&[], Some(n), ctx);
            let pth = theta_with(&plain, &[("log10_s", -0.4), ("w", 0.6)]);
            let (p, _) = plain.simulate(&pth, &[0.0, 0.0, -1.0], &u);
            for k in [1000, 1200, 1400] {
                assert!((out[k] / p[k] - (1.0 + rho)).abs() < 1e-3, "{k}");
            }
        }
        // ...and keeps its state while the drive holds, however the rate decays.
        assert!(out[1600..].iter().all(|x| *x == out[1600]));
    }
}

#[test]
fn drift_columns_recover_a_linear_drift() {
    let dt = 1e-3;
    let u = sine(2000, 2.0, dt);
    let ctx = Context::from_training(&u, dt);
    let plain = Structure::new(&[], Some(1.0), ctx);
    let theta = [-0.4, 0.6, 0.0];
    let (y0, _) = plain.simulate(&theta, &[0.15, 0.0, 0.05], &u);
    let y: Vec<f64> = y0
        .iter()
        .enumerate()
        .map(|(k, v)| v + 3e-3 * k as f64 * dt)
        .collect();
    let st = Structure::new(&[Effect::OffsetDrift], Some(1.0), ctx);
    let fit = st.fit_linear(&theta, &u, &y);
    assert!(fit.cost < 1e-20);
    let named = st.named_params(&theta, &fit.coef);
    let rate = named.iter().find(|x| x.0 == "drift_per_s").unwrap().1;
    assert!((rate - 3e-3).abs() < 1e-9, "{rate}");
}

#[test]
fn hostile_shapes_give_finite_costs() {
    let dt = 1e-3;
    let u = sine(300, 8.0, dt);
    let y: Vec<f64> = u.iter().map(|x| 0.15 * x).collect();
    let ctx = Context::from_training(&u, dt);
    let st = Structure::new(&Effect::ALL, None, ctx);
    let cap = cost_cap(&y);
    let d = st.specs().len();
    for v in [f64::NAN, f64::INFINITY, -1e300, 1e300, 0.0, -5.0] {
        for i in 0..d {
            let mut theta: Vec<f64> = st.specs().iter().map(|s| s.neutral).collect();
            theta[i] = v;
            let f = st.fit_linear(&theta, &u, &y);
            assert!(f.cost.is_finite() && f.cost >= 0.0, "{i}={v}: {}", f.cost);
            assert!(f.cost <= 2.0 * cap);
            let (out, _) = st.simulate(&theta, &f.coef, &u);
            assert!(out.iter().all(|x| x.is_finite()));
        }
    }
    // Bounds: every corner is finite too.
    for corner in 0..(1u32 << d.min(10)) {
        let theta: Vec<f64> = st
            .specs()
            .iter()
            .enumerate()
            .map(|(i, s)| {
                if corner >> (i % 10) & 1 == 1 {
                    s.upper
                } else {
                    s.lower
                }
            })
            .collect();
        assert!(st.fit_linear(&theta, &u, &y).cost.is_finite());
    }
}

/// The theta of physical restoring-force parameters `(m, c, k, α, β, γ, n)` on `ctx`,
/// and the output scale `a` (the structure's first linear coefficient).
fn feedback_theta(st: &Structure, p: [f64; 7]) -> (Vec<f64>, f64) {
    let [m, c, k, alpha, beta, gamma, n] = p;
    let stiff = k + alpha;
    let a = st.context().u_ref / stiff;
    let w = (stiff / m).sqrt();
    let pa = a.powf(n) * alpha.powf(n - 1.0);
    let theta = st
        .specs()
        .iter()
        .map(|s| match s.name {
            "fb_log10_hz" => (w / (2.0 * std::f64::consts::PI)).log10(),
            "fb_log10_zeta" => (c / (2.0 * (stiff * m).sqrt())).log10(),
            "fb_r" => alpha / stiff,
            "fb_b" => beta * pa,
            "fb_c" => gamma * pa,
            "n" => n,
            _ => s.neutral,
        })
        .collect();
    (theta, a)
}

#[test]
fn feedback_placement_is_the_physical_restoring_force_model() {
    // Data from the oscillator in physical form; the structure's fit reproduces them
    // and its named parameters are the physical ones.
    let dt = 1.0 / 750.0;
    let u: Vec<f64> = (0..3000)
        .map(|k| {
            let t = k as f64 * dt;
            60.0 * (2.0 * std::f64::consts::PI * 13.0 * t).sin()
                + 35.0 * (2.0 * std::f64::consts::PI * 41.0 * t + 1.0).sin()
        })
        .collect();
    let ctx = Context::from_training(&u, dt).with_hold(Hold::Linear);
    let st = Structure::placed(&[], None, ctx, Placement::Feedback);
    assert!(st.has(Effect::Dynamics));
    assert_eq!(st.label(), "bouc-wen+dynamics(feedback)");
    let phys = [2.0, 10.0, 5e4, 5e4, 800.0, -1100.0, 1.3];
    let (theta, a) = feedback_theta(&st, phys);
    let osc = Oscillator {
        omega: 2.0 * std::f64::consts::PI * 10f64.powf(theta[0]),
        zeta: 10f64.powf(theta[1]),
        r: theta[2],
        b: theta[3],
        c: theta[4],
        n: 1.3,
    };
    let x: Vec<f64> = u.iter().map(|v| v / ctx.u_ref).collect();
    let fine = upsample(&x, Hold::Linear, osc.substeps(dt, MIN_SUBSTEPS));
    let yi = osc.respond(&fine, dt, x[0], 0.0).unwrap();
    let y: Vec<f64> = yi.iter().map(|v| a * v + 3e-5).collect();
    let lf = st.fit_linear(&theta, &u, &y);
    assert_eq!(lf.status, Status::Ok);
    assert!((lf.coef[0] / a - 1.0).abs() < 1e-9, "{:?}", lf.coef);
    assert!((lf.coef[1] - 3e-5).abs() < 1e-12);
    assert!(lf.cost < 1e-20, "{}", lf.cost);
    let named: std::collections::BTreeMap<String, f64> =
        st.named_params(&theta, &lf.coef).into_iter().collect();
    for (name, want) in [
        ("mass", 2.0),
        ("damping", 10.0),
        ("stiffness", 5e4),
        ("alpha", 5e4),
        ("beta", 800.0),
        ("gamma", -1100.0),
        ("n", 1.3),
    ] {
        assert!(
            (named[name] / want - 1.0).abs() < 1e-6,
            "{name}: {}",
            named[name]
        );
    }
}

#[test]
fn feedback_placement_embeds_shared_parameters_and_stays_finite() {
    let dt = 1e-3;
    let u = sine(800, 5.0, dt);
    let ctx = Context::from_training(&u, dt);
    let after = Structure::new(&[Effect::Delay], None, ctx);
    let fb = after.with_placement(Placement::Feedback);
    assert_eq!(fb.effects(), &[Effect::Delay, Effect::Dynamics]);
    assert_eq!(fb.linear_names(), vec!["scale", "d0"]);
    let mut theta: Vec<f64> = after.specs().iter().map(|s| s.neutral).collect();
    let i = after
        .specs()
        .iter()
        .position(|s| s.name == "delay_samples")
        .unwrap();
    theta[i] = 2.5;
    let moved = after.embed(&theta, &fb);
    let j = fb
        .specs()
        .iter()
        .position(|s| s.name == "delay_samples")
        .unwrap();
    assert_eq!(moved[j], 2.5);
    // Rate-dependence is not offered around a feedback loop.
    assert!(
        !fb.extended(Effect::RateDependence)
            .has(Effect::RateDependence)
    );
    // Every corner of the box: a finite cost, never NaN.
    let y: Vec<f64> = u.iter().map(|v| 0.3 * v).collect();
    let specs = fb.specs().to_vec();
    for corner in 0..(1usize << specs.len()) {
        let th: Vec<f64> = specs
            .iter()
            .enumerate()
            .map(|(b, s)| {
                if corner >> b & 1 == 1 {
                    s.upper
                } else {
                    s.lower
                }
            })
            .collect();
        let lf = fb.fit_linear(&th, &u, &y);
        assert!(
            lf.cost.is_finite() && lf.cost <= 2.0 * cost_cap(&y),
            "{th:?}"
        );
    }
}

#[test]
fn projected_fit_equals_least_squares_on_all_columns() {
    let dt = 1e-3;
    let u = sine(3000, 2.0, dt);
    let ctx = Context::from_training(&u, dt);
    for (parts, placement) in [
        (vec![(Effect::OffsetDrift, Form::Spline)], Placement::After),
        (
            vec![
                (Effect::OffsetDrift, Form::Spline),
                (Effect::Creep, Form::KelvinVoigt),
            ],
            Placement::After,
        ),
        (
            vec![
                (Effect::OffsetDrift, Form::Polynomial),
                (Effect::Creep, Form::KelvinVoigt),
            ],
            Placement::After,
        ),
        (vec![], Placement::After),
        (
            vec![(Effect::OffsetDrift, Form::Polynomial)],
            Placement::Feedback,
        ),
    ] {
        let st = Structure::with_forms(&parts, Some(1.0), ctx, placement);
        // Creep with gain (its states free inside their bounds), two time constants a
        // decade apart on a spline drift: near-collinear decays and hats.
        let theta = theta_with(
            &st,
            &[
                ("creep_g", 0.05),
                ("creep_log10_tau_s", 0.3f64.log10()),
                ("creep_g2", 0.03),
                ("creep_log10_tau2_s", 3f64.log10()),
            ],
        );
        let y: Vec<f64> = u
            .iter()
            .enumerate()
            .map(|(k, x)| 0.3 * x + 0.1 * (k as f64 * 0.01).sin() + 0.02 * (k % 7) as f64)
            .collect();
        let (cols, _) = st.columns(&theta, &u);
        assert_eq!(cols.len(), st.linear_names().len(), "{}", st.label());
        let reference = st.fit_linear_reference(&theta, &u, &y);
        let (direct, e) = (reference.coef, reference.cost);
        let fit = st.fit_linear(&theta, &u, &y);
        assert!(
            (fit.cost / e - 1.0).abs() < 1e-9,
            "{} {} {e}",
            st.label(),
            fit.cost
        );
        for (a, b) in fit.coef.iter().zip(&direct) {
            assert!(
                (a - b).abs() <= 1e-7 * (1.0 + b.abs()),
                "{}: {a} vs {b}",
                st.label()
            );
        }
        // The residuals a Gauss-Newton polish linearises are the fit's own: y minus
        // every column (the fixed ones included) times its coefficient.
        let (with_r, r) = st.fit_linear_residuals(&theta, &u, &y, &st.projection(&u, &y));
        assert_eq!(with_r.cost.to_bits(), fit.cost.to_bits());
        assert_eq!(r.len(), y.len());
        let scale = y.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (k, rk) in r.iter().enumerate() {
            let m: f64 = cols.iter().zip(&fit.coef).map(|(c, b)| c[k] * b).sum();
            assert!(
                (rk - (y[k] - m)).abs() < 1e-9 * scale,
                "{}: sample {k}",
                st.label()
            );
        }
        assert!((0.5 * dot(&r, &r) / fit.cost - 1.0).abs() < 1e-12);
    }
}

/// Three seconds of a 9 rad/s sine about `centre`, its amplitude beating between 0 and
/// `amp`: nested minor loops for a hysteresis core.
fn beating(centre: f64, amp: f64, dt: f64) -> Vec<f64> {
    (0..3000)
        .map(|k| {
            let t = k as f64 * dt;
            centre + amp * (0.5 + 0.5 * (1.3 * t).cos()) * (9.0 * t).sin()
        })
        .collect()
}

/// The plain structure on a linear-in-weights `core` over `u`, with its neutral shape; it
/// is labelled `label` and has neither a Bouc-Wen exponent nor initial state.
fn core_structure(u: &[f64], dt: f64, core: PiCore, label: &str) -> (Structure, Vec<f64>) {
    let st = Structure::new(&[], None, Context::from_training(u, dt).with_pi(Some(core)));
    assert_eq!(st.label(), label);
    assert!(
        st.specs()
            .iter()
            .all(|s| s.name != "n" && s.name != "g0_frac")
    );
    let theta = st.specs().iter().map(|s| s.neutral).collect();
    (st, theta)
}

/// A PI core without extensions is the plain PI model ([`PiModel`], computed by its own
/// code), and its linear fit finds that model's weights and offset exactly.
#[test]
fn a_pi_core_is_the_plain_pi_model_and_fits_its_weights() {
    use crate::physics::prandtl_ishlinskii::{PiForm, PiModel};
    let dt = 1e-3;
    let u = beating(2.0, 1.8, dt);
    let core = PiCore::new(6, &[&u]);
    let pi = PiModel {
        form: PiForm::Plain,
        thresholds: core.thresholds(),
        weights: vec![3.0, 1.0, 0.5, 0.0, 0.25, 0.1],
        rate_weights: vec![],
        poly: vec![],
        offset: -4.0,
        input_offset: 0.0,
    };
    let (st, theta) = core_structure(&u, dt, core, "pi");
    let mut coef = vec![pi.weights[0], pi.offset];
    coef.extend(&pi.weights[1..]);
    let (y, status) = st.simulate(&theta, &coef, &u);
    assert_eq!(status, Status::Ok);
    let want = pi.simulate(&u, dt);
    let worst = y
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-12, "{worst}");
    let fit = st.fit_linear(&theta, &u, &want);
    for (a, b) in fit.coef.iter().zip(&coef) {
        assert!((a - b).abs() < 1e-8, "{:?} vs {coef:?}", fit.coef);
    }
    // With asymmetry the core is the asymmetric PI model (its quadratic `a₂ v²`, again
    // computed by `PiModel`'s own code): one more linear column, weight `a₂ u_ref`.
    let st2 = st.extended(Effect::Asymmetry).extended(Effect::Creep);
    assert_eq!(st2.effects(), &[Effect::Asymmetry, Effect::Creep]);
    let sa = st.extended(Effect::Asymmetry);
    assert_eq!(sa.pi_operators(), 7);
    let asym = PiModel {
        form: PiForm::Asymmetric,
        poly: vec![0.3, 0.0],
        ..pi.clone()
    };
    let theta_a: Vec<f64> = sa.specs().iter().map(|s| s.neutral).collect();
    let mut coef_a = coef.clone();
    coef_a.push(0.3 * sa.context().u_ref);
    let (ya, status) = sa.simulate(&theta_a, &coef_a, &u);
    assert_eq!(status, Status::Ok);
    let worst_a = ya
        .iter()
        .zip(asym.simulate(&u, dt))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst_a < 1e-9, "{worst_a}");
    let named = sa.named_params(&theta_a, &coef_a);
    assert!(
        named
            .iter()
            .any(|(k, v)| k == "asymmetry_a2" && *v == coef_a[7])
    );
}

/// A Preisach core without extensions is the Preisach model of its grid ([`Preisach`],
/// computed by its own code, demagnetised at the first input), and its linear fit
/// reproduces a record that model made. (The relay columns need not be independent, so
/// the output, not each weight, is what the fit must recover.)
#[test]
fn a_preisach_core_is_the_preisach_model_and_fits_its_records() {
    use crate::physics::preisach::{Preisach, PreisachGrid};
    let dt = 1e-3;
    let u = beating(1.0, 1.5, dt);
    let core = PiCore::preisach(5, &[&u]);
    let grid = core.grid();
    assert_eq!(grid, PreisachGrid::for_input(5, &u).unwrap());
    assert_eq!(core.columns(), 15);
    let weights: Vec<f64> = (0..15).map(|k| 0.1 + 0.05 * (k % 4) as f64).collect();
    let model = Preisach {
        grid,
        weights: weights.clone(),
        offset: -0.7,
    };
    let (st, theta) = core_structure(&u, dt, core, "preisach");
    let names = st.linear_names();
    assert_eq!(names[..3], ["mu[0,0]", "d0", "mu[1,0]"]);
    assert_eq!(names.len(), 16);
    let mut coef = vec![weights[0], model.offset];
    coef.extend(&weights[1..]);
    let (y, status) = st.simulate(&theta, &coef, &u);
    assert_eq!(status, Status::Ok);
    let want = model.simulate(&u, dt);
    let worst = |a: &[f64]| {
        a.iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    };
    assert!(worst(&y) < 1e-12, "{}", worst(&y));
    let fit = st.fit_linear(&theta, &u, &want);
    let (refit, _) = st.simulate(&theta, &fit.coef, &u);
    assert!(worst(&refit) < 1e-9, "{}", worst(&refit));
    // Each relay's parameters name its weight and its (up, down) thresholds.
    let p = st.named_params(&theta, &coef);
    let t = model.grid.thresholds();
    let get = |n: &str| p.iter().find(|(k, _)| k == n).map(|x| x.1);
    assert_eq!(get("mu[3,1]"), Some(weights[PreisachGrid::index(3, 1)]));
    assert_eq!(get("up[3,1]"), Some(t[3]));
    assert_eq!(get("down[3,1]"), Some(t[1]));
    // Asymmetry is left out (the plane shapes any asymmetric loop); rate dependence is
    // taken in its weights' form only.
    let st2 = st
        .extended(Effect::Asymmetry)
        .extended(Effect::RateDependence)
        .extended(Effect::Creep);
    assert_eq!(st2.effects(), &[Effect::RateDependence, Effect::Creep]);
    assert_eq!(st2.form(Effect::RateDependence), Some(Form::Gain));
}

/// The Preisach core's static weight names are the grid's own, and a structure file
/// written before the Preisach core (no `kind`) still reads as a PI core.
#[test]
fn preisach_names_match_the_grid_and_old_files_read_as_pi() {
    use crate::physics::preisach::PreisachGrid;
    let g = PreisachGrid::new(MAX_PREISACH_LEVELS, 0.0, 1.0).unwrap();
    let mut names = crate::physics::prandtl_ishlinskii::LinearInWeights::names(&g);
    names.pop();
    assert_eq!(names, PREISACH_WEIGHTS);
    let old: PiCore = serde_json::from_str(r#"{"operators":6,"half_range":2.0}"#).unwrap();
    assert_eq!(old.kind, CoreKind::Plays);
    assert_eq!(old.columns(), 6);
}
