//! The Allan variance of each IEEE Std 952 noise term, as a function of the averaging
//! time tau \[s\]: AVAR(tau) = coefficient^2 * basis(tau).
//!
//! Sources: IEEE Std 952-1997, Annex C (C.1-C.6: quantization, angle random walk, bias
//! instability, rate random walk, rate ramp, exponentially correlated (Markov) noise);
//! N. El-Sheimy, H. Hou, X. Niu, "Analysis and modeling of inertial sensors using Allan
//! variance", IEEE Trans. Instrum. Meas. 57(1), 2008 (the terms and their Allan
//! variances, exponentially correlated noise included).
//!
//! | term | coefficient | AVAR(tau) |
//! |---|---|---|
//! | quantization | Q [u s] | 3 Q^2 / tau^2 |
//! | white noise (angle random walk) | N [u sqrt(s)] | N^2 / tau |
//! | bias instability | B \[u\] | (2 ln 2 / pi) B^2 (the flat floor; ADEV 0.664 B) |
//! | rate random walk | K [u / sqrt(s)] | K^2 tau / 3 |
//! | rate ramp | R [u / s] | R^2 tau^2 / 2 |
//! | first-order Gauss-Markov | sigma \[u\], T \[s\] | sigma^2 g(tau / T) |
//!
//! Gauss-Markov (autocovariance sigma^2 exp(-|s| / T)): with the angle structure
//! function D(s) = E[(theta(t+s) - theta(t))^2] = 2 sigma^2 (T s - T^2 (1 - e^{-s/T})),
//! AVAR(tau) = (4 D(tau) - D(2 tau)) / (2 tau^2), which is
//! g(x) = (1 / x) [2 - (1 / x)(3 - 4 e^{-x} + e^{-2x})], x = tau / T
//! (El-Sheimy et al.'s form, with their q_c^2 = 2 sigma^2 / T; derived here from D and
//! checked against a numerical integral in the tests below). Limits: g ~ 2x/3 for
//! x -> 0 (a rate random walk with K^2 = 2 sigma^2 / T) and g ~ 2 / x for x -> inf
//! (white noise with N^2 = 2 sigma^2 T). Below x = 0.1 the Taylor series
//! g(x) = 2x/3 - x^2/2 + 7x^3/30 - x^4/12 + 31x^5/1260 - x^6/160 + ... replaces the
//! closed form, whose bracket cancels.
//!
//! Each formula is the Allan variance of the rate averaged over tau (the continuous-time
//! definition); for a log whose samples are averages over their interval (a gyro's
//! angle increments divided by the interval) it holds exactly at every tau = m / rate.

use std::f64::consts::{LN_2, PI};

/// The terms of the identification, in the order of the IEEE 952 Allan plot (short tau
/// to long tau), with the Gauss-Markov hump last.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Term {
    Quantization,
    WhiteNoise,
    BiasInstability,
    RateRandomWalk,
    RateRamp,
    GaussMarkov,
}

impl Term {
    /// Every term.
    pub const ALL: [Term; 6] = [
        Term::Quantization,
        Term::WhiteNoise,
        Term::BiasInstability,
        Term::RateRandomWalk,
        Term::RateRamp,
        Term::GaussMarkov,
    ];

    /// The five terms linear in their squared coefficient (all but Gauss-Markov).
    pub const LINEAR: [Term; 5] = [
        Term::Quantization,
        Term::WhiteNoise,
        Term::BiasInstability,
        Term::RateRandomWalk,
        Term::RateRamp,
    ];

