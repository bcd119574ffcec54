//! Correlated noise from first-order recursions: Gauss-Markov, rate random walk and
//! bias instability (flicker approximated by a bank of Gauss-Markov processes). All
//! run by chunks with a carry fix-up ([`super::streams::ar1_bank`]).

use super::streams::{Ar1, StreamKey, ar1_bank, normals};

/// gauss_markov: x_k = phi x_{k-1} + sigma sqrt(1 - phi^2) w_k with
/// phi = exp(-dt / tau_s): the exact discretisation of the first-order Gauss-Markov
/// process (Ornstein-Uhlenbeck; Brown and Hwang, "Introduction to Random Signals and
/// Applied Kalman Filtering", 4th ed., section 2.9), stationary standard deviation
/// `sigma` [u], autocorrelation sigma^2 exp(-|lag| / tau_s). x_{-1} is drawn from the
/// stationary law N(0, sigma^2), so the process is stationary from the first sample.
pub fn gauss_markov(out: &mut [f64], sigma: f64, tau_s: f64, rate_hz: f64, key: &StreamKey) {
    let phi = (-1.0 / (rate_hz * tau_s)).exp();
    let x_init = sigma * normals(&mut key.init_rng(0), 1)[0];
    let ar = Ar1 {
        phi,
        gain: sigma * (1.0 - phi * phi).sqrt(),
        x_init,
    };
    ar1_bank(out, &[ar], key);
}

/// rate_random_walk: x_k = x_{k-1} + k sqrt(dt) w_k from x_{-1} = 0: the rate is the
/// integral of white noise of PSD k^2 (IEEE Std 952-1997 Annex C, rate random walk
/// K), so ADEV(tau) = k sqrt(tau / 3). In discrete time the Allan variance at
/// tau = m dt is k^2 tau / 3 (1 + 1 / (2 m^2)).
pub fn rate_random_walk(out: &mut [f64], k: f64, rate_hz: f64, key: &StreamKey) {
    let ar = Ar1 {
        phi: 1.0,
        gain: k / rate_hz.sqrt(),
        x_init: 0.0,
    };
    ar1_bank(out, &[ar], key);
}

/// Gauss-Markov processes per decade of correlation time in the flicker bank.
pub const BI_PER_DECADE: f64 = 3.0;
/// The bank extends this factor beyond tau_min_s and tau_max_s on each side.
pub const BI_MARGIN: f64 = 10.0;

/// The Gauss-Markov bank approximating bias instability `b` whose ADEV floor should
/// hold for tau between `tau_min_s` and `tau_max_s`: returns (T_i, s_i), the
/// correlation time and standard deviation of each process.
///
/// Flicker rate noise with one-sided PSD h_{-1} / f has the flat Allan variance
/// 2 ln 2 h_{-1} (Barnes et al., NBS Technical Note 394, 1971); IEEE Std 952's floor
/// 0.664 b = b sqrt(2 ln 2 / pi) is h_{-1} = b^2 / pi. A Gauss-Markov process of
/// variance s^2 and correlation time T has one-sided PSD 4 s^2 T / (1 + (2 pi f T)^2);
/// spreading variance c per unit of ln T gives, integrated over T, exactly c / f. So
/// the bank spreads c = b^2 / pi over ln T in [ln(tau_min_s / 10), ln(10 tau_max_s)]:
/// K = ceil(3 per decade) cells of equal width D, one process at each cell's midpoint
/// with s_i^2 = b^2 D / pi. The margin of a decade on each side is needed because the
/// Allan variance at tau collects the 1/f spectrum over several decades around
/// 1 / tau: with it, the exact Allan deviation of the bank stays within about 8 % of
/// 0.664 b for tau in [tau_min_s, tau_max_s] (tests/simulate.rs checks the exact
/// Allan variance of the bank, then the simulation against it).
pub fn bias_instability_bank(b: f64, tau_min_s: f64, tau_max_s: f64) -> Vec<(f64, f64)> {
    let lo = (tau_min_s / BI_MARGIN).ln();
    let span = (tau_max_s * BI_MARGIN).ln() - lo;
    let k = ((BI_PER_DECADE * span / std::f64::consts::LN_10).ceil() as usize).max(1);
    let cell = span / k as f64;
    let s = b * (cell / std::f64::consts::PI).sqrt();
    (0..k)
        .map(|i| ((lo + (i as f64 + 0.5) * cell).exp(), s))
        .collect()
}

/// bias_instability: the sum of the bank's Gauss-Markov processes (see
/// [`bias_instability_bank`]), each stationary from the first sample.
pub fn bias_instability(
    out: &mut [f64],
    b: f64,
    tau_min_s: f64,
    tau_max_s: f64,
    rate_hz: f64,
    key: &StreamKey,
) {
    let bank = bias_instability_bank(b, tau_min_s, tau_max_s);
    let inits = normals(&mut key.init_rng(0), bank.len());
    let ars: Vec<Ar1> = bank
        .iter()
        .zip(inits)
        .map(|(&(tau, s), w)| {
            let phi = (-1.0 / (rate_hz * tau)).exp();
            Ar1 {
                phi,
                gain: s * (1.0 - phi * phi).sqrt(),
                x_init: s * w,
            }
        })
        .collect();
    ar1_bank(out, &ars, key);
}
