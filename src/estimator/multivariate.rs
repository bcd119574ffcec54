//! The multivariate index: f_m depends on U_t = (x_{t-d}, z_{t-d2}), the model's own
//! lagged value and another channel z of the log (for example temperature):
//! x_t = sum_m f_m(x_{t-d}, z_{t-d2}) x_{t-m} + e_t + sum_m b_m e_{t-m}.
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
//! - Bandwidths: GCV over a common scaled ladder h_j = 1.1^-j (range_1/2, range_2/2),
//!   j = 0..20 (the paper's rule applied to each coordinate's range with one j), so
//!   the box is a square in scaled units and the Chebyshev gather fetches nothing
//!   outside it; the ladder is extended while the minimum sits at an end, as in 1-D.
//!   A fixed pair (h_1, h_2) can be given instead.
//! - Between grid points f is bilinear, constant beyond the grid in each coordinate;
//!   RSS and the trace of the smoother tr(H) = sum_t d yhat_t / d y_t are exact for
//!   that evaluation (the four corners of U_t's cell, as in `direct::rss_trace`).
//! - A grid point without a fit (status `empty_support`, `too_few_samples` (< 3p
//!   samples), `singular`) is filled with the f of the nearest grid point with a fit
//!   (distance in scaled units, ties to the lower index) and flagged.
//! - The alternation (ARMA start, f-step, Gauss-Newton b-step, residual recursion,
//!   GCV on the first f-step and again each time the RSS settles, at most twice; a
//!   new pair continues the alternation) is the one of
//!   [`super::fit`](fn@super::fit), written here for the 2-D smoother: fit.rs's loop is built around
//!   its 1-D smoother and is being restructured for speed; `ma_cls` and `fit_arma`
//!   are shared. Index values before the first sample: x is 0 (as in 1-D), z is z_0.

use std::sync::Arc;

use arrow_array::builder::{Float64Builder, ListBuilder};
use arrow_array::{
    ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray, UInt64Array,
};
use kiddo::{Chebyshev, ImmutableKdTree};
use rayon::prelude::*;

use super::arma::fit_arma;
use super::fit::{
    FarmaParams, FitPath, ma_cls, ma_edge_note, missing_se_note, reselection_limit_note,
    stretched_ladder_note, undefined_trace_note,
};
use super::kernel::biweight;
use super::linalg::spd_solve_inverse;
use super::moments::sandwich_diag;
use super::problem::PointStatus;
use crate::error::{Error, Result};
use crate::output::batch;

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
    /// weights (constant beyond the grid in each coordinate).
    #[inline]
    pub fn corners(&self, u1: f64, u2: f64) -> [(usize, f64); 4] {
        let (i0, i1, a) = axis(&self.g1, u1);
        let (j0, j1, c) = axis(&self.g2, u2);
        let n2 = self.g2.len();
        [
            (i0 * n2 + j0, (1.0 - a) * (1.0 - c)),
            (i1 * n2 + j0, a * (1.0 - c)),
            (i0 * n2 + j1, (1.0 - a) * c),
            (i1 * n2 + j1, a * c),
        ]
    }
}

