//! Deterministic components: constant bias, rate ramp, sinusoid, warm-up. Sample k is
//! at time t_k = k / sample_rate_hz (the first sample at t = 0). Each adds its signal
//! to `out`; values depend only on k, so the parallel loops are thread-count
//! independent.

use rayon::prelude::*;

use super::streams::CHUNK;

fn add_by_index(out: &mut [f64], f: impl Fn(usize) -> f64 + Sync) {
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, s)| {
        let base = c * CHUNK;
        for (j, v) in s.iter_mut().enumerate() {
            *v += f(base + j);
        }
    });
}

/// constant_bias: `value` \[u\] at every sample.
pub fn constant_bias(out: &mut [f64], value: f64) {
    add_by_index(out, |_| value);
}

/// rate_ramp: r t_k \[u\]. IEEE Std 952-1997 Annex C: a rate ramp R gives
/// ADEV(tau) = R tau / sqrt(2).
pub fn rate_ramp(out: &mut [f64], r: f64, rate_hz: f64) {
    add_by_index(out, |k| r * (k as f64 / rate_hz));
}

/// sinusoid: amplitude sin(2 pi freq_hz t_k + phase_rad) \[u\].
pub fn sinusoid(out: &mut [f64], amplitude: f64, freq_hz: f64, phase_rad: f64, rate_hz: f64) {
    let w = 2.0 * std::f64::consts::PI * freq_hz;
    add_by_index(out, |k| {
        amplitude * (w * (k as f64 / rate_hz) + phase_rad).sin()
    });
}

/// warmup: amplitude exp(-t_k / tau_s) \[u\] (contracts.md section 2).
pub fn warmup(out: &mut [f64], amplitude: f64, tau_s: f64, rate_hz: f64) {
    add_by_index(out, |k| amplitude * (-(k as f64 / rate_hz) / tau_s).exp());
}
