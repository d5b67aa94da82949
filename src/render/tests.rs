//! Tests across figure kinds: degenerate and long inputs, and the demo figures.

use super::measured::MEASURED;
use super::test_util::*;
use super::*;
use crate::base::error::Error;
use std::path::PathBuf;

#[test]
fn degenerate_inputs_still_give_figures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let inf = ConvergenceSeries {
        label: "never finite".into(),
        evals: vec![0, 1, 10],
        median: vec![f64::INFINITY; 3],
        q1: vec![f64::INFINITY; 3],
        q3: vec![f64::NAN; 3],
    };
    let zeros = ConvergenceSeries {
        label: "all zero".into(),
        evals: vec![5, 5],
        median: vec![0.0; 2],
        q1: vec![-1.0; 2],
        q3: vec![0.0; 2],
    };
    convergence(&d.join("c0"), "no series", &[], "error", true).unwrap();
    convergence(
        &d.join("c1"),
        "odd series",
        &[inf, zeros.clone()],
        "error",
        true,
    )
    .unwrap();
    convergence(
        &d.join("c2"),
        "odd series, linear",
        &[zeros],
        "error",
        false,
    )
    .unwrap();
    boxplot(&d.join("b0"), "no groups", &[], "error", true).unwrap();
    let groups = vec![
        ("empty".to_string(), vec![]),
        ("inf".to_string(), vec![f64::INFINITY, f64::NAN]),
        ("one".to_string(), vec![0.0]),
    ];
    boxplot(&d.join("b1"), "odd groups", &groups, "error", true).unwrap();
    let f = files(d, "b1");
    assert_eq!(texts(&f.svg, "(no finite value)"), 1);
    ecdf(&d.join("e0"), "no series", &[], "evaluations", (1.0, 1.0)).unwrap();
    let series = vec![
        ("none".to_string(), vec![]),
        ("zero".to_string(), vec![0.0, 1.0]),
    ];
    ecdf(
        &d.join("e1"),
        "odd series",
        &series,
        "evaluations",
        (1.0, 100.0),
    )
    .unwrap();
    let f = files(d, "e1");
    assert_eq!(texts(&f.svg, "x values ≤ 0 drawn at 0.1"), 1);
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 14);
}

#[test]
fn long_records_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut r = piezo(150_000, 0.05);
    r.measured[777] = f64::NAN;
    timeseries_with_error(
        &d.join("ts"),
        "150 000 samples",
        &r.t,
        (MEASURED, &r.measured),
        &r.models,
        "time [s]",
        "y [µm]",
    )
    .unwrap();
    loops(
        &d.join("loops"),
        "150 000 samples",
        &r.u,
        (MEASURED, &r.measured),
        &r.models,
        "u [V]",
        "y [µm]",
    )
    .unwrap();
    let f = files(d, "ts");
    check_common(&f, "150 000 samples", &[MEASURED, "Bouc-Wen"]);
    assert_eq!(texts(&f.svg, "1 non-finite sample not drawn"), 1);
    for i in 0..=r.models.len() {
        // At most two points per pixel column.
        let lines = polylines(&f.svg, color(i));
        assert!(lines.iter().all(|l| l.len() <= 2 * WIDTH as usize));
    }
    let f = files(d, "loops");
    check_common(&f, "150 000 samples", &[MEASURED, "Bouc-Wen"]);
    assert_eq!(
        texts(
            &f.svg,
            "1 in 30 samples drawn; 1 non-finite sample not drawn"
        ),
        1
    );
}

#[test]
fn odd_records_still_give_figures_or_input_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nan = vec![("all NaN".to_string(), vec![f64::NAN; 3])];
    timeseries_with_error(&d.join("t0"), "empty", &[], (MEASURED, &[]), &[], "t", "y").unwrap();
    loops(&d.join("l0"), "empty", &[], (MEASURED, &[]), &[], "u", "y").unwrap();
    let (t, y) = ([0.0, 1.0, 2.0], [1.0, 1.0, 1.0]);
    timeseries_with_error(&d.join("t1"), "flat", &t, (MEASURED, &y), &nan, "t", "y").unwrap();
    loops(&d.join("l1"), "flat", &t, (MEASURED, &y), &nan, "u", "y").unwrap();
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 8);
    let short = vec![("short".to_string(), vec![1.0])];
    assert!(matches!(
        timeseries_with_error(&d.join("x"), "x", &t, (MEASURED, &y), &short, "t", "y"),
        Err(Error::Input(_))
    ));
    assert!(matches!(
        loops(&d.join("x"), "x", &t, (MEASURED, &y[..2]), &[], "u", "y"),
        Err(Error::Input(_))
    ));
}

