//! `optbench diagnose` end to end: the concealed-effect proof in small (one noise seed of
//! every case on 4 s twin records), reproducibility across thread counts, and the command
//! on CSV files (outputs, refusals). The full proof is `optbench diagnose --proof`.

mod common;

use common::{code_and_stderr, data_set, lab_csv, ok, optbench, read_json};
use optbench::diagnose::{Options, diagnose, proof};

fn opts(seed: u64) -> Options {
    Options {
        model: "bouc-wen-n1".into(),
        seed,
        ..Options::default()
    }
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// The JSON of a diagnosis without its wall time.
fn json_without_time(d: &optbench::diagnose::Diagnosis) -> serde_json::Value {
    let mut v = serde_json::to_value(d).unwrap();
    v.as_object_mut().unwrap().remove("wall_s");
    v
}

/// Runs `optbench diagnose` with `args` in `dir`, asserts it succeeded, and returns its
/// report and the `diagnosis.json` it wrote to `dir/out`.
fn diagnose_command(
    args: &[&str],
    dir: &std::path::Path,
    out: &str,
) -> (String, serde_json::Value) {
    let mut a = vec!["diagnose"];
    a.extend_from_slice(args);
    a.extend_from_slice(&["--out", out]);
    let o = optbench(&a, dir);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    (text, read_json(&dir.join(out).join("diagnosis.json")))
}

/// [`diagnose_command`] on `dir/train.csv` against `dir/validate.csv` with `columns`, n = 1
/// and `extra`.
fn diagnose_files(
    dir: &std::path::Path,
    columns: &str,
    extra: &[&str],
    out: &str,
) -> (String, serde_json::Value) {
    let mut a = vec![
        "--train",
        "train.csv",
        "--validate",
        "validate.csv",
        "--columns",
        columns,
        "--model",
        "bouc-wen-n1",
    ];
    a.extend_from_slice(extra);
    diagnose_command(&a, dir, out)
}

/// `optbench simulate` of the twin with overrides `twin`, driven by `signal` for `duration`
/// s every `dt` s, noise seed `seed`, into `dir/out`.
fn simulate_twin(
    dir: &std::path::Path,
    signal: &str,
    duration: &str,
    twin: &str,
    seed: &str,
    dt: &str,
    out: &str,
) {
    let args = [
        "simulate",
        "--signal",
        signal,
        "--duration",
        duration,
        "--twin",
        twin,
        "--seed",
        seed,
        "--dt",
        dt,
        "--out",
        out,
        "-q",
    ];
    ok(&optbench(&args, dir));
}

#[test]
fn every_concealed_effect_is_named_and_the_null_case_raises_no_alarm() {
    let kinds = proof::kinds();
    let (p, diagnoses) = pool(2)
        .install(|| proof::run(&kinds, &[1], 4.0, &opts(1)))
        .unwrap();
    print!("{}", proof::markdown(&p));
    let get = |name: &str| &diagnoses.iter().find(|d| d.0 == name).unwrap().1;
    for r in &p.rows {
        // Judged by prediction alone, the twin's 4-s sensor ramp is forecast by a drift
        // no better than creep predicts it: the diagnosis names one and reports the other
        // as tied (the old rule refitted the drift on the validation record and so named
        // it). A tie with the truth is what the records support; anything else fails.
        if r.truth == "offset-drift" && !r.exact {
            let d = get("offset-drift-seed1");
            let tied = d
                .in_final()
                .any(|c| c.ties.iter().any(|t| t.name == "offset-drift"));
            assert!(tied && r.found.len() == 1 && r.final_ratio < 1.3, "{r:?}");
            continue;
        }
        // Concealed: the plain model's validation residual only a few times the noise.
        if r.truth == "none" {
            assert!(r.baseline_ratio < 1.2, "{r:?}");
        } else {
            // (Up to 6x: the plain model's validation RMSE is a prediction now, its
            // record's own state fitted on the lead only; the sizes were set when it was a
            // fit, at most 4x.)
            assert!(
                (1.5..=6.0).contains(&r.baseline_ratio),
                "{} is not concealed: {r:?}",
                r.truth
            );
            // The accepted model brings the residual down to the noise.
            assert!(r.final_ratio < 1.15, "{r:?}");
        }
        assert!(r.exact, "{} diagnosed as {:?}", r.truth, r.found);
    }
    assert!(
        p.detection.0 >= 7 && p.detection.1 == 8,
        "{:?}",
        p.detection
    );
    assert_eq!(p.false_alarms, (0, 1));
    // The diagnosis carries its evidence: the null case passes the calibrated tests, a
    // concealed effect's baseline fails them and is located.
    let null = get("none-seed1");
    assert!(null.baseline.p_value > 0.05 && !null.unexplained);
    assert!(null.candidates.iter().all(|c| !c.accepted));
    let delay = get("delay-seed1");
    assert!(delay.baseline.p_value <= 0.05 && !delay.located.is_empty());
    let c = delay.candidates.iter().find(|c| c.accepted).unwrap();
    assert!(c.delta_bic < -10.0 && c.validate_rmse < delay.baseline.validate_band[0]);
    // The delay is the effect plus the sub-sample timing the baseline attributes to the
    // recording set-up (up to half a sample later).
    let d = c.params["delay_s"] + c.params["timing_offset_s"];
    assert!((d - 1e-3).abs() < 1e-4, "delay {d}");
    assert!(c.params["delay_s"] >= 0.5e-3 - 1e-4, "{:?}", c.params);
    assert_eq!(c.transfer.split(':').next(), Some("actuator"));
    let dynamics = get("dynamics-seed1");
    let f = dynamics.final_model.params["mode_freq_hz"];
    assert!((f - 185.0).abs() < 10.0, "mode at {f} Hz");
    // The null case attributes a sub-sample timing and its offsets to the set-up.
    assert!(null.nuisances.contains_key("timing_offset_s"));
    assert!(null.nuisances.contains_key("offset_validate"));

    // Same seed, one thread: the same diagnosis, number for number.
    let kind = kinds.iter().find(|k| k.name() == "delay").unwrap();
    let (t, v) = proof::generate(kind, 1, 4.0).unwrap();
    let again = pool(1).install(|| diagnose(&t, &v, &opts(1))).unwrap();
    assert_eq!(json_without_time(&again), json_without_time(delay));
}

#[test]
fn command_writes_json_and_figures_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let kind = proof::kinds()
        .into_iter()
        .find(|k| k.name() == "asymmetry")
        .unwrap();
    let (t, v) = proof::generate(&kind, 2, 3.0).unwrap();
    let columns = optbench::data::recording::Columns::parse("t_s,u_V,y_mm").unwrap();
    t.write_csv(&dir.path().join("train.csv"), &columns)
        .unwrap();
    v.write_csv(&dir.path().join("validate.csv"), &columns)
        .unwrap();
    let (text, json) = diagnose_files(
        dir.path(),
        "t_s,u_V,y_mm",
        &["--test", "validate.csv", "--test-periodic", "train.csv"],
        "diag",
    );
    assert!(text.contains("left out: asymmetry"), "{text}");
    for key in [
        "model",
        "noise_floor",
        "baseline",
        "located",
        "candidates",
        "left_out",
        "final",
        "unexplained",
        "search_stop",
    ] {
        assert!(json.get(key).is_some(), "missing {key}");
    }
    // The search ends for a stated reason, and every candidate says what its fit cost.
    let stop = json["search_stop"].as_str().unwrap();
    assert!(
        stop.contains("no candidate passes") || stop.contains("no structure"),
        "{stop}"
    );
    for c in json["candidates"].as_array().unwrap() {
        assert!(c["evaluations"].as_u64().unwrap() > 0);
    }
    assert_eq!(json["model"], "bouc-wen-n1");
    assert_eq!(json["left_out"], serde_json::json!(["asymmetry"]));
    let noise = json["noise_floor"].as_f64().unwrap();
    assert!((noise / 3e-4 - 1.0).abs() < 0.1, "noise floor {noise}");
    // White noise on a 1 kHz record: the difference orders agree, the floor is measured.
    assert_eq!(json["noise_floor_settled"], true);
    assert!(!text.contains("not settled"), "{text}");
    for key in ["train_rmse", "validate_rmse", "params", "plausibility"] {
        assert!(json["baseline"].get(key).is_some() && json["final"].get(key).is_some());
    }
    // Plausibility: every candidate carries its flags (a list), each flag names a reported
    // parameter or the model's own, its kind and why; the excited band is stated.
    assert!(json["excited_band_hz"].as_f64().unwrap() > 0.0);
    for c in json["candidates"].as_array().unwrap() {
        for f in c["plausibility"].as_array().unwrap() {
            assert!(
                ["at-bound", "unsupported", "implausible"].contains(&f["kind"].as_str().unwrap())
            );
            assert!(!f["why"].as_str().unwrap().is_empty() && f["value"].is_number());
        }
    }
    // Dynamics is tried after the hysteresis in each of its forms in the first round; the
    // feedback placement (searched afresh, the costliest candidate) only if a mode after
    // the hysteresis is the best (lowest ΔBIC + validation evidence) of the candidates that
    // pass the gate (evidence lines with three "yes") and leaves over 1.5x the noise.
    let round1: Vec<&serde_json::Value> = json["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["name"] == "dynamics" && c["round"] == 1)
        .collect();
    let after = |form: &str| {
        round1
            .iter()
            .any(|c| c["placement"] == "after-hysteresis" && c["form"] == form)
    };
    assert!(after("one-mode") && after("two-modes"), "{round1:?}");
    let best_passing = json["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| {
            c["round"] == 1
                && c["placement"] != "feedback"
                && c["evidence"].as_str().unwrap().matches("yes)").count() == 3
        })
        .min_by(|a, b| {
            let e = |c: &serde_json::Value| {
                c["delta_bic"].as_f64().unwrap() + c["validate_ic"].as_f64().unwrap()
            };
            e(a).total_cmp(&e(b))
        });
    let helps = best_passing.is_some_and(|c| {
        c["name"] == "dynamics" && c["validate_rmse"].as_f64().unwrap() > 1.5 * noise
    });
    let fb = round1.iter().any(|c| c["placement"] == "feedback");
    assert_eq!(fb, helps, "{round1:?}");
    // Test records: free run from the input alone, both models, finite; on the validation
    // record (from rest, its initial state not fitted) close to the diagnosis's own figure.
    let tests = json["tests"].as_array().unwrap();
    assert_eq!(tests.len(), 2);
    assert!(
        tests[1]["protocol"]
            .as_str()
            .unwrap()
            .starts_with("periodic")
    );
    let free = tests[0]["final_rmse"].as_f64().unwrap();
    let fitted = json["final"]["validate_rmse"].as_f64().unwrap();
    assert!(
        free >= 0.9 * fitted && free < 3.0 * fitted,
        "{free} vs {fitted}"
    );
    assert!(tests[1]["baseline_rmse"].as_f64().unwrap().is_finite());
    for c in json["candidates"].as_array().unwrap() {
        for key in [
            "name",
            "delta_bic",
            "validate_rmse",
            "accepted",
            "params",
            "evidence",
        ] {
            assert!(c.get(key).is_some(), "candidate without {key}");
        }
    }
    for stem in [
        "validate_residual_time",
        "validate_residual_loop",
        "validate_residual_spectrum",
        "validate_loops",
        "train_loops",
    ] {
        for ext in ["svg", "png"] {
            let p = dir.path().join(format!("diag/{stem}.{ext}"));
            assert!(
                std::fs::metadata(&p).unwrap().len() > 1000,
                "{}",
                p.display()
            );
        }
    }

    // Refusals: exit 2, a message naming the problem, nothing written.
    std::fs::write(
        dir.path().join("bad.csv"),
        "t_s,u_V,y_mm\n0,1,2\n0.001,x,3\n",
    )
    .unwrap();
    for (args, needle) in [
        (
            vec!["--train", "bad.csv", "--validate", "validate.csv"],
            "bad.csv:3",
        ),
        (
            vec!["--train", "missing.csv", "--validate", "validate.csv"],
            "missing.csv",
        ),
        (
            vec![
                "--train",
                "train.csv",
                "--validate",
                "validate.csv",
                "--model",
                "hammerstein",
            ],
            "invalid value 'hammerstein' for '--model <MODEL>'",
        ),
        (
            vec![
                "--train",
                "train.csv",
                "--validate",
                "validate.csv",
                "--hold",
                "staircase",
            ],
            "invalid value 'staircase' for '--hold <HOLD>'",
        ),
        (
            vec![
                "--train",
                "train.csv",
                "--validate",
                "validate.csv",
                "--effects",
                "delay,magic",
            ],
            "unknown effect `magic`",
        ),
    ] {
        let mut a = vec!["diagnose", "--columns", "t_s,u_V,y_mm", "--out", "refused"];
        a.extend(args);
        let out = optbench(&a, dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_ne!(out.status.code(), Some(0), "{a:?}");
        assert!(err.contains(needle), "{a:?}: {err}");
        assert!(!dir.path().join("refused").exists());
    }
}

/// Records at different rates diagnose together: the twin with a 3 ms delay recorded at
/// 1 kHz for training and at 400 Hz for validation. The model is simulated on each at its
/// own interval (the delay carried in seconds, the validation record's own sub-sample
/// timing refitted): the delay is named and the validation record is predicted to its
/// noise.
#[test]
fn records_at_different_rates_diagnose_together() {
    use optbench::data::signal::Signal;
    use optbench::physics::twin::{self, TwinConfig};
    let cfg = TwinConfig::parse_overrides("amp=off,mode=off,delay=0.003").unwrap();
    let record = |spec: &str, dt: f64, seed: u64| {
        let u = Signal::parse(spec).unwrap().sample(dt, 8.0);
        twin::recording(&cfg, format!("twin at {dt} s"), u, dt, seed).unwrap()
    };
    let train = record(
        "multisine:fmin=0.25,fmax=2.5,period=8,rms=1.2,seed=3,offset=2.35 + sine:freq=40,amp=0.05",
        1e-3,
        1,
    );
    let validate = record(
        "triangle:freq=0.7,amp=2.2,offset=2.35 + chirp:f0=15,f1=80,duration=8,amp=0.05,law=log",
        2.5e-3,
        2,
    );
    let d = diagnose(&train, &validate, &opts(1)).unwrap();
    assert_eq!(d.sampling_intervals_s, [1e-3, 2.5e-3]);
    assert_eq!(d.accepted_labels(), ["delay"], "{}", d.search_stop);
    let p = &d.final_model.params;
    let delay = p["delay_s"] + p["timing_offset_s"];
    assert!((delay - 3e-3).abs() < 2e-4, "delay {delay}");
    let ratio = d.final_model.validate_rmse / d.noise_floor;
    assert!(ratio < 1.2, "validation {ratio}x the noise floor");
    assert!(d.baseline.validate_rmse > 5.0 * d.noise_floor);
}

#[test]
fn command_reads_lab_files_and_resamples_on_request() {
    // The training record as lab software writes it: `;`-separated, decimal commas, time
    // from 1234.5 s with 2e-6 s jitter; and with a sample left out (no jitter).
    let dir = tempfile::tempdir().unwrap();
    let kind = proof::kinds()
        .into_iter()
        .find(|k| k.name() == "delay")
        .unwrap();
    let (t, v) = proof::generate(&kind, 1, 2.0).unwrap();
    let columns = optbench::data::recording::Columns::parse("t_s,u_V,y_mm").unwrap();
    t.write_csv(&dir.path().join("train.csv"), &columns)
        .unwrap();
    v.write_csv(&dir.path().join("validate.csv"), &columns)
        .unwrap();
    lab_csv(&t, &dir.path().join("lab.csv"), 1234.5, 2e-6, None);
    lab_csv(&t, &dir.path().join("gap.csv"), 1234.5, 0.0, Some(700));
    let run = |train: &str, extra: &[&str], out: &str| {
        let mut a = vec![
            "diagnose",
            "--train",
            train,
            "--validate",
            "validate.csv",
            "--columns",
            "t_s,u_V,y_mm",
            "--model",
            "bouc-wen-n1",
            "--effects",
            "delay,input-lag",
            "--bootstrap",
            "3",
            "--out",
            out,
        ];
        a.extend(extra);
        code_and_stderr(&a, dir.path())
    };
    // The diagnosis without its wall time and training file name; the timing offset (half
    // a sample of the zero-order hold) kept apart, as the fitted step of jittered stamps
    // differs from the true one by parts in 10^9.
    let diagnosis = |out: &str| {
        let mut j = read_json(&dir.path().join(out).join("diagnosis.json"));
        let o = j.as_object_mut().unwrap();
        for key in ["wall_s", "train"] {
            o.remove(key);
        }
        let mut offsets = Vec::new();
        for set in ["baseline", "final"] {
            let params = j[set]["params"].as_object_mut().unwrap();
            offsets.extend(params.remove("timing_offset_s").and_then(|v| v.as_f64()));
        }
        (j, offsets)
    };
    let (code, err) = run("train.csv", &[], "plain");
    assert_eq!(code, Some(0), "{err}");
    // Time offset, jitter and the file's format change nothing in the diagnosis.
    let (code, err) = run("lab.csv", &[], "lab");
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("note: ./lab.csv: time stamps jitter by up to 2.0"),
        "{err}"
    );
    let ((lab, lab_offsets), (plain, plain_offsets)) = (diagnosis("lab"), diagnosis("plain"));
    // The fitted step and what follows from it (the timing offset in seconds, wherever it
    // is reported) agree to parts in 10^9.
    let strip = |mut j: serde_json::Value| {
        j["nuisances"]
            .as_object_mut()
            .unwrap()
            .remove("timing_offset_s");
        let steps = j
            .as_object_mut()
            .unwrap()
            .remove("sampling_intervals_s")
            .unwrap();
        for s in steps.as_array().unwrap() {
            assert!((s.as_f64().unwrap() / 1e-3 - 1.0).abs() < 1e-7, "{steps}");
        }
        // The same steps, with each record's length.
        let records = j.as_object_mut().unwrap().remove("records").unwrap();
        for r in records.as_array().unwrap() {
            assert_eq!(r[0][0], 2000, "{records}");
            assert!(
                (r[0][1].as_f64().unwrap() / 1e-3 - 1.0).abs() < 1e-7,
                "{records}"
            );
        }
        for set in ["baseline", "final"] {
            for f in j[set]["plausibility"].as_array_mut().unwrap() {
                if f["parameter"] == "timing_offset_s" {
                    f.as_object_mut().unwrap().remove("value");
                }
            }
        }
        j
    };
    let band = |j: &serde_json::Value| j["excited_band_hz"].as_f64().unwrap();
    assert!((band(&lab) / band(&plain) - 1.0).abs() < 1e-7);
    let (mut lab, mut plain) = (strip(lab), strip(plain));
    for j in [&mut lab, &mut plain] {
        j.as_object_mut().unwrap().remove("excited_band_hz");
    }
    assert_eq!(lab, plain);
    for (a, b) in lab_offsets.iter().zip(&plain_offsets) {
        assert!((a / b - 1.0).abs() < 1e-7, "{a} vs {b}");
    }
    let (code, err) = run("lab.csv", &["--delimiter", ","], "refused");
    assert_eq!(code, Some(2));
    assert!(
        err.contains("(columns: t_s;u_V;y_mm, separated by ',')"),
        "{err}"
    );
    // A missing sample: refused at the sample after it, or resampled on request.
    let (code, err) = run("gap.csv", &[], "refused");
    assert_eq!(code, Some(2));
    assert!(err.contains("./gap.csv:702: time column 't_s'"), "{err}");
    assert!(
        err.contains("a gap of 2.00 steps") && err.contains("--resample"),
        "{err}"
    );
    assert!(!dir.path().join("refused").exists());
    let (code, err) = run("gap.csv", &["--resample"], "gap");
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("resampled: 2000 samples, step 0.001 s, largest gap 0.002 s at line 702"),
        "{err}"
    );
    assert_eq!(
        diagnosis("gap").0["samples"],
        diagnosis("plain").0["samples"]
    );
}

