//! `optbench list`: every objective and optimizer kind with its parameters and defaults.

use crate::base::error::{Error, Result};
use crate::registry::{objective_kinds, optimizer_kinds};
use crate::render::table::markdown;

#[derive(clap::Args, Debug)]
pub struct ListArgs {
    /// Print JSON (objectives and optimizers with their parameters) for scripts.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: ListArgs) -> Result<()> {
    if a.json {
        let text = serde_json::to_string_pretty(&list_json())
            .map_err(|e| Error::Input(format!("list as JSON: {e}")))?;
        println!("{text}");
    } else {
        print!("{}", list());
    }
    Ok(())
}

/// The same content as [`list`], as data: `{"objectives": [...], "optimizers": [...]}`, each
/// kind with `name`, `help` and `params` (`name`, `type`, `default`, `help`).
pub fn list_json() -> serde_json::Value {
    let kind = |name: &str, help: &str, params: &[crate::base::params::Spec]| {
        serde_json::json!({
            "name": name,
            "help": help,
            "params": params.iter().map(|p| serde_json::json!({
                "name": p.name,
                "type": p.kind.to_string(),
                "default": p.default.to_string(),
                "help": p.help,
            })).collect::<Vec<_>>(),
        })
    };
    serde_json::json!({
        "objectives": objective_kinds().iter().map(|k| kind(k.name, k.help, k.params)).collect::<Vec<_>>(),
        "optimizers": optimizer_kinds().iter().map(|k| kind(k.name, k.help, k.params)).collect::<Vec<_>>(),
    })
}

/// The text of `optbench list`.
pub fn list() -> String {
    let mut s = String::new();
    let section = |s: &mut String,
                   title: &str,
                   name: &str,
                   help: &str,
                   params: &[crate::base::params::Spec]| {
        s.push_str(&format!("{title} `{name}`: {help}\n"));
        let rows: Vec<Vec<String>> = params
            .iter()
            .map(|p| {
                vec![
                    p.name.to_string(),
                    p.kind.to_string(),
                    p.default.to_string(),
                    p.help.to_string(),
                ]
            })
            .collect();
        if rows.is_empty() {
            s.push_str("  (no parameters)\n\n");
        } else {
            for line in markdown(&["parameter", "type", "default", "meaning"], &rows, &[]).lines() {
                s.push_str("  ");
                s.push_str(line);
                s.push('\n');
            }
            s.push('\n');
        }
    };
    s.push_str(
        "OBJECTIVES ([[objective]] kind = ...; also id, budget, targets, stop_at, optimizers)\n\n",
    );
    for k in objective_kinds() {
        section(&mut s, "objective", k.name, k.help, k.params);
    }
    s.push_str("OPTIMIZERS ([[optimizer]] kind = ...; also id, polish, polish_with)\n\n");
    for k in optimizer_kinds() {
        section(&mut s, "optimizer", k.name, k.help, k.params);
    }
    s
}
