//! Linear ARMA(p,q) by conditional least squares: the start of the FARMA alternation
//! and the linear baseline a user would fit instead.
//!
//! Model: x_t = sum_{m=1..p} a_m x_{t-m} + e_t + sum_{m=1..q} b_m e_{t-m}, residuals
//! by the recursion with zeros before the first sample. Start: Hannan and Rissanen
//! (1982): a long AR(k) by least squares (k = ceil(10 log10 N), at most 40) gives
//! residual estimates, then x_t is regressed on its p lags and q lagged residuals.
//! Refinement: Gauss-Newton on sum e_t^2 (t >= max(p,q)), the derivatives following
//! d e_t/d a_m = -x_{t-m} - sum_k b_k d e_{t-k}/d a_m and
//! d e_t/d b_m = -e_{t-m} - sum_k b_k d e_{t-k}/d b_m (Box, Jenkins and Reinsel, 7.2),
//! with step halving; an MA part outside the invertible region is rejected.

use super::linalg::normal_equations;

/// A fitted linear ARMA model.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearArma {
    pub ar: Vec<f64>,
    pub ma: Vec<f64>,
    /// Sum of squared residuals over t >= max(p, q).
    pub rss: f64,
    pub iterations: usize,
}

/// Residuals of a linear ARMA by the recursion (zeros before the first sample).
pub fn arma_residuals(x: &[f64], ar: &[f64], ma: &[f64], e: &mut [f64]) {
    for t in 0..x.len() {
        let mut s = x[t];
        for (m, a) in ar.iter().enumerate() {
            if t > m {
                s -= a * x[t - m - 1];
            }
        }
        for (m, b) in ma.iter().enumerate() {
            if t > m {
                s -= b * e[t - m - 1];
            }
        }
        e[t] = s;
    }
}

/// Least squares of y_t on columns of lagged series, rows t in `rows`.
/// `cols` gives for each regressor (series, lag).
fn lagged_ls(
    y: &[f64],
    series: &[&[f64]],
    cols: &[(usize, usize)],
    rows: std::ops::Range<usize>,
) -> Option<Vec<f64>> {
    let k = cols.len();
    if k > 2 && cols.iter().enumerate().all(|(i, c)| *c == (0, i + 1)) {
        return lagged_ls_one_series(y, series[0], k, rows);
    }
    let mut ata = vec![0.0; k * k];
    let mut aty = vec![0.0; k];
    let mut v = vec![0.0; k];
    for t in rows {
        for (i, (s, lag)) in cols.iter().enumerate() {
            v[i] = series[*s][t - lag];
        }
        // the upper triangle only (v_i v_j = v_j v_i exactly: the mirrored sums are
        // the same bits)
        for i in 0..k {
            let vi = v[i];
            for (a, vj) in ata[i * k + i..(i + 1) * k].iter_mut().zip(&v[i..]) {
                *a += vi * vj;
            }
            aty[i] += vi * y[t];
        }
    }
    for i in 0..k {
        for j in 0..i {
            ata[i * k + j] = ata[j * k + i];
        }
    }
    normal_equations(&ata, &aty, k)
}

/// [`lagged_ls`] on the lags 1..=k of one series x (the long autoregression of
/// Hannan-Rissanen): the Gram matrix of lagged x is Toeplitz up to its ends, so only
/// its first row is summed over the rows (O(N k) instead of O(N k^2)); along each
/// diagonal, G[i+1][j+1] = G[i][j] + x[r0-2-i] x[r0-2-j] - x[r1-2-i] x[r1-2-j] for
/// rows r0..r1 (the window of products moved back by one sample). Each step adds one
/// product to a sum of N, so the rounding stays at the level of the direct sums (the
/// results differ from them in the last bits only). Twin-tested against the direct
/// sums below.
fn lagged_ls_one_series(
    y: &[f64],
    x: &[f64],
    k: usize,
    rows: std::ops::Range<usize>,
) -> Option<Vec<f64>> {
    let (r0, r1) = (rows.start, rows.end);
    if r1 <= r0 {
        return None;
    }
    let mut ata = vec![0.0; k * k];
    let mut aty = vec![0.0; k];
    // first row: G[0][j] = sum_t x[t-1] x[t-1-j]; aty[i] = sum_t x[t-1-i] y[t]
    for t in rows {
        let x1 = x[t - 1];
        for (j, a) in ata[..k].iter_mut().enumerate() {
            *a += x1 * x[t - 1 - j];
        }
        for (i, a) in aty.iter_mut().enumerate() {
            *a += x[t - 1 - i] * y[t];
        }
    }
    for i in 0..k - 1 {
        for j in i..k - 1 {
            let v = ata[i * k + j] + x[r0 - 2 - i] * x[r0 - 2 - j] - x[r1 - 2 - i] * x[r1 - 2 - j];
            ata[(i + 1) * k + j + 1] = v;
        }
    }
    for i in 0..k {
        for j in 0..i {
            ata[i * k + j] = ata[j * k + i];
        }
    }
    normal_equations(&ata, &aty, k)
}

/// True when the MA polynomial 1 + b_1 z + ... has all roots outside the unit circle
/// (checked by the Schur-Cohn / Jury recursion on the reversed coefficients).
pub fn ma_invertible(b: &[f64]) -> bool {
    // Step-down (Levinson) recursion: invertible iff every reflection coefficient |k| < 1.
    let mut a: Vec<f64> = b.to_vec();
    while let Some(&k) = a.last() {
        if k.abs() >= 1.0 {
            return false;
        }
        let n = a.len();
        let denom = 1.0 - k * k;
        let next: Vec<f64> = (0..n - 1)
            .map(|i| (a[i] - k * a[n - 2 - i]) / denom)
            .collect();
        a = next;
    }
    true
}

