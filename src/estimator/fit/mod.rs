//! Fitting a FARMA(p,q,d) model: validated parameters in, a fitted model out.
//!
//! The scheme of the paper, made to converge to the right answer:
//! 1. start: a linear ARMA(p,q) by conditional least squares ([`super::arma`]) on the
//!    first [`START_MAX`] samples, refined on longer prefixes and then on every sample
//!    ([`linear_start`]), gives
//!    constant f_m = a_m and b (`Init::Arma`, default); `Init::Literal` is the paper's
//!    literal start (least-squares AR(p), b = 0), kept for comparison: it stalls with
//!    b near 0 when the MA part is strong;
//! 2. f-step: with e and b fixed, y_t = x_t - sum b_m e_{t-m}; local-linear Biweight
//!    fits at the grid points; the bandwidth by GCV over the ladder
//!    h_j = 1.1^-j range/2 on the first f-step and again after convergence, extended
//!    when the minimum sits at an end of the ladder;
//! 3. b-step: with f fixed, w_t = x_t - sum f_m(U_t) x_{t-m} and b minimises
//!    sum e_t^2, e_t = w_t - sum b_m e_{t-m}, by Gauss-Newton from the b of the
//!    f-step's response (`Arma`). One pass (`gn_b_step`, q <= 2) computes w, the
//!    residuals at that b and the Gauss-Newton step from it: the iterate is (f, that
//!    b), its residuals and RSS in hand, and a small step (predicted RSS decrease
//!    below [`SMALL_STEP`] of the RSS) goes into the next f-step's response without a
//!    pass of its own (the next iterate's RSS is its check, and the rule below returns
//!    the iterate of least RSS). A larger step is checked ([`ma_step`]'s check, from
//!    the one-pass step): the step kept when the filter at its b lowers the RSS, else
//!    Gauss-Newton with step halving to convergence, then the residuals at its b (the
//!    iterate is then (f, that b)); q > 2 runs [`ma_step`] whole.
//!    `Literal`: one least-squares regression of w on the previous residuals (a b
//!    that is not invertible is refused, the previous one kept, with a note);
//! 4. residuals recomputed recursively (zeros before the first sample), f between grid
//!    points by linear interpolation; repeat until the RSS settles: it changes by less
//!    than `tol` relative (default 1e-6), or the least RSS so far has not been beaten
//!    for [`PATIENCE`] alternations and the last RSS is above it by more than `tol`.
//!    sigma^2 = RSS / (N - max(p,q,d)).
//!
//! The alternation is not a descent method (the f-step holds the residuals fixed): on
//! the FARMA(2,1,1) of the tests its RSS falls by 1.6 % in the first step, then moves
//! by about 1e-6 relative, in a slowly damped two-cycle, while b changes in the fifth
//! digit; on the benchmark's 1e6 samples it is least at the third alternation and then
//! rises slowly towards a fixed point 1.2e-5 above. `rss_history` records every step.
//! The iterate of least global RSS (the linear start included) is returned when the
//! last one ends above it by more than `tol` relative, with a note: the fit never ends
//! more than `tol` above the linear ARMA it nests. Residuals that are not finite stop
//! the alternation (`converged` false) and the iterate of least RSS is returned. A returned linear start reports the
//! linear model's degrees of freedom, trace = p, its GCV from them and the
//! least-squares standard errors of its constant coefficients (the bandwidth field
//! keeps the one GCV last chose, which that model does not use). Alternating on past
//! that iterate cannot change what is returned unless the RSS comes back below it, hence the
//! [`PATIENCE`] rule (`converged` is true when either rule stopped the alternation,
//! false when `max_iter` did).

mod bstep;
mod gcv;
mod grid;
pub(crate) mod grid2;
mod notes;
mod params;
mod passes;
mod report;
mod smoother;
pub(crate) mod smoother2;
mod start;
#[cfg(test)]
mod tests;

