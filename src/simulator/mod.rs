//! The gyro drift simulator: a spec of noise components per channel, and (later) the
//! generator.
//!
//! - [`spec`]: the simulation spec of `../shared/design/contracts.md` section 2 (TOML):
//!   parsing, validation with errors that name the key, and writing a spec back out.

pub mod spec;

pub use spec::{ChannelSpec, Component, FarmaModel, Kind, Spec, load_spec, parse_spec};
