//! `optbench report DIR [OTHER]`: a results folder's report regenerated from its traces, or
//! two runs of one suite compared.

use crate::base::error::Result;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ReportArgs {
    /// Results folder written by `optbench run`.
    pub results: PathBuf,
    /// A second results folder of the same suite: print the differences instead.
    pub other: Option<PathBuf>,
}

pub fn run(args: ReportArgs) -> Result<()> {
    match args.other {
        Some(other) => print!("{}", crate::report::compare(&args.results, &other)?),
        None => {
            let table = crate::report::generate(&args.results)?;
            print!("{table}");
            println!("\nreport: {}", args.results.join("report.md").display());
        }
    }
    Ok(())
}
