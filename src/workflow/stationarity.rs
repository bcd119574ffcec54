//! The reverse-arrangement test of stationarity (Bendat and Piersol, Random Data,
//! 4th ed., 4.5.2).
//!
//! The series is cut into K equal segments (the remainder dropped at the end) and a
//! statistic y_i of each is taken (the mean, or the mean square). A reverse
//! arrangement is a pair i < j with y_i > y_j; A is their number. For K independent,
//! identically distributed y_i, E\[A\] = K (K - 1) / 4 and
//! Var\[A\] = K (2K + 5) (K - 1) / 72; z = (A - E\[A\]) / sqrt(Var\[A\]) and the two-sided
//! p-value 2 (1 - Phi(|z|)) (a trend in either direction rejects). A is counted by a
//! merge sort in O(K log K), twin-tested against the O(K^2) definition.

use crate::stats::special::normal_two_sided_p;

/// The per-segment statistic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SegmentStat {
    Mean,
    MeanSquare,
}

impl SegmentStat {
    pub fn as_str(self) -> &'static str {
        match self {
            SegmentStat::Mean => "mean",
            SegmentStat::MeanSquare => "mean_square",
        }
    }
}

/// Result of the reverse-arrangement test.
#[derive(Clone, Debug, PartialEq)]
pub struct ReverseArrangement {
    pub segments: usize,
    /// The number of reverse arrangements A.
    pub statistic: u64,
    pub mean: f64,
    pub variance: f64,
    pub z: f64,
    /// Two-sided p-value (normal approximation).
    pub p_value: f64,
}

/// Number of pairs i < j with y_i > y_j, by definition (O(n^2)).
pub fn reverse_arrangements_brute(y: &[f64]) -> u64 {
    let mut a = 0;
    for i in 0..y.len() {
        for j in i + 1..y.len() {
            if y[i] > y[j] {
                a += 1;
            }
        }
    }
    a
}

/// Number of pairs i < j with y_i > y_j, by merge sort (O(n log n)).
pub fn reverse_arrangements(y: &[f64]) -> u64 {
    fn sort_count(v: &mut [f64], buf: &mut [f64]) -> u64 {
        let n = v.len();
        if n < 2 {
            return 0;
        }
        let mid = n / 2;
        let mut c = sort_count(&mut v[..mid], &mut buf[..mid]);
        c += sort_count(&mut v[mid..], &mut buf[mid..]);
        let (mut i, mut j, mut k) = (0, mid, 0);
        while i < mid && j < n {
            // strict: equal values are not reverse arrangements
            if v[j] < v[i] {
                c += (mid - i) as u64;
                buf[k] = v[j];
                j += 1;
            } else {
                buf[k] = v[i];
                i += 1;
            }
            k += 1;
        }
        buf[k..k + mid - i].copy_from_slice(&v[i..mid]);
        k += mid - i;
        buf[k..k + n - j].copy_from_slice(&v[j..n]);
        v.copy_from_slice(&buf[..n]);
        c
    }
    let mut v = y.to_vec();
    let mut buf = vec![0.0; y.len()];
    sort_count(&mut v, &mut buf)
}

/// The segment statistics of `x` cut into `k` equal segments.
pub fn segment_stats(x: &[f64], k: usize, stat: SegmentStat) -> Vec<f64> {
    let len = x.len() / k.max(1);
    (0..k)
        .map(|i| {
            let s = &x[i * len..(i + 1) * len];
            match stat {
                SegmentStat::Mean => s.iter().sum::<f64>() / len as f64,
                SegmentStat::MeanSquare => s.iter().map(|v| v * v).sum::<f64>() / len as f64,
            }
        })
        .collect()
}

/// The test on values `y` taken as the K segment statistics.
pub fn reverse_arrangement_test(y: &[f64]) -> ReverseArrangement {
    let k = y.len() as f64;
    let a = reverse_arrangements(y);
    let mean = k * (k - 1.0) / 4.0;
    let variance = k * (2.0 * k + 5.0) * (k - 1.0) / 72.0;
    let z = (a as f64 - mean) / variance.sqrt();
    ReverseArrangement {
        segments: y.len(),
        statistic: a,
        mean,
        variance,
        z,
        p_value: normal_two_sided_p(z),
    }
}

/// The test on series `x` cut into `segments` pieces (each at least 2 samples).
pub fn reverse_arrangement_series(
    x: &[f64],
    segments: usize,
    stat: SegmentStat,
) -> ReverseArrangement {
    reverse_arrangement_test(&segment_stats(x, segments, stat))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_cases() {
        // (3,1,2): 3>1, 3>2 -> 2. (5,3,8,1): 5>3, 5>1, 3>1, 8>1 -> 4.
        assert_eq!(reverse_arrangements(&[3.0, 1.0, 2.0]), 2);
        assert_eq!(reverse_arrangements(&[5.0, 3.0, 8.0, 1.0]), 4);
        assert_eq!(reverse_arrangements(&[1.0, 1.0, 1.0]), 0);
        assert_eq!(reverse_arrangements(&[4.0, 3.0, 2.0, 1.0]), 6);
        // K = 4, A = 4: E = 3, Var = 4 * 13 * 3 / 72 = 2.1667, z = 1 / 1.4720 = 0.6794
        let r = reverse_arrangement_test(&[5.0, 3.0, 8.0, 1.0]);
        assert_eq!(r.mean, 3.0);
        assert!((r.variance - 156.0 / 72.0).abs() < 1e-15);
        assert!((r.z - 1.0 / (156.0f64 / 72.0).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn merge_count_matches_the_definition() {
        let mut s = 12345u64;
        for n in [0, 1, 2, 7, 64, 301] {
            let y: Vec<f64> = (0..n)
                .map(|_| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    ((s >> 40) % 50) as f64 // ties included
                })
                .collect();
            assert_eq!(
                reverse_arrangements(&y),
                reverse_arrangements_brute(&y),
                "n = {n}"
            );
        }
    }
}
