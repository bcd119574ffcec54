//! A linear output filter seen through block means: the finite impulse response, at
//! the averaged rate, that gives the averaged spec's white-type stand-ins the spectrum
//! the block means of the filtered log have ([`block_mean_fir`]).
//!
//! The block mean of K samples is the boxcar B(v) = (1/K) sum_{t<K} e^(-i v t)
//! followed by keeping every K-th sample, so a stationary series of spectrum S(v) at
//! the log's rate has at the averaged rate the aliased spectrum
//! S_K(w) = (1/K) sum_{j<K} S(v_j) |B(v_j)|^2, v_j = (w + 2 pi j) / K
//! (decimation: Oppenheim & Schafer, *Discrete-Time Signal Processing*, 3rd ed.,
//! section 4.6.1), |B(v)|^2 = (sin(K v / 2) / (K sin(v / 2)))^2. A white noise of
//! variance s^2 per sample has S = s^2 and S_K = s^2 / K (the boxcar's aliases sum to
//! one); through a filter of power response P(v) it has S_K = s^2 A(w) with
//! A(w) = (1/K) sum_j P(v_j) |B(v_j)|^2.
//!
//! In the averaged spec the white noise is white at the averaged rate (s^2 / K) and a
//! rounding of the rate stands in as white noise of variance `round_var`; both pass
//! the averaged spec's output filter G. In the log the rounding comes after the filter.
//! So the input spectrum is I(w) = s^2 / K + round_var and the target
//! T(w) = s^2 A(w) + round_var, and |G(w)|^2 = T(w) / I(w). G is the minimum-phase factor of that ratio by the real
//! cepstrum (Kolmogorov's method; Oppenheim & Schafer, section 13.6.2): c = the inverse
//! DFT of ln(T / I) / 2 on N points, folded (c_0, 2 c_1, ..., 2 c_(N/2-1), c_(N/2),
//! zeros), G = exp(DFT of the folded c), g = the inverse DFT of G. With a filter of unit
//! gain at 0 Hz, A(0) = 1 / K and G has unit gain at 0 Hz too: slow components pass
//! it as they pass the filter.

use std::f64::consts::PI;

/// Points of the DFT grid the factor is computed on.
const GRID: usize = 1024;

/// The relative energy of the impulse response beyond the taps kept above which no
/// FIR is returned (the filter is too slow for a short FIR at the averaged rate).
const TAIL: f64 = 1e-6;

/// The taps (at most `max_taps`) of the minimum-phase FIR G at the averaged rate with
/// |G|^2 = T / I (module doc) for a filter of power response `power(v)` (v in radians
/// per sample at the log's rate) on a white noise of variance `white_var` per sample at
/// the log's rate, block means of `k` samples and a rate rounding's stand-in of variance
/// `round_var` per averaged sample. None when `white_var` is not positive, or when
/// more than `TAIL` (1e-6) of the response's energy lies beyond `max_taps` taps.
pub fn block_mean_fir(
    power: impl Fn(f64) -> f64,
    k: usize,
    white_var: f64,
    round_var: f64,
    max_taps: usize,
) -> Option<Vec<f64>> {
    if white_var.is_nan() || white_var <= 0.0 || k == 0 || max_taps == 0 {
        return None;
    }
    let kf = k as f64;
    let n = GRID;
    // ln |G|^2 / 2 = ln(T / I) / 2 on the grid w_m = 2 pi m / n
    let half_log: Vec<f64> = (0..n)
        .map(|m| {
            let w = 2.0 * PI * m as f64 / n as f64;
            let a = (0..k)
                .map(|j| {
                    let v = (w + 2.0 * PI * j as f64) / kf;
                    power(v) * boxcar_power(v, k)
                })
                .sum::<f64>()
                / kf;
            let t = white_var * a + round_var;
            let i = white_var / kf + round_var;
            0.5 * (t.max(1e-300) / i).ln()
        })
        .collect();
    let (cos, sin) = twiddles(n);
    // the real cepstrum: the log spectrum is real and even, so its inverse DFT is
    // c_q = (1/n) sum_m L_m cos(2 pi q m / n)
    let c: Vec<f64> = (0..n)
        .map(|q| (0..n).map(|m| half_log[m] * cos[(q * m) % n]).sum::<f64>() / n as f64)
        .collect();
    let mut folded = vec![0.0; n];
    folded[0] = c[0];
    for q in 1..n / 2 {
        folded[q] = 2.0 * c[q];
    }
    folded[n / 2] = c[n / 2];
    // G_m = exp(sum_q folded_q e^(-i 2 pi q m / n))
    let g_spec: Vec<(f64, f64)> = (0..n)
        .map(|m| {
            let (mut re, mut im) = (0.0, 0.0);
            for (q, f) in folded.iter().enumerate().take(n / 2 + 1) {
                re += f * cos[(q * m) % n];
                im -= f * sin[(q * m) % n];
            }
            let e = re.exp();
            (e * im.cos(), e * im.sin())
        })
        .collect();
    // g_t = (1/n) Re sum_m G_m e^(i 2 pi t m / n)
    let g: Vec<f64> = (0..n)
        .map(|t| {
            g_spec
                .iter()
                .enumerate()
                .map(|(m, &(re, im))| re * cos[(t * m) % n] - im * sin[(t * m) % n])
                .sum::<f64>()
                / n as f64
        })
        .collect();
    let total: f64 = g.iter().map(|v| v * v).sum();
    let kept = max_taps.min(n / 2);
    let tail: f64 = g[kept..n / 2].iter().map(|v| v * v).sum();
    if total.is_nan() || total <= 0.0 || tail > TAIL * total {
        return None;
    }
    let mut taps = g[..kept].to_vec();
    // the smallest trailing taps add nothing
    while taps.len() > 1 && taps[taps.len() - 1].abs() < 1e-12 * taps[0].abs() {
        taps.pop();
    }
    Some(taps)
}

