//! Jobs: one log, many channels. A job takes an opened log and parameters checked
//! once, runs its channels in parallel, names every channel that failed at once (its
//! outputs are written for every channel or for none), stages its tables in an
//! output folder and commits them; it returns what a caller prints. The commands of
//! `cli/` build a job from their arguments and print its result as text or JSON;
//! a batch of many logs runs the same jobs.
//!
//! - [`adev`]: Allan deviation curves and noise terms (`farma adev`);
//! - [`fit`]: FARMA fits (`farma fit`), with the update state; [`fit2`]: fits on a 2-D
//!   index (`farma fit --index lag,CHANNEL`);
//! - [`update`]: online updates of a model folder over a new log (`farma update`);
//! - [`check`]: a saved model checked on a log (`farma check`);
//! - [`prep`]: the paper's preparation of channels (`farma prep`);
//! - [`psd`]: Welch power spectral densities (`farma psd`);
//! - [`select`]: the order table, F-tests and constancy test (`farma select`);
//! - [`analyze`]: the whole workflow (`farma analyze`).

pub mod adev;
pub mod analyze;
pub mod check;
pub mod fit;
pub mod fit2;
pub mod gap;
pub mod prep;
pub mod psd;
pub mod select;
pub mod update;

use std::path::Path;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::output::OutputSet;
use crate::store::Store;

/// An error of one channel's work on `log`, named with the channel: a usage or data
/// error becomes an error of the log's channel, a too-short series says which log and
/// channel; other errors (which name their file and column already) stay as they are.
pub fn on_channel(log: &Path, channel: &str, e: Error) -> Error {
    match e {
        Error::Usage(msg) | Error::Data(msg) => Error::Column {
            path: log.to_path_buf(),
            msg: format!("channel '{channel}': {msg}"),
        },
        Error::TooShort { what, need, have } => Error::TooShort {
            what: format!("{}: channel {channel}: {what}", log.display()),
            need,
            have,
        },
        other => other,
    }
}

/// The results of a job's per-channel work, in channel order: every value; or the
/// error of the one channel that failed; or, when several did, all their errors in
/// channel order ([`Error::Channels`]), so that one rerun sees every failing channel.
/// `hint` says what to do (the last line of the message).
pub fn every_channel<T>(results: Vec<Result<T>>, hint: &'static str) -> Result<Vec<T>> {
    let of = results.len();
    let mut values = Vec::with_capacity(of);
    let mut errors = Vec::new();
    for r in results {
        match r {
            Ok(v) => values.push(v),
            Err(e) => errors.push(e),
        }
    }
    match errors.len() {
        0 => Ok(values),
        1 => Err(errors.pop().expect("one error")),
        _ => Err(Error::Channels { errors, of, hint }),
    }
}

/// Runs `work` on every channel of `names` in parallel (rayon), each error named with
/// its channel ([`on_channel`]); every failing channel is named at once
/// ([`every_channel`]).
pub fn map_channels<T, F>(
    log: &Path,
    names: &[String],
    hint: &'static str,
    work: F,
) -> Result<Vec<T>>
where
    T: Send,
    F: Fn(&str) -> Result<T> + Sync + Send,
{
    every_channel(
        names
            .par_iter()
            .map(|n| work(n).map_err(|e| on_channel(log, n, e)))
            .collect(),
        hint,
    )
}

/// Commits an output set ([`OutputSet::commit`]) and says on stderr which files of an
/// earlier run it removed.
pub fn commit_outputs(set: OutputSet, outputs: &[&str]) -> Result<()> {
    for stale in set.commit(outputs)? {
        eprintln!(
            "farma: removed {} (an earlier run's; this run does not write it)",
            stale.display()
        );
    }
    Ok(())
}

/// The file metadata every table of a job on `log` carries: the source's path, size
/// and modification time (what a rerun compares to know the input unchanged) and
/// the sample rate.
pub fn source_metadata(log: &Path, store: &Store) -> Result<Vec<(&'static str, String)>> {
    let (size, mtime) = crate::log::source_identity(log)?;
    Ok(vec![
        ("source", log.display().to_string()),
        ("source_size", size.to_string()),
        ("source_mtime_ns", mtime.to_string()),
        ("sample_rate_hz", store.sample_rate_hz().to_string()),
    ])
}

/// A log of several uniform segments (`--gaps split`) is fitted as one series: the
/// lags and residuals of the first samples after a gap reach across it. Said on
/// stderr (`adev`, `psd` and `acf` use the longest segment instead).
pub fn warn_gaps(store: &Store, log: &Path) {
    let segments = &store.meta().segments;
    if segments.len() > 1 {
        eprintln!(
            "farma: warning: {}: {} segments (gaps): fitted as one series, the lags x_(t-m) and residuals of the first samples after each gap reach across it; for a fit without, cut the log at its gaps or use --gaps interpolate",
            log.display(),
            segments.len()
        );
    }
}

/// Averages must not straddle a gap: the rows (start, len) of the longest uniform
/// segment (the whole log when it has one), with a warning on stderr when there are
/// several. Shared by `adev`, `psd` and `acf`.
pub fn longest_segment(store: &crate::store::Store, log: &std::path::Path) -> (usize, usize) {
    let segments = &store.meta().segments;
    match segments.iter().max_by_key(|s| s.len) {
        Some(s) if segments.len() > 1 => {
            eprintln!(
                "farma: warning: {}: {} segments (gaps); using the longest, rows {}..{}",
                log.display(),
                segments.len(),
                s.start,
                s.start + s.len
            );
            (s.start as usize, s.len as usize)
        }
        _ => (0, store.n_samples()),
    }
}
