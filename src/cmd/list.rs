//! `optbench list`: every objective and optimizer kind with its parameters and defaults.

use crate::registry::{objective_kinds, optimizer_kinds};
use crate::render::table::markdown;

pub fn run() {
    print!("{}", list());
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
