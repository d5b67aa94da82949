//! Resume after a kill, shards and merge: the binary is killed mid-suite (SIGKILL), resumed,
//! and its summary compared with an uninterrupted run's; shards of several sizes merged
//! and compared the same way.

mod common;

use common::{ok, optbench, refused, summary, traces};
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_optbench");

fn progress_lines(dir: &Path) -> usize {
    std::fs::read_to_string(dir.join("progress.jsonl"))
        .map(|t| t.lines().count())
        .unwrap_or(0)
}

/// 36 trials of some tens of milliseconds each.
const SUITE: &str = r#"name = "killme"
seed = 5
trials = 12
budget = 20000

[[objective]]
kind = "griewank"
dim = 30

[[optimizer]]
kind = "pso"
population = 50

[[optimizer]]
kind = "de"
population = 40

[[optimizer]]
kind = "cmaes"
"#;

#[test]
fn a_run_killed_mid_suite_resumes_to_the_uninterrupted_summary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SUITE).unwrap();
    ok(&optbench(
        &["run", "s.toml", "--out", "full", "-q", "--threads", "2"],
        d,
    ));
    assert_eq!(progress_lines(&d.join("full")), 1 + 36);

    // Kill (SIGKILL) once a few trials are stored.
    let mut child = Command::new(BIN)
        .args(["run", "s.toml", "--out", "cut", "-q", "--threads", "2"])
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while progress_lines(&d.join("cut")) < 1 + 4 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before it could be killed"
        );
        assert!(
            started.elapsed() < Duration::from_secs(600),
            "no progress stored"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap(); // SIGKILL on Unix
    child.wait().unwrap();
    let stored = progress_lines(&d.join("cut")) - 1;
    assert!(
        (4..36).contains(&stored),
        "killed mid-suite: {stored} trials stored"
    );
    assert!(!d.join("cut/summary.json").exists());

    // A plain run refuses to throw the finished trials away.
    refused(
        &optbench(&["run", "s.toml", "--out", "cut", "-q"], d),
        &["interrupted run", "--resume"],
    );

    // Simulate a kill in the middle of a write as well: a torn last line.
    let mut log = std::fs::OpenOptions::new()
        .append(true)
        .open(d.join("cut/progress.jsonl"))
        .unwrap();
    std::io::Write::write_all(&mut log, b"{\"key\":\"0123\",\"record\":{\"obj").unwrap();
    drop(log);

    // Killed again while resuming, at a later point (or let finish, if it is quicker).
    let mut child = Command::new(BIN)
        .args([
            "run",
            "s.toml",
            "--out",
            "cut",
            "-q",
            "--resume",
            "--threads",
            "2",
        ])
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while progress_lines(&d.join("cut")) < 1 + 20 && child.try_wait().unwrap().is_none() {
        assert!(
            started.elapsed() < Duration::from_secs(600),
            "no progress stored"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = child.kill();
    child.wait().unwrap();

    ok(&optbench(
        &[
            "run",
            "s.toml",
            "--out",
            "cut",
            "-q",
            "--resume",
            "--threads",
            "1",
        ],
        d,
    ));
    assert_eq!(summary(&d.join("cut")), summary(&d.join("full")));
    assert_eq!(traces(&d.join("cut")), traces(&d.join("full")));
    assert_eq!(progress_lines(&d.join("cut")), 1 + 36, "no duplicate lines");

    // Resuming a finished run reruns nothing and changes nothing.
    ok(&optbench(
        &["run", "s.toml", "--out", "cut", "-q", "--resume"],
        d,
    ));
    assert_eq!(summary(&d.join("cut")), summary(&d.join("full")));
}

#[test]
fn a_changed_suite_refuses_to_resume_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SUITE).unwrap();
    ok(&optbench(
        &["run", "s.toml", "--out", "r", "-q", "--budget", "2000"],
        d,
    ));
    // Another budget on the command line is another run.
    refused(
        &optbench(&["run", "s.toml", "--out", "r", "-q", "--resume"], d),
        &["cannot resume", "seed/trials/budget", "--force-resume"],
    );
    // An edited suite: DE's population changes, the rest does not.
    let changed = SUITE.replace("population = 40", "population = 30");
    std::fs::write(d.join("s.toml"), &changed).unwrap();
    refused(
        &optbench(
            &[
                "run", "s.toml", "--out", "r", "-q", "--resume", "--budget", "2000",
            ],
            d,
        ),
        &[
            "cannot resume",
            "the suite file has changed",
            "--force-resume",
        ],
    );
    let before = traces(&d.join("r"));
    ok(&optbench(
        &[
            "run",
            "s.toml",
            "--out",
            "r",
            "-q",
            "--force-resume",
            "--budget",
            "2000",
        ],
        d,
    ));
    // Kept: PSO and CMA-ES trials (same records); rerun: DE's; the result is the changed
    // suite's uninterrupted run.
    ok(&optbench(
        &["run", "s.toml", "--out", "fresh", "-q", "--budget", "2000"],
        d,
    ));
    assert_eq!(summary(&d.join("r")), summary(&d.join("fresh")));
    let after = traces(&d.join("r"));
    let same = |name: &str| {
        let pick = |v: &[Value]| -> Vec<Value> {
            v.iter()
                .filter(|r| r["optimizer"] == name)
                .cloned()
                .collect()
        };
        pick(&before) == pick(&after)
    };
    assert!(same("pso") && same("cmaes") && !same("de"));
}

