//! Statistics of channels: summaries, Allan deviations, noise-term identification,
//! Welch PSD and autocorrelation, and the special functions (`special`).

pub mod acf;
pub mod adev;
pub mod noise_terms;
pub mod psd;
pub mod rate_unit;
pub mod special;
pub mod summary;

pub use summary::{ChannelSummary, Summarizer, summarize};

/// An error (exit 2) naming `what` (the log and channel) and the first non-finite
/// sample of `y` when it holds one: curves and spectra of a series holding Inf or NaN
/// are NaN throughout, so they are refused rather than written. (A log's NaN cells,
/// gaps, are refused or interpolated when it is read, `--nan`; a series reaching here
/// with one comes from a store written with it: a simulation that overflowed, a foreign
/// or damaged store.)
pub fn require_finite(what: &str, y: &[f64], rate_hz: f64) -> crate::error::Result<()> {
    match y.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => {
            let count = y.iter().filter(|v| !v.is_finite()).count();
            Err(crate::error::Error::Data(format!(
                "{what}: sample {i} (t = {} s into the series) is {}, and {count} value(s) in all are not finite: the result would be NaN throughout; repair or cut the log",
                crate::fmt::num(i as f64 / rate_hz),
                y[i]
            )))
        }
    }
}

/// An error naming `what` when a result computed from finite values overflowed:
/// `quantity` at `at` is not finite because the values of `y` are too large.
pub fn overflow_error(what: &str, quantity: &str, at: &str, y: &[f64]) -> crate::error::Error {
    let peak = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    crate::error::Error::Data(format!(
        "{what}: the {quantity} at {at} overflows f64: the values reach {}, whose squares and sums pass 1.8e308; rescale the channel (other units)",
        crate::fmt::num(peak)
    ))
}
