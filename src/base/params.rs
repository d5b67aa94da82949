//! Declarative parameter specifications.
//!
//! Every objective and optimizer kind declares its parameters once (name, type, range,
//! default, help). The same table validates suites with errors that name the file, line and
//! key, and prints `optbench list`, so documentation and checks cannot drift apart.

use super::error::Error;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// The type and admissible range of a parameter.
#[derive(Debug, Clone, Copy)]
pub enum Kind {
    /// Integer in `[min, max]`.
    Int { min: i64, max: i64 },
    /// Real number in `[min, max]` (integers are accepted).
    Float { min: f64, max: f64 },
    /// One of a fixed set of strings.
    Choice(&'static [&'static str]),
    /// true or false.
    Bool,
    /// Free text: a path, a signal or twin specification.
    Text,
}

/// What happens when a suite leaves a parameter out.
#[derive(Debug, Clone, Copy)]
pub enum Default {
    Int(i64),
    Float(f64),
    Str(&'static str),
    Bool(bool),
    /// The suite must give it.
    Required,
    /// Absent unless given; the text says what is used instead.
    Derived(&'static str),
}

/// One parameter of an objective or optimizer kind.
#[derive(Debug, Clone, Copy)]
pub struct Spec {
    pub name: &'static str,
    pub kind: Kind,
    pub default: Default,
    pub help: &'static str,
}

/// A validated parameter value.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(untagged)]
pub enum Value {
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{b}"),
            Value::Int(i) => write!(f, "{i}"),
            Value::Float(x) => write!(f, "{x}"),
            Value::Str(s) => write!(f, "\"{s}\""),
        }
    }
}

/// `x` as written in a suite: huge and tiny magnitudes in exponent form (`1e30`).
fn num(x: f64) -> String {
    if x != 0.0 && !(1e-4..1e15).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Kind::Int { min, max } if max == i64::MAX => write!(f, "integer >= {min}"),
            Kind::Int { min, max } => write!(f, "integer in [{min}, {max}]"),
            Kind::Float { min, max } => match (min.is_finite(), max.is_finite()) {
                (true, true) if min == f64::MIN_POSITIVE => {
                    write!(f, "number in (0, {}]", num(max))
                }
                (true, true) => write!(f, "number in [{}, {}]", num(min), num(max)),
                (true, false) if min == f64::MIN_POSITIVE => write!(f, "number > 0"),
                (true, false) => write!(f, "number >= {}", num(min)),
                (false, true) => write!(f, "number <= {}", num(max)),
                (false, false) => write!(f, "finite number"),
            },
            Kind::Choice(c) => write!(f, "one of {}", c.join(" | ")),
            Kind::Bool => write!(f, "true | false"),
            Kind::Text => write!(f, "text"),
        }
    }
}

impl fmt::Display for Default {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Default::Int(i) => write!(f, "{i}"),
            Default::Float(x) => write!(f, "{x}"),
            Default::Str(s) => write!(f, "\"{s}\""),
            Default::Bool(b) => write!(f, "{b}"),
            Default::Required => write!(f, "required"),
            Default::Derived(s) => write!(f, "{s}"),
        }
    }
}

impl Spec {
    fn check(&self, v: &toml::Value) -> Result<Value, String> {
        match (self.kind, v) {
            (Kind::Int { min, max }, toml::Value::Integer(i)) => {
                if *i < min || *i > max {
                    Err(format!("{i} is out of range: expected {}", self.kind))
                } else {
                    Ok(Value::Int(*i))
                }
            }
            (Kind::Float { min, max }, toml::Value::Integer(_) | toml::Value::Float(_)) => {
                let x = match v {
                    toml::Value::Integer(i) => *i as f64,
                    toml::Value::Float(x) => *x,
                    _ => unreachable!(),
                };
                if !x.is_finite() || x < min || x > max {
                    Err(format!(
                        "{} is out of range: expected {}",
                        num(x),
                        self.kind
                    ))
                } else {
                    Ok(Value::Float(x))
                }
            }
            (Kind::Choice(options), toml::Value::String(s)) => {
                if options.contains(&s.as_str()) {
                    Ok(Value::Str(s.clone()))
                } else {
                    Err(format!("\"{s}\" is not valid: expected {}", self.kind))
                }
            }
            (Kind::Bool, toml::Value::Boolean(b)) => Ok(Value::Bool(*b)),
            (Kind::Text, toml::Value::String(s)) => Ok(Value::Str(s.clone())),
            (kind, other) => Err(format!("expected {kind}, found {}", other.type_str())),
        }
    }

