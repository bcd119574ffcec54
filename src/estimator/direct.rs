//! The direct path: for each grid point the KD-tree (kiddo) gathers the samples inside
//! the Biweight support, the local normal equations are summed sample by sample (in
//! row order) and solved with faer. Works for any kernel and evaluation point; it is
//! the reference the moment tables are checked against.
//!
//! Also the direct (second data pass) RSS and trace of the smoother with f between
//! grid points by linear interpolation:
//! RSS = sum_t (y_t - X_t' f(U_t))^2 and tr(H) = sum_t d yhat_t / d y_t, where
//! d yhat_t / d y_t = sum_{g in {k, k+1}} omega_g(U_t) K((U_t - u_g)/h) X_t' [I 0] S_g^{-1} Z_t(u_g),
//! omega the linear interpolation weights of the cell [u_k, u_{k+1}) holding U_t.
//! A support is the half-open window [u_g - h, u_g + h) (the kernel is zero at its
//! edges, so this only fixes which tied samples are counted).

use kiddo::{ImmutableKdTree, Manhattan};
use rayon::prelude::*;

use super::kernel::biweight;
use super::problem::{GridFit, VcProblem};

/// A KD-tree over the index values of the rows of a problem.
pub struct DirectIndex {
    tree: ImmutableKdTree<f64, 1>,
    start: usize,
}

impl DirectIndex {
    pub fn build(prob: &VcProblem) -> DirectIndex {
        let pts: Vec<[f64; 1]> = (prob.start..prob.x.len()).map(|t| [prob.u(t)]).collect();
        assert!(
            pts.len() < u32::MAX as usize,
            "direct path: at most 2^32 - 1 rows"
        );
        let tree = ImmutableKdTree::new_from_slice(&pts).expect("kd-tree construction");
        DirectIndex {
            tree,
            start: prob.start,
        }
    }

    /// Rows t with |U_t - centre| <= radius, ascending.
    pub fn gather(&self, centre: f64, radius: f64) -> Vec<usize> {
        let mut rows = Vec::new();
        self.tree
            .query(&[centre])
            .within::<Manhattan<f64>>(radius)
            .unsorted()
            .visit(|hit| rows.push(self.start + hit.item as usize));
        rows.sort_unstable();
        rows
    }
}

/// Local-linear fits at every grid point for bandwidth `h`.
pub fn fit_grid(prob: &VcProblem, index: &DirectIndex, grid: &[f64], h: f64) -> GridFit {
    let p = prob.p;
    let n = 2 * p;
    let points: Vec<(Vec<f64>, Vec<f64>, u64, f64)> = grid
        .par_iter()
        .map(|&ug| {
            let mut s = vec![0.0; n * n];
            let mut rhs = vec![0.0; n];
            let mut z = vec![0.0; n];
            let mut v = vec![0.0; p + 1];
            let mut mass = 0.0;
            // The support is the half-open window [u_g - h, u_g + h), with the edges
            // computed exactly as the moment tables' breakpoints are.
            let (lo, hi) = (ug - h, ug + h);
            let rows = index.gather(ug, h * (1.0 + 1e-12));
            let mut count = 0u64;
            for &t in &rows {
                let u = prob.u(t);
                if !(lo <= u && u < hi) {
                    continue;
                }
                let w = (u - ug) / h;
                count += 1;
                let k = biweight(w);
                mass += k;
                prob.row(t, &mut v);
                for m in 0..p {
                    z[m] = v[m];
                    z[p + m] = w * v[m];
                }
                for i in 0..n {
                    let kz = k * z[i];
                    for j in 0..n {
                        s[i * n + j] += kz * z[j];
                    }
                    rhs[i] += kz * v[p];
                }
            }
            (s, rhs, count, mass)
        })
        .collect();
    let mut fit = GridFit::new(grid.len(), p, h);
    for (g, (s, rhs, count, mass)) in points.into_iter().enumerate() {
        fit.set_point(g, &s, &rhs, count, mass);
    }
    fit
}

