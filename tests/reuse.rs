//! A fitted model you can reuse: `fit` and `diagnose` write `model.json` and the predicted
//! output beside the measured one; `simulate --model` runs the model again and reproduces
//! the validation RMSE they reported (to 1e-9 relative) on twin recordings and, where
//! `$OPTBENCH_DATA` has it, a real piezo stack; parameters left at a search bound are
//! flagged; bad model files are refused with file and field.

mod common;

use common::{fit_metric, optbench, read_json, refused};
use std::path::Path;

/// Runs optbench in `dir`, asserts success, returns stdout.
fn ok(args: &[&str], dir: &Path) -> String {
    let o = optbench(args, dir);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{args:?}\n{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

/// Column names of the twin files (units from the names).
const COLS: &str = "t_s,u_V,y_mm";

/// A twin recording of `signal` for `seconds` written to `dir/name.csv`.
fn twin_csv(dir: &Path, name: &str, signal: &str, seconds: &str) {
    ok(
        &[
            "simulate",
            "--signal",
            signal,
            "--duration",
            seconds,
            "--out",
            "twin",
            "--columns",
            COLS,
        ],
        dir,
    );
    std::fs::rename(dir.join("twin/twin.csv"), dir.join(format!("{name}.csv"))).unwrap();
}

/// RMS of the residual column of a predicted-output CSV from row `skip` on, and the
/// column names.
fn residual_rmse(path: &Path, skip: usize) -> (f64, Vec<String>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let names: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    let col = names
        .iter()
        .position(|n| n.starts_with("residual_"))
        .unwrap_or_else(|| panic!("no residual column in {names:?}"));
    let e: Vec<f64> = r
        .records()
        .map(|row| row.unwrap()[col].parse::<f64>().unwrap())
        .skip(skip)
        .collect();
    let ss: f64 = e.iter().map(|v| v * v).sum();
    ((ss / e.len() as f64).sqrt(), names)
}

/// `simulate --model` of `model` on `input` read with `columns` (with `extra` flags) into
/// `dir/sim`: the RMSE of its residual from sample `skip` on, and the column names.
fn simulate_model(
    dir: &Path,
    model: &str,
    (input, columns): (&str, &str),
    extra: &[&str],
    skip: usize,
) -> (f64, Vec<String>) {
    let mut a = vec![
        "simulate",
        "--model",
        model,
        "--input",
        input,
        "--out",
        "sim",
        "--columns",
        columns,
    ];
    a.extend_from_slice(extra);
    let text = ok(&a, dir);
    assert!(text.contains("RMSE against the measured"), "{text}");
    let stem = Path::new(input).file_stem().unwrap().to_string_lossy();
    residual_rmse(&dir.join("sim").join(format!("{stem}_predicted.csv")), skip)
}

fn assert_close(got: f64, want: f64, what: &str) {
    let rel = (got - want).abs() / want;
    eprintln!("{what}: {got:e} vs {want:e} ({rel:.1e} relative)");
    assert!(rel <= 1e-9, "{what}: {got} vs {want} ({rel:e} relative)");
}

/// Bouc-Wen and RBF fits to twin recordings: the saved model reproduces the validation
/// RMSE of fit.json through `simulate --model` on the validation file, the fit's own
/// predicted CSV agrees, and a signal spec runs too.
#[test]
fn a_fitted_model_reproduces_its_validation_rmse_on_twin_recordings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    twin_csv(d, "train", "sine:freq=2,amp=2.3,offset=2.35", "1");
    twin_csv(d, "validate", "sine:freq=10,amp=2.3,offset=2.35", "0.5");
    for (model, metric, budget) in [
        ("bouc-wen", "validate RMSE [mm]", "1500"),
        ("rbf", "validate free-run RMSE [mm]", "2000"),
    ] {
        let out = format!("fit-{model}");
        let text = ok(
            &[
                "fit",
                "--model",
                model,
                "--recording",
                "train.csv",
                "--validate",
                "validate.csv",
                "--budget",
                budget,
                "--columns",
                COLS,
                "--out",
                &out,
                "-q",
            ],
            d,
        );
        assert!(text.contains("model.json"), "{text}");
        let want = fit_metric(&d.join(&out), metric);
        let model_file = read_json(&d.join(&out).join("model.json"));
        assert_eq!(model_file["kind"], model);
        assert_eq!(model_file["version"], 1);
        assert_eq!(model_file["units"]["output"], "mm");
        // An RBF's first samples are its initial conditions (measured), left out as the
        // fit leaves them out.
        let skip = if model == "rbf" { 1 } else { 0 };
        let (got, names) = simulate_model(
            d,
            &format!("{out}/model.json"),
            ("validate.csv", COLS),
            &[],
            skip,
        );
        assert_eq!(
            names,
            ["t_s", "u_V", "y_mm", "predicted_y_mm", "residual_y_mm"]
        );
        assert_close(got, want, &format!("{model} validation RMSE via simulate"));
        let (own, _) = residual_rmse(&d.join(&out).join("validate_predicted.csv"), skip);
        assert_close(own, want, &format!("{model} validate_predicted.csv"));
        // A signal spec: input and prediction only, at the model's interval, under the
        // column names the model was fitted on.
        ok(
            &[
                "simulate",
                "--model",
                &format!("{out}/model.json"),
                "--input",
                "sine:freq=5,amp=2,offset=2.3",
                "--duration",
                "0.2",
                "--out",
                "spec",
            ],
            d,
        );
        let mut r = csv::Reader::from_path(d.join("spec/signal_predicted.csv")).unwrap();
        assert_eq!(r.headers().unwrap(), vec!["t_s", "u_V", "predicted_y_mm"]);
        assert_eq!(r.records().count(), 200);
    }
}

/// Several training records (each its own offset and initial state) and a validation
/// record whose own are refitted: `--record validate` starts from them and reproduces the
/// fit's validation RMSE; from rest it is worse.
#[test]
fn a_record_of_the_fit_is_run_from_its_own_state() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    twin_csv(d, "a", "sine:freq=2,amp=2.3,offset=2.35", "0.6");
    twin_csv(d, "b", "sine:freq=5,amp=1.5,offset=2.35", "0.4");
    twin_csv(d, "c", "sine:freq=8,amp=2,offset=2.5", "0.4");
    ok(
        &[
            "fit",
            "--model",
            "bouc-wen",
            "--recording",
            "a.csv",
            "--recording",
            "b.csv",
            "--validate",
            "c.csv",
            "--param",
            "d0=true",
            "--budget",
            "1500",
            "--columns",
            COLS,
            "--out",
            "fit",
        ],
        d,
    );
    let want = fit_metric(&d.join("fit"), "validate RMSE [mm]");
    let m = read_json(&d.join("fit/model.json"));
    let labels: Vec<&str> = m["records"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["label"].as_str().unwrap())
        .collect();
    assert_eq!(labels, ["train1", "train2", "validate"]);
    let (got, _) = simulate_model(
        d,
        "fit/model.json",
        ("c.csv", COLS),
        &["--record", "validate"],
        0,
    );
    assert_close(got, want, "refitted validation record via --record");
    let (from_rest, _) = simulate_model(d, "fit/model.json", ("c.csv", COLS), &[], 0);
    assert!(from_rest > got, "{from_rest} vs {got}");
}

