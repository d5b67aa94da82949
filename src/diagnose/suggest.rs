//! The experiment that would settle a tie: candidate excitations from the signal library,
//! kept within the recorded input range (the actuator was driven there, so it is safe), on
//! which each tied model predicts the record and the other model, taking the freedoms it
//! has on every record (its offset, drift and initial states refitted), tries to explain
//! that prediction. What it cannot explain, relative to the noise floor, is the separation;
//! the excitation with the largest separation (the larger of the two directions: a record
//! one reading cannot explain decides, even where the other, nesting it, could) is
//! proposed, as a signal spec a lab can play. Without the refit a drift would look
//! separated from creep on any record, though on each new record it would be refitted.

use super::evaluate::from_rest;
use super::refit::{self, Fitted};
use crate::data::signal::Signal;
#[cfg(test)]
use crate::physics::structure::Form;
use crate::render::table::sig;
use serde::Serialize;
use std::sync::Arc;

/// Longest proposed record (s) of the training's kind.
pub const MAX_SECONDS: f64 = 20.0;

/// Longest record of holds (s): short enough to record.
pub const MAX_HOLD_SECONDS: f64 = 120.0;

/// Polish of every parameter of the other model to a prediction: enough to take up what
/// its structure can explain near its fit, far less than a search.
const REFIT_POLISH: u64 = 300;

/// What model `b`, all its parameters refitted (a polish from its fit), leaves of model
/// `a`'s prediction on input `x` from rest (RMS). Refitting everything, not only each
/// record's offset and drift, keeps parameters the training drive left loose (a sub-sample
/// timing, the loop shape at rates it never reached) from passing for a separation of the
/// effects.
fn unexplained(a: &Fitted, b: &Fitted, x: &[f64], seed: u64) -> f64 {
    let ya = from_rest(a, x);
    if ya.iter().any(|v| !v.is_finite()) {
        return 0.0;
    }
    let budget = refit::Budget {
        global: 0,
        swarm: 1,
        polish: REFIT_POLISH,
        starts: 1,
        global_window: 0,
        screen: 0.0,
    };
    let (x, ya) = (Arc::new(x.to_vec()), Arc::new(ya));
    let fb = refit::fit(&b.structure, &x, &ya, Some(&b.theta), None, budget, seed);
    let r = fb.rmse(x.len());
    if r.is_finite() { r } else { 0.0 }
}

/// The slowest time constant either model holds (s), 0 if none.
fn slowest(models: [&Fitted; 2]) -> f64 {
    models
        .iter()
        .flat_map(|f| f.structure.named_params(&f.theta, &f.linear.coef))
        .filter(|(n, _)| {
            matches!(
                n.as_str(),
                "creep_tau_s" | "creep_tau_slow_s" | "drift_settling_tau_s" | "rate_tau_s"
            )
        })
        .map(|(_, v)| v)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
}

/// One excitation tried.
#[derive(Clone, Debug, Serialize)]
pub struct Probe {
    /// What kind of excitation (`steps and holds`, `chirp`, ...).
    pub kind: String,
    /// The signal spec (`optbench simulate --signal`, the suites' grammar).
    pub signal: String,
    /// RMS of the difference of the two predicted outputs, over the noise floor.
    pub separation_over_noise: f64,
}

/// The proposed recording (`next_experiment` in `diagnosis.json`).
#[derive(Clone, Debug, Serialize)]
pub struct NextExperiment {
    /// The two readings to separate: `effect [form]` each (tied ones), or a candidate the
    /// validation record did not confirm and the final model.
    pub tied: [String; 2],
    /// What the recording would settle.
    pub question: String,
    pub kind: String,
    pub signal: String,
    pub duration_s: f64,
    pub dt: f64,
    /// RMS of the difference of the two models' predicted outputs (output units).
    pub separation_rms: f64,
    pub separation_over_noise: f64,
    /// Every excitation tried, best first.
    pub tried: Vec<Probe>,
}

/// A number short enough for a spec, exact to 6 significant digits.
fn num(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    let scale = 10f64.powi(5 - x.abs().log10().floor() as i32);
    format!("{}", (x * scale).round() / scale)
}