/// A quick suite with two objectives (one stopping at a target) for the shard tests.
const SMALL: &str = r#"name = "shardme"
seed = 9
trials = 5
budget = 1500

[[objective]]
kind = "rastrigin"
dim = 4

[[objective]]
kind = "sphere"
dim = 3
stop_at = 1e-6

[[optimizer]]
kind = "ga"
population = 30

[[optimizer]]
kind = "shade"
population = 20

[[optimizer]]
kind = "msga"
objects = 10
"#;

#[test]
fn shards_merge_to_the_single_run_for_several_n() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SMALL).unwrap();
    ok(&optbench(&["run", "s.toml", "--out", "single", "-q"], d));
    let single = summary(&d.join("single"));
    for n in [1usize, 2, 3, 7, 30] {
        let mut dirs = Vec::new();
        for k in 1..=n {
            let out = format!("n{n}/k{k}");
            ok(&optbench(
                &[
                    "run",
                    "s.toml",
                    "--shard",
                    &format!("{k}/{n}"),
                    "--out",
                    &out,
                    "-q",
                    "--threads",
                    "1",
                ],
                d,
            ));
            assert!(
                !d.join(&out).join("summary.json").exists(),
                "a shard writes no partial summary"
            );
            dirs.push(out);
        }
        let merged = format!("n{n}/merged");
        let mut args = vec!["merge"];
        args.extend(dirs.iter().map(String::as_str));
        args.extend(["--out", &merged, "-q"]);
        ok(&optbench(&args, d));
        assert_eq!(summary(&d.join(&merged)), single, "n = {n}");
        assert_eq!(
            traces(&d.join(&merged)),
            traces(&d.join("single")),
            "n = {n}"
        );
        assert!(d.join(&merged).join("report.md").exists());
    }
    // A missing shard is named, and nothing is written.
    let out = optbench(&["merge", "n3/k1", "n3/k3", "--out", "partial"], d);
    refused(
        &out,
        &["merge:", "of 30 planned trials are missing", "1/3, 3/3"],
    );
    assert!(!d.join("partial").exists());
}

#[test]
fn merge_refuses_shards_of_different_runs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SMALL).unwrap();
    ok(&optbench(
        &["run", "s.toml", "--shard", "1/2", "--out", "a", "-q"],
        d,
    ));
    ok(&optbench(
        &[
            "run", "s.toml", "--shard", "2/2", "--out", "b", "-q", "--seed", "10",
        ],
        d,
    ));
    refused(
        &optbench(&["merge", "a", "b", "--out", "m"], d),
        &[
            "b: suite `shardme` (seed 10",
            "only shards of the same suite",
        ],
    );
    refused(
        &optbench(&["merge", "a", "nowhere", "--out", "m"], d),
        &["nowhere: no progress.jsonl"],
    );
    refused(
        &optbench(&["run", "s.toml", "--shard", "3/2"], d),
        &["expected K/N with 1 <= K <= N"],
    );
    assert!(!d.join("m").exists());
}
