//! `optbench diagnose`: where a model misses recorded files and what physics it left out, or
//! (`--proof`) the concealed-effect proof on the twin.

use crate::base::error::{Error, Result};
use crate::base::limits;
use crate::data::recording::{Columns, Delimiter, ReadOptions};
use crate::diagnose::recordings::{Files, diagnose_files};
use crate::diagnose::{Options, proof};
use crate::physics::structure::{
    Effect, Hold, MAX_PI_OPERATORS, MAX_PREISACH_LEVELS, MIN_SUBSTEPS,
};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct DiagnoseArgs {
    /// Training recording (CSV with a header). Repeatable: several records of the device
    /// (at any sampling intervals) fitted together, the actuator's parameters shared, each
    /// record's initial state, timing, offset, drift and creep states its own.
    #[arg(long, required_unless_present = "proof")]
    pub train: Vec<PathBuf>,
    /// Validation recording, a different excitation (CSV), never fitted. Repeatable, as
    /// --train.
    #[arg(long, required_unless_present_any = ["proof", "holdout"], conflicts_with = "holdout")]
    pub validate: Vec<PathBuf>,
    /// Instead of --validate: hold out this share of every training record's end (e.g.
    /// 0.2), never fitted, as its validation record; for when no second recording exists,
    /// or when the other recordings are kept for --test. The tail is the same excitation
    /// continued, so it checks the fit on unseen samples, not on an unseen kind of input.
    #[arg(long, conflicts_with = "validate_periodic")]
    pub holdout: Option<f64>,
    /// Model family: auto (the core chosen by the data: Bouc-Wen first; when its exponent
    /// sits at a bound or its final model predicts above the noise floor, the pi and
    /// preisach cores are searched too, and one that predicts the validation records below
    /// Bouc-Wen's band is kept: "the loop is not Bouc-Wen's"), bouc-wen (n fitted, kept
    /// only if BIC says so), bouc-wen-n1 (n = 1), pi (a Prandtl-Ishlinskii core:
    /// --pi-operators plays with fixed thresholds, their weights fitted by least squares
    /// like Bouc-Wen's gains; delay, input-lag, saturation and asymmetry act on its drive,
    /// rate-dependence scales its weights or thresholds with the rate, creep, dynamics and
    /// offset-drift act after it), or preisach (a discretised Preisach core the same way:
    /// --preisach-levels levels over the training input's range, one relay weight per cell
    /// of the threshold plane; its plane makes any asymmetric loop, so asymmetry is not
    /// searched, and its rate-dependence scales the weights). The operator cores take no
    /// feedback placement of dynamics. Default: auto; bouc-wen-n1 for --proof (the twin's n
    /// is 1; ten times faster).
    #[arg(long, value_parser = ["auto", "bouc-wen", "bouc-wen-n1", "pi", "preisach"])]
    pub model: Option<String>,
    /// Plays of the pi core (thresholds uniform over the training input's half-range).
    #[arg(long, default_value_t = 10,
          value_parser = clap::value_parser!(u32).range(1..=MAX_PI_OPERATORS as i64))]
    pub pi_operators: u32,
    /// Levels of the preisach core: levels·(levels+1)/2 relays (2 levels are 3 relays, 7
    /// are 28), thresholds at the centres of equal cells over the training input's range.
    #[arg(long, default_value_t = 6,
          value_parser = clap::value_parser!(u32).range(1..=MAX_PREISACH_LEVELS as i64))]
    pub preisach_levels: u32,
    /// Time, input and output column names.
    #[arg(long, default_value = "t,u,y")]
    pub columns: String,
    /// Records with gaps or irregular time stamps are linearly interpolated onto a uniform
    /// grid (jitter within 1 % of the step is accepted without it).
    #[arg(long)]
    pub resample: bool,
    /// Column separator: auto, ',', ';', tab or whitespace (decimal commas are detected).
    #[arg(long, default_value = "auto")]
    pub delimiter: Delimiter,
    /// Seconds left out at the start of every record (training, validation, test): for
    /// records that start in motion, e.g. a stage stepped from rest to the first command as
    /// recording began (the report's 'starts in motion' finding suggests a value).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub trim_start: f64,
    /// Output folder (default: results/diagnose, or results/diagnose-proof with --proof).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of the fits' and the bootstrap's random streams.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: one per core). Results do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=limits::MAX_THREADS as i64))]
    pub threads: Option<u32>,
    /// Candidate effects, comma-separated (default: all eight).
    #[arg(long)]
    pub effects: Option<String>,
    /// Bootstrap refits calibrating the residual tests.
    #[arg(long, default_value_t = 19)]
    pub bootstrap: usize,
    /// Run the concealed-effect proof on the twin instead of diagnosing files.
    #[arg(long)]
    pub proof: bool,
    /// Noise seeds per case of the proof.
    #[arg(long, default_value_t = 3)]
    pub seeds: u64,
    /// Proof cases, comma-separated effect names and `none` (default: all nine).
    #[arg(long)]
    pub cases: Option<String>,
    /// Keep every proof case's diagnosis (JSON, text, figures) in OUT/<case>-seed<k>/.
    #[arg(long)]
    pub keep: bool,
    /// Seconds per recording of the proof.
    #[arg(long, default_value_t = 4.0)]
    pub seconds: f64,
    /// How the input moves between samples: zoh (a D/A staircase), linear, bandlimited
    /// (a continuous excitation sampled without aliasing, e.g. a multisine or sweep), or
    /// auto (diagnosed under zoh; if the final model has the hysteresis inside the
    /// mechanical feedback, the only block that sees the hold, it is refitted under each
    /// and the one the data support best is kept).
    #[arg(long, default_value = "zoh", value_parser = ["zoh", "linear", "bandlimited", "auto"])]
    pub hold: String,
    /// The fewest RK4 sub-steps per sample of that integrator (more where the fitted mode
    /// needs them): raise it to check that a result does not depend on the integration.
    #[arg(long, default_value_t = MIN_SUBSTEPS)]
    pub min_substeps: usize,
    /// Test record (CSV, same columns), never used by the diagnosis: baseline and final
    /// model are simulated from its input alone, from rest. Repeatable.
    #[arg(long)]
    pub test: Vec<PathBuf>,
    /// As --test, for one period of a periodic steady state (two periods simulated, the
    /// second scored). Repeatable.
    #[arg(long)]
    pub test_periodic: Vec<PathBuf>,
    /// The validation record is one period of a periodic steady state (simulated twice,
    /// the second period scored).
    #[arg(long)]
    pub validate_periodic: bool,
    /// For each tie (candidates the records cannot tell apart), design the recording that
    /// would separate them: the excitation, within the recorded input range, on which the
    /// tied models' predictions differ most (`next_experiment` in diagnosis.json).
    #[arg(long)]
    pub suggest: bool,
    /// No progress display (it shows only when stderr is a terminal anyway).
    #[arg(short, long)]
    pub quiet: bool,
}

