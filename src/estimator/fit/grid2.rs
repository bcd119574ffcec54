//! The 2-D index's grid and its local-linear fits: U_t = (x_{t-d}, z_{t-d2}), the
//! model's own lagged value and another channel z of the log.
//!
//! Local-linear fits in both coordinates with the product Biweight kernel
//! K(w_1) K(w_2), w_k = (U_k - u_k)/h_k: at a grid point (u_1, u_2) the fit minimises
//! sum_t K(w_1) K(w_2) (y_t - X_t' (a + c_1 w_1 + c_2 w_2))^2 (3p unknowns), so
//! f = a, df/du_k = c_k / h_k (Ruppert and Wand 1994, multivariate local linear;
//! Cai, Fan and Yao 2000 for varying coefficients). The support is the box
//! [u_k - h_k, u_k + h_k) in each coordinate (half-open as in the 1-D path).
//!
//! - Grid: G1 x G2 points, each coordinate uniform over its central quantiles
//!   (0.01, 0.99); point g = i G2 + j is (grid1\[i\], grid2\[j\]).
//! - Gather: a kiddo 2-D KD-tree over the index values scaled by s_k = range_k / 2;
//!   a support is gathered with a Chebyshev (L-infinity) radius max(h_1/s_1, h_2/s_2)
//!   in scaled units, which covers the box, then filtered to the box exactly.
//! - Between grid points f is bilinear, constant beyond the grid in each coordinate;
//!   RSS and the trace of the smoother tr(H) = sum_t d yhat_t / d y_t are exact for
//!   that evaluation (the four corners of U_t's cell, as in `direct::rss_trace`).
//! - A grid point without a fit (status `empty_support`, `too_few_samples` (< 3p
//!   samples), `singular`) is filled with the f of the nearest grid point with a fit
//!   (distance in scaled units, ties to the lower index) and flagged.
//! - Index values before the first sample: x is 0 (as in 1-D), z is z_0.

use kiddo::{Chebyshev, ImmutableKdTree};
use rayon::prelude::*;

use crate::estimator::kernel::biweight;
use crate::estimator::linalg::spd_solve_inverse;
use crate::estimator::moments::sandwich_diag;
use crate::estimator::problem::PointStatus;
use crate::model::coef::{bilinear_corners, interp_rows2};

/// The regression data with a 2-D index (borrowed).
#[derive(Clone, Copy, Debug)]
pub struct Vc2Problem<'a> {
    /// The series (centred).
    pub x: &'a [f64],
    /// The second index channel (channel units), same length as x.
    pub z: &'a [f64],
    pub e: &'a [f64],
    pub b: &'a [f64],
    pub p: usize,
    pub d: usize,
    pub d2: usize,
    /// First row used: max(p, q, d, d2).
    pub start: usize,
}

impl Vc2Problem<'_> {
    pub fn n_rows(&self) -> usize {
        self.x.len().saturating_sub(self.start)
    }

    #[inline]
    pub fn u(&self, t: usize) -> (f64, f64) {
        (self.x[t - self.d], self.z[t - self.d2])
    }

    #[inline]
    pub fn y(&self, t: usize) -> f64 {
        let mut y = self.x[t];
        for (m, bm) in self.b.iter().enumerate() {
            y -= bm * self.e[t - m - 1];
        }
        y
    }

    #[inline]
    pub fn xr(&self, t: usize, m: usize) -> f64 {
        self.x[t - 1 - m]
    }
}

/// The 2-D grid: point g = i * n2 + j is (g1\[i\], g2\[j\]).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid2 {
    pub g1: Vec<f64>,
    pub g2: Vec<f64>,
}

