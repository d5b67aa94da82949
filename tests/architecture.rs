//! The declared layering of `src/`: floors from the ground up, a module importing only its
//! own files and the floors below. A new module must be given a floor here; an import that
//! runs upward or sideways fails with the file and line. (`scripts/import_graph.py` draws
//! the same graph.)

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Floors from the ground up; modules on one floor do not import each other.
const FLOORS: &[&[&str]] = &[
    &["base"],
    &["data"],
    &["physics"],
    &["objective"],
    &["harness"],
    &["optimizer"],
    &["stats"],
    &["registry"],
    &["render"],
    &["pipeline"],
    &["speed"],
    &["report"],
    &["diagnose", "control"],
    &["cmd"],
];

fn floor(module: &str) -> Option<usize> {
    FLOORS.iter().position(|f| f.contains(&module))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The code of a line without its comment (doc links name modules they do not import).
fn code(line: &str) -> &str {
    line.find("//").map_or(line, |i| &line[..i])
}

/// The top-level modules a line names as `crate::NAME`.
fn imports(line: &str) -> Vec<&str> {
    code(line)
        .match_indices("crate::")
        .filter(|(i, _)| {
            // `crate::` itself, not the tail of another identifier.
            !line[..*i]
                .chars()
                .next_back()
                .is_some_and(|c| c.is_alphanumeric() || c == '_')
        })
        .map(|(i, _)| {
            let rest = &line[i + "crate::".len()..];
            let end = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            &rest[..end]
        })
        .filter(|m| !m.is_empty())
        .collect()
}

#[test]
fn no_module_imports_a_floor_above_or_beside_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut top = BTreeSet::new();
    for e in std::fs::read_dir(&src).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if p.is_dir() {
            top.insert(name);
        } else {
            assert!(
                name == "main.rs" || name == "lib.rs",
                "src/{name}: the top of src/ holds only main.rs, lib.rs and module folders"
            );
        }
    }
    for m in &top {
        assert!(
            floor(m).is_some(),
            "src/{m}/ has no floor: add it to FLOORS in tests/architecture.rs"
        );
    }
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut wrong = Vec::new();
    let mut seen = 0;
    for f in &files {
        let rel = f.strip_prefix(&src).unwrap();
        let Some(module) = rel
            .components()
            .next()
            .filter(|_| rel.components().count() > 1)
        else {
            continue; // main.rs, lib.rs
        };
        let module = module.as_os_str().to_string_lossy();
        let here = floor(&module).unwrap();
        for (n, line) in std::fs::read_to_string(f).unwrap().lines().enumerate() {
            for to in imports(line) {
                seen += 1;
                if to == module || !top.contains(to) {
                    continue;
                }
                let there = floor(to).unwrap();
                if there >= here {
                    wrong.push(format!(
                        "src/{}:{}: `{module}` (floor {here}) imports `{to}` (floor {there})",
                        rel.display(),
                        n + 1
                    ));
                }
            }
        }
    }
    assert!(seen > 100, "the scan found only {seen} crate:: paths");
    assert!(
        wrong.is_empty(),
        "imports against the layering:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn the_scan_reads_code_not_comments() {
    assert_eq!(
        imports("use crate::base::x; let y = crate::stats::f(); // crate::cmd"),
        ["base", "stats"]
    );
    assert!(imports("/// see [`crate::report`]").is_empty());
    assert!(imports("let a = mycrate::x;").is_empty());
}
