//! Runs of an optimizer outside optbench (`pipeline::external`): a random search written
//! here drives a suite's plan through `ExternalRun`, its folder is reported by the binary
//! and merged with a built-in run; budgets are counted exactly (one point at a time or in
//! batches, the same trace), an interrupted run resumes to the uninterrupted one, the same
//! seeds give the same results, and bad calls, suites and merges are refused.

mod common;

use common::{ok, optbench, refused, summary, traces};
use optbench::pipeline::external::{EvalError, ExternalOptions, ExternalRun, ExternalTrial};
use optbench::pipeline::run::Overrides;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;
use std::path::Path;

/// Two objectives (one with a stop level) x 4 trials; built-in PSO and random search.
const SUITE: &str = r#"name = "ext"
seed = 11
trials = 4
budget = 300
targets = [1e-1]

[[objective]]
kind = "sphere"
dim = 3

[[objective]]
kind = "griewank"
id = "griewank-2d"
dim = 2
budget = 250
stop_at = 1e-2

[[optimizer]]
kind = "pso"
id = "PSO"
population = 10

[[optimizer]]
kind = "random"
id = "Random"
batch = 10
"#;

/// How the random search asks for its points.
#[derive(Clone, Copy)]
enum Ask {
    /// One `evaluate` per point.
    Loop,
    /// `evaluate_many` of this many points.
    Batch(usize),
}

/// A uniform point in the trial's box from `rng`.
fn point(t: &ExternalTrial, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let i = t.info();
    i.lower
        .iter()
        .zip(&i.upper)
        .map(|(&l, &u)| l + (u - l) * rng.random::<f64>())
        .collect()
}

/// Random search on one trial, seeded from the trial's seed, until the evaluator says the
/// trial is over. Returns the evaluations it was answered.
fn search(t: &mut ExternalTrial, ask: Ask) -> u64 {
    let mut rng = ChaCha8Rng::seed_from_u64(t.info().seed);
    let mut answered = 0u64;
    loop {
        match ask {
            Ask::Loop => {
                let x = point(t, &mut rng);
                match t.evaluate(&x) {
                    Ok(v) => {
                        assert!(v.is_finite());
                        answered += 1;
                    }
                    Err(EvalError::Exhausted { .. }) => return answered,
                    Err(e) => panic!("{e}"),
                }
            }
            Ask::Batch(k) => {
                let xs: Vec<Vec<f64>> = (0..k).map(|_| point(t, &mut rng)).collect();
                match t.evaluate_many(&xs) {
                    Ok(v) => {
                        answered += v.len() as u64;
                        if v.len() < k {
                            return answered;
                        }
                    }
                    Err(EvalError::Exhausted { .. }) => return answered,
                    Err(e) => panic!("{e}"),
                }
            }
        }
    }
}

/// Options that write the report at close.
fn reported() -> ExternalOptions {
    ExternalOptions {
        report: Some(optbench::report::generate),
        ..ExternalOptions::default()
    }
}

/// Opens an external run of `id` on the suite in `d` into `d/out`, runs every pending
/// trial with `ask` and closes it.
fn external(d: &Path, id: &str, out: &str, ask: Ask, opts: ExternalOptions) -> ExternalRun {
    let mut run = ExternalRun::open(&d.join("s.toml"), id, Some(&d.join(out)), opts).unwrap();
    for i in run.pending() {
        let mut t = run.start(i).unwrap();
        let answered = search(&mut t, ask);
        assert_eq!(answered, t.evaluations(), "every answer counted once");
        run.finish(t).unwrap();
    }
    let closed = run.close(false).unwrap();
    assert_eq!(closed.finished, closed.planned);
    run
}

/// The results of `optimizer` in a summary (wall times zeroed).
fn cells(summary: &Value, optimizer: &str) -> Vec<Value> {
    summary["results"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["optimizer"] == optimizer)
        .cloned()
        .collect()
}

