//! The `bbob` kind against COCO itself: `tests/reference/bbob_cocoex.json`, written by
//! `python3 scripts/bbob_reference.py` from cocoex (24 functions x dimensions 2-40 x
//! instances 1, 2, 7, 15, 101; points inside and outside [-5, 5]^d and the optimum).

mod common;

use optbench::objective::bbob::Bbob;
use optbench::objective::{Objective, SuiteId};
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
struct Entry {
    function: usize,
    dim: usize,
    instance: usize,
    id: String,
    xopt: Vec<f64>,
    f_xopt: f64,
    points: Vec<Vec<f64>>,
    values: Vec<f64>,
}

#[derive(Deserialize)]
struct Table {
    entries: Vec<Entry>,
}

fn table() -> Table {
    serde_json::from_str(include_str!("reference/bbob_cocoex.json")).unwrap()
}

/// Relative error, measured against |expected| but never against less than 1: the values
/// all carry COCO's offset f_opt (|f_opt| up to 1000), so a value near 0 is f_opt cancelling
/// a raw value of about the same size, and its rounding error is absolute, of the order of
/// the terms' ulp, not of the small difference.
fn rel_err(actual: f64, expected: f64) -> f64 {
    (actual - expected).abs() / expected.abs().max(1.0)
}

const TOL: f64 = 1e-12;

#[test]
fn every_reference_value_matches_cocoex() {
    let t = table();
    assert_eq!(
        t.entries.len(),
        24 * 6 * 5,
        "24 functions x 6 dims x 5 instances"
    );
    let mut worst: Vec<(f64, String)> = Vec::new();
    let mut failures = Vec::new();
    for e in &t.entries {
        let f = Bbob::new(e.function, e.dim, e.instance).unwrap();
        // COCO's id, with our name's fields: one reference entry per problem.
        assert_eq!(
            e.id,
            format!("bbob_f{:03}_i{:02}_d{:02}", e.function, e.instance, e.dim)
        );
        assert_eq!(
            f.name(),
            format!("bbob-f{:02}-i{:02}-d{:02}", e.function, e.instance, e.dim)
        );
        let mut pairs: Vec<(f64, f64, String)> = e
            .points
            .iter()
            .zip(&e.values)
            .enumerate()
            .map(|(i, (x, &v))| (f.evaluate(x), v, format!("point {i}")))
            .collect();
        pairs.push((f.evaluate(&e.xopt), e.f_xopt, "x_opt".into()));
        for (a, b, what) in pairs {
            let err = rel_err(a, b);
            worst.push((err, format!("{} {what}", e.id)));
            if err > TOL || !a.is_finite() {
                failures.push(format!(
                    "{} {what}: optbench {a:e}, cocoex {b:e} (rel {err:.1e})",
                    e.id
                ));
            }
        }
    }
    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
    eprintln!("largest errors: {:?}", &worst[..5]);
    assert!(
        failures.is_empty(),
        "{} of {} values differ:\n{}",
        failures.len(),
        worst.len(),
        failures.join("\n")
    );
}

#[test]
fn the_optimum_is_where_and_what_cocoex_says() {
    for e in &table().entries {
        let f = Bbob::new(e.function, e.dim, e.instance).unwrap();
        // cocoex prints x_opt with 16 significant digits.
        for (a, b) in f.x_opt().iter().zip(&e.xopt) {
            assert!(
                (a - b).abs() <= 1e-14 * b.abs().max(1.0),
                "{}: x_opt {a} vs {b}",
                e.id
            );
        }
        let fopt = f.optimum().unwrap();
        let at = f.evaluate(f.x_opt());
        // COCO's optimum lies exactly at x_opt except f20 (its x_opt is rounded to 10
        // digits) and Gallagher's (the peak's centre is rotated twice, in different orders).
        let slack = match e.function {
            20 => 1e-9,
            21 | 22 => 1e-12,
            _ => 0.0,
        };
        assert!(
            at >= fopt - 1e-12 && at - fopt <= slack + 1e-12 * fopt.abs(),
            "{}: f(x_opt) = {at}, f_opt = {fopt}",
            e.id
        );
        assert_eq!(
            f.suite_id(),
            Some(SuiteId {
                suite: "bbob",
                function: e.function,
                instance: e.instance
            })
        );
    }
}

