//! The library's errors: one enum for everything a caller can be told went wrong, and the
//! case-file error that names the file, the field and the value.

use std::fmt;
use std::path::{Path, PathBuf};

/// Longest value echoed in a message (characters); longer values are cut.
const MAX_VALUE_CHARS: usize = 80;

/// An error in a case file, naming the file, the field and the value.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseError {
    /// The file (or built-in example name) the case came from.
    pub file: String,
    /// Dotted path of the field, e.g. `particles.spacing` (empty when unknown).
    pub field: String,
    /// The offending value as written, cut to a readable length (empty when not applicable).
    pub value: String,
    /// What is wrong.
    pub message: String,
}

impl CaseError {
    /// The error of `field` (dotted path) in `file`, with the offending `value` (cut to
    /// 80 characters) and a one-line `message`.
    pub fn new(
        file: impl Into<String>,
        field: impl Into<String>,
        value: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        let one_line = |s: String| s.replace(['\n', '\r'], " ").trim().to_string();
        let mut value = one_line(value.into());
        if value.chars().count() > MAX_VALUE_CHARS {
            value = value.chars().take(MAX_VALUE_CHARS).collect::<String>() + "...";
        }
        CaseError {
            file: file.into(),
            field: field.into(),
            value,
            message: one_line(message.into()),
        }
    }
}

impl fmt::Display for CaseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if !self.field.is_empty() {
            write!(f, ": {}", self.field)?;
            if !self.value.is_empty() {
                write!(f, " = {}", self.value)?;
            }
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for CaseError {}

/// Everything the library reports as failed. A numerical breakdown is not an error: it is a
/// result of the run, recorded in its summary.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad input in a case file or on the command line.
    #[error(transparent)]
    Case(#[from] CaseError),
    /// A checkpoint that cannot be read or does not belong to the case.
    #[error("{}: {message}", path.display())]
    Checkpoint {
        /// The checkpoint file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A file that cannot be read as what it should be (VTU, CSV, summary).
    #[error("{}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
}

impl Error {
    /// An I/O error at `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// True for bad input (case, checkpoint or a file read back) as opposed to a failed
    /// read or write.
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, Error::Io { .. })
    }
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Attaches the path to an I/O result.
pub trait IoContext<T> {
    /// Turns an I/O error into [`Error::Io`] naming `path`.
    fn at(self, path: &Path) -> Result<T>;
}

impl<T> IoContext<T> for std::io::Result<T> {
    fn at(self, path: &Path) -> Result<T> {
        self.map_err(|e| Error::io(path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn case_errors_are_one_line_and_cut_long_values() {
        let e = CaseError::new("c.toml", "name", "x".repeat(5000), "bad\nname");
        let s = e.to_string();
        assert!(!s.contains('\n'));
        assert!(s.len() < 200, "{s}");
        assert!(s.starts_with("c.toml: name = xxx"));
    }
}
