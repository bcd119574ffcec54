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
//!
//! The alternation is one loop, `alternate`, generic over the f-step's smoother (the
//! trait `Smoother`): the lag index's (`smoother::LagSmoother`, fast and direct paths)
//! and the 2-D index's (`smoother2::Index2Smoother`). The smoother brings what depends on the index:
//! its local fits, GCV over its ladder, the fill of grid points without a fit, the
//! b-step and the residual recursion; the loop holds what does not: the order of the
//! steps, the rules that stop it, the bandwidth re-selections, the iterate of least
//! RSS and the notes on them. A trait, not an enum: the two indexes differ in their
//! types (a bandwidth is h or (h_1, h_2); the local fits differ), which an enum would
//! have to unify at every use, and each keeps caches of its own; a third index is a
//! third implementation, with no match to extend. Both end in the one model type,
//! [`Farma`], and a [`FitReport`] over their local fits (GCV rows hold one bandwidth
//! or two).
//!
//! This file is over 600 lines because it also holds [`fit`], the lag index's entry
//! (data checks, grid, linear start, the loop, then the returned model's trace and
//! standard errors).

mod bstep;
mod gcv;
mod grid;
pub(crate) mod grid2;
mod notes;
mod params;
mod passes;

mod smoother;
pub(crate) mod smoother2;
mod start;
#[cfg(test)]
mod tests;

use crate::error::Error;
use crate::error::Result;
use crate::estimator::arma::fit_arma;
use crate::estimator::buffers;
use crate::estimator::direct;
use crate::estimator::moments::Families;
use crate::estimator::moments::MomentTable;
use crate::estimator::moments::breakpoints;
use crate::estimator::problem::GridFit;
use crate::estimator::problem::PointStatus;
pub use crate::model::report::{AlternationTiming, FitReport, FitTimings, GcvRow};
use crate::model::{Coef, Farma, Order};
pub use bstep::{SMALL_STEP, ma_cls, ma_step};
use grid::quantiles;
pub use notes::{
    MA_EDGE, STRETCH_RATIO, ma_edge_note, missing_se_note, reselection_limit_note,
    stretched_ladder_note, undefined_trace_note,
};
pub use params::{
    DIRECT_MAGNITUDE_LIMITS, Farma2Params, FarmaParams, FitPath, Init, MAGNITUDE_LIMITS, MAX_GRID,
    MAX_GRID2_POINTS, ValidParams, check_fit2, check_grid2, check_magnitude,
};
use passes::rss_from;
pub use passes::{FILTER_CHUNK, FILTER_LEAD, residuals, residuals_indexed};
pub use smoother::fill_failed;
use smoother::{LagSmoother, LagStep};
pub use start::{REFINE_RATIO, START_ENOUGH, START_MAX, arma_cls, arma_cls_within, linear_start};
use start::{arma_residuals_rss, linear_se_factors, linear_start_into};
use std::time::Instant;

/// Whether the last iterate's RSS `rss` ends above the least one, `best_rss`, by more
/// than `tol` relative (the iterate of least RSS is then returned, module doc); a
/// non-finite `rss` always does (the difference alone would compare inf > inf or NaN,
/// both false).
fn went_back(rss: f64, best_rss: f64, tol: f64) -> bool {
    !rss.is_finite() || rss - best_rss > tol * rss
}

/// One iterate of the alternation, kept while it has the least global RSS.
pub(super) struct Iterate<C, H> {
    /// Its index in `rss_history` (0: the linear start).
    pub(super) index: usize,
    pub(super) rss: f64,
    pub(super) coef: C,
    pub(super) b: Vec<f64>,
    /// Its bandwidth (NaN for the start).
    pub(super) h: H,
    pub(super) filled: Vec<bool>,
}

/// Alternations without a new least RSS after which the alternation stops when its
/// last RSS is above that least one by more than `tol` (it is past its minimum; the
/// iterate of least RSS is returned).
pub const PATIENCE: usize = 2;

