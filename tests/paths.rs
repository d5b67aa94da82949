//! Names and paths from suite files: an id that would write outside the results folder or
//! over a built-in output is refused with its file and line (also from the suite copy of a
//! results folder someone sent), and recordings named relative to the suite file are found
//! again by `report`, `--resume` and `merge`, wherever the run was started.

mod common;

use common::{ok, optbench, refused};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Every path under `root`, relative to it (`skip` left out with its contents).
fn tree(root: &Path, skip: Option<&Path>) -> BTreeSet<PathBuf> {
    let mut all = BTreeSet::new();
    let mut todo = vec![root.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if Some(p.as_path()) == skip {
                continue;
            }
            if p.is_dir() {
                todo.push(p.clone());
            }
            all.insert(p.strip_prefix(root).unwrap().to_path_buf());
        }
    }
    all
}

/// The ids that must not become file names: traversal, absolute (inside the test's own
/// folder, so a failure writes nowhere else), a separator, empty, a built-in table's name.
fn hostile_ids(root: &Path) -> Vec<String> {
    let abs = root.join("abs").display().to_string();
    ["../../x", &abs, "a/b", "..", "", "summary", "Summary"]
        .map(String::from)
        .to_vec()
}

/// A benchmark suite: line 13 is the table's `id`.
fn benchmark(table_id: &str) -> String {
    format!(
        r#"name = "names"
seed = 1
trials = 1
budget = 30

[[objective]]
kind = "sphere"
dim = 2

[[optimizer]]
kind = "random"

[[table]]
id = {table_id:?}
title = "T"
columns = ["random"]
rows = [{{ label = "a", cells = ["sphere-2d:random"] }}]
"#
    )
}

/// A control suite: line 13 is the table's `id`.
fn control(table_id: &str) -> String {
    format!(
        r#"name = "names"
seed = 1
trials = 1

[control]
references = [{{ id = "sine5", spec = "sine:freq=5,amp=0.2,offset=0.3", duration = 0.3 }}]
transient = 0.1
figures = false

[[controller]]
id = "P"
kind = "pid"
[[table]]
id = {table_id:?}
title = "T"
columns = ["twin"]
rows = [{{ label = "P", cells = ["P/twin/sine5"] }}]
"#
    )
}

/// Runs `text` as `work/bad.toml` from `work`, expects exit 2 naming `bad.toml:line`, and
/// checks that nothing was written anywhere under the test's folder.
fn run_refused(text: &str, line: usize, needle: &str) {
    let root = tempfile::tempdir().unwrap();
    let work = root.path().join("work");
    std::fs::create_dir(&work).unwrap();
    std::fs::write(work.join("bad.toml"), text).unwrap();
    let before = tree(root.path(), None);
    let out = optbench(&["run", "bad.toml", "-q"], &work);
    refused(&out, &[&format!("bad.toml:{line}:"), needle]);
    assert_eq!(tree(root.path(), None), before, "nothing may be written");
}

#[test]
fn hostile_table_ids_are_refused_at_load_in_benchmark_and_control_suites() {
    let root = tempfile::tempdir().unwrap();
    for id in hostile_ids(root.path()) {
        run_refused(&benchmark(&id), 14, "table id");
        run_refused(&control(&id), 14, "table id");
    }
}

#[test]
fn hostile_names_and_entry_ids_are_refused_at_load() {
    let b = benchmark("t1");
    let c = control("t1");
    for bad in ["../../x", "/abs", "a/b", "..", ""] {
        let q = format!("{bad:?}");
        run_refused(
            &b.replace("name = \"names\"", &format!("name = {q}")),
            1,
            "`name`",
        );
        run_refused(
            &b.replace("dim = 2", &format!("dim = 2\nid = {q}")),
            6,
            "objective id",
        );
        run_refused(
            &b.replace("kind = \"random\"", &format!("kind = \"random\"\nid = {q}")),
            10,
            "optimizer id",
        );
        run_refused(
            &c.replace("id = \"P\"", &format!("id = {q}")),
            10,
            "controller id",
        );
    }
}

#[test]
fn ids_that_would_share_a_file_are_refused() {
    let b = benchmark("t1");
    // Two tables with one id would write one file.
    let twice = format!("{b}{}", &b[b.find("[[table]]").unwrap()..]);
    run_refused(&twice, 18, "used twice");
    // So would `A` and `a` on a case-insensitive file system.
    let cased = b.replace(
        "dim = 2\n",
        "dim = 2\nid = \"A\"\n\n[[objective]]\nkind = \"sphere\"\ndim = 2\nid = \"a\"\n",
    );
    run_refused(&cased, 11, "used twice");
}

/// Runs the benchmark suite into `root/out` (from `root/work`) and returns the folder.
fn stored_run(root: &Path) -> PathBuf {
    let work = root.join("work");
    std::fs::create_dir(&work).unwrap();
    std::fs::write(work.join("s.toml"), benchmark("t1")).unwrap();
    ok(&optbench(
        &["run", "s.toml", "--out", "../out", "-q"],
        &work,
    ));
    root.join("out")
}

