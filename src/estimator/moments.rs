//! The fast exact path: one pass over the data builds per-interval polynomial moment
//! tables; every grid fit for every bandwidth, and the exact RSS and trace of the
//! smoother, follow from the tables without touching the data again.
//!
//! Method (`shared/design/fast-exact-fits.md`, prototype `reference/exact_vc_moments.py`):
//! the Biweight is a polynomial on its support, so every entry of a local system is a
//! sum of V_a V_b (U_t - u_g)^s over the samples in the window, V = (X_1..X_p, y).
//! The breakpoints (every grid point and every window edge u_g +- h_j) cut the index
//! axis into elementary intervals; each window and each cell between grid points is an
//! exact union of intervals. The pass accumulates, for each interval e with centre c_e
//! and half-width s_e, M_e\[ab\]\[i\] = sum_{t in e} V_a V_b v^i with v = (U_t - c_e)/s_e
//! (|v| <= 1, no cancellation), i = 0..deg. Moments about any point u follow exactly
//! from the binomial theorem: sum V_a V_b (U - u)^s = sum_i C(s,i) s_e^i (c_e - u)^(s-i) M_e\[ab\]\[i\].
//! Sums of intervals are only ever added, never differenced (no prefix-sum
//! cancellation between far intervals): inside each cell between grid points the runs
//! of intervals from either edge are summed once (`Cells`), a window is its two edge
//! runs plus the whole cells between, and for one grid point the windows of all
//! bandwidths are nested, so its whole cells are summed once, from the nearest
//! outwards. A GCV ladder costs O(G (G + J)) recentrings of a moment block, whatever N.
//! The left-hand sides of the local systems depend on X and U only; an f-step at a
//! bandwidth already seen sums only the X_a y families ([`Families::Response`]) and
//! reuses them ([`LocalSystems`]); a second ladder over the same table with new
//! residuals ([`MomentTable::with_response`]) reuses the first one's, rung by rung, and
//! grows only the X_a y windows ([`MomentTable::fit_ladder_response`]).
//!
//! The pass runs over fixed blocks of rows (their size depends on N only), blocks in
//! parallel, block tables added in block order: the result does not depend on the
//! number of threads. The interval of a sample is found through a uniform bucket
//! table over the breakpoints (a guess, corrected by stepping to the exact interval),
//! not by a binary search.

use rayon::prelude::*;

use super::kernel::{BIWEIGHT, binomial_table, poly_mul};
use super::linalg::{SMALL_N, SpdFactor, small_spd_factor};
use super::problem::{GridFit, VcProblem};

/// Which products of V = (X_1..X_p, y) a table holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Families {
    /// Every pair V_a V_b (a <= b) and the constant 1: local systems, RSS, trace.
    All,
    /// X_a y only: the right-hand sides of the local systems, the only part that
    /// changes between alternations (X and U do not).
    Response,
    /// X_a y and y y: every family that holds the response (what a GCV ladder needs
    /// anew when only the residuals changed, [`MomentTable::with_response`]).
    ResponseAndSquare,
    /// X_a X_b (a <= b) and the constant 1: the design alone, what the local systems'
    /// left-hand sides, the smoother's trace and the standard errors need (they do
    /// not depend on the response).
    Design,
}

/// Moment tables over the elementary intervals of `breaks`.
pub struct MomentTable {
    /// Sorted, distinct breakpoints; interval e covers [breaks[e-1], breaks\[e\]).
    pub breaks: Vec<f64>,
    centre: Vec<f64>,
    half: Vec<f64>,
    pub p: usize,
    /// Families: pairs a <= b of V = (X_1..X_p, y), then the constant 1.
    nfam: usize,
    fam_of: Vec<usize>,
    /// The (a, b) of each family; index p + 1 is the constant 1.
    pairs: Vec<(usize, usize)>,
    /// Highest power of v kept.
    pub deg: usize,
    /// E x nfam x (deg + 1).
    m: Vec<f64>,
    /// Samples per interval.
    count: Vec<u64>,
    /// Lower and upper edge of each interval.
    lo_edge: Vec<f64>,
    hi_edge: Vec<f64>,
    /// Cell sums for the last grid asked about (built on first use).
    cells: std::sync::Mutex<Option<std::sync::Arc<Cells>>>,
}

/// A run of intervals summed into one moment block: its moments are powers of
/// (U - anchor)/scale, `count` samples.
#[derive(Clone, Copy)]
struct Piece<'a> {
    m: &'a [f64],
    anchor: f64,
    scale: f64,
    count: u64,
}

/// The whole cells of a growing window of grid point g, summed about u_g: cells
/// `left..=g` and `g+1..=right` (none at first), each side in its own sum, from the
/// nearest cell outwards. A window's sum is then the same whichever narrower windows
/// were summed before it: a ladder's fit at one bandwidth has the same bits whatever
/// other bandwidths it is computed with, and the same as a window summed alone.
struct WholeCells {
    g: usize,
    left: usize,
    right: usize,
    acc_left: Vec<f64>,
    acc_right: Vec<f64>,
    count: u64,
}

impl WholeCells {
    fn new(table: &MomentTable, g: usize) -> Self {
        Self::for_fams(table, g, table.nfam)
    }

    /// Sums of `nfam` families (all of the table's, or a subset).
    fn for_fams(table: &MomentTable, g: usize, nfam: usize) -> Self {
        let width = nfam * (table.deg + 1);
        WholeCells {
            g,
            left: g + 1,
            right: g,
            acc_left: vec![0.0; width],
            acc_right: vec![0.0; width],
            count: 0,
        }
    }
}

/// The intervals grouped by the cells between grid points (cell c lies between grid
/// points c-1 and c; cell 0 below the first, cell G above the last), with every run of
/// intervals that starts or ends at a cell's edge summed once:
/// `prefix[e]` = intervals first(c)..=e about the cell's lower edge, scaled by the
/// run's length; `suffix[e]` = intervals e..=last(c) about the cell's upper edge.
/// A window (g, h) is then the suffix that holds its left edge, the whole cells
/// between, and the prefix that holds its right edge: O(cells in the window)
/// recentrings instead of O(intervals in the window). Each run is anchored at the
/// cell edge nearest the grid point it is shifted to, and lies inside the window, so
/// the binomial shift has |a| + |b| <= 1 (no coefficient above 1 in the scaled powers,
/// as with single intervals).
#[derive(Clone)]
struct Cells {
    grid: Vec<f64>,
    /// Cell of each interval; first and last interval of each cell.
    cell_of: Vec<usize>,
    first: Vec<usize>,
    last: Vec<usize>,
    prefix: Vec<f64>,
    prefix_scale: Vec<f64>,
    prefix_count: Vec<u64>,
    suffix: Vec<f64>,
    suffix_scale: Vec<f64>,
    suffix_count: Vec<u64>,
}

/// The left-hand sides of the local systems at one bandwidth: S_g, the support's
/// sample count and kernel mass for every grid point.
#[derive(Clone)]
pub struct LocalSystems {
    grid: Vec<f64>,
    pub h: f64,
    p: usize,
    points: Vec<(Vec<f64>, u64, f64)>,
    /// Each point's factored S_g ([`small_spd_factor`]; inner None: singular) where
    /// 2p <= [`SMALL_N`] and the support has 2p samples or more, so that the fits
    /// of each new response solve by substitution alone; outer None: solved
    /// afresh by [`GridFit::set_point`].
    factors: Vec<Option<Option<SpdFactor>>>,
}

impl LocalSystems {
    /// Systems at `h` from each grid point's (S_g, count, kernel mass), factored.
    fn new(grid: &[f64], h: f64, p: usize, points: Vec<(Vec<f64>, u64, f64)>) -> Self {
        let n = 2 * p;
        let factors = points
            .iter()
            .map(|(s, count, _)| {
                (n <= SMALL_N && *count as usize >= n).then(|| small_spd_factor(s, n))
            })
            .collect();
        LocalSystems {
            grid: grid.to_vec(),
            h,
            p,
            points,
            factors,
        }
    }

    /// The grid points they are at.
    pub fn grid(&self) -> &[f64] {
        &self.grid
    }

    /// The systems' status, inverses S_g^-1, counts and kernel masses as a
    /// [`GridFit`] with f = 0 and slope 0 (a zero right-hand side): what the trace
    /// and the standard errors read, which do not depend on the response.
    pub fn design_fit(&self) -> GridFit {
        let zero = vec![0.0; 2 * self.p];
        self.fit_with(|_| &zero)
    }

    /// The local fits with these left-hand sides and the right-hand side `rhs(g)` at
    /// grid point g ([`GridFit::set_point`]).
    fn fit_with<'r>(&self, rhs: impl Fn(usize) -> &'r [f64]) -> GridFit {
        let mut fit = GridFit::new(self.grid.len(), self.p, self.h);
        for (g, ((s, count, mass), factor)) in self.points.iter().zip(&self.factors).enumerate() {
            match factor {
                Some(f) => fit.set_point_factored(g, f.as_ref(), rhs(g), *count, *mass),
                None => fit.set_point(g, s, rhs(g), *count, *mass),
            }
        }
        fit
    }
}

/// A(f, r) = sum_k kappa_k acc[f][k + r] / h^(k + r): the kernel-weighted moment
/// sum_t L(w_t) V_a V_b w_t^r, w = (U - u_g)/h, of the kernel polynomial
/// L(w) = sum_k kappa_k w^k (`kern`: the Biweight for fits, its square for standard
/// errors), from moments about u_g in unscaled powers (`acc`, rows of `d1`).
fn kernel_contraction<'a>(
    acc: &'a [f64],
    d1: usize,
    h: f64,
    kern: &'a [f64],
) -> impl Fn(usize, usize) -> f64 + 'a {
    let mut hp = [1.0f64; 13];
    for k in 1..13 {
        hp[k] = hp[k - 1] / h;
    }
    move |f: usize, r: usize| -> f64 {
        kern.iter()
            .enumerate()
            .filter(|(_, c)| **c != 0.0)
            .map(|(k, c)| c * acc[f * d1 + k + r] * hp[k + r])
            .sum()
    }
}

