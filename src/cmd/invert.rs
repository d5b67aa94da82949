//! `optbench invert`: the feedforward command of an inverted Prandtl-Ishlinskii model for a
//! desired trajectory, compared with a recorded command where one is given.

use crate::base::error::Result;
use crate::control::invert::{DesiredOffset, InvertOptions, InvertRequest, Window};
use crate::data::recording::{Columns, Delimiter, ReadOptions};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct InvertArgs {
    /// Training recording (CSV with a header): the plain PI model is fitted to it at its
    /// exact least-squares optimum (non-negative play weights).
    #[arg(long)]
    pub train: PathBuf,
    /// Time, input and output columns of --train.
    #[arg(long, default_value = "t,u,y")]
    pub columns: String,
    /// Recording (CSV) holding the desired trajectory.
    #[arg(long)]
    pub desired: PathBuf,
    /// Column of --desired with the desired output.
    #[arg(long, default_value = "y")]
    pub desired_column: String,
    /// Time column of --desired.
    #[arg(long, default_value = "t")]
    pub time_column: String,
    /// Column of --desired with a command actually sent for that trajectory: reported as
    /// its RMS difference from ours and what the model predicts it achieves.
    #[arg(long)]
    pub compare_command: Option<String>,
    /// Column of --desired with the output measured under that command: its real tracking
    /// error, and the model's free-run error against it.
    #[arg(long, requires = "compare_command")]
    pub compare_output: Option<String>,
    /// Where the desired trajectory sits: none (as given, in the output's units),
    /// train-mean (shifted to the training output's mean: a trajectory given about zero
    /// while the sensor has an offset), or a shift in output units.
    #[arg(long, default_value = "none", allow_hyphen_values = true)]
    pub desired_offset: String,
    /// Play operators (thresholds uniform over the training input's half-range).
    #[arg(long, default_value_t = 20)]
    pub operators: usize,
    /// Samples between a command and the output it produces (an acquisition delay).
    #[arg(long, default_value_t = 0)]
    pub lag: usize,
    /// Score tracking over NAME=FROM:TO[,FROM:TO...] (seconds). Repeatable; default the
    /// whole record.
    #[arg(long)]
    pub window: Vec<String>,
    /// Column separator: auto, ',', ';', tab or whitespace.
    #[arg(long, default_value = "auto")]
    pub delimiter: Delimiter,
    /// Records with gaps or irregular time stamps are linearly interpolated onto a uniform
    /// grid.
    #[arg(long)]
    pub resample: bool,
    /// Output folder: feedforward.csv (time, desired, command, predicted, ...) and
    /// invert.json (model, inverse, figures).
    #[arg(long, default_value = "results/invert")]
    pub out: PathBuf,
}

pub fn run(a: InvertArgs) -> Result<()> {
    let req = InvertRequest {
        train: a.train,
        train_columns: Columns::parse(&a.columns)?,
        desired: a.desired,
        time_column: a.time_column,
        desired_column: a.desired_column,
        compare_command: a.compare_command,
        compare_output: a.compare_output,
        read: ReadOptions {
            resample: a.resample,
            delimiter: a.delimiter,
        },
        options: InvertOptions {
            operators: a.operators,
            offset: DesiredOffset::parse(&a.desired_offset)?,
            lag: a.lag,
            windows: a
                .window
                .iter()
                .map(|w| Window::parse(w))
                .collect::<Result<_>>()?,
        },
        out: a.out,
    };
    print!("{}", crate::control::invert::run(&req)?);
    Ok(())
}