/// Hannan-Rissanen start, then conditional least squares.
pub fn fit_arma(x: &[f64], p: usize, q: usize) -> Option<LinearArma> {
    let n = x.len();
    let pq = p.max(q);
    if n < 10 * (p + q + 1) {
        return None;
    }
    let mut e = vec![0.0; n];
    let (mut ar, mut ma) = if q == 0 {
        let cols: Vec<(usize, usize)> = (1..=p).map(|l| (0, l)).collect();
        (lagged_ls(x, &[x], &cols, p..n)?, vec![])
    } else {
        let k = ((10.0 * (n as f64).log10()).ceil() as usize)
            .clamp(p + q, 40)
            .min(n / 5);
        let cols: Vec<(usize, usize)> = (1..=k).map(|l| (0, l)).collect();
        let long = lagged_ls(x, &[x], &cols, k..n)?;
        let mut eh = vec![0.0; n];
        for t in k..n {
            eh[t] = x[t] - (1..=k).map(|l| long[l - 1] * x[t - l]).sum::<f64>();
        }
        let mut cols: Vec<(usize, usize)> = (1..=p).map(|l| (0, l)).collect();
        cols.extend((1..=q).map(|l| (1, l)));
        let c = lagged_ls(x, &[x, &eh], &cols, k + q..n)?;
        let mut ma = c[p..].to_vec();
        if !ma_invertible(&ma) {
            ma = vec![0.0; q];
        }
        (c[..p].to_vec(), ma)
    };
    arma_residuals(x, &ar, &ma, &mut e);
    let rss_of = |e: &[f64]| e[pq..].iter().map(|v| v * v).sum::<f64>();
    let mut rss = rss_of(&e);
    let k = p + q;
    let mut iterations = 0;
    let mut de = vec![0.0; n * k];
    for _ in 0..50 {
        iterations += 1;
        // derivative series
        for t in 0..n {
            for j in 0..k {
                let mut v = if j < p {
                    if t > j { -x[t - j - 1] } else { 0.0 }
                } else {
                    let m = j - p;
                    if t > m { -e[t - m - 1] } else { 0.0 }
                };
                for (kk, b) in ma.iter().enumerate() {
                    if t > kk {
                        v -= b * de[(t - kk - 1) * k + j];
                    }
                }
                de[t * k + j] = v;
            }
        }
        let mut jtj = vec![0.0; k * k];
        let mut jte = vec![0.0; k];
        for t in pq..n {
            let row = &de[t * k..(t + 1) * k];
            for i in 0..k {
                for j in 0..k {
                    jtj[i * k + j] += row[i] * row[j];
                }
                jte[i] -= row[i] * e[t];
            }
        }
        let Some(step) = normal_equations(&jtj, &jte, k) else {
            break;
        };
        let mut scale = 1.0;
        let mut improved = false;
        let mut e_try = vec![0.0; n];
        for _ in 0..20 {
            let ar_try: Vec<f64> = (0..p).map(|i| ar[i] + scale * step[i]).collect();
            let ma_try: Vec<f64> = (0..q).map(|i| ma[i] + scale * step[p + i]).collect();
            if ma_invertible(&ma_try) {
                arma_residuals(x, &ar_try, &ma_try, &mut e_try);
                let r = rss_of(&e_try);
                if r <= rss {
                    let done = rss - r <= 1e-12 * rss;
                    ar = ar_try;
                    ma = ma_try;
                    rss = r;
                    std::mem::swap(&mut e, &mut e_try);
                    improved = !done;
                    break;
                }
            }
            scale *= 0.5;
        }
        if !improved {
            break;
        }
    }
    Some(LinearArma {
        ar,
        ma,
        rss,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    #[test]
    fn one_series_gram_equals_the_direct_sums() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let x: Vec<f64> = (0..5000)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                0.3 + z
            })
            .collect();
        for k in [3, 12, 40] {
            let cols: Vec<(usize, usize)> = (1..=k).map(|l| (0, l)).collect();
            let fast = lagged_ls(&x, &[&x], &cols, k + 1..x.len()).unwrap();
            // the direct sums: the general path, reached by listing the columns reversed
            let rev: Vec<(usize, usize)> = cols.iter().rev().copied().collect();
            let mut slow = lagged_ls(&x, &[&x], &rev, k + 1..x.len()).unwrap();
            slow.reverse();
            for (a, b) in fast.iter().zip(&slow) {
                assert!(
                    (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                    "k {k}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn recovers_an_arma21() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let n = 50_000;
        let mut x = vec![0.0; n];
        let mut u = vec![0.0; n];
        for t in 0..n {
            u[t] = StandardNormal.sample(&mut rng);
            x[t] = u[t];
            if t >= 2 {
                x[t] += 0.5 * x[t - 1] - 0.3 * x[t - 2] + 0.4 * u[t - 1];
            }
        }
        let m = fit_arma(&x, 2, 1).unwrap();
        assert!(
            (m.ar[0] - 0.5).abs() < 0.03 && (m.ar[1] + 0.3).abs() < 0.03,
            "{m:?}"
        );
        assert!((m.ma[0] - 0.4).abs() < 0.03, "{m:?}");
        assert!(
            ma_invertible(&[0.5])
                && !ma_invertible(&[1.2])
                && ma_invertible(&[0.5, 0.2])
                && !ma_invertible(&[0.0, 1.5])
        );
    }
}