/// T = sum K(w) Z y with Z = (X, w X) from the weighted moments `a_of(family, r)`,
/// X_a y being family `fy(a)` (its index in a full table, or its row in a table of
/// the X_a y families alone).
fn local_rhs_of(
    p: usize,
    a_of: &impl Fn(usize, usize) -> f64,
    fy: impl Fn(usize) -> usize,
) -> Vec<f64> {
    let mut rhs = vec![0.0; 2 * p];
    for a in 0..p {
        rhs[a] = a_of(fy(a), 0);
        rhs[p + a] = a_of(fy(a), 1);
    }
    rhs
}

/// Adds moments `src` (nfam rows of deg + 1, powers of (U - c_src)/s_src) to `acc` as
/// powers 0..=smax of (U - c_dst)/s_dst: with a = s_src/s_dst, b = (c_src - c_dst)/s_dst,
/// ((U - c_dst)/s_dst)^s = sum_i C(s,i) a^i b^(s-i) ((U - c_src)/s_src)^i.
/// With `s_dst = 1` the powers are unscaled, (U - c_dst)^s.
#[allow(clippy::too_many_arguments)]
#[inline]
fn recentre_into(
    src: &[f64],
    (c_src, s_src): (f64, f64),
    (c_dst, s_dst): (f64, f64),
    nfam: usize,
    d1: usize,
    smax: usize,
    binom: &[[f64; 13]; 13],
    acc: &mut [f64],
) {
    let (a, b) = (s_src / s_dst, (c_src - c_dst) / s_dst);
    match smax {
        2 => recentre_fixed::<3>(src, a, b, recentre_all(nfam), d1, binom, acc),
        5 => recentre_fixed::<6>(src, a, b, recentre_all(nfam), d1, binom, acc),
        6 => recentre_fixed::<7>(src, a, b, recentre_all(nfam), d1, binom, acc),
        10 => recentre_fixed::<11>(src, a, b, recentre_all(nfam), d1, binom, acc),
        _ => {
            let mut sp = [1.0f64; 13];
            let mut dp = [1.0f64; 13];
            for k in 1..=smax {
                sp[k] = sp[k - 1] * a;
                dp[k] = dp[k - 1] * b;
            }
            for f in 0..nfam {
                let mrow = &src[f * d1..(f + 1) * d1];
                let arow = &mut acc[f * d1..(f + 1) * d1];
                for s in 0..=smax {
                    let mut sum = 0.0;
                    for i in 0..=s {
                        sum += binom[s][i] * sp[i] * dp[s - i] * mrow[i];
                    }
                    arow[s] += sum;
                }
            }
        }
    }
}

/// [`recentre_into`] for powers 0..S-1: the coefficient table C(s,i) a^i b^(s-i) built
/// once (same products in the same order as the general case) and shared by every
/// family. `rows` gives (family of `src`, row of `acc`): every family into its own row
/// ([`recentre_all`]), or a subset packed into the first rows of `acc`; a family's
/// sums have the same bits either way.
#[inline]
fn recentre_fixed<const S: usize>(
    src: &[f64],
    a: f64,
    b: f64,
    rows: impl Iterator<Item = (usize, usize)>,
    d1: usize,
    binom: &[[f64; 13]; 13],
    acc: &mut [f64],
) {
    let mut sp = [1.0f64; S];
    let mut dp = [1.0f64; S];
    for k in 1..S {
        sp[k] = sp[k - 1] * a;
        dp[k] = dp[k - 1] * b;
    }
    let mut coef = [[0.0f64; S]; S];
    for s in 0..S {
        for i in 0..=s {
            coef[s][i] = binom[s][i] * sp[i] * dp[s - i];
        }
    }
    for (f, r) in rows {
        let mrow: &[f64; S] = src[f * d1..f * d1 + S].try_into().unwrap();
        let arow: &mut [f64; S] = (&mut acc[r * d1..r * d1 + S]).try_into().unwrap();
        for s in 0..S {
            let mut sum = 0.0;
            for i in 0..=s {
                sum += coef[s][i] * mrow[i];
            }
            arow[s] += sum;
        }
    }
}

/// Every family of `nfam` into its own row: the `rows` of [`recentre_fixed`].
fn recentre_all(nfam: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..nfam).map(|f| (f, f))
}

/// Adds `ratio^s` times moments `src` to `acc`: the same samples about the same anchor,
/// powers of (U - c)/s_src rewritten as powers of (U - c)/s_dst, ratio = s_src/s_dst.
#[inline]
fn rescale_into(src: &[f64], ratio: f64, nfam: usize, d1: usize, acc: &mut [f64]) {
    let mut rp = [1.0f64; 13];
    for k in 1..d1 {
        rp[k] = rp[k - 1] * ratio;
    }
    for f in 0..nfam {
        for s in 0..d1 {
            acc[f * d1 + s] += rp[s] * src[f * d1 + s];
        }
    }
}

impl Clone for MomentTable {
    /// Every field, the cell sums of the last grid included (shared until one of the
    /// tables changes them: [`MomentTable::into_response`] copies them then).
    fn clone(&self) -> Self {
        let cells = self.cells.lock().unwrap_or_else(|e| e.into_inner()).clone();
        MomentTable {
            breaks: self.breaks.clone(),
            centre: self.centre.clone(),
            half: self.half.clone(),
            p: self.p,
            nfam: self.nfam,
            fam_of: self.fam_of.clone(),
            pairs: self.pairs.clone(),
            deg: self.deg,
            m: self.m.clone(),
            count: self.count.clone(),
            lo_edge: self.lo_edge.clone(),
            hi_edge: self.hi_edge.clone(),
            cells: std::sync::Mutex::new(cells),
        }
    }
}

impl MomentTable {
    fn n_intervals(&self) -> usize {
        self.breaks.len() + 1
    }

    fn fam(&self, a: usize, b: usize) -> usize {
        let nv = self.p + 1;
        self.fam_of[a.min(b) * nv + a.max(b)]
    }

    fn one_fam(&self) -> usize {
        self.nfam - 1
    }

    /// Index of an exact breakpoint value.
    fn break_index(&self, value: f64) -> usize {
        self.breaks
            .binary_search_by(|b| b.total_cmp(&value))
            .unwrap_or_else(|_| panic!("{value} is not a breakpoint"))
    }

    /// Builds the tables of every family in one pass. `umin`, `umax` bound the index
    /// values (they centre the two unbounded end intervals).
    pub fn build(
        prob: &VcProblem,
        breaks: Vec<f64>,
        umin: f64,
        umax: f64,
        deg: usize,
    ) -> MomentTable {
        Self::build_families(prob, breaks, umin, umax, deg, Families::All)
    }

    /// [`MomentTable::build`] for a chosen set of families.
    pub fn build_families(
        prob: &VcProblem,
        breaks: Vec<f64>,
        umin: f64,
        umax: f64,
        deg: usize,
        families: Families,
    ) -> MomentTable {
        Self::build_with(
            prob,
            sorted_breaks(breaks),
            None,
            (umin, umax),
            deg,
            families,
        )
    }

    /// [`MomentTable::build_families`] on the breakpoints of `index`, each row's
    /// interval read from it instead of found: the same table, bit for bit.
    pub fn build_indexed(
        prob: &VcProblem,
        index: &IntervalIndex,
        umin: f64,
        umax: f64,
        deg: usize,
        families: Families,
    ) -> MomentTable {
        assert_eq!(index.start, prob.start, "an index of the same rows");
        assert_eq!(index.rows.len(), prob.n_rows(), "an index of the same rows");
        let breaks = index.breaks.clone();
        Self::build_with(prob, breaks, Some(index), (umin, umax), deg, families)
    }

    /// The table of `families` over `index`'s breakpoints when there is one (each
    /// row's interval read from it, [`MomentTable::build_indexed`]), else over
    /// `breaks()` ([`MomentTable::build_families`]): the same table either way
    /// when `breaks()` are the index's.
    pub fn build_over(
        prob: &VcProblem,
        index: Option<&IntervalIndex>,
        breaks: impl FnOnce() -> Vec<f64>,
        (umin, umax): (f64, f64),
        deg: usize,
        families: Families,
    ) -> MomentTable {
        match index {
            Some(ix) => Self::build_indexed(prob, ix, umin, umax, deg, families),
            None => Self::build_families(prob, breaks(), umin, umax, deg, families),
        }
    }

    fn build_with(
        prob: &VcProblem,
        breaks: Vec<f64>,
        index: Option<&IntervalIndex>,
        (umin, umax): (f64, f64),
        deg: usize,
        families: Families,
    ) -> MomentTable {
        assert!(deg <= 12, "moments up to degree 12");
        let p = prob.p;
        let nv = p + 1;
        let mut fam_of = vec![usize::MAX; nv * nv];
        let mut pairs = Vec::new();
        match families {
            Families::All => {
                for a in 0..nv {
                    for b in a..nv {
                        fam_of[a * nv + b] = pairs.len();
                        pairs.push((a, b));
                    }
                }
                pairs.push((nv, nv)); // the constant
            }
            Families::Design => {
                for a in 0..p {
                    for b in a..p {
                        fam_of[a * nv + b] = pairs.len();
                        pairs.push((a, b));
                    }
                }
                pairs.push((nv, nv));
            }
            Families::Response | Families::ResponseAndSquare => {
                for a in 0..p {
                    fam_of[a * nv + p] = pairs.len();
                    pairs.push((a, p));
                }
                if families == Families::ResponseAndSquare {
                    fam_of[p * nv + p] = pairs.len();
                    pairs.push((p, p));
                }
            }
        }
        let nfam = pairs.len();
        let e_count = breaks.len() + 1;
        let mut centre = vec![0.0; e_count];
        let mut half = vec![0.0; e_count];
        let mut lo_edge = vec![0.0; e_count];
        let mut hi_edge = vec![0.0; e_count];
        for e in 0..e_count {
            let lo = if e == 0 {
                umin.min(breaks[0])
            } else {
                breaks[e - 1]
            };
            let hi = if e == e_count - 1 {
                umax.max(breaks[e_count - 2])
            } else {
                breaks[e]
            };
            centre[e] = 0.5 * (lo + hi);
            half[e] = (0.5 * (hi - lo)).max(f64::MIN_POSITIVE);
            lo_edge[e] = lo;
            hi_edge[e] = hi;
        }
        let mut t = MomentTable {
            breaks,
            centre,
            half,
            p,
            nfam,
            fam_of,
            pairs,
            deg,
            m: vec![0.0; e_count * nfam * (deg + 1)],
            count: vec![0; e_count],
            lo_edge,
            hi_edge,
            cells: std::sync::Mutex::new(None),
        };
        t.accumulate(prob, index);
        t
    }