use crate::error::Error;
use crate::error::Result;
use crate::estimator::arma::fit_arma;
use crate::estimator::arma::lagged_normal;
use crate::estimator::arma::ma_invertible;
use crate::estimator::buffers;
use crate::estimator::direct;
use crate::estimator::linalg::normal_equations;
use crate::estimator::linalg::spd_solve_inverse;
use crate::estimator::moments::Families;
use crate::estimator::moments::IntervalLookup;
use crate::estimator::moments::MomentTable;
use crate::estimator::moments::breakpoints;
use crate::estimator::problem::GridFit;
use crate::estimator::problem::PointStatus;
pub use bstep::{SMALL_STEP, ma_cls, ma_step};
use bstep::{gn_b_step, ma_step_from};
use gcv::gcv_select;
use grid::quantiles;
pub use notes::{
    MA_EDGE, STRETCH_RATIO, ma_edge_note, missing_se_note, reselection_limit_note,
    stretched_ladder_note, undefined_trace_note,
};
pub use params::{
    DIRECT_MAGNITUDE_LIMITS, FarmaParams, FitPath, Init, MAGNITUDE_LIMITS, MAX_GRID, ValidParams,
    check_magnitude,
};
pub use passes::{FILTER_CHUNK, FILTER_LEAD, residuals, residuals_indexed};
use passes::{SpanFill, eval_with, rss_from, w_indexed_filler};
pub use report::{AlternationTiming, FitTimings, FittedFarma, GcvRow};
pub use smoother::fill_failed;
use smoother::{Smoother, StepCache, residuals_at};
pub use start::{REFINE_RATIO, START_ENOUGH, START_MAX, arma_cls, arma_cls_within, linear_start};
use start::{arma_residuals_rss, linear_start_into};
use std::time::Instant;

/// Whether the last iterate's RSS `rss` ends above the least one, `best_rss`, by more
/// than `tol` relative (the iterate of least RSS is then returned, module doc); a
/// non-finite `rss` always does (the difference alone would compare inf > inf or NaN,
/// both false).
fn went_back(rss: f64, best_rss: f64, tol: f64) -> bool {
    !rss.is_finite() || rss - best_rss > tol * rss
}

/// One iterate of the alternation, kept while it has the least global RSS.
struct Iterate {
    /// Its index in `rss_history` (0: the linear start).
    index: usize,
    rss: f64,
    coef: GridFit,
    b: Vec<f64>,
    /// Its bandwidth (NaN for the start).
    h: f64,
    filled: Vec<bool>,
}

/// Alternations without a new least RSS after which the alternation stops when its
/// last RSS is above that least one by more than `tol` (it is past its minimum; the
/// iterate of least RSS is returned).
pub const PATIENCE: usize = 2;

