//! Solving the local systems: the kernel-weighted sums of a window give the local-linear
//! system S_g b = T_g at each grid point; its left-hand side depends on X and U only
//! ([`LocalSystems`], factored once and reused), its right-hand side on the response.
//! Fits at one bandwidth, a ladder of bandwidths, and a ladder's refit for new
//! residuals.

use rayon::prelude::*;

use super::MomentTable;
use super::cells::WholeCells;
use crate::estimator::kernel::{BIWEIGHT, binomial_table};
use crate::estimator::linalg::{SMALL_N, SpdFactor, small_spd_factor};
use crate::estimator::problem::GridFit;

/// The left-hand sides of the local systems at one bandwidth: S_g, the support's
/// sample count and kernel mass for every grid point.
#[derive(Clone)]
pub struct LocalSystems {
    grid: Vec<f64>,
    pub h: f64,
    p: usize,
    pub(super) points: Vec<(Vec<f64>, u64, f64)>,
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
pub(super) fn kernel_contraction<'a>(
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
pub(super) fn local_rhs_of(
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

impl MomentTable {
    /// S = sum K(w) Z Z' with Z = (X, w X) (row-major 2p x 2p) from the weighted
    /// moments `a_of(family, r)` of [`kernel_contraction`].
    pub(super) fn local_lhs(&self, a_of: &impl Fn(usize, usize) -> f64) -> Vec<f64> {
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
    pub(super) fn local_rhs(&self, a_of: &impl Fn(usize, usize) -> f64) -> Vec<f64> {
        local_rhs_of(self.p, a_of, |a| self.fam(a, self.p))
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
    /// [`Families::Response`](super::Families::Response) or full table of the same
    /// breakpoints, degree 5 or more: the right-hand sides need powers up to 5) and the
    /// reused left-hand sides: the windows are summed as in [`MomentTable::fit_ladder`] (the
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
}
