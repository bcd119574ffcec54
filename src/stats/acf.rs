//! Sample autocorrelation of a channel up to a maximum lag, by FFT with zero padding,
//! with the +-1.96 / sqrt(N) band of a white series.
//!
//! Definition (G. E. P. Box, G. M. Jenkins, "Time Series Analysis", 1976, chapter 2;
//! statsmodels `acf(x, nlags, fft=True, adjusted=False)`): with the mean x-bar,
//! c_k = (1 / N) sum_{t=0}^{N-1-k} (x_t - x-bar)(x_{t+k} - x-bar) and r_k = c_k / c_0,
//! k = 0..=max_lag. Under the null of a white series, r_k (k >= 1) is about
//! normal(0, 1 / N), hence the band +-1.96 / sqrt(N) (95 %; Box and Jenkins ch. 2 on
//! the standard error of autocorrelations under white noise).
//!
//! Speed: the lagged sums are computed block by block: for a block of B samples
//! starting at s, the cross-correlation of x[s..s+B] with x[s..s+B+L] (L = max_lag) by
//! one real FFT of size F >= B + L each (zero padded, so the circular correlation holds
//! no wrapped terms) and one inverse; blocks in parallel, their partial sums added in
//! order (results do not depend on the thread count). O(N log F) time, O(F) memory per
//! worker, instead of one FFT of 2N. [`acf_slow`] is the twin: the lagged sums directly.

use rayon::prelude::*;
use realfft::RealFftPlanner;

use crate::error::{Error, Result};

/// The autocorrelation of one channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Acf {
    /// r_0..=r_max_lag (r_0 = 1).
    pub acf: Vec<f64>,
    /// c_0: the variance with divisor N.
    pub variance: f64,
    /// Samples N.
    pub n: usize,
    /// 1.96 / sqrt(N).
    pub band: f64,
}

/// The default maximum lag: 1000 samples, or N - 1 for shorter series.
pub fn default_max_lag(n: usize) -> usize {
    1000.min(n.saturating_sub(1))
}

fn check(what: &str, n: usize, max_lag: usize) -> Result<()> {
    if n < 2 {
        return Err(Error::TooShort {
            what: format!("{what}: autocorrelation"),
            need: 2,
            have: n as u64,
        });
    }
    if max_lag >= n {
        return Err(Error::Usage(format!(
            "{what}: --max-lag {max_lag} must be less than the number of samples ({n})"
        )));
    }
    Ok(())
}

fn finish(sums: Vec<f64>, n: usize, what: &str) -> Result<Acf> {
    let c0 = sums[0] / n as f64;
    if c0.is_nan() || c0 <= 0.0 {
        return Err(Error::Data(format!(
            "{what}: the channel is constant; its autocorrelation is undefined"
        )));
    }
    Ok(Acf {
        acf: sums.iter().map(|s| s / sums[0]).collect(),
        variance: c0,
        n,
        band: 1.96 / (n as f64).sqrt(),
    })
}

/// Mean by pairwise-compensated blocks (a plain sum per block, blocks added in order).
fn mean(y: &[f64]) -> f64 {
    let parts: Vec<f64> = y
        .par_chunks(1 << 16)
        .map(|c| c.iter().sum::<f64>())
        .collect();
    parts.iter().sum::<f64>() / y.len() as f64
}

/// The memory [`acf`] plans for `n` samples to `max_lag` with `threads` blocks in
/// flight, in bytes: per block in flight two real buffers of the FFT length f and its
/// complex spectrum (f/2 + 1 values of 16 bytes), and per block its max_lag + 1 sums.
pub fn planned_bytes(n: usize, max_lag: usize, threads: usize) -> f64 {
    let f = (2.0 * (max_lag as f64 + 1.0))
        .max(32768.0)
        .log2()
        .ceil()
        .exp2();
    let b = (f - max_lag as f64).max(1.0);
    let blocks = (n as f64 / b).ceil().max(1.0);
    threads.max(1) as f64 * (2.0 * f * 8.0 + (f / 2.0 + 1.0) * 16.0)
        + blocks * (max_lag as f64 + 1.0) * 8.0
}

