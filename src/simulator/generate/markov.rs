//! Correlated noise from first-order recursions: Gauss-Markov, rate random walk and
//! bias instability (flicker approximated by a bank of Gauss-Markov processes). All
//! run by chunks with a carry fix-up ([`super::streams::ar1_bank`]).
//!
//! Every sample is the **average of the continuous-time rate over its interval**
//! [t_k, t_k + dt] (what a gyro's angle increment divided by dt is), as for
//! white_noise and quantization ([`super::noise`]). Then the IEEE Std 952 Allan
//! variances of contracts.md section 2 hold exactly at every tau = m dt: a Gauss-Markov
//! process gives sigma^2 g(tau / T) ([`crate::stats::noise_terms::gauss_markov_g`]), a
//! rate random walk k^2 tau / 3. Point samples of the process (the values at t_k) do
//! not: they alias the spectrum above the Nyquist frequency into the band, which reads
//! as extra white noise: a point-sampled random walk has Allan variance
//! k^2 tau / 3 + (k^2 dt^2 / 6) / tau, and a point-sampled flicker bank reaching below
//! one sample interval doubled the Allan variance at tau = dt (see
//! [`bias_instability_bank`]).
//!
//! The interval average of a Gauss-Markov process (stationary standard deviation s,
//! correlation time T, phi = exp(-dt / T)) is exactly
//!
//! y_k = c (x_{k-1} + x_k) + r z_k, with u = dt / (2 T), c = tanh(u) / (2 u),
//! r^2 = s^2 (u - tanh u) / u^2,
//!
//! x_k the process at the interval ends (the exact AR(1) discretisation) and z_k
//! standard normal, independent of x. Derivation: the end value x_k and the integral
//! I_k over the interval are jointly Gaussian given x_{k-1} (Gillespie, "Exact numerical
//! simulation of the Ornstein-Uhlenbeck process and its integral", Phys. Rev. E 54,
//! 1996): x_k = phi x_{k-1} + e1, I_k = T (1 - phi) x_{k-1} + e2, Var e1 =
//! s^2 (1 - phi^2), Cov(e1, e2) = s^2 T (1 - phi)^2, Var e2 =
//! 2 s^2 T (dt - 2 T (1 - phi) + T (1 - phi^2) / 2); regressing e2 on e1 gives
//! I_k = T (1 - phi) / (1 + phi) (x_{k-1} + x_k) + residual, and
//! (1 - phi) / (1 + phi) = tanh(u). The unit tests check the variance and
//! autocovariances of y against those of the interval average computed directly. For
//! T -> infinity with 2 s^2 / T = k^2 (a rate random walk) c -> 1/2 and
//! r^2 -> k^2 dt / 12. The z_k of every process of a component are summed into one
//! normal draw per sample, from sub-stream [`WHITE_SUB`].

use rand_distr::{Distribution, StandardNormal};

use super::streams::{Ar1, StreamKey, ar1_bank_from, for_chunks_from, normals};

/// Sub-stream of the white part (the r z_k terms) of a component.
pub const WHITE_SUB: usize = 255;

/// (c, r / s) of the interval average of a Gauss-Markov process of correlation time
/// `tau_s` sampled at `rate_hz` (module doc): y_k = c (x_{k-1} + x_k) + r z_k with
/// c = tanh(u) / (2 u), (r / s)^2 = (u - tanh u) / u^2, u = dt / (2 tau_s). Below
/// u = 0.1, u - tanh u is its Taylor series (u^3/3 - 2u^5/15 + 17u^7/315 - ...;
/// truncation about 1e-12 relative at u = 0.1), which the closed form would cancel.
pub fn interval_average(tau_s: f64, rate_hz: f64) -> (f64, f64) {
    let u = 0.5 / (rate_hz * tau_s);
    let t = u.tanh();
    let u_minus_tanh = if u < 0.1 {
        // Coefficients of u - tanh u: 1/3, -2/15, 17/315, -62/2835, 1382/155925.
        const C: [f64; 5] = [
            1.0 / 3.0,
            -2.0 / 15.0,
            17.0 / 315.0,
            -62.0 / 2835.0,
            1382.0 / 155_925.0,
        ];
        let u2 = u * u;
        C.iter().rev().fold(0.0, |acc, c| acc * u2 + c) * u2 * u
    } else {
        u - t
    };
    let ratio = if u < 1e-100 {
        // (u - tanh u) / u^2 = u / 3 to f64 precision; u * u would underflow to 0
        u / 3.0
    } else {
        u_minus_tanh / (u * u)
    };
    (t / (2.0 * u), ratio.sqrt())
}

