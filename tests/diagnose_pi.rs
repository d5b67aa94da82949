//! `optbench diagnose --model pi` and `--model preisach`: a Prandtl-Ishlinskii (Preisach)
//! core names a linear effect added to a PI (Preisach) model's output (data made by
//! `PiModel` or `Preisach`, not by the chain it diagnoses with), and on the twin (a
//! Bouc-Wen core) what the PI core names beside the effect is said.

mod common;

use optbench::data::recording::Recording;
use optbench::diagnose::{Options, diagnose, forecast, proof, report};
use optbench::physics::linear::Mode;
use optbench::physics::prandtl_ishlinskii::{PiForm, PiModel};
use optbench::physics::preisach::{Preisach, PreisachGrid};
use optbench::render::table::sig;

fn pi_opts(seed: u64) -> Options {
    Options {
        model: "pi".into(),
        seed,
        ..Options::default()
    }
}

/// `h` through a lightly damped 60 Hz mode (a stack driving a structure), with a small
/// deterministic noise (xorshift), 0.02 % of the stroke.
fn through_a_mode(name: &str, u: &[f64], h: &[f64], dt: f64, seed: u64) -> Recording {
    let mut mode = Mode::new(60.0, 0.05, dt);
    mode.settle(h[0]);
    let mut s = seed;
    let y: Vec<f64> = h
        .iter()
        .map(|&x| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            mode.step(x) + 2e-3 * ((s % 2001) as f64 / 1000.0 - 1.0)
        })
        .collect();
    Recording::uniform(name, dt, u.to_vec(), y).unwrap()
}

/// `hysteresis` through the mode on the training and validation inputs `(ut, uv)`:
/// diagnosed with a `model` core, `dynamics` alone is named, at the mode's frequency, and
/// the effects the core does not take are said (`not_taken` of them).
fn mode_is_named(
    model: &str,
    (ut, uv): (&[f64], &[f64]),
    dt: f64,
    hysteresis: impl Fn(&[f64]) -> Vec<f64>,
    not_taken: usize,
) {
    let record =
        |u: &[f64], seed: u64, name: &str| through_a_mode(name, u, &hysteresis(u), dt, seed);
    let (t, v) = (record(ut, 3, "train"), record(uv, 5, "validate"));
    let opts = Options {
        model: model.into(),
        ..pi_opts(2)
    };
    let d = diagnose(&t, &v, &opts).unwrap();
    assert_eq!(d.accepted_labels(), vec!["dynamics".to_string()]);
    let f = d.final_model.params["mode_freq_hz"];
    assert!((f - 60.0).abs() < 3.0, "mode at {f} Hz");
    assert_eq!(d.not_applicable.len(), not_taken, "{:?}", d.not_applicable);
}

/// A PI model's output through a lightly damped mode (a stack driving a structure), with
/// noise: the diagnosis with a PI core of the same thresholds names `dynamics` alone, at
/// the mode's frequency. The records come from two different excitations.
#[test]
fn a_mode_after_a_pi_model_is_named() {
    let dt = 1e-3;
    let (ut, uv) = proof::signals(4.0, dt, 11).unwrap();
    let thresholds = PiModel::uniform_thresholds(10, &ut);
    let pi = PiModel {
        form: PiForm::Plain,
        weights: vec![2.0, 0.9, 0.7, 0.5, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05],
        thresholds,
        rate_weights: vec![],
        poly: vec![],
        offset: 1.0,
        input_offset: 0.0,
    };
    mode_is_named("pi", (&ut, &uv), dt, |u| pi.simulate(u, dt), 0);
}

/// A Preisach model's output through the same mode: the diagnosis with a Preisach core of
/// the same grid (the training input's range, six levels, the default) names `dynamics`
/// alone, at the mode's frequency (weights and sizes chosen once, not tuned).
#[test]
fn a_mode_after_a_preisach_model_is_named() {
    let dt = 1e-3;
    let (ut, uv) = proof::signals(4.0, dt, 11).unwrap();
    let grid = PreisachGrid::for_input(6, &ut).unwrap();
    // Heavier weights near the diagonal (narrow loops), lighter far from it.
    let weights: Vec<f64> = (0..6)
        .flat_map(|i| (0..=i).map(move |j| 0.6 / (1.0 + (i - j) as f64)))
        .collect();
    let model = Preisach {
        grid,
        weights,
        offset: 1.0,
    };
    mode_is_named("preisach", (&ut, &uv), dt, |u| model.simulate(u, dt), 1);
}

