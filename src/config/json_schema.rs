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
    let mut text = serde_json::to_string_pretty(&schema).expect("a schema is plain JSON");
    text.push('\n');
    text
}
