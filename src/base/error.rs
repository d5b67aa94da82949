//! Errors, split by who can fix them: the user (bad input, exit code 2) or the system.

use std::path::Path;

/// Everything that can stop optbench.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The user's input is wrong (suite file, flags, recording); reported with exit code 2.
    #[error("{0}")]
    Input(String),
    /// Reading or writing a file failed.
    #[error("{context}: {source}")]
    Io {
        context: String,
        #[source]
        source: std::io::Error,
    },
}

impl Error {
    /// An input error located in `file` at `line` (line 0: no line, e.g. the command line).
    pub fn at(file: &Path, line: usize, msg: impl std::fmt::Display) -> Self {
        if line == 0 {
            Error::Input(format!("{}: {msg}", file.display()))
        } else {
            Error::Input(format!("{}:{line}: {msg}", file.display()))
        }
    }

    /// An I/O error with a description of what was being done.
    pub fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io {
            context: context.into(),
            source,
        }
    }

    /// Process exit code: 2 for bad input (like a usage error), 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input(_) => 2,
            Error::Io { .. } => 1,
        }
    }
}

/// Result with optbench's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
