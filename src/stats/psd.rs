//! Power spectral density of a rate channel by Welch's method: Hann window, 50 %
//! overlap, one-sided density in u^2/Hz, averaged over segments; and log-spaced band
//! averaging for plots.
//!
//! Definition (P. D. Welch, "The use of fast Fourier transform for the estimation of
//! power spectra", IEEE Trans. Audio Electroacoust. 15(2), 1967; the conventions of
//! scipy.signal.welch with window="hann", noverlap=L/2, detrend="constant",
//! scaling="density", average="mean", return_onesided=True): segments of L samples
//! start at 0, L/2, L, ... while they fit in the series (the tail is dropped); each has
//! its mean removed (or not, `Detrend::None`) and is multiplied by the periodic Hann
//! window w_i = 0.5 - 0.5 cos(2 pi i / L); with X_k = sum_i w_i x_i e^{-2 pi i j k / L},
//! P_k = c_k |X_k|^2 / (f_s sum_i w_i^2), c_k = 2 except at k = 0 and (L even) k = L/2
//! where c_k = 1, at f_k = k f_s / L, k = 0..=L/2; the estimate is the mean of P_k over
//! the segments. With this scaling, white noise of variance s^2 has P = 2 s^2 / f_s,
//! and the PSD sums to the variance: sum_k P_k f_s / L = mean square of the windowed
//! data / mean square of the window.
//!
//! IEEE Std 952 writes its rate PSDs two-sided: a white_noise n has one-sided
//! P = 2 n^2 here, bias instability b has P(f) = b^2 / (pi f).
//!
//! Speed: one real FFT per segment (realfft), segments in parallel in fixed chunks whose
//! partial sums are added in order, so results do not depend on the thread count.
//! [`welch_slow`] is the twin: the same estimate with a direct O(L^2) DFT.

use std::sync::Arc;

use rayon::prelude::*;
use realfft::{RealFftPlanner, RealToComplex};

use crate::error::{Error, Result};

/// What to subtract from each segment before windowing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Detrend {
    /// Nothing.
    None,
    /// The segment's mean (scipy's default).
    Constant,
}

/// A one-sided PSD estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Psd {
    /// Frequencies f_k = k rate_hz / L, k = 0..=L/2, Hz.
    pub freq_hz: Vec<f64>,
    /// One-sided PSD, u^2/Hz.
    pub psd: Vec<f64>,
    /// Segment length L (samples).
    pub segment_len: usize,
    /// Number of segments averaged.
    pub n_segments: usize,
}

/// Default segment length for N samples: the largest power of two <= N / 8 (so that
/// about 15 half-overlapping segments are averaged), within [16, 2^16], and never more
/// than N.
pub fn default_segment_len(n: usize) -> usize {
    let target = (n / 8).max(16);
    let mut l = 16usize;
    while l * 2 <= target && l * 2 <= 1 << 16 {
        l *= 2;
    }
    l.min(n)
}

/// The periodic Hann window of length L.
pub fn hann(l: usize) -> Vec<f64> {
    (0..l)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / l as f64).cos())
        .collect()
}

fn check(what: &str, n: usize, rate_hz: f64, segment_len: usize) -> Result<()> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(Error::Usage(format!(
            "{what}: sample rate {} Hz",
            crate::fmt::num(rate_hz)
        )));
    }
    if segment_len < 2 {
        return Err(Error::Usage(format!(
            "{what}: segment length must be at least 2 samples, got {segment_len}"
        )));
    }
    if n < segment_len {
        return Err(Error::TooShort {
            what: format!("{what}: Welch PSD with segments of {segment_len} samples"),
            need: segment_len as u64,
            have: n as u64,
        });
    }
    Ok(())
}

/// Segment starts: 0, step, 2 step, ... while a whole segment fits (step = L / 2).
fn starts(n: usize, l: usize) -> Vec<usize> {
    let step = (l / 2).max(1);
    (0..).map(|j| j * step).take_while(|s| s + l <= n).collect()
}

fn scale_and_freqs(sums: &mut [f64], l: usize, rate_hz: f64, n_seg: usize, w: &[f64]) -> Vec<f64> {
    let s2: f64 = w.iter().map(|v| v * v).sum();
    let base = 1.0 / (rate_hz * s2 * n_seg as f64);
    let last = sums.len() - 1;
    for (k, v) in sums.iter_mut().enumerate() {
        let one = k == 0 || (l.is_multiple_of(2) && k == last);
        *v *= if one { base } else { 2.0 * base };
    }
    (0..sums.len())
        .map(|k| k as f64 * rate_hz / l as f64)
        .collect()
}

