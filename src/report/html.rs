//! `report.html`: a results folder on one self-contained page (no file beside it, no
//! network): the report's text and tables, every figure embedded as a data URI, the
//! statistics explained, and the provenance. Built from the same `report.md` text the
//! folder holds, through a converter for the Markdown subset optbench writes (headings,
//! paragraphs, lists, GFM tables, `**bold**`, `` `code` `` and links), so the page and the
//! Markdown never disagree. Every piece of text is HTML-escaped; links to the folder's
//! figures become anchors to their embedded copies, other links plain text.

use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use crate::render::table::gfm_cells;
use std::fmt::Write as _;
use std::path::Path;

/// What one page shows.
pub struct Page<'a> {
    /// The `<title>` and the page's heading.
    pub title: &'a str,
    /// The report as written to `report.md` (its own first heading is dropped: the page
    /// has one).
    pub markdown: &'a str,
    /// Markdown explaining the statistics the report uses.
    pub statistics: &'a str,
    /// Folder of the figures (`<stem>.svg`, `<stem>.png`), and the prefix `report.md`
    /// links them with (`plots/`, `figures/`).
    pub figures: &'a Path,
    pub figures_link: &'a str,
    /// Headings to group figures by: a figure whose stem ends in `_{key}` goes under `key`
    /// (objectives); the rest under "Other figures", or all together when empty.
    pub figure_groups: &'a [String],
    /// `provenance.json` (shown as a key/value table; absent: said so).
    pub provenance: &'a Path,
}

