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
//!
//! Layout: this file holds the table ([`MomentTable`], [`Families`]) and the
//! breakpoints; `build.rs` the pass that fills it, `index.rs` the interval of each row
//! ([`IntervalIndex`], [`IntervalLookup`]), `recentre.rs` the binomial shift of moments
//! between anchors, `cells.rs` the cell and window sums, `fits.rs` the local systems
//! and the ladder of fits ([`LocalSystems`]), `smoother.rs` the exact RSS, trace and
//! standard errors ([`sandwich_diag`]).

mod build;
mod cells;
mod fits;
mod index;
mod recentre;
mod smoother;

pub use fits::LocalSystems;
pub use index::{ABOVE_GRID, BELOW_GRID, IntervalIndex, IntervalLookup};
pub use smoother::sandwich_diag;

use cells::Cells;

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
    /// Elementary intervals: one more than the breakpoints (two unbounded ends).
    fn n_intervals(&self) -> usize {
        self.breaks.len() + 1
    }

    /// The family of the product V_a V_b.
    fn fam(&self, a: usize, b: usize) -> usize {
        let nv = self.p + 1;
        self.fam_of[a.min(b) * nv + a.max(b)]
    }

    /// The family of the constant 1 (the last).
    fn one_fam(&self) -> usize {
        self.nfam - 1
    }

    /// Index of an exact breakpoint value.
    fn break_index(&self, value: f64) -> usize {
        self.breaks
            .binary_search_by(|b| b.total_cmp(&value))
            .unwrap_or_else(|_| panic!("{value} is not a breakpoint"))
    }
}

/// Sorted, distinct breakpoints (the order `MomentTable` keeps them in).
fn sorted_breaks(mut breaks: Vec<f64>) -> Vec<f64> {
    breaks.sort_by(f64::total_cmp);
    breaks.dedup();
    breaks
}

/// The breakpoints for grid `grid` and bandwidths `hs`: every u_g, u_g - h, u_g + h
/// (u_g alone for an infinite h, whose window is every row).
pub fn breakpoints(grid: &[f64], hs: &[f64]) -> Vec<f64> {
    let mut b = Vec::with_capacity(grid.len() * (2 * hs.len() + 1));
    for &g in grid {
        b.push(g);
        for &h in hs.iter().filter(|h| h.is_finite()) {
            b.push(g - h);
            b.push(g + h);
        }
    }
    b
}

#[cfg(test)]
mod tests;
