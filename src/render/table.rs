//! Plain-text tables for the terminal.

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

/// A cell's `|` escaped, so it stays one cell when rendered (`true | false`).
fn cell(c: &str) -> String {
    c.replace('|', "\\|")
}

/// Renders rows as an aligned Markdown table (readable raw and pasteable); a `|` inside a
/// cell is escaped.
pub fn markdown(header: &[&str], rows: &[Vec<String>], right_align: &[bool]) -> String {
    let header: Vec<String> = header.iter().map(|h| cell(h)).collect();
    let rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| r.iter().map(|c| cell(c)).collect())
        .collect();
    let n = header.len();
    let mut width: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for r in &rows {
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
    let mut out = line(header.clone());
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
    for r in &rows {
        out += &line(r.clone());
    }
    out
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
        // A `|` in a cell stays in its cell: every line has as many separators.
        let t = markdown(&["kind"], &[vec!["true | false".into()]], &[]);
        assert_eq!(
            t,
            "| kind          |\n| ------------- |\n| true \\| false |\n"
        );
    }
}