    fn default_value(&self) -> Option<Value> {
        match self.default {
            Default::Int(i) => Some(Value::Int(i)),
            Default::Float(x) => Some(Value::Float(x)),
            Default::Str(s) => Some(Value::Str(s.into())),
            Default::Bool(b) => Some(Value::Bool(b)),
            Default::Required | Default::Derived(_) => None,
        }
    }
}

/// Where a parameter table came from, for error messages.
#[derive(Debug, Clone)]
pub struct Origin {
    pub file: PathBuf,
    /// Line of the table's header or first key.
    pub line: usize,
    /// E.g. `optimizer "GA" (kind ga)`.
    pub what: String,
}

/// Parameters validated against their [`Spec`]s, defaults filled in.
#[derive(Debug, Clone)]
pub struct Params {
    origin: Origin,
    values: BTreeMap<&'static str, Value>,
    lines: BTreeMap<&'static str, usize>,
}

impl Params {
    /// Validates `given` (key -> (value, line)) against `specs`.
    pub fn validate(
        specs: &[Spec],
        given: &BTreeMap<String, (toml::Value, usize)>,
        origin: Origin,
    ) -> Result<Params, Error> {
        let mut values = BTreeMap::new();
        let mut lines = BTreeMap::new();
        for (key, (value, line)) in given {
            let Some(spec) = specs.iter().find(|s| s.name == key) else {
                let valid: Vec<_> = specs.iter().map(|s| s.name).collect();
                return Err(Error::at(
                    &origin.file,
                    *line,
                    format!(
                        "{}: unknown parameter `{key}`; valid parameters: {}",
                        origin.what,
                        if valid.is_empty() {
                            "none".to_string()
                        } else {
                            valid.join(", ")
                        }
                    ),
                ));
            };
            let v = spec.check(value).map_err(|msg| {
                Error::at(
                    &origin.file,
                    *line,
                    format!("{}: `{key}`: {msg}", origin.what),
                )
            })?;
            values.insert(spec.name, v);
            lines.insert(spec.name, *line);
        }
        for spec in specs {
            if values.contains_key(spec.name) {
                continue;
            }
            if let Default::Required = spec.default {
                return Err(Error::at(
                    &origin.file,
                    origin.line,
                    format!(
                        "{}: missing parameter `{}` ({})",
                        origin.what, spec.name, spec.kind
                    ),
                ));
            }
            if let Some(v) = spec.default_value() {
                values.insert(spec.name, v);
            }
        }
        Ok(Params {
            origin,
            values,
            lines,
        })
    }

    /// All defaults of `specs`, for building kinds in code (tests, benches).
    pub fn defaults(specs: &[Spec], what: &str) -> Result<Params, Error> {
        Self::validate(
            specs,
            &BTreeMap::new(),
            Origin {
                file: PathBuf::from("<defaults>"),
                line: 0,
                what: what.into(),
            },
        )
    }

    /// An error about parameter `name` (at its line when it was given).
    pub fn error(&self, name: &str, msg: impl fmt::Display) -> Error {
        let line = self.lines.get(name).copied().unwrap_or(self.origin.line);
        Error::at(
            &self.origin.file,
            line,
            format!("{}: `{name}`: {msg}", self.origin.what),
        )
    }

    /// An error about the whole table.
    pub fn entry_error(&self, msg: impl fmt::Display) -> Error {
        Error::at(
            &self.origin.file,
            self.origin.line,
            format!("{}: {msg}", self.origin.what),
        )
    }

    pub fn file(&self) -> &Path {
        &self.origin.file
    }

