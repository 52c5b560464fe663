//! Configuration errors, which always name the file and the field, and a checker that builds
//! them.

use std::fmt::Display;

use thiserror::Error;

/// A configuration problem; the message names the file, the field and what is allowed.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// The file could not be read. The cause is part of the message and not chained again,
    /// so an error report gives it once.
    #[error("{file}: cannot read: {cause}")]
    Io {
        /// The file.
        file: String,
        /// Why.
        cause: std::io::Error,
    },
    /// A path a config gives (`layout = "…"`) could not be read: where it came from, as
    /// written, and where it resolved to (against the folder of the file that holds it).
    #[error(
        "{file}: {key} = \"{written}\" resolves to {resolved} (relative paths resolve \
         against the folder of the file that holds them), which cannot be read: {cause}"
    )]
    Path {
        /// The config file that gives the path.
        file: String,
        /// The key.
        key: String,
        /// The path as written.
        written: String,
        /// The path it resolved to.
        resolved: String,
        /// Why it cannot be read.
        cause: std::io::Error,
    },
    /// TOML syntax error or a field of the wrong type (the parser's message has line and key).
    #[error("{file}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// The parser's message.
        message: String,
    },
    /// A field has a value outside what is allowed.
    #[error("{file}: `{field}` = {value}: expected {expected}")]
    Invalid {
        /// The file.
        file: String,
        /// Dotted field path.
        field: String,
        /// The value found.
        value: String,
        /// What is allowed (a range or a list).
        expected: String,
    },
    /// A backend name that this build does not provide.
    #[error(
        "{file}: `{field}` = \"{name}\": not available in this build{later}; available: {available}"
    )]
    Unavailable {
        /// The file.
        file: String,
        /// Dotted field path.
        field: String,
        /// The name asked for.
        name: String,
        /// " (arrives with …)" when the name is planned, else empty.
        later: String,
        /// Names that do work, comma-separated.
        available: String,
    },
}

/// Builds errors for one file.
#[derive(Debug, Clone)]
pub struct FieldCheck {
    file: String,
}

impl FieldCheck {
    /// A checker for `file`.
    pub fn new(file: impl Into<String>) -> Self {
        Self { file: file.into() }
    }

    /// The file name.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// Deserialize `text` as TOML into `T`.
    pub fn parse<T: serde::de::DeserializeOwned>(&self, text: &str) -> Result<T, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::Parse {
            file: self.file.clone(),
            message: e.to_string().trim_end().to_string(),
        })
    }

    /// Deserialize one sub-table into `T`; `prefix` names it in errors.
    pub fn parse_table<T: serde::de::DeserializeOwned>(
        &self,
        prefix: &str,
        table: &toml::Table,
    ) -> Result<T, ConfigError> {
        T::deserialize(toml::Value::Table(table.clone())).map_err(|e| ConfigError::Parse {
            file: self.file.clone(),
            message: format!("in [{prefix}]: {}", e.to_string().trim_end()),
        })
    }

    /// The `version` key must be 1.
    pub fn version(&self, version: i64) -> Result<(), ConfigError> {
        if version == 1 {
            Ok(())
        } else {
            Err(self.invalid("version", version, "1"))
        }
    }

    /// An [`ConfigError::Invalid`] for this file.
    pub fn invalid(&self, field: &str, value: impl Display, expected: &str) -> ConfigError {
        ConfigError::Invalid {
            file: self.file.clone(),
            field: field.to_string(),
            value: value.to_string(),
            expected: expected.to_string(),
        }
    }

    /// `value` must be finite and within `[min, max]`.
    pub fn range(&self, field: &str, value: f64, min: f64, max: f64) -> Result<f64, ConfigError> {
        if value.is_finite() && (min..=max).contains(&value) {
            Ok(value)
        } else {
            Err(self.invalid(field, value, &format!("a number in [{min}, {max}]")))
        }
    }

    /// An [`ConfigError::Unavailable`] for this file.
    pub fn unavailable(
        &self,
        field: &str,
        name: &str,
        later: Option<&str>,
        available: &[&str],
    ) -> ConfigError {
        ConfigError::Unavailable {
            file: self.file.clone(),
            field: field.to_string(),
            name: name.to_string(),
            later: later
                .map(|l| format!(" (arrives with {l})"))
                .unwrap_or_default(),
            available: available.join(", "),
        }
    }
}
