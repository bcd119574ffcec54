//! Building a table: the one pass over the rows that accumulates every interval's
//! moments (fixed blocks of rows, in parallel, added in block order), its constructors,
//! and the re-summing of the response families alone when only the residuals change
//! ([`MomentTable::with_response`], [`MomentTable::into_response`]).

use rayon::prelude::*;

use super::index::{IntervalIndex, IntervalLookup};
use super::{Families, MomentTable, sorted_breaks};
use crate::estimator::problem::VcProblem;

impl MomentTable {
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
            let u = x.at(t - d);
            let e = find(t, u);
            count[e] += 1;
            let z = (u - centre[e]) / half[e];
            let mut pw = [1.0f64; D1];
            for k in 1..D1 {
                pw[k] = pw[k - 1] * z;
            }
            for (mm, vm) in v[..p].iter_mut().enumerate() {
                *vm = x.at(t - 1 - mm);
            }
            // y_t = x_t - sum b_m e_{t-m} (as VcProblem::y), when a family holds it
            if with_y {
                v[p] = match prob.resp {
                    Some((r, lag)) => r[t - lag],
                    None => {
                        let mut y = x.at(t);
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
            let u = x.at(t - d);
            let e = find(t, u);
            count[e] += 1;
            let z = (u - centre[e]) / half[e];
            let mut pw = [1.0f64; D1];
            for k in 1..D1 {
                pw[k] = pw[k - 1] * z;
            }
            let mut y = x.at(t);
            for (mm, bm) in bb.iter().enumerate() {
                y -= bm * ee[t - mm - 1];
            }
            let row: &mut [f64] = &mut m[e * width..(e + 1) * width];
            for a in 0..P {
                let val = x.at(t - 1 - a) * y;
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
}
