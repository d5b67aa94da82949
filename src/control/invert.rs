//! Offline feedforward by an inverted Prandtl-Ishlinskii model: fit the plain PI model to a
//! training recording at its exact least-squares optimum, invert it analytically and
//! compute the command that makes the model follow a desired trajectory. Where a recording
//! also holds a command that was actually sent (e.g. by another inverse model) and the
//! output it produced, the command is compared with ours, and the model predicts what each
//! command achieves.
//!
//! Only the recorded command's *measured* tracking is real: our command was never sent to
//! the device, so everything said about it is what the fitted model predicts.

use crate::base::error::{Error, Result};
use crate::data::recording::Recording;
use crate::physics::prandtl_ishlinskii::{PiForm, PiModel};
use serde::Serialize;

/// Most play operators (each one a column over the whole record).
pub const MAX_OPERATORS: usize = 200;

/// Where the desired trajectory sits in the model's output units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DesiredOffset {
    /// As given (the desired column is in the recorded output's units).
    AsGiven,
    /// Shifted so its mean is the training output's: a desired trajectory given about zero
    /// while the sensor carries an offset (the mean removal of the P-885 authors).
    TrainMean,
    /// Shifted by this many output units.
    Shift(f64),
}

impl DesiredOffset {
    /// `none`, `train-mean` or a number.
    pub fn parse(s: &str) -> Result<DesiredOffset> {
        match s {
            "none" => Ok(DesiredOffset::AsGiven),
            "train-mean" => Ok(DesiredOffset::TrainMean),
            x => x
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .map(DesiredOffset::Shift)
                .ok_or_else(|| {
                    Error::Input(format!(
                        "--desired-offset {x}: expected none, train-mean or a number in the \
                         output's units"
                    ))
                }),
        }
    }
}

/// A named set of time intervals over which tracking is scored (`compensated=37:47,56:70.8`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Window {
    pub name: String,
    /// `[from, to)` in seconds.
    pub intervals: Vec<(f64, f64)>,
}

impl Window {
    /// `NAME=A:B[,C:D...]`, or `A:B[,...]` named by itself.
    pub fn parse(spec: &str) -> Result<Window> {
        let bad = |why: &str| {
            Error::Input(format!(
                "--window {spec}: {why}; expected NAME=FROM:TO[,FROM:TO...] in seconds, \
                 e.g. compensated=37:47,56:70.8"
            ))
        };
        let (name, list) = match spec.split_once('=') {
            Some((n, l)) if !n.trim().is_empty() => (n.trim().to_string(), l),
            Some(_) => return Err(bad("empty name")),
            None => (spec.to_string(), spec),
        };
        let intervals = list
            .split(',')
            .map(|iv| {
                let (a, b) = iv.split_once(':').ok_or_else(|| bad("no FROM:TO"))?;
                let num = |s: &str| s.trim().parse::<f64>().ok().filter(|x| x.is_finite());
                match (num(a), num(b)) {
                    (Some(a), Some(b)) if b > a => Ok((a, b)),
                    (Some(_), Some(_)) => Err(bad("TO must exceed FROM")),
                    _ => Err(bad("FROM and TO must be numbers")),
                }
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Window { name, intervals })
    }

    fn contains(&self, t: f64) -> bool {
        self.intervals.iter().any(|&(a, b)| t >= a && t < b)
    }
}

/// What to invert and how.
#[derive(Clone, Debug)]
pub struct InvertOptions {
    /// Play operators of the PI model (thresholds uniform over the training input).
    pub operators: usize,
    pub offset: DesiredOffset,
    /// Samples between a command and the output it produces (an acquisition delay): the
    /// model is fitted to `u(k) → y(k + lag)` and the command leads the desired trajectory.
    pub lag: usize,
    /// Where tracking is scored (empty: the whole desired record).
    pub windows: Vec<Window>,
}

/// The desired trajectory, and what was recorded with it.
#[derive(Clone, Debug)]
pub struct Desired {
    pub name: String,
    pub t: Vec<f64>,
    /// Desired output, in the model's output units before [`DesiredOffset`].
    pub y: Vec<f64>,
    /// A command that was sent to follow it (compared with ours).
    pub command: Option<Vec<f64>>,
    /// The output measured under that command.
    pub output: Option<Vec<f64>>,
}

/// Tracking over one window: RMS of output minus desired, and the same after removing the
/// window's mean error (an offset the sensor or the alignment may add).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Tracking {
    pub rmse: f64,
    pub rmse_centred: f64,
}

