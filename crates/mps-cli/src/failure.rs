//! What a command can fail with, and the one place failures become exit codes: bad input
//! (a case file, a command-line value, a file read back) exits 1, a failed read or write
//! exits 3. A numerical breakdown is not a failure: the run command returns exit code 2.

use std::fmt;
use std::process::ExitCode;

/// A command's failure.
#[derive(Debug)]
pub enum Failure {
    /// Bad input: exit 1.
    BadInput(String),
    /// Reading or writing failed: exit 3.
    Io(String),
}

impl Failure {
    /// The exit code of this failure.
    pub fn exit_code(&self) -> ExitCode {
        match self {
            Failure::BadInput(_) => ExitCode::from(1),
            Failure::Io(_) => ExitCode::from(3),
        }
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Failure::BadInput(m) | Failure::Io(m) => write!(f, "{}", m.replace('\n', " ")),
        }
    }
}

impl From<mps::Error> for Failure {
    fn from(e: mps::Error) -> Self {
        if e.is_bad_input() {
            Failure::BadInput(e.to_string())
        } else {
            Failure::Io(e.to_string())
        }
    }
}

impl From<mps::CaseError> for Failure {
    fn from(e: mps::CaseError) -> Self {
        Failure::BadInput(e.to_string())
    }
}

/// Bad input with a message.
pub fn bad(message: impl Into<String>) -> Failure {
    Failure::BadInput(message.into())
}

/// An I/O failure at `path`.
pub fn io_error(path: &std::path::Path, e: impl fmt::Display) -> Failure {
    Failure::Io(format!("{}: {e}", path.display()))
}

/// A command's result: its exit code, or a failure.
pub type CmdResult = Result<ExitCode, Failure>;