/// Cell of `u` on an ascending axis: (left, right, weight of right).
#[inline]
fn axis(g: &[f64], u: f64) -> (usize, usize, f64) {
    let n = g.len();
    if u <= g[0] {
        (0, 0, 0.0)
    } else if u >= g[n - 1] {
        (n - 1, n - 1, 0.0)
    } else {
        let k = g.partition_point(|v| *v <= u) - 1;
        (k, k + 1, (u - g[k]) / (g[k + 1] - g[k]))
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

    /// f at (u1, u2): bilinear between grid points, constant beyond (all points set).
    #[inline]
    pub fn eval(&self, grid: &Grid2, u1: f64, u2: f64, out: &mut [f64]) {
        let p = self.p;
        out.iter_mut().for_each(|v| *v = 0.0);
        for (g, w) in grid.corners(u1, u2) {
            if w != 0.0 {
                for m in 0..p {
                    out[m] += w * self.f[g * p + m];
                }
            }
        }
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

/// The most grid points (G1 x G2) of a 2-D index. Every rung of the GCV ladders
/// keeps its local fits (an inverse 3p x 3p system per point: 2.6 kB at p = 6) and
/// gathers every point's support, so memory and time grow with G1 x G2: 200 x 200
/// is about 100 MB per rung at p = 6, and 100,000 x 100,000 would have the allocator
/// abort the process.
pub const MAX_GRID2_POINTS: usize = 40_000;

/// `--index-grid N1,N2`: at least 3 points per coordinate and at most
/// [`MAX_GRID2_POINTS`] in all (a usage error, before any work).
pub fn check_grid2((g1, g2): (usize, usize)) -> Result<()> {
    if g1 < 3 || g2 < 3 {
        return Err(Error::Usage(format!(
            "--index-grid: at least 3 points per coordinate (got {g1},{g2})"
        )));
    }
    match g1.checked_mul(g2) {
        Some(g) if g <= MAX_GRID2_POINTS => Ok(()),
        _ => Err(Error::Usage(format!(
            "--index-grid {g1},{g2}: at most {MAX_GRID2_POINTS} grid points in all (G1 x G2, e.g. 200,200; the default 21,21 has 441): every rung of the GCV ladders keeps a local fit per point and gathers its support, so memory and time grow with G1 x G2"
        ))),
    }
}

/// Parameters of a fit with a 2-D index.
#[derive(Clone, Debug)]
pub struct Farma2Params {
    /// p, q, d, tolerances, demeaning, grid quantiles (grid_size and bandwidth unused).
    pub base: FarmaParams,
    /// Lag of the second index channel.
    pub d2: usize,
    /// Grid points per coordinate (G1, G2).
    pub grid: (usize, usize),
    /// A fixed bandwidth pair instead of GCV.
    pub bandwidth: Option<(f64, f64)>,
}

/// One row of the 2-D GCV table.
#[derive(Clone, Debug, PartialEq)]
pub struct Gcv2Row {
    pub j: i32,
    pub bandwidth: (f64, f64),
    pub rss: f64,
    pub trace: f64,
    pub gcv: f64,
    pub n_failed: usize,
}

/// A fitted FARMA model with a 2-D index.
#[derive(Clone, Debug)]
pub struct Fitted2 {
    pub p: usize,
    pub q: usize,
    pub d: usize,
    pub d2: usize,
    pub mean: f64,
    pub grid: Grid2,
    pub coef: Grid2Fit,
    /// sigma times the sandwich factor, G x p; NaN at filled points.
    pub se: Vec<f64>,
    pub filled: Vec<bool>,
    pub b: Vec<f64>,
    pub bandwidth: (f64, f64),
    pub rss: f64,
    pub sigma2: f64,
    pub trace: f64,
    /// GCV = (RSS/m) / (1 - trace/m)^2 of the returned model, from its own RSS
    /// (`rss`) and the smoother's trace at its bandwidths, as the 1-D fit's.
    pub gcv: f64,
    pub gcv_table: Vec<Gcv2Row>,
    pub ladder_extended: bool,
    pub iterations: usize,
    pub converged: bool,
    pub n: usize,
    pub n_rows: usize,
    pub residuals: Vec<f64>,
    pub notes: Vec<String>,
}

fn range_of(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        })
}

fn quantile_pair(mut v: Vec<f64>, (lo, hi): (f64, f64)) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    let q = |q: f64| {
        let pos = q * (v.len() - 1) as f64;
        let (i, frac) = (pos.floor() as usize, pos - pos.floor());
        if i + 1 < v.len() {
            v[i] + frac * (v[i + 1] - v[i])
        } else {
            v[i]
        }
    };
    (q(lo), q(hi))
}

struct Smoother2<'a> {
    prob: Vc2Problem<'a>,
    grid: &'a Grid2,
    index: &'a Index2,
}

impl Smoother2<'_> {
    fn at(&self, h: (f64, f64)) -> (Grid2Fit, Option<(f64, f64)>) {
        let f = fit_grid2(&self.prob, self.index, self.grid, h);
        let rt = f.all_ok().then(|| rss_trace2(&self.prob, self.grid, &f));
        (f, rt)
    }
}

