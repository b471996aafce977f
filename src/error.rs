//! Library errors. Only I/O and user input fail; every error names the file and, where there is
//! one, the element (docs/how-it-works.md#errors-at-the-boundary). The binary maps these to
//! messages and exit codes.

use std::path::{Path, PathBuf};

/// Everything the library can fail with.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The input is malformed; `element` says where (e.g. "vertex 17", "accessor 3").
    #[error("{path}: {element}: {message}")]
    Invalid {
        path: PathBuf,
        element: String,
        message: String,
    },
    /// The input parsed but holds nothing to bake.
    #[error("{path}: {message}")]
    Empty { path: PathBuf, message: String },
    /// The file type is not one we read.
    #[error("{path}: unsupported input format (expected .obj, .gltf or .glb)")]
    Format { path: PathBuf },
    /// An output path that would overwrite the input, another output, or something that is not
    /// a regular file.
    #[error("{path}: {message}")]
    Output { path: PathBuf, message: String },
    /// Parameters out of range.
    #[error("invalid parameters: {0}")]
    Params(String),
    /// A scene file that does not parse, or whose values are out of range: the file, the line
    /// (1-based, when the key is in the file) and the key (`surface[1].shells.layers`).
    #[error("{}: {}{key}: {message}", path.display(), line.map(|l| format!("line {l}: ")).unwrap_or_default())]
    Scene {
        path: PathBuf,
        line: Option<usize>,
        key: String,
        message: String,
    },
}

/// A parameter out of range: its key inside the parameters (`layers`; a stage's `check` names
/// its own fields, `BakeParams::check` prefixes the section, `shells.layers`)
/// and what is wrong, naming the parameter.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct ParamError {
    pub key: String,
    pub message: String,
}

impl ParamError {
    pub fn new(key: &str, message: impl Into<String>) -> ParamError {
        ParamError {
            key: key.into(),
            message: message.into(),
        }
    }

    /// `Ok` when `value` lies in `lo..=hi`, else an error naming `key` and the range.
    pub fn in_range(key: &str, value: f32, lo: f32, hi: f32) -> Result<(), ParamError> {
        if (lo..=hi).contains(&value) {
            return Ok(());
        }
        Err(ParamError::new(
            key,
            format!("{key} must be in {lo}..={hi}, got {value}"),
        ))
    }

    /// `Ok` when `v` is a direction (finite, non-zero), else an error naming `key`.
    pub fn direction(key: &str, v: &[f32]) -> Result<(), ParamError> {
        let length = v.iter().map(|c| c * c).sum::<f32>().sqrt();
        if v.iter().all(|c| c.is_finite()) && length > 1e-6 {
            return Ok(());
        }
        Err(ParamError::new(
            key,
            format!("{key} must be a non-zero vector, got {v:?}"),
        ))
    }

    /// The same error with its key inside `section`.
    pub fn within(self, section: &str) -> ParamError {
        ParamError {
            key: format!("{section}.{}", self.key),
            ..self
        }
    }
}

impl Error {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Error {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn invalid(
        path: &Path,
        element: impl Into<String>,
        message: impl Into<String>,
    ) -> Error {
        Error::Invalid {
            path: path.to_path_buf(),
            element: element.into(),
            message: message.into(),
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
