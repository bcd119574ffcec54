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
//!    when the minimum sits at an end of the ladder; at the top, the limit
//!    h -> infinity (`global`: f_m linear in the index) is evaluated first and chosen
//!    when its GCV is lower;
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
//! 5. the guard (issue 25): when the iterate of steps 2-4 has an RSS above the one it
//!    started from by more than `tol` relative (or not finite), it is not taken. Near
//!    the MA unit root (b_1 = -0.9996 on the ADIS16405 gyros, what differencing gives)
//!    the recursion e_t = w_t - b e_(t-1) integrates every error of the f-step over
//!    thousands of samples, and an f-step computed with e held fixed can raise the
//!    true RSS by fourteen orders of magnitude (2.3e19 from 1.2e5). The damped step
//!    (`damped_step`) goes back towards the iterate: with b held at the iterate's,
//!    the residuals are affine in f, so over the plane f_old + alpha D + beta D_c
//!    (D = f_new - f_old; D_c = D less its mean over the grid points, per m) the RSS
//!    is a quadratic in (alpha, beta), known exactly from three residual passes
//!    (f_old, and each direction, shrunk 1000-fold while it overflows). Its minimiser
//!    (over the plane or over one direction; the one of largest predicted decrease that
//!    keeps a positive share alpha + beta of the f-step, at most the f-step itself) is
//!    the step; the b-step then runs from the iterate's b, and the step is taken when
//!    the RSS falls by more than `tol` relative, else halved ([`DAMP_HALVINGS`] times).
//!    The centred direction matters at the linear start: that is the least-squares
//!    ARMA, so a constant shift of f is no descent there, while the shape of f may be.
//!    When no step is taken the alternation stays at its iterate: at the bandwidth
//!    that iterate was fitted at this counts as settled (GCV re-checks the bandwidth
//!    at its residuals, and the alternation goes on at another one it chooses); at a
//!    bandwidth GCV has just chosen at these very residuals (the first f-step, or the
//!    one after a re-selection) the alternation stops there (`Ended::Stalled`,
//!    converged). The cost is paid only when the guard acts: two N-long buffers and
//!    three to seven passes over the series. A fit that never leaves its start
//!    returns it with [`StartReason::NoDescent`] and a note saying so.
//!
//! Degrees of freedom of a damped iterate: f = (1 - lambda) f_old + lambda S_h y plus
//! a constant shift, lambda = alpha + beta; the trace reported is (1 - lambda)
//! tr_old + lambda tr(S_h), tr of the linear start p, applied recursively (the
//! iterate's `Mix`: the weight of each bandwidth's smoother, and of the linear start,
//! in its f). An approximation: f_old was fitted to other residuals than S_h's y (the
//! trace of a combination of smoothers of one response is the combination of their
//! traces; here the responses differ by the residuals the alternation moved), and the
//! constant shift -beta mean(D) is counted with the smoothers it came from (its own
//! trace, the projection of each smoother on constants, is about p for either, so the
//! two cancel). The standard-error factors are combined with the same weights (by the
//! triangle inequality an upper bound on the standard error of the combination when
//! the two are computed from one response). The model's bandwidth is the last f-step's.
//!
//! Without the guard the alternation is not a descent method (the f-step holds the
//! residuals fixed): on the FARMA(2,1,1) of the tests its RSS falls by 1.6 % in the
//! first step, then moves by about 1e-6 relative, in a slowly damped two-cycle, while
//! b changes in the fifth digit; on the benchmark's 1e6 samples it is least at the
//! third alternation and then rises slowly towards a fixed point 1.2e-5 above. Rises
//! within `tol` per alternation are still taken (the guard leaves them to the rules
//! below, so those fits are unchanged); a larger one is damped (step 5).
//! `rss_history` records every iterate taken.
//! The iterate of least global RSS (the linear start included) is returned when the
//! last one ends above it by more than `tol` relative, with a note: the fit never ends
//! more than `tol` above the linear ARMA it nests (with [`StartReason::EndedAbove`]
//! when that is the start). Residuals that are not finite are damped (step 5); were a
//! step to leave them non-finite it would stop the alternation (`converged` false)
//! and the iterate of least RSS would be returned. A returned linear start reports the
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
mod global;
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
use crate::estimator::series::Centred;
pub use crate::model::report::{AlternationTiming, FitReport, FitTimings, GcvRow};
use crate::model::{Coef, Farma, Order, StartReason};
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