/// GCV over the common scaled ladder, extended while the minimum sits at an end.
fn gcv_select2(
    sm: &Smoother2,
    half: (f64, f64),
) -> (Vec<Gcv2Row>, Grid2Fit, usize, bool, Vec<String>) {
    let m = sm.prob.n_rows() as f64;
    let mut rows: Vec<Gcv2Row> = Vec::new();
    let mut fits: Vec<Grid2Fit> = Vec::new();
    let mut notes = Vec::new();
    let mut extended = false;
    let mut js: Vec<i32> = (0..=20).collect();
    loop {
        for &j in &js {
            if rows.iter().any(|r| r.j == j) {
                continue;
            }
            let s = 1.1f64.powi(-j);
            let h = (s * half.0, s * half.1);
            let (f, rt) = sm.at(h);
            let n_failed = f.status.iter().filter(|s| **s != PointStatus::Ok).count();
            let row = match rt {
                Some((rss, tr)) if tr < m => Gcv2Row {
                    j,
                    bandwidth: h,
                    rss,
                    trace: tr,
                    gcv: (rss / m) / (1.0 - tr / m).powi(2),
                    n_failed,
                },
                _ => Gcv2Row {
                    j,
                    bandwidth: h,
                    rss: f64::NAN,
                    trace: f64::NAN,
                    gcv: f64::INFINITY,
                    n_failed,
                },
            };
            rows.push(row);
            fits.push(f);
        }
        let mut order: Vec<usize> = (0..rows.len()).collect();
        order.sort_by_key(|k| rows[*k].j);
        rows = order.iter().map(|k| rows[*k].clone()).collect();
        fits = order.iter().map(|k| fits[*k].clone()).collect();
        let best = rows
            .iter()
            .enumerate()
            .filter(|(_, r)| r.gcv.is_finite())
            .min_by(|a, b| a.1.gcv.total_cmp(&b.1.gcv))
            .map(|(i, _)| i);
        let last = rows.len() - 1;
        match best {
            Some(i) if i == last && rows[last].j < 60 => {
                let next = rows[last].j + 1;
                notes.push(format!(
                    "GCV minimum at the smallest bandwidths of the ladder (j = {}): extended to j = {}",
                    rows[last].j,
                    next + 9
                ));
                js = (next..next + 10).collect();
                extended = true;
            }
            // the minimum at the largest bandwidths, or no pair that fits every grid
            // point: wider bandwidths
            Some(0) | None if rows[0].j > -10 => {
                let first = rows[0].j;
                notes.push(if best.is_some() {
                    format!(
                        "GCV minimum at the largest bandwidths of the ladder (j = {first}): extended upwards"
                    )
                } else {
                    format!(
                        "GCV: no bandwidth pair of the ladder from j = {first} down gives a fit at every grid point: extended upwards"
                    )
                });
                js = (first - 5..first).collect();
                extended = true;
            }
            Some(i) => {
                if i == 0 || i == last {
                    // at an end no further extension reaches (as in 1-D)
                    notes.push(format!(
                        "GCV minimum at the {} bandwidths h_j (j = {}), the end of the ladder's extensions: the optimum may lie beyond it",
                        if i == 0 { "largest" } else { "smallest" },
                        rows[i].j
                    ));
                }
                let f = fits.swap_remove(i);
                return (rows, f, i, extended, notes);
            }
            None => {
                notes.push(
                    "GCV: no bandwidth pair of the ladder gives a fit at every grid point: the one with the fewest grid points without a fit is used (its GCV is not defined)".into(),
                );
                let i = rows
                    .iter()
                    .enumerate()
                    .min_by_key(|(_, r)| r.n_failed)
                    .map(|(i, _)| i)
                    .unwrap_or(0);
                let f = fits.swap_remove(i);
                return (rows, f, i, extended, notes);
            }
        }
    }
}

/// The checks of a 2-D fit of `n` samples on the index channel `z` that do not depend
/// on the fitted channel: the index lag, the grid and the bandwidths, the length, and
/// the index channel (finite, not constant). [`fit2`] makes them; a run over several
/// channels makes them once before, so that such a problem is said once, not once per
/// channel.
pub fn check_fit2(n: usize, z: &[f64], params: &Farma2Params) -> Result<()> {
    let prm = &params.base;
    let (p, q, d, d2) = (prm.p, prm.q, prm.d, params.d2);
    let bad = |m: String| Err(Error::Usage(m));
    if d2 > 1000 {
        return bad(format!("--index-lag: at most 1000 (got {d2})"));
    }
    check_grid2(params.grid)?;
    if let Some((a, b)) = params.bandwidth
        && !(a.is_finite() && a > 0.0 && b.is_finite() && b > 0.0)
    {
        return bad(format!(
            "--bandwidth: ({a}, {b}) is not a pair of positive numbers"
        ));
    }
    let pp = p.max(q).max(d).max(d2);
    let need = (20 * (3 * p + q) + pp + 1).max(100);
    if n < need {
        return Err(Error::TooShort {
            what: format!("FARMA({p},{q},{d}) fit with a 2-D index"),
            need: need as u64,
            have: n as u64,
        });
    }
    if z.iter().any(|v| !v.is_finite()) {
        return bad("the index channel holds NaN or infinite values".into());
    }
    let (z_lo, z_hi) = range_of(z);
    if z_hi - z_lo <= 0.0 {
        return bad("the index channel is constant: it cannot index anything".into());
    }
    Ok(())
}