/// Writes `dir/report.html`.
pub fn write(dir: &Path, page: &Page<'_>) -> Result<()> {
    atomic_write(&dir.join("report.html"), render(page)?.as_bytes())
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1280px;margin:1em auto;padding:0 1em;\
color:#111;line-height:1.45}table{border-collapse:collapse;margin:.6em 0 1.2em;font-size:.9em}\
th,td{border:1px solid #bbb;padding:.2em .5em;vertical-align:top}th{background:#eee}\
td.r,th.r{text-align:right;font-variant-numeric:tabular-nums}td.c,th.c{text-align:center}\
code{background:#f3f3f3;padding:0 .2em}nav li{display:inline;margin-right:1em}\
.figs{display:flex;flex-wrap:wrap;gap:1em}figure{margin:0;width:610px;max-width:100%}\
figure img{width:100%;height:auto;border:1px solid #ddd}figcaption{font-size:.85em;color:#333}\
h2{border-bottom:1px solid #ccc;margin-top:1.6em}.note{color:#444}";

/// The whole page.
pub fn render(page: &Page<'_>) -> Result<String> {
    let figures = list_figures(page.figures)?;
    let stems: Vec<&str> = figures.iter().map(|f| f.0.as_str()).collect();
    let ctx = Links {
        prefix: page.figures_link,
        stems: &stems,
    };
    // The report's own title line is the page's heading.
    let body = page
        .markdown
        .strip_prefix('#')
        .filter(|_| !page.markdown.starts_with("##"))
        .map_or(page.markdown, |rest| {
            rest.split_once('\n').map_or("", |x| x.1)
        });
    let mut report = String::new();
    blocks(body, &ctx, &mut report);
    let mut stats = String::new();
    blocks(page.statistics, &ctx, &mut stats);

    let mut s = String::new();
    writeln!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{0}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{0}</h1>",
        escape(page.title)
    )
    .unwrap();
    s += "<nav><ul><li><a href=\"#report\">Report</a></li><li><a href=\"#figures\">Figures</a></li>\
          <li><a href=\"#statistics\">Statistics explained</a></li>\
          <li><a href=\"#provenance\">Provenance</a></li></ul></nav>\n";
    writeln!(s, "<section id=\"report\">\n{report}</section>").unwrap();
    writeln!(s, "<section id=\"figures\">\n<h2>Figures</h2>").unwrap();
    if figures.is_empty() {
        s += "<p class=\"note\">This run drew no figures.</p>\n";
    }
    for (heading, group) in group_figures(&figures, page.figure_groups) {
        if let Some(h) = heading {
            writeln!(s, "<h3>{}</h3>", escape(&h)).unwrap();
        }
        s += "<div class=\"figs\">\n";
        for (stem, kind, data) in group {
            writeln!(
                s,
                "<figure id=\"{}\"><img alt=\"{}\" src=\"data:{kind};base64,{}\">\
                 <figcaption>{}</figcaption></figure>",
                escape(&figure_anchor(stem)),
                escape(stem),
                base64(data),
                escape(stem)
            )
            .unwrap();
        }
        s += "</div>\n";
    }
    s += "</section>\n";
    writeln!(
        s,
        "<section id=\"statistics\">\n<h2>Statistics explained</h2>\n{stats}</section>"
    )
    .unwrap();
    writeln!(
        s,
        "<section id=\"provenance\">\n<h2>Provenance</h2>\n{}</section>",
        provenance_table(page.provenance)?
    )
    .unwrap();
    s += "</body>\n</html>\n";
    Ok(s)
}

/// What the statistics of a benchmark or fitting suite's report mean, as the report uses
/// them (Markdown, for [`Page::statistics`]).
pub fn benchmark_statistics() -> String {
    use super::analysis::{ALPHA, CI_LEVEL, RESAMPLES};
    format!(
        "Every number summarises the trials of one cell (objective x optimizer): each trial \
         is an independent seeded run, and counts with its **final best**: the error to the \
         optimum (f - f*) where the optimum is known, else the value itself (for a fit, the \
         RMSE named beside the objective).

- **Median**: the middle final value over the trials; robust to a few failed runs, so the \
  tables rank by it. **q1, q3**: the quartiles (type 7, linear interpolation); q3 - q1 is \
  the interquartile range (**IQR**), the spread of the middle half. The convergence \
  figures draw the median and the IQR band of the best-so-far value over the evaluations.
- **[{lo}, {hi}] after a median**: a {ci} % confidence interval of the median, by the \
  percentile bootstrap ({RESAMPLES} resamples of the trials, seeded, so it is reproducible). \
  With few trials it is wide: two intervals that overlap do not show a difference, nor do \
  two that do not overlap prove one; the tests below decide.
- **mean, std, min, max**: over the same final values; the mean and std are pulled by \
  outliers, shown for completeness.
- **Bold**: {tie}. A dagger in LaTeX, a star here: significantly different from the best.
- **Mann-Whitney U** (p): two-sided rank test of whether two optimizers' final values come \
  from the same distribution; it needs no normality. Every pair of optimizers on an \
  objective is tested, so the p-values are **Holm**-corrected over those pairs (the \
  step-down correction that keeps the chance of any false 'different' below {ALPHA}); \
  p (Holm) < {ALPHA} counts as different.
- **A12** (Vargha-Delaney): the probability that a random trial of A ends higher (worse) \
  than a random trial of B, ties counting half; 0.5 = no difference, 0.71 or more (0.29 \
  or less) is conventionally a large effect. It says how much, where p says how sure.
- **Average rank and Friedman test**: each objective ranks the optimizers by median (1 = \
  best); the ranks are averaged over the objectives, and Friedman's test asks whether \
  they differ more than chance would make them.
- **Fixed budget**: the median best-so-far value after 1 %, 10 % and 100 % of the \
  evaluation budget: who is good early, who late.
- **Success rate and ERT** (fixed target): a trial succeeds when its error reaches the \
  target. The expected running time ERT = evaluations spent by all trials (a failed trial \
  counts its whole budget) / successes: the evaluations a restarted optimizer needs on \
  average to reach the target once. The runtime ECDF figures show, over all (trial, \
  target) pairs, the share reached within so many evaluations.",
        ci = (CI_LEVEL * 100.0).round(),
        lo = "lo",
        hi = "hi",
        tie = super::paper::TIE_RULE,
    )
}

/// A figure: stem, MIME type and bytes (the SVG where there is one, else the PNG).
type Figure = (String, &'static str, Vec<u8>);

fn list_figures(dir: &Path) -> Result<Vec<Figure>> {
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    let entries =
        std::fs::read_dir(dir).map_err(|e| Error::io(format!("reading {}", dir.display()), e))?;
    let mut stems = std::collections::BTreeSet::new();
    for e in entries {
        let e = e.map_err(|e| Error::io(format!("reading {}", dir.display()), e))?;
        let p = e.path();
        if matches!(p.extension().and_then(|x| x.to_str()), Some("svg" | "png"))
            && let Some(stem) = p.file_stem().and_then(|x| x.to_str())
        {
            stems.insert(stem.to_string());
        }
    }
    let mut out = Vec::new();
    for stem in stems {
        let (path, kind) = match dir.join(format!("{stem}.svg")) {
            svg if svg.is_file() => (svg, "image/svg+xml"),
            _ => (dir.join(format!("{stem}.png")), "image/png"),
        };
        let data = std::fs::read(&path)
            .map_err(|e| Error::io(format!("reading {}", path.display()), e))?;
        out.push((stem, kind, data));
    }
    Ok(out)
}

/// Figures under their group's heading, in the groups' order, then the rest.
fn group_figures<'f>(
    figures: &'f [Figure],
    keys: &[String],
) -> Vec<(Option<String>, Vec<&'f Figure>)> {
    if keys.is_empty() {
        return vec![(None, figures.iter().collect())];
    }
    let key_of = |stem: &str| {
        keys.iter()
            .filter(|k| stem.ends_with(&format!("_{k}")))
            .max_by_key(|k| k.len())
    };
    let mut out: Vec<(Option<String>, Vec<&Figure>)> = keys
        .iter()
        .map(|k| {
            let of: Vec<&Figure> = figures.iter().filter(|f| key_of(&f.0) == Some(k)).collect();
            (Some(k.clone()), of)
        })
        .collect();
    out.push((
        Some("Other figures".into()),
        figures.iter().filter(|f| key_of(&f.0).is_none()).collect(),
    ));
    out.retain(|g| !g.1.is_empty());
    out
}

fn figure_anchor(stem: &str) -> String {
    format!("fig-{stem}")
}

fn provenance_table(path: &Path) -> Result<String> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(format!(
            "<p class=\"note\">No provenance: {} is missing.</p>\n",
            escape(&path.display().to_string())
        ));
    };
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::at(path, e.line(), e))?;
    let Some(map) = v.as_object() else {
        return Err(Error::Input(format!(
            "{}: expected a JSON object of provenance fields",
            path.display()
        )));
    };
    let mut s = String::from("<table>\n");
    for (k, v) in map {
        let text = match v {
            serde_json::Value::String(x) => x.clone(),
            serde_json::Value::Array(a) if a.iter().all(|x| x.is_string()) => a
                .iter()
                .filter_map(|x| x.as_str())
                .collect::<Vec<_>>()
                .join(" "),
            other => other.to_string(),
        };
        writeln!(
            s,
            "<tr><th>{}</th><td>{}</td></tr>",
            escape(k),
            escape(&text)
        )
        .unwrap();
    }
    s += "</table>\n";
    Ok(s)
}

/// Text safe in HTML content and in quoted attributes.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out += "&amp;",
            '<' => out += "&lt;",
            '>' => out += "&gt;",
            '"' => out += "&quot;",
            '\'' => out += "&#39;",
            _ => out.push(c),
        }
    }
    out
}