/// On the twin (a Bouc-Wen core) a concealed effect, enlarged above the PI core's own
/// misfit of a Bouc-Wen loop (seed and sizes chosen once, not tuned), is named by the PI
/// diagnosis as by the Bouc-Wen one; the PI core's misfit itself stays well above the
/// noise, and what it names beside the effect stands in for it.
#[test]
fn a_concealed_twin_effect_is_named_by_both_cores() {
    use optbench::physics::structure::Effect;
    let kinds = [
        proof::CaseKind {
            truth: Some(Effect::Delay),
            size: 6e-3,
        },
        proof::CaseKind {
            truth: Some(Effect::Dynamics),
            size: 45.0,
        },
    ];
    for kind in &kinds {
        let (t, v) = proof::generate(kind, 7, 4.0).unwrap();
        let pi = diagnose(&t, &v, &pi_opts(7)).unwrap();
        let bw_opts = Options {
            model: "bouc-wen-n1".into(),
            seed: 7,
            ..Options::default()
        };
        let bw = diagnose(&t, &v, &bw_opts).unwrap();
        let name = kind.name().to_string();
        assert_eq!(bw.accepted_labels(), vec![name.clone()]);
        assert!(
            pi.accepted_labels().contains(&name),
            "{:?}",
            pi.accepted_labels()
        );
        let ratio = pi.final_model.validate_rmse / pi.noise_floor;
        assert!(
            ratio > 5.0,
            "{name}: the PI core fits the Bouc-Wen twin to {ratio}x the noise"
        );
    }
}

/// The one effect the Preisach core does not take is refused when named, and `--help`
/// says why; the PI core takes every effect (`--proof --cases` with it accepted).
#[test]
fn effects_a_core_does_not_take_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |args: &[&str]| common::optbench(args, d);
    common::refused(
        &run(&[
            "diagnose",
            "--model",
            "preisach",
            "--train",
            "a.csv",
            "--validate",
            "b.csv",
            "--effects",
            "asymmetry",
        ]),
        &["asymmetry", "does not apply", "Preisach weights"],
    );
    // With a PI core asymmetry is accepted: the error is the missing file, not the effect.
    let out = run(&[
        "diagnose",
        "--model",
        "pi",
        "--train",
        "a.csv",
        "--validate",
        "b.csv",
        "--effects",
        "asymmetry,rate-dependence",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("a.csv"), "{err}");
    assert!(!err.contains("does not apply"), "{err}");
    let help = common::ok(&run(&["diagnose", "--help"]));
    assert!(
        help.contains("so asymmetry is not") && help.contains("searched"),
        "{help}"
    );
    assert!(help.contains("--preisach-levels"), "{help}");
    assert!(help.contains("the loop is not Bouc-Wen's"), "{help}");
}

/// A plain PI model with small noise (a separate implementation, `PiModel`, not the chain
/// the diagnosis fits), `offset` added.
fn pi_record(name: &str, pi: &PiModel, u: &[f64], dt: f64, seed: u64) -> Recording {
    let mut s = seed;
    let y: Vec<f64> = pi
        .simulate(u, dt)
        .into_iter()
        .map(|x| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            x + 2e-3 * ((s % 2001) as f64 / 1000.0 - 1.0)
        })
        .collect();
    Recording::uniform(name, dt, u.to_vec(), y).unwrap()
}

/// The training and validation records of `pi` on `(ut, uv)`, noise seeds `seed` and
/// `seed + 2`.
fn pi_records(
    pi: &PiModel,
    (ut, uv): (&[f64], &[f64]),
    dt: f64,
    seed: u64,
) -> (Recording, Recording) {
    (
        pi_record("train", pi, ut, dt, seed),
        pi_record("validate", pi, uv, dt, seed + 2),
    )
}

/// The final model predicts the validation record below `share` of the baseline's error.
fn predicts_better(d: &optbench::diagnose::Diagnosis, share: f64) {
    assert!(
        d.final_model.validate_rmse < share * d.baseline.validate_rmse,
        "{} against {}",
        d.final_model.validate_rmse,
        d.baseline.validate_rmse
    );
}

