//! Plain-text tables for the terminal.

use crate::results::Summary;

/// `x` with `sig` significant digits, in scientific notation when very large or small.
pub fn sig(x: f64, sig: usize) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".into();
    }
    let mag = x.abs().log10().floor() as i32;
    if (-3..6).contains(&mag) {
        let decimals = (sig as i32 - 1 - mag).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.prec$e}", prec = sig - 1)
    }
}

/// Renders rows as an aligned Markdown table (readable raw and pasteable).
pub fn markdown(header: &[&str], rows: &[Vec<String>], right_align: &[bool]) -> String {
    let n = header.len();
    let mut width: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (w, c) in width.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    let line = |cells: Vec<String>| -> String {
        let mut s = String::from("|");
        for (i, c) in cells.iter().enumerate() {
            let pad = width[i] - c.chars().count();
            if right_align.get(i).copied().unwrap_or(false) {
                s += &format!(" {}{} |", " ".repeat(pad), c);
            } else {
                s += &format!(" {}{} |", c, " ".repeat(pad));
            }
        }
        s + "\n"
    };
    let mut out = line(header.iter().map(|h| h.to_string()).collect());
    let mut sep = String::from("|");
    for (i, w) in width.iter().enumerate().take(n) {
        if right_align.get(i).copied().unwrap_or(false) {
            sep += &format!(" {}: |", "-".repeat(w - 1));
        } else {
            sep += &format!(" {} |", "-".repeat(*w));
        }
    }
    out += &sep;
    out.push('\n');
    for r in rows {
        out += &line(r.clone());
    }
    out
}

/// The summary as a table: one row per objective x optimizer.
pub fn summary_table(summary: &Summary) -> String {
    let header = [
        "objective",
        "optimizer",
        "median",
        "q1",
        "q3",
        "mean",
        "std",
        "min",
        "max",
        "evals/trial",
        "trials",
        "wall s",
    ];
    let rows: Vec<Vec<String>> = summary
        .results
        .iter()
        .map(|c| {
            vec![
                c.objective.clone(),
                c.optimizer.clone(),
                sig(c.median, 4),
                sig(c.q1, 4),
                sig(c.q3, 4),
                sig(c.mean, 4),
                sig(c.std, 3),
                sig(c.min, 4),
                sig(c.max, 4),
                format!("{}", c.evaluations / c.trials.max(1) as u64),
                format!("{}", c.trials),
                format!("{:.2}", c.wall_s),
            ]
        })
        .collect();
    let right: Vec<bool> = (0..header.len()).map(|i| i >= 2).collect();
    markdown(&header, &rows, &right)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.000_02, 3), "2.00e-5");
        assert_eq!(sig(-837.965_7, 4), "-838.0");
        assert_eq!(sig(0.024_1, 3), "0.0241");
        assert_eq!(sig(123_456_789.0, 3), "1.23e8");
        assert_eq!(sig(0.0, 3), "0");
    }

    #[test]
    fn markdown_aligns_columns() {
        let t = markdown(
            &["a", "bb"],
            &[vec!["xyz".into(), "1".into()]],
            &[false, true],
        );
        assert_eq!(t, "| a   | bb |\n| --- | -: |\n| xyz |  1 |\n");
    }
}