/// The damped step's values f = f_old + alpha D + beta (D - mean D) at every grid point
/// (D = f_new - f_old, its mean over the grid points per function; `p` functions
/// interleaved per point) into `out`: the one combination of both indexes' smoothers.
pub(super) fn combine_f(old: &[f64], new: &[f64], p: usize, (al, be): (f64, f64), out: &mut [f64]) {
    let g = old.len() / p.max(1);
    for m in 0..p {
        let mean = (0..g).map(|k| new[k * p + m] - old[k * p + m]).sum::<f64>() / g as f64;
        for k in 0..g {
            let (o, d) = (old[k * p + m], new[k * p + m] - old[k * p + m]);
            out[k * p + m] = o + al * d + be * (d - mean);
        }
    }
}

/// The damped step's slopes: old + (alpha + beta) (new - old), into `out`.
pub(super) fn combine_slopes(old: &[f64], new: &[f64], w: f64, out: &mut [f64]) {
    for ((v, o), n) in out.iter_mut().zip(old).zip(new) {
        *v = o + w * (n - o);
    }
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
    /// What its f is a combination of (module doc, damped f-steps).
    pub(super) mix: Mix<H>,
}

/// The smoothers an iterate's f combines, with their weights (summing to 1): Some(h)
/// the local fits at bandwidth h, None the linear start. One entry (weight 1) unless
/// a damped f-step (module doc) mixed the new local fits with the iterate's f.
pub(super) type Mix<H> = Vec<(f64, Option<H>)>;

/// The linear start's mix.
pub(super) fn start_mix<H>() -> Mix<H> {
    vec![(1.0, None)]
}

/// `lam` of the smoother at `h` and 1 - `lam` of `old` (entries at the same bandwidth
/// merged).
fn mixed<H: PartialEq + Copy>(old: &Mix<H>, h: H, lam: f64) -> Mix<H> {
    let mut out: Mix<H> = vec![(lam, Some(h))];
    for &(w, k) in old {
        match out.iter_mut().find(|(_, o)| *o == k) {
            Some(e) => e.0 += (1.0 - lam) * w,
            None => out.push(((1.0 - lam) * w, k)),
        }
    }
    out
}

/// Attempts of the damped f-step at a step that overflows: lambda is divided by
/// [`DAMP_SHRINK`] after each until the residuals at lambda are finite.
pub const DAMP_OVERFLOW_TRIES: usize = 4;
/// See [`DAMP_OVERFLOW_TRIES`].
pub const DAMP_SHRINK: f64 = 1e3;
/// Halvings of the line search's lambda when the b-step's RSS at it is not below the
/// iterate's (the quadratic's minimum lost to rounding, or the b-step's own step).
pub const DAMP_HALVINGS: usize = 3;

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
    /// The damped f-step's f (module doc): `old` + alpha D + beta D_c, D = `new` -
    /// `old` and D_c = D less its mean over the grid points (per m), f and slopes at
    /// every grid point; the other diagnostics are `new`'s.
    fn combine(old: &Self::Coef, new: &Self::Coef, ab: (f64, f64)) -> Self::Coef;
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
    /// An f-step raised the RSS and no damped step lowered it (module doc): the
    /// alternation stopped at its last iterate (counted as converged).
    Stalled,
}

/// The order and the rules of an alternation.
pub(super) struct Control<H> {
    pub(super) p: usize,
    pub(super) q: usize,
    pub(super) max_iter: usize,
    pub(super) tol: f64,
    /// A fixed bandwidth instead of GCV.
    pub(super) bandwidth: Option<H>,
    /// The first row of the regression, max(p, q, d): the RSS sums from it.
    pub(super) start: usize,
}

