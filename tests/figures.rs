//! The figures of a results folder plot what the tables report: on a fitting suite the
//! RMSE in the recording's units (not the cost J), on a test function the error to the
//! optimum; every axis says which, and the PNGs are 300 dpi.

mod common;

use common::{optbench, read_json};
use optbench::report::{StoredRun, plot_data};
use std::path::Path;

const SUITE: &str = r#"
name = "tiny-figures"
description = "a Bouc-Wen fit and a test function, a few trials each"
seed = 11
trials = 3
budget = 300

[[objective]]
kind = "bouc-wen"
id = "bw"
recording = "twin:sine:freq=10,amp=2.3,offset=2.35"
duration = 0.1
normalize = false

[[objective]]
kind = "griewank"
id = "griewank-2d"
dim = 2

[[optimizer]]
kind = "de"
id = "DE"
population = 20

[[optimizer]]
kind = "pso"
id = "PSO"
population = 20
"#;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

/// Texts of the SVG `<text>` elements.
fn svg_texts(path: &Path) -> Vec<String> {
    let svg = std::fs::read_to_string(path).unwrap();
    svg.split("<text")
        .skip(1)
        .filter_map(|t| t.split_once('>').and_then(|(_, r)| r.split_once("</text>")))
        .map(|(inner, _)| inner.trim().to_string())
        .collect()
}

#[test]
fn plotted_values_are_the_tables_values_and_axes_say_what_they_are() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("suite.toml"), SUITE).unwrap();
    let out = optbench(&["run", "suite.toml", "--out", "r", "-q"], dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r = dir.path().join("r");
    let run = StoredRun::load(&r).unwrap();
    let plots = plot_data(&run, &run.analyse());
    // The numbers the tables print, as written to analysis.json.
    let analysis = read_json(&r.join("analysis.json"));
    let objectives = analysis["objectives"].as_array().unwrap();
    assert_eq!(plots.len(), 2);
    for (p, o) in plots.iter().zip(objectives) {
        assert_eq!(p.id, o["id"].as_str().unwrap());
        for ((c, (name, finals)), cell) in p
            .convergence
            .iter()
            .zip(&p.finals)
            .zip(o["cells"].as_array().unwrap())
        {
            let median = cell["stats"]["median"].as_f64().unwrap();
            let last = *c.median.last().unwrap();
            assert!(
                close(last, median),
                "{} {name}: plotted {last}, table {median}",
                p.id
            );
            let errors: Vec<f64> = cell["errors"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            assert_eq!(finals, &errors, "{} {name}: box plot values", p.id);
            // The plotted quantity is not the stored objective value (the cost J) on the fit.
            let raw: Vec<f64> = run
                .records
                .iter()
                .filter(|t| t.objective == p.id && &t.optimizer == name)
                .map(|t| t.best)
                .collect();
            let on_fit = p.id == "bw";
            assert_eq!(
                !raw.iter().any(|&j| close(j, last)),
                on_fit,
                "{} {name}: cost {raw:?} against plotted {last}",
                p.id
            );
        }
    }

    // Every axis says what it shows, in the recording's units; the cost is never called RMSE.
    let fit = &plots[0];
    assert_eq!(fit.quantity, "train RMSE [mm]");
    assert_eq!(fit.convergence_label(), "best-so-far train RMSE [mm]");
    assert_eq!(fit.final_label(), "final train RMSE [mm]");
    assert_eq!(plots[1].quantity, "error to optimum f − f*");
    let plots_dir = r.join("plots");
    let has = |file: &str, label: &str| svg_texts(&plots_dir.join(file)).iter().any(|t| t == label);
    assert!(has("convergence_bw.svg", "best-so-far train RMSE [mm]"));
    assert!(has("box_bw.svg", "final train RMSE [mm]"));
    assert!(has(
        "convergence_griewank-2d.svg",
        "best-so-far error to optimum f − f*"
    ));
    assert!(has("box_griewank-2d.svg", "final error to optimum f − f*"));
    for stem in ["ecdf_bw", "ecdf_griewank-2d"] {
        let file = format!("{stem}.svg");
        assert!(has(&file, "function evaluations"), "{file}");
        assert!(
            has(&file, "fraction of (trial, target) pairs reached"),
            "{file}"
        );
    }
    let t = svg_texts(&plots_dir.join("ecdf_bw.svg"));
    assert!(
        t.iter().any(|t| t.contains("targets on train RMSE [mm]")),
        "{t:?}"
    );
    for t in svg_texts(&plots_dir.join("convergence_griewank-2d.svg")) {
        assert!(!t.contains("RMSE"), "{t}");
    }

    // Every PNG at 300 dpi, 6.4 x 4.8 in.
    for e in std::fs::read_dir(&plots_dir).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_some_and(|x| x == "png") {
            let decoder = png::Decoder::new(std::fs::File::open(&path).unwrap());
            let reader = decoder.read_info().unwrap();
            let info = reader.info();
            let dims = info.pixel_dims.expect("pHYs chunk");
            assert_eq!(dims.unit, png::Unit::Meter, "{}", path.display());
            let dpi = f64::from(dims.xppu) * 0.0254;
            assert!((dpi - 300.0).abs() < 0.01, "{}: {dpi} dpi", path.display());
            assert_eq!(
                (info.width, info.height),
                (1920, 1440),
                "{}",
                path.display()
            );
        }
    }
}
