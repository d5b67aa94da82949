//! LaTeX writers shared by every table: numbers, bold, escaping and the booktabs float.
//! Everything written compiles with pdflatex and `\usepackage{booktabs}` alone
//! (`scripts/check_latex.py` compiles a results folder's tables to check it).

use super::table::sig;

/// `x` in LaTeX math: `1.23`, or `1.23\cdot10^{-5}` when very small or large.
pub fn latex_num(x: f64) -> String {
    if x.is_nan() {
        return "--".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "$\\infty$" } else { "$-\\infty$" }.into();
    }
    let s = sig(x, 3);
    match s.split_once('e') {
        Some((m, e)) => format!("${m}\\cdot10^{{{e}}}$"),
        None => format!("${s}$"),
    }
}

/// `tex` (text, or math in `$...$` as [`latex_num`] writes it) in bold. `\textbf{$0$}`
/// leaves math digits regular, so the bold would be invisible: `\boldmath` switches math
/// to bold fonts too (minus signs and `\cdot` included), and `\bfseries` the text.
pub fn latex_bold(tex: &str) -> String {
    format!("{{\\bfseries\\boldmath {tex}}}")
}

/// `tex` with a math superscript: inside its math when it ends in math (`$x^{s}$`, not
/// `$x$$^{s}$`, which TeX may read as display math), else appended.
pub fn latex_sup(tex: &str, sup: &str) -> String {
    match tex.strip_prefix('$').and_then(|t| t.strip_suffix('$')) {
        // Braced: a number in powers of ten already ends in a superscript, and `x^a^b` is
        // TeX's "Double superscript" error.
        Some(math) => format!("${{{math}}}^{{{sup}}}$"),
        None => format!("{tex}$^{{{sup}}}$"),
    }
}

/// Text for LaTeX: every character that is special in text mode escaped (one escaper for
/// every table), and the few non-ASCII signs optbench writes (∞, —, ±) spelled in LaTeX,
/// since pdflatex's default inputenc knows no glyph for them.
pub(crate) fn latex_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '\\' => out += "\\textbackslash{}",
            '&' | '%' | '$' | '#' | '_' | '{' | '}' => {
                out.push('\\');
                out.push(ch);
            }
            '^' => out += "\\textasciicircum{}",
            '~' => out += "\\textasciitilde{}",
            '<' => out += "\\textless{}",
            '>' => out += "\\textgreater{}",
            '∞' => out += "$\\infty$",
            '—' => out += "---",
            '–' => out += "--",
            '±' => out += "$\\pm$",
            '×' => out += "$\\times$",
            _ => out.push(ch),
        }
    }
    out
}

/// A `\label` key from a name: letters, digits, `-`, `.` and `:` kept, the rest `-` (an
/// escaped `\_` in a label breaks `\ref`).
pub(crate) fn latex_label(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '.' | ':') {
                c
            } else {
                '-'
            }
        })
        .collect()
}

/// `s` ending as a sentence, so a caption's next sentence does not run on.
pub(crate) fn sentence(s: &str) -> String {
    let t = s.trim_end();
    if t.ends_with(['.', '!', '?']) {
        t.to_string()
    } else {
        format!("{t}.")
    }
}

/// A booktabs table with its float: `% optbench: {tag}` comment, `caption` (already
/// escaped), a label column and right-aligned `columns`, then `body` (rows ending in `\\`).
pub(crate) fn booktabs(tag: &str, caption: &str, columns: &[String], body: &str) -> String {
    let head: Vec<String> = columns.iter().map(|c| latex_escape(c)).collect();
    format!(
        "% optbench: {tag}\n% requires \\usepackage{{booktabs}}\n\\begin{{table}}[t]\n\\centering\n\\caption{{{caption}}}\n\\begin{{tabular}}{{l{}}}\n\\toprule\n & {} \\\\\n\\midrule\n{body}\\bottomrule\n\\end{{tabular}}\n\\end{{table}}\n",
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
        assert_eq!(latex_num(f64::INFINITY), "$\\infty$");
        assert_eq!(latex_num(f64::NAN), "--");
    }

    #[test]
    fn bold_reaches_math() {
        assert_eq!(latex_bold("$0$"), "{\\bfseries\\boldmath $0$}");
        assert_eq!(latex_sup("$0$", "1/3"), "${0}^{1/3}$");
        // A power of ten: the number braced, else "Double superscript" in TeX.
        assert_eq!(
            latex_sup(&latex_num(5.94e-15), "\\dagger"),
            "${5.94\\cdot10^{-15}}^{\\dagger}$"
        );
        assert_eq!(latex_sup("diverged", "3/3"), "diverged$^{3/3}$");
    }

    #[test]
    fn escaping_leaves_no_special_character_bare() {
        let s = latex_escape("a_b & 5% #1 {x} $y$ ^~ \\ ∞ <>");
        assert_eq!(
            s,
            "a\\_b \\& 5\\% \\#1 \\{x\\} \\$y\\$ \\textasciicircum{}\\textasciitilde{} \
             \\textbackslash{} $\\infty$ \\textless{}\\textgreater{}"
        );
        assert!(s.is_ascii());
        assert_eq!(latex_label("my_suite 2"), "my-suite-2");
        assert_eq!(sentence("Table 1 [mm]"), "Table 1 [mm].");
        assert_eq!(sentence("Done."), "Done.");
    }
}
