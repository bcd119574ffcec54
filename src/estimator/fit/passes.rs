//! Passes over the series: w_t = x_t - sum f_m(U_t) x_{t-m} with f interpolated on the
//! grid (searched or read from an interval index), and the MA filter that turns w into
//! the residuals e_t = w_t - sum b_m e_{t-m}, in chunks that run in parallel, with the
//! RSS and the Gauss-Newton sums of the b-step in the same pass.

use crate::estimator::arma::PassState;
use crate::estimator::arma::PassSums;
use crate::estimator::arma::pass_rows;
use crate::estimator::moments::ABOVE_GRID;
use crate::estimator::moments::BELOW_GRID;
use crate::estimator::moments::IntervalIndex;
use crate::estimator::moments::IntervalLookup;
use crate::estimator::problem::GridFit;
use crate::estimator::series::Centred;
use std::ops::Range;

/// e_t = x_t - sum f_m(U_t) x_{t-m} - sum b_m e_{t-m}, zeros before the first sample,
/// U_t = x_{t-d} (0 before the first sample). First w_t = x_t - sum f_m(U_t) x_{t-m}
/// (independent rows: chunks in parallel), then the MA recursion in place; the same
/// operations in the same order as the one-loop recursion, so the same bits.
pub fn residuals<'a>(
    x: impl Into<Centred<'a>>,
    d: usize,
    grid: &[f64],
    coef: &GridFit,
    b: &[f64],
    e: &mut [f64],
) {
    let x = x.into();
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
pub fn residuals_indexed<'a>(
    x: impl Into<Centred<'a>>,
    d: usize,
    grid: &[f64],
    coef: &GridFit,
    b: &[f64],
    e: &mut [f64],
    index: &IntervalIndex,
) {
    let x = x.into();
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
pub(super) struct CellSegment<const P: usize> {
    pub(super) base: f64,
    pub(super) width: f64,
    pub(super) fa: [f64; P],
    pub(super) diff: [f64; P],
}

/// The [`CellSegment`] of every interval, from the grid cell of each (`cells`).
pub(super) fn cell_segments<const P: usize>(
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
pub(super) fn w_indexed<const P: usize>(
    x: Centred,
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
pub(super) fn w_indexed_span<const P: usize>(
    x: Centred,
    d: usize,
    segs: &[CellSegment<P>],
    index: &IntervalIndex,
    t0: usize,
    out: &mut [f64],
) {
    for (i, w) in out.iter_mut().enumerate() {
        let t = t0 + i;
        let r = &segs[index.interval(t)];
        let u = x.at(t - d);
        let lam = (u - r.base) / r.width;
        let mut s = x.at(t);
        for m in 0..P {
            s -= (r.fa[m] + lam * r.diff[m]) * x.at(t - m - 1);
        }
        *w = s;
    }
}

/// The w of [`residuals_indexed`] for any span of rows: `fill(t0, out)` writes w_t for
/// rows t0..t0 + out.len() (the same operations, so the same bits: the warm rows one
/// by one when the span starts at row 0, which it then covers). None for p > 4.
pub(super) fn w_indexed_filler<'a>(
    x: Centred<'a>,
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
pub(super) fn w_head(x: Centred, d: usize, grid: &[f64], coef: &GridFit, e: &mut [f64]) {
    let lookup = IntervalLookup::new(grid);
    let p = coef.p;
    let mut f = [0.0f64; 8];
    for (t, w) in e.iter_mut().enumerate() {
        let u = if t >= d { x.at(t - d) } else { 0.0 };
        eval_cell(coef, grid, grid_cell(grid, &lookup, u), u, &mut f[..p]);
        let mut s = x.at(t);
        for m in 0..p.min(t) {
            s -= f[m] * x.at(t - m - 1);
        }
        *w = s;
    }
}

/// w_t for rows `warm..` (every lag inside the series: the sums without the checks),
/// chunks in parallel, `cell(t, U_t)` giving the grid cell.
pub(super) fn w_rows<F: Fn(usize, f64) -> u32 + Sync>(
    x: Centred,
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
                let u = x.at(t - d);
                eval_cell(coef, grid, cell(t, u), u, f);
                let mut s = x.at(t);
                for (m, fm) in f.iter().enumerate() {
                    s -= fm * x.at(t - m - 1);
                }
                *w = s;
            }
        });
}

