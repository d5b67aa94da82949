//! The `optbench` binary: a tiny suite end to end, and bad input rejected with a located
//! message, exit code 2 and nothing written.

mod common;

use common::{optbench, run_shipped_suite};
use serde_json::Value;
use std::path::Path;

const TINY: &str = r#"name = "tiny"
seed = 3
trials = 3
budget = 600
targets = [1.0, 0.1]

[[objective]]
kind = "griewank"
dim = 2

[[objective]]
kind = "schwefel"
id = "schwefel-seed"
dim = 2

[[optimizer]]
kind = "ga"
id = "GA"

[[optimizer]]
kind = "msga"
id = "MSGA"
"#;

#[test]
fn tiny_suite_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let out = optbench(&["run", "tiny.toml", "--threads", "2"], dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("| griewank-2d") && stdout.contains("| MSGA"),
        "{stdout}"
    );

    let res = dir.path().join("results/tiny");
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(res.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["suite"], "tiny");
    assert_eq!(summary["seed"], 3);
    let cells = summary["results"].as_array().unwrap();
    assert_eq!(cells.len(), 4);
    assert_eq!(cells[2]["objective"], "schwefel-seed");
    assert_eq!(cells[3]["optimizer"], "MSGA");
    for c in cells {
        let finals: Vec<f64> = c["finals"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(finals.len(), 3);
        let mut s = finals.clone();
        s.sort_by(f64::total_cmp);
        assert_eq!(c["median"].as_f64().unwrap(), s[1]);
        assert_eq!(c["min"].as_f64().unwrap(), s[0]);
        assert_eq!(c["max"].as_f64().unwrap(), s[2]);
        let mean = finals.iter().sum::<f64>() / 3.0;
        assert!((c["mean"].as_f64().unwrap() - mean).abs() < 1e-12 * (1.0 + mean.abs()));
        assert!(c["std"].as_f64().unwrap() >= 0.0);
        assert_eq!(c["evaluations"], 1800);
        assert!(c["wall_s"].as_f64().unwrap() > 0.0);
    }
    let traces = std::fs::read_to_string(res.join("traces.jsonl")).unwrap();
    assert_eq!(traces.lines().count(), 12);
    let prov: Value =
        serde_json::from_str(&std::fs::read_to_string(res.join("provenance.json")).unwrap())
            .unwrap();
    assert_eq!(prov["threads"], 2);
    assert_eq!(prov["seed"], 3);
    assert_eq!(
        std::fs::read_to_string(res.join("suite.toml")).unwrap(),
        TINY
    );
    // No temporary files are left behind.
    for e in std::fs::read_dir(&res).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().to_string();
        assert!(!name.contains(".tmp-"), "{name}");
    }

    // Overrides and --out.
    let out = optbench(
        &[
            "run",
            "tiny.toml",
            "--trials",
            "2",
            "--seed",
            "9",
            "--out",
            "elsewhere",
            "-q",
        ],
        dir.path(),
    );
    assert!(out.status.success());
    assert!(out.stdout.is_empty(), "--quiet prints nothing");
    let summary: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("elsewhere/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(summary["seed"], 9);
    assert_eq!(summary["results"][0]["finals"].as_array().unwrap().len(), 2);
}

