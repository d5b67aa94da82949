//! The hysteresis core chosen by the data (`--model auto`, the default).
//!
//! The search starts from Bouc-Wen with its exponent. When the data reject it (its
//! exponent at a bound, or its final model still predicting the validation records above
//! the noise floor), the operator cores search the same records too: a Prandtl-Ishlinskii
//! core (plays) and a Preisach core (relays), each with the effects it takes. The cores
//! compete on prediction alone (the same scored samples, the same forecast rule): another
//! core is chosen only when its final model predicts below the Bouc-Wen model's 95 % band,
//! and that is the diagnosis' first finding ("the loop is not Bouc-Wen's: ..."). A Bouc-Wen
//! search that reaches the noise floor with its exponent inside its range has nothing to
//! reject, and the other cores are not run.

use super::Options;
use super::search::Search;
use crate::base::error::Result;
use crate::render::table::sig;
use serde::Serialize;

/// The model families that compete, the one the search starts from first.
pub const CORES: [&str; 3] = ["bouc-wen", "pi", "preisach"];

/// Within this of an end of its range (the structure's `n` spec) the Bouc-Wen exponent
/// sits at the bound.
const AT_BOUND: f64 = 0.02;

/// One core's search: its final model and how well that predicts.
#[derive(Clone, Debug, Serialize)]
pub struct CoreTrial {
    /// `bouc-wen`, `pi` or `preisach`.
    pub core: String,
    /// The final model the search reached with it.
    pub model: String,
    /// Its validation RMSE on the scored samples (predicted, [`super::forecast`]).
    pub validate_rmse: f64,
    /// 95 % band of that RMSE (moving-block bootstrap).
    pub validate_band: [f64; 2],
    pub train_rmse: f64,
    pub evaluations: u64,
    pub chosen: bool,
    /// Its final model's predicted output on the validation records (the same samples as
    /// [`super::Series`]' validation ones), for the figure.
    #[serde(skip)]
    pub validate_out: Vec<f64>,
}

/// How the core was chosen.
#[derive(Clone, Debug, Serialize)]
pub struct CoreChoice {
    pub started_with: String,
    /// What in the starting core's search made the other cores run (empty: nothing did).
    pub tried_because: Vec<String>,
    /// Each core searched, the starting one first.
    pub trials: Vec<CoreTrial>,
    pub chosen: String,
    /// The finding in words: the loop is not Bouc-Wen's, or why Bouc-Wen stays.
    pub finding: String,
}

/// What in a finished Bouc-Wen search rejects the core: its exponent at a bound, a final
/// prediction above the noise floor.
fn rejections(s: &Search) -> Vec<String> {
    let mut why = Vec::new();
    if let (Some(&n), Some([lo, hi])) = (s.final_summary().params.get("n"), s.param_range("n")) {
        let at = if n <= lo + AT_BOUND {
            Some(lo)
        } else if n >= hi - AT_BOUND {
            Some(hi)
        } else {
            None
        };
        if let Some(b) = at {
            why.push(format!(
                "its exponent n = {} sits at its bound {b}",
                sig(n, 3)
            ));
        }
    }
    if !s.at_floor() {
        let f = s.final_summary();
        why.push(format!(
            "its final model predicts the validation records to {}x the noise floor",
            sig(f.validate_rmse / s.noise().max(1e-300), 3)
        ));
    }
    why
}

fn trial(core: &str, s: &Search) -> CoreTrial {
    let f = s.final_summary();
    CoreTrial {
        core: core.into(),
        model: f.model.clone(),
        validate_rmse: f.validate_rmse,
        validate_band: f.validate_band,
        train_rmse: f.train_rmse,
        evaluations: s.evaluations(),
        chosen: false,
        validate_out: s.validate_output().to_vec(),
    }
}

/// A plain-words name of a core for the finding.
fn described(core: &str, opts: &Options) -> String {
    match core {
        "pi" => format!("a Prandtl-Ishlinskii core ({} plays)", opts.pi_operators),
        "preisach" => format!(
            "a Preisach core ({} levels, {} relays)",
            opts.preisach_levels,
            opts.preisach_levels * (opts.preisach_levels + 1) / 2
        ),
        _ => "the Bouc-Wen core".into(),
    }
}

/// The core the data choose: `bw` is the finished Bouc-Wen search; `search(model)` runs
/// the whole search with another core. The search kept, how it was chosen, and the
/// evaluations of the searches not kept.
pub(super) fn choose(
    bw: Search,
    opts: &Options,
    search: impl Fn(&str) -> Result<Search> + Sync,
) -> Result<(Search, CoreChoice, u64)> {
    let tried_because = rejections(&bw);
    let mut trials = vec![trial(CORES[0], &bw)];
    if tried_because.is_empty() {
        trials[0].chosen = true;
        let choice = CoreChoice {
            started_with: CORES[0].into(),
            tried_because,
            trials,
            chosen: CORES[0].into(),
            finding: "the Bouc-Wen core stays: its final model predicts to the noise floor \
                      and its exponent lies inside its range, so the other cores were not \
                      searched"
                .into(),
        };
        return Ok((bw, choice, 0));
    }
    bw.say("the Bouc-Wen core rejected: searching the operator cores");
    let (pi, preisach) = rayon::join(|| search(CORES[1]), || search(CORES[2]));
    let others = [(CORES[1], pi?), (CORES[2], preisach?)];
    trials.extend(others.iter().map(|(c, s)| trial(c, s)));
    let band = bw.final_summary().validate_band;
    // The best predictor among the other cores, taken if it predicts below the band.
    let best = (1..trials.len())
        .min_by(|&a, &b| trials[a].validate_rmse.total_cmp(&trials[b].validate_rmse))
        .filter(|&i| trials[i].validate_rmse < band[0]);
    let unit = bw.unit().to_string();
    let u = |x: f64| format!("{} {unit}", sig(x, 3));
    let because = tried_because.join("; ");
    let bwt = trials[0].clone();
    let (chosen_at, finding) = match best {
        Some(i) => {
            let t = &trials[i];
            (
                i,
                format!(
                    "the loop is not Bouc-Wen's: with {} the search reaches {}, which predicts \
                     the validation records to {}, below the band of the Bouc-Wen search's \
                     final model {} ({} to {} around {}; questioned because {because}); the \
                     effect search went on with the {} core",
                    described(&t.core, opts),
                    t.model,
                    u(t.validate_rmse),
                    bwt.model,
                    u(band[0]),
                    u(band[1]),
                    u(bwt.validate_rmse),
                    t.core
                ),
            )
        }
        None => {
            let other: Vec<String> = trials[1..]
                .iter()
                .map(|t| format!("{} {}", t.model, u(t.validate_rmse)))
                .collect();
            (
                0,
                format!(
                    "the Bouc-Wen core stays although {because}: no operator core predicts \
                     below its band ({} to {}): {}",
                    u(band[0]),
                    u(band[1]),
                    other.join(", ")
                ),
            )
        }
    };
    trials[chosen_at].chosen = true;
    let chosen = trials[chosen_at].core.clone();
    let mut all = vec![bw];
    all.extend(others.into_iter().map(|(_, s)| s));
    let kept = all.swap_remove(chosen_at);
    let spent = all.iter().map(Search::evaluations).sum();
    let choice = CoreChoice {
        started_with: CORES[0].into(),
        tried_because,
        trials,
        chosen,
        finding,
    };
    Ok((kept, choice, spent))
}
