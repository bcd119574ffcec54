//! Choosing the FARMA order: the paper's order table with the evidence a user needs.
//!
//! For every order (p,q,d) of the grid (default the paper's eight) the FARMA model is
//! fitted (bandwidth by GCV) and the linear ARMA(p,q) by conditional least squares on
//! the same series; both RSS are summed over the same rows t >= max(p,q,d). The ARMA
//! baseline is the FARMA fit's own linear start ([`linear_start`]), the model it nests,
//! and the FARMA fit never ends above its start (beyond the convergence tolerance), so
//! the F statistic against the ARMA is not negative.
//! Per order: RSS, sigma^2 = RSS / m (m = N - max(p,q,d)), the effective degrees of
//! freedom df = tr(S) + q (trace of the f-step smoother plus the MA coefficients; p + q
//! when the fit returned its linear start, which is then the ARMA itself, so its F
//! against the ARMA is 0/0, printed NaN),
//! GCV, and the corrected AIC of Hurvich, Simonoff and Tsai (1998, JRSS B 60, eq. 3)
//! AICc = ln(RSS/m) + (1 + df/m) / (1 - (df + 2)/m), the same formula with df = p + q
//! for the ARMA baseline. The order with the smallest AICc is selected.
//!
//! F-tests (approximate, with effective degrees of freedom as in Hastie and Tibshirani,
//! Generalized Additive Models, 1990, 3.9): for a smaller model 0 inside a larger
//! model 1, F = ((RSS_0 - RSS_1) / (df_1 - df_0)) / (RSS_1 / (m - df_1)) against
//! F(df_1 - df_0, m - df_1). Nested: the same d, p_0 <= p_1, q_0 <= q_1; and every
//! ARMA(p,q) inside its FARMA(p,q,d).
//!
//! A pair is tested only where the test is defined: df_1 > df_0, m > df_1 and both RSS
//! finite. Effective degrees of freedom need not grow with the order (a FARMA fit
//! that returned its linear start has df = p + q, fewer than a smaller order's local
//! fit), so a nested pair can have df_1 <= df_0: such a pair is left out of
//! [`Selection::ftests`] (and ftests.parquet) and listed in [`Selection::untested`]
//! with the reason in words. An ARMA(p,q) inside a FARMA(p,q,d) that returned its
//! linear start is untested: that FARMA is the ARMA. Every F-test then has positive,
//! finite degrees of freedom (before this rule such pairs were printed with a negative
//! or zero df1 and F = NaN).

use crate::error::{Error, Result};
use crate::estimator::arma::arma_residuals;
use crate::estimator::fit::{linear_start, residuals};
use crate::estimator::{FarmaParams, fit};
use crate::model::{Farma, FitReport, StartReason};
use crate::stats::special::f_sf;

/// The paper's eight orders.
pub const PAPER_ORDERS: [(usize, usize, usize); 8] = [
    (1, 1, 1),
    (1, 1, 2),
    (2, 1, 1),
    (2, 1, 2),
    (3, 1, 1),
    (3, 1, 2),
    (3, 2, 1),
    (3, 2, 2),
];

/// One row of the order table.
#[derive(Clone, Debug)]
pub struct OrderRow {
    pub order: (usize, usize, usize),
    /// Rows of the regression, m = N - max(p,q,d).
    pub m: usize,
    pub rss: f64,
    pub sigma2: f64,
    /// Trace of the smoother at the chosen bandwidth.
    pub trace: f64,
    /// Effective degrees of freedom, trace + q.
    pub df: f64,
    pub gcv: f64,
    pub aicc: f64,
    pub bandwidth: f64,
    pub converged: bool,
    /// The linear ARMA(p,q) on the same rows.
    pub arma_rss: f64,
    pub arma_sigma2: f64,
    pub arma_aicc: f64,
    pub arma_ar: Vec<f64>,
    pub arma_ma: Vec<f64>,
    /// F-test of ARMA(p,q) inside FARMA(p,q,d) (NaN when untested: see
    /// [`Selection::untested`]).
    pub f_vs_arma: f64,
    pub p_vs_arma: f64,
    /// Why the FARMA fit returned its linear start (None: it returned a local fit).
    pub returned_start_reason: Option<StartReason>,
}

/// An F-test between nested models.
#[derive(Clone, Debug)]
pub struct FTest {
    /// `FARMA(p,q,d)` or `ARMA(p,q)`.
    pub small: String,
    pub large: String,
    pub f: f64,
    pub df1: f64,
    pub df2: f64,
    pub p_value: f64,
}

/// A nested pair that is not F-tested (module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct Untested {
    pub small: String,
    pub large: String,
    /// Why, in words.
    pub reason: String,
}

/// The result of order selection.
#[derive(Clone, Debug)]
pub struct Selection {
    pub rows: Vec<OrderRow>,
    /// The F-tests that are defined (positive, finite degrees of freedom).
    pub ftests: Vec<FTest>,
    /// Nested pairs left out of `ftests`, with the reason (module doc).
    pub untested: Vec<Untested>,
    /// Index of the selected row.
    pub selected: usize,
    /// Why it was selected, in words.
    pub reason: String,
    /// The fitted model of each order, in the order of `rows`. Only the selected
    /// one keeps its `residuals` (N values each: the others' are dropped as each fit
    /// ends, so a channel holds one residual series, not one per order); theirs are
    /// empty.
    pub fits: Vec<(Farma, FitReport)>,
}

