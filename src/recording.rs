//! Sampled input/output records: what an actuator experiment (or the twin) produces and what
//! the fitting objectives consume.

use crate::error::{Error, Result};
use crate::results::atomic::atomic_write;
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
    /// Checked constructor: equal lengths, at least [`MIN_SAMPLES`], finite values, strictly
    /// increasing uniform time.
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
        for (i, ((a, b), c)) in t.iter().zip(&u).zip(&y).enumerate() {
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                return Err(Error::Input(format!("{name}: sample {i} is not finite")));
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
    pub fn slice(&self, range: std::ops::Range<usize>) -> Result<Self> {
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

/// How [`Recording::read_csv`] treats imperfect files.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Accept non-uniform (but strictly increasing) time by linearly interpolating onto a
    /// uniform grid with the mean step. Off by default: silently resampling a record
    /// changes the data a model is fitted to, so it must be asked for.
    pub resample: bool,
}

/// The folder of recorded data sets (kept outside the repository, read by path).
///
/// `$OPTBENCH_DATA` if set and non-empty; otherwise `../shared/data` relative to the current
/// directory if that folder exists (the CI layout: data beside the checkout); otherwise
/// `<crate root>/../shared/data`, so tests and binaries run from elsewhere still find it.
/// The path may not exist: callers check and say where they looked.
pub fn data_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("OPTBENCH_DATA").filter(|v| !v.is_empty()) {
        return PathBuf::from(dir);
    }
    let rel = Path::new("../shared/data");
    let dir = if rel.is_dir() {
        rel.to_path_buf()
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data")
    };
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

impl Recording {
    /// Reads a recording from a CSV file with a header row, picking the time, input and
    /// output columns by name; units come from the names (see [`unit_from_name`]).
    ///
    /// Every refusal is an [`Error::Input`] located at `file:line` naming the column:
    /// missing column (with the header's names), empty/non-numeric/non-finite value, empty
    /// file, time not strictly increasing, non-uniform sampling, fewer than
    /// [`MIN_SAMPLES`] rows.
    ///
    /// Uniformity is checked to 1e-6 of the mean step plus the rounding of the printed time
    /// values: files print a fixed number of significant digits (the most seen in any
    /// field), so `t = k/750` printed as `10.9213333` is off by up to half a unit in the
    /// last digit. Times that are uniform only within that rounding are snapped to the grid
    /// `t0 + i*dt` they denote; exactly printed times are kept as read (so
    /// [`Recording::write_csv`] round-trips bit for bit). With [`ReadOptions::resample`],
    /// non-uniform time is interpolated instead and the name says so.
    ///
    /// The name is `<path> [<input> -> <output>]`.
    pub fn read_csv(path: &Path, columns: &Columns, opts: &ReadOptions) -> Result<Recording> {
        let bytes =
            std::fs::read(path).map_err(|e| Error::io(format!("reading {}", path.display()), e))?;
        // Spreadsheet exports often start with a UTF-8 byte-order mark; csv keeps it in the
        // first header name.
        let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::All)
            .from_reader(text);
        let csv_err = |e: csv::Error, fallback_line: u64| {
            let line = e.position().map_or(fallback_line, |p| p.line()) as usize;
            match e.kind() {
                csv::ErrorKind::UnequalLengths {
                    expected_len, len, ..
                } => Error::at(
                    path,
                    line,
                    format!("row has {len} fields but the header has {expected_len}"),
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
        let available = headers.iter().collect::<Vec<_>>().join(", ");
        let numeric_header = headers.iter().all(|h| h.parse::<f64>().is_ok());
        let pick = |role: &str, name: &str| -> Result<usize> {
            let hits: Vec<usize> = headers
                .iter()
                .enumerate()
                .filter(|(_, h)| *h == name)
                .map(|(i, _)| i)
                .collect();
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
                    format!("no {role} column '{name}' (columns: {available})"),
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
        let mut printed_digits = 0u32;
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
            for field in record.iter() {
                printed_digits = printed_digits.max(significant_digits(field));
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
                let v: f64 = text
                    .parse()
                    .map_err(|_| at(format!("'{text}' is not a number")))?;
                if !v.is_finite() {
                    return Err(at(format!("'{text}' is not finite")));
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
        // Rounding of a printed time value: half a unit in its last significant digit
        // when printed with `digits` digits, plus f64 noise.
        let digits = printed_digits.clamp(1, 17) as i32;
        let noise = |v: f64| {
            if v == 0.0 {
                return 0.0;
            }
            let mut e = v.abs().log10().floor() as i32;
            if 10f64.powi(e + 1) <= v.abs() {
                e += 1;
            }
            0.5 * 10f64.powi(e + 1 - digits) + 4.0 * f64::EPSILON * v.abs()
        };
        let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
        let tolerance = |i: usize| 1e-6 * dt + noise(t[i]) + noise(t[i - 1]);
        let non_uniform = (1..n).find(|&i| (t[i] - t[i - 1] - dt).abs() > tolerance(i));
        let mut name = format!(
            "{} [{} -> {}]",
            path.display(),
            columns.input,
            columns.output
        );
        let t0 = t[0];
        let grid = move |k: usize| t0 + k as f64 * dt;
        let (t, u, y) = match non_uniform {
            Some(i) if !opts.resample => {
                return Err(Error::at(
                    path,
                    lines[i],
                    format!(
                        "time column '{}': non-uniform sampling: step {} s from line {} \
                         differs from the mean step {dt} s by {:e} s (tolerance {:e} s: 1e-6 \
                         of the step plus the rounding of the printed times); enable \
                         resampling to interpolate onto a uniform grid",
                        time.name,
                        t[i] - t[i - 1],
                        lines[i - 1],
                        (t[i] - t[i - 1] - dt).abs(),
                        tolerance(i)
                    ),
                ));
            }
            Some(_) => {
                let g: Vec<f64> = (0..n).map(grid).collect();
                let u2 = interpolate(&t, &u, &g);
                let y2 = interpolate(&t, &y, &g);
                name.push_str(&format!(
                    " (resampled: non-uniform time linearly interpolated onto dt = {dt} s)"
                ));
                (g, u2, y2)
            }
            None => (t, u, y),
        };
        let mut rec = match Recording::new(name.clone(), t.clone(), u.clone(), y.clone()) {
            Ok(r) => r,
            // Uniform only to the printed precision: use the grid the values denote,
            // anchored at the first time, with the least-squares step (the end points alone
            // carry their rounding into dt: 2e-9 relative for the benchmark files).
            Err(_) => {
                let (num, den) = (1..n).fold((0.0, 0.0), |(a, b), i| {
                    let k = i as f64;
                    (a + k * (t[i] - t0), b + k * k)
                });
                let step = num / den;
                let t = (0..n).map(|k| t0 + k as f64 * step).collect();
                Recording::new(name, t, u, y)?
            }
        };
        rec.units = cols.map(|c| unit_from_name(c.name));
        Ok(rec)
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
    use crate::harness::TrialSeed;
    use rand::RngExt;

    fn cols(spec: &str) -> Columns {
        Columns::parse(spec).unwrap()
    }

    /// Writes `text` to a temporary CSV and reads it with `columns`; returns the path used.
    fn read_text(
        text: &str,
        columns: &Columns,
        opts: &ReadOptions,
    ) -> (PathBuf, Result<Recording>) {
        // The folder is removed on return; the path is only kept for messages.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rec.csv");
        std::fs::write(&p, text).unwrap();
        let r = Recording::read_csv(&p, columns, opts);
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

    fn table(rows: usize, f: impl Fn(usize) -> String) -> String {
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
            .map(|_| (rng.random::<f64>() - 0.5) * 10f64.powi(rng.random_range(-300..300)))
            .collect();
        let y: Vec<f64> = (0..n).map(|_| rng.random::<f64>() * 1e-4).collect();
        u[0] = -0.0;
        u[1] = f64::MIN_POSITIVE / 8.0; // subnormal
        u[2] = f64::MAX;
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
        assert!(m.contains("(columns: k, t_s, u_N, y_m)"), "{m}");
        let m = refusal(&good(10), &Columns::default(), 1);
        assert!(m.contains("time column 't'"), "{m}");
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
        // 1e-4 relative jitter: far above tolerance, and resolved by 9 printed digits.
        let m = refusal(&t_at(5, 0.050001), &c, 7);
        assert!(m.contains("time column 't_s': non-uniform sampling"), "{m}");
        assert!(m.contains("resampl"), "{m}");
        // Non-increasing time is refused even when resampling.
        let (_, r) = read_text(&t_at(5, 0.04), &c, &ReadOptions { resample: true });
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
        // A real 1e-4 relative jitter with the same printing is still caught.
        let text = table(1000, |k| {
            let t = k as f64 / 750.0 + if k == 600 { 1.4e-7 } else { 0.0 };
            format!("{k},{},1,1.23456789", g9(t))
        });
        let m = refusal(&text, &c, 602);
        assert!(m.contains("non-uniform sampling"), "{m}");
    }

    /// `%.9g`-style printing, as in the benchmark files.
    fn g9(v: f64) -> String {
        if v == 0.0 {
            return "0".into();
        }
        let digits = 9 - 1 - v.abs().log10().floor() as i32;
        let s = format!("{:.*}", digits.max(0) as usize, v);
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
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
        assert!(r.unwrap_err().to_string().contains("non-uniform sampling"));
        let (_, r) = read_text(&text, &c, &ReadOptions { resample: true });
        let r = r.unwrap();
        assert_eq!(r.len(), n);
        assert!(r.name.contains("resampled"), "{}", r.name);
        assert!((r.dt() - 2.0 / (n - 1) as f64).abs() < 1e-15);
        for i in 0..n {
            assert!((r.u[i] - 3.0 * r.t[i]).abs() < 1e-12);
            assert!((r.y[i] - (1.0 - r.t[i])).abs() < 1e-12);
        }
        // Uniform data is left alone even when resampling is allowed.
        let (_, r) = read_text(&good(10), &c, &ReadOptions { resample: true });
        let r = r.unwrap();
        assert!(!r.name.contains("resampled"));
        assert_eq!(r.u[9], 18.0);
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
    fn reads_the_bouc_wen_benchmark() {
        let c = cols("t_s,u_N,y_m");
        let Some(p) = real("boucwen-benchmark/test_multisine.csv") else {
            return;
        };
        let r = Recording::read_csv(&p, &c, &ReadOptions::default()).unwrap();
        assert_eq!(r.len(), 8192);
        assert!((1.0 / r.dt() - 750.0).abs() < 1e-9, "fs {}", 1.0 / r.dt());
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