#[test]
fn an_external_run_is_reported_and_merged_beside_a_built_in_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SUITE).unwrap();
    external(d, "my-rs", "ext", Ask::Loop, reported());
    let ext = d.join("ext");
    for f in [
        "suite.toml",
        "provenance.json",
        "traces.jsonl",
        "summary.json",
    ] {
        assert!(ext.join(f).is_file(), "{f}");
    }
    let report_md = std::fs::read_to_string(ext.join("report.md")).unwrap();
    assert!(report_md.contains("my-rs"), "{report_md}");
    // The binary rebuilds the report from the folder alone, byte for byte.
    ok(&optbench(&["report", "ext"], d));
    assert_eq!(
        std::fs::read_to_string(ext.join("report.md")).unwrap(),
        report_md
    );
    let s = summary(&ext);
    let mine = cells(&s, "my-rs");
    assert_eq!(mine.len(), 2, "one cell per objective");
    // Budgets: every trial spent its budget, or stopped at griewank's stop level.
    for t in traces(&ext) {
        let (used, budget) = (t["evaluations"].as_u64().unwrap(), t["budget"].as_u64());
        assert!(Some(used) <= budget, "{t}");
        if t["stopped_at_target"] == false {
            assert_eq!(Some(used), budget, "{t}");
        }
    }

    // The built-in run of the same suite, and the two merged.
    ok(&optbench(&["run", "s.toml", "--out", "builtin", "-q"], d));
    let text = ok(&optbench(&["merge", "builtin", "ext", "--out", "both"], d));
    assert!(text.contains("of optimizers PSO, Random, my-rs"), "{text}");
    let both = d.join("both");
    let merged = summary(&both);
    for (folder, id) in [("builtin", "PSO"), ("builtin", "Random"), ("ext", "my-rs")] {
        assert_eq!(
            cells(&merged, id),
            cells(&summary(&d.join(folder)), id),
            "{id}"
        );
    }
    let merged_md = std::fs::read_to_string(both.join("report.md")).unwrap();
    for id in ["PSO", "Random", "my-rs"] {
        assert!(merged_md.contains(id), "{id} not in the merged report");
    }
    // The merged folder is a folder like any: reported again byte for byte.
    ok(&optbench(&["report", "both"], d));
    assert_eq!(
        std::fs::read_to_string(both.join("report.md")).unwrap(),
        merged_md
    );
    let provenance = common::read_json(&both.join("provenance.json"));
    assert_eq!(provenance["parts"].as_array().map(Vec::len), Some(2));
    // Merging in the other order names the same cells; the built-in run's shards merge
    // with the external run in one call, to the same folder.
    ok(&optbench(
        &["merge", "ext", "builtin", "--out", "both2", "-q"],
        d,
    ));
    for id in ["PSO", "Random", "my-rs"] {
        assert_eq!(cells(&summary(&d.join("both2")), id), cells(&merged, id));
    }
    for k in ["1/2", "2/2"] {
        let out = format!("shard{}", &k[..1]);
        ok(&optbench(
            &["run", "s.toml", "--shard", k, "--out", &out, "-q"],
            d,
        ));
    }
    ok(&optbench(
        &["merge", "shard1", "ext", "shard2", "--out", "both3", "-q"],
        d,
    ));
    assert_eq!(summary(&d.join("both3")), merged);
    assert_eq!(traces(&d.join("both3")), traces(&both));
}

