//! YAML parse errors in plain words: where (line and column), what is wrong and a fix,
//! with the offending line quoted; no parser internals (type names such as `u64`, its
//! option names, its `--> <input>` snippets).

use crate::model::names::hint;
use serde_saphyr::{Error, MessageFormatter, UserMessageFormatter};

/// A parse error's position (1-based, when the parser knows it) and its message, the
/// offending line quoted under it with a caret.
pub struct Described {
    pub line: Option<usize>,
    pub column: Option<usize>,
    pub message: String,
}

pub fn describe(e: &Error, text: &str) -> Described {
    if let Some(described) = missing_section(e, text) {
        return described;
    }
    let location = e.location().filter(|l| l.line() > 0);
    let line = location.and_then(|l| usize::try_from(l.line()).ok());
    let column = location.and_then(|l| usize::try_from(l.column()).ok());
    let message = match e.without_snippet() {
        Error::SerdeUnknownField { field, expected, .. } => format!(
            "unknown key `{field}`{}; the keys here: {}",
            hint(field, expected.iter().copied()),
            expected.join(", ")
        ),
        Error::SerdeUnknownVariant { variant, expected, .. } => format!(
            "unknown value `{variant}`{}; one of: {}",
            hint(variant, expected.iter().copied()),
            expected.join(", ")
        ),
        Error::DuplicateMappingKey { key: Some(key), .. } => duplicate(key, line, column, text),
        Error::InvalidScalar { ty, .. } => scalar(ty, &token(text, line, column)),
        Error::SerdeInvalidType { unexpected, expected, .. } | Error::SerdeInvalidValue { unexpected, expected, .. } => {
            format!("is {unexpected}; expected {}", type_words(expected))
        }
        Error::SerdeInvalidLength { len, expected, .. } => {
            format!("has {len} item(s); expected {}", type_words(expected))
        }
        Error::SerdeMissingField { field, .. } => format!("missing key `{field}`"),
        Error::Unexpected {
            expected: "sequence start",
            ..
        } => list_expected(text, line),
        other => UserMessageFormatter.format_message(other).into_owned(),
    };
    Described {
        line,
        column,
        message: message + &quote(text, line, column),
    }
}

/// A required top-level section the config does not have: the parser notices at the end
/// of the file and points there, at whatever key comes last; it is said of the config as a
/// whole, at its first line.
fn missing_section(e: &Error, text: &str) -> Option<Described> {
    let Error::SerdeMissingField { field, .. } = e.without_snippet() else {
        return None;
    };
    let what = match *field {
        "substitution" => "the real materials that replace the members, e.g. `substitution: { strut: aluminium, cable: rubber }`",
        "model" => "the structure: `tower`, `grid`, or `nodes` and `members`",
        _ => return None,
    };
    let given = text.lines().any(|l| l.starts_with(&format!("{field}:")));
    (!given).then(|| Described {
        line: Some(1),
        column: None,
        message: format!("the config has no `{field}` section: {what} (docs/config.md)"),
    })
}

/// A Rust type name as a reader says it.
fn type_words(ty: &str) -> &str {
    match ty {
        "f64" | "f32" | "floating point" => "a number",
        "u64" | "u32" | "u16" | "u8" | "usize" => "a whole number ≥ 0",
        "i64" | "i32" | "i16" | "i8" | "isize" => "a whole number",
        "bool" | "boolean" | "a boolean" => "true or false",
        "char" => "a single character",
        "a string" | "String" => "text",
        other => other,
    }
}

/// The scalar that starts at (line, column): up to the end of its flow entry.
fn token(text: &str, line: Option<usize>, column: Option<usize>) -> String {
    let (Some(line), Some(column)) = (line, column) else {
        return String::new();
    };
    let l = text.lines().nth(line - 1).unwrap_or_default();
    let rest: String = l.chars().skip(column - 1).collect();
    rest.split([',', '}', ']', '#']).next().unwrap_or_default().trim().to_string()
}

