//! Sampled input/output records: what an actuator experiment (or the twin) produces and what
//! the fitting objectives consume.

use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use crate::base::limits::{MAX_MAGNITUDE, MAX_SAMPLES};
use std::path::{Path, PathBuf};

/// A uniformly sampled single-input single-output record.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Where it came from (file name, or a description of the simulation).
    pub name: String,
    /// Sample times, strictly increasing and uniform (to 1e-6 relative).
    pub t: Vec<f64>,
    /// Input (e.g. drive command in V, or force in N).
    pub u: Vec<f64>,
    /// Output (e.g. displacement in mm).
    pub y: Vec<f64>,
    /// Units of t, u, y for labels ("s", "V", "mm"); free text.
    pub units: [String; 3],
}

/// Fewest samples a recording may have (a fit needs lags and some data).
pub const MIN_SAMPLES: usize = 8;

impl Recording {
    /// Checked constructor: equal lengths, [`MIN_SAMPLES`] to [`MAX_SAMPLES`], finite values
    /// within ±[`MAX_MAGNITUDE`], strictly increasing uniform time.
    pub fn new(name: impl Into<String>, t: Vec<f64>, u: Vec<f64>, y: Vec<f64>) -> Result<Self> {
        let name = name.into();
        if t.len() != u.len() || t.len() != y.len() {
            return Err(Error::Input(format!(
                "{name}: t, u, y have {}, {}, {} samples",
                t.len(),
                u.len(),
                y.len()
            )));
        }
        if t.len() < MIN_SAMPLES {
            return Err(Error::Input(format!(
                "{name}: {} samples, at least {MIN_SAMPLES} needed",
                t.len()
            )));
        }
        if t.len() > MAX_SAMPLES {
            return Err(Error::Input(format!(
                "{name}: {} samples, above the limit of {MAX_SAMPLES} (derived from memory)",
                t.len()
            )));
        }
        for (i, ((a, b), c)) in t.iter().zip(&u).zip(&y).enumerate() {
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                return Err(Error::Input(format!("{name}: sample {i} is not finite")));
            }
            if [a, b, c].iter().any(|v| v.abs() > MAX_MAGNITUDE) {
                return Err(Error::Input(format!(
                    "{name}: sample {i} ({a}, {b}, {c}) is beyond ±{MAX_MAGNITUDE:e}"
                )));
            }
        }
        let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        for i in 1..t.len() {
            let step = t[i] - t[i - 1];
            if step <= 0.0 {
                return Err(Error::Input(format!(
                    "{name}: time is not strictly increasing at sample {i}"
                )));
            }
            if (step - dt).abs() > 1e-6 * dt.abs().max(1e-300) + 1e-9 * t[i].abs() {
                return Err(Error::Input(format!(
                    "{name}: non-uniform sampling at sample {i} (step {step} s, mean {dt} s)"
                )));
            }
        }
        Ok(Recording {
            name,
            t,
            u,
            y,
            units: ["s".into(), String::new(), String::new()],
        })
    }

    /// A recording sampled at `dt` from time 0.
    pub fn uniform(name: impl Into<String>, dt: f64, u: Vec<f64>, y: Vec<f64>) -> Result<Self> {
        let t = (0..u.len()).map(|k| k as f64 * dt).collect();
        Self::new(name, t, u, y)
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Sampling interval.
    pub fn dt(&self) -> f64 {
        (self.t[self.len() - 1] - self.t[0]) / (self.len() - 1) as f64
    }

    /// The samples `range` as a new recording.
    /// The record without its first `seconds`: a record that starts in motion (a stage
    /// stepped from rest to the first command as recording began) holds a start-up no model
    /// of the actuator's steady behaviour is asked to explain. Refused if fewer than
    /// [`MIN_SAMPLES`] samples would remain.
    pub fn trim_start(&self, seconds: f64) -> Result<Self> {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(Error::Input(format!(
                "trim start {seconds}: expected a number of seconds >= 0 to leave out"
            )));
        }
        let k = (seconds / self.dt() - 1e-9).ceil().max(0.0) as usize;
        if k == 0 {
            return Ok(self.clone());
        }
        if self.len() < k + MIN_SAMPLES {
            return Err(Error::Input(format!(
                "cannot leave out the first {seconds} s: {} has {} samples ({} s); at least {MIN_SAMPLES} must remain",
                self.name,
                self.len(),
                self.len() as f64 * self.dt()
            )));
        }
        let mut r = self.slice(k..self.len())?;
        r.name = format!("{} (first {seconds} s left out)", self.name);
        Ok(r)
    }

    /// Refuses a constant input or output (a disconnected channel, a column of zeros):
    /// nothing to fit, and scaled fits and diagnoses would divide by zero. For records read
    /// with `columns`, to name them.
    pub fn check_varies(&self, columns: &Columns) -> Result<()> {
        for (role, name, v) in [
            ("input", &columns.input, &self.u),
            ("output", &columns.output, &self.y),
        ] {
            if let Some(first) = v.first()
                && v.iter().all(|x| x == first)
            {
                return Err(Error::Input(format!(
                    "{}: {role} column '{name}': every value is {first} (all {} samples): \
                     nothing to fit",
                    self.name,
                    v.len()
                )));
            }
        }
        Ok(())
    }

    pub fn slice(&self, range: std::ops::Range<usize>) -> Result<Self> {
        if range.start > range.end || range.end > self.len() {
            return Err(Error::Input(format!(
                "{}: samples {}..{} requested but it has {}",
                self.name,
                range.start,
                range.end,
                self.len()
            )));
        }
        let mut r = Self::new(
            format!("{}[{}..{}]", self.name, range.start, range.end),
            self.t[range.clone()].to_vec(),
            self.u[range.clone()].to_vec(),
            self.y[range].to_vec(),
        )?;
        r.units = self.units.clone();
        Ok(r)
    }
}

/// Which CSV columns hold time, input and output, by header name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Columns {
    /// Sample times (column name, e.g. `t_s`).
    pub time: String,
    /// Input (e.g. `u_N`, `velocity_mm_per_s`).
    pub input: String,
    /// Output (e.g. `y_m`, `force_N`).
    pub output: String,
}

impl Default for Columns {
    /// `t,u,y`: the names [`Recording::write_csv`] uses when nothing else is asked for.
    fn default() -> Self {
        Columns {
            time: "t".into(),
            input: "u".into(),
            output: "y".into(),
        }
    }
}

impl Columns {
    /// Parses `time,input,output`, e.g. `t_s,u_N,y_m`: exactly three distinct, non-empty
    /// comma-separated names (surrounding spaces ignored).
    pub fn parse(spec: &str) -> Result<Columns> {
        let names: Vec<&str> = spec.split(',').map(str::trim).collect();
        let bad = |why: &str| {
            Error::Input(format!(
                "columns '{spec}': {why}; expected three comma-separated names \
                 time,input,output (e.g. t_s,u_N,y_m)"
            ))
        };
        if names.len() != 3 {
            return Err(bad(&format!("{} names given", names.len())));
        }
        if names.iter().any(|n| n.is_empty()) {
            return Err(bad("empty name"));
        }
        if names[0] == names[1] || names[0] == names[2] || names[1] == names[2] {
            return Err(bad("names must be distinct"));
        }
        Ok(Columns {
            time: names[0].into(),
            input: names[1].into(),
            output: names[2].into(),
        })
    }
}

impl std::str::FromStr for Columns {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        Columns::parse(s)
    }
}

/// How the columns of a recording file are separated.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Delimiter {
    /// Found from the first lines: tab, `;` or `,`, the first that splits the header and
    /// most of the first 20 lines into the same number of fields; else runs of blanks.
    #[default]
    Auto,
    /// One character: `,`, `;` or tab.
    Char(u8),
    /// Runs of spaces and tabs (aligned tables, Matlab's `save -ascii`).
    Whitespace,
}

impl Delimiter {
    /// Parses `auto`, `,` (`comma`), `;` (`semicolon`), `tab` (`\t`) or `whitespace`
    /// (`space`).
    pub fn parse(spec: &str) -> Result<Delimiter> {
        match spec {
            "auto" => Ok(Delimiter::Auto),
            "," | "comma" => Ok(Delimiter::Char(b',')),
            ";" | "semicolon" => Ok(Delimiter::Char(b';')),
            "\t" | "\\t" | "tab" => Ok(Delimiter::Char(b'\t')),
            " " | "space" | "whitespace" => Ok(Delimiter::Whitespace),
            _ => Err(Error::Input(format!(
                "delimiter '{spec}': expected auto, ',' (comma), ';' (semicolon), tab or \
                 whitespace"
            ))),
        }
    }

