//! The bandwidth choice: GCV over the ladder h_j = 1.1^-j range/2, extended while the
//! minimum sits at an end. A rung where some grid point has no local fit has no GCV
//! (infinite): the ladder's bottom is where the local systems lose their support, and
//! a minimum right above it says so in a note. At the top, the ladder's limit h ->
//! infinity (the global fit, f_m linear in the index: [`super::global`]) is evaluated
//! directly when the minimum sits at the largest rung: it is chosen when its GCV is
//! lower, and the ladder is extended upwards only when it is not (the optimum then
//! lies between).

use super::global::GlobalDesign;
use super::params::FitPath;
use super::smoother::{LagStep, StepCache};
use crate::estimator::moments::Families;
use crate::estimator::moments::IntervalIndex;
use crate::estimator::moments::LocalSystems;
use crate::estimator::moments::MomentTable;
use crate::estimator::moments::breakpoints;
use crate::estimator::problem::GridFit;
use crate::estimator::problem::PointStatus;
use crate::model::report::GcvRow;

/// The ladder's bandwidth h_j = 1.1^-j range/2.
pub(super) fn ladder_h(j: i32, range: f64) -> f64 {
    1.1f64.powi(-j) * range / 2.0
}

/// Rungs a ladder table is built for beyond the smallest bandwidth asked, so that the
/// usual extensions (10 rungs each, when the GCV minimum is at the smallest) need no
/// new pass: 10 up to 1e6 rows, and 10 more for every decade beyond (or part of one).
/// The bandwidth GCV chooses shrinks with N (as N^(-1/5) for the error-optimal one of
/// a local-linear fit, Fan and Gijbels 1996, sec. 3.2: about 5 rungs of 1.1 per
/// decade); on the bench's FARMA(2,1,1) series it moved faster, h_26, h_33 and h_40 at
/// 1e6, 1e7 and 1e8 rows, the last after the extensions to j = 30, 40 and 50. With 10
/// rungs ahead the 1e7 and 1e8 fits built their ladder's table twice.
pub(super) fn ladder_ahead(n_rows: usize) -> i32 {
    let decades = (n_rows as f64 / 1e6).log10().max(0.0);
    10 * (1 + decades.ceil() as i32)
}

/// A ladder rung's fit, with its RSS and trace when every grid point has a fit.
pub(super) type RungFit = (GridFit, Option<(f64, f64)>);

/// A GCV ladder's moment table (fast path): every family over the breakpoints of the
/// rungs `js`, and each row's interval. The next ladder (the re-check after
/// convergence: the same X and U, new residuals) sums only the families that hold y.
pub(super) struct LadderCache {
    pub(super) js: (i32, i32),
    pub(super) table: MomentTable,
    pub(super) index: Option<IntervalIndex>,
    /// Fits (and RSS, trace) at the rungs of `js` asked for so far (index j - js.0),
    /// from the table as it is now.
    pub(super) fits: Vec<Option<RungFit>>,
    /// The left-hand sides of the rungs fitted on this table (index j - js.0): they
    /// depend on X and U only, so they outlive a refresh of the y families.
    pub(super) systems: Vec<Option<LocalSystems>>,
    /// The smoother's trace at those rungs (None: not every point fitted); it too
    /// depends on X and U only (a refreshed table keeps the design's families bit for
    /// bit, and the kept left-hand sides give the same inverses), so a refit on new
    /// residuals sums the RSS alone.
    pub(super) traces: Vec<Option<Option<f64>>>,
}

impl LadderCache {
    /// The left-hand sides at bandwidth h: those kept for its rung (the same bits as
    /// [`MomentTable::local_systems`]: a window grown from narrower ones has the bits
    /// of one summed alone), else computed from the table.
    pub(super) fn systems_at(&self, grid: &[f64], h: f64) -> LocalSystems {
        self.systems
            .iter()
            .flatten()
            .find(|s| s.h == h && s.grid() == grid)
            .cloned()
            .unwrap_or_else(|| self.table.local_systems(grid, h))
    }
}

/// The GCV table's rung of the limit h -> infinity: `j` is this (the rungs sort by
/// decreasing h as by increasing j), written as null in gcv.parquet.
pub const LIMIT_J: i32 = i32::MIN;

