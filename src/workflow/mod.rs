//! The paper's workflow, end to end: preparing a static gyro log (Pauta outlier
//! rejection, the reverse-arrangement stationarity test, trend removal or differencing,
//! mean removal), choosing the FARMA order with evidence (order table, F-tests, the
//! linear ARMA baseline, a bootstrap test of constant coefficients), checking the
//! chosen model (residual whiteness, hold-out prediction, polynomial fits of the f_m),
//! and all of it for every channel of a log.
//!
//! One file per step: [`pauta`], [`stationarity`], [`prep`], [`select`],
//! [`constancy`], [`ljung_box`], [`check`], [`analyze`] (all of it for one channel);
//! [`tables`] holds the Parquet outputs. The distribution functions the tests need
//! (normal, chi-squared and F tails) are in [`crate::stats::special`].

#![allow(clippy::needless_range_loop)] // numeric kernels index several arrays in step

pub mod analyze;
pub mod budget;
pub mod check;
pub mod constancy;
pub mod ljung_box;
pub mod pauta;
pub mod prep;
pub mod select;
pub mod stationarity;
pub mod tables;

/// The level of the workflow's tests (5 %): the default of `--alpha` and the level the
/// order table, the constancy test and the stationarity test are read at.
pub const ALPHA: f64 = 0.05;

/// The one rejection rule of every test of the workflow: H0 is rejected when
/// p <= alpha. For a bootstrap p-value p = (1 + #{T* >= T}) / (B + 1) this is the Monte
/// Carlo test of exact level alpha when alpha (B + 1) is an integer (Davison and
/// Hinkley, Bootstrap Methods and their Application, 1997, section 4.2.5): with B = 19
/// the one way to reject at 5 % is T above every T*, p = 0.05 exactly, which `<` would
/// never reject. A NaN p-value rejects nothing.
pub fn rejects(p_value: f64, alpha: f64) -> bool {
    p_value <= alpha
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejection_rule_includes_the_level_itself() {
        assert!(rejects(0.05, ALPHA));
        assert!(rejects(1.0 / 20.0, ALPHA)); // B = 19, T above every T*
        assert!(rejects(0.0, ALPHA));
        assert!(!rejects(0.050_000_001, ALPHA));
        assert!(!rejects(2.0 / 20.0, ALPHA)); // B = 19, one T* at least T
        assert!(!rejects(f64::NAN, ALPHA));
    }
}