/// Standard base64 with padding (RFC 4648), for the data URIs.
fn base64(data: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ABC[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Where links may go: the folder's figures (as anchors) and anchors in the page.
struct Links<'a> {
    prefix: &'a str,
    stems: &'a [&'a str],
}

impl Links<'_> {
    /// The anchor a Markdown link target becomes, if it stays a link.
    fn target(&self, href: &str) -> Option<String> {
        if let Some(anchor) = href.strip_prefix('#') {
            return Some(anchor.to_string());
        }
        let file = href.strip_prefix(self.prefix)?;
        let stem = file.rsplit_once('.').map_or(file, |x| x.0);
        self.stems.contains(&stem).then(|| figure_anchor(stem))
    }
}

/// A heading's anchor: lower case, alphanumerics kept, runs of anything else one `-`.
fn slug(text: &str) -> String {
    let mut s = String::new();
    for c in text.chars().flat_map(char::to_lowercase) {
        if c.is_alphanumeric() {
            s.push(c);
        } else if !s.ends_with('-') && !s.is_empty() {
            s.push('-');
        }
    }
    s.trim_end_matches('-').to_string()
}

fn is_table_start(lines: &[&str], i: usize) -> bool {
    lines[i].trim_start().starts_with('|')
        && lines.get(i + 1).is_some_and(|l| {
            let cells = gfm_cells(l);
            !cells.is_empty()
                && cells.iter().all(|c| {
                    let d = c.trim_matches(':');
                    !d.is_empty() && d.chars().all(|x| x == '-')
                })
        })
}

