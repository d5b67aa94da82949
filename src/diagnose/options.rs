//! What the diagnosis is asked ([`Options`]) and what it answers: the serialised
//! summaries of `diagnosis.json` and the figures' series.

use super::refit::Budget;
use super::residual::{Located, TestResult};
use super::{coupling, plausible, suggest, tie};
use crate::base::error::{Error, Result};
use crate::data::recording::Recording;
use crate::physics::structure::{CoreKind, Effect, Hold, MIN_SUBSTEPS, PiCore};
use serde::Serialize;
use std::collections::BTreeMap;

/// What the diagnosis does; the defaults are what `optbench diagnose` runs.
#[derive(Clone, Debug)]
pub struct Options {
    /// Model family: `auto` (the core chosen by the data, [`super::core_choice`]; the
    /// command line's default), `bouc-wen` (n fitted; this struct's default, so a library
    /// caller pins the core unless asking), `bouc-wen-n1` (n = 1), `pi` (a
    /// Prandtl-Ishlinskii core of [`Self::pi_operators`] plays, [`PiCore`]) or `preisach`
    /// (a Preisach core of [`Self::preisach_levels`] levels).
    pub model: String,
    /// Plays of the `pi` core.
    pub pi_operators: usize,
    /// Levels of the `preisach` core (`levels·(levels+1)/2` relays).
    pub preisach_levels: usize,
    pub seed: u64,
    /// Extensions tried as candidates.
    pub effects: Vec<Effect>,
    /// Bootstrap replicates calibrating the residual battery.
    pub bootstrap: usize,
    /// Required BIC improvement (natural-log units) for a candidate.
    pub bic_margin: f64,
    /// Family level of the residual battery.
    pub alpha: f64,
    /// Lags of the residual tests.
    pub lags: usize,
    /// Budgets of the baseline fit and of each candidate refit.
    pub baseline_budget: Budget,
    pub candidate_budget: Budget,
    /// Budget of a candidate in a new placement (not nested: its oscillator and loop shape
    /// are searched afresh, the global stage on the first samples only).
    pub placement_budget: Budget,
    /// At most this many rounds of extensions.
    pub max_rounds: usize,
    /// When no single candidate passes: pairs of this many best singles are tried.
    pub pair_pool: usize,
    /// How the input moves between samples (for the feedback placement's integrator).
    pub hold: Hold,
    /// Choose the hold from the data ([`choose_hold`]), starting from `hold`.
    ///
    /// [`choose_hold`]: super::evaluate::choose_hold
    pub choose_hold: bool,
    /// The fewest RK4 sub-steps per sample of that integrator.
    pub min_substeps: usize,
    /// Offer `dynamics` with the hysteresis inside the mechanical feedback too.
    pub feedback: bool,
    /// The validation record is one period of a periodic steady state.
    pub validate_periodic: bool,
    /// Design the excitation that would separate each tie ([`suggest::design`]).
    pub suggest: bool,
    /// Show the stage on stderr (a terminal only).
    pub progress: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            model: "bouc-wen".into(),
            pi_operators: 10,
            preisach_levels: 6,
            seed: 1,
            effects: Effect::ALL.to_vec(),
            bootstrap: 19,
            bic_margin: 10.0,
            alpha: 0.01,
            lags: 20,
            baseline_budget: Budget {
                global: 1500,
                swarm: 30,
                polish: 800,
                starts: 3,
                global_window: 0,
                screen: 0.0,
            },
            candidate_budget: Budget {
                global: 300,
                swarm: 15,
                polish: 700,
                starts: 3,
                global_window: 0,
                screen: 2.0,
            },
            placement_budget: Budget {
                global: 1500,
                swarm: 30,
                polish: 700,
                starts: 3,
                global_window: 4096,
                screen: 0.0,
            },
            max_rounds: 4,
            pair_pool: 3,
            hold: Hold::Zoh,
            choose_hold: false,
            min_substeps: MIN_SUBSTEPS,
            feedback: true,
            validate_periodic: false,
            suggest: false,
            progress: false,
        }
    }
}

impl Options {
    /// The exponent the model pins, or an error for an unknown model.
    pub fn fixed_n(&self) -> Result<Option<f64>> {
        match self.model.as_str() {
            "bouc-wen" | "auto" => Ok(None),
            // The PI core has no exponent; pinning it keeps the exponent search off.
            "bouc-wen-n1" | "pi" | "preisach" => Ok(Some(1.0)),
            m => Err(Error::Input(format!(
                "--model {m}: unknown; valid: auto, bouc-wen, bouc-wen-n1, pi, preisach"
            ))),
        }
    }