    /// The cell sums for `grid` (every grid point must be a breakpoint), built on the
    /// first call for a grid and kept for the next calls with the same grid.
    fn cells(&self, grid: &[f64]) -> std::sync::Arc<Cells> {
        let mut slot = self.cells.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(c) = slot.as_ref()
            && c.grid == grid
        {
            return c.clone();
        }
        let c = std::sync::Arc::new(self.build_cells(grid));
        *slot = Some(c.clone());
        c
    }

    fn build_cells(&self, grid: &[f64]) -> Cells {
        let ne = self.n_intervals();
        let width = self.nfam * (self.deg + 1);
        let d1 = self.deg + 1;
        let gidx: Vec<usize> = grid.iter().map(|g| self.break_index(*g)).collect();
        let gl = grid.len();
        let mut first = Vec::with_capacity(gl + 1);
        let mut last = Vec::with_capacity(gl + 1);
        first.push(0);
        for k in 0..gl {
            last.push(gidx[k]);
            first.push(gidx[k] + 1);
        }
        last.push(ne - 1);
        let mut cell_of = vec![0; ne];
        for c in 0..=gl {
            for e in first[c]..=last[c] {
                cell_of[e] = c;
            }
        }
        let binom = binomial_table();
        // one cell's prefix and suffix runs, cells in parallel
        type Runs = (Vec<f64>, Vec<f64>, Vec<u64>, Vec<f64>, Vec<f64>, Vec<u64>);
        let per_cell: Vec<Runs> = (0..=gl)
            .into_par_iter()
            .map(|c| {
                let (f, l) = (first[c], last[c]);
                let len = l + 1 - f;
                let (lo_c, hi_c) = (self.lo_edge[f], self.hi_edge[l]);
                let mut pm = vec![0.0; len * width];
                let mut ps = vec![0.0; len];
                let mut pc = vec![0u64; len];
                for (i, e) in (f..=l).enumerate() {
                    let s = (self.hi_edge[e] - lo_c).max(f64::MIN_POSITIVE);
                    ps[i] = s;
                    let (done, rest) = pm.split_at_mut(i * width);
                    let cur = &mut rest[..width];
                    if i > 0 {
                        let prev = &done[(i - 1) * width..];
                        rescale_into(prev, ps[i - 1] / s, self.nfam, d1, cur);
                        pc[i] = pc[i - 1];
                    }
                    recentre_into(
                        &self.m[e * width..(e + 1) * width],
                        (self.centre[e], self.half[e]),
                        (lo_c, s),
                        self.nfam,
                        d1,
                        self.deg,
                        &binom,
                        cur,
                    );
                    pc[i] += self.count[e];
                }
                let mut sm = vec![0.0; len * width];
                let mut ss = vec![0.0; len];
                let mut sc = vec![0u64; len];
                for (i, e) in (f..l + 1).enumerate().rev() {
                    let s = (hi_c - self.lo_edge[e]).max(f64::MIN_POSITIVE);
                    ss[i] = s;
                    let (head, done) = sm.split_at_mut((i + 1) * width);
                    let cur = &mut head[i * width..];
                    if i + 1 < len {
                        rescale_into(&done[..width], ss[i + 1] / s, self.nfam, d1, cur);
                        sc[i] = sc[i + 1];
                    }
                    recentre_into(
                        &self.m[e * width..(e + 1) * width],
                        (self.centre[e], self.half[e]),
                        (hi_c, s),
                        self.nfam,
                        d1,
                        self.deg,
                        &binom,
                        cur,
                    );
                    sc[i] += self.count[e];
                }
                (pm, ps, pc, sm, ss, sc)
            })
            .collect();
        let mut cells = Cells {
            grid: grid.to_vec(),
            cell_of,
            first,
            last,
            prefix: Vec::with_capacity(ne * width),
            prefix_scale: Vec::with_capacity(ne),
            prefix_count: Vec::with_capacity(ne),
            suffix: Vec::with_capacity(ne * width),
            suffix_scale: Vec::with_capacity(ne),
            suffix_count: Vec::with_capacity(ne),
        };
        for (pm, ps, pc, sm, ss, sc) in per_cell {
            cells.prefix.extend(pm);
            cells.prefix_scale.extend(ps);
            cells.prefix_count.extend(pc);
            cells.suffix.extend(sm);
            cells.suffix_scale.extend(ss);
            cells.suffix_count.extend(sc);
        }
        cells
    }