/// Adds `sd` times a standard normal per sample, drawn from sub-stream [`WHITE_SUB`].
fn add_white(out: &mut [f64], sd: f64, key: &StreamKey, c0: u64) {
    if sd == 0.0 {
        return;
    }
    for_chunks_from(out, c0, |c, s| {
        let mut rng = key.rng(WHITE_SUB, c);
        for v in s.iter_mut() {
            let w: f64 = StandardNormal.sample(&mut rng);
            *v += sd * w;
        }
    });
}

/// A component made of first-order recursions and a white part (gauss_markov,
/// rate_random_walk, bias_instability), with its state carried from block to block.
#[derive(Debug, Clone)]
pub struct Ar1Comp {
    bank: Vec<Ar1>,
    /// Each recursion's state before the next block.
    x: Vec<f64>,
    white_sd: f64,
}

impl Ar1Comp {
    fn new(bank: Vec<Ar1>, white_sd: f64) -> Self {
        let x = bank.iter().map(|a| a.x_init).collect();
        Ar1Comp { bank, x, white_sd }
    }

    /// Adds the component's next block (starting at sample `c0 * CHUNK`) to `out`.
    pub fn add_block(&mut self, out: &mut [f64], key: &StreamKey, c0: u64) {
        ar1_bank_from(out, &self.bank, key, c0, &mut self.x);
        add_white(out, self.white_sd, key, c0);
    }
}

/// gauss_markov: the interval averages (module doc) of the first-order Gauss-Markov
/// process (Ornstein-Uhlenbeck; Brown and Hwang, "Introduction to Random Signals and
/// Applied Kalman Filtering", 4th ed., section 2.9) of stationary standard deviation
/// `sigma` \[u\] and autocorrelation sigma^2 exp(-|lag| / tau_s), whose end values
/// follow the exact discretisation x_k = phi x_{k-1} + sigma sqrt(1 - phi^2) w_k,
/// phi = exp(-dt / tau_s). x_{-1} is drawn from the stationary law N(0, sigma^2), so the
/// process is stationary from the first sample. The Allan variance is
/// sigma^2 g(tau / tau_s) exactly at every tau = m dt (IEEE Std 952-1997 Annex C,
/// exponentially correlated noise); the samples' variance is
/// sigma^2 (2 T / dt^2) (dt - T (1 - phi)), slightly below sigma^2 when T >> dt.
pub fn gauss_markov(out: &mut [f64], sigma: f64, tau_s: f64, rate_hz: f64, key: &StreamKey) {
    gauss_markov_comp(sigma, tau_s, rate_hz, key).add_block(out, key, 0)
}

/// [`gauss_markov`] as a component generated by blocks.
pub fn gauss_markov_comp(sigma: f64, tau_s: f64, rate_hz: f64, key: &StreamKey) -> Ar1Comp {
    let phi = (-1.0 / (rate_hz * tau_s)).exp();
    let (c, r) = interval_average(tau_s, rate_hz);
    let x_init = sigma * normals(&mut key.init_rng(0), 1)[0];
    let ar = Ar1 {
        phi,
        gain: c * sigma * (1.0 - phi * phi).sqrt(),
        x_init: c * x_init,
        prev: 1.0,
    };
    Ar1Comp::new(vec![ar], r * sigma)
}