    /// The validated values, for provenance.
    pub fn values(&self) -> &BTreeMap<&'static str, Value> {
        &self.values
    }

    fn get(&self, name: &str) -> Option<&Value> {
        self.values.get(name)
    }

    /// An integer parameter. Panics on a name missing from the specs (a programming error).
    pub fn int(&self, name: &str) -> i64 {
        match self.get(name) {
            Some(Value::Int(i)) => *i,
            other => panic!("parameter {name} is not an integer: {other:?}"),
        }
    }

    /// A non-negative integer parameter as usize.
    pub fn usize(&self, name: &str) -> usize {
        usize::try_from(self.int(name)).expect("spec guarantees a non-negative integer")
    }

    /// A real parameter.
    pub fn float(&self, name: &str) -> f64 {
        self.opt_float(name)
            .unwrap_or_else(|| panic!("parameter {name} has no value"))
    }

    /// A real parameter with [`Default::Derived`].
    pub fn opt_float(&self, name: &str) -> Option<f64> {
        match self.get(name) {
            Some(Value::Float(x)) => Some(*x),
            None => None,
            other => panic!("parameter {name} is not a number: {other:?}"),
        }
    }

    /// An integer parameter with [`Default::Derived`].
    pub fn opt_int(&self, name: &str) -> Option<i64> {
        match self.get(name) {
            Some(Value::Int(i)) => Some(*i),
            None => None,
            other => panic!("parameter {name} is not an integer: {other:?}"),
        }
    }

    /// A text parameter with [`Default::Derived`].
    pub fn opt_str(&self, name: &str) -> Option<&str> {
        match self.get(name) {
            Some(Value::Str(s)) => Some(s),
            None => None,
            other => panic!("parameter {name} is not a string: {other:?}"),
        }
    }

    /// A boolean parameter with [`Default::Derived`].
    pub fn opt_bool(&self, name: &str) -> Option<bool> {
        match self.get(name) {
            Some(Value::Bool(b)) => Some(*b),
            None => None,
            other => panic!("parameter {name} is not a boolean: {other:?}"),
        }
    }

    /// A choice or text parameter.
    pub fn str(&self, name: &str) -> &str {
        match self.get(name) {
            Some(Value::Str(s)) => s,
            other => panic!("parameter {name} is not a string: {other:?}"),
        }
    }

    /// A boolean parameter.
    pub fn bool(&self, name: &str) -> bool {
        match self.get(name) {
            Some(Value::Bool(b)) => *b,
            other => panic!("parameter {name} is not a boolean: {other:?}"),
        }
    }
}

/// Shorthand for a probability parameter.
pub const fn probability(name: &'static str, default: f64, help: &'static str) -> Spec {
    Spec {
        name,
        kind: Kind::Float { min: 0.0, max: 1.0 },
        default: Default::Float(default),
        help,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPECS: &[Spec] = &[
        Spec {
            name: "population",
            kind: Kind::Int {
                min: 2,
                max: i64::MAX,
            },
            default: Default::Int(200),
            help: "individuals",
        },
        probability("pc", 0.9, "crossover"),
        Spec {
            name: "mode",
            kind: Kind::Choice(&["a", "b"]),
            default: Default::Required,
            help: "mode",
        },
    ];

    fn origin() -> Origin {
        Origin {
            file: "s.toml".into(),
            line: 3,
            what: "optimizer \"X\"".into(),
        }
    }

    fn given(pairs: &[(&str, toml::Value, usize)]) -> BTreeMap<String, (toml::Value, usize)> {
        pairs
            .iter()
            .map(|(k, v, l)| (k.to_string(), (v.clone(), *l)))
            .collect()
    }

    #[test]
    fn defaults_are_filled_and_values_checked() {
        let p = Params::validate(
            SPECS,
            &given(&[("mode", toml::Value::String("b".into()), 4)]),
            origin(),
        )
        .unwrap();
        assert_eq!(p.usize("population"), 200);
        assert_eq!(p.float("pc"), 0.9);
        assert_eq!(p.str("mode"), "b");
    }

    #[test]
    fn errors_name_file_line_and_key() {
        let e = Params::validate(
            SPECS,
            &given(&[
                ("mode", toml::Value::String("a".into()), 4),
                ("pc", toml::Value::Float(1.5), 7),
            ]),
            origin(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("s.toml:7:"), "{e}");
        assert!(e.contains("`pc`") && e.contains("[0, 1]"), "{e}");

        let e = Params::validate(SPECS, &given(&[]), origin())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("s.toml:3:") && e.contains("missing parameter `mode`"),
            "{e}"
        );

        let e = Params::validate(
            SPECS,
            &given(&[("popsize", toml::Value::Integer(3), 5)]),
            origin(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("unknown parameter `popsize`"), "{e}");
        assert!(e.contains("population, pc, mode"), "{e}");

        let e = Params::validate(
            SPECS,
            &given(&[
                ("mode", toml::Value::String("a".into()), 4),
                ("population", toml::Value::Float(2.5), 6),
            ]),
            origin(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("expected integer >= 2, found float"), "{e}");
    }
}
