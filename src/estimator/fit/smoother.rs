//! The f-step's smoother on the lag index U_t = x_{t-d}: local-linear Biweight fits at
//! the grid points by either path (moment tables or KD-tree gathers), with the caches
//! an alternation keeps between its steps, and the b-steps and residual recursion that
//! go with it ([`LagSmoother`], the lag index's [`Smoother`]).

use super::bstep::{SMALL_STEP, gn_b_step, ma_step, ma_step_from};
use super::gcv::{LadderCache, RungFit, gcv_select};
use super::params::{FitPath, Init};
use super::passes::{
    SpanFill, eval_with, residuals, residuals_indexed, rss_from, w_indexed_filler,
};
use super::{Alternation, BandwidthWords, Selection, Smoother};
use crate::error::{Error, Result};
use crate::estimator::arma::ma_invertible;
use crate::estimator::direct;
use crate::estimator::direct::DirectIndex;
use crate::estimator::linalg::normal_equations;
use crate::estimator::moments::Families;
use crate::estimator::moments::IntervalIndex;
use crate::estimator::moments::IntervalLookup;
use crate::estimator::moments::LocalSystems;
use crate::estimator::moments::MomentTable;
use crate::estimator::moments::breakpoints;
use crate::estimator::problem::GridFit;
use crate::estimator::problem::PointStatus;
use crate::estimator::problem::VcProblem;
use crate::estimator::series::Centred;

/// Fills failed grid points by linear interpolation between the nearest Ok points
/// (constant beyond the outermost). Returns which were filled; None if none is Ok.
pub fn fill_failed(fit: &mut GridFit, grid: &[f64]) -> Option<Vec<bool>> {
    let p = fit.p;
    let ok: Vec<usize> = (0..grid.len())
        .filter(|g| fit.status[*g] == PointStatus::Ok)
        .collect();
    if ok.is_empty() {
        return None;
    }
    let mut filled = vec![false; grid.len()];
    for g in 0..grid.len() {
        if fit.status[g] == PointStatus::Ok {
            continue;
        }
        filled[g] = true;
        let right = ok.partition_point(|k| *k < g);
        for m in 0..p {
            fit.f[g * p + m] = match (right.checked_sub(1).map(|i| ok[i]), ok.get(right)) {
                (Some(a), Some(&c)) => {
                    let lam = (grid[g] - grid[a]) / (grid[c] - grid[a]);
                    fit.f[a * p + m] + lam * (fit.f[c * p + m] - fit.f[a * p + m])
                }
                (Some(a), None) => fit.f[a * p + m],
                (None, Some(&c)) => fit.f[c * p + m],
                (None, None) => unreachable!(),
            };
        }
    }
    Some(filled)
}

/// The f-step machinery for one alternation: fits for a set of bandwidths and their
/// RSS / trace, by either path.
pub(super) struct LagStep<'a> {
    pub(super) prob: VcProblem<'a>,
    pub(super) grid: &'a [f64],
    pub(super) path: FitPath,
    pub(super) umin: f64,
    pub(super) umax: f64,
}

impl<'a> LagStep<'a> {
    /// The smoother for series `x`, residuals `e`, MA coefficients `b`, shape
    /// (p, d) (first row max(p, q, d)), on `grid`, with index values in `span`.
    pub(super) fn new(
        x: Centred<'a>,
        e: &'a [f64],
        b: &'a [f64],
        (p, d): (usize, usize),
        grid: &'a [f64],
        path: FitPath,
        (umin, umax): (f64, f64),
    ) -> Self {
        let prob = VcProblem::new(x, e, b, p, d);
        LagStep {
            prob,
            grid,
            path,
            umin,
            umax,
        }
    }

    /// Local fits at one bandwidth, without RSS and trace. On the fast path the
    /// left-hand sides of the local systems (which depend on X and U only) are kept in
    /// `cache` and reused while h stays the same: then the pass sums only the
    /// response's moments, X_a y (after a GCV ladder the kept left-hand sides come from
    /// the ladder's table: the same sums over finer intervals, equal to rounding).
    /// Each row's interval is read from the cache's index (built on first use at h).
    pub(super) fn fit_at(&self, h: f64, cache: &mut StepCache) -> GridFit {
        match self.path {
            FitPath::Fast => {
                let span = (self.umin, self.umax);
                cache.index_for(&self.prob, self.grid, h);
                let index = cache.any_index();
                // degree 6 for the left-hand sides, 5 for the right-hand sides alone
                let breaks = || breakpoints(self.grid, &[h]);
                let build = |families, deg| {
                    MomentTable::build_over(&self.prob, index, breaks, span, deg, families)
                };
                if let Some(sys) = cache.systems.as_ref().filter(|s| s.h == h) {
                    return build(Families::Response, 5).fit_response(sys);
                }
                let table = build(Families::All, 6);
                let sys = table.local_systems(self.grid, h);
                let fit = table.fit_response(&sys);
                cache.systems = Some(sys);
                fit
            }
            FitPath::Direct => {
                let index = cache.direct_index(&self.prob);
                direct::fit_grid(&self.prob, index, self.grid, h)
            }
        }
    }