/// Fits a FARMA model whose f_m depend on (x_{t-d}, z_{t-d2}).
pub fn fit2(series: &[f64], z: &[f64], params: &Farma2Params) -> Result<Fitted2> {
    let prm = &params.base;
    let (p, q, d, d2) = (prm.p, prm.q, prm.d, params.d2);
    let n = series.len();
    let bad = |m: String| Err(Error::Usage(m));
    if z.len() != n {
        return bad("the index channel and the series differ in length".into());
    }
    check_fit2(n, z, params)?;
    let pp = p.max(q).max(d).max(d2);
    let mean = if prm.demean {
        series.iter().sum::<f64>() / n as f64
    } else {
        0.0
    };
    let x: Vec<f64> = series.iter().map(|v| v - mean).collect();
    if x.iter().any(|v| !v.is_finite()) {
        return bad("the channel holds NaN or infinite values".into());
    }
    let (x_lo, x_hi) = range_of(&x);
    let (z_lo, z_hi) = range_of(z);
    let range = (x_hi - x_lo, z_hi - z_lo);
    if range.0 <= 0.0 {
        return bad("the channel is constant: nothing to fit".into());
    }
    if range.1 <= 0.0 {
        return bad("the index channel is constant: it cannot index anything".into());
    }
    // the 2-D fit sums squares of the values and of their products with the index
    // offsets (z - c), as the direct path does
    super::fit::check_magnitude("the channel", x_lo, x_hi, FitPath::Direct)
        .map_err(Error::Usage)?;
    super::fit::check_magnitude(
        "the index channel's spread (max - min)",
        0.0,
        range.1,
        FitPath::Direct,
    )
    .map_err(Error::Usage)?;
    let half = (range.0 / 2.0, range.1 / 2.0);
    let q1 = quantile_pair((pp..n).map(|t| x[t - d]).collect(), prm.grid_quantiles);
    let q2 = quantile_pair((pp..n).map(|t| z[t - d2]).collect(), prm.grid_quantiles);
    if q1.1 <= q1.0 || q2.1 <= q2.0 {
        return bad(
            "an index coordinate takes one value over its central quantiles: no grid to fit on"
                .into(),
        );
    }
    let uni = |(lo, hi): (f64, f64), g: usize| -> Vec<f64> {
        (0..g)
            .map(|k| lo + (hi - lo) * k as f64 / (g - 1) as f64)
            .collect()
    };
    let grid = Grid2 {
        g1: uni(q1, params.grid.0),
        g2: uni(q2, params.grid.1),
    };
    let gl = grid.len();

    // 1. start: linear ARMA(p,q)
    let arma = fit_arma(&x, p, q)
        .ok_or_else(|| Error::Usage("the linear ARMA start failed (singular design)".into()))?;
    let mut b = arma.ma;
    let mut coef = Grid2Fit::new(gl, p, (f64::NAN, f64::NAN));
    for g in 0..gl {
        coef.status[g] = PointStatus::Ok;
        coef.f[g * p..(g + 1) * p].copy_from_slice(&arma.ar);
    }
    let mut e = vec![0.0; n];
    residuals2(&x, z, (d, d2), &grid, &coef, &b, &mut e);
    let rss_of = |e: &[f64]| e[pp..].iter().map(|v| v * v).sum::<f64>();
    let mut rss = rss_of(&e);

    // the index values do not change during the alternation: one tree
    let prob0 = Vc2Problem {
        x: &x,
        z,
        e: &[],
        b: &[],
        p,
        d,
        d2,
        start: pp,
    };
    let index = Index2::build(&prob0, half);
    let mut h = params.bandwidth.unwrap_or((f64::NAN, f64::NAN));
    let mut gcv_table = Vec::new();
    let mut notes = Vec::new();
    if params.bandwidth.is_none() {
        notes.extend(stretched_ladder_note(
            &format!("the index values x_(t-{d}) (less the channel's mean)"),
            (x_lo, x_hi),
            q1,
            prm.grid_quantiles,
        ));
        notes.extend(stretched_ladder_note(
            &format!("the index channel's values (lag {d2})"),
            (z_lo, z_hi),
            q2,
            prm.grid_quantiles,
        ));
    }
    let mut ladder_extended = false;
    let mut filled = vec![false; gl];
    let (mut iterations, mut converged, mut reselections) = (0, false, 0);
    // the bandwidth pairs the alternation has run at, in order (GCV's choices)
    let mut visited: Vec<(f64, f64)> = Vec::new();
    let mut stopped_at_reselection = false;
    let mut need_gcv = params.bandwidth.is_none();
    while iterations < prm.max_iter {
        iterations += 1;
        let prob = Vc2Problem {
            e: &e,
            b: &b,
            ..prob0
        };
        let sm = Smoother2 {
            prob,
            grid: &grid,
            index: &index,
        };
        let mut fit_h = if need_gcv {
            need_gcv = false;
            let (rows, f, best, ext, nt) = gcv_select2(&sm, half);
            ladder_extended |= ext;
            notes.extend(nt);
            h = rows[best].bandwidth;
            gcv_table = rows;
            f
        } else {
            sm.at(h).0
        };
        filled = fill_failed2(&mut fit_h, &grid, half).ok_or_else(|| {
            Error::Usage(format!(
                "no grid point has a local fit at bandwidths ({:.6e}, {:.6e}): every local system is empty or singular: bandwidths far from the index values' spread, too few distinct index values near each grid point (a quantised channel, or a spike that stretches the range; `farma prep` removes outliers), or regressors that are exactly dependent (an index channel that copies a lag of the channel, a deterministic trend)",
                h.0, h.1
            ))
        })?;
        coef = fit_h;
        if q > 0 {
            let mut w = vec![0.0; n];
            residuals2(&x, z, (d, d2), &grid, &coef, &[], &mut w);
            b = ma_cls(&w, pp, &b);
        }
        residuals2(&x, z, (d, d2), &grid, &coef, &b, &mut e);
        let new_rss = rss_of(&e);
        let change = (rss - new_rss).abs();
        rss = new_rss;
        if change <= prm.tol * rss.max(f64::MIN_POSITIVE) {
            if params.bandwidth.is_none() && reselections < 2 {
                let prob = Vc2Problem {
                    e: &e,
                    b: &b,
                    ..prob0
                };
                let sm = Smoother2 {
                    prob,
                    grid: &grid,
                    index: &index,
                };
                let (rows, _, best, ext, nt) = gcv_select2(&sm, half);
                reselections += 1;
                if rows[best].bandwidth != h && iterations == prm.max_iter {
                    // no alternation left to fit at the new pair: the model stays at h
                    // (its coefficients are the f-step's at h), not converged
                    notes.push(format!(
                        "alternation {iterations}: the RSS settled at bandwidths ({:.6e}, {:.6e}); GCV at those residuals chose ({:.6e}, {:.6e}), but --max-iter {} ends the alternation here: NOT converged, the model is at the bandwidths it settled at",
                        h.0, h.1, rows[best].bandwidth.0, rows[best].bandwidth.1, prm.max_iter
                    ));
                    stopped_at_reselection = true;
                    break;
                }
                if rows[best].bandwidth != h {
                    // the alternation settled at h, but has not converged: it goes on
                    // at the new pair, and may not settle again within --max-iter
                    notes.push(format!(
                        "alternation {iterations}: the RSS settled at bandwidths ({:.6e}, {:.6e}); GCV at those residuals chose ({:.6e}, {:.6e}), and the alternation went on at them",
                        h.0, h.1, rows[best].bandwidth.0, rows[best].bandwidth.1
                    ));
                    if visited.is_empty() {
                        visited.push(h);
                    }
                    visited.push(rows[best].bandwidth);
                    ladder_extended |= ext;
                    notes.extend(nt);
                    h = rows[best].bandwidth;
                    gcv_table = rows;
                    continue;
                }
                gcv_table = rows;
            } else if params.bandwidth.is_none() {
                notes.push(reselection_limit_note(iterations, &visited, |h| {
                    format!("({:.6e}, {:.6e})", h.0, h.1)
                }));
            }
            converged = true;
            break;
        }
    }
    if !converged && !stopped_at_reselection && !visited.is_empty() {
        let fmt = |h: (f64, f64)| format!("({:.6e}, {:.6e})", h.0, h.1);
        let swing = visited[..visited.len() - 1].contains(&h);
        notes.push(format!(
            "NOT converged: after {} bandwidth re-selection(s) the alternation did not settle again within --max-iter {} alternations; the model is at bandwidths {}, GCV's last choice{}",
            visited.len() - 1,
            prm.max_iter,
            fmt(h),
            if swing {
                format!(
                    "; GCV swung back and forth ({}): fix the pair with --bandwidth H1 --bandwidth2 H2, or raise --max-iter",
                    visited.iter().map(|v| fmt(*v)).collect::<Vec<_>>().join(" -> ")
                )
            } else {
                String::new()
            }
        ));
    }
    let prob = Vc2Problem {
        e: &e,
        b: &b,
        ..prob0
    };
    let sm = Smoother2 {
        prob,
        grid: &grid,
        index: &index,
    };
    let (final_fit, rt) = sm.at(h);
    let m = (n - pp) as f64;
    // the returned model's GCV, from its own RSS (as the 1-D fit's)
    let trace = rt.map_or(f64::NAN, |(_, tr)| tr);
    if trace.is_nan() {
        let at = format!("bandwidths ({:.6e}, {:.6e})", h.0, h.1);
        notes.push(undefined_trace_note(&final_fit.status, &at));
    }
    let gcv = (rss / m) / (1.0 - trace / m).powi(2);
    let sigma2 = rss / m;
    let se: Vec<f64> = se_factors2(&prob, &index, &grid, &final_fit)
        .iter()
        .map(|f| f * sigma2.sqrt())
        .collect();
    notes.extend(missing_se_note(&final_fit.status, &final_fit.cond, &se, p));
    notes.extend(ma_edge_note(&b));
    let n_filled = filled.iter().filter(|f| **f).count();
    if n_filled > 0 {
        notes.push(format!(
            "{n_filled} grid point(s) without a local fit were filled from the nearest point with one (see status)"
        ));
    }
    Ok(Fitted2 {
        p,
        q,
        d,
        d2,
        mean,
        grid,
        coef,
        se,
        filled,
        b,
        bandwidth: h,
        rss,
        sigma2,
        trace,
        gcv,
        gcv_table,
        ladder_extended,
        iterations,
        converged,
        n,
        n_rows: n - pp,
        residuals: e,
        notes,
    })
}