/// Steps from the middle of `[lo, hi]` to near either end and back, five holds filling
/// `duration` s.
fn steps_and_holds(lo: f64, hi: f64, duration: f64) -> String {
    let (mid, a) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    format!(
        "steps:levels={};{};{};{};{},hold={}",
        num(mid),
        num(mid + 0.9 * a),
        num(mid),
        num(mid - 0.9 * a),
        num(mid),
        num(duration / 5.0)
    )
}

/// Candidate excitations within `[lo, hi]` for a record of `duration` s sampled every
/// `dt`: `(kind, spec)`.
pub fn library(lo: f64, hi: f64, dt: f64, duration: f64) -> Vec<(String, String)> {
    let (mid, a) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let slow = 1.0 / duration;
    let fast = 0.1 / dt;
    let mut v = vec![
        (
            "steps and holds".to_string(),
            steps_and_holds(lo, hi, duration),
        ),
        (
            "chirp".to_string(),
            format!(
                "chirp:f0={},f1={},duration={},law=log,amp={},offset={}",
                num(slow),
                num(0.2 / dt),
                num(duration),
                num(0.9 * a),
                num(mid)
            ),
        ),
        (
            "rate-varied triangle".to_string(),
            format!(
                "{} + am:carrier=(triangle:freq={},amp={}),envelope=(ramp:from=0.1,to=1,duration={})",
                num(mid),
                num(10.0 * slow),
                num(0.9 * a),
                num(duration)
            ),
        ),
        (
            "multisine".to_string(),
            format!(
                "multisine:fmin={},fmax={},period={},rms={},seed=1,offset={}",
                num(slow),
                num(0.2 / dt),
                num(duration),
                num(0.3 * a),
                num(mid)
            ),
        ),
    ];
    for (k, f) in [("slow", 0.02 / dt), ("fast", fast)] {
        v.push((
            format!("small {k} probes on a slow excursion"),
            format!(
                "triangle:freq={},amp={},offset={} + sine:freq={},amp={}",
                num(slow),
                num(0.8 * a),
                num(mid),
                num(f),
                num(0.1 * a)
            ),
        ));
    }
    if lo < 0.0 && hi > 0.0 {
        v.push((
            "bipolar drive".to_string(),
            format!(
                "sine:freq={},amp={}",
                num(5.0 * slow),
                num(0.9 * lo.abs().min(hi))
            ),
        ));
    }
    v
}

/// The excitation that best separates `a` from `b` (labels `tied`), trained on input `u`
/// sampled every `dt` with noise floor `noise`.
pub(super) fn design(
    a: &Fitted,
    b: &Fitted,
    tied: [String; 2],
    u: &[f64],
    dt: f64,
    noise: f64,
) -> NextExperiment {
    let lo = u.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = u.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let duration = (u.len() as f64 * dt).clamp(200.0 * dt, MAX_SECONDS);
    let mut probes: Vec<(String, String, f64)> = library(lo, hi, dt, duration)
        .into_iter()
        .map(|(k, s)| (k, s, duration))
        .collect();
    // Holds long enough for the slowest time constant to show, and at least four times
    // the training's (a creep per decade of time has none).
    let long = (5.0 * slowest([a, b]))
        .max(4.0 * duration)
        .min(MAX_HOLD_SECONDS);
    if long > 1.5 * duration {
        probes.push((
            "long steps and holds".to_string(),
            steps_and_holds(lo, hi, long),
            long,
        ));
    }
    let mut tried: Vec<(Probe, f64, f64)> = probes
        .into_iter()
        .filter_map(|(kind, spec, seconds)| {
            let signal = Signal::parse(&spec).ok()?;
            let x = signal.sample(dt, seconds);
            // Within the recorded range (a multisine's crest may leave it).
            let inside = x.iter().all(|v| *v >= lo - 1e-9 && *v <= hi + 1e-9);
            if x.is_empty() || !inside {
                return None;
            }
            let rms = unexplained(a, b, &x, 1).max(unexplained(b, a, &x, 2));
            Some((
                Probe {
                    kind,
                    signal: signal.to_string(),
                    separation_over_noise: rms / noise.max(1e-300),
                },
                rms,
                seconds,
            ))
        })
        .collect();
    tried.sort_by(|p, q| q.1.total_cmp(&p.1));
    let (best, rms, seconds) = tried
        .first()
        .map(|(p, r, s)| (p.clone(), *r, *s))
        .unwrap_or_else(|| {
            (
                Probe {
                    kind: "none".into(),
                    signal: String::new(),
                    separation_over_noise: 0.0,
                },
                0.0,
                duration,
            )
        });
    NextExperiment {
        question: format!("tie: the records cannot tell {} from {}", tied[0], tied[1]),
        tied,
        kind: best.kind,
        signal: best.signal,
        duration_s: seconds,
        dt,
        separation_rms: rms,
        separation_over_noise: best.separation_over_noise,
        tried: tried.into_iter().map(|p| p.0).collect(),
    }
}

