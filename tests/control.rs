//! `optbench control` end to end: a run's files, a diverging run reported as a result, and
//! bad input refused with exit code 2 and nothing written.

mod common;

use common::optbench;
use serde_json::Value;
use std::path::Path;

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
    // The dissertation's PID gains on the twin: its 103 Hz mode makes the loop unstable.
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
            "[possible values: imc-rbf, pid, ff-pi, ff-bw, ff-pi+pid, ff-bw+pid]",
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

/// A control suite small enough for a test: 2 trials, 1.5 s references, quick model fits.
const TINY_SUITE: &str = r#"name = "tiny-control"
seed = 5
trials = 2

[control]
references = ["sweep-1-2hz", { id = "sine3", spec = "sine:freq=3,amp=0.2,offset=0.3,phase=-1.5707963267948966", duration = 1.5 }]
transient = 0.5
figures = FIGURES

[[controller]]
id = "IMC"
kind = "imc-rbf"
model_budget = 600
model_duration = 1.0

[[controller]]
id = "PID"
kind = "pid"
ki = 0.4
kp = 0.3
kd = 0.2

[[plant]]
id = "twin"

[[plant]]
id = "mismatch"
twin = "creep=on"
model_twin = "mode=off"
references = ["sine3"]

[[table]]
id = "t"
title = "Tiny table"
columns = ["3 Hz"]
rows = [{ label = "IMC", cells = ["IMC/twin/sine3"], seed = [0.003] }]
"#;

fn write_suite(dir: &Path, figures: bool) -> std::path::PathBuf {
    let p = dir.join("tiny.toml");
    std::fs::write(&p, TINY_SUITE.replace("FIGURES", &figures.to_string())).unwrap();
    p
}

