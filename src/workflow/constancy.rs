//! Are the coefficient functions constant at all? A bootstrap generalized likelihood
//! ratio test of H0: f_m(u) = a_m for every m (the linear ARMA(p,q)) against the
//! FARMA(p,q,d) alternative.
//!
//! Statistic (Fan, Zhang and Zhang 2001, Ann. Statist. 29, eq. 2.4; for functional-
//! coefficient autoregressions Cai, Fan and Yao 2000, JASA 95, section 3.2):
//! T = (m / 2) ln(RSS_0 / RSS_1), RSS_0 of the linear ARMA(p,q) by conditional least
//! squares (the FARMA fit's own linear start, [`linear_start`]), RSS_1 of the
//! FARMA(p,q,d) at a fixed bandwidth h, both over the rows t >= max(p,q,d), m their
//! number. Null distribution by the residual bootstrap of
//! Cai, Fan and Yao: B series are simulated from the fitted ARMA(p,q) with innovations
//! drawn with replacement from its centred residuals (200 samples of burn-in,
//! discarded), T* is computed on each with the same h and grid, and
//! p = (1 + #{T* >= T}) / (B + 1). The bandwidth is either fixed in advance (the same h
//! for T and every T*), or, with `farma.bandwidth` None, chosen by GCV on the series
//! and chosen again by GCV on every replicate: the selection is then part of the
//! statistic and the bootstrap reproduces it. A bandwidth chosen by GCV on the data and
//! held fixed in the replicates is not a valid use: GCV picks a small h where the
//! series happens to look nonlinear, T is large there and the replicates, without that
//! chance structure, do not follow; measured, that rejected 16 of 100 linear ARMA(2,1)
//! series at 5 % (BENCHMARKS.md, `benches/constancy.rs`). Replicate i draws from its own ChaCha8 stream
//! (seed, i), so the result does not depend on the number of threads.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::estimator::arma::arma_residuals;
use crate::estimator::fit::linear_start;
use crate::estimator::{FarmaParams, fit};

/// Parameters of the constancy test.
#[derive(Clone, Debug)]
pub struct ConstancyParams {
    /// Bootstrap replicates B.
    pub bootstrap: usize,
    pub seed: u64,
    /// The FARMA fit's parameters (order, grid); a bandwidth fixed in advance, or None:
    /// GCV on the series and on every replicate.
    pub farma: FarmaParams,
}

/// Result of the constancy test.
#[derive(Clone, Debug)]
pub struct Constancy {
    pub statistic: f64,
    pub p_value: f64,
    pub bootstrap: usize,
    /// The bandwidth of T (fixed, or GCV's choice on the series).
    pub bandwidth: f64,
    pub rss0: f64,
    pub rss1: f64,
    /// The bootstrap statistics T*, replicate order.
    pub t_boot: Vec<f64>,
}

impl Constancy {
    /// The smallest p-value the test can return: 1 / (B + 1) for a bootstrap of B
    /// replicates (what B can resolve).
    pub fn min_p(&self) -> f64 {
        1.0 / (self.bootstrap + 1) as f64
    }
}

/// The GLR statistic of one series and the null model behind it.
struct Glr {
    t: f64,
    rss0: f64,
    rss1: f64,
    /// The FARMA fit's bandwidth.
    h: f64,
    ar: Vec<f64>,
    ma: Vec<f64>,
    /// Residuals of the ARMA fit.
    e: Vec<f64>,
}

/// T, RSS_0, RSS_1 and the ARMA fit of a (demeaned) series (at the fixed bandwidth,
/// or by GCV).
fn glr(x: &[f64], prm: &FarmaParams) -> Result<Glr> {
    let (p, q, d) = (prm.p, prm.q, prm.d);
    let n = x.len();
    let start = p.max(q).max(d);
    let (ar, ma) = linear_start(x, p, q, start).ok_or_else(|| {
        Error::Data(format!(
            "constancy test: the linear ARMA({p},{q}) fit failed (singular design)"
        ))
    })?;
    let mut e = vec![0.0; n];
    arma_residuals(x, &ar, &ma, &mut e);
    let rss0: f64 = e[start..].iter().map(|v| v * v).sum();
    let valid = FarmaParams {
        demean: false,
        ..prm.clone()
    }
    .validate(n)?;
    let (m1, r1) = fit(x, &valid)?;
    let t = 0.5 * (n - start) as f64 * (rss0 / r1.rss).ln();
    Ok(Glr {
        t,
        rss0,
        rss1: r1.rss,
        h: m1.bandwidth,
        ar,
        ma,
        e,
    })
}

/// The test on series `x` (its mean is removed first).
pub fn constancy_test(x: &[f64], prm: &ConstancyParams) -> Result<Constancy> {
    if prm.bootstrap == 0 {
        return Err(Error::Usage("--bootstrap must be at least 1".into()));
    }
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let xc: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let Glr {
        t,
        rss0,
        rss1,
        h,
        ar,
        ma,
        e,
    } = glr(&xc, &prm.farma)?;
    let start = prm.farma.p.max(prm.farma.q).max(prm.farma.d);
    let pool: Vec<f64> = {
        let r = &e[start..];
        let m = r.iter().sum::<f64>() / r.len() as f64;
        r.iter().map(|v| v - m).collect()
    };
    let burn = 200;
    let t_boot: Vec<f64> = (0..prm.bootstrap)
        .into_par_iter()
        .map(|i| {
            let mut rng = ChaCha8Rng::seed_from_u64(prm.seed);
            rng.set_stream(i as u64 + 1);
            let total = n + burn;
            let mut xs = vec![0.0; total];
            let mut es = vec![0.0; total];
            for s in 0..total {
                es[s] = pool[rng.random_range(0..pool.len())];
                let mut v = es[s];
                for (k, a) in ar.iter().enumerate() {
                    if s > k {
                        v += a * xs[s - k - 1];
                    }
                }
                for (k, b) in ma.iter().enumerate() {
                    if s > k {
                        v += b * es[s - k - 1];
                    }
                }
                xs[s] = v;
            }
            let xb = &xs[burn..];
            let mb = xb.iter().sum::<f64>() / n as f64;
            let xb: Vec<f64> = xb.iter().map(|v| v - mb).collect();
            glr(&xb, &prm.farma).map(|r| r.t).unwrap_or(f64::NAN)
        })
        .collect();
    let ok: Vec<f64> = t_boot.iter().copied().filter(|v| v.is_finite()).collect();
    if ok.is_empty() {
        return Err(Error::Data(
            "constancy test: no bootstrap replicate could be fitted".into(),
        ));
    }
    let exceed = ok.iter().filter(|v| **v >= t).count();
    Ok(Constancy {
        statistic: t,
        p_value: (1 + exceed) as f64 / (ok.len() + 1) as f64,
        bootstrap: ok.len(),
        bandwidth: h,
        rss0,
        rss1,
        t_boot,
    })
}