/// The autocorrelation of `y` at lags 0..=max_lag by blocked FFT (module doc).
pub fn acf(what: &str, y: &[f64], max_lag: usize) -> Result<Acf> {
    check(what, y.len(), max_lag)?;
    let n = y.len();
    let mu = mean(y);
    let l = max_lag;
    let f = (2 * (l + 1)).max(1 << 15).next_power_of_two();
    let b = f - l;
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(f);
    let inv = planner.plan_fft_inverse(f);
    let blocks: Vec<usize> = (0..n).step_by(b).collect();
    let partial: Vec<Vec<f64>> = blocks
        .par_iter()
        .map(|&s| {
            let mut a = fwd.make_input_vec();
            let mut c = fwd.make_input_vec();
            for (d, &v) in a.iter_mut().zip(&y[s..(s + b).min(n)]) {
                *d = v - mu;
            }
            for (d, &v) in c.iter_mut().zip(&y[s..(s + b + l).min(n)]) {
                *d = v - mu;
            }
            let mut fa = fwd.make_output_vec();
            let mut fc = fwd.make_output_vec();
            fwd.process(&mut a, &mut fa).expect("plan sizes");
            fwd.process(&mut c, &mut fc).expect("plan sizes");
            // Cross-correlation sum_i a_i c_{i+k} = IFFT(conj(A) C)_k.
            for (x, z) in fc.iter_mut().zip(&fa) {
                *x *= z.conj();
            }
            // The imaginary parts of DC and Nyquist are zero in exact arithmetic.
            fc[0].im = 0.0;
            let last = fc.len() - 1;
            fc[last].im = 0.0;
            let mut out = inv.make_output_vec();
            inv.process(&mut fc, &mut out).expect("plan sizes");
            out.truncate(l + 1);
            for v in &mut out {
                *v /= f as f64;
            }
            out
        })
        .collect();
    let mut sums = vec![0.0; l + 1];
    for p in &partial {
        for (s, v) in sums.iter_mut().zip(p) {
            *s += v;
        }
    }
    finish(sums, n, what)
}

/// The twin of [`acf`]: the lagged sums summed directly, O(N L).
pub fn acf_slow(what: &str, y: &[f64], max_lag: usize) -> Result<Acf> {
    check(what, y.len(), max_lag)?;
    let n = y.len();
    let mu = y.iter().sum::<f64>() / n as f64;
    let sums = (0..=max_lag)
        .map(|k| (0..n - k).map(|t| (y[t] - mu) * (y[t + k] - mu)).sum())
        .collect();
    finish(sums, n, what)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn ar1(n: usize, phi: f64, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut x = 0.0;
        (0..n)
            .map(|_| {
                x = phi * x + rng.random::<f64>() - 0.5;
                5.0 + x
            })
            .collect()
    }

    #[test]
    fn fast_matches_direct_sums() {
        // Several blocks (block size F - L with F >= 2^15), lags up to past one block.
        for (n, l, seed) in [
            (100_000usize, 50usize, 1u64),
            (70_000, 20_000, 2),
            (10, 9, 3),
            (33_000, 0, 4),
        ] {
            let y = ar1(n, 0.9, seed);
            let a = acf("t", &y, l).unwrap();
            let b = acf_slow("t", &y, l).unwrap();
            for (k, (x, z)) in a.acf.iter().zip(&b.acf).enumerate() {
                assert!((x - z).abs() < 1e-12, "n={n} lag {k}: {x} vs {z}");
            }
            assert!((a.variance / b.variance - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn ar1_decays_geometrically() {
        let y = ar1(200_000, 0.8, 9);
        let a = acf("t", &y, 5).unwrap();
        for k in 1..=5 {
            assert!((a.acf[k] - 0.8f64.powi(k as i32)).abs() < 0.01, "lag {k}");
        }
    }

    #[test]
    fn thread_count_does_not_change_results() {
        let y = ar1(100_000, 0.5, 3);
        let run = |t| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .unwrap()
                .install(|| acf("t", &y, 300).unwrap())
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn errors() {
        assert!(acf("t", &[1.0], 0).is_err());
        assert!(acf("t", &[1.0, 2.0, 3.0], 3).is_err());
        assert!(acf("t", &[2.0; 10], 3).is_err());
    }
}
