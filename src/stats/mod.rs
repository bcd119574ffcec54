//! Statistics of channels: summaries, Allan deviations, noise-term identification,
//! Welch PSD and autocorrelation, and the special functions (`special`).

pub mod acf;
pub mod adev;
pub mod noise_terms;
pub mod psd;
pub mod rate_unit;
pub mod special;
pub mod summary;

pub use summary::{ChannelSummary, summarize};
