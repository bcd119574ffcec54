//! The bias instability as a datasheet reads it: the minimum of the Allan deviation
//! divided by sqrt(2 ln 2 / pi) = 0.664.
//!
//! IEEE Std 952-1997 Annex C reads the bias instability B off the flat part of the
//! Allan deviation, sigma(tau) = B sqrt(2 ln 2 / pi) where the curve's slope is 0;
//! MATLAB's `allanvar` example ("Inertial Sensor Noise Analysis Using Allan Variance")
//! and sensor datasheets take the curve's minimum for that point. The fitted `b` of
//! [`super::identify_curve`] is the flicker term's own coefficient: where white noise
//! and a rate random walk still add to the curve at its minimum, it is smaller than
//! the reading, which counts them as bias instability. Both are reported; the reading
//! is the number to compare with a datasheet or a published curve.
//!
//! Uncertainty: the overlapping Allan deviation at the minimum with Greenhall's EDF nu
//! for flicker FM (alpha = -1, the noise type that is flat there) has a relative
//! standard uncertainty 1 / sqrt(2 nu) (chi-square with nu degrees of freedom, to first
//! order); the reading's is the same relative uncertainty. Taking the minimum of noisy
//! points biases the reading low by a fraction of that; it is not corrected.

use super::fit::AvarPoint;
use crate::stats::adev::edf_greenhall;

/// sqrt(2 ln 2 / pi): the flat level of the Allan deviation of a bias instability B,
/// sigma = B sqrt(2 ln 2 / pi) (IEEE Std 952-1997 Annex C, table C.1).
pub fn flicker_floor_factor() -> f64 {
    (2.0 * std::f64::consts::LN_2 / std::f64::consts::PI).sqrt()
}

/// The curve-minimum reading of the bias instability.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MinimumReading {
    /// The averaging time of the minimum \[s\] and its averaging factor.
    pub tau_s: f64,
    pub m: usize,
    /// The Allan deviation there, u.
    pub adev: f64,
    /// Greenhall's EDF of that point for flicker FM.
    pub edf: f64,
    /// The reading B = adev / sqrt(2 ln 2 / pi), u, and its standard uncertainty.
    pub b: f64,
    pub b_unc: f64,
    /// True when the minimum is the curve's last tau: the curve was still falling
    /// there, so the reading is an upper bound of the floor, not a floor.
    pub at_last_tau: bool,
}

/// The reading from the octave points of the overlapping AVAR of `n_samples` rate
/// samples (points with zero or non-finite AVAR skipped); None when no point is left
/// or the curve has fewer than three points.
pub fn minimum_reading(points: &[AvarPoint], n_samples: usize) -> Option<MinimumReading> {
    let pts: Vec<&AvarPoint> = points
        .iter()
        .filter(|p| p.avar.is_finite() && p.avar > 0.0)
        .collect();
    if pts.len() < 3 {
        return None;
    }
    let (i, p) = pts
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.avar.total_cmp(&b.1.avar))?;
    let adev = p.avar.sqrt();
    let edf = edf_greenhall(-1, 2, p.m, n_samples + 1, true, false)
        .filter(|v| v.is_finite() && *v > 0.0)?;
    let b = adev / flicker_floor_factor();
    Some(MinimumReading {
        tau_s: p.tau_s,
        m: p.m,
        adev,
        edf,
        b,
        b_unc: b / (2.0 * edf).sqrt(),
        at_last_tau: i + 1 == pts.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(m: usize, avar: f64) -> AvarPoint {
        AvarPoint {
            m,
            tau_s: m as f64 * 0.01,
            avar,
        }
    }

    #[test]
    fn the_reading_is_the_minimum_deviation_over_0_664() {
        // white noise n = 0.1 u sqrt(s) plus a flat floor 0.02 u, rate 100 Hz
        let pts: Vec<AvarPoint> = (0..16)
            .map(|j| {
                let m = 1usize << j;
                let tau = m as f64 * 0.01;
                pt(m, 0.01 / tau + 0.0004 + 1e-5 * tau)
            })
            .collect();
        let r = minimum_reading(&pts, 1 << 20).unwrap();
        let best = pts
            .iter()
            .map(|p| p.avar)
            .fold(f64::INFINITY, f64::min)
            .sqrt();
        assert_eq!(r.adev, best);
        assert!((r.b - best / 0.664_282_9).abs() < 1e-6 * r.b, "{}", r.b);
        assert!(!r.at_last_tau);
        assert!(r.b_unc > 0.0 && r.b_unc < 0.5 * r.b);
        // the floor plus what the white noise and the walk still add there
        assert!(r.b > 0.02 / flicker_floor_factor());
    }

    #[test]
    fn a_falling_curve_is_flagged_as_a_bound() {
        let pts: Vec<AvarPoint> = (0..8).map(|j| pt(1 << j, 1.0 / (1 << j) as f64)).collect();
        let r = minimum_reading(&pts, 1 << 12).unwrap();
        assert!(r.at_last_tau);
        assert_eq!(r.m, 128);
        assert!(minimum_reading(&pts[..2], 1 << 12).is_none());
    }
}