impl<'a> LagStep<'a> {
    /// The ladder's limit h -> infinity ([`super::global`]): the global fit in the
    /// local fits' form (bandwidth +inf) with its RSS and trace; None when its
    /// design is singular.
    /// The design's sums are kept in `cache` (X and U are the same for every f-step).
    pub(super) fn limit_fit(&self, cache: &mut StepCache) -> Option<RungFit> {
        if cache.global.is_none() {
            let centre_scale = ((self.umin + self.umax) / 2.0, (self.umax - self.umin) / 2.0);
            cache.global = Some(GlobalDesign::new(&self.prob, self.grid, centre_scale));
        }
        let g = cache
            .global
            .as_ref()
            .and_then(|d| d.as_ref())?
            .fit(&self.prob);
        Some((g.grid_fit(self.grid), Some((g.rss, g.trace))))
    }

    /// Fits (and RSS, trace) on the fast path for rungs `js`, through `cache`: a kept
    /// table covering them is brought up to date (`fresh`: it already is) with the
    /// y families only; otherwise one is built for the rungs plus [`ladder_ahead`].
    pub(super) fn ladder_cached(
        &self,
        js: &[i32],
        range: f64,
        cache: &mut StepCache,
        fresh: &mut bool,
    ) -> Vec<RungFit> {
        let (lo, hi) = (js[0], js[js.len() - 1]);
        let span = (self.umin, self.umax);
        let kept = cache.ladder.take().filter(|l| l.js.0 <= lo && l.js.1 >= hi);
        let lad = match kept {
            Some(l) if *fresh => l,
            Some(l) => LadderCache {
                table: l.table.into_response(&self.prob, l.index.as_ref(), span),
                fits: vec![None; l.fits.len()],
                ..l
            },
            None => {
                let ahead = ladder_ahead(self.prob.n_rows());
                let all: Vec<f64> = (lo..=hi + ahead).map(|j| ladder_h(j, range)).collect();
                let breaks = breakpoints(self.grid, &all);
                let index = IntervalIndex::build(&self.prob, breaks.clone());
                let table = MomentTable::build_over(
                    &self.prob,
                    index.as_ref(),
                    || breaks,
                    span,
                    6,
                    Families::All,
                );
                let rungs = (hi + ahead - lo + 1) as usize;
                LadderCache {
                    js: (lo, hi + ahead),
                    table,
                    index,
                    fits: vec![None; rungs],
                    systems: (0..rungs).map(|_| None).collect(),
                    traces: vec![None; rungs],
                }
            }
        };
        *fresh = true;
        // the rungs asked for and not fitted yet (a rung's fit has the same bits
        // whichever other rungs it is computed with: `MomentTable::fit_ladder`)
        let mut lad = lad;
        let missing: Vec<i32> = js
            .iter()
            .copied()
            .filter(|j| lad.fits[(j - lad.js.0) as usize].is_none())
            .collect();
        if !missing.is_empty() {
            use rayon::prelude::*;
            let table = &lad.table;
            // the left-hand sides kept from an earlier ladder on this table: only the
            // right-hand sides are summed (the same bits)
            let kept: Option<Vec<&LocalSystems>> = missing
                .iter()
                .map(|j| lad.systems[(j - lad.js.0) as usize].as_ref())
                .collect();
            let (fits, systems) = match kept {
                Some(sys) => (table.fit_ladder_response(&sys), None),
                None => {
                    let hs: Vec<f64> = missing.iter().map(|&j| ladder_h(j, range)).collect();
                    let (f, s) = table.fit_ladder_systems(self.grid, &hs);
                    (f, Some(s))
                }
            };
            // the traces known for these rungs (kept left-hand sides)
            let known: Vec<Option<Option<f64>>> = missing
                .iter()
                .map(|j| lad.traces[(j - lad.js.0) as usize])
                .collect();
            let fits: Vec<RungFit> = fits
                .into_par_iter()
                .zip(known)
                .map(|(f, known)| {
                    let rt = match known {
                        Some(tr) => tr.map(|tr| (table.rss(self.grid, &f), tr)),
                        None => f.all_ok().then(|| table.rss_trace(self.grid, &f)),
                    };
                    (f, rt)
                })
                .collect();
            for (j, fit) in missing.iter().zip(fits) {
                lad.traces[(j - lad.js.0) as usize] = Some(fit.1.map(|(_, tr)| tr));
                lad.fits[(j - lad.js.0) as usize] = Some(fit);
            }
            if let Some(systems) = systems {
                for (j, sys) in missing.iter().zip(systems) {
                    lad.systems[(j - lad.js.0) as usize] = Some(sys);
                }
            }
        }
        let out = js
            .iter()
            .map(|j| {
                lad.fits[(j - lad.js.0) as usize]
                    .clone()
                    .expect("fitted above")
            })
            .collect();
        cache.ladder = Some(lad);
        out
    }
}

