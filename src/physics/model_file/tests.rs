//! Model files: what reads back, what is refused (with the field), and that the
//! de-normalised Bouc-Wen runs as the normalised one it came from.

use super::*;
use crate::physics::fixtures;

fn bouc_wen_file() -> ModelFile {
    let t = fixtures::TRUTH;
    let params = vec![
        Param::new("d_e", t.d_e, "mm/V").searched(t.d_e, 0.0, 1.5),
        Param::new("alpha", t.alpha, "mm/V").searched(t.alpha, 0.0, 1.5),
        Param::new("beta", t.beta, "mm^(1-n)/V").searched(t.beta, 0.0, 1.5),
        Param::new("gamma", t.gamma, "mm^(1-n)/V").searched(t.gamma, 0.0, 1.5),
        Param::new("n", t.n, "").searched(t.n, 0.0, 1.5),
    ];
    ModelFile::new(
        "bouc-wen",
        "test",
        Units {
            time: "s".into(),
            input: "V".into(),
            output: "mm".into(),
        },
        1e-3,
        Normalisation {
            input_scale: 1.0,
            output_scale: 1.0,
        },
        Integration {
            scheme: "fast".into(),
            substeps: Some(2),
            hold: None,
        },
        "from rest",
        params,
    )
}

fn dir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Writes `json` to a file and reads it as a model: the error text.
fn refused(json: &serde_json::Value) -> String {
    let d = dir();
    let p = d.path().join("model.json");
    std::fs::write(&p, serde_json::to_vec(json).unwrap()).unwrap();
    let e = ModelFile::read(&p).unwrap_err().to_string();
    assert!(e.contains("model.json"), "names the file: {e}");
    e
}

#[test]
fn a_written_model_reads_back_identical_and_runs() {
    let d = dir();
    let p = d.path().join("model.json");
    let m = bouc_wen_file();
    m.write(&p).unwrap();
    let back = ModelFile::read(&p).unwrap();
    assert_eq!(back, m);
    let (u, _) = fixtures::record(400);
    let out = back
        .run(
            &p,
            &Input {
                u: &u,
                y: None,
                dt: 1e-3,
            },
            None,
        )
        .unwrap();
    let mut want = vec![0.0; u.len()];
    bouc_wen_fast::simulate(&fixtures::TRUTH, &u, 2, &mut want);
    assert_eq!(out, want);
}

#[test]
fn bad_files_are_refused_with_the_field() {
    let good = serde_json::to_value(bouc_wen_file()).unwrap();
    let with = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut v = good.clone();
        f(&mut v);
        refused(&v)
    };
    let e = with(&|v| v["kind"] = "hammerstein".into());
    assert!(
        e.contains("kind")
            && e.contains("hammerstein")
            && e.contains("bouc-wen, rbf, structure, pi, preisach"),
        "{e}"
    );
    let e = with(&|v| v["version"] = 2.into());
    assert!(
        e.contains("version") && e.contains("reads version 1"),
        "{e}"
    );
    let e = with(&|v| v["format"] = "something".into());
    assert!(e.contains("format"), "{e}");
    let e = with(&|v| {
        v["parameters"].as_array_mut().unwrap().remove(2);
    });
    assert!(e.contains("parameters.beta: missing"), "{e}");
    let e = with(&|v| v["parameters"][1]["value"] = "nan".into());
    assert!(
        e.contains("parameters.alpha") && e.contains("not a finite number"),
        "{e}"
    );
    let e = with(&|v| v["integration"]["scheme"] = "rk45".into());
    assert!(e.contains("integration.scheme"), "{e}");
    let e = with(&|v| v["sampling_interval_s"] = (-1.0).into());
    assert!(e.contains("sampling_interval_s"), "{e}");
    // Not JSON at all.
    let d = dir();
    let p = d.path().join("model.json");
    std::fs::write(&p, "d_e = 1").unwrap();
    let e = ModelFile::read(&p).unwrap_err().to_string();
    assert!(e.contains("JSON"), "{e}");
}

#[test]
fn parameters_at_a_bound_are_flagged() {
    assert_eq!(
        Search::new(0.0, 0.0, 1.5).at_bound.as_deref(),
        Some("lower")
    );
    // Within a hundredth of the range of a bound, not further.
    assert_eq!(
        Search::new(1.49, 0.0, 1.5).at_bound.as_deref(),
        Some("upper")
    );
    assert_eq!(
        Search::new(-0.99, -1.0, 1.0).at_bound.as_deref(),
        Some("lower")
    );
    assert_eq!(Search::new(0.75, 0.0, 1.5).at_bound, None);
    assert_eq!(Search::new(1.48, 0.0, 1.5).at_bound, None);
    assert_eq!(Search::new(-0.97, -1.0, 1.0).at_bound, None);
    let mut m = bouc_wen_file();
    m.parameters[2] = m.parameters[2].clone().searched(1.5, 0.0, 1.5);
    assert_eq!(m.at_bounds(), vec![("beta", "upper")]);
}

#[test]
fn a_record_not_in_the_file_is_refused() {
    let d = dir();
    let p = d.path().join("model.json");
    let m = bouc_wen_file();
    let (u, _) = fixtures::record(50);
    let e = m
        .run(
            &p,
            &Input {
                u: &u,
                y: None,
                dt: 1e-3,
            },
            Some("validate"),
        )
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no record `validate`") && e.contains("none"),
        "{e}"
    );
}