fn sa(v: Vec<String>) -> ArrayRef {
    Arc::new(StringArray::from(v))
}
fn fa(v: Vec<f64>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}
fn ia(v: Vec<i64>) -> ArrayRef {
    Arc::new(Int64Array::from(v))
}

/// Coefficient functions on the 2-D grid: the columns of the 1-D coef.parquet plus
/// `grid2` (the second index value) and `slope2` (df/du_2); `slope` is df/du_1.
pub fn coef_table2(models: &[(String, &Fitted2)]) -> Result<RecordBatch> {
    let (mut ch, mut m_, mut g1, mut g2, mut fv) = (vec![], vec![], vec![], vec![], vec![]);
    let (mut s1, mut s2, mut se, mut nsup, mut mass) = (vec![], vec![], vec![], vec![], vec![]);
    let (mut cond, mut status, mut filled) = (vec![], vec![], vec![]);
    for (name, m) in models {
        let p = m.p;
        for g in 0..m.grid.len() {
            let (a, b) = m.grid.point(g);
            for k in 0..p {
                ch.push(name.clone());
                m_.push(k as i64 + 1);
                g1.push(a + m.mean);
                g2.push(b);
                fv.push(m.coef.f[g * p + k]);
                s1.push(m.coef.slope1[g * p + k]);
                s2.push(m.coef.slope2[g * p + k]);
                se.push(m.se[g * p + k]);
                nsup.push(m.coef.n_support[g]);
                mass.push(m.coef.kernel_mass[g]);
                cond.push(m.coef.cond[g]);
                status.push(m.coef.status[g].as_str().to_string());
                filled.push(m.filled[g]);
            }
        }
    }
    batch(vec![
        ("channel", sa(ch)),
        ("m", ia(m_)),
        ("grid", fa(g1)),
        ("grid2", fa(g2)),
        ("f", fa(fv)),
        ("slope", fa(s1)),
        ("slope2", fa(s2)),
        ("se", fa(se)),
        ("n_support", Arc::new(UInt64Array::from(nsup))),
        ("kernel_mass", fa(mass)),
        ("cond", fa(cond)),
        ("status", sa(status)),
        ("filled", Arc::new(BooleanArray::from(filled))),
    ])
}

