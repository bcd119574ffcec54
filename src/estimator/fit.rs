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

use std::ops::Range;

use super::arma::{
    PassState, PassSums, arma_pass, arma_pass_into, fit_arma, lagged_normal, ma_invertible,
    ma_root_modulus, pass_rows,
};
use super::buffers;
use super::direct::{self, DirectIndex};
use super::linalg::{normal_equations, spd_solve_inverse};
use super::moments::{
    ABOVE_GRID, BELOW_GRID, Families, IntervalIndex, IntervalLookup, LocalSystems, MomentTable,
    breakpoints,
};
use super::problem::{GridFit, PointStatus, VcProblem};
use crate::error::{Error, Result};
use std::time::Instant;

/// How the alternation starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Init {
    /// Linear ARMA(p,q) by conditional least squares; b by Gauss-Newton in each b-step.
    Arma,
    /// The paper's literal scheme: AR(p) least squares, b = 0, b by one LS step.
    Literal,
}

/// Which computation gives the local fits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FitPath {
    /// One-pass exact moment tables (every bandwidth of the ladder at once).
    Fast,
    /// KD-tree gather and dense least squares per grid point and bandwidth.
    Direct,
}

/// Parameters of a fit; check them with [`FarmaParams::validate`].
#[derive(Clone, Debug)]
pub struct FarmaParams {
    pub p: usize,
    pub q: usize,
    pub d: usize,
    /// Grid points over the central quantiles of the index values.
    pub grid_size: usize,
    /// Quantiles of U_t the grid spans.
    pub grid_quantiles: (f64, f64),
    /// A fixed bandwidth instead of GCV.
    pub bandwidth: Option<f64>,
    pub init: Init,
    pub path: FitPath,
    pub max_iter: usize,
    /// Relative RSS change that ends the alternation.
    pub tol: f64,
    /// Subtract the mean before fitting (recorded in the model).
    pub demean: bool,
}

impl Default for FarmaParams {
    fn default() -> Self {
        FarmaParams {
            p: 2,
            q: 1,
            d: 1,
            grid_size: 201,
            grid_quantiles: (0.01, 0.99),
            bandwidth: None,
            init: Init::Arma,
            path: FitPath::Fast,
            max_iter: 50,
            tol: 1e-6,
            demean: true,
        }
    }
}

/// Parameters that passed validation for a series of `n` samples.
#[derive(Clone, Debug)]
pub struct ValidParams(FarmaParams);

/// Most grid points of a fit: each GCV rung sums, for every grid point, the cells of
/// its window, so the ladder's cost grows with the square of the grid (on a 2,000-
/// sample channel `farma fit` took 12.0 s with 2,001 grid points, 0.57 s with the
/// default 201; one run each, 2026-11-23).
pub const MAX_GRID: usize = 5000;

impl FarmaParams {
    /// Checks the parameters against a series of `n` samples.
    pub fn validate(self, n: usize) -> Result<ValidParams> {
        let bad = |m: String| Err(Error::Usage(m));
        if self.p == 0 || self.d == 0 {
            return bad(format!(
                "--order: p and d must be at least 1 (got p = {}, d = {})",
                self.p, self.d
            ));
        }
        if self.p > 6 || self.q > 6 || self.d > 1000 {
            return bad(format!(
                "--order: p, q at most 6 and d at most 1000 (got {},{},{})",
                self.p, self.q, self.d
            ));
        }
        if self.grid_size < 3 || self.grid_size > MAX_GRID {
            return bad(format!(
                "--grid: 3 to {MAX_GRID} points (got {}; a few hundred resolve the coefficient functions, and the GCV ladder's cost grows with the square of the grid)",
                self.grid_size
            ));
        }
        if self.tol.is_infinite() {
            return bad("--tol must be finite".into());
        }
        let (lo, hi) = self.grid_quantiles;
        if !(0.0..0.5).contains(&lo) || !(0.5..=1.0).contains(&hi) {
            return bad(format!(
                "grid quantiles ({lo}, {hi}) must satisfy 0 <= lo < 0.5 <= hi <= 1"
            ));
        }
        if let Some(h) = self.bandwidth
            && !(h.is_finite() && h > 0.0)
        {
            return bad(format!("--bandwidth: {h} is not a positive number"));
        }
        if self.tol.is_nan() || self.tol <= 0.0 || self.max_iter == 0 {
            return bad("--tol must be positive and --max-iter at least 1".into());
        }
        let pp = self.p.max(self.q).max(self.d);
        let need = (20 * (2 * self.p + self.q) + pp + 1).max(100);
        if n < need {
            return Err(Error::TooShort {
                what: format!("FARMA({},{},{}) fit", self.p, self.q, self.d),
                need: need as u64,
                have: n as u64,
            });
        }
        Ok(ValidParams(self))
    }
}

impl ValidParams {
    pub fn params(&self) -> &FarmaParams {
        &self.0
    }
}

/// One row of the GCV table.
#[derive(Clone, Debug, PartialEq)]
pub struct GcvRow {
    /// The rung: h_j = 1.1^-j range/2 (j = 0..20 the paper's ladder; below 0 and
    /// above 20 its extensions).
    pub j: i32,
    pub bandwidth: f64,
    pub rss: f64,
    pub trace: f64,
    /// (RSS/m) / (1 - tr/m)^2; infinite when some grid point has no fit.
    pub gcv: f64,
    /// Grid points without a fit at this bandwidth.
    pub n_failed: usize,
}

/// Wall-clock seconds of the steps of one alternation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AlternationTiming {
    /// The f-step: moment tables (or KD-tree gathers) and local solves, GCV excluded.
    pub f_step_s: f64,
    /// GCV ladders run in this alternation (the first one, and re-checks after
    /// convergence), tables and solves for every bandwidth included.
    pub gcv_s: f64,
    /// The b-step (Gauss-Newton or one least-squares step); on the Gauss-Newton path
    /// it ends with the residual recursion and the RSS ([`ma_step`]).
    pub b_step_s: f64,
    /// Residual recursion and RSS after a least-squares b-step (`Init::Literal`); 0 on
    /// the Gauss-Newton path, where the b-step holds them.
    pub residuals_s: f64,
}

impl AlternationTiming {
    pub fn total_s(&self) -> f64 {
        self.f_step_s + self.gcv_s + self.b_step_s + self.residuals_s
    }
}

/// Where the time of a fit went (wall clock, seconds), for benchmarks and logs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FitTimings {
    /// Mean, checks, range, quantiles, grid.
    pub prepare_s: f64,
    /// Linear ARMA start and the first residuals.
    pub start_s: f64,
    /// One entry per alternation.
    pub alternations: Vec<AlternationTiming>,
    /// Final fit, trace and standard errors at the chosen bandwidth.
    pub final_s: f64,
    pub total_s: f64,
}

/// A fitted FARMA model.
#[derive(Clone, Debug)]
pub struct FittedFarma {
    pub p: usize,
    pub q: usize,
    pub d: usize,
    /// Mean subtracted before fitting (0 without demeaning).
    pub mean: f64,
    pub grid: Vec<f64>,
    /// Local fits at the chosen bandwidth; failed points filled by interpolation.
    pub coef: GridFit,
    /// Pointwise standard error of f_m at the grid points (G x p), sigma times the
    /// sandwich factor; NaN at filled points. For a returned linear start, the
    /// least-squares standard error of the constant a_m with the MA part taken as a
    /// known offset, sigma sqrt([(X'X)^-1]_mm) with X the lagged values, at every
    /// grid point.
    pub se: Vec<f64>,
    /// Grid points whose f was filled from their neighbours (status not Ok).
    pub filled: Vec<bool>,
    pub b: Vec<f64>,
    pub bandwidth: f64,
    pub rss: f64,
    pub sigma2: f64,
    /// Trace of the smoother at the chosen bandwidth (effective degrees of freedom);
    /// p when the fit returned its linear start (constant f_m, see the module doc).
    pub trace: f64,
    /// GCV = (RSS/m) / (1 - trace/m)^2, m = N - max(p,q,d), of the returned model:
    /// its own RSS (`rss`) and the smoother's trace at its bandwidth (NaN where a
    /// grid point has no local fit there). The GCV table's rows are the ladder's
    /// criterion instead (the RSS of each rung's smoother on that ladder's
    /// residuals), so the chosen row's value differs from this one slightly.
    pub gcv: f64,
    pub gcv_table: Vec<GcvRow>,
    /// Whether the ladder was extended beyond the paper's 21 bandwidths.
    pub ladder_extended: bool,
    pub iterations: usize,
    pub converged: bool,
    /// RSS after the start and after each alternation.
    pub rss_history: Vec<f64>,
    pub init: Init,
    pub path: FitPath,
    /// Samples in the series and rows in the regression.
    pub n: usize,
    pub n_rows: usize,
    /// Residuals e_t for every t.
    pub residuals: Vec<f64>,
    /// Whether the fit returned its linear ARMA start (the alternation ended above it:
    /// constant f_m, no local systems); `farma update` has no local fits to continue.
    pub linear_start: bool,
    /// Messages for the user (ladder extensions, filled points).
    pub notes: Vec<String>,
    /// Where the time went.
    pub timings: FitTimings,
}

/// Quantile of a strided sample of at most 1e6 values (exact for shorter series):
/// linear interpolation between the order statistics of ranks floor(q (n - 1)) and
/// the next (type 7 of Hyndman and Fan 1996, numpy's default), in
/// [`f64::total_cmp`]'s order.
///
/// The order statistics by radix selection: the values' keys
/// ([`total_order_key`]) are counted by their top 16 bits, which gives the bucket
/// and the rank within it of every order statistic asked for; only the values of
/// those buckets are then copied and selected among (nearly all of them when one
/// bucket holds most values, as a copy of all did before). The values a full sort
/// would put at those ranks (tested against one).
fn quantiles(u: impl Fn(usize) -> f64, rows: std::ops::Range<usize>, qs: &[f64]) -> Vec<f64> {
    let n = rows.len();
    let stride = n.div_ceil(1_000_000).max(1);
    // the values, read twice where they are (the counting copies none)
    let values = || rows.clone().step_by(stride).map(&u);
    let len = values().len();
    if len == 0 {
        return vec![f64::NAN; qs.len()];
    }
    const SHIFT: u32 = 48;
    let mut counts = vec![0u32; 1 << (64 - SHIFT)];
    for x in values() {
        counts[(total_order_key(x) >> SHIFT) as usize] += 1;
    }
    // every rank asked for: floor(q (n - 1)) and the next one
    let last = len - 1;
    let at: Vec<(usize, f64)> = qs
        .iter()
        .map(|q| {
            let pos = q * last as f64;
            (pos.floor() as usize, pos - pos.floor())
        })
        .collect();
    let mut ranks: Vec<usize> = at
        .iter()
        .flat_map(|&(i, _)| [i.min(last), (i + 1).min(last)])
        .collect();
    ranks.sort_unstable();
    ranks.dedup();
    // (bucket, rank of its first value) of each rank
    let mut first_rank = Vec::with_capacity(ranks.len());
    let (mut bucket, mut below) = (0usize, 0usize);
    for &r in &ranks {
        while below + counts[bucket] as usize <= r {
            below += counts[bucket] as usize;
            bucket += 1;
        }
        first_rank.push((bucket, below));
    }
    let mut buckets: Vec<usize> = first_rank.iter().map(|&(b, _)| b).collect();
    buckets.dedup();
    let mut members: Vec<Vec<f64>> = buckets
        .iter()
        .map(|&b| Vec::with_capacity(counts[b] as usize))
        .collect();
    for x in values() {
        let b = (total_order_key(x) >> SHIFT) as usize;
        if let Ok(k) = buckets.binary_search(&b) {
            members[k].push(x);
        }
    }
    // the order statistics, ranks in increasing order: after selecting local rank
    // i, every larger one lies in m[i + 1..], so the next selects within what is left
    let mut stats = vec![f64::NAN; ranks.len()];
    let mut from = 0;
    let mut last_bucket = usize::MAX;
    for (k, (&r, &(b, below))) in ranks.iter().zip(&first_rank).enumerate() {
        if b != last_bucket {
            (from, last_bucket) = (0, b);
        }
        let m = &mut members[buckets.binary_search(&b).expect("its bucket")];
        let i = r - below;
        stats[k] = *m[from..].select_nth_unstable_by(i - from, f64::total_cmp).1;
        from = i;
    }
    let order_stat = |r: usize| stats[ranks.binary_search(&r).expect("a rank asked for")];
    at.iter()
        .map(|&(i, frac)| {
            let i = i.min(last);
            let vi = order_stat(i);
            if i < last {
                vi + frac * (order_stat(i + 1) - vi)
            } else {
                vi
            }
        })
        .collect()
}