#[test]
fn budgets_are_exact_and_batches_leave_the_trace_of_a_loop() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SUITE).unwrap();
    external(d, "rs", "loop", Ask::Loop, ExternalOptions::default());
    for k in [7, 300] {
        let out = format!("batch{k}");
        external(d, "rs", &out, Ask::Batch(k), ExternalOptions::default());
        assert_eq!(traces(&d.join(&out)), traces(&d.join("loop")), "batch {k}");
        assert_eq!(
            summary(&d.join(&out)),
            summary(&d.join("loop")),
            "batch {k}"
        );
    }

    // One trial by hand: the budget (300) is never exceeded, a batch across it is cut.
    let mut run = ExternalRun::open(
        &d.join("s.toml"),
        "hand",
        Some(&d.join("hand")),
        ExternalOptions::default(),
    )
    .unwrap();
    let mut t = run.start(0).unwrap();
    assert_eq!((t.info().budget, t.dim()), (300, 3));
    let x = vec![0.5; 3];
    for _ in 0..290 {
        t.evaluate(&x).unwrap();
    }
    assert_eq!((t.evaluations(), t.remaining()), (290, 10));
    let values = t.evaluate_many(&vec![x.clone(); 25]).unwrap();
    assert_eq!(values, vec![0.75; 10]);
    assert_eq!(t.evaluations(), 300);
    assert!(t.done());
    match t.evaluate(&x) {
        Err(EvalError::Exhausted {
            evaluations: 300,
            budget: 300,
            reached_target: false,
        }) => {}
        other => panic!("past the budget: {other:?}"),
    }
    assert!(matches!(
        t.evaluate_many(std::slice::from_ref(&x)),
        Err(EvalError::Exhausted { .. })
    ));
    assert_eq!(t.evaluations(), 300, "a refused evaluation is not counted");
    run.finish(t).unwrap();

    // The stop level: griewank's minimum is 0 at the origin, stop_at 1e-2; a batch stops at
    // the hit and the rest of it is neither evaluated nor counted.
    let i = run
        .trials()
        .iter()
        .position(|t| t.objective == "griewank-2d")
        .unwrap();
    let mut t = run.start(i).unwrap();
    assert_eq!(t.info().stop_value, Some(1e-2));
    assert_eq!(t.info().optimum, Some(0.0));
    let far = vec![100.0, -50.0];
    let batch = vec![far.clone(), far.clone(), vec![0.0, 0.0], far.clone(), far];
    let values = t.evaluate_many(&batch).unwrap();
    assert_eq!(values.len(), 3);
    assert_eq!(values[2], 0.0);
    assert_eq!(t.evaluations(), 3);
    match t.evaluate(&[1.0, 1.0]) {
        Err(
            e @ EvalError::Exhausted {
                reached_target: true,
                ..
            },
        ) => assert!(e.to_string().contains("stop value"), "{e}"),
        other => panic!("after the stop value: {other:?}"),
    }
    run.finish(t).unwrap();
    let closed = run.close(true).unwrap();
    assert_eq!((closed.finished, closed.planned), (2, 8));
    let hand = traces(&d.join("hand"));
    assert_eq!(hand.len(), 2);
    assert_eq!(hand[0]["evaluations"], 300);
    assert_eq!(hand[1]["evaluations"], 3);
    assert_eq!(hand[1]["stopped_at_target"], true);
    let provenance = common::read_json(&d.join("hand/provenance.json"));
    assert_eq!(provenance["extra"]["partial"], "2 of 8 trials finished");
}

