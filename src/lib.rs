//! farma: nonparametric ARMA (FARMA) models of gyroscope random drift from long
//! test-stand logs, and diagnosis of where a gyro simulator differs from the sensor.
//!
//! Where things are:
//! - [`model`]: the fitted FARMA model every verb reads, its fit and update reports,
//!   the update state and the model folder on disk;
//! - [`estimator`]: the FARMA estimator (the alternation, local-linear fits, GCV,
//!   fast exact moment tables, online updates);
//! - [`log`]: reading logs (CSV, Parquet, Arrow IPC) with their time base and the
//!   policies for bad values and irregular sampling;
//! - [`store`]: the memory-mapped Arrow IPC store every command reads;
//! - [`stats`]: channel statistics (Allan deviations, noise terms, PSD, ACF);
//! - [`simulator`]: the gyro drift simulator (the simulation spec and the generator);
//! - [`diagnosis`]: the sim-to-real gap diagnosis (`farma gap`);
//! - [`num`]: numeric primitives (fast exact rounding);
//! - [`output`]: Parquet tables written atomically, JSON helpers;
//! - [`workflow`]: the paper's workflow (prep, select, check, analyze);
//! - [`cli`]: the `farma` command line (a thin layer over the above);
//! - [`error`]: the error enum and exit codes.

pub mod batch;
pub mod cli;
pub mod diagnosis;
pub mod error;
pub mod estimator;
pub mod fmt;
pub mod jobs;
pub mod log;
pub mod model;
pub mod num;
pub mod output;
pub mod report;
pub mod simulator;
pub mod stats;
pub mod store;
pub mod workflow;

pub use error::{Error, Result};