/// Writes `text` as bad.toml, runs it, and checks exit 2, the message, nothing written.
fn rejects(text: &str, expected: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.toml"), text).unwrap();
    let out = optbench(&["run", "bad.toml"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    for e in expected {
        assert!(stderr.contains(e), "expected {e:?} in: {stderr}");
    }
    assert!(
        !dir.path().join("results").exists(),
        "nothing may be written"
    );
}

const HEAD: &str = "name = \"bad\"\nseed = 1\ntrials = 2\nbudget = 100\n";

#[test]
fn malformed_toml_names_file_and_line() {
    rejects(
        &format!("{HEAD}[[objective]]\nkind = \"griewank\ndim = 2\n"),
        &["bad.toml:6:"],
    );
    rejects(
        &format!("{HEAD}[[objective]]\nkind = \"griewank\"\ndim = 2\ndim = 3\n"),
        &["bad.toml:8:", "duplicate key"],
    );
}

#[test]
fn unknown_names_list_the_valid_ones() {
    rejects(
        &format!(
            "{HEAD}[[objective]]\nkind = \"griewonk\"\ndim = 2\n[[optimizer]]\nkind = \"ga\"\n"
        ),
        &[
            "bad.toml:6:",
            "unknown objective kind `griewonk`",
            "sphere, griewank, schwefel, rastrigin, rosenbrock, ackley",
        ],
    );
    rejects(
        &format!(
            "{HEAD}[[objective]]\nkind = \"griewank\"\ndim = 2\n[[optimizer]]\nkind = \"cma-es\"\n"
        ),
        &[
            "bad.toml:9:",
            "unknown optimizer kind `cma-es`",
            "ga, pso, msga, bp, nelder-mead, random, de, shade, cmaes, lbfgs",
        ],
    );
    rejects(
        &format!(
            "{HEAD}[[objective]]\nkind = \"griewank\"\ndim = 2\n[[optimizer]]\nkind = \"ga\"\npopsize = 3\n"
        ),
        &[
            "bad.toml:10:",
            "unknown parameter `popsize`",
            "population, pc, pm, elite",
        ],
    );
    rejects(
        &format!(
            "{HEAD}budgett = 3\n[[objective]]\nkind = \"griewank\"\ndim = 2\n[[optimizer]]\nkind = \"ga\"\n"
        ),
        &["bad.toml:5:", "unknown field `budgett`"],
    );
}

#[test]
fn impossible_parameters_are_refused() {
    let obj = "[[objective]]\nkind = \"griewank\"\ndim = 2\n";
    rejects(
        &format!("{HEAD}{obj}[[optimizer]]\nkind = \"ga\"\npc = 1.5\n"),
        &["bad.toml:10:", "`pc`", "1.5 is out of range", "[0, 1]"],
    );
    rejects(
        &format!("{HEAD}{obj}[[optimizer]]\nkind = \"pso\"\npopulation = 0\n"),
        &["bad.toml:10:", "`population`", "integer in [1, 10000]"],
    );
    rejects(
        &format!("{HEAD}{obj}[[optimizer]]\nkind = \"ga\"\npopulation = 10\nelite = 10\n"),
        &["bad.toml:11:", "`elite`", "smaller than the population"],
    );
    rejects(
        &format!("{HEAD}[[objective]]\nkind = \"sphere\"\ndim = 0\n[[optimizer]]\nkind = \"ga\"\n"),
        &["bad.toml:7:", "`dim`", "integer in [1, 4000]"],
    );
    rejects(
        &format!(
            "{HEAD}[[objective]]\nkind = \"sphere\"\ndim = 2\nlower = 5\nupper = -5\n[[optimizer]]\nkind = \"ga\"\n"
        ),
        &["bad.toml:8:", "lower bound 5 is not below upper bound -5"],
    );
    rejects(
        "name = \"bad\"\nseed = 1\ntrials = 0\nbudget = 100\n[[objective]]\nkind = \"sphere\"\ndim = 2\n[[optimizer]]\nkind = \"ga\"\n",
        &["bad.toml:3:", "`trials` = 0"],
    );
    rejects(
        &format!("{HEAD}{obj}[[optimizer]]\nkind = \"pso\"\npolish = 1.5\n"),
        &[
            "bad.toml:10:",
            "`polish` = 1.5: expected a budget share in (0, 1)",
        ],
    );
    rejects(
        &format!("{HEAD}{obj}[[optimizer]]\nkind = \"ga\"\n[[optimizer]]\nkind = \"ga\"\n"),
        &["bad.toml:10:", "optimizer id `ga` is used twice"],
    );
    rejects(
        &format!("{HEAD}[[objective]]\ndim = 2\n[[optimizer]]\nkind = \"ga\"\n"),
        &["bad.toml:5:", "objective without `kind`"],
    );
}

#[test]
fn missing_suite_file_is_an_input_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = optbench(&["run", "nope.toml"], dir.path());
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nope.toml: cannot read suite"));
}

#[test]
fn list_shows_every_kind_with_parameters_and_defaults() {
    let out = optbench(&["list"], Path::new("."));
    assert!(out.status.success());
    let s = String::from_utf8_lossy(&out.stdout);
    for k in [
        "griewank",
        "schwefel",
        "sphere",
        "rastrigin",
        "rosenbrock",
        "ackley",
        "ga",
        "pso",
        "msga",
        "random",
    ] {
        assert!(s.contains(&format!("`{k}`")), "{k} missing:\n{s}");
    }
    assert!(s.contains("| exchange") && s.contains("| 0.3 "), "{s}");
    assert!(s.contains("| threads") && s.contains("| true "), "{s}");
}

#[test]
fn shipped_suites_are_valid() {
    for entry in std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/suites")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let text = std::fs::read_to_string(&path).unwrap();
            let data = optbench::data::recording::data_dir();
            if text.contains("$OPTBENCH_DATA") && !data.exists() {
                eprintln!(
                    "skipping {}: data not found at {} (set OPTBENCH_DATA)",
                    path.display(),
                    data.display()
                );
                continue;
            }
            if optbench::control::suite::is_control_suite(&text) {
                optbench::control::suite::ControlSuite::load(&path)
                    .unwrap_or_else(|e| panic!("{e}"));
                continue;
            }
            optbench::pipeline::suite::Suite::load(&path).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}

#[test]
fn main_suite_runs_end_to_end_at_small_size() {
    // The README's first command, with every optimizer of the shipped suite (the polished
    // MSGA included) at a budget that spans several MSGA rounds past the polish switch.
    let dir = run_shipped_suite("functions", "2", "2000");
    let summary: Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("r/summary.json")).unwrap()).unwrap();
    let text = summary.to_string();
    for id in ["MSGA", "MSGA-LBFGS", "CMA-ES", "SHADE"] {
        assert!(text.contains(&format!("\"{id}\"")), "{id} missing");
    }
}