#[test]
fn an_interrupted_run_resumes_to_the_uninterrupted_one_and_seeds_repeat() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SUITE).unwrap();
    external(d, "rs", "full", Ask::Loop, ExternalOptions::default());
    external(d, "rs", "again", Ask::Batch(13), ExternalOptions::default());
    assert_eq!(traces(&d.join("again")), traces(&d.join("full")));
    assert_eq!(summary(&d.join("again")), summary(&d.join("full")));
    assert_eq!(
        std::fs::read(d.join("again/suite.toml")).unwrap(),
        std::fs::read(d.join("full/suite.toml")).unwrap()
    );

    // Three trials finished, a fourth started, then the process "dies" (nothing closed).
    let suite = d.join("s.toml");
    let cut = d.join("cut");
    let first_infos = {
        let mut run =
            ExternalRun::open(&suite, "rs", Some(&cut), ExternalOptions::default()).unwrap();
        let infos = run.trials();
        for i in [0, 5, 2] {
            let mut t = run.start(i).unwrap();
            search(&mut t, Ask::Loop);
            run.finish(t).unwrap();
        }
        let mut t = run.start(3).unwrap();
        t.evaluate(&[0.1, 0.2, 0.3]).unwrap();
        infos
    };
    // Seeds: fixed per trial, distinct between trials.
    let seeds: std::collections::BTreeSet<u64> = first_infos.iter().map(|i| i.seed).collect();
    assert_eq!(seeds.len(), first_infos.len());

    // Opening it afresh is refused; resuming keeps the three.
    let again = ExternalRun::open(&suite, "rs", Some(&cut), ExternalOptions::default());
    let msg = again.err().expect("an interrupted folder").to_string();
    assert!(msg.contains("pass --resume"), "{msg}");
    let mut run = ExternalRun::open(
        &suite,
        "rs",
        Some(&cut),
        ExternalOptions {
            resume: true,
            ..ExternalOptions::default()
        },
    )
    .unwrap();
    assert_eq!(run.resumed(), 3);
    assert_eq!(run.pending(), vec![1, 3, 4, 6, 7]);
    let infos = run.trials();
    for (a, b) in infos.iter().zip(&first_infos) {
        assert_eq!(a.seed, b.seed);
        assert_eq!(a.finished, [0, 2, 5].contains(&a.index));
    }
    let refused_start = run.start(5).err().expect("a finished trial");
    assert!(refused_start.to_string().contains("finished already"));
    for i in run.pending() {
        let mut t = run.start(i).unwrap();
        search(&mut t, Ask::Loop);
        run.finish(t).unwrap();
    }
    let closed = run.close(false).unwrap();
    assert!(closed.text.contains("3 trials resumed"), "{}", closed.text);
    assert_eq!(traces(&cut), traces(&d.join("full")));
    assert_eq!(summary(&cut), summary(&d.join("full")));
}