    /// Whether the data choose the core ([`super::core_choice`]): Bouc-Wen first, the
    /// operator cores searched too when the data reject it.
    pub fn chooses_core(&self) -> bool {
        self.model == "auto"
    }

    /// Whether the core is linear in its weights (a Prandtl-Ishlinskii or Preisach model).
    pub fn is_pi(&self) -> bool {
        self.core_kind().is_some()
    }

    /// The kind of a linear-in-weights core (`None`: Bouc-Wen).
    pub fn core_kind(&self) -> Option<CoreKind> {
        match self.model.as_str() {
            "pi" => Some(CoreKind::Plays),
            "preisach" => Some(CoreKind::Relays),
            _ => None,
        }
    }

    /// The core of the training inputs `inputs` (`None`: Bouc-Wen).
    pub fn core(&self, inputs: &[&[f64]]) -> Option<PiCore> {
        self.core_kind().map(|k| match k {
            CoreKind::Plays => PiCore::new(self.pi_operators, inputs),
            CoreKind::Relays => PiCore::preisach(self.preisach_levels, inputs),
        })
    }

    /// The effects that do not apply to the model, each with why ([`Effect::not_for_core`]).
    pub fn not_applicable(&self) -> Vec<(Effect, &'static str)> {
        let Some(kind) = self.core_kind() else {
            return Vec::new();
        };
        Effect::ALL
            .iter()
            .filter_map(|&e| e.not_for_core(kind).map(|why| (e, why)))
            .collect()
    }

    /// The candidate effects the model can take: [`Self::effects`] without those that do
    /// not apply; an error naming them if they were asked for explicitly (`explicit`).
    pub fn applicable_effects(&self, explicit: bool) -> Result<Vec<Effect>> {
        let na = self.not_applicable();
        let asked: Vec<String> = na
            .iter()
            .filter(|(e, _)| self.effects.contains(e))
            .map(|(e, why)| format!("{}: {why}", e.name()))
            .collect();
        if explicit && !asked.is_empty() {
            return Err(Error::Input(format!(
                "--effects with --model {}: {} does not apply ({}); leave it out",
                self.model,
                asked.len(),
                asked.join("; ")
            )));
        }
        Ok(self
            .effects
            .iter()
            .copied()
            .filter(|e| !na.iter().any(|(x, _)| x == e))
            .collect())
    }
}

/// A model's numbers in the report.
#[derive(Clone, Debug, Serialize)]
pub struct ModelSummary {
    pub model: String,
    pub train_rmse: f64,
    /// Validation RMSE on the scored samples, all predicted ([`super::forecast`]).
    pub validate_rmse: f64,
    /// Validation RMSE with the record's own parts fitted on all of it, as `model.json`
    /// holds them (what `simulate --record` reproduces): a fit, never a judge.
    pub validate_fitted_rmse: f64,
    /// 95 % band of the validation RMSE (moving-block bootstrap).
    pub validate_band: [f64; 2],
    pub bic: f64,
    pub params: BTreeMap<String, f64>,
    /// Residual battery on the validation data.
    pub tests: Vec<TestResult>,
    /// Largest statistic / critical value of the battery.
    pub score: f64,
    /// Bootstrap p-value of the score under the fitted baseline (structure left if small).
    pub p_value: f64,
    /// Parameters at a bound, or beyond what the training record can show
    /// ([`plausible::check`]).
    pub plausibility: Vec<plausible::Flag>,
    pub evaluations: u64,
}

/// One nested refit: an effect in one form, or a pair of effects (`name` `a+b`).
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    pub name: String,
    /// The functional form (`a+b` for a pair), e.g. `smooth` for a saturation.
    pub form: String,
    /// `actuator` (parameters carried to the validation record) or `per-record`
    /// (refitted on every record, like a sensor's drift).
    pub transfer: String,
    /// For `dynamics`: `after-hysteresis` or `feedback` (hysteresis inside the mechanical
    /// feedback, a restoring force).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placement: Option<String>,
    /// Round (1 = added to the baseline).
    pub round: usize,
    /// The model it extends.
    pub parent: String,
    pub delta_bic: f64,
    pub train_rmse: f64,
    pub validate_rmse: f64,
    /// Evidence on the validation record (`N ln(SSE/N)` over its scored samples, all
    /// predicted); among passing candidates the lowest wins.
    pub validate_ic: f64,
    /// Parameters fitted on each record's samples: `[training, validation]` (all of them
    /// on training, judged there by BIC; on validation the record's own parts, fitted on
    /// the samples before each forecast origin, none on a sample that judges).
    pub fitted_on: [usize; 2],
    pub score: f64,
    pub accepted: bool,
    /// Accepted, then removed by the backward step (the final model no longer needs it).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub dropped: bool,
    pub params: BTreeMap<String, f64>,
    /// The gate: ΔBIC, the validation band, the residual battery.
    pub evidence: String,
    /// Not named although the gate passed: why (its own parameters implausible or at a
    /// bound, [`plausible::refusal`]); absent when not refused.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refused: Option<String>,
    /// Where a tie rule or the backward step overrode the gate's choice, and why.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// The flags ([`plausible::check`]) on the parameters of its own effects: what its
    /// evidence rests on.
    pub plausibility: Vec<plausible::Flag>,
    /// For an accepted candidate: the others of its round the records cannot tell from it.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub ties: Vec<tie::Tie>,
    /// Model evaluations its fit took (the search, the polish and the validation states).
    pub evaluations: u64,
}