    /// Fits (and RSS, trace where every point is Ok) for each bandwidth, on the
    /// direct path (the fast path's ladders go through [`LagStep::ladder_cached`]),
    /// with `index` the KD-tree over this problem's index values.
    pub(super) fn ladder_direct(&self, index: &DirectIndex, hs: &[f64]) -> Vec<RungFit> {
        hs.iter()
            .map(|&h| {
                let f = direct::fit_grid(&self.prob, index, self.grid, h);
                let rt = f
                    .all_ok()
                    .then(|| direct::rss_trace(&self.prob, self.grid, &f));
                (f, rt)
            })
            .collect()
    }
}

/// What the f-steps at one bandwidth keep between alternations.
#[derive(Default)]
pub(super) struct StepCache {
    /// Left-hand sides of the local systems (fast path), at their own h.
    pub(super) systems: Option<LocalSystems>,
    /// Each row's interval over breakpoints(grid, [h]), with that h. Every grid point
    /// is among its breakpoints, so it also gives the residuals' grid cells at any h.
    pub(super) index: Option<(f64, Option<IntervalIndex>)>,
    /// The last GCV ladder's table.
    pub(super) ladder: Option<LadderCache>,
    /// The direct path's KD-tree over the index values U_t = x_(t-d), which do not
    /// change during a fit: built once.
    pub(super) direct: Option<DirectIndex>,
    /// The design's sums of the ladder's limit h -> infinity (`super::global`), built
    /// on first use (inner None: a singular design).
    pub(super) global: Option<Option<super::global::GlobalDesign>>,
}

impl StepCache {
    /// The index at bandwidth h (built now if the one kept is for another h; None
    /// when the intervals do not fit a u16).
    pub(super) fn index_for(
        &mut self,
        prob: &VcProblem,
        grid: &[f64],
        h: f64,
    ) -> Option<&IntervalIndex> {
        if self.index.as_ref().is_none_or(|(hi, _)| *hi != h) {
            // from the ladder's index when its breakpoints hold h's (read through a
            // table), else by searching
            let breaks = breakpoints(grid, &[h]);
            let ladder = self.ladder.as_ref().and_then(|l| l.index.as_ref());
            let index = match ladder.and_then(|l| l.coarsened(breaks.clone())) {
                Some(ix) => Some(ix),
                None => IntervalIndex::build(prob, breaks),
            };
            self.index = Some((h, index));
        }
        self.index.as_ref().and_then(|(_, ix)| ix.as_ref())
    }

    /// The direct path's KD-tree of `prob`'s index values (built on first use; every
    /// problem of one fit has the same series, delay and rows).
    pub(super) fn direct_index(&mut self, prob: &VcProblem) -> &DirectIndex {
        self.direct.get_or_insert_with(|| DirectIndex::build(prob))
    }

    /// Whatever index is kept, for the grid cells.
    pub(super) fn any_index(&self) -> Option<&IntervalIndex> {
        self.index.as_ref().and_then(|(_, ix)| ix.as_ref())
    }
}

/// [`residuals`], with the grid cells from `index` when there is one.
pub(super) fn residuals_at(
    x: Centred,
    d: usize,
    grid: &[f64],
    (coef, b): (&GridFit, &[f64]),
    e: &mut [f64],
    index: Option<&IntervalIndex>,
) {
    match index {
        Some(ix) => residuals_indexed(x, d, grid, coef, b, e, ix),
        None => residuals(x, d, grid, coef, b, e),
    }
}

