//! Statistics of channels: summaries now; Allan deviation, PSD and ACF as they arrive.

pub mod adev;
pub mod summary;

pub use summary::{ChannelSummary, summarize};