    fn describe(self) -> String {
        match self {
            Delimiter::Auto => "detected".into(),
            Delimiter::Char(b'\t') => "tab".into(),
            Delimiter::Char(c) => format!("'{}'", c as char),
            Delimiter::Whitespace => "whitespace".into(),
        }
    }

    /// The delimiter of `text`, found from its first lines (see [`Delimiter::Auto`]).
    fn detect(text: &[u8]) -> Delimiter {
        let lines: Vec<&[u8]> = text
            .split(|&b| b == b'\n')
            .filter(|l| !l.trim_ascii().is_empty())
            .take(20)
            .collect();
        let Some(head) = lines.first() else {
            return Delimiter::Char(b',');
        };
        // Most rows, not all: a ragged row should be reported as such, not change the
        // delimiter.
        let agree = |count: &dyn Fn(&[u8]) -> usize, min: usize| {
            let n = count(head);
            n >= min && 2 * lines.iter().filter(|l| count(l) == n).count() > lines.len()
        };
        for c in [b'\t', b';', b','] {
            if agree(&|l: &[u8]| l.iter().filter(|&&b| b == c).count(), 1) {
                return Delimiter::Char(c);
            }
        }
        if agree(&|l: &[u8]| blank_fields(l).count(), 2) {
            Delimiter::Whitespace
        } else {
            Delimiter::Char(b',')
        }
    }
}

/// The form [`Delimiter::parse`] reads back.
impl std::fmt::Display for Delimiter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Delimiter::Auto => write!(f, "auto"),
            Delimiter::Char(b'\t') => write!(f, "tab"),
            Delimiter::Char(c) => write!(f, "{}", *c as char),
            Delimiter::Whitespace => write!(f, "whitespace"),
        }
    }
}

impl std::str::FromStr for Delimiter {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        Delimiter::parse(s)
    }
}

/// The fields of a blank-separated line.
fn blank_fields(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|f| !f.is_empty())
}

/// `text` with each line's blank-separated fields joined by tabs (lines kept, so the csv
/// reader's line numbers stay the file's).
fn blanks_to_tabs(text: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(text.len());
    for (i, line) in text.split(|&b| b == b'\n').enumerate() {
        if i > 0 {
            out.push(b'\n');
        }
        for (j, f) in blank_fields(line).enumerate() {
            if j > 0 {
                out.push(b'\t');
            }
            out.extend_from_slice(f);
        }
    }
    out
}

/// How [`Recording::read_csv`] treats imperfect files.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Accept gaps and irregular (but strictly increasing) time by linearly interpolating
    /// onto a uniform grid at the typical step. Off by default: resampling changes the data
    /// a model is fitted to, so it must be asked for (jitter within the tolerance of
    /// [`Recording::read_csv`] needs no resampling).
    pub resample: bool,
    /// Column separator; the decimal separator (point or comma) is always detected.
    pub delimiter: Delimiter,
}

/// The folder of recorded data sets (kept outside the repository, read by path).
///
/// `$OPTBENCH_DATA` if set and non-empty; otherwise `shared/data` beside the checkout the
/// binary was built from (`<crate root>/../shared/data`), wherever it is run from: the same
/// folder as `../shared/data` seen from the checkout, never one that depends on the working
/// directory. The path may not exist: callers check and say where they looked.
pub fn data_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("OPTBENCH_DATA").filter(|v| !v.is_empty()) {
        return PathBuf::from(dir);
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    // Resolved (no `..`) when it exists, so messages show where the data really is.
    dir.canonicalize().unwrap_or(dir)
}

/// The unit encoded in a column name: the part after the last `_` (`t_s` -> `s`,
/// `position_mm` -> `mm`); `a_b_per_c` reads as `b/c` (`velocity_mm_per_s` -> `mm/s`);
/// no `_` -> `""`.
pub fn unit_from_name(name: &str) -> String {
    if let Some((left, per)) = name.rsplit_once("_per_")
        && !per.is_empty()
    {
        let num = unit_from_name(left);
        return format!("{}/{per}", if num.is_empty() { "1" } else { &num });
    }
    match name.rsplit_once('_') {
        Some((_, unit)) => unit.to_string(),
        None => String::new(),
    }
}

/// Significant digits printed in a numeric token (`0.00133333333` -> 9, `15` -> 2,
/// `1500` -> 2): how precisely the writer printed its numbers.
fn significant_digits(token: &str) -> u32 {
    let mantissa = token
        .trim_start_matches(['+', '-'])
        .split(['e', 'E'])
        .next()
        .unwrap_or("");
    let has_point = mantissa.contains('.');
    let digits: String = mantissa.chars().filter(|c| c.is_ascii_digit()).collect();
    let digits = digits.trim_start_matches('0');
    let digits = if has_point {
        digits
    } else {
        digits.trim_end_matches('0')
    };
    digits.len() as u32
}

/// One picked CSV column: its role, header name and position.
struct Col<'a> {
    role: &'a str,
    name: &'a str,
    index: usize,
}

/// `v` with `digits` significant digits, trailing zeros dropped (`%g`-style without the
/// exponent): readable steps and gaps in messages, `0.01` rather than `0.009999999999999787`.
fn sig(v: f64, digits: i32) -> String {
    if v == 0.0 || !v.is_finite() {
        return v.to_string();
    }
    let decimals = digits - 1 - v.abs().log10().floor() as i32;
    let s = format!("{:.*}", decimals.max(0) as usize, v);
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Decimals printed in a numeric token (`40.125` -> 3, `15` -> 0); `None` in exponent form.
fn decimals(token: &str) -> Option<u32> {
    if token.contains(['e', 'E']) {
        return None;
    }
    Some(token.split_once('.').map_or(0, |(_, f)| f.len() as u32))
}

/// How the time column was printed, so the rounding of its values is known: with a fixed
/// number of decimals (`%.3f`: half a unit in the last decimal) or of significant digits
/// (`%.9g`, or shortest round-trip form: half a unit in the last significant digit, the
/// most any field of the file shows, as a writer prints every column alike and a time
/// such as `0.05` says nothing of its own precision).
#[derive(Default)]
struct Printing {
    /// Decimals of the first time, and whether every time had as many.
    decimals: Option<u32>,
    fixed: bool,
    /// Most significant digits seen in any field.
    digits: u32,
    seen: bool,
}

impl Printing {
    fn see_time(&mut self, token: &str) {
        let d = decimals(token);
        if !self.seen {
            (self.decimals, self.fixed, self.seen) = (d, d.is_some(), true);
        } else if d != self.decimals {
            self.fixed = false;
        }
    }

    fn see_field(&mut self, field: &str) {
        let digits = if field.contains(',') {
            significant_digits(&field.replace(',', "."))
        } else {
            significant_digits(field)
        };
        self.digits = self.digits.max(digits);
    }

    /// Largest rounding error of a printed value `v`, plus f64 noise.
    fn rounding(&self, v: f64) -> f64 {
        let noise = 4.0 * f64::EPSILON * v.abs();
        if let (true, Some(d)) = (self.fixed, self.decimals) {
            return 0.5 * 10f64.powi(-(d as i32)) + noise;
        }
        if v == 0.0 {
            return 0.0;
        }
        let mut e = v.abs().log10().floor() as i32;
        if 10f64.powi(e + 1) <= v.abs() {
            e += 1;
        }
        0.5 * 10f64.powi(e + 1 - self.digits.clamp(1, 17) as i32) + noise
    }
}

/// The value of a numeric field written with a decimal point or a decimal comma (as
/// European lab software writes); `decimal` remembers the first separator seen and its
/// line, so a file mixing them (or grouping digits) is refused instead of misread.
/// Returns the value and the token in point form.
fn number(
    text: &str,
    line: usize,
    decimal: &mut Option<(char, usize)>,
) -> std::result::Result<(f64, String), String> {
    let shown = clipped(text);
    let (comma, point) = (text.contains(','), text.contains('.'));
    if comma && point {
        return Err(format!(
            "'{shown}' has both a decimal point and a comma (digit grouping is not read); \
             expected a plain number such as 1234.5"
        ));
    }
    let token = if comma {
        text.replace(',', ".")
    } else {
        text.to_string()
    };
    if comma || point {
        let sep = if comma { ',' } else { '.' };
        match *decimal {
            Some((other, at)) if other != sep => {
                let name = |c| if c == ',' { "comma" } else { "point" };
                return Err(format!(
                    "'{shown}' has a decimal {} but line {at} a decimal {}; expected one \
                     decimal separator throughout the file",
                    name(sep),
                    name(other)
                ));
            }
            Some(_) => {}
            None => *decimal = Some((sep, line)),
        }
    }
    let v: f64 = token
        .parse()
        .map_err(|_| format!("'{shown}' is not a number"))?;
    if !v.is_finite() {
        return Err(format!("'{shown}' is not finite"));
    }
    if v.abs() > MAX_MAGNITUDE {
        return Err(format!(
            "'{text}' is beyond ±{MAX_MAGNITUDE:e} (squared errors would overflow; rescale the \
             column's unit)"
        ));
    }
    Ok((v, token))
}

/// `text` as quoted in a message: a cell of megabytes (a corrupt or binary file) is cut to
/// its start and its length, so an error stays one readable line.
fn clipped(text: &str) -> std::borrow::Cow<'_, str> {
    const KEEP: usize = 40;
    match text.char_indices().nth(KEEP) {
        None => text.into(),
        Some((end, _)) => format!("{}... ({} bytes)", &text[..end], text.len()).into(),
    }
}

