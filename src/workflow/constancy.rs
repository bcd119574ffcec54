//! Are the coefficient functions constant at all? A test of H0: f_m(u) = a_m for every
//! m (the linear ARMA(p,q)) against the FARMA(p,q,d) alternative, by the generalized
//! likelihood ratio (Fan, Zhang and Zhang 2001, Ann. Statist. 29, eq. 2.4; for
//! functional-coefficient autoregressions Cai, Fan and Yao 2000, JASA 95, section 3.2):
//! T = (m / 2) ln(RSS_0 / RSS_1), RSS_0 of the linear ARMA(p,q) by conditional least
//! squares (the FARMA fit's own linear start, [`linear_start`]), RSS_1 of the
//! FARMA(p,q,d) at bandwidth h, both over the rows t >= max(p,q,d), m their number.
//! Two null distributions:
//!
//! - **chi2** (the default, [`ConstancyTest::Chi2`]): h fixed in advance, h = 0.5 sd(x)
//!   ([`CHI2_H_SD`]) unless the user fixed one; at a fixed h the local-linear f-step is
//!   a linear smoother S that reproduces the null's constant f_m, and 2T, about
//!   (RSS_0 - RSS_1) / sigma^2, is referred to chi2 on tr(S) - p degrees of freedom
//!   (the effective-degrees-of-freedom test of Hastie and Tibshirani, Generalized
//!   Additive Models, 1990, 3.9; the Wilks phenomenon of FZZ 2001 says the null
//!   distribution does not depend on the nuisance a_m, b). Cost: one FARMA fit at a
//!   fixed bandwidth (no GCV ladder) besides the linear start. Why this and not FZZ's
//!   own r_K scaling, and why a fixed h: measured on linear ARMA(2,1), ARMA(1,1) and
//!   AR(1) series at N = 2000 and 1e5 (`benches/constancy_scan.rs`, BENCHMARKS.md),
//!   the null mean of T is (tr S - p) / 2 within 5 % at h = 0.5 and 1 sd, while FZZ's
//!   asymptotic tr S c_K / K(0) - p / 2 ([`wilks_mu`]) is 25 % too large at these N
//!   (a test of level 0-0.5 % instead of 5 %); and at GCV's bandwidth the chi2(tr S - p)
//!   reference rejected 6-12 % of linear series: GCV picks the h where a linear series
//!   happens to look nonlinear.
//! - **bootstrap** ([`ConstancyTest::Bootstrap`]): the residual bootstrap of Cai, Fan
//!   and Yao: B series are simulated from the fitted ARMA(p,q) with innovations
//!   drawn with replacement from its centred residuals (200 samples of burn-in,
//!   discarded), T* is computed on each with the same h and grid, and
//!   p = (1 + #{T* >= T}) / (B + 1). The bandwidth is either fixed in advance (the same
//!   h for T and every T*), or, with `farma.bandwidth` None, chosen by GCV on the
//!   series and chosen again by GCV on every replicate: the selection is then part of
//!   the statistic and the bootstrap reproduces it. A bandwidth chosen by GCV on the
//!   data and held fixed in the replicates is not a valid use: GCV picks a small h
//!   where the series happens to look nonlinear, T is large there and the replicates,
//!   without that chance structure, do not follow; measured, that rejected 16 of 100
//!   linear ARMA(2,1) series at 5 % (BENCHMARKS.md, `benches/constancy.rs`). Replicate
//!   i draws from its own ChaCha8 stream (seed, i), so the result does not depend on
//!   the number of threads. Cost: B + 1 FARMA fits, each with GCV.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::estimator::arma::arma_residuals;
use crate::estimator::fit::linear_start;
use crate::estimator::{FarmaParams, fit};

/// The default test's bandwidth in standard deviations of the (demeaned) series: h =
/// 0.5 sd(x) (module doc).
pub const CHI2_H_SD: f64 = 0.5;

/// Which constancy test to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConstancyTest {
    /// No test.
    None,
    /// The fixed-bandwidth chi-squared test (module doc; the default).
    Chi2,
    /// The bootstrap GLR with B replicates (B >= 1).
    Bootstrap(usize),
}

