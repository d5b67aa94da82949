//! Issue 17, defects 5 to 8, as the release binary sees them: sizes beyond their limits,
//! ordinary values that panicked, absurd or constant recordings and bounds are refused
//! with exit 2, a located message and the limit, before anything large is allocated;
//! nothing non-finite reaches a result.

mod common;

use common::{code_and_stderr, optbench, read_json};
use std::path::Path;

/// A 500-sample recording of a hysteresis-like response; `cell` replaces one output.
fn recording(dir: &Path, name: &str, cell: Option<(usize, &str)>, zero: bool) {
    recording_of(500, dir, name, cell, zero);
}

/// [`recording`] with `n` samples.
fn recording_of(n: usize, dir: &Path, name: &str, cell: Option<(usize, &str)>, zero: bool) {
    let mut s = String::from("t,u,y\n");
    for k in 0..n {
        let t = k as f64 * 1e-3;
        let u = (std::f64::consts::TAU * 10.0 * t).sin();
        let y = match cell {
            Some((at, v)) if at == k => v.to_string(),
            _ if zero => "0".to_string(),
            _ => format!(
                "{}",
                0.8 * u + 0.1 * (std::f64::consts::TAU * 10.0 * t - 0.3).sin()
            ),
        };
        s += &format!("{t},{u},{y}\n");
    }
    std::fs::write(dir.join(name), s).unwrap();
}