/// A u64 whose unsigned order is [`f64::total_cmp`]'s order of `x`: the sign bit set
/// for positive values, every bit flipped for negative ones (IEEE 754-2008, 5.10,
/// totalOrder).
fn total_order_key(x: f64) -> u64 {
    let b = x.to_bits();
    if b >> 63 == 1 { !b } else { b | (1 << 63) }
}

/// e_t = x_t - sum f_m(U_t) x_{t-m} - sum b_m e_{t-m}, zeros before the first sample,
/// U_t = x_{t-d} (0 before the first sample). First w_t = x_t - sum f_m(U_t) x_{t-m}
/// (independent rows: chunks in parallel), then the MA recursion in place; the same
/// operations in the same order as the one-loop recursion, so the same bits.
pub fn residuals(x: &[f64], d: usize, grid: &[f64], coef: &GridFit, b: &[f64], e: &mut [f64]) {
    let lookup = IntervalLookup::new(grid);
    let warm = coef.p.max(d).min(x.len());
    let cell = |_t: usize, u: f64| grid_cell(grid, &lookup, u);
    let fill = |e: &mut [f64]| {
        w_head(x, d, grid, coef, &mut e[..warm]);
        w_rows(x, d, grid, coef, e, warm, &cell);
    };
    fill(e);
    ma_filter_rss(e, b, usize::MAX, fill);
}

/// [`residuals`] with the grid cell of every row from `start` on read from `index`
/// (built over breakpoints that hold every grid point, for this series and d):
/// the same values, bit for bit.
pub fn residuals_indexed(
    x: &[f64],
    d: usize,
    grid: &[f64],
    coef: &GridFit,
    b: &[f64],
    e: &mut [f64],
    index: &IntervalIndex,
) {
    let p = coef.p;
    let warm = p.max(d).max(index.start()).min(x.len());
    let cells = index.grid_cells(grid);
    let fill = |e: &mut [f64]| {
        w_head(x, d, grid, coef, &mut e[..warm]);
        match p {
            1 => w_indexed::<1>(x, d, &cell_segments(grid, coef, &cells), index, e, warm),
            2 => w_indexed::<2>(x, d, &cell_segments(grid, coef, &cells), index, e, warm),
            3 => w_indexed::<3>(x, d, &cell_segments(grid, coef, &cells), index, e, warm),
            4 => w_indexed::<4>(x, d, &cell_segments(grid, coef, &cells), index, e, warm),
            _ => {
                let cell = |t: usize, _u: f64| cells[index.interval(t)];
                w_rows(x, d, grid, coef, e, warm, &cell);
            }
        }
    };
    fill(e);
    ma_filter_rss(e, b, usize::MAX, fill);
}

/// f on one interval of an [`IntervalIndex`] as `(u - base) / width` times `diff`
/// plus `fa`: the operands of [`eval_cell`]'s interpolation, read instead of
/// recomputed. Below the grid `fa` = f at the first point and `diff` = 0 (the same
/// value: fa + lam * 0 = fa for finite lam), above it the last point's. P is known at
/// compile time, so a row's operands are read without bounds checks.
struct CellSegment<const P: usize> {
    base: f64,
    width: f64,
    fa: [f64; P],
    diff: [f64; P],
}

/// The [`CellSegment`] of every interval, from the grid cell of each (`cells`).
fn cell_segments<const P: usize>(
    grid: &[f64],
    coef: &GridFit,
    cells: &[u32],
) -> Vec<CellSegment<P>> {
    debug_assert_eq!(coef.p, P);
    let g = grid.len();
    cells
        .iter()
        .map(|&c| {
            let (k, inside) = match c {
                BELOW_GRID => (0, false),
                ABOVE_GRID => (g - 1, false),
                k => (k as usize, true),
            };
            let mut seg = CellSegment {
                base: grid[k],
                width: if inside { grid[k + 1] - grid[k] } else { 1.0 },
                fa: [0.0; P],
                diff: [0.0; P],
            };
            for m in 0..P {
                let fa = coef.f[k * P + m];
                seg.fa[m] = fa;
                seg.diff[m] = if inside {
                    coef.f[(k + 1) * P + m] - fa
                } else {
                    0.0
                };
            }
            seg
        })
        .collect()
}

/// w_t for rows `warm..` with p known at compile time, chunks in parallel.
fn w_indexed<const P: usize>(
    x: &[f64],
    d: usize,
    segs: &[CellSegment<P>],
    index: &IntervalIndex,
    e: &mut [f64],
    warm: usize,
) {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 16;
    e[warm..]
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, out)| w_indexed_span(x, d, segs, index, warm + c * CHUNK, out));
}

/// w_t for rows t0..t0 + out.len() (all at or after the warm rows), into `out`.
fn w_indexed_span<const P: usize>(
    x: &[f64],
    d: usize,
    segs: &[CellSegment<P>],
    index: &IntervalIndex,
    t0: usize,
    out: &mut [f64],
) {
    for (i, w) in out.iter_mut().enumerate() {
        let t = t0 + i;
        let r = &segs[index.interval(t)];
        let u = x[t - d];
        let lam = (u - r.base) / r.width;
        let mut s = x[t];
        for m in 0..P {
            s -= (r.fa[m] + lam * r.diff[m]) * x[t - m - 1];
        }
        *w = s;
    }
}

/// The w of [`residuals_indexed`] for any span of rows: `fill(t0, out)` writes w_t for
/// rows t0..t0 + out.len() (the same operations, so the same bits: the warm rows one
/// by one when the span starts at row 0, which it then covers). None for p > 4.
fn w_indexed_filler<'a>(
    x: &'a [f64],
    d: usize,
    grid: &'a [f64],
    coef: &'a GridFit,
    index: &'a IntervalIndex,
) -> Option<impl Fn(usize, &mut [f64]) + Sync + 'a> {
    let p = coef.p;
    if p > 4 {
        return None;
    }
    let warm = p.max(d).max(index.start()).min(x.len());
    let cells = index.grid_cells(grid);
    enum Segs {
        P1(Vec<CellSegment<1>>),
        P2(Vec<CellSegment<2>>),
        P3(Vec<CellSegment<3>>),
        P4(Vec<CellSegment<4>>),
    }
    let segs = match p {
        1 => Segs::P1(cell_segments(grid, coef, &cells)),
        2 => Segs::P2(cell_segments(grid, coef, &cells)),
        3 => Segs::P3(cell_segments(grid, coef, &cells)),
        _ => Segs::P4(cell_segments(grid, coef, &cells)),
    };
    Some(move |t0: usize, out: &mut [f64]| {
        let head = if t0 == 0 { warm.min(out.len()) } else { 0 };
        assert!(
            t0 >= warm || head == warm,
            "a span from row 0 covers the warm rows"
        );
        w_head(x, d, grid, coef, &mut out[..head]);
        let (t1, rest) = (t0 + head, &mut out[head..]);
        match &segs {
            Segs::P1(sg) => w_indexed_span(x, d, sg, index, t1, rest),
            Segs::P2(sg) => w_indexed_span(x, d, sg, index, t1, rest),
            Segs::P3(sg) => w_indexed_span(x, d, sg, index, t1, rest),
            Segs::P4(sg) => w_indexed_span(x, d, sg, index, t1, rest),
        }
    })
}

/// w_t = x_t - sum f_m(U_t) x_{t-m} for the first rows, `e.len()` of them, one by one
/// (some lags fall before the first sample; U_t = 0 before it; cells by search).
fn w_head(x: &[f64], d: usize, grid: &[f64], coef: &GridFit, e: &mut [f64]) {
    let lookup = IntervalLookup::new(grid);
    let p = coef.p;
    let mut f = [0.0f64; 8];
    for (t, w) in e.iter_mut().enumerate() {
        let u = if t >= d { x[t - d] } else { 0.0 };
        eval_cell(coef, grid, grid_cell(grid, &lookup, u), u, &mut f[..p]);
        let mut s = x[t];
        for m in 0..p.min(t) {
            s -= f[m] * x[t - m - 1];
        }
        *w = s;
    }
}

/// w_t for rows `warm..` (every lag inside the series: the sums without the checks),
/// chunks in parallel, `cell(t, U_t)` giving the grid cell.
fn w_rows<F: Fn(usize, f64) -> u32 + Sync>(
    x: &[f64],
    d: usize,
    grid: &[f64],
    coef: &GridFit,
    e: &mut [f64],
    warm: usize,
    cell: &F,
) {
    use rayon::prelude::*;
    let p = coef.p;
    const CHUNK: usize = 1 << 16;
    e[warm..]
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, out)| {
            let mut f = [0.0f64; 8];
            let f = &mut f[..p];
            let t0 = warm + c * CHUNK;
            for (i, w) in out.iter_mut().enumerate() {
                let t = t0 + i;
                let u = x[t - d];
                eval_cell(coef, grid, cell(t, u), u, f);
                let mut s = x[t];
                for (m, fm) in f.iter().enumerate() {
                    s -= fm * x[t - m - 1];
                }
                *w = s;
            }
        });
}

/// The grid cell of `u` as [`IntervalIndex::grid_cells`] gives it, except that
/// u = grid[0] counts as below the grid (the interpolation there gives the same value).
#[inline]
fn grid_cell(grid: &[f64], lookup: &IntervalLookup, u: f64) -> u32 {
    let g = grid.len();
    if u <= grid[0] {
        BELOW_GRID
    } else if u >= grid[g - 1] {
        ABOVE_GRID
    } else {
        (lookup.find(u) - 1) as u32
    }
}

