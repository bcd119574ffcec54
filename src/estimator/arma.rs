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

/// One streaming pass of the ARMA(p,q) recursion e_t = x_t - sum a_m x_{t-m} -
/// sum b_m e_{t-m} (zeros before the first sample) with its derivatives
/// d e_t / d a_j = -x_{t-j} - sum_k b_k d e_{t-k} / d a_j and
/// d e_t / d b_j = -e_{t-j} - sum_k b_k d e_{t-k} / d b_j (Box, Jenkins and Reinsel,
/// 7.2): returns the RSS over t >= `start` and the Gauss-Newton normal equations J'J
/// and -J'e (k = p + q unknowns, row-major). The recursions keep only the last q
/// values of e and of the derivatives: nothing N-long is allocated.
pub(crate) fn arma_pass(
    x: &[f64],
    start: usize,
    a: &[f64],
    b: &[f64],
) -> (f64, Vec<f64>, Vec<f64>) {
    macro_rules! fixed {
        ($(($p:literal, $q:literal)),*) => {
            match (a.len(), b.len()) {
                $(($p, $q) => return arma_pass_fixed::<$p, $q, { $p + $q }>(x, start, a, b),)*
                _ => {}
            }
        };
    }
    fixed!(
        (0, 1),
        (0, 2),
        (1, 1),
        (2, 1),
        (3, 1),
        (1, 2),
        (2, 2),
        (3, 2)
    );
    arma_pass_any(x, start, a, b)
}

/// [`arma_pass`] for orders known at compile time: the last p values of x, q of e and
/// of the derivatives kept in registers, zeros before the first sample (subtracting
/// a zero term leaves every sum as the general version's, bit for bit).
fn arma_pass_fixed<const P: usize, const Q: usize, const K: usize>(
    x: &[f64],
    start: usize,
    a: &[f64],
    b: &[f64],
) -> (f64, Vec<f64>, Vec<f64>) {
    debug_assert_eq!(P + Q, K);
    let mut aa = [0.0f64; P];
    aa.copy_from_slice(a);
    let mut bb = [0.0f64; Q];
    bb.copy_from_slice(b);
    let mut xh = [0.0f64; P];
    let mut eh = [0.0f64; Q];
    let mut dh = [[0.0f64; K]; Q];
    let mut jtj = [[0.0f64; K]; K];
    let mut jte = [0.0f64; K];
    let mut rss = 0.0;
    for (t, &xt) in x.iter().enumerate() {
        let mut s = xt;
        for m in 0..P {
            s -= aa[m] * xh[m];
        }
        for m in 0..Q {
            s -= bb[m] * eh[m];
        }
        let mut de = [0.0f64; K];
        for j in 0..K {
            let mut v = if j < P { -xh[j] } else { -eh[j - P] };
            for kk in 0..Q {
                v -= bb[kk] * dh[kk][j];
            }
            de[j] = v;
        }
        if t >= start {
            rss += s * s;
            for i in 0..K {
                for j in 0..K {
                    jtj[i][j] += de[i] * de[j];
                }
                jte[i] -= de[i] * s;
            }
        }
        for m in (1..P).rev() {
            xh[m] = xh[m - 1];
        }
        if P > 0 {
            xh[0] = xt;
        }
        for kk in (1..Q).rev() {
            eh[kk] = eh[kk - 1];
            dh[kk] = dh[kk - 1];
        }
        if Q > 0 {
            eh[0] = s;
            dh[0] = de;
        }
    }
    let jtj: Vec<f64> = (0..K * K).map(|i| jtj[i / K][i % K]).collect();
    (rss, jtj, jte.to_vec())
}

