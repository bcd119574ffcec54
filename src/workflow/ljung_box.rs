//! Residual whiteness: the sample autocorrelation with its white-noise band and the
//! Ljung-Box portmanteau test.
//!
//! r_k = sum_{t=0}^{n-k-1} (x_t - xbar)(x_{t+k} - xbar) / sum_t (x_t - xbar)^2 (the
//! biased estimator, as statsmodels `acf(adjusted=False)`); band +-1.96 / sqrt(n)
//! (Box, Jenkins and Reinsel, 4th ed., 2.1.6). Ljung and Box (1978):
//! Q(h) = n (n + 2) sum_{k=1}^{h} r_k^2 / (n - k), against chi-squared with h - model_df
//! degrees of freedom (statsmodels `acorr_ljungbox(x, lags, model_df)`). A small ACF is
//! written here (direct sums, O(n L)); `stats::acf` of the `char` branch is the general one.

use crate::stats::special::chi2_sf;

/// Sample autocorrelations r_1 .. r_maxlag.
pub fn acf(x: &[f64], maxlag: usize) -> Vec<f64> {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let c: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let c0: f64 = c.iter().map(|v| v * v).sum();
    (1..=maxlag.min(n.saturating_sub(1)))
        .map(|k| {
            c[..n - k]
                .iter()
                .zip(&c[k..])
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / c0
        })
        .collect()
}

/// One Ljung-Box row.
#[derive(Clone, Debug, PartialEq)]
pub struct LjungBox {
    pub lag: usize,
    pub q: f64,
    /// Degrees of freedom, lag - model_df.
    pub df: usize,
    pub p_value: f64,
}

/// Ljung-Box Q at each of `lags` (each > model_df), from autocorrelations `r`
/// (r\[0\] = r_1) of a series of length n.
pub fn ljung_box(r: &[f64], n: usize, lags: &[usize], model_df: usize) -> Vec<LjungBox> {
    let nf = n as f64;
    lags.iter()
        .filter(|&&h| h > model_df && h <= r.len())
        .map(|&h| {
            let q = nf
                * (nf + 2.0)
                * (1..=h)
                    .map(|k| r[k - 1] * r[k - 1] / (nf - k as f64))
                    .sum::<f64>();
            let df = h - model_df;
            LjungBox {
                lag: h,
                q,
                df,
                p_value: chi2_sf(q, df as f64),
            }
        })
        .collect()
}

/// The whiteness summary of a residual series.
#[derive(Clone, Debug)]
pub struct Whiteness {
    pub n: usize,
    /// r_1 .. r_L.
    pub acf: Vec<f64>,
    /// 1.96 / sqrt(n).
    pub band: f64,
    /// Lags with |r_k| above the band.
    pub outside: usize,
    pub ljung_box: Vec<LjungBox>,
}

/// ACF up to `maxlag` and Ljung-Box at `lags` (those above model_df).
pub fn whiteness(e: &[f64], maxlag: usize, lags: &[usize], model_df: usize) -> Whiteness {
    let r = acf(e, maxlag);
    let band = 1.96 / (e.len() as f64).sqrt();
    Whiteness {
        n: e.len(),
        outside: r.iter().filter(|v| v.abs() > band).count(),
        ljung_box: ljung_box(&r, e.len(), lags, model_df),
        acf: r,
        band,
    }
}
