//! Reference trajectories (mm) for the closed loop: the dissertation's sinusoids whose frequency
//! rises with time (§4.2: 1 -> 2, 1 -> 3, 1 -> 4 and 1 -> 10 Hz), or any signal of the
//! signal library ([`crate::data::signal`]).

use crate::base::error::{Error, Result};
use crate::base::limits;
use crate::data::signal::{ChirpLaw, Signal};
use std::f64::consts::FRAC_PI_2;

/// Seconds of the dissertation's sweeps: the frequency rises linearly over the whole run.
pub const SWEEP_SECONDS: f64 = 5.0;
/// Mid-range of the sweeps (mm): the twin spans 0-0.6 mm over its 0-70 V drive.
pub const SWEEP_OFFSET: f64 = 0.3;
/// Amplitude of the sweeps (mm): 0.05-0.55 mm, inside the span with a margin at both ends.
pub const SWEEP_AMP: f64 = 0.25;
/// The dissertation's end frequencies (Hz), all sweeps starting at 1 Hz.
pub const SEED_SWEEPS: [f64; 4] = [2.0, 3.0, 4.0, 10.0];

/// A named reference trajectory of fixed length.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Short name (file names, tables): `sweep-1-2hz`, or the spec as given.
    pub name: String,
    pub signal: Signal,
    /// Seconds.
    pub duration: f64,
}

impl Reference {
    /// The dissertation's sinusoid from 1 Hz rising linearly to `f1` Hz over [`SWEEP_SECONDS`]
    /// (phase-continuous; the dissertation's figures are not available and its text does not say
    /// how the frequency changed), 0.05-0.55 mm, starting at the bottom (phase −π/2) so the
    /// loop does not begin with a jump.
    pub fn sweep(f1: f64) -> Reference {
        Reference {
            name: format!("sweep-1-{f1}hz"),
            signal: Signal::Chirp {
                f0: 1.0,
                f1,
                duration: SWEEP_SECONDS,
                law: ChirpLaw::Linear,
                amp: SWEEP_AMP,
                phase: -FRAC_PI_2,
                offset: SWEEP_OFFSET,
            },
            duration: SWEEP_SECONDS,
        }
    }

    /// The dissertation's four sweeps of §4.2.
    pub fn seed_references() -> Vec<Reference> {
        SEED_SWEEPS.iter().map(|&f| Reference::sweep(f)).collect()
    }

    /// Parses a reference: `sweep-1-F hz` names (`sweep-1-2hz`, `sweep-1-10hz`, any F > 0)
    /// or a signal spec in mm (`sine:freq=5,amp=0.2,offset=0.3`). `duration` (s) overrides
    /// the length; a signal other than a chirp needs it.
    pub fn parse(spec: &str, duration: Option<f64>) -> Result<Reference> {
        let spec = spec.trim();
        let mut r = match sweep_end(spec) {
            Some(f1) => Reference::sweep(f1),
            None => {
                let signal = Signal::parse(spec).map_err(|e| {
                    Error::Input(format!(
                        "reference `{spec}`: {e} (or name a sweep: sweep-1-2hz, sweep-1-3hz, \
                         sweep-1-4hz, sweep-1-10hz)"
                    ))
                })?;
                let d = match (&signal, duration) {
                    (_, Some(d)) => d,
                    (Signal::Chirp { duration, .. }, None) => *duration,
                    _ => {
                        return Err(Error::Input(format!(
                            "reference `{spec}`: give a duration (seconds) for this signal"
                        )));
                    }
                };
                Reference {
                    name: spec.to_string(),
                    signal,
                    duration: d,
                }
            }
        };
        if let Some(d) = duration {
            r.duration = d;
        }
        if !(r.duration > 0.0 && r.duration.is_finite()) {
            return Err(Error::Input(format!(
                "reference `{spec}`: duration {} must be > 0",
                r.duration
            )));
        }
        // Sampled at the loop's step (`control::run::DT`, 1 ms).
        limits::samples(r.duration, 1e-3)
            .map_err(|e| Error::Input(format!("reference `{spec}`: {e}")))?;
        Ok(r)
    }

    /// Samples at `0, dt, 2dt, ...` over the duration.
    pub fn sample(&self, dt: f64) -> Vec<f64> {
        self.signal.sample(dt, self.duration)
    }
}

/// `F` of a `sweep-1-Fhz` name.
fn sweep_end(spec: &str) -> Option<f64> {
    let f = spec.strip_prefix("sweep-1-")?.strip_suffix("hz")?;
    let f: f64 = f.parse().ok()?;
    (f > 0.0 && f.is_finite()).then_some(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweeps_rise_from_one_hz_within_the_span() {
        let refs = Reference::seed_references();
        let names: Vec<&str> = refs.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(
            names,
            ["sweep-1-2hz", "sweep-1-3hz", "sweep-1-4hz", "sweep-1-10hz"]
        );
        for r in &refs {
            let y = r.sample(1e-3);
            assert_eq!(y.len(), 5000);
            assert!((y[0] - 0.05).abs() < 1e-12, "starts at the bottom");
            assert!(y.iter().all(|v| (0.05 - 1e-12..=0.55 + 1e-12).contains(v)));
        }
        // Zero crossings of y - 0.3 upwards: one per cycle, the cycles shorten with time.
        let y = Reference::sweep(10.0).sample(1e-3);
        let ups: Vec<usize> = (1..y.len())
            .filter(|&k| y[k - 1] < 0.3 && y[k] >= 0.3)
            .collect();
        // Cycles = ∫ f dt = 1·5 + 9·5/2 = 27.5 over 5 s.
        assert!((27..=28).contains(&ups.len()), "{}", ups.len());
        let first = ups[1] - ups[0];
        let last = ups[ups.len() - 1] - ups[ups.len() - 2];
        assert!(first > 5 * last, "{first} vs {last}");
    }

    #[test]
    fn parses_names_and_signals() {
        assert_eq!(
            Reference::parse("sweep-1-3hz", None).unwrap(),
            Reference::sweep(3.0)
        );
        let r = Reference::parse("sweep-1-2hz", Some(2.0)).unwrap();
        assert_eq!((r.duration, r.sample(1e-3).len()), (2.0, 2000));
        let r = Reference::parse("sine:freq=5,amp=0.2,offset=0.3", Some(1.5)).unwrap();
        assert_eq!(r.sample(1e-3).len(), 1500);
        let r = Reference::parse("chirp:f0=1,f1=3,duration=2,amp=0.1", None).unwrap();
        assert_eq!(r.duration, 2.0);
        for (bad, needle) in [
            ("sine:freq=5", "give a duration"),
            ("sinus:freq=5", "sweep-1-2hz"),
            ("sweep-1-0hz", "sweep-1-2hz"),
        ] {
            let e = Reference::parse(bad, None).unwrap_err().to_string();
            assert!(e.contains(needle), "{bad}: {e}");
        }
        assert!(Reference::parse("sweep-1-2hz", Some(-1.0)).is_err());
    }
}
