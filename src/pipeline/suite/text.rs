//! The suite-text loader shared by benchmark and control suites: reading the file, TOML
//! errors located to their line, the common header (name, seed, trials), names that become
//! paths, and typed fields taken out of free-form entries (`[[objective]]`, `[[optimizer]]`,
//! `[[controller]]`), so every suite error names the file, the line and the key alike.

use crate::base::SafeName;
use crate::base::error::{Error, Result};
use crate::base::limits::MAX_TRIALS;
use crate::base::params::Origin;
use serde::de::DeserializeOwned;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use toml::Spanned;

/// A free-form entry: its keys with their values and where they stand.
pub type Fields = BTreeMap<String, Spanned<toml::Value>>;

/// A suite file's text and path: what every message of the loader points into.
#[derive(Clone, Copy)]
pub struct SuiteText<'a> {
    pub path: &'a Path,
    pub text: &'a str,
}

/// The header every suite starts with.
pub struct Header {
    pub name: SafeName,
    pub seed: u64,
    pub trials: usize,
}

/// Reads a suite file, or says which file could not be read.
pub fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path)
        .map_err(|e| Error::Input(format!("{}: cannot read suite: {e}", path.display())))
}

/// A TOML value as a parameter's text (strings without their quotes).
pub fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

fn as_float(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Float(x) => Some(*x),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

impl<'a> SuiteText<'a> {
    pub fn new(path: &'a Path, text: &'a str) -> Self {
        SuiteText { path, text }
    }

    /// The 1-based line of byte `offset`.
    pub fn line(&self, offset: usize) -> usize {
        self.text[..offset.min(self.text.len())]
            .matches('\n')
            .count()
            + 1
    }

    /// An input error at byte `offset`.
    pub fn at(&self, offset: usize, msg: impl Into<String>) -> Error {
        Error::at(self.path, self.line(offset), msg.into())
    }

    /// An input error on `line`.
    pub fn on(&self, line: usize, msg: impl Into<String>) -> Error {
        Error::at(self.path, line, msg.into())
    }

    /// The text as `T`, a syntax or schema error located to its line.
    pub fn parse<T: DeserializeOwned>(&self) -> Result<T> {
        toml::from_str(self.text).map_err(|e| {
            let line = e.span().map(|s| self.line(s.start)).unwrap_or(1);
            Error::at(self.path, line, e.message().trim_end())
        })
    }

    /// Checks `name`, `seed` and `trials`.
    pub fn header(
        &self,
        name: &Spanned<String>,
        seed: &Spanned<i64>,
        trials: &Spanned<i64>,
    ) -> Result<Header> {
        let n = name.get_ref();
        let n = SafeName::new(n).map_err(|why| {
            self.at(
                name.span().start,
                format!("`name` = {n:?} {why} (it names the results folder)"),
            )
        })?;
        let s = u64::try_from(*seed.get_ref())
            .map_err(|_| self.at(seed.span().start, "`seed` must be >= 0"))?;
        let t = *trials.get_ref();
        if !(1..=MAX_TRIALS as i64).contains(&t) {
            return Err(self.at(
                trials.span().start,
                format!("`trials` = {t}: expected an integer in [1, {MAX_TRIALS}] (a limit derived from memory)"),
            ));
        }
        Ok(Header {
            name: n,
            seed: s,
            trials: t as usize,
        })
    }

    /// An entry's `id` as a [`SafeName`] (not one of `reserved`), refused when `seen` has it
    /// already, in any case: ids name files, and case-insensitive file systems would
    /// merge `A` and `a`.
    pub fn check_id(
        &self,
        id: &str,
        seen: &mut BTreeSet<String>,
        line: usize,
        what: &str,
        reserved: &[&str],
    ) -> Result<SafeName> {
        let name = SafeName::not_reserved(id, reserved)
            .map_err(|why| self.on(line, format!("{what} id {id:?} {why}")))?;
        if !seen.insert(id.to_ascii_lowercase()) {
            return Err(self.on(
                line,
                format!(
                    "{what} id `{id}` is used twice (ids differing only in case count as one); give each entry a distinct `id`"
                ),
            ));
        }
        Ok(name)
    }

    /// Takes the entry's `kind` and finds it among `kinds`, or says which kinds exist.
    pub fn take_kind<'k, K>(
        &self,
        kinds: &'k [K],
        name: impl Fn(&K) -> &'static str,
        fields: &mut Fields,
        line: usize,
        what: &str,
    ) -> Result<&'k K> {
        let valid = || kinds.iter().map(&name).collect::<Vec<_>>().join(", ");
        let kind_line = fields
            .get("kind")
            .map_or(line, |v| self.line(v.span().start));
        let wanted = self.take_str(fields, "kind")?.ok_or_else(|| {
            self.on(
                line,
                format!("{what} without `kind`; valid kinds: {}", valid()),
            )
        })?;
        kinds.iter().find(|k| name(k) == wanted).ok_or_else(|| {
            self.on(
                kind_line,
                format!("unknown {what} kind `{wanted}`; valid kinds: {}", valid()),
            )
        })
    }

    pub fn take_str(&self, fields: &mut Fields, key: &str) -> Result<Option<String>> {
        match fields.remove(key) {
            None => Ok(None),
            Some(v) => match v.get_ref() {
                toml::Value::String(s) => Ok(Some(s.clone())),
                other => Err(self.at(
                    v.span().start,
                    format!("`{key}`: expected a string, found {}", other.type_str()),
                )),
            },
        }
    }

    pub fn take_int(&self, fields: &mut Fields, key: &str) -> Result<Option<(i64, usize)>> {
        match fields.remove(key) {
            None => Ok(None),
            Some(v) => {
                let line = self.line(v.span().start);
                match v.get_ref() {
                    toml::Value::Integer(i) => Ok(Some((*i, line))),
                    other => Err(self.on(
                        line,
                        format!("`{key}`: expected an integer, found {}", other.type_str()),
                    )),
                }
            }
        }
    }

    pub fn take_float(&self, fields: &mut Fields, key: &str) -> Result<Option<(f64, usize)>> {
        match fields.remove(key) {
            None => Ok(None),
            Some(v) => {
                let line = self.line(v.span().start);
                as_float(v.get_ref())
                    .map(|x| Some((x, line)))
                    .ok_or_else(|| {
                        self.on(
                            line,
                            format!(
                                "`{key}`: expected a number, found {}",
                                v.get_ref().type_str()
                            ),
                        )
                    })
            }
        }
    }

    /// Takes an optional array `key`, converting each element with `conv` (`what` names
    /// the element type in the message).
    pub fn take_array<T>(
        &self,
        fields: &mut Fields,
        key: &str,
        what: &str,
        conv: fn(&toml::Value) -> Option<T>,
    ) -> Result<Option<(Vec<T>, usize)>> {
        let Some(v) = fields.remove(key) else {
            return Ok(None);
        };
        let line = self.line(v.span().start);
        let err = || self.on(line, format!("`{key}`: expected an array of {what}"));
        match v.get_ref() {
            toml::Value::Array(a) => a
                .iter()
                .map(|x| conv(x).ok_or_else(err))
                .collect::<Result<Vec<_>>>()
                .map(|x| Some((x, line))),
            _ => Err(err()),
        }
    }

    pub fn take_floats(&self, fields: &mut Fields, key: &str) -> Result<Option<(Vec<f64>, usize)>> {
        self.take_array(fields, key, "numbers", as_float)
    }

    /// The remaining fields with their lines, as parameter tables take them.
    pub fn given(&self, fields: Fields) -> BTreeMap<String, (toml::Value, usize)> {
        fields
            .into_iter()
            .map(|(k, v)| {
                let line = self.line(v.span().start);
                (k, (v.into_inner(), line))
            })
            .collect()
    }

    /// Where an entry's parameters come from, for their messages.
    pub fn origin(&self, line: usize, what: String) -> Origin {
        Origin {
            file: self.path.to_path_buf(),
            line,
            what,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Deserialize)]
    struct Head {
        name: Spanned<String>,
        seed: Spanned<i64>,
        trials: Spanned<i64>,
        #[serde(default)]
        entry: Vec<Spanned<Fields>>,
    }

    fn load(text: &str) -> Result<(Header, Vec<Spanned<Fields>>)> {
        let t = SuiteText::new(Path::new("s.toml"), text);
        let h: Head = t.parse()?;
        Ok((t.header(&h.name, &h.seed, &h.trials)?, h.entry))
    }

    fn message(r: Result<impl Sized>) -> String {
        match r {
            Ok(_) => panic!("expected an error"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn header_errors_name_the_file_the_line_and_the_key() {
        let m = message(load("name = \"a\"\nseed = -1\ntrials = 2\n"));
        assert!(
            m.contains("s.toml") && m.contains('2') && m.contains("`seed`"),
            "{m}"
        );
        let m = message(load("name = \"a\"\nseed = 1\n\ntrials = 0\n"));
        assert!(m.contains(":4") && m.contains("`trials` = 0"), "{m}");
        let m = message(load("name = \"../x\"\nseed = 1\ntrials = 1\n"));
        assert!(m.contains(":1") && m.contains("`name`"), "{m}");
        let m = message(load("name = \"a\"\nseed = 1\ntrials = \"x\"\n"));
        assert!(m.contains(":3"), "{m}");
        let (h, _) = load("name = \"a.b-c_d\"\nseed = 7\ntrials = 3\n").unwrap();
        assert_eq!((h.name.as_str(), h.seed, h.trials), ("a.b-c_d", 7, 3));
        for bad in ["", "..", "/abs", "a/b", "-x"] {
            let m = message(load(&format!("seed = 1\nname = {bad:?}\ntrials = 1\n")));
            assert!(
                m.contains("s.toml:2") && m.contains("results folder"),
                "{m}"
            );
        }
    }

    #[test]
    fn fields_are_taken_with_their_types_and_lines() {
        let text = "name = \"a\"\nseed = 1\ntrials = 1\n[[entry]]\nkind = \"x\"\nid = 3\nbudget = 10\nshare = 0.5\nlist = [1, 2.5]\nrest = \"r\"\n";
        let (_, entries) = load(text).unwrap();
        let t = SuiteText::new(Path::new("s.toml"), text);
        let mut f = entries[0].get_ref().clone();
        let kinds = ["x", "y"];
        assert_eq!(
            *t.take_kind(&kinds, |k| k, &mut f, 4, "thing").unwrap(),
            "x"
        );
        let m = message(t.take_str(&mut f, "id"));
        assert!(
            m.contains(":6") && m.contains("expected a string, found integer"),
            "{m}"
        );
        assert_eq!(t.take_int(&mut f, "budget").unwrap(), Some((10, 7)));
        assert_eq!(t.take_float(&mut f, "share").unwrap(), Some((0.5, 8)));
        assert_eq!(
            t.take_floats(&mut f, "list").unwrap(),
            Some((vec![1.0, 2.5], 9))
        );
        assert_eq!(t.take_int(&mut f, "absent").unwrap(), None);
        let given = t.given(f);
        assert_eq!(given.keys().collect::<Vec<_>>(), ["rest"]);
        assert_eq!(given["rest"].1, 10);
        let mut g = Fields::new();
        let m = message(t.take_kind(&kinds, |k| k, &mut g, 4, "thing"));
        assert!(m.contains("thing without `kind`"), "{m}");
        let mut seen = BTreeSet::new();
        t.check_id("a", &mut seen, 5, "thing", &[]).unwrap();
        let m = message(t.check_id("A", &mut seen, 6, "thing", &[]));
        assert!(m.contains(":6") && m.contains("used twice"), "{m}");
        let m = message(t.check_id("../a", &mut seen, 7, "thing", &[]));
        assert!(m.contains(":7") && m.contains("use letters"), "{m}");
        let m = message(t.check_id("Summary", &mut seen, 8, "table", &["summary"]));
        assert!(m.contains(":8") && m.contains("reserved"), "{m}");
    }
}