/// A `--columns` value built from a header: the time column (`t`, `t_*`, `time*`), the
/// first input (`u*`, else the first other column) and the first output (`y*`, else the
/// last other column); columns named like a sample index are skipped. `None` when the
/// header does not hold three such columns.
fn suggest_columns(header: &[&str]) -> Option<String> {
    let lower = |h: &str| h.to_ascii_lowercase();
    let index_like =
        |h: &str| ["k", "n", "i", "index", "sample", "samples"].contains(&lower(h).as_str());
    let starts = |h: &str, p: &str| {
        let l = lower(h);
        l == p
            || l.strip_prefix(p)
                .is_some_and(|r| r.starts_with(|c: char| c == '_' || c.is_ascii_digit()))
    };
    let time = header
        .iter()
        .find(|h| starts(h, "t") || lower(h).starts_with("time"))?;
    let rest: Vec<&str> = header
        .iter()
        .copied()
        .filter(|h| h != time && !h.is_empty() && !index_like(h))
        .collect();
    let input = rest.iter().find(|h| starts(h, "u")).or(rest.first())?;
    let output = rest
        .iter()
        .find(|h| starts(h, "y"))
        .or(rest.last())
        .filter(|o| o != &input)?;
    Some(format!("{time},{input},{output}"))
}

/// The middle value of `v` (the upper of an even count), reordering it; O(n).
fn middle(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// A uniform time grid `start + k * step`.
#[derive(Debug, Clone, Copy)]
struct Grid {
    start: f64,
    step: f64,
}

impl Grid {
    fn at(&self, k: usize) -> f64 {
        self.start + k as f64 * self.step
    }

    /// Robust line through the stamps `(k, t[k])` (at least two): the median step and the
    /// median offset, refined by least squares over the stamps within a quarter step of
    /// the line, twice (a median step biased by the printing's rounding misses the far
    /// stamps at first), then over those within `tolerance(step)`. Gaps and outliers do
    /// not move it; O(n).
    fn fit(t: &[f64], tolerance: impl Fn(f64) -> f64) -> Grid {
        let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        let step = middle(&mut steps);
        let mut offsets: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, v)| v - k as f64 * step)
            .collect();
        let mut g = Grid {
            start: middle(&mut offsets),
            step,
        };
        for round in 0..3 {
            let within = if round < 2 {
                0.25 * g.step
            } else {
                tolerance(g.step)
            };
            let near = |k: &usize| (t[*k] - g.at(*k)).abs() <= within;
            let (mut m, mut kbar, mut tbar) = (0.0, 0.0, 0.0);
            for k in (0..t.len()).filter(near) {
                m += 1.0;
                kbar += k as f64;
                tbar += t[k];
            }
            if m < 2.0 {
                break;
            }
            (kbar, tbar) = (kbar / m, tbar / m);
            let (mut sxy, mut sxx) = (0.0, 0.0);
            for k in (0..t.len()).filter(near) {
                let dk = k as f64 - kbar;
                sxy += dk * (t[k] - tbar);
                sxx += dk * dk;
            }
            let step = sxy / sxx;
            if !(step > 0.0 && step.is_finite()) {
                break;
            }
            g = Grid {
                start: tbar - step * kbar,
                step,
            };
        }
        g
    }
}

/// Relative tolerance of the time stamps' jitter around the fitted grid.
pub const JITTER_TOLERANCE: f64 = 0.01;

/// A CSV file's text ready for the csv reader (byte-order mark dropped, blanks made tabs
/// for a whitespace-separated file), its delimiter byte and the delimiter used.
fn table_text(path: &Path, opts: &ReadOptions) -> Result<(Vec<u8>, u8, Delimiter)> {
    let size = std::fs::metadata(path)
        .map_err(|e| Error::io(format!("reading {}", path.display()), e))?
        .len();
    if size > crate::base::limits::MAX_FILE_BYTES {
        return Err(Error::Input(format!(
            "{}: {size} bytes, more than a recording may hold ({} bytes, \
             base::limits::MAX_FILE_BYTES); cut the file or resample it coarser",
            path.display(),
            crate::base::limits::MAX_FILE_BYTES
        )));
    }
    let bytes =
        std::fs::read(path).map_err(|e| Error::io(format!("reading {}", path.display()), e))?;
    // Spreadsheet exports often start with a UTF-8 byte-order mark; csv keeps it in the
    // first header name.
    let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
    let delimiter = match opts.delimiter {
        Delimiter::Auto => Delimiter::detect(text),
        d => d,
    };
    Ok(match delimiter {
        Delimiter::Char(c) => (text.to_vec(), c, delimiter),
        _ => (blanks_to_tabs(text), b'\t', delimiter),
    })
}

fn table_reader(text: &[u8], byte: u8) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new()
        .has_headers(true)
        .delimiter(byte)
        .trim(csv::Trim::All)
        .from_reader(text)
}

/// The column names of a CSV file's header row.
pub fn header_names(path: &Path, opts: &ReadOptions) -> Result<Vec<String>> {
    let (text, byte, _) = table_text(path, opts)?;
    let mut reader = table_reader(&text, byte);
    let headers = reader.headers().map_err(|e| Error::at(path, 1, e))?;
    Ok(headers.iter().map(str::to_string).collect())
}

/// Most samples `--resample` may make per sample read (a record with a long pause sampled
/// at its typical step would otherwise be huge).
const RESAMPLE_GROWTH: usize = 10;

impl Recording {
    /// Reads a recording from a CSV file with a header row, picking the time, input and
    /// output columns by name; units come from the names (see [`unit_from_name`]).
    /// [`Recording::read_csv_noted`] also says what was done to the file.
    pub fn read_csv(path: &Path, columns: &Columns, opts: &ReadOptions) -> Result<Recording> {
        Self::read_csv_noted(path, columns, opts).map(|(r, _)| r)
    }

