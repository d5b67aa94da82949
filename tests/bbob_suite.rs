//! COCO's BBOB functions in a suite, through the release binary: a `[bbob]` section expands to
//! one objective per (function, dimension), each trial runs the instance its `instances`
//! list assigns (with that instance's optimum), budgets follow `budget_per_dim`, resumed
//! runs keep their instances, the report draws cocopp's aggregated runtime ECDFs and writes
//! a COCO export that `cocopp` loads with every run (scripts/cocopp_check.py, skipped
//! without cocopp), and bad values are refused with file, line and key.

mod common;

use common::{ok, optbench, refused, run_check_script};
use serde_json::Value;
use std::path::Path;

/// 3 functions x 2 dimensions x 2 optimizers x 4 trials over instances 1-3 (trial 3 runs
/// instance 1 again).
const TINY: &str = r#"name = "tiny-bbob"
seed = 11
trials = 4

[bbob]
functions = [1, 8, 21]
dimensions = [2, 3]
instances = "1-3"
budget_per_dim = 60

[[objective]]
kind = "bbob"
id = "sphere-i7"
function = 1
dim = 2
instances = [7]
budget = 50
optimizers = ["RS"]

[[optimizer]]
kind = "random"
id = "RS"
batch = 5

[[optimizer]]
kind = "cmaes"
id = "CMA"
"#;

fn traces(dir: &Path) -> Vec<Value> {
    std::fs::read_to_string(dir.join("traces.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn a_bbob_section_runs_every_instance_and_exports_for_cocopp() {
    let root = tempfile::tempdir().unwrap();
    std::fs::write(root.path().join("tiny.toml"), TINY).unwrap();
    ok(&optbench(
        &["run", "tiny.toml", "--out", "r", "-q"],
        root.path(),
    ));
    let out = root.path().join("r");
    let t = traces(&out);
    assert_eq!(t.len(), 3 * 2 * 2 * 4 + 4);
    // Budgets proportional to the dimension; each trial its instance's optimum.
    let of = |obj: &str, opt: &str| -> Vec<&Value> {
        t.iter()
            .filter(|r| r["objective"] == obj && r["optimizer"] == opt)
            .collect()
    };
    let f8 = of("bbob-f08-d03", "RS");
    assert_eq!(f8.len(), 4);
    assert!(f8.iter().all(|r| r["budget"] == 180));
    assert_eq!(of("bbob-f01-d02", "CMA")[0]["budget"], 120);
    let opt: Vec<f64> = {
        let mut v = f8.clone();
        v.sort_by_key(|r| r["trial"].as_u64());
        v.iter().map(|r| r["optimum"].as_f64().unwrap()).collect()
    };
    assert_eq!(opt[0], opt[3], "trial 3 runs instance 1 again");
    assert!(opt[0] != opt[1] && opt[1] != opt[2], "{opt:?}");
    assert!(of("sphere-i7", "CMA").is_empty());

    // The report: aggregated ECDFs per dimension and the COCO export.
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## BBOB: runtime ECDFs over functions"), "{md}");
    for d in ["02", "03"] {
        assert!(out.join(format!("plots/ecdf-d{d}_bbob.png")).is_file());
        assert!(out.join(format!("plots/ecdf-d{d}_bbob.svg")).is_file());
    }
    let info = std::fs::read_to_string(out.join("coco/RS/bbobexp_f1.info")).unwrap();
    let lines: Vec<&str> = info.lines().collect();
    assert_eq!(lines.len(), 6, "two dimensions, three lines each: {info}");
    assert!(
        lines[0].starts_with(
            "suite = 'bbob', funcId = 1, DIM = 2, Precision = 1.000e-08, algId = 'RS'"
        ),
        "{info}"
    );
    // Function 1 in 2-D: the [bbob] objective's 4 trials, then sphere-i7's 4.
    let runs: Vec<&str> = lines[2].split(", ").skip(1).collect();
    let instances: Vec<&str> = runs.iter().map(|r| r.split(':').next().unwrap()).collect();
    assert_eq!(
        instances,
        ["1", "2", "3", "1", "7", "7", "7", "7"],
        "{info}"
    );
    assert!(
        lines[2].starts_with("data_f1/bbobexp_f1_DIM2.dat, 1:120|"),
        "{info}"
    );
    let dat = std::fs::read_to_string(out.join("coco/RS/data_f1/bbobexp_f1_DIM2.dat")).unwrap();
    assert_eq!(dat.matches("% f evaluations").count(), 8);
    assert!(
        out.join("coco/CMA/data_f21/bbobexp_f21_DIM3.tdat")
            .is_file()
    );
    // sphere-i7 is RS's alone: CMA's function 1 in 2-D has the [bbob] objective's runs only.
    let cma = std::fs::read_to_string(out.join("coco/CMA/data_f1/bbobexp_f1_DIM2.dat")).unwrap();
    assert_eq!(cma.matches("% f evaluations").count(), 4);
    assert!(!cma.contains("instance = 7"));
    run_check_script("cocopp_check.py", &[&out]);
    // The check can fail: a run dropped from an .info file is caught (or cocopp is missing).
    let info_path = out.join("coco/CMA/bbobexp_f8.info");
    let info = std::fs::read_to_string(&info_path).unwrap();
    let cut = info.trim_end().rsplit_once(", ").unwrap().0.to_string() + "\n";
    std::fs::write(&info_path, cut).unwrap();
    let check = std::process::Command::new("python3")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scripts/cocopp_check.py"
        ))
        .arg(&out)
        .output();
    if let Ok(check) = check {
        let err = String::from_utf8_lossy(&check.stderr);
        match check.status.code() {
            Some(3) => eprintln!("skipping the failing cocopp check: {err}"),
            code => assert!(
                code == Some(1) && err.contains("CMA f8 3-D: instances [1, 2, 3]"),
                "{code:?} {err}"
            ),
        }
    }
    std::fs::write(&info_path, info).unwrap();

    // Resuming keeps each trial's instance: the same traces.
    ok(&optbench(
        &["run", "tiny.toml", "--out", "r", "--resume", "-q"],
        root.path(),
    ));
    assert_eq!(traces(&out).len(), t.len());
}