/// The diagnosis (`diagnosis.json`).
#[derive(Clone, Debug, Serialize)]
pub struct Diagnosis {
    pub model: String,
    pub train: String,
    pub validate: String,
    pub unit: String,
    pub samples: [usize; 2],
    /// Sampling interval of each record (s; the first record's of several); each is
    /// simulated at its own.
    pub sampling_intervals_s: [f64; 2],
    /// Training and validation records as `[samples, interval s]` each, in the order given.
    pub records: [Vec<(usize, f64)>; 2],
    pub noise_floor: f64,
    /// Whether both records' noise floors have settled ([`residual::noise_floor_and_settled`]);
    /// if not, the floor is an upper bound and the noise-floor stop is off.
    ///
    /// [`residual::noise_floor_and_settled`]: super::residual::noise_floor_and_settled
    pub noise_floor_settled: bool,
    /// How the Bouc-Wen exponent was chosen.
    pub exponent: String,
    pub baseline: ModelSummary,
    pub located: Vec<Located>,
    pub candidates: Vec<Candidate>,
    pub left_out: Vec<String>,
    /// Effects the model does not take, each with why (`--model pi`: the PI model's own
    /// asymmetric and rate-dependent forms).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_applicable: Vec<String>,
    #[serde(rename = "final")]
    pub final_model: ModelSummary,
    /// What the final model attributes to the recording set-up, not to the actuator: the
    /// input's sub-sample timing (`timing_offset_s`, from the inter-sample convention and
    /// where the sensor samples) and each record's own sensor offset.
    pub nuisances: BTreeMap<String, f64>,
    /// Structure left in the final residual that no candidate explains.
    pub unexplained: bool,
    /// Half the training record's noise floor: residual structure smaller than this is
    /// reported but not counted as unexplained.
    pub resolution: f64,
    /// The battery still finds structure in the final residual (whatever its size).
    pub residual_structured: bool,
    /// The validation record is predicted above its noise even at its band's lower end
    /// while the training residual may be noise: its drive excites what the training
    /// drive does not show (counted in `unexplained`).
    pub validation_unpredicted: bool,
    /// Why the forward search ended.
    pub search_stop: String,
    /// How the validation records judged: by prediction alone ([`super::forecast`]).
    pub judging_rule: String,
    /// When structure remains unexplained: what it depends on and whether a correction on
    /// those features predicts the validation records ([`super::unexplained`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub outside_vocabulary: Option<super::unexplained::OutsideVocabulary>,
    /// Per validation record: samples, those scored, and the final model's parameters
    /// fitted on its own samples (none on a scored one).
    pub validation_judging: Vec<super::forecast::Judging>,
    /// The training residual over the drive's holds, set against the moves before them
    /// ([`super::steps`]): creep follows the steps, a drift does not. `None` where the
    /// drive has too few holds both ways.
    pub step_evidence: StepsReport,
    /// Bootstrap scores of the battery under the fitted baseline, sorted.
    pub bootstrap_scores: Vec<f64>,
    /// How the input moves between samples (`--hold`, or the one `--hold auto` kept).
    pub hold: String,
    /// `--hold auto`: the final model refitted under each hold ([`choose_hold`]).
    ///
    /// [`choose_hold`]: super::evaluate::choose_hold
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub hold_trials: Vec<HoldTrial>,
    /// The fewest RK4 sub-steps per sample of the feedback placement's integrator.
    pub min_substeps: usize,
    /// Top of the band the training drive excites ([`plausible::Scope::band_hz`]).
    pub excited_band_hz: f64,
    /// Free-run simulation on test records from their input alone (`--test`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tests: Vec<FreeRun>,
    pub seed: u64,
    pub evaluations: u64,
    pub wall_s: f64,
    /// Series for the figures (not serialised).
    #[serde(skip)]
    pub series: Series,
    /// With `--suggest`, when structure stays unexplained: the recording that would pin
    /// what it depends on ([`suggest::for_unexplained`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub next_experiment_unexplained: Option<suggest::UnexplainedProbe>,
    /// `--model auto`: how the data chose the hysteresis core ([`super::core_choice`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub core_choice: Option<super::core_choice::CoreChoice>,
    /// The recording that would settle the first tie the final model holds (`--suggest`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub next_experiment: Option<suggest::NextExperiment>,
    /// The final model as `model.json` (not in diagnosis.json).
    #[serde(skip)]
    pub model_file: crate::physics::model_file::ModelFile,
    /// Column names of the recordings (`None`: t,u,y), for the predicted-output files.
    #[serde(skip)]
    pub columns: Option<crate::data::recording::Columns>,
    /// Other inputs of the validation file the final residual is coherent with
    /// ([`coupling::couplings`]; filled by the command, which reads the file).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub couplings: Vec<coupling::Coupling>,
}