/// A scalar that is not of its type; `a: 1 b: 2` in a flow mapping is a missing comma.
fn scalar(ty: &str, token: &str) -> String {
    let want = type_words(ty);
    if token.is_empty() {
        return format!("expected {want} here");
    }
    match token.split_once(": ") {
        Some((before, _)) if before.contains(' ') => {
            let (value, key) = before.rsplit_once(' ').unwrap_or((before, ""));
            format!(
                "`{token}` is not {want}: a comma is missing between `{}` and `{key}:`? (entries of a flow mapping are separated by commas: `{{ a: 1, b: 2 }}`)",
                value.trim()
            )
        }
        _ => format!("`{token}` is not {want}"),
    }
}

/// A single value where a list is expected (`gravity: -9.81`): the key of the line, and
/// the list's form.
fn list_expected(text: &str, line: Option<usize>) -> String {
    let key = line
        .and_then(|l| text.lines().nth(l - 1))
        .and_then(|l| l.trim_start().trim_start_matches("- ").split_once(':'))
        .map(|(key, _)| key.trim())
        .filter(|key| !key.is_empty() && !key.contains(['{', '[', ' ']));
    let what = key.map_or_else(|| "a list".to_string(), |key| format!("`{key}` takes a list"));
    format!("{what} here, not a single value: its items in brackets, `[a, b, c]` (a vector: `[x, y, z]`)")
}

/// A key given twice in one mapping: the line of its first use too.
fn duplicate(key: &str, line: Option<usize>, column: Option<usize>, text: &str) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let first = line.zip(column).and_then(|(line, column)| {
        let indent = |l: &str| l.len() - l.trim_start().len();
        let this = lines.get(line - 1)?;
        let pattern = format!("{key}:");
        // Earlier on the same line (a flow mapping).
        let before: String = this.chars().take(column - 1).collect();
        if before.contains(&pattern) {
            return Some(line);
        }
        // Earlier lines of the same block mapping: same indent, until a line indented less.
        let at = column - 1;
        (0..line - 1).rev().map(|k| (k, lines[k])).find_map(|(k, l)| {
            let content = !l.trim().is_empty() && !l.trim_start().starts_with('#');
            let key_at = l.get(at..).is_some_and(|s| s.starts_with(&pattern));
            match () {
                _ if content && key_at && indent(l) <= at => Some(Some(k + 1)),
                _ if content && indent(l) < at => Some(None),
                _ => None,
            }
        })?
    });
    match (first, line) {
        (Some(a), Some(b)) if a != b => format!("key `{key}` appears twice (lines {a} and {b}); keep one"),
        _ => format!("key `{key}` appears twice in one mapping; keep one"),
    }
}

/// The line at `line`, numbered, with a caret under `column`.
fn quote(text: &str, line: Option<usize>, column: Option<usize>) -> String {
    let (Some(line), Some(column)) = (line, column) else {
        return String::new();
    };
    let Some(l) = text.lines().nth(line - 1) else {
        return String::new();
    };
    let number = line.to_string();
    format!("\n  {number} | {l}\n  {} | {}^", " ".repeat(number.len()), " ".repeat(column - 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicates_name_both_lines() {
        let text = "a: 1\nb:\n  c: 1\n  d: 2\n  c: 3\n";
        assert_eq!(
            duplicate("c", Some(5), Some(3), text),
            "key `c` appears twice (lines 3 and 5); keep one"
        );
        assert!(duplicate("x", Some(1), Some(9), "m: { x: 1, x: 2 }").contains("appears twice"));
    }

    #[test]
    fn a_missing_comma_is_named() {
        let m = scalar("u64", "3 stages: 1");
        assert!(m.contains("comma is missing between `3` and `stages:`"), "{m}");
        assert_eq!(scalar("f64", "abc"), "`abc` is not a number");
    }
}