/// f(u) from the grid values (`GridFit::eval`) with u's grid cell given: linear
/// interpolation inside the grid, the end values beyond it.
#[inline]
fn eval_cell(coef: &GridFit, grid: &[f64], cell: u32, u: f64, out: &mut [f64]) {
    let p = coef.p;
    let g = grid.len();
    match cell {
        BELOW_GRID => out.copy_from_slice(&coef.f[..p]),
        ABOVE_GRID => out.copy_from_slice(&coef.f[(g - 1) * p..g * p]),
        k => {
            let k = k as usize;
            let lam = (u - grid[k]) / (grid[k + 1] - grid[k]);
            let (fa, fb) = (
                &coef.f[k * p..(k + 1) * p],
                &coef.f[(k + 1) * p..(k + 2) * p],
            );
            for m in 0..p {
                out[m] = fa[m] + lam * (fb[m] - fa[m]);
            }
        }
    }
}

/// `GridFit::eval` with the grid cell found by an [`IntervalLookup`] instead of a
/// binary search: the same cell, the same arithmetic, the same bits.
#[inline]
fn eval_with(coef: &GridFit, grid: &[f64], lookup: &IntervalLookup, u: f64, out: &mut [f64]) {
    eval_cell(coef, grid, grid_cell(grid, lookup, u), u, out)
}

/// Turns w (in `buf`) into the residuals e_t = w_t - sum b_m e_{t-m} in place, zeros
/// before the first sample (e_t needs only earlier e, already in place), and returns
/// their RSS over t >= `start` ([`rss_from`]'s sum, the same bits). For q = 1, 2 on
/// series of two [`FILTER_CHUNK`]s or more the recursion runs in chunks, in parallel,
/// with every e_t exact ([`ma_filter_chunked`]); when a chunk cannot be made exact
/// (b near the edge of invertibility) `refill` puts w back into `buf` and the
/// recursion runs serially.
fn ma_filter_rss(buf: &mut [f64], b: &[f64], start: usize, refill: impl FnOnce(&mut [f64])) -> f64 {
    match b.len() {
        0 => rss_from(buf, start),
        1 => ma_filter_fixed::<1>(buf, b, start, refill),
        2 => ma_filter_fixed::<2>(buf, b, start, refill),
        _ => {
            let q = b.len().min(buf.len());
            for t in 0..q {
                let mut s = buf[t];
                for (m, bm) in b.iter().enumerate() {
                    if t > m {
                        s -= bm * buf[t - m - 1];
                    }
                }
                buf[t] = s;
            }
            for t in q..buf.len() {
                let mut s = buf[t];
                for (m, bm) in b.iter().enumerate() {
                    s -= bm * buf[t - m - 1];
                }
                buf[t] = s;
            }
            rss_from(buf, start)
        }
    }
}

/// [`ma_filter_rss`] for q known at compile time: in parallel chunks on long series
/// ([`ma_filter_chunked`]), else (or after `refill`) serially, the RSS summed on the
/// way in [`rss_from`]'s order.
fn ma_filter_fixed<const Q: usize>(
    buf: &mut [f64],
    b: &[f64],
    start: usize,
    refill: impl FnOnce(&mut [f64]),
) -> f64 {
    let mut bb = [0.0f64; Q];
    bb.copy_from_slice(b);
    if buf.len() >= 2 * FILTER_CHUNK {
        if let Some(rss) = ma_filter_chunked(buf, &bb, start) {
            return rss;
        }
        refill(buf);
    }
    let mut eh = [0.0f64; Q];
    let mut rss = 0.0;
    for (head, rest) in rss_groups(buf.len()) {
        let (h0, r0) = (head.start, rest.start);
        let head_sum = filter_rows(&mut buf[head], &bb, h0, &mut eh, start);
        rss += head_sum + filter_rows(&mut buf[rest], &bb, r0, &mut eh, start);
    }
    rss
}

/// Rows per chunk of the parallel MA filter, and of the RSS's sum on series of two
/// chunks or more (`rss_from`).
pub const FILTER_CHUNK: usize = 1 << 18;

/// Rows at the head of each chunk that are re-run from the true state
/// (`ma_filter_chunked`); the RSS sums them apart from the rest of their chunk.
pub const FILTER_LEAD: usize = 1 << 12;

/// The MA recursion over `rows` (row t0 first) from the lags `eh` (left at the state
/// after them), e_t in place; returns sum e_t^2 over rows t >= `start`. The last q
/// residuals are kept in registers (zeros before the first sample: subtracting
/// b_m * 0 leaves every value as the general loop's).
fn filter_rows<const Q: usize>(
    rows: &mut [f64],
    b: &[f64; Q],
    t0: usize,
    eh: &mut [f64; Q],
    start: usize,
) -> f64 {
    let mut rss = 0.0;
    for (i, v) in rows.iter_mut().enumerate() {
        let mut s = *v;
        for m in 0..Q {
            s -= b[m] * eh[m];
        }
        *v = s;
        if t0 + i >= start {
            rss += s * s;
        }
        for m in (1..Q).rev() {
            eh[m] = eh[m - 1];
        }
        eh[0] = s;
    }
    rss
}

/// [`ma_filter_rss`] in chunks of [`FILTER_CHUNK`] rows, in parallel, every e_t the
/// serial recursion's, bit for bit (as `arma_pass` does for its passes), through
/// [`chunked_in_place`]. None when the chunks' states do not agree (rho near 1):
/// `buf` then holds neither w nor e. The RSS is summed per chunk (its lead rows, then
/// the rest) and the chunks in order, as [`rss_from`].
fn ma_filter_chunked<const Q: usize>(buf: &mut [f64], bb: &[f64; Q], start: usize) -> Option<f64> {
    let mut rss = 0.0;
    let run = |rows: &mut [f64], t0: usize, eh: &mut [f64; Q]| filter_rows(rows, bb, t0, eh, start);
    let same =
        |a: &[f64; Q], o: &[f64; Q]| a.iter().zip(o).all(|(u, v)| u.to_bits() == v.to_bits());
    let add = |h: &f64, r: &f64| rss += h + r;
    chunked_in_place(buf, None, [0.0f64; Q], run, same, add).then_some(rss)
}

/// Writes w_t for rows t0..t0 + out.len() into `out` (`fill(t0, out)`).
type SpanFill<'a> = dyn Fn(usize, &mut [f64]) + Sync + 'a;

/// `arma_pass`'s row recursion with p = 0 (`pass_rows`; Box, Jenkins and Reinsel 7.2:
/// d e_t / d b_j = -e_{t-j} - sum_k b_k d e_{t-k} / d b_j) in place: each w_t of `rows`
/// (row t0 first) becomes e_t, the operations of [`filter_rows`]; returns the
/// Gauss-Newton sums of rows t >= `start`.
fn gn_rows<const Q: usize>(
    rows: &mut [f64],
    b: &[f64; Q],
    t0: usize,
    st: &mut PassState<0, Q, Q>,
    start: usize,
) -> PassSums<Q> {
    let mut sums = PassSums::zero();
    let n = rows.len();
    pass_rows(rows, 0..n, t0, start, &[], b, st, &mut sums);
    sums
}

/// The chunked in-place recursion of both MA filters ([`ma_filter_chunked`],
/// [`ma_filter_gn`]): chunks of [`FILTER_CHUNK`] rows in parallel, each first written
/// by `fill` when given (`fill(t0, rows)`), its first [`FILTER_LEAD`] values of w kept,
/// run by `run(rows, t0, state)` from the `zero` state, its state after the lead and
/// at its end recorded; then, chunk after chunk, the lead rows re-run from the true
/// state (the previous chunk's end). The zero start's error decays like rho^t (rho
/// the largest root of the MA polynomial); once the two states agree to the bit
/// (`same`) every later row is the same computation, so the chunk's values, end state
/// and sums are exact. `add(head, rest)` takes each chunk's lead and rest sums in
/// chunk order. False when the states do not agree (rho near 1): `buf` then holds
/// neither w nor e.
fn chunked_in_place<S, A>(
    buf: &mut [f64],
    fill: Option<&SpanFill<'_>>,
    zero: S,
    run: impl Fn(&mut [f64], usize, &mut S) -> A + Sync,
    same: impl Fn(&S, &S) -> bool,
    mut add: impl FnMut(&A, &A),
) -> bool
where
    S: Copy + Send + Sync,
    A: Send,
{
    use rayon::prelude::*;
    let n = buf.len();
    // (w of the lead rows, state after the lead, end state, lead sums, rest sums)
    let parts: Vec<(Vec<f64>, S, S, A, A)> = buf
        .par_chunks_mut(FILTER_CHUNK)
        .enumerate()
        .map(|(c, rows)| {
            let t0 = c * FILTER_CHUNK;
            if let Some(f) = fill {
                f(t0, rows);
            }
            let lead = FILTER_LEAD.min(rows.len());
            let w_head = if c > 0 {
                rows[..lead].to_vec()
            } else {
                Vec::new()
            };
            let mut st = zero;
            let (head, rest) = rows.split_at_mut(lead);
            let head_sums = run(head, t0, &mut st);
            let at_lead = st;
            let rest_sums = run(rest, t0 + lead, &mut st);
            (w_head, at_lead, st, head_sums, rest_sums)
        })
        .collect();
    add(&parts[0].3, &parts[0].4);
    let mut state = parts[0].2;
    for (c, part) in parts.iter().enumerate().skip(1) {
        let t0 = c * FILTER_CHUNK;
        let rows = &mut buf[t0..t0 + part.0.len()];
        rows.copy_from_slice(&part.0);
        let mut st = state;
        let head_sums = run(rows, t0, &mut st);
        // a last chunk of its lead rows only is exact from this re-run alone
        let lead_only = t0 + part.0.len() == n;
        if !(same(&st, &part.1) || lead_only) {
            return false;
        }
        add(&head_sums, &part.4);
        state = part.2;
    }
    true
}

/// One pass that turns w into the residuals at `b` in place (e_t and their RSS the
/// values of [`ma_filter_rss`] at `b`, bit for bit) and sums the Gauss-Newton normal
/// equations for b there: the alternation's b-step without a pass of its own
/// (`gn_b_step`). `fill`, when given, first writes w into each chunk, so that w is
/// computed, filtered and summed while the chunk is in cache. Long series in parallel
/// chunks ([`chunked_in_place`]), else (or, after `refill` has put w back, when the
/// chunks' states disagree) serially; the sums are grouped by [`rss_groups`] either
/// way, so the result depends on N and b, not on the threads.
fn ma_filter_gn<const Q: usize>(
    buf: &mut [f64],
    b: &[f64; Q],
    start: usize,
    fill: Option<&SpanFill<'_>>,
    refill: impl FnOnce(&mut [f64]),
) -> PassSums<Q> {
    let zero = PassState::<0, Q, Q>::at(&[], 0);
    let run =
        |rows: &mut [f64], t0: usize, st: &mut PassState<0, Q, Q>| gn_rows(rows, b, t0, st, start);
    let n = buf.len();
    let mut total = PassSums::zero();
    if n >= 2 * FILTER_CHUNK {
        let add = |h: &PassSums<Q>, r: &PassSums<Q>| total.add_group(h, r);
        if chunked_in_place(buf, fill, zero, run, |a, o| a.same(o), add) {
            return total;
        }
        total = PassSums::zero();
        refill(buf);
    } else if let Some(f) = fill {
        f(0, buf);
    }
    let mut st = zero;
    for (head, rest) in rss_groups(n) {
        let (h0, r0) = (head.start, rest.start);
        let head_sums = run(&mut buf[head], h0, &mut st);
        let rest_sums = run(&mut buf[rest], r0, &mut st);
        total.add_group(&head_sums, &rest_sums);
    }
    total
}

