use super::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A wandering input with reversals of every size (nested minor loops included).
fn wander(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut x = 0.0f64;
    let mut v = 0.0f64;
    (0..n)
        .map(|k| {
            v = 0.9 * v + 0.1 * (rng.random::<f64>() - 0.5);
            x = (x + v).clamp(-1.0, 3.0);
            x + 0.8 * (k as f64 * 0.05).sin()
        })
        .collect()
}

fn random_model(form: PiForm, n: usize, seed: u64) -> PiModel {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let thresholds: Vec<f64> = (0..n).map(|i| 0.3 * i as f64).collect();
    let weights: Vec<f64> = (0..n)
        .map(|i| {
            if i == 0 {
                0.5
            } else {
                rng.random::<f64>() * 0.3
            }
        })
        .collect();
    let rate_weights = if form == PiForm::RateDependent {
        (0..n).map(|_| rng.random::<f64>() * 0.01 - 0.003).collect()
    } else {
        Vec::new()
    };
    let poly = if form == PiForm::Asymmetric {
        vec![0.05, -0.01]
    } else {
        Vec::new()
    };
    PiModel {
        form,
        thresholds,
        weights,
        rate_weights,
        poly,
        offset: -1.7,
        input_offset: 0.0,
    }
}

#[test]
fn a_play_holds_inside_its_band_and_follows_at_the_edges() {
    let mut z = 0.0;
    for (u, want) in [(1.0, 0.5), (0.8, 0.5), (0.2, 0.5), (-0.4, 0.1), (0.0, 0.1)] {
        z = play(0.5, z, u);
        assert!((z - want).abs() < 1e-15, "input {u}: {z}");
    }
}

#[test]
fn the_inverse_composed_with_the_model_is_the_identity() {
    let model = random_model(PiForm::Plain, 12, 3);
    let inv = model.inverse().unwrap();
    // A desired output within the model's range, with minor loops.
    let yd: Vec<f64> = wander(5000, 11).iter().map(|x| -1.7 + 0.6 * x).collect();
    let u = inv.simulate(&yd, 1e-3);
    let y = model.simulate(&u, 1e-3);
    let range = 0.6 * 4.0;
    let worst = y
        .iter()
        .zip(&yd)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-12 * range, "|Γ[Γ⁻¹[y]] − y| up to {worst:e}");
    // And the other way round.
    let u0 = wander(5000, 12);
    let back = inv.simulate(&model.simulate(&u0, 1e-3), 1e-3);
    let worst = back
        .iter()
        .zip(&u0)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-12 * 4.0, "|Γ⁻¹[Γ[u]] − u| up to {worst:e}");
    // Not a trivial identity: the model is far from linear on this input.
    let linear: f64 = y
        .iter()
        .zip(&u0)
        .map(|(a, b)| (a - (-1.7 + model.weights[0] * b)).abs())
        .fold(0.0, f64::max);
    assert!(linear > 0.1, "{linear}");
}

#[test]
fn only_invertible_models_get_an_inverse() {
    let mut m = random_model(PiForm::Plain, 4, 1);
    m.weights[0] = 0.0;
    assert!(m.inverse().unwrap_err().contains("positive linear weight"));
    let r = random_model(PiForm::RateDependent, 4, 1);
    assert!(r.inverse().unwrap_err().contains("rate-dependent"));
}

#[test]
fn the_fit_recovers_the_weights_of_every_form() {
    for form in PiForm::ALL {
        let truth = random_model(form, 8, 5);
        let u = wander(4000, 21);
        let y = truth.simulate(&u, 1e-3);
        let fit = PiModel::fit(form, truth.thresholds.clone(), &u, &y, 1e-3).unwrap();
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-8);
        assert!(
            close(&fit.weights, &truth.weights),
            "{form:?}: {:?}",
            fit.weights
        );
        assert!(close(&fit.rate_weights, &truth.rate_weights), "{form:?}");
        assert!(close(&fit.poly, &truth.poly), "{form:?}");
        assert!((fit.offset - truth.offset).abs() < 1e-8, "{form:?}");
        let sim = fit.simulate(&u, 1e-3);
        let worst = sim
            .iter()
            .zip(&y)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-8, "{form:?}: {worst:e}");
    }
}

#[test]
fn fitted_weights_are_never_negative_and_satisfy_the_optimality_conditions() {
    // Data no PI model fits exactly: the best plain fit has weights at 0.
    let u = wander(3000, 31);
    let y: Vec<f64> = u.iter().map(|x| (2.0 * x).sin() + 0.1 * x * x).collect();
    let th = PiModel::uniform_thresholds(10, &u);
    let basis = PiBasis {
        form: PiForm::Plain,
        thresholds: th.clone(),
    };
    let fit = PiModel::fit(PiForm::Plain, th, &u, &y, 1e-3).unwrap();
    assert!(fit.weights.iter().all(|w| *w >= 0.0));
    assert!(fit.weights.contains(&0.0), "{:?}", fit.weights);
    let r: Vec<f64> = y
        .iter()
        .zip(fit.simulate(&u, 1e-3))
        .map(|(a, b)| a - b)
        .collect();
    let cols = basis.columns(&u, 1e-3);
    let scale = crate::base::lstsq::dot(&y, &y).sqrt();
    let mut theta = fit.weights.clone();
    theta.push(fit.offset);
    for (j, c) in cols.iter().enumerate() {
        if crate::base::lstsq::dot(c, c) == 0.0 {
            continue; // a play the input never moves
        }
        let g = crate::base::lstsq::dot(c, &r) / (crate::base::lstsq::dot(c, c).sqrt() * scale);
        if theta[j] > 0.0 || j == cols.len() - 1 {
            assert!(
                g.abs() < 1e-9,
                "column {j}: gradient {g:e} at a free coefficient"
            );
        } else {
            assert!(g <= 1e-9, "column {j}: could improve by leaving 0 ({g:e})");
        }
    }
}

#[test]
fn bad_thresholds_and_data_are_refused() {
    let u = [0.0, 1.0, 2.0];
    let y = [0.0, 1.0, 2.0];
    for (th, want) in [
        (vec![], "at least one"),
        (vec![0.1, 0.2], "must be 0"),
        (vec![0.0, 0.5, 0.5], "increase strictly"),
        (vec![0.0, f64::NAN], "increase strictly"),
    ] {
        let e = PiModel::fit(PiForm::Plain, th, &u, &y, 1e-3).unwrap_err();
        assert!(e.contains(want), "{e}");
    }
    let e = PiModel::fit(PiForm::Plain, vec![0.0], &u, &y[..2], 1e-3).unwrap_err();
    assert!(e.contains("equally long"), "{e}");
    let e = PiModel::fit(PiForm::Plain, vec![0.0], &u, &[0.0, f64::NAN, 1.0], 1e-3).unwrap_err();
    assert!(e.contains("non-finite"), "{e}");
}

#[test]
fn a_stepper_runs_as_the_simulation_does() {
    let m = random_model(PiForm::RateDependent, 6, 8);
    let u = wander(500, 2);
    let sim = m.simulate(&u, 1e-3);
    let mut s = m.stepper(1e-3);
    for (k, x) in u.iter().enumerate() {
        assert_eq!(s.step(*x), sim[k]);
    }
}
