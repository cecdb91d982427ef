//! From a TOML parser's error to a [`ConfigError::Parse`] that names the field and its line
//! and column, in one line.

use super::error::ConfigError;

/// Turns a deserialization error into one message naming the field and where it is.
pub(super) fn parse_error(
    text: &str,
    source_name: &str,
    error: serde_path_to_error::Error<toml::de::Error>,
) -> ConfigError {
    let path = error.path().to_string();
    // serde_path_to_error writes "." for the top level (syntax errors).
    let field = (path != ".").then_some(path);
    let inner = error.into_inner();
    let line_column = inner.span().map(|span| line_column_at(text, span.start));
    // Syntax errors come as several lines; the CLI prints one.
    let detail = inner.message().trim_end().replace('\n', "; ");
    let message = match &field {
        None => detail,
        Some(field) => match unknown_field_rest(&detail, field) {
            // The path ends with the unknown key itself: say it once, in full.
            Some(rest) => format!("unknown field `{field}`{rest}"),
            None => format!("{field}: {detail}"),
        },
    };
    ConfigError::Parse {
        source_name: source_name.to_string(),
        line_column,
        field,
        message,
    }
}

/// For serde's "unknown field `key`, expected ..." about the last key of `field`, the text
/// after the key.
fn unknown_field_rest<'m>(detail: &'m str, field: &str) -> Option<&'m str> {
    let rest = detail.strip_prefix("unknown field `")?;
    let (key, rest) = rest.split_once('`')?;
    let last_key = field.rsplit('.').next()?;
    (key == last_key).then_some(rest)
}

/// 1-based line and column (in characters) of a byte offset.
fn line_column_at(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |newline| newline + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}
