//! The gyro drift simulator: a spec of noise components per channel, and the generator
//! that turns it into simulated channels.
//!
//! - [`spec`]: the simulation spec of `docs/contracts.md` section 2 (TOML):
//!   parsing, validation with errors that name the key, and writing a spec back out.
//! - [`generate`]: the generator, every component kind, deterministic per seed and
//!   independent of the thread count.
//! - [`write`](mod@write): writing a simulated log (Parquet, farma store, CSV) atomically.

pub mod generate;
pub mod spec;
pub mod write;

pub use generate::{SimRequest, Simulated, Simulator, component_signal, simulate};
pub use spec::{
    ChannelSpec, Component, Discretization, FarmaModel, Kind, Spec, load_spec, parse_spec,
};
