//! Errors of the hand-written TOML files (models, scenes, configuration): every one names the
//! file, the field and what was wrong with it.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum SpecError {
    /// The cause follows in the error chain (`{:#}` prints it).
    #[error("cannot read {}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    /// TOML syntax or a field of the wrong type or an unknown field; the message of the TOML
    /// parser carries the line, the column and the key.
    #[error("{}: {message}", path.display())]
    Syntax { path: PathBuf, message: String },
    #[error("{}: {field}: {message}", path.display())]
    Invalid {
        path: PathBuf,
        field: String,
        message: String,
    },
}

impl SpecError {
    /// The message with its causes, for embedding in another message.
    pub fn with_causes(&self) -> String {
        let mut out = self.to_string();
        let mut cause = std::error::Error::source(self);
        while let Some(c) = cause {
            out += &format!(": {c}");
            cause = c.source();
        }
        out
    }

    pub fn invalid(path: &Path, field: impl Into<String>, message: impl Into<String>) -> Self {
        SpecError::Invalid {
            path: path.to_owned(),
            field: field.into(),
            message: message.into(),
        }
    }
}

/// Read and parse a TOML file into its serde form.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, SpecError> {
    let text = std::fs::read_to_string(path).map_err(|source| SpecError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_toml(&text, path)
}

/// Parse TOML text that came from `path` (used for messages only).
pub fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, path: &Path) -> Result<T, SpecError> {
    toml::from_str(text).map_err(|e| SpecError::Syntax {
        path: path.to_owned(),
        message: e.to_string().trim_end().replace('\n', " | "),
    })
}
