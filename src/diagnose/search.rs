//! The search's stages on one [`Search`]: the records and the plain model, forward rounds
//! (singles, the feedback placement, pairs), the backward step, exchanges, the hold, and
//! the [`Diagnosis`] assembled.

use super::evaluate::{
    Data, Evaluated, bic, bootstrap_scores, choose_hold, evaluate, free_run, named, repolish,
    repolish_budget, summary, training_residual,
};
use super::forecast::{self, JUDGING_RULE};
use super::judge::{
    FEEDBACK_WORTH, Gate, MIN_EXPLAINED, RESOLVED_FRACTION, Verdict, at_noise_floor, beside_alone,
    creep_pinned_fast, drift_first, exchange_gate, held_at_plausible, judge, low_pass_for_timing,
    refuse_implausible, resonant, round_ties, validation_gain,
};
use super::propose::{
    MAX_EXCHANGES, Memory, Proposal, SAME_RESIDUAL, Seeds, candidate, candidate_pool, exchanges,
    fit_proposal, pair_members, pair_proposals, remember,
};
use super::refit::{self, Budget, Fitted};
use super::residual::{self, Located};
use super::{
    Candidate, Diagnosis, FreeRun, HoldTrial, ModelSummary, Options, Series, StepsReport, TestSet,
    plausible, saved, suggest,
};
use super::{steps, unexplained};
use crate::base::error::{Error, Result};
use crate::data::recording::Recording;
use crate::physics::structure::{Context, CoreKind, Effect, MAX_RECORDS, Placement, Structure};
use indicatif::ProgressBar;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

/// Several records as one: concatenated (time counted on at the first record's interval)
/// with each record's length and sampling interval, their pooled noise floor and whether
/// every record's floor settled.
struct Joined {
    record: Recording,
    parts: Vec<(usize, f64)>,
    noise: f64,
    settled: bool,
}

impl Joined {
    fn of(records: &[Recording], role: &str) -> Result<Joined> {
        if records.is_empty() || records.len() > MAX_RECORDS {
            return Err(Error::Input(format!(
                "diagnose takes 1 to {MAX_RECORDS} {role} records, not {}",
                records.len()
            )));
        }
        if let Some(r) = records.iter().find(|r| r.len() < 200) {
            return Err(Error::Input(format!(
                "diagnose needs at least 200 samples per recording ({}: {})",
                r.name,
                r.len()
            )));
        }
        let floors: Vec<(f64, bool)> = records
            .iter()
            .map(|r| residual::noise_floor_and_settled(&r.y))
            .collect();
        let n: usize = records.iter().map(Recording::len).sum();
        let power: f64 = records
            .iter()
            .zip(&floors)
            .map(|(r, f)| r.len() as f64 * f.0 * f.0)
            .sum();
        let first = &records[0];
        // One record keeps its own time stamps.
        let record = if records.len() == 1 {
            first.clone()
        } else {
            let cat = |f: fn(&Recording) -> &Vec<f64>| -> Vec<f64> {
                records.iter().flat_map(|r| f(r).iter().copied()).collect()
            };
            let name = records
                .iter()
                .map(|r| r.name.as_str())
                .collect::<Vec<_>>()
                .join(" + ");
            let mut r = Recording::uniform(name, first.dt(), cat(|r| &r.u), cat(|r| &r.y))?;
            r.units = first.units.clone();
            r
        };
        Ok(Joined {
            record,
            parts: records.iter().map(|r| (r.len(), r.dt())).collect(),
            noise: (power / n as f64).sqrt(),
            settled: floors.iter().all(|f| f.1),
        })
    }

    fn several(&self) -> bool {
        self.parts.len() > 1
    }

    /// Time stamps for figures: each record at its own interval, one after the other from
    /// the first's start.
    fn times(&self) -> Vec<f64> {
        if !self.several() {
            return self.record.t.clone();
        }
        let mut t = Vec::with_capacity(self.record.len());
        let mut at = self.record.t.first().copied().unwrap_or(0.0);
        for &(n, dt) in &self.parts {
            t.extend((0..n).map(|k| at + k as f64 * dt));
            at += n as f64 * dt;
        }
        t
    }

    /// Each record's input with its interval.
    fn inputs(&self) -> Vec<(&[f64], f64)> {
        let mut from = 0;
        self.parts
            .iter()
            .map(|&(n, dt)| {
                from += n;
                (&self.record.u[from - n..from], dt)
            })
            .collect()
    }
}

/// A round's candidate the training record supports (ΔBIC beyond the margin) that the
/// validation record does not confirm, and the model it extends.
struct Unconfirmed {
    fitted: Fitted,
    label: String,
    delta_bic: f64,
    parent: String,
}

/// What every stage of the search reads: the options (a PI core's own), the records as
/// given, the data the fits use, and the noise floor.
pub(super) struct Records {
    opts: Options,
    /// The exponent the model pins ([`Options::fixed_n`]).
    fixed_n: Option<f64>,
    tj: Joined,
    vj: Joined,
    /// The first training and validation record's sampling intervals.
    dt: f64,
    dv: f64,
    d: Data,
    ctx: Context,
    train_noise: f64,
    validate_noise: f64,
    /// Both records' noise floors pooled.
    noise: f64,
    /// Both records' floors have settled: the noise-floor stop applies.
    floor_settled: bool,
    /// The output's unit (the validation record's).
    unit: String,
}

impl Records {
    /// The records joined and checked, the data the fits use, the context of the models
    /// and the noise floor of each record.
    pub(super) fn new(train: &[Recording], validate: &[Recording], opts: &Options) -> Result<Self> {
        let fixed_n = opts.fixed_n()?;
        // A PI core takes fewer extensions and no feedback placement ([`Options::not_applicable`]).
        let opts = if opts.is_pi() {
            Options {
                effects: opts.applicable_effects(false)?,
                feedback: false,
                ..opts.clone()
            }
        } else {
            opts.clone()
        };
        let (tj, vj) = (
            Joined::of(train, "training")?,
            Joined::of(validate, "validation")?,
        );
        if vj.several() && opts.validate_periodic {
            return Err(Error::Input(
                "--validate-periodic takes one validation record (one period of a steady state)"
                    .into(),
            ));
        }
        let (train, validate) = (&tj.record, &vj.record);
        // Each record at its own sampling interval: the models are continuous-time, the
        // validation and test records' linear blocks discretised for theirs.
        let dt = tj.parts[0].1;
        let dv = vj.parts[0].1;
        let mut d = Data::new(
            train.u.clone(),
            train.y.clone(),
            validate.u.clone(),
            validate.y.clone(),
            opts.validate_periodic,
            dt,
        );
        d.dv = dv;
        let inputs = tj.inputs();
        if tj.several() {
            d.scope = plausible::Scope::of_records(&inputs, &train.y);
        }
        if vj.several() {
            d.validation_parts = Some(vj.parts.clone());
        }
        let ctx = Context::from_records(&inputs)
            .with_hold(opts.hold)
            .with_min_substeps(opts.min_substeps)
            .with_pi(opts.core(&inputs.iter().map(|r| r.0).collect::<Vec<_>>()));
        let (train_noise, train_settled) = (tj.noise, tj.settled);
        let (validate_noise, validate_settled) = (vj.noise, vj.settled);
        let noise = (0.5 * (train_noise * train_noise + validate_noise * validate_noise)).sqrt();
        let unit = validate.units[2].clone();
        Ok(Records {
            opts,
            fixed_n,
            dt,
            dv,
            d,
            ctx,
            train_noise,
            validate_noise,
            noise,
            // The noise-floor stop only where the floor is a measurement, not an upper bound.
            floor_settled: train_settled && validate_settled,
            unit,
            tj,
            vj,
        })
    }

