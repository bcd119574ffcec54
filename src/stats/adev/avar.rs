//! The maximum-overlap Allan variance exactly as the R package avar computes it
//! (`avar_mo_cpp` in src/allan_variance.cpp of github.com/SMAC-Group/avar, used by
//! `avar(x, type = "mo")`), for comparison with curves that package produced.
//!
//! avar uses cluster sizes m = 2^1, 2^2, ..., 2^J with J = floor(log2 T) - 1 (T rate
//! samples; no m = 1), cluster means ybar_j = mean(y_j..y_{j+m-1}) for j = 0..=T-m, and
//!
//!   AVAR_avar(m) = sum_{k=0}^{T-2m-1} (ybar_k - ybar_{k+m})^2 / (2 (T - 2m + 1)).
//!
//! The sum runs over T - 2m terms but the divisor counts T - 2m + 1: the last available
//! difference (k = T - 2m) is left out of the sum yet counted. The standard overlapping
//! estimator (SP 1065 eq. (10), allantools `oadev`, [`super::Kind::Adev`]) sums all
//! T - 2m + 1 terms, so
//!
//!   AVAR_avar(m) = AVAR_oadev(m) - (ybar_{T-2m} - ybar_{T-m})^2 / (2 (T - 2m + 1)),
//!
//! a difference of order 1 / (T - 2m + 1) relative, larger at large m.

use super::fast::sum_sq_diffs;

/// avar's cluster sizes for T samples: 2, 4, ..., 2^J, J = floor(log2 T) - 1.
pub fn avar_levels(n_samples: usize) -> Vec<usize> {
    if n_samples < 4 {
        return Vec::new();
    }
    let j = (usize::BITS - 1 - n_samples.leading_zeros()) as usize - 1;
    (1..=j).map(|i| 1usize << i).collect()
}

/// avar's maximum-overlap Allan *deviation* at cluster size m (the square root of the
/// variance above), from the phase `x` of the series ([`super::phase::phase`]).
pub fn avar_mo_deviation(x: &[f64], m: usize) -> f64 {
    let t = x.len() - 1;
    assert!(
        m >= 1 && 2 * m < t,
        "cluster size {m} out of range for {t} samples"
    );
    let summed_terms = t - 2 * m;
    let s = sum_sq_diffs(x, 2, &[(m, summed_terms)])[0];
    let mf = m as f64;
    (s / (mf * mf) / (2.0 * (t - 2 * m + 1) as f64)).sqrt()
}

/// The same straight from avar's loops (the slow twin).
pub fn avar_mo_deviation_slow(y: &[f64], m: usize) -> f64 {
    let t = y.len();
    assert!(m >= 1 && 2 * m < t);
    let ybar: Vec<f64> = (0..=t - m)
        .map(|j| y[j..j + m].iter().sum::<f64>() / m as f64)
        .collect();
    let mut summed = 0.0;
    for k in 0..t - 2 * m {
        let d = ybar[k] - ybar[k + m];
        summed += d * d;
    }
    (summed / (2.0 * (t - 2 * m + 1) as f64)).sqrt()
}