/// The alternation's b-step in one pass ([`ma_filter_gn`]; w written by `fill` chunk
/// by chunk, or already in `buf` when `fill` is None): `buf` becomes the residuals at
/// `b0`, and the Gauss-Newton step from `b0` is taken. Returns (RSS at b0, the
/// stepped b, the step's predicted RSS decrease), or None for q other than 1 and 2
/// (`buf` untouched).
fn gn_b_step(
    buf: &mut [f64],
    start: usize,
    b0: &[f64],
    fill: Option<&SpanFill<'_>>,
    refill: impl FnOnce(&mut [f64]),
) -> Option<(f64, Vec<f64>, f64)> {
    fn solve<const Q: usize>(s: PassSums<Q>, b0: &[f64]) -> (f64, Vec<f64>, f64) {
        let jtj: Vec<f64> = s.jtj.iter().flatten().copied().collect();
        match normal_equations(&jtj, &s.jte, Q) {
            Some(step) => (
                s.rss,
                b0.iter().zip(&step).map(|(b, d)| b + d).collect(),
                predicted_decrease(&step, &s.jte),
            ),
            None => (s.rss, b0.to_vec(), 0.0),
        }
    }
    match *b0 {
        [b1] => Some(solve(ma_filter_gn(buf, &[b1], start, fill, refill), b0)),
        [b1, b2] => Some(solve(ma_filter_gn(buf, &[b1, b2], start, fill, refill), b0)),
        _ => None,
    }
}

/// How a sum of squares over n rows is grouped, the same wherever an RSS of
/// residuals is summed ([`rss_from`], the MA filters): a series shorter than two
/// [`FILTER_CHUNK`]s in one sequential sum (one group, its rest empty); a longer one
/// per chunk of [`FILTER_CHUNK`] rows, its first [`FILTER_LEAD`] rows and then the
/// rest, the chunk's (lead + rest) added to the total chunk after chunk (the order
/// [`ma_filter_chunked`] sums in). Yields (lead rows, rest rows) per group.
fn rss_groups(n: usize) -> impl Iterator<Item = (Range<usize>, Range<usize>)> {
    let (chunk, lead) = if n < 2 * FILTER_CHUNK {
        (n.max(1), n)
    } else {
        (FILTER_CHUNK, FILTER_LEAD)
    };
    (0..n).step_by(chunk).map(move |s| {
        let end = (s + chunk).min(n);
        let mid = (s + lead).min(end);
        (s..mid, mid..end)
    })
}

/// Sum of e_t^2 over t >= `start`, grouped by [`rss_groups`].
fn rss_from(e: &[f64], start: usize) -> f64 {
    // rows r from `start` on
    let sq = |r: Range<usize>| -> f64 {
        let mut s = 0.0;
        for v in &e[r.start.max(start).min(r.end)..r.end] {
            s += v * v;
        }
        s
    };
    let mut rss = 0.0;
    for (head, rest) in rss_groups(e.len()) {
        rss += sq(head) + sq(rest);
    }
    rss
}

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
struct Smoother<'a> {
    prob: VcProblem<'a>,
    grid: &'a [f64],
    path: FitPath,
    umin: f64,
    umax: f64,
}