    /// The component kind of the simulation spec (contracts.md section 2).
    pub fn kind_name(self) -> &'static str {
        match self {
            Term::Quantization => "quantization",
            Term::WhiteNoise => "white_noise",
            Term::BiasInstability => "bias_instability",
            Term::RateRandomWalk => "rate_random_walk",
            Term::RateRamp => "rate_ramp",
            Term::GaussMarkov => "gauss_markov",
        }
    }

    /// Name of the coefficient in the spec: q, n, b, k, r, sigma.
    pub fn coef_name(self) -> &'static str {
        match self {
            Term::Quantization => "q",
            Term::WhiteNoise => "n",
            Term::BiasInstability => "b",
            Term::RateRandomWalk => "k",
            Term::RateRamp => "r",
            Term::GaussMarkov => "sigma",
        }
    }

    /// Unit of the coefficient, with `u` the rate unit of the log.
    pub fn coef_unit(self) -> &'static str {
        match self {
            Term::Quantization => "u s",
            Term::WhiteNoise => "u sqrt(s)",
            Term::BiasInstability => "u",
            Term::RateRandomWalk => "u/sqrt(s)",
            Term::RateRamp => "u/s",
            Term::GaussMarkov => "u",
        }
    }

    /// Exponent alpha of the rate PSD S_y(f) ~ f^alpha the term has (for Greenhall's
    /// EDF): quantization 2 (white PM), white noise 0, bias instability -1, rate random
    /// walk -2; the ramp is deterministic and takes -2 (the steepest case the Allan EDF
    /// has); Gauss-Markov -2 below its correlation time and 0 above.
    pub fn alpha(self, tau_s: f64, corr_time_s: f64) -> i32 {
        match self {
            Term::Quantization => 2,
            Term::WhiteNoise => 0,
            Term::BiasInstability => -1,
            Term::RateRandomWalk | Term::RateRamp => -2,
            Term::GaussMarkov => {
                if tau_s < corr_time_s {
                    -2
                } else {
                    0
                }
            }
        }
    }

    /// AVAR(tau) per unit squared coefficient; `corr_time_s` is the Gauss-Markov T
    /// (ignored by the other terms).
    pub fn basis(self, tau_s: f64, corr_time_s: f64) -> f64 {
        match self {
            Term::Quantization => 3.0 / (tau_s * tau_s),
            Term::WhiteNoise => 1.0 / tau_s,
            Term::BiasInstability => BIAS_FLOOR,
            Term::RateRandomWalk => tau_s / 3.0,
            Term::RateRamp => tau_s * tau_s / 2.0,
            Term::GaussMarkov => gauss_markov_g(tau_s / corr_time_s),
        }
    }
}

/// 2 ln 2 / pi: AVAR of bias instability per B^2 on its floor (ADEV floor
/// sqrt(2 ln 2 / pi) B = 0.6643 B).
pub const BIAS_FLOOR: f64 = 2.0 * LN_2 / PI;

/// g(x) = AVAR / sigma^2 of first-order Gauss-Markov noise at tau = x T (module doc).
pub fn gauss_markov_g(x: f64) -> f64 {
    if x < 0.1 {
        // Taylor series (coefficients exact, from the expansion of the closed form).
        const C: [f64; 9] = [
            2.0 / 3.0,
            -1.0 / 2.0,
            7.0 / 30.0,
            -1.0 / 12.0,
            31.0 / 1260.0,
            -1.0 / 160.0,
            127.0 / 90720.0,
            -17.0 / 60480.0,
            73.0 / 1425600.0,
        ];
        let mut acc = 0.0;
        for &c in C.iter().rev() {
            acc = acc * x + c;
        }
        acc * x
    } else {
        (2.0 - (3.0 - 4.0 * (-x).exp() + (-2.0 * x).exp()) / x) / x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_markov_series_meets_closed_form_and_limits() {
        let closed = |x: f64| (2.0 - (3.0 - 4.0 * (-x).exp() + (-2.0 * x).exp()) / x) / x;
        // Both sides of the switch against the exact value (mpmath, 40 digits:
        // g(0.1 - 1e-12) = 0.061891906585070053436..., g(0.1) = 0.061891906585643398706...).
        let below = gauss_markov_g(0.1 - 1e-12);
        assert!(
            // Truncation of the 9-term series at x = 0.1: about 1.4e-14 relative.
            (below / 0.061_891_906_585_070_05 - 1.0).abs() < 1e-13,
            "{below}"
        );
        let at = gauss_markov_g(0.1);
        assert!((at / 0.061_891_906_585_643_4 - 1.0).abs() < 1e-12, "{at}");
        assert!((closed(0.1) / at - 1.0).abs() < 1e-12);
        for x in [0.02, 0.05, 0.08] {
            assert!((gauss_markov_g(x) - closed(x)).abs() / closed(x) < 1e-9);
        }
        // Limits: 2x/3 (rate random walk) and 2/x (white noise).
        assert!((gauss_markov_g(1e-6) / (2e-6 / 3.0) - 1.0).abs() < 1e-6);
        assert!((gauss_markov_g(1e4) / (2.0 / 1e4) - 1.0).abs() < 2e-4);
    }

    #[test]
    fn gauss_markov_matches_its_structure_function() {
        // AVAR = (4 D(tau) - D(2 tau)) / (2 tau^2), D from the autocovariance by a
        // numerical double integral (trapezoid over the triangle), sigma = 1, T = 1.
        let d = |s: f64| {
            let n = 20_000;
            let h = s / n as f64;
            let mut acc = 0.0;
            for i in 0..=n {
                let u = i as f64 * h;
                let w = if i == 0 || i == n { 0.5 } else { 1.0 };
                acc += w * (s - u) * (-u).exp();
            }
            2.0 * acc * h
        };
        for tau in [0.3, 1.0, 2.5, 7.0] {
            let want = (4.0 * d(tau) - d(2.0 * tau)) / (2.0 * tau * tau);
            let got = gauss_markov_g(tau);
            assert!(
                (got - want).abs() / want < 1e-6,
                "tau {tau}: {got} vs {want}"
            );
        }
    }
}
