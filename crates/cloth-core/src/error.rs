//! Error types of the core: scene loading and validation, and simulation.

use std::fmt;

/// One thing wrong with a scene: where, what, and how to fix it.
#[derive(Clone, Debug, PartialEq)]
pub struct Problem {
    /// Path of the offending field, e.g. `cloth.resolution[0]` or `spheres[1].radius`.
    pub field: String,
    /// What is wrong, with the offending value.
    pub message: String,
    /// What to do about it.
    pub fix: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {} (fix: {})", self.field, self.message, self.fix)
    }
}

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    ///
    /// The message carries the operating system's error itself rather than exposing it as a
    /// `source`, so that a report of the error chain names it once.
    #[error("cannot read scene file {path}: {error}")]
    Io {
        /// The path given.
        path: String,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// The text is not a valid RON scene.
    #[error("scene is not valid RON at line {line}, column {column}: {message}")]
    Parse {
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// The parser's message.
        message: String,
    },
    /// The scene parsed but some values are unusable; every problem is listed.
    #[error("scene has {} problem(s):\n{}", .0.len(), list(.0))]
    Invalid(Vec<Problem>),
}

fn list(problems: &[Problem]) -> String {
    problems.iter().map(|p| format!("  - {p}")).collect::<Vec<_>>().join("\n")
}

impl SceneError {
    pub(crate) fn from_ron(e: ron::error::SpannedError) -> Self {
        SceneError::Parse { line: e.span.start.line, column: e.span.start.col, message: e.code.to_string() }
    }

    /// The validation problems, if this is [`SceneError::Invalid`].
    pub fn problems(&self) -> &[Problem] {
        match self {
            SceneError::Invalid(p) => p,
            _ => &[],
        }
    }
}

/// Why a simulator could not be created or stepped.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The scene is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A live parameter change touches something only a rebuild can change.
    #[error("changing {what} needs a rebuild of the simulator (use reset/rebuild instead of a live update)")]
    RebuildRequired {
        /// What changed, e.g. "the grid resolution".
        what: String,
    },
    /// A state handed to `write_state` does not fit this simulator.
    #[error("state has {got} vertices but the simulator has {expected}: hand over a state from the same scene")]
    StateMismatch {
        /// Vertex count of the simulator.
        expected: usize,
        /// Vertex count of the state.
        got: usize,
    },
    /// The backend cannot run here (no adapter, no loader, ...).
    #[error("backend {backend} is unavailable: {reason}")]
    Unavailable {
        /// Backend name.
        backend: &'static str,
        /// Why, and what to do.
        reason: String,
    },
    /// The backend does not implement something the scene asks for.
    #[error("backend {backend} does not support {what} yet: {fix}")]
    Unsupported {
        /// Backend name.
        backend: &'static str,
        /// What the scene asks for.
        what: String,
        /// What to do instead.
        fix: String,
    },
    /// An option passed to a backend (e.g. a GPU tuning value) is invalid.
    #[error("option {option} = {value} is invalid: {expected}")]
    InvalidOption {
        /// The option's name, as the type that holds it names its field.
        option: &'static str,
        /// The value given.
        value: String,
        /// What it must be.
        expected: String,
    },
    /// The scene does not fit on the device.
    #[error(
        "grid {nx}x{ny} needs {needed_bytes} bytes in one {resource}, but the device allows {limit_bytes}: use a smaller grid (the largest square one that fits is {largest_square}x{largest_square})"
    )]
    TooLarge {
        /// Vertices along u.
        nx: u32,
        /// Vertices along v.
        ny: u32,
        /// Which buffer or limit.
        resource: String,
        /// Bytes needed.
        needed_bytes: u64,
        /// The device's limit.
        limit_bytes: u64,
        /// Side of the largest square grid of this scene that fits the limit.
        largest_square: u32,
    },
    /// The device failed during the run (lost, out of memory, ...).
    #[error("backend {backend} failed: {reason}")]
    Device {
        /// Backend name.
        backend: &'static str,
        /// What went wrong.
        reason: String,
    },
}