/// The lag index's smoother under the alternation: its grid, its caches (kept from one
/// f-step to the next) and its b-step, by Gauss-Newton (`Init::Arma`) or the paper's
/// least-squares step (`Init::Literal`), as the module doc of [`super`] describes.
pub(super) struct LagSmoother<'a> {
    x: Centred<'a>,
    grid: &'a [f64],
    /// (p, q, d) and the first row max(p, q, d).
    pqd: (usize, usize, usize),
    pp: usize,
    path: FitPath,
    init: Init,
    /// The index values' extremes (xmin, xmax) and their range.
    span: (f64, f64),
    range: f64,
    /// Whether --bandwidth fixed the bandwidth (for the message of a grid without fits).
    fixed: bool,
    /// Whether GCV may choose the ladder's limit h -> infinity (`super::global`).
    limit: bool,
    pub(super) cache: StepCache,
    /// `Init::Literal`: (first alternation, its least-squares b, alternations) where the
    /// least-squares b was not invertible and the previous b was kept.
    not_invertible_kept: Option<(usize, Vec<f64>, usize)>,
}

impl<'a> LagSmoother<'a> {
    /// The smoother of series `x` (centred, extremes `span`) on `grid`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        x: Centred<'a>,
        grid: &'a [f64],
        (p, q, d): (usize, usize, usize),
        path: FitPath,
        init: Init,
        span: (f64, f64),
        (fixed, limit): (bool, bool),
    ) -> Self {
        LagSmoother {
            x,
            grid,
            pqd: (p, q, d),
            pp: p.max(q).max(d),
            path,
            init,
            span,
            range: span.1 - span.0,
            fixed,
            limit,
            cache: StepCache::default(),
            not_invertible_kept: None,
        }
    }

    /// The f-step machinery at residuals `e` and MA coefficients `b`.
    pub(super) fn step<'s>(&self, e: &'s [f64], b: &'s [f64]) -> LagStep<'s>
    where
        'a: 's,
    {
        let (p, _, d) = self.pqd;
        LagStep::new(self.x, e, b, (p, d), self.grid, self.path, self.span)
    }
}