#[test]
fn control_suite_runs_through_optbench_run() {
    let tmp = tempfile::tempdir().unwrap();
    let suite = write_suite(tmp.path(), true);
    let out = tmp.path().join("res");
    let o = optbench(
        &[
            "run",
            suite.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            "2",
        ],
        tmp.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("Tiny table") && text.contains("(dissertation 0.00300)"),
        "{text}"
    );
    // 2 controllers x (2 references on twin + 1 on mismatch) x 2 trials.
    let runs = std::fs::read_to_string(out.join("runs.jsonl")).unwrap();
    assert_eq!(runs.lines().count(), 12);
    // One model per (identification twin, trial): default and mode=off.
    let models = std::fs::read_to_string(out.join("models.jsonl")).unwrap();
    assert_eq!(models.lines().count(), 4);
    // Controllers share the noise of a (reference, plant, trial); IMC runs of one trial
    // share the model across references.
    let recs: Vec<Value> = runs
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let find = |c: &str, p: &str, r: &str, t: u64| {
        recs.iter()
            .find(|x| {
                x["controller"] == c && x["plant"] == p && x["reference"] == r && x["trial"] == t
            })
            .unwrap()
            .clone()
    };
    assert_eq!(
        find("IMC", "twin", "sine3", 1)["noise_seed"],
        find("PID", "twin", "sine3", 1)["noise_seed"]
    );
    assert_ne!(
        find("IMC", "twin", "sine3", 0)["noise_seed"],
        find("IMC", "twin", "sine3", 1)["noise_seed"]
    );
    assert_eq!(
        find("IMC", "twin", "sine3", 0)["model_seed"],
        find("IMC", "twin", "sweep-1-2hz", 0)["model_seed"]
    );
    assert_ne!(
        find("IMC", "twin", "sine3", 0)["model_seed"],
        find("IMC", "mismatch", "sine3", 0)["model_seed"]
    );
    for f in [
        "report.md",
        "summary.json",
        "provenance.json",
        "suite.toml",
        "tables/t.md",
        "tables/t.tex",
        "tables/cells.csv",
        "signals/IMC_twin_sine3_trial0.csv",
        "figures/IMC_twin_sine3_time.png",
        "figures/IMC_twin_sine3_compensation.svg",
        "figures/PID_mismatch_sine3_compensation-transient.png",
        "figures/rmse_twin_sweep-1-2hz.png",
        "report.html",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // The page, the Markdown, the LaTeX and the browser's rendering (tools permitting).
    common::check_report_outputs(&out);
    let cells: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(cells.as_array().unwrap().len(), 6);
}

#[test]
fn control_suite_same_seed_same_bytes_on_any_thread_count() {
    let tmp = tempfile::tempdir().unwrap();
    let suite = write_suite(tmp.path(), false);
    let run = |threads: &str, seed: &str| {
        let out = tmp.path().join(format!("r{threads}-{seed}"));
        let o = optbench(
            &[
                "run",
                suite.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--threads",
                threads,
                "--seed",
                seed,
                "-q",
            ],
            tmp.path(),
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        ["runs.jsonl", "models.jsonl", "summary.json", "tables/t.md"]
            .map(|f| std::fs::read(out.join(f)).unwrap())
    };
    let a = run("1", "5");
    let b = run("2", "5");
    assert_eq!(a, b);
    let c = run("2", "6");
    assert_ne!(a[0], c[0]);
}

#[test]
fn bad_control_suites_name_file_line_and_key() {
    let tmp = tempfile::tempdir().unwrap();
    let base = TINY_SUITE.replace("FIGURES", "false");
    for (from, to, needle) in [
        (
            "kind = \"pid\"",
            "kind = \"lqr\"",
            ":18: unknown controller kind `lqr`",
        ),
        (
            "ki = 0.4",
            "kx = 0.4",
            ":19: controller `PID`: controller `pid`: unknown parameter `kx`",
        ),
        (
            "twin = \"creep=on\"",
            "twin = \"creep=maybe\"",
            "plant `mismatch`",
        ),
        (
            "\"IMC/twin/sine3\"",
            "\"IMC/mismatch/sweep-1-2hz\"",
            "does not run",
        ),
        ("transient = 0.5", "transient = 2.0", "`transient` = 2"),
        ("model_budget = 600", "model_budget = 0", "model_budget"),
        (
            "references = [\"sine3\"]",
            "references = [\"sine9\"]",
            "`references` names `sine9`",
        ),
    ] {
        assert!(base.contains(from), "{from}");
        let p = tmp.path().join("bad.toml");
        std::fs::write(&p, base.replace(from, to)).unwrap();
        let out = tmp.path().join("never");
        let o = optbench(
            &["run", p.to_str().unwrap(), "--out", out.to_str().unwrap()],
            tmp.path(),
        );
        assert_eq!(o.status.code(), Some(2), "{to}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("bad.toml") && err.contains(needle),
            "{to}: {err}"
        );
        assert!(!out.exists());
    }
}

/// The four feedforward kinds beside the PID, on the twin and the mismatch plant.
const FF_SUITE: &str = r#"name = "tiny-ff"
seed = 7
trials = 2

[control]
references = [{ id = "sine3", spec = "sine:freq=3,amp=0.2,offset=0.3,phase=-1.5707963267948966", duration = 1.5 }]
transient = 0.5
figures = false

[[controller]]
id = "FF-PI"
kind = "ff-pi"
operators = 8

[[controller]]
id = "FF-BW"
kind = "ff-bw"
model_budget = 800
model_duration = 2.0

[[controller]]
kind = "ff-pi+pid"             # id defaults to the kind with '-' for '+'
operators = 8

[[controller]]
id = "FF-BW-PID"
kind = "ff-bw+pid"
model_budget = 800
model_duration = 2.0
ki = 0.2

[[controller]]
id = "PID"
kind = "pid"
ki = 0.4
kp = 0.3
kd = 0.2

[[plant]]
id = "twin"

[[plant]]
id = "mismatch"
twin = "creep=on"
model_twin = "mode=off"

[[table]]
id = "ff"
title = "Feedforward table"
columns = ["twin", "mismatch"]
rows = [
  { label = "ff-pi", cells = ["FF-PI/twin/sine3", "FF-PI/mismatch/sine3"] },
  { label = "ff-bw", cells = ["FF-BW/twin/sine3", "FF-BW/mismatch/sine3"] },
  { label = "ff-pi+pid", cells = ["ff-pi-pid/twin/sine3", "ff-pi-pid/mismatch/sine3"] },
  { label = "ff-bw+pid", cells = ["FF-BW-PID/twin/sine3", "FF-BW-PID/mismatch/sine3"] },
  { label = "pid", cells = ["PID/twin/sine3", "PID/mismatch/sine3"] },
]
"#;

#[test]
fn feedforward_controllers_run_in_a_suite_and_fill_its_tables() {
    let tmp = tempfile::tempdir().unwrap();
    let suite = tmp.path().join("ff.toml");
    std::fs::write(&suite, FF_SUITE).unwrap();
    let out = tmp.path().join("res");
    let o = optbench(
        &[
            "run",
            suite.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        tmp.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = std::fs::read_to_string(out.join("tables/ff.md")).unwrap();
    for label in ["ff-pi", "ff-bw", "ff-pi+pid", "ff-bw+pid", "pid"] {
        let row = table
            .lines()
            .find(|l| l.starts_with(&format!("| {label} ")))
            .unwrap_or_else(|| panic!("no row {label}:\n{table}"));
        // Both cells ran and are finite: "median [lo, hi]".
        assert_eq!(row.matches(" [").count(), 2, "{row}");
        assert!(
            !row.contains("not run") && !row.contains("diverged"),
            "{row}"
        );
    }
    // The feedforward tracks the twin far better than the PID (median RMSE, mm).
    let cells: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let median = |c: &str, p: &str| {
        cells
            .as_array()
            .unwrap()
            .iter()
            .find(|x| x["controller"] == c && x["plant"] == p)
            .unwrap()["rmse"]["median"]
            .as_f64()
            .unwrap()
    };
    assert!(
        median("FF-PI", "twin") < 0.5 * median("PID", "twin"),
        "{cells}"
    );
    // One model per (model kind, identification twin, trial), shared with the +pid kind.
    let models: Vec<Value> = std::fs::read_to_string(out.join("models.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(models.len(), 2 * 2 * 2);
    let kinds: Vec<&str> = models
        .iter()
        .map(|m| m["config"]["model"]["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds.iter().filter(|k| **k == "pi").count(), 4, "{kinds:?}");
    assert!(
        models
            .iter()
            .all(|m| m["free_run_rmse_mm"].as_f64().unwrap() < 0.05)
    );
    let runs: Vec<Value> = std::fs::read_to_string(out.join("runs.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let seed_of = |c: &str| {
        runs.iter()
            .find(|r| r["controller"] == c && r["plant"] == "twin" && r["trial"] == 0)
            .unwrap()["model_seed"]
            .clone()
    };
    assert_eq!(seed_of("FF-PI"), seed_of("ff-pi-pid"));
    assert_ne!(seed_of("FF-PI"), seed_of("FF-BW"));
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("## Identified models") && report.contains("Prandtl-Ishlinskii"));
}
