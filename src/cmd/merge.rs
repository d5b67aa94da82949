//! `optbench merge DIR... --out DIR`: the shards of a run combined into one results folder.

use crate::base::error::Result;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// Results folders of the shards.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Where the merged results go.
    #[arg(long)]
    pub out: PathBuf,
    /// No table.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn run(a: MergeArgs) -> Result<()> {
    print!(
        "{}",
        crate::pipeline::scale::merge(&a.dirs, &a.out, a.quiet, Some(crate::report::generate))?
    );
    Ok(())
}
