//! LaTeX writers shared by every table: numbers, escaping and the booktabs float.

use super::table::sig;

/// `x` in LaTeX math: `1.23`, or `1.23\cdot10^{-5}` when very small or large.
pub fn latex_num(x: f64) -> String {
    let s = sig(x, 3);
    match s.split_once('e') {
        Some((m, e)) => format!("${m}\\cdot10^{{{e}}}$"),
        None => format!("${s}$"),
    }
}

/// Text for LaTeX: backslash, `&`, `%`, `_` and `#` escaped (one escaper for every table).
pub(crate) fn latex_escape(s: &str) -> String {
    s.replace('\\', "\\textbackslash{}")
        .replace('&', "\\&")
        .replace('%', "\\%")
        .replace('_', "\\_")
        .replace('#', "\\#")
}

/// A booktabs table with its float: `% optbench: {tag}` comment, `caption` (already
/// escaped), a label column and right-aligned `columns`, then `body` (rows ending in `\\`).
pub(crate) fn booktabs(tag: &str, caption: &str, columns: &[String], body: &str) -> String {
    let head: Vec<String> = columns.iter().map(|c| latex_escape(c)).collect();
    format!(
        "% optbench: {tag}\n\\begin{{table}}[t]\n\\centering\n\\caption{{{caption}}}\n\\begin{{tabular}}{{l{}}}\n\\toprule\n & {} \\\\\n\\midrule\n{body}\\bottomrule\n\\end{{tabular}}\n\\end{{table}}\n",
        "r".repeat(columns.len()),
        head.join(" & ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latex_numbers() {
        assert_eq!(latex_num(0.000_012_3), "$1.23\\cdot10^{-5}$");
        assert_eq!(latex_num(12.0), "$12.0$");
    }
}
