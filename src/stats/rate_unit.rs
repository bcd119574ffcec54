//! The rate unit of a gyro channel, and the identified IEEE Std 952 noise terms in the
//! units a datasheet prints and under the names of MATLAB's `gyroparams`.
//!
//! A coefficient identified in the log's rate unit u (q in u s, n in u sqrt(s), b in u,
//! k in u/sqrt(s), r in u/s, sigma in u: `noise_terms::Term::coef_unit`) is converted with
//! c = the unit in deg/s (deg/s 1, rad/s 180/pi, deg/h 1/3600):
//!
//! | term | datasheet | factor | gyroparams (SI) | factor |
//! |---|---|---|---|---|
//! | white_noise n | angle random walk, deg/sqrt(h) | c 60 | `NoiseDensity`, (rad/s)/sqrt(Hz) | c pi/180 |
//! | bias_instability b | bias instability, deg/h | c 3600 | `BiasInstability`, rad/s | c pi/180 |
//! | rate_random_walk k | rate random walk, deg/h/sqrt(h) | c 3600 60 | `RandomWalk`, (rad/s) sqrt(Hz) | c pi/180 |
//! | rate_ramp r | rate ramp, deg/h/h | c 3600^2 | none | |
//! | quantization q | angle quantization, deg | c | none | |
//! | gauss_markov sigma | correlated noise, deg/h | c 3600 | none | |
//!
//! (deg/sqrt(h): 1 deg/sqrt(s) is 60 deg/sqrt(h), as sqrt(3600 s) = 60 sqrt(s); IEEE Std
//! 952-1997 annex C; MATLAB's `gyroparams` documents NoiseDensity, BiasInstability and
//! RandomWalk in these SI units.)

use crate::error::{Error, Result};

/// A rate unit farma converts from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RateUnit {
    DegPerS,
    RadPerS,
    DegPerH,
}

impl RateUnit {
    /// From `--unit`: deg/s, rad/s or deg/h (also dps, rps, dph).
    pub fn from_flag(s: &str) -> Result<RateUnit> {
        match s.trim().to_ascii_lowercase().as_str() {
            "deg/s" | "dps" | "degps" => Ok(RateUnit::DegPerS),
            "rad/s" | "rps" | "rads" => Ok(RateUnit::RadPerS),
            "deg/h" | "dph" | "degph" => Ok(RateUnit::DegPerH),
            other => Err(Error::Usage(format!(
                "--unit: '{other}' is not deg/s, rad/s or deg/h"
            ))),
        }
    }

    /// From a channel name's suffix: `_dps`, `_degps`, `_deg_s` (deg/s); `_rps`,
    /// `_rads`, `_rad_s` (rad/s); `_dph`, `_degph`, `_deg_h` (deg/h). None otherwise.
    pub fn from_channel_name(name: &str) -> Option<RateUnit> {
        let n = name.to_ascii_lowercase();
        let ends = |s: &[&str]| s.iter().any(|x| n.ends_with(x));
        if ends(&["_dps", "_degps", "_deg_s"]) {
            Some(RateUnit::DegPerS)
        } else if ends(&["_rps", "_rads", "_rad_s"]) {
            Some(RateUnit::RadPerS)
        } else if ends(&["_dph", "_degph", "_deg_h"]) {
            Some(RateUnit::DegPerH)
        } else {
            None
        }
    }

    /// The unit as written: deg/s, rad/s, deg/h.
    pub fn name(self) -> &'static str {
        match self {
            RateUnit::DegPerS => "deg/s",
            RateUnit::RadPerS => "rad/s",
            RateUnit::DegPerH => "deg/h",
        }
    }

    /// One unit in deg/s.
    pub fn deg_per_s(self) -> f64 {
        match self {
            RateUnit::DegPerS => 1.0,
            RateUnit::RadPerS => 180.0 / std::f64::consts::PI,
            RateUnit::DegPerH => 1.0 / 3600.0,
        }
    }
}

/// A coefficient in another unit: value, uncertainty, unit and what it is called there.
#[derive(Clone, Debug, PartialEq)]
pub struct Converted {
    pub name: &'static str,
    pub value: f64,
    pub unc: f64,
    pub unit: &'static str,
}

