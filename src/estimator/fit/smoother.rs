//! The f-step's smoother on the lag index U_t = x_{t-d}: local-linear Biweight fits at
//! the grid points by either path (moment tables or KD-tree gathers), with the caches
//! an alternation keeps between its steps.

use super::gcv::{LadderCache, RungFit};
use super::params::FitPath;
use super::passes::{residuals, residuals_indexed};
use crate::estimator::direct;
use crate::estimator::direct::DirectIndex;
use crate::estimator::moments::Families;
use crate::estimator::moments::IntervalIndex;
use crate::estimator::moments::LocalSystems;
use crate::estimator::moments::MomentTable;
use crate::estimator::moments::breakpoints;
use crate::estimator::problem::GridFit;
use crate::estimator::problem::PointStatus;
use crate::estimator::problem::VcProblem;

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
pub(super) struct Smoother<'a> {
    pub(super) prob: VcProblem<'a>,
    pub(super) grid: &'a [f64],
    pub(super) path: FitPath,
    pub(super) umin: f64,
    pub(super) umax: f64,
}

impl<'a> Smoother<'a> {
    /// The smoother for series `x`, residuals `e`, MA coefficients `b`, shape
    /// (p, d) (first row max(p, q, d)), on `grid`, with index values in `span`.
    pub(super) fn new(
        x: &'a [f64],
        e: &'a [f64],
        b: &'a [f64],
        (p, d): (usize, usize),
        grid: &'a [f64],
        path: FitPath,
        (umin, umax): (f64, f64),
    ) -> Self {
        let prob = VcProblem::new(x, e, b, p, d);
        Smoother {
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
    /// direct path (the fast path's ladders go through [`Smoother::ladder_cached`]),
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
    x: &[f64],
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
