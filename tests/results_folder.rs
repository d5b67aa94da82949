//! What a results folder holds after `run` and `report`, through the release binary: the IOH
//! export loads in the IOH project's own loader (`iohinspector`, when Python has it) with
//! every run and the summary's finals; a folder of another suite or of other files is
//! refused with how to proceed; `--overwrite` removes only optbench's files; and no file of
//! an earlier run or report (a plot, an `ioh/` folder, a table of an objective no longer in
//! the suite) stays beside the new ones.

mod common;

use common::{ok, optbench, read_json, refused};
use std::path::Path;
use std::process::{Command, Output};

/// Two functions in two dimensions, one on a narrow box (another instance), one at a second
/// budget (an instance of its own), and a fit: 6 objectives x 2 optimizers x 3 trials = 36
/// runs in 4 (function, dimension) pairs.
const TINY: &str = r#"name = "tiny"
seed = 7
trials = 3
budget = 300

[[objective]]
kind = "griewank"
id = "griewank-2d"
dim = 2

[[objective]]
kind = "griewank"
id = "griewank-2d-long"
dim = 2
budget = 400

[[objective]]
kind = "griewank"
id = "griewank-5d"
dim = 5

[[objective]]
kind = "schwefel"
id = "schwefel-2d"
dim = 2

[[objective]]
kind = "schwefel"
id = "schwefel-narrow"
dim = 2
lower = -100
upper = 100

[[objective]]
kind = "bouc-wen"
id = "bw"
recording = "twin:sine:freq=10,amp=2.3,offset=2.35"
duration = 0.1

[[optimizer]]
kind = "random"
id = "RS"
batch = 10

[[optimizer]]
kind = "lbfgs"
id = "LBFGS"
"#;

/// Another suite: one objective, another optimizer.
const OTHER: &str = r#"name = "other"
seed = 1
trials = 2
budget = 100

[[objective]]
kind = "sphere"
dim = 2

[[optimizer]]
kind = "de"
id = "DE"
population = 10
"#;

/// Every file below `dir` (relative paths), sorted.
fn files(dir: &Path) -> Vec<String> {
    fn walk(root: &Path, at: &Path, out: &mut Vec<String>) {
        for e in std::fs::read_dir(at).unwrap() {
            let e = e.unwrap();
            let p = e.path();
            if e.file_type().unwrap().is_dir() {
                walk(root, &p, out);
            } else {
                out.push(p.strip_prefix(root).unwrap().display().to_string());
            }
        }
    }
    let mut v = Vec::new();
    walk(dir, dir, &mut v);
    v.sort();
    v
}

fn write_suites(root: &Path) {
    std::fs::write(root.join("tiny.toml"), TINY).unwrap();
    std::fs::write(root.join("other.toml"), OTHER).unwrap();
}

/// python3 with iohinspector, or why not.
fn iohinspector() -> Result<(), String> {
    match Command::new("python3")
        .args(["-c", "import iohinspector"])
        .output()
    {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(String::from_utf8_lossy(&o.stderr).trim().to_string()),
        Err(e) => Err(format!("python3: {e}")),
    }
}

fn ioh_check(dir: &Path) -> Output {
    Command::new("python3")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/ioh_check.py"))
        .arg(dir)
        .output()
        .unwrap()
}

#[test]
fn iohinspector_loads_every_run_with_the_summarys_finals() {
    if let Err(why) = iohinspector() {
        eprintln!(
            "SKIPPED iohinspector_loads_every_run_with_the_summarys_finals: python3 with iohinspector is not available ({why}); pip install iohinspector"
        );
        return;
    }
    let root = tempfile::tempdir().unwrap();
    write_suites(root.path());
    ok(&optbench(
        &["run", "tiny.toml", "--out", "r", "-q"],
        root.path(),
    ));
    let out = root.path().join("r");
    let check = ioh_check(&out);
    let stdout = String::from_utf8_lossy(&check.stdout);
    assert!(
        check.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&check.stderr)
    );
    assert!(
        stdout.contains("loaded 36 runs of 36 in 8 (function, dimension, algorithm) groups"),
        "{stdout}"
    );
    // The check can fail: a final value changed in one .dat file is caught.
    let dat = out.join("ioh/RS/data_f27_schwefel/IOHprofiler_f27_DIM2.dat");
    let text = std::fs::read_to_string(&dat).unwrap();
    let first_run_end = text[1..].find("evaluations").unwrap();
    let last_line = text[..first_run_end]
        .trim_end()
        .rsplit('\n')
        .next()
        .unwrap();
    let evals = last_line.split(' ').next().unwrap();
    let edited = text.replacen(last_line, &format!("{evals} 123.5"), 1);
    std::fs::write(&dat, edited).unwrap();
    let check = ioh_check(&out);
    let stdout = String::from_utf8_lossy(&check.stdout);
    assert_eq!(check.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("MISMATCH: schwefel-2d x RS run") && stdout.contains(".dat ends at 123.5"),
        "{stdout}"
    );
}

