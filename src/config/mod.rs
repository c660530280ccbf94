//! The YAML case configuration: schema, defaults, the material library and validation.
//! Every key is documented in `docs/config.md`; unknown keys are errors (with line and
//! column from the YAML parser, which stops at the first); out-of-range values name the
//! field and the range, and all of them are reported, each at its line.

mod build;
mod contact;
mod input;
mod json_schema;
mod kinds;
mod limits;
mod loading;
mod locate;
mod materials;
mod plan;
mod schema;
mod sequence;
mod syntax;
mod tables;
mod validate;

pub use contact::{ContactRadiusSpec, ContactSpec, GroundSpec};
pub use input::{excerpt, read_input, MAX_INPUT_BYTES};
pub use json_schema::{json_schema, SCHEMA_FILE};
pub use kinds::{HoldSpec, RestChangeSpec};
pub use limits::{bytes_text, Estimate, LimitSpec, Limits, Part, MAX_MEMORY_GB, MAX_OUTPUT_GB, MAX_STEPS};
pub use loading::*;
pub use materials::{library, LawSpec, MaterialSpec};
pub use schema::*;
pub use tables::{parse_table, table_csv, SharedTables, TableError, TableFiles, KEPT_TABLES};
pub use validate::{ConfigError, FieldError, ValueError};

/// Line of a dotted field path in the YAML text (see `locate`).
pub fn locate_line(text: &str, field: &str) -> Option<usize> {
    locate::line_of(text, field)
}

/// Parses one case configuration without the value checks of `validate`. `origin` names
/// the file in errors.
pub fn parse(text: &str, origin: &str) -> Result<CaseConfig, ConfigError> {
    let cfg = serde_saphyr::from_str(text).map_err(|e| {
        let syntax::Described { line, column, message } = syntax::describe(&e, text);
        ConfigError::Syntax {
            file: origin.to_string(),
            line,
            column,
            message,
        }
    })?;
    match non_finite_literal(text) {
        Some((line, literal)) => Err(ConfigError::Values(vec![ValueError {
            file: origin.to_string(),
            line: Some(line),
            field: literal.to_string(),
            message: "not a finite number: every value tsim reads must be finite".into(),
        }])),
        None => Ok(cfg),
    }
}

/// The first YAML literal of a non-finite float (`.nan`, `.inf`, `-.Inf`, ...) outside
/// quotes and comments, with its 1-based line. Caught here, where the line is known:
/// further on a NaN would pass comparisons silently, or turn into a null in the sweep's
/// JSON copy of the config.
fn non_finite_literal(text: &str) -> Option<(usize, &str)> {
    text.lines().enumerate().find_map(|(i, line)| {
        // A comment starts at a `#` that opens the line or follows a space.
        let code = match line.trim_start().starts_with('#') {
            true => "",
            false => line.split(" #").next().unwrap_or(line),
        };
        let mut quoted = false;
        code.split(|c: char| {
            if c == '"' || c == '\'' {
                quoted = !quoted;
            }
            quoted || matches!(c, ' ' | ',' | ':' | '[' | ']' | '{' | '}' | '"' | '\'')
        })
        .find(|t| {
            let t = t.trim_start_matches(['-', '+']).to_ascii_lowercase();
            t == ".nan" || t == ".inf"
        })
        .map(|t| (i + 1, t))
    })
}

/// Parses and validates one case configuration, reporting every bad value; its time
/// tables are read relative to the directory of `origin`.
pub fn parse_case(text: &str, origin: &str) -> Result<CaseConfig, ConfigError> {
    let mut cfg = parse(text, origin)?;
    resolve_tables(&mut cfg, text, origin, &mut TableFiles::default())?;
    cfg.validate()
        .map_err(|errors| ConfigError::Values(locate_errors(origin, text, errors)))?;
    Ok(cfg)
}

/// The directory a config file's relative paths start from: that of `origin`, `.` for a
/// bare file name (whose parent is the empty path, which does not resolve).
pub fn config_dir(origin: &str) -> &std::path::Path {
    match std::path::Path::new(origin).parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => std::path::Path::new("."),
    }
}

/// Reads the CSV time tables of `cfg` (parsed from `text`, the file `origin`) into their
/// points (sharing those `read` holds); a missing file is reported at its field's line, a
/// bad row at its CSV line.
pub fn resolve_tables(cfg: &mut CaseConfig, text: &str, origin: &str, read: &mut TableFiles) -> Result<(), ConfigError> {
    cfg.resolve_tables(config_dir(origin), read).map_err(|errors| {
        let (mut fields, mut rows) = (Vec::new(), Vec::new());
        for e in errors {
            match e {
                TableError::Field(f) => fields.push(f),
                TableError::Csv(v) if v.line.is_some() => rows.push(v),
                // About the whole table (too few rows): at the config's `file:` line.
                TableError::Csv(v) => fields.push(FieldError {
                    field: v.field,
                    message: format!("`{}` {}", v.file, v.message),
                }),
            }
        }
        let mut located = locate_errors(origin, text, fields);
        located.extend(rows);
        ConfigError::Values(located)
    })
}

/// `errors` of the file `origin`, each at its field's line, in file order.
pub fn locate_errors(origin: &str, text: &str, errors: Vec<FieldError>) -> Vec<ValueError> {
    let mut located: Vec<ValueError> = errors
        .into_iter()
        .map(|e| ValueError {
            file: origin.to_string(),
            line: locate_line(text, &e.field),
            field: e.field,
            message: e.message,
        })
        .collect();
    located.sort_by_key(|e| e.line);
    located
}

#[cfg(test)]
mod tests {
    use super::non_finite_literal;

    /// Literals are found in values, with their line; comments and quoted strings that
    /// mention them are not values.
    #[test]
    fn non_finite_literals_are_values_only() {
        assert_eq!(non_finite_literal("a: 1\nb: [0, -.Inf]\n"), Some((2, "-.Inf")));
        assert_eq!(non_finite_literal("c: { d: .nan }"), Some((1, ".nan")));
        assert_eq!(non_finite_literal("# .nan in a comment\na: 1 # or .inf here\n"), None);
        assert_eq!(non_finite_literal("source: \"a .inf of text\"\nname: '.nan'\n"), None);
    }

    /// A config given by a bare file name (`tsim check sweep.yaml`) reads its tables from
    /// the current directory: its parent, the empty path, did not resolve, so every table
    /// was refused as lying outside the config's directory.
    #[test]
    fn a_bare_file_name_is_in_the_current_directory() {
        assert_eq!(super::config_dir("sweep.yaml"), std::path::Path::new("."));
        assert_eq!(super::config_dir("configs/sweep.yaml"), std::path::Path::new("configs"));
        assert!(super::config_dir("sweep.yaml").canonicalize().is_ok());
    }
}