/// One row per channel: the columns of the 1-D params.parquet (`bandwidth` is h_1)
/// plus `bandwidth2`, `d2` and `index2` (the second index channel).
pub fn params_table2(models: &[(String, &Fitted2)], index2: &str) -> Result<RecordBatch> {
    let mut b = ListBuilder::new(Float64Builder::new());
    for (_, m) in models {
        b.values().append_slice(&m.b);
        b.append(true);
    }
    let col = |g: &dyn Fn(&Fitted2) -> f64| fa(models.iter().map(|(_, m)| g(m)).collect());
    let coli = |g: &dyn Fn(&Fitted2) -> i64| ia(models.iter().map(|(_, m)| g(m)).collect());
    let k = models.len();
    batch(vec![
        (
            "channel",
            sa(models.iter().map(|(n, _)| n.clone()).collect()),
        ),
        ("p", coli(&|m| m.p as i64)),
        ("q", coli(&|m| m.q as i64)),
        ("d", coli(&|m| m.d as i64)),
        ("b", Arc::new(b.finish())),
        ("mean", col(&|m| m.mean)),
        ("sigma2", col(&|m| m.sigma2)),
        ("bandwidth", col(&|m| m.bandwidth.0)),
        ("rss", col(&|m| m.rss)),
        ("trace", col(&|m| m.trace)),
        ("gcv", col(&|m| m.gcv)),
        ("iterations", coli(&|m| m.iterations as i64)),
        (
            "converged",
            Arc::new(BooleanArray::from(
                models.iter().map(|(_, m)| m.converged).collect::<Vec<_>>(),
            )),
        ),
        (
            "ladder_extended",
            Arc::new(BooleanArray::from(
                models
                    .iter()
                    .map(|(_, m)| m.ladder_extended)
                    .collect::<Vec<_>>(),
            )),
        ),
        ("init", sa(vec!["arma".to_string(); k])),
        ("method", sa(vec!["direct".to_string(); k])),
        ("n", coli(&|m| m.n as i64)),
        ("n_rows", coli(&|m| m.n_rows as i64)),
        ("bandwidth2", col(&|m| m.bandwidth.1)),
        ("d2", coli(&|m| m.d2 as i64)),
        ("index2", sa(vec![index2.to_string(); k])),
    ])
}