/// Segments per parallel work item (partial sums are added in this fixed grouping).
const CHUNK: usize = 8;

/// The memory [`welch`] plans for `n` samples in segments of `segment_len` with
/// `threads` chunks in flight, in bytes: the Hann window, per chunk in flight the
/// segment buffer, its spectrum (16 bytes a bin), an FFT scratch of the same size and
/// the chunk's sums, and per chunk of segments its l/2 + 1 sums.
pub fn planned_bytes(n: usize, segment_len: usize, threads: usize) -> f64 {
    let l = segment_len as f64;
    let nk = l / 2.0 + 1.0;
    let segments = (2.0 * n as f64 / l).max(1.0);
    let chunks = (segments / CHUNK as f64).ceil();
    l * 8.0 + threads.max(1) as f64 * (l * 8.0 + 2.0 * nk * 16.0 + nk * 8.0) + chunks * nk * 8.0
}

/// Welch's PSD of `y` (module doc), segments of `segment_len` samples.
pub fn welch(
    what: &str,
    y: &[f64],
    rate_hz: f64,
    segment_len: usize,
    detrend: Detrend,
) -> Result<Psd> {
    check(what, y.len(), rate_hz, segment_len)?;
    crate::stats::require_finite(what, y, rate_hz)?;
    let l = segment_len;
    let w = hann(l);
    let st = starts(y.len(), l);
    let plan: Arc<dyn RealToComplex<f64>> = RealFftPlanner::<f64>::new().plan_fft_forward(l);
    let nk = l / 2 + 1;
    let partial: Vec<Vec<f64>> = st
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut buf = plan.make_input_vec();
            let mut spec = plan.make_output_vec();
            let mut scratch = plan.make_scratch_vec();
            let mut acc = vec![0.0; nk];
            for &s in chunk {
                let seg = &y[s..s + l];
                let mu = match detrend {
                    Detrend::None => 0.0,
                    Detrend::Constant => seg.iter().sum::<f64>() / l as f64,
                };
                for ((b, &v), &wi) in buf.iter_mut().zip(seg).zip(&w) {
                    *b = (v - mu) * wi;
                }
                plan.process_with_scratch(&mut buf, &mut spec, &mut scratch)
                    .expect("buffer sizes come from the plan");
                for (a, c) in acc.iter_mut().zip(&spec) {
                    *a += c.norm_sqr();
                }
            }
            acc
        })
        .collect();
    let mut sums = vec![0.0; nk];
    for p in &partial {
        for (s, v) in sums.iter_mut().zip(p) {
            *s += v;
        }
    }
    let freq_hz = scale_and_freqs(&mut sums, l, rate_hz, st.len(), &w);
    if let Some(k) = sums.iter().position(|v| !v.is_finite()) {
        return Err(crate::stats::overflow_error(
            what,
            "PSD",
            &format!("{} Hz", crate::fmt::num(freq_hz[k])),
            y,
        ));
    }
    Ok(Psd {
        freq_hz,
        psd: sums,
        segment_len: l,
        n_segments: st.len(),
    })
}

/// The twin of [`welch`]: the same estimate by a direct DFT of each segment
/// (O(L^2) per segment; for tests on short series).
pub fn welch_slow(y: &[f64], rate_hz: f64, segment_len: usize, detrend: Detrend) -> Psd {
    let l = segment_len;
    let w = hann(l);
    let st = starts(y.len(), l);
    let nk = l / 2 + 1;
    let mut sums = vec![0.0; nk];
    for &s in &st {
        let seg = &y[s..s + l];
        let mu = match detrend {
            Detrend::None => 0.0,
            Detrend::Constant => seg.iter().sum::<f64>() / l as f64,
        };
        for (k, sum) in sums.iter_mut().enumerate() {
            let (mut re, mut im) = (0.0, 0.0);
            for (i, &v) in seg.iter().enumerate() {
                let ang = -2.0 * std::f64::consts::PI * ((i * k) % l) as f64 / l as f64;
                let x = (v - mu) * w[i];
                re += x * ang.cos();
                im += x * ang.sin();
            }
            *sum += re * re + im * im;
        }
    }
    let freq_hz = scale_and_freqs(&mut sums, l, rate_hz, st.len(), &w);
    Psd {
        freq_hz,
        psd: sums,
        segment_len: l,
        n_segments: st.len(),
    }
}

/// One log-spaced band of a PSD.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Band {
    /// Mean frequency of the bins in the band, Hz.
    pub freq_hz: f64,
    /// Mean PSD of the bins in the band, u^2/Hz.
    pub psd: f64,
    /// Number of bins averaged.
    pub n_bins: usize,
}