impl<'a> Smoother<'a> {
    /// The smoother for series `x`, residuals `e`, MA coefficients `b`, shape
    /// (p, d) (first row max(p, q, d)), on `grid`, with index values in `span`.
    fn new(
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
    fn fit_at(&self, h: f64, cache: &mut StepCache) -> GridFit {
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
    fn ladder_direct(&self, index: &DirectIndex, hs: &[f64]) -> Vec<RungFit> {
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
struct StepCache {
    /// Left-hand sides of the local systems (fast path), at their own h.
    systems: Option<LocalSystems>,
    /// Each row's interval over breakpoints(grid, [h]), with that h. Every grid point
    /// is among its breakpoints, so it also gives the residuals' grid cells at any h.
    index: Option<(f64, Option<IntervalIndex>)>,
    /// The last GCV ladder's table.
    ladder: Option<LadderCache>,
    /// The direct path's KD-tree over the index values U_t = x_(t-d), which do not
    /// change during a fit: built once.
    direct: Option<DirectIndex>,
}

impl StepCache {
    /// The index at bandwidth h (built now if the one kept is for another h; None
    /// when the intervals do not fit a u16).
    fn index_for(&mut self, prob: &VcProblem, grid: &[f64], h: f64) -> Option<&IntervalIndex> {
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
    fn direct_index(&mut self, prob: &VcProblem) -> &DirectIndex {
        self.direct.get_or_insert_with(|| DirectIndex::build(prob))
    }

    /// Whatever index is kept, for the grid cells.
    fn any_index(&self) -> Option<&IntervalIndex> {
        self.index.as_ref().and_then(|(_, ix)| ix.as_ref())
    }
}

/// [`residuals`], with the grid cells from `index` when there is one.
fn residuals_at(
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

/// The ladder's bandwidth h_j = 1.1^-j range/2.
fn ladder_h(j: i32, range: f64) -> f64 {
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
fn ladder_ahead(n_rows: usize) -> i32 {
    let decades = (n_rows as f64 / 1e6).log10().max(0.0);
    10 * (1 + decades.ceil() as i32)
}

/// A ladder rung's fit, with its RSS and trace when every grid point has a fit.
type RungFit = (GridFit, Option<(f64, f64)>);

/// A GCV ladder's moment table (fast path): every family over the breakpoints of the
/// rungs `js`, and each row's interval. The next ladder (the re-check after
/// convergence: the same X and U, new residuals) sums only the families that hold y.
struct LadderCache {
    js: (i32, i32),
    table: MomentTable,
    index: Option<IntervalIndex>,
    /// Fits (and RSS, trace) at the rungs of `js` asked for so far (index j - js.0),
    /// from the table as it is now.
    fits: Vec<Option<RungFit>>,
    /// The left-hand sides of the rungs fitted on this table (index j - js.0): they
    /// depend on X and U only, so they outlive a refresh of the y families.
    systems: Vec<Option<LocalSystems>>,
    /// The smoother's trace at those rungs (None: not every point fitted); it too
    /// depends on X and U only (a refreshed table keeps the design's families bit for
    /// bit, and the kept left-hand sides give the same inverses), so a refit on new
    /// residuals sums the RSS alone.
    traces: Vec<Option<Option<f64>>>,
}

impl LadderCache {
    /// The left-hand sides at bandwidth h: those kept for its rung (the same bits as
    /// [`MomentTable::local_systems`]: a window grown from narrower ones has the bits
    /// of one summed alone), else computed from the table.
    fn systems_at(&self, grid: &[f64], h: f64) -> LocalSystems {
        self.systems
            .iter()
            .flatten()
            .find(|s| s.h == h && s.grid() == grid)
            .cloned()
            .unwrap_or_else(|| self.table.local_systems(grid, h))
    }
}

impl<'a> Smoother<'a> {
    /// Fits (and RSS, trace) on the fast path for rungs `js`, through `cache`: a kept
    /// table covering them is brought up to date (`fresh`: it already is) with the
    /// y families only; otherwise one is built for the rungs plus [`ladder_ahead`].
    fn ladder_cached(
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

/// GCV over the ladder, extended at either end while the minimum sits there.
/// Returns (table sorted by decreasing h, index of the minimum, extended?, notes).
fn gcv_select(
    sm: &Smoother,
    range: f64,
    cache: &mut StepCache,
) -> (Vec<GcvRow>, Vec<GridFit>, usize, bool, Vec<String>) {
    let m = sm.prob.n_rows() as f64;
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
        let rows: Vec<GcvRow> = hs
            .iter()
            .zip(&fits)
            .zip(&js)
            .map(|((&h, (f, rt)), &j)| {
                let n_failed = f.status.iter().filter(|s| **s != PointStatus::Ok).count();
                match rt {
                    Some((rss, tr)) if *tr < m => GcvRow {
                        j,
                        bandwidth: h,
                        rss: *rss,
                        trace: *tr,
                        gcv: (rss / m) / (1.0 - tr / m).powi(2),
                        n_failed,
                    },
                    _ => GcvRow {
                        j,
                        bandwidth: h,
                        rss: f64::NAN,
                        trace: f64::NAN,
                        gcv: f64::INFINITY,
                        n_failed,
                    },
                }
            })
            .collect();
        let best = rows
            .iter()
            .enumerate()
            .filter(|(_, r)| r.gcv.is_finite())
            .min_by(|a, b| a.1.gcv.total_cmp(&b.1.gcv))
            .map(|(i, _)| i);
        let last = rows.len() - 1;
        match best {
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
            Some(0) | None if js[0] > -20 => {
                let first = js[0];
                notes.push(if best.is_some() {
                    format!(
                        "GCV minimum at the largest bandwidth h_{first} = {:.6e}: ladder extended upwards",
                        rows[0].bandwidth
                    )
                } else {
                    format!(
                        "GCV: no bandwidth from h_{first} = {:.6e} down gives a fit at every grid point: ladder extended upwards",
                        rows[0].bandwidth
                    )
                });
                let mut more: Vec<i32> = (first - 5..first).collect();
                more.extend(js);
                js = more;
                extended = true;
            }
            Some(i) => {
                if i == 0 || i == last {
                    // at an end no further extension reaches
                    notes.push(format!(
                        "GCV minimum at the {} bandwidth h_{} = {:.6e}, the end of the ladder's extensions: the optimum may lie beyond it",
                        if i == 0 { "largest" } else { "smallest" },
                        js[i],
                        rows[i].bandwidth
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

/// The largest magnitudes of a channel's centred values that a fast-path fit
/// (`FitPath::Fast`) accepts: its moment tables carry the local systems' entries as
/// sums of products of up to the 8th power of the values (x_a x_b (U - u_g)^k, shifted
/// between centres by the binomial theorem), which overflow or lose their digits to
/// underflow far enough from 1. The direct path (a KD-tree gather and a dense solve
/// per grid point, squares of the values at most) reaches further,
/// [`DIRECT_MAGNITUDE_LIMITS`]: the same fit at k = -55, -45, 40 and 60 below.
/// Measured (`farma fit --order 2,1,1` on a Gaussian series of 5,000 samples
/// scaled by 10^k, its largest magnitude 3.9 10^k): the same b to 4e-12 relative and
/// sigma^2 / 10^2k, trace and GCV / 10^2k to 1e-14 for k = -35, -30, -20, -10, 0, 10,
/// 20, 25, 30, 35; at k = -40 the trace off by 2e-9;
/// at k = -45 127 of 201 grid points without a local fit; at k = -50 the linear start
/// returned; at k = 40 and -55 no local fit at all. The limits keep 5 orders of
/// margin (sums over up to 1e10 samples).
pub const MAGNITUDE_LIMITS: (f64, f64) = (1e-30, 1e30);

/// The largest magnitudes of a channel's centred values that a direct-path fit
/// (`FitPath::Direct`, and the 2-D index's fit) accepts: its sums are of squares of
/// the values (the linear start's normal equations, the local systems, the RSS), which
/// leave f64's range near 1e+-154 for one value, less the log10 of the number of
/// samples. Measured (`farma fit --order 2,1,1 --method direct --grid 31` on an
/// ARMA(1,1) series of 3,000 samples scaled by 10^k, 2026-11-26): the same b, trace
/// and sigma^2 / 10^2k for k = -150, -140, -100, -60, 60, 100, 140, 150; at k = 155,
/// 160 .. 190 and -160 .. -190 the linear start fails (its sums overflow, or underflow
/// to zero), and at k = -155 sigma^2 is subnormal. The limits keep sums over up to
/// 1e10 samples inside f64's normal range.
pub const DIRECT_MAGNITUDE_LIMITS: (f64, f64) = (1e-140, 1e140);

/// Refuses values (centred, from `lo` to `hi`) when their largest magnitude is
/// outside the limits of `path` ([`MAGNITUDE_LIMITS`] for the fast path,
/// [`DIRECT_MAGNITUDE_LIMITS`] for the direct one), naming `what` and the power of ten
/// to rescale by.
pub fn check_magnitude(
    what: &str,
    lo: f64,
    hi: f64,
    path: FitPath,
) -> std::result::Result<(), String> {
    let (min, max) = match path {
        FitPath::Fast => MAGNITUDE_LIMITS,
        FitPath::Direct => DIRECT_MAGNITUDE_LIMITS,
    };
    let mag = lo.abs().max(hi.abs());
    if (min..=max).contains(&mag) {
        return Ok(());
    }
    let (verb, after, spike) = if mag > max {
        (
            "reaches",
            "",
            "; a single spike: `farma prep` removes outliers",
        )
    } else {
        ("reaches only", " after removing the mean", "")
    };
    let (dmin, dmax) = DIRECT_MAGNITUDE_LIMITS;
    let why = match path {
        FitPath::Fast if (dmin..=dmax).contains(&mag) => format!(
            "the fast path's moment tables sum products of up to the 8th power of the values, which leave f64's range outside {min:.0e}..{max:.0e} in magnitude"
        ),
        FitPath::Fast => format!(
            "the fast path's moment tables sum products of up to the 8th power of the values, which leave f64's range outside {min:.0e}..{max:.0e} in magnitude, and the direct path's sums of squares outside {dmin:.0e}..{dmax:.0e}"
        ),
        FitPath::Direct => format!(
            "the fit's sums of squares of the values leave f64's range outside {min:.0e}..{max:.0e} in magnitude"
        ),
    };
    let direct = if path == FitPath::Fast && (dmin..=dmax).contains(&mag) {
        format!(", or fit with `--method direct` (slower; it takes {dmin:.0e}..{dmax:.0e})")
    } else {
        String::new()
    };
    Err(format!(
        "{what} {verb} {mag:.3e} in magnitude{after}: {why}; express it in other units (scaled by about 1e{}){spike}{direct}",
        -mag.log10().round() as i64
    ))
}

/// Above this modulus of the MA part's largest root ([`ma_root_modulus`]), 0.99,
/// [`ma_edge_note`] says that b is near the edge of invertibility. Measured
/// (2026-11-26, FARMA(2,1,1)): differenced white noise (true b_1 = -1) gave b_1 =
/// -0.9947 and -0.9869 on 4,000 samples (two series: a short one can stay below the
/// edge), below -0.99 on 20,000 (tests/suite/estimator_recovery.rs); a step in a constant
/// channel -0.99999999939.
pub const MA_EDGE: f64 = 0.99;

/// The note of a fit whose RSS settled at a bandwidth GCV had re-selected twice, the
/// most the alternation makes: GCV is not run again at the final residuals, so the
/// bandwidth is not confirmed there, and a choice that swung back to one it had left
/// says so. `chosen` holds the bandwidths GCV chose in order (its last is the model's),
/// `fmt` writes one (a pair for the 2-D index).
pub fn reselection_limit_note<H: PartialEq + Copy>(
    iterations: usize,
    chosen: &[H],
    fmt: impl Fn(H) -> String,
) -> String {
    let (at, swung) = match chosen.split_last() {
        Some((last, before)) => (format!(" {}", fmt(*last)), before.contains(last)),
        None => (String::new(), false),
    };
    format!(
        "alternation {iterations}: the RSS settled at bandwidth{at}, GCV's second re-selection ({}); GCV is not run a third time at these residuals, so it may prefer another bandwidth there{}; a fixed --bandwidth settles the choice",
        chosen
            .iter()
            .map(|h| fmt(*h))
            .collect::<Vec<_>>()
            .join(" -> "),
        if swung {
            ", and it had swung back to a bandwidth it left before"
        } else {
            ""
        }
    )
}

/// A note when the MA part `b` is near the edge of invertibility (its largest root's
/// modulus above [`MA_EDGE`]): what an over-differenced channel (differencing white
/// noise gives b_1 = -1), or a step or trend left in it, gives. None otherwise.
pub fn ma_edge_note(b: &[f64]) -> Option<String> {
    let modulus = ma_root_modulus(b);
    (modulus > MA_EDGE).then(|| {
        format!(
            "the MA part b = {b:?} is near the edge of invertibility (its largest root has modulus {modulus:.10}, 1 - {:.1e}): an over-differenced channel (differencing white noise gives b_1 = -1), or a step or trend that removing the mean leaves; `farma prep` tests stationarity and differences or detrends only where needed",
            1.0 - modulus
        )
    })
}

/// Above this ratio of an index's span (max - min) to the spread of its central
/// values (the grid's quantiles), [`stretched_ladder_note`] says that an outlier
/// stretches the bandwidth ladder. Ratios without outliers, measured with numpy
/// (2026-11-26, span over the 1 %-99 % quantile range, one draw each): Gaussian 2.12
/// at 1e6 samples and 2.24 at 1e7, Laplace 3.40 and 3.79, uniform 1.02; the gyro
/// channels of the real ADIS16405 static runs 1.8-2.2 (and 5.3 and 17.8 in the run
/// with a bump of -17 deg/s, README).
pub const STRETCH_RATIO: f64 = 10.0;

/// A note when the span `lo..hi` of an index (named by `what`) is more than
/// [`STRETCH_RATIO`] times the spread of its central values `qlo..qhi` (quantiles
/// `qs`): the ladder h_j = 1.1^-j span/2 then starts far above the bandwidths the data
/// can use, and GCV may end at a bandwidth wider than the central values' spread; an
/// outlier, which `farma prep` removes. None otherwise.
pub fn stretched_ladder_note(
    what: &str,
    (lo, hi): (f64, f64),
    (qlo, qhi): (f64, f64),
    qs: (f64, f64),
) -> Option<String> {
    let ratio = (hi - lo) / (qhi - qlo);
    (ratio > STRETCH_RATIO).then(|| {
        format!(
            "{what} span {:.6e} (from {lo:.6e} to {hi:.6e}), {ratio:.0} times the spread of their central values (quantiles {} to {}: {qlo:.6e} to {qhi:.6e}): an outlier? It stretches the bandwidth ladder, which starts at half the span; `farma prep` removes outliers",
            hi - lo,
            qs.0,
            qs.1
        )
    })
}

/// A note on the grid points with a local fit (`status` Ok) but no standard error
/// (`se` NaN: [`super::moments::sandwich_diag`]), naming how many and the largest
/// condition number among them; None when there are none. `se` and `cond` as the
/// coefficient table's: p values per grid point, one condition number per point.
pub fn missing_se_note(
    status: &[PointStatus],
    cond: &[f64],
    se: &[f64],
    p: usize,
) -> Option<String> {
    let missing: Vec<usize> = (0..status.len())
        .filter(|&g| {
            status[g] == PointStatus::Ok && se[g * p..(g + 1) * p].iter().any(|v| v.is_nan())
        })
        .collect();
    if missing.is_empty() {
        return None;
    }
    let worst = missing.iter().map(|&g| cond[g]).fold(0.0f64, f64::max);
    Some(format!(
        "{} fitted grid point(s) have no standard error (se NaN): their local systems (condition number up to {worst:.1e}) are too ill-conditioned for the sandwich form, which squares it",
        missing.len()
    ))
}

/// The note of a model whose trace and GCV are not defined: grid points without a
/// local fit (`status`) at the bandwidth(s) `at`.
pub fn undefined_trace_note(status: &[PointStatus], at: &str) -> String {
    let failed = status.iter().filter(|s| **s != PointStatus::Ok).count();
    format!(
        "trace and GCV not defined: {failed} grid point(s) have no local fit at {at} (see status)"
    )
}

/// Whether the last iterate's RSS `rss` ends above the least one, `best_rss`, by more
/// than `tol` relative (the iterate of least RSS is then returned, module doc); a
/// non-finite `rss` always does (the difference alone would compare inf > inf or NaN,
/// both false).
fn went_back(rss: f64, best_rss: f64, tol: f64) -> bool {
    !rss.is_finite() || rss - best_rss > tol * rss
}

/// A Gauss-Newton step's predicted RSS decrease, step . (-J'e): with
/// step = (J'J)^-1 (-J'e), ||e + J step||^2 = RSS - step . (-J'e).
fn predicted_decrease(step: &[f64], neg_jte: &[f64]) -> f64 {
    step.iter().zip(neg_jte).map(|(s, g)| s * g).sum()
}

/// Relative RSS decrease below which a Gauss-Newton step is taken without a line
/// search: a sum of N squares is resolved to about 1e-16 sqrt(N) relative, so for
/// N up to 1e8 a decrease below 1e-12 of the RSS cannot be told from rounding.
const FLAT_RSS: f64 = 1e-12;

/// Gauss-Newton for b minimising sum_{t >= start} e_t^2, e_t = w_t - sum b_m e_{t-m}
/// (`arma_pass` with p = 0), with step halving. Each trial point's pass also gives
/// the normal equations there, so an accepted step costs one pass in all.
pub fn ma_cls(w: &[f64], start: usize, b0: &[f64]) -> Vec<f64> {
    let q = b0.len();
    let mut b = b0.to_vec();
    let (mut rss, mut jtj, mut jte) = arma_pass(w, start, &[], &b);
    for _ in 0..30 {
        let Some(step) = normal_equations(&jtj, &jte, q) else {
            break;
        };
        // Stop on the size of the step, not on the RSS: near the optimum the RSS is
        // flat to rounding while b is still determined to ~1e-12.
        if step.iter().all(|s| s.abs() < 1e-12) {
            break;
        }
        // A step this small is inside the quadratic basin: the RSS cannot tell the
        // trial from b any more, so the line search would only halve the step 30
        // times, a pass each, and give up. Take the Gauss-Newton step and stop.
        if step
            .iter()
            .zip(&b)
            .all(|(s, bi)| s.abs() < 1e-9 * (1.0 + bi.abs()))
        {
            let bt: Vec<f64> = (0..q).map(|i| b[i] + step[i]).collect();
            if ma_invertible(&bt) {
                b = bt;
            }
            break;
        }
        // The same when the model predicts a decrease below the RSS's resolution, but
        // such a step need not be small (a flat direction of a badly conditioned J'J):
        // one pass checks that the RSS did not rise beyond rounding, else b stays.
        if predicted_decrease(&step, &jte) < FLAT_RSS * rss {
            let bt: Vec<f64> = (0..q).map(|i| b[i] + step[i]).collect();
            if ma_invertible(&bt) && arma_pass(w, start, &[], &bt).0 <= rss * (1.0 + FLAT_RSS) {
                b = bt;
            }
            break;
        }
        let mut scale = 1.0;
        let mut moved = false;
        for _ in 0..30 {
            let bt: Vec<f64> = (0..q).map(|i| b[i] + scale * step[i]).collect();
            if ma_invertible(&bt) {
                let (r, jt, je) = arma_pass(w, start, &[], &bt);
                if r <= rss * (1.0 + 1e-14) {
                    moved = true;
                    (b, rss, jtj, jte) = (bt, r, jt, je);
                    break;
                }
            }
            scale *= 0.5;
        }
        if !moved {
            break;
        }
    }
    b
}

/// The alternation's checked b-step for q > 2 (for q <= 2 the alternation runs
/// `ma_step_from` from `gn_b_step`'s step when that step is not small, see
/// [`SMALL_STEP`]): one Gauss-Newton step for b on w (in `buf`) from `b0`, then the
/// MA filter at the new b, turning w into the residuals in place, with their RSS: two
/// passes. Near the optimum (every alternation after the first few) one step
/// is about as good as [`ma_cls`]'s several (Gauss-Newton converges linearly here,
/// the residuals not being zero, but one step cuts the start's error about 200-fold:
/// see the test).
/// When the step does not lower the RSS below its value at `b0` (beyond rounding),
/// `refill` puts w back into `buf`, [`ma_cls`] runs with step halving, and the filter
/// runs at its b. Returns (b, RSS over t >= `start`).
pub fn ma_step(
    buf: &mut [f64],
    start: usize,
    b0: &[f64],
    refill: impl FnMut(&mut [f64]),
) -> (Vec<f64>, f64) {
    let q = b0.len();
    let (rss0, jtj, jte) = arma_pass(buf, start, &[], b0);
    let b1: Vec<f64> = match normal_equations(&jtj, &jte, q) {
        Some(step) => b0.iter().zip(&step).map(|(b, s)| b + s).collect(),
        None => b0.to_vec(),
    };
    ma_step_from(buf, start, b0, (rss0, b1), refill)
}

/// [`ma_step`] from its Gauss-Newton step already taken: `rss0` the RSS at `b0`, `b1`
/// the stepped b (from `gn_b_step`'s pass, which the alternation has run): the filter
/// at b1 and the check, without `arma_pass`'s pass again.
fn ma_step_from(
    buf: &mut [f64],
    start: usize,
    b0: &[f64],
    (rss0, b1): (f64, Vec<f64>),
    mut refill: impl FnMut(&mut [f64]),
) -> (Vec<f64>, f64) {
    if ma_invertible(&b1) {
        let rss1 = ma_filter_rss(buf, &b1, start, &mut refill);
        if rss1 <= rss0 * (1.0 + FLAT_RSS) {
            return (b1, rss1);
        }
        refill(buf);
    }
    let b = ma_cls(buf, start, b0);
    let rss = ma_filter_rss(buf, &b, start, &mut refill);
    (b, rss)
}

/// Gauss-Newton for the linear ARMA(p,q) on every sample, from (a0, b0): (a, b)
/// minimise sum_{t >= start} e_t^2 (`arma_pass`), with step halving and the MA part
/// kept invertible: the conditional least squares of [`super::arma::fit_arma`] from a
/// given start. Streaming (one pass per iteration, the trial's pass giving the next
/// normal equations), nothing N-long allocated, so it runs on series of any length.
/// Returns (a, b, RSS).
pub fn arma_cls(
    x: &[f64],
    start: usize,
    a0: &[f64],
    b0: &[f64],
    max_iter: usize,
) -> (Vec<f64>, Vec<f64>, f64) {
    arma_cls_within(x, start, (a0, b0), max_iter, 0.0)
}

/// [`arma_cls`], stopping where it is, without a pass for the step, once the
/// Gauss-Newton model predicts a further RSS decrease below `enough` times the RSS
/// (0: never; [`arma_cls`]). Returns (a, b, RSS).
pub fn arma_cls_within(
    x: &[f64],
    start: usize,
    ab0: (&[f64], &[f64]),
    max_iter: usize,
    enough: f64,
) -> (Vec<f64>, Vec<f64>, f64) {
    let (a, b, rss, _) = arma_cls_residuals(x, start, ab0, max_iter, enough, None);
    (a, b, rss)
}

/// [`arma_cls_within`], each pass writing its residuals to `e` (when given, and the
/// order has a kernel of its own, [`arma_pass_into`]). The last value is true when
/// `e` then holds the residuals at the returned (a, b) (the pass that evaluated them
/// was the last to write), false when it must be filled again (a rejected trial
/// step wrote last, or nothing was written).
fn arma_cls_residuals(
    x: &[f64],
    start: usize,
    (a0, b0): (&[f64], &[f64]),
    max_iter: usize,
    enough: f64,
    mut e: Option<&mut [f64]>,
) -> (Vec<f64>, Vec<f64>, f64, bool) {
    let (p, q) = (a0.len(), b0.len());
    let k = p + q;
    // the (a, b) whose residuals `e` holds
    let mut written: Option<(Vec<f64>, Vec<f64>)> = None;
    let mut pass = |x: &[f64], start: usize, a: &[f64], b: &[f64]| {
        let into = e
            .as_deref_mut()
            .and_then(|e| arma_pass_into(x, start, a, b, e));
        match into {
            Some(out) => {
                written = Some((a.to_vec(), b.to_vec()));
                out
            }
            None => arma_pass(x, start, a, b),
        }
    };
    let (mut a, mut b) = (a0.to_vec(), b0.to_vec());
    let (mut rss, mut jtj, mut jte) = pass(x, start, &a, &b);
    for _ in 0..max_iter {
        let Some(step) = normal_equations(&jtj, &jte, k) else {
            break;
        };
        let theta: Vec<f64> = a.iter().chain(&b).copied().collect();
        if step
            .iter()
            .zip(&theta)
            .all(|(s, v)| s.abs() < 1e-9 * (1.0 + v.abs()))
        {
            break;
        }
        if enough > 0.0 && predicted_decrease(&step, &jte) < enough * rss {
            break;
        }
        // below the RSS's resolution (see ma_cls): take the step if the RSS did not
        // rise beyond rounding, and stop
        if predicted_decrease(&step, &jte) < FLAT_RSS * rss {
            let at: Vec<f64> = (0..p).map(|i| a[i] + step[i]).collect();
            let bt: Vec<f64> = (0..q).map(|i| b[i] + step[p + i]).collect();
            if ma_invertible(&bt) {
                let r = pass(x, start, &at, &bt).0;
                if r <= rss * (1.0 + FLAT_RSS) {
                    (a, b, rss) = (at, bt, r);
                }
            }
            break;
        }
        let mut scale = 1.0;
        let mut moved = false;
        for _ in 0..30 {
            let at: Vec<f64> = (0..p).map(|i| a[i] + scale * step[i]).collect();
            let bt: Vec<f64> = (0..q).map(|i| b[i] + scale * step[p + i]).collect();
            if ma_invertible(&bt) {
                let (r, jt, je) = pass(x, start, &at, &bt);
                if r <= rss {
                    moved = rss - r > 1e-12 * rss;
                    (a, b, rss, jtj, jte) = (at, bt, r, jt, je);
                    break;
                }
            }
            scale *= 0.5;
        }
        if !moved {
            break;
        }
    }
    let holds = written.is_some_and(|(wa, wb)| same_bits(&wa, &a) && same_bits(&wb, &b));
    (a, b, rss, holds)
}

/// Whether two slices hold the same values bit for bit.
fn same_bits(u: &[f64], v: &[f64]) -> bool {
    u.len() == v.len() && u.iter().zip(v).all(|(a, b)| a.to_bits() == b.to_bits())
}

/// The linear ARMA(p,q) the FARMA fit starts from (and nests): conditional least
/// squares ([`fit_arma`]) on the first [`START_MAX`] samples of `x`, refined on longer
/// prefixes and then on every sample by [`arma_cls_within`] (rows t >= `start`, to
/// [`START_ENOUGH`]) when the series is longer. The workflow's
/// ARMA baseline is this same fit, so a FARMA RSS can be compared with it. None when
/// the design is singular.
///
/// The refinement runs on prefixes of N / [`REFINE_RATIO`]^k samples, k = ..., 1, 0
/// (those longer than [`START_MAX`]), shortest first: each prefix's optimum is within
/// about 1/sqrt(its length) of the next one's, so the passes over every sample start
/// close to their optimum and need fewer steps, while all the prefixes' passes
/// together cost less than one over every sample. On the bench's FARMA(2,1,1) series
/// at 1e7 samples (timing prints, BENCHMARKS.md): 5 passes over every sample from a
/// fit on the first 2^16, 4 from the prefixes, 2 with [`START_ENOUGH`] as well.
pub fn linear_start(x: &[f64], p: usize, q: usize, start: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    linear_start_into(x, p, q, start, None).map(|(a, b, _)| (a, b))
}

/// [`linear_start`], the passes over every sample writing their residuals to `e`
/// (when given); the last value says whether `e` holds the residuals at the
/// returned (a, b) ([`arma_cls_residuals`]).
fn linear_start_into(
    x: &[f64],
    p: usize,
    q: usize,
    start: usize,
    mut e: Option<&mut [f64]>,
) -> Option<(Vec<f64>, Vec<f64>, bool)> {
    let m = fit_arma(&x[..x.len().min(START_MAX)], p, q)?;
    let (mut a, mut b) = (m.ar, m.ma);
    // N / RATIO^k for k = ..., 2, 1, 0, those longer than the first fit's
    let mut lens: Vec<usize> = std::iter::successors(Some(x.len()), |l| Some(l / REFINE_RATIO))
        .take_while(|l| *l > START_MAX)
        .collect();
    lens.reverse();
    let mut holds = false;
    for len in lens {
        let out = if len == x.len() {
            e.as_deref_mut()
        } else {
            None
        };
        (a, b, _, holds) = arma_cls_residuals(&x[..len], start, (&a, &b), 30, START_ENOUGH, out);
    }
    Some((a, b, holds))
}

/// The linear ARMA (a, b)'s residuals, e_t = x_t - sum a_m x_{t-m} -
/// sum b_m e_{t-m} with zeros before the first sample (the values of
/// [`super::arma::arma_residuals`], in the same operations), and their RSS over t >= `start` in
/// [`rss_from`]'s order: w_t = x_t - sum a_m x_{t-m} in parallel, then the MA filter
/// ([`ma_filter_rss`], in parallel chunks for q = 1, 2).
fn arma_residuals_rss(x: &[f64], a: &[f64], b: &[f64], start: usize) -> (Vec<f64>, f64) {
    use rayon::prelude::*;
    let w_rows = |t0: usize, rows: &mut [f64]| {
        for (i, v) in rows.iter_mut().enumerate() {
            let t = t0 + i;
            let mut s = x[t];
            for (m, am) in a.iter().enumerate() {
                if t > m {
                    s -= am * x[t - m - 1];
                }
            }
            *v = s;
        }
    };
    let fill = |buf: &mut [f64]| {
        buf.par_chunks_mut(FILTER_CHUNK)
            .enumerate()
            .for_each(|(c, rows)| w_rows(c * FILTER_CHUNK, rows))
    };
    // w written straight into a new buffer (its first write), then filtered in place
    let (mut e, _) = buffers::filled(x.len(), w_rows);
    let rss = ma_filter_rss(&mut e, b, start, fill);
    (e, rss)
}

/// [`linear_start`] stops refining once the Gauss-Newton model predicts less than
/// this relative RSS decrease ([`arma_cls_within`]): its RSS is then within about
/// 1e-10 of the linear ARMA's least one, far below the alternation's tolerance
/// (1e-6 by default) and any test's resolution, and a pass over every sample is saved
/// on long series (the step that would check a decrease of that size).
pub const START_ENOUGH: f64 = 1e-10;

/// Growth of the prefixes [`linear_start`] refines the linear ARMA on.
pub const REFINE_RATIO: usize = 16;

/// Largest predicted RSS decrease, relative to the RSS, of a Gauss-Newton step for b
/// that the alternation takes without checking it (`gn_b_step`: the step goes into
/// the next f-step's response, and the next pass's RSS tells whether it helped); a
/// larger step is taken by [`ma_step`], which checks it with a pass of its own. On the
/// bench's FARMA(2,1,1) series (1e6-1e8 samples) the first alternation's step predicts
/// 1.1-1.5e-4 of the RSS (checked), the later ones 4e-6 down to 4e-7.
pub const SMALL_STEP: f64 = 1e-4;

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

/// Samples the linear ARMA start is first fitted on (the first ones); on longer series
/// it is then refined on longer prefixes and on every sample by the streaming
/// [`arma_cls_within`] ([`linear_start`]).
pub const START_MAX: usize = 1 << 14;

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

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    #[test]
    fn indexed_residuals_equal_the_searched_ones() {
        let x = uniform(200_000, 5);
        let grid: Vec<f64> = (0..31).map(|k| -0.4 + 0.025 * k as f64).collect();
        // every specialised w pass (p <= 4) and the general one
        for p in [1, 2, 3, 4, 5] {
            let mut coef = GridFit::new(grid.len(), p, 0.1);
            for (i, f) in coef.f.iter_mut().enumerate() {
                *f = 0.3 * ((i * 7 % 13) as f64 / 13.0 - 0.5);
            }
            for d in [1, 2] {
                let prob = VcProblem::new(&x, &[], &[], p, d);
                let ix = IntervalIndex::build(&prob, breakpoints(&grid, &[0.07])).unwrap();
                let (mut e1, mut e2) = (vec![0.0; x.len()], vec![0.0; x.len()]);
                residuals(&x, d, &grid, &coef, &[-0.4], &mut e1);
                residuals_indexed(&x, d, &grid, &coef, &[-0.4], &mut e2, &ix);
                assert_eq!(e1, e2, "p = {p}, d = {d}");
            }
        }
    }

    #[test]
    fn one_gauss_newton_step_near_the_optimum_is_the_converged_b() {
        // w from an MA(1) with b = -0.6: from a start near the optimum one step (and
        // the filter) gives ma_cls's b and the residuals and RSS at it
        let z = uniform(100_000, 9);
        let w: Vec<f64> = (0..z.len())
            .map(|t| z[t] - 0.6 * if t > 0 { z[t - 1] } else { 0.0 })
            .collect();
        let b_opt = ma_cls(&w, 1, &[0.0]);
        assert!((b_opt[0] + 0.6).abs() < 0.02, "{b_opt:?}");
        // Gauss-Newton on a problem with residuals converges linearly: one step cuts
        // the start's error about 200-fold here (3e-3 off leaves 1.0e-5, 1e-4 off
        // 6e-7); an alternation moves b by ~1e-5, and each one takes a step
        for (off, tol) in [(3e-3, 3e-5), (1e-4, 1e-6)] {
            let mut buf = w.clone();
            let (b, _) = ma_step(&mut buf, 1, &[b_opt[0] + off], |_| {
                panic!("no refill near the optimum")
            });
            assert!((b[0] - b_opt[0]).abs() < tol, "{b:?} vs {b_opt:?}");
        }
        let mut buf = w.clone();
        let (b, rss) = ma_step(&mut buf, 1, &[b_opt[0] + 1e-4], |_| {
            panic!("no refill near the optimum")
        });
        let mut e = w.clone();
        let rss_e = ma_filter_rss(&mut e, &b, 1, |_| unreachable!("q = 1, N below two chunks"));
        assert_eq!(buf, e);
        assert_eq!(rss.to_bits(), rss_e.to_bits());
        assert_eq!(rss.to_bits(), rss_from(&e, 1).to_bits());
        // far from it: one step still lowers the RSS, and the returned RSS is the one
        // at the returned b; had the step raised it, ma_step would refill w and run
        // ma_cls (no start tried here, for MA(1) or MA(2), made the step raise it)
        for b_far in [0.95, 0.9, 0.7, 0.5] {
            let mut buf = w.clone();
            let (b, rss) = ma_step(&mut buf, 1, &[b_far], |v: &mut [f64]| v.copy_from_slice(&w));
            let (r_far, _, _) = arma_pass(&w, 1, &[], &[b_far]);
            let (r_new, _, _) = arma_pass(&w, 1, &[], &b);
            assert!(r_new < r_far, "{b:?}");
            assert_eq!(rss.to_bits(), r_new.to_bits());
        }
    }

    /// The serial MA recursion, the general loop (the chunked filter's slow twin).
    fn serial_filter(w: &[f64], b: &[f64]) -> Vec<f64> {
        let mut e = w.to_vec();
        for t in 0..e.len() {
            let mut s = e[t];
            for (m, bm) in b.iter().enumerate() {
                if t > m {
                    s -= bm * e[t - m - 1];
                }
            }
            e[t] = s;
        }
        e
    }

    #[test]
    fn chunked_ma_filter_is_the_serial_recursion_bit_for_bit() {
        // three chunks and a short fourth: every e_t the serial recursion's, the RSS
        // rss_from's (its chunked order) and within rounding of a plain sum, for 1 and
        // 2 threads; b near the edge of invertibility (0.9999^4096 = 0.66: the chunk
        // states cannot agree) refills w and runs serially, with the same results
        // (and a last chunk of 100 rows, fewer than the lead: exact from its re-run,
        // no refill even for b = 0.99, whose zero start needs thousands of rows)
        for (n, b) in [
            (3 * FILTER_CHUNK + 12_345, vec![-0.6]),
            (3 * FILTER_CHUNK + 12_345, vec![0.5, -0.3]),
            (3 * FILTER_CHUNK + 12_345, vec![0.9999]),
            (3 * FILTER_CHUNK + 12_345, vec![-1.2, 0.36]),
            (2 * FILTER_CHUNK + 100, vec![0.99]),
        ] {
            let w = uniform(n, 21);
            let want = serial_filter(&w, &b);
            let plain: f64 = want[2..].iter().map(|v| v * v).sum();
            let near_edge = b == [0.9999];
            let mut outs = Vec::new();
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut buf = w.clone();
                let mut refills = 0;
                let rss = pool.install(|| {
                    ma_filter_rss(&mut buf, &b, 2, |v: &mut [f64]| {
                        refills += 1;
                        v.copy_from_slice(&w)
                    })
                });
                assert_eq!(refills, usize::from(near_edge), "b = {b:?}");
                assert!(same_bits(&buf, &want), "b = {b:?}");
                assert_eq!(rss.to_bits(), rss_from(&want, 2).to_bits(), "b = {b:?}");
                assert!((rss - plain).abs() <= 1e-12 * plain, "{rss} vs {plain}");
                outs.push(rss.to_bits());
            }
            assert_eq!(outs[0], outs[1]);
        }
    }

    #[test]
    fn the_one_pass_b_step_filters_as_the_serial_recursion_and_sums_as_arma_pass() {
        // e and the RSS the serial recursion's bit for bit (one chunk, several with a
        // short last one, a last chunk of lead rows only), the Gauss-Newton sums
        // arma_pass's to rounding (other grouping), w written by `fill` chunk by chunk
        // or already in the buffer, 1 and 2 threads; b near the edge of invertibility
        // refills w and runs serially, with the same results
        for (n, b) in [
            (5_000, vec![-0.6]),
            (3 * FILTER_CHUNK + 12_345, vec![-0.6]),
            (3 * FILTER_CHUNK + 12_345, vec![0.5, -0.3]),
            (3 * FILTER_CHUNK + 12_345, vec![0.9999]),
            (2 * FILTER_CHUNK + 100, vec![0.99]),
        ] {
            let w = uniform(n, 31);
            let want = serial_filter(&w, &b);
            let (rss_want, jtj_want, jte_want) = arma_pass(&w, 2, &[], &b);
            let near_edge = b == [0.9999];
            let fill = |t0: usize, rows: &mut [f64]| rows.copy_from_slice(&w[t0..t0 + rows.len()]);
            let mut outs = Vec::new();
            for threads in [1, 2] {
                for chunked_fill in [false, true] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let mut buf = if chunked_fill {
                        vec![f64::NAN; n]
                    } else {
                        w.clone()
                    };
                    let mut refills = 0;
                    let f: Option<&SpanFill<'_>> = if chunked_fill { Some(&fill) } else { None };
                    let (rss, b1, dec) = pool
                        .install(|| {
                            gn_b_step(&mut buf, 2, &b, f, |v: &mut [f64]| {
                                refills += 1;
                                v.copy_from_slice(&w)
                            })
                        })
                        .unwrap();
                    assert_eq!(refills, usize::from(near_edge), "b = {b:?}");
                    assert!(same_bits(&buf, &want), "b = {b:?}");
                    assert_eq!(rss.to_bits(), rss_from(&want, 2).to_bits(), "b = {b:?}");
                    assert!((rss - rss_want).abs() <= 1e-12 * rss_want);
                    // the step from arma_pass's normal equations
                    let step = normal_equations(&jtj_want, &jte_want, b.len()).unwrap();
                    for i in 0..b.len() {
                        let s = b1[i] - b[i];
                        assert!(
                            (s - step[i]).abs() <= 1e-9 * (1e-6 + step[i].abs()),
                            "{s} vs {}",
                            step[i]
                        );
                    }
                    let dec_want = predicted_decrease(&step, &jte_want);
                    assert!((dec - dec_want).abs() <= 1e-6 * dec_want.abs() + 1e-9 * rss_want);
                    outs.push((
                        rss.to_bits(),
                        b1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    ));
                }
            }
            assert!(outs.iter().all(|o| *o == outs[0]), "b = {b:?}");
        }
        // only q = 1 and 2
        let mut buf = uniform(100, 1);
        assert!(gn_b_step(&mut buf, 3, &[0.1, 0.1, 0.1], None, |_| {}).is_none());
    }

    #[test]
    fn the_reselection_limit_note_names_a_swing_back() {
        let f = |h: f64| format!("{h}");
        let on = reselection_limit_note(5, &[0.5, 0.25, 0.125], f);
        assert!(on.contains("(0.5 -> 0.25 -> 0.125)") && on.contains("bandwidth 0.125,"));
        assert!(!on.contains("swung back"), "{on}");
        let back = reselection_limit_note(7, &[0.5, 0.25, 0.5], f);
        assert!(
            back.contains("alternation 7:") && back.contains("swung back"),
            "{back}"
        );
    }

    #[test]
    fn a_fit_returns_the_residuals_and_rss_of_its_own_f_and_b() {
        // FARMA(2,1,1) long enough for the chunked one-pass b-step (more than two
        // filter chunks): whichever b-step made the returned iterate, its residuals are
        // the recursion's at the returned (f, b), bit for bit, and its RSS theirs
        let n = 2 * FILTER_CHUNK + 50_000;
        let z = uniform(n, 77);
        let mut x = vec![0.0; n];
        let (mut x1, mut x2, mut e1) = (0.0f64, 0.0f64, 0.0f64);
        for t in 0..n {
            let e = 3.4 * z[t];
            let f1 = 0.3 + 0.4 * (-x1 * x1).exp();
            let f2 = -0.2 + 0.1 * x1.tanh();
            x[t] = f1 * x1 + f2 * x2 + e - 0.5 * e1;
            (x2, x1, e1) = (x1, x[t], e);
        }
        let params = FarmaParams {
            grid_size: 41,
            ..FarmaParams::default()
        }
        .validate(n)
        .unwrap();
        let m = fit(&x, &params).unwrap();
        assert!(m.iterations >= 2, "{}", m.iterations);
        assert!((m.b[0] + 0.5).abs() < 0.05, "{:?}", m.b);
        let xc: Vec<f64> = x.iter().map(|v| v - m.mean).collect();
        let mut e = vec![0.0; n];
        residuals(&xc, 1, &m.grid, &m.coef, &m.b, &mut e);
        assert!(same_bits(&e, &m.residuals));
        assert_eq!(m.rss.to_bits(), rss_from(&e, 2).to_bits());
    }

    #[test]
    fn w_written_span_by_span_is_the_indexed_residuals_w() {
        let x = uniform(300_000, 8);
        let grid: Vec<f64> = (0..31).map(|k| -0.4 + 0.025 * k as f64).collect();
        for p in [1, 2, 3, 4] {
            let mut coef = GridFit::new(grid.len(), p, 0.1);
            for (i, f) in coef.f.iter_mut().enumerate() {
                *f = 0.3 * ((i * 7 % 13) as f64 / 13.0 - 0.5);
            }
            for d in [1, 3] {
                let prob = VcProblem::new(&x, &[], &[], p, d);
                let ix = IntervalIndex::build(&prob, breakpoints(&grid, &[0.07])).unwrap();
                let mut want = vec![0.0; x.len()];
                residuals_indexed(&x, d, &grid, &coef, &[], &mut want, &ix);
                let fill = w_indexed_filler(&x, d, &grid, &coef, &ix).unwrap();
                let mut got = vec![f64::NAN; x.len()];
                for (c, rows) in got.chunks_mut(70_001).enumerate() {
                    fill(c * 70_001, rows);
                }
                assert!(same_bits(&got, &want), "p = {p}, d = {d}");
            }
        }
        let coef = GridFit::new(grid.len(), 5, 0.1);
        let prob = VcProblem::new(&x, &[], &[], 5, 1);
        let ix = IntervalIndex::build(&prob, breakpoints(&grid, &[0.07])).unwrap();
        assert!(w_indexed_filler(&x, 1, &grid, &coef, &ix).is_none());
    }

    #[test]
    fn the_starts_parallel_residuals_are_the_serial_recursions_bit_for_bit() {
        // one chunk (serial filter) and several chunks with a short last one
        for n in [5_000, 3 * FILTER_CHUNK + 123] {
            let w = uniform(n, 17);
            let orders: [(&[f64], &[f64]); 5] = [
                (&[0.36, -0.2], &[-0.48]),
                (&[0.5], &[0.3, -0.2]),
                (&[0.2, 0.1, -0.1], &[0.1, 0.05, 0.02]),
                (&[0.4, -0.1], &[]),
                (&[], &[0.6]),
            ];
            for (a, b) in orders {
                let start = a.len().max(b.len()).max(1);
                let mut want = vec![0.0; n];
                super::super::arma::arma_residuals(&w, a, b, &mut want);
                let rss_want = rss_from(&want, start);
                let (got, rss) = arma_residuals_rss(&w, a, b, start);
                assert!(same_bits(&got, &want), "n = {n}, a = {a:?}, b = {b:?}");
                assert_eq!(
                    rss.to_bits(),
                    rss_want.to_bits(),
                    "n = {n}, a = {a:?}, b = {b:?}"
                );
            }
        }
    }

    #[test]
    fn radix_selected_quantiles_equal_those_of_a_full_sort_over_signs_and_scales() {
        // values of both signs over many binades, both zeros, ties, and a bucket of
        // the key's top bits holding most of the values
        let u = uniform(30_001, 9);
        let v: Vec<f64> = u
            .iter()
            .enumerate()
            .map(|(i, w)| match i % 7 {
                0 => 0.0,
                1 => -0.0,
                2 => (w - 0.5) * 1e-300,
                3 => (w - 0.5) * 1e12,
                4 => 1.0 + w * 1e-9,
                _ => w - 0.5,
            })
            .collect();
        let mut sorted = v.clone();
        sorted.sort_by(f64::total_cmp);
        let qs = [0.0, 1e-5, 0.01, 0.1, 0.2857, 0.5, 0.71, 0.9, 0.99, 1.0];
        let got = quantiles(|t| v[t], 0..v.len(), &qs);
        for (q, g) in qs.iter().zip(&got) {
            let pos = q * (sorted.len() - 1) as f64;
            let (i, frac) = (pos.floor() as usize, pos - pos.floor());
            let want = match sorted.get(i + 1) {
                Some(next) => sorted[i] + frac * (next - sorted[i]),
                None => sorted[i],
            };
            assert_eq!(g.to_bits(), want.to_bits(), "q = {q}");
        }
        let mut keys: Vec<u64> = v.iter().map(|x| total_order_key(*x)).collect();
        keys.sort_unstable();
        let by_key: Vec<u64> = sorted.iter().map(|x| total_order_key(*x)).collect();
        assert_eq!(keys, by_key, "the keys' order is total_cmp's");
    }

    #[test]
    fn the_starts_residuals_from_its_last_pass_are_those_filled_afresh() {
        // linear_start_into's last pass over every sample (several chunks) writes the
        // residuals at the (a, b) it returns: bit for bit those of arma_residuals_rss,
        // and rss_from gives its RSS; the same (a, b) as linear_start
        let x: Vec<f64> = {
            let w = uniform(600_000, 21);
            let mut x = vec![0.0; w.len()];
            for t in 2..w.len() {
                x[t] = 0.5 * x[t - 1] - 0.2 * x[t - 2] + w[t] - 0.4 * w[t - 1];
            }
            x
        };
        for (p, q) in [(2, 1), (1, 2), (3, 1)] {
            let start = p.max(q);
            let mut e = vec![0.0; x.len()];
            let (a, b, holds) = linear_start_into(&x, p, q, start, Some(&mut e)).unwrap();
            assert!(
                holds,
                "({p}, {q}): the last pass evaluated the returned (a, b)"
            );
            let (a2, b2) = linear_start(&x, p, q, start).unwrap();
            assert!(same_bits(&a, &a2) && same_bits(&b, &b2));
            let (want, rss) = arma_residuals_rss(&x, &a, &b, start);
            assert!(same_bits(&e, &want), "({p}, {q})");
            assert_eq!(rss_from(&e, start).to_bits(), rss.to_bits());
        }
    }

    /// A sandwich variance that rounds to 0 or below is NaN, not 0, and the note counts
    /// the fitted points without one. (A helper's fuzzing found 23 fitted rows with se
    /// exactly 0 on a 2-level channel with 1e-6 noise, condition numbers near 9e11; on
    /// such a channel at `--bandwidth 0.5 --grid 1000`, 29 fitted points now have NaN
    /// se, condition numbers up to 4.2e12.)
    #[test]
    fn a_standard_error_lost_to_rounding_is_nan_and_noted() {
        use super::super::moments::sandwich_diag;
        let q = [1.0, 0.0, 0.0, 1.0];
        assert_eq!(sandwich_diag(&q, &[4.0, 0.0, 0.0, 1.0], 2, 1), vec![2.0]);
        assert!(sandwich_diag(&q, &[0.0, 0.0, 0.0, 1.0], 2, 1)[0].is_nan());
        assert!(sandwich_diag(&q, &[-1e-30, 0.0, 0.0, 1.0], 2, 1)[0].is_nan());
        let status = [PointStatus::Ok, PointStatus::Ok, PointStatus::Singular];
        let cond = [10.0, 4.2e12, f64::NAN];
        let se = [0.1, 0.2, 0.3, f64::NAN, f64::NAN, f64::NAN];
        let note = missing_se_note(&status, &cond, &se, 2).unwrap();
        assert!(note.starts_with("1 fitted grid point(s)"), "{note}");
        assert!(note.contains("4.2e12"), "{note}");
        assert_eq!(
            missing_se_note(&status, &cond, &[0.1, 0.2, 0.3, 0.4, f64::NAN, f64::NAN], 2),
            None
        );
    }

    #[test]
    fn a_non_finite_rss_always_goes_back_to_the_least_one() {
        let tol = 1e-6;
        assert!(!went_back(100.0, 100.0, tol));
        assert!(!went_back(100.00001, 100.0, tol), "within tol");
        assert!(went_back(100.001, 100.0, tol));
        assert!(!went_back(99.0, 100.0, tol), "below the least");
        // inf - 100 > tol inf and NaN > x are both false: the plain difference would
        // return these iterates
        assert!(went_back(f64::INFINITY, 100.0, tol));
        assert!(went_back(f64::NAN, 100.0, tol));
        assert!(went_back(f64::NEG_INFINITY, 100.0, tol));
    }

    #[test]
    fn quantiles_by_selection_equal_those_of_a_full_sort() {
        // increasing, decreasing and repeated levels, with ties in the data
        let v: Vec<f64> = uniform(10_001, 4)
            .iter()
            .map(|u| (u * 50.0).round())
            .collect();
        let mut sorted = v.clone();
        sorted.sort_by(f64::total_cmp);
        let by_sort = |q: f64| {
            let pos = q * (sorted.len() - 1) as f64;
            let (i, frac) = (pos.floor() as usize, pos - pos.floor());
            match sorted.get(i + 1) {
                Some(next) => sorted[i] + frac * (next - sorted[i]),
                None => sorted[i],
            }
        };
        for qs in [
            vec![0.1, 0.9],
            vec![0.9, 0.1],
            vec![0.0, 0.5, 0.5, 1.0],
            vec![0.33],
        ] {
            let got = quantiles(|t| v[t], 0..v.len(), &qs);
            for (q, g) in qs.iter().zip(&got) {
                assert_eq!(g.to_bits(), by_sort(*q).to_bits(), "q = {q} of {qs:?}");
            }
        }
    }
}