impl Diagnosis {
    /// The accepted candidates the final model holds: not dropped, and not replaced by a
    /// later form of the same effects (a two-element creep by a logarithmic one).
    pub fn in_final(&self) -> impl Iterator<Item = &Candidate> {
        let held = |c: &Candidate| c.accepted && !c.dropped;
        self.candidates
            .iter()
            .enumerate()
            .filter(move |(i, c)| {
                held(c)
                    && !self.candidates[i + 1..]
                        .iter()
                        .any(|l| held(l) && l.name == c.name)
            })
            .map(|(_, c)| c)
    }

    /// The accepted effects in order, `dynamics(feedback)` when the hysteresis was placed
    /// inside the mechanical feedback.
    pub fn accepted_labels(&self) -> Vec<String> {
        self.in_final()
            .flat_map(|c| {
                c.name.split('+').map(|n| match c.placement.as_deref() {
                    Some("feedback") if n == "dynamics" => format!("{n}(feedback)"),
                    _ => n.to_string(),
                })
            })
            .collect()
    }
}

/// A record the diagnosis never looks at, simulated from its input alone.
#[derive(Clone, Debug)]
pub struct TestSet {
    pub recording: Recording,
    /// One period of a periodic steady state: two periods are simulated and the second
    /// scored (no initial transient).
    pub periodic: bool,
}

/// Free-run RMSE of the baseline and the final model on a [`TestSet`].
#[derive(Clone, Debug, Serialize)]
pub struct FreeRun {
    pub name: String,
    pub samples: usize,
    /// `from rest` or `periodic steady state`.
    pub protocol: String,
    pub baseline_rmse: f64,
    pub final_rmse: f64,
}

/// Model outputs kept for the figures.
#[derive(Clone, Debug, Default)]
pub struct Series {
    pub t: [Vec<f64>; 2],
    pub u: [Vec<f64>; 2],
    pub y: [Vec<f64>; 2],
    /// Baseline and final outputs on training (0) and validation (1) data.
    pub baseline: [Vec<f64>; 2],
    pub final_model: [Vec<f64>; 2],
    /// Sampling interval of each record (the first one's, for several; each one's in
    /// [`Diagnosis::records`]).
    pub dt: [f64; 2],
    pub final_label: String,
    /// Unit of the input (the validation record's), for the figures' axes.
    pub input_unit: String,
    /// The validation samples where a forecast starts ([`super::forecast::origins`] of
    /// each record, offset to the records back to back; a periodic record's lead end
    /// alone): the samples before each are fitted, those from it to the next predicted.
    pub origins: Vec<usize>,
    /// Each validation record's lead (fitted, never scored).
    pub leads: Vec<std::ops::Range<usize>>,
}

/// The step evidence ([`super::steps::step_evidence`]) of the baseline's and the final
/// model's training residuals.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StepsReport {
    /// The training drive's holds ([`super::steps::holds`]), whether or not enough for a
    /// verdict.
    pub holds: usize,
    pub baseline: Option<super::steps::StepEvidence>,
    #[serde(rename = "final")]
    pub final_model: Option<super::steps::StepEvidence>,
}

/// The final model under one hold (`--hold auto`).
#[derive(Clone, Debug, Serialize)]
pub struct HoldTrial {
    pub hold: String,
    pub train_rmse: f64,
    pub validate_rmse: f64,
    /// Training BIC plus the validation record's evidence: what candidates are ranked by.
    pub evidence: f64,
    pub kept: bool,
}