/// A rung's GCV row from its fit (and RSS, trace): GCV infinite where a grid point
/// has no fit or the trace reaches the rows.
fn gcv_row(j: i32, h: f64, (f, rt): &RungFit, m: f64) -> GcvRow {
    let n_failed = f.status.iter().filter(|s| **s != PointStatus::Ok).count();
    match rt {
        Some((rss, tr)) if *tr < m => GcvRow {
            j,
            bandwidth: h,
            bandwidth2: None,
            rss: *rss,
            trace: *tr,
            gcv: (rss / m) / (1.0 - tr / m).powi(2),
            n_failed,
        },
        _ => GcvRow {
            j,
            bandwidth: h,
            bandwidth2: None,
            rss: f64::NAN,
            trace: f64::NAN,
            gcv: f64::INFINITY,
            n_failed,
        },
    }
}

/// GCV over the ladder, extended at either end while the minimum sits there; with
/// `limit`, the limit h -> infinity is evaluated when the minimum is at the largest
/// rung (module doc) and heads the table when it was. Returns (table sorted by
/// decreasing h, index of the minimum, extended?, notes).
pub(super) fn gcv_select(
    sm: &LagStep,
    range: f64,
    cache: &mut StepCache,
    limit: bool,
) -> (Vec<GcvRow>, Vec<GridFit>, usize, bool, Vec<String>) {
    let m = sm.prob.n_rows() as f64;
    // the limit's row and fit, once evaluated
    let mut at_limit: Option<(GcvRow, GridFit)> = None;
    let mut limit_tried = !limit;
    let mut js: Vec<i32> = (0..=20).collect();
    let mut notes = Vec::new();
    let mut extended = false;
    // whether the kept ladder table holds this smoother's residuals yet
    let mut fresh = false;
    // the direct path's rung fits so far: an extension fits only its new rungs
    let mut direct_fits: std::collections::BTreeMap<i32, RungFit> = Default::default();
    loop {
        let hs: Vec<f64> = js.iter().map(|j| ladder_h(*j, range)).collect();
        let fits = match sm.path {
            FitPath::Fast => sm.ladder_cached(&js, range, cache, &mut fresh),
            FitPath::Direct => {
                let new: Vec<i32> = js
                    .iter()
                    .copied()
                    .filter(|j| !direct_fits.contains_key(j))
                    .collect();
                let new_hs: Vec<f64> = new.iter().map(|j| ladder_h(*j, range)).collect();
                let index = cache.direct_index(&sm.prob);
                direct_fits.extend(new.into_iter().zip(sm.ladder_direct(index, &new_hs)));
                js.iter().map(|j| direct_fits[j].clone()).collect()
            }
        };
        let mut rows: Vec<GcvRow> = hs
            .iter()
            .zip(&fits)
            .zip(&js)
            .map(|((&h, fit), &j)| gcv_row(j, h, fit, m))
            .collect();
        let mut fits: Vec<RungFit> = fits;
        // the limit heads the table (index 0) once evaluated; `top` is the largest rung's
        let top = usize::from(at_limit.is_some());
        if let Some((row, fit)) = &at_limit {
            rows.insert(0, row.clone());
            fits.insert(0, (fit.clone(), None));
        }
        let best = rows
            .iter()
            .enumerate()
            .filter(|(_, r)| r.gcv.is_finite())
            .min_by(|a, b| a.1.gcv.total_cmp(&b.1.gcv))
            .map(|(i, _)| i);
        let last = rows.len() - 1;
        match best {
            // the minimum at the largest rung: the limit h -> infinity, once
            Some(i) if i == top && !limit_tried => {
                limit_tried = true;
                if let Some(fit) = sm.limit_fit(cache) {
                    let row = gcv_row(LIMIT_J, f64::INFINITY, &fit, m);
                    if row.gcv.is_finite() {
                        at_limit = Some((row, fit.0));
                    }
                }
                // the ladder's rungs are kept (their fits cached): the next round
                // compares them with the limit
            }
            Some(i) if i == last && js[last] < 80 && rows.len() < 120 => {
                let next = js[last] + 1;
                notes.push(format!(
                    "GCV minimum at the smallest bandwidth h_{} = {:.6e}: ladder extended to j = {}",
                    js[last],
                    rows[last].bandwidth,
                    next + 9
                ));
                js.extend(next..next + 10);
                extended = true;
            }
            // the minimum at the largest bandwidth, or no rung that fits every grid
            // point (a quantised channel whose levels are as far apart as the largest
            // bandwidth, say): wider bandwidths
            Some(i) if i == 0 && at_limit.is_some() => {
                let (lim, h0) = (&rows[0], &rows[1]);
                notes.push(format!(
                    "GCV minimum at the ladder's limit h -> infinity (the global fit, f_m linear in the index): GCV {:.9e} against {:.9e} at the largest bandwidth h_{} = {:.6e}; the trace is {:.4}",
                    lim.gcv, h0.gcv, h0.j, h0.bandwidth, lim.trace
                ));
                let fits: Vec<GridFit> = fits.into_iter().map(|(f, _)| f).collect();
                return (rows, fits, 0, extended, notes);
            }
            Some(i) if i == top && js[0] > -20 => {
                let first = js[0];
                notes.push(match &at_limit {
                    Some((lim, _)) => format!(
                        "GCV minimum at the largest bandwidth h_{first} = {:.6e}, below the limit h -> infinity's ({:.9e} against {:.9e}): ladder extended upwards",
                        rows[top].bandwidth, rows[top].gcv, lim.gcv
                    ),
                    None => format!(
                        "GCV minimum at the largest bandwidth h_{first} = {:.6e}: ladder extended upwards",
                        rows[top].bandwidth
                    ),
                });
                let mut more: Vec<i32> = (first - 5..first).collect();
                more.extend(js);
                js = more;
                extended = true;
            }
            None if js[0] > -20 => {
                let first = js[0];
                notes.push(format!(
                    "GCV: no bandwidth from h_{first} = {:.6e} down gives a fit at every grid point: ladder extended upwards",
                    rows[0].bandwidth
                ));
                let mut more: Vec<i32> = (first - 5..first).collect();
                more.extend(js);
                js = more;
                extended = true;
            }
            Some(i) => {
                if i == top || i == last {
                    // at an end no further extension reaches
                    notes.push(format!(
                        "GCV minimum at the {} bandwidth h_{} = {:.6e}, the end of the ladder's extensions: the optimum may lie beyond it",
                        if i == top { "largest" } else { "smallest" },
                        js[i],
                        rows[i].bandwidth
                    ));
                }
                if i < last && rows[i + 1].n_failed > 0 {
                    // the minimum at the edge of the local systems' support: the
                    // ladder stops there (a smaller bandwidth has no GCV)
                    notes.push(format!(
                        "GCV minimum at h_{} = {:.6e}, the smallest bandwidth with a local fit at every grid point: at h_{} = {:.6e} {} of {} grid points have none, so the ladder stops there (the optimum may lie below, where the local systems lose their support)",
                        js[i],
                        rows[i].bandwidth,
                        js[i + 1],
                        rows[i + 1].bandwidth,
                        rows[i + 1].n_failed,
                        sm.grid.len()
                    ));
                }
                let fits: Vec<GridFit> = fits.into_iter().map(|(f, _)| f).collect();
                return (rows, fits, i, extended, notes);
            }
            None => {
                notes.push(format!(
                    "GCV: no bandwidth of the ladder (h_{} = {:.6e} down to h_{} = {:.6e}) gives a fit at every grid point: the one with the fewest grid points without a fit is used (its GCV is not defined)",
                    js[0],
                    rows[0].bandwidth,
                    js[last],
                    rows[last].bandwidth
                ));
                let fits: Vec<GridFit> = fits.into_iter().map(|(f, _)| f).collect();
                // take the one with the fewest failed points, widest first
                let i = rows
                    .iter()
                    .enumerate()
                    .min_by_key(|(_, r)| r.n_failed)
                    .map(|(i, _)| i)
                    .unwrap_or(0);
                return (rows, fits, i, extended, notes);
            }
        }
    }
}