/// Fits a FARMA model to `series`.
pub fn fit(series: &[f64], params: &ValidParams) -> Result<FittedFarma> {
    let prm = params.params();
    let (p, q, d) = (prm.p, prm.q, prm.d);
    let n = series.len();
    let t_total = Instant::now();
    let mut timings = FitTimings::default();
    let mut clock = Instant::now();
    // seconds since the last lap
    let mut lap = move || {
        let s = clock.elapsed().as_secs_f64();
        clock = Instant::now();
        s
    };
    let pp = p.max(q).max(d);
    let mean = if prm.demean {
        series.iter().sum::<f64>() / n as f64
    } else {
        0.0
    };
    // the centred series, with its extremes and the NaN check in the same pass
    // (f64::min and max skip NaN; an infinite value shows as an infinite extreme),
    // chunks in parallel
    let (x, parts) = buffers::filled(n, |at, out: &mut [f64]| {
        let (mut lo, mut hi, mut nan) = (f64::INFINITY, f64::NEG_INFINITY, false);
        for (o, v) in out.iter_mut().zip(&series[at..]) {
            let c = v - mean;
            *o = c;
            lo = lo.min(c);
            hi = hi.max(c);
            nan |= c.is_nan();
        }
        (lo, hi, nan)
    });
    let (xmin, xmax, nan) = parts.into_iter().fold(
        (f64::INFINITY, f64::NEG_INFINITY, false),
        |(a, b, nan), (lo, hi, n)| (a.min(lo), b.max(hi), nan | n),
    );
    if nan || !xmin.is_finite() || !xmax.is_finite() {
        return Err(Error::Usage(
            "the channel holds NaN or infinite values".into(),
        ));
    }
    let range = xmax - xmin;
    if range.is_nan() || range <= 0.0 {
        return Err(Error::Usage(
            "the channel is constant: nothing to fit".into(),
        ));
    }
    check_magnitude("the channel", xmin, xmax, prm.path).map_err(Error::Usage)?;
    let qs = quantiles(
        |t| x[t - d],
        pp..n,
        &[prm.grid_quantiles.0, prm.grid_quantiles.1],
    );
    let (glo, ghi) = (qs[0], qs[1]);
    if ghi.is_nan() || ghi <= glo {
        return Err(Error::Usage(format!(
            "the index values x_(t-{d}) take one value over the central quantiles ({glo:.6e}): no grid to fit on (the channel ranges over [{:.6e}, {:.6e}]: a channel quantised to a few levels, or an outlier so large that the other values are lost to rounding once the mean is taken out; `farma prep` removes outliers)",
            xmin + mean,
            xmax + mean
        )));
    }
    let g = prm.grid_size;
    let grid: Vec<f64> = (0..g)
        .map(|k| glo + (ghi - glo) * k as f64 / (g - 1) as f64)
        .collect();

    timings.prepare_s = lap();
    // 1. start, on the first START_MAX samples (it is only a start: the alternation
    // then uses every sample; on longer series the linear ARMA's own passes would
    // cost as much as the alternation, and its work arrays several copies of the
    // series)
    let x_start = &x[..n.min(START_MAX)];
    // the residuals at the start: written by the linear start's last pass over every
    // sample when it evaluated the returned (a, b), else by arma_residuals_rss
    let mut e_start = vec![0.0; if prm.init == Init::Arma { n } else { 0 }];
    let (a0, mut b, start_holds) = match prm.init {
        Init::Arma => match linear_start_into(&x, p, q, pp, Some(&mut e_start)) {
            Some(abh) => abh,
            None => {
                return Err(Error::Usage(
                    "the linear ARMA start failed (singular design)".into(),
                ));
            }
        },
        Init::Literal => match fit_arma(x_start, p, 0) {
            Some(m) => (m.ar, vec![0.0; q], false),
            None => return Err(Error::Usage("the AR start failed (singular design)".into())),
        },
    };
    let mut coef = GridFit::new(g, p, f64::NAN);
    for k in 0..g {
        coef.status[k] = PointStatus::Ok;
        coef.f[k * p..(k + 1) * p].copy_from_slice(&a0);
        // constant f_m: slope 0 (no local system: n_support and kernel_mass 0, cond
        // NaN, as the note of a returned start says)
        coef.slope[k * p..(k + 1) * p].fill(0.0);
    }
    // constant f_m = a_m: the linear ARMA's recursion, the same operations as
    // `residuals` with every grid value a_m (interpolating between equal values
    // gives a_m itself), without finding cells
    let (mut e, mut rss) = if start_holds {
        let rss = rss_from(&e_start, pp);
        (e_start, rss)
    } else {
        drop(e_start);
        arma_residuals_rss(&x, &a0, &b, pp)
    };
    let mut rss_history = vec![rss];
    timings.start_s = lap();
    // The best iterate by global RSS, the linear start being iterate 0 (see the end).
    let mut best = Iterate {
        index: 0,
        rss,
        coef: coef.clone(),
        b: b.clone(),
        h: f64::NAN,
        filled: vec![false; g],
    };

    let mut h = prm.bandwidth.unwrap_or(f64::NAN);
    let mut gcv_table = Vec::new();
    let mut ladder_extended = false;
    let mut notes = Vec::new();
    if prm.bandwidth.is_none() {
        notes.extend(stretched_ladder_note(
            &format!("the index values x_(t-{d}) (less the channel's mean)"),
            (xmin, xmax),
            (glo, ghi),
            prm.grid_quantiles,
        ));
    }
    let mut filled = vec![false; g];
    let mut iterations = 0;
    let mut converged = false;
    let mut reselections = 0;
    // the bandwidths GCV chose, in order (the first selection, then each re-selection)
    let mut chosen: Vec<f64> = Vec::new();
    // rss_history index of the last bandwidth re-selection
    let mut reselected_at = 0;
    let mut need_gcv = prm.bandwidth.is_none();
    // the b of the response y_t = x_t - sum b_m e_{t-m} of the next f-step: the
    // iterate's own b, or the Gauss-Newton step from it (see the b-step)
    let mut b_resp = b.clone();
    // left-hand sides of the local systems and each row's interval at the current h
    let mut cache = StepCache::default();
    // `Init::Literal`: (first alternation, its least-squares b, alternations) where the
    // least-squares b was not invertible and the previous b was kept
    let mut not_invertible_kept: Option<(usize, Vec<f64>, usize)> = None;
    while iterations < prm.max_iter {
        iterations += 1;
        let mut at = AlternationTiming::default();
        lap();
        // 2. f-step
        let sm = Smoother::new(&x, &e, &b_resp, (p, d), &grid, prm.path, (xmin, xmax));
        let mut fit_h = if need_gcv {
            need_gcv = false;
            let (rows, mut fits, best, ext, nt) = gcv_select(&sm, range, &mut cache);
            // the next f-steps' left-hand sides, from the ladder's table (they depend
            // on X and U only)
            if let Some(lad) = &cache.ladder {
                cache.systems = Some(lad.systems_at(&grid, rows[best].bandwidth));
            }
            at.gcv_s = lap();
            ladder_extended |= ext;
            notes.extend(nt);
            h = rows[best].bandwidth;
            chosen.push(h);
            gcv_table = rows;
            fits.swap_remove(best)
        } else {
            sm.fit_at(h, &mut cache)
        };
        filled = fill_failed(&mut fit_h, &grid).ok_or_else(|| {
            let fixed = match prm.bandwidth {
                Some(_) => format!(
                    "a --bandwidth far from the index values' spread (they span {range:.6e}; the grid {:.6e}), ",
                    grid[g - 1] - grid[0]
                ),
                None => String::new(),
            };
            Error::Usage(format!(
                "no grid point has a local fit at bandwidth {h:.6e}: every local system is empty or singular: {fixed}too few distinct index values near each grid point (a quantised channel, or a spike that stretches the range; `farma prep` removes outliers), or regressors that are exactly dependent (a deterministic trend or sinusoid)"
            ))
        })?;
        coef = fit_h;
        at.f_step_s = lap();
        // 3. b-step; 4. residuals. For Gauss-Newton the residual buffer first takes
        // w_t = x_t - sum f_m(U_t) x_{t-m} (the old residuals are no longer needed),
        // b is fitted to it by streaming passes, and the MA filter then turns w into
        // the new residuals in place: one N-long vector in all.
        let new_rss;
        if q > 0 && prm.init == Init::Arma {
            let index = cache.index_for(&sm.prob, &grid, h);
            let w_into = |buf: &mut [f64]| residuals_at(&x, d, &grid, (&coef, &[]), buf, index);
            // one pass: w, the residuals at b_resp and the Gauss-Newton sums there,
            // chunk by chunk; with a small step the iterate is (f, b_resp), its
            // residuals in hand, and the step goes into the next f-step's response
            // (q > 2: no one-pass step; w written in place for ma_step)
            let filler = index
                .filter(|_| q <= 2)
                .and_then(|ix| w_indexed_filler(&x, d, &grid, &coef, ix));
            let fill = filler.as_ref().map(|f| f as &SpanFill<'_>);
            if fill.is_none() {
                w_into(&mut e);
            }
            // (the iterate's b, the next response's b, the iterate's RSS)
            let (b_iter, b_next, rss_iter) = match gn_b_step(&mut e, pp, &b_resp, fill, w_into) {
                // the iterate is (f, b_resp), its residuals in `e`; the step goes
                // into the next f-step's response
                Some((rss_b, b_next, decrease))
                    if decrease <= SMALL_STEP * rss_b && ma_invertible(&b_next) =>
                {
                    (b_resp.clone(), b_next, rss_b)
                }
                // a larger step, checked: w again, the filter at the stepped b (the
                // Gauss-Newton step is the one-pass step's, not summed again)
                Some((rss_b, b_next, _)) => {
                    w_into(&mut e);
                    let (b_new, rss_new) =
                        ma_step_from(&mut e, pp, &b_resp, (rss_b, b_next), w_into);
                    (b_new.clone(), b_new, rss_new)
                }
                // q > 2: ma_step's own passes on w
                None => {
                    let (b_new, rss_new) = ma_step(&mut e, pp, &b_resp, w_into);
                    (b_new.clone(), b_new, rss_new)
                }
            };
            b = b_iter;
            b_resp = b_next;
            new_rss = rss_iter;
            at.b_step_s = lap();
        } else {
            if q > 0 {
                // the paper's step: least squares of w_t on the previous residuals
                let lookup = IntervalLookup::new(&grid);
                let mut f = vec![0.0; p];
                let mut ata = vec![0.0; q * q];
                let mut aty = vec![0.0; q];
                for t in pp..n {
                    eval_with(&coef, &grid, &lookup, x[t - d], &mut f);
                    let mut w = x[t];
                    for m in 0..p {
                        w -= f[m] * x[t - m - 1];
                    }
                    for i in 0..q {
                        for j in 0..q {
                            ata[i * q + j] += e[t - i - 1] * e[t - j - 1];
                        }
                        aty[i] += e[t - i - 1] * w;
                    }
                }
                // a b that is not invertible makes the residual recursion grow
                // without bound: the previous b is kept (as the Gauss-Newton step's
                // check does for `Init::Arma`)
                match normal_equations(&ata, &aty, q) {
                    Some(b_ls) if ma_invertible(&b_ls) => b = b_ls,
                    Some(b_ls) => {
                        let kept = not_invertible_kept.get_or_insert((iterations, b_ls, 0));
                        kept.2 += 1;
                    }
                    None => {}
                }
            }
            at.b_step_s = lap();
            residuals_at(&x, d, &grid, (&coef, &b), &mut e, cache.any_index());
            new_rss = rss_from(&e, pp);
            b_resp = b.clone();
        }
        at.residuals_s = lap();
        if !new_rss.is_finite() {
            // residuals that overflow (local fits far off the data's scale at a small
            // bandwidth): no later step can start from them; the iterate of least RSS
            // is returned below (`went_back`), not converged
            notes.push(format!(
                "alternation {iterations}: the residuals are not finite (RSS {new_rss}): the alternation stops"
            ));
            rss = new_rss;
            rss_history.push(rss);
            timings.alternations.push(at);
            break;
        }
        let change = (rss - new_rss).abs();
        rss = new_rss;
        rss_history.push(rss);
        if rss < best.rss {
            best = Iterate {
                index: rss_history.len() - 1,
                rss,
                coef: coef.clone(),
                b: b.clone(),
                h,
                filled: filled.clone(),
            };
        }
        // settled: the RSS changed by less than tol, or the least RSS so far was not
        // beaten for PATIENCE alternations while the last is above it by more than tol
        // (the iterate of least RSS is then returned, see below)
        // (counted from the last bandwidth re-selection, if later: a new h gets its own
        // PATIENCE alternations)
        let since_best = rss_history.len() - 1 - best.index.max(reselected_at);
        let settled = change <= prm.tol * rss.max(f64::MIN_POSITIVE)
            || (since_best >= PATIENCE && rss - best.rss > prm.tol * rss);
        if settled {
            if prm.bandwidth.is_none() && reselections < 2 {
                // re-check the bandwidth at the converged residuals
                let sm = Smoother::new(&x, &e, &b_resp, (p, d), &grid, prm.path, (xmin, xmax));
                let (rows, _, best, ext, nt) = gcv_select(&sm, range, &mut cache);
                at.gcv_s += lap();
                timings.alternations.push(at.clone());
                reselections += 1;
                if rows[best].bandwidth != h && iterations == prm.max_iter {
                    // no alternation left to fit at the new bandwidth: the model stays
                    // at h (its coefficients are the f-step's at h), not converged
                    notes.push(format!(
                        "alternation {iterations}: the RSS settled at bandwidth {h:.6e}; GCV at those residuals chose {:.6e}, but --max-iter {} ends the alternation here: NOT converged, the model is at the bandwidth it settled at (the GCV table is the re-check's)",
                        rows[best].bandwidth, prm.max_iter
                    ));
                    gcv_table = rows;
                    break;
                }
                if rows[best].bandwidth != h {
                    notes.push(format!(
                        "alternation {iterations}: the RSS settled at bandwidth {h:.6e}; GCV at those residuals chose {:.6e}, and the alternation went on at it",
                        rows[best].bandwidth
                    ));
                    ladder_extended |= ext;
                    notes.extend(nt);
                    h = rows[best].bandwidth;
                    chosen.push(h);
                    if let Some(lad) = &cache.ladder {
                        cache.systems = Some(lad.systems_at(&grid, h));
                    }
                    gcv_table = rows;
                    reselected_at = rss_history.len() - 1;
                    continue;
                }
                gcv_table = rows;
            } else {
                if prm.bandwidth.is_none() {
                    notes.push(reselection_limit_note(iterations, &chosen, |h| {
                        format!("{h:.6e}")
                    }));
                }
                timings.alternations.push(at.clone());
            }
            converged = true;
            break;
        }
        timings.alternations.push(at);
    }
    // The alternation is not a descent method (module doc): the f-step minimises local
    // weighted sums of squares with the residuals held fixed, not the global RSS, so it
    // can end above an earlier iterate, even above the linear start it nests (on the
    // quantised ADIS16405 gyros with q = 2, see tests/suite/estimator_recovery.rs). The
    // iterate of least global RSS is returned when the last one is above it by more
    // than the convergence tolerance. The linear start (constant f_m = a_m) is the
    // linear model: trace p, its GCV, and the least-squares standard errors of a_m
    // (the bandwidth field keeps the one GCV last chose, unused by that model).
    if let Some((first, b_ls, times)) = not_invertible_kept {
        notes.push(format!(
            "the least-squares b was not invertible in {times} alternation(s) (first in alternation {first}: {b_ls:?}); the previous b was kept each time"
        ));
    }
    let went_back = went_back(rss, best.rss, prm.tol);
    let returned_start = went_back && best.index == 0;
    if went_back {
        notes.push(if best.index == 0 {
            format!(
                "the alternation ended above its linear ARMA({p},{q}) start (RSS {rss:.7e} > {:.7e}): the linear start is returned (constant f_m, slope 0, no local systems: n_support and kernel_mass 0, cond NaN; trace p = {p}, the linear model's; h = {h:.6e} is the bandwidth {})",
                best.rss,
                if prm.bandwidth.is_some() {
                    "fixed by --bandwidth"
                } else {
                    "GCV last chose"
                }
            )
        } else {
            format!(
                "the alternation ended above its iterate {} (RSS {rss:.7e} > {:.7e}): that iterate is returned",
                best.index, best.rss
            )
        });
        coef = best.coef;
        b = best.b;
        filled = best.filled;
        if best.index > 0 {
            h = best.h;
        }
        residuals_at(&x, d, &grid, (&coef, &b), &mut e, cache.any_index());
        rss = rss_from(&e, pp);
    }
    lap();
    // trace, GCV and standard errors at the final bandwidth: the trace and the
    // standard errors depend on X and U only (not on the residuals), and the GCV is
    // the returned model's, from its own RSS
    let sm = Smoother::new(&x, &e, &b, (p, d), &grid, prm.path, (xmin, xmax));
    let prob = sm.prob;
    let m = (n - pp) as f64;
    let sigma2 = rss / (n - pp) as f64;
    let (trace, factors) = match prm.path {
        _ if returned_start => {
            // the linear model with constant f_m: trace p (the least-squares hat
            // matrix on X_1..X_p), and Var(a) = sigma^2 (X'X)^-1 with the MA part
            // sum b_m e_{t-m} taken as a known offset, the same at every grid point
            let lags: Vec<(usize, usize)> = (1..=p).map(|m| (0, m)).collect();
            let (xtx, _) = lagged_normal(&x, &[&x], &lags, pp..n);
            let rhs = vec![0.0; p];
            let diag: Vec<f64> = match spd_solve_inverse(&xtx, &rhs, p) {
                Some((_, inv, _)) => (0..p).map(|i| inv[i * p + i].sqrt()).collect(),
                None => vec![f64::NAN; p],
            };
            (Some(p as f64), diag.repeat(g))
        }
        FitPath::Fast => {
            // one table of the design's families to degree 10 (K^2 for the standard
            // errors): the local systems' inverses, the trace, the standard errors
            let index = cache.index_for(&prob, &grid, h);
            let breaks = || breakpoints(&grid, &[h]);
            let table =
                MomentTable::build_over(&prob, index, breaks, (xmin, xmax), 10, Families::Design);
            let f = table.local_systems(&grid, h).design_fit();
            let trace = f.all_ok().then(|| table.trace(&grid, &f));
            (trace, table.se_factors(&grid, &f))
        }
        FitPath::Direct => {
            let index = cache.direct_index(&prob);
            let (f, rt) = sm.ladder_direct(index, &[h]).remove(0);
            let factors = direct::se_factors(&prob, index, &grid, &f);
            (rt.map(|(_, tr)| tr), factors)
        }
    };
    let trace = trace.unwrap_or(f64::NAN);
    if trace.is_nan() {
        notes.push(undefined_trace_note(&coef.status, &format!("h = {h:.6e}")));
    }
    let gcv = (rss / m) / (1.0 - trace / m).powi(2);
    let se: Vec<f64> = factors.iter().map(|f| f * sigma2.sqrt()).collect();
    notes.extend(missing_se_note(&coef.status, &coef.cond, &se, p));
    notes.extend(ma_edge_note(&b));
    let n_filled = filled.iter().filter(|f| **f).count();
    if n_filled > 0 {
        notes.push(format!("{n_filled} grid point(s) without a local fit were filled from their neighbours (see status)"));
    }
    timings.final_s = lap();
    timings.total_s = t_total.elapsed().as_secs_f64();
    Ok(FittedFarma {
        p,
        q,
        d,
        mean,
        grid,
        coef,
        filled,
        b,
        bandwidth: h,
        rss,
        sigma2,
        trace,
        se,
        gcv,
        gcv_table,
        ladder_extended,
        iterations,
        converged,
        rss_history,
        init: prm.init,
        path: prm.path,
        n,
        n_rows: n - pp,
        residuals: e,
        linear_start: returned_start,
        notes,
        timings,
    })
}
