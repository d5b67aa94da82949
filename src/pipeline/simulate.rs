//! `optbench simulate`: recordings of the piezo twin, by default the dissertation's experiments
//! (sinusoids at 1, 4, 10, 20 and 28 Hz and the validation signal of Fig. 3.27(b)).

use crate::base::error::{Error, Result};
use crate::data::recording::Columns;
use crate::data::signal::seed_experiments;
use crate::objective::source::{SimOptions, Source};
use std::path::{Path, PathBuf};

/// What to simulate.
#[derive(Debug, Clone)]
pub struct SimulateRequest {
    /// One signal (with its duration), or None for the dissertation's experiments.
    pub signal: Option<(String, Option<f64>)>,
    pub twin: String,
    pub seed: u64,
    pub dt: f64,
    pub columns: Columns,
    pub out: PathBuf,
}

/// Writes the recordings and returns one line per file.
pub fn run(req: &SimulateRequest) -> Result<String> {
    let opts = |duration: Option<f64>| SimOptions {
        duration,
        dt: req.dt,
        twin: req.twin.clone(),
        seed: req.seed,
    };
    let jobs: Vec<(String, Source)> = match &req.signal {
        Some((spec, duration)) => vec![(
            "twin".into(),
            Source::parse(
                &format!("twin:{spec}"),
                Path::new("."),
                "t,u,y",
                opts(*duration),
            )?,
        )],
        None => seed_experiments()
            .into_iter()
            .map(|(name, signal, duration)| {
                let src = Source::Twin {
                    signal,
                    opts: opts(Some(duration)),
                };
                (name, src)
            })
            .collect(),
    };
    std::fs::create_dir_all(&req.out)
        .map_err(|e| Error::io(format!("creating {}", req.out.display()), e))?;
    let mut text = String::new();
    for (name, src) in jobs {
        let rec = src.load()?;
        let path = req.out.join(format!("{name}.csv"));
        rec.write_csv(&path, &req.columns)?;
        let (lo, hi) = rec
            .y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        text += &format!(
            "{}: {} samples, {:.3} s, y in [{lo:.4}, {hi:.4}] {}\n",
            path.display(),
            rec.len(),
            rec.dt() * (rec.len() - 1) as f64,
            rec.units[2]
        );
    }
    Ok(text)
}