impl Grid2 {
    pub fn len(&self) -> usize {
        self.g1.len() * self.g2.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    #[inline]
    pub fn point(&self, g: usize) -> (f64, f64) {
        let n2 = self.g2.len();
        (self.g1[g / n2], self.g2[g % n2])
    }

    /// The grid points whose bilinear weights at (u1, u2) may be non-zero, with the
    /// weights (constant beyond the grid in each coordinate): the model's
    /// interpolation ([`bilinear_corners`]).
    #[inline]
    pub fn corners(&self, u1: f64, u2: f64) -> [(usize, f64); 4] {
        bilinear_corners(&self.g1, &self.g2, u1, u2)
    }
}

/// Local-linear fits at every 2-D grid point for one bandwidth pair.
#[derive(Clone, Debug)]
pub struct Grid2Fit {
    pub bandwidth: (f64, f64),
    pub p: usize,
    /// f_m at each point, G x p (NaN where the status is not Ok).
    pub f: Vec<f64>,
    /// df_m/du_1 and df_m/du_2, G x p.
    pub slope1: Vec<f64>,
    pub slope2: Vec<f64>,
    /// S_g^-1, G x (3p)^2.
    pub s_inv: Vec<f64>,
    pub n_support: Vec<u64>,
    pub kernel_mass: Vec<f64>,
    pub cond: Vec<f64>,
    pub status: Vec<PointStatus>,
}

impl Grid2Fit {
    pub fn new(g: usize, p: usize, bandwidth: (f64, f64)) -> Self {
        Grid2Fit {
            bandwidth,
            p,
            f: vec![f64::NAN; g * p],
            slope1: vec![f64::NAN; g * p],
            slope2: vec![f64::NAN; g * p],
            s_inv: vec![f64::NAN; g * 9 * p * p],
            n_support: vec![0; g],
            kernel_mass: vec![0.0; g],
            cond: vec![f64::NAN; g],
            status: vec![PointStatus::EmptySupport; g],
        }
    }

    pub fn all_ok(&self) -> bool {
        self.status.iter().all(|s| *s == PointStatus::Ok)
    }

    /// Stores the solution of point g from its normal equations (3p x 3p).
    pub fn set_point(&mut self, g: usize, s: &[f64], rhs: &[f64], count: u64, mass: f64) {
        let p = self.p;
        let n = 3 * p;
        self.n_support[g] = count;
        self.kernel_mass[g] = mass;
        if count == 0 {
            self.status[g] = PointStatus::EmptySupport;
            return;
        }
        if (count as usize) < n {
            self.status[g] = PointStatus::TooFewSamples;
            return;
        }
        match spd_solve_inverse(s, rhs, n) {
            None => self.status[g] = PointStatus::Singular,
            Some((sol, inv, cond)) => {
                self.status[g] = PointStatus::Ok;
                self.cond[g] = cond;
                for m in 0..p {
                    self.f[g * p + m] = sol[m];
                    self.slope1[g * p + m] = sol[p + m] / self.bandwidth.0;
                    self.slope2[g * p + m] = sol[2 * p + m] / self.bandwidth.1;
                }
                self.s_inv[g * n * n..(g + 1) * n * n].copy_from_slice(&inv);
            }
        }
    }

    /// f at (u1, u2): bilinear between grid points, constant beyond (all points set):
    /// the model's interpolation ([`interp_rows2`]).
    #[inline]
    pub fn eval(&self, grid: &Grid2, u1: f64, u2: f64, out: &mut [f64]) {
        interp_rows2(&grid.g1, &grid.g2, &self.f, u1, u2, out)
    }
}

/// A 2-D KD-tree over the rows' index values, scaled by `scale`.
pub struct Index2 {
    tree: ImmutableKdTree<f64, 2>,
    start: usize,
    scale: (f64, f64),
}

impl Index2 {
    pub fn build(prob: &Vc2Problem, scale: (f64, f64)) -> Index2 {
        let pts: Vec<[f64; 2]> = (prob.start..prob.x.len())
            .map(|t| {
                let (a, b) = prob.u(t);
                [a / scale.0, b / scale.1]
            })
            .collect();
        assert!(pts.len() < u32::MAX as usize, "at most 2^32 - 1 rows");
        let tree = ImmutableKdTree::new_from_slice(&pts).expect("kd-tree construction");
        Index2 {
            tree,
            start: prob.start,
            scale,
        }
    }