impl ConstancyTest {
    /// The test from the user's `--constancy` (chi2, bootstrap, none; None when not
    /// given) and `--bootstrap` (None when not given): `--bootstrap 0` is no test,
    /// `--bootstrap B` alone the bootstrap with B replicates, `--constancy bootstrap`
    /// alone B = 99; neither: the chi2 test.
    pub fn from_flags(method: Option<&str>, bootstrap: Option<usize>) -> Result<Self> {
        match (method, bootstrap) {
            (None, None) => Ok(ConstancyTest::Chi2),
            (None, Some(0)) => Ok(ConstancyTest::None),
            (None, Some(b)) => Ok(ConstancyTest::Bootstrap(b)),
            (Some("none"), _) => Ok(ConstancyTest::None),
            (Some("chi2"), None) => Ok(ConstancyTest::Chi2),
            (Some("chi2"), Some(b)) => Err(Error::Usage(format!(
                "--bootstrap {b} goes with --constancy bootstrap, not chi2"
            ))),
            (Some("bootstrap"), None) => Ok(ConstancyTest::Bootstrap(DEFAULT_BOOTSTRAP)),
            (Some("bootstrap"), Some(0)) => Err(Error::Usage(
                "--constancy bootstrap needs --bootstrap of at least 1 (or --constancy none)"
                    .into(),
            )),
            (Some("bootstrap"), Some(b)) => Ok(ConstancyTest::Bootstrap(b)),
            (Some(m), _) => Err(Error::Usage(format!(
                "constancy test '{m}': chi2, bootstrap or none"
            ))),
        }
    }

    /// Its name in tables and JSON: "chi2", "bootstrap" or "none".
    pub fn name(&self) -> &'static str {
        match self {
            ConstancyTest::None => "none",
            ConstancyTest::Chi2 => "chi2",
            ConstancyTest::Bootstrap(_) => "bootstrap",
        }
    }
}

/// Replicates of `--constancy bootstrap` without `--bootstrap`.
pub const DEFAULT_BOOTSTRAP: usize = 99;

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
    /// "chi2" or "bootstrap" ([`ConstancyTest::name`]).
    pub method: &'static str,
    pub statistic: f64,
    pub p_value: f64,
    /// Bootstrap replicates that could be fitted (0 for the chi2 test).
    pub bootstrap: usize,
    /// The chi2 test's degrees of freedom tr(S) - p (NaN for the bootstrap).
    pub df: f64,
    /// The FARMA fit's smoother trace at the test's bandwidth.
    pub trace: f64,
    /// The bandwidth of T (fixed, or GCV's choice on the series).
    pub bandwidth: f64,
    pub rss0: f64,
    pub rss1: f64,
    /// The bootstrap statistics T*, replicate order.
    pub t_boot: Vec<f64>,
}

impl Constancy {
    /// The smallest p-value the test can return: 1 / (B + 1) for a bootstrap of B
    /// replicates (what B can resolve), 0 for the chi2 test.
    pub fn min_p(&self) -> f64 {
        if self.method == "bootstrap" {
            1.0 / (self.bootstrap + 1) as f64
        } else {
            0.0
        }
    }
}

/// The GLR statistic of one series and the null model behind it.
struct Glr {
    t: f64,
    rss0: f64,
    rss1: f64,
    /// The FARMA fit's bandwidth.
    h: f64,
    /// Its smoother's trace.
    trace: f64,
    /// Whether it returned its linear start.
    linear: bool,
    ar: Vec<f64>,
    ma: Vec<f64>,
    /// Residuals of the ARMA fit.
    e: Vec<f64>,
}

/// r_K of the Biweight kernel for local-linear fits: the scale that makes r_K T
/// asymptotically chi-squared on r_K mu degrees of freedom (Fan, Zhang and Zhang 2001,
/// Theorem 5 and Table 1: r_K = c_K / int (K - K*K/2)^2 with c_K = K(0) - int K^2 / 2;
/// for K(u) = 15/16 (1 - u^2)^2, c_K = 0.580357 and the integral 0.251660, computed
/// by quadrature, = 2.3061 as in their table).
pub const R_K: f64 = 2.306_119;

