//! The layering of ARCHITECTURE.md ("What each room may touch") as a test: every
//! `crate::<room>` path in a module's code (comments and `#[cfg(test)]` modules left out)
//! must be an import the table allows. The crate boundary already keeps tsim-core from
//! the config, the files and the runner; this keeps the rooms inside each crate in order.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Each room and the rooms it may import: ARCHITECTURE.md's table.
const ALLOWED: &[(&str, &[&str])] = &[
    ("main", &["cli"]),
    ("cli", &["run", "config"]),
    ("run", &["pipeline", "output", "config", "record", "model"]),
    ("output", &["config", "record", "model", "contact"]),
    (
        "pipeline",
        &["config", "stage", "structure", "record", "model", "rigidity", "dynamics", "error"],
    ),
    (
        "config",
        &[
            "stage",
            "dynamics",
            "solve",
            "law",
            "model",
            "record",
            "contact",
            "structure",
            "error",
        ],
    ),
    (
        "stage",
        &[
            "structure",
            "record",
            "dynamics",
            "rigidity",
            "tsm",
            "solve",
            "law",
            "model",
            "error",
        ],
    ),
    ("error", &["record", "solve", "model"]),
    ("record", &["dynamics", "rigidity", "contact", "model"]),
    ("structure", &["tsm", "contact", "model"]),
    ("dynamics", &["tsm", "solve"]),
    ("rigidity", &["tsm", "solve", "model"]),
    ("tsm", &["law", "model", "solve", "contact"]),
    ("contact", &["model", "solve"]),
    ("law", &[]),
    ("model", &[]),
    ("solve", &[]),
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The rooms a file's code names as `crate::<room>` (or `tsim_core::<room>`), up to its
/// first `#[cfg(test)]`, comments removed.
fn imports(text: &str) -> BTreeSet<String> {
    let mut rooms = BTreeSet::new();
    for line in text.lines().take_while(|l| !l.trim_start().starts_with("#[cfg(test)]")) {
        let code = line.split("//").next().unwrap();
        for prefix in ["crate::", "tsim_core::", "tsim::"] {
            for (at, _) in code.match_indices(prefix) {
                if code[..at].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_') {
                    continue; // `tsim::` inside `my_tsim::`
                }
                rooms.extend(heads(&code[at + prefix.len()..]));
            }
        }
    }
    rooms
}

/// The first path segments after `crate::`: one (`law::x`), or each of a group
/// (`{law::x, tsm::{a, b}}`); only module names (lower case) count.
fn heads(rest: &str) -> Vec<String> {
    let ident = |s: &str| -> String {
        s.trim_start()
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let Some(group) = rest.strip_prefix('{') else {
        return vec![ident(rest)]
            .into_iter()
            .filter(|r| r.starts_with(|c: char| c.is_ascii_lowercase()))
            .collect();
    };
    let (mut depth, mut start, mut out) = (0, 0, Vec::new());
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => {
                out.push(ident(&group[start..i]));
                break;
            }
            '}' => depth -= 1,
            ',' if depth == 0 => {
                out.push(ident(&group[start..i]));
                start = i + 1;
            }
            _ => {}
        }
    }
    out.retain(|r| r.starts_with(|c: char| c.is_ascii_lowercase()));
    out
}

#[test]
fn every_import_runs_down_the_table() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let allowed: BTreeMap<&str, &[&str]> = ALLOWED.iter().copied().collect();
    let mut files = Vec::new();
    for dir in ["src", "crates/tsim-core/src"] {
        rust_files(&root.join(dir), &mut files);
    }
    let mut wrong = Vec::new();
    let mut seen = 0;
    for file in &files {
        let rel = file.strip_prefix(root).unwrap();
        let inner = rel
            .strip_prefix("src")
            .or_else(|_| rel.strip_prefix("crates/tsim-core/src"))
            .unwrap();
        let first = inner.components().next().unwrap().as_os_str().to_str().unwrap();
        let room = first.trim_end_matches(".rs");
        if room == "lib" {
            continue; // the crate roots declare and re-export the rooms
        }
        if file.file_name().is_some_and(|n| n == "tests.rs") {
            // A `tests.rs` is the `#[cfg(test)] mod tests;` of its folder's module, left
            // out like an inline test module; the parent must declare it so.
            let parent = std::fs::read_to_string(file.with_file_name("mod.rs")).unwrap();
            assert!(
                parent.contains("#[cfg(test)]\npub(super) mod tests;") || parent.contains("#[cfg(test)]\nmod tests;"),
                "{}: its mod.rs does not declare it under #[cfg(test)]",
                rel.display()
            );
            continue;
        }
        let may = allowed
            .get(room)
            .unwrap_or_else(|| panic!("{}: room `{room}` is not in the table", rel.display()));
        for import in imports(&std::fs::read_to_string(file).unwrap()) {
            seen += 1;
            if import != room && !may.contains(&import.as_str()) {
                wrong.push(format!("{}: `{room}` imports `{import}`", rel.display()));
            }
        }
    }
    // A scan that found no imports at all would pass vacuously.
    assert!(seen > 100, "only {seen} imports found: is the scan reading the sources?");
    assert!(
        wrong.is_empty(),
        "imports the table (ARCHITECTURE.md) does not allow:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn the_scan_sees_an_import_and_skips_comments_and_tests() {
    let text = "use crate::solve::Newton;\n// crate::output in a comment\nfn f() { crate::law::x(); }\n\
                use crate::{tsm::{A, B}, model::Model, Error};\n#[cfg(test)]\nmod tests { use crate::config; }\n";
    let found: Vec<String> = imports(text).into_iter().collect();
    assert_eq!(found, ["law", "model", "solve", "tsm"]);
}