/// The GCV ladder: the 1-D columns (`bandwidth` is h_1) plus `bandwidth2`.
pub fn gcv_table2(models: &[(String, &Fitted2)]) -> Result<RecordBatch> {
    let (mut ch, mut j, mut h1, mut h2, mut rss) = (vec![], vec![], vec![], vec![], vec![]);
    let (mut tr, mut gcv, mut nf, mut chosen) = (vec![], vec![], vec![], vec![]);
    for (name, m) in models {
        for r in &m.gcv_table {
            ch.push(name.clone());
            // the rung, as the notes name it (h_j = 1.1^-j (range_1/2, range_2/2))
            j.push(r.j as i64);
            h1.push(r.bandwidth.0);
            h2.push(r.bandwidth.1);
            rss.push(r.rss);
            tr.push(r.trace);
            gcv.push(r.gcv);
            nf.push(r.n_failed as i64);
            chosen.push(r.bandwidth == m.bandwidth);
        }
    }
    batch(vec![
        ("channel", sa(ch)),
        ("j", ia(j)),
        ("bandwidth", fa(h1)),
        ("bandwidth2", fa(h2)),
        ("rss", fa(rss)),
        ("trace", fa(tr)),
        ("gcv", fa(gcv)),
        ("n_failed", ia(nf)),
        ("chosen", Arc::new(BooleanArray::from(chosen))),
    ])
}
