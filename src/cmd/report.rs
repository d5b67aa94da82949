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
    /// No table: only the path of the report.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn run(args: ReportArgs) -> Result<()> {
    match args.other {
        Some(other) => print!("{}", crate::report::compare(&args.results, &other)?),
        None => {
            // The report writes into the folder: not while a run or merge writes it.
            let _lock = match args.results.is_dir() {
                true => Some(crate::pipeline::store::lock_folder(&args.results)?),
                false => None, // nothing to lock; `generate` says what is missing
            };
            let table = crate::report::generate(&args.results)?;
            if !args.quiet {
                print!("{table}");
            }
            println!("\nreport: {}", args.results.join("report.md").display());
        }
    }
    Ok(())
}