#[test]
fn the_export_has_fixed_ids_instances_and_errors_to_the_optimum() {
    let root = tempfile::tempdir().unwrap();
    write_suites(root.path());
    ok(&optbench(
        &["run", "tiny.toml", "--out", "r", "-q"],
        root.path(),
    ));
    let ioh = root.path().join("r/ioh");
    let csv = std::fs::read_to_string(ioh.join("instances.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    // Griewank in 2 and 5 dimensions: one function id; the narrow box another instance.
    assert_eq!(&rows[0][..5], ["26", "griewank", "2", "1", "griewank-2d"]);
    // The same function at another budget: an instance of its own.
    assert_eq!(
        &rows[1][..5],
        ["26", "griewank", "2", "2", "griewank-2d-long"]
    );
    assert_eq!(&rows[2][..5], ["26", "griewank", "5", "1", "griewank-5d"]);
    assert_eq!(&rows[3][..4], ["27", "schwefel", "2", "1"]);
    assert_eq!(&rows[4][..3], ["27", "schwefel", "2"]);
    assert_ne!(rows[4][3], "1");
    assert_eq!(&rows[5][..2], ["101", "bouc-wen"]);
    // Schwefel's values are errors to its (negative) optimum: never negative, and the
    // meta file's best equals summary's final minus the optimum.
    let meta = read_json(&ioh.join("RS/IOHprofiler_f27_schwefel.json"));
    let summary = read_json(&root.path().join("r/summary.json"));
    let cell = summary["results"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["objective"] == "schwefel-2d" && c["optimizer"] == "RS")
        .unwrap();
    let optimum = cell["optimum"].as_f64().unwrap();
    assert!(optimum < -800.0);
    let runs = meta["scenarios"][0]["runs"].as_array().unwrap();
    assert_eq!(
        runs.len(),
        6,
        "two instances of three trials in one scenario"
    );
    for (r, f) in runs.iter().zip(cell["finals"].as_array().unwrap()) {
        assert_eq!(
            r["best"]["y"].as_f64().unwrap(),
            (f.as_f64().unwrap() - optimum).max(0.0)
        );
    }
    let dat =
        std::fs::read_to_string(ioh.join("RS/data_f27_schwefel/IOHprofiler_f27_DIM2.dat")).unwrap();
    // The first three runs are schwefel-2d's (instance 1); the narrow box misses the
    // optimum, which is then unknown, and its values are raw (negative).
    let blocks: Vec<&str> = dat.split("evaluations raw_y\n").skip(1).collect();
    assert_eq!(blocks.len(), 6);
    for l in blocks[..3].iter().flat_map(|b| b.lines()) {
        let y: f64 = l.split(' ').nth(1).unwrap().parse().unwrap();
        assert!(y >= 0.0, "{l}");
    }
    assert!(rows[4][5].contains("optimum unknown"), "{csv}");
    // No legacy .info beside the meta files (loaders would read every run twice).
    assert!(!files(&ioh).iter().any(|f| f.ends_with(".info")));
}

#[test]
fn another_suites_folder_or_other_files_are_refused_and_the_same_suite_resumes() {
    let root = tempfile::tempdir().unwrap();
    write_suites(root.path());
    let dir = root.path();
    ok(&optbench(&["run", "other.toml", "--out", "r", "-q"], dir));
    let before = files(&dir.join("r"));
    let r = optbench(&["run", "tiny.toml", "--out", "r", "-q"], dir);
    refused(
        &r,
        &[
            "holds the results of suite `other`, not `tiny`",
            "--resume",
            "another --out",
            "--overwrite",
        ],
    );
    assert_eq!(files(&dir.join("r")), before, "nothing written");
    // The same suite: a rerun and a resume are welcome.
    ok(&optbench(&["run", "other.toml", "--out", "r", "-q"], dir));
    let text = ok(&optbench(
        &["run", "other.toml", "--out", "r", "--resume"],
        dir,
    ));
    assert!(text.contains("2 trials resumed"), "{text}");
    // A folder of someone else's files: refused, and left exactly as it was.
    std::fs::create_dir_all(dir.join("mine")).unwrap();
    std::fs::write(dir.join("mine/notes.txt"), "mine").unwrap();
    let r = optbench(&["run", "tiny.toml", "--out", "mine", "-q"], dir);
    refused(
        &r,
        &[
            "not empty and holds no optbench results (notes.txt)",
            "--overwrite",
        ],
    );
    let r = optbench(
        &["run", "tiny.toml", "--out", "mine", "--resume", "-q"],
        dir,
    );
    refused(&r, &["holds no optbench results"]);
    assert_eq!(files(&dir.join("mine")), ["notes.txt"]);
    assert_eq!(std::fs::read_dir(dir.join("mine")).unwrap().count(), 1);
}

#[cfg(unix)]
#[test]
fn overwrite_leaves_other_files_and_no_stale_output() {
    let root = tempfile::tempdir().unwrap();
    write_suites(root.path());
    let dir = root.path();
    let out = dir.join("r");
    ok(&optbench(&["run", "tiny.toml", "--out", "r", "-q"], dir));
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    std::fs::create_dir_all(dir.join("elsewhere")).unwrap();
    std::fs::write(dir.join("elsewhere/keep.txt"), "keep").unwrap();
    std::os::unix::fs::symlink(dir.join("elsewhere"), out.join("link")).unwrap();
    ok(&optbench(
        &["run", "other.toml", "--out", "r", "--overwrite", "-q"],
        dir,
    ));
    let left = files(&out);
    assert!(left.contains(&"notes.txt".to_string()));
    assert!(out.join("link").is_symlink());
    assert_eq!(files(&dir.join("elsewhere")), ["keep.txt"]);
    // Only the new suite's outputs: its optimizer and objective, nothing of tiny's.
    for f in &left {
        assert!(
            !["RS", "LBFGS", "griewank", "schwefel", "bw"]
                .iter()
                .any(|old| f.contains(old)),
            "stale {f} in {left:?}"
        );
    }
    assert!(left.iter().any(|f| f.starts_with("ioh/DE/")), "{left:?}");
    assert!(left.iter().any(|f| f.starts_with("plots/")), "{left:?}");
    assert_eq!(read_json(&out.join("summary.json"))["suite"], "other");
    // --overwrite with --resume is a contradiction, refused by the command line.
    let r = optbench(
        &["run", "other.toml", "--out", "r", "--overwrite", "--resume"],
        dir,
    );
    assert_eq!(r.status.code(), Some(2));
}

#[test]
fn a_suite_that_lost_an_objective_and_a_regenerated_report_leave_no_stale_file() {
    let root = tempfile::tempdir().unwrap();
    write_suites(root.path());
    let dir = root.path();
    let out = dir.join("r");
    ok(&optbench(&["run", "tiny.toml", "--out", "r", "-q"], dir));
    assert!(files(&out).iter().any(|f| f.contains("griewank-5d")));
    // The same suite without griewank-5d and without LBFGS.
    let smaller = TINY
        .replace(
            "[[objective]]\nkind = \"griewank\"\nid = \"griewank-5d\"\ndim = 5\n",
            "",
        )
        .replace("[[optimizer]]\nkind = \"lbfgs\"\nid = \"LBFGS\"\n", "");
    assert_ne!(smaller, TINY);
    std::fs::write(dir.join("tiny.toml"), smaller).unwrap();
    ok(&optbench(&["run", "tiny.toml", "--out", "r", "-q"], dir));
    let left = files(&out);
    for f in &left {
        assert!(
            !f.contains("griewank-5d") && !f.contains("LBFGS") && !f.contains("f26_DIM5"),
            "stale {f}"
        );
    }
    assert!(
        !left
            .iter()
            .any(|f| f.contains(".staged-") || f.contains(".retired-"))
    );
    // A report regenerated over planted files of an earlier report removes them.
    std::fs::write(out.join("plots/convergence_gone.svg"), "old").unwrap();
    std::fs::create_dir_all(out.join("ioh/Gone")).unwrap();
    std::fs::write(out.join("ioh/Gone/IOHprofiler_f25_sphere.json"), "{}").unwrap();
    std::fs::write(out.join("tables/gone.md"), "old").unwrap();
    ok(&optbench(&["report", "r"], dir));
    assert_eq!(files(&out), left);
}

#[test]
fn provenance_and_summary_name_their_build_and_format() {
    let root = tempfile::tempdir().unwrap();
    write_suites(root.path());
    ok(&optbench(
        &["run", "other.toml", "--out", "r", "-q"],
        root.path(),
    ));
    let p = read_json(&root.path().join("r/provenance.json"));
    assert!(p["rustc"].as_str().unwrap().starts_with("rustc "), "{p}");
    if let Some(commit) = p["git_commit"].as_str() {
        assert_eq!(p["git_dirty"].as_bool(), Some(commit.ends_with("-dirty")));
    }
    if Path::new("/proc/cpuinfo").exists() {
        assert!(!p["cpu_model"].as_str().unwrap().is_empty(), "{p}");
    }
    let s = read_json(&root.path().join("r/summary.json"));
    assert_eq!(s["format_version"], 1);
}
