//! The operator models (Prandtl-Ishlinskii, Preisach) against peers: their least-squares
//! optimum on a real recording equals an independent solver's.

mod common;

use optbench::data::recording::{Columns, ReadOptions, Recording, data_dir};
use optbench::physics::prandtl_ishlinskii::{PiForm, PiModel};
use std::path::Path;
use std::process::Command;

/// The P-885 identification run, or None (with a note) when the data folder is absent.
fn p885() -> Option<Recording> {
    let path = data_dir().join("pea_p885_dbo/dbo_identification_1Hz_sine.csv");
    if !path.exists() {
        eprintln!("skipping: {} not found (set OPTBENCH_DATA)", path.display());
        return None;
    }
    let cols = Columns::parse("t_s,u_V,y_um").unwrap();
    Some(Recording::read_csv(&path, &cols, &ReadOptions::default()).unwrap())
}

/// Weights and offset of a reference file written by scripts/pi_nnls_check.py.
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

fn assert_same(fit: &PiModel, (th, w, d0): &(Vec<f64>, Vec<f64>, f64), what: &str) {
    let scale = w.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (a, b) in fit.thresholds.iter().zip(th) {
        assert!((a - b).abs() < 1e-12, "{what}: threshold {a} vs {b}");
    }
    assert_eq!(fit.weights.len(), w.len(), "{what}");
    for (i, (a, b)) in fit.weights.iter().zip(w).enumerate() {
        assert!(
            (a - b).abs() < 1e-7 * scale,
            "{what}: weight {i}: optbench {a}, scipy {b}"
        );
        // The active set: a weight scipy holds at 0 is 0 here too.
        assert_eq!(*a == 0.0, *b == 0.0, "{what}: weight {i}: {a} vs {b}");
    }
    assert!(
        (fit.offset - d0).abs() < 1e-7 * d0.abs(),
        "{what}: offset {} vs {d0}",
        fit.offset
    );
}

#[test]
fn pi_weights_at_the_least_squares_optimum_match_scipy_nnls_on_the_p885_stack() {
    let Some(rec) = p885() else { return };
    let th = PiModel::uniform_thresholds(10, &rec.u);
    let fit = PiModel::fit(PiForm::Plain, th, &rec.u, &rec.y, rec.dt()).unwrap();
    // Recorded: scripts/pi_nnls_check.py --operators 10 on this file (scipy 1.17.1).
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let recorded = reference(&dir.join("tests/reference/pi_nnls_p885.json"));
    assert_same(&fit, &recorded, "recorded scipy reference");
    assert!(
        recorded.1.contains(&0.0),
        "the case should exercise the non-negativity bound"
    );
    // And live, where scipy is installed.
    let out = tempfile::tempdir().unwrap();
    let json = out.path().join("pi.json");
    let script = dir.join("scripts/pi_nnls_check.py");
    let csv = data_dir().join("pea_p885_dbo/dbo_identification_1Hz_sine.csv");
    let run = Command::new("python3")
        .arg(&script)
        .arg(&csv)
        .args(["--columns", "t_s,u_V,y_um", "--operators", "10", "--out"])
        .arg(&json)
        .output();
    match run {
        Ok(o) if o.status.success() => assert_same(&fit, &reference(&json), "live scipy"),
        Ok(o) if o.status.code() == Some(3) => {
            eprintln!(
                "skipping the live check: {}",
                String::from_utf8_lossy(&o.stderr)
            )
        }
        Ok(o) => panic!(
            "pi_nnls_check.py failed: {}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => eprintln!("skipping the live check: python3: {e}"),
    }
    // The model runs as fitted: its RMSE on the record equals scipy's residual norm.
    let sim = fit.simulate(&rec.u, rec.dt());
    let rmse = (sim
        .iter()
        .zip(&rec.y)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / rec.len() as f64)
        .sqrt();
    let v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("tests/reference/pi_nnls_p885.json")).unwrap(),
    )
    .unwrap();
    let theirs = v["rmse"].as_f64().unwrap();
    assert!(
        (rmse - theirs).abs() < 1e-9 * theirs,
        "P-885 plain PI RMSE {rmse} um, scipy's residual {theirs} um"
    );
}
