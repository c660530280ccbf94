//! The YAML case configuration: schema, defaults, the material library and validation.
//! Every key is documented in `docs/config.md`; unknown keys are errors (with line and
//! column from the YAML parser), out-of-range values name the field and the range.

mod build;
mod materials;
mod schema;
mod validate;

pub use materials::{library, LawSpec, MaterialSpec};
pub use schema::*;
pub use validate::ConfigError;

/// Parses and validates one case configuration. `origin` names the file in errors.
pub fn parse_case(text: &str, origin: &str) -> Result<CaseConfig, ConfigError> {
    let cfg: CaseConfig = serde_saphyr::from_str(text).map_err(|e| ConfigError::Syntax {
        file: origin.to_string(),
        message: e.to_string(),
    })?;
    cfg.validate().map_err(|(field, message)| ConfigError::Value {
        file: origin.to_string(),
        field,
        message,
    })?;
    Ok(cfg)
}
