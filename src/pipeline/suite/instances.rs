//! Instance lists (`instances = "1-15"` or `[1, 2, 5]`) and budgets proportional to the
//! dimension (`budget_per_dim`): the two keys a benchmark suite such as COCO's sets per
//! function, shared by `[[objective]]` entries and the `[bbob]` section.

/// Most instances one list may name: COCO's largest published campaigns use 15, and every
/// instance is a built objective held for the run.
pub const MAX_INSTANCES: usize = 1000;

/// Parses an instance list: a string of numbers and ranges (`"1-15"`, `"1-5, 7, 9-10"`) or
/// an array of integers, each >= 1, no number twice. `key` names the field in messages.
pub fn parse_list(v: &toml::Value, key: &str) -> Result<Vec<usize>, String> {
    let expected = || {
        format!(
            "`{key}`: expected numbers >= 1 as a range string (\"1-15\", \"1-5, 7\") or an array of integers ([1, 2, 3])"
        )
    };
    let mut out = Vec::new();
    match v {
        toml::Value::String(s) => {
            for part in s.split(',').map(str::trim) {
                let (a, b) = part.split_once('-').unwrap_or((part, part));
                let (a, b) = match (a.trim().parse::<usize>(), b.trim().parse::<usize>()) {
                    (Ok(a), Ok(b)) if a >= 1 && a <= b => (a, b),
                    _ => return Err(format!("{} (`{part}` is not one)", expected())),
                };
                if b - a >= MAX_INSTANCES {
                    return Err(too_many(key));
                }
                out.extend(a..=b);
            }
        }
        toml::Value::Array(a) => {
            for x in a {
                match x.as_integer() {
                    Some(i) if i >= 1 => out.push(i as usize),
                    _ => return Err(format!("{} (found {x})", expected())),
                }
            }
        }
        other => return Err(format!("{}, found {}", expected(), other.type_str())),
    }
    if out.is_empty() {
        return Err(format!("{} (the list is empty)", expected()));
    }
    if out.len() > MAX_INSTANCES {
        return Err(too_many(key));
    }
    let mut seen = std::collections::BTreeSet::new();
    if let Some(d) = out.iter().find(|&&i| !seen.insert(i)) {
        return Err(format!("`{key}` names {d} twice; list each number once"));
    }
    Ok(out)
}

fn too_many(key: &str) -> String {
    format!("`{key}`: more than {MAX_INSTANCES} numbers; list fewer")
}

/// A key's value and the line it stands on, where it is set.
pub type Given = Option<(i64, usize)>;
/// The `budget` and `budget_per_dim` of one level (an entry or the suite).
pub type BudgetKeys = (Given, Given);

/// The budget of an objective of `dim` dimensions: its own `budget`, else its own
/// `budget_per_dim` x `dim`, else the suite's the same way; the suite's two are given
/// as (value, line) pairs where set.
pub fn budget(own: BudgetKeys, suite: BudgetKeys, dim: usize) -> Result<u64, (usize, String)> {
    for (budget, per_dim) in [own, suite] {
        if let (Some((_, l)), Some(_)) = (budget, per_dim) {
            return Err((
                l,
                "both `budget` and `budget_per_dim` are set; give one of them".into(),
            ));
        }
        if let Some((b, l)) = budget {
            return positive(b, "budget").map_err(|m| (l, m));
        }
        if let Some((k, l)) = per_dim {
            let k = positive(k, "budget_per_dim").map_err(|m| (l, m))?;
            return k.checked_mul(dim as u64).ok_or_else(|| {
                (
                    l,
                    format!("`budget_per_dim` = {k} x dim {dim} overflows; give a smaller one"),
                )
            });
        }
    }
    Err((
        0,
        "no budget: set `budget` (evaluations per trial) or `budget_per_dim` (evaluations per trial and dimension) at the top of the suite or in the entry".into(),
    ))
}

fn positive(b: i64, key: &str) -> Result<u64, String> {
    if b < 1 {
        Err(format!(
            "`{key}` = {b}: expected a number of evaluations >= 1"
        ))
    } else {
        Ok(b as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn list(text: &str) -> Result<Vec<usize>, String> {
        let v: toml::Table = toml::from_str(&format!("x = {text}")).unwrap();
        parse_list(&v["x"], "instances")
    }

    #[test]
    fn lists_take_ranges_and_arrays_and_refuse_the_rest() {
        assert_eq!(list("\"1-15\"").unwrap(), (1..=15).collect::<Vec<_>>());
        assert_eq!(list("\"1-3, 7 ,9-10\"").unwrap(), [1, 2, 3, 7, 9, 10]);
        assert_eq!(list("[4, 2]").unwrap(), [4, 2]);
        assert_eq!(list("\"5\"").unwrap(), [5]);
        for bad in [
            "\"0-3\"",
            "\"3-1\"",
            "\"a\"",
            "[0]",
            "[1.5]",
            "[]",
            "2",
            "\"1-2000\"",
        ] {
            let m = list(bad).unwrap_err();
            assert!(m.contains("`instances`"), "{bad}: {m}");
        }
        assert!(list("\"1-3, 2\"").unwrap_err().contains("names 2 twice"));
    }

    #[test]
    fn budgets_come_from_the_entry_first_then_the_suite_per_dimension_or_not() {
        let none = (None, None);
        assert_eq!(
            budget((Some((50, 3)), None), (Some((9, 1)), None), 5),
            Ok(50)
        );
        assert_eq!(
            budget((None, Some((100, 3))), (Some((9, 1)), None), 5),
            Ok(500)
        );
        assert_eq!(budget(none, (None, Some((20, 1))), 10), Ok(200));
        assert_eq!(budget(none, (Some((7, 1)), None), 10), Ok(7));
        let (line, m) = budget((Some((1, 4)), Some((2, 5))), none, 2).unwrap_err();
        assert!(line == 4 && m.contains("give one"), "{line} {m}");
        let (line, m) = budget(none, (None, Some((0, 2))), 2).unwrap_err();
        assert!(line == 2 && m.contains("`budget_per_dim` = 0"), "{m}");
        assert!(budget(none, none, 2).unwrap_err().1.contains("no budget"));
    }
}
