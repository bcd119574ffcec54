//! Finding a row's interval: [`IntervalIndex`] (every row's interval over one set of
//! breakpoints, found once and read by every later pass) and [`IntervalLookup`] (a
//! uniform bucket table over the breakpoints, a guess corrected by stepping, instead
//! of a binary search).

use super::sorted_breaks;
use crate::estimator::problem::VcProblem;

/// The elementary interval of every row's index value U_t = x_{t-d} for one set of
/// breakpoints, found once (an [`IntervalLookup`] pass) and then read by every pass
/// over the same breakpoints: the index values do not change during a fit, so while
/// the bandwidth stays, the f-step tables, the residuals' grid cells and the final
/// table read a u16 per row (a quarter of the channel's size) instead of searching.
pub struct IntervalIndex {
    /// Sorted, distinct breakpoints; interval e covers [breaks[e-1], breaks[e]).
    pub(super) breaks: Vec<f64>,
    /// First row (rows[i] is the interval of row start + i).
    pub(super) start: usize,
    pub(super) rows: Vec<u16>,
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
        let (rows, _) = crate::estimator::buffers::filled(prob.n_rows(), |at, out: &mut [u16]| {
            let t0 = start + at;
            for (i, r) in out.iter_mut().enumerate() {
                *r = lookup.find(x.at(t0 + i - d)) as u16;
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
        let (rows, _) = crate::estimator::buffers::filled(from.len(), |at, out: &mut [u16]| {
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