/// rate_random_walk: the interval averages of the rate k W(t), W a Wiener process from
/// W(0) = 0 (IEEE Std 952-1997 Annex C, rate random walk K: the rate is the integral of
/// white noise of PSD k^2). With x_k = k W(t_k + dt) = x_{k-1} + k sqrt(dt) w_k, the
/// average over the interval is (x_{k-1} + x_k) / 2 + k sqrt(dt / 12) z_k (the
/// integral of a Brownian path given its end points: a Brownian bridge, whose integral
/// has variance dt^3 / 12), so ADEV(tau) = k sqrt(tau / 3) exactly at every tau = m dt.
pub fn rate_random_walk(out: &mut [f64], k: f64, rate_hz: f64, key: &StreamKey) {
    rate_random_walk_comp(k, rate_hz).add_block(out, key, 0)
}

/// [`rate_random_walk`] as a component generated by blocks.
pub fn rate_random_walk_comp(k: f64, rate_hz: f64) -> Ar1Comp {
    let ar = Ar1 {
        phi: 1.0,
        gain: 0.5 * k / rate_hz.sqrt(),
        x_init: 0.0,
        prev: 1.0,
    };
    Ar1Comp::new(vec![ar], k / (12.0 * rate_hz).sqrt())
}

/// Gauss-Markov processes per decade of correlation time in the flicker bank.
pub const BI_PER_DECADE: f64 = 2.0;
/// The bank starts this factor below tau_min_s ...
pub const BI_MARGIN_LOW: f64 = 100.0;
/// ... and ends this factor above tau_max_s.
pub const BI_MARGIN_HIGH: f64 = 100.0;

/// The flicker bank of bias instability `b` whose ADEV floor should hold for tau
/// between `tau_min_s` and `tau_max_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct FlickerBank {
    /// (T_i, s_i): the correlation time \[s\] and standard deviation \[u\] of each process.
    pub processes: Vec<(f64, f64)>,
    /// n^2 [u^2 s] of the white noise standing for the spectrum above the bank: the
    /// processes of correlation time below T_low = tau_min_s / [`BI_MARGIN_LOW`].
    pub white_n2: f64,
}

impl FlickerBank {
    /// The exact Allan variance [u^2] of the bank's interval averages at tau \[s\]:
    /// sum_i s_i^2 g(tau / T_i) + white_n2 / tau.
    pub fn avar(&self, tau_s: f64) -> f64 {
        use crate::stats::noise_terms::gauss_markov_g;
        self.processes
            .iter()
            .map(|&(t, s)| s * s * gauss_markov_g(tau_s / t))
            .sum::<f64>()
            + self.white_n2 / tau_s
    }
}

