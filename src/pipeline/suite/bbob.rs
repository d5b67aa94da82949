//! The `[bbob]` suite section: COCO's BBOB campaign (functions x dimensions, each over a
//! list of instances) written in a few lines instead of one `[[objective]]` per
//! (function, dimension), expanded into exactly those entries before validation, so they
//! are checked, run and reported like written ones.
//!
//! ```toml
//! [bbob]
//! functions = "1-24"          # optional, default all 24
//! dimensions = [2, 5, 10, 20]
//! instances = "1-15"          # optional, default "1-15" (COCO's current campaign)
//! budget_per_dim = 1000       # optional, as are budget, targets, stop_at, optimizers
//! ```
//!
//! Objective `bbob-f07-d10` is function 7 in 10 dimensions; its trial t runs instance
//! `instances[t mod n]`.

use super::instances::parse_list;
use super::text::{Fields, SuiteText};
use crate::base::error::Result;
use toml::{Spanned, Value};

/// The objective kind the section expands to.
pub const KIND: &str = "bbob";
/// COCO's function count.
pub const FUNCTIONS: usize = 24;
/// The instance list when the section names none.
pub const DEFAULT_INSTANCES: &str = "1-15";
/// Keys copied unchanged into every expanded entry.
const PASSED_ON: &[&str] = &[
    "budget",
    "budget_per_dim",
    "targets",
    "stop_at",
    "optimizers",
];

/// The id of function `f` in `dim` dimensions.
pub fn objective_id(f: usize, dim: usize) -> String {
    format!("bbob-f{f:02}-d{dim:02}")
}

/// The `[[objective]]` entries of a `[bbob]` section, dimension-major, each spanned where
/// its values stand in the section (so messages point into it).
pub fn expand(st: &SuiteText<'_>, section: &Spanned<Fields>) -> Result<Vec<Spanned<Fields>>> {
    let mut fields = section.get_ref().clone();
    let head = section.span();
    let line = st.line(head.start);
    let list = |fields: &mut Fields, key: &str| -> Result<Option<(Vec<usize>, Spanned<Value>)>> {
        match fields.remove(key) {
            None => Ok(None),
            Some(v) => parse_list(v.get_ref(), &format!("[bbob] {key}"))
                .map(|l| Some((l, v.clone())))
                .map_err(|m| st.at(v.span().start, m)),
        }
    };
    let functions = match list(&mut fields, "functions")? {
        Some((l, v)) => {
            if let Some(f) = l.iter().find(|&&f| f > FUNCTIONS) {
                return Err(st.at(
                    v.span().start,
                    format!("[bbob] `functions` names {f}: BBOB has functions 1 to {FUNCTIONS}"),
                ));
            }
            l
        }
        None => (1..=FUNCTIONS).collect(),
    };
    let Some((dims, dims_at)) = list(&mut fields, "dimensions")? else {
        return Err(st.on(
            line,
            "[bbob] without `dimensions`: name them, e.g. dimensions = [2, 5, 10, 20]",
        ));
    };
    let instances = match fields.remove("instances") {
        Some(v) => v,
        None => Spanned::new(head.clone(), Value::String(DEFAULT_INSTANCES.into())),
    };
    parse_list(instances.get_ref(), "[bbob] instances")
        .map_err(|m| st.at(instances.span().start, m))?;
    let passed: Vec<(&str, Spanned<Value>)> = PASSED_ON
        .iter()
        .filter_map(|&k| fields.remove(k).map(|v| (k, v)))
        .collect();
    if let Some((k, v)) = fields.iter().next() {
        return Err(st.at(
            v.span().start,
            format!(
                "[bbob]: unknown key `{k}`; valid keys: functions, dimensions, instances, {}",
                PASSED_ON.join(", ")
            ),
        ));
    }
    let at = |v: Value| Spanned::new(dims_at.span(), v);
    let mut out = Vec::new();
    for &dim in &dims {
        for &f in &functions {
            let mut e = Fields::new();
            e.insert("kind".into(), at(Value::String(KIND.into())));
            e.insert("id".into(), at(Value::String(objective_id(f, dim))));
            e.insert("function".into(), at(Value::Integer(f as i64)));
            e.insert("dim".into(), at(Value::Integer(dim as i64)));
            e.insert("instances".into(), instances.clone());
            for (k, v) in &passed {
                e.insert((*k).into(), v.clone());
            }
            out.push(Spanned::new(head.clone(), e));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn expanded(text: &str) -> Result<Vec<Fields>> {
        #[derive(serde::Deserialize)]
        struct S {
            bbob: Spanned<Fields>,
        }
        let st = SuiteText::new(Path::new("s.toml"), text);
        let s: S = st.parse()?;
        Ok(expand(&st, &s.bbob)?
            .into_iter()
            .map(Spanned::into_inner)
            .collect())
    }

    #[test]
    fn the_section_expands_dimension_major_with_its_keys_passed_on() {
        let e = expanded("[bbob]\nfunctions = [3, 1]\ndimensions = [2, 10]\nbudget_per_dim = 50\n")
            .unwrap();
        let ids: Vec<&str> = e
            .iter()
            .map(|f| f["id"].get_ref().as_str().unwrap())
            .collect();
        assert_eq!(
            ids,
            [
                "bbob-f03-d02",
                "bbob-f01-d02",
                "bbob-f03-d10",
                "bbob-f01-d10"
            ]
        );
        assert_eq!(e[2]["dim"].get_ref().as_integer(), Some(10));
        assert_eq!(e[2]["function"].get_ref().as_integer(), Some(3));
        assert_eq!(e[0]["budget_per_dim"].get_ref().as_integer(), Some(50));
        assert_eq!(
            e[0]["instances"].get_ref().as_str(),
            Some(DEFAULT_INSTANCES)
        );
        let all = expanded("[bbob]\ndimensions = \"5\"\ninstances = [1, 2]\n").unwrap();
        assert_eq!(all.len(), FUNCTIONS);
        assert_eq!(all[23]["id"].get_ref().as_str(), Some("bbob-f24-d05"));
    }

    #[test]
    fn bad_sections_say_where_and_what() {
        let m = |t: &str| expanded(t).unwrap_err().to_string();
        let e = m("[bbob]\nfunctions = [1, 25]\ndimensions = [2]\n");
        assert!(
            e.contains("s.toml:2") && e.contains("functions 1 to 24"),
            "{e}"
        );
        let e = m("[bbob]\nfunctions = [1]\n");
        assert!(
            e.contains("s.toml:1") && e.contains("without `dimensions`"),
            "{e}"
        );
        let e = m("[bbob]\ndimensions = [2]\n\ndims = 3\n");
        assert!(
            e.contains("s.toml:4") && e.contains("unknown key `dims`"),
            "{e}"
        );
        let e = m("[bbob]\ndimensions = [2]\ninstances = \"0-3\"\n");
        assert!(
            e.contains("s.toml:3") && e.contains("`[bbob] instances`"),
            "{e}"
        );
    }
}