    /// No name needing `share` of the noise variance can be earned from a validation RMSE
    /// `rmse` ([`at_noise_floor`], where the floor has settled).
    fn no_room(&self, rmse: f64, share: f64) -> bool {
        self.floor_settled && at_noise_floor(rmse, self.validate_noise, self.noise, share)
    }

    /// `st` on the training records, where there are several.
    fn on_records(&self, st: Structure) -> Structure {
        if self.tj.several() {
            st.on_records(&self.tj.parts)
        } else {
            st
        }
    }

    /// The plain model fitted to the training record, and how its exponent was chosen; also
    /// the evaluations.
    fn fit_plain(&self) -> (Evaluated, String, u64) {
        let (opts, d) = (&self.opts, &self.d);
        let plain = self.on_records(Structure::new(&[], self.fixed_n, self.ctx));
        // With n free the kernel is several times slower: explore on the first samples only
        // (the polish, and the n = 1 refit that BIC compares it with, see the whole record).
        let base_budget = match self.fixed_n {
            Some(_) => opts.baseline_budget,
            None => Budget {
                global_window: opts.placement_budget.global_window,
                ..opts.baseline_budget
            },
        };
        let base_fit = refit::fit(&plain, &d.ut, &d.yt, None, None, base_budget, opts.seed);
        let mut evaluations = base_fit.evaluations;
        let (base_fit, n_choice) = match self.fixed_n {
            Some(_) if opts.core_kind() == Some(CoreKind::Relays) => {
                let why = format!(
                    "none: a Preisach core of {} relays on {} levels (thresholds fixed, weights \
                     fitted by least squares, unconstrained in sign)",
                    plain.pi_operators(),
                    plain.context().pi.map_or(0, |p| p.operators)
                );
                (base_fit, why)
            }
            Some(_) if opts.is_pi() => {
                let why = format!(
                    "none: a Prandtl-Ishlinskii core of {} plays (thresholds fixed, weights \
                     fitted by least squares, unconstrained in sign)",
                    plain.pi_operators()
                );
                (base_fit, why)
            }
            Some(n) => (
                base_fit,
                format!("n pinned at {n} by --model {}", opts.model),
            ),
            None => {
                let (f, why, used) = self.exponent(&plain, base_fit);
                evaluations += used;
                (f, why)
            }
        };
        let base_evals_fit = base_fit.evaluations;
        let base = evaluate(base_fit, d, opts);
        evaluations += base.fitted.evaluations - base_evals_fit;
        (base, n_choice, evaluations)
    }

    /// With n free, ask BIC whether n = 1 (the closed-form kernel, ten times faster) is as
    /// good: keep n free (`free`, the fit of `plain`) only if it improves BIC by the margin.
    /// The fit kept, why, and the evaluations of the n = 1 refit.
    fn exponent(&self, plain: &Structure, free: Fitted) -> (Fitted, String, u64) {
        let (opts, d) = (&self.opts, &self.d);
        let pinned = self.on_records(Structure::new(&[], Some(1.0), self.ctx));
        let start = plain.embed(&free.theta, &pinned);
        let f1 = refit::fit(
            &pinned,
            &d.ut,
            &d.yt,
            Some(&start),
            None,
            Budget {
                global: 0,
                ..opts.baseline_budget
            },
            opts.seed,
        );
        let used = f1.evaluations;
        let (b_free, b_one) = (bic(&free, d.ut.len()), bic(&f1, d.ut.len()));
        let n_fit = free.structure.named_params(&free.theta, &free.linear.coef)[4].1;
        let sig = crate::render::table::sig;
        let (n, gain, margin) = (sig(n_fit, 4), sig(b_one - b_free, 3), opts.bic_margin);
        if b_free < b_one - margin {
            let why = format!("n fitted: {n} (BIC {gain} below n = 1's, margin {margin})");
            (free, why, used)
        } else {
            let why =
                format!("n = 1: the fitted n = {n} improves BIC by only {gain} (margin {margin})");
            (f1, why, used)
        }
    }

    /// Where the plain model `base` misses the validation record, a start-up in either
    /// record the first finding.
    fn locate(&self, base: &Evaluated) -> Vec<Located> {
        let (d, noise, unit) = (&self.d, self.noise, &self.unit);
        // Where, not how well: the whole record, its lead (fitted, not scored) included.
        let ev_base: Vec<f64> = d.yv.iter().zip(&base.out_v).map(|(y, m)| y - m).collect();
        let mut located = residual::locate(&d.uv, &ev_base, self.dv, noise, unit);
        let et_base = training_residual(&d.yt, base);
        // A start-up in either record: one finding, the longest window to leave out.
        let mut starts: Vec<String> = Vec::new();
        let mut longest = 0.0f64;
        for (record, e, step) in [
            ("training", &et_base, self.dt),
            ("validation", &ev_base, self.dv),
        ] {
            if let Some((w, share, ri, ro)) = residual::start_transient(e, step, noise) {
                let f = |x: f64| crate::render::table::sig(x, 3);
                longest = longest.max(w);
                starts.push(format!(
                    "the {record} record starts in motion: its first {w} s hold {} % of the residual power (RMS {} {unit} against {} {unit} after)",
                    f(100.0 * share),
                    f(ri),
                    f(ro)
                ));
            }
        }
        if !starts.is_empty() {
            located.insert(
                0,
                residual::Located {
                    place: "time".into(),
                    detail: format!(
                        "{}: a start-up the model does not hold (--trim-start {longest} leaves it out of every record)",
                        starts.join("; ")
                    ),
                    strength: f64::INFINITY,
                },
            );
        }
        located
    }
}

/// A forward round's proposals on one parent (the model the search has reached), their
/// fits and their verdicts, in the same order.
struct Round {
    parent: Structure,
    pool: Vec<Proposal>,
    tried: Vec<Evaluated>,
    verdicts: Vec<Verdict>,
    /// Where the parent's training residual peaks (Hz): modes are started there too.
    peaks_hz: Vec<f64>,
}

/// A proposal picked in a round: its index in the round's pool, its index in the report's
/// candidates, and what ranks it (training ΔBIC plus validation evidence).
type Pick = (usize, usize, f64);

/// The search under way: the records, the plain model and what the tests make of its
/// residual, the model reached so far and everything reported on the way there.
pub(super) struct Search {
    rec: Records,
    started: Instant,
    spin: ProgressBar,
    /// How the Bouc-Wen exponent was chosen.
    n_choice: String,
    evaluations: u64,
    /// Bootstrap scores of the battery under the fitted baseline, sorted.
    boot: Vec<f64>,
    located: Vec<Located>,
    baseline: ModelSummary,
    /// The plain model's outputs on training and validation data, for the figures.
    base_out: [Vec<f64>; 2],
    base_fitted: Fitted,
    /// The model the search has reached.
    current: Evaluated,
    current_summary: ModelSummary,
    /// The last round's reading the validation record did not confirm.
    unconfirmed: Option<Unconfirmed>,
    candidates: Vec<Candidate>,
    /// The effects named, in order.
    left_out: Vec<String>,
    round: usize,
    search_stop: String,
    /// Exchanges taken so far, each pair at most once (either way round).
    exchanged: Vec<(Effect, Effect)>,
    memory: Memory,
    exchange_note: String,
    hold_trials: Vec<HoldTrial>,
}