/// Standard-error factors by direct sums (the twin of `MomentTable::se_factors`).
pub fn se_factors(prob: &VcProblem, index: &DirectIndex, grid: &[f64], fit: &GridFit) -> Vec<f64> {
    let p = prob.p;
    let n = 2 * p;
    let h = fit.bandwidth;
    let per_g: Vec<Vec<f64>> = grid
        .par_iter()
        .enumerate()
        .map(|(g, &ug)| {
            if fit.status[g] != super::problem::PointStatus::Ok {
                return vec![f64::NAN; p];
            }
            let (lo, hi) = (ug - h, ug + h);
            let mut s2 = vec![0.0; n * n];
            let mut z = vec![0.0; n];
            for t in index.gather(ug, h * (1.0 + 1e-12)) {
                let u = prob.u(t);
                if !(lo <= u && u < hi) {
                    continue;
                }
                let w = (u - ug) / h;
                let k = biweight(w);
                for m in 0..p {
                    z[m] = prob.xr(t, m);
                    z[p + m] = w * z[m];
                }
                for i in 0..n {
                    for j in 0..n {
                        s2[i * n + j] += k * k * z[i] * z[j];
                    }
                }
            }
            super::moments::sandwich_diag(&fit.s_inv[g * n * n..(g + 1) * n * n], &s2, n, p)
        })
        .collect();
    per_g.concat()
}

/// RSS and trace of the smoother by a pass over the data (all grid points Ok).
pub fn rss_trace(prob: &VcProblem, grid: &[f64], fit: &GridFit) -> (f64, f64) {
    const BLOCK: usize = 1 << 14;
    let p = prob.p;
    let n = 2 * p;
    let h = fit.bandwidth;
    let gl = grid.len();
    let rows: Vec<usize> = (prob.start..prob.x.len()).collect();
    let parts: Vec<(f64, f64)> = rows
        .par_chunks(BLOCK)
        .map(|chunk| {
            let mut v = vec![0.0; p + 1];
            let mut f = vec![0.0; p];
            let mut z = vec![0.0; n];
            let (mut rss, mut tr) = (0.0, 0.0);
            for &t in chunk {
                prob.row(t, &mut v);
                let u = prob.u(t);
                fit.eval(grid, u, &mut f);
                let yhat: f64 = (0..p).map(|m| v[m] * f[m]).sum();
                rss += (v[p] - yhat) * (v[p] - yhat);
                let targets: [(usize, f64); 2] = if u < grid[0] {
                    [(0, 1.0), (0, 0.0)]
                } else if u >= grid[gl - 1] {
                    [(gl - 1, 1.0), (0, 0.0)]
                } else {
                    let k = grid.partition_point(|g| *g <= u) - 1;
                    let lam = (u - grid[k]) / (grid[k + 1] - grid[k]);
                    [(k, 1.0 - lam), (k + 1, lam)]
                };
                for (g, omega) in targets {
                    if omega == 0.0 || !(grid[g] - h <= u && u < grid[g] + h) {
                        continue;
                    }
                    let w = (u - grid[g]) / h;
                    let kw = biweight(w);
                    if kw == 0.0 {
                        continue;
                    }
                    for m in 0..p {
                        z[m] = v[m];
                        z[p + m] = w * v[m];
                    }
                    let inv = &fit.s_inv[g * n * n..(g + 1) * n * n];
                    let mut acc = 0.0;
                    for a in 0..p {
                        let row = &inv[a * n..(a + 1) * n];
                        let rz: f64 = row.iter().zip(&z).map(|(r, zz)| r * zz).sum();
                        acc += v[a] * rz;
                    }
                    tr += omega * kw * acc;
                }
            }
            (rss, tr)
        })
        .collect();
    parts
        .into_iter()
        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
}