/// How the alternation's notes name a smoother's bandwidth.
pub(super) struct BandwidthWords {
    /// "bandwidth" or "bandwidths".
    pub(super) noun: &'static str,
    /// "it" or "them".
    pub(super) pronoun: &'static str,
    /// "is" or "are".
    pub(super) verb: &'static str,
    /// The options that fix it.
    pub(super) fixed_by: &'static str,
}

/// GCV's choice over a smoother's ladder.
pub(super) struct Selection<S: Smoother + ?Sized> {
    /// The ladder's table.
    pub(super) rows: Vec<GcvRow>,
    /// The local fits at the chosen bandwidth.
    pub(super) fit: S::Coef,
    pub(super) h: S::H,
    /// Whether the ladder was extended.
    pub(super) extended: bool,
    pub(super) notes: Vec<String>,
}

/// The f-step's smoother of one index, with the b-step and the residual recursion
/// that go with its local fits (module doc).
pub(super) trait Smoother {
    /// A bandwidth: h on the lag index, (h_1, h_2) on the 2-D one.
    type H: Copy + PartialEq;
    /// The local fits at the grid points.
    type Coef: Clone;
    const WORDS: BandwidthWords;
    /// Whether the model keeps the GCV table of a re-check that `--max-iter` leaves no
    /// alternation to act on (else the table of the bandwidth it settled at).
    const RECHECK_TABLE_AT_MAX_ITER: bool;
    /// A bandwidth as the notes print it.
    fn fmt_h(h: Self::H) -> String;
    /// GCV over the ladder at residuals `e`, the response's MA coefficients `b`.
    fn select(&mut self, e: &[f64], b: &[f64]) -> Selection<Self>;
    /// GCV chose `h` (first choice or a re-selection that changed it).
    fn chose(&mut self, _h: Self::H) {}
    /// Local fits at bandwidth `h` at residuals `e` and MA coefficients `b`.
    fn fit_at(&mut self, e: &[f64], b: &[f64], h: Self::H) -> Self::Coef;
    /// Fills the grid points without a local fit, returning which; an error when no
    /// point has one.
    fn fill(&self, coef: &mut Self::Coef, h: Self::H) -> Result<Vec<bool>>;
    /// The b-step with f = `coef` fixed, from the residuals `e` of the last iterate and
    /// the response's `b_resp`: sets the iterate's `b` and the next response's
    /// `b_resp`. Some(RSS) when it also left the iterate's residuals in `e`; None when
    /// they are still to be computed ([`Smoother::residuals`], with `b_resp` = `b`).
    fn b_step(
        &mut self,
        coef: &Self::Coef,
        h: Self::H,
        b: (&mut Vec<f64>, &mut Vec<f64>),
        e: &mut [f64],
        iteration: usize,
    ) -> Option<f64>;
    /// The residuals of (`coef`, `b`) into `e` (zeros before the first sample), and
    /// their RSS.
    fn residuals(&mut self, coef: &Self::Coef, b: &[f64], e: &mut [f64]) -> f64;
    /// Notes of its own when the loop has ended, before the iterate of least RSS is
    /// taken back.
    fn end_notes(&mut self, _alt: &Alternation<Self>) -> Vec<String> {
        Vec::new()
    }
}

/// What ended the alternation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Ended {
    /// The RSS settled (either rule of the module doc): converged.
    Settled,
    /// `max_iter` alternations without settling.
    MaxIter,
    /// The RSS settled in the last alternation `max_iter` allows and GCV chose another
    /// bandwidth there.
    MaxIterAtReselection,
    /// The residuals were not finite.
    NotFinite,
}

/// The order and the rules of an alternation.
pub(super) struct Control<H> {
    pub(super) p: usize,
    pub(super) q: usize,
    pub(super) max_iter: usize,
    pub(super) tol: f64,
    /// A fixed bandwidth instead of GCV.
    pub(super) bandwidth: Option<H>,
}