fn plain_pi(weights: Vec<f64>, u: &[f64]) -> PiModel {
    PiModel {
        form: PiForm::Plain,
        thresholds: PiModel::uniform_thresholds(weights.len(), u),
        weights,
        rate_weights: vec![],
        poly: vec![],
        offset: 1.0,
        input_offset: 0.0,
    }
}

/// The PI model's asymmetric form (a quadratic in the input added to the plays,
/// `PiModel`'s own code) is named `asymmetry` by a PI core, which now takes it as a drive
/// warped before its plays (sizes chosen once, not tuned).
#[test]
fn an_asymmetric_pi_model_is_named_asymmetry_by_a_pi_core() {
    let dt = 1e-3;
    let (ut, uv) = proof::signals(4.0, dt, 13).unwrap();
    let pi = PiModel {
        form: PiForm::Asymmetric,
        poly: vec![0.25, 0.0],
        ..plain_pi(
            vec![2.0, 0.9, 0.7, 0.5, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05],
            &ut,
        )
    };
    let (t, v) = pi_records(&pi, (&ut, &uv), dt, 3);
    let d = diagnose(&t, &v, &pi_opts(3)).unwrap();
    assert_eq!(d.accepted_labels(), vec!["asymmetry".to_string()]);
    predicts_better(&d, 0.2);
}

/// The rate-dependent PI of Ang et al. (each weight growing with the instantaneous rate,
/// `PiModel`'s own code) is named `rate-dependence` by a PI core, whose form low-passes the
/// rate: the independent model's instantaneous rate lies inside that family's range.
#[test]
fn a_rate_dependent_pi_model_is_named_rate_dependence_by_a_pi_core() {
    let dt = 1e-3;
    let (ut, uv) = proof::signals(4.0, dt, 17).unwrap();
    let weights = vec![2.0, 0.9, 0.7, 0.5, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05];
    let pi = PiModel {
        form: PiForm::RateDependent,
        rate_weights: weights.iter().map(|w| 0.02 * w).collect(),
        ..plain_pi(weights, &ut)
    };
    let (t, v) = pi_records(&pi, (&ut, &uv), dt, 7);
    let d = diagnose(&t, &v, &pi_opts(5)).unwrap();
    assert!(
        d.accepted_labels()
            .first()
            .is_some_and(|l| l.starts_with("rate-dependence")),
        "{:?}",
        d.accepted_labels()
    );
    predicts_better(&d, 0.5);
}