/// [`arma_pass`] for any order.
fn arma_pass_any(x: &[f64], start: usize, a: &[f64], b: &[f64]) -> (f64, Vec<f64>, Vec<f64>) {
    let (p, q) = (a.len(), b.len());
    let k = p + q;
    let n = x.len();
    let mut ehist = [0.0f64; 8];
    // dhist[kk * k + j] = d e_{t-kk-1} / d theta_j, theta = (a, b)
    let mut dhist = [0.0f64; 8 * 16];
    let mut de = [0.0f64; 16];
    let mut jtj = vec![0.0; k * k];
    let mut jte = vec![0.0; k];
    let mut rss = 0.0;
    for t in 0..n {
        let mut s = x[t];
        for (m, am) in a.iter().enumerate() {
            if t > m {
                s -= am * x[t - m - 1];
            }
        }
        for (m, bm) in b.iter().enumerate() {
            if t > m {
                s -= bm * ehist[m];
            }
        }
        for j in 0..k {
            let mut v = if j < p {
                if t > j { -x[t - j - 1] } else { 0.0 }
            } else if t > j - p {
                -ehist[j - p]
            } else {
                0.0
            };
            for (kk, bk) in b.iter().enumerate() {
                if t > kk {
                    v -= bk * dhist[kk * k + j];
                }
            }
            de[j] = v;
        }
        if t >= start {
            rss += s * s;
            for i in 0..k {
                for j in 0..k {
                    jtj[i * k + j] += de[i] * de[j];
                }
                jte[i] -= de[i] * s;
            }
        }
        for kk in (1..q).rev() {
            ehist[kk] = ehist[kk - 1];
            for j in 0..k {
                dhist[kk * k + j] = dhist[(kk - 1) * k + j];
            }
        }
        ehist[0] = s;
        dhist[..k].copy_from_slice(&de[..k]);
    }
    (rss, jtj, jte)
}

/// Hannan-Rissanen start, then conditional least squares.
pub fn fit_arma(x: &[f64], p: usize, q: usize) -> Option<LinearArma> {
    let n = x.len();
    let pq = p.max(q);
    if n < 10 * (p + q + 1) {
        return None;
    }
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
    // Gauss-Newton: each pass gives the RSS and the normal equations at its point
    // (the derivative recursion above, summed over t >= max(p, q)), so an accepted
    // step costs one pass
    let k = p + q;
    let (mut rss, mut jtj, mut jte) = arma_pass(x, pq, &ar, &ma);
    let mut iterations = 0;
    for _ in 0..50 {
        iterations += 1;
        let Some(step) = normal_equations(&jtj, &jte, k) else {
            break;
        };
        let mut scale = 1.0;
        let mut improved = false;
        for _ in 0..20 {
            let ar_try: Vec<f64> = (0..p).map(|i| ar[i] + scale * step[i]).collect();
            let ma_try: Vec<f64> = (0..q).map(|i| ma[i] + scale * step[p + i]).collect();
            if ma_invertible(&ma_try) {
                let (r, jt, je) = arma_pass(x, pq, &ar_try, &ma_try);
                if r <= rss {
                    let done = rss - r <= 1e-12 * rss;
                    (ar, ma, rss, jtj, jte) = (ar_try, ma_try, r, jt, je);
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
    fn fixed_order_pass_equals_the_general_pass() {
        // arma_pass_fixed (registers, zeros before the first sample) against
        // arma_pass_any (explicit checks), every specialised order, to the bit
        let mut s: u64 = 7;
        let x: Vec<f64> = (0..3000)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let a_all = [0.4, -0.2, 0.1];
        let b_all = [-0.5, 0.2];
        for (p, q) in [
            (0, 1),
            (0, 2),
            (1, 1),
            (2, 1),
            (3, 1),
            (1, 2),
            (2, 2),
            (3, 2),
        ] {
            let (a, b) = (&a_all[..p], &b_all[..q]);
            for start in [p.max(q), 5] {
                let fast = arma_pass(&x, start, a, b);
                let slow = arma_pass_any(&x, start, a, b);
                assert_eq!(fast.0.to_bits(), slow.0.to_bits(), "({p},{q}) rss");
                for (u, v) in fast
                    .1
                    .iter()
                    .chain(&fast.2)
                    .zip(slow.1.iter().chain(&slow.2))
                {
                    assert_eq!(u.to_bits(), v.to_bits(), "({p},{q}) normal equations");
                }
            }
        }
    }

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