/// The datasheet form of the term `kind` (a component kind: white_noise,
/// bias_instability, ...) with coefficient `value` +- `unc` in `unit` (module doc).
pub fn datasheet(kind: &str, value: f64, unc: f64, unit: RateUnit) -> Option<Converted> {
    let c = unit.deg_per_s();
    let (name, factor, u) = match kind {
        "white_noise" => ("angle random walk", c * 60.0, "deg/sqrt(h)"),
        "bias_instability" => ("bias instability", c * 3600.0, "deg/h"),
        "rate_random_walk" => ("rate random walk", c * 3600.0 * 60.0, "deg/h/sqrt(h)"),
        "rate_ramp" => ("rate ramp", c * 3600.0 * 3600.0, "deg/h/h"),
        "quantization" => ("angle quantization", c, "deg"),
        "gauss_markov" => ("correlated noise", c * 3600.0, "deg/h"),
        _ => return None,
    };
    Some(Converted {
        name,
        value: value * factor,
        unc: unc * factor,
        unit: u,
    })
}

/// The MATLAB `gyroparams` property of the term `kind`, in SI units (module doc); None
/// for a term `gyroparams` has no property for.
pub fn gyroparams(kind: &str, value: f64, unc: f64, unit: RateUnit) -> Option<Converted> {
    let f = unit.deg_per_s() * std::f64::consts::PI / 180.0;
    let (name, u) = match kind {
        "white_noise" => ("NoiseDensity", "(rad/s)/sqrt(Hz)"),
        "bias_instability" => ("BiasInstability", "rad/s"),
        "rate_random_walk" => ("RandomWalk", "(rad/s)*sqrt(Hz)"),
        _ => return None,
    };
    Some(Converted {
        name,
        value: value * f,
        unc: unc * f,
        unit: u,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Datasheet figures of known sensors converted by hand: the ADIS16405's angle
    /// random walk 2.0 deg/sqrt(h) is n = 2/60 deg/s sqrt(s) (its spec in
    /// fixtures/specs), and 0.007 deg/s of bias instability is 25.2 deg/h.
    #[test]
    fn conversions_match_hand_computed_datasheet_figures() {
        let arw = datasheet("white_noise", 2.0 / 60.0, 0.0, RateUnit::DegPerS).unwrap();
        assert!((arw.value - 2.0).abs() < 1e-12 && arw.unit == "deg/sqrt(h)");
        let bi = datasheet("bias_instability", 0.007, 0.001, RateUnit::DegPerS).unwrap();
        assert!((bi.value - 25.2).abs() < 1e-9 && (bi.unc - 3.6).abs() < 1e-12);
        // 1 deg/h of bias instability given in rad/s
        let bi = datasheet(
            "bias_instability",
            1.0 / 3600.0 * std::f64::consts::PI / 180.0,
            0.0,
            RateUnit::RadPerS,
        )
        .unwrap();
        assert!((bi.value - 1.0).abs() < 1e-12);
        // a rate in deg/h: ARW n deg/h sqrt(s) = n / 60 deg/sqrt(h)
        let arw = datasheet("white_noise", 6.0, 0.0, RateUnit::DegPerH).unwrap();
        assert!((arw.value - 0.1).abs() < 1e-12);
        let rrw = datasheet("rate_random_walk", 1e-6, 0.0, RateUnit::DegPerS).unwrap();
        assert!((rrw.value - 0.216).abs() < 1e-12 && rrw.unit == "deg/h/sqrt(h)");
        // gyroparams: 1 deg/s sqrt(s) of white noise is pi/180 (rad/s)/sqrt(Hz)
        let nd = gyroparams("white_noise", 1.0, 0.0, RateUnit::DegPerS).unwrap();
        assert_eq!(nd.name, "NoiseDensity");
        assert!((nd.value - std::f64::consts::PI / 180.0).abs() < 1e-15);
        assert!(gyroparams("quantization", 1.0, 0.0, RateUnit::DegPerS).is_none());
    }

    #[test]
    fn units_from_flags_and_names() {
        assert_eq!(RateUnit::from_flag("deg/s").unwrap(), RateUnit::DegPerS);
        assert_eq!(RateUnit::from_flag("RAD/S").unwrap(), RateUnit::RadPerS);
        assert!(RateUnit::from_flag("g").is_err());
        assert_eq!(
            RateUnit::from_channel_name("gyro_x_dps"),
            Some(RateUnit::DegPerS)
        );
        assert_eq!(
            RateUnit::from_channel_name("wz_rad_s"),
            Some(RateUnit::RadPerS)
        );
        assert_eq!(
            RateUnit::from_channel_name("fog_dph"),
            Some(RateUnit::DegPerH)
        );
        assert_eq!(RateUnit::from_channel_name("gyro_x"), None);
    }
}