fn report_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for sub in ["", "tables", "plots"] {
        for e in std::fs::read_dir(dir.join(sub)).unwrap() {
            let p = e.unwrap().path();
            // The folder's lock file names its last holder (pid, time), not a result.
            if p.is_file() && !p.ends_with(optbench::pipeline::store::lock::LOCK_FILE) {
                out.push((p.display().to_string(), std::fs::read(&p).unwrap()));
            }
        }
    }
    let mut stack = vec![dir.join("ioh")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((p.display().to_string(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn run_writes_the_report_and_report_reproduces_it_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    assert!(
        optbench(&["run", "tiny.toml", "-q"], dir.path())
            .status
            .success()
    );
    let res = dir.path().join("results/tiny");
    let before = report_files(&res);
    let names: Vec<String> = before
        .iter()
        .map(|(p, _)| p.trim_start_matches(&res.display().to_string()).to_string())
        .collect();
    for expected in [
        "/report.md",
        "/analysis.json",
        "/tables/summary.tex",
        "/tables/summary.md",
        "/tables/summary.csv",
        "/tables/pairwise.csv",
        "/tables/ert.csv",
        "/tables/fixed_budget.csv",
        "/plots/convergence_griewank-2d.svg",
        "/plots/convergence_griewank-2d.png",
        "/plots/box_schwefel-seed.png",
        "/plots/ecdf_schwefel-seed.svg",
        "/ioh/MSGA/IOHprofiler_f27_schwefel.json",
        "/ioh/GA/data_f26_griewank/IOHprofiler_f26_DIM2.dat",
        "/ioh/instances.csv",
    ] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing in {names:?}"
        );
    }
    // Regenerate from the stored traces only: identical bytes.
    let out = optbench(&["report", "results/tiny"], dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("median [95% CI]"));
    assert_eq!(before, report_files(&res));

    // The report says what the traces say: 3 trials per cell, ERT columns for both targets.
    let report = std::fs::read_to_string(res.join("report.md")).unwrap();
    assert!(
        report.contains("err <= 1.0") && report.contains("err <= 0.10"),
        "{report}"
    );
    let analysis: Value =
        serde_json::from_str(&std::fs::read_to_string(res.join("analysis.json")).unwrap()).unwrap();
    assert_eq!(analysis["objectives"][0]["cells"][0]["stats"]["n"], 3);
    assert_eq!(
        analysis["objectives"][0]["pairs"].as_array().unwrap().len(),
        1
    );

    // Comparing a folder with itself finds every cell identical.
    let out = optbench(&["report", "results/tiny", "results/tiny"], dir.path());
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(text.matches("identical").count(), 4, "{text}");
}

#[test]
fn compare_refuses_different_suites() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    std::fs::write(
        dir.path().join("other.toml"),
        TINY.replace("name = \"tiny\"", "name = \"other\""),
    )
    .unwrap();
    assert!(
        optbench(&["run", "tiny.toml", "-q"], dir.path())
            .status
            .success()
    );
    assert!(
        optbench(&["run", "other.toml", "-q"], dir.path())
            .status
            .success()
    );
    let out = optbench(&["report", "results/tiny", "results/other"], dir.path());
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("compare results of the same suite"));
}

#[test]
fn objectives_can_run_a_subset_of_the_optimizers() {
    let suite = format!(
        "{HEAD}[[objective]]\nkind = \"sphere\"\ndim = 2\noptimizers = [\"b\"]\n\
         [[objective]]\nkind = \"griewank\"\ndim = 2\n\
         [[optimizer]]\nkind = \"ga\"\nid = \"a\"\n[[optimizer]]\nkind = \"pso\"\nid = \"b\"\n"
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("sub.toml"), &suite).unwrap();
    let out = optbench(&["run", "sub.toml", "-q"], dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("results/bad/summary.json")).unwrap(),
    )
    .unwrap();
    let cells: Vec<(String, String)> = summary["results"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["objective"].as_str().unwrap().into(),
                c["optimizer"].as_str().unwrap().into(),
            )
        })
        .collect();
    let expected = [
        ("sphere-2d", "b"),
        ("griewank-2d", "a"),
        ("griewank-2d", "b"),
    ];
    assert_eq!(cells, expected.map(|(o, p)| (o.to_string(), p.to_string())));

    rejects(
        &suite.replace("optimizers = [\"b\"]", "optimizers = [\"c\"]"),
        &[
            "bad.toml:8:",
            "names `c`, which is not an optimizer id of this suite (a, b)",
        ],
    );
}