impl Search {
    /// Stages 1-4 of the module's description: the plain model fitted, the residual battery
    /// calibrated by the bootstrap, the residual located; the search starts from it.
    pub(super) fn baseline(rec: Records, started: Instant, spin: ProgressBar) -> Search {
        let (base, n_choice, mut evaluations) = rec.fit_plain();
        let opts = &rec.opts;
        spin.set_message(format!(
            "calibrating the residual tests ({} bootstrap refits)",
            opts.bootstrap
        ));
        let (boot, boot_evals) =
            bootstrap_scores(&base.fitted, &rec.d, rec.noise.max(1e-300), opts);
        evaluations += boot_evals;
        let located = rec.locate(&base);
        let baseline = summary(&base, &rec.d, &boot, opts.seed);
        Search {
            base_out: [base.out_t.clone(), base.out_v.clone()],
            base_fitted: base.fitted.clone(),
            current: base,
            unconfirmed: None,
            current_summary: baseline.clone(),
            candidates: Vec::new(),
            left_out: Vec::new(),
            round: 0,
            search_stop: format!("{} rounds, the most allowed", opts.max_rounds),
            exchanged: Vec::new(),
            memory: Memory::new(),
            exchange_note: String::new(),
            hold_trials: Vec::new(),
            n_choice,
            evaluations,
            boot,
            located,
            baseline,
            rec,
            started,
            spin,
        }
    }