/// c_K / K(0) of the Biweight kernel: 1 - (int K^2) / (2 K(0)) = 1 - (5/7) / (15/8) =
/// 13/21. mu, the null mean of T, is (FZZ 2001, Theorem 5) p c_K |Omega| / h for p
/// coefficient functions over an index range |Omega|; the smoother's trace is
/// p K(0) |Omega| / h to the same order (the hat matrix's diagonal at u is
/// K(0) / (n h f(u)), summed over the rows: K(0) |Omega| / h per function), so
/// mu = trace c_K / K(0), read off the fit at that bandwidth instead of a |Omega| that
/// a Gaussian-tailed index does not have. Less p / 2: the exact null mean of
/// (RSS_0 - RSS_1) / (2 sigma^2) for a linear smoother S that reproduces the null's
/// constants is (2 tr S - tr S'S - p) / 2, and tr S'S = trace int K^2 / K(0) to the
/// same order.
pub const C_K_OVER_K0: f64 = 13.0 / 21.0;

/// The asymptotic null mean of T at a fit whose smoother has trace `trace`, for `p`
/// coefficient functions ([`C_K_OVER_K0`]); at least 0.
pub fn wilks_mu(trace: f64, p: usize) -> f64 {
    (trace * C_K_OVER_K0 - 0.5 * p as f64).max(0.0)
}

/// The asymptotic p-value of T: P(chi2(r_K mu) >= r_K T) (FZZ 2001, Theorem 5); 1 when
/// T <= 0 (the fit is the null model) and NaN when mu is 0 with T > 0.
pub fn wilks_p(t: f64, mu: f64) -> f64 {
    if t.is_nan() || t <= 0.0 {
        return 1.0;
    }
    if mu.is_nan() || mu <= 0.0 {
        return f64::NAN;
    }
    crate::stats::special::chi2_sf(R_K * t, R_K * mu)
}

/// T of a (demeaned) series at the bandwidth of `prm` (fixed, or GCV's), with the
/// smoother's trace and the asymptotic p-value.
#[derive(Clone, Debug)]
pub struct GlrAt {
    pub t: f64,
    pub rss0: f64,
    pub rss1: f64,
    pub h: f64,
    pub trace: f64,
    pub mu: f64,
    pub p_wilks: f64,
    /// Whether the FARMA fit returned its linear start.
    pub linear: bool,
}

/// [`GlrAt`] of series `x` (already demeaned).
pub fn glr_at(x: &[f64], prm: &FarmaParams) -> Result<GlrAt> {
    let g = glr(x, prm)?;
    let mu = wilks_mu(g.trace, prm.p);
    Ok(GlrAt {
        t: g.t,
        rss0: g.rss0,
        rss1: g.rss1,
        h: g.h,
        trace: g.trace,
        mu,
        p_wilks: wilks_p(g.t, mu),
        linear: g.linear,
    })
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
        trace: r1.trace,
        linear: r1.linear_start,
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
    // the replicates' statistics (and the collection of them), and the fits in flight
    crate::workflow::budget::check_memory(
        &format!("--bootstrap {}", prm.bootstrap),
        &format!("{} bootstrap replicates of {n} samples", prm.bootstrap),
        16.0 * prm.bootstrap as f64
            + rayon::current_num_threads() as f64
                * crate::workflow::budget::FIT_BYTES_PER_SAMPLE
                * n as f64,
    )?;
    let mean = x.iter().sum::<f64>() / n as f64;
    let xc: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let Glr {
        t,
        rss0,
        rss1,
        h,
        trace,
        ar,
        ma,
        e,
        ..
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
        method: "bootstrap",
        statistic: t,
        p_value: (1 + exceed) as f64 / (ok.len() + 1) as f64,
        bootstrap: ok.len(),
        df: f64::NAN,
        trace,
        bandwidth: h,
        rss0,
        rss1,
        t_boot,
    })
}