    /// Intervals first(cell(e))..=e, about the cell's lower edge.
    fn prefix<'c>(&self, cells: &'c Cells, e: usize) -> Piece<'c> {
        let c = cells.cell_of[e];
        let anchor = self.lo_edge[cells.first[c]];
        self.run_piece(
            e,
            anchor,
            (&cells.prefix, &cells.prefix_scale, &cells.prefix_count),
        )
    }

    /// Intervals e..=last(cell(e)), about the cell's upper edge.
    fn suffix<'c>(&self, cells: &'c Cells, e: usize) -> Piece<'c> {
        let c = cells.cell_of[e];
        let anchor = self.hi_edge[cells.last[c]];
        self.run_piece(
            e,
            anchor,
            (&cells.suffix, &cells.suffix_scale, &cells.suffix_count),
        )
    }

    /// The run of cell sums `runs` (moments, scales, counts) that ends or starts at e.
    fn run_piece<'c>(
        &self,
        e: usize,
        anchor: f64,
        (m, scale, count): (&'c [f64], &'c [f64], &'c [u64]),
    ) -> Piece<'c> {
        let width = self.nfam * (self.deg + 1);
        Piece {
            m: &m[e * width..(e + 1) * width],
            anchor,
            scale: scale[e],
            count: count[e],
        }
    }

    /// Adds a piece's moments about `u` (unscaled powers 0..=smax) to `acc`.
    fn add_piece(
        &self,
        piece: Piece,
        u: f64,
        smax: usize,
        binom: &[[f64; 13]; 13],
        acc: &mut [f64],
    ) -> u64 {
        recentre_into(
            piece.m,
            (piece.anchor, piece.scale),
            (u, 1.0),
            self.nfam,
            self.deg + 1,
            smax,
            binom,
            acc,
        );
        piece.count
    }

    /// [`MomentTable::add_piece`] for the families `fams` only (row i of `acc` takes
    /// family fams[i]), powers 0..=6 (what the local fits read; the table's degree
    /// at least 6): the coefficient table of [`recentre_fixed`] built once for every
    /// family, each family summed with the same operations, so its sums have the bits
    /// of the all-family version (`recentre_into` with s_dst = 1 gives a = scale and
    /// b = anchor - u exactly).
    fn add_piece_fams(
        &self,
        piece: Piece,
        u: f64,
        binom: &[[f64; 13]; 13],
        fams: &[usize],
        acc: &mut [f64],
    ) -> u64 {
        let d1 = self.deg + 1;
        assert!(d1 >= 7, "powers up to 6 need a table of degree 6 or more");
        let (a, b) = (piece.scale, piece.anchor - u);
        let rows = fams.iter().enumerate().map(|(r, &f)| (f, r));
        recentre_fixed::<7>(piece.m, a, b, rows, d1, binom, acc);
        piece.count
    }

    /// Moments of window (g, h) about u_g, unscaled powers 0..=smax, and its sample
    /// count: the suffix holding its left edge, the whole cells between (nearest
    /// first), the prefix holding its right edge.
    fn window(
        &self,
        cells: &Cells,
        g: usize,
        h: f64,
        smax: usize,
        binom: &[[f64; 13]; 13],
    ) -> (Vec<f64>, u64) {
        let mut whole = WholeCells::new(self, g);
        self.grown_window(cells, &mut whole, h, smax, binom, None)
    }

    /// Window (g, h) from `whole`, the whole cells already summed for a narrower
    /// window of the same grid point: adds the cells that (g, h) now holds whole
    /// (left ones from the nearest outwards, then right ones), and returns the whole
    /// cells plus its two edge runs, with the sample count. Every family of the table,
    /// or the families `fams` only when given (`whole` made for them,
    /// [`WholeCells::for_fams`]): the same bits for those families.
    fn grown_window(
        &self,
        cells: &Cells,
        whole: &mut WholeCells,
        h: f64,
        smax: usize,
        binom: &[[f64; 13]; 13],
        fams: Option<&[usize]>,
    ) -> (Vec<f64>, u64) {
        let add = |piece: Piece, u: f64, acc: &mut [f64]| match fams {
            None => self.add_piece(piece, u, smax, binom, acc),
            Some(fs) => {
                assert_eq!(smax, 6, "a subset of families is summed to power 6");
                self.add_piece_fams(piece, u, binom, fs, acc)
            }
        };
        let g = whole.g;
        let ug = cells.grid[g];
        let (lo, hi) = self.window_edges(cells, g, h);
        let cl = lo.map_or(g, |e| cells.cell_of[e]);
        let ch = hi.map_or(g + 1, |e| cells.cell_of[e]);
        while whole.left > cl + 1 {
            whole.left -= 1;
            let piece = self.suffix(cells, cells.first[whole.left]);
            whole.count += add(piece, ug, &mut whole.acc_left);
        }
        while whole.right + 1 < ch {
            whole.right += 1;
            let piece = self.prefix(cells, cells.last[whole.right]);
            whole.count += add(piece, ug, &mut whole.acc_right);
        }
        let mut acc = whole.acc_left.clone();
        for (a, r) in acc.iter_mut().zip(&whole.acc_right) {
            *a += r;
        }
        let mut count = whole.count;
        if let Some(lo) = lo {
            count += add(self.suffix(cells, lo), ug, &mut acc);
        }
        if let Some(hi) = hi {
            count += add(self.prefix(cells, hi), ug, &mut acc);
        }
        (acc, count)
    }

    /// S = sum K(w) Z Z' with Z = (X, w X) (row-major 2p x 2p) from the weighted
    /// moments `a_of(family, r)` of [`kernel_contraction`].
    fn local_lhs(&self, a_of: &impl Fn(usize, usize) -> f64) -> Vec<f64> {
        let p = self.p;
        let n = 2 * p;
        let mut s = vec![0.0; n * n];
        for a in 0..p {
            for b in 0..p {
                let f = self.fam(a, b);
                let (m0, m1, m2) = (a_of(f, 0), a_of(f, 1), a_of(f, 2));
                s[a * n + b] = m0;
                s[a * n + p + b] = m1;
                s[(p + a) * n + b] = m1;
                s[(p + a) * n + p + b] = m2;
            }
        }
        s
    }

    /// T = sum K(w) Z y (2p) from the weighted moments `a_of(family, r)`.
    fn local_rhs(&self, a_of: &impl Fn(usize, usize) -> f64) -> Vec<f64> {
        local_rhs_of(self.p, a_of, |a| self.fam(a, self.p))
    }

    /// The first and last interval of window (g, h): (lo, hi) with lo in a cell at or
    /// left of u_g and hi right of it; None for a side that is empty because u_g -+ h
    /// rounds to u_g (h below half an ulp of u_g).
    fn window_edges(&self, cells: &Cells, g: usize, h: f64) -> (Option<usize>, Option<usize>) {
        let ug = cells.grid[g];
        // the last interval left of u_g ends at u_g
        let gi = cells.last[g];
        let lo = self.break_index(ug - h) + 1;
        let hi = self.break_index(ug + h);
        ((lo <= gi).then_some(lo), (hi > gi).then_some(hi))
    }

    /// The pass: blocks of rows of a size set by N alone, `threads` blocks at a time,
    /// block tables added in block order (the same bits for any number of threads).
    fn accumulate(&mut self, prob: &VcProblem, index: Option<&IntervalIndex>) {
        match index {
            Some(ix) => {
                let (rows, start) = (&ix.rows[..], prob.start);
                self.accumulate_find(prob, &|t: usize, _u: f64| rows[t - start] as usize)
            }
            None => {
                let lookup = IntervalLookup::new(&self.breaks);
                self.accumulate_find(prob, &|_t: usize, u: f64| lookup.find(u))
            }
        }
    }

    fn accumulate_find<F: Fn(usize, f64) -> usize + Sync>(&mut self, prob: &VcProblem, find: &F) {
        match self.deg + 1 {
            3 => self.accumulate_with::<3, F>(prob, find),
            4 => self.accumulate_with::<4, F>(prob, find),
            5 => self.accumulate_with::<5, F>(prob, find),
            6 => self.accumulate_with::<6, F>(prob, find),
            7 => self.accumulate_with::<7, F>(prob, find),
            8 => self.accumulate_with::<8, F>(prob, find),
            9 => self.accumulate_with::<9, F>(prob, find),
            10 => self.accumulate_with::<10, F>(prob, find),
            11 => self.accumulate_with::<11, F>(prob, find),
            12 => self.accumulate_with::<12, F>(prob, find),
            _ => self.accumulate_with::<13, F>(prob, find),
        }
    }

    /// The pass with `find(t, U_t)` giving row t's interval.
    fn accumulate_with<const D1: usize, F: Fn(usize, f64) -> usize + Sync>(
        &mut self,
        prob: &VcProblem,
        find: &F,
    ) {
        assert_eq!(self.deg + 1, D1, "tables of degree 2..=12");
        let n_rows = prob.n_rows();
        // blocks of a size set by N, p and the number of intervals (never by the
        // threads, nor by the families or degree: tables of other families over the
        // same breakpoints are summed in the same blocks, so a family has the same bits
        // in every table that holds it); many intervals (a GCV ladder's) get larger
        // blocks, so that zeroing and adding the block tables stays small beside the pass
        let table_len = self.m.len();
        let nv = prob.p + 1;
        let full_len = self.count.len() * (nv * (nv + 1) / 2 + 1) * 7;
        let block = (n_rows / 16)
            .clamp(1 << 17, 1 << 22)
            .max((n_rows / 4).min(4 * full_len));
        let starts: Vec<usize> = (prob.start..prob.x.len()).step_by(block).collect();
        let wave = rayon::current_num_threads().max(1);
        let ne = self.count.len();
        let response: Vec<(usize, usize)> = (0..prob.p).map(|a| (a, prob.p)).collect();
        // (a response of its own is read in `block_any`)
        let xy_only = self.pairs == response && prob.resp.is_none();
        // the sums leave the table while the blocks read it
        let mut total_m = std::mem::take(&mut self.m);
        let mut total_count = std::mem::take(&mut self.count);
        let this = &*self;
        // one table per block of a wave, allocated once and zeroed for each block (a
        // fresh large allocation per block costs a page fault per 4 KiB)
        let mut tables: Vec<(Vec<f64>, Vec<u64>)> = Vec::new();
        for group in starts.chunks(wave) {
            tables.resize_with(group.len().max(tables.len()), || {
                (vec![0.0; table_len], vec![0u64; ne])
            });
            group
                .par_iter()
                .zip(tables.par_iter_mut())
                .for_each(|(&s, (m, count))| {
                    m.fill(0.0);
                    count.fill(0);
                    let rows = s..(s + block).min(prob.x.len());
                    match (xy_only, prob.p) {
                        (true, 1) => this.block_xy::<D1, 1, F>(prob, find, rows, m, count),
                        (true, 2) => this.block_xy::<D1, 2, F>(prob, find, rows, m, count),
                        (true, 3) => this.block_xy::<D1, 3, F>(prob, find, rows, m, count),
                        _ => this.block_any::<D1, F>(prob, find, rows, m, count),
                    }
                });
            for (m, count) in &tables[..group.len()] {
                for (a, b) in total_m.iter_mut().zip(m) {
                    *a += b;
                }
                for (a, b) in total_count.iter_mut().zip(count) {
                    *a += b;
                }
            }
        }
        self.m = total_m;
        self.count = total_count;
    }

    /// One block of the pass, any families: adds V_a V_b v^k (k < D1) of rows `rows`
    /// to `m` (intervals x families x D1) and counts to `count`.
    fn block_any<const D1: usize, F: Fn(usize, f64) -> usize>(
        &self,
        prob: &VcProblem,
        find: &F,
        rows: std::ops::Range<usize>,
        m: &mut [f64],
        count: &mut [u64],
    ) {
        let width = self.nfam * D1;
        let (p, d) = (prob.p, prob.d);
        let (x, ee, bb) = (prob.x, prob.e, prob.b);
        let (centre, half, pairs) = (&self.centre[..], &self.half[..], &self.pairs[..]);
        let with_y = pairs.iter().any(|&(a, b)| a == p || b == p);
        // V = (X_1..X_p, y, 1)
        let mut v = [0.0f64; 8];
        v[p + 1] = 1.0;
        for t in rows {
            let u = x[t - d];
            let e = find(t, u);
            count[e] += 1;
            let z = (u - centre[e]) / half[e];
            let mut pw = [1.0f64; D1];
            for k in 1..D1 {
                pw[k] = pw[k - 1] * z;
            }
            for (mm, vm) in v[..p].iter_mut().enumerate() {
                *vm = x[t - 1 - mm];
            }
            // y_t = x_t - sum b_m e_{t-m} (as VcProblem::y), when a family holds it
            if with_y {
                v[p] = match prob.resp {
                    Some((r, lag)) => r[t - lag],
                    None => {
                        let mut y = x[t];
                        for (mm, bm) in bb.iter().enumerate() {
                            y -= bm * ee[t - mm - 1];
                        }
                        y
                    }
                };
            }
            let row = &mut m[e * width..(e + 1) * width];
            for (chunk, &(a, b)) in row.chunks_exact_mut(D1).zip(pairs) {
                let val = v[a] * v[b];
                let chunk: &mut [f64; D1] = chunk.try_into().unwrap();
                for k in 0..D1 {
                    chunk[k] += val * pw[k];
                }
            }
        }
    }

    /// [`MomentTable::block_any`] for the X_a y families ([`Families::Response`]) with
    /// p known at compile time: the same products in the same order, so the same
    /// bits, without the family loop's indirection.
    fn block_xy<const D1: usize, const P: usize, F: Fn(usize, f64) -> usize>(
        &self,
        prob: &VcProblem,
        find: &F,
        rows: std::ops::Range<usize>,
        m: &mut [f64],
        count: &mut [u64],
    ) {
        debug_assert_eq!(self.nfam, P);
        let width = P * D1;
        let d = prob.d;
        let (x, ee, bb) = (prob.x, prob.e, prob.b);
        let (centre, half) = (&self.centre[..], &self.half[..]);
        for t in rows {
            let u = x[t - d];
            let e = find(t, u);
            count[e] += 1;
            let z = (u - centre[e]) / half[e];
            let mut pw = [1.0f64; D1];
            for k in 1..D1 {
                pw[k] = pw[k - 1] * z;
            }
            let mut y = x[t];
            for (mm, bm) in bb.iter().enumerate() {
                y -= bm * ee[t - mm - 1];
            }
            let row: &mut [f64] = &mut m[e * width..(e + 1) * width];
            for a in 0..P {
                let val = x[t - 1 - a] * y;
                let chunk: &mut [f64; D1] = (&mut row[a * D1..(a + 1) * D1]).try_into().unwrap();
                for k in 0..D1 {
                    chunk[k] += val * pw[k];
                }
            }
        }
    }

    /// This table (every family) with the families that hold the response y summed
    /// anew for `prob` (the same series, index values and rows, other residuals or b):
    /// one pass of p + 1 families instead of all of them, the others kept. The result
    /// is the table [`MomentTable::build`] gives for `prob`, bit for bit (each family
    /// is summed alone, in the same order). `index`, when given, must be over this
    /// table's breakpoints.
    pub fn with_response(
        &self,
        prob: &VcProblem,
        index: Option<&IntervalIndex>,
        span: (f64, f64),
    ) -> MomentTable {
        self.clone().into_response(prob, index, span)
    }

    /// [`MomentTable::with_response`] in place: the kept families' moments and the
    /// cell sums of the last grid stay where they are (the cell sums of each family
    /// are its own, so the design's are kept and only those of the y families are
    /// summed anew, the same bits as a fresh table's, tested).
    pub fn into_response(
        mut self,
        prob: &VcProblem,
        index: Option<&IntervalIndex>,
        (umin, umax): (f64, f64),
    ) -> MomentTable {
        assert_eq!(
            self.pairs.last(),
            Some(&(self.p + 1, self.p + 1)),
            "a full table"
        );
        assert_eq!(prob.p, self.p);
        assert_eq!(
            self.nfam,
            (self.p + 1) * (self.p + 2) / 2 + 1,
            "a table of every family"
        );
        let fams = Families::ResponseAndSquare;
        assert!(
            index.is_none_or(|ix| ix.breaks == self.breaks),
            "an index over the same breakpoints"
        );
        let breaks = || self.breaks.clone();
        let fresh = Self::build_over(prob, index, breaks, (umin, umax), self.deg, fams);
        assert!(fresh.centre == self.centre && fresh.half == self.half);
        let d1 = self.deg + 1;
        let (w_all, w_new) = (self.nfam * d1, fresh.nfam * d1);
        // (family of `fresh`, family of this table)
        let map: Vec<(usize, usize)> = fresh
            .pairs
            .iter()
            .enumerate()
            .map(|(k, &(a, b))| (k, self.fam(a, b)))
            .collect();
        let copy_families = |dst: &mut [f64], src: &[f64]| {
            for (drow, srow) in dst.chunks_exact_mut(w_all).zip(src.chunks_exact(w_new)) {
                for &(k, f) in &map {
                    drow[f * d1..(f + 1) * d1].copy_from_slice(&srow[k * d1..(k + 1) * d1]);
                }
            }
        };
        copy_families(&mut self.m, &fresh.m);
        let slot = self.cells.get_mut().unwrap_or_else(|e| e.into_inner());
        if let Some(kept) = slot.take() {
            let mut cells = std::sync::Arc::try_unwrap(kept).unwrap_or_else(|a| (*a).clone());
            let new = fresh.build_cells(&cells.grid);
            debug_assert!(new.prefix_count == cells.prefix_count && new.first == cells.first);
            copy_families(&mut cells.prefix, &new.prefix);
            copy_families(&mut cells.suffix, &new.suffix);
            *slot = Some(std::sync::Arc::new(cells));
        }
        self
    }

    /// The left-hand sides of the local systems at bandwidth `h` (they depend on X and
    /// U only), for [`MomentTable::fit_response`] to reuse while the response changes.
    pub fn local_systems(&self, grid: &[f64], h: f64) -> LocalSystems {
        assert!(self.deg >= 6 && self.pairs.last() == Some(&(self.p + 1, self.p + 1)));
        let d1 = self.deg + 1;
        let binom = binomial_table();
        let cells = self.cells(grid);
        let per_g: Vec<(Vec<f64>, u64, f64)> = (0..grid.len())
            .into_par_iter()
            .map(|g| {
                let (acc, count) = self.window(&cells, g, h, 6, &binom);
                let a_of = kernel_contraction(&acc, d1, h, &BIWEIGHT);
                (self.local_lhs(&a_of), count, a_of(self.one_fam(), 0))
            })
            .collect();
        LocalSystems::new(grid, h, self.p, per_g)
    }

    /// Local fits at `sys.h` from the right-hand sides of this table (a
    /// [`Families::Response`] or full table of the same breakpoints, degree 5 or more:
    /// the right-hand sides need powers up to 5) and the reused
    /// left-hand sides: the windows are summed as in [`MomentTable::fit_ladder`] (the
    /// same right-hand sides, bit for bit, as a ladder's fit at `sys.h`).
    pub fn fit_response(&self, sys: &LocalSystems) -> GridFit {
        assert_eq!(self.p, sys.p);
        assert!(
            self.deg >= 5,
            "right-hand sides need moments up to degree 5"
        );
        let d1 = self.deg + 1;
        let h = sys.h;
        let binom = binomial_table();
        let cells = self.cells(&sys.grid);
        let rhs: Vec<Vec<f64>> = (0..sys.grid.len())
            .into_par_iter()
            .map(|g| {
                let (acc, _) = self.window(&cells, g, h, self.deg.min(6), &binom);
                self.local_rhs(&kernel_contraction(&acc, d1, h, &BIWEIGHT))
            })
            .collect();
        sys.fit_with(|g| &rhs[g])
    }

    /// Local-linear fits at every grid point for every bandwidth in `hs`. Every
    /// `u_g`, `u_g - h` and `u_g + h` must be a breakpoint. For one grid point the
    /// windows of all bandwidths are nested: the whole cells inside them are summed
    /// once, from the nearest outwards on either side (`WholeCells`), and each
    /// window adds its two edge runs. The fit at one h has the same bits whatever the
    /// other bandwidths in `hs` (tested), so a ladder can be fitted rung by rung.
    pub fn fit_ladder(&self, grid: &[f64], hs: &[f64]) -> Vec<GridFit> {
        self.fit_ladder_systems(grid, hs).0
    }

    /// [`MomentTable::fit_ladder`], with each bandwidth's left-hand sides: they
    /// depend on X and U only, so a ladder over the same table with new residuals
    /// ([`MomentTable::with_response`]) can reuse them
    /// ([`MomentTable::fit_ladder_response`]).
    pub fn fit_ladder_systems(
        &self,
        grid: &[f64],
        hs: &[f64],
    ) -> (Vec<GridFit>, Vec<LocalSystems>) {
        assert!(self.deg >= 6, "local fits need moments up to degree 6");
        let p = self.p;
        let d1 = self.deg + 1;
        let binom = binomial_table();
        let cells = self.cells(grid);
        let mut order: Vec<usize> = (0..hs.len()).collect();
        order.sort_by(|a, b| hs[*a].total_cmp(&hs[*b]));
        // per grid point: for each h, (S, T, count, mass)
        type Point = (Vec<f64>, Vec<f64>, u64, f64);
        let per_g: Vec<Vec<Point>> = (0..grid.len())
            .into_par_iter()
            .map(|g| {
                let mut whole = WholeCells::new(self, g);
                let mut out: Vec<Option<Point>> = vec![None; hs.len()];
                for &j in &order {
                    let h = hs[j];
                    let (acc, count) = self.grown_window(&cells, &mut whole, h, 6, &binom, None);
                    let a_of = kernel_contraction(&acc, d1, h, &BIWEIGHT);
                    let point = (
                        self.local_lhs(&a_of),
                        self.local_rhs(&a_of),
                        count,
                        a_of(self.one_fam(), 0),
                    );
                    out[j] = Some(point);
                }
                out.into_iter()
                    .map(|o| o.expect("every h visited"))
                    .collect()
            })
            .collect();
        // the local solves, bandwidths in parallel
        hs.par_iter()
            .enumerate()
            .map(|(j, &h)| {
                let points = per_g
                    .iter()
                    .map(|pts| (pts[j].0.clone(), pts[j].2, pts[j].3))
                    .collect();
                let sys = LocalSystems::new(grid, h, p, points);
                (sys.fit_with(|g| &per_g[g][j].1), sys)
            })
            .unzip()
    }

    /// Fits at the bandwidths of `systems` (left-hand sides of this table's X and U,
    /// kept from [`MomentTable::fit_ladder_systems`]): only the X_a y families'
    /// windows are summed, grown as in [`MomentTable::fit_ladder`], so each fit has
    /// the bits of that ladder's fit on this table (tested).
    pub fn fit_ladder_response(&self, systems: &[&LocalSystems]) -> Vec<GridFit> {
        assert!(self.deg >= 6, "a ladder's table has degree 6 or more");
        let Some(first) = systems.first() else {
            return Vec::new();
        };
        let (p, grid) = (self.p, &first.grid[..]);
        assert!(systems.iter().all(|s| s.p == p && s.grid == grid));
        let d1 = self.deg + 1;
        let binom = binomial_table();
        let cells = self.cells(grid);
        let fams: Vec<usize> = (0..p).map(|a| self.fam(a, p)).collect();
        let mut order: Vec<usize> = (0..systems.len()).collect();
        order.sort_by(|a, b| systems[*a].h.total_cmp(&systems[*b].h));
        let per_g: Vec<Vec<Vec<f64>>> = (0..grid.len())
            .into_par_iter()
            .map(|g| {
                let mut whole = WholeCells::for_fams(self, g, p);
                let mut out: Vec<Vec<f64>> = vec![Vec::new(); systems.len()];
                for &j in &order {
                    let h = systems[j].h;
                    let (acc, _) = self.grown_window(&cells, &mut whole, h, 6, &binom, Some(&fams));
                    // row a of acc holds X_a y
                    out[j] = local_rhs_of(p, &kernel_contraction(&acc, d1, h, &BIWEIGHT), |a| a);
                }
                out
            })
            .collect();
        systems
            .par_iter()
            .enumerate()
            .map(|(j, sys)| sys.fit_with(|g| &per_g[g][j]))
            .collect()
    }

    /// Exact RSS and trace of the smoother (f between grid points by linear
    /// interpolation, constant beyond the ends) for a fit whose points are all Ok.
    /// Per cell: the RSS from the cell's moments about its left grid point; the trace
    /// from the part of each neighbouring grid point's window inside the cell (the
    /// whole cell, or the run from the grid point to the window's edge).
    pub fn rss_trace(&self, grid: &[f64], fit: &GridFit) -> (f64, f64) {
        self.rss_trace_parts(grid, fit, true, true)
    }

    /// The RSS alone ([`MomentTable::rss_trace`]'s, the same bits): for a fit whose
    /// trace is known (the same left-hand sides, another response).
    pub fn rss(&self, grid: &[f64], fit: &GridFit) -> f64 {
        self.rss_trace_parts(grid, fit, true, false).0
    }

    /// The smoother's trace alone ([`MomentTable::rss_trace`]'s, the same bits): it
    /// needs only the design's families (an [`Families::All`] or [`Families::Design`]
    /// table) and `fit`'s inverses S_g^-1, not its values.
    pub fn trace(&self, grid: &[f64], fit: &GridFit) -> f64 {
        self.rss_trace_parts(grid, fit, false, true).1
    }

    /// RSS (0 unless `with_rss`) and trace (0 unless `with_trace`).
    fn rss_trace_parts(
        &self,
        grid: &[f64],
        fit: &GridFit,
        with_rss: bool,
        with_trace: bool,
    ) -> (f64, f64) {
        let p = self.p;
        assert!(
            self.pairs.contains(&(0, 0)) && (!with_rss || self.pairs.contains(&(p, p))),
            "the trace needs the design's families, the RSS every family"
        );
        let n = 2 * p;
        let d1 = self.deg + 1;
        let width = self.nfam * d1;
        let h = fit.bandwidth;
        let gl = grid.len();
        let binom = binomial_table();
        let cells = self.cells(grid);
        let kern: Vec<f64> = {
            let mut hp = 1.0;
            BIWEIGHT
                .iter()
                .map(|c| {
                    let v = c * hp;
                    hp /= h;
                    v
                })
                .collect()
        };
        let parts: Vec<(f64, f64)> = (0..=gl)
            .into_par_iter()
            .map(|c| {
                // (left grid point k, right grid point k1): cell 0 uses f(u_0), cell G f(u_{G-1})
                let (k, k1) = match c {
                    0 => (0, None),
                    c if c == gl => (gl - 1, None),
                    c => (c - 1, Some(c)),
                };
                let (f0, l0) = (cells.first[c], cells.last[c]);
                let rss = if with_rss {
                    // the whole cell anchored at the edge nearest u_k
                    let whole_at_k = if c == 0 {
                        self.suffix(&cells, f0)
                    } else {
                        self.prefix(&cells, l0)
                    };
                    let mut r = vec![0.0; width];
                    self.add_piece(whole_at_k, grid[k], 2, &binom, &mut r);
                    let mom = |f: usize, s: usize| r[f * d1 + s];
                    let fa = &fit.f[k * p..(k + 1) * p];
                    let fb: Vec<f64> = match k1 {
                        Some(k1) => (0..p)
                            .map(|m| (fit.f[k1 * p + m] - fa[m]) / (grid[k1] - grid[k]))
                            .collect(),
                        None => vec![0.0; p],
                    };
                    let mut rss = mom(self.fam(p, p), 0);
                    for a in 0..p {
                        let fy = self.fam(a, p);
                        rss -= 2.0 * (fa[a] * mom(fy, 0) + fb[a] * mom(fy, 1));
                        for b in 0..p {
                            let f = self.fam(a, b);
                            rss += fa[a] * fa[b] * mom(f, 0)
                                + (fa[a] * fb[b] + fb[a] * fa[b]) * mom(f, 1)
                                + fb[a] * fb[b] * mom(f, 2);
                        }
                    }
                    rss
                } else {
                    0.0
                };
                // trace: (grid point, interpolation weight in powers of U - u_g, piece)
                let mut targets: Vec<(usize, Vec<f64>, Option<Piece>)> = Vec::with_capacity(2);
                // window of g inside the cell to its right, [u_g, u_g + h); None when
                // u_g + h rounds to u_g
                let right_part = |g: usize| {
                    let (_, whi) = self.window_edges(&cells, g, h);
                    whi.map(|whi| self.prefix(&cells, whi.min(l0)))
                };
                // window of g inside the cell to its left, [u_g - h, u_g)
                let left_part = |g: usize| {
                    let (wlo, _) = self.window_edges(&cells, g, h);
                    wlo.map(|wlo| self.suffix(&cells, wlo.max(f0)))
                };
                // (none without the trace: its window pieces are not even found)
                match k1 {
                    _ if !with_trace => {}
                    None if c == 0 => targets.push((0, vec![1.0], left_part(0))),
                    None => targets.push((k, vec![1.0], right_part(k))),
                    Some(k1) => {
                        let dlt = grid[k1] - grid[k];
                        targets.push((k, vec![1.0, -1.0 / dlt], right_part(k)));
                        targets.push((k1, vec![1.0, 1.0 / dlt], left_part(k1)));
                    }
                }
                let mut tr = 0.0;
                for (g, omega, piece) in targets {
                    let Some(piece) = piece.filter(|pc| pc.count > 0) else {
                        continue;
                    };
                    let mut r = vec![0.0; width];
                    self.add_piece(piece, grid[g], 6, &binom, &mut r);
                    let base = poly_mul(&omega, &kern);
                    let base2 = poly_mul(&base, &[0.0, 1.0 / h]);
                    let q = &fit.s_inv[g * n * n..(g + 1) * n * n];
                    for a in 0..p {
                        for b in 0..p {
                            let f = self.fam(a, b);
                            let c0: f64 = base
                                .iter()
                                .enumerate()
                                .map(|(s, c)| c * r[f * d1 + s])
                                .sum();
                            let c1: f64 = base2
                                .iter()
                                .enumerate()
                                .map(|(s, c)| c * r[f * d1 + s])
                                .sum();
                            tr += q[a * n + b] * c0 + q[a * n + p + b] * c1;
                        }
                    }
                }
                (rss, tr)
            })
            .collect();
        parts
            .into_iter()
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// Pointwise standard-error factors of f at bandwidth `fit.bandwidth`: for each
    /// grid point and m, sqrt([S^-1 S2 S^-1]_mm) with S2 = sum K(w)^2 Z Z', so that
    /// se = sigma * factor (the sandwich variance of a local least-squares fit with
    /// homoskedastic errors; Fan and Gijbels 1996, eq. 3.6). Needs `deg >= 10`
    /// (K^2 is of degree 8). NaN where the point is not Ok.
    pub fn se_factors(&self, grid: &[f64], fit: &GridFit) -> Vec<f64> {
        assert!(
            self.deg >= 10,
            "standard errors need moments up to degree 10"
        );
        let p = self.p;
        let n = 2 * p;
        let d1 = self.deg + 1;
        let h = fit.bandwidth;
        let binom = binomial_table();
        let cells = self.cells(grid);
        let k2 = poly_mul(&BIWEIGHT, &BIWEIGHT);
        let per_g: Vec<Vec<f64>> = (0..grid.len())
            .into_par_iter()
            .map(|g| {
                if fit.status[g] != super::problem::PointStatus::Ok {
                    return vec![f64::NAN; p];
                }
                let (acc, _) = self.window(&cells, g, h, 10, &binom);
                let s2 = self.local_lhs(&kernel_contraction(&acc, d1, h, &k2));
                sandwich_diag(&fit.s_inv[g * n * n..(g + 1) * n * n], &s2, n, p)
            })
            .collect();
        per_g.concat()
    }

    /// The normal equations of the online state at bandwidth `h` from a table of the
    /// design's families ([`Families::Design`], degree 10), for every grid point: S_g =
    /// sum K(w) Z Z' (Z = (X, w X), w = (U - u_g)/h, row-major 2p x 2p), S2_g = sum
    /// K(w)^2 Z Z', the support's sample count and kernel mass sum K(w): the sums of
    /// `update::state_from_fit_direct` over the rows in [u_g - h, u_g + h), from the
    /// window moments of [`MomentTable::se_factors`].
    pub fn state_design(&self, grid: &[f64], h: f64) -> Vec<(Vec<f64>, Vec<f64>, u64, f64)> {
        assert!(
            self.deg >= 10 && self.pairs.last() == Some(&(self.p + 1, self.p + 1)),
            "the design's families to degree 10"
        );
        let d1 = self.deg + 1;
        let binom = binomial_table();
        let cells = self.cells(grid);
        let k2 = poly_mul(&BIWEIGHT, &BIWEIGHT);
        (0..grid.len())
            .into_par_iter()
            .map(|g| {
                let (acc, count) = self.window(&cells, g, h, 10, &binom);
                let a1 = kernel_contraction(&acc, d1, h, &BIWEIGHT);
                let a2 = kernel_contraction(&acc, d1, h, &k2);
                let mass = a1(self.one_fam(), 0);
                (self.local_lhs(&a1), self.local_lhs(&a2), count, mass)
            })
            .collect()
    }

    /// T_g = sum K(w) Z y (2p) at every grid point at bandwidth `h`, from a table of
    /// the X_a y families ([`Families::Response`], degree 5 or more), the windows
    /// summed as in [`MomentTable::fit_response`].
    pub fn local_rhs_at(&self, grid: &[f64], h: f64) -> Vec<Vec<f64>> {
        assert!(
            self.deg >= 5,
            "right-hand sides need moments up to degree 5"
        );
        let d1 = self.deg + 1;
        let binom = binomial_table();
        let cells = self.cells(grid);
        (0..grid.len())
            .into_par_iter()
            .map(|g| {
                let (acc, _) = self.window(&cells, g, h, self.deg.min(6), &binom);
                self.local_rhs(&kernel_contraction(&acc, d1, h, &BIWEIGHT))
            })
            .collect()
    }
}