/// Block-level Markdown into `out`.
fn blocks(md: &str, links: &Links<'_>, out: &mut String) {
    let lines: Vec<&str> = md.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i];
        let t = line.trim();
        if t.is_empty() {
            i += 1;
        } else if let Some(level) = heading_level(t) {
            let text = t[level..].trim();
            writeln!(
                out,
                "<h{l} id=\"{}\">{}</h{l}>",
                escape(&slug(text)),
                inline(text, links),
                l = level
            )
            .unwrap();
            i += 1;
        } else if t.starts_with("```") {
            i += 1;
            out.push_str("<pre><code>");
            while i < lines.len() && !lines[i].trim_start().starts_with("```") {
                out.push_str(&escape(lines[i]));
                out.push('\n');
                i += 1;
            }
            out.push_str("</code></pre>\n");
            i += 1;
        } else if is_table_start(&lines, i) {
            let head = gfm_cells(line);
            let align: Vec<&str> = gfm_cells(lines[i + 1])
                .iter()
                .map(|c| match (c.starts_with(':'), c.ends_with(':')) {
                    (true, true) => " class=\"c\"",
                    (false, true) => " class=\"r\"",
                    _ => "",
                })
                .collect();
            let a = |k: usize| align.get(k).copied().unwrap_or("");
            out.push_str("<table>\n<thead><tr>");
            for (k, h) in head.iter().enumerate() {
                write!(out, "<th{}>{}</th>", a(k), inline(h, links)).unwrap();
            }
            out.push_str("</tr></thead>\n<tbody>\n");
            i += 2;
            while i < lines.len() && lines[i].trim_start().starts_with('|') {
                let mut cells = gfm_cells(lines[i]);
                cells.resize(head.len(), String::new());
                out.push_str("<tr>");
                for (k, c) in cells.iter().enumerate() {
                    write!(out, "<td{}>{}</td>", a(k), inline(c, links)).unwrap();
                }
                out.push_str("</tr>\n");
                i += 1;
            }
            out.push_str("</tbody>\n</table>\n");
        } else if t.starts_with("- ") || t.starts_with("* ") {
            out.push_str("<ul>\n");
            while i < lines.len() {
                let l = lines[i].trim();
                let Some(item) = l.strip_prefix("- ").or_else(|| l.strip_prefix("* ")) else {
                    break;
                };
                writeln!(out, "<li>{}</li>", inline(item, links)).unwrap();
                i += 1;
            }
            out.push_str("</ul>\n");
        } else {
            let mut para = Vec::new();
            while i < lines.len() {
                let l = lines[i].trim();
                if l.is_empty()
                    || heading_level(l).is_some()
                    || l.starts_with("```")
                    || l.starts_with("- ")
                    || is_table_start(&lines, i)
                {
                    break;
                }
                para.push(l);
                i += 1;
            }
            writeln!(out, "<p>{}</p>", inline(&para.join("\n"), links)).unwrap();
        }
    }
}

fn heading_level(t: &str) -> Option<usize> {
    let n = t.chars().take_while(|&c| c == '#').count();
    ((1..=6).contains(&n) && t[n..].starts_with(' ')).then_some(n)
}