#[test]
fn names_domains_and_odd_points() {
    let f = Bbob::new(3, 5, 2).unwrap();
    assert_eq!(f.name(), "bbob-f03-i02-d05");
    assert_eq!(f.bounds().lower(), &[-5.0; 5]);
    assert_eq!(f.bounds().upper(), &[5.0; 5]);
    assert_eq!(Bbob::new(24, 40, 101).unwrap().name(), "bbob-f24-i101-d40");
    // Non-finite or absurdly far points are worth +inf, never NaN.
    for func in 1..=24 {
        let f = Bbob::new(func, 3, 1).unwrap();
        for x in [
            [f64::NAN, 0.0, 0.0],
            [f64::INFINITY, 0.0, 0.0],
            [1e300, -1e300, 1e300],
        ] {
            let v = f.evaluate(&x);
            assert!(!v.is_nan(), "f{func} at {x:?}: {v}");
        }
    }
}

#[test]
fn bad_keys_are_refused_with_what_to_do() {
    for (bad, needle) in [
        ("function = 0", "`function`"),
        ("function = 25", "`function`"),
        ("function = 3\ninstance = 0", "`instance`"),
        ("function = 3\ndim = 1", "`dim`"),
        ("function = 3\ndim = 41", "`dim`"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let dim = if bad.contains("dim") { "" } else { "dim = 2\n" };
        let suite = format!(
            "name = \"b\"\nseed = 1\ntrials = 1\nbudget = 10\n\n[[objective]]\nkind = \"bbob\"\n{dim}{bad}\n\n[[optimizer]]\nkind = \"random\"\n"
        );
        std::fs::write(dir.path().join("s.toml"), &suite).unwrap();
        let out = common::optbench(&["run", "s.toml"], dir.path());
        common::refused(&out, &["s.toml", needle]);
    }
    assert!(Bbob::new(0, 2, 1).unwrap_err().contains("1 to 24"));
    assert!(Bbob::new(25, 2, 1).unwrap_err().contains("1 to 24"));
    assert!(Bbob::new(1, 1, 1).unwrap_err().contains("2..="));
    assert!(Bbob::new(1, 2, 0).unwrap_err().contains("from 1"));
}

#[test]
fn list_shows_the_bbob_kind() {
    let dir = tempfile::tempdir().unwrap();
    let text = common::ok(&common::optbench(&["list"], dir.path()));
    let bbob = text
        .split("\nobjective `")
        .find(|k| k.starts_with("bbob`"))
        .unwrap_or_else(|| panic!("no bbob kind in:\n{text}"));
    for key in ["| function ", "| dim ", "| instance "] {
        assert!(bbob.contains(key), "{key} not in {bbob}");
    }
}

/// The stored table against cocoex as installed now (skipped without cocoex).
#[test]
fn the_stored_table_is_what_cocoex_computes() {
    common::run_check_script("bbob_reference.py", &[Path::new("--check")]);
}

/// A suite of BBOB problems runs, names each objective by its problem and exports BBOB's
/// own function and instance numbers to IOH (checked with iohinspector where installed).
#[test]
fn a_bbob_suite_runs_and_exports_bbob_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let suite = "name = \"bb\"\nseed = 7\ntrials = 2\nbudget = 100\n\n\
        [[objective]]\nkind = \"bbob\"\nfunction = 3\ndim = 2\ninstance = 2\n\n\
        [[objective]]\nkind = \"bbob\"\nfunction = 21\ndim = 2\n\n\
        [[objective]]\nkind = \"sphere\"\ndim = 2\n\n\
        [[optimizer]]\nkind = \"random\"\n";
    std::fs::write(dir.path().join("s.toml"), suite).unwrap();
    common::ok(&common::optbench(&["run", "s.toml"], dir.path()));
    let out = dir.path().join("results/bb");
    let csv = std::fs::read_to_string(out.join("ioh/instances.csv")).unwrap();
    assert!(
        csv.contains("\n3,bbob,2,2,bbob-f03-i02-d02,f - f* (f* = 7.766e1)\n"),
        "{csv}"
    );
    assert!(csv.contains("\n21,bbob,2,1,bbob-f21-i01-d02,"), "{csv}");
    assert!(csv.contains("\n25,sphere,2,1,sphere-2d,"), "{csv}");
    let meta = common::read_json(&out.join("ioh/random/IOHprofiler_f3_bbob.json"));
    assert_eq!(meta["suite"], "BBOB");
    assert_eq!(meta["function_id"], 3);
    assert!(
        out.join("ioh/random/data_f21_bbob/IOHprofiler_f21_DIM2.dat")
            .exists()
    );
    common::run_check_script("ioh_check.py", &[&out]);
}