/// Sorted, distinct breakpoints (the order `MomentTable` keeps them in).
fn sorted_breaks(mut breaks: Vec<f64>) -> Vec<f64> {
    breaks.sort_by(f64::total_cmp);
    breaks.dedup();
    breaks
}

/// The elementary interval of every row's index value U_t = x_{t-d} for one set of
/// breakpoints, found once (an [`IntervalLookup`] pass) and then read by every pass
/// over the same breakpoints: the index values do not change during a fit, so while
/// the bandwidth stays, the f-step tables, the residuals' grid cells and the final
/// table read a u16 per row (a quarter of the channel's size) instead of searching.
pub struct IntervalIndex {
    /// Sorted, distinct breakpoints; interval e covers [breaks[e-1], breaks[e]).
    breaks: Vec<f64>,
    /// First row (rows[i] is the interval of row start + i).
    start: usize,
    rows: Vec<u16>,
}

impl IntervalIndex {
    /// The index of `prob`'s rows over `breaks`; None when there are more intervals
    /// than a u16 holds (then the passes search, as without an index).
    pub fn build(prob: &VcProblem, breaks: Vec<f64>) -> Option<IntervalIndex> {
        let breaks = sorted_breaks(breaks);
        if breaks.is_empty() || breaks.len() > u16::MAX as usize {
            return None;
        }
        let lookup = IntervalLookup::new(&breaks);
        let (x, d, start) = (prob.x, prob.d, prob.start);
        let (rows, _) = super::buffers::filled(prob.n_rows(), |at, out: &mut [u16]| {
            let t0 = start + at;
            for (i, r) in out.iter_mut().enumerate() {
                *r = lookup.find(x[t0 + i - d]) as u16;
            }
        });
        Some(IntervalIndex {
            breaks,
            start,
            rows,
        })
    }

