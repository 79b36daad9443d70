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

/// The largest model, scene, configuration or labels file read (bytes): the largest shipped is
/// a few kilobytes, and a path to a device or a huge file must not be read until memory ends.
pub const MAX_SPEC_BYTES: u64 = 1 << 20;

/// The text of a specification file: a regular file of at most [`MAX_SPEC_BYTES`], UTF-8.
pub fn read_text(path: &Path) -> Result<String, SpecError> {
    use std::io::Read;
    let io = |source: std::io::Error| SpecError::Io {
        path: path.to_owned(),
        source,
    };
    let file = open_regular(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(SpecError::Syntax {
            path: path.to_owned(),
            message: "not a regular file".into(),
        });
    }
    let mut bytes = Vec::new();
    file.take(MAX_SPEC_BYTES + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > MAX_SPEC_BYTES {
        return Err(SpecError::Syntax {
            path: path.to_owned(),
            message: format!("over {MAX_SPEC_BYTES} bytes: not a model, scene, configuration or labels file"),
        });
    }
    String::from_utf8(bytes).map_err(|e| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        ))
    })
}

/// Open a file for reading without blocking in open(2): a FIFO (a configuration replaced by one,
/// a `*.toml` in the models directory) would wait there for a writer, on the path a SIGHUP's
/// reload and `sqscand --check` take. The caller still checks that what it opened is a regular
/// file; reads of a regular file do not heed `O_NONBLOCK`.
pub fn open_regular(path: &Path) -> std::io::Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
}

/// Read and parse a TOML file into its serde form.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, SpecError> {
    parse_toml(&read_text(path)?, path)
}

/// Parse TOML text that came from `path` (used for messages only). The message gives the line
/// and column and what was wrong, never the line itself (a path given by mistake may name a
/// file that is nobody's business), with control characters escaped.
pub fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, path: &Path) -> Result<T, SpecError> {
    toml::from_str(text).map_err(|e| {
        let place = e.span().map(|s| {
            let before = &text[..s.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let start = before.rsplit('\n').next().unwrap_or("");
            let column = start.chars().count() + 1;
            // The key the value belongs to, when the line is a plain `key = value`: a name
            // of this format's, not the file's content.
            let key = start
                .split_once('=')
                .map(|(k, _)| k.trim())
                .filter(|k| {
                    !k.is_empty() && k.len() <= 40 && k.chars().all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c))
                })
                .map(|k| format!(" ({k})"))
                .unwrap_or_default();
            format!("line {line}, column {column}{key}: ")
        });
        SpecError::Syntax {
            path: path.to_owned(),
            message: format!(
                "{}{}",
                place.unwrap_or_default(),
                escape_controls(e.message().trim_end())
            ),
        }
    })
}

/// `text` with its control characters (a terminal's escape sequences among them, line breaks,
/// and the bidirectional overrides that reorder what a terminal shows) escaped as `\u{1b}`.
pub fn escape_controls(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if c.is_control() || matches!(c, '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}') {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}
