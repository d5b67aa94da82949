//! JSON numbers that may be infinite or NaN. JSON has neither, and serde_json writes both
//! as `null`, which loses the sign of an infinity and fails to read back as a number.
//! Stored results therefore write finite values as numbers and the others as the strings
//! `"inf"`, `"-inf"` and `"nan"`; readers accept those, numbers, and `null` as +inf (files
//! written before this encoding, where `null` only ever stood for a best-so-far of +inf).
//!
//! Use with `#[serde(with = "crate::base::json_float::one")]` (an `f64`), `::many`
//! (`Vec<f64>`) or `::pairs` (`Vec<(u64, f64)>`).

use serde::de::{Deserializer, Error, Visitor};
use serde::{Deserialize, Serialize, Serializer};

/// An `f64` in the encoding above.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JsonF64(pub f64);

impl Serialize for JsonF64 {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let v = self.0;
        if v.is_finite() {
            s.serialize_f64(v)
        } else if v.is_nan() {
            s.serialize_str("nan")
        } else if v > 0.0 {
            s.serialize_str("inf")
        } else {
            s.serialize_str("-inf")
        }
    }
}

impl<'de> Deserialize<'de> for JsonF64 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = JsonF64;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str(r#"a number, "inf", "-inf", "nan" or null"#)
            }
            fn visit_f64<E: Error>(self, v: f64) -> Result<JsonF64, E> {
                Ok(JsonF64(v))
            }
            fn visit_i64<E: Error>(self, v: i64) -> Result<JsonF64, E> {
                Ok(JsonF64(v as f64))
            }
            fn visit_u64<E: Error>(self, v: u64) -> Result<JsonF64, E> {
                Ok(JsonF64(v as f64))
            }
            fn visit_str<E: Error>(self, v: &str) -> Result<JsonF64, E> {
                match v {
                    "inf" => Ok(JsonF64(f64::INFINITY)),
                    "-inf" => Ok(JsonF64(f64::NEG_INFINITY)),
                    "nan" => Ok(JsonF64(f64::NAN)),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
            fn visit_unit<E: Error>(self) -> Result<JsonF64, E> {
                Ok(JsonF64(f64::INFINITY))
            }
            fn visit_none<E: Error>(self) -> Result<JsonF64, E> {
                Ok(JsonF64(f64::INFINITY))
            }
            fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<JsonF64, D::Error> {
                JsonF64::deserialize(d)
            }
        }
        d.deserialize_any(V)
    }
}

/// One `f64`.
pub mod one {
    use super::*;
    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        JsonF64(*v).serialize(s)
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(JsonF64::deserialize(d)?.0)
    }
}

/// A `Vec<f64>`.
pub mod many {
    use super::*;
    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.iter().map(|&x| JsonF64(x)))
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Ok(Vec::<JsonF64>::deserialize(d)?
            .into_iter()
            .map(|v| v.0)
            .collect())
    }
}

/// A `Vec<(u64, f64)>` of (evaluation, value) pairs.
pub mod pairs {
    use super::*;
    pub fn serialize<S: Serializer>(v: &[(u64, f64)], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.iter().map(|&(e, x)| (e, JsonF64(x))))
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<(u64, f64)>, D::Error> {
        Ok(Vec::<(u64, JsonF64)>::deserialize(d)?
            .into_iter()
            .map(|(e, v)| (e, v.0))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct T {
        #[serde(with = "one")]
        a: f64,
        #[serde(with = "many")]
        b: Vec<f64>,
        #[serde(with = "pairs")]
        c: Vec<(u64, f64)>,
    }

    #[test]
    fn infinities_and_nan_round_trip_and_old_null_reads_as_inf() {
        let t = T {
            a: f64::NEG_INFINITY,
            b: vec![1.5, f64::INFINITY, f64::NEG_INFINITY, 0.1 + 0.2],
            c: vec![(1, f64::INFINITY), (2, -1e308), (3, f64::NEG_INFINITY)],
        };
        let s = serde_json::to_string(&t).unwrap();
        assert!(!s.contains("null"), "{s}");
        assert_eq!(serde_json::from_str::<T>(&s).unwrap(), t);
        let nan: T = serde_json::from_str(r#"{"a":"nan","b":[],"c":[]}"#).unwrap();
        assert!(nan.a.is_nan());
        let old: T = serde_json::from_str(r#"{"a":null,"b":[null,2],"c":[[1,null]]}"#).unwrap();
        assert_eq!(old.a, f64::INFINITY);
        assert_eq!(old.b, [f64::INFINITY, 2.0]);
        assert_eq!(old.c, [(1, f64::INFINITY)]);
        assert!(serde_json::from_str::<T>(r#"{"a":"x","b":[],"c":[]}"#).is_err());
    }
}
