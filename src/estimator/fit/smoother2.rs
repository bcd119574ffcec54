//! The 2-D index's smoother under the alternation ([`super::alternate`]), its fit
//! ([`fit2`]: data checks, grid, linear start, the alternation, the returned model's
//! trace and standard errors; a [`Farma`] whose coefficients are on the 2-D grid, and
//! a [`FitReport2`]); its parameters and their checks are in `params.rs`
//! ([`Farma2Params`], [`check_fit2`]).
//!
//! - Bandwidths: GCV over a common scaled ladder h_j = 1.1^-j (range_1/2, range_2/2),
//!   j = 0..20 (the paper's rule applied to each coordinate's range with one j), so
//!   the box is a square in scaled units and the Chebyshev gather fetches nothing
//!   outside it; the ladder is extended while the minimum sits at an end, as in 1-D.
//!   A fixed pair (h_1, h_2) can be given instead.
//! - Start: a linear ARMA(p,q) by conditional least squares on every sample
//!   ([`fit_arma`]), constant f_m = a_m.
//! - b-step: least squares of w_t = x_t - sum f_m(U_t) x_{t-m} on its own MA
//!   recursion ([`ma_cls`]: Gauss-Newton with step halving, from the previous b); the
//!   residuals are then recomputed with that b.
//! - The rest is the alternation's (GCV on the first f-step and again each time the
//!   RSS settles, at most twice; the [`super::PATIENCE`] rule; the stop at residuals
//!   that are not finite; the iterate of least RSS returned, the linear start
//!   included, with the linear model's trace p and standard errors). A fit whose
//!   bandwidths GCV changed and that then runs to `max_iter` gets a note of its own.

use super::bstep::ma_cls;
use super::grid2::{
    Grid2, Grid2Fit, Index2, Vc2Problem, fill_failed2, fit_grid2, residuals2, rss_trace2,
    se_factors2,
};
use super::notes::{ma_edge_note, missing_se_note, stretched_ladder_note, undefined_trace_note};
use super::params::{Farma2Params, FitPath, Init, check_fit2, check_magnitude, range_of};
use super::start::linear_se_factors;
use super::{
    Alternation, BandwidthWords, Control, Ended, Iterate, Selection, Smoother, alternate,
    mix_parts, start_mix,
};
use crate::error::{Error, Result};
use crate::estimator::arma::fit_arma;
use crate::estimator::problem::PointStatus;
use crate::estimator::series::Centred;
use crate::model::report::{FitReport2, FitTimings, GcvRow};
use crate::model::{Coef, Farma, Order, SecondIndex};

fn quantile_pair(mut v: Vec<f64>, (lo, hi): (f64, f64)) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    let q = |q: f64| {
        let pos = q * (v.len() - 1) as f64;
        let (i, frac) = (pos.floor() as usize, pos - pos.floor());
        if i + 1 < v.len() {
            v[i] + frac * (v[i + 1] - v[i])
        } else {
            v[i]
        }
    };
    (q(lo), q(hi))
}

/// The f-step machinery at one alternation's residuals and MA coefficients.
struct Step2<'a> {
    prob: Vc2Problem<'a>,
    grid: &'a Grid2,
    index: &'a Index2,
}

impl Step2<'_> {
    fn at(&self, h: (f64, f64)) -> (Grid2Fit, Option<(f64, f64)>) {
        let f = fit_grid2(&self.prob, self.index, self.grid, h);
        let rt = f.all_ok().then(|| rss_trace2(&self.prob, self.grid, &f));
        (f, rt)
    }
}

/// RSS of the rows from `start` on, summed in order.
fn rss_of(e: &[f64], start: usize) -> f64 {
    e[start..].iter().map(|v| v * v).sum::<f64>()
}

#[cfg(test)]
thread_local! {
    /// Test hook: the residual pass of the alternation with this number (1 the first)
    /// leaves its first residual NaN (the recursion would carry it to every later one,
    /// as an overflow does).
    pub(super) static NAN_RESIDUALS_AT: std::cell::Cell<Option<usize>> =
        const { std::cell::Cell::new(None) };
}