#[test]
fn report_refuses_a_results_folder_whose_suite_copy_was_tampered_with() {
    let root = tempfile::tempdir().unwrap();
    for (i, id) in hostile_ids(root.path()).iter().enumerate() {
        let case = root.path().join(format!("case{i}"));
        std::fs::create_dir(&case).unwrap();
        let out = stored_run(&case);
        let copy = out.join("suite.toml");
        let text = std::fs::read_to_string(&copy).unwrap();
        std::fs::write(&copy, text.replace("id = \"t1\"", &format!("id = {id:?}"))).unwrap();
        let outside = tree(root.path(), Some(&out));
        let r = optbench(&["report", "out"], &case);
        refused(&r, &["suite.toml:14:", "table id"]);
        assert_eq!(tree(root.path(), Some(&out)), outside, "{id:?}");
    }
}

#[test]
fn report_refuses_traces_that_name_an_optimizer_the_suite_does_not_have() {
    let root = tempfile::tempdir().unwrap();
    let out = stored_run(root.path());
    let traces = out.join("traces.jsonl");
    let text = std::fs::read_to_string(&traces).unwrap();
    let evil = text.replace("\"optimizer\":\"random\"", "\"optimizer\":\"../../evil\"");
    assert_ne!(evil, text);
    std::fs::write(&traces, evil).unwrap();
    let outside = tree(root.path(), Some(&out));
    let r = optbench(&["report", "out"], root.path());
    refused(&r, &["optimizer `../../evil`"]);
    assert_eq!(tree(root.path(), Some(&out)), outside);
}

#[cfg(unix)]
#[test]
fn report_refuses_a_results_folder_whose_subfolders_are_links() {
    for sub in ["tables", "plots", "ioh"] {
        let root = tempfile::tempdir().unwrap();
        let out = stored_run(root.path());
        let elsewhere = root.path().join("elsewhere");
        std::fs::create_dir(&elsewhere).unwrap();
        std::fs::remove_dir_all(out.join(sub)).unwrap();
        std::os::unix::fs::symlink(&elsewhere, out.join(sub)).unwrap();
        let r = optbench(&["report", "out"], root.path());
        refused(&r, &[sub, "symbolic link"]);
        assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0, "{sub}");
    }
}

/// A fitting suite whose recording is named relative to the suite file.
const RELATIVE: &str = r#"name = "relative"
seed = 4
trials = 2
budget = 40

[[objective]]
kind = "bouc-wen"
id = "bw"
recording = "data/rec.csv"
validate = "data/rec.csv"

[[optimizer]]
kind = "random"
"#;

#[test]
fn recordings_relative_to_the_suite_are_found_by_report_resume_and_merge() {
    let root = tempfile::tempdir().unwrap();
    let suite_dir = root.path().join("suite");
    std::fs::create_dir_all(suite_dir.join("data")).unwrap();
    let mut csv = String::from("t,u,y\n");
    for k in 0..300 {
        let t = k as f64 * 1e-3;
        let u = (2.0 * std::f64::consts::PI * 5.0 * t).sin();
        csv += &format!("{t},{u},{}\n", 0.8 * u + 0.1 * (31.4 * t - 0.3).sin());
    }
    std::fs::write(suite_dir.join("data/rec.csv"), csv).unwrap();
    std::fs::write(suite_dir.join("s.toml"), RELATIVE).unwrap();
    // Started from another folder, results into a third one.
    let cwd = root.path().join("elsewhere");
    std::fs::create_dir(&cwd).unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["run", "../suite/s.toml", "-q"];
        args.extend_from_slice(extra);
        optbench(&args, &cwd)
    };
    ok(&run(&["--out", "../results/all"]));
    let all = root.path().join("results/all");
    assert!(all.join("report.md").exists());
    ok(&optbench(&["report", "results/all"], root.path()));
    ok(&run(&["--out", "../results/all", "--resume"]));
    ok(&run(&["--out", "../results/s1", "--shard", "1/2"]));
    ok(&run(&["--out", "../results/s2", "--shard", "2/2"]));
    ok(&optbench(
        &["merge", "s1", "s2", "--out", "merged", "-q"],
        &root.path().join("results"),
    ));
    let summary = |d: &str| {
        let mut v = common::read_json(&root.path().join("results").join(d).join("summary.json"));
        for c in v["results"].as_array_mut().unwrap() {
            c["wall_s"] = 0.into();
        }
        v
    };
    assert_eq!(summary("merged"), summary("all"));
    // The stored copy names the file itself, read from wherever the copy is.
    let copy = std::fs::read_to_string(all.join("suite.toml")).unwrap();
    let abs = std::fs::canonicalize(suite_dir.join("data/rec.csv")).unwrap();
    assert!(
        copy.contains(&format!("recording = {:?}", abs.display().to_string())),
        "{copy}"
    );
    // The shipped suites' `$OPTBENCH_DATA` paths and simulated sources stay as written.
    let shipped = format!("{}/suites/hysteresis.toml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&shipped).unwrap();
    let suite = optbench::pipeline::suite::Suite::parse(&text, Path::new(&shipped)).unwrap();
    assert_eq!(suite.text, text);
}
