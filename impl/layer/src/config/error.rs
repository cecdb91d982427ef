//! What goes wrong with a configuration ([`ConfigError`], [`InvalidValue`]), and the helpers
//! the sections' validation phrases its rules with.

use std::fmt;

/// Why a configuration could not be had. Every variant names its source (the file path, or
/// whatever name the caller gave a string), and every variant but `Read` names the field.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{source_name}: cannot read the configuration: {error}")]
    Read {
        /// The file path, or the name the caller gave the string.
        source_name: String,
        /// The I/O error from reading the file.
        #[source]
        error: std::io::Error,
    },
    /// Not TOML, an unknown field, or a value of the wrong type.
    #[error("{source_name}{}: {message}", display_line_column(.line_column))]
    Parse {
        /// The file path, or the name the caller gave the string.
        source_name: String,
        /// 1-based line and column of the offending text, when the parser knows it.
        line_column: Option<(usize, usize)>,
        /// Dotted path of the field (`timing.peer_deadline_ms`); `None` for syntax errors.
        field: Option<String>,
        /// What is wrong, naming the field: `timing.peer_deadline_ms: invalid type: ...`.
        message: String,
    },
    /// Well-formed, but a value breaks a rule.
    #[error("{source_name}: {invalid}")]
    Invalid {
        /// The file path, or the name the caller gave the string.
        source_name: String,
        /// The field, its value and the rule it breaks.
        #[source]
        invalid: InvalidValue,
    },
}

impl ConfigError {
    /// The dotted path of the field at fault, if the error is about one field.
    pub fn field(&self) -> Option<&str> {
        match self {
            ConfigError::Read { .. } => None,
            ConfigError::Parse { field, .. } => field.as_deref(),
            ConfigError::Invalid { invalid, .. } => Some(&invalid.field),
        }
    }
}

fn display_line_column(line_column: &Option<(usize, usize)>) -> String {
    match line_column {
        Some((line, column)) => format!(":{line}:{column}"),
        None => String::new(),
    }
}

/// A value that breaks a validation rule: `timing.peer_deadline_ms = 300: must be ...`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field} = {value}: {rule}")]
pub struct InvalidValue {
    /// Dotted path of the field (`timing.peer_deadline_ms`).
    pub field: String,
    /// The value as it would be written in TOML.
    pub value: String,
    /// The rule it breaks, phrased as what the value must be.
    pub rule: String,
}

impl InvalidValue {
    pub(super) fn new(
        field: &str,
        value: impl fmt::Display,
        rule: impl Into<String>,
    ) -> InvalidValue {
        InvalidValue {
            field: field.to_string(),
            value: value.to_string(),
            rule: rule.into(),
        }
    }
}

/// Fails with `rule` unless `holds`.
pub(super) fn check(
    holds: bool,
    field: &str,
    value: impl fmt::Display,
    rule: impl FnOnce() -> String,
) -> Result<(), InvalidValue> {
    if holds {
        Ok(())
    } else {
        Err(InvalidValue::new(field, value, rule()))
    }
}

/// A string value as TOML writes it (`"YELLOW"`).
pub(super) fn quoted(text: &str) -> String {
    format!("{text:?}")
}