/// The chi2 test (module doc) on series `x` (its mean is removed first) at the order of
/// `farma`, at its fixed bandwidth or h = [`CHI2_H_SD`] sd(x).
pub fn chi2_test(x: &[f64], farma: &FarmaParams) -> Result<Constancy> {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let xc: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let sd = (xc.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    let h = farma.bandwidth.unwrap_or(CHI2_H_SD * sd);
    let g = glr(
        &xc,
        &FarmaParams {
            bandwidth: Some(h),
            ..farma.clone()
        },
    )?;
    let df = g.trace - farma.p as f64;
    // a fit that returned its linear start is the null model itself: T is 0 up to
    // rounding (its RSS is the start's, summed by another pass), and nothing is tested
    let p_value = if g.linear { 1.0 } else { chi2_p(g.t, df) };
    if p_value.is_nan() {
        return Err(Error::Data(format!(
            "constancy test: the FARMA fit at bandwidth {h:.6e} has an undefined smoother trace ({}): no degrees of freedom to refer T = {:.4} to; run it with --constancy bootstrap",
            g.trace, g.t
        )));
    }
    Ok(Constancy {
        method: "chi2",
        statistic: g.t,
        p_value,
        bootstrap: 0,
        df,
        trace: g.trace,
        bandwidth: g.h,
        rss0: g.rss0,
        rss1: g.rss1,
        t_boot: Vec::new(),
    })
}

/// P(chi2(df) >= 2T): 1 when T <= 0 (the fit is no better than the null model, as when
/// it returned its linear start), NaN when df is not a positive number.
pub fn chi2_p(t: f64, df: f64) -> f64 {
    if df.is_nan() || df <= 0.0 {
        return if t <= 0.0 { 1.0 } else { f64::NAN };
    }
    if t <= 0.0 {
        return 1.0;
    }
    crate::stats::special::chi2_sf(2.0 * t, df)
}

/// The test `test` on `x` at the order and grid of `farma` (None for
/// [`ConstancyTest::None`]).
pub fn run_test(
    x: &[f64],
    test: ConstancyTest,
    farma: &FarmaParams,
    seed: u64,
) -> Result<Option<Constancy>> {
    match test {
        ConstancyTest::None => Ok(None),
        ConstancyTest::Chi2 => chi2_test(x, farma).map(Some),
        ConstancyTest::Bootstrap(b) => constancy_test(
            x,
            &ConstancyParams {
                bootstrap: b,
                seed,
                farma: farma.clone(),
            },
        )
        .map(Some),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_pick_the_test() {
        let t = |m, b| ConstancyTest::from_flags(m, b);
        assert_eq!(t(None, None).unwrap(), ConstancyTest::Chi2);
        assert_eq!(t(None, Some(0)).unwrap(), ConstancyTest::None);
        assert_eq!(t(None, Some(19)).unwrap(), ConstancyTest::Bootstrap(19));
        assert_eq!(
            t(Some("bootstrap"), None).unwrap(),
            ConstancyTest::Bootstrap(99)
        );
        assert_eq!(t(Some("none"), Some(5)).unwrap(), ConstancyTest::None);
        assert!(t(Some("chi2"), Some(5)).is_err());
        assert!(t(Some("bootstrap"), Some(0)).is_err());
        assert!(t(Some("wilks"), None).is_err());
    }

    #[test]
    fn chi2_p_value_is_the_upper_tail_of_2t() {
        // 2T = 3.84 on 1 df is the 5 % point
        assert!((chi2_p(3.841_459 / 2.0, 1.0) - 0.05).abs() < 1e-6);
        assert_eq!(chi2_p(0.0, 3.0), 1.0);
        assert_eq!(chi2_p(-1e-9, 3.0), 1.0);
        assert_eq!(chi2_p(0.0, 0.0), 1.0);
        assert!(chi2_p(1.0, 0.0).is_nan());
    }
}