/// The alternation's result: the returned iterate and the alternation's record.
pub(super) struct Alternation<S: Smoother + ?Sized> {
    pub(super) coef: S::Coef,
    pub(super) b: Vec<f64>,
    /// Residuals e_t for every t, of (`coef`, `b`).
    pub(super) e: Vec<f64>,
    /// What `coef` combines (module doc, damped f-steps).
    pub(super) mix: Mix<S::H>,
    /// Why the linear start was returned (Some exactly when `returned_start`).
    pub(super) returned_start_reason: Option<StartReason>,
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

/// The damped f-step (module doc): the f-step's `new` f raised the RSS above the
/// iterate's (`old`, `b_old`, RSS `rss_old`). At b = `b_old` the residuals are affine
/// in f, so over the plane f_old + alpha D + beta D_c (D = f_new - f_old, D_c = D less
/// its mean over the grid points, per m) their RSS is a quadratic in (alpha, beta):
/// three residual passes (at f_old, at D and at D_c) give it, and its minimiser is
/// the step (the centred direction matters at a linear start, where the constant part
/// of D is no descent: the start is the least-squares ARMA). When D overflows, both
/// directions are shrunk by [`DAMP_SHRINK`] ([`DAMP_OVERFLOW_TRIES`] times). The b-step
/// then runs from `b_old` at the step's f; the step is taken when that RSS is below
/// `rss_old` by more than `tol` relative, else it is halved ([`DAMP_HALVINGS`] times). Returns ((alpha, beta),
/// f, RSS) with `b`, `b_resp` and `e` the b-step's, or None with `b`, `b_resp` set to
/// `b_old` and `e` holding the residuals of (`old`, `b_old`); the scale of every step
/// tried (alpha + beta) is pushed to `tried`.
#[allow(clippy::too_many_arguments)]
fn damped_step<S: Smoother>(
    sm: &mut S,
    start: usize,
    (old, b_old, rss_old): (&S::Coef, &[f64], f64),
    new: &S::Coef,
    tol: f64,
    h: S::H,
    (b, b_resp): (&mut Vec<f64>, &mut Vec<f64>),
    e: &mut [f64],
    iteration: usize,
    tried: &mut Vec<f64>,
) -> Option<((f64, f64), S::Coef, f64)> {
    let restore = |b: &mut Vec<f64>, b_resp: &mut Vec<f64>| {
        b.clear();
        b.extend_from_slice(b_old);
        b_resp.clear();
        b_resp.extend_from_slice(b_old);
    };
    // the iterate's residuals at b_old (the plane's origin), and the responses of the
    // two directions (residuals at f_old + scale D, less e0)
    let mut e0 = vec![0.0; e.len()];
    sm.residuals(old, b_old, &mut e0);
    let mut ec = vec![0.0; e.len()];
    let dot = |a: &[f64], b: &[f64]| -> f64 {
        a[start..].iter().zip(&b[start..]).map(|(x, y)| x * y).sum()
    };
    let mut scale = 1.0;
    let mut gram = None;
    for k in 0..DAMP_OVERFLOW_TRIES {
        if k > 0 {
            scale /= DAMP_SHRINK;
            tried.push(scale);
        }
        sm.residuals(&S::combine(old, new, (scale, 0.0)), b_old, e);
        sm.residuals(&S::combine(old, new, (0.0, scale)), b_old, &mut ec);
        for ((v, c), v0) in e.iter_mut().zip(ec.iter_mut()).zip(&e0) {
            *v -= v0;
            *c -= v0;
        }
        let g = [
            dot(e, e),
            dot(e, &ec),
            dot(&ec, &ec),
            dot(&e0, e),
            dot(&e0, &ec),
        ];
        if g.iter().all(|v| v.is_finite()) {
            gram = Some(g);
            break;
        }
    }
    let stop = |e: &mut [f64], b: &mut Vec<f64>, b_resp: &mut Vec<f64>| {
        e.copy_from_slice(&e0);
        restore(b, b_resp);
        None
    };
    let Some([a11, a12, a22, g1, g2]) = gram else {
        return stop(e, b, b_resp);
    };
    // the step: of the quadratic's minimisers over the plane and over each direction
    // alone, the one of largest predicted decrease -(alpha g1 + beta g2) among those
    // that take a positive share alpha + beta of the f-step (a damped f-step, not a
    // step away from it), scaled to at most the f-step itself
    let det = a11 * a22 - a12 * a12;
    let mut cands = Vec::new();
    if det > 1e-9 * a11 * a22 {
        cands.push(((-g1 * a22 + g2 * a12) / det, (g1 * a12 - g2 * a11) / det));
    }
    if a11 > 0.0 {
        cands.push((-g1 / a11, 0.0));
    }
    if a22 > 0.0 {
        cands.push((0.0, -g2 / a22));
    }
    let step = cands
        .into_iter()
        .map(|(al, be): (f64, f64)| {
            let big = al.abs().max(be.abs()).max(1.0);
            (al / big, be / big)
        })
        .filter(|(al, be)| al + be > 0.0 && al * g1 + be * g2 < 0.0)
        .max_by(|x, y| (-(x.0 * g1 + x.1 * g2)).total_cmp(&-(y.0 * g1 + y.1 * g2)));
    let Some((mut al, mut be)) = step else {
        return stop(e, b, b_resp);
    };
    for _ in 0..=DAMP_HALVINGS {
        tried.push(scale * (al + be));
        let f = S::combine(old, new, (scale * al, scale * be));
        restore(b, b_resp);
        let rss = match sm.b_step(&f, h, (b, b_resp), e, iteration) {
            Some(rss) => rss,
            None => {
                b_resp.clone_from(b);
                sm.residuals(&f, b, e)
            }
        };
        // a decrease beyond the tolerance (a smaller one is what the alternation
        // calls settled: no better than the iterate)
        if rss_old - rss > tol * rss_old {
            return Some(((scale * al, scale * be), f, rss));
        }
        (al, be) = (al * 0.5, be * 0.5);
    }
    stop(e, b, b_resp)
}

/// The lambdas of a note.
fn fmt_lambdas(l: &[f64]) -> String {
    l.iter()
        .map(|v| format!("{v:.3e}"))
        .collect::<Vec<_>>()
        .join(", ")
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
    let mut mix = start.mix.clone();
    let mut h = ctl.bandwidth.unwrap_or(start.h);
    // the current iterate's bandwidth and rss_history index (h is the next f-step's)
    let (mut iter_h, mut current) = (start.h, 0);
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
    // the lambdas of the damped f-steps taken
    let mut damped: Vec<f64> = Vec::new();
    let words = S::WORDS;
    while iterations < ctl.max_iter {
        iterations += 1;
        let mut at = AlternationTiming::default();
        lap();
        // the iterate the f-step starts from (the damped step goes back towards it)
        let (coef_old, b_old) = (coef.clone(), b.clone());
        let filled_old = filled.clone();
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
        let mut new_rss = match stepped {
            Some(rss) => rss,
            None => {
                b_resp = b.clone();
                sm.residuals(&coef, &b, &mut e)
            }
        };
        let mut lam = 1.0;
        let mut stalled = false;
        if went_back(new_rss, rss, ctl.tol) {
            // the f-step raised the RSS (beyond the tolerance) or overflowed: the
            // damped step towards the iterate (module doc)
            let mut tried = vec![1.0];
            match damped_step(
                sm,
                ctl.start,
                (&coef_old, &b_old, rss),
                &coef,
                ctl.tol,
                h,
                (&mut b, &mut b_resp),
                &mut e,
                iterations,
                &mut tried,
            ) {
                Some(((al, be), f, r)) => {
                    // (the mix's weight of the new smoother: the constant shift of the
                    // centred direction is left out of the trace, module doc)
                    let l = al + be;
                    (lam, coef, new_rss) = (l, f, r);
                    for (f, o) in filled.iter_mut().zip(&filled_old) {
                        *f |= *o;
                    }
                    damped.push(l);
                }
                None => {
                    // no step lowers the RSS: the alternation stays at its iterate
                    // (b_resp is b_old again, e its residuals)
                    (coef, b, filled) = (coef_old, b_old, filled_old);
                    let at_new_h = h != iter_h;
                    notes.push(format!(
                        "alternation {iterations}: the f-step at {} {} raised the RSS ({new_rss:.7e} > {rss:.7e}) and no damped step f_old + alpha D + beta D_c (D = f_new - f_old, D_c = D less its mean) lowered it (steps tried, alpha + beta: {}): the alternation stays at its iterate {current} (RSS {rss:.7e}){}",
                        words.noun,
                        S::fmt_h(h),
                        fmt_lambdas(&tried),
                        if at_new_h {
                            " and stops"
                        } else {
                            ", as if it had settled there"
                        }
                    ));
                    if at_new_h {
                        // the bandwidth GCV chose at these very residuals: a re-check
                        // would choose it again
                        at.residuals_s = lap();
                        timings.push(at);
                        ended = Ended::Stalled;
                        break;
                    }
                    stalled = true;
                }
            }
        }
        at.residuals_s = lap();
        if !stalled && !new_rss.is_finite() {
            // (the damped step gives a finite RSS or none: not reached from it) the
            // iterate of least RSS is returned below (`went_back`), not converged
            notes.push(format!(
                "alternation {iterations}: the residuals are not finite (RSS {new_rss}): the alternation stops"
            ));
            rss = new_rss;
            rss_history.push(rss);
            timings.push(at);
            ended = Ended::NotFinite;
            break;
        }
        // a stall at the iterate's own bandwidth counts as settled there: GCV re-checks
        // the bandwidth at its residuals (module doc)
        let settled = stalled || {
            let change = (rss - new_rss).abs();
            rss = new_rss;
            rss_history.push(rss);
            current = rss_history.len() - 1;
            iter_h = h;
            mix = if lam == 1.0 {
                vec![(1.0, Some(h))]
            } else {
                mixed(&mix, h, lam)
            };
            if rss < best.rss {
                best = Iterate {
                    index: current,
                    rss,
                    coef: coef.clone(),
                    b: b.clone(),
                    h,
                    filled: filled.clone(),
                    mix: mix.clone(),
                };
            }
            // settled: the RSS changed by less than tol, or the least RSS so far was not
            // beaten for PATIENCE alternations while the last is above it by more than tol
            // (the iterate of least RSS is then returned, see below)
            // (counted from the last bandwidth re-selection, if later: a new h gets its own
            // PATIENCE alternations)
            let since_best = rss_history.len() - 1 - best.index.max(reselected_at);
            change <= ctl.tol * rss.max(f64::MIN_POSITIVE)
                || (since_best >= PATIENCE && rss - best.rss > ctl.tol * rss)
        };
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
            ended = if stalled {
                Ended::Stalled
            } else {
                Ended::Settled
            };
            break;
        }
        timings.push(at);
    }
    let converged = matches!(ended, Ended::Settled | Ended::Stalled);
    let (p, q) = (ctl.p, ctl.q);
    if !damped.is_empty() {
        let lo = damped.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = damped.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        notes.push(format!(
            "{} f-step(s) raised the RSS and were damped (f = f_old + alpha D + beta D_c, D = f_new - f_old, D_c = D less its mean, from the RSS's quadratic at fixed b; weight of the new local fits alpha + beta from {lo:.3e} to {hi:.3e}; the trace is the same combination of the smoothers' traces, an approximation)",
            damped.len()
        ));
    }
    let mut alt = Alternation {
        coef,
        b,
        e,
        mix,
        rss,
        h: if current == 0 { h } else { iter_h },
        filled,
        rss_history,
        gcv_table,
        ladder_extended,
        notes,
        iterations,
        converged,
        ended,
        chosen,
        returned_start: current == 0,
        returned_start_reason: None,
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
    let how = || {
        format!(
            "constant f_m, slope 0, no local systems: n_support and kernel_mass 0, cond NaN; trace p = {p}, the linear model's; h = {} {} the {} {}",
            S::fmt_h(alt.h),
            words.verb,
            words.noun,
            if ctl.bandwidth.is_some() {
                format!("fixed by {}", words.fixed_by)
            } else {
                "GCV last chose".to_string()
            }
        )
    };
    if went_back(alt.rss, best.rss, ctl.tol) {
        let rss = alt.rss;
        alt.notes.push(if best.index == 0 {
            format!(
                "the alternation ended above its linear ARMA({p},{q}) start (RSS {rss:.7e} > {:.7e}): the linear start is returned ({})",
                best.rss,
                how()
            )
        } else {
            format!(
                "the alternation ended above its iterate {} (RSS {rss:.7e} > {:.7e}): that iterate is returned",
                best.index, best.rss
            )
        });
        alt.returned_start = best.index == 0;
        alt.returned_start_reason = alt.returned_start.then_some(StartReason::EndedAbove);
        alt.coef = best.coef;
        alt.b = best.b;
        alt.filled = best.filled;
        alt.mix = best.mix;
        if best.index > 0 {
            alt.h = best.h;
        }
        alt.rss = sm.residuals(&alt.coef, &alt.b, &mut alt.e);
    } else if alt.returned_start {
        // the alternation never left its start: the first f-step, damped down to the
        // smallest lambda tried, did not lower the RSS (max_iter >= 1)
        alt.notes.push(format!(
            "no local fit at any tried step lowered the RSS below the linear ARMA({p},{q}) start's ({:.7e}): the linear start is returned ({})",
            alt.rss,
            how()
        ));
        alt.returned_start_reason = Some(StartReason::NoDescent);
    }
    Ok(alt)
}

/// The trace and standard-error factors of a mixed f (module doc): each smoother's
/// from `part`, combined with the mix's weights (one smoother: its own, bit for bit).
/// A trace that is not known for one of them is not known for the mix.
pub(super) fn mix_parts<H: Copy>(
    mix: &Mix<H>,
    mut part: impl FnMut(Option<H>) -> (Option<f64>, Vec<f64>),
) -> (Option<f64>, Vec<f64>) {
    if let [(_, h)] = mix[..] {
        return part(h);
    }
    let mut trace = Some(0.0);
    let mut factors: Vec<f64> = Vec::new();
    for &(w, h) in mix {
        let (tr, f) = part(h);
        trace = trace.zip(tr).map(|(a, t)| a + w * t);
        if factors.is_empty() {
            factors = vec![0.0; f.len()];
        }
        for (a, v) in factors.iter_mut().zip(&f) {
            *a += w * v;
        }
    }
    (trace, factors)
}

/// Fits a FARMA model to `series`, from a centred copy of it (N values held beside
/// the series while the fit runs): the in-memory path that
/// [`fit_then_release`]'s reading of the series itself is tested against.
pub fn fit(series: &[f64], params: &ValidParams) -> Result<(Farma, FitReport)> {
    fit_series(series, params, true)
}

/// How often [`fit_then_release`] calls its `release` while the fit runs.
pub const RELEASE_EVERY: std::time::Duration = std::time::Duration::from_millis(10);

/// [`fit`] without the centred copy: every pass reads `series` itself with the mean
/// taken out on the fly ([`Centred`]: the copy's values, bit for bit, so the same
/// fit), and a thread calls `release` every [`RELEASE_EVERY`] while the fit runs and
/// once after it. A caller whose series is a store's mapped column drops the column's
/// pages from the resident set there ([`crate::store::Store::release`]): the pages a
/// pass reads are faulted back in from the page cache, and released behind it, so
/// the fit's resident set holds its own vectors (the residuals, the interval indexes)
/// and the pages read in the last few milliseconds, not the column (measured on 1e8
/// samples: BENCHMARKS.md).
pub fn fit_then_release(
    series: &[f64],
    params: &ValidParams,
    release: impl Fn() + Sync,
) -> Result<(Farma, FitReport)> {
    fit_releasing(series, params, release, RELEASE_EVERY)
}

/// [`fit_then_release`] with `release` called every `every` (the tests release all
/// the time: `every` zero).
pub(super) fn fit_releasing(
    series: &[f64],
    params: &ValidParams,
    release: impl Fn() + Sync,
    every: std::time::Duration,
) -> Result<(Farma, FitReport)> {
    let release = &release;
    let out = std::thread::scope(|s| {
        // `stop` is dropped at the fit's end, or while a panic of the fit unwinds out
        // of this closure (before the scope joins the thread)
        let (stop, stopped) = std::sync::mpsc::channel::<()>();
        s.spawn(move || {
            use std::sync::mpsc::RecvTimeoutError;
            while let Err(RecvTimeoutError::Timeout) = stopped.recv_timeout(every) {
                release();
            }
        });
        let out = fit_series(series, params, false);
        drop(stop);
        out
    });
    release();
    out
}

/// The least and largest of `values` and whether one is NaN (f64::min and max skip
/// NaN; an infinite value shows as an infinite extreme).
fn extremes(values: impl Iterator<Item = f64>) -> (f64, f64, bool) {
    let (mut lo, mut hi, mut nan) = (f64::INFINITY, f64::NEG_INFINITY, false);
    for c in values {
        lo = lo.min(c);
        hi = hi.max(c);
        nan |= c.is_nan();
    }
    (lo, hi, nan)
}

/// [`fit`] (`copy`: the passes read a centred copy of `series`) or
/// [`fit_then_release`] (they read `series` less its mean).
fn fit_series(series: &[f64], params: &ValidParams, copy: bool) -> Result<(Farma, FitReport)> {
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
    // the centred series' extremes and the NaN check (f64::min and max skip NaN; an
    // infinite value shows as an infinite extreme), chunks in parallel, with the
    // centred copy written in the same pass when there is one
    let copied: Vec<f64>;
    let (x, parts) = if copy {
        let parts;
        (copied, parts) = buffers::filled(n, |at, out: &mut [f64]| {
            extremes(out.iter_mut().zip(&series[at..]).map(|(o, v)| {
                *o = v - mean;
                *o
            }))
        });
        (Centred::plain(&copied), parts)
    } else {
        use rayon::prelude::*;
        let parts: Vec<_> = series
            .par_chunks(buffers::FILL_CHUNK)
            .map(|vs| extremes(vs.iter().map(|v| v - mean)))
            .collect();
        (Centred::new(series, mean), parts)
    };
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
        |t| x.at(t - d),
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
    let x_start = &x.prefix(n.min(START_MAX)).to_vec();
    // the residuals at the start: written by the linear start's last pass over every
    // sample when it evaluated the returned (a, b), else by arma_residuals_rss
    let mut e_start = vec![0.0; if prm.init == Init::Arma { n } else { 0 }];
    let (a0, b, start_holds) = match prm.init {
        Init::Arma => match linear_start_into(x, p, q, pp, Some(&mut e_start)) {
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
        arma_residuals_rss(x, &a0, &b, pp)
    };
    timings.start_s = lap();
    let start = Iterate {
        index: 0,
        rss,
        coef,
        b,
        h: f64::NAN,
        filled: vec![false; g],
        mix: start_mix(),
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
        x,
        &grid,
        (p, q, d),
        prm.path,
        prm.init,
        (xmin, xmax),
        (prm.bandwidth.is_some(), prm.bandwidth_limit),
    );
    let ctl = Control {
        p,
        q,
        max_iter: prm.max_iter,
        tol: prm.tol,
        bandwidth: prm.bandwidth,
        start: pp,
    };
    let alt = alternate(&mut sm, &ctl, start, e, notes)?;
    timings.alternations = alt.timings;
    let (coef, b, e, rss, h) = (alt.coef, alt.b, alt.e, alt.rss, alt.h);
    let (filled, rss_history, gcv_table) = (alt.filled, alt.rss_history, alt.gcv_table);
    let (ladder_extended, mut notes, iterations) = (alt.ladder_extended, alt.notes, alt.iterations);
    let (converged, returned_start) = (alt.converged, alt.returned_start);
    let (returned_start_reason, mix) = (alt.returned_start_reason, alt.mix);
    let mut cache = sm.cache;
    lap();
    // trace, GCV and standard errors at the final bandwidth: the trace and the
    // standard errors depend on X and U only (not on the residuals), and the GCV is
    // the returned model's, from its own RSS
    let sm = LagStep::new(x, &e, &b, (p, d), &grid, prm.path, (xmin, xmax));
    let prob = sm.prob;
    let m = (n - pp) as f64;
    let sigma2 = rss / (n - pp) as f64;
    // the trace and standard-error factors of each smoother the returned f combines
    // (one, weight 1, unless a damped f-step mixed two or more: module doc)
    let mut part = |at: Option<f64>| -> (Option<f64>, Vec<f64>) {
        let Some(h) = at else {
            // the linear model with constant f_m: trace p, the least-squares standard
            // errors of a_m
            return (Some(p as f64), linear_se_factors(x, p, pp).repeat(g));
        };
        if h.is_infinite() {
            // the ladder's limit: the global fit's trace and standard errors (its
            // design is the one the alternation fitted with)
            let sm = LagStep::new(x, &e, &b, (p, d), &grid, prm.path, (xmin, xmax));
            return match sm.limit_fit(&mut cache) {
                Some((f, rt)) => (rt.map(|(_, tr)| tr), global::GlobalFit::se_factors(&f)),
                None => (None, vec![f64::NAN; g * p]),
            };
        }
        match prm.path {
            FitPath::Fast => {
                // one table of the design's families to degree 10 (K^2 for the standard
                // errors): the local systems' inverses, the trace, the standard errors
                let index = cache.index_for(&prob, &grid, h);
                let breaks = || breakpoints(&grid, &[h]);
                let table = MomentTable::build_over(
                    &prob,
                    index,
                    breaks,
                    (xmin, xmax),
                    10,
                    Families::Design,
                );
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
        }
    };
    let (trace, factors) = if returned_start {
        part(None)
    } else {
        mix_parts(&mix, part)
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
        returned_start_reason,
        notes,
        timings,
    };
    Ok((model, report))
}