    /// The index of the same rows over `breaks`, a subset of this index's breakpoints
    /// (None when one of them is not among them, or the intervals do not fit a u16),
    /// without searching: each row's interval is read through a table from its
    /// interval here (a pass over the u16 rows, in parallel). The intervals of
    /// [`IntervalIndex::build`]: with the breakpoints `b`
    /// of this index and `c` of the new one, c ⊆ b, a value u with b\[e-1\] <= u < b\[e\]
    /// has as many values of c at or below it as b\[e-1\] has (a value of c in
    /// (b\[e-1\], u\] would be a value of b there).
    pub fn coarsened(&self, breaks: Vec<f64>) -> Option<IntervalIndex> {
        let breaks = sorted_breaks(breaks);
        if breaks.is_empty()
            || breaks.len() > u16::MAX as usize
            || !breaks
                .iter()
                .all(|c| self.breaks.binary_search_by(|b| b.total_cmp(c)).is_ok())
        {
            return None;
        }
        let to: Vec<u16> = (0..=self.breaks.len())
            .map(|e| match e {
                0 => 0,
                _ => breaks.partition_point(|c| *c <= self.breaks[e - 1]) as u16,
            })
            .collect();
        let from = &self.rows[..];
        let (rows, _) = super::buffers::filled(from.len(), |at, out: &mut [u16]| {
            for (r, f) in out.iter_mut().zip(&from[at..]) {
                *r = to[*f as usize];
            }
        });
        Some(IntervalIndex {
            breaks,
            start: self.start,
            rows,
        })
    }