/// A real piezo stack (PI P-885.91, `$OPTBENCH_DATA/pea_p885_dbo`, micrometres at 200 Hz):
/// Bouc-Wen (with offset) and RBF fits reproduce their validation RMSE on the test file
/// through `simulate --model`, under the file's own column names.
#[test]
fn a_model_fitted_to_a_real_recording_reproduces_its_validation_rmse() {
    let Some(data) = common::data_set("pea_p885_dbo") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let train = data.join("dbo_identification_1Hz_sine.csv");
    let test = data.join("dbo_test_ramped_sine_with_holds.csv");
    let (train, test) = (train.to_str().unwrap(), test.to_str().unwrap());
    let cols = "t_s,u_V,y_um";
    for (model, extra, metric, skip) in [
        ("bouc-wen", "d0=true", "validate RMSE [um]", 0),
        ("rbf", "hidden=7", "validate free-run RMSE [um]", 1),
    ] {
        let out = format!("fit-{model}");
        ok(
            &[
                "fit",
                "--model",
                model,
                "--recording",
                train,
                "--validate",
                test,
                "--columns",
                cols,
                "--param",
                extra,
                "--budget",
                "1200",
                "--out",
                &out,
            ],
            d,
        );
        let want = fit_metric(&d.join(&out), metric);
        let m = read_json(&d.join(&out).join("model.json"));
        assert_eq!(m["units"]["output"], "um");
        if model == "bouc-wen" {
            // The stack sits near -96 um; the default range [0, 1.5] of the normalised
            // offset cannot reach it, and the flag says so.
            let d0 = m["parameters"]
                .as_array()
                .unwrap()
                .iter()
                .find(|p| p["name"] == "d0")
                .unwrap();
            assert_eq!(d0["search"]["at_bound"], "lower", "{d0}");
            let d_e = &m["parameters"][0];
            assert_eq!(
                (d_e["name"].as_str(), d_e["unit"].as_str()),
                (Some("d_e"), Some("um/V"))
            );
        }
        let (got, names) = simulate_model(d, &format!("{out}/model.json"), (test, cols), &[], skip);
        assert_eq!(
            names,
            ["t_s", "u_V", "y_um", "predicted_y_um", "residual_y_um"]
        );
        assert_close(
            got,
            want,
            &format!("P-885 {model} validation RMSE via simulate"),
        );
    }
}

