//! Markdown tables (GitHub-flavoured: they render on GitHub and in any GFM viewer, and
//! read aligned as plain text in the terminal) and the number format every table shares.

/// `x` with `sig` significant digits, in scientific notation when very large or small.
pub fn sig(x: f64, sig: usize) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".into();
    }
    // The magnitude after rounding, so 0.9996 prints as 1.00, not 1.000 (integers keep
    // their digits: 6288, not 6290).
    let rounded: f64 = format!("{x:.prec$e}", prec = sig.max(1) - 1)
        .parse()
        .unwrap_or(x);
    let mag = rounded.abs().log10().floor() as i32;
    if (-3..6).contains(&mag) {
        let decimals = (sig as i32 - 1 - mag).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.prec$e}", prec = sig - 1)
    }
}

/// A cell's `|` escaped, so it stays one cell when rendered (`true | false`), and a line
/// break made a space (a newline would end the table).
fn cell(c: &str) -> String {
    c.replace('|', "\\|").replace(['\n', '\r'], " ")
}

/// Narrowest column: a GFM delimiter cell needs a `-` besides its `:` (`-:`), and three
/// keep empty headers visible in the raw text.
const MIN_WIDTH: usize = 3;

/// Renders rows as an aligned GFM table (readable raw and pasteable); a `|` inside a cell
/// is escaped. Every row gets the header's cell count: short rows are padded with empty
/// cells and long ones are a bug of the caller (debug assertion), since GFM drops the
/// excess silently.
pub fn markdown(header: &[&str], rows: &[Vec<String>], right_align: &[bool]) -> String {
    let header: Vec<String> = header.iter().map(|h| cell(h)).collect();
    let n = header.len();
    debug_assert!(
        rows.iter().all(|r| r.len() <= n),
        "a Markdown row has more cells than its header {header:?}"
    );
    let rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let mut r: Vec<String> = r.iter().take(n).map(|c| cell(c)).collect();
            r.resize(n, String::new());
            r
        })
        .collect();
    let mut width: Vec<usize> = header
        .iter()
        .map(|h| h.chars().count().max(MIN_WIDTH))
        .collect();
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

/// The cells of a GFM table line, split at unescaped `|` as GitHub does (outer pipes
/// optional), each trimmed, with `\|` read as the `|` it stands for.
pub(crate) fn gfm_cells(line: &str) -> Vec<String> {
    let t = line.trim();
    let t = t.strip_prefix('|').unwrap_or(t);
    let t = match t.strip_suffix('|') {
        Some(inner) if !inner.ends_with('\\') => inner,
        _ => t,
    };
    let mut cells = vec![String::new()];
    let mut chars = t.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                cells.last_mut().expect("one cell").push('|');
                chars.next();
            }
            '|' => cells.push(String::new()),
            _ => cells.last_mut().expect("one cell").push(c),
        }
    }
    cells.iter().map(|c| c.trim().to_string()).collect()
}

/// Checks every table of a Markdown document as a GFM renderer reads it: a block of lines
/// starting with `|` must have a delimiter row as its second line with the header's cell
/// count, and every row must have that count too. Returns how many tables it saw.
#[cfg(test)]
pub(crate) fn check_gfm_tables(md: &str) -> Result<usize, String> {
    let lines: Vec<&str> = md.lines().collect();
    let mut i = 0;
    let mut tables = 0;
    while i < lines.len() {
        if !lines[i].trim_start().starts_with('|') {
            i += 1;
            continue;
        }
        let start = i;
        while i < lines.len() && lines[i].trim_start().starts_with('|') {
            i += 1;
        }
        let block = &lines[start..i];
        let head = gfm_cells(block[0]);
        let delim = block.get(1).map(|l| gfm_cells(l)).unwrap_or_default();
        let is_delim = |c: &String| {
            let d = c.trim_start_matches(':').trim_end_matches(':');
            !d.is_empty() && d.chars().all(|x| x == '-')
        };
        if delim.is_empty() || !delim.iter().all(is_delim) {
            return Err(format!(
                "line {}: a table without a delimiter row: {:?}",
                start + 2,
                block.get(1)
            ));
        }
        if delim.len() != head.len() {
            return Err(format!(
                "line {}: {} header cells but {} delimiter cells",
                start + 1,
                head.len(),
                delim.len()
            ));
        }
        for (k, row) in block.iter().enumerate().skip(2) {
            let n = gfm_cells(row).len();
            if n != head.len() {
                return Err(format!(
                    "line {}: {n} cells, the header has {}: {row}",
                    start + k + 1,
                    head.len()
                ));
            }
        }
        // A paragraph line right after a table would render as one more row.
        if let Some(next) = lines.get(i).filter(|l| !l.trim().is_empty()) {
            return Err(format!(
                "line {}: text right after a table becomes a row; leave a blank line: {next}",
                i + 1
            ));
        }
        tables += 1;
    }
    Ok(tables)
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
        // Rounding up to the next decade keeps the digits.
        assert_eq!(sig(0.999_6, 3), "1.00");
        assert_eq!(sig(999_999.0, 3), "1.00e6");
    }

    #[test]
    fn markdown_aligns_columns() {
        let t = markdown(
            &["a", "bb"],
            &[vec!["xyz".into(), "1".into()]],
            &[false, true],
        );
        assert_eq!(t, "| a   |  bb |\n| --- | --: |\n| xyz |   1 |\n");
        // A `|` in a cell stays in its cell: every line has as many separators.
        let t = markdown(&["kind"], &[vec!["true | false".into()]], &[]);
        assert_eq!(
            t,
            "| kind          |\n| ------------- |\n| true \\| false |\n"
        );
    }

    #[test]
    fn every_row_has_the_headers_cell_count_and_pipes_are_escaped() {
        let rows = vec![
            vec!["a | b".to_string(), "x".into(), "1".into()],
            vec!["short".to_string()],
            vec!["line\nbreak".to_string(), "|".into(), "".into()],
        ];
        let t = markdown(&["", "p", "q|r"], &rows, &[false, true, true]);
        assert_eq!(check_gfm_tables(&t), Ok(1), "{t}");
        for line in t.lines() {
            assert_eq!(gfm_cells(line).len(), 3, "{line}");
        }
        assert_eq!(gfm_cells(t.lines().next().unwrap())[2], "q|r");
        assert_eq!(
            gfm_cells(t.lines().nth(3).unwrap()),
            ["short", "", ""],
            "{t}"
        );
        // The checker itself: it sees the issue's broken header, a row too long, no
        // delimiter row, and a paragraph glued under a table.
        let broken = "| o | median (1% | 10%) |\n| --- | --- |\n| a | 1 |\n";
        assert!(
            check_gfm_tables(broken)
                .unwrap_err()
                .contains("3 header cells but 2")
        );
        assert!(check_gfm_tables("| a |\n| - |\n| 1 | 2 |\n").is_err());
        assert!(check_gfm_tables("| a |\n| b |\n").is_err());
        assert!(check_gfm_tables("| a |\n| - |\nmore\n").is_err());
        assert_eq!(check_gfm_tables("| a |\n| :-: |\n\ntext\n"), Ok(1));
    }
}