/// Figures on one window.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WindowFigures {
    pub name: String,
    pub samples: usize,
    /// Model-predicted tracking of our command.
    pub ours_predicted: Tracking,
    /// RMS of (recorded command − ours).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub command_rms_difference: Option<f64>,
    /// Model-predicted tracking of the recorded command. A recorded command is scored
    /// against the desired value at its own sample, its output `lag` samples later (a
    /// command that does not lead, as the P-885 authors compare theirs); ours leads by
    /// `lag` and is scored at the same sample.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recorded_predicted: Option<Tracking>,
    /// Measured tracking of the recorded command (real).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recorded_measured: Option<Tracking>,
    /// The model's free-run error on the recorded output under the recorded command.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model_free_run: Option<Tracking>,
}

/// The fitted model, its inverse, the command and the comparison.
#[derive(Clone, Debug, Serialize)]
pub struct Inversion {
    pub train: String,
    pub desired: String,
    pub operators: usize,
    pub lag: usize,
    /// What was added to the desired column.
    pub desired_shift: f64,
    pub model: PiModel,
    pub inverse: PiModel,
    pub train_rmse: f64,
    /// Training input range; a command outside it asks the model to extrapolate.
    pub train_input_range: [f64; 2],
    pub command_range: [f64; 2],
    /// Share of our command's samples outside the training input range.
    pub command_outside_share: f64,
    pub windows: Vec<WindowFigures>,
    #[serde(skip)]
    pub t: Vec<f64>,
    /// Desired output after the shift.
    #[serde(skip)]
    pub y_desired: Vec<f64>,
    #[serde(skip)]
    pub command: Vec<f64>,
    /// The model's output under our command, aligned with the desired samples.
    #[serde(skip)]
    pub predicted: Vec<f64>,
    #[serde(skip)]
    pub recorded_command: Option<Vec<f64>>,
    #[serde(skip)]
    pub recorded_predicted: Option<Vec<f64>>,
    #[serde(skip)]
    pub recorded_output: Option<Vec<f64>>,
}

fn range(x: &[f64]) -> [f64; 2] {
    x.iter()
        .fold([f64::INFINITY, f64::NEG_INFINITY], |[a, b], &v| {
            [a.min(v), b.max(v)]
        })
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len().max(1) as f64
}

/// Tracking of `out` `shift` samples later against `want` on the samples `idx`.
fn tracking(out: &[f64], want: &[f64], idx: &[usize], shift: usize) -> Tracking {
    let e: Vec<f64> = idx
        .iter()
        .filter(|&&k| k + shift < out.len())
        .map(|&k| out[k + shift] - want[k])
        .collect();
    let m = mean(&e);
    let rms = |f: &dyn Fn(f64) -> f64| {
        (e.iter().map(|&x| f(x).powi(2)).sum::<f64>() / e.len().max(1) as f64).sqrt()
    };
    Tracking {
        rmse: rms(&|x| x),
        rmse_centred: rms(&|x| x - m),
    }
}

/// `sim` (the model's output sample by sample) as the output `lag` samples later: the first
/// `lag` samples, before any command acts, repeat the first value.
fn delayed(sim: &[f64], lag: usize) -> Vec<f64> {
    (0..sim.len()).map(|k| sim[k.saturating_sub(lag)]).collect()
}