/// A loop Bouc-Wen cannot shape: a PI model whose weight sits on two wide plays (flat
/// stretches, sharp corners, and nested minor loops inside them that stay linear, the
/// nonlocal memory Bouc-Wen's single state does not have). With `--model auto` the Bouc-Wen
/// search is rejected, the operator cores are searched, and the PI core is kept for
/// predicting the validation record's nested loops below Bouc-Wen's band: the first
/// finding. Weights and signals chosen once, not tuned.
#[test]
fn a_loop_bouc_wen_cannot_shape_is_given_to_the_pi_core() {
    let dt = 1e-3;
    let (ut, _) = proof::signals(4.0, dt, 19).unwrap();
    // The validation drive: a sine at 1 Hz whose amplitude shrinks over the record, nested
    // loops about the centre of the training range.
    let n = ut.len();
    let uv: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 * dt;
            let a = 2.2 * (1.0 - 0.8 * t / (n as f64 * dt));
            2.35 + a * (2.0 * std::f64::consts::PI * t).sin()
        })
        .collect();
    let pi = plain_pi(vec![1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.5, 1.5, 0.0], &ut);
    let (t, v) = pi_records(&pi, (&ut, &uv), dt, 11);
    let opts = Options {
        model: "auto".into(),
        seed: 7,
        ..Options::default()
    };
    let d = diagnose(&t, &v, &opts).unwrap();
    let c = d
        .core_choice
        .as_ref()
        .expect("auto says how the core was chosen");
    assert_eq!(c.chosen, "pi", "{}", c.finding);
    assert!(
        c.finding.starts_with("the loop is not Bouc-Wen's"),
        "{}",
        c.finding
    );
    assert!(!c.tried_because.is_empty());
    assert_eq!(c.trials.len(), 3);
    let bw = &c.trials[0];
    assert_eq!(bw.core, "bouc-wen");
    assert!(d.final_model.validate_rmse < bw.validate_band[0]);
    assert!(
        d.final_model.model.starts_with("pi"),
        "{}",
        d.final_model.model
    );
    assert_eq!(d.model, "auto: pi");
    // The figures of the method: each core's final model (one series per core, named by
    // its final model and its validation RMSE), the validation residual with its lead and
    // every forecast origin marked where the judging put them.
    for t in &c.trials {
        assert_eq!(t.validate_out.len(), d.series.y[1].len(), "{}", t.core);
    }
    let kept = c.trials.iter().find(|t| t.chosen).unwrap();
    assert_eq!(kept.validate_out, d.series.final_model[1]);
    let series = report::core_series(&d);
    assert_eq!(series.len(), c.trials.len());
    for (t, (label, pts)) in c.trials.iter().zip(&series) {
        assert!(label.starts_with(&t.model), "{label}");
        assert!(label.contains(&sig(t.validate_rmse, 3)), "{label}");
        assert!(!pts.is_empty());
    }
    let origins = forecast::origins(&d.series.u[1]);
    assert_eq!(d.series.origins, origins);
    assert_eq!(d.series.leads.len(), 1);
    assert_eq!(d.series.leads[0], 0..origins[0]);
    let marks = report::judging_marks(&d.series);
    let at: Vec<f64> = origins.iter().map(|&k| d.series.t[1][k]).collect();
    assert_eq!(marks.rules.unwrap().1, at);
    assert_eq!(marks.band.unwrap().1, vec![(d.series.t[1][0], at[0])]);
    let dir = tempfile::tempdir().unwrap();
    report::write(&d, dir.path()).unwrap();
    for stem in ["validate_cores", "validate_residual_time"] {
        for ext in ["png", "svg"] {
            assert!(dir.path().join(format!("{stem}.{ext}")).exists(), "{stem}");
        }
    }
    // The training drive has no holds: no holds' figure.
    assert!(!dir.path().join("train_steps.png").exists());
    assert_eq!(d.step_evidence.holds, 0);
    // Unexplained structure: its figure, the residual against the feature, on training and
    // validation, with the correction.
    let unexplained = dir.path().join("validate_unexplained.png").exists();
    assert_eq!(
        unexplained,
        d.outside_vocabulary
            .as_ref()
            .is_some_and(|o| o.plot.is_some())
    );
    if let Some(p) = d.outside_vocabulary.as_ref().and_then(|o| o.plot.as_ref()) {
        let series = report::unexplained_series(&d);
        assert_eq!(series.len(), if p.by_direction { 6 } else { 3 });
        assert_eq!(p.train_x.len(), d.series.u[0].len());
    }
    // A refusal is a field of its own, set exactly where the evidence says so.
    for c in &d.candidates {
        assert_eq!(
            c.refused.is_some(),
            c.evidence.contains("refused"),
            "{}",
            c.evidence
        );
    }
}

/// On the twin (a Bouc-Wen core) with a concealed delay, `--model auto` has nothing to
/// reject: the Bouc-Wen search reaches the noise floor, the other cores are not searched,
/// and the effect is named as with `--model bouc-wen`.
#[test]
fn auto_keeps_bouc_wen_on_the_twin() {
    let kind = proof::CaseKind {
        truth: Some(optbench::physics::structure::Effect::Delay),
        size: 6e-3,
    };
    let (t, v) = proof::generate(&kind, 3, 4.0).unwrap();
    let opts = Options {
        model: "auto".into(),
        seed: 3,
        ..Options::default()
    };
    let d = diagnose(&t, &v, &opts).unwrap();
    let c = d
        .core_choice
        .as_ref()
        .expect("auto says how the core was chosen");
    assert_eq!(c.chosen, "bouc-wen", "{}", c.finding);
    assert_eq!(c.trials.len(), 1, "{}", c.finding);
    assert!(c.tried_because.is_empty());
    assert_eq!(d.accepted_labels(), vec!["delay".to_string()]);
}