/// Exit 2 with every `expected` piece in the message, no panic.
fn refused(args: &[&str], dir: &Path, expected: &[&str]) {
    let (code, err) = code_and_stderr(args, dir);
    assert_eq!(code, Some(2), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    for e in expected {
        assert!(err.contains(e), "{args:?}: expected {e:?} in: {err}");
    }
}

const HEAD: &str = "name = \"big\"\nseed = 1\ntrials = 2\nbudget = 100\n";
const SPHERE: &str = "[[objective]]\nkind = \"sphere\"\ndim = 2\n";

/// Writes `suite` and checks that `run` refuses it with the message pieces.
fn suite_refused(suite: &str, expected: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    recording(dir.path(), "rec.csv", Some((100, "-1e308")), false);
    std::fs::write(dir.path().join("big.toml"), suite).unwrap();
    refused(&["run", "big.toml", "-q"], dir.path(), expected);
    assert!(
        !dir.path().join("results").exists(),
        "nothing may be written"
    );
}

/// Defect 6: every size a suite can set has an upper limit, refused at file:line with it.
#[test]
fn suite_sizes_beyond_their_limits_are_refused_at_their_line() {
    let huge = "9223372036854775807";
    for (optimizer, key, limit) in [
        ("ga", "population", "10000"),
        ("pso", "population", "10000"),
        ("de", "population", "10000"),
        ("cmaes", "lambda", "10000"),
        ("random", "batch", "10000"),
        ("shade", "memory", "10000"),
        ("msga", "objects", "2000"),
    ] {
        suite_refused(
            &format!("{HEAD}{SPHERE}[[optimizer]]\nkind = \"{optimizer}\"\n{key} = {huge}\n"),
            &["big.toml:10:", &format!("`{key}`"), limit],
        );
    }
    for optimizer in ["cmaes", "lbfgs"] {
        suite_refused(
            &format!(
                "{HEAD}[[objective]]\nkind = \"sphere\"\ndim = 100000\n[[optimizer]]\nkind = \"{optimizer}\"\n"
            ),
            &["big.toml:7:", "`dim`", "4000"],
        );
    }
    suite_refused(
        &format!(
            "{HEAD}{SPHERE}[[optimizer]]\nkind = \"shade\"\npopulation = 10000\narchive = 10\n"
        ),
        &["big.toml:11:", "`archive`", "10000"],
    );
    suite_refused(
        &format!(
            "name = \"big\"\nseed = 1\ntrials = 1000000000\nbudget = 100\n{SPHERE}[[optimizer]]\nkind = \"ga\"\n"
        ),
        &["big.toml:3:", "`trials`", "10000"],
    );
    // Each size within its limit, the plan's records together beyond the budget.
    let optimizers = "[[optimizer]]\nkind = \"random\"\n".to_string()
        + &(0..9)
            .map(|i| format!("[[optimizer]]\nkind = \"random\"\nid = \"r{i}\"\n"))
            .collect::<String>();
    suite_refused(
        &format!(
            "name = \"big\"\nseed = 1\ntrials = 10000\nbudget = 100\n[[objective]]\nkind = \"sphere\"\ndim = 4000\n{optimizers}"
        ),
        &["big.toml:3:", "trial records", "1073741824"],
    );
    suite_refused(
        &format!(
            "{HEAD}[[objective]]\nkind = \"rbf\"\nrecording = \"twin:sine:freq=1\"\nduration = 1e6\n[[optimizer]]\nkind = \"ga\"\n"
        ),
        &["big.toml:8:", "`duration`", "10000000"],
    );
    suite_refused(
        &format!(
            "{HEAD}[[objective]]\nkind = \"rbf\"\nrecording = \"twin:sine:freq=1\"\nduration = 1\nhidden = 1000000000\n[[optimizer]]\nkind = \"ga\"\n"
        ),
        &["big.toml:9:", "`hidden`", "4000"],
    );
}

/// Defect 6 on the command line: the flag and the limit in the message.
#[test]
fn flag_sizes_beyond_their_limits_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    recording(d, "r.csv", None, false);
    let fit = ["fit", "--recording", "r.csv", "--optimizer", "random"];
    let with = |extra: &[&'static str]| {
        let mut v: Vec<&str> = fit.to_vec();
        v.extend_from_slice(extra);
        v
    };
    refused(
        &with(&["--model", "rbf", "--param", "hidden=1000000000"]),
        d,
        &["--model rbf", "`hidden`", "4000"],
    );
    refused(
        &with(&[
            "--model",
            "rbf",
            "--param",
            "input_lags=3000",
            "--param",
            "hidden=2",
        ]),
        d,
        &["`hidden`", "parameters", "4000"],
    );
    refused(
        &with(&["--model", "bouc-wen", "--opt", "batch=9223372036854775807"]),
        d,
        &["--optimizer random", "`batch`", "10000"],
    );
    refused(
        &[
            "diagnose",
            "--train",
            "r.csv",
            "--holdout",
            "0.2",
            "--bootstrap",
            "1000000000",
        ],
        d,
        &["--bootstrap 1000000000", "100000"],
    );
    refused(
        &["diagnose", "--proof", "--seeds", "18446744073709551615"],
        d,
        &["--seeds", "10000"],
    );
    refused(
        &[
            "simulate",
            "--signal",
            "sine:freq=1",
            "--duration",
            "1e6",
            "--out",
            "s",
        ],
        d,
        &["--duration", "10000000"],
    );
    refused(
        &["simulate", "--dt", "1e-300", "--out", "s"],
        d,
        &["--dt 1e-300", "10000000"],
    );
    refused(
        &["run", "x.toml", "--trials", "1000000"],
        d,
        &["--trials", "10000"],
    );
    refused(
        &["run", "x.toml", "--threads", "4000000000"],
        d,
        &["--threads", "512"],
    );
    assert!(!d.join("s").exists());
}