#[test]
fn bad_instances_and_budgets_are_refused_with_file_line_and_key() {
    let root = tempfile::tempdir().unwrap();
    let cases: &[(&str, &[&str])] = &[
        (
            "name = \"b\"\nseed = 1\ntrials = 3\nbudget = 10\n[[objective]]\nkind = \"sphere\"\ndim = 2\ninstances = \"1-3\"\n[[optimizer]]\nkind = \"random\"\n",
            &[
                "b.toml:8",
                "instance 2 of sphere without shift or rotate is the same problem",
            ],
        ),
        (
            "name = \"b\"\nseed = 1\ntrials = 3\nbudget = 10\n[[objective]]\nkind = \"bouc-wen\"\nrecording = \"twin:chirp\"\ninstances = \"1-3\"\n[[optimizer]]\nkind = \"random\"\n",
            &["b.toml:8", "takes no `instance`"],
        ),
        (
            "name = \"b\"\nseed = 1\ntrials = 2\nbudget = 10\n[bbob]\ndimensions = [2]\ninstances = \"1-3\"\n[[optimizer]]\nkind = \"random\"\n",
            &["b.toml:3", "lists 3 instances"],
        ),
        (
            "name = \"b\"\nseed = 1\ntrials = 2\nbudget = 10\n[bbob]\ndimensions = [2]\ninstances = \"0-1\"\n[[optimizer]]\nkind = \"random\"\n",
            &["b.toml:7", "[bbob] instances"],
        ),
        (
            "name = \"b\"\nseed = 1\ntrials = 2\nbudget = 10\nbudget_per_dim = 5\n[bbob]\ndimensions = [2]\ninstances = [1]\n[[optimizer]]\nkind = \"random\"\n",
            &["b.toml:4", "both `budget` and `budget_per_dim`"],
        ),
        (
            "name = \"b\"\nseed = 1\ntrials = 2\n[bbob]\ndimensions = [2]\nfunctions = [3]\ninstances = [1]\n[[optimizer]]\nkind = \"random\"\n",
            &["b.toml:", "no budget"],
        ),
        (
            "name = \"b\"\nseed = 1\ntrials = 2\nbudget_per_dim = -4\n[bbob]\ndimensions = [2]\n[[optimizer]]\nkind = \"random\"\n",
            &["b.toml:4", "`budget_per_dim` = -4"],
        ),
    ];
    for (text, needles) in cases {
        std::fs::write(root.path().join("b.toml"), text).unwrap();
        refused(
            &optbench(&["run", "b.toml", "--out", "r", "-q"], root.path()),
            needles,
        );
        assert!(
            !root.path().join("r").exists(),
            "nothing written for {text}"
        );
    }
}

#[test]
fn fewer_trials_than_instances_from_the_command_line_runs_the_first_and_says_so() {
    let root = tempfile::tempdir().unwrap();
    std::fs::write(root.path().join("tiny.toml"), TINY).unwrap();
    let out = optbench(
        &["run", "tiny.toml", "--out", "r", "-q", "--trials", "2"],
        root.path(),
    );
    ok(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--trials 2 runs only the first 2 of the 3 instances"),
        "{err}"
    );
    let ran: std::collections::BTreeSet<(String, u64)> = traces(&root.path().join("r"))
        .iter()
        .filter(|t| t["objective"] != "sphere-i7")
        .map(|t| {
            (
                t["objective"].as_str().unwrap().to_string(),
                t["trial"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        ran.len(),
        6 * 2,
        "two trials of each [bbob] objective: {ran:?}"
    );
}
