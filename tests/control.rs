//! `optbench control` end to end: a run's files, a diverging run reported as a result, and
//! bad input refused with exit code 2 and nothing written.

use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

fn optbench(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_optbench"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("run optbench")
}

fn summary(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn control_writes_signals_numbers_and_figures() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("imc");
    let o = optbench(
        &[
            "control",
            "--controller",
            "imc-rbf",
            "--reference",
            "sweep-1-2hz",
            "--duration",
            "1.5",
            "--transient",
            "0.5",
            "--param",
            "model_budget=1500",
            "--param",
            "model_duration=1",
            "--out",
            out.to_str().unwrap(),
        ],
        tmp.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("RMS error"), "{text}");
    let csv = std::fs::read_to_string(out.join("run.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1501);
    assert!(csv.starts_with("t_s,reference_mm,output_mm,error_mm,command_V,feedback_mm\n"));
    let s = summary(&out);
    assert_eq!(s["controller"]["kind"], "imc-rbf");
    assert_eq!(s["model_fit_evaluations"], 1500);
    let rmse = s["metrics"]["rmse_mm"].as_f64().unwrap();
    assert!(rmse > 0.0 && rmse < 0.3, "{rmse}");
    for f in [
        "time",
        "time-transient",
        "compensation",
        "compensation-transient",
    ] {
        for ext in ["svg", "png"] {
            assert!(out.join(format!("{f}.{ext}")).is_file(), "{f}.{ext}");
        }
    }
    // Same seed, same bytes.
    let again = tmp.path().join("again");
    let o = optbench(
        &[
            "control",
            "--controller",
            "imc-rbf",
            "--reference",
            "sweep-1-2hz",
            "--duration",
            "1.5",
            "--transient",
            "0.5",
            "--param",
            "model_budget=1500",
            "--param",
            "model_duration=1",
            "--out",
            again.to_str().unwrap(),
        ],
        tmp.path(),
    );
    assert!(o.status.success());
    assert_eq!(
        std::fs::read(out.join("run.csv")).unwrap(),
        std::fs::read(again.join("run.csv")).unwrap()
    );
}

#[test]
fn a_diverging_loop_is_a_result_not_an_error() {
    // The seed's PID gains on the twin: its 103 Hz mode makes the loop unstable.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("pid");
    let o = optbench(
        &[
            "control",
            "--controller",
            "pid",
            "--reference",
            "sweep-1-2hz",
            "--out",
            out.to_str().unwrap(),
        ],
        tmp.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("FAILED at"), "{text}");
    let s = summary(&out);
    let t = s["metrics"]["failure"]["time_s"].as_f64().unwrap();
    assert!(t > 0.0 && t < 1.0, "{t}");
    assert!(s["metrics"]["rmse_mm"].is_null());
    // The same loop without the mode is stable.
    let o = optbench(
        &[
            "control",
            "--controller",
            "pid",
            "--reference",
            "sweep-1-2hz",
            "--plant",
            "mode=off",
            "--out",
            out.to_str().unwrap(),
        ],
        tmp.path(),
    );
    assert!(o.status.success());
    assert!(summary(&out)["metrics"]["failure"].is_null());
}

#[test]
fn bad_input_exits_2_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("never");
    for (args, needle) in [
        (
            vec!["--controller", "lqr", "--reference", "sweep-1-2hz"],
            "valid: imc-rbf, pid",
        ),
        (
            vec![
                "--controller",
                "pid",
                "--reference",
                "sweep-1-2hz",
                "--param",
                "kq=1",
            ],
            "valid: kp, ki, kd",
        ),
        (
            vec![
                "--controller",
                "imc-rbf",
                "--reference",
                "sweep-1-2hz",
                "--param",
                "momentum=1.5",
            ],
            "momentum",
        ),
        (
            vec!["--controller", "pid", "--reference", "sine:freq=2"],
            "give a duration",
        ),
        (
            vec![
                "--controller",
                "pid",
                "--reference",
                "sweep-1-2hz",
                "--plant",
                "modes=off",
            ],
            "valid keys",
        ),
        (
            vec![
                "--controller",
                "pid",
                "--reference",
                "sweep-1-2hz",
                "--transient",
                "9",
            ],
            "transient",
        ),
    ] {
        let mut a = vec!["control"];
        a.extend(args);
        a.extend(["--out", out.to_str().unwrap()]);
        let o = optbench(&a, tmp.path());
        assert_eq!(o.status.code(), Some(2), "{a:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(needle), "{a:?}: {err}");
        assert!(!out.exists(), "{a:?} wrote {}", out.display());
    }
}