#[test]
fn bad_calls_suites_and_merges_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SUITE).unwrap();
    let suite = d.join("s.toml");
    let open = |id: &str, out: &str, o: ExternalOptions| {
        ExternalRun::open(&suite, id, Some(&d.join(out)), o)
    };
    let err = open("a/b", "x", ExternalOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("optimizer id \"a/b\""), "{err}");

    let mut run = open("rs", "bad", ExternalOptions::default()).unwrap();
    let err = run.start(8).err().unwrap().to_string();
    assert!(err.contains("the plan has 8 trials (0 to 7)"), "{err}");
    let mut t = run.start(0).unwrap();
    match t.evaluate(&[1.0, 2.0]) {
        Err(EvalError::Shape(m)) => assert!(m.contains("has 3 coordinates, got 2"), "{m}"),
        other => panic!("a 2-D point on a 3-D objective: {other:?}"),
    }
    match t.evaluate_many(&[vec![0.0; 3], vec![0.0; 4]]) {
        Err(EvalError::Shape(m)) => assert!(m.contains("point 1 of the batch has 4"), "{m}"),
        other => panic!("a ragged batch: {other:?}"),
    }
    // A coordinate that is not a number is refused, in a batch too; outside the box is
    // evaluated (sphere is defined everywhere).
    match t.evaluate(&[f64::NAN, 0.0, 0.0]) {
        Err(EvalError::NotFinite(m)) => {
            assert!(m.contains("coordinate 0 of point 0 is NaN"), "{m}")
        }
        other => panic!("a NaN coordinate: {other:?}"),
    }
    match t.evaluate_many(&[vec![0.0; 3], vec![0.0, f64::INFINITY, 0.0]]) {
        Err(EvalError::NotFinite(m)) => {
            assert!(m.contains("coordinate 1 of point 1 is inf"), "{m}")
        }
        other => panic!("an infinite coordinate: {other:?}"),
    }
    assert_eq!(t.evaluations(), 0, "refused points are not counted");
    assert_eq!(t.evaluate(&[10.0, 0.0, 0.0]).unwrap(), 100.0);
    let t2 = run.start(1).unwrap();
    let err = run.finish(t2).err().unwrap().to_string();
    assert!(err.contains("has no evaluation"), "{err}");
    run.finish(t).unwrap();
    let err = run.close(false).err().unwrap().to_string();
    assert!(err.contains("7 of 8 trials are unfinished"), "{err}");
    run.close(true).unwrap();
    let err = run.start(1).err().unwrap().to_string();
    assert!(err.contains("the run is closed"), "{err}");
    drop(run);

    // `optbench run` cannot drive an external optimizer and says how to run it.
    let with_external = SUITE.replace(
        "[[optimizer]]\nkind = \"random\"",
        "[[optimizer]]\nkind = \"external\"\nid = \"mine\"\ndescription = \"my PSO\"\n\n[[optimizer]]\nkind = \"random\"",
    );
    std::fs::write(d.join("e.toml"), &with_external).unwrap();
    refused(
        &optbench(&["run", "e.toml", "--out", "e"], d),
        &[
            "e.toml",
            "`mine`",
            "kind `external`",
            "optbench.Experiment",
        ],
    );
    assert!(!d.join("e").exists());
    // ... while an external run of it takes the entry's description.
    let run = ExternalRun::open(
        &d.join("e.toml"),
        "mine",
        Some(&d.join("mine")),
        ExternalOptions::default(),
    )
    .unwrap();
    assert!(run.suite().text.contains("description = \"my PSO\""));
    drop(run);

    // Merges of runs that did not run the same trials name the field and the folders.
    ok(&optbench(&["run", "s.toml", "--out", "builtin", "-q"], d));
    let with = |o: Overrides| ExternalOptions {
        overrides: o,
        ..ExternalOptions::default()
    };
    external(
        d,
        "rs",
        "seed12",
        Ask::Loop,
        with(Overrides {
            seed: Some(12),
            ..Overrides::default()
        }),
    );
    refused(
        &optbench(&["merge", "builtin", "seed12", "--out", "m"], d),
        &["seed differs between the folders: 11 in builtin, 12 in seed12"],
    );
    external(
        d,
        "rs",
        "budget",
        Ask::Loop,
        with(Overrides {
            budget: Some(200),
            ..Overrides::default()
        }),
    );
    refused(
        &optbench(&["merge", "builtin", "budget", "--out", "m"], d),
        &[
            "objective `sphere-3d`: budget differs between the folders: 300 in builtin, 200 in budget",
        ],
    );
    external(
        d,
        "rs",
        "trials",
        Ask::Loop,
        with(Overrides {
            trials: Some(3),
            ..Overrides::default()
        }),
    );
    refused(
        &optbench(&["merge", "builtin", "trials", "--out", "m"], d),
        &["trials differs between the folders: 4 in builtin, 3 in trials"],
    );
    let other = SUITE.replace("kind = \"sphere\"\ndim = 3", "kind = \"sphere\"\ndim = 4");
    std::fs::write(d.join("o.toml"), other).unwrap();
    let mut run = ExternalRun::open(
        &d.join("o.toml"),
        "rs",
        Some(&d.join("dim4")),
        ExternalOptions::default(),
    )
    .unwrap();
    for i in run.pending() {
        let mut t = run.start(i).unwrap();
        search(&mut t, Ask::Loop);
        run.finish(t).unwrap();
    }
    run.close(false).unwrap();
    refused(
        &optbench(&["merge", "builtin", "dim4", "--out", "m"], d),
        &[
            "the list of objectives differs",
            "sphere-3d",
            "sphere-4d",
            "dim4",
        ],
    );
    // Two runs of the same optimizer id are not shards of one run.
    external(d, "PSO", "pso-too", Ask::Loop, ExternalOptions::default());
    refused(
        &optbench(&["merge", "builtin", "pso-too", "--out", "m"], d),
        &["pso-too: suite `ext-PSO`", "only shards of the same suite"],
    );
    // An unfinished external run is named with its missing trials.
    refused(
        &optbench(&["merge", "builtin", "bad", "--out", "m"], d),
        &["7 of 24 planned trials are missing", "optimizer `rs`"],
    );
    assert!(!d.join("m").exists());
}
