//! Sampled input/output records: what an actuator experiment (or the twin) produces and what
//! the fitting objectives consume.

use crate::error::{Error, Result};

/// A uniformly sampled single-input single-output record.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Where it came from (file name, or a description of the simulation).
    pub name: String,
    /// Sample times, strictly increasing and uniform (to 1e-6 relative).
    pub t: Vec<f64>,
    /// Input (e.g. drive command in V, or force in N).
    pub u: Vec<f64>,
    /// Output (e.g. displacement in mm).
    pub y: Vec<f64>,
    /// Units of t, u, y for labels ("s", "V", "mm"); free text.
    pub units: [String; 3],
}

/// Fewest samples a recording may have (a fit needs lags and some data).
pub const MIN_SAMPLES: usize = 8;

impl Recording {
    /// Checked constructor: equal lengths, at least [`MIN_SAMPLES`], finite values, strictly
    /// increasing uniform time.
    pub fn new(name: impl Into<String>, t: Vec<f64>, u: Vec<f64>, y: Vec<f64>) -> Result<Self> {
        let name = name.into();
        if t.len() != u.len() || t.len() != y.len() {
            return Err(Error::Input(format!(
                "{name}: t, u, y have {}, {}, {} samples",
                t.len(),
                u.len(),
                y.len()
            )));
        }
        if t.len() < MIN_SAMPLES {
            return Err(Error::Input(format!(
                "{name}: {} samples, at least {MIN_SAMPLES} needed",
                t.len()
            )));
        }
        for (i, ((a, b), c)) in t.iter().zip(&u).zip(&y).enumerate() {
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                return Err(Error::Input(format!("{name}: sample {i} is not finite")));
            }
        }
        let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        for i in 1..t.len() {
            let step = t[i] - t[i - 1];
            if step <= 0.0 {
                return Err(Error::Input(format!(
                    "{name}: time is not strictly increasing at sample {i}"
                )));
            }
            if (step - dt).abs() > 1e-6 * dt.abs().max(1e-300) + 1e-9 * t[i].abs() {
                return Err(Error::Input(format!(
                    "{name}: non-uniform sampling at sample {i} (step {step} s, mean {dt} s)"
                )));
            }
        }
        Ok(Recording {
            name,
            t,
            u,
            y,
            units: ["s".into(), String::new(), String::new()],
        })
    }

    /// A recording sampled at `dt` from time 0.
    pub fn uniform(name: impl Into<String>, dt: f64, u: Vec<f64>, y: Vec<f64>) -> Result<Self> {
        let t = (0..u.len()).map(|k| k as f64 * dt).collect();
        Self::new(name, t, u, y)
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Sampling interval.
    pub fn dt(&self) -> f64 {
        (self.t[self.len() - 1] - self.t[0]) / (self.len() - 1) as f64
    }

    /// The samples `range` as a new recording.
    pub fn slice(&self, range: std::ops::Range<usize>) -> Result<Self> {
        let mut r = Self::new(
            format!("{}[{}..{}]", self.name, range.start, range.end),
            self.t[range.clone()].to_vec(),
            self.u[range.clone()].to_vec(),
            self.y[range].to_vec(),
        )?;
        r.units = self.units.clone();
        Ok(r)
    }
}
