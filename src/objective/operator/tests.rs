use super::*;
use crate::objective::hysteresis::tests::bw_record;
use crate::physics::model_file::Input;
use crate::physics::prandtl_ishlinskii::check_thresholds;

/// A Bouc-Wen record `(name, f, skip, samples)` in volts-like and millimetre-like scales
/// (so normalisation has work to do).
fn record(name: &str, f: f64, skip: usize, samples: usize, seed: u64) -> Recording {
    let (r, _) = bw_record(name, f, skip, samples, 0.05, 0.002, seed);
    let u = r.u.iter().map(|v| 3.0 * v).collect();
    let y = r.y.iter().map(|v| 0.2 * v - 0.1).collect();
    let mut rec = Recording::uniform(name, r.dt(), u, y).unwrap();
    rec.units = ["s".into(), "V".into(), "mm".into()];
    rec
}

fn fit(form: PiForm, search: OperatorSearch) -> OperatorFit {
    OperatorFit::pi(
        &[record("a", 1.0, 0, 600, 1)],
        &[("v".into(), record("v", 0.7, 300, 500, 2))],
        form,
        6,
        search,
        4.0,
    )
    .unwrap()
}

fn metric(o: &dyn Objective, p: &[f64], name: &str) -> f64 {
    let m = o.metrics(p);
    m.iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("no {name} in {m:?}"))
        .value
}

/// The reported optimum is the least-squares optimum: no point of the box around it is
/// lower, it equals the PI model's own fit, and its presentation is the training RMSE.
#[test]
fn the_weights_search_knows_its_exact_optimum() {
    for form in PiForm::ALL {
        let f = fit(form, OperatorSearch::Weights);
        let j = f.optimum().unwrap();
        let x = f.optimum_point().unwrap().to_vec();
        assert!(f.bounds().contains(&x));
        assert_eq!(f.evaluate(&x), j);
        let mut rng = crate::base::TrialSeed::from_u64(5).rng(0);
        for k in 0..200 {
            let mut y = x.clone();
            let i = k % y.len();
            let step =
                1e-3 * f.bounds().width(i) * (2.0 * rand::RngExt::random::<f64>(&mut rng) - 1.0);
            y[i] += step;
            f.bounds().clamp(&mut y);
            assert!(f.evaluate(&y) >= j * (1.0 - 1e-12), "{form:?} {y:?}");
        }
        // The same optimum as PiModel::fit on the normalised data.
        let t = f.data.train();
        let own =
            PiModel::fit(form, PiModel::uniform_thresholds(6, &t.u), &t.u, &t.y, 2e-3).unwrap();
        let out = own.simulate(&t.u, 2e-3);
        let sse: f64 = t.y.iter().zip(&out).map(|(a, b)| (a - b) * (a - b)).sum();
        assert!(
            (0.5 * sse - j).abs() <= 1e-9 * j,
            "{form:?}: {} vs {j}",
            0.5 * sse
        );
        let rmse = f.presentation().unwrap().apply(j);
        assert!((rmse - metric(&f, &x, "train RMSE [mm]")).abs() < 1e-12 * rmse);
        assert_eq!(metric(&f, &x, "train RMSE above the optimum [mm]"), 0.0);
        let mid: Vec<f64> = f
            .bounds()
            .lower()
            .iter()
            .zip(f.bounds().upper())
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        assert!(metric(&f, &mid, "train RMSE above the optimum [mm]") > 0.0);
    }
}

/// Bounds are chosen from the data: too tight a box is refused with the coefficient named.
#[test]
fn a_box_that_misses_the_optimum_is_refused() {
    let e = OperatorFit::pi(
        &[record("a", 1.0, 0, 600, 1)],
        &[],
        PiForm::Plain,
        6,
        OperatorSearch::Weights,
        1e-3,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        e.contains("lies outside its search range") && e.contains("raise coefficient_bound"),
        "{e}"
    );
}

/// Equal increments give the uniform thresholds (the same cost as the weights search);
/// any increments give strictly increasing thresholds below r_max.
#[test]
fn the_full_search_keeps_thresholds_ordered() {
    for form in PiForm::ALL {
        let w = fit(form, OperatorSearch::Weights);
        let a = fit(form, OperatorSearch::All);
        assert_eq!(a.dim(), w.dim() + 6);
        assert!(a.optimum().is_none());
        let x = w.optimum_point().unwrap();
        let mut p = vec![0.7; 6];
        p.extend_from_slice(x);
        let (jw, ja) = (w.evaluate(x), a.evaluate(&p));
        assert!((jw - ja).abs() <= 1e-12 * jw, "{form:?}: {jw} vs {ja}");
        let s = a.shape.as_ref().unwrap();
        let mut rng = crate::base::TrialSeed::from_u64(3).rng(0);
        for _ in 0..100 {
            a.bounds().sample(&mut rng, &mut p);
            let r = s.thresholds(&p[..6]);
            assert_eq!(r.len(), 6);
            check_thresholds(&r).unwrap();
            assert!(r[5] < s.r_max);
        }
    }
}

/// Non-finite points cost the finite cap, counted as a penalty; points in the box cost less.
#[test]
fn non_finite_points_cost_the_penalty() {
    let f = fit(PiForm::RateDependent, OperatorSearch::Weights);
    let cap = f.penalty_threshold().unwrap();
    let mut p = f.optimum_point().unwrap().to_vec();
    p[1] = f64::NAN;
    assert_eq!(f.evaluate(&p), cap);
    let mut r = Vec::new();
    assert_eq!(f.residuals(&p, &mut r), Some(cap));
    assert!(r.is_empty());
    p[1] = f64::MAX;
    assert_eq!(f.evaluate(&p), cap);
    let corner = f.bounds().upper().to_vec();
    assert!(f.evaluate(&corner) < cap);
}

/// The written model (de-normalised, in the recording's units) predicts what the fit
/// scored on every record, for every form and both searches, and reads back.
#[test]
fn the_model_file_reproduces_the_fits_errors() {
    let path = std::path::Path::new("model.json");
    let mut rng = crate::base::TrialSeed::from_u64(8).rng(0);
    for form in PiForm::ALL {
        for search in [OperatorSearch::Weights, OperatorSearch::All] {
            let f = fit(form, search);
            let mut p = vec![0.0; f.dim()];
            f.bounds().sample(&mut rng, &mut p);
            let m = f.model(&p);
            assert_eq!(m.kind, "pi");
            assert_eq!(m.units.output, "mm");
            let json = serde_json::to_string(&m).unwrap();
            let back: ModelFile = serde_json::from_str(&json).unwrap();
            for (label, rec) in f.recordings() {
                let input = Input {
                    u: &rec.u,
                    y: Some(&rec.y),
                    dt: rec.dt(),
                };
                let out = back.run(path, &input, None).unwrap();
                let got = back.rmse(&rec.y, &out);
                let want = metric(&f, &p, &format!("{label} RMSE [mm]"));
                assert!(
                    (got - want).abs() <= 1e-9 * want,
                    "{form:?} {search:?} {label}: {got} vs {want}"
                );
            }
            let names: Vec<String> = f.named_params(&p).into_iter().map(|n| n.0).collect();
            assert_eq!(names[0], "w0 [mm/V]", "{names:?}");
            assert!(names.contains(&"d0 [mm]".to_string()), "{names:?}");
            assert!(names.contains(&"r5 [V]".to_string()), "{names:?}");
            assert!(!names.iter().any(|n| n.starts_with('s')), "{names:?}");
        }
    }
}
