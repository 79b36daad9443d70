//! Everything that can go wrong reading or writing a cloud, with the file, record and field at
//! fault.

use std::io;
use std::path::{Path, PathBuf};

use thiserror::Error;

/// Everything that can go wrong reading or writing a cloud.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum CloudError {
    /// An error while reading or writing the file `path`.
    #[error("{}: {error}", path.display())]
    File { path: PathBuf, error: Box<CloudError> },
    #[error("I/O error: {0}")]
    Io(#[from] io::Error),
    /// A malformed header; `line` is 1-based.
    #[error("header line {line}: {msg}")]
    Header { line: usize, msg: String },
    /// A malformed record of the data section: `element` `index` (0-based; `point` for PCD and
    /// text, the element name for PLY), the 1-based text line when the data is text, the field.
    #[error("{}", fmt_record(element, *index, *line, field.as_deref(), msg))]
    Record {
        element: String,
        index: usize,
        line: Option<usize>,
        field: Option<String>,
        msg: String,
    },
    /// Corrupt LZF data; `offset` is the byte of the offending instruction (in the file when read
    /// from a PCD file, else in the compressed block).
    #[error("LZF data corrupt at byte {offset}: {msg}")]
    Lzf { offset: usize, msg: &'static str },
    /// A file-level inconsistency (e.g. `POINTS 100 but WIDTH*HEIGHT = 120`).
    #[error("{0}")]
    Format(String),
    /// The cloud handed to a writer breaks the [`PointCloud`](super::PointCloud) invariants.
    #[error("invalid cloud: {0}")]
    InvalidCloud(String),
}

fn fmt_record(element: &str, index: usize, line: Option<usize>, field: Option<&str>, msg: &str) -> String {
    let mut s = format!("{element} {index}");
    if let Some(line) = line {
        s += &format!(" (line {line})");
    }
    if let Some(field) = field {
        s += &format!(", field `{field}`");
    }
    s + ": " + msg
}

impl CloudError {
    pub(crate) fn header(line: usize, msg: impl Into<String>) -> CloudError {
        CloudError::Header { line, msg: msg.into() }
    }

    pub(crate) fn record(
        element: &str,
        index: usize,
        line: Option<usize>,
        field: Option<&str>,
        msg: impl Into<String>,
    ) -> CloudError {
        CloudError::Record {
            element: element.to_string(),
            index,
            line,
            field: field.map(str::to_string),
            msg: msg.into(),
        }
    }

    pub(super) fn in_file(self, path: &Path) -> CloudError {
        CloudError::File {
            path: path.to_path_buf(),
            error: Box::new(self),
        }
    }
}