/// The alternation's result: the returned iterate and the alternation's record.
pub(super) struct Alternation<S: Smoother + ?Sized> {
    pub(super) coef: S::Coef,
    pub(super) b: Vec<f64>,
    /// Residuals e_t for every t, of (`coef`, `b`).
    pub(super) e: Vec<f64>,
    pub(super) rss: f64,
    pub(super) h: S::H,
    pub(super) filled: Vec<bool>,
    /// RSS after the start and after each alternation.
    pub(super) rss_history: Vec<f64>,
    pub(super) gcv_table: Vec<GcvRow>,
    pub(super) ladder_extended: bool,
    pub(super) notes: Vec<String>,
    pub(super) iterations: usize,
    pub(super) converged: bool,
    pub(super) ended: Ended,
    /// The bandwidths GCV chose, in order (the first selection, then each re-selection
    /// that changed it).
    pub(super) chosen: Vec<S::H>,
    /// Whether the returned iterate is the linear start.
    pub(super) returned_start: bool,
    pub(super) timings: Vec<AlternationTiming>,
}

/// The alternation (module doc, steps 2 to 4) from `start` (iterate 0, with its
/// residuals `e`), with smoother `sm`; `notes` are the fit's notes so far.
pub(super) fn alternate<S: Smoother>(
    sm: &mut S,
    ctl: &Control<S::H>,
    start: Iterate<S::Coef, S::H>,
    mut e: Vec<f64>,
    mut notes: Vec<String>,
) -> Result<Alternation<S>> {
    let mut clock = Instant::now();
    // seconds since the last lap
    let mut lap = move || {
        let s = clock.elapsed().as_secs_f64();
        clock = Instant::now();
        s
    };
    let (mut coef, mut b, mut rss) = (start.coef.clone(), start.b.clone(), start.rss);
    let mut filled = start.filled.clone();
    let mut h = ctl.bandwidth.unwrap_or(start.h);
    // The best iterate by global RSS, the linear start being iterate 0 (see the end).
    let mut best = start;
    let mut rss_history = vec![rss];
    let mut timings = Vec::new();
    let mut gcv_table = Vec::new();
    let mut ladder_extended = false;
    let mut iterations = 0;
    let mut ended = Ended::MaxIter;
    let mut reselections = 0;
    let mut chosen: Vec<S::H> = Vec::new();
    // rss_history index of the last bandwidth re-selection
    let mut reselected_at = 0;
    let mut need_gcv = ctl.bandwidth.is_none();
    // the b of the response y_t = x_t - sum b_m e_{t-m} of the next f-step: the
    // iterate's own b, or the Gauss-Newton step from it (see the b-step)
    let mut b_resp = b.clone();
    let words = S::WORDS;
    while iterations < ctl.max_iter {
        iterations += 1;
        let mut at = AlternationTiming::default();
        lap();
        // 2. f-step
        let mut fit_h = if need_gcv {
            need_gcv = false;
            let s = sm.select(&e, &b_resp);
            sm.chose(s.h);
            at.gcv_s = lap();
            ladder_extended |= s.extended;
            notes.extend(s.notes);
            h = s.h;
            chosen.push(h);
            gcv_table = s.rows;
            s.fit
        } else {
            sm.fit_at(&e, &b_resp, h)
        };
        filled = sm.fill(&mut fit_h, h)?;
        coef = fit_h;
        at.f_step_s = lap();
        // 3. b-step; 4. residuals
        let stepped = sm.b_step(&coef, h, (&mut b, &mut b_resp), &mut e, iterations);
        at.b_step_s = lap();
        let new_rss = match stepped {
            Some(rss) => rss,
            None => {
                b_resp = b.clone();
                sm.residuals(&coef, &b, &mut e)
            }
        };
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
            timings.push(at);
            ended = Ended::NotFinite;
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
        let settled = change <= ctl.tol * rss.max(f64::MIN_POSITIVE)
            || (since_best >= PATIENCE && rss - best.rss > ctl.tol * rss);
        if settled {
            if ctl.bandwidth.is_none() && reselections < 2 {
                // re-check the bandwidth at the converged residuals
                let s = sm.select(&e, &b_resp);
                at.gcv_s += lap();
                timings.push(at.clone());
                reselections += 1;
                let (noun, now, new) = (words.noun, S::fmt_h(h), S::fmt_h(s.h));
                if s.h != h && iterations == ctl.max_iter {
                    // no alternation left to fit at the new bandwidth: the model stays
                    // at h (its coefficients are the f-step's at h), not converged
                    let table = if S::RECHECK_TABLE_AT_MAX_ITER {
                        gcv_table = s.rows;
                        " (the GCV table is the re-check's)"
                    } else {
                        ""
                    };
                    notes.push(format!(
                        "alternation {iterations}: the RSS settled at {noun} {now}; GCV at those residuals chose {new}, but --max-iter {} ends the alternation here: NOT converged, the model is at the {noun} it settled at{table}",
                        ctl.max_iter
                    ));
                    ended = Ended::MaxIterAtReselection;
                    break;
                }
                if s.h != h {
                    notes.push(format!(
                        "alternation {iterations}: the RSS settled at {noun} {now}; GCV at those residuals chose {new}, and the alternation went on at {}",
                        words.pronoun
                    ));
                    ladder_extended |= s.extended;
                    notes.extend(s.notes);
                    h = s.h;
                    chosen.push(h);
                    sm.chose(h);
                    gcv_table = s.rows;
                    reselected_at = rss_history.len() - 1;
                    continue;
                }
                gcv_table = s.rows;
            } else {
                if ctl.bandwidth.is_none() {
                    notes.push(reselection_limit_note(iterations, &chosen, S::fmt_h));
                }
                timings.push(at.clone());
            }
            ended = Ended::Settled;
            break;
        }
        timings.push(at);
    }
    let mut alt = Alternation {
        coef,
        b,
        e,
        rss,
        h,
        filled,
        rss_history,
        gcv_table,
        ladder_extended,
        notes,
        iterations,
        converged: ended == Ended::Settled,
        ended,
        chosen,
        returned_start: false,
        timings,
    };
    let end = sm.end_notes(&alt);
    alt.notes.extend(end);
    // The alternation is not a descent method (module doc): the f-step minimises local
    // weighted sums of squares with the residuals held fixed, not the global RSS, so it
    // can end above an earlier iterate, even above the linear start it nests (on the
    // quantised ADIS16405 gyros with q = 2, see tests/suite/estimator_recovery.rs). The
    // iterate of least global RSS is returned when the last one is above it by more
    // than the convergence tolerance. The linear start (constant f_m = a_m) is the
    // linear model: trace p, its GCV, and the least-squares standard errors of a_m
    // (the bandwidth field keeps the one GCV last chose, unused by that model).
    if went_back(alt.rss, best.rss, ctl.tol) {
        let (p, q, rss) = (ctl.p, ctl.q, alt.rss);
        alt.notes.push(if best.index == 0 {
            format!(
                "the alternation ended above its linear ARMA({p},{q}) start (RSS {rss:.7e} > {:.7e}): the linear start is returned (constant f_m, slope 0, no local systems: n_support and kernel_mass 0, cond NaN; trace p = {p}, the linear model's; h = {} {} the {} {})",
                best.rss,
                S::fmt_h(alt.h),
                words.verb,
                words.noun,
                if ctl.bandwidth.is_some() {
                    format!("fixed by {}", words.fixed_by)
                } else {
                    "GCV last chose".to_string()
                }
            )
        } else {
            format!(
                "the alternation ended above its iterate {} (RSS {rss:.7e} > {:.7e}): that iterate is returned",
                best.index, best.rss
            )
        });
        alt.returned_start = best.index == 0;
        alt.coef = best.coef;
        alt.b = best.b;
        alt.filled = best.filled;
        if best.index > 0 {
            alt.h = best.h;
        }
        alt.rss = sm.residuals(&alt.coef, &alt.b, &mut alt.e);
    }
    Ok(alt)
}

