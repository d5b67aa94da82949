//! Test functions without the centre: the `shift`, `rotate` and `instance` keys as a suite
//! reads them. The transform itself (optimum, orthogonality, gradients) is unit-tested in
//! src/objective/functions.rs; here: what a user writes, what the suite in suites/ builds.

use optbench::objective::Objective;
use optbench::pipeline::suite::Suite;
use std::path::Path;

fn suite(objective: &str) -> Result<Suite, String> {
    suite_with_seed(objective, 1)
}

fn suite_with_seed(objective: &str, seed: u64) -> Result<Suite, String> {
    let text = format!(
        "name = \"s\"\nseed = {seed}\ntrials = 1\nbudget = 100\n[[objective]]\n{objective}\n\
         [[optimizer]]\nkind = \"random\"\n"
    );
    Suite::parse(&text, Path::new("s.toml")).map_err(|e| e.to_string())
}

fn built(objective: &str) -> std::sync::Arc<dyn Objective> {
    let s = suite(objective).unwrap_or_else(|e| panic!("{objective}: {e}"));
    s.objectives[0].objective.clone()
}

#[test]
fn bad_keys_are_refused_with_file_line_and_what_to_write() {
    let cases = [
        (
            "kind = \"griewank\"\ndim = 2\nshift = \"left\"",
            "`shift`",
            "random",
        ),
        (
            "kind = \"griewank\"\ndim = 2\nrotate = \"yes\"",
            "`rotate`",
            "true | false",
        ),
        (
            "kind = \"griewank\"\ndim = 2\nshift = \"random\"\ninstance = 0",
            "`instance`",
            "1",
        ),
        (
            "kind = \"schwefel\"\ndim = 2\ninstance = 2",
            "`instance`",
            "set shift = \"random\" or rotate = true",
        ),
        (
            "kind = \"sphere\"\ndim = 501\nrotate = true",
            "`rotate`",
            "<= 500",
        ),
    ];
    for (objective, field, hint) in cases {
        let e = match suite(objective) {
            Ok(_) => panic!("accepted:\n{objective}"),
            Err(e) => e,
        };
        assert!(e.contains("s.toml:"), "{objective}: {e}");
        assert!(e.contains(field), "{objective}: {e}");
        assert!(
            e.to_lowercase().contains(&hint.to_lowercase()),
            "{objective}: {e}"
        );
    }
}

#[test]
fn the_centre_suite_moves_every_minimiser_off_the_centre_and_keeps_the_optimum() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("suites/functions-shifted.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let s = Suite::parse(&text, &path).unwrap();
    let mut moved = 0;
    for o in &s.objectives {
        let f = &o.objective;
        let optimum = f
            .optimum()
            .expect("a moved test function keeps a known optimum");
        let b = f.bounds();
        let centre: Vec<f64> = (0..f.dim())
            .map(|i| 0.5 * (b.lower()[i] + b.upper()[i]))
            .collect();
        let at_centre = f.evaluate(&centre);
        let is_moved = o.params.str("shift") == "random";
        if o.kind == "griewank" {
            // The formula's minimiser is the centre; a moved one is not there.
            assert_eq!(at_centre == optimum, !is_moved, "{}: {at_centre}", o.id);
        }
        if is_moved {
            moved += 1;
            assert!(
                at_centre > optimum + 1e-3,
                "{}: {at_centre} vs {optimum}",
                o.id
            );
        }
        // No corner or face centre of the box is below the optimum.
        for k in 0..4usize {
            let x: Vec<f64> = (0..f.dim())
                .map(|i| {
                    if k >> i & 1 == 1 {
                        b.upper()[i]
                    } else {
                        b.lower()[i]
                    }
                })
                .collect();
            assert!(f.evaluate(&x) >= optimum, "{} at {x:?}", o.id);
        }
    }
    assert_eq!(moved, 12, "three instances x two variants x two functions");
}

#[test]
fn an_instance_is_the_same_problem_in_every_suite_whatever_its_seed_or_id() {
    let a = "kind = \"schwefel\"\ndim = 3\nshift = \"random\"\nrotate = true\ninstance = 4";
    let b = format!("id = \"other-name\"\n{a}");
    let fa = built(a);
    let fb = suite_with_seed(&b, 99).unwrap().objectives[0]
        .objective
        .clone();
    let other = built(&a.replace("instance = 4", "instance = 5"));
    let probes = [
        [1.0, 2.0, 3.0],
        [-499.0, 250.5, 100.0],
        [420.0, -420.0, 0.0],
    ];
    let mut differs = false;
    for x in probes {
        assert_eq!(fa.evaluate(&x).to_bits(), fb.evaluate(&x).to_bits());
        differs |= fa.evaluate(&x) != other.evaluate(&x);
    }
    assert!(differs, "instances 4 and 5 are different problems");
    // Without shift or rotate, the keys' defaults leave the formula as it was.
    let plain = built("kind = \"griewank\"\ndim = 2");
    let explicit =
        built("kind = \"griewank\"\ndim = 2\nshift = \"none\"\nrotate = false\ninstance = 1");
    assert_eq!(
        plain.evaluate(&[3.0, -7.0]).to_bits(),
        explicit.evaluate(&[3.0, -7.0]).to_bits()
    );
    assert_eq!(plain.evaluate(&[0.0, 0.0]), 0.0);
}
