//! Names that become path components: a suite's name (its results folder) and the ids of
//! objectives, optimizers, tables, controllers, plants and references (file and folder
//! names of tables, plots, figures and the IOHprofiler export). They come from suite files,
//! including the stored copy in a results folder someone else sent, so a [`SafeName`] can
//! only be made by checking: a conservative character set that means the same on every file
//! system, no separator, no `..`, nothing hidden or flag-like, a bounded length.

use std::fmt;
use std::path::Path;

/// The longest name: three ids and a suffix still fit a 255-byte file name
/// (a control figure is `<controller>_<plant>_<reference>_compensation-transient.png`,
/// written through a `.<file>.tmp-<pid>` temporary).
pub const MAX_LEN: usize = 64;

/// Table ids that would overwrite a built-in table of `tables/` (`<id>.md`, `<id>.tex`
/// beside `summary.md`, `summary.tex` and the CSV tables), compared ignoring case as
/// case-insensitive file systems do.
pub const RESERVED_TABLE_IDS: &[&str] = &["summary", "pairwise", "ert", "fixed_budget", "cells"];

/// A checked path component: letters, digits, '-', '_' and '.', at most [`MAX_LEN`] bytes,
/// not starting with '.' or '-', without `..`.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct SafeName(String);

impl SafeName {
    /// The name, or why it cannot be one (a phrase to follow "`id` = ...: ").
    pub fn new(s: &str) -> Result<SafeName, String> {
        let allowed = |c: char| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.');
        let why = if s.is_empty() {
            "is empty".to_string()
        } else if s.len() > MAX_LEN {
            format!("is {} bytes long", s.len())
        } else if s.starts_with(['.', '-']) {
            format!("starts with '{}'", &s[..1])
        } else if s.contains("..") {
            "contains `..`".to_string()
        } else if let Some(c) = s.chars().find(|&c| !allowed(c)) {
            format!("has {c:?}")
        } else {
            return Ok(SafeName(s.to_string()));
        };
        Err(format!(
            "{why}; it names files: use letters, digits, '-', '_' or '.' (not first), no `..`, at most {MAX_LEN} bytes"
        ))
    }

    /// [`SafeName::new`], also refusing `reserved` names (ignoring case).
    pub fn not_reserved(s: &str, reserved: &[&str]) -> Result<SafeName, String> {
        let n = Self::new(s)?;
        match reserved.iter().find(|r| r.eq_ignore_ascii_case(s)) {
            Some(r) => Err(format!(
                "is reserved: a built-in output is named `{r}`; reserved: {}",
                reserved.join(", ")
            )),
            None => Ok(n),
        }
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl std::ops::Deref for SafeName {
    type Target = str;
    fn deref(&self) -> &str {
        &self.0
    }
}

impl AsRef<Path> for SafeName {
    fn as_ref(&self) -> &Path {
        Path::new(&self.0)
    }
}

impl AsRef<str> for SafeName {
    fn as_ref(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for SafeName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl PartialEq<str> for SafeName {
    fn eq(&self, o: &str) -> bool {
        self.0 == o
    }
}

impl PartialEq<&str> for SafeName {
    fn eq(&self, o: &&str) -> bool {
        self.0 == *o
    }
}

impl PartialEq<String> for SafeName {
    fn eq(&self, o: &String) -> bool {
        &self.0 == o
    }
}

impl PartialEq<SafeName> for String {
    fn eq(&self, o: &SafeName) -> bool {
        *self == o.0
    }
}

impl PartialEq<SafeName> for str {
    fn eq(&self, o: &SafeName) -> bool {
        self == o.0
    }
}

impl PartialEq<SafeName> for &str {
    fn eq(&self, o: &SafeName) -> bool {
        *self == o.0
    }
}

impl From<SafeName> for String {
    fn from(n: SafeName) -> String {
        n.0
    }
}

impl serde::Serialize for SafeName {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.0)
    }
}

/// Read names are checked like parsed ones (the message says what is wrong, the reader
/// where).
impl<'de> serde::Deserialize<'de> for SafeName {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        SafeName::new(&s).map_err(|why| serde::de::Error::custom(format!("{s:?} {why}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_would_leave_their_folder_or_hide_are_refused() {
        let long = "a".repeat(MAX_LEN + 1);
        for bad in [
            "", ".", "..", ".hidden", "-flag", "a/b", "../../x", "/abs", "a b", "a\\b", "a..b",
            "C:x", "nul\0", "é", &long,
        ] {
            assert!(SafeName::new(bad).is_err(), "{bad:?}");
        }
        for good in [
            "a",
            "griewank-2d",
            "table3.2",
            "MSGA_1",
            &"a".repeat(MAX_LEN),
        ] {
            assert_eq!(SafeName::new(good).unwrap(), *good);
        }
        let m = SafeName::new("../x").unwrap_err();
        assert!(m.contains("starts with '.'"), "{m}");
        assert!(SafeName::new("a/..").unwrap_err().contains("`..`"));
    }

    #[test]
    fn reserved_names_are_refused_in_any_case() {
        for bad in ["summary", "Summary", "SUMMARY", "cells", "ert"] {
            let m = SafeName::not_reserved(bad, RESERVED_TABLE_IDS).unwrap_err();
            assert!(m.contains("reserved"), "{m}");
        }
        assert!(SafeName::not_reserved("summary2", RESERVED_TABLE_IDS).is_ok());
        assert!(SafeName::not_reserved("../summary", RESERVED_TABLE_IDS).is_err());
    }

    #[test]
    fn names_read_back_are_checked() {
        let ok: SafeName = serde_json::from_str("\"t1\"").unwrap();
        assert_eq!(ok, "t1");
        assert_eq!(serde_json::to_string(&ok).unwrap(), "\"t1\"");
        let e = serde_json::from_str::<SafeName>("\"../../x\"").unwrap_err();
        assert!(e.to_string().contains("../../x"), "{e}");
    }
}