    /// Interval of row t (t >= the first row).
    #[inline]
    pub fn interval(&self, t: usize) -> usize {
        self.rows[t - self.start] as usize
    }

    /// First row indexed.
    pub fn start(&self) -> usize {
        self.start
    }

    /// For each interval, the grid cell its values lie in, for `grid` (every grid
    /// point a breakpoint): k when grid\[k\] <= U < grid[k+1], `BELOW_GRID` below the
    /// first grid point and `ABOVE_GRID` at or above the last.
    pub fn grid_cells(&self, grid: &[f64]) -> Vec<u32> {
        let g = grid.len();
        (0..=self.breaks.len())
            .map(|e| {
                // every grid point is a breakpoint, so the grid points <= U are those
                // <= the interval's lower edge
                let n_le = if e == 0 {
                    0
                } else {
                    grid.partition_point(|v| *v <= self.breaks[e - 1])
                };
                if n_le == 0 {
                    BELOW_GRID
                } else if n_le == g {
                    ABOVE_GRID
                } else {
                    (n_le - 1) as u32
                }
            })
            .collect()
    }
}

/// [`IntervalIndex::grid_cells`] of an interval below the first grid point.
pub const BELOW_GRID: u32 = u32::MAX;
/// [`IntervalIndex::grid_cells`] of an interval at or above the last grid point.
pub const ABOVE_GRID: u32 = u32::MAX - 1;

/// The interval of a value among sorted distinct breakpoints: exactly
/// `breaks.partition_point(|b| *b <= u)`, found from a guess out of a uniform bucket
/// table (4 buckets per breakpoint) corrected by stepping, instead of a binary search.
/// The first step is taken without a branch (most buckets hold at most one
/// breakpoint), so the loops that follow are rarely entered and their branches
/// predicted.
pub struct IntervalLookup {
    /// The breakpoints with +inf appended (so `ext[e] <= u` is false at the end).
    ext: Vec<f64>,
    lo: f64,
    scale: f64,
    first: Vec<u32>,
}

impl IntervalLookup {
    pub fn new(breaks: &[f64]) -> Self {
        let nb = breaks.len();
        let buckets = 4 * nb + 1;
        let (lo, hi) = (breaks[0], breaks[nb - 1]);
        let scale = if hi > lo {
            buckets as f64 / (hi - lo)
        } else {
            0.0
        };
        let first = (0..buckets)
            .map(|k| {
                let edge = if scale > 0.0 {
                    lo + k as f64 / scale
                } else {
                    lo
                };
                breaks.partition_point(|b| *b <= edge) as u32
            })
            .collect();
        let mut ext = breaks.to_vec();
        ext.push(f64::INFINITY);
        IntervalLookup {
            ext,
            lo,
            scale,
            first,
        }
    }

    #[inline]
    pub fn find(&self, u: f64) -> usize {
        let k = (u - self.lo) * self.scale;
        let k = if k > 0.0 {
            (k as usize).min(self.first.len() - 1)
        } else {
            0
        };
        let b = &self.ext[..];
        let nb = b.len() - 1;
        let mut e = self.first[k] as usize;
        // e <= nb, and b[nb] = +inf: no bounds to check, no branch
        e += ((e < nb) & (b[e] <= u)) as usize;
        while e < nb && b[e] <= u {
            e += 1;
        }
        while e > 0 && b[e - 1] > u {
            e -= 1;
        }
        e
    }
}

/// sqrt of the first p diagonal entries of Q S2 Q (Q symmetric, row-major n x n); NaN
/// where the computed entry is not positive: with S2 positive definite it is positive,
/// but Q S2 Q squares the condition number of the local system (Q = S^-1), and past
/// about 1e8 rounding can leave it at or below 0 (the callers count such points in a
/// note, [`super::fit::missing_se_note`]).
pub fn sandwich_diag(q: &[f64], s2: &[f64], n: usize, p: usize) -> Vec<f64> {
    (0..p)
        .map(|m| {
            let mut v = 0.0;
            for i in 0..n {
                for j in 0..n {
                    v += q[m * n + i] * s2[i * n + j] * q[j * n + m];
                }
            }
            if v > 0.0 && v.is_finite() {
                v.sqrt()
            } else {
                f64::NAN
            }
        })
        .collect()
}