/// The 2-D index's smoother under the alternation: its grid, the KD-tree of its index
/// values (which do not change during a fit) and its b-step, least squares of w on its
/// own residual recursion ([`ma_cls`], Gauss-Newton with step halving).
struct Index2Smoother<'a> {
    /// The series, index channel, shape and first row (no residuals, no b).
    prob0: Vc2Problem<'a>,
    grid: &'a Grid2,
    index: &'a Index2,
    /// Half the range of each coordinate: the ladder's scale and the fill's distance.
    half: (f64, f64),
    q: usize,
    #[cfg(test)]
    residual_passes: usize,
}

impl<'a> Index2Smoother<'a> {
    fn step<'s>(&self, e: &'s [f64], b: &'s [f64]) -> Step2<'s>
    where
        'a: 's,
    {
        Step2 {
            prob: Vc2Problem { e, b, ..self.prob0 },
            grid: self.grid,
            index: self.index,
        }
    }
}

impl Smoother for Index2Smoother<'_> {
    type H = (f64, f64);
    type Coef = Grid2Fit;
    const WORDS: BandwidthWords = BandwidthWords {
        noun: "bandwidths",
        pronoun: "them",
        verb: "are",
        fixed_by: "--bandwidth and --bandwidth2",
    };
    const RECHECK_TABLE_AT_MAX_ITER: bool = false;

    fn fmt_h(h: (f64, f64)) -> String {
        format!("({:.6e}, {:.6e})", h.0, h.1)
    }

    fn select(&mut self, e: &[f64], b: &[f64]) -> Selection<Self> {
        let (rows, fit, h, extended, notes) = gcv_select2(&self.step(e, b), self.half);
        Selection {
            h,
            fit,
            rows,
            extended,
            notes,
        }
    }

    fn fit_at(&mut self, e: &[f64], b: &[f64], h: (f64, f64)) -> Grid2Fit {
        let step = self.step(e, b);
        fit_grid2(&step.prob, self.index, self.grid, h)
    }

    fn combine(old: &Grid2Fit, new: &Grid2Fit, (al, be): (f64, f64)) -> Grid2Fit {
        let mut out = new.clone();
        super::combine_f(&old.f, &new.f, old.p, (al, be), &mut out.f);
        super::combine_slopes(&old.slope1, &new.slope1, al + be, &mut out.slope1);
        super::combine_slopes(&old.slope2, &new.slope2, al + be, &mut out.slope2);
        out
    }

    fn fill(&self, coef: &mut Grid2Fit, h: (f64, f64)) -> Result<Vec<bool>> {
        fill_failed2(coef, self.grid, self.half).ok_or_else(|| {
            Error::Data(format!(
                "no grid point has a local fit at bandwidths ({:.6e}, {:.6e}): every local system is empty or singular: bandwidths far from the index values' spread, too few distinct index values near each grid point (a quantised channel, or a spike that stretches the range; `farma prep` removes outliers), or regressors that are exactly dependent (an index channel that copies a lag of the channel, a deterministic trend)",
                h.0, h.1
            ))
        })
    }

    /// b minimises sum e_t^2 with e_t = w_t - sum b_m e_{t-m}, w_t = x_t - sum
    /// f_m(U_t) x_{t-m} ([`ma_cls`] from the previous b); the residuals are then
    /// recomputed ([`Smoother::residuals`]).
    fn b_step(
        &mut self,
        coef: &Grid2Fit,
        _h: (f64, f64),
        (b, _): (&mut Vec<f64>, &mut Vec<f64>),
        _e: &mut [f64],
        _iteration: usize,
    ) -> Option<f64> {
        if self.q > 0 {
            let pr = &self.prob0;
            let mut w = vec![0.0; pr.x.len()];
            residuals2(pr.x, pr.z, (pr.d, pr.d2), self.grid, coef, &[], &mut w);
            *b = ma_cls(&w, pr.start, b);
        }
        None
    }

    fn residuals(&mut self, coef: &Grid2Fit, b: &[f64], e: &mut [f64]) -> f64 {
        let pr = &self.prob0;
        residuals2(pr.x, pr.z, (pr.d, pr.d2), self.grid, coef, b, e);
        #[cfg(test)]
        {
            self.residual_passes += 1;
            if NAN_RESIDUALS_AT.get() == Some(self.residual_passes) {
                e[pr.start] = f64::NAN;
            }
        }
        rss_of(e, pr.start)
    }

    /// A fit whose bandwidths GCV changed and that then ran to `--max-iter` without
    /// settling again says so.
    fn end_notes(&mut self, alt: &Alternation<Self>) -> Vec<String> {
        if alt.ended != Ended::MaxIter || alt.chosen.len() < 2 {
            return Vec::new();
        }
        let (visited, h) = (&alt.chosen, alt.h);
        let swing = visited[..visited.len() - 1].contains(&h);
        vec![format!(
            "NOT converged: after {} bandwidth re-selection(s) the alternation did not settle again within --max-iter {} alternations; the model is at bandwidths {}, GCV's last choice{}",
            visited.len() - 1,
            alt.iterations,
            Self::fmt_h(h),
            if swing {
                format!(
                    "; GCV swung back and forth ({}): fix the pair with --bandwidth H1 --bandwidth2 H2, or raise --max-iter",
                    visited
                        .iter()
                        .map(|v| Self::fmt_h(*v))
                        .collect::<Vec<_>>()
                        .join(" -> ")
                )
            } else {
                String::new()
            }
        )]
    }
}

