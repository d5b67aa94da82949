//! `optbench completions SHELL` and `optbench man --out DIR`: generated from the command
//! definitions themselves, so they never fall behind the flags.

use crate::base::error::{Error, Result};
use clap::CommandFactory;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct CompletionsArgs {
    /// Shell to complete in, e.g. `optbench completions bash > ~/.local/share/bash-completion/completions/optbench`.
    pub shell: clap_complete::Shell,
}

#[derive(clap::Args, Debug)]
pub struct ManArgs {
    /// Folder the pages are written into (created; e.g. ~/.local/share/man/man1).
    #[arg(long, default_value = "results/man")]
    pub out: PathBuf,
}

pub fn completions(a: CompletionsArgs) -> Result<()> {
    let mut cmd = super::Cli::command();
    clap_complete::generate(a.shell, &mut cmd, "optbench", &mut std::io::stdout());
    Ok(())
}

pub fn man(a: ManArgs) -> Result<()> {
    if a.out.is_file() {
        return Err(Error::Input(format!(
            "--out {}: is a file, expected a folder",
            a.out.display()
        )));
    }
    std::fs::create_dir_all(&a.out)
        .map_err(|e| Error::io(format!("creating {}", a.out.display()), e))?;
    let root = super::Cli::command();
    // One page per command, named as `man` looks them up: optbench.1, optbench-run.1, ...
    let mut pages = vec![("optbench".to_string(), root.clone())];
    for sub in root.get_subcommands() {
        let name = format!("optbench-{}", sub.get_name());
        pages.push((name.clone(), sub.clone().name(name)));
    }
    for (name, cmd) in pages {
        let mut page = Vec::new();
        clap_mangen::Man::new(cmd)
            .render(&mut page)
            .map_err(|e| Error::io(format!("rendering the man page {name}"), e))?;
        let path = a.out.join(format!("{name}.1"));
        crate::base::atomic::atomic_write(&path, &page)?;
        println!("{}", path.display());
    }
    println!("read with: man -l {}", a.out.join("optbench.1").display());
    Ok(())
}
