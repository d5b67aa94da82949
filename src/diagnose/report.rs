//! What a diagnosis shows: a short text, `diagnosis.json` and the figures.

use super::{Diagnosis, Series, residual, steps};
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
        if d.unexplained && !d.residual_structured {
            format!(
                "the training residual is noise, yet the validation record is predicted at {:.1}x the noise floor (above it over its whole band): its drive excites what the training drive does not show, and nothing fitted on the training record predicts it (a training drive like the validation one would)",
                fm.validate_rmse / d.noise_floor.max(1e-300)
            )
        } else if d.unexplained {
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
    // Each refusal with what its round named instead: a candidate of plausible parameters,
    // or the model without an effect (the stronger test the refused one did not pass).
    let refused: Vec<String> = d
        .candidates
        .iter()
        .filter(|c| c.refused.is_some())
        .map(|c| {
            let instead = d
                .candidates
                .iter()
                .find(|o| o.accepted && o.round == c.round)
                .map_or("nothing (the model without it)".to_string(), |o| {
                    format!("{} [{}]", o.name, o.form)
                });
            format!(
                "{} [{}] (round {}; preferred instead: {instead})",
                c.name, c.form, c.round
            )
        })
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
        let (title, decor) = if i == 1 {
            judging_decor(s, set)
        } else {
            (
                format!("{set}: residual over time"),
                render::Decor::default(),
            )
        };
        render::lines_with(
            &dir.join(format!("{name}_residual_time")),
            &title,
            &[(bl.clone(), pts(&eb)), (format!("final ({fl})"), pts(&ef))],
            "time [s]",
            &unit(2, RESIDUAL),
            (false, false),
            &decor,
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
            &unit(2, "mean residual, measured − model"),
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
    method_figures(d, dir)
}

/// The residual's axis label: its sign said.
const RESIDUAL: &str = "residual, measured − model";

/// What marks how the validation records were judged on their residual's figure: each
/// record's lead shaded (fitted, not scored) and a rule at each forecast origin.
pub fn judging_marks(s: &Series) -> render::Decor {
    judging_decor(s, "validate").1
}

/// The validation residual's title and [`judging_marks`].
fn judging_decor(s: &Series, set: &str) -> (String, render::Decor) {
    let t = &s.t[1];
    let at = |k: usize| t[k.min(t.len().saturating_sub(1))];
    let decor = render::Decor {
        band: Some((
            "lead (fitted, not scored)".into(),
            s.leads.iter().map(|r| (at(r.start), at(r.end))).collect(),
        )),
        rules: Some((
            "forecast origins".into(),
            s.origins.iter().map(|&k| at(k)).collect(),
        )),
        ..render::Decor::default()
    };
    (
        format!("{set}: residual predicted from each forecast origin"),
        decor,
    )
}

/// The figures of the method's four findings, each written when its finding is there:
/// the residual over the training drive's holds (`train_steps`), each core's final model
/// on the validation records (`validate_cores`), the residual against the feature it
/// depends on most (`validate_unexplained`).
fn method_figures(d: &Diagnosis, dir: &Path) -> Result<()> {
    steps_figure(d, dir)?;
    cores_figure(d, dir)?;
    unexplained_figure(d, dir)
}

/// The unit of the output in brackets, or nothing.
fn bracket(u: &str) -> String {
    if u.is_empty() {
        String::new()
    } else {
        format!(" [{u}]")
    }
}

/// The holds' points of the baseline's and the final model's training residual: the move
/// before each hold against the residual's change over it.
pub fn step_points(s: &Series) -> [Vec<(f64, f64)>; 2] {
    let on = |out: &[f64]| -> Vec<(f64, f64)> {
        let e: Vec<f64> = s.y[0].iter().zip(out).map(|(y, m)| y - m).collect();
        steps::hold_changes(&s.u[0], &e, s.dt[0])
            .into_iter()
            .map(|(h, c)| (h.step, c))
            .collect()
    };
    [on(&s.baseline[0]), on(&s.final_model[0])]
}

/// `train_steps`: for each hold of the training drive the residual's change over it against
/// the move before it, for the baseline and the final model, with the line through the
/// origin the correlation measures and the verdict; written when the drive has holds.
fn steps_figure(d: &Diagnosis, dir: &Path) -> Result<()> {
    write_steps(&d.series, &d.step_evidence, &d.baseline.model, &d.unit, dir)
}

/// [`steps_figure`] from the series, the step evidence, the baseline's name and the
/// output's unit.
pub fn write_steps(
    s: &Series,
    ev: &super::StepsReport,
    baseline: &str,
    unit: &str,
    dir: &Path,
) -> Result<()> {
    let points = step_points(s);
    let k = points[0].len();
    if k == 0 {
        return Ok(());
    }
    let p = |x: f64| sig(x, 2);
    let evidence = [&ev.baseline, &ev.final_model];
    let names = [
        format!("baseline ({baseline})"),
        format!("final ({})", s.final_label),
    ];
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (i, pts) in points.iter().enumerate() {
        let verdict = match evidence[i] {
            Some(e) => format!("{}, p = {}", e.verdict, p(e.p_value)),
            None => "too few holds".into(),
        };
        series.push((format!("{}: {verdict}", names[i]), pts.clone()));
    }
    // The line through the origin whose fit the correlation measures, where it is judged.
    let (lo, hi) = points[0]
        .iter()
        .fold((0.0f64, 0.0f64), |(a, b), q| (a.min(q.0), b.max(q.0)));
    let mut styles = vec![0, 1];
    for (i, pts) in points.iter().enumerate() {
        if let Some(e) = evidence[i] {
            styles.push(i);
            let sxx: f64 = pts.iter().map(|q| q.0 * q.0).sum();
            let sxd: f64 = pts.iter().map(|q| q.0 * q.1).sum();
            let b = if sxx > 0.0 { sxd / sxx } else { 0.0 };
            series.push((
                format!(
                    "{}: change ∝ move, r = {}",
                    if i == 0 { "baseline" } else { "final" },
                    p(e.correlation)
                ),
                vec![(lo, lo * b), (hi, hi * b)],
            ));
        }
    }
    let up = points[0].iter().filter(|q| q.0 > 0.0).count();
    let title = if evidence.iter().any(|e| e.is_some()) {
        format!("train: residual over the drive's {k} holds ({up} after a rise)")
    } else {
        format!(
            "train: residual over the drive's {k} hold{} (a verdict needs 2 up, 2 down, 5 in all)",
            if k == 1 { "" } else { "s" }
        )
    };
    // Both directions of the move and no change shown, whatever the holds.
    let reach = points[0].iter().fold(0.0f64, |m, q| m.max(q.0.abs()));
    let (lo_d, hi_d) = points
        .iter()
        .flatten()
        .fold((0.0f64, 0.0f64), |(a, b), q| (a.min(q.1), b.max(q.1)));
    let pad = 0.12 * (hi_d - lo_d);
    let input = if s.input_unit.is_empty() {
        "move before the hold".to_string()
    } else {
        format!("move before the hold [{}]", s.input_unit)
    };
    render::lines_with(
        &dir.join("train_steps"),
        &title,
        &series,
        &input,
        &format!("Δ(measured − model) over the hold{}", bracket(unit)),
        (false, false),
        &render::Decor {
            points: vec![0, 1],
            include: vec![(-1.15 * reach, lo_d - pad), (1.15 * reach, hi_d + pad)],
            styles,
            ..render::Decor::default()
        },
    )
}

/// RMS of `e` in consecutive windows of `w` samples, at each window's middle time.
fn windowed_rms(t: &[f64], e: &[f64], w: usize) -> Vec<(f64, f64)> {
    let w = w.max(1);
    t.chunks(w)
        .zip(e.chunks(w))
        .map(|(tc, ec)| {
            let ms = ec.iter().map(|v| v * v).sum::<f64>() / ec.len() as f64;
            (tc[tc.len() / 2], ms.sqrt())
        })
        .collect()
}

/// The validation residual of each core's final model, as RMS in windows of about a
/// second (at least 20 samples): one series per trial, the lead shaded and the origins
/// marked as in `validate_residual_time`.
pub fn core_series(d: &Diagnosis) -> Vec<(String, Vec<(f64, f64)>)> {
    let s = &d.series;
    let Some(c) = &d.core_choice else {
        return Vec::new();
    };
    let w = ((1.0 / s.dt[1]).round() as usize).max(20);
    let u = bracket(&d.unit);
    c.trials
        .iter()
        .map(|t| {
            let e: Vec<f64> = s.y[1]
                .iter()
                .zip(&t.validate_out)
                .map(|(y, m)| y - m)
                .collect();
            (
                format!(
                    "{}{}: validation RMSE {}{}",
                    t.model,
                    if t.chosen { " (kept)" } else { "" },
                    sig(t.validate_rmse, 3),
                    u.replace(['[', ']'], "")
                ),
                windowed_rms(&s.t[1], &e, w),
            )
        })
        .collect()
}

/// `validate_cores`: each core's final model predicting the validation records; written
/// when more than one core was searched.
fn cores_figure(d: &Diagnosis, dir: &Path) -> Result<()> {
    if d.core_choice.as_ref().is_none_or(|c| c.trials.len() < 2) {
        return Ok(());
    }
    let series = core_series(d);
    let (_, decor) = judging_decor(&d.series, "validate");
    let w = ((1.0 / d.series.dt[1]).round() as usize).max(20);
    render::lines_with(
        &dir.join("validate_cores"),
        &format!(
            "validate: each core's final model, residual RMS per {} s",
            sig(w as f64 * d.series.dt[1], 2)
        ),
        &series,
        "time [s]",
        &format!("RMS of the residual{}", bracket(&d.unit)),
        (false, false),
        &decor,
    )
}

/// Means of `v` in 20 equal-count bins of `x` (the samples where `keep` holds), at each
/// bin's mean `x`.
fn binned_by(x: &[f64], v: &[f64], keep: impl Fn(usize) -> bool) -> Vec<(f64, f64)> {
    let mut idx: Vec<usize> = (0..x.len().min(v.len()))
        .filter(|&i| keep(i) && x[i].is_finite() && v[i].is_finite())
        .collect();
    if idx.is_empty() {
        return Vec::new();
    }
    idx.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
    let bins = 20.min(idx.len());
    (0..bins)
        .map(|b| {
            let part = &idx[b * idx.len() / bins..(b + 1) * idx.len() / bins];
            let m = |f: &dyn Fn(usize) -> f64| {
                part.iter().map(|&i| f(i)).sum::<f64>() / part.len() as f64
            };
            (m(&|i| x[i]), m(&|i| v[i]))
        })
        .collect()
}

/// The series of `validate_unexplained`: the binned training and validation residual
/// against the feature and the training correction (per direction when it depends on it).
pub fn unexplained_series(d: &Diagnosis) -> Vec<(String, Vec<(f64, f64)>)> {
    let Some(p) = d.outside_vocabulary.as_ref().and_then(|o| o.plot.as_ref()) else {
        return Vec::new();
    };
    let dirs: &[(&str, f64)] = if p.by_direction {
        &[(", drive rising", 1.0), (", drive falling", -1.0)]
    } else {
        &[("", 0.0)]
    };
    let mut out = Vec::new();
    for &(dname, sign) in dirs {
        let on = |dv: &[f64], i: usize| !p.by_direction || dv[i] == sign;
        out.push((
            format!("training residual{dname}"),
            binned_by(&p.train_x, &p.train_e, |i| on(&p.train_dir, i)),
        ));
        out.push((
            format!("validation residual (scored){dname}"),
            binned_by(&p.validate_x, &p.validate_e, |i| on(&p.validate_dir, i)),
        ));
        out.push((
            format!("correction fitted on training{dname}"),
            binned_by(&p.train_x, &p.train_correction, |i| on(&p.train_dir, i)),
        ));
    }
    out
}

/// `validate_unexplained`: the final residual against the feature it depends on most;
/// written when structure is left outside the vocabulary.
fn unexplained_figure(d: &Diagnosis, dir: &Path) -> Result<()> {
    let Some(o) = &d.outside_vocabulary else {
        return Ok(());
    };
    let Some(p) = &o.plot else {
        return Ok(());
    };
    let mut series = unexplained_series(d);
    let pct = |x: f64| format!("{} %", sig(100.0 * x, 2));
    if let Some(r) = o.ranked.iter().find(|r| r.feature == p.feature) {
        let gain = format!(
            ": removes {} of the validation mean square (95 % {} to {})",
            pct(r.gain),
            pct(r.gain_band[0]),
            pct(r.gain_band[1])
        );
        for (label, _) in series
            .iter_mut()
            .filter(|(l, _)| l.starts_with("correction"))
        {
            label.push_str(&gain);
        }
    }
    let unit = match p.unit.as_str() {
        "input" => d.series.input_unit.clone(),
        "output" => d.unit.clone(),
        "input²" if !d.series.input_unit.is_empty() => format!("{}²", d.series.input_unit),
        "input²" => String::new(),
        u => u.to_string(),
    };
    render::lines(
        &dir.join("validate_unexplained"),
        &format!("final residual against {}", p.feature),
        &series,
        &format!("{}{} (20 equal-count bins)", p.feature, bracket(&unit)),
        &format!("mean {RESIDUAL}{}", bracket(&d.unit)),
        (false, false),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::StepsReport;
    use crate::diagnose::steps::tests::staircase;

    /// A training record of steps and holds (or a sine), its residual a creep after each
    /// step, for the holds' figure.
    fn series(u: Vec<f64>, dt: f64) -> Series {
        let t: Vec<f64> = (0..u.len()).map(|k| k as f64 * dt).collect();
        let (mut last, mut since, mut step) = (u[0], 0usize, 0.0);
        let y: Vec<f64> = u
            .iter()
            .enumerate()
            .map(|(k, &v)| {
                if v != last {
                    (step, last, since) = (v - last, v, k);
                }
                v + 0.01 * step * (1.0 + (k - since) as f64 * dt / 0.01).log10()
            })
            .collect();
        Series {
            t: [t.clone(), t],
            u: [u.clone(), u.clone()],
            y: [y.clone(), y],
            baseline: [u.clone(), u.clone()],
            final_model: [u.clone(), u],
            dt: [dt, dt],
            final_label: "bouc-wen+creep".into(),
            input_unit: "V".into(),
            ..Series::default()
        }
    }

    #[test]
    fn the_holds_figure_has_one_point_per_hold_and_is_left_out_without_holds() {
        let dt = 0.01;
        let u = staircase(&[0.0, 80.0, 20.0, 100.0, 40.0, 90.0, 10.0, 60.0], 2.0, dt);
        let s = series(u, dt);
        let holds = steps::holds(&s.u[0], dt);
        assert_eq!(holds.len(), 7);
        let pts = step_points(&s);
        for p in &pts {
            assert_eq!(p.len(), holds.len());
            // The move of each point is its hold's; creep follows it.
            for (q, h) in p.iter().zip(&holds) {
                assert_eq!(q.0, h.step);
                assert!(q.1 * h.step > 0.0, "{q:?} {h:?}");
            }
        }
        let e: Vec<f64> = s.y[0].iter().zip(&s.u[0]).map(|(y, u)| y - u).collect();
        let ev = StepsReport {
            holds: holds.len(),
            baseline: steps::step_evidence(&s.u[0], &e, dt, 1),
            final_model: None,
        };
        assert_eq!(ev.baseline.as_ref().unwrap().verdict, steps::FOLLOWS);
        let dir = tempfile::tempdir().unwrap();
        write_steps(&s, &ev, "bouc-wen", "um", dir.path()).unwrap();
        for ext in ["png", "svg"] {
            assert!(dir.path().join(format!("train_steps.{ext}")).exists());
        }
        // A sine has no holds: no figure.
        let sine: Vec<f64> = (0..2000).map(|k| (k as f64 * dt).sin()).collect();
        let s = series(sine, dt);
        assert!(step_points(&s)[0].is_empty());
        let dir = tempfile::tempdir().unwrap();
        write_steps(&s, &StepsReport::default(), "bouc-wen", "um", dir.path()).unwrap();
        assert!(!dir.path().join("train_steps.png").exists());
    }

    #[test]
    fn the_judging_marks_shade_each_lead_and_rule_each_origin() {
        let dt = 0.01;
        let u: Vec<f64> = (0..1000).map(|k| (k as f64 * dt * 3.0).sin()).collect();
        let mut s = series(u.clone(), dt);
        let o = crate::diagnose::forecast::origins(&u);
        s.origins.clone_from(&o);
        s.leads = std::iter::once(0..o[0]).collect();
        let d = judging_marks(&s);
        let (label, band) = d.band.unwrap();
        assert!(label.starts_with("lead"));
        assert_eq!(band, vec![(0.0, s.t[1][o[0]])]);
        let (label, at) = d.rules.unwrap();
        assert_eq!(label, "forecast origins");
        let want: Vec<f64> = o.iter().map(|&k| s.t[1][k]).collect();
        assert_eq!(at, want);
    }
}