/// Defect 7: ordinary values that panicked are refused.
#[test]
fn ordinary_values_do_not_panic() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    recording(d, "r.csv", None, false);
    let fit = [
        "fit",
        "--recording",
        "r.csv",
        "--model",
        "bouc-wen",
        "--optimizer",
        "random",
    ];
    let mut zero = fit.to_vec();
    zero.extend(["--budget", "0"]);
    refused(&zero, d, &["--budget", "0"]);
    for first in ["500", "501"] {
        let p = format!("first={first}");
        let mut past = fit.to_vec();
        past.extend(["--budget", "10", "--param", &p]);
        refused(&past, d, &["`first`", "500"]);
    }
    let deep = format!("{}sine:freq=1{}", "(".repeat(10_000), ")".repeat(10_000));
    let chain = format!("{}sine:freq=1", "2*".repeat(10_000));
    for spec in [&deep, &chain] {
        refused(
            &[
                "simulate",
                "--signal",
                spec,
                "--duration",
                "1",
                "--out",
                "s",
            ],
            d,
            &["nested more than 64 levels"],
        );
    }
    let ok = format!("{}sine:freq=1{}", "(".repeat(60), ")".repeat(60));
    let out = optbench(
        &[
            "simulate",
            "--signal",
            &ok,
            "--duration",
            "0.1",
            "--out",
            "s",
        ],
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Defect 8 and the input side of 5: absurd or constant recordings and bounds are refused
/// where fit, diagnose and suites read them, so nothing non-finite reaches a result.
#[test]
fn absurd_recordings_and_bounds_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    recording(d, "big.csv", Some((100, "-1e308")), false);
    recording(d, "zero.csv", None, true);
    // Long enough for diagnose's hold-out (which ran on it and wrote NaN parameters).
    recording_of(1000, d, "zero1000.csv", None, true);
    let fit = |file: &'static str| {
        [
            "fit",
            "--recording",
            file,
            "--model",
            "bouc-wen",
            "--optimizer",
            "random",
            "--budget",
            "20",
            "--out",
            "o",
        ]
    };
    refused(
        &fit("big.csv"),
        d,
        &["big.csv:102:", "output column 'y'", "1e30"],
    );
    refused(
        &fit("zero.csv"),
        d,
        &["zero.csv", "output column 'y'", "every value is 0"],
    );
    refused(
        &[
            "diagnose",
            "--train",
            "zero1000.csv",
            "--holdout",
            "0.2",
            "--bootstrap",
            "0",
            "--out",
            "o",
        ],
        d,
        &["zero1000.csv", "output column 'y'", "every value is 0"],
    );
    let mut bounds = fit("r.csv").to_vec();
    recording(d, "r.csv", None, false);
    bounds.extend(["--param", "lower=-1e308"]);
    refused(&bounds, d, &["`lower`", "1e30"]);
    assert!(!d.join("o").exists());

    suite_refused(
        &format!(
            "{HEAD}[[objective]]\nkind = \"bouc-wen\"\nrecording = \"rec.csv\"\n[[optimizer]]\nkind = \"random\"\n"
        ),
        &["rec.csv:102:", "output column 'y'", "1e30"],
    );
    for bound in ["1e155", "1e308"] {
        suite_refused(
            &format!(
                "{HEAD}[[objective]]\nkind = \"sphere\"\ndim = 2\nlower = -{bound}\nupper = {bound}\n[[optimizer]]\nkind = \"random\"\n"
            ),
            &["big.toml:8:", "`lower`", "1e30"],
        );
    }
}

/// Defect 8: bounds at the limit give finite results in summary.json (no null).
#[test]
fn results_at_the_largest_bounds_are_finite() {
    let dir = tempfile::tempdir().unwrap();
    let suite = "name = \"edge\"\nseed = 1\ntrials = 2\nbudget = 50\n[[objective]]\nkind = \"rosenbrock\"\ndim = 3\nlower = -1e30\nupper = 1e30\n[[optimizer]]\nkind = \"random\"\nbatch = 10\n";
    std::fs::write(dir.path().join("edge.toml"), suite).unwrap();
    let out = optbench(&["run", "edge.toml", "-q", "--threads", "1"], dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("results/edge/summary.json")).unwrap();
    assert!(!text.contains("null") && !text.contains("NaN"), "{text}");
    let s = read_json(&dir.path().join("results/edge/summary.json"));
    for f in s["results"][0]["finals"].as_array().unwrap() {
        assert!(f.as_f64().unwrap().is_finite());
    }
}
