//! Where a fitting objective's recording comes from, as written in suites and on the
//! command line:
//!
//! - a CSV file: `$OPTBENCH_DATA/boucwen-benchmark/test_multisine.csv` (`$OPTBENCH_DATA`
//!   expands to [`data_dir`]), or a path relative to the suite file's folder (a suite
//!   stores it made absolute, see [`anchored`]); columns are
//!   picked by name, read with [`ReadOptions`] (suite keys `resample`, `delimiter`);
//! - `twin:<signal>`: the piezo twin driven by a signal (see [`crate::data::signal`]), simulated
//!   from a fixed noise seed, so a suite regenerates the same recording every time;
//! - `eq318:<signal>`: the dissertation's numerical identification example (eq. 3.18).

use crate::base::error::{Error, Result};
use crate::base::limits;
use crate::data::recording::{Columns, ReadOptions, Recording, data_dir};
use crate::data::signal::Signal;
use crate::physics::rbf;
use crate::physics::twin::{self, TwinConfig};
use std::path::{Path, PathBuf};

/// Options that apply to simulated sources.
#[derive(Debug, Clone)]
pub struct SimOptions {
    /// Seconds of signal (chirps carry their own duration when this is None).
    pub duration: Option<f64>,
    /// Sampling interval in seconds (1 ms, as in the dissertation).
    pub dt: f64,
    /// Twin overrides, e.g. `mode=off,creep=on`.
    pub twin: String,
    /// Noise seed of the twin.
    pub seed: u64,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            duration: None,
            dt: 1e-3,
            twin: String::new(),
            seed: 1,
        }
    }
}

/// A parsed recording source.
#[derive(Debug, Clone)]
pub enum Source {
    Csv {
        path: PathBuf,
        columns: Columns,
        read: ReadOptions,
    },
    Twin {
        signal: Signal,
        opts: SimOptions,
    },
    Eq318 {
        signal: Signal,
        opts: SimOptions,
    },
}

/// Expands a leading `$OPTBENCH_DATA` and resolves relative paths against `base`.
pub fn resolve_path(spec: &str, base: &Path) -> PathBuf {
    if let Some(rest) = spec.strip_prefix("$OPTBENCH_DATA") {
        return data_dir().join(rest.trim_start_matches(['/', '\\']));
    }
    let p = PathBuf::from(spec);
    if p.is_absolute() { p } else { base.join(p) }
}

/// `spec` with a relative CSV path made absolute against `base` (the suite's folder), so the
/// spec means the same file read from anywhere, e.g. from the suite's copy in a results
/// folder; None when it already does: simulated sources, absolute paths, and
/// `$OPTBENCH_DATA` paths (kept symbolic: each reader's data folder is where the data is).
pub fn anchored(spec: &str, base: &Path) -> Option<String> {
    if spec.starts_with("twin:") || spec.starts_with("eq318:") || spec.starts_with("$OPTBENCH_DATA")
    {
        return None;
    }
    let p = Path::new(spec);
    if p.is_absolute() {
        return None;
    }
    let joined = base.join(p);
    // The file itself where it exists (no `dir/../` left), else the path made absolute.
    let abs = std::fs::canonicalize(&joined)
        .or_else(|_| std::path::absolute(&joined))
        .ok()?;
    abs.to_str().map(String::from)
}

/// The duration of a simulated source; its samples (`duration / dt`) within
/// [`MAX_SAMPLES`](crate::base::limits::MAX_SAMPLES).
fn duration_of(signal: &Signal, opts: &SimOptions, spec: &str) -> Result<f64> {
    let d = match (opts.duration, signal) {
        (Some(d), _) if d > 0.0 && d.is_finite() => Ok(d),
        (Some(d), _) => Err(Error::Input(format!("`{spec}`: duration {d} must be > 0"))),
        (None, Signal::Chirp { duration, .. }) => Ok(*duration),
        (None, _) => Err(Error::Input(format!(
            "`{spec}`: give a duration (seconds) for this signal"
        ))),
    }?;
    limits::samples(d, opts.dt).map_err(|e| Error::Input(format!("`{spec}`: {e}")))?;
    Ok(d)
}

impl Source {
    /// Parses `spec`; file paths are resolved against `base` (the suite's folder).
    pub fn parse(spec: &str, base: &Path, columns: &str, opts: SimOptions) -> Result<Source> {
        if let Some(sig) = spec.strip_prefix("twin:") {
            let signal = Signal::parse(sig)?;
            duration_of(&signal, &opts, spec)?;
            return Ok(Source::Twin { signal, opts });
        }
        if let Some(sig) = spec.strip_prefix("eq318:") {
            let signal = Signal::parse(sig)?;
            duration_of(&signal, &opts, spec)?;
            return Ok(Source::Eq318 { signal, opts });
        }
        Ok(Source::Csv {
            path: resolve_path(spec, base),
            columns: Columns::parse(columns)?,
            read: ReadOptions::default(),
        })
    }

    /// The source with `read` for a CSV file (simulated sources ignore it).
    pub fn read_with(mut self, read: ReadOptions) -> Source {
        if let Source::Csv { read: r, .. } = &mut self {
            *r = read;
        }
        self
    }

    /// The recording (read, or simulated deterministically); what reading did to a file
    /// (delimiter, jitter absorbed, resampling) is printed to stderr.
    pub fn load(&self) -> Result<Recording> {
        match self {
            Source::Csv {
                path,
                columns,
                read,
            } => {
                if !path.exists() {
                    return Err(Error::Input(format!(
                        "{}: no such file (data sets are read from $OPTBENCH_DATA, now {})",
                        path.display(),
                        data_dir().display()
                    )));
                }
                read_noting(path, columns, read)
            }
            Source::Twin { signal, opts } => {
                let d = duration_of(signal, opts, "twin")?;
                let u = signal.sample(opts.dt, d);
                twin_recording(signal, u, opts)
            }
            Source::Eq318 { signal, opts } => {
                let d = duration_of(signal, opts, "eq318")?;
                let r = signal.sample(opts.dt, d);
                let y = rbf::eq_3_18(&r);
                Recording::uniform(format!("eq. 3.18 driven by {signal}"), opts.dt, r, y)
            }
        }
    }
}
/// [`Recording::read_csv_noted`], its notes printed to stderr (where every command that
/// reads recordings says what was done to them), a constant input or output refused
/// ([`Recording::check_varies`]): the one read of fit, suites, diagnose and control.
pub fn read_noting(path: &Path, columns: &Columns, read: &ReadOptions) -> Result<Recording> {
    let (rec, notes) = Recording::read_csv_noted(path, columns, read)?;
    rec.check_varies(columns)?;
    for n in notes {
        eprintln!("note: {n}");
    }
    Ok(rec)
}

/// The twin driven by `u` (samples of `signal`), with the options' overrides and seed.
fn twin_recording(signal: &Signal, u: Vec<f64>, opts: &SimOptions) -> Result<Recording> {
    let cfg = TwinConfig::parse_overrides(&opts.twin)?;
    let name = if opts.twin.is_empty() {
        format!("twin driven by {signal} (seed {})", opts.seed)
    } else {
        format!(
            "twin [{}] driven by {signal} (seed {})",
            opts.twin, opts.seed
        )
    };
    twin::recording(&cfg, name, u, opts.dt, opts.seed)
}