/// Bounds made tight with --param: the parameters that end at one are flagged in
/// model.json and in fit's summary.
#[test]
fn parameters_at_a_search_bound_are_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    twin_csv(d, "train", "sine:freq=2,amp=2.3,offset=2.35", "0.5");
    let text = ok(
        &[
            "fit",
            "--model",
            "bouc-wen",
            "--recording",
            "train.csv",
            "--param",
            "lower=1",
            "--optimizer",
            "cmaes",
            "--budget",
            "1500",
            "--columns",
            COLS,
            "--out",
            "fit",
        ],
        d,
    );
    let m = read_json(&d.join("fit/model.json"));
    let flagged: Vec<(String, String)> = m["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| {
            let b = p["search"]["at_bound"].as_str()?;
            Some((p["name"].as_str().unwrap().to_string(), b.to_string()))
        })
        .collect();
    // Every parameter searched in [1, 1.5]: the hysteretic slope alpha (0.4 on data
    // normalised to 1) ends at the lower bound, the loop shape beta at the upper.
    for want in [("alpha", "lower"), ("beta", "upper")] {
        assert!(
            flagged.contains(&(want.0.to_string(), want.1.to_string())),
            "{want:?} not in {flagged:?}\n{text}"
        );
    }
    for (name, side) in &flagged {
        let line = format!("{name} at its {side} bound: widen the range or check the model");
        assert!(text.contains(&line), "{line}\n{text}");
    }
    assert!(!flagged.iter().any(|f| f.0 == "d_e"), "{flagged:?}");
}