/// |B(v)|^2 of the boxcar of `k` samples (module doc), 1 at v = 0.
fn boxcar_power(v: f64, k: usize) -> f64 {
    let d = (v / 2.0).sin();
    if d.abs() < 1e-12 {
        return 1.0;
    }
    let r = (k as f64 * v / 2.0).sin() / (k as f64 * d);
    r * r
}

/// cos and sin of 2 pi m / n, m < n.
fn twiddles(n: usize) -> (Vec<f64>, Vec<f64>) {
    (0..n)
        .map(|m| {
            let w = 2.0 * PI * m as f64 / n as f64;
            (w.cos(), w.sin())
        })
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulator::generate::output::LowPass;

    /// The block means' autocovariance at averaged lags 0..m of a white noise of
    /// variance `var` filtered by the impulse response `h`, in the time domain:
    /// R(m) = (1/k^2) sum_{|l|<k} (k - |l|) r(m k + l), r(l) = var sum_i h_i h_{i+|l|}.
    fn block_acov(h: &[f64], var: f64, k: usize, lags: usize) -> Vec<f64> {
        let r = |l: i64| -> f64 {
            let l = l.unsigned_abs() as usize;
            if l >= h.len() {
                return 0.0;
            }
            var * h.iter().zip(&h[l..]).map(|(a, b)| a * b).sum::<f64>()
        };
        (0..lags)
            .map(|m| {
                let mut s = 0.0;
                for l in -(k as i64 - 1)..k as i64 {
                    s += (k as i64 - l.abs()) as f64 * r((m * k) as i64 + l);
                }
                s / (k * k) as f64
            })
            .collect()
    }

    fn impulse_response(f: &mut LowPass, len: usize) -> Vec<f64> {
        let mut x = vec![0.0; len];
        x[0] = 1.0;
        f.apply(&mut x);
        x
    }

    #[test]
    fn the_fir_gives_the_block_means_autocovariance_of_the_filtered_noise() {
        let fs = 100.0;
        for &(order, bw, k) in &[(1, 12.0, 4), (2, 8.0, 4), (1, 3.0, 16), (2, 30.0, 2)] {
            let f = LowPass::new(order, bw, None, fs);
            let var = 0.7;
            let taps = block_mean_fir(
                |v| f.power_response(v * fs / (2.0 * PI), fs),
                k,
                var,
                0.0,
                64,
            )
            .expect("a fast filter fits 64 taps");
            let h = impulse_response(&mut f.clone(), 64 * k + 4 * k);
            let want = block_acov(&h, var, k, 6);
            for (m, w) in want.iter().enumerate() {
                let got = var / k as f64
                    * taps
                        .iter()
                        .zip(taps.iter().skip(m))
                        .map(|(a, b)| a * b)
                        .sum::<f64>();
                assert!(
                    (got - w).abs() < 1e-6 * want[0],
                    "order {order} bw {bw} k {k} lag {m}: {got} vs {w}"
                );
            }
            // unit gain at 0 Hz, as the filter's
            let dc: f64 = taps.iter().sum();
            assert!((dc - 1.0).abs() < 1e-6, "dc gain {dc}");
        }
    }

    #[test]
    fn a_rounding_after_the_filter_is_not_filtered() {
        // white noise of variance 1 filtered, plus a rounding's white variance v at the
        // averaged rate: the stand-ins (white 1/k + v) through G have the target's
        // lag-0 variance A_0 + v
        let fs = 100.0;
        let (k, v) = (4, 0.05);
        let f = LowPass::new(1, 12.0, None, fs);
        let taps =
            block_mean_fir(|w| f.power_response(w * fs / (2.0 * PI), fs), k, 1.0, v, 64).unwrap();
        let h = impulse_response(&mut f.clone(), 400);
        let want = block_acov(&h, 1.0, k, 2);
        let g2: f64 = taps.iter().map(|t| t * t).sum();
        let g11: f64 = taps.iter().zip(&taps[1..]).map(|(a, b)| a * b).sum();
        let input = 1.0 / k as f64 + v;
        assert!(
            (input * g2 - (want[0] + v)).abs() < 1e-6,
            "{} vs {}",
            input * g2,
            want[0] + v
        );
        assert!(
            (input * g11 - want[1]).abs() < 1e-6,
            "{} vs {}",
            input * g11,
            want[1]
        );
    }

    #[test]
    fn a_slow_filter_has_no_short_fir() {
        let fs = 100.0;
        let f = LowPass::new(1, 0.05, None, fs);
        assert!(
            block_mean_fir(
                |w| f.power_response(w * fs / (2.0 * PI), fs),
                4,
                1.0,
                0.0,
                64
            )
            .is_none()
        );
        assert!(block_mean_fir(|_| 1.0, 4, 0.0, 0.0, 64).is_none());
    }
}
