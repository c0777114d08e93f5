//! The one error type of the library: every message names the thing at fault and what was expected.

use std::path::PathBuf;

/// Result alias used across the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything a user can get wrong, and every I/O failure, as a typed error with context.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An operating-system I/O failure on a named path. The OS message is part of the text and
    /// not also a `source()`, so a printed chain (`{:#}`) says it once.
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    /// A file exists but its contents are not what its format requires.
    #[error("{path}: {reason}")]
    Format { path: PathBuf, reason: String },
    /// A value passed in (flag, config field, array) is outside what the operation accepts.
    #[error("invalid {what}: {reason}")]
    Invalid { what: String, reason: String },
    /// Two inputs that must agree in shape do not.
    #[error("shape mismatch in {what}: expected {expected}, found {found}")]
    Shape {
        what: String,
        expected: String,
        found: String,
    },
    /// A JSON configuration could not be read or parsed.
    #[error("config {path}: {reason}")]
    Config { path: PathBuf, reason: String },
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            error: source,
        }
    }

    /// A malformed file at `path`.
    pub fn format(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            reason: reason.into(),
        }
    }

    /// An invalid value for `what`.
    pub fn invalid(what: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::Invalid {
            what: what.into(),
            reason: reason.into(),
        }
    }

    /// A shape mismatch in `what`.
    pub fn shape(
        what: impl Into<String>,
        expected: impl std::fmt::Display,
        found: impl std::fmt::Display,
    ) -> Self {
        Error::Shape {
            what: what.into(),
            expected: expected.to_string(),
            found: found.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_os_error_is_printed_once() {
        let e = Error::io("x.png", std::io::Error::from(std::io::ErrorKind::NotFound));
        let chain = format!("{:#}", anyhow::Error::from(e));
        assert_eq!(chain.matches("not found").count(), 1, "{chain}");
    }
}
