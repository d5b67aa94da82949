//! Shared helpers for integration tests.
#![allow(dead_code)]

use optbench::objective::functions::{Function, TestFunction};
use optbench::objective::{Bounds, Objective};
use serde_json::Value;
use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Output};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Wraps an objective (a test function by default) and records what the harness cannot
/// fake: every real call on whatever thread, every point outside the box, the threads that
/// evaluated, and the size of every call in call order.
pub struct Probe {
    inner: Arc<dyn Objective>,
    /// Values computed: alone, in batches, with a gradient, or with residuals.
    pub calls: AtomicU64,
    /// Values computed with their gradient.
    pub gradients: AtomicU64,
    pub out_of_bounds: AtomicU64,
    pub threads: Mutex<BTreeSet<String>>,
    /// Evaluations of every call, in call order (`1 + d` for a gradient).
    pub sizes: Mutex<Vec<u64>>,
}

impl Probe {
    pub fn new(kind: TestFunction, dim: usize) -> Self {
        Self::of(Arc::new(Function::standard(kind, dim).unwrap()))
    }

    pub fn of(inner: Arc<dyn Objective>) -> Self {
        Probe {
            inner,
            calls: AtomicU64::new(0),
            gradients: AtomicU64::new(0),
            out_of_bounds: AtomicU64::new(0),
            threads: Mutex::new(BTreeSet::new()),
            sizes: Mutex::new(Vec::new()),
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

    /// Whether evaluation `e` (1-based, in call order) lies inside a call with more points
    /// after it.
    pub fn inside_a_call(&self, e: u64) -> bool {
        let mut end = 0;
        for &n in self.sizes.lock().unwrap().iter() {
            end += n;
            if e <= end {
                return e < end;
            }
        }
        false
    }

    /// Notes one value computed at `x`.
    fn note(&self, x: &[f64]) {
        self.calls.fetch_add(1, Ordering::SeqCst);
        if !self.inner.bounds().contains(x) {
            self.out_of_bounds.fetch_add(1, Ordering::SeqCst);
        }
        let name = std::thread::current()
            .name()
            .unwrap_or("unnamed")
            .to_string();
        self.threads.lock().unwrap().insert(name);
    }

    fn log(&self, n: u64) {
        self.sizes.lock().unwrap().push(n);
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
        self.log(1);
        self.note(x);
        self.inner.evaluate(x)
    }
    fn evaluate_batch(&self, points: &[f64], out: &mut [f64]) {
        self.log(out.len() as u64);
        points.chunks_exact(self.dim()).for_each(|x| self.note(x));
        self.inner.evaluate_batch(points, out);
    }
    fn optimum(&self) -> Option<f64> {
        self.inner.optimum()
    }
    fn penalty_threshold(&self) -> Option<f64> {
        self.inner.penalty_threshold()
    }
    fn value_and_gradient(&self, x: &[f64], grad: &mut [f64]) -> Option<f64> {
        let f = self.inner.value_and_gradient(x, grad)?;
        self.gradients.fetch_add(1, Ordering::SeqCst);
        self.log(1 + self.dim() as u64);
        self.note(x);
        Some(f)
    }
    fn has_gradient(&self) -> bool {
        self.inner.has_gradient()
    }
    fn residuals(&self, x: &[f64], r: &mut Vec<f64>) -> Option<f64> {
        let c = self.inner.residuals(x, r)?;
        self.log(1);
        self.note(x);
        Some(c)
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

/// Asserts that the command succeeded (its exit code and stderr in the message); its stdout.
pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// [`optbench`]'s exit code and standard error.
pub fn code_and_stderr(args: &[&str], cwd: &Path) -> (Option<i32>, String) {
    let o = optbench(args, cwd);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The data set `$OPTBENCH_DATA/name`, or `None` after saying the test is skipped.
pub fn data_set(name: &str) -> Option<std::path::PathBuf> {
    let dir = optbench::data::recording::data_dir().join(name);
    if !dir.is_dir() {
        eprintln!(
            "skipped: {} is absent (set OPTBENCH_DATA to the data folder)",
            dir.display()
        );
        return None;
    }
    Some(dir)
}

/// A JSON file the command wrote.
pub fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// A metric of `fit.json` by name.
pub fn fit_metric(out: &Path, name: &str) -> f64 {
    let j = read_json(&out.join("fit.json"));
    j["metrics"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"] == name)
        .unwrap_or_else(|| panic!("no {name} in {j}"))["value"]
        .as_f64()
        .unwrap()
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

/// Asserts a refusal: exit 2 and every needle in stderr.
pub fn refused(out: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` not in: {err}");
    }
}

/// summary.json with the wall times (the only values that may differ) zeroed.
pub fn summary(dir: &Path) -> Value {
    let mut v: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for c in v["results"].as_array_mut().unwrap() {
        c["wall_s"] = Value::from(0.0);
    }
    v
}

/// traces.jsonl records with wall times zeroed.
pub fn traces(dir: &Path) -> Vec<Value> {
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

/// The figure stems (file names without extension) of a results folder's `plots/` or
/// `figures/`.
fn figure_stems(folder: &Path) -> BTreeSet<String> {
    let mut stems = BTreeSet::new();
    for sub in ["plots", "figures"] {
        let Ok(entries) = std::fs::read_dir(folder.join(sub)) else {
            continue;
        };
        for e in entries {
            let p = e.unwrap().path();
            if matches!(p.extension().and_then(|x| x.to_str()), Some("svg" | "png")) {
                stems.insert(p.file_stem().unwrap().to_string_lossy().into_owned());
            }
        }
    }
    stems
}

/// `report.html` of `folder` is one self-contained, well-formed page: every figure file
/// embedded as a data URI, nothing loaded from elsewhere, one `<table>` per table of
/// `report.md`, and every `<` and `&` of the text escaped.
pub fn assert_html_report(folder: &Path) {
    let html = std::fs::read_to_string(folder.join("report.html")).expect("report.html");
    assert!(html.starts_with("<!DOCTYPE html>") && html.ends_with("</html>\n"));
    for banned in ["<script", "<link", "<iframe", "<object", "<embed"] {
        assert!(!html.contains(banned), "{banned} in report.html");
    }
    for (attr, allowed) in [("src=\"", "data:image/"), ("href=\"", "#")] {
        for (i, _) in html.match_indices(attr) {
            let value = &html[i + attr.len()..];
            assert!(
                value.starts_with(allowed),
                "{attr}{} does not start with {allowed}",
                &value[..value.len().min(60)]
            );
        }
    }
    // Markup, or an escaped character: a raw '<' or '&' of the text would be neither.
    for (i, _) in html.match_indices('<') {
        let next = html[i + 1..].chars().next().unwrap_or(' ');
        assert!(
            next.is_ascii_alphabetic() || next == '/' || next == '!',
            "unescaped '<' in report.html: {}",
            &html[i..(i + 40).min(html.len())]
        );
    }
    for (i, _) in html.match_indices('&') {
        let entity: String = html[i + 1..].chars().take_while(|c| *c != ';').collect();
        assert!(
            entity.len() <= 6
                && (entity.chars().all(|c| c.is_ascii_alphabetic())
                    || entity
                        .strip_prefix('#')
                        .is_some_and(|n| n.parse::<u32>().is_ok())),
            "unescaped '&' in report.html: {}",
            &html[i..(i + 40).min(html.len())]
        );
    }
    for tag in ["table", "tr", "figure", "section", "ul", "p"] {
        assert_eq!(
            html.matches(&format!("<{tag}>")).count() + html.matches(&format!("<{tag} ")).count(),
            html.matches(&format!("</{tag}>")).count(),
            "<{tag}> opened and closed as often"
        );
    }
    let stems = figure_stems(folder);
    assert_eq!(
        html.matches("<figure ").count(),
        stems.len(),
        "one figure per file"
    );
    for s in &stems {
        assert!(html.contains(&format!(
            "<figure id=\"fig-{s}\"><img alt=\"{s}\" src=\"data:image/"
        )));
    }
    // One <table> per table of report.md (a delimiter row opens each).
    let md = std::fs::read_to_string(folder.join("report.md")).unwrap();
    let md_tables = md
        .lines()
        .filter(|l| l.starts_with("| -") || l.starts_with("| :"))
        .count();
    assert!(md_tables > 0);
    // The page adds the provenance table.
    assert_eq!(html.matches("<table>").count(), md_tables + 1);
    assert!(html.contains("<h2>Statistics explained</h2>") && html.contains("Provenance"));
}

/// Runs `python3 scripts/NAME ARGS` from the crate root when python3 is there. Exit 3
/// means a tool the script needs is missing: said on stderr and skipped.
pub fn run_check_script(name: &str, args: &[&Path]) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scripts")
        .join(name);
    let Ok(out) = Command::new("python3").arg(&script).args(args).output() else {
        eprintln!("skipping {name}: python3 not found");
        return;
    };
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    match out.status.code() {
        Some(0) => {}
        Some(3) => eprintln!("skipping {name}: {}", text.trim()),
        _ => panic!("{name} failed on {args:?}:\n{text}"),
    }
}

/// Every output check of a results folder: the page here, then the Markdown (GFM
/// renderer), LaTeX (pdflatex) and browser (Chromium) checks of scripts/ where their tools
/// are installed.
pub fn check_report_outputs(folder: &Path) {
    assert_html_report(folder);
    run_check_script("check_markdown.py", &[folder]);
    run_check_script("check_latex.py", &[folder]);
    run_check_script("check_html.py", &[folder]);
}