    /// The gate of a forward round's single against the current model.
    fn gate(&self) -> Gate<'_> {
        Gate {
            band: self.current_summary.validate_band,
            margin: self.rec.opts.bic_margin,
            min_explained: MIN_EXPLAINED,
            nt: self.rec.d.ut.len(),
            noise: self.rec.noise,
            unit: &self.rec.unit,
            seed: self.rec.opts.seed,
        }
    }

    /// Whether the current model predicts the validation record above its noise even at
    /// its band's lower end (a floor not settled is an upper bound: no evidence).
    fn validation_room(&self) -> bool {
        self.rec.floor_settled
            && !self
                .rec
                .no_room(self.current_summary.validate_band[0], MIN_EXPLAINED)
    }

    /// Whether the search ends before another forward round (with why): no round left,
    /// nothing the battery can tell from noise, or the validation error at the noise floor.
    fn stops(&mut self) -> bool {
        if self.round >= self.rec.opts.max_rounds {
            return true;
        }
        let at = match self.round {
            0 => "at the baseline".to_string(),
            r => format!("after round {r}"),
        };
        // Nothing the battery can tell from noise is left (at least one of the baseline's
        // bootstrap refits scores as high): no name can be earned, the search ends. Unless
        // the validation record, whose drive may excite what the training drive barely
        // does, is predicted above its noise even at its band's lower end: the battery reads
        // the training residual only (blind seed 20261161 case 65: a 0.5-sample lag, the
        // training fit at the floor, the validation record at 1.6x it; nothing searched).
        if self.current_summary.p_value > 0.05 && !self.validation_room() {
            self.search_stop = format!(
                "{at}: the residual battery finds no structure (bootstrap p {})",
                crate::render::table::sig(self.current_summary.p_value, 2)
            );
            return true;
        }
        if self.rec.no_room(self.current.validate_rmse, MIN_EXPLAINED) {
            self.search_stop = format!(
                concat!(
                    "{}: the validation error is at the noise floor ({}x; a name must ",
                    "explain {} % of the noise variance, which would predict the ",
                    "validation record better than its noise)"
                ),
                at,
                crate::render::table::sig(
                    self.current.validate_rmse / self.rec.noise.max(1e-300),
                    3
                ),
                100.0 * MIN_EXPLAINED
            );
            return true;
        }
        false
    }

    /// A forward round (stage 5): every extension of the current model fitted and judged,
    /// pairs of the best when no single passes, the best that passes named. Whether one was
    /// (otherwise the forward search ends, [`Self::search_stop`] saying why).
    pub(super) fn forward_round(&mut self) -> bool {
        if self.stops() {
            return false;
        }
        self.round += 1;
        let round = self.round;
        self.spin.set_message(format!(
            "round {round}: extending {}",
            self.current.fitted.structure.label()
        ));
        let parent = self.current.fitted.structure.clone();
        let pool = candidate_pool(&parent, &self.rec.opts);
        if pool.is_empty() {
            self.search_stop = format!("after round {}: no effect left to try", round - 1);
            return false;
        }
        let r = self.fit_singles(parent, pool);
        let parent_bic = bic(&self.current.fitted, self.rec.d.ut.len());
        remember(
            &mut self.memory,
            &r.pool,
            &r.tried,
            parent_bic,
            self.rec.d.ut.len(),
        );
        // The reading the training record supports most that the validation record does
        // not confirm: if the search stops here, --suggest asks for the recording that
        // would settle it.
        self.unconfirmed = r
            .verdicts
            .iter()
            .enumerate()
            .filter(|(_, v)| !v.passed && v.delta_bic < -self.rec.opts.bic_margin)
            .min_by(|a, b| a.1.delta_bic.total_cmp(&b.1.delta_bic))
            .map(|(i, v)| Unconfirmed {
                fitted: r.tried[i].fitted.clone(),
                label: format!("{} [{}]", r.pool[i].name(), r.pool[i].form()),
                delta_bic: v.delta_bic,
                parent: r.parent.label(),
            });
        let (best, singles) = self.best_single(&r);
        let mut chosen: Option<(Proposal, Evaluated, usize)> = best.map(|(i, at, _)| {
            let c = r.tried.get(i).expect("index of a candidate");
            (r.pool[i].clone(), c.clone(), at)
        });
        // No single effect passes, but the residual is structured: two effects concealed
        // together may each be too small alone.
        if chosen.is_none()
            && self.current_summary.p_value <= 0.05
            && !self
                .rec
                .no_room(self.current.validate_rmse, 2.0 * MIN_EXPLAINED)
        {
            chosen = self.best_pair(&r, singles);
        }
        let Some((p, c, at)) = chosen else {
            self.search_stop = format!("after round {round}: no candidate passes the gate");
            return false;
        };
        self.accept(&p, c, at, &r.parent);
        true
    }

    /// The round's singles on `parent` fitted and judged. A new placement (the hysteresis
    /// inside the mechanical feedback) is searched afresh on a fine integration grid, the
    /// costliest candidate by far: it is asked only when a mode after the hysteresis is the
    /// best candidate that passes the gate (so a mode is about to be named) and still leaves
    /// more than 1.5x the noise on validation (so where it sits may matter: a restoring
    /// force fitted as a mode after the hysteresis leaves tens of times the noise).
    fn fit_singles(&self, parent: Structure, mut pool: Vec<Proposal>) -> Round {
        let (opts, d, round, current) = (&self.rec.opts, &self.rec.d, self.round, &self.current);
        let noise = self.rec.noise;
        let dt = self.rec.dt;
        let moves = |p: &Proposal| p.placement != parent.placement();
        let (placed, mut rest): (Vec<Proposal>, Vec<Proposal>) =
            pool.drain(..).partition(|p| moves(p));
        // Where the parent's training residual peaks: modes are started there too.
        let e_t = training_residual(&d.yt, current);
        let peaks_hz = residual::peak_frequencies(&d.ut, &e_t, dt, self.rec.train_noise, 3);
        // One proposal per job (here and in every fan-out of the search): fits take
        // seconds, and their balance should not rest on rayon's split heuristics
        // (measured on seed 20261134 case 95: 1.7 of 2 cores busy either way).
        let fit_all = |proposals: &[Proposal]| -> Vec<Evaluated> {
            proposals
                .par_iter()
                .with_max_len(1)
                .map(|p| {
                    let seeds = Seeds::Hinted(&self.memory, &peaks_hz);
                    fit_proposal(&parent, &current.fitted.theta, p, seeds, d, opts, round)
                })
                .collect()
        };
        let mut tried = fit_all(&rest);
        let gate = self.gate();
        let verdict =
            |p: &Proposal, c: &Evaluated| refuse_implausible(judge(c, current, &gate), p, c, d);
        let mut verdicts: Vec<Verdict> = rest
            .iter()
            .zip(&tried)
            .map(|(p, c)| verdict(p, c))
            .collect();
        for (i, (c, v)) in tried.iter_mut().zip(&mut verdicts).enumerate() {
            self.stronger_test(&rest[i], c, v, &gate, 400 + i as u64);
        }
        let timing_passes = rest
            .iter()
            .zip(&verdicts)
            .any(|(p, v)| v.passed && p.is_timing());
        let dynamics_helps = rest
            .iter()
            .zip(&tried)
            .zip(&verdicts)
            .filter(|(_, v)| v.passed)
            .min_by(|((_, a), va), ((_, b), vb)| {
                (va.delta_bic + a.validate_ic).total_cmp(&(vb.delta_bic + b.validate_ic))
            })
            .is_some_and(|((p, c), _)| {
                p.effects().contains(&Effect::Dynamics)
                    && c.validate_rmse > FEEDBACK_WORTH * noise
                    && !(timing_passes && resonant(&c.fitted, dt) == Some(false))
            });
        if dynamics_helps {
            let moved = fit_all(&placed);
            verdicts.extend(placed.iter().zip(&moved).map(|(p, c)| verdict(p, c)));
            tried.extend(moved);
            rest.extend(placed);
        }
        Round {
            parent,
            pool: rest,
            tried,
            verdicts,
            peaks_hz,
        }
    }

    /// The stronger test of a candidate `c` refused only for its creep
    /// ([`held_at_plausible`]): when the fit with the creep held inside what is plausible
    /// still passes `gate`, it takes `c`'s place and `v` says so; otherwise `v` says it
    /// does not.
    /// The held fit's evaluations are counted with `c`'s either way.
    fn stronger_test(
        &self,
        p: &Proposal,
        c: &mut Evaluated,
        v: &mut Verdict,
        gate: &Gate,
        salt: u64,
    ) {
        if v.refused.is_none() {
            return;
        }
        let (d, opts) = (&self.rec.d, &self.rec.opts);
        let Some((mut held, limit)) = held_at_plausible(c, p, d, opts, salt) else {
            return;
        };
        let limit = format!("{limit} with every other parameter polished again");
        let vh = refuse_implausible(judge(&held, &self.current, gate), p, &held, d);
        if vh.passed {
            held.fitted.evaluations += c.fitted.evaluations;
            *c = held;
            *v = vh;
            v.held = true;
            v.evidence.push_str(&format!(
                "; {limit}, it passes: named at the edge of plausible"
            ));
        } else {
            c.fitted.evaluations += held.fitted.evaluations;
            v.evidence.push_str(&format!(
                "; {limit}, it no longer passes (ΔBIC {}, validation RMSE {} {})",
                crate::render::table::sig(vh.delta_bic, 3),
                crate::render::table::sig(held.validate_rmse, 3),
                self.rec.unit
            ));
        }
    }

    /// A fitted proposal of this round on `parent` into the report (its evaluations
    /// counted); its index there.
    fn record(&mut self, p: &Proposal, c: &Evaluated, v: &Verdict, parent: &Structure) -> usize {
        self.evaluations += c.fitted.evaluations;
        let mut line = candidate(
            p,
            c,
            self.round,
            parent.label(),
            v.delta_bic,
            v.evidence.clone(),
            &self.rec.d,
        );
        line.refused.clone_from(&v.refused);
        self.candidates.push(line);
        self.candidates.len() - 1
    }

    /// The round's singles into the report, and the one to name, with its ties. Among the
    /// candidates that pass the gate, the one all the data support best: its training BIC
    /// plus its information criterion on the validation record it was not fitted to
    /// (training BIC alone favours flexible forms that do not predict; the validation record
    /// alone cannot tell forms that predict alike). Also every single's training ΔBIC.
    fn best_single(&mut self, r: &Round) -> (Option<Pick>, Vec<(usize, f64)>) {
        let mut best: Option<Pick> = None;
        let mut best_per_record: Option<Pick> = None;
        let mut best_timing: Option<Pick> = None;
        let mut singles: Vec<(usize, f64)> = Vec::new();
        for (i, ((p, c), v)) in r.pool.iter().zip(&r.tried).zip(&r.verdicts).enumerate() {
            let at = self.record(p, c, v, &r.parent);
            let evidence = v.delta_bic + c.validate_ic;
            if v.passed && best.is_none_or(|b| evidence < b.2) {
                best = Some((i, at, evidence));
            }
            if v.passed && p.is_timing() && best_timing.is_none_or(|b| evidence < b.2) {
                best_timing = Some((i, at, evidence));
            }
            let per_record = p.parts.iter().all(|x| x.0.per_record());
            if v.passed && per_record && best_per_record.is_none_or(|b| evidence < b.2) {
                best_per_record = Some((i, at, evidence));
            }
            singles.push((i, v.delta_bic));
        }
        let best = self.simpler_first(r, best, best_per_record, best_timing, &singles);
        if let Some((i, at, _)) = best {
            self.candidates[at].ties = round_ties(
                (&self.current, &r.parent),
                i,
                (&r.pool, &r.tried, &r.verdicts),
                &self.rec.d,
                self.rec.noise,
                &self.rec.opts,
            );
        }
        (best, singles)
    }

    /// The tie rules of a round: where the data cannot tell the best single from a simpler
    /// reading that passes too (a drift for creep, input timing for a lag in disguise), the
    /// simpler is named, and the best's line says why.
    fn simpler_first(
        &mut self,
        r: &Round,
        mut best: Option<Pick>,
        best_per_record: Option<Pick>,
        best_timing: Option<Pick>,
        singles: &[(usize, f64)],
    ) -> Option<Pick> {
        let (pool, tried, parent) = (&r.pool, &r.tried, &r.parent);
        // Transfer: creep's initial-state decays are a drift of each record; when a drift
        // of the record's own explains the training record about as well (ΔBIC within the
        // margin of creep's), the drift is taken first and creep must then pass on top of
        // it by what the input drives (carried to the validation record with the same
        // parameters); the backward step drops the drift if creep turns out to explain it.
        // Unless the parent's training residual follows the drive's steps (creep's
        // signature, which a drift of the record cannot have): then creep is not made to wait.
        let train_delta = |i: usize| singles.iter().find(|x| x.0 == i).map_or(0.0, |x| x.1);
        if let (Some(b), Some(r)) = (best, best_per_record)
            && pool[b.0].effects().contains(&Effect::Creep)
            && drift_first(
                [train_delta(b.0), tried[b.0].validate_ic],
                [train_delta(r.0), tried[r.0].validate_ic],
                self.rec.opts.bic_margin,
            )
        {
            let d = &self.rec.d;
            let e = training_residual(&d.yt, &self.current);
            match steps::step_evidence(&d.ut, &e, self.rec.dt, self.rec.opts.seed) {
                Some(s) if s.verdict == steps::FOLLOWS => {
                    self.candidates[b.1].notes.push(format!(
                        "transfer: a drift of each record ({}) passes too, but the residual follows the drive's steps ({} up and {} down holds, correlation {:.2} with the moves, sign-flip p = {:.3}): creep's signature, so creep is named",
                        pool[r.0].form(),
                        s.up,
                        s.down,
                        s.correlation,
                        s.p_value
                    ));
                }
                _ => {
                    self.candidates[b.1].notes.push(format!(
                        "transfer: a drift of each record ({}) passes too: taken first, so creep must add what the input drives",
                        pool[r.0].form()
                    ));
                    best = Some(r);
                }
            }
        }
        // A lag in disguise yields to input timing that passes too: a mode with no
        // resonance is a low-pass; creep pinned at its fastest time constant is a lag
        // faster than any creep (the backward step drops the timing if creep, named
        // later, explains it).
        if let (Some(b), Some(t)) = (best, best_timing) {
            let fitted = &tried[b.0].fitted;
            let why = if !parent.has(Effect::Dynamics)
                && resonant(fitted, self.rec.dt) == Some(false)
            {
                Some(format!(
                    "no resonance (no mode peaks 2x below {RESOLVED_FRACTION} of the sampling rate): a low-pass; input timing ({}) passes too and is named instead",
                    pool[t.0].name()
                ))
            } else if pool[b.0].effects() == [Effect::Creep] && creep_pinned_fast(fitted) {
                Some(format!(
                    "its fast element sits at the fastest creep time constant (ten samples): a lag; input timing ({}) passes too and is named first",
                    pool[t.0].name()
                ))
            } else {
                None
            };
            if let Some(why) = why {
                self.candidates[b.1].notes.push(why);
                best = Some(t);
            }
        }
        best
    }

    /// Pairs of the best singles (`singles`: each single's training ΔBIC), one form per
    /// effect, started at the singles' fits, each effect earning what a single must; the best
    /// that passes, and its index in the report.
    fn best_pair(
        &mut self,
        r: &Round,
        mut singles: Vec<(usize, f64)>,
    ) -> Option<(Proposal, Evaluated, usize)> {
        let (pool, tried, parent) = (&r.pool, &r.tried, &r.parent);
        singles.sort_by(|a, b| a.1.total_cmp(&b.1));
        // Corrections to the parent's training output; one residual explained twice
        // when they correlate this closely.
        let correction = |i: usize| -> Vec<f64> {
            tried[i]
                .out_t
                .iter()
                .zip(&self.current.out_t)
                .map(|(a, b)| a - b)
                .collect()
        };
        let same = |a: usize, b: usize| {
            residual::correlation(&correction(a), &correction(b)) >= SAME_RESIDUAL
        };
        let opts = &self.rec.opts;
        let top = pair_members(pool, &singles, parent, opts.pair_pool, &same);
        let (proposals, pairs): (Vec<Proposal>, Vec<Option<(usize, usize)>>) =
            pair_proposals(pool, &top, parent.placement())
                .into_iter()
                .unzip();
        let fitted: Vec<Evaluated> = proposals
            .par_iter()
            .with_max_len(1)
            .enumerate()
            .map(|(i, p)| {
                let seeds = match pairs[i] {
                    Some((a, b)) => Seeds::At(&[&tried[a].fitted, &tried[b].fitted]),
                    None => Seeds::Hinted(&self.memory, &r.peaks_hz),
                };
                let theta = &self.current.fitted.theta;
                fit_proposal(parent, theta, p, seeds, &self.rec.d, opts, self.round)
            })
            .collect();
        // Each effect of a pair earns what a single must.
        let gate = Gate {
            margin: 2.0 * opts.bic_margin,
            min_explained: 2.0 * MIN_EXPLAINED,
            ..self.gate()
        };
        let mut fitted = fitted;
        let mut verdicts: Vec<Verdict> = proposals
            .iter()
            .zip(&fitted)
            .map(|(p, c)| refuse_implausible(judge(c, &self.current, &gate), p, c, &self.rec.d))
            .collect();
        for (i, (c, v)) in fitted.iter_mut().zip(&mut verdicts).enumerate() {
            self.stronger_test(&proposals[i], c, v, &gate, 500 + i as u64);
        }
        let mut best: Option<Pick> = None;
        for (i, ((p, c), v)) in proposals.iter().zip(&fitted).zip(&verdicts).enumerate() {
            let at = self.record(p, c, v, parent);
            let evidence = v.delta_bic + c.validate_ic;
            if v.passed && best.is_none_or(|b| evidence < b.2) {
                best = Some((i, at, evidence));
            }
        }
        best.map(|(i, at, _)| (proposals[i].clone(), fitted[i].clone(), at))
    }

    /// Names `p` (fitted as `c`, the report's line `at`) on `parent`: the next round's
    /// parent, polished to convergence: otherwise every candidate of the next round gains
    /// from the parent's own unfinished polish, and the first to pass is a passenger.
    fn accept(&mut self, p: &Proposal, c: Evaluated, at: usize, parent: &Structure) {
        self.candidates[at].accepted = true;
        for e in p.effects() {
            if !parent.has(e) {
                self.left_out.push(e.name().to_string());
            }
        }
        let (d, opts) = (&self.rec.d, &self.rec.opts);
        let used;
        (self.current, used) = repolish(c, d, opts, 200 + self.round as u64);
        self.evaluations += used;
        self.current_summary = summary(&self.current, d, &self.boot, opts.seed);
    }

    /// Backward, after every acceptance: an accepted effect the model no longer needs
    /// (removing it leaves the validation RMSE inside the model's band) is dropped, the
    /// least needed first, and the search goes on from the smaller model (an effect that
    /// stood in for two, e.g. a fast creep for an input lag and its initial state for a
    /// drift, leaves room for the second once the first is named).
    pub(super) fn backward(&mut self) {
        while self.left_out.len() >= 2 {
            if !self.drop_one() {
                break;
            }
        }
    }

    /// One backward step: the named effect the model needs least dropped, if one is not
    /// needed; whether one was.
    fn drop_one(&mut self) -> bool {
        let (d, opts, noise) = (&self.rec.d, &self.rec.opts, self.rec.noise);
        let st = self.current.fitted.structure.clone();
        let removable: Vec<Effect> = st
            .effects()
            .iter()
            .copied()
            .filter(|e| self.left_out.iter().any(|n| n == e.name()))
            .filter(|e| !(*e == Effect::Dynamics && st.placement() == Placement::Feedback))
            .collect();
        let reduced: Vec<Evaluated> = removable
            .par_iter()
            .with_max_len(1)
            .map(|&e| {
                let smaller = st.without(e);
                let start = st.embed(&self.current.fitted.theta, &smaller);
                let f = refit::fit(
                    &smaller,
                    &d.ut,
                    &d.yt,
                    Some(&start),
                    None,
                    repolish_budget(opts),
                    opts.seed.wrapping_add(100 + self.round as u64),
                );
                evaluate(f, d, opts)
            })
            .collect();
        // An effect stays only if it would pass the gate's validation test on top
        // of the others now: a significant paired gain explaining the share of the
        // noise variance a single must (the parent's band alone, as wide as its
        // residual is uneven, dropped what the forward gate had just accepted).
        let drop = removable
            .iter()
            .zip(&reduced)
            .map(|(e, r)| {
                let needed = MIN_EXPLAINED * noise * noise;
                let gain = validation_gain(r, &self.current, opts.seed, needed);
                (e, r, gain)
            })
            .filter(|(_, _, k)| !k.2)
            .min_by(|a, b| a.1.validate_ic.total_cmp(&b.1.validate_ic));
        self.evaluations += reduced.iter().map(|r| r.fitted.evaluations).sum::<u64>();
        let Some((&e, r, (gain, _, _))) = drop else {
            return false;
        };
        let fmt = |x: f64| crate::render::table::sig(x, 3);
        for c in self
            .candidates
            .iter_mut()
            .filter(|c| c.accepted && !c.dropped)
        {
            if c.name.split('+').any(|n| n == e.name()) {
                // A pair keeps its other effect: only a single is dropped whole.
                c.dropped = c.name == e.name();
                c.notes.push(format!(
                    concat!(
                        "{} dropped by the backward step: without it the final ",
                        "model's validation RMSE is {} against {} {} (mean-square ",
                        "gain of keeping it 95 % [{}, {}]: not significant or under ",
                        "{} % of the noise variance)"
                    ),
                    e.name(),
                    fmt(r.validate_rmse),
                    fmt(self.current.validate_rmse),
                    self.rec.unit,
                    fmt(gain[0]),
                    fmt(gain[1]),
                    100.0 * MIN_EXPLAINED
                ));
            }
        }
        self.left_out.retain(|n| n != e.name());
        self.current = r.clone();
        self.current_summary = summary(&self.current, d, &self.boot, opts.seed);
        true
    }

    /// Once the forward search ends: the model with a named effect exchanged for its
    /// stand-in (see [`EXCHANGES`](super::propose::EXCHANGES)) is taken when all the data
    /// support it better by the margin, neither record worse by more than it, and it
    /// predicts the validation record inside the model's band; then the search goes on from
    /// it. Whether one was taken.
    pub(super) fn exchange_round(&mut self) -> bool {
        if self.exchanged.len() >= MAX_EXCHANGES {
            return false;
        }
        let tried = exchanges(
            &self.current.fitted,
            &self.left_out,
            &self.exchanged,
            &self.memory,
            &self.rec.d,
            &self.rec.opts,
            self.round + 1,
        );
        if tried.is_empty() {
            return false;
        }
        self.round += 1;
        let (best, at) = self.judge_exchanges(&tried);
        let Some((i, _)) = best else {
            let mut pairs: Vec<String> = Vec::new();
            for (out, p, _) in &tried {
                let pair = format!("{} for {}", out.name(), p.parts[0].0.name());
                if !pairs.contains(&pair) {
                    pairs.push(pair);
                }
            }
            self.exchange_note.push_str(&format!(
                "; round {} tried exchanging {}: none taken",
                self.round,
                pairs.join(", ")
            ));
            return false;
        };
        self.take_exchange(&tried[i], at[i]);
        true
    }

    /// The exchanges `tried` into the report, each judged against the current model (two
    /// for one: the second effect beside the partner alone too); the best that passes (its
    /// index in `tried`, its evidence), and each one's index in the report.
    fn judge_exchanges(
        &mut self,
        tried: &[(Effect, Proposal, Evaluated)],
    ) -> (Option<(usize, f64)>, Vec<usize>) {
        let parent_label = self.current.fitted.structure.label();
        let band = self.current_summary.validate_band;
        let (nt, margin) = (self.rec.d.ut.len(), self.rec.opts.bic_margin);
        let fmt = |x: f64| crate::render::table::sig(x, 3);
        let mut best: Option<(usize, f64)> = None;
        let mut at = Vec::new();
        for (i, (out, p, c)) in tried.iter().enumerate() {
            self.evaluations += c.fitted.evaluations;
            let ([d_bic, d_fit, d_vic, d_all], mut passed) =
                exchange_gate(c, &self.current, band, nt, margin);
            // Two for one: the second effect must also earn its place beside the partner
            // alone, as a single of a forward round would.
            let mut beside = String::new();
            if p.parts.len() == 2 {
                let alone = tried
                    .iter()
                    .find(|(e, q, _)| e == out && q.parts == p.parts[..1])
                    .map(|t| &t.2);
                let (d, noise, unit, opts) =
                    (&self.rec.d, self.rec.noise, &self.rec.unit, &self.rec.opts);
                let v = alone.map(|a| beside_alone(c, a, d, noise, unit, opts));
                passed &= v.as_ref().is_some_and(|v| v.passed);
                beside = format!(
                    "; {} beside {} alone: {}",
                    p.parts[1].0.name(),
                    p.parts[0].0.name(),
                    v.map_or("not fitted".to_string(), |v| v.evidence)
                );
            }
            let refused = plausible::refusal(&plausible::check_effects(
                &c.fitted,
                &self.rec.d.scope,
                &p.effects(),
            ));
            if let Some(why) = &refused {
                beside.push_str(&format!(
                    "; refused, its own parameters are not plausible: {why}"
                ));
            }
            passed &= refused.is_none();
            if passed && low_pass_for_timing(*out, &p.effects(), &c.fitted, self.rec.dt) {
                passed = false;
                beside.push_str(&format!(
                    "; refused: its modes have no resonance (none peaks 2x below {RESOLVED_FRACTION} of the sampling rate), a low-pass that {} already explains",
                    out.name()
                ));
            }
            if passed && best.is_none_or(|b| d_all < b.1) {
                best = Some((i, d_all));
            }
            at.push(self.candidates.len());
            let evidence = format!(
                concat!(
                    "exchange for {}: training N ln SSE {} (ΔBIC {} with the parameters) and ",
                    "validation evidence {} against the model with it (each needs < {}), ",
                    "together {} (needs < -{}); ",
                    "validation RMSE {} vs band [{}, {}] {} (needs at most the top): {}"
                ),
                out.name(),
                fmt(d_fit),
                fmt(d_bic),
                fmt(d_vic),
                margin,
                fmt(d_all),
                margin,
                fmt(c.validate_rmse),
                fmt(band[0]),
                fmt(band[1]),
                self.rec.unit,
                if passed { "yes" } else { "no" },
            ) + &beside;
            let mut line = candidate(
                p,
                c,
                self.round,
                format!("{parent_label} without {}", out.name()),
                d_bic,
                evidence,
                &self.rec.d,
            );
            line.refused = refused;
            self.candidates.push(line);
        }
        (best, at)
    }

    /// Takes the exchange `(out, p, c)` (the report's line `at`): `out` dropped wherever it
    /// was named, `p` named, the model polished again.
    fn take_exchange(&mut self, (out, p, c): &(Effect, Proposal, Evaluated), at: usize) {
        let round = self.round;
        self.exchanged.extend(p.parts.iter().map(|x| (*out, x.0)));
        self.candidates[at].accepted = true;
        self.candidates[at].notes.push(format!(
            "taken in place of {}: all the data support it better",
            out.name()
        ));
        for (j, c) in self.candidates.iter_mut().enumerate() {
            if !c.accepted || c.dropped || j == at {
                continue;
            }
            if c.name.split('+').any(|n| n == out.name()) {
                // A pair keeps its other effect: only a single is dropped whole.
                c.dropped = c.name == out.name();
                c.notes.push(format!(
                    "{} dropped by the exchange of round {round}: {} in its place",
                    out.name(),
                    p.name()
                ));
            }
        }
        self.left_out.retain(|n| n != out.name());
        for x in &p.parts {
            let name = x.0.name().to_string();
            if !self.left_out.contains(&name) {
                self.left_out.push(name);
            }
        }
        let (d, opts) = (&self.rec.d, &self.rec.opts);
        let used;
        (self.current, used) = repolish(c.clone(), d, opts, 200 + round as u64);
        self.evaluations += used;
        self.current_summary = summary(&self.current, d, &self.boot, opts.seed);
        self.exchange_note.push_str(&format!(
            "; round {round} exchanged {} for {}{}",
            out.name(),
            p.name(),
            if round < opts.max_rounds {
                ", then the search went on"
            } else {
                ""
            }
        ));
    }

    /// The rounds from the baseline until nothing more is named or exchanged, then
    /// [`Self::finish`].
    pub(super) fn run(mut self) -> Search {
        loop {
            while self.forward_round() {
                self.backward();
            }
            if !self.exchange_round() {
                break;
            }
        }
        self.finish()
    }

    /// The model the search has reached, as the report shows it.
    pub(super) fn final_summary(&self) -> &ModelSummary {
        &self.current_summary
    }

    /// The model reached predicts the validation records to the noise floor (where the
    /// floor has settled): no name could be earned on it.
    pub(super) fn at_floor(&self) -> bool {
        self.rec.no_room(self.current.validate_rmse, MIN_EXPLAINED)
    }

    /// The range of the reached model's shape parameter `name` (`None` when it has none).
    pub(super) fn param_range(&self, name: &str) -> Option<[f64; 2]> {
        self.current
            .fitted
            .structure
            .specs()
            .iter()
            .find(|s| s.name == name)
            .map(|s| [s.lower, s.upper])
    }

    /// The reached model's predicted output on the validation records.
    pub(super) fn validate_output(&self) -> &[f64] {
        &self.current.out_v
    }

    pub(super) fn noise(&self) -> f64 {
        self.rec.noise
    }

    pub(super) fn unit(&self) -> &str {
        &self.rec.unit
    }

    pub(super) fn evaluations(&self) -> u64 {
        self.evaluations
    }

    /// Shows `what` on the progress line.
    pub(super) fn say(&self, what: &str) {
        self.spin.set_message(what.to_string());
    }

    /// Once the search ends: the exchanges' notes joined to why it stopped, and with
    /// `--hold auto` the hold chosen for a model with the hysteresis inside the feedback
    /// ([`choose_hold`]).
    fn finish(mut self) -> Search {
        self.search_stop.push_str(&self.exchange_note);
        let opts = &self.rec.opts;
        if opts.choose_hold && self.current.fitted.structure.placement() == Placement::Feedback {
            self.spin
                .set_message("refitting the final model under each hold");
            let (current, trials, used) = choose_hold(self.current, &self.rec.d, opts);
            self.current = current;
            self.hold_trials = trials;
            self.evaluations += used;
            self.current_summary = summary(&self.current, &self.rec.d, &self.boot, opts.seed);
        }
        self
    }

    /// The diagnosis: the search's findings, the baseline and the final model in free run on
    /// each of `tests`, the final model as a file, and (`--suggest`) the next experiment.
    pub(super) fn diagnosis(self, tests: &[TestSet]) -> Diagnosis {
        let free_runs = self.free_runs(tests);
        // Structure the battery finds below half the training noise cannot be resolved by a
        // model fitted to the training data (it shows only on a cleaner validation record).
        let resolution = 0.5 * self.rec.train_noise;
        let threshold = self.boot.last().copied().unwrap_or(1.0).max(1.0);
        let structured = self.current_summary.p_value <= 0.05 && self.current.score > threshold;
        let validation_unpredicted = self.validation_room();
        let unexplained = (structured && self.current_summary.validate_rmse > resolution)
            || validation_unpredicted;
        let series = self.series();
        let nuisances = self.nuisances();
        let validation_judging = self.rec.d.judging(&self.current.fitted);
        let (outside_vocabulary, unexplained_probe) = if unexplained {
            self.outside_vocabulary()
        } else {
            (None, None)
        };
        let step_evidence = {
            let d = &self.rec.d;
            let on = |out: &[f64]| {
                let e: Vec<f64> = d.yt.iter().zip(out).map(|(y, m)| y - m).collect();
                steps::step_evidence(&d.ut, &e, self.rec.dt, self.rec.opts.seed)
            };
            StepsReport {
                holds: steps::holds(&d.ut, self.rec.dt).len(),
                baseline: on(&series.baseline[0]),
                final_model: on(&series.final_model[0]),
            }
        };
        self.spin.finish_and_clear();
        let model = self.model_file();
        let (rec, opts) = (&self.rec, &self.rec.opts);
        let (train, validate) = (&rec.tj.record, &rec.vj.record);
        let mut diag = Diagnosis {
            model: opts.model.clone(),
            not_applicable: opts
                .not_applicable()
                .into_iter()
                .map(|(e, why)| format!("{}: {why}", e.name()))
                .collect(),
            train: train.name.clone(),
            validate: validate.name.clone(),
            unit: rec.unit.clone(),
            samples: [train.len(), validate.len()],
            sampling_intervals_s: [rec.dt, rec.dv],
            records: [rec.tj.parts.clone(), rec.vj.parts.clone()],
            noise_floor: rec.noise,
            noise_floor_settled: rec.floor_settled,
            exponent: self.n_choice,
            baseline: self.baseline,
            located: self.located,
            candidates: self.candidates,
            left_out: self.left_out,
            final_model: self.current_summary,
            nuisances,
            unexplained,
            resolution,
            residual_structured: structured,
            validation_unpredicted,
            search_stop: self.search_stop,
            judging_rule: JUDGING_RULE.to_string(),
            outside_vocabulary,
            validation_judging,
            step_evidence,
            bootstrap_scores: self.boot,
            hold: self.current.fitted.structure.hold().name().into(),
            hold_trials: self.hold_trials,
            min_substeps: opts.min_substeps,
            excited_band_hz: rec.d.scope.band_hz,
            tests: free_runs,
            seed: opts.seed,
            evaluations: self.evaluations,
            wall_s: self.started.elapsed().as_secs_f64(),
            series,
            next_experiment: None,
            next_experiment_unexplained: unexplained_probe,
            core_choice: None,
            couplings: Vec::new(),
            model_file: model,
            columns: None,
        };
        let next = diag
            .in_final()
            .flat_map(|c| &c.ties)
            .find_map(|t| t.next_experiment.clone());
        diag.next_experiment = next;
        if opts.suggest && diag.next_experiment.is_none() {
            let last = self
                .unconfirmed
                .filter(|u| u.parent == self.current.fitted.structure.label());
            diag.next_experiment =
                last.map(|u| unconfirmed_experiment(u, &diag, &self.current, rec));
        }
        diag
    }

    /// The baseline's and the final model's free-run RMSE on each of `tests`.
    fn free_runs(&self, tests: &[TestSet]) -> Vec<FreeRun> {
        tests
            .iter()
            .map(|t| FreeRun {
                name: t.recording.name.clone(),
                samples: t.recording.len(),
                protocol: if t.periodic {
                    "periodic steady state (second of two periods)".into()
                } else {
                    "from rest".into()
                },
                baseline_rmse: free_run(&self.base_fitted, t),
                final_rmse: free_run(&self.current.fitted, t),
            })
            .collect()
    }

    /// What the structure the final model leaves depends on, and whether a correction on
    /// those features fitted on training predicts the validation records
    /// ([`unexplained::characterise`]; the validation records judged on their scored
    /// samples, as every candidate was); with `--suggest`, the recording that would pin it
    /// ([`suggest::for_unexplained`]), from the same residuals.
    fn outside_vocabulary(
        &self,
    ) -> (
        Option<unexplained::OutsideVocabulary>,
        Option<suggest::UnexplainedProbe>,
    ) {
        let (d, c) = (&self.rec.d, &self.current);
        let et = training_residual(&d.yt, c);
        let ev: Vec<f64> = d.yv.iter().zip(&c.out_v).map(|(y, m)| y - m).collect();
        let train = unexplained::Record {
            u: &d.ut,
            e: &et,
            y: &c.out_t,
            dt: self.rec.dt,
            scored: 0..et.len(),
        };
        let mut at = 0;
        let parts: Vec<unexplained::Record> = d
            .parts()
            .into_iter()
            .map(|(n, dt)| {
                let r = unexplained::Record {
                    u: &d.uv[at..at + n],
                    e: &ev[at..at + n],
                    y: &c.out_v[at..at + n],
                    dt,
                    scored: forecast::scored(&d.uv[at..at + n]),
                };
                at += n;
                r
            })
            .collect();
        let ov = unexplained::characterise(&train, &parts, self.rec.noise, self.rec.opts.seed);
        // The first validation record (a spectrum needs one sampling interval).
        let probe = match (&ov, parts.first()) {
            (Some(ov), Some(first)) if self.rec.opts.suggest => {
                suggest::for_unexplained(ov, &train, (first.u, first.e, first.dt))
            }
            _ => None,
        };
        (ov, probe)
    }

    /// The records and the baseline's and final model's outputs, for the figures.
    fn series(&self) -> Series {
        let (rec, current) = (&self.rec, &self.current);
        let (train, validate) = (&rec.tj.record, &rec.vj.record);
        let d = &rec.d;
        let (mut origins, mut leads, mut at) = (Vec::new(), Vec::new(), 0);
        for (n, _) in d.parts() {
            let o = forecast::origins(&d.uv[at..at + n]);
            leads.push(at..at + o[0]);
            // A periodic record is predicted from its lead's end alone.
            let take = if d.periodic { 1 } else { o.len() };
            origins.extend(o[..take].iter().map(|k| at + k));
            at += n;
        }
        Series {
            t: [rec.tj.times(), rec.vj.times()],
            u: [train.u.clone(), validate.u.clone()],
            y: [train.y.clone(), validate.y.clone()],
            baseline: self.base_out.clone(),
            final_model: [current.out_t.clone(), current.out_v.clone()],
            dt: [rec.dt, rec.dv],
            final_label: self.current_summary.model.clone(),
            input_unit: validate.units[1].clone(),
            origins,
            leads,
        }
    }

    /// What the final model attributes to the recording set-up: the input's timing and
    /// each record's own offset.
    fn nuisances(&self) -> BTreeMap<String, f64> {
        let f = &self.current.fitted;
        let names = f.structure.linear_names();
        let at = |c: &[f64], name: &str| names.iter().position(|n| *n == name).map(|i| c[i]);
        let mut m = BTreeMap::new();
        let params = named(f);
        for key in [
            "timing_offset_s",
            "intersample_curvature",
            "block_hold_samples",
        ] {
            if let Some(t) = params.get(key) {
                m.insert(key.to_string(), *t);
            }
        }
        if let Some(o) = at(&f.linear.coef, "d0") {
            m.insert("offset_train".to_string(), o);
        }
        if let Some(o) = at(&self.current.coef_v, "d0") {
            m.insert("offset_validate".to_string(), o);
        }
        m
    }

    /// The final model as a file that runs again, with the validation record's own state
    /// where that is one record run once (a periodic one is scored on its second period).
    fn model_file(&self) -> crate::physics::model_file::ModelFile {
        let (rec, opts, current) = (&self.rec, &self.rec.opts, &self.current);
        let (train, validate) = (&rec.tj.record, &rec.vj.record);
        let d = &rec.d;
        let validation = (!opts.validate_periodic && d.validation_parts.is_none()).then(|| {
            let (_, theta, _, _, coef) = d.validation_fit(&current.fitted, &d.uv, &d.yv, opts.seed);
            saved::ValidationState {
                name: validate.name.clone(),
                dt: rec.dv,
                theta,
                coef,
            }
        });
        let [ut, ui, uo] = &train.units;
        let mut model = saved::model_file(&current.fitted, [ut, ui, uo], validation);
        model.fitted = crate::physics::model_file::Fitted {
            command: "diagnose".into(),
            optimizer: "pso + levenberg-marquardt".into(),
            budget: 0,
            evaluations: self.evaluations,
            seed: opts.seed,
            train: vec![train.name.clone()],
            validate: vec![validate.name.clone()],
        };
        model
    }
}

/// `--suggest` where no tie the final model holds has an experiment: the recording that
/// would settle the last round's reading `u` the validation record did not confirm, against
/// the final model `current`.
fn unconfirmed_experiment(
    u: Unconfirmed,
    diag: &Diagnosis,
    current: &Evaluated,
    rec: &Records,
) -> suggest::NextExperiment {
    let Unconfirmed {
        fitted,
        label,
        delta_bic: delta,
        ..
    } = u;
    let mut x = suggest::design(
        &fitted.single(),
        &current.fitted.single(),
        [label.clone(), diag.final_model.model.clone()],
        &rec.d.ut,
        rec.d.scope.dt,
        rec.noise,
    );
    x.question = format!(
        "{label} gains {} in training BIC on the final model but the validation record does not confirm it",
        crate::render::table::sig(-delta, 3)
    );
    x
}
