//! The fast path: each estimator is a sum of squared m-lag finite differences of a
//! phase-like series, O(N) per tau, in parallel over fixed blocks of the summation
//! index with the taus of one pass fused (each block of the phase is read once for all
//! taus while it is in cache). Partial sums are combined in block order with a
//! compensated sum, so the result does not depend on the number of threads.

use rayon::prelude::*;

use super::Kind;
use super::phase::{DoubleDouble, compensated_prefix};

/// Summation indices per parallel block (fixed, so results do not depend on threads).
const SUM_BLOCK: usize = 1 << 14;

/// The m-lag difference of order `order` (2: p[j+2m] - 2p[j+m] + p[j]; 3:
/// p[j+3m] - 3p[j+2m] + 3p[j+m] - p[j]), squared and summed over j in `lo..hi`.
/// Accumulator lanes of the kernels (independent chains; two SSE2 or AVX registers).
const ACC: usize = 8;

/// The m-lag difference of order `order` (2: p[j+2m] - 2p[j+m] + p[j]; 3:
/// p[j+3m] - 3p[j+2m] + 3p[j+m] - p[j]), squared and summed over j in `lo..hi`.
#[inline]
fn block_sum_sq(p: &[f64], m: usize, order: usize, lo: usize, hi: usize) -> f64 {
    if hi <= lo {
        return 0.0;
    }
    let len = hi - lo;
    let mut acc = [0.0f64; ACC];
    let mut tail = 0.0f64;
    match order {
        2 => {
            let (a, ar) = p[lo..lo + len].as_chunks::<ACC>();
            let (b, br) = p[lo + m..lo + m + len].as_chunks::<ACC>();
            let (c, cr) = p[lo + 2 * m..lo + 2 * m + len].as_chunks::<ACC>();
            for ((x0, x1), x2) in a.iter().zip(b).zip(c) {
                for l in 0..ACC {
                    let d = (x2[l] - 2.0 * x1[l]) + x0[l];
                    acc[l] += d * d;
                }
            }
            for ((x0, x1), x2) in ar.iter().zip(br).zip(cr) {
                let d = (x2 - 2.0 * x1) + x0;
                tail += d * d;
            }
        }
        3 => {
            let (a, ar) = p[lo..lo + len].as_chunks::<ACC>();
            let (b, br) = p[lo + m..lo + m + len].as_chunks::<ACC>();
            let (c, cr) = p[lo + 2 * m..lo + 2 * m + len].as_chunks::<ACC>();
            let (e, er) = p[lo + 3 * m..lo + 3 * m + len].as_chunks::<ACC>();
            for (((x0, x1), x2), x3) in a.iter().zip(b).zip(c).zip(e) {
                for l in 0..ACC {
                    let d = (x3[l] - x0[l]) + 3.0 * (x1[l] - x2[l]);
                    acc[l] += d * d;
                }
            }
            for (((x0, x1), x2), x3) in ar.iter().zip(br).zip(cr).zip(er) {
                let d = (x3 - x0) + 3.0 * (x1 - x2);
                tail += d * d;
            }
        }
        _ => unreachable!("difference order {order}"),
    }
    acc.iter().sum::<f64>() + tail
}

/// For each (m, count) in `lags`, sum_{j < count} (order-th m-lag difference of p at
/// j)^2. Needs count - 1 + order * m < p.len().
pub fn sum_sq_diffs(p: &[f64], order: usize, lags: &[(usize, usize)]) -> Vec<f64> {
    for &(m, count) in lags {
        assert!(
            count == 0 || count - 1 + order * m < p.len(),
            "lag {m} x {count} terms past the phase"
        );
    }
    let max_count = lags.iter().map(|l| l.1).max().unwrap_or(0);
    let n_blocks = max_count.div_ceil(SUM_BLOCK);
    let partials: Vec<Vec<f64>> = (0..n_blocks)
        .into_par_iter()
        .map(|b| {
            let lo = b * SUM_BLOCK;
            lags.iter()
                .map(|&(m, count)| {
                    let hi = ((b + 1) * SUM_BLOCK).min(count);
                    block_sum_sq(p, m, order, lo, hi)
                })
                .collect()
        })
        .collect();
    (0..lags.len())
        .map(|t| {
            partials
                .iter()
                .fold(DoubleDouble::default(), |a, v| a.plus_f64(v[t]))
                .value()
        })
        .collect()
}

/// Deviations of `kind` at the averaging factors `ms` from the phase `x` (N + 1
/// points, see [`super::phase::phase`]), in the units of the rate series. Every m
/// must satisfy 1 <= m <= [`super::max_m`].
pub fn deviations_from_phase(x: &[f64], kind: Kind, ms: &[usize]) -> Vec<f64> {
    let n_samples = x.len().saturating_sub(1);
    for &m in ms {
        assert!(
            m >= 1 && m <= super::max_m(kind, n_samples),
            "averaging factor {m} out of range for {n_samples} samples"
        );
    }
    match kind {
        Kind::Adev | Kind::Hdev => {
            let order = kind.order();
            let lags: Vec<(usize, usize)> = ms
                .iter()
                .map(|&m| (m, kind.n_terms(n_samples, m)))
                .collect();
            let sums = sum_sq_diffs(x, order, &lags);
            lags.iter()
                .zip(sums)
                .map(|(&(m, n), s)| kind.normalize(s, m, n))
                .collect()
        }
        Kind::Mdev => {
            // V_j = sum_{i=j}^{j+m-1} (X[i+2m] - 2X[i+m] + X[i]) = Z[j+2m] - 2Z[j+m] + Z[j]
            // with Z the running sum of the window sums W_i = X[i+m] - X[i]: the same
            // second difference as ADEV, one level up. Z (N + 2 - m points) is built
            // with the compensated scan; |Z| <= 2m max|X| keeps it well conditioned.
            let mut z = vec![0.0f64; n_samples + 2];
            ms.iter()
                .map(|&m| {
                    let zl = &mut z[..n_samples + 2 - m];
                    compensated_prefix(zl, |i| x[i + m] - x[i]);
                    let n = kind.n_terms(n_samples, m);
                    let s = sum_sq_diffs(zl, 2, &[(m, n)])[0];
                    kind.normalize(s, m, n)
                })
                .collect()
        }
    }
}
