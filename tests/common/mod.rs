//! Shared helpers for integration tests.
#![allow(dead_code)]

use optbench::objective::functions::{Function, TestFunction};
use optbench::objective::{Bounds, Objective};
use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Output};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Wraps a test function and records what the harness cannot fake: every real call, every
/// point outside the box, and the threads that evaluated.
pub struct Probe {
    inner: Function,
    /// Values computed (alone or with a gradient).
    pub calls: AtomicU64,
    /// Values computed with their gradient.
    pub gradients: AtomicU64,
    pub out_of_bounds: AtomicU64,
    pub threads: Mutex<BTreeSet<String>>,
}

impl Probe {
    pub fn new(kind: TestFunction, dim: usize) -> Self {
        Probe {
            inner: Function::standard(kind, dim).unwrap(),
            calls: AtomicU64::new(0),
            gradients: AtomicU64::new(0),
            out_of_bounds: AtomicU64::new(0),
            threads: Mutex::new(BTreeSet::new()),
        }
    }

    pub fn calls(&self) -> u64 {
        self.calls.load(Ordering::SeqCst)
    }

    /// The real calls in evaluations: one per value, and `d` more per gradient (the harness
    /// charges a value with its gradient `1 + d`).
    pub fn cost(&self) -> u64 {
        self.calls() + self.dim() as u64 * self.gradients.load(Ordering::SeqCst)
    }
}

impl Objective for Probe {
    fn name(&self) -> &str {
        "probe"
    }
    fn bounds(&self) -> &Bounds {
        self.inner.bounds()
    }
    fn evaluate(&self, x: &[f64]) -> f64 {
        self.calls.fetch_add(1, Ordering::SeqCst);
        if !self.inner.bounds().contains(x) {
            self.out_of_bounds.fetch_add(1, Ordering::SeqCst);
        }
        let name = std::thread::current()
            .name()
            .unwrap_or("unnamed")
            .to_string();
        self.threads.lock().unwrap().insert(name);
        self.inner.evaluate(x)
    }
    fn optimum(&self) -> Option<f64> {
        self.inner.optimum()
    }
    fn value_and_gradient(&self, x: &[f64], grad: &mut [f64]) -> Option<f64> {
        self.gradients.fetch_add(1, Ordering::SeqCst);
        let f = self.evaluate(x);
        self.inner.value_and_gradient(x, grad)?;
        Some(f)
    }
    fn has_gradient(&self) -> bool {
        true
    }
}

/// A trial record with its wall time removed, for equality checks.
pub fn without_time(mut r: optbench::harness::TrialRecord) -> optbench::harness::TrialRecord {
    r.wall_s = 0.0;
    r
}

/// Runs the `optbench` binary with `args` in `cwd`.
pub fn optbench(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_optbench"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("run optbench")
}

/// [`optbench`]'s exit code and standard error.
pub fn code_and_stderr(args: &[&str], cwd: &Path) -> (Option<i32>, String) {
    let o = optbench(args, cwd);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A JSON file the command wrote.
pub fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// `rec` written as lab software does: `;`-separated with decimal commas, time from `t0`
/// printed with 9 decimals and off the grid by up to `jitter` s; `skip` leaves a sample
/// out (a gap).
pub fn lab_csv(
    rec: &optbench::data::recording::Recording,
    path: &Path,
    t0: f64,
    jitter: f64,
    skip: Option<usize>,
) {
    let comma = |v: f64| v.to_string().replace('.', ",");
    let mut s = String::from("t_s;u_V;y_mm\n");
    for k in (0..rec.len()).filter(|k| Some(*k) != skip) {
        let t = t0 + rec.t[k] + jitter * (0.7 * k as f64).sin();
        s += &format!(
            "{};{};{}\n",
            format!("{t:.9}").replace('.', ","),
            comma(rec.u[k]),
            comma(rec.y[k])
        );
    }
    std::fs::write(path, s).unwrap();
}

/// `optbench run suites/<name>.toml` at small size into `<tempdir>/r`, which must succeed.
pub fn run_shipped_suite(name: &str, trials: &str, budget: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let suite = format!("{}/suites/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    let out = optbench(
        &[
            "run", &suite, "--trials", trials, "--budget", budget, "--out", "r", "-q",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}
