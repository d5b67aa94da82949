//! `optbench diagnose --model pi` and `--model preisach`: a Prandtl-Ishlinskii (Preisach)
//! core names a linear effect added to a PI (Preisach) model's output (data made by
//! `PiModel` or `Preisach`, not by the chain it diagnoses with), and on the twin (a
//! Bouc-Wen core) what the PI core names beside the effect is said.

mod common;

use optbench::data::recording::Recording;
use optbench::diagnose::{Options, diagnose, proof};
use optbench::physics::linear::Mode;
use optbench::physics::prandtl_ishlinskii::{PiForm, PiModel};
use optbench::physics::preisach::{Preisach, PreisachGrid};

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
/// the two effects the core does not take are said.
fn mode_is_named(
    model: &str,
    (ut, uv): (&[f64], &[f64]),
    dt: f64,
    hysteresis: impl Fn(&[f64]) -> Vec<f64>,
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
    assert_eq!(d.not_applicable.len(), 2);
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
    mode_is_named("pi", (&ut, &uv), dt, |u| pi.simulate(u, dt));
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
    mode_is_named("preisach", (&ut, &uv), dt, |u| model.simulate(u, dt));
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

/// Effects the PI core does not take are refused when named, and `--help` says why.
#[test]
fn effects_a_pi_core_does_not_take_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |args: &[&str]| common::optbench(args, d);
    common::refused(
        &run(&[
            "diagnose",
            "--model",
            "pi",
            "--train",
            "a.csv",
            "--validate",
            "b.csv",
            "--effects",
            "delay,asymmetry",
        ]),
        &["asymmetry", "does not apply", "asymmetric form"],
    );
    common::refused(
        &run(&[
            "diagnose",
            "--proof",
            "--model",
            "pi",
            "--cases",
            "none,rate-dependence",
        ]),
        &["--cases rate-dependence", "does not search rate-dependence"],
    );
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
    let help = common::ok(&run(&["diagnose", "--help"]));
    assert!(
        help.contains("asymmetry and rate-dependence are not searched"),
        "{help}"
    );
    assert!(help.contains("--preisach-levels"), "{help}");
}