/// The chosen row's bandwidth pair.
fn pair(r: &GcvRow) -> (f64, f64) {
    (r.bandwidth, r.bandwidth2.expect("a row of a 2-D ladder"))
}

/// GCV over the common scaled ladder, extended while the minimum sits at an end: the
/// table, the chosen rung's fit and bandwidths, whether the ladder was extended, notes.
fn gcv_select2(
    sm: &Step2,
    half: (f64, f64),
) -> (Vec<GcvRow>, Grid2Fit, (f64, f64), bool, Vec<String>) {
    let m = sm.prob.n_rows() as f64;
    let mut rows: Vec<GcvRow> = Vec::new();
    let mut fits: Vec<Grid2Fit> = Vec::new();
    let mut notes = Vec::new();
    let mut extended = false;
    let mut js: Vec<i32> = (0..=20).collect();
    loop {
        for &j in &js {
            if rows.iter().any(|r| r.j == j) {
                continue;
            }
            let s = 1.1f64.powi(-j);
            let h = (s * half.0, s * half.1);
            let (f, rt) = sm.at(h);
            let n_failed = f.status.iter().filter(|s| **s != PointStatus::Ok).count();
            let row = match rt {
                Some((rss, tr)) if tr < m => GcvRow {
                    j,
                    bandwidth: h.0,
                    bandwidth2: Some(h.1),
                    rss,
                    trace: tr,
                    gcv: (rss / m) / (1.0 - tr / m).powi(2),
                    n_failed,
                },
                _ => GcvRow {
                    j,
                    bandwidth: h.0,
                    bandwidth2: Some(h.1),
                    rss: f64::NAN,
                    trace: f64::NAN,
                    gcv: f64::INFINITY,
                    n_failed,
                },
            };
            rows.push(row);
            fits.push(f);
        }
        let mut order: Vec<usize> = (0..rows.len()).collect();
        order.sort_by_key(|k| rows[*k].j);
        rows = order.iter().map(|k| rows[*k].clone()).collect();
        fits = order.iter().map(|k| fits[*k].clone()).collect();
        let best = rows
            .iter()
            .enumerate()
            .filter(|(_, r)| r.gcv.is_finite())
            .min_by(|a, b| a.1.gcv.total_cmp(&b.1.gcv))
            .map(|(i, _)| i);
        let last = rows.len() - 1;
        match best {
            Some(i) if i == last && rows[last].j < 60 => {
                let next = rows[last].j + 1;
                notes.push(format!(
                    "GCV minimum at the smallest bandwidths of the ladder (j = {}): extended to j = {}",
                    rows[last].j,
                    next + 9
                ));
                js = (next..next + 10).collect();
                extended = true;
            }
            // the minimum at the largest bandwidths, or no pair that fits every grid
            // point: wider bandwidths
            Some(0) | None if rows[0].j > -10 => {
                let first = rows[0].j;
                notes.push(if best.is_some() {
                    format!(
                        "GCV minimum at the largest bandwidths of the ladder (j = {first}): extended upwards"
                    )
                } else {
                    format!(
                        "GCV: no bandwidth pair of the ladder from j = {first} down gives a fit at every grid point: extended upwards"
                    )
                });
                js = (first - 5..first).collect();
                extended = true;
            }
            Some(i) => {
                if i == 0 || i == last {
                    // at an end no further extension reaches (as in 1-D)
                    notes.push(format!(
                        "GCV minimum at the {} bandwidths h_j (j = {}), the end of the ladder's extensions: the optimum may lie beyond it",
                        if i == 0 { "largest" } else { "smallest" },
                        rows[i].j
                    ));
                }
                let (f, h) = (fits.swap_remove(i), pair(&rows[i]));
                return (rows, f, h, extended, notes);
            }
            None => {
                notes.push(
                    "GCV: no bandwidth pair of the ladder gives a fit at every grid point: the one with the fewest grid points without a fit is used (its GCV is not defined)".into(),
                );
                let i = rows
                    .iter()
                    .enumerate()
                    .min_by_key(|(_, r)| r.n_failed)
                    .map(|(i, _)| i)
                    .unwrap_or(0);
                let (f, h) = (fits.swap_remove(i), pair(&rows[i]));
                return (rows, f, h, extended, notes);
            }
        }
    }
}