/// Fits a FARMA model to `series`.
pub fn fit(series: &[f64], params: &ValidParams) -> Result<(Farma, FitReport)> {
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
        return Err(Error::Data(
            "the channel holds NaN or infinite values".into(),
        ));
    }
    let range = xmax - xmin;
    if range.is_nan() || range <= 0.0 {
        return Err(Error::Data(
            "the channel is constant: nothing to fit".into(),
        ));
    }
    check_magnitude("the channel", xmin, xmax, prm.path).map_err(Error::Data)?;
    let qs = quantiles(
        |t| x[t - d],
        pp..n,
        &[prm.grid_quantiles.0, prm.grid_quantiles.1],
    );
    let (glo, ghi) = (qs[0], qs[1]);
    if ghi.is_nan() || ghi <= glo {
        return Err(Error::Data(format!(
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
    let (a0, b, start_holds) = match prm.init {
        Init::Arma => match linear_start_into(&x, p, q, pp, Some(&mut e_start)) {
            Some(abh) => abh,
            None => {
                return Err(Error::Data(
                    "the linear ARMA start failed (singular design)".into(),
                ));
            }
        },
        Init::Literal => match fit_arma(x_start, p, 0) {
            Some(m) => (m.ar, vec![0.0; q], false),
            None => return Err(Error::Data("the AR start failed (singular design)".into())),
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
    let (e, rss) = if start_holds {
        let rss = rss_from(&e_start, pp);
        (e_start, rss)
    } else {
        drop(e_start);
        arma_residuals_rss(&x, &a0, &b, pp)
    };
    timings.start_s = lap();
    let start = Iterate {
        index: 0,
        rss,
        coef,
        b,
        h: f64::NAN,
        filled: vec![false; g],
    };
    let mut notes = Vec::new();
    if prm.bandwidth.is_none() {
        notes.extend(stretched_ladder_note(
            &format!("the index values x_(t-{d}) (less the channel's mean)"),
            (xmin, xmax),
            (glo, ghi),
            prm.grid_quantiles,
        ));
    }
    let mut sm = LagSmoother::new(
        &x,
        &grid,
        (p, q, d),
        prm.path,
        prm.init,
        (xmin, xmax),
        prm.bandwidth.is_some(),
    );
    let ctl = Control {
        p,
        q,
        max_iter: prm.max_iter,
        tol: prm.tol,
        bandwidth: prm.bandwidth,
    };
    let alt = alternate(&mut sm, &ctl, start, e, notes)?;
    timings.alternations = alt.timings;
    let (coef, b, e, rss, h) = (alt.coef, alt.b, alt.e, alt.rss, alt.h);
    let (filled, rss_history, gcv_table) = (alt.filled, alt.rss_history, alt.gcv_table);
    let (ladder_extended, mut notes, iterations) = (alt.ladder_extended, alt.notes, alt.iterations);
    let (converged, returned_start) = (alt.converged, alt.returned_start);
    let mut cache = sm.cache;
    lap();
    // trace, GCV and standard errors at the final bandwidth: the trace and the
    // standard errors depend on X and U only (not on the residuals), and the GCV is
    // the returned model's, from its own RSS
    let sm = LagStep::new(&x, &e, &b, (p, d), &grid, prm.path, (xmin, xmax));
    let prob = sm.prob;
    let m = (n - pp) as f64;
    let sigma2 = rss / (n - pp) as f64;
    let (trace, factors) = match prm.path {
        // the linear model with constant f_m: trace p, the least-squares standard
        // errors of a_m
        _ if returned_start => (Some(p as f64), linear_se_factors(&x, p, pp).repeat(g)),
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
    let model = Farma {
        order: Order::new(p, q, d),
        mean,
        b,
        sigma2,
        bandwidth: h,
        coef: Coef {
            grid,
            grid_shift: 0.0,
            f: coef.f.clone(),
            se,
            filled,
            second: None,
        },
    };
    let report = FitReport {
        local: coef,
        rss,
        trace,
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
    };
    Ok((model, report))
}
