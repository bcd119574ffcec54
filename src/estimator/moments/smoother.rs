//! What the smoother's fit gives beyond f: the exact RSS and trace of the smoother (f
//! linear between grid points), the standard-error factors (the sandwich S^-1 S2 S^-1
//! with the squared kernel), and the per-grid-point systems that an online update
//! keeps.

use rayon::prelude::*;

use super::MomentTable;
use super::cells::Piece;
use super::fits::kernel_contraction;
use crate::estimator::kernel::{BIWEIGHT, binomial_table, poly_mul};
use crate::estimator::problem::GridFit;

impl MomentTable {
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

    /// The smoother's trace alone ([`MomentTable::rss_trace`]'s, the same bits): it needs only the
    /// design's families (an [`Families::All`](super::Families::All) or
    /// [`Families::Design`](super::Families::Design) table) and `fit`'s inverses S_g^-1, not its
    /// values.
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
                if fit.status[g] != crate::estimator::problem::PointStatus::Ok {
                    return vec![f64::NAN; p];
                }
                let (acc, _) = self.window(&cells, g, h, 10, &binom);
                let s2 = self.local_lhs(&kernel_contraction(&acc, d1, h, &k2));
                sandwich_diag(&fit.s_inv[g * n * n..(g + 1) * n * n], &s2, n, p)
            })
            .collect();
        per_g.concat()
    }

    /// The normal equations of the online state at bandwidth `h` from a table of the design's
    /// families ([`Families::Design`](super::Families::Design), degree 10), for every grid point:
    /// S_g = sum K(w) Z Z' (Z = (X, w X), w = (U - u_g)/h, row-major 2p x 2p), S2_g =
    /// sum K(w)^2 Z Z', the support's sample count and kernel mass sum K(w): the sums of
    /// `update::state_from_fit_direct` over the rows in [u_g - h, u_g + h), from the window moments
    /// of [`MomentTable::se_factors`].
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
    /// the X_a y families ([`Families::Response`](super::Families::Response), degree 5 or
    /// more), the windows summed as in [`MomentTable::fit_response`].
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

/// sqrt of the first p diagonal entries of Q S2 Q (Q symmetric, row-major n x n); NaN
/// where the computed entry is not positive: with S2 positive definite it is positive,
/// but Q S2 Q squares the condition number of the local system (Q = S^-1), and past
/// about 1e8 rounding can leave it at or below 0 (the callers count such points in a
/// note, [`crate::estimator::fit::missing_se_note`]).
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