/// Longest a function may be, from its `fn` line to its closing brace (issue 28): one
/// longer than this does more than one thing, and is split where a phase ends.
const MAX_FN_LINES: usize = 80;

/// The name in a line that opens a function (`pub(crate) const fn name`), if it does.
fn fn_name(line: &str) -> Option<String> {
    let mut rest = line.trim_start();
    if let Some(r) = rest.strip_prefix("pub") {
        rest = match r.strip_prefix('(') {
            Some(r) => r.split_once(')')?.1,
            None => r,
        }
        .trim_start();
    }
    for qualifier in ["const ", "unsafe ", "async ", "extern \"C\" "] {
        rest = rest.strip_prefix(qualifier).unwrap_or(rest);
    }
    let name: String = rest
        .strip_prefix("fn ")?
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    (!name.is_empty()).then_some(name)
}

/// A line's code without its comment and the contents of its string and char literals,
/// whose braces do not count.
fn code_of(line: &str) -> String {
    let chars: Vec<char> = line.chars().collect();
    let (mut out, mut i, mut in_string) = (String::new(), 0, false);
    while i < chars.len() {
        let c = chars[i];
        match (in_string, c) {
            (true, '\\') => i += 1,
            (true, '"') | (false, '"') => in_string = !in_string,
            (true, _) => {}
            (false, '/') if chars.get(i + 1) == Some(&'/') => break,
            // '{' or '\n' (not a lifetime such as 'a)
            (false, '\'') if chars.get(i + 2) == Some(&'\'') => i += 2,
            (false, '\'') if chars.get(i + 1) == Some(&'\\') => {
                i += chars[i + 2..].iter().position(|&c| c == '\'').map_or(0, |p| p + 2);
            }
            (false, _) => out.push(c),
        }
        i += 1;
    }
    out
}

/// (name, first line, lines) of each function of `text` longer than `max` lines.
fn long_functions(text: &str, max: usize) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let Some(name) = fn_name(line) else { continue };
        let (mut depth, mut opened, mut end) = (0_i64, false, i);
        for (j, l) in lines.iter().enumerate().skip(i) {
            let code = code_of(l);
            for c in code.chars() {
                match c {
                    '{' => (depth, opened) = (depth + 1, true),
                    '}' => depth -= 1,
                    _ => {}
                }
            }
            end = j;
            // Closed, or a declaration without a body (a trait's method, an extern fn).
            if (opened && depth == 0) || (!opened && code.trim_end().ends_with(';')) {
                break;
            }
        }
        if end - i + 1 > max {
            out.push((name, i + 1, end - i + 1));
        }
    }
    out
}

#[test]
fn no_function_is_over_80_lines() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for dir in ["src", "crates/tsim-core/src", "examples", "tests", "benches"] {
        if root.join(dir).is_dir() {
            rust_files(&root.join(dir), &mut files);
        }
    }
    assert!(
        files.len() > 50,
        "only {} files found: is the scan reading the sources?",
        files.len()
    );
    let mut long = Vec::new();
    for file in &files {
        for (name, line, n) in long_functions(&std::fs::read_to_string(file).unwrap(), MAX_FN_LINES) {
            long.push(format!("{}:{line} {name}: {n} lines", file.strip_prefix(root).unwrap().display()));
        }
    }
    assert!(long.is_empty(), "functions over {MAX_FN_LINES} lines:\n{}", long.join("\n"));
}

#[test]
fn the_length_scan_counts_to_the_closing_brace() {
    let body = "    let s = \"}\"; let c = '}'; // }\n".repeat(3);
    let text = format!("pub(crate) fn f<'a>(x: &'a str) {{\n{body}}}\nfn g();\nconst fn h() {{ }}\n");
    assert_eq!(long_functions(&text, 4), [("f".to_string(), 1, 5)]);
    assert!(long_functions(&text, 5).is_empty());
}