/// The Gauss-Markov bank approximating bias instability `b` whose ADEV floor should
/// hold for tau between `tau_min_s` and `tau_max_s`.
///
/// Flicker rate noise with one-sided PSD h_{-1} / f has the flat Allan variance
/// 2 ln 2 h_{-1} (Barnes et al., NBS Technical Note 394, 1971); IEEE Std 952's floor
/// 0.664 b = b sqrt(2 ln 2 / pi) is h_{-1} = b^2 / pi. A Gauss-Markov process of
/// variance s^2 and correlation time T has one-sided PSD 4 s^2 T / (1 + (2 pi f T)^2);
/// spreading variance c per unit of ln T gives, integrated over T, exactly c / f. So
/// the bank spreads c = b^2 / pi over ln T in [ln T_low, ln T_high],
/// T_low = tau_min_s / 100, T_high = 100 tau_max_s: K = ceil(2 per decade) cells of
/// equal width D, one process at each cell's midpoint with s_i^2 = b^2 D / pi. The
/// processes below T_low, which the Allan variance at tau >> T_low sees as white
/// noise (s^2 g(tau / T) -> 2 s^2 T / tau), are replaced by white noise of
/// n^2 = integral_0^T_low 2 c T dT / T = 2 b^2 T_low / pi (exact to O((T_low / tau)^2)).
///
/// With every sample an interval average ([`bias_instability`]), the exact Allan
/// deviation of this bank ([`FlickerBank::avar`]) is within 0.06 % of 0.664 b at every
/// octave tau in [tau_min_s, tau_max_s / 4] and within 0.23 % up to tau_max_s
/// (computed for tau_min_s = 1 s and 30 values of tau_max_s from 10 s to 1e7 s, and
/// for the tests' bands; tests/suite/simulate.rs checks it, then the simulation against
/// it). A margin of 10 above tau_max_s would leave it 0.22 % low at tau_max_s / 10
/// and 2.2 % at tau_max_s. Two per decade is enough: with 3 per decade the exact Allan
/// deviation changes by less than 0.02 %. Below tau_min_s / 100 the spectrum is white
/// rather than 1 / f; above 100 tau_max_s it is flat.
///
/// Why the lower margin and the interval averages: a bank over
/// [tau_min_s / 10, 10 tau_max_s] that took point samples of each process would,
/// with the default tau_min_s of one sample, have nearly white fastest processes
/// (T = 0.18 and 0.55 samples), and a point sample keeps their whole variance s^2
/// where an interval average keeps about 2 s^2 T / dt: at 100 Hz, b = 0.01, 2^18
/// samples that bank's exact Allan variance is 2.08 times the floor at tau = dt (1.49
/// at 2 dt, 1.22 at 4 dt, 1.10 at 8 dt: an excess falling as 1 / tau, white noise of
/// n^2 = 4.8e-7), its simulated curve (mean of seeds 1-4) 2.08, 1.49, 1.22, 1.10, and
/// the identification of white n = 0.005 + rate random walk + that bias instability
/// reads n = 0.0050455 (n^2 = 2.5e-5 + 4.6e-7). Interval averages of the
/// same bank would have been 13 % below the floor at tau = dt (the 1 / f spectrum
/// above 1 / (2 pi T_low) missing), hence the margin of 100 and the white fill.
pub fn bias_instability_bank(b: f64, tau_min_s: f64, tau_max_s: f64) -> FlickerBank {
    let t_low = tau_min_s / BI_MARGIN_LOW;
    let lo = t_low.ln();
    let span = (tau_max_s * BI_MARGIN_HIGH).ln() - lo;
    let k = ((BI_PER_DECADE * span / std::f64::consts::LN_10).ceil() as usize).max(1);
    let cell = span / k as f64;
    let s = b * (cell / std::f64::consts::PI).sqrt();
    FlickerBank {
        processes: (0..k)
            .map(|i| ((lo + (i as f64 + 0.5) * cell).exp(), s))
            .collect(),
        white_n2: 2.0 * b * b * t_low / std::f64::consts::PI,
    }
}

/// bias_instability: the interval averages of the sum of the bank's Gauss-Markov
/// processes (see [`bias_instability_bank`] and the module doc), each stationary from
/// the first sample, plus the bank's white fill; one normal draw per process and one
/// for the white part per sample.
pub fn bias_instability(
    out: &mut [f64],
    b: f64,
    tau_min_s: f64,
    tau_max_s: f64,
    rate_hz: f64,
    key: &StreamKey,
) {
    bias_instability_comp(b, tau_min_s, tau_max_s, rate_hz, key).add_block(out, key, 0)
}