#[test]
fn command_handles_a_record_starting_in_motion_and_one_with_long_rests() {
    // Training starts mid-swing at t = 0.3 s; validation holds the input for 1.5 s at a
    // time (the twin, written by `simulate`).
    let dir = tempfile::tempdir().unwrap();
    for (signal, seconds, out) in [
        ("sine:freq=2,amp=1.5,offset=2.35", "3", "sine"),
        ("steps:levels=1;3.6;1.8;3,hold=1.5", "6", "rests"),
    ] {
        let o = optbench(
            &[
                "simulate",
                "--signal",
                signal,
                "--duration",
                seconds,
                "--columns",
                "t_s,u_V,y_mm",
                "--out",
                out,
            ],
            dir.path(),
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let sine = std::fs::read_to_string(dir.path().join("sine/twin.csv")).unwrap();
    let lines: Vec<&str> = sine.lines().collect();
    let motion = [&lines[..1], &lines[301..]].concat().join("\n");
    assert!(lines[301].starts_with("0.3,"), "{}", lines[301]);
    std::fs::write(dir.path().join("motion.csv"), motion).unwrap();
    let o = optbench(
        &[
            "diagnose",
            "--train",
            "motion.csv",
            "--validate",
            "rests/twin.csv",
            "--columns",
            "t_s,u_V,y_mm",
            "--model",
            "bouc-wen-n1",
            "--effects",
            "delay,creep",
            "--bootstrap",
            "3",
            "--out",
            "d",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json = read_json(&dir.path().join("d/diagnosis.json"));
    assert_eq!(json["samples"], serde_json::json!([2700, 6000]));
    // The initial hysteretic state is fitted: the record did not start at rest.
    let h0 = json["final"]["params"]["h0"].as_f64().unwrap();
    assert!(h0.is_finite() && h0.abs() > 1e-3, "h0 {h0}");
    let rmse = json["final"]["validate_rmse"].as_f64().unwrap();
    assert!(rmse.is_finite() && rmse > 0.0, "{rmse}");
}

/// A real piezo stack (PI P-885.91, `$OPTBENCH_DATA/pea_p885_dbo`) as a regression case:
/// both runs load as the lab wrote them, the start-up each begins with is found, and with
/// it left out the creep the identification run supports, more than a piezo has, is not
/// named so: only held at the most a piezo shows, if it passes there (n pinned at 1 to
/// keep the test short).
#[test]
fn the_p885_stack_is_diagnosed_with_its_start_up_found_and_its_creep_flagged() {
    let Some(dir) = data_set("pea_p885_dbo") else {
        return;
    };
    let train = dir.join("dbo_identification_1Hz_sine.csv");
    let validate = dir.join("dbo_test_ramped_sine_with_holds.csv");
    let tmp = tempfile::tempdir().unwrap();
    let run = |extra: &[&str], out: &str| {
        let mut a = vec![
            "--train",
            train.to_str().unwrap(),
            "--validate",
            validate.to_str().unwrap(),
            "--columns",
            "t_s,u_V,y_um",
            "--model",
            "bouc-wen-n1",
        ];
        a.extend_from_slice(extra);
        diagnose_command(&a, tmp.path(), out)
    };
    let (text, _) = run(&["--effects", "delay"], "plain");
    for record in ["training", "validation"] {
        assert!(
            text.contains(&format!("the {record} record starts in motion")),
            "{text}"
        );
    }
    let (text, json) = run(&["--trim-start", "1", "--suggest"], "trimmed");
    // Creep fits the identification run only with more creep than a piezo has (its total
    // over a quarter of the drive): not named so (issue 50). The stronger test holds it at
    // a quarter, polishes the rest again and judges that; each creep candidate says which.
    let candidates = json["candidates"].as_array().unwrap();
    let creep: Vec<&serde_json::Value> = candidates
        .iter()
        .filter(|c| c["name"].as_str().unwrap().split('+').any(|n| n == "creep"))
        .collect();
    assert!(
        creep.iter().any(|c| c["evidence"]
            .as_str()
            .unwrap()
            .contains("held at 25 % creep in all")),
        "{text}"
    );
    for c in &creep {
        let e = c["evidence"].as_str().unwrap();
        let flagged = c["plausibility"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f["parameter"] == "creep_total" && f["kind"] == "implausible");
        if c["accepted"] == true {
            assert!(!flagged, "{c}");
        }
        // Refused for its creep: the held fit did not pass, and the line says so.
        if c["refused"]
            .as_str()
            .is_some_and(|r| r.starts_with("[implausible] creep_total") && !r.contains(';'))
        {
            assert!(e.contains("it no longer passes"), "{e}");
        }
    }
    // The refusal is a field of its own (the text report lists from it), set exactly on
    // the candidates whose evidence says refused, with the why.
    for c in candidates {
        let says = c["evidence"].as_str().unwrap().contains("refused");
        assert_eq!(c["refused"].is_string(), says, "{c}");
    }
    // Each refusal says what its round named instead (a plausible candidate or nothing).
    let line = text
        .lines()
        .find(|l| l.starts_with("not named although the gate passed"))
        .unwrap_or_else(|| panic!("{text}"));
    let first = candidates
        .iter()
        .find(|c| c["refused"].is_string())
        .unwrap();
    let round = first["round"].as_u64().unwrap();
    let instead = candidates
        .iter()
        .find(|c| c["accepted"] == true && c["round"].as_u64() == Some(round))
        .map_or("nothing".to_string(), |c| {
            format!(
                "{} [{}]",
                c["name"].as_str().unwrap(),
                c["form"].as_str().unwrap()
            )
        });
    assert!(
        line.contains(&format!(
            "{} [{}] (round {round}; preferred instead: {instead}",
            first["name"].as_str().unwrap(),
            first["form"].as_str().unwrap()
        )),
        "{line}"
    );
    // The validation residual's figure is written (with the lead and the origins); the
    // identification sine has no holds, so there is no holds' figure.
    let out = tmp.path().join("trimmed");
    assert!(out.join("validate_residual_time.png").exists());
    assert!(!out.join("train_steps.png").exists());
    assert_eq!(json["step_evidence"]["holds"], 0);
    assert_eq!(json["samples"], serde_json::json!([7827, 13955]));
    let v = |set: &str| json[set]["validate_rmse"].as_f64().unwrap();
    assert!(v("final") < v("baseline"), "{text}");
    // Nothing implausible is accepted.
    let flags = json["final"]["plausibility"].as_array().unwrap();
    assert!(!flags.iter().any(|f| f["kind"] == "implausible"), "{text}");
    assert!(
        !text.contains("! accepted although [implausible]"),
        "{text}"
    );
}

/// The core chosen by the data on a real stack (P-885, first second left out, only a delay
/// offered to keep the test short): the Bouc-Wen search with its exponent ends well above
/// the noise floor, the operator cores are searched, and the PI core, whose plays shape the
/// stack's minor loops, predicts the ramped test record below Bouc-Wen's band: the first
/// finding is that the loop is not Bouc-Wen's, and the search goes on with the PI core.
#[test]
fn the_p885_loop_is_given_to_the_pi_core_by_the_data() {
    let Some(dir) = data_set("pea_p885_dbo") else {
        return;
    };
    let train = dir.join("dbo_identification_1Hz_sine.csv");
    let validate = dir.join("dbo_test_ramped_sine_with_holds.csv");
    let tmp = tempfile::tempdir().unwrap();
    let (text, json) = diagnose_command(
        &[
            "--train",
            train.to_str().unwrap(),
            "--validate",
            validate.to_str().unwrap(),
            "--columns",
            "t_s,u_V,y_um",
            "--trim-start",
            "1",
            "--effects",
            "delay",
        ],
        tmp.path(),
        "auto",
    );
    let c = &json["core_choice"];
    assert_eq!(c["chosen"], "pi", "{text}");
    assert!(text.contains("core: the loop is not Bouc-Wen's"), "{text}");
    let trials = c["trials"].as_array().unwrap();
    assert_eq!(trials.len(), 3, "{text}");
    assert_eq!(trials[0]["core"], "bouc-wen");
    let band = trials[0]["validate_band"][0].as_f64().unwrap();
    let kept = json["final"]["validate_rmse"].as_f64().unwrap();
    assert!(kept < band, "{kept} against Bouc-Wen's band from {band}");
    assert!(
        json["final"]["model"].as_str().unwrap().starts_with("pi"),
        "{text}"
    );
    assert_eq!(json["model"], "auto: pi");
    // The model file holds the PI core: what `simulate --model` and `invert` read.
    let model = read_json(&tmp.path().join("auto/model.json"));
    assert_eq!(
        model["structure"]["context"]["pi"]["kind"], "plays",
        "{model}"
    );
}

/// The Bouc-Wen benchmark (`$OPTBENCH_DATA/boucwen-benchmark`) in small, as a user without
/// knowledge of it would run it (`scripts/docsgen/boucwen.py --small` runs the same): the
/// first 6000 training samples, the last 20 % of them held out for validation, n fitted,
/// the hold chosen by the data, only `dynamics` offered. The diagnosis must put the
/// hysteresis inside the mechanical feedback, choose the band-limited hold, and predict the
/// official multisine test set (never seen) within 5e-6 m (2.1e-6 m now; the static model
/// misses it by 5.7e-4 m, a mode after the hysteresis by about 1.5e-4 m).
#[test]
fn the_bouc_wen_benchmark_is_diagnosed_in_small_without_knowledge_of_it() {
    let Some(dir) = data_set("boucwen-benchmark") else {
        return;
    };
    let text = std::fs::read_to_string(dir.join("train_multisine_forgione.csv")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let lines: Vec<&str> = text.lines().take(6001).collect();
    std::fs::write(tmp.path().join("train.csv"), lines.join("\n") + "\n").unwrap();
    let test = dir.join("test_multisine.csv");
    let args = [
        "--train",
        "train.csv",
        "--holdout",
        "0.2",
        "--hold",
        "auto",
        "--model",
        "bouc-wen",
        "--effects",
        "dynamics",
        "--test-periodic",
        test.to_str().unwrap(),
        "--columns",
        "t_s,u_N,y_m",
    ];
    let (text, json) = diagnose_command(&args, tmp.path(), "out");
    assert_eq!(json["left_out"], serde_json::json!(["dynamics"]), "{text}");
    assert_eq!(
        json["final"]["model"], "bouc-wen+dynamics(feedback)",
        "{text}"
    );
    assert_eq!(json["samples"], serde_json::json!([4800, 1200]));
    assert_eq!(json["hold"], "bandlimited", "{text}");
    let trials = json["hold_trials"].as_array().unwrap();
    assert_eq!(trials.len(), 3, "{text}");
    let t = &json["tests"][0];
    let (base, fin) = (
        t["baseline_rmse"].as_f64().unwrap(),
        t["final_rmse"].as_f64().unwrap(),
    );
    assert!(base > 1e-4, "{text}");
    assert!(fin < 5e-6, "multisine test RMSE {fin:e} m\n{text}");
}

/// A second input driven at the same time (a mirror on several piezos): the command reads
/// the validation file's other columns in the input's unit and reports the one the final
/// residual is coherent with; a column that drives nothing is not reported, nor is an
/// output column.
#[test]
fn another_input_driving_the_output_is_reported_as_coupling() {
    use optbench::data::signal::Signal;
    use optbench::physics::twin::{self, TwinConfig};
    let dir = tempfile::tempdir().unwrap();
    let cfg = TwinConfig::parse_overrides("amp=off,mode=off").unwrap();
    let dt = 1e-3;
    let write = |name: &str, drive: &str, seed: u64| {
        let u1 = Signal::parse(drive).unwrap().sample(dt, 4.0);
        let r = twin::recording(&cfg, "twin", u1.clone(), dt, seed).unwrap();
        let u2 = Signal::parse(&format!(
            "multisine:fmin=1,fmax=40,period=4,rms=1,seed={seed}"
        ))
        .unwrap()
        .sample(dt, 4.0);
        let u3 = Signal::parse(&format!(
            "multisine:fmin=1,fmax=40,period=4,rms=1,seed={}",
            seed + 10
        ))
        .unwrap()
        .sample(dt, 4.0);
        let mut text = String::from("t_s,u1_V,u2_V,u3_V,y_mm,y2_mm\n");
        for k in 0..r.len() {
            // u2 drives the output through a first-order lag; u3 drives nothing here.
            let lagged = if k > 0 {
                0.5 * (u2[k] + u2[k - 1])
            } else {
                u2[k]
            };
            let y = r.y[k] + 0.01 * lagged;
            text.push_str(&format!(
                "{},{},{},{},{},{}\n",
                r.t[k],
                u1[k],
                u2[k],
                u3[k],
                y,
                0.3 * y
            ));
        }
        std::fs::write(dir.path().join(name), text).unwrap();
    };
    write("train.csv", "sine:freq=1,amp=2.3,offset=2.35", 1);
    write("validate.csv", "triangle:freq=0.7,amp=2.2,offset=2.35", 2);
    let (text, json) = diagnose_files(dir.path(), "t_s,u1_V,y_mm", &["--effects", "delay"], "d");
    let couplings = json["couplings"].as_array().expect("a coupling");
    let columns: Vec<&str> = couplings
        .iter()
        .map(|c| c["column"].as_str().unwrap())
        .collect();
    assert_eq!(columns, ["u2_V"], "{text}");
    assert!(couplings[0]["share"].as_f64().unwrap() > 0.5, "{text}");
    assert!(text.contains("coupling: u2_V holds"), "{text}");
}

/// Several training records of one twin, at 1 kHz and 400 Hz, each with a sensor offset of
/// its own: one joint fit shares the actuator's creep and hysteresis, refits each record's
/// offset, initial state and timing, names creep with the twin's gains and time constants,
/// and returns the offsets as given; validated on two records at a third rate, at the
/// noise floor, one of them starting at the top of the range (its initial states found by
/// a grid before the polish, its creep states bounded by the excursion from 0 V that
/// brought it there: before, 5.6x the floor without creep, 2.7x with). The step record
/// alone identifies too little of the loop to predict the triangle.
#[test]
fn several_records_at_several_rates_are_fitted_together() {
    use optbench::data::signal::Signal;
    use optbench::diagnose::diagnose_with_tests;
    use optbench::physics::twin::{self, TwinConfig};
    let cfg = TwinConfig::parse_overrides(
        "amp=off,mode=off,creep.enabled=on,creep.gain_fast=0.04,creep.tau_fast=0.3,creep.gain_slow=0.04,creep.tau_slow=3",
    )
    .unwrap();
    let record = |spec: &str, dt: f64, seconds: f64, offset: f64, seed: u64| {
        let u = Signal::parse(spec).unwrap().sample(dt, seconds);
        let mut r = twin::recording(&cfg, format!("{spec} at {dt} s"), u, dt, seed).unwrap();
        r.y.iter_mut().for_each(|y| *y += offset);
        r
    };
    let train = [
        record(
            "steps:levels=0.5;4.2;1.5;3.3;0.8,hold=1.2",
            1e-3,
            6.0,
            0.0,
            1,
        ),
        record("sine:freq=0.8,amp=2.0,offset=2.35", 2.5e-3, 6.0, 0.05, 2),
    ];
    let validate = [
        record("triangle:freq=0.6,amp=2.1,offset=2.35", 2e-3, 5.0, -0.03, 3),
        // Starts at the top of the range, where the twin was stepped from 0 V before
        // recording: its hysteretic and creep states are its own and far from rest.
        record("steps:levels=4.0;1.0;2.5,hold=1.5", 2e-3, 4.5, 0.02, 4),
    ];
    let d = diagnose_with_tests(&train, &validate, &[], &opts(1)).unwrap();
    assert_eq!(d.accepted_labels(), ["creep"], "{}", d.search_stop);
    assert_eq!(d.samples, [6000 + 2400, 2500 + 2250]);
    assert_eq!(
        d.records,
        [
            vec![(6000, 1e-3), (2400, 2.5e-3)],
            vec![(2500, 2e-3), (2250, 2e-3)]
        ]
    );
    let text = optbench::diagnose::report::text(&d);
    assert!(
        text.contains("(2 records: 6000 every 0.001 s, 2400 every 0.0025 s)"),
        "{text}"
    );
    let p = &d.final_model.params;
    for (name, want) in [
        ("creep_gain", 0.04),
        ("creep_tau_s", 0.3),
        ("creep_gain_slow", 0.04),
        ("creep_tau_slow_s", 3.0),
    ] {
        assert!((p[name] / want - 1.0).abs() < 0.05, "{name} {}", p[name]);
    }
    let step = p["d0@2"] - p["d0"];
    assert!((step - 0.05).abs() < 0.002, "offset step {step}");
    assert!(p.contains_key("g0_frac@2") && p.contains_key("timing_samples@2"));
    let ratio = d.final_model.validate_rmse / d.noise_floor;
    assert!(ratio < 1.15, "validation {ratio}x the noise floor");
    // The step record alone: the loop between its five levels is not identified.
    let alone = diagnose_with_tests(&train[..1], &validate[..1], &[], &opts(1)).unwrap();
    let ratio_alone = alone.final_model.validate_rmse / alone.noise_floor;
    assert!(
        ratio_alone > 3.0,
        "one record: {ratio_alone}x the noise floor"
    );
}

/// The command takes --train and --validate more than once; the JSON lists the records and
/// the figures put them on one time axis, each at its own interval.
#[test]
fn command_takes_several_records() {
    use optbench::data::recording::Columns;
    use optbench::data::signal::Signal;
    use optbench::physics::twin::{self, TwinConfig};
    let cfg = TwinConfig::parse_overrides("amp=off,mode=off,creep=on").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let columns = Columns::parse("t,u,y").unwrap();
    for (name, spec, dt, seconds) in [
        (
            "a.csv",
            "steps:levels=0.5;4.2;1.5;3.3;0.8,hold=1.2",
            1e-3,
            6.0,
        ),
        ("b.csv", "sine:freq=0.8,amp=2.0,offset=2.35", 2.5e-3, 6.0),
        ("c.csv", "triangle:freq=0.6,amp=2.1,offset=2.35", 2e-3, 5.0),
    ] {
        let u = Signal::parse(spec).unwrap().sample(dt, seconds);
        twin::recording(&cfg, name, u, dt, 1)
            .unwrap()
            .write_csv(&dir.path().join(name), &columns)
            .unwrap();
    }
    let args: Vec<&str> = "--train a.csv --train b.csv --validate c.csv --model bouc-wen-n1"
        .split(' ')
        .collect();
    let (text, json) = diagnose_command(&args, dir.path(), "out");
    assert_eq!(json["left_out"], serde_json::json!(["creep"]), "{text}");
    assert_eq!(
        json["records"][0],
        serde_json::json!([[6000, 0.001], [2400, 0.0025]])
    );
    assert!(
        text.contains("2 records: 6000 every 0.001 s, 2400 every 0.0025 s"),
        "{text}"
    );
    assert!(dir.path().join("out/train_residual_time.png").exists());
    // Refused with exit code 2 and the reason.
    let refused = |args: &str, why: &str| {
        let a: Vec<&str> = args.split(' ').collect();
        let (code, err) = code_and_stderr(&a, dir.path());
        assert_eq!(code, Some(2), "{args}");
        assert!(err.contains(why), "{err}");
    };
    refused(
        "diagnose --train a.csv --validate c.csv --validate a.csv --validate-periodic",
        "--validate-periodic takes one validation record",
    );
    refused(
        "diagnose --train a.csv --validate c.csv --trim-start -1",
        "--trim-start -1: expected the seconds (>= 0)",
    );
    // --holdout: each training record's tail is its validation record, never fitted.
    let args: Vec<&str> = "--train a.csv --train b.csv --holdout 0.25 --model bouc-wen-n1 --effects creep --bootstrap 3"
        .split(' ')
        .collect();
    let (text, json) = diagnose_command(&args, dir.path(), "held");
    let parts: Vec<Vec<(u64, f64)>> = (0..2)
        .map(|i| {
            json["records"][i]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| (p[0].as_u64().unwrap(), p[1].as_f64().unwrap()))
                .collect()
        })
        .collect();
    for (part, want) in parts.iter().zip([[4500, 1800], [1500, 600]]) {
        assert_eq!(part.iter().map(|p| p.0).collect::<Vec<_>>(), want, "{text}");
        assert!((part[0].1 - 1e-3).abs() < 1e-12 && (part[1].1 - 2.5e-3).abs() < 1e-12);
    }
    let validate = json["validate"].as_str().unwrap();
    assert!(
        validate.contains("a.csv [u -> y] (last 25 %, held out)")
            && validate.contains("b.csv [u -> y] (last 25 %, held out)"),
        "{validate}"
    );
    assert!(
        json["train"].as_str().unwrap().contains("(first 75 %)"),
        "{text}"
    );
    refused(
        "diagnose --train a.csv --holdout 1",
        "--holdout 1: expected the share of each training record held out",
    );
    refused(
        "diagnose --train a.csv --holdout 0.2 --validate c.csv",
        "cannot be used with",
    );
    refused(
        "diagnose --train a.csv --holdout 0.2 --validate-periodic",
        "cannot be used with",
    );
    refused(
        "diagnose --train a.csv --holdout 0.99",
        "needs at least 200 samples per recording",
    );
    refused(
        "diagnose --train a.csv --validate c.csv --hold cubic",
        "[possible values: zoh, linear, bandlimited, auto]",
    );
    refused(
        "diagnose --train a.csv --validate c.csv --min-substeps 0",
        "--min-substeps 0: expected 1 to 64",
    );
}

/// Creep whose slow element (200 s) is far slower than 8-s records can show: the fit runs
/// that element's time constant to its upper bound, which alone refuses creep (a trend
/// over the record, not identified). The stronger test switches the slow element off,
/// polishes the rest again and judges that: creep is named so, with the fast element the
/// twin has (5 % at 0.3 s), and predicts the validation record near the noise floor.
#[test]
fn creep_with_a_slow_element_beyond_the_record_is_named_without_it() {
    let tmp = tempfile::tempdir().unwrap();
    let twin = "amp=off,mode=off,creep=on,creep.gain_fast=0.05,creep.tau_fast=0.3,\
                creep.gain_slow=0.05,creep.tau_slow=200";
    for (signal, duration, seed, out) in [
        (
            "steps:levels=2.35;4.4;2.35;0.3;2.35;4.0;1.0,hold=1.2",
            "8.4",
            "3",
            "t",
        ),
        ("sine:freq=0.5,amp=2,offset=2.35", "8", "4", "v"),
    ] {
        simulate_twin(tmp.path(), signal, duration, twin, seed, "0.005", out);
    }
    let args = [
        "--train",
        "t/twin.csv",
        "--validate",
        "v/twin.csv",
        "--model",
        "bouc-wen-n1",
    ];
    let (text, json) = diagnose_command(&args, tmp.path(), "d");
    assert_eq!(json["left_out"], serde_json::json!(["creep"]), "{text}");
    let named = json["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["accepted"] == true && c["name"] == "creep")
        .unwrap();
    let evidence = named["evidence"].as_str().unwrap();
    assert!(
        evidence.contains("without its slow element") && evidence.contains("it passes"),
        "{evidence}"
    );
    let p = &json["final"]["params"];
    let (gain, tau) = (
        p["creep_gain"].as_f64().unwrap(),
        p["creep_tau_s"].as_f64().unwrap(),
    );
    assert!(
        (gain - 0.05).abs() < 0.01 && (tau - 0.3).abs() < 0.06,
        "{p}"
    );
    let flags = json["final"]["plausibility"].as_array().unwrap();
    assert!(
        !flags
            .iter()
            .any(|f| f["kind"] == "at-bound" || f["kind"] == "implausible"),
        "{text}"
    );
    let over =
        json["final"]["validate_rmse"].as_f64().unwrap() / json["noise_floor"].as_f64().unwrap();
    assert!(over < 1.3, "final at {over}x the noise floor");
}

/// A model fitted on a slow record and judged on one twenty times faster misses it by
/// twice its noise while the training residual is noise: the report says the validation
/// record is not predicted, never that the plain model is enough; with a validation drive
/// like the training one it is enough.
#[test]
fn a_validation_record_predicted_above_its_noise_is_not_called_explained() {
    let tmp = tempfile::tempdir().unwrap();
    let twin = "amp=off,mode=off,creep=off";
    for (signal, duration, seed, out) in [
        ("sine:freq=0.2,amp=2,offset=2.35", "10", "3", "t"),
        ("sine:freq=4,amp=2,offset=2.35", "3", "4", "fast"),
        ("sine:freq=0.3,amp=2,offset=2.35", "8", "4", "slow"),
    ] {
        simulate_twin(tmp.path(), signal, duration, twin, seed, "0.002", out);
    }
    for (validate, unpredicted) in [("fast", true), ("slow", false)] {
        let v = format!("{validate}/twin.csv");
        let args = [
            "--train",
            "t/twin.csv",
            "--validate",
            v.as_str(),
            "--model",
            "bouc-wen-n1",
            "--effects",
            "saturation",
        ];
        let (text, json) = diagnose_command(&args, tmp.path(), validate);
        assert_eq!(json["residual_structured"], false, "{text}");
        assert_eq!(json["validation_unpredicted"], unpredicted, "{text}");
        assert_eq!(json["unexplained"], unpredicted, "{text}");
        assert_eq!(
            text.contains("the plain model is enough"),
            !unpredicted,
            "{text}"
        );
        if unpredicted {
            let over = json["final"]["validate_rmse"].as_f64().unwrap()
                / json["noise_floor"].as_f64().unwrap();
            assert!(over > 1.5, "{over}");
            assert!(text.contains("its drive excites what the training drive does not show"));
        }
    }
}
