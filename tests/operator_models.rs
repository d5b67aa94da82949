//! The operator models (Prandtl-Ishlinskii, Preisach) against peers: their least-squares
//! optimum on a real recording equals an independent solver's.

mod common;

use optbench::base::lstsq::least_squares;
use optbench::data::recording::{Columns, ReadOptions, Recording, data_dir};
use optbench::data::signal::seed_experiments;
use optbench::physics::prandtl_ishlinskii::{PiForm, PiModel};
use optbench::physics::preisach::Preisach;
use optbench::physics::twin::{self, TwinConfig};
use std::path::Path;
use std::process::Command;

const IDENTIFICATION: &str = "pea_p885_dbo/dbo_identification_1Hz_sine.csv";
const RAMPED: &str = "pea_p885_dbo/dbo_test_ramped_sine_with_holds.csv";

/// A P-885 recording of the data folder, or None (with a note) when it is absent.
fn p885(file: &str) -> Option<Recording> {
    let path = data_dir().join(file);
    if !path.exists() {
        eprintln!("skipping: {} not found (set OPTBENCH_DATA)", path.display());
        return None;
    }
    let cols = Columns::parse("t_s,u_V,y_um").unwrap();
    Some(Recording::read_csv(&path, &cols, &ReadOptions::default()).unwrap())
}