fn effects(spec: &Option<String>) -> Result<Vec<Effect>> {
    let Some(s) = spec else {
        return Ok(Effect::ALL.to_vec());
    };
    s.split(',')
        .map(str::trim)
        .filter(|x| !x.is_empty())
        .map(|x| {
            Effect::parse(x).ok_or_else(|| {
                Error::Input(format!(
                    "--effects: unknown effect `{x}`; valid: {}",
                    Effect::ALL.map(Effect::name).join(", ")
                ))
            })
        })
        .collect()
}

pub fn run(a: DiagnoseArgs) -> Result<()> {
    super::with_threads(a.threads, move || diagnose(a))
}

fn diagnose(a: DiagnoseArgs) -> Result<()> {
    let model = a
        .model
        .clone()
        .unwrap_or_else(|| if a.proof { "bouc-wen-n1" } else { "auto" }.to_string());
    let choose_hold = a.hold == "auto";
    let hold = if choose_hold {
        Hold::Zoh
    } else {
        Hold::parse(&a.hold).ok_or_else(|| {
            Error::Input(format!(
                "--hold {}: unknown; valid: zoh, linear, bandlimited, auto",
                a.hold
            ))
        })?
    };
    if !(1..=64).contains(&a.min_substeps) {
        return Err(Error::Input(format!(
            "--min-substeps {}: expected 1 to 64",
            a.min_substeps
        )));
    }
    limits::at_most("--bootstrap", a.bootstrap as u64, limits::MAX_BOOTSTRAP)
        .map_err(Error::Input)?;
    limits::at_most("--seeds", a.seeds, limits::MAX_TRIALS).map_err(Error::Input)?;
    let mut opts = Options {
        model,
        pi_operators: a.pi_operators as usize,
        preisach_levels: a.preisach_levels as usize,
        seed: a.seed,
        effects: effects(&a.effects)?,
        bootstrap: a.bootstrap,
        hold,
        choose_hold,
        min_substeps: a.min_substeps,
        validate_periodic: a.validate_periodic,
        suggest: a.suggest,
        progress: !a.quiet,
        ..Options::default()
    };
    opts.fixed_n()?;
    // Refuse what the model cannot take when asked for by name; by default leave it out.
    opts.effects = opts.applicable_effects(a.effects.is_some())?;
    if a.proof {
        if !(a.seconds >= 1.0 && a.seconds <= 600.0) {
            return Err(Error::Input(format!(
                "--seconds {}: expected 1 to 600",
                a.seconds
            )));
        }
        let out = a
            .out
            .unwrap_or_else(|| PathBuf::from("results/diagnose-proof"));
        let seeds: Vec<u64> = (1..=a.seeds).collect();
        let mut kinds = proof::kinds();
        if let Some(c) = &a.cases {
            let want: Vec<&str> = c.split(',').map(str::trim).collect();
            if let Some(bad) = want.iter().find(|w| !kinds.iter().any(|k| k.name() == **w)) {
                return Err(Error::Input(format!(
                    "--cases: unknown case `{bad}`; valid: none, {}",
                    Effect::ALL.map(Effect::name).join(", ")
                )));
            }
            kinds.retain(|k| want.contains(&k.name()));
        }
        let na = opts.not_applicable();
        let named: Vec<&str> = kinds
            .iter()
            .filter(|k| k.truth.is_some_and(|e| na.iter().any(|(x, _)| *x == e)))
            .map(|k| k.name())
            .collect();
        if a.cases.is_some() && !named.is_empty() {
            return Err(Error::Input(format!(
                "--cases {}: --model {} does not search {} (see --help)",
                named.join(","),
                opts.model,
                named.join(", ")
            )));
        }
        kinds.retain(|k| !k.truth.is_some_and(|e| na.iter().any(|(x, _)| *x == e)));
        print!(
            "{}",
            proof::run_and_write(&kinds, &seeds, a.seconds, &opts, &out, a.keep)?
        );
        return Ok(());
    }
    let files = Files {
        train: a.train,
        validate: a.validate,
        test: a.test,
        test_periodic: a.test_periodic,
        columns: Columns::parse(&a.columns)?,
        read: ReadOptions {
            resample: a.resample,
            delimiter: a.delimiter,
        },
        trim_start: a.trim_start,
        holdout: a.holdout,
    };
    let out = a.out.unwrap_or_else(|| PathBuf::from("results/diagnose"));
    print!("{}", diagnose_files(&files, &opts, &out)?);
    Ok(())
}