/// The grid cell of `u` as [`IntervalIndex::grid_cells`] gives it, except that
/// u = grid[0] counts as below the grid (the interpolation there gives the same value).
#[inline]
pub(super) fn grid_cell(grid: &[f64], lookup: &IntervalLookup, u: f64) -> u32 {
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
pub(super) fn eval_cell(coef: &GridFit, grid: &[f64], cell: u32, u: f64, out: &mut [f64]) {
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
pub(super) fn eval_with(
    coef: &GridFit,
    grid: &[f64],
    lookup: &IntervalLookup,
    u: f64,
    out: &mut [f64],
) {
    eval_cell(coef, grid, grid_cell(grid, lookup, u), u, out)
}

/// Turns w (in `buf`) into the residuals e_t = w_t - sum b_m e_{t-m} in place, zeros
/// before the first sample (e_t needs only earlier e, already in place), and returns
/// their RSS over t >= `start` ([`rss_from`]'s sum, the same bits). For q = 1, 2 on
/// series of two [`FILTER_CHUNK`]s or more the recursion runs in chunks, in parallel,
/// with every e_t exact ([`ma_filter_chunked`]); when a chunk cannot be made exact
/// (b near the edge of invertibility) `refill` puts w back into `buf` and the
/// recursion runs serially.
pub(super) fn ma_filter_rss(
    buf: &mut [f64],
    b: &[f64],
    start: usize,
    refill: impl FnOnce(&mut [f64]),
) -> f64 {
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
pub(super) fn ma_filter_fixed<const Q: usize>(
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
pub(super) fn filter_rows<const Q: usize>(
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
pub(super) fn ma_filter_chunked<const Q: usize>(
    buf: &mut [f64],
    bb: &[f64; Q],
    start: usize,
) -> Option<f64> {
    let mut rss = 0.0;
    let run = |rows: &mut [f64], t0: usize, eh: &mut [f64; Q]| filter_rows(rows, bb, t0, eh, start);
    let same =
        |a: &[f64; Q], o: &[f64; Q]| a.iter().zip(o).all(|(u, v)| u.to_bits() == v.to_bits());
    let add = |h: &f64, r: &f64| rss += h + r;
    chunked_in_place(buf, None, [0.0f64; Q], run, same, add).then_some(rss)
}

/// Writes w_t for rows t0..t0 + out.len() into `out` (`fill(t0, out)`).
pub(super) type SpanFill<'a> = dyn Fn(usize, &mut [f64]) + Sync + 'a;

/// `arma_pass`'s row recursion with p = 0 (`pass_rows`; Box, Jenkins and Reinsel 7.2:
/// d e_t / d b_j = -e_{t-j} - sum_k b_k d e_{t-k} / d b_j) in place: each w_t of `rows`
/// (row t0 first) becomes e_t, the operations of [`filter_rows`]; returns the
/// Gauss-Newton sums of rows t >= `start`.
pub(super) fn gn_rows<const Q: usize>(
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
pub(super) fn chunked_in_place<S, A>(
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
pub(super) fn ma_filter_gn<const Q: usize>(
    buf: &mut [f64],
    b: &[f64; Q],
    start: usize,
    fill: Option<&SpanFill<'_>>,
    refill: impl FnOnce(&mut [f64]),
) -> PassSums<Q> {
    let zero = PassState::<0, Q, Q>::at(Centred::plain(&[]), 0);
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

/// How a sum of squares over n rows is grouped, the same wherever an RSS of
/// residuals is summed ([`rss_from`], the MA filters): a series shorter than two
/// [`FILTER_CHUNK`]s in one sequential sum (one group, its rest empty); a longer one
/// per chunk of [`FILTER_CHUNK`] rows, its first [`FILTER_LEAD`] rows and then the
/// rest, the chunk's (lead + rest) added to the total chunk after chunk (the order
/// [`ma_filter_chunked`] sums in). Yields (lead rows, rest rows) per group.
pub(super) fn rss_groups(n: usize) -> impl Iterator<Item = (Range<usize>, Range<usize>)> {
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
pub(super) fn rss_from(e: &[f64], start: usize) -> f64 {
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
