//! One error type for the recipes, and the one table from what went wrong
//! to the process exit status.
//!
//! | exit | [`ErrorKind`]   | when                                                        |
//! |------|-----------------|-------------------------------------------------------------|
//! | 0    | (success)       | the command did what it was asked                           |
//! | 1    | `Runtime`       | a stage failed, a file could not be read or written         |
//! | 2    | `Usage`         | a bad flag or value, a bad pipeline/scene file, a bad input |
//! | 130  | `Interrupted`   | Ctrl-C: the outputs were finalised with what was processed  |
//! | 143, 129 | `Interrupted` | SIGTERM, SIGHUP (the binary exits 128 + the signal)     |

use crate::engine::config::ConfigError;
use crate::engine::RunReport;
use std::fmt;
use std::path::{Path, PathBuf};

/// What kind of failure an error is; decides the exit status.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorKind {
    /// Something failed while running (exit 1).
    Runtime,
    /// The request was wrong: a flag, a value, a configuration or input file (exit 2).
    Usage,
    /// Stopped by the user (exit 130).
    Interrupted,
}

impl ErrorKind {
    /// The exit status table (see the module documentation).
    pub const fn exit_code(self) -> u8 {
        match self {
            ErrorKind::Runtime => 1,
            ErrorKind::Usage => 2,
            ErrorKind::Interrupted => 130,
        }
    }
}

/// A wrong option value, named by the option (its command-line spelling,
/// e.g. `--fps`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UsageError {
    pub option: String,
    pub message: String,
}

impl UsageError {
    pub fn new(option: impl Into<String>, message: impl Into<String>) -> UsageError {
        UsageError {
            option: option.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for UsageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.option, self.message)
    }
}

impl std::error::Error for UsageError {}

/// Why a recipe failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An option's value is wrong.
    #[error(transparent)]
    Usage(#[from] UsageError),
    /// A pipeline or scene file (or a stage parameter) is wrong.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// An input file is missing or unusable (the user's to fix).
    #[error("{}: {message}", path.display())]
    Input { path: PathBuf, message: String },
    /// One or more stages failed; sinks finalised what reached them.
    #[error("{}", stage_errors(report))]
    Stages { report: Box<RunReport> },
    /// Ctrl-C; sinks finalised what reached them.
    #[error("interrupted: outputs were finalised with what was processed")]
    Interrupted { report: Box<RunReport> },
    /// Anything else that failed at run time (I/O, a failed fit, ...).
    #[error(transparent)]
    Runtime(#[from] anyhow::Error),
}

fn stage_errors(r: &RunReport) -> String {
    r.errors
        .iter()
        .map(|e| crate::engine::error_chain(e))
        .collect::<Vec<_>>()
        .join("\nerror: ")
}

impl Error {
    /// The kind of failure (and so the exit status).
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::Usage(_) | Error::Config(_) | Error::Input { .. } => ErrorKind::Usage,
            Error::Stages { .. } => ErrorKind::Runtime,
            Error::Interrupted { .. } => ErrorKind::Interrupted,
            Error::Runtime(e) => kind_of(e),
        }
    }

    /// The run's per-stage report, when a pipeline ran (for `--stats`).
    pub fn run_report(&self) -> Option<&RunReport> {
        match self {
            Error::Stages { report } | Error::Interrupted { report } => Some(report),
            _ => None,
        }
    }

    pub(crate) fn input(path: impl Into<PathBuf>, message: impl Into<String>) -> Error {
        Error::Input {
            path: path.into(),
            message: message.into(),
        }
    }

    pub(crate) fn usage(option: impl Into<String>, message: impl Into<String>) -> Error {
        Error::Usage(UsageError::new(option, message))
    }
}

/// Refuses, before any work starts, an output that would destroy an input
/// or cannot be written: an output that is the same file as an input
/// ([`crate::io::atomic::same_file`]: device and inode), two outputs that
/// are one file, an output that is a directory or whose directory does not
/// exist. Each is a usage error naming the paths.
pub fn check_outputs(inputs: &[&Path], outputs: &[&Path]) -> Result<()> {
    for (k, out) in outputs.iter().enumerate() {
        if out.as_os_str() == "-" {
            continue;
        }
        if let Some(input) = inputs
            .iter()
            .find(|i| i.as_os_str() != "-" && crate::io::atomic::same_file(i, out))
        {
            return Err(Error::input(
                out,
                format!(
                    "is the same file as the input {}; refusing to overwrite an input (choose another output path)",
                    input.display()
                ),
            ));
        }
        if let Some(other) = outputs[..k]
            .iter()
            .find(|o| *o == out || crate::io::atomic::same_file(o, out))
        {
            return Err(Error::input(
                out,
                format!(
                    "is also the path of another output ({}); give each output its own path",
                    other.display()
                ),
            ));
        }
        if out.is_dir() {
            return Err(Error::input(out, "is a directory; give a file path"));
        }
        let parent = out.parent().filter(|p| !p.as_os_str().is_empty());
        if let Some(d) = parent {
            if !d.is_dir() {
                return Err(Error::input(
                    out,
                    format!("the directory {} does not exist", d.display()),
                ));
            }
        }
    }
    Ok(())
}

/// The kind of any error chain: a recipe [`Error`], a [`ConfigError`] or a
/// [`UsageError`] anywhere in it decides; anything else is a runtime error.
pub fn kind_of(e: &anyhow::Error) -> ErrorKind {
    for cause in e.chain() {
        if let Some(r) = cause.downcast_ref::<Error>() {
            if !matches!(r, Error::Runtime(_)) {
                return r.kind();
            }
        }
        if cause.is::<ConfigError>() || cause.is::<UsageError>() {
            return ErrorKind::Usage;
        }
    }
    ErrorKind::Runtime
}

/// Results of the recipes.
pub type Result<T, E = Error> = std::result::Result<T, E>;
