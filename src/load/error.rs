//! Errors of the input boundary: every one names the file and, where it can, the place in it.

use std::fmt;
use std::path::{Path, PathBuf};

/// What went wrong while reading a scene file.
#[derive(Debug)]
pub enum LoadErrorKind {
    /// The file could not be read.
    Io(std::io::Error),
    /// The extension is not one mirage reads.
    UnknownFormat,
    /// The file is not well-formed (JSON syntax, truncated binary, bad buffer...).
    Malformed,
    /// The file is well-formed but asks for something mirage does not support.
    Unsupported,
    /// The content is invalid (NaN values, out-of-range indices, bad parameters...).
    Invalid,
}

/// An error reading a scene file, with its path and location.
#[derive(Debug)]
pub struct LoadError {
    /// The file being read.
    pub path: PathBuf,
    /// Where in the file: "node 2, mesh 0, primitive 1", "line 14", "material 'glass'".
    pub location: Option<String>,
    /// The category.
    pub kind: LoadErrorKind,
    /// One sentence for the user.
    pub message: String,
}

impl LoadError {
    /// An error of `kind` in `path`.
    pub fn new(path: &Path, kind: LoadErrorKind, message: impl Into<String>) -> Self {
        LoadError { path: path.to_path_buf(), location: None, kind, message: message.into() }
    }

    /// The same error at a location inside the file.
    pub fn at(mut self, location: impl Into<String>) -> Self {
        self.location = Some(location.into());
        self
    }

    /// A read failure.
    pub fn io(path: &Path, err: std::io::Error) -> Self {
        let message = match err.kind() {
            std::io::ErrorKind::NotFound => "file not found".to_string(),
            _ => format!("cannot read file: {err}"),
        };
        LoadError { path: path.to_path_buf(), location: None, kind: LoadErrorKind::Io(err), message }
    }
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(loc) = &self.location {
            write!(f, ": {loc}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for LoadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            LoadErrorKind::Io(e) => Some(e),
            _ => None,
        }
    }
}