    /// Rows whose scaled index lies within Chebyshev distance covering the box
    /// |U_k - c_k| <= h_k, ascending (a superset of the box; filter exactly after).
    pub fn gather(&self, centre: (f64, f64), h: (f64, f64)) -> Vec<usize> {
        let r = (h.0 / self.scale.0).max(h.1 / self.scale.1) * (1.0 + 1e-12);
        let mut rows = Vec::new();
        self.tree
            .query(&[centre.0 / self.scale.0, centre.1 / self.scale.1])
            .within::<Chebyshev<f64>>(r)
            .unsorted()
            .visit(|hit| rows.push(self.start + hit.item as usize));
        rows.sort_unstable();
        rows
    }
}

/// Row t's local design z = (X, w1 X, w2 X) at point (c1, c2); returns the product
/// kernel weight, or None when U_t is outside the box.
#[inline]
fn design(prob: &Vc2Problem, t: usize, c: (f64, f64), h: (f64, f64), z: &mut [f64]) -> Option<f64> {
    let (u1, u2) = prob.u(t);
    if !(c.0 - h.0 <= u1 && u1 < c.0 + h.0 && c.1 - h.1 <= u2 && u2 < c.1 + h.1) {
        return None;
    }
    let (w1, w2) = ((u1 - c.0) / h.0, (u2 - c.1) / h.1);
    let p = prob.p;
    for m in 0..p {
        let v = prob.xr(t, m);
        z[m] = v;
        z[p + m] = w1 * v;
        z[2 * p + m] = w2 * v;
    }
    Some(biweight(w1) * biweight(w2))
}

/// Local-linear fits at every grid point for bandwidths `h` (points in parallel,
/// rows summed in order: independent of the number of threads).
pub fn fit_grid2(prob: &Vc2Problem, index: &Index2, grid: &Grid2, h: (f64, f64)) -> Grid2Fit {
    let p = prob.p;
    let n = 3 * p;
    let points: Vec<(Vec<f64>, Vec<f64>, u64, f64)> = (0..grid.len())
        .into_par_iter()
        .map(|g| {
            let c = grid.point(g);
            let (mut s, mut rhs, mut z) = (vec![0.0; n * n], vec![0.0; n], vec![0.0; n]);
            let (mut count, mut mass) = (0u64, 0.0);
            for t in index.gather(c, h) {
                let Some(k) = design(prob, t, c, h, &mut z) else {
                    continue;
                };
                count += 1;
                mass += k;
                let y = prob.y(t);
                for i in 0..n {
                    let kz = k * z[i];
                    for j in 0..n {
                        s[i * n + j] += kz * z[j];
                    }
                    rhs[i] += kz * y;
                }
            }
            (s, rhs, count, mass)
        })
        .collect();
    let mut fit = Grid2Fit::new(grid.len(), p, h);
    for (g, (s, rhs, count, mass)) in points.into_iter().enumerate() {
        fit.set_point(g, &s, &rhs, count, mass);
    }
    fit
}

/// RSS and trace of the smoother by a pass over the rows (all points Ok).
pub fn rss_trace2(prob: &Vc2Problem, grid: &Grid2, fit: &Grid2Fit) -> (f64, f64) {
    const BLOCK: usize = 1 << 14;
    let p = prob.p;
    let n = 3 * p;
    let h = fit.bandwidth;
    let rows: Vec<usize> = (prob.start..prob.x.len()).collect();
    let parts: Vec<(f64, f64)> = rows
        .par_chunks(BLOCK)
        .map(|chunk| {
            let (mut f, mut z) = (vec![0.0; p], vec![0.0; n]);
            let (mut rss, mut tr) = (0.0, 0.0);
            for &t in chunk {
                let (u1, u2) = prob.u(t);
                fit.eval(grid, u1, u2, &mut f);
                let y = prob.y(t);
                let yhat: f64 = (0..p).map(|m| prob.xr(t, m) * f[m]).sum();
                rss += (y - yhat) * (y - yhat);
                for (g, omega) in grid.corners(u1, u2) {
                    if omega == 0.0 {
                        continue;
                    }
                    let Some(k) = design(prob, t, grid.point(g), h, &mut z) else {
                        continue;
                    };
                    let inv = &fit.s_inv[g * n * n..(g + 1) * n * n];
                    let mut acc = 0.0;
                    for a in 0..p {
                        let row = &inv[a * n..(a + 1) * n];
                        let rz: f64 = row.iter().zip(&z).map(|(r, zz)| r * zz).sum();
                        acc += z[a] * rz;
                    }
                    tr += omega * k * acc;
                }
            }
            (rss, tr)
        })
        .collect();
    parts
        .into_iter()
        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Sandwich standard-error factors sqrt(diag(S^-1 S2 S^-1)) for f (direct sums).
pub fn se_factors2(prob: &Vc2Problem, index: &Index2, grid: &Grid2, fit: &Grid2Fit) -> Vec<f64> {
    let p = prob.p;
    let n = 3 * p;
    let h = fit.bandwidth;
    let per_g: Vec<Vec<f64>> = (0..grid.len())
        .into_par_iter()
        .map(|g| {
            if fit.status[g] != PointStatus::Ok {
                return vec![f64::NAN; p];
            }
            let c = grid.point(g);
            let (mut s2, mut z) = (vec![0.0; n * n], vec![0.0; n]);
            for t in index.gather(c, h) {
                let Some(k) = design(prob, t, c, h, &mut z) else {
                    continue;
                };
                for i in 0..n {
                    for j in 0..n {
                        s2[i * n + j] += k * k * z[i] * z[j];
                    }
                }
            }
            sandwich_diag(&fit.s_inv[g * n * n..(g + 1) * n * n], &s2, n, p)
        })
        .collect();
    per_g.concat()
}

/// Fills points without a fit with the f of the nearest point with one (scaled
/// distance, ties to the lower index). Returns which were filled; None if none is Ok.
pub fn fill_failed2(fit: &mut Grid2Fit, grid: &Grid2, scale: (f64, f64)) -> Option<Vec<bool>> {
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
        let (a1, a2) = grid.point(g);
        let best = ok
            .iter()
            .copied()
            .min_by(|x, y| {
                let d = |k: usize| {
                    let (b1, b2) = grid.point(k);
                    ((a1 - b1) / scale.0).powi(2) + ((a2 - b2) / scale.1).powi(2)
                };
                d(*x).total_cmp(&d(*y)).then(x.cmp(y))
            })
            .unwrap();
        for m in 0..p {
            fit.f[g * p + m] = fit.f[best * p + m];
        }
    }
    Some(filled)
}

/// e_t = x_t - sum f_m(U_t) x_{t-m} - sum b_m e_{t-m}, zeros before the first sample;
/// U_t = (x_{t-d} (0 before the first sample), z_{max(t-d2, 0)}).
#[allow(clippy::too_many_arguments)]
pub fn residuals2(
    x: &[f64],
    z: &[f64],
    (d, d2): (usize, usize),
    grid: &Grid2,
    fit: &Grid2Fit,
    b: &[f64],
    e: &mut [f64],
) {
    let p = fit.p;
    let mut f = vec![0.0; p];
    for t in 0..x.len() {
        let u1 = if t >= d { x[t - d] } else { 0.0 };
        let u2 = z[t.saturating_sub(d2)];
        fit.eval(grid, u1, u2, &mut f);
        let mut s = x[t];
        for m in 0..p.min(t) {
            s -= f[m] * x[t - m - 1];
        }
        for (m, bm) in b.iter().enumerate() {
            if t > m {
                s -= bm * e[t - m - 1];
            }
        }
        e[t] = s;
    }
}