impl NextExperiment {
    /// Lines for the text report.
    pub fn lines(&self) -> Vec<String> {
        let mut v = vec![format!(
            "next experiment ({}) to separate {} from {}: record {} s at dt = {} s of the {} `{}`: one fitted model, all its parameters refitted, leaves {} times the noise floor (RMS) of the other's prediction unexplained",
            self.question,
            self.tied[0],
            self.tied[1],
            sig(self.duration_s, 3),
            sig(self.dt, 3),
            self.kind,
            self.signal,
            sig(self.separation_over_noise, 3)
        )];
        for p in self.tried.iter().skip(1) {
            v.push(format!(
                "  also tried: {} ({}x the noise floor)",
                p.kind,
                sig(p.separation_over_noise, 3)
            ));
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::recording::Recording;
    use crate::diagnose::evaluate::bic;
    use crate::diagnose::{Options, diagnose};
    use crate::physics::structure::{Context, Effect, Placement, Structure};
    use crate::physics::twin::{self, TwinConfig};

    /// The twin with `overrides`, driven by sines about one level at 200 Hz: on each record
    /// the slow response to that level is a settling trend, which both a creep and a drift
    /// of the record's own explain. The diagnosis must report that tie and propose a
    /// recording; made on the twin, both readings fitted afresh to it, the true one
    /// (`truth`) must lead the other by far. Returns the truth's BIC lead on the training
    /// record and on the proposed one.
    fn tie_separated_by_proposal(overrides: &str, truth: Effect) -> (f64, f64) {
        let twin = TwinConfig::parse_overrides(overrides).unwrap();
        let dt = 0.005;
        let record = |spec: &str, seconds: f64, seed: u64| {
            let u = Signal::parse(spec).unwrap().sample(dt, seconds);
            twin::recording(&twin, "twin", u, dt, seed).unwrap()
        };
        let train = record("sine:freq=1,amp=2.3,offset=2.35", 8.0, 1);
        let validate = record("sine:freq=0.6,amp=2,offset=2.35", 8.0, 2);
        let opts = Options {
            model: "bouc-wen-n1".into(),
            suggest: true,
            ..Options::default()
        };
        let d = diagnose(&train, &validate, &opts).unwrap();
        let x = d
            .next_experiment
            .as_ref()
            .expect("a tie and its experiment");
        let readings: Vec<(Effect, Form)> = x
            .tied
            .iter()
            .map(|t| {
                let (name, form) = t.trim_end_matches(']').split_once(" [").unwrap();
                let e = Effect::parse(name).unwrap();
                (e, *e.forms().iter().find(|f| f.name() == form).unwrap())
            })
            .collect();
        let effects: Vec<Effect> = readings.iter().map(|r| r.0).collect();
        assert!(
            effects.contains(&Effect::Creep) && effects.contains(&Effect::OffsetDrift),
            "{:?}",
            x.tied
        );
        assert!(x.kind.contains("steps and holds"), "{}", x.kind);
        assert!(x.separation_over_noise > 1.0, "{}", x.separation_over_noise);
        // Each reading fitted afresh to a record: the other's BIC minus the truth's.
        let lead = |r: &Recording| {
            let (u, y) = (Arc::new(r.u.clone()), Arc::new(r.y.clone()));
            let ctx = Context::from_training(&r.u, dt);
            let b: Vec<f64> = readings
                .iter()
                .map(|&p| {
                    let st = Structure::with_forms(&[p], Some(1.0), ctx, Placement::After);
                    bic(
                        &refit::fit(&st, &u, &y, None, None, opts.baseline_budget, 1),
                        r.len(),
                    )
                })
                .collect();
            let t = effects.iter().position(|&e| e == truth).unwrap();
            b[1 - t] - b[t]
        };
        let new = record(&x.signal, x.duration_s, 3);
        // Diagnosed again with the proposed record beside the training one: the true
        // reading is named, the other not.
        let again = super::super::diagnose_with_tests(
            &[train.clone(), new.clone()],
            std::slice::from_ref(&validate),
            &[],
            &Options {
                suggest: false,
                ..opts.clone()
            },
        )
        .unwrap();
        let named = again.accepted_labels();
        let other = effects.iter().find(|&&e| e != truth).unwrap();
        assert!(
            named.iter().any(|l| l.starts_with(truth.name()))
                && !named.iter().any(|l| l.starts_with(other.name())),
            "diagnosed with the proposed record: {named:?}; {}",
            again.search_stop
        );
        (lead(&train), lead(&new))
    }

    /// A 20 s creep, tied with a drift: the proposed steps and holds make it show (creep's
    /// lead -120 on the training record, 3,086 on the proposed one); diagnosed again with
    /// the proposed record beside the training one, creep alone is named (validation at
    /// 1.00x the noise floor).
    #[test]
    fn a_creep_tied_with_a_drift_is_separated_by_the_proposed_record() {
        let (before, after) = tie_separated_by_proposal(
            "amp=off,mode=off,creep=on,creep.gain_fast=0,creep.gain_slow=0.03",
            Effect::Creep,
        );
        let margin = Options::default().bic_margin;
        assert!(
            after > 10.0 * margin && after > 5.0 * before.abs(),
            "creep's BIC lead: {before} on the training record, {after} on the proposed one"
        );
    }

    /// A sensor drift, tied with creep in the search's nested fits while the validation
    /// record refitted the drift on itself (the proposed steps and holds then separated
    /// them): judged by prediction alone the drift forecasts the validation record and
    /// creep does not, so the drift alone is named, at the noise floor, with no tie left.
    #[test]
    fn a_drift_once_tied_with_creep_is_told_apart_by_prediction_alone() {
        let twin =
            TwinConfig::parse_overrides("amp=off,mode=off,drift=on,drift.rate=0.002").unwrap();
        let dt = 0.005;
        let record = |spec: &str, seed: u64| {
            let u = Signal::parse(spec).unwrap().sample(dt, 8.0);
            twin::recording(&twin, "twin", u, dt, seed).unwrap()
        };
        let train = record("sine:freq=1,amp=2.3,offset=2.35", 1);
        let validate = record("sine:freq=0.6,amp=2,offset=2.35", 2);
        let opts = Options {
            model: "bouc-wen-n1".into(),
            suggest: true,
            ..Options::default()
        };
        let d = diagnose(&train, &validate, &opts).unwrap();
        assert_eq!(d.accepted_labels(), ["offset-drift"], "{}", d.search_stop);
        assert!(d.in_final().all(|c| c.ties.is_empty()));
        let over = d.final_model.validate_rmse / d.noise_floor;
        assert!(over < 1.2, "final at {over}x the noise floor");
        // Creep was fitted and predicted worse than the drift.
        let best = |name: &str| {
            d.candidates
                .iter()
                .filter(|c| c.round == 1 && c.name == name)
                .map(|c| c.validate_rmse)
                .fold(f64::INFINITY, f64::min)
        };
        assert!(best("creep") > 3.0 * best("offset-drift"));
    }

    #[test]
    fn every_excitation_parses_and_stays_in_the_recorded_range() {
        for (lo, hi) in [(0.05, 4.65), (-2.0, 3.0), (0.2, 0.3)] {
            let lib = library(lo, hi, 1e-3, 8.0);
            assert_eq!(lib.len(), if lo < 0.0 { 7 } else { 6 });
            for (kind, spec) in lib {
                let s = Signal::parse(&spec).unwrap_or_else(|e| panic!("{kind}: {spec}: {e}"));
                // The printed spec is the parsed signal's own form.
                assert_eq!(Signal::parse(&s.to_string()).unwrap(), s);
                let x = s.sample(1e-3, 8.0);
                assert_eq!(x.len(), 8000);
                if kind != "multisine" {
                    assert!(
                        x.iter().all(|v| *v >= lo - 1e-9 && *v <= hi + 1e-9),
                        "{kind} leaves [{lo}, {hi}]"
                    );
                }
            }
        }
        assert_eq!(num(0.123456789), "0.123457");
        assert_eq!(num(2500.0), "2500");
    }
}
