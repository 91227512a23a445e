//! What can stop the viewer, each naming the flag, file or window-system call at fault.

use std::fmt;
use std::path::PathBuf;

use super::path::CameraPathError;
use crate::output::SaveError;
use crate::render::PrepareError;

/// Why `mirage view` stopped.
#[derive(Debug)]
pub enum ViewError {
    /// A flag value that makes no sense.
    Options(String),
    /// No window can be opened (no display, or the window system refused).
    NoDisplay(String),
    /// The window system failed while running.
    Window(String),
    /// The scene could not be loaded or validated.
    Prepare(PrepareError),
    /// The camera path file is unusable.
    CameraPath(CameraPathError),
    /// A screenshot, recorded frame or reference image could not be written or read.
    Save(SaveError),
    /// The reference image does not fit the render.
    Reference {
        /// The reference file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

impl fmt::Display for ViewError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ViewError::Options(m) | ViewError::Window(m) => f.write_str(m),
            ViewError::NoDisplay(reason) => write!(
                f,
                "cannot open a window ({reason}); `mirage view` needs a display: run `mirage view --headless` for \
                 the frame loop without a window, or `mirage render` for images"
            ),
            ViewError::Prepare(e) => e.fmt(f),
            ViewError::CameraPath(e) => e.fmt(f),
            ViewError::Save(e) => e.fmt(f),
            ViewError::Reference { path, message } => write!(f, "{}: {message}", path.display()),
        }
    }
}

impl std::error::Error for ViewError {}

impl From<PrepareError> for ViewError {
    fn from(e: PrepareError) -> Self {
        ViewError::Prepare(e)
    }
}

impl From<CameraPathError> for ViewError {
    fn from(e: CameraPathError) -> Self {
        ViewError::CameraPath(e)
    }
}

impl From<SaveError> for ViewError {
    fn from(e: SaveError) -> Self {
        ViewError::Save(e)
    }
}
