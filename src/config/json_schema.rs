//! The config's JSON Schema (`tsim schema`), derived from the same types serde reads, so
//! it cannot drift from what tsim accepts: every key, its type, default and doc comment.
//! Editors use it to complete and check keys (docs/config.md, "Editor support").
//! Value ranges and cross-references (a group that exists, a material in the library)
//! stay with `validate`, which reports them at their line.

use super::CaseConfig;

/// Where the schema is published in the repository (`# yaml-language-server: $schema=`).
pub const SCHEMA_FILE: &str = "docs/tsim.schema.json";

/// The JSON Schema (draft 2020-12) of a config file, pretty-printed, ending in a newline.
pub fn json_schema() -> String {
    let mut schema = schemars::schema_for!(CaseConfig);
    schema.insert("title".into(), "tsim config".into());
    schema.insert(
        "description".into(),
        "A tsim case or sweep config (YAML). Every key: docs/config.md".into(),
    );
    let mut value = schema.to_value();
    let objects: Vec<String> = (value.get("$defs").and_then(|d| d.as_object()).into_iter().flatten())
        .filter(|(_, def)| def.get("type").and_then(|t| t.as_str()) == Some("object"))
        .map(|(name, _)| format!("#/$defs/{name}"))
        .collect();
    branch_optional_sections(&mut value, &objects);
    let mut text = serde_json::to_string_pretty(&value).expect("a schema is plain JSON");
    text.push('\n');
    text
}

/// Rewrites every optional section, `anyOf: [{$ref: <an object>}, {type: null}]` (an
/// `Option` of a struct), as `if: {type: object}, then: {$ref}, else: {type: null}`. Both
/// accept the same values; but where a section has one wrong key, a validator can only
/// say that neither branch of `anyOf` matched, and an editor underlines the whole section,
/// while `if` picks the object branch and its error names the key.
fn branch_optional_sections(v: &mut serde_json::Value, objects: &[String]) {
    use serde_json::{json, Value};
    match v {
        Value::Object(map) => {
            let section = match map.get("anyOf").and_then(Value::as_array).map(Vec::as_slice) {
                Some([first, null]) if *null == json!({"type": "null"}) => first
                    .get("$ref")
                    .and_then(Value::as_str)
                    .filter(|r| objects.iter().any(|o| o == r))
                    .map(|_| first.clone()),
                _ => None,
            };
            if let Some(object) = section {
                map.remove("anyOf");
                map.insert("if".into(), json!({"type": "object"}));
                map.insert("then".into(), object);
                map.insert("else".into(), json!({"type": "null"}));
            }
            map.values_mut().for_each(|x| branch_optional_sections(x, objects));
        }
        Value::Array(items) => items.iter_mut().for_each(|x| branch_optional_sections(x, objects)),
        _ => {}
    }
}