    /// [`Recording::read_csv`], with one line per thing done that the user should know:
    /// an unusual delimiter or decimal comma, jitter absorbed, resampling.
    ///
    /// Columns are separated by `,`, `;`, tabs or blanks ([`ReadOptions::delimiter`],
    /// detected by default); numbers may use a decimal point or a decimal comma.
    ///
    /// Time: the step comes from a robust line through the stamps (median step, refined by
    /// least squares over the stamps near it). Stamps that all lie within
    /// ±([`JITTER_TOLERANCE`] of the step + the rounding of the printed times) of one grid
    /// at that step are taken as that uniform grid: exactly printed uniform times are
    /// kept as read (so [`Recording::write_csv`] round-trips bit for bit), others
    /// (jitter, printing with few digits) become the fitted grid, and jitter beyond the
    /// printing's rounding is noted. Otherwise (a gap, irregular or drifting sampling) the
    /// file is refused at the first sample that cannot lie on one grid with every sample
    /// before it: after a missing sample, the sample after the gap (the second sample of
    /// the long step). With [`ReadOptions::resample`] it is instead linearly interpolated
    /// onto a uniform grid from the first to the last time at the typical step, and the
    /// name and the note say so.
    ///
    /// Every refusal is an [`Error::Input`] located at `file:line` naming the column:
    /// missing column (with the header's names and a `--columns` suggestion), empty,
    /// non-numeric or non-finite value, mixed decimal separators, empty file, time not
    /// strictly increasing, non-uniform sampling, fewer than [`MIN_SAMPLES`] rows.
    ///
    /// The name is `<path> [<input> -> <output>]`.
    pub fn read_csv_noted(
        path: &Path,
        columns: &Columns,
        opts: &ReadOptions,
    ) -> Result<(Recording, Vec<String>)> {
        let (text, byte, delimiter) = table_text(path, opts)?;
        let mut reader = table_reader(&text, byte);
        let csv_err = |e: csv::Error, fallback_line: u64| {
            let line = e.position().map_or(fallback_line, |p| p.line()) as usize;
            match e.kind() {
                csv::ErrorKind::UnequalLengths {
                    expected_len, len, ..
                } => Error::at(
                    path,
                    line,
                    format!(
                        "row has {len} fields but the header has {expected_len} (columns \
                         separated by {}; set --delimiter if that is wrong)",
                        delimiter.describe()
                    ),
                ),
                csv::ErrorKind::Utf8 { .. } => Error::at(path, line, "not valid UTF-8 text"),
                _ => Error::at(path, line, e),
            }
        };
        let headers = reader.headers().map_err(|e| csv_err(e, 1))?.clone();
        let header_line = headers.position().map_or(1, |p| p.line()) as usize;
        if headers.iter().all(str::is_empty) {
            return Err(Error::at(
                path,
                header_line,
                "empty file: expected a header row naming the columns (e.g. t_s,u_N,y_m)",
            ));
        }
        let names: Vec<&str> = headers.iter().collect();
        let available = names
            .iter()
            .map(|n| clipped(n))
            .collect::<Vec<_>>()
            .join(", ");
        let numeric_header = names
            .iter()
            .all(|h| h.replace(',', ".").parse::<f64>().is_ok());
        let suggestion = suggest_columns(&names)
            .map(|s| format!("; did you mean --columns {s}?"))
            .unwrap_or_default();
        let pick = |role: &str, name: &str| -> Result<usize> {
            let hits: Vec<usize> = (0..names.len()).filter(|&i| names[i] == name).collect();
            match hits.as_slice() {
                [i] => Ok(*i),
                [] if numeric_header => Err(Error::at(
                    path,
                    header_line,
                    format!(
                        "no {role} column '{name}': the first line ({available}) is data, \
                         but a header row naming the columns is required"
                    ),
                )),
                [] => Err(Error::at(
                    path,
                    header_line,
                    format!(
                        "no {role} column '{name}' (columns: {available}, separated by {})\
                         {suggestion}",
                        delimiter.describe()
                    ),
                )),
                _ => Err(Error::at(
                    path,
                    header_line,
                    format!(
                        "{role} column '{name}' appears {} times in the header",
                        hits.len()
                    ),
                )),
            }
        };
        let cols = [
            Col {
                role: "time",
                name: &columns.time,
                index: pick("time", &columns.time)?,
            },
            Col {
                role: "input",
                name: &columns.input,
                index: pick("input", &columns.input)?,
            },
            Col {
                role: "output",
                name: &columns.output,
                index: pick("output", &columns.output)?,
            },
        ];

        let mut data: [Vec<f64>; 3] = Default::default();
        let mut lines: Vec<usize> = Vec::new();
        let mut printing = Printing::default();
        let mut decimal = None;
        let mut record = csv::StringRecord::new();
        let mut last_line = header_line;
        loop {
            match reader.read_record(&mut record) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => return Err(csv_err(e, last_line as u64 + 1)),
            }
            let line = record
                .position()
                .map_or(last_line + 1, |p| p.line() as usize);
            last_line = line;
            if lines.len() == MAX_SAMPLES {
                return Err(Error::at(
                    path,
                    line,
                    format!("more than {MAX_SAMPLES} data rows (a limit derived from memory)"),
                ));
            }
            for field in record.iter() {
                printing.see_field(field);
            }
            for (col, out) in cols.iter().zip(data.iter_mut()) {
                let text = &record[col.index];
                let at = |what: String| {
                    Error::at(
                        path,
                        line,
                        format!("{} column '{}': {what}", col.role, col.name),
                    )
                };
                if text.is_empty() {
                    return Err(at("empty value".into()));
                }
                let (v, token) = number(text, line, &mut decimal).map_err(at)?;
                if col.role == "time" {
                    printing.see_time(&token);
                }
                out.push(v);
            }
            lines.push(line);
        }
        let [t, u, y] = data;
        let n = t.len();
        if n < MIN_SAMPLES {
            return Err(Error::at(
                path,
                last_line,
                format!("{n} data rows, at least {MIN_SAMPLES} samples needed"),
            ));
        }
        let time = &cols[0];
        for i in 1..n {
            if t[i] <= t[i - 1] {
                return Err(Error::at(
                    path,
                    lines[i],
                    format!(
                        "time column '{}': time is not strictly increasing ({} after {} on line {})",
                        time.name,
                        t[i],
                        t[i - 1],
                        lines[i - 1]
                    ),
                ));
            }
        }
        let mut notes = Vec::new();
        let comma = matches!(decimal, Some((',', _)));
        if delimiter != Delimiter::Char(b',') || comma {
            notes.push(format!(
                "{}: columns separated by {}, decimal {}",
                path.display(),
                delimiter.describe(),
                if comma { "comma" } else { "point" }
            ));
        }
        let mut name = format!(
            "{} [{} -> {}]",
            path.display(),
            columns.input,
            columns.output
        );

        // Deviations from the robust grid; the grid is uniform when they fit in a band of
        // twice the tolerance, the first sample that widens the band past it is off.
        // The rounding is at most a quarter step, so a missing sample is caught however
        // coarse the printing looks.
        let printed = printing.rounding(t[0].abs().max(t[n - 1].abs()));
        let tolerance = |step: f64| JITTER_TOLERANCE * step + printed.min(0.25 * step);
        let grid = Grid::fit(&t, tolerance);
        let rounding = printed.min(0.25 * grid.step);
        let tol = tolerance(grid.step);
        let dev: Vec<f64> = (0..n).map(|k| t[k] - grid.at(k)).collect();
        let (mut lo, mut hi) = (dev[0], dev[0]);
        let off = (1..n).find(|&k| {
            (lo, hi) = (lo.min(dev[k]), hi.max(dev[k]));
            hi - lo > 2.0 * tol
        });
        let tolerated = format!(
            "±{tol:.2e} s: {} % of the step plus {rounding:.1e} s rounding of the printed times",
            JITTER_TOLERANCE * 100.0
        );
        let mut rec = match off {
            Some(k) if !opts.resample => {
                let step = t[k] - t[k - 1];
                let ratio = step / grid.step;
                let what = if ratio.round() >= 2.0 && (ratio - ratio.round()).abs() < 0.1 {
                    match ratio.round() as usize - 1 {
                        1 => format!("a gap of {ratio:.2} steps: a missing sample"),
                        m => format!("a gap of {ratio:.2} steps: {m} missing samples"),
                    }
                } else if (step - grid.step).abs() > 2.0 * tol {
                    format!("irregular sampling: the step is {ratio:.4} steps")
                } else {
                    format!(
                        "the sampling drifts: samples through this line spread {:.2e} s \
                         around one grid",
                        hi - lo
                    )
                };
                return Err(Error::at(
                    path,
                    lines[k],
                    format!(
                        "time column '{}': time {} s is off the uniform grid of the samples \
                         before it ({what}); expected about {} s after {} s on line {} (step \
                         {} s, a robust fit of the {n} stamps; jitter tolerated {tolerated}). \
                         To interpolate onto a uniform grid, pass --resample (suites: \
                         resample = true)",
                        time.name,
                        t[k],
                        sig(t[k - 1] + grid.step, 9),
                        t[k - 1],
                        lines[k - 1],
                        sig(grid.step, 9)
                    ),
                ));
            }
            Some(k) => {
                let span = t[n - 1] - t[0];
                let m = ((span / grid.step).round() as usize).saturating_add(1);
                if m > RESAMPLE_GROWTH * n || m > MAX_SAMPLES {
                    return Err(Error::at(
                        path,
                        0,
                        format!(
                            "time column '{}': resampling {} s at the typical step {} s \
                             would make {m} samples from {n}; cut the record where it pauses",
                            time.name,
                            sig(span, 9),
                            sig(grid.step, 9)
                        ),
                    ));
                }
                let step = span / (m.max(2) - 1) as f64;
                let g: Vec<f64> = (0..m.max(2)).map(|k| t[0] + k as f64 * step).collect();
                let (gap, at) = (1..n)
                    .map(|k| (t[k] - t[k - 1], lines[k]))
                    .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
                let what = format!(
                    "resampled: {} samples, step {} s, largest gap {} s at line {at}",
                    g.len(),
                    sig(step, 6),
                    sig(gap, 6)
                );
                notes.push(format!(
                    "{}: {what} ({n} stamps not uniform from line {}: linearly interpolated \
                     onto a uniform grid)",
                    path.display(),
                    lines[k]
                ));
                name.push_str(&format!(" ({what})"));
                let u2 = interpolate(&t, &u, &g);
                let y2 = interpolate(&t, &y, &g);
                Recording::new(name, g, u2, y2)?
            }
            None => {
                let grid_t = || (0..n).map(|k| grid.at(k) + 0.5 * (lo + hi)).collect();
                let jitter = (hi - lo) / 2.0;
                if jitter > rounding {
                    notes.push(format!(
                        "{}: time stamps jitter by up to {jitter:.2e} s ({:.2} % of the step) \
                         around a uniform grid: step {} s fitted (tolerance {tolerated}); \
                         the grid is used",
                        path.display(),
                        100.0 * jitter / grid.step,
                        sig(grid.step, 9)
                    ));
                    Recording::new(name, grid_t(), u, y)?
                } else {
                    // Exactly printed stamps are kept; rounded ones become the grid they
                    // denote.
                    match Recording::new(name.clone(), t, u.clone(), y.clone()) {
                        Ok(r) => r,
                        Err(_) => Recording::new(name, grid_t(), u, y)?,
                    }
                }
            }
        };
        rec.units = cols.map(|c| unit_from_name(c.name));
        Ok((rec, notes))
    }

    /// Writes the recording as CSV with a header of `columns`' names and every number in
    /// shortest round-trip form, so [`Recording::read_csv`] gives back identical samples.
    /// Atomic: the file is either the old or the new version.
    pub fn write_csv(&self, path: &Path, columns: &Columns) -> Result<()> {
        let names = [&columns.time, &columns.input, &columns.output];
        if names
            .iter()
            .any(|n| n.trim().is_empty() || n.trim() != n.as_str())
            || names[0] == names[1]
            || names[0] == names[2]
            || names[1] == names[2]
        {
            return Err(Error::Input(format!(
                "writing {}: column names must be distinct, non-empty and without surrounding \
                 spaces (got '{}', '{}', '{}')",
                path.display(),
                names[0],
                names[1],
                names[2]
            )));
        }
        let mut w = csv::Writer::from_writer(Vec::new());
        let fail = |e: csv::Error| Error::Input(format!("writing {}: {e}", path.display()));
        w.write_record(names).map_err(fail)?;
        for i in 0..self.len() {
            w.write_record([
                self.t[i].to_string(),
                self.u[i].to_string(),
                self.y[i].to_string(),
            ])
            .map_err(fail)?;
        }
        let bytes = w
            .into_inner()
            .map_err(|e| Error::Input(format!("writing {}: {e}", path.display())))?;
        atomic_write(path, &bytes)
    }
}