/// Thresholds, weights and offset of a reference file written by
/// scripts/pi_nnls_check.py or scripts/preisach_nnls_check.py.
fn reference(path: &Path) -> (Vec<f64>, Vec<f64>, f64) {
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let nums = |k: &str| -> Vec<f64> {
        v[k].as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    (
        nums("thresholds"),
        nums("weights"),
        v["offset"].as_f64().unwrap(),
    )
}

/// A fit's thresholds, weights and offset equal a reference's (weights to 1e-7 of the
/// largest, with the same ones held at 0).
fn assert_same(fit: (&[f64], &[f64], f64), (th, w, d0): &(Vec<f64>, Vec<f64>, f64), what: &str) {
    let scale = w.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (a, b) in fit.0.iter().zip(th) {
        assert!((a - b).abs() < 1e-12, "{what}: threshold {a} vs {b}");
    }
    assert_eq!(fit.1.len(), w.len(), "{what}");
    for (i, (a, b)) in fit.1.iter().zip(w).enumerate() {
        assert!(
            (a - b).abs() < 1e-7 * scale,
            "{what}: weight {i}: optbench {a}, scipy {b}"
        );
        // The active set: a weight scipy holds at 0 is 0 here too.
        assert_eq!(*a == 0.0, *b == 0.0, "{what}: weight {i}: {a} vs {b}");
    }
    assert!(
        (fit.2 - d0).abs() < 1e-7 * d0.abs(),
        "{what}: offset {} vs {d0}",
        fit.2
    );
}

/// Runs a check script of scripts/ on a data-folder recording (`args` after the CSV, then
/// `--out JSON`) and returns its reference; None, with a note, where python3, numpy or
/// scipy is missing (the script exits 3).
fn live_reference(script: &str, csv: &str, args: &[&str]) -> Option<(Vec<f64>, Vec<f64>, f64)> {
    let out = tempfile::tempdir().unwrap();
    let json = out.path().join("reference.json");
    let run = Command::new("python3")
        .arg(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("scripts")
                .join(script),
        )
        .arg(data_dir().join(csv))
        .args(args)
        .arg("--out")
        .arg(&json)
        .output();
    match run {
        Ok(o) if o.status.success() => Some(reference(&json)),
        Ok(o) if o.status.code() == Some(3) => {
            eprintln!(
                "skipping the live check: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            None
        }
        Ok(o) => panic!("{script} failed: {}", String::from_utf8_lossy(&o.stderr)),
        Err(e) => {
            eprintln!("skipping the live check: python3: {e}");
            None
        }
    }
}

fn rmse(a: &[f64], b: &[f64]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
}

/// The `rmse` field of a reference file in tests/reference.
fn reference_rmse(name: &str) -> f64 {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/reference")
        .join(name);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["rmse"].as_f64().unwrap()
}

#[test]
fn pi_weights_at_the_least_squares_optimum_match_scipy_nnls_on_the_p885_stack() {
    let Some(rec) = p885(IDENTIFICATION) else {
        return;
    };
    let th = PiModel::uniform_thresholds(10, &rec.u);
    let fit = PiModel::fit(PiForm::Plain, th, &rec.u, &rec.y, rec.dt()).unwrap();
    let ours = (&fit.thresholds[..], &fit.weights[..], fit.offset);
    // Recorded: scripts/pi_nnls_check.py --operators 10 on this file (scipy 1.17.1).
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let recorded = reference(&dir.join("tests/reference/pi_nnls_p885.json"));
    assert_same(ours, &recorded, "recorded scipy reference");
    assert!(
        recorded.1.contains(&0.0),
        "the case should exercise the non-negativity bound"
    );
    // And live, where scipy is installed.
    let args = ["--columns", "t_s,u_V,y_um", "--operators", "10"];
    if let Some(live) = live_reference("pi_nnls_check.py", IDENTIFICATION, &args) {
        assert_same(ours, &live, "live scipy");
    }
    // The model runs as fitted: its RMSE on the record equals scipy's residual norm.
    let rmse = rmse(&fit.simulate(&rec.u, rec.dt()), &rec.y);
    let theirs = reference_rmse("pi_nnls_p885.json");
    assert!(
        (rmse - theirs).abs() < 1e-9 * theirs,
        "P-885 plain PI RMSE {rmse} um, scipy's residual {theirs} um"
    );
}

/// The ramped sine with holds visits every relay state the 8-level grid can tell apart
/// (the script's rank is full, 37), so the optimal weights are unique and comparable one
/// by one; one of them sits on its bound.
#[test]
fn preisach_weights_at_the_least_squares_optimum_match_scipy_nnls_on_the_p885_stack() {
    let Some(rec) = p885(RAMPED) else { return };
    let fit = Preisach::fit(8, &rec.u, &rec.y, rec.dt()).unwrap();
    let ours = (fit.grid.thresholds(), &fit.weights[..], fit.offset);
    // Recorded: scripts/preisach_nnls_check.py --levels 8 on this file (scipy 1.17.1).
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let recorded = reference(&dir.join("tests/reference/preisach_nnls_p885.json"));
    assert_same(ours, &recorded, "recorded scipy reference");
    assert!(
        recorded.1.contains(&0.0),
        "the case should exercise the non-negativity bound"
    );
    let args = ["--columns", "t_s,u_V,y_um", "--levels", "8"];
    if let Some(live) = live_reference("preisach_nnls_check.py", RAMPED, &args) {
        assert_same(ours, &live, "live scipy");
    }
    let rmse = rmse(&fit.simulate(&rec.u, rec.dt()), &rec.y);
    let theirs = reference_rmse("preisach_nnls_p885.json");
    eprintln!("P-885 ramped sine, Preisach with 8 levels: RMSE {rmse:.4} um");
    assert!(
        (rmse - theirs).abs() < 1e-9 * theirs,
        "P-885 Preisach RMSE {rmse} um, scipy's residual {theirs} um"
    );
}

/// The Preisach fit on the twin (the dissertation's 10 → 1 Hz validation chirp, whose
/// falling and rising amplitude makes nested minor loops), and the fitted model on the
/// 1 Hz sine it was not fitted on: RMSEs reported. The model's output is a staircase (it
/// moves only when the input crosses a threshold), so its error falls with the levels: at
/// 10 it is no better than the best straight line; at 30 it is well below it on both
/// records.
#[test]
fn preisach_fit_on_the_twin() {
    let cfg = TwinConfig::default();
    let dt = 1e-3;
    let record = |name: &str| {
        let (_, sig, dur) = seed_experiments()
            .into_iter()
            .find(|(n, _, _)| n == name)
            .unwrap();
        twin::recording(&cfg, name, sig.sample(dt, dur), dt, 7).unwrap()
    };
    let (train, test) = (record("validation-chirp-10-1hz"), record("sine-1hz"));
    let um = |r: &Recording, y: &[f64]| 1e3 * rmse(y, &r.y);
    // The best straight line y = a + b u on the training record.
    let ab = least_squares(&[vec![1.0; train.len()], train.u.clone()], &train.y);
    let line = |r: &Recording| -> f64 {
        let y: Vec<f64> = r.u.iter().map(|x| ab[0] + ab[1] * x).collect();
        um(r, &y)
    };
    let (ltr, lte) = (line(&train), line(&test));
    let errors: Vec<(f64, f64)> = [10, 30]
        .into_iter()
        .map(|levels| {
            let fit = Preisach::fit(levels, &train.u, &train.y, dt).unwrap();
            let tr = um(&train, &fit.simulate(&train.u, dt));
            let te = um(&test, &fit.simulate(&test.u, dt));
            eprintln!(
                "twin, Preisach {levels} levels: RMSE {tr:.2} um on the chirp (fitted), \
                 {te:.2} um on the 1 Hz sine; straight line {ltr:.2} and {lte:.2} um"
            );
            (tr, te)
        })
        .collect();
    let (coarse, fine) = (errors[0], errors[1]);
    assert!(fine.0 < 0.5 * coarse.0, "{errors:?}");
    assert!(
        fine.0 < 0.6 * ltr && fine.1 < 0.7 * lte,
        "{errors:?} vs {ltr}, {lte}"
    );
}
