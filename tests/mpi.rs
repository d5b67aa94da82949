//! `mpirun -np N optbench run SUITE` writes the same results as one process (feature `mpi`;
//! needs Open MPI's `mpirun`; `.ci/run` installs it and runs this file).
#![cfg(feature = "mpi")]

use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_optbench");

fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "exit {:?}: {}{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn mpirun(np: usize, args: &[&str], cwd: &Path) -> Output {
    Command::new("mpirun")
        .args([
            "--allow-run-as-root",
            "--oversubscribe",
            "-np",
            &np.to_string(),
            BIN,
        ])
        .args(args)
        .current_dir(cwd)
        // Containers often forbid the cross-memory attach of Open MPI's shared-memory path.
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        .output()
        .expect("mpirun (install openmpi-bin)")
}

fn single(args: &[&str], cwd: &Path) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap()
}

fn summary(dir: &Path) -> Value {
    let mut v: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for c in v["results"].as_array_mut().unwrap() {
        c["wall_s"] = Value::from(0.0);
    }
    v
}

fn traces(dir: &Path) -> Vec<Value> {
    std::fs::read_to_string(dir.join("traces.jsonl"))
        .unwrap()
        .lines()
        .map(|l| {
            let mut v: Value = serde_json::from_str(l).unwrap();
            v["wall_s"] = Value::from(0.0);
            v
        })
        .collect()
}

const SUITE: &str = r#"name = "ranks"
seed = 21
trials = 6
budget = 3000

[[objective]]
kind = "griewank"
dim = 10

[[objective]]
kind = "sphere"
dim = 4
stop_at = 1e-6

[[optimizer]]
kind = "pso"
population = 30

[[optimizer]]
kind = "msga"
objects = 10

[[optimizer]]
kind = "cmaes"
"#;

#[test]
fn ranks_write_what_one_process_writes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SUITE).unwrap();
    ok(&single(&["run", "s.toml", "--out", "one", "-q"], d));
    let out = mpirun(2, &["run", "s.toml", "--out", "two"], d);
    ok(&out);
    // Only rank 0 prints (the table once) and writes.
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(text.matches("results and report:").count(), 1, "{text}");
    assert!(text.contains("2 threads"), "{text}");
    assert_eq!(summary(&d.join("two")), summary(&d.join("one")));
    assert_eq!(traces(&d.join("two")), traces(&d.join("one")));

    // Resume under MPI (3 ranks) from a log cut after 5 trials.
    let log = std::fs::read_to_string(d.join("one/progress.jsonl")).unwrap();
    std::fs::create_dir(d.join("cut")).unwrap();
    let kept: Vec<&str> = log.lines().take(1 + 5).collect();
    std::fs::write(d.join("cut/progress.jsonl"), kept.join("\n") + "\n").unwrap();
    ok(&mpirun(
        3,
        &["run", "s.toml", "--out", "cut", "-q", "--resume"],
        d,
    ));
    assert_eq!(summary(&d.join("cut")), summary(&d.join("one")));
    assert_eq!(traces(&d.join("cut")), traces(&d.join("one")));
}
