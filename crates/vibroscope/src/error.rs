//! One error type for the recipes, and the one table from what went wrong
//! to the process exit status.
//!
//! | exit | [`ErrorKind`]   | when                                                        |
//! |------|-----------------|-------------------------------------------------------------|
//! | 0    | (success)       | the command did what it was asked                           |
//! | 1    | `Runtime`       | a stage failed, a file could not be read or written, a fit  |
//! |      |                 | failed, a device or ffmpeg failed                           |
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
    /// A file could not be read or written: a video, a WAV, a whole-file
    /// write, a picture or a plot (each message names the file).
    #[error(transparent)]
    File(#[from] crate::io::Error),
    /// A JSON document could not be encoded or read back.
    #[error("{}: {message}", path.display())]
    Document { path: PathBuf, message: String },
    /// The mathematics refused its input or could not fit it.
    #[error(transparent)]
    Math(#[from] crate::math::MathError),
    /// The forward model refused a parameter or its sound file.
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
    /// The analysis ran but found nothing it can report (said in words:
    /// what is missing and why).
    #[error("{0}")]
    Analysis(String),
    /// A capture device or sound card could not be listed or opened.
    #[error("{0}")]
    Device(String),
    /// An external program (ffmpeg) could not run or failed.
    #[error("{program}: {message}")]
    Program {
        program: &'static str,
        message: String,
    },
    /// The engine could not start the pipeline: a stage failed to open.
    #[error("{file}: cannot start the pipeline")]
    Start {
        file: String,
        #[source]
        source: Box<crate::engine::RunError>,
    },
}

impl From<crate::io::VideoError> for Error {
    fn from(e: crate::io::VideoError) -> Error {
        Error::File(e.into())
    }
}

impl From<crate::io::wav::WavError> for Error {
    fn from(e: crate::io::wav::WavError) -> Error {
        Error::File(e.into())
    }
}

impl From<crate::io::atomic::WriteError> for Error {
    fn from(e: crate::io::atomic::WriteError) -> Error {
        Error::File(e.into())
    }
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
            Error::Interrupted { .. } => ErrorKind::Interrupted,
            // A stage that cannot open because of its configuration is the
            // user's to fix; anything else failed while running.
            Error::Start { source, .. } => kind_of(source.as_ref()),
            Error::Stages { .. }
            | Error::File(_)
            | Error::Document { .. }
            | Error::Math(_)
            | Error::Sim(_)
            | Error::Analysis(_)
            | Error::Device(_)
            | Error::Program { .. } => ErrorKind::Runtime,
        }
    }

    /// The run's per-stage report, when a pipeline ran (for `--stats`).
    pub fn run_report(&self) -> Option<&RunReport> {
        match self {
            Error::Stages { report } | Error::Interrupted { report } => Some(report),
            _ => None,
        }
    }

    /// A run stopped by damage in its recording (a frame cut short or
    /// malformed, a bad header) becomes [`Error::Input`] naming the file
    /// (exit 2); any other error is returned unchanged. For a command that
    /// makes nothing of part of a recording (`calibrate`): the file is the
    /// user's to fix, where `listen` keeps what it read and exits 1.
    pub(crate) fn damaged_recording_as_input(self) -> Error {
        use crate::engine::StageError;
        use crate::io::VideoError;
        let Error::Stages { report } = &self else {
            return self;
        };
        let damaged = report.errors.iter().find_map(|e| match &e.source {
            StageError::Video(
                v @ (VideoError::Truncated { .. }
                | VideoError::BadFrame { .. }
                | VideoError::Malformed { .. }
                | VideoError::Header { .. }),
            ) => Some(v),
            _ => None,
        });
        match damaged {
            Some(v) => {
                let text = v.to_string();
                let prefix = format!("{}: ", v.path());
                let message = text.strip_prefix(&prefix).unwrap_or(&text).to_string();
                Error::input(v.path(), message)
            }
            None => self,
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

/// The kind of any error and its chain of sources: a recipe [`Error`], a
/// [`ConfigError`] or a [`UsageError`] anywhere in it decides; anything
/// else is a runtime error.
pub fn kind_of(e: &(dyn std::error::Error + 'static)) -> ErrorKind {
    let mut cause = Some(e);
    while let Some(c) = cause {
        if let Some(r) = c.downcast_ref::<Error>() {
            return r.kind();
        }
        if c.is::<ConfigError>() || c.is::<UsageError>() {
            return ErrorKind::Usage;
        }
        cause = c.source();
    }
    ErrorKind::Runtime
}

/// Results of the recipes.
pub type Result<T, E = Error> = std::result::Result<T, E>;