/// AICc of Hurvich, Simonoff and Tsai (1998).
pub fn aicc(rss: f64, m: usize, df: f64) -> f64 {
    let m = m as f64;
    (rss / m).ln() + (1.0 + df / m) / (1.0 - (df + 2.0) / m)
}

/// F-test of a smaller model (rss0, df0) inside a larger (rss1, df1) on m rows.
pub fn f_test(rss0: f64, df0: f64, rss1: f64, df1: f64, m: usize) -> (f64, f64, f64, f64) {
    let d1 = df1 - df0;
    let d2 = m as f64 - df1;
    if !(d1 > 0.0 && d2 > 0.0) {
        return (f64::NAN, d1, d2, f64::NAN);
    }
    let f = ((rss0 - rss1) / d1) / (rss1 / d2);
    (f, d1, d2, f_sf(f, d1, d2))
}

pub fn order_name(o: (usize, usize, usize)) -> String {
    format!("FARMA({},{},{})", o.0, o.1, o.2)
}

/// Fits every order of `orders` to `x` (FARMA with `base` parameters, p,q,d replaced)
/// and the ARMA baseline, in parallel; selects by AICc.
pub fn select(
    x: &[f64],
    orders: &[(usize, usize, usize)],
    base: &FarmaParams,
) -> Result<Selection> {
    let valid: Vec<_> = orders
        .iter()
        .map(|&(p, q, d)| {
            FarmaParams {
                p,
                q,
                d,
                ..base.clone()
            }
            .validate(x.len())
        })
        .collect::<Result<_>>()?;
    let n = x.len();
    let mean = if base.demean {
        x.iter().sum::<f64>() / n as f64
    } else {
        0.0
    };
    let xc: Vec<f64> = x.iter().map(|v| v - mean).collect();
    // the orders' fits, at most `fits_in_flight` at once (the memory budget)
    let pairs: Vec<_> = valid.iter().zip(orders.iter().copied()).collect();
    let in_flight = super::budget::fits_in_flight(n);
    let results: Vec<(OrderRow, (Farma, FitReport))> =
        super::budget::par_map_waves(&pairs, in_flight, |&(vp, (p, q, d))| {
            let (m, mut r) = fit(x, vp)?;
            // (the selected fit's residuals are recomputed below, the same bits)
            r.residuals = Vec::new();
            let start = p.max(q).max(d);
            let rows = n - start;
            let (arma_ar, arma_ma) = linear_start(&xc, p, q, start).ok_or_else(|| {
                Error::Data(format!(
                    "the linear ARMA({p},{q}) fit failed (singular design)"
                ))
            })?;
            let mut e = vec![0.0; n];
            arma_residuals(&xc, &arma_ar, &arma_ma, &mut e);
            let arma_rss: f64 = e[start..].iter().map(|v| v * v).sum();
            let df = r.trace + q as f64;
            let adf = (p + q) as f64;
            let (f, _, _, pv) = f_test(arma_rss, adf, r.rss, df, rows);
            Ok((
                OrderRow {
                    order: (p, q, d),
                    m: rows,
                    rss: r.rss,
                    sigma2: m.sigma2,
                    trace: r.trace,
                    df,
                    gcv: r.gcv,
                    aicc: aicc(r.rss, rows, df),
                    bandwidth: m.bandwidth,
                    converged: r.converged,
                    arma_rss,
                    arma_sigma2: arma_rss / rows as f64,
                    arma_aicc: aicc(arma_rss, rows, adf),
                    arma_ar,
                    arma_ma,
                    f_vs_arma: f,
                    p_vs_arma: pv,
                    returned_start_reason: r.returned_start_reason,
                },
                (m, r),
            ))
        })
        .into_iter()
        .collect::<Result<_>>()?;
    let (rows, mut fits): (Vec<OrderRow>, Vec<(Farma, FitReport)>) = results.into_iter().unzip();
    let (ftests, untested) = nested_tests(&rows);
    let selected = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.aicc.is_finite())
        .min_by(|a, b| a.1.aicc.total_cmp(&b.1.aicc))
        .map(|(i, _)| i)
        .ok_or_else(|| Error::Data("no order gave a finite AICc".into()))?;
    let reason = explain(&rows, &ftests, selected);
    // the selected model's residuals, from its own f and b: the recursion the fit
    // ran, bit for bit (`fit`'s test `a_fit_returns_the_residuals_and_rss_of_its_own_f_and_b`)
    // (on `xc`, the series less the mean computed as `fit` computes it: the fit's
    // own centred series)
    let (m, r) = &mut fits[selected];
    debug_assert_eq!(m.mean.to_bits(), mean.to_bits());
    let mut e = vec![0.0; n];
    residuals(&xc, m.d(), &m.coef.grid, &r.local, &m.b, &mut e);
    r.residuals = e;
    Ok(Selection {
        rows,
        ftests,
        untested,
        selected,
        reason,
        fits,
    })
}

