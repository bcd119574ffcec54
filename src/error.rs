//! Errors: what can go wrong, and the exit code each maps to.
//!
//! Every error names the file and, where it applies, the line, column or key that is
//! wrong. Problems with what the user handed us (the log, a flag, a spec) exit with
//! code 2; problems of our own making or of the machine (a failed write of an output,
//! an internal invariant) exit with code 1. Nothing is printed here: the binary prints
//! `farma: error: {error}` on stderr.

use std::path::{Path, PathBuf};

/// Exit code for success.
pub const EXIT_OK: i32 = 0;
/// Exit code for failures not caused by the input (output I/O, internal errors).
pub const EXIT_FAILURE: i32 = 1;
/// Exit code for bad input: malformed logs, unknown channels, bad flags or specs.
pub const EXIT_BAD_INPUT: i32 = 2;

/// Result alias used throughout the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in farma.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A row of a text log does not have the expected shape (field count, truncated line).
    #[error("{}:{line}: {msg}", path.display())]
    Malformed {
        path: PathBuf,
        line: u64,
        msg: String,
    },

    /// A cell that should hold a number does not.
    #[error("{}:{line}: column '{column}': cannot parse '{text}' as a number", path.display())]
    NonNumeric {
        path: PathBuf,
        line: u64,
        column: String,
        text: String,
    },

    /// NaN, infinite or missing values under `--nan reject`.
    #[error("{}: column '{column}' has {count} non-finite or missing value(s) (NaN/Inf/empty), first at {first}; {hint}", path.display())]
    NonFinite {
        path: PathBuf,
        column: String,
        count: u64,
        /// Human-readable list of the first positions ("line 12, line 40").
        first: String,
        /// What to do about it.
        hint: String,
    },

    /// The time column is not strictly increasing or not uniformly sampled.
    #[error("{}: {msg}", path.display())]
    Timestamps { path: PathBuf, msg: String },

    /// A requested column is missing, unknown, duplicated or of the wrong type.
    #[error("{}: {msg}", path.display())]
    Column { path: PathBuf, msg: String },

    /// The file holds no data (empty, header only, or cut short).
    #[error("{}: {msg}", path.display())]
    Empty { path: PathBuf, msg: String },

    /// The file is not a log farma can read (unknown or corrupt format).
    #[error("{}: {msg}", path.display())]
    Format { path: PathBuf, msg: String },

    /// No time column, no `sample_rate_hz` metadata and no `--rate`.
    #[error("{}: no time base: no time column (time, time_s, t, timestamp or --time-col), no 'sample_rate_hz' in the file metadata, and no --rate", path.display())]
    NoTimeBase { path: PathBuf },

    /// The log holds fewer samples than the request needs.
    #[error("{what}: the log is too short: {have} sample(s), need at least {need}")]
    TooShort { what: String, need: u64, have: u64 },

    /// Invalid flags or parameters.
    #[error("{0}")]
    Usage(String),

    /// Units of a batch failed (each error printed and kept in the manifest); the
    /// others ran.
    #[error(
        "{failed} of {of} unit(s) failed (listed above; the manifest's error column holds each)"
    )]
    BatchFailed { failed: usize, of: usize },

    /// A channel's values cannot be processed as asked: constant, non-finite, beyond
    /// f64's reach, or a singular design. Raised by the numeric code, which does not
    /// know the log; a job names the log and channel ([`crate::jobs::on_channel`]).
    #[error("{0}")]
    Data(String),

    /// The input could not be read (missing file, permission).
    #[error("cannot read {}: {source}", path.display())]
    InputIo {
        path: PathBuf,
        source: std::io::Error,
    },

    /// An output could not be written.
    #[error("cannot write {}: {source}", path.display())]
    OutputIo {
        path: PathBuf,
        source: std::io::Error,
    },

    /// The reader of stdout closed it (`farma ... --json | head -1`): the command stops
    /// printing and exits 0 without a message (its outputs are already committed).
    #[error("stdout closed by its reader")]
    StdoutClosed,

    /// A bug or an unexpected library failure.
    #[error("internal error: {0}")]
    Internal(String),

    /// Several channels of one run failed: each one's error, in channel order (`of`
    /// channels in the run); nothing was written. Shown as one `farma: error:` line
    /// per channel and a last one that counts them and gives `hint`.
    #[error("{}", channels_message(errors, *of, hint))]
    Channels {
        errors: Vec<Error>,
        of: usize,
        hint: &'static str,
    },
}

fn channels_message(errors: &[Error], of: usize, hint: &str) -> String {
    let mut s = String::new();
    for e in errors {
        s.push_str(&e.to_string());
        s.push_str("\nfarma: error: ");
    }
    s.push_str(&format!(
        "{} of {of} channels failed (above); nothing was written: a run writes the outputs of every channel or of none ({hint})",
        errors.len()
    ));
    s
}

impl Error {
    /// The process exit code for this error: 2 for bad input, 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::OutputIo { .. } | Error::Internal(_) => EXIT_FAILURE,
            // bad input if any channel's input was bad: that is the user's to fix
            Error::Channels { errors, .. } => errors
                .iter()
                .map(Error::exit_code)
                .max()
                .unwrap_or(EXIT_FAILURE),
            _ => EXIT_BAD_INPUT,
        }
    }

    pub(crate) fn input_io(path: &Path, source: std::io::Error) -> Self {
        Error::InputIo {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn output_io(path: &Path, source: std::io::Error) -> Self {
        Error::OutputIo {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn format(path: &Path, msg: impl Into<String>) -> Self {
        Error::Format {
            path: path.to_path_buf(),
            msg: msg.into(),
        }
    }

    pub(crate) fn column(path: &Path, msg: impl Into<String>) -> Self {
        Error::Column {
            path: path.to_path_buf(),
            msg: msg.into(),
        }
    }

    pub(crate) fn empty(path: &Path, msg: impl Into<String>) -> Self {
        Error::Empty {
            path: path.to_path_buf(),
            msg: msg.into(),
        }
    }

    pub(crate) fn timestamps(path: &Path, msg: impl Into<String>) -> Self {
        Error::Timestamps {
            path: path.to_path_buf(),
            msg: msg.into(),
        }
    }
}