/// Writes the demo figures to `$OPTBENCH_PLOT_DIR` to look at:
/// `OPTBENCH_PLOT_DIR=/tmp/figs cargo test --release --lib demo_figures -- --ignored`.
#[test]
#[ignore]
fn demo_figures() {
    let dir = PathBuf::from(std::env::var("OPTBENCH_PLOT_DIR").expect("OPTBENCH_PLOT_DIR"));
    std::fs::create_dir_all(&dir).unwrap();
    let mut series = demo_series();
    convergence(
        &dir.join("convergence"),
        "Sphere d=10: convergence",
        &series,
        "best-so-far error to optimum",
        true,
    )
    .unwrap();
    for (i, name) in ["MSGA", "PSO (ring)", "GA (tournament)", "CMA-ES", "DE"]
        .iter()
        .enumerate()
    {
        let mut c = series[i % 3].clone();
        c.label = name.to_string();
        for m in c.median.iter_mut().chain(&mut c.q1).chain(&mut c.q3) {
            *m *= 1.5f64.powi(i as i32 + 1);
        }
        series.push(c);
    }
    convergence(
        &dir.join("convergence8"),
        "Eight optimizers, linear y",
        &series,
        "best-so-far value",
        false,
    )
    .unwrap();
    let groups: Vec<(String, Vec<f64>)> = ["GA", "PSO", "MSGA", "random search"]
        .iter()
        .enumerate()
        .map(|(i, n)| {
            let v = (0..30)
                .map(|k| 10f64.powf(-(i as f64) - 0.05 * k as f64 + if k == 7 { 2.0 } else { 0.0 }))
                .collect();
            (n.to_string(), v)
        })
        .collect();
    boxplot(
        &dir.join("box"),
        "Final error, Rastrigin d=5 (30 trials)",
        &groups,
        "final error to optimum",
        true,
    )
    .unwrap();
    let long: Vec<(String, Vec<f64>)> = (0..8)
        .map(|i| {
            (
                format!("optimizer_variant_{i}"),
                vec![1.0 + i as f64, 2.0, 3.0, 2.5 + i as f64 * 0.3],
            )
        })
        .collect();
    boxplot(
        &dir.join("box_long"),
        "Long names, linear y",
        &long,
        "final value",
        false,
    )
    .unwrap();
    let ecdf_series = vec![
        (
            "GA".to_string(),
            (0..60)
                .map(|k| {
                    if k % 4 == 0 {
                        f64::INFINITY
                    } else {
                        10f64.powf(1.0 + k as f64 * 0.06)
                    }
                })
                .collect(),
        ),
        (
            "PSO".to_string(),
            (0..60).map(|k| 10f64.powf(0.5 + k as f64 * 0.05)).collect(),
        ),
        (
            "random search".to_string(),
            (0..60)
                .map(|k| {
                    if k % 3 == 0 {
                        10f64.powf(2.0 + k as f64 * 0.04)
                    } else {
                        f64::INFINITY
                    }
                })
                .collect(),
        ),
    ];
    ecdf(
        &dir.join("ecdf"),
        "Runtime ECDF, 20 targets in [10⁻⁸, 10²]",
        &ecdf_series,
        "function evaluations",
        (1.0, 40_000.0),
    )
    .unwrap();
    let r = piezo(40_000, 0.02);
    timeseries_with_error(
        &dir.join("timeseries"),
        "Piezo actuator, 1 Hz sine: output and model error",
        &r.t,
        (MEASURED, &r.measured),
        &r.models,
        "time [s]",
        "displacement y [µm]",
    )
    .unwrap();
    loops(
        &dir.join("loops"),
        "Piezo actuator, 1 Hz sine: hysteresis loops",
        &r.u,
        (MEASURED, &r.measured),
        &r.models,
        "input voltage u [V]",
        "displacement y [µm]",
    )
    .unwrap();
    // Long record with spikes and gaps: the envelope keeps the spikes.
    let mut r = piezo(150_000, 0.05);
    r.measured[40_000] += 3.0;
    r.measured[100_000] -= 4.0;
    for k in (1000..1100).step_by(7) {
        r.measured[k] = f64::NAN;
    }
    timeseries_with_error(
        &dir.join("timeseries_long"),
        "150 000 samples, two spikes, a gap",
        &r.t,
        (MEASURED, &r.measured),
        &r.models[..1],
        "time [s]",
        "displacement y [µm]",
    )
    .unwrap();
    // Many models with long names, one exact; no unit; a short record.
    let r = piezo(300, 0.0);
    let mut many = r.models.clone();
    many.push(("exact copy of the measurement".into(), r.measured.clone()));
    for k in 1..=3 {
        let v = r
            .measured
            .iter()
            .map(|m| m * (1.0 + 0.01 * k as f64))
            .collect();
        many.push((format!("rate-dependent PI, {} operators", 5 * k), v));
    }
    timeseries_with_error(
        &dir.join("timeseries_many"),
        "Six models, 300 samples, a y label without a unit",
        &r.t,
        (MEASURED, &r.measured),
        &many,
        "t",
        "normalised output",
    )
    .unwrap();
    loops(
        &dir.join("loops_many"),
        "Six models",
        &r.u,
        (MEASURED, &r.measured),
        &many,
        "u",
        "normalised output",
    )
    .unwrap();
    loops(
        &dir.join("loops_long"),
        "150 000 samples",
        &r.u,
        (MEASURED, &r.measured),
        &r.models,
        "input voltage u [V]",
        "displacement y [µm]",
    )
    .unwrap();
}
