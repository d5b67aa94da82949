//! What a diagnosis shows: a short text, `diagnosis.json` and the figures.

use super::{Diagnosis, residual};
use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use crate::physics::model_file;
use crate::render;
use crate::render::table::sig;
use std::fmt::Write as _;
use std::path::Path;

/// The short human report.
pub fn text(d: &Diagnosis) -> String {
    let u = if d.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", d.unit)
    };
    let f = |x: f64| sig(x, 3);
    // An interval without trailing zeros (0.001, 0.0025).
    let step = |x: f64| {
        let t = sig(x, 4);
        if t.contains('.') && !t.contains('e') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    // `N samples every dt s`, or for several records each one's.
    let sampled = |i: usize| -> String {
        match d.records[i].as_slice() {
            [(n, dt)] => format!("{n} samples every {} s", step(*dt)),
            parts => {
                let each: Vec<String> = parts
                    .iter()
                    .map(|&(n, dt)| format!("{n} every {} s", step(dt)))
                    .collect();
                format!("{} records: {}", parts.len(), each.join(", "))
            }
        }
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        "diagnosis of {} ({}) against {} ({}), model {}",
        d.train,
        sampled(0),
        d.validate,
        sampled(1),
        d.model
    );
    let _ = writeln!(
        s,
        "noise floor (from the data): {}{u} RMS{}",
        f(d.noise_floor),
        if d.noise_floor_settled {
            ""
        } else {
            " (not settled: the 4th and 5th differences disagree, signal is left in them; an upper bound, the noise-floor stop is off)"
        }
    );
    let b = &d.baseline;
    if let Some(c) = &d.core_choice {
        let _ = writeln!(s, "core: {}", c.finding);
        for t in c.trials.iter().filter(|_| c.trials.len() > 1) {
            let _ = writeln!(
                s,
                "  {} {:<9} {:<48} validation RMSE {}{u} (band {}-{})",
                if t.chosen { "*" } else { " " },
                t.core,
                t.model,
                f(t.validate_rmse),
                f(t.validate_band[0]),
                f(t.validate_band[1])
            );
        }
    }
    let _ = writeln!(s, "exponent: {}", d.exponent);
    for na in &d.not_applicable {
        let _ = writeln!(s, "not searched: {na}");
    }
    let _ = writeln!(
        s,
        "baseline {}: train RMSE {}{u}, validation RMSE {}{u} (band {}-{}, {:.1}x the noise floor)",
        b.model,
        f(b.train_rmse),
        f(b.validate_rmse),
        f(b.validate_band[0]),
        f(b.validate_band[1]),
        b.validate_rmse / d.noise_floor.max(1e-300)
    );
    let _ = writeln!(
        s,
        "residual tests: score {} (p = {:.2} against {} bootstrap refits of the baseline)",
        f(b.score),
        b.p_value,
        d.bootstrap_scores.len()
    );
    for t in &b.tests {
        if t.ratio() > 1.0 {
            let _ = writeln!(
                s,
                "  fails: {} = {} > {}{}",
                t.name,
                f(t.statistic),
                f(t.critical),
                t.lag.map_or(String::new(), |l| format!(" at lag {l}"))
            );
        }
    }
    if d.located.is_empty() {
        let _ = writeln!(s, "where: nothing stands out of the noise");
    } else {
        let _ = writeln!(s, "where:");
        for l in &d.located {
            let _ = writeln!(s, "  [{}] {}", l.place, l.detail);
        }
    }
    let mut round = 0;
    for c in &d.candidates {
        if c.round != round {
            round = c.round;
            let _ = writeln!(s, "round {round}, extending {}:", c.parent);
        }
        let _ = writeln!(
            s,
            "  {} {:<40} ΔBIC {:>9}  validation RMSE {}{u}  evidence {}",
            match (c.accepted, c.dropped) {
                (true, false) => "+",
                (true, true) => "-",
                _ => " ",
            },
            format!(
                "{} [{}]",
                match &c.placement {
                    Some(p) if p != "after-hysteresis" => format!("{}({p})", c.name),
                    _ => c.name.clone(),
                },
                c.form
            ),
            f(c.delta_bic),
            f(c.validate_rmse),
            f(c.validate_ic)
        );
        for n in &c.notes {
            let _ = writeln!(s, "      note: {n}");
        }
        for t in &c.ties {
            let _ = writeln!(s, "      = tied: {}", t.why);
        }
        if c.accepted {
            for g in &c.plausibility {
                let _ = writeln!(s, "      ! accepted although {}", g.line());
            }
        }
    }
    if d.candidates.iter().any(|c| c.dropped) {
        let _ = writeln!(
            s,
            "  (- accepted, then dropped by the backward step or an exchange: its note says which)"
        );
    }
    for c in d.in_final() {
        let _ = writeln!(s, "{} [{}]: {}", c.name, c.form, c.transfer);
    }
    if !d.nuisances.is_empty() {
        let parts: Vec<String> = d
            .nuisances
            .iter()
            .map(|(k, v)| format!("{k} {}", sig(*v, 3)))
            .collect();
        let _ = writeln!(
            s,
            "nuisances (the recording set-up, not named as physics): {}",
            parts.join(", ")
        );
    }
    if !d.hold_trials.is_empty() {
        let parts: Vec<String> = d
            .hold_trials
            .iter()
            .map(|h| {
                format!(
                    "{} {} (validation RMSE {}{u})",
                    h.hold,
                    sig(h.evidence, 6),
                    sig(h.validate_rmse, 3)
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "hold chosen by the data (training BIC + validation evidence, lowest kept): {}; kept {}",
            parts.join(", "),
            d.hold
        );
    }
    let fm = &d.final_model;
    if d.left_out.is_empty() {
        let _ = writeln!(
            s,
            "{}",
            if d.unexplained {
                "left out: no candidate is accepted, yet the plain model is not enough (below)"
            } else {
                "left out: nothing; the plain model is enough for these data"
            }
        );
    } else {
        let _ = writeln!(s, "left out: {}", d.left_out.join(", "));
        let _ = writeln!(
            s,
            "final {}: train RMSE {}{u}, validation RMSE {}{u} ({:.1}x the noise floor)",
            fm.model,
            f(fm.train_rmse),
            f(fm.validate_rmse),
            fm.validate_rmse / d.noise_floor.max(1e-300)
        );
        for (k, v) in &fm.params {
            let _ = writeln!(s, "  {k:<22} {}", sig(*v, 5));
        }
    }
    if !fm.plausibility.is_empty() {
        let _ = writeln!(
            s,
            "plausibility of the final model (the training record's drive excites up to {} Hz):",
            sig(d.excited_band_hz, 3)
        );
        for g in &fm.plausibility {
            let _ = writeln!(s, "  ! {}", g.line());
        }
    }
    for t in &d.tests {
        let _ = writeln!(
            s,
            "test {} ({} samples, free run from the input alone, {}): baseline RMSE {}{u}, final RMSE {}{u}",
            t.name,
            t.samples,
            t.protocol,
            f(t.baseline_rmse),
            f(t.final_rmse)
        );
    }
    let _ = writeln!(
        s,
        "{}",
        if d.unexplained {
            "unexplained structure remains in the final residual (battery fails beyond every bootstrap refit)".to_string()
        } else if d.residual_structured {
            format!(
                "the battery still finds structure in the final residual, but at {}{u} RMS it is below the training data's resolution ({}{u}, half their noise floor): nothing a fit to them can explain",
                f(d.final_model.validate_rmse),
                f(d.resolution)
            )
        } else {
            "no structure left that the residual tests can tell from noise".to_string()
        }
    );
    if let Some(o) = &d.outside_vocabulary {
        let _ = writeln!(s, "outside the vocabulary: {}", o.text);
    }
    for c in &d.couplings {
        let _ = writeln!(s, "coupling: {}", c.line());
    }
    let ties: Vec<String> = d
        .in_final()
        .flat_map(|c| {
            c.ties
                .iter()
                .map(move |t| format!("{} with {} [{}]", c.name, t.name, t.form))
        })
        .collect();
    if !ties.is_empty() {
        let _ = writeln!(
            s,
            "tied (the records cannot tell them apart; see '= tied' above): {}",
            ties.join("; ")
        );
        match &d.next_experiment {
            Some(x) => {
                for line in x.lines() {
                    let _ = writeln!(s, "{line}");
                }
            }
            None => {
                let _ = writeln!(
                    s,
                    "  (--suggest designs the recording that would separate them)"
                );
            }
        }
    } else if let Some(x) = &d.next_experiment {
        for line in x.lines() {
            let _ = writeln!(s, "{line}");
        }
    }
    if let Some(x) = &d.next_experiment_unexplained {
        for line in x.lines() {
            let _ = writeln!(s, "{line}");
        }
    }
    for (name, e) in [
        ("baseline", &d.step_evidence.baseline),
        ("final model", &d.step_evidence.final_model),
    ] {
        if let Some(e) = e {
            let _ = writeln!(
                s,
                "the {name}'s training residual over the drive's holds ({} after a rise, {} after a fall): {} (change per unit of the move {} after rises, {} after falls; correlation with the moves {:.2}, sign-flip p = {:.3}; common change t = {:.1})",
                e.up,
                e.down,
                e.verdict,
                f(e.per_unit_up),
                f(e.per_unit_down),
                e.correlation,
                e.p_value,
                e.common_t
            );
        }
    }
    let refused: Vec<String> = d
        .candidates
        .iter()
        .filter(|c| c.evidence.contains("refused"))
        .map(|c| format!("{} [{}] (round {})", c.name, c.form, c.round))
        .collect();
    if !refused.is_empty() {
        let _ = writeln!(
            s,
            "not named although the gate passed, their own parameters implausible or at a bound (see their evidence): {}",
            refused.join(", ")
        );
    }
    let scored: usize = d.validation_judging.iter().map(|j| j.scored).sum();
    let all: usize = d.validation_judging.iter().map(|j| j.samples).sum();
    let _ = writeln!(
        s,
        "judged {} ({scored} of {all} validation samples scored)",
        d.judging_rule
    );
    let _ = writeln!(s, "search ended {}", d.search_stop);
    let _ = writeln!(s, "{} evaluations, {:.1} s", d.evaluations, d.wall_s);
    s
}

/// Writes `dir/diagnosis.json` and the figures (`dir` is created).
pub fn write(d: &Diagnosis, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::io(format!("creating {}", dir.display()), e))?;
    let mut json = serde_json::to_vec_pretty(d).expect("serialisable");
    json.push(b'\n');
    atomic_write(&dir.join("diagnosis.json"), &json)?;
    write_model(d, dir)?;
    figures(d, dir)
}

/// `model.json` of the final model, and its output beside the measured one on the training
/// and validation data (`train_predicted.csv`, `validate_predicted.csv`).
fn write_model(d: &Diagnosis, dir: &Path) -> Result<()> {
    d.model_file.write(&dir.join("model.json"))?;
    let columns = d.columns.clone().unwrap_or_default();
    let names = [
        columns.time.as_str(),
        columns.input.as_str(),
        columns.output.as_str(),
    ];
    let s = &d.series;
    for (i, label) in ["train", "validate"].into_iter().enumerate() {
        model_file::write_prediction(
            &dir.join(format!("{label}_predicted.csv")),
            names,
            &s.t[i],
            &s.u[i],
            Some(&s.y[i]),
            &s.final_model[i],
        )?;
    }
    Ok(())
}

/// Mean residual in 20 equal-count bins of `u`, per direction of `u`.
fn binned(u: &[f64], e: &[f64]) -> [Vec<(f64, f64)>; 2] {
    let n = u.len().min(e.len());
    let mut sorted: Vec<f64> = u[..n].to_vec();
    sorted.sort_by(f64::total_cmp);
    let bins = 20;
    let edges: Vec<f64> = (0..=bins).map(|i| sorted[((n - 1) * i) / bins]).collect();
    let mut acc = [[(0.0, 0.0, 0usize); 20]; 2];
    for k in 1..n {
        let d = u[k] - u[k - 1];
        if d == 0.0 {
            continue;
        }
        let dir = usize::from(d < 0.0);
        let b = edges[1..bins].iter().filter(|&&x| u[k] > x).count();
        let a = &mut acc[dir][b];
        a.0 += u[k];
        a.1 += e[k];
        a.2 += 1;
    }
    acc.map(|row| {
        row.iter()
            .filter(|a| a.2 > 0)
            .map(|a| (a.0 / a.2 as f64, a.1 / a.2 as f64))
            .collect()
    })
}

fn figures(d: &Diagnosis, dir: &Path) -> Result<()> {
    let s = &d.series;
    let unit = |i: usize, name: &str| {
        if d.unit.is_empty() || i != 2 {
            name.to_string()
        } else {
            format!("{name} [{}]", d.unit)
        }
    };
    let fl = s.final_label.clone();
    let bl = format!("baseline ({})", d.baseline.model);
    let input = if s.input_unit.is_empty() {
        "input u".to_string()
    } else {
        format!("input u [{}]", s.input_unit)
    };
    for (name, i) in [("train", 0), ("validate", 1)] {
        let parts = &d.records[i];
        // Several records: said in every title, with where each further one starts.
        let set = if parts.len() > 1 {
            let mut from = 0;
            let starts: Vec<String> = parts[..parts.len() - 1]
                .iter()
                .map(|&(n, _)| {
                    from += n;
                    format!("{} s", sig(s.t[i][from] - s.t[i][0], 3))
                })
                .collect();
            format!(
                "{name} ({} records back to back; the next from {})",
                parts.len(),
                starts.join(", ")
            )
        } else {
            name.to_string()
        };
        let set = set.as_str();
        let eb: Vec<f64> = s.y[i]
            .iter()
            .zip(&s.baseline[i])
            .map(|(a, b)| a - b)
            .collect();
        let ef: Vec<f64> = s.y[i]
            .iter()
            .zip(&s.final_model[i])
            .map(|(a, b)| a - b)
            .collect();
        let pts = |e: &[f64]| -> Vec<(f64, f64)> {
            s.t[i].iter().copied().zip(e.iter().copied()).collect()
        };
        render::lines(
            &dir.join(format!("{name}_residual_time")),
            &format!("{set}: residual over time"),
            &[(bl.clone(), pts(&eb)), (format!("final ({fl})"), pts(&ef))],
            "time [s]",
            &unit(2, "residual"),
            (false, false),
        )?;
        let [br, bf] = binned(&s.u[i], &eb);
        let [fr, ff] = binned(&s.u[i], &ef);
        render::lines(
            &dir.join(format!("{name}_residual_loop")),
            &format!("{set}: mean residual by input and direction"),
            &[
                ("baseline, u rising".into(), br),
                ("baseline, u falling".into(), bf),
                ("final, u rising".into(), fr),
                ("final, u falling".into(), ff),
            ],
            &format!("{input} (20 equal-count bins)"),
            &unit(2, "mean residual"),
            (false, false),
        )?;
        // A spectrum needs one sampling interval: the records at the first one's.
        let one_rate = if parts.len() > 1 {
            parts
                .iter()
                .take_while(|p| crate::physics::structure::same_interval(p.1, s.dt[i]))
                .map(|p| p.0)
                .sum::<usize>()
                .min(eb.len())
        } else {
            eb.len()
        };
        let sb = residual::spectra(&s.u[i][..one_rate], &eb[..one_rate], s.dt[i], 1024);
        let sf = residual::spectra(&s.u[i][..one_rate], &ef[..one_rate], s.dt[i], 1024);
        let floor = 2.0 * d.noise_floor * d.noise_floor * s.dt[i];
        let psd = |sp: &residual::Spectra| -> Vec<(f64, f64)> {
            sp.freq
                .iter()
                .zip(&sp.psd_e)
                .skip(1)
                .map(|(a, b)| (*a, *b))
                .collect()
        };
        let flat: Vec<(f64, f64)> = sb.freq.iter().skip(1).map(|f| (*f, floor)).collect();
        let psd_unit = if d.unit.is_empty() {
            "residual PSD [1/Hz]".to_string()
        } else {
            format!("residual PSD [{}²/Hz]", d.unit)
        };
        render::lines(
            &dir.join(format!("{name}_residual_spectrum")),
            &if one_rate < eb.len() {
                format!("{set}: residual spectrum (Welch; the records at the first's rate)")
            } else {
                format!("{set}: residual spectrum (Welch)")
            },
            &[
                ("baseline".into(), psd(&sb)),
                (format!("final ({fl})"), psd(&sf)),
                ("noise floor".into(), flat),
            ],
            "frequency [Hz]",
            &psd_unit,
            (true, true),
        )?;
        render::loops(
            &dir.join(format!("{name}_loops")),
            &format!("{set}: measured and model loops"),
            &s.u[i],
            (render::MEASURED, &s.y[i]),
            &[
                (bl.clone(), s.baseline[i].clone()),
                (format!("final ({fl})"), s.final_model[i].clone()),
            ],
            &input,
            &unit(2, "output"),
        )?;
    }
    Ok(())
}
