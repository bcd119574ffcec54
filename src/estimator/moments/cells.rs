//! Window sums: the intervals grouped by the cells between grid points, with every run
//! that starts or ends at a cell edge summed once ([`Cells`], kept for the last grid),
//! and a window (g, h) as its two edge runs plus the whole cells between
//! ([`WholeCells`], grown from the nearest cell outwards so that nested windows share
//! their sums).

use rayon::prelude::*;

use super::MomentTable;
use super::recentre::{recentre_fixed, recentre_into, rescale_into};
use crate::estimator::kernel::binomial_table;

/// A run of intervals summed into one moment block: its moments are powers of
/// (U - anchor)/scale, `count` samples.
#[derive(Clone, Copy)]
pub(super) struct Piece<'a> {
    pub(super) m: &'a [f64],
    pub(super) anchor: f64,
    pub(super) scale: f64,
    pub(super) count: u64,
}

/// The whole cells of a growing window of grid point g, summed about u_g: cells
/// `left..=g` and `g+1..=right` (none at first), each side in its own sum, from the
/// nearest cell outwards. A window's sum is then the same whichever narrower windows
/// were summed before it: a ladder's fit at one bandwidth has the same bits whatever
/// other bandwidths it is computed with, and the same as a window summed alone.
pub(super) struct WholeCells {
    g: usize,
    left: usize,
    right: usize,
    acc_left: Vec<f64>,
    acc_right: Vec<f64>,
    count: u64,
}

impl WholeCells {
    pub(super) fn new(table: &MomentTable, g: usize) -> Self {
        Self::for_fams(table, g, table.nfam)
    }

    /// Sums of `nfam` families (all of the table's, or a subset).
    pub(super) fn for_fams(table: &MomentTable, g: usize, nfam: usize) -> Self {
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
pub(super) struct Cells {
    pub(super) grid: Vec<f64>,
    /// Cell of each interval; first and last interval of each cell.
    pub(super) cell_of: Vec<usize>,
    pub(super) first: Vec<usize>,
    pub(super) last: Vec<usize>,
    pub(super) prefix: Vec<f64>,
    pub(super) prefix_scale: Vec<f64>,
    pub(super) prefix_count: Vec<u64>,
    pub(super) suffix: Vec<f64>,
    pub(super) suffix_scale: Vec<f64>,
    pub(super) suffix_count: Vec<u64>,
}

impl MomentTable {
    /// The cell sums for `grid` (every grid point must be a breakpoint), built on the
    /// first call for a grid and kept for the next calls with the same grid.
    pub(super) fn cells(&self, grid: &[f64]) -> std::sync::Arc<Cells> {
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

    pub(super) fn build_cells(&self, grid: &[f64]) -> Cells {
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
    pub(super) fn prefix<'c>(&self, cells: &'c Cells, e: usize) -> Piece<'c> {
        let c = cells.cell_of[e];
        let anchor = self.lo_edge[cells.first[c]];
        self.run_piece(
            e,
            anchor,
            (&cells.prefix, &cells.prefix_scale, &cells.prefix_count),
        )
    }

    /// Intervals e..=last(cell(e)), about the cell's upper edge.
    pub(super) fn suffix<'c>(&self, cells: &'c Cells, e: usize) -> Piece<'c> {
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
    pub(super) fn add_piece(
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
    pub(super) fn window(
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
    pub(super) fn grown_window(
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

    /// The first and last interval of window (g, h): (lo, hi) with lo in a cell at or
    /// left of u_g and hi right of it; None for a side that is empty because u_g -+ h
    /// rounds to u_g (h below half an ulp of u_g).
    pub(super) fn window_edges(
        &self,
        cells: &Cells,
        g: usize,
        h: f64,
    ) -> (Option<usize>, Option<usize>) {
        let ug = cells.grid[g];
        // the last interval left of u_g ends at u_g
        let gi = cells.last[g];
        let lo = self.break_index(ug - h) + 1;
        let hi = self.break_index(ug + h);
        ((lo <= gi).then_some(lo), (hi > gi).then_some(hi))
    }
}