impl Smoother for LagSmoother<'_> {
    type H = f64;
    type Coef = GridFit;
    const WORDS: BandwidthWords = BandwidthWords {
        noun: "bandwidth",
        pronoun: "it",
        verb: "is",
        fixed_by: "--bandwidth",
    };
    const RECHECK_TABLE_AT_MAX_ITER: bool = true;

    fn fmt_h(h: f64) -> String {
        format!("{h:.6e}")
    }

    fn select(&mut self, e: &[f64], b: &[f64]) -> Selection<Self> {
        let sm = self.step(e, b);
        let (rows, mut fits, best, extended, notes) =
            gcv_select(&sm, self.range, &mut self.cache, self.limit);
        Selection {
            h: rows[best].bandwidth,
            fit: fits.swap_remove(best),
            rows,
            extended,
            notes,
        }
    }

    /// The next f-steps' left-hand sides, from the ladder's table (they depend on X
    /// and U only).
    fn chose(&mut self, h: f64) {
        if let Some(lad) = self.cache.ladder.as_ref().filter(|_| h.is_finite()) {
            self.cache.systems = Some(lad.systems_at(self.grid, h));
        }
    }

    /// At h = +inf the global fit (`super::global`), a grid without fits when its
    /// design is singular.
    fn fit_at(&mut self, e: &[f64], b: &[f64], h: f64) -> GridFit {
        let sm = self.step(e, b);
        if h.is_infinite() {
            return match sm.limit_fit(&mut self.cache) {
                Some((fit, _)) => fit,
                None => {
                    let mut fit = GridFit::new(self.grid.len(), self.pqd.0, h);
                    fit.status.fill(PointStatus::Singular);
                    fit
                }
            };
        }
        sm.fit_at(h, &mut self.cache)
    }

    fn combine(old: &GridFit, new: &GridFit, (al, be): (f64, f64)) -> GridFit {
        let mut out = new.clone();
        super::combine_f(&old.f, &new.f, old.p, (al, be), &mut out.f);
        super::combine_slopes(&old.slope, &new.slope, al + be, &mut out.slope);
        out
    }

    fn fill(&self, coef: &mut GridFit, h: f64) -> Result<Vec<bool>> {
        let (grid, range) = (self.grid, self.range);
        fill_failed(coef, grid).ok_or_else(|| {
            let fixed = if self.fixed {
                format!(
                    "a --bandwidth far from the index values' spread (they span {range:.6e}; the grid {:.6e}), ",
                    grid[grid.len() - 1] - grid[0]
                )
            } else {
                String::new()
            };
            Error::Data(format!(
                "no grid point has a local fit at bandwidth {h:.6e}: every local system is empty or singular: {fixed}too few distinct index values near each grid point (a quantised channel, or a spike that stretches the range; `farma prep` removes outliers), or regressors that are exactly dependent (a deterministic trend or sinusoid)"
            ))
        })
    }

    /// For Gauss-Newton the residual buffer first takes w_t = x_t - sum f_m(U_t)
    /// x_{t-m} (the old residuals are no longer needed), b is fitted to it by streaming
    /// passes, and the MA filter then turns w into the new residuals in place: one
    /// N-long vector in all.
    fn b_step(
        &mut self,
        coef: &GridFit,
        h: f64,
        (b, b_resp): (&mut Vec<f64>, &mut Vec<f64>),
        e: &mut [f64],
        iteration: usize,
    ) -> Option<f64> {
        let (x, grid, pp) = (self.x, self.grid, self.pp);
        let (p, q, d) = self.pqd;
        if q > 0 && self.init == Init::Arma {
            let index = self
                .cache
                .index_for(&VcProblem::new(x, e, b_resp, p, d), grid, h);
            let w_into = |buf: &mut [f64]| residuals_at(x, d, grid, (coef, &[]), buf, index);
            // one pass: w, the residuals at b_resp and the Gauss-Newton sums there,
            // chunk by chunk; with a small step the iterate is (f, b_resp), its
            // residuals in hand, and the step goes into the next f-step's response
            // (q > 2: no one-pass step; w written in place for ma_step)
            let filler = index
                .filter(|_| q <= 2)
                .and_then(|ix| w_indexed_filler(x, d, grid, coef, ix));
            let fill = filler.as_ref().map(|f| f as &SpanFill<'_>);
            if fill.is_none() {
                w_into(e);
            }
            // (the iterate's b, the next response's b, the iterate's RSS)
            let (b_iter, b_next, rss_iter) = match gn_b_step(e, pp, b_resp, fill, w_into) {
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
                    w_into(e);
                    let (b_new, rss_new) = ma_step_from(e, pp, b_resp, (rss_b, b_next), w_into);
                    (b_new.clone(), b_new, rss_new)
                }
                // q > 2: ma_step's own passes on w
                None => {
                    let (b_new, rss_new) = ma_step(e, pp, b_resp, w_into);
                    (b_new.clone(), b_new, rss_new)
                }
            };
            *b = b_iter;
            *b_resp = b_next;
            return Some(rss_iter);
        }
        if q > 0 {
            // the paper's step: least squares of w_t on the previous residuals
            let lookup = IntervalLookup::new(grid);
            let mut f = vec![0.0; p];
            let mut ata = vec![0.0; q * q];
            let mut aty = vec![0.0; q];
            for t in pp..x.len() {
                eval_with(coef, grid, &lookup, x.at(t - d), &mut f);
                let mut w = x.at(t);
                for m in 0..p {
                    w -= f[m] * x.at(t - m - 1);
                }
                for i in 0..q {
                    for j in 0..q {
                        ata[i * q + j] += e[t - i - 1] * e[t - j - 1];
                    }
                    aty[i] += e[t - i - 1] * w;
                }
            }
            // a b that is not invertible makes the residual recursion grow without
            // bound: the previous b is kept (as the Gauss-Newton step's check does
            // for `Init::Arma`)
            match normal_equations(&ata, &aty, q) {
                Some(b_ls) if ma_invertible(&b_ls) => *b = b_ls,
                Some(b_ls) => {
                    let kept = self.not_invertible_kept.get_or_insert((iteration, b_ls, 0));
                    kept.2 += 1;
                }
                None => {}
            }
        }
        None
    }

    fn residuals(&mut self, coef: &GridFit, b: &[f64], e: &mut [f64]) -> f64 {
        let d = self.pqd.2;
        residuals_at(self.x, d, self.grid, (coef, b), e, self.cache.any_index());
        rss_from(e, self.pp)
    }

    fn end_notes(&mut self, _: &Alternation<Self>) -> Vec<String> {
        self.not_invertible_kept
            .take()
            .map(|(first, b_ls, times)| {
                format!(
                    "the least-squares b was not invertible in {times} alternation(s) (first in alternation {first}: {b_ls:?}); the previous b was kept each time"
                )
            })
            .into_iter()
            .collect()
    }
}
