//! The YAML case configuration: schema, defaults, the material library and validation.
//! Every key is documented in `docs/config.md`; unknown keys are errors (with line and
//! column from the YAML parser), out-of-range values name the field and the range.

mod build;
mod locate;
mod materials;
mod schema;
mod validate;

pub use materials::{library, LawSpec, MaterialSpec};
pub use schema::*;
pub use validate::ConfigError;

/// Line of a dotted field path in the YAML text (see `locate`).
pub fn locate_line(text: &str, field: &str) -> Option<usize> {
    locate::line_of(text, field)
}

/// `file:line` for a field when its line can be found, else `file`.
pub fn located(origin: &str, text: &str, field: &str) -> String {
    match locate_line(text, field) {
        Some(line) => format!("{origin}:{line}"),
        None => origin.to_string(),
    }
}

/// Parses and validates one case configuration. `origin` names the file in errors.
pub fn parse_case(text: &str, origin: &str) -> Result<CaseConfig, ConfigError> {
    let cfg: CaseConfig = serde_saphyr::from_str(text).map_err(|e| {
        let message = e.to_string();
        ConfigError::Syntax {
            file: origin.to_string(),
            // The CLI adds its own `error: `.
            message: message.strip_prefix("error: ").unwrap_or(&message).to_string(),
        }
    })?;
    cfg.validate().map_err(|(field, message)| ConfigError::Value {
        file: located(origin, text, &field),
        field,
        message,
    })?;
    Ok(cfg)
}