/// Diagnose's final model runs again: `--record validate` reproduces the final model's
/// validation RMSE, and from its training state the training RMSE.
#[test]
fn a_diagnosed_model_reproduces_its_validation_rmse() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    twin_csv(d, "train", "sine:freq=2,amp=2.3,offset=2.35", "1.5");
    twin_csv(d, "validate", "sine:freq=7,amp=2,offset=2.35", "1");
    ok(
        &[
            "diagnose",
            "--train",
            "train.csv",
            "--validate",
            "validate.csv",
            "--model",
            "bouc-wen-n1",
            "--effects",
            "delay,creep",
            "--bootstrap",
            "3",
            "--columns",
            COLS,
            "--out",
            "diag",
            "-q",
        ],
        d,
    );
    let j = read_json(&d.join("diag/diagnosis.json"));
    let m = read_json(&d.join("diag/model.json"));
    assert_eq!(m["kind"], "structure");
    assert_eq!(m["records"][0]["label"], "validate");
    let (got, _) = simulate_model(
        d,
        "diag/model.json",
        ("validate.csv", COLS),
        &["--record", "validate"],
        0,
    );
    // model.json holds the validation record's own parts fitted on all of it: simulate
    // reproduces that reading of the record, not the prediction that judged.
    let fitted = j["final"]["validate_fitted_rmse"].as_f64().unwrap();
    assert_close(got, fitted, "diagnosed validation RMSE via simulate");
    let want = j["final"]["validate_rmse"].as_f64().unwrap();
    let (train, _) = simulate_model(d, "diag/model.json", ("train.csv", COLS), &[], 0);
    assert_close(
        train,
        j["final"]["train_rmse"].as_f64().unwrap(),
        "diagnosed training RMSE via simulate",
    );
    // The predicted CSV holds the forecast that judged: from the lead's end on, its
    // residual is the validation RMSE.
    let v = &j["validation_judging"][0];
    let lead = v["samples"].as_u64().unwrap() - v["scored"].as_u64().unwrap();
    let (own, _) = residual_rmse(&d.join("diag/validate_predicted.csv"), lead as usize);
    assert_close(own, want, "diagnose's validate_predicted.csv");
}

/// A change to a model file.
type Edit = Box<dyn Fn(&mut serde_json::Value)>;

/// Bad model files: exit 2 with the file and the field.
#[test]
fn bad_model_files_are_refused_with_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    twin_csv(d, "train", "sine:freq=2,amp=2.3,offset=2.35", "0.3");
    ok(
        &[
            "fit",
            "--model",
            "bouc-wen",
            "--recording",
            "train.csv",
            "--budget",
            "200",
            "--out",
            "fit",
            "--columns",
            COLS,
        ],
        d,
    );
    let good = read_json(&d.join("fit/model.json"));
    let cases: Vec<(&str, Edit, Vec<&str>)> = vec![
        (
            "kind",
            Box::new(|v| v["kind"] = "hammerstein".into()),
            vec![
                "kind",
                "hammerstein",
                "valid: bouc-wen, rbf, structure, pi, preisach",
            ],
        ),
        (
            "version",
            Box::new(|v| v["version"] = 7.into()),
            vec!["version", "7", "reads version 1"],
        ),
        (
            "missing",
            Box::new(|v| {
                v["parameters"].as_array_mut().unwrap().remove(3);
            }),
            vec!["parameters.gamma: missing"],
        ),
        (
            "nonfinite",
            Box::new(|v| v["parameters"][0]["value"] = "inf".into()),
            vec!["parameters.d_e", "not a finite number"],
        ),
    ];
    // A file that is not there: the user's input, exit 2 with what was expected.
    let out = optbench(
        &[
            "simulate",
            "--model",
            "nope.json",
            "--input",
            "train.csv",
            "--out",
            "sim",
        ],
        d,
    );
    refused(&out, &["--model nope.json", "cannot read", "model.json"]);
    for (name, edit, needles) in cases {
        let mut v = good.clone();
        edit(&mut v);
        let file = format!("{name}.json");
        std::fs::write(d.join(&file), serde_json::to_vec(&v).unwrap()).unwrap();
        let out = optbench(
            &[
                "simulate",
                "--model",
                &file,
                "--input",
                "train.csv",
                "--out",
                "sim",
                "--columns",
                COLS,
            ],
            d,
        );
        let mut all = vec![file.as_str()];
        all.extend(needles);
        refused(&out, &all);
    }
    // The good one runs; a record it does not have is named with the ones it has.
    let out = optbench(
        &[
            "simulate",
            "--model",
            "fit/model.json",
            "--input",
            "train.csv",
            "--record",
            "validate",
            "--out",
            "sim",
            "--columns",
            COLS,
        ],
        d,
    );
    refused(&out, &["model.json", "no record `validate`", "train"]);
}