/// The F-tests of every nested pair of `rows` where defined, and the pairs left
/// untested with the reason (module doc).
pub fn nested_tests(rows: &[OrderRow]) -> (Vec<FTest>, Vec<Untested>) {
    let (mut ftests, mut untested) = (Vec::new(), Vec::new());
    let start_words = |r: &OrderRow| {
        r.returned_start_reason
            .map(|w| {
                format!(
                    "; {} returned its linear start: {}",
                    order_name(r.order),
                    w.words()
                )
            })
            .unwrap_or_default()
    };
    // t: the test (F, df1, df2, p), None for a pair untested whatever its df
    let mut pair = |small: String, large: String, t: Option<(f64, f64, f64, f64)>, why: String| {
        let (f, d1, d2, pv) = t.unwrap_or((f64::NAN, f64::NAN, f64::NAN, f64::NAN));
        if d1 > 0.0 && d2 > 0.0 && d1.is_finite() && d2.is_finite() && !f.is_nan() {
            ftests.push(FTest {
                small,
                large,
                f,
                df1: d1,
                df2: d2,
                p_value: pv,
            });
        } else {
            untested.push(Untested {
                small,
                large,
                reason: why,
            });
        }
    };
    for a in rows {
        for b in rows {
            let (o0, o1) = (a.order, b.order);
            if o0 != o1 && o0.2 == o1.2 && o0.0 <= o1.0 && o0.1 <= o1.1 {
                let rw = a.m.min(b.m);
                let (small, large) = (order_name(o0), order_name(o1));
                let t = f_test(a.rss, a.df, b.rss, b.df, rw);
                let why = if !(a.rss.is_finite() && b.rss.is_finite()) {
                    "an RSS is not finite".to_string()
                } else if b.df <= a.df {
                    format!(
                        "{large} has no more effective degrees of freedom than {small} ({:.2} <= {:.2}){}",
                        b.df,
                        a.df,
                        start_words(b)
                    )
                } else {
                    format!(
                        "{large} leaves no residual degrees of freedom (m - df = {:.2})",
                        t.2
                    )
                };
                pair(small, large, Some(t), why);
            }
        }
    }
    for r in rows {
        let (p, q) = (r.order.0, r.order.1);
        let (small, large) = (format!("ARMA({p},{q})"), order_name(r.order));
        if r.returned_start_reason.is_some() {
            let why = format!("{large} returned its linear start: it is the {small}");
            pair(small, large, None, why);
            continue;
        }
        let t = f_test(r.arma_rss, (p + q) as f64, r.rss, r.df, r.m);
        let why = if !(r.arma_rss.is_finite() && r.rss.is_finite()) {
            "an RSS is not finite".to_string()
        } else if r.df <= (p + q) as f64 {
            format!(
                "{large} has no more effective degrees of freedom than {small} ({:.2} <= {})",
                r.df,
                p + q
            )
        } else {
            format!(
                "{large} leaves no residual degrees of freedom (m - df = {:.2})",
                t.2
            )
        };
        pair(small, large, Some(t), why);
    }
    (ftests, untested)
}

fn explain(rows: &[OrderRow], ftests: &[FTest], sel: usize) -> String {
    let r = &rows[sel];
    let name = order_name(r.order);
    let mut others: Vec<&OrderRow> = rows.iter().filter(|o| o.order != r.order).collect();
    others.sort_by(|a, b| a.aicc.total_cmp(&b.aicc));
    let mut s = format!("{name} has the smallest AICc ({:.4}", r.aicc);
    if let Some(o) = others.first() {
        s += &format!("; next {} by {:.4}", order_name(o.order), o.aicc - r.aicc);
    }
    s += ")";
    let smaller: Vec<&FTest> = ftests
        .iter()
        .filter(|t| t.large == name && t.small.starts_with("FARMA"))
        .collect();
    for t in smaller {
        s += &format!(
            "; against {} F = {:.3} on ({:.1}, {:.0}) df, p = {:.3e}",
            t.small, t.f, t.df1, t.df2, t.p_value
        );
    }
    let larger: Vec<&FTest> = ftests.iter().filter(|t| t.small == name).collect();
    for t in larger {
        s += &format!(
            "; the larger {}: F = {:.3}, p = {:.3e}",
            t.large, t.f, t.p_value
        );
    }
    if let Some(w) = r.returned_start_reason {
        s += &format!(
            "; it returned its linear start ({}): it is the linear ARMA({},{}), RSS {:.6e}",
            w.words(),
            r.order.0,
            r.order.1,
            r.rss
        );
    } else {
        s += &format!(
            "; against the linear ARMA({},{}): RSS {:.6e} vs {:.6e}, F = {:.3}, p = {:.3e}",
            r.order.0, r.order.1, r.rss, r.arma_rss, r.f_vs_arma, r.p_vs_arma
        );
    }
    s
}