/// Fits a FARMA model whose f_m depend on (x_{t-d}, z_{t-d2}): the model, its grid
/// centred in x (`grid_shift` 0) and in z's units, and the fit's report.
pub fn fit2(series: &[f64], z: &[f64], params: &Farma2Params) -> Result<(Farma, FitReport2)> {
    let prm = &params.base;
    let (p, q, d, d2) = (prm.p, prm.q, prm.d, params.d2);
    let n = series.len();
    let bad = |m: String| Err(Error::Usage(m));
    if z.len() != n {
        return bad("the index channel and the series differ in length".into());
    }
    check_fit2(n, z, params)?;
    let pp = p.max(q).max(d).max(d2);
    let mean = if prm.demean {
        series.iter().sum::<f64>() / n as f64
    } else {
        0.0
    };
    let x: Vec<f64> = series.iter().map(|v| v - mean).collect();
    if x.iter().any(|v| !v.is_finite()) {
        return bad("the channel holds NaN or infinite values".into());
    }
    let (x_lo, x_hi) = range_of(&x);
    let (z_lo, z_hi) = range_of(z);
    let range = (x_hi - x_lo, z_hi - z_lo);
    if range.0 <= 0.0 {
        return bad("the channel is constant: nothing to fit".into());
    }
    if range.1 <= 0.0 {
        return bad("the index channel is constant: it cannot index anything".into());
    }
    // the 2-D fit sums squares of the values and of their products with the index
    // offsets (z - c), as the direct path does
    check_magnitude("the channel", x_lo, x_hi, FitPath::Direct).map_err(Error::Data)?;
    check_magnitude(
        "the index channel's spread (max - min)",
        0.0,
        range.1,
        FitPath::Direct,
    )
    .map_err(Error::Data)?;
    let half = (range.0 / 2.0, range.1 / 2.0);
    let q1 = quantile_pair((pp..n).map(|t| x[t - d]).collect(), prm.grid_quantiles);
    let q2 = quantile_pair((pp..n).map(|t| z[t - d2]).collect(), prm.grid_quantiles);
    if q1.1 <= q1.0 || q2.1 <= q2.0 {
        return bad(
            "an index coordinate takes one value over its central quantiles: no grid to fit on"
                .into(),
        );
    }
    let uni = |(lo, hi): (f64, f64), g: usize| -> Vec<f64> {
        (0..g)
            .map(|k| lo + (hi - lo) * k as f64 / (g - 1) as f64)
            .collect()
    };
    let grid = Grid2 {
        g1: uni(q1, params.grid.0),
        g2: uni(q2, params.grid.1),
    };
    let gl = grid.len();

    // 1. start: linear ARMA(p,q)
    let arma = fit_arma(&x, p, q)
        .ok_or_else(|| Error::Data("the linear ARMA start failed (singular design)".into()))?;
    let b = arma.ma;
    let mut coef = Grid2Fit::new(gl, p, (f64::NAN, f64::NAN));
    for g in 0..gl {
        coef.status[g] = PointStatus::Ok;
        coef.f[g * p..(g + 1) * p].copy_from_slice(&arma.ar);
        // constant f_m: slopes 0 (no local system), as the note of a returned start says
        coef.slope1[g * p..(g + 1) * p].fill(0.0);
        coef.slope2[g * p..(g + 1) * p].fill(0.0);
    }
    // the index values do not change during the alternation: one tree
    let prob0 = Vc2Problem {
        x: &x,
        z,
        e: &[],
        b: &[],
        p,
        d,
        d2,
        start: pp,
    };
    let index = Index2::build(&prob0, half);
    let mut sm = Index2Smoother {
        prob0,
        grid: &grid,
        index: &index,
        half,
        q,
        #[cfg(test)]
        residual_passes: 0,
    };
    let mut e = vec![0.0; n];
    residuals2(&x, z, (d, d2), &grid, &coef, &b, &mut e);
    let rss = rss_of(&e, pp);
    let mut notes = Vec::new();
    if params.bandwidth.is_none() {
        notes.extend(stretched_ladder_note(
            &format!("the index values x_(t-{d}) (less the channel's mean)"),
            (x_lo, x_hi),
            q1,
            prm.grid_quantiles,
        ));
        notes.extend(stretched_ladder_note(
            &format!("the index channel's values (lag {d2})"),
            (z_lo, z_hi),
            q2,
            prm.grid_quantiles,
        ));
    }
    let start = Iterate {
        index: 0,
        rss,
        coef,
        b,
        h: (f64::NAN, f64::NAN),
        filled: vec![false; gl],
        mix: start_mix(),
    };
    let ctl = Control {
        p,
        q,
        max_iter: prm.max_iter,
        tol: prm.tol,
        bandwidth: params.bandwidth,
        start: pp,
    };
    let alt = alternate(&mut sm, &ctl, start, e, notes)?;
    let (coef, b, e, rss, h) = (alt.coef, alt.b, alt.e, alt.rss, alt.h);
    let (filled, gcv_table, mut notes) = (alt.filled, alt.gcv_table, alt.notes);
    let (ladder_extended, iterations, converged) =
        (alt.ladder_extended, alt.iterations, alt.converged);
    let (rss_history, returned_start) = (alt.rss_history, alt.returned_start);
    let (returned_start_reason, mix) = (alt.returned_start_reason, alt.mix);
    let m = (n - pp) as f64;
    let sigma2 = rss / m;
    // the returned model's trace, GCV (from its own RSS, as the 1-D fit's) and standard
    // errors
    let prob = Vc2Problem {
        e: &e,
        b: &b,
        ..prob0
    };
    let step = Step2 {
        prob,
        grid: &grid,
        index: &index,
    };
    // each smoother the returned f combines (one unless a damped f-step mixed them:
    // module doc): its trace and standard-error factors; the status and condition
    // numbers are those of the local fits at the returned bandwidths
    let (mut status, mut cond) = (coef.status.clone(), coef.cond.clone());
    let mut part = |at: Option<(f64, f64)>| -> (Option<f64>, Vec<f64>) {
        match at {
            // the linear model with constant f_m (as the 1-D fit's)
            None => (
                Some(p as f64),
                linear_se_factors(Centred::plain(&x), p, pp).repeat(gl),
            ),
            Some(hh) => {
                let (final_fit, rt) = step.at(hh);
                let factors = se_factors2(&prob, &index, &grid, &final_fit);
                if hh == h {
                    (status, cond) = (final_fit.status, final_fit.cond);
                }
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
        let at = format!("bandwidths ({:.6e}, {:.6e})", h.0, h.1);
        notes.push(undefined_trace_note(&status, &at));
    }
    let gcv = (rss / m) / (1.0 - trace / m).powi(2);
    let se: Vec<f64> = factors.iter().map(|f| f * sigma2.sqrt()).collect();
    notes.extend(missing_se_note(&status, &cond, &se, p));
    notes.extend(ma_edge_note(&b));
    let n_filled = filled.iter().filter(|f| **f).count();
    if n_filled > 0 {
        notes.push(format!(
            "{n_filled} grid point(s) without a local fit were filled from the nearest point with one (see status)"
        ));
    }
    let model = Farma {
        order: Order::new(p, q, d),
        mean,
        b,
        sigma2,
        bandwidth: h.0,
        coef: Coef {
            grid: grid.g1,
            grid_shift: 0.0,
            f: coef.f.clone(),
            se,
            filled,
            second: Some(SecondIndex {
                channel: params.index2.clone(),
                lag: d2,
                grid: grid.g2,
                bandwidth: h.1,
            }),
        },
    };
    let report = FitReport2 {
        local: coef,
        rss,
        trace,
        gcv,
        gcv_table,
        ladder_extended,
        iterations,
        converged,
        rss_history,
        init: Init::Arma,
        path: FitPath::Direct,
        n,
        n_rows: n - pp,
        residuals: e,
        linear_start: returned_start,
        returned_start_reason,
        notes,
        timings: FitTimings::default(),
    };
    Ok((model, report))
}