/// Averages the PSD over log-spaced bands, `per_decade` per decade: bin k > 0 goes to
/// band floor(per_decade log10(f_k / f_1)); empty bands are skipped, the DC bin is left
/// out (it has no place on a log axis). Low bands hold single bins, high bands many.
pub fn band_average(psd: &Psd, per_decade: usize) -> Vec<Band> {
    let per_decade = per_decade.max(1) as f64;
    let mut out: Vec<Band> = Vec::new();
    let mut cur: Option<(i64, f64, f64, usize)> = None;
    let f1 = match psd.freq_hz.get(1) {
        Some(&f) => f,
        None => return out,
    };
    for (&f, &p) in psd.freq_hz.iter().zip(&psd.psd).skip(1) {
        // Bin index k = f / f1 >= 1; a tiny bias keeps exact decade points in place.
        let band = (per_decade * (f / f1).log10() + 1e-9).floor() as i64;
        match &mut cur {
            Some((b, sf, sp, n)) if *b == band => {
                *sf += f;
                *sp += p;
                *n += 1;
            }
            _ => {
                if let Some((_, sf, sp, n)) = cur.take() {
                    out.push(Band {
                        freq_hz: sf / n as f64,
                        psd: sp / n as f64,
                        n_bins: n,
                    });
                }
                cur = Some((band, f, p, 1));
            }
        }
    }
    if let Some((_, sf, sp, n)) = cur {
        out.push(Band {
            freq_hz: sf / n as f64,
            psd: sp / n as f64,
            n_bins: n,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn series(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut walk = 0.0;
        (0..n)
            .map(|_| {
                walk += 0.1 * (rng.random::<f64>() - 0.5);
                3.0 + walk + (rng.random::<f64>() - 0.5)
            })
            .collect()
    }

    #[test]
    fn fast_matches_direct_dft_twin() {
        for (n, l, seed) in [
            (1000usize, 64usize, 1u64),
            (777, 100, 2),
            (513, 17, 3),
            (64, 64, 4),
        ] {
            let y = series(n, seed);
            for d in [Detrend::None, Detrend::Constant] {
                let a = welch("t", &y, 50.0, l, d).unwrap();
                let b = welch_slow(&y, 50.0, l, d);
                assert_eq!(a.n_segments, b.n_segments);
                assert_eq!(a.freq_hz, b.freq_hz);
                let top = b.psd.iter().cloned().fold(0.0, f64::max);
                for (x, z) in a.psd.iter().zip(&b.psd) {
                    assert!((x - z).abs() <= 1e-10 * top, "n={n} l={l}: {x} vs {z}");
                }
            }
        }
    }

    #[test]
    fn white_noise_level_and_parseval() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let y: Vec<f64> = (0..1 << 16).map(|_| rng.random::<f64>() - 0.5).collect();
        let p = welch("t", &y, 10.0, 256, Detrend::Constant).unwrap();
        // Uniform(-1/2, 1/2): variance 1/12, one-sided PSD 2 / (12 f_s).
        let want = 2.0 / 12.0 / 10.0;
        let mid: Vec<f64> = p.psd[1..128].to_vec();
        let mean = mid.iter().sum::<f64>() / mid.len() as f64;
        assert!((mean / want - 1.0).abs() < 0.02, "{mean} vs {want}");
        assert_eq!(p.n_segments, (y.len() - 256) / 128 + 1);
    }

    #[test]
    fn thread_count_does_not_change_results() {
        let y = series(50_000, 5);
        let run = |t| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .unwrap()
                .install(|| welch("t", &y, 1.0, 512, Detrend::Constant).unwrap())
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn bands_cover_every_bin_once() {
        let y = series(4096, 6);
        let p = welch("t", &y, 1.0, 1024, Detrend::Constant).unwrap();
        let b = band_average(&p, 10);
        assert_eq!(b.iter().map(|x| x.n_bins).sum::<usize>(), p.psd.len() - 1);
        assert!(b.windows(2).all(|w| w[0].freq_hz < w[1].freq_hz));
        assert_eq!(b[0].n_bins, 1);
    }

    #[test]
    fn errors() {
        assert!(welch("t", &[1.0; 10], 1.0, 16, Detrend::Constant).is_err());
        assert!(welch("t", &[1.0; 10], 0.0, 4, Detrend::Constant).is_err());
        assert!(welch("t", &[1.0; 10], 1.0, 1, Detrend::Constant).is_err());
    }
}