/// Inline Markdown: `code`, **bold**, [links](target) and backslash escapes; the rest
/// escaped.
fn inline(text: &str, links: &Links<'_>) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        if c == '\\'
            && let Some(next) = rest[1..]
                .chars()
                .next()
                .filter(|n| n.is_ascii_punctuation())
        {
            out += &escape(&next.to_string());
            rest = &rest[1 + next.len_utf8()..];
        } else if c == '`'
            && let Some(end) = rest[1..].find('`')
        {
            write!(out, "<code>{}</code>", escape(&rest[1..1 + end])).unwrap();
            rest = &rest[end + 2..];
        } else if let Some(after) = rest.strip_prefix("**")
            && let Some(end) = after.find("**").filter(|&e| e > 0)
        {
            write!(out, "<strong>{}</strong>", inline(&after[..end], links)).unwrap();
            rest = &after[end + 2..];
        } else if c == '['
            && let Some(close) = rest.find("](")
            && let Some(end) = rest[close..].find(')')
        {
            let label = inline(&rest[1..close], links);
            let href = &rest[close + 2..close + end];
            match links.target(href) {
                Some(anchor) => write!(out, "<a href=\"#{}\">{label}</a>", escape(&anchor)),
                None => write!(out, "{label}"),
            }
            .unwrap();
            rest = &rest[close + end + 1..];
        } else {
            out += &escape(&c.to_string());
            rest = &rest[c.len_utf8()..];
        }
    }
    out.replace('\n', " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648() {
        for (raw, enc) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(raw.as_bytes()), enc);
        }
    }

    #[test]
    fn markdown_subset_becomes_escaped_html() {
        let stems = ["box_f"];
        let links = Links {
            prefix: "plots/",
            stems: &stems,
        };
        let mut out = String::new();
        blocks(
            "## Ranks & <tests>\n\nA **bold [x](plots/box_f.png)** and `a<b` \\* \
             [far](http://example.org) [gone](plots/none.png)\n\n\
             | a | b \\| c |\n| --- | --: |\n| **1** | <2> |\n| short |\n\n- `x`: y & z\n",
            &links,
            &mut out,
        );
        assert_eq!(
            out,
            "<h2 id=\"ranks-tests\">Ranks &amp; &lt;tests&gt;</h2>\n\
             <p>A <strong>bold <a href=\"#fig-box_f\">x</a></strong> and <code>a&lt;b</code> * \
             far gone</p>\n\
             <table>\n<thead><tr><th>a</th><th class=\"r\">b | c</th></tr></thead>\n<tbody>\n\
             <tr><td><strong>1</strong></td><td class=\"r\">&lt;2&gt;</td></tr>\n\
             <tr><td>short</td><td class=\"r\"></td></tr>\n</tbody>\n</table>\n\
             <ul>\n<li><code>x</code>: y &amp; z</li>\n</ul>\n"
        );
    }

    #[test]
    fn a_page_embeds_every_figure_escapes_its_text_and_links_nothing_outside() {
        let dir = tempfile::tempdir().unwrap();
        let plots = dir.path().join("plots");
        std::fs::create_dir(&plots).unwrap();
        std::fs::write(plots.join("box_f.svg"), "<svg/>").unwrap();
        std::fs::write(plots.join("box_f.png"), [0x89, b'P']).unwrap();
        std::fs::write(plots.join("ecdf_g.png"), [0x89, b'P']).unwrap();
        std::fs::write(plots.join("extra.png"), [1]).unwrap();
        let prov = dir.path().join("provenance.json");
        std::fs::write(
            &prov,
            r#"{"git_commit": "abc", "command": ["run", "a<b.toml"]}"#,
        )
        .unwrap();
        let groups = ["f".to_string(), "g".to_string()];
        let html = render(&Page {
            title: "S & <T>",
            markdown: "# S\n\nSee [box](plots/box_f.png).\n",
            statistics: "- **Median**: the middle",
            figures: &plots,
            figures_link: "plots/",
            figure_groups: &groups,
            provenance: &prov,
        })
        .unwrap();
        assert!(html.contains("<title>S &amp; &lt;T&gt;</title>"), "{html}");
        assert_eq!(
            html.matches("<h1>").count(),
            1,
            "the report's own title dropped"
        );
        assert!(html.contains("See <a href=\"#fig-box_f\">box</a>."));
        // The SVG where there is one (base64 of "<svg/>"), else the PNG.
        assert!(html.contains("<figure id=\"fig-box_f\"><img alt=\"box_f\" src=\"data:image/svg+xml;base64,PHN2Zy8+\">"));
        assert!(html.contains("src=\"data:image/png;base64,iVA=\""));
        let order: Vec<usize> = [
            "<h3>f</h3>",
            "<h3>g</h3>",
            "<h3>Other figures</h3>",
            "fig-extra",
        ]
        .iter()
        .map(|x| html.find(x).unwrap_or_else(|| panic!("{x} missing")))
        .collect();
        assert!(order.windows(2).all(|w| w[0] < w[1]), "{order:?}");
        assert!(html.contains("<tr><th>command</th><td>run a&lt;b.toml</td></tr>"));
        assert!(html.contains("<li><strong>Median</strong>: the middle</li>"));
    }
}