/// The breakpoints for grid `grid` and bandwidths `hs`: every u_g, u_g - h, u_g + h.
pub fn breakpoints(grid: &[f64], hs: &[f64]) -> Vec<f64> {
    let mut b = Vec::with_capacity(grid.len() * (2 * hs.len() + 1));
    for &g in grid {
        b.push(g);
        for &h in hs {
            b.push(g - h);
            b.push(g + h);
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_coarsened_index_has_the_intervals_of_one_built_by_search() {
        let (x, _) = series(50_000, 12);
        let grid: Vec<f64> = (0..21).map(|k| -0.8 + 0.08 * k as f64).collect();
        let hs = [0.5, 0.3, 0.11, 0.05];
        let prob = VcProblem::new(&x, &[], &[], 2, 1);
        let fine = IntervalIndex::build(&prob, breakpoints(&grid, &hs)).unwrap();
        for h in hs {
            let coarse = fine.coarsened(breakpoints(&grid, &[h])).unwrap();
            let built = IntervalIndex::build(&prob, breakpoints(&grid, &[h])).unwrap();
            assert_eq!(coarse.breaks, built.breaks);
            assert!((prob.start..x.len()).all(|t| coarse.interval(t) == built.interval(t)));
            // coarsened twice (fine -> two bandwidths -> one): the same intervals
            let mid = fine.coarsened(breakpoints(&grid, &[h, 0.05])).unwrap();
            let twice = mid.coarsened(breakpoints(&grid, &[h])).unwrap();
            assert!((prob.start..x.len()).all(|t| twice.interval(t) == built.interval(t)));
            // a table over the coarsened index is the one over the searched index
            let span = (-3.0, 3.0);
            let a = MomentTable::build_indexed(&prob, &coarse, span.0, span.1, 6, Families::All);
            let b = MomentTable::build_indexed(&prob, &built, span.0, span.1, 6, Families::All);
            assert_eq!(bits(&a), bits(&b));
        }
        // a bandwidth the fine index does not hold
        assert!(fine.coarsened(breakpoints(&grid, &[0.2])).is_none());
    }

    #[test]
    fn interval_lookup_equals_binary_search() {
        // uneven breakpoints (a grid and its windows), values inside, outside, on breaks
        let grid: Vec<f64> = (0..21).map(|k| -1.3 + 0.13 * k as f64).collect();
        let hs: Vec<f64> = (0..21).map(|j| 1.1f64.powi(-j) * 1.7).collect();
        let mut b = breakpoints(&grid, &hs);
        b.sort_by(f64::total_cmp);
        b.dedup();
        let lk = IntervalLookup::new(&b);
        let mut us: Vec<f64> = b.clone();
        us.extend(b.iter().map(|v| v.next_up()));
        us.extend(b.iter().map(|v| v.next_down()));
        us.extend((0..20_001).map(|i| -6.0 + 12.0 * i as f64 / 20_000.0));
        us.extend([
            f64::MAX,
            f64::MIN,
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ]);
        for u in us {
            assert_eq!(lk.find(u), b.partition_point(|v| *v <= u), "u = {u}");
        }
        let one = [0.5];
        let lk = IntervalLookup::new(&one);
        for u in [0.0, 0.5, 1.0] {
            assert_eq!(lk.find(u), one.partition_point(|v| *v <= u));
        }
    }

    /// An AR(2)-like series with uniform innovations, residuals and b for tables.
    fn series(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut x = vec![0.0f64; n];
        for t in 2..n {
            x[t] = 0.5 * x[t - 1] - 0.2 * x[t - 2] + next();
        }
        let e: Vec<f64> = (0..n).map(|_| next()).collect();
        (x, e)
    }

    fn bits(m: &MomentTable) -> (Vec<u64>, Vec<u64>) {
        (m.m.iter().map(|v| v.to_bits()).collect(), m.count.clone())
    }

    #[test]
    fn indexed_and_refreshed_tables_equal_fresh_ones_bit_for_bit() {
        // N above one block, so that several block tables are added
        let (x, e) = series(300_000, 11);
        let e2: Vec<f64> = e.iter().map(|v| 0.5 * v + 0.01).collect();
        let grid: Vec<f64> = (0..41).map(|k| -0.6 + 0.03 * k as f64).collect();
        let hs = [0.25, 0.1];
        for p in [1, 2, 3, 4] {
            let prob = VcProblem::new(&x, &e, &[-0.4], p, 1);
            let breaks = breakpoints(&grid, &hs);
            let ix = IntervalIndex::build(&prob, breaks.clone()).unwrap();
            for t in [p, p + 1, 1000, x.len() - 1] {
                let b = &ix.breaks;
                assert_eq!(ix.interval(t), b.partition_point(|v| *v <= x[t - 1]));
            }
            for (fam, deg) in [(Families::All, 6), (Families::Response, 5)] {
                let a = MomentTable::build_families(&prob, breaks.clone(), -2.0, 2.0, deg, fam);
                let b = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, deg, fam);
                assert_eq!(bits(&a), bits(&b), "p = {p}, {fam:?}");
            }
            // the X_a y families alone (the specialised pass for p <= 3) against the
            // same families of the full table (the general pass)
            let all = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 6, Families::All);
            let xy = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 6, Families::Response);
            let (wa, wx) = (all.nfam * 7, xy.nfam * 7);
            for e in 0..all.n_intervals() {
                for a in 0..p {
                    let fa = all.fam(a, p);
                    let ra = &all.m[e * wa + fa * 7..e * wa + (fa + 1) * 7];
                    let rx = &xy.m[e * wx + a * 7..e * wx + (a + 1) * 7];
                    assert!(ra.iter().zip(rx).all(|(u, v)| u.to_bits() == v.to_bits()));
                }
            }
            // new residuals and b: the refreshed table is the fresh one
            let prob2 = VcProblem {
                e: &e2,
                b: &[0.3],
                ..prob
            };
            let fresh = MomentTable::build(&prob2, breaks.clone(), -2.0, 2.0, 6);
            // with the cell sums of the grid kept from the first table: the y
            // families' are summed anew, and all equal a fresh table's
            let _ = all.cells(&grid);
            let cell_bits = |t: &MomentTable| {
                let c = t.cells(&grid);
                let b = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
                (
                    b(&c.prefix),
                    b(&c.suffix),
                    b(&c.prefix_scale),
                    c.prefix_count.clone(),
                )
            };
            for index in [Some(&ix), None] {
                let refreshed = all.with_response(&prob2, index, (-2.0, 2.0));
                assert_eq!(bits(&refreshed), bits(&fresh), "p = {p}");
                assert!(cell_bits(&refreshed) == cell_bits(&fresh), "p = {p}");
            }
            let moved = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 6, Families::All);
            let _ = moved.cells(&grid);
            let moved = moved.into_response(&prob2, Some(&ix), (-2.0, 2.0));
            assert_eq!(bits(&moved), bits(&fresh), "p = {p}");
            assert!(cell_bits(&moved) == cell_bits(&fresh), "p = {p}");
        }
    }

    #[test]
    fn a_design_table_gives_the_full_tables_trace_and_standard_errors() {
        // the final step's table: the design's families alone, degree 10. Its local
        // systems, trace and standard-error factors must be the full table's, bit for
        // bit (they do not depend on y), and its pass must not read the residuals
        let (x, e) = series(200_000, 5);
        let grid: Vec<f64> = (0..31).map(|k| -0.45 + 0.03 * k as f64).collect();
        let h = 0.12;
        for p in [1, 2, 3] {
            let prob = VcProblem::new(&x, &e, &[-0.4], p, 1);
            let ix = IntervalIndex::build(&prob, breakpoints(&grid, &[h])).unwrap();
            let full = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 10, Families::All);
            let fit = full.fit_ladder(&grid, &[h]).remove(0);
            assert!(fit.all_ok());
            // other residuals: the design table is the same
            let e_other: Vec<f64> = e.iter().map(|v| 3.0 * v - 1.0).collect();
            let prob_other = VcProblem {
                e: &e_other,
                b: &[0.7],
                ..prob
            };
            let design =
                MomentTable::build_indexed(&prob_other, &ix, -2.0, 2.0, 10, Families::Design);
            assert_eq!(design.nfam, p * (p + 1) / 2 + 1);
            let dfit = design.local_systems(&grid, h).design_fit();
            assert_eq!(dfit.status, fit.status);
            let sinv = |f: &GridFit| f.s_inv.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(sinv(&dfit), sinv(&fit), "p = {p}");
            let (_, trace) = full.rss_trace(&grid, &fit);
            assert_eq!(
                design.trace(&grid, &dfit).to_bits(),
                trace.to_bits(),
                "p = {p}"
            );
            assert_eq!(full.trace(&grid, &fit).to_bits(), trace.to_bits());
            let se = |v: Vec<f64>| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                se(design.se_factors(&grid, &dfit)),
                se(full.se_factors(&grid, &fit)),
                "p = {p}"
            );
        }
    }

    #[test]
    fn tables_of_other_families_are_summed_in_the_same_blocks() {
        // many intervals and N large enough that the blocks are above their minimum
        // size (here N/4): a table of fewer families or a lower degree must still be
        // cut into the same blocks, or its sums (and the refreshed table) lose the
        // bits (the formula that followed each table's own length gave the X_a y
        // table of degree 5 blocks of 2^17 rows, the full table N/4)
        let (x, e) = series(700_000, 13);
        let grid: Vec<f64> = (0..101).map(|k| -0.6 + 0.012 * k as f64).collect();
        let hs: Vec<f64> = (0..13).map(|j| 0.3 * 1.1f64.powi(-j)).collect();
        let prob = VcProblem::new(&x, &e, &[-0.4], 1, 1);
        let breaks = breakpoints(&grid, &hs);
        let ix = IntervalIndex::build(&prob, breaks.clone()).unwrap();
        let all = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 6, Families::All);
        let xy = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 5, Families::Response);
        let f = all.fam(0, 1);
        let (wa, wx) = (all.nfam * 7, 6);
        for e in 0..all.n_intervals() {
            let ra = &all.m[e * wa + f * 7..e * wa + f * 7 + 6];
            let rx = &xy.m[e * wx..e * wx + 6];
            assert!(ra.iter().zip(rx).all(|(u, v)| u.to_bits() == v.to_bits()));
        }
        let e2: Vec<f64> = e.iter().map(|v| 0.5 * v).collect();
        let prob2 = VcProblem { e: &e2, ..prob };
        let fresh = MomentTable::build(&prob2, breaks, -2.0, 2.0, 6);
        let refreshed = all.with_response(&prob2, Some(&ix), (-2.0, 2.0));
        assert_eq!(bits(&refreshed), bits(&fresh));
    }

    #[test]
    fn a_rung_has_the_same_bits_in_any_ladder() {
        // the whole cells of each side are summed nearest first in their own sum, so a
        // window does not depend on the narrower ones summed before it
        let (x, e) = series(50_000, 23);
        let grid: Vec<f64> = (0..41).map(|k| -0.6 + 0.03 * k as f64).collect();
        let hs: Vec<f64> = (0..12).map(|j| 0.9 * 1.1f64.powi(-j)).collect();
        let prob = VcProblem::new(&x, &e, &[-0.4], 2, 1);
        let table = MomentTable::build(&prob, breakpoints(&grid, &hs), -2.0, 2.0, 6);
        let fbits = |f: &GridFit| -> Vec<u64> { f.f.iter().map(|v| v.to_bits()).collect() };
        let all = table.fit_ladder(&grid, &hs);
        for (k, &h) in hs.iter().enumerate() {
            let alone = table.fit_ladder(&grid, &[h]).remove(0);
            assert_eq!(fbits(&alone), fbits(&all[k]), "h_{k}");
            let some = table.fit_ladder(&grid, &[hs[0], h, hs[hs.len() - 1]]);
            assert_eq!(fbits(&some[1]), fbits(&all[k]), "h_{k}");
            // and the f-step's path: kept left-hand sides, the right-hand sides alone
            let sys = table.local_systems(&grid, h);
            assert_eq!(fbits(&table.fit_response(&sys)), fbits(&all[k]), "h_{k}");
        }
    }

    #[test]
    fn a_ladder_on_kept_left_hand_sides_has_the_full_ladders_bits() {
        // the re-check's path: the left-hand sides of a first ladder (X and U only),
        // new residuals and b in the y families, the right-hand sides alone, against
        // the full ladder on the refreshed table, for every p of the fixed passes
        let (x, e) = series(60_000, 29);
        let e2: Vec<f64> = e.iter().map(|v| 0.7 * v - 0.02).collect();
        let grid: Vec<f64> = (0..41).map(|k| -0.6 + 0.03 * k as f64).collect();
        let hs: Vec<f64> = (0..12).map(|j| 0.9 * 1.1f64.powi(-j)).collect();
        let fbits = |f: &GridFit| -> Vec<u64> {
            f.f.iter()
                .chain(&f.slope)
                .chain(&f.s_inv)
                .map(|v| v.to_bits())
                .collect()
        };
        for p in [1, 2, 3] {
            let prob = VcProblem::new(&x, &e, &[-0.4], p, 1);
            let table = MomentTable::build(&prob, breakpoints(&grid, &hs), -2.0, 2.0, 6);
            let (_, systems) = table.fit_ladder_systems(&grid, &hs);
            // the kept left-hand sides are those of local_systems at each h
            for (sys, &h) in systems.iter().zip(&hs) {
                let alone = table.local_systems(&grid, h);
                assert_eq!(sys.h, h);
                for (a, b) in sys.points.iter().zip(&alone.points) {
                    assert_eq!(a.1, b.1);
                    assert_eq!(a.2.to_bits(), b.2.to_bits());
                    assert!(
                        a.0.iter()
                            .zip(&b.0)
                            .all(|(u, v)| u.to_bits() == v.to_bits())
                    );
                }
            }
            let prob2 = VcProblem {
                e: &e2,
                b: &[0.3],
                ..prob
            };
            let fresh = table.with_response(&prob2, None, (-2.0, 2.0));
            let full = fresh.fit_ladder(&grid, &hs);
            // every rung, and a subset in another order
            let all: Vec<&LocalSystems> = systems.iter().collect();
            let kept = fresh.fit_ladder_response(&all);
            for (k, f) in kept.iter().enumerate() {
                assert_eq!(fbits(f), fbits(&full[k]), "p = {p}, h_{k}");
                assert_eq!(f.status, full[k].status);
                assert_eq!(f.n_support, full[k].n_support);
            }
            let some = fresh.fit_ladder_response(&[&systems[7], &systems[2]]);
            assert_eq!(fbits(&some[0]), fbits(&full[7]), "p = {p}");
            assert_eq!(fbits(&some[1]), fbits(&full[2]), "p = {p}");
            // the residuals changed, so the fits did
            assert_ne!(
                fbits(&kept[3]),
                fbits(&table.fit_ladder(&grid, &[hs[3]])[0])
            );
        }
    }
}
