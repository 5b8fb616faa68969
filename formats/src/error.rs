//! Typed errors of the formats crate. Messages name the file last.

use std::path::PathBuf;

/// An error decoding one piece of input (no file attached yet).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FormatError {
    /// The raw log's header is unusable.
    #[error("bad UNZ header: {reason}")]
    Header {
        /// What is wrong.
        reason: String,
    },
    /// The file could not be opened (missing, not readable, not a regular file).
    #[error("cannot open it: {source}")]
    Open {
        /// The I/O error.
        source: std::io::Error,
    },
    /// Reading failed at a byte offset.
    #[error("read failed at byte offset {offset}: {source}")]
    Io {
        /// Byte offset in the file.
        offset: u64,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Writing failed.
    #[error("write failed: {source}")]
    Write {
        /// The I/O error.
        source: std::io::Error,
    },
    /// A text log line could not be used.
    #[error("line {line}: {reason}")]
    Line {
        /// 1-based line number.
        line: u64,
        /// What is wrong.
        reason: String,
    },
    /// A run manifest is invalid.
    #[error("line {line}: {reason}")]
    Manifest {
        /// 1-based line number (0 when the whole manifest is concerned).
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// Parquet failed (the cause kept as the source).
    #[error("parquet: {}", with_causes(.0))]
    Parquet(#[from] parquet::errors::ParquetError),
    /// Arrow failed.
    #[error("arrow: {}", with_causes(.0))]
    Arrow(#[from] arrow::error::ArrowError),
    /// A CDR message could not be encoded.
    #[error("cdr: {}", with_causes(.0))]
    Cdr(#[from] re_cdr::Error),
    /// A JSON report could not be encoded.
    #[error("json: {}", with_causes(.0))]
    Json(#[from] serde_json::Error),
    /// Anything else, said in words.
    #[error("{0}")]
    Invalid(String),
}

/// `e` and each of its causes that says something new, joined by ": " (a library's
/// message may hide its cause: an "I/O error from writing" need not say "No space left
/// on device").
pub fn with_causes(e: &(dyn std::error::Error + 'static)) -> String {
    let mut out = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let m = s.to_string();
        if !out.contains(&m) {
            out.push_str(": ");
            out.push_str(&m);
        }
        source = s.source();
    }
    out
}

/// A [`FormatError`] with the file it concerns. Its message says both, so the error is
/// not chained again (a chain would repeat the cause).
#[derive(Debug, thiserror::Error)]
#[error("{error} (in {path})")]
pub struct FileError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub error: FormatError,
}

impl FormatError {
    /// Attaches the file this error concerns.
    pub fn in_file(self, path: impl Into<PathBuf>) -> FileError {
        FileError {
            path: path.into(),
            error: self,
        }
    }
}

/// Attaches a path to an I/O error that happened opening, reading or renaming a file.
pub fn io_in_file(path: impl Into<PathBuf>, source: std::io::Error) -> FileError {
    FormatError::Io { offset: 0, source }.in_file(path)
}

/// Attaches a path to an I/O error that happened opening a file to read it.
pub fn open_error_in_file(path: impl Into<PathBuf>, source: std::io::Error) -> FileError {
    FormatError::Open { source }.in_file(path)
}

/// Attaches a path to an I/O error that happened writing a file.
pub fn write_error_in_file(path: impl Into<PathBuf>, source: std::io::Error) -> FileError {
    FormatError::Write { source }.in_file(path)
}
