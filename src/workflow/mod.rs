//! The paper's workflow, end to end: preparing a static gyro log (Pauta outlier
//! rejection, the reverse-arrangement stationarity test, trend removal or differencing,
//! mean removal), choosing the FARMA order with evidence (order table, F-tests, the
//! linear ARMA baseline, a bootstrap test of constant coefficients), checking the
//! chosen model (residual whiteness, hold-out prediction, polynomial fits of the f_m),
//! and all of it for every channel of a log.
//!
//! One file per step: [`pauta`], [`stationarity`], [`prep`], [`select`],
//! [`constancy`], [`ljung_box`], [`check`], [`analyze`] (all of it for one channel);
//! [`dist`] holds the distribution functions the tests need; [`tables`] the Parquet
//! outputs.

#![allow(clippy::needless_range_loop)] // numeric kernels index several arrays in step

pub mod analyze;
pub mod check;
pub mod constancy;
pub mod dist;
pub mod ljung_box;
pub mod pauta;
pub mod prep;
pub mod select;
pub mod stationarity;
pub mod tables;
