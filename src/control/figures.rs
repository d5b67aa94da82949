//! The dissertation's control figures for one run, drawn with the render kit (bundled
//! font, SVG + PNG, atomic writes): output and reference over time with the tracking error
//! below (Fig. 4.3, 4.5, 4.7, 4.9), and output against reference, the hysteresis
//! compensation picture (Fig. 4.4, 4.6, 4.8, 4.10), with the transient removed as the dissertation
//! did, and the transient on its own.

use super::closed_loop::LoopRun;
use crate::base::error::Result;
use crate::render;
use std::path::Path;

/// Writes `<prefix>time`, `<prefix>time-transient`, `<prefix>compensation` and
/// `<prefix>compensation-transient` (.svg and .png) into `dir` (which must exist). `title`
/// names the run (controller, reference). Parts with no samples (a run that failed inside
/// its transient) are skipped; returns the stems written.
pub fn write_run_figures(
    dir: &Path,
    prefix: &str,
    title: &str,
    run: &LoopRun,
    transient_s: f64,
) -> Result<Vec<String>> {
    let t = run.time();
    let k0 = ((transient_s / run.dt) - 1e-9).ceil().max(0.0) as usize;
    let k0 = k0.min(run.len());
    let failed = run
        .failure
        .as_ref()
        .map(|f| format!(" — FAILED at {:.3} s", f.time_s))
        .unwrap_or_default();
    let mut written = Vec::new();
    let time = |stem: &str, range: std::ops::Range<usize>, what: &str| -> Result<()> {
        render::timeseries_with_error(
            &dir.join(stem),
            &format!("{title}: {what}{failed}"),
            &t[range.clone()],
            ("output", &run.output[range.clone()]),
            &[("reference".to_string(), run.reference[range].to_vec())],
            "time [s]",
            "displacement [mm]",
        )
    };
    let loops = |stem: &str, range: std::ops::Range<usize>, what: &str| -> Result<()> {
        render::loops(
            &dir.join(stem),
            &format!("{title}: {what}{failed}"),
            &run.reference[range.clone()],
            ("output", &run.output[range.clone()]),
            &[(
                "ideal (y = reference)".to_string(),
                run.reference[range].to_vec(),
            )],
            "reference [mm]",
            "output [mm]",
        )
    };
    if run.is_empty() {
        return Ok(written);
    }
    let n = run.len();
    let stem = format!("{prefix}time");
    time(&stem, 0..n, "tracking (error = reference - output)")?;
    written.push(stem);
    if k0 > 0 {
        let stem = format!("{prefix}time-transient");
        time(&stem, 0..k0, &format!("first {transient_s} s"))?;
        written.push(stem);
        let stem = format!("{prefix}compensation-transient");
        loops(
            &stem,
            0..k0,
            &format!("output vs reference, first {transient_s} s"),
        )?;
        written.push(stem);
    }
    if k0 < n {
        let stem = format!("{prefix}compensation");
        loops(
            &stem,
            k0..n,
            &format!("output vs reference after {transient_s} s"),
        )?;
        written.push(stem);
    }
    Ok(written)
}
