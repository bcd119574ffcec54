//! Statistics of channels: summaries now; Allan deviation, PSD and ACF as they arrive.

pub mod acf;
pub mod adev;
pub mod noise_terms;
pub mod psd;
pub mod summary;

pub use summary::{ChannelSummary, summarize};
