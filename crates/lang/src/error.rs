//! Errors of the model language, each located in its file.

use std::fmt;
use std::path::PathBuf;

/// Where a problem is: the file, and the line and column when known (both 1-based).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Location {
    /// The model file (or the config holding an inline model); `None` for a model given as a
    /// string.
    pub path: Option<PathBuf>,
    /// 1-based line.
    pub line: Option<usize>,
    /// 1-based column (in characters).
    pub column: Option<usize>,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.path {
            Some(p) => write!(f, "{}", p.display())?,
            None => write!(f, "<model>")?,
        }
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(col) = self.column {
                write!(f, ":{col}")?;
            }
        }
        Ok(())
    }
}

/// Errors of the model language.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The file could not be read.
    #[error("cannot read model file {path}: {reason}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        reason: String,
    },
    /// The text is not valid TOML.
    #[error("{location}: not valid TOML: {message}")]
    Toml {
        /// Where.
        location: Location,
        /// The parser's message.
        message: String,
    },
    /// A key holds something the model language does not accept.
    #[error("{location}: {key}: {message}")]
    Invalid {
        /// Where.
        location: Location,
        /// The key path, e.g. `modes.damped.v`.
        key: String,
        /// What is wrong and what was expected.
        message: String,
    },
    /// A parameter set through the API is unknown or out of its bounds.
    #[error("parameter {name}: {message}")]
    Parameter {
        /// The parameter.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// A model without a `[forcing]` has no period to look for an orbit with.
    #[error("the model has no [forcing] with a period: a forced periodic orbit needs one")]
    NoPeriod,
    /// The limit cycle could not be found.
    #[error(transparent)]
    Orbit(#[from] htfid_orbit::OrbitError),
}

impl ModelError {
    /// The location, when the error has one.
    pub fn location(&self) -> Option<&Location> {
        match self {
            ModelError::Toml { location, .. } | ModelError::Invalid { location, .. } => {
                Some(location)
            }
            _ => None,
        }
    }
}