/// [`bias_instability`] as a component generated by blocks.
pub fn bias_instability_comp(
    b: f64,
    tau_min_s: f64,
    tau_max_s: f64,
    rate_hz: f64,
    key: &StreamKey,
) -> Ar1Comp {
    let bank = bias_instability_bank(b, tau_min_s, tau_max_s);
    let inits = normals(&mut key.init_rng(0), bank.processes.len());
    // Per-sample variance of the white part: the r_i^2 of the processes and the fill
    // (white noise n^2 has variance n^2 rate_hz per interval average).
    let mut white_var = bank.white_n2 * rate_hz;
    let ars: Vec<Ar1> = bank
        .processes
        .iter()
        .zip(inits)
        .map(|(&(tau, s), w)| {
            let phi = (-1.0 / (rate_hz * tau)).exp();
            let (c, r) = interval_average(tau, rate_hz);
            white_var += (r * s) * (r * s);
            Ar1 {
                phi,
                gain: c * s * (1.0 - phi * phi).sqrt(),
                x_init: c * s * w,
                prev: 1.0,
            }
        })
        .collect();
    Ar1Comp::new(ars, white_var.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Autocovariance at lag L (samples) of the interval averages of a Gauss-Markov
    /// process of variance 1 and correlation time T, from the angle structure function
    /// D(s) = E[(theta(t + s) - theta(t))^2] = 2 (T s - T^2 (1 - exp(-s / T))) (the
    /// double integral of exp(-|t - t'| / T) over [0, s]^2): the average over interval k
    /// is (theta(t_k + dt) - theta(t_k)) / dt, so its autocovariance at lag L is
    /// (D((L + 1) dt) - 2 D(L dt) + D(|L - 1| dt)) / (2 dt^2).
    fn direct_acov(t: f64, dt: f64, lag: usize) -> f64 {
        let d = |s: f64| 2.0 * (t * s + t * t * (-s / t).exp_m1());
        let l = lag as f64;
        (d((l + 1.0) * dt) - 2.0 * d(l * dt) + d((l - 1.0).abs() * dt)) / (2.0 * dt * dt)
    }

    #[test]
    fn interval_average_has_the_covariances_of_the_average() {
        let dt: f64 = 0.1;
        for t in [0.001, 0.02, 0.1, 0.5, 3.0, 50.0] {
            let phi: f64 = (-dt / t).exp();
            let (c, r) = interval_average(t, 1.0 / dt);
            // From the representation y_k = c (x_{k-1} + x_k) + r z_k, Var x = 1.
            let var = 2.0 * c * c * (1.0 + phi) + r * r;
            let lag1 = c * c * (1.0 + phi) * (1.0 + phi);
            let lag2 = lag1 * phi;
            let scale = direct_acov(t, dt, 0);
            for (lag, got) in [(0, var), (1, lag1), (2, lag2)] {
                let want = direct_acov(t, dt, lag);
                assert!(
                    (got - want).abs() <= 1e-9 * scale,
                    "T {t} lag {lag}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn interval_average_series_meets_the_closed_form_and_the_limits() {
        // Both sides of the switch at u = 0.1 (tau_s = 5 s at 1 Hz), and the limits.
        let closed = |u: f64| ((u - u.tanh()) / (u * u)).sqrt();
        let (_, below) = interval_average(5.0 * (1.0 + 1e-9), 1.0);
        let (_, above) = interval_average(5.0 * (1.0 - 1e-9), 1.0);
        assert!((below / closed(0.1) - 1.0).abs() < 1e-9, "{below}");
        assert!((above / closed(0.1) - 1.0).abs() < 1e-9, "{above}");
        for u in [0.09, 0.05, 0.02] {
            let (_, r) = interval_average(0.5 / u, 1.0);
            assert!((r / closed(u) - 1.0).abs() < 1e-10, "u {u}");
        }
        // Rate random walk limit: T large, 2 s^2 / T = k^2 = 1: c -> 1/2, r s -> sqrt(dt / 12).
        let t = 1e7;
        let (c, r) = interval_average(t, 1.0);
        let s = (t / 2.0).sqrt();
        assert!((c - 0.5).abs() < 1e-12);
        assert!((r * s / (1.0f64 / 12.0).sqrt() - 1.0).abs() < 1e-6);
        // White limit: T << dt: c -> T / dt, r^2 -> 2 T / dt.
        let (c, r) = interval_average(1e-6, 1.0);
        assert!((c / 1e-6 - 1.0).abs() < 1e-9 && (r * r / 2e-6 - 1.0).abs() < 1e-5);
    }
}