/// Piecewise-linear interpolation of `(t, v)` (t strictly increasing) at sorted times `at`,
/// clamped to the end values outside `t`'s range.
fn interpolate(t: &[f64], v: &[f64], at: &[f64]) -> Vec<f64> {
    let mut j = 0;
    at.iter()
        .map(|&x| {
            while j + 2 < t.len() && t[j + 1] < x {
                j += 1;
            }
            if x <= t[0] {
                v[0]
            } else if x >= t[t.len() - 1] {
                v[v.len() - 1]
            } else {
                let w = (x - t[j]) / (t[j + 1] - t[j]);
                v[j] + w * (v[j + 1] - v[j])
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_too_large_is_refused_before_it_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("huge.csv");
        // Sparse: the size is set, no byte is written or read.
        let f = std::fs::File::create(&path).unwrap();
        f.set_len(crate::base::limits::MAX_FILE_BYTES + 1).unwrap();
        let err = Recording::read_csv(&path, &Columns::default(), &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("more than a recording may hold"), "{err}");
    }

    #[test]
    fn trim_start_leaves_out_the_first_seconds() {
        let r = Recording::uniform(
            "r",
            0.01,
            vec![1.0; 1000],
            (0..1000).map(f64::from).collect(),
        )
        .unwrap();
        let t = r.trim_start(0.5).unwrap();
        assert_eq!(t.len(), 950);
        assert_eq!(t.y[0], 50.0);
        assert!((t.t[0] - 0.5).abs() < 1e-12);
        assert!(t.name.contains("first 0.5 s left out"));
        assert_eq!(r.trim_start(0.0).unwrap(), r);
        assert!(r.trim_start(9.95).is_err());
        assert!(r.trim_start(-1.0).is_err());
        assert!(r.trim_start(f64::NAN).is_err());
    }
    use crate::base::TrialSeed;
    use rand::RngExt;

    fn cols(spec: &str) -> Columns {
        Columns::parse(spec).unwrap()
    }

    const RESAMPLE: ReadOptions = ReadOptions {
        resample: true,
        delimiter: Delimiter::Auto,
    };

    /// Writes `text` to a temporary CSV and reads it with `columns`; returns the path used.
    fn read_text(
        text: &str,
        columns: &Columns,
        opts: &ReadOptions,
    ) -> (PathBuf, Result<Recording>) {
        let (p, r) = read_noted(text, columns, opts);
        (p, r.map(|(r, _)| r))
    }

    /// [`read_text`] with the notes.
    fn read_noted(
        text: &str,
        columns: &Columns,
        opts: &ReadOptions,
    ) -> (PathBuf, Result<(Recording, Vec<String>)>) {
        // The folder is removed on return; the path is only kept for messages.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rec.csv");
        std::fs::write(&p, text).unwrap();
        let r = Recording::read_csv_noted(&p, columns, opts);
        (p, r)
    }

    /// The message of a refused read, checked to name the file and `file:line`.
    fn refusal(text: &str, columns: &Columns, line: usize) -> String {
        let (p, r) = read_text(text, columns, &ReadOptions::default());
        let msg = r.expect_err("should be refused").to_string();
        let loc = format!("{}:{line}: ", p.display());
        assert!(msg.starts_with(&loc), "expected '{loc}' in: {msg}");
        msg
    }

    fn table(rows: usize, mut f: impl FnMut(usize) -> String) -> String {
        let mut s = String::from("k,t_s,u_N,y_m\n");
        for k in 0..rows {
            s.push_str(&f(k));
            s.push('\n');
        }
        s
    }

    fn good(rows: usize) -> String {
        table(rows, |k| {
            format!("{k},{},{},{}", k as f64 * 0.01, k * 2, -(k as f64))
        })
    }

    #[test]
    fn columns_parse_default_and_refusals() {
        assert_eq!(
            Columns::default(),
            Columns {
                time: "t".into(),
                input: "u".into(),
                output: "y".into()
            }
        );
        assert_eq!(cols(" t_s , u_N,y_m").input, "u_N");
        for bad in ["t_s,u_N", "t,u,y,z", "t,,y", "t,t,y", ""] {
            let e = Columns::parse(bad).unwrap_err().to_string();
            assert!(e.contains("three comma-separated names"), "{e}");
        }
    }

    #[test]
    fn units_come_from_the_name_suffix() {
        assert_eq!(unit_from_name("t_s"), "s");
        assert_eq!(unit_from_name("u_N"), "N");
        assert_eq!(unit_from_name("y_m"), "m");
        assert_eq!(unit_from_name("position_mm"), "mm");
        assert_eq!(unit_from_name("velocity_mm_per_s"), "mm/s");
        assert_eq!(unit_from_name("rate_per_s"), "1/s");
        assert_eq!(unit_from_name("t"), "");
    }

    #[test]
    fn reads_columns_by_name_in_any_order() {
        let text = "y_m, extra ,t_s,u_N\n".to_string()
            + &(0..10)
                .map(|k| format!("{}, x{k} ,{},{}\n", k as f64 / 4.0, k as f64 * 0.5, 3 * k))
                .collect::<String>();
        let (_, r) = read_text(&text, &cols("t_s,u_N,y_m"), &ReadOptions::default());
        let r = r.unwrap();
        // A spreadsheet's byte-order mark does not hide the first column.
        let (_, with_bom) = read_text(
            &format!("\u{feff}{text}"),
            &cols("y_m,t_s,u_N"),
            &ReadOptions::default(),
        );
        assert_eq!(with_bom.unwrap().t, r.y);
        assert_eq!(r.len(), 10);
        assert_eq!(r.t[3], 1.5);
        assert_eq!(r.u[3], 9.0);
        assert_eq!(r.y[3], 0.75);
        assert_eq!(r.dt(), 0.5);
        assert_eq!(r.units, ["s", "N", "m"]);
        assert!(r.name.ends_with("rec.csv [u_N -> y_m]"), "{}", r.name);
    }

    #[test]
    fn round_trip_is_exact() {
        let mut rng = TrialSeed::from_u64(7).rng(0);
        let n = 500;
        let dt = 1.0 / 750.0;
        let t: Vec<f64> = (0..n).map(|k| 3.0 + k as f64 * dt).collect();
        let mut u: Vec<f64> = (0..n)
            .map(|_| (rng.random::<f64>() - 0.5) * 10f64.powi(rng.random_range(-300..30)))
            .collect();
        let y: Vec<f64> = (0..n).map(|_| rng.random::<f64>() * 1e-4).collect();
        u[0] = -0.0;
        u[1] = f64::MIN_POSITIVE / 8.0; // subnormal
        u[2] = MAX_MAGNITUDE; // the largest accepted
        let mut r = Recording::new("orig", t, u, y).unwrap();
        r.units = ["s".into(), "V".into(), "mm".into()];
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.csv");
        let c = cols("time_s,drive_V,disp_mm");
        r.write_csv(&p, &c).unwrap();
        let back = Recording::read_csv(&p, &c, &ReadOptions::default()).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back.t), bits(&r.t));
        assert_eq!(bits(&back.u), bits(&r.u));
        assert_eq!(bits(&back.y), bits(&r.y));
        assert_eq!(back.units, r.units);
        let header = std::fs::read_to_string(&p).unwrap();
        assert!(header.starts_with("time_s,drive_V,disp_mm\n"));
        // Written atomically: no temporary left beside it.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        // Default names, and names that would not read back are refused.
        r.write_csv(&p, &Columns::default()).unwrap();
        let back = Recording::read_csv(&p, &Columns::default(), &ReadOptions::default()).unwrap();
        assert_eq!(back.t, r.t);
        let dup = Columns {
            time: "t".into(),
            input: "t".into(),
            output: "y".into(),
        };
        assert!(r.write_csv(&p, &dup).is_err());
    }

    #[test]
    fn refuses_missing_column_listing_the_header() {
        let m = refusal(&good(10), &cols("t_s,u_V,y_m"), 1);
        assert!(m.contains("input column 'u_V'"), "{m}");
        assert!(
            m.contains("(columns: k, t_s, u_N, y_m, separated by ',')"),
            "{m}"
        );
        assert!(m.ends_with("did you mean --columns t_s,u_N,y_m?"), "{m}");
        let m = refusal(&good(10), &Columns::default(), 1);
        assert!(m.contains("time column 't'"), "{m}");
        assert!(m.ends_with("did you mean --columns t_s,u_N,y_m?"), "{m}");
        // Multi-channel headers: the first input and output; other names: time, the first
        // and the last other column.
        let fsm =
            "t_s,u1_V,u2_V,u3_V,y1_um,y2_um,y3_um\n".to_string() + &"0,1,2,3,4,5,6\n".repeat(8);
        let m = refusal(&fsm, &cols("t_s,u_V,y_um"), 1);
        assert!(m.ends_with("did you mean --columns t_s,u1_V,y1_um?"), "{m}");
        let damper =
            "k,t_s,position_mm,velocity_mm_per_s,force_N\n".to_string() + &"0,1,2,3,4\n".repeat(8);
        let m = refusal(&damper, &Columns::default(), 1);
        assert!(
            m.ends_with("did you mean --columns t_s,position_mm,force_N?"),
            "{m}"
        );
        // No time-like column: nothing to suggest.
        let m = refusal("a,b,c\n", &Columns::default(), 1);
        assert!(!m.contains("did you mean"), "{m}");
    }

    #[test]
    fn refuses_files_without_header_or_data() {
        let m = refusal("", &Columns::default(), 1);
        assert!(m.contains("empty file") && m.contains("header row"), "{m}");
        let m = refusal("0,0,1,2\n1,0.1,1,2\n", &cols("t_s,u_N,y_m"), 1);
        assert!(
            m.contains("header row naming the columns is required"),
            "{m}"
        );
        let m = refusal("k,t_s,u_N,y_m\n", &cols("t_s,u_N,y_m"), 1);
        assert!(m.contains("0 data rows, at least 8"), "{m}");
        let m = refusal(&good(5), &cols("t_s,u_N,y_m"), 6);
        assert!(m.contains("5 data rows, at least 8"), "{m}");
    }

    #[test]
    fn refuses_bad_values_naming_line_and_column() {
        let c = cols("t_s,u_N,y_m");
        let with = |row: usize, field: &str| {
            table(10, |k| {
                if k == row {
                    format!("{k},{},1,{field}", k as f64 * 0.01)
                } else {
                    format!("{k},{},1,2", k as f64 * 0.01)
                }
            })
        };
        // Data row k sits on line k + 2 (line 1 is the header).
        let m = refusal(&with(3, "abc"), &c, 5);
        assert!(
            m.contains("output column 'y_m': 'abc' is not a number"),
            "{m}"
        );
        let m = refusal(&with(4, "NaN"), &c, 6);
        assert!(
            m.contains("output column 'y_m': 'NaN' is not finite"),
            "{m}"
        );
        let m = refusal(&with(5, "-inf"), &c, 7);
        assert!(m.contains("'-inf' is not finite"), "{m}");
        let m = refusal(&with(6, ""), &c, 8);
        assert!(m.contains("output column 'y_m': empty value"), "{m}");
        let ragged = good(10).replace("\n4,0.04,8,-4\n", "\n4,0.04,8\n");
        let m = refusal(&ragged, &c, 6);
        assert!(m.contains("row has 3 fields but the header has 4"), "{m}");
    }

    #[test]
    fn a_huge_cell_is_cut_in_the_message() {
        let c = cols("t_s,u_N,y_m");
        let cell = "7".repeat(1 << 20) + "x";
        let text = table(10, |k| {
            let y = if k == 3 { cell.as_str() } else { "2" };
            format!("{k},{},1,{y}", k as f64 * 0.01)
        });
        let m = refusal(&text, &c, 5);
        assert!(m.len() < 300, "{} bytes: {}...", m.len(), &m[..300]);
        assert!(
            m.contains("is not a number") && m.contains("(1048577 bytes)"),
            "{m}"
        );
        // A huge header name is cut as well.
        let m = refusal(&format!("{cell},u_N,y_m\n"), &c, 1);
        assert!(m.len() < 400, "{} bytes", m.len());
    }

    #[test]
    fn refuses_non_increasing_and_non_uniform_time() {
        let c = cols("t_s,u_N,y_m");
        let t_at = |bad: usize, value: f64| {
            table(12, move |k| {
                let t = if k == bad { value } else { k as f64 * 0.01 };
                format!("{k},{t},0,1.23456789")
            })
        };
        let m = refusal(&t_at(5, 0.04), &c, 7);
        assert!(
            m.contains("time column 't_s': time is not strictly increasing"),
            "{m}"
        );
        let m = refusal(&t_at(5, 0.03), &c, 7);
        assert!(
            m.contains("not strictly increasing (0.03 after 0.04 on line 6)"),
            "{m}"
        );
        // 5 % of the step off: above the 1 % tolerance, refused at that sample.
        let m = refusal(&t_at(5, 0.0505), &c, 7);
        assert!(
            m.contains("time column 't_s': time 0.0505 s is off the uniform grid"),
            "{m}"
        );
        assert!(
            m.contains("irregular sampling: the step is 1.0500 steps"),
            "{m}"
        );
        assert!(
            m.contains("expected about 0.05 s after 0.04 s on line 6"),
            "{m}"
        );
        assert!(
            m.contains("pass --resample (suites: resample = true)"),
            "{m}"
        );
        // 1e-4 of the step off: jitter, absorbed (and the grid used).
        let (_, r) = read_text(&t_at(5, 0.050001), &c, &ReadOptions::default());
        let r = r.unwrap();
        assert!((r.t[5] - 0.05).abs() < 1e-6 && (r.dt() - 0.01).abs() < 1e-7);
        assert!(r.t.windows(2).all(|w| (w[1] - w[0] - r.dt()).abs() < 1e-15));
        // Non-increasing time is refused even when resampling.
        let (_, r) = read_text(&t_at(5, 0.04), &c, &RESAMPLE);
        assert!(
            r.unwrap_err()
                .to_string()
                .contains("not strictly increasing")
        );
    }

    #[test]
    fn time_printed_with_nine_digits_is_uniform_but_jitter_is_not() {
        // Like the benchmark files: t = k/750 printed with 9 significant digits, up to
        // t = 204 s where rounding moves a step by ~1e-6 s (7e-4 of the step).
        let c = cols("t_s,u_N,y_m");
        let n = 153_000;
        let text = table(n, |k| {
            format!(
                "{k},{},{},0.000123456789",
                g9(k as f64 / 750.0),
                g9(k as f64)
            )
        });
        let (_, r) = read_text(&text, &c, &ReadOptions::default());
        let r = r.unwrap();
        assert_eq!(r.len(), n);
        assert!((r.dt() - 1.0 / 750.0).abs() < 1e-12);
        assert!((r.t[n - 1] - (n - 1) as f64 / 750.0).abs() < 1e-9);
        assert!(!r.name.contains("resampled"));
        // A sample 3 % of the step off with the same printing is caught.
        let text = table(1000, |k| {
            let t = k as f64 / 750.0 + if k == 600 { 4e-5 } else { 0.0 };
            format!("{k},{},1,1.23456789", g9(t))
        });
        let m = refusal(&text, &c, 602);
        assert!(m.contains("off the uniform grid"), "{m}");
    }

    /// `%.9g`-style printing, as in the benchmark files.
    fn g9(v: f64) -> String {
        sig(v, 9)
    }

    #[test]
    fn resample_interpolates_non_uniform_time() {
        // Time warped smoothly; u and y linear in time, so interpolation is exact.
        let n = 50;
        let warp = |k: usize| {
            let x = k as f64 / (n - 1) as f64;
            2.0 * (x + 0.05 * (std::f64::consts::PI * x).sin())
        };
        let text = table(n, |k| {
            format!("{k},{},{},{}", warp(k), 3.0 * warp(k), 1.0 - warp(k))
        });
        let c = cols("t_s,u_N,y_m");
        let (_, r) = read_text(&text, &c, &ReadOptions::default());
        assert!(r.unwrap_err().to_string().contains("off the uniform grid"));
        let (_, r) = read_text(&text, &c, &RESAMPLE);
        let r = r.unwrap();
        assert!(r.name.contains("(resampled: "), "{}", r.name);
        // From the first to the last time, at about the median step.
        let mut steps: Vec<f64> = (1..n).map(|k| warp(k) - warp(k - 1)).collect();
        let h = middle(&mut steps);
        assert_eq!(r.len(), (2.0 / h).round() as usize + 1);
        assert_eq!(r.t[0], 0.0);
        assert!((r.t[r.len() - 1] - 2.0).abs() < 1e-12);
        for i in 0..r.len() {
            assert!((r.u[i] - 3.0 * r.t[i]).abs() < 1e-12);
            assert!((r.y[i] - (1.0 - r.t[i])).abs() < 1e-12);
        }
        // Uniform data is left alone even when resampling is allowed.
        let (_, r) = read_text(&good(10), &c, &RESAMPLE);
        let r = r.unwrap();
        assert!(!r.name.contains("resampled"));
        assert_eq!(r.u[9], 18.0);
    }

    #[test]
    fn jittered_stamps_of_a_5khz_record_load_without_a_flag() {
        // 50,000 samples at 2e-4 s, each stamp off by up to ±1e-8 s, 9 significant digits.
        let mut rng = TrialSeed::from_u64(15).rng(0);
        let (n, h) = (50_000, 2e-4);
        let text = table(n, |k| {
            let jitter = (rng.random::<f64>() - 0.5) * 2e-8;
            format!(
                "{k},{},{},1.5",
                g9(k as f64 * h + jitter),
                g9(k as f64 * 0.25)
            )
        });
        let (_, r) = read_noted(&text, &cols("t_s,u_N,y_m"), &ReadOptions::default());
        let (r, notes) = r.unwrap();
        assert_eq!(r.len(), n);
        assert!(!r.name.contains("resampled"), "{}", r.name);
        assert!((r.dt() - h).abs() < 1e-15, "dt {}", r.dt());
        // The fitted grid is within the jitter of the true one, everywhere.
        let worst = (0..n)
            .map(|k| (r.t[k] - k as f64 * h).abs())
            .fold(0.0, f64::max);
        assert!(worst < 2e-8, "{worst}");
        assert_eq!(r.u[n - 1], (n - 1) as f64 * 0.25);
        assert_eq!(notes.len(), 1, "{notes:?}");
        let note = &notes[0];
        for part in [
            "time stamps jitter by up to 1.",
            "e-8 s (0.01 % of the step)",
            "step 0.0002 s fitted",
            "1 % of the step plus 5.0e-9 s rounding of the printed times",
            "the grid is used",
        ] {
            assert!(note.contains(part), "{part} in {note}");
        }
    }

    #[test]
    fn a_gap_is_refused_at_the_sample_after_it_or_resampled() {
        let c = cols("t_s,u_N,y_m");
        // One sample missing early (most samples after the gap) or late, at t0 = 1234.5 s;
        // u and y linear in time, so the interpolation restores them.
        for missing in [3, 30] {
            let rows: Vec<usize> = (0..40).filter(|&k| k != missing).collect();
            let text = table(rows.len(), |i| {
                let k = rows[i] as f64;
                format!("{i},{},{},{}", 1234.5 + k * 0.01, 2.0 * k, 5.0 - k)
            });
            // Row i is on line i + 2: the sample after the gap is row `missing`.
            let line = missing + 2;
            let m = refusal(&text, &c, line);
            assert!(m.contains("(a gap of 2.00 steps: a missing sample)"), "{m}");
            assert!(m.contains(&format!("on line {}", line - 1)), "{m}");
            assert!(
                m.contains("step 0.01 s, a robust fit of the 39 stamps"),
                "{m}"
            );
            let (_, r) = read_noted(&text, &c, &RESAMPLE);
            let (r, notes) = r.unwrap();
            assert_eq!(r.len(), 40);
            assert!((r.dt() - 0.01).abs() < 1e-12);
            assert_eq!(r.t[0], 1234.5);
            for k in 0..40 {
                assert!((r.u[k] - 2.0 * k as f64).abs() < 1e-9, "{k}: {}", r.u[k]);
                assert!((r.y[k] - (5.0 - k as f64)).abs() < 1e-9);
            }
            let what =
                format!("resampled: 40 samples, step 0.01 s, largest gap 0.02 s at line {line}");
            assert!(r.name.contains(&what), "{}", r.name);
            assert!(notes.iter().any(|n| n.contains(&what)), "{notes:?}");
        }
        // Three missing samples, and a late stamp; resampling a long pause is refused.
        let text = table(20, |k| {
            let t = if k < 10 { k as f64 } else { k as f64 + 3.0 };
            format!("{k},{t},1,2")
        });
        let m = refusal(&text, &c, 12);
        assert!(
            m.contains("(a gap of 4.00 steps: 3 missing samples)"),
            "{m}"
        );
        let text = table(20, |k| {
            format!("{k},{},1,2", k as f64 + if k >= 10 { 400.0 } else { 0.0 })
        });
        let (_, r) = read_text(&text, &c, &RESAMPLE);
        let m = r.unwrap_err().to_string();
        assert!(m.contains("would make 420 samples from 20"), "{m}");
    }

    #[test]
    fn delimiters_and_decimal_commas_are_detected_or_set() {
        let c = cols("t_s,u_V,y_um");
        let n = 12;
        let value = |k: usize| [k as f64 * 0.005, 1.8 + k as f64 / 64.0, -120.25 + k as f64];
        let file = |sep: &str, comma: bool| {
            let mut s = format!("t_s{sep}u_V{sep}y_um\n");
            for k in 0..n {
                let f: Vec<String> = value(k)
                    .iter()
                    .map(|v| {
                        let v = v.to_string();
                        if comma { v.replace('.', ",") } else { v }
                    })
                    .collect();
                s += &f.join(sep);
                s.push('\n');
            }
            s
        };
        let aligned = {
            let mut s = format!("{:>8} {:>10} {:>10}\n", "t_s", "u_V", "y_um");
            for k in 0..n {
                let [t, u, y] = value(k);
                s += &format!("{t:>8} {u:>10}  {y:>10}\n");
            }
            s
        };
        for (text, note) in [
            (file(",", false), None),
            (file(";", true), Some("separated by ';', decimal comma")),
            (file(";", false), Some("separated by ';', decimal point")),
            (file("\t", true), Some("separated by tab, decimal comma")),
            (
                aligned.clone(),
                Some("separated by whitespace, decimal point"),
            ),
        ] {
            let (_, r) = read_noted(&text, &c, &ReadOptions::default());
            let (r, notes) = r.unwrap_or_else(|e| panic!("{e}\n{text}"));
            for k in 0..n {
                assert_eq!([r.t[k], r.u[k], r.y[k]], value(k), "{text}");
            }
            match note {
                Some(note) => assert!(notes[0].ends_with(note), "{notes:?}"),
                None => assert!(notes.is_empty(), "{notes:?}"),
            }
        }
        // Set explicitly: the same; the wrong one says what it split by.
        let set = |d: &str| ReadOptions {
            delimiter: Delimiter::parse(d).unwrap(),
            ..ReadOptions::default()
        };
        let (_, r) = read_text(&file(";", true), &c, &set(";"));
        assert_eq!(r.unwrap().y[3], -117.25);
        let (_, r) = read_text(&aligned, &c, &set("whitespace"));
        assert_eq!(r.unwrap().u[2], 1.8 + 2.0 / 64.0);
        let (_, r) = read_text(&file(";", true), &c, &set(","));
        let m = r.unwrap_err().to_string();
        assert!(
            m.contains("(columns: t_s;u_V;y_um, separated by ',')"),
            "{m}"
        );
        // One decimal separator per file; digit grouping is refused, not misread.
        let mixed = file(";", true).replace("\n0,015;", "\n0.015;");
        let m = refusal(&mixed, &c, 5);
        assert!(
            m.contains("time column 't_s': '0.015' has a decimal point but line 2 a decimal comma"),
            "{m}"
        );
        let grouped = file(";", false).replace(";-115.25\n", ";-1,115.25\n");
        let m = refusal(&grouped, &c, 7);
        assert!(
            m.contains("'-1,115.25' has both a decimal point and a comma"),
            "{m}"
        );
        // The flag's spellings, and its printed form read back.
        for (spec, d) in [
            ("auto", Delimiter::Auto),
            (",", Delimiter::Char(b',')),
            ("semicolon", Delimiter::Char(b';')),
            ("\\t", Delimiter::Char(b'\t')),
            ("tab", Delimiter::Char(b'\t')),
            ("space", Delimiter::Whitespace),
        ] {
            assert_eq!(Delimiter::parse(spec).unwrap(), d);
            assert_eq!(Delimiter::parse(&d.to_string()).unwrap(), d);
        }
        let e = Delimiter::parse("|").unwrap_err().to_string();
        assert!(e.contains("expected auto, ',' (comma), ';' (semicolon), tab or whitespace"));
    }

    #[test]
    fn time_offset_motion_at_the_start_and_long_rests_are_read_as_they_are() {
        // Starts at 1234.5 s in mid-swing (u and y far from rest), then holds u for 5 s.
        let c = cols("t_s,u_N,y_m");
        let (n, h) = (8000, 1e-3);
        let u = |k: usize| {
            if k < 3000 {
                (k as f64 * 0.01 + 1.0).sin()
            } else {
                0.25
            }
        };
        let text = table(n, |k| {
            format!("{k},{},{},{}", 1234.5 + k as f64 * h, u(k), 3.0 * u(k))
        });
        let (_, r) = read_noted(&text, &c, &ReadOptions::default());
        let (r, notes) = r.unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(r.t[0], 1234.5);
        assert!((r.dt() - h).abs() < 1e-12);
        assert_eq!((r.u[0], r.u[n - 1]), (u(0), 0.25));
        // Jittered stamps at the offset too (2e-6 s, printed with 12 digits: 5e-9 s).
        let mut rng = TrialSeed::from_u64(3).rng(0);
        let text = table(n, |k| {
            let t = 1234.5 + k as f64 * h + (rng.random::<f64>() - 0.5) * 4e-6;
            format!("{k},{},{},{}", sig(t, 12), g9(u(k)), g9(3.0 * u(k)))
        });
        let (_, r) = read_noted(&text, &c, &ReadOptions::default());
        let (r, notes) = r.unwrap();
        assert!((r.t[0] - 1234.5).abs() < 2e-5 && (r.dt() - h).abs() < 1e-9);
        assert!(notes[0].contains("jitter by up to 2."), "{notes:?}");
        assert!(notes[0].contains("plus 5.0e-9 s rounding"), "{notes:?}");
    }

    #[test]
    fn data_dir_defaults_to_shared_data() {
        if std::env::var_os("OPTBENCH_DATA").is_none_or(|v| v.is_empty()) {
            assert!(
                data_dir().ends_with("shared/data"),
                "{}",
                data_dir().display()
            );
        }
    }

    /// The real file, or `None` after saying why the test is skipped.
    fn real(rel: &str) -> Option<PathBuf> {
        let p = data_dir().join(rel);
        if p.is_file() {
            Some(p)
        } else {
            eprintln!("skipping: data not found at {}", p.display());
            None
        }
    }

    fn std_dev(v: &[f64]) -> f64 {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
    }

    #[test]
    fn every_real_recording_loads_without_a_flag() {
        // (file, columns, samples, step): the P-885 stack, the CubeSpec mirror (each
        // piezo to its own mirror point), the Bouc-Wen training set; the MR damper and the
        // benchmark's test sets have their own tests.
        let mut files = vec![
            (
                "pea_p885_dbo/dbo_identification_1Hz_sine.csv".to_string(),
                "t_s,u_V,y_um".to_string(),
                8027,
                0.005,
            ),
            (
                "pea_p885_dbo/dbo_test_ramped_sine_with_holds.csv".into(),
                "t_s,u_V,y_um".into(),
                14155,
                0.005,
            ),
            (
                "boucwen-benchmark/train_multisine_forgione.csv".into(),
                "t_s,u_N,y_m".into(),
                40960,
                1.0 / 750.0,
            ),
        ];
        for level in ["100", "200", "300"] {
            for (set, i) in [("train_r0", 1), ("train_r2", 2), ("test_r0", 3)] {
                files.push((
                    format!("fsm_cubespec_piezo/fsm_{level}mV_{set}.csv"),
                    format!("t_s,u{i}_V,y{i}_um"),
                    16384,
                    1.0 / 6400.0,
                ));
            }
        }
        for (rel, columns, n, dt) in files {
            let Some(p) = real(&rel) else {
                return;
            };
            let (r, notes) =
                Recording::read_csv_noted(&p, &cols(&columns), &ReadOptions::default())
                    .unwrap_or_else(|e| panic!("{e}"));
            eprintln!(
                "{rel}: {} samples, dt {} s, notes {notes:?}",
                r.len(),
                r.dt()
            );
            assert_eq!(r.len(), n, "{rel}");
            assert!((r.dt() / dt - 1.0).abs() < 1e-9, "{rel}: dt {}", r.dt());
            // Exactly printed (or only rounded) uniform stamps: nothing to say.
            assert!(notes.is_empty(), "{rel}: {notes:?}");
            assert!(std_dev(&r.y) > 0.0 && std_dev(&r.u) > 0.0, "{rel}");
        }
    }

    #[test]
    fn reads_the_bouc_wen_benchmark() {
        let c = cols("t_s,u_N,y_m");
        let Some(p) = real("boucwen-benchmark/test_multisine.csv") else {
            return;
        };
        let r = Recording::read_csv(&p, &c, &ReadOptions::default()).unwrap();
        assert_eq!(r.len(), 8192);
        // The 9 printed digits' rounding limits the fitted step to about 1e-11 of itself.
        assert!((1.0 / r.dt() - 750.0).abs() < 1e-8, "fs {}", 1.0 / r.dt());
        assert_eq!(r.units, ["s", "N", "m"]);
        assert!(
            (std_dev(&r.u) - 50.0).abs() < 0.01,
            "u std {}",
            std_dev(&r.u)
        );
        assert!(
            (std_dev(&r.y) - 6.67e-4).abs() < 0.01e-4,
            "y std {}",
            std_dev(&r.y)
        );
        assert_eq!(r.u[0], -10.8634532);
        assert_eq!(r.y[8191], -0.000255699045);
        let Some(p) = real("boucwen-benchmark/test_sinesweep.csv") else {
            return;
        };
        let r = Recording::read_csv(&p, &c, &ReadOptions::default()).unwrap();
        assert_eq!(r.len(), 153_000);
        assert!((1.0 / r.dt() - 750.0).abs() < 1e-9, "fs {}", 1.0 / r.dt());
        assert!((r.t[152_999] - 203.998667).abs() < 1e-6);
    }

    #[test]
    fn reads_the_mr_damper_runs() {
        let dir = "mr-damper-labcontrol";
        let names: Vec<String> = (1..=10)
            .map(|i| format!("ensaio_A_{i}.csv"))
            .chain((1..=3).map(|i| format!("ensaio_vali_A_{i}.csv")))
            .collect();
        for name in names {
            let Some(p) = real(&format!("{dir}/{name}")) else {
                return;
            };
            let v = Recording::read_csv(
                &p,
                &cols("t_s,velocity_mm_per_s,force_N"),
                &ReadOptions::default(),
            )
            .unwrap();
            assert_eq!(v.len(), 1501, "{name}");
            assert!((v.dt() - 0.01).abs() < 1e-12, "{name}");
            assert_eq!(v.units, ["s", "mm/s", "N"]);
            assert!(std_dev(&v.y) > 100.0, "{name}: force std {}", std_dev(&v.y));
            let x = Recording::read_csv(
                &p,
                &cols("t_s,position_mm,force_N"),
                &ReadOptions::default(),
            )
            .unwrap();
            assert_eq!(x.units[1], "mm");
            assert_eq!(x.y, v.y);
        }
    }
}
