//! The renderer's error type: one variant per kind of failure, carrying the offending values.

use std::path::PathBuf;

/// Everything that can go wrong when loading a scene or rendering it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// A scene file could not be parsed as TOML of the expected shape.
    #[error("{file}: {message}")]
    Parse { file: String, message: String },
    /// A scene file parsed, but a value is wrong: the file, the key and what was expected.
    #[error("{file}: `{key}`: expected {expected}")]
    Invalid { file: String, key: String, expected: String },
    /// A file the scene refers to (mesh, texture, environment map, photograph) is missing or
    /// unreadable.
    #[error("{what} `{path}` could not be read: {reason}")]
    MissingFile { what: &'static str, path: PathBuf, reason: String },
    /// No built-in scene has this name and no file exists at this path.
    #[error("no built-in scene is named `{name}` and no such file exists (try `mrstudy render --list`)")]
    UnknownScene { name: String },
    /// An image could not be written.
    #[error("could not write `{path}`: {reason}")]
    Write { path: PathBuf, reason: String },
    /// Two images that must match in size do not.
    #[error("image sizes differ: {a_width}x{a_height} against {b_width}x{b_height}")]
    SizeMismatch { a_width: u32, a_height: u32, b_width: u32, b_height: u32 },
    /// A request the scene cannot satisfy (e.g. a ground truth for a scene with a real photograph).
    #[error("{0}")]
    Unsupported(String),
}

pub type Result<T> = std::result::Result<T, RenderError>;