/// Fits, inverts and compares (see the module documentation).
pub fn invert(train: &Recording, desired: &Desired, opts: &InvertOptions) -> Result<Inversion> {
    if !(1..=MAX_OPERATORS).contains(&opts.operators) {
        return Err(Error::Input(format!(
            "--operators {}: expected 1 to {MAX_OPERATORS}",
            opts.operators
        )));
    }
    let n_train = train.len();
    if opts.lag * 4 >= n_train || opts.lag * 4 >= desired.y.len() {
        return Err(Error::Input(format!(
            "--lag {}: expected fewer than a quarter of each record's samples ({} training, {} \
             desired)",
            opts.lag,
            n_train,
            desired.y.len()
        )));
    }
    let n = desired.y.len();
    for (what, col) in [("command", &desired.command), ("output", &desired.output)] {
        if let Some(c) = col
            && c.len() != n
        {
            return Err(Error::Input(format!(
                "{}: the recorded {what} has {} samples, the desired trajectory {n}",
                desired.name,
                c.len()
            )));
        }
    }
    let (u, y) = (&train.u[..n_train - opts.lag], &train.y[opts.lag..]);
    let dt = train.dt();
    let thresholds = PiModel::uniform_thresholds(opts.operators, u);
    let model = PiModel::fit(PiForm::Plain, thresholds, u, y, dt)
        .map_err(|e| Error::Input(format!("{}: the PI fit failed: {e}", train.name)))?;
    let inverse = model.inverse().map_err(|e| {
        Error::Input(format!(
            "{}: the fitted PI model cannot be inverted ({e}); the output must rise with the \
             input (flip the output's sign if it falls)",
            train.name
        ))
    })?;
    let fitted = model.simulate(u, dt);
    let train_rmse = (fitted
        .iter()
        .zip(y)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / y.len() as f64)
        .sqrt();
    let desired_shift = match opts.offset {
        DesiredOffset::AsGiven => 0.0,
        DesiredOffset::TrainMean => mean(&train.y) - mean(&desired.y),
        DesiredOffset::Shift(s) => s,
    };
    let y_desired: Vec<f64> = desired.y.iter().map(|v| v + desired_shift).collect();
    // The command at k makes the output at k + lag: it inverts the desired trajectory that
    // far ahead, holding the last value where the record ends.
    let ahead: Vec<f64> = (0..n)
        .map(|k| y_desired[(k + opts.lag).min(n - 1)])
        .collect();
    let command = inverse.simulate(&ahead, dt);
    let predicted = delayed(&model.simulate(&command, dt), opts.lag);
    let recorded_predicted = desired
        .command
        .as_ref()
        .map(|c| delayed(&model.simulate(c, dt), opts.lag));
    let train_input_range = range(u);
    let command_range = range(&command);
    let outside = command
        .iter()
        .filter(|&&c| c < train_input_range[0] || c > train_input_range[1])
        .count();
    let whole = Window {
        name: "all".into(),
        intervals: vec![(f64::NEG_INFINITY, f64::INFINITY)],
    };
    let windows = if opts.windows.is_empty() {
        std::slice::from_ref(&whole)
    } else {
        &opts.windows[..]
    };
    let figures = windows
        .iter()
        .map(|w| {
            // Samples before the first command acts are not scored.
            let idx: Vec<usize> = (opts.lag..n)
                .filter(|&k| w.contains(desired.t[k]))
                .collect();
            if idx.is_empty() {
                return Err(Error::Input(format!(
                    "--window {}: no sample of {} lies in it (the record spans {} to {} s)",
                    w.name,
                    desired.name,
                    desired.t[0],
                    desired.t[n - 1]
                )));
            }
            let rms_diff = desired.command.as_ref().map(|c| {
                (idx.iter()
                    .map(|&k| (c[k] - command[k]).powi(2))
                    .sum::<f64>()
                    / idx.len() as f64)
                    .sqrt()
            });
            Ok(WindowFigures {
                name: w.name.clone(),
                samples: idx.len(),
                ours_predicted: tracking(&predicted, &y_desired, &idx, 0),
                command_rms_difference: rms_diff,
                recorded_predicted: recorded_predicted
                    .as_ref()
                    .map(|p| tracking(p, &y_desired, &idx, opts.lag)),
                recorded_measured: desired
                    .output
                    .as_ref()
                    .map(|o| tracking(o, &y_desired, &idx, opts.lag)),
                model_free_run: match (&recorded_predicted, &desired.output) {
                    (Some(p), Some(o)) => Some(tracking(p, o, &idx, 0)),
                    _ => None,
                },
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(Inversion {
        train: train.name.clone(),
        desired: desired.name.clone(),
        operators: opts.operators,
        lag: opts.lag,
        desired_shift,
        model,
        inverse,
        train_rmse,
        train_input_range,
        command_range,
        command_outside_share: outside as f64 / n as f64,
        windows: figures,
        t: desired.t.clone(),
        y_desired,
        command,
        predicted,
        recorded_command: desired.command.clone(),
        recorded_predicted,
        recorded_output: desired.output.clone(),
    })
}

impl Inversion {
    /// The feedforward CSV: time, desired output, our command, the model's output under it,
    /// then (when recorded) the recorded command, the model's output under it and the
    /// measured output.
    pub fn csv(&self) -> String {
        let mut head = vec!["t_s", "desired", "command", "predicted"];
        let mut extra: Vec<&Vec<f64>> = Vec::new();
        for (name, col) in [
            ("recorded_command", &self.recorded_command),
            ("recorded_predicted", &self.recorded_predicted),
            ("recorded_output", &self.recorded_output),
        ] {
            if let Some(c) = col {
                head.push(name);
                extra.push(c);
            }
        }
        let mut s = head.join(",");
        s.push('\n');
        for k in 0..self.t.len() {
            let mut row = vec![
                self.t[k],
                self.y_desired[k],
                self.command[k],
                self.predicted[k],
            ];
            row.extend(extra.iter().map(|c| c[k]));
            let cells: Vec<String> = row.iter().map(|v| format!("{v}")).collect();
            s.push_str(&cells.join(","));
            s.push('\n');
        }
        s
    }

    /// The report for humans: the fit, our command, and per window what each command
    /// achieves (saying which figures are predicted and which measured).
    pub fn report(&self) -> String {
        use std::fmt::Write;
        let g = |x: f64| crate::render::table::sig(x, 3);
        let mut s = String::new();
        let _ = writeln!(
            s,
            "plain PI model, {} operators, fitted at its least-squares optimum on {} \
             (output {} sample(s) after the command): training RMSE {}",
            self.operators,
            self.train,
            self.lag,
            g(self.train_rmse)
        );
        let _ = writeln!(
            s,
            "desired trajectory: {} shifted by {}; our command spans {} to {} (training input \
             {} to {}; {} % of samples outside it, where the model extrapolates)",
            self.desired,
            g(self.desired_shift),
            g(self.command_range[0]),
            g(self.command_range[1]),
            g(self.train_input_range[0]),
            g(self.train_input_range[1]),
            g(100.0 * self.command_outside_share)
        );
        let tr = |t: &Tracking| format!("{} ({} mean removed)", g(t.rmse), g(t.rmse_centred));
        for w in &self.windows {
            let _ = writeln!(s, "window {} ({} samples):", w.name, w.samples);
            let _ = writeln!(
                s,
                "  our command, model-predicted tracking RMSE: {} (predicted: never sent to the device)",
                tr(&w.ours_predicted)
            );
            if let Some(d) = w.command_rms_difference {
                let _ = writeln!(s, "  recorded command minus ours: RMS {}", g(d));
            }
            if let Some(t) = &w.recorded_predicted {
                let _ = writeln!(
                    s,
                    "  recorded command, model-predicted tracking RMSE: {}",
                    tr(t)
                );
            }
            if let Some(t) = &w.recorded_measured {
                let _ = writeln!(
                    s,
                    "  recorded command, measured tracking RMSE: {} (real; output {} sample(s) later)",
                    tr(t),
                    self.lag
                );
            }
            if let Some(t) = &w.model_free_run {
                let _ = writeln!(
                    s,
                    "  model free run against the measured output: RMSE {}",
                    tr(t)
                );
            }
        }
        s
    }
}

/// What `optbench invert` asks: files and columns as given on the command line.
#[derive(Clone, Debug)]
pub struct InvertRequest {
    pub train: std::path::PathBuf,
    /// Time, input and output columns of the training recording.
    pub train_columns: crate::data::recording::Columns,
    pub desired: std::path::PathBuf,
    pub time_column: String,
    pub desired_column: String,
    pub compare_command: Option<String>,
    pub compare_output: Option<String>,
    pub read: crate::data::recording::ReadOptions,
    pub options: InvertOptions,
    pub out: std::path::PathBuf,
}

/// One column of a CSV file (with its time column), through the recording reader so the
/// same checks and messages apply.
fn read_column(
    path: &std::path::Path,
    time: &str,
    column: &str,
    read: &crate::data::recording::ReadOptions,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let columns = crate::data::recording::Columns {
        time: time.into(),
        input: column.into(),
        output: column.into(),
    };
    let r = Recording::read_csv(path, &columns, read)?;
    Ok((r.t, r.u))
}

/// Reads the files, inverts, writes `feedforward.csv` and `invert.json` into `out`, and
/// returns the report.
pub fn run(req: &InvertRequest) -> Result<String> {
    let train = Recording::read_csv(&req.train, &req.train_columns, &req.read)?;
    let (t, y) = read_column(
        &req.desired,
        &req.time_column,
        &req.desired_column,
        &req.read,
    )?;
    let other = |c: &Option<String>| {
        c.as_ref()
            .map(|c| read_column(&req.desired, &req.time_column, c, &req.read).map(|r| r.1))
            .transpose()
    };
    let desired = Desired {
        name: format!("{} [{}]", req.desired.display(), req.desired_column),
        t,
        y,
        command: other(&req.compare_command)?,
        output: other(&req.compare_output)?,
    };
    let inv = invert(&train, &desired, &req.options)?;
    crate::base::create_dir_within(&req.out, &req.out)?;
    crate::base::atomic_write(&req.out.join("feedforward.csv"), inv.csv().as_bytes())?;
    let json = serde_json::to_string_pretty(&inv)
        .map_err(|e| Error::Input(format!("invert.json: {e}")))?;
    crate::base::atomic_write(&req.out.join("invert.json"), json.as_bytes())?;
    Ok(format!(
        "{}feedforward.csv and invert.json in {}\n",
        inv.report(),
        req.out.display()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine_record(n: usize, dt: f64) -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        // Amplitude ramps make minor loops, which a PI model must nest.
        let u = t
            .iter()
            .map(|&s| 1.8 + 1.7 * (0.3 + 0.7 * (s / 3.0).sin().abs()) * (6.3 * s).sin())
            .collect();
        (t, u)
    }

    #[test]
    fn windows_and_offsets_parse_or_say_what_is_expected() {
        let w = Window::parse("comp=37:47,56:70.8").unwrap();
        assert_eq!(w.intervals, vec![(37.0, 47.0), (56.0, 70.8)]);
        assert!(w.contains(40.0) && !w.contains(50.0));
        assert_eq!(Window::parse("1:2").unwrap().name, "1:2");
        for bad in ["a=3:1", "=1:2", "a=1", "a=x:2"] {
            let e = Window::parse(bad).unwrap_err().to_string();
            assert!(e.contains("expected NAME=FROM:TO"), "{e}");
        }
        assert_eq!(
            DesiredOffset::parse("train-mean").unwrap(),
            DesiredOffset::TrainMean
        );
        assert_eq!(
            DesiredOffset::parse("-2.5").unwrap(),
            DesiredOffset::Shift(-2.5)
        );
        assert!(DesiredOffset::parse("nan").is_err());
    }

    /// On a recording made by a PI model the fit recovers it and our command makes the
    /// fitted model follow the desired trajectory to rounding; a command recorded with a
    /// different trajectory is reported as different.
    #[test]
    fn the_inverse_makes_the_model_track_and_a_lag_is_honoured() {
        let dt = 0.005;
        let (t, u) = sine_record(2400, dt);
        let truth = PiModel {
            form: PiForm::Plain,
            thresholds: vec![0.0, 0.4, 0.9, 1.5],
            weights: vec![6.0, 2.0, 1.5, 0.7],
            rate_weights: vec![],
            poly: vec![],
            offset: -96.0,
            input_offset: 0.0,
        };
        for lag in [0usize, 2] {
            let y0 = truth.simulate(&u, dt);
            let y: Vec<f64> = (0..u.len()).map(|k| y0[k.saturating_sub(lag)]).collect();
            let train = Recording::uniform("pi", dt, u.clone(), y).unwrap();
            let want: Vec<f64> = t.iter().map(|&s| 8.0 * (6.0 * s).sin()).collect();
            let desired = Desired {
                name: "want".into(),
                t: t.clone(),
                y: want,
                command: Some(u.clone()),
                output: None,
            };
            let opts = InvertOptions {
                operators: 16,
                offset: DesiredOffset::TrainMean,
                lag,
                windows: vec![Window::parse("late=2:12").unwrap()],
            };
            let inv = invert(&train, &desired, &opts).unwrap();
            let centre = inv.desired_shift + mean(&desired.y);
            let w = &inv.windows[0];
            assert!(inv.train_rmse < 0.05, "lag {lag}: {}", inv.train_rmse);
            assert!(
                w.ours_predicted.rmse < 1e-9,
                "lag {lag}: {:?}",
                w.ours_predicted
            );
            assert!(w.command_rms_difference.unwrap() > 0.1);
            assert!(w.recorded_predicted.as_ref().unwrap().rmse > 1.0);
            assert!((centre - mean(&train.y)).abs() < 1e-9);
            assert_eq!(inv.csv().lines().count(), t.len() + 1);
        }
    }

    #[test]
    fn bad_requests_are_refused_with_the_reason() {
        let dt = 0.01;
        let (t, u) = sine_record(400, dt);
        let train = Recording::uniform("pi", dt, u.clone(), u.clone()).unwrap();
        let desired = Desired {
            name: "want".into(),
            t,
            y: u.clone(),
            command: None,
            output: None,
        };
        let opts = |operators, lag, w: &str| InvertOptions {
            operators,
            offset: DesiredOffset::AsGiven,
            lag,
            windows: vec![Window::parse(w).unwrap()],
        };
        let err = |o| invert(&train, &desired, &o).unwrap_err().to_string();
        assert!(err(opts(0, 0, "0:1")).contains("--operators 0"));
        assert!(err(opts(8, 300, "0:1")).contains("--lag 300"));
        assert!(err(opts(8, 0, "x=50:60")).contains("no sample"));
        // An output falling with the input has no positive linear weight to invert.
        let falling =
            Recording::uniform("neg", dt, u.clone(), u.iter().map(|v| -v).collect()).unwrap();
        let e = invert(&falling, &desired, &opts(8, 0, "0:1"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot be inverted"), "{e}");
    }
}
