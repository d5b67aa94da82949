//! Another input the validation file holds: a structure driven on several inputs at once
//! (a mirror on three piezos) puts the responses to the others into the output, which no
//! single-input model can explain. Each other column in the input's unit is set beside the
//! final residual: the share of the residual's power that is coherent with it (the coherent
//! output power, `Σ γ² S_ee / Σ S_ee` over Welch bins) says how much of what is left that
//! input drives.

use super::Diagnosis;
use super::residual;
use crate::render::table::sig;
use serde::Serialize;

/// A column holding at least this share of the residual's power coherently is reported.
pub const COUPLING_SHARE: f64 = 0.1;

/// Welch segment length (samples) of the coherence.
const SEGMENT: usize = 1024;

/// One other input of the validation file set beside the final residual.
#[derive(Clone, Debug, Serialize)]
pub struct Coupling {
    pub column: String,
    /// Share of the final validation residual's power coherent with the column.
    pub share: f64,
    /// Largest significant coherence and its frequency (Hz).
    pub peak_coherence: f64,
    pub peak_hz: f64,
}

impl Coupling {
    /// One line for the text report.
    pub fn line(&self) -> String {
        format!(
            "{} holds {} % of the final validation residual's power coherently (coherence up to {} at {} Hz): another input drives this output, which a single-input model cannot hold",
            self.column,
            sig(100.0 * self.share, 3),
            sig(self.peak_coherence, 3),
            sig(self.peak_hz, 3)
        )
    }
}

/// The other inputs (`(column, samples)`, the validation record's length) that hold at
/// least [`COUPLING_SHARE`] of the final validation residual coherently.
pub fn couplings(d: &Diagnosis, others: &[(String, Vec<f64>)]) -> Vec<Coupling> {
    let s = &d.series;
    let e: Vec<f64> = s.y[1]
        .iter()
        .zip(&s.final_model[1])
        .map(|(y, m)| y - m)
        .collect();
    others
        .iter()
        .filter(|(_, x)| x.len() == e.len())
        .filter_map(|(column, x)| {
            let sp = residual::spectra(x, &e, s.dt[1], SEGMENT);
            // 95 % significance of a coherence estimated from K segments.
            let k = sp.segments.max(2) as f64;
            let level = 1.0 - 0.05f64.powf(1.0 / (k - 1.0));
            let total: f64 = sp.psd_e.iter().sum();
            let coherent: f64 = sp
                .coherence
                .iter()
                .zip(&sp.psd_e)
                .filter(|(c, _)| **c > level)
                .map(|(c, p)| c * p)
                .sum();
            let (at, peak) = sp
                .coherence
                .iter()
                .enumerate()
                .skip(1)
                .fold((0, 0.0), |b, (i, &c)| if c > b.1 { (i, c) } else { b });
            let share = if total > 0.0 { coherent / total } else { 0.0 };
            (share >= COUPLING_SHARE).then(|| Coupling {
                column: column.clone(),
                share,
                peak_coherence: peak,
                peak_hz: sp.freq[at],
            })
        })
        .collect()
}
