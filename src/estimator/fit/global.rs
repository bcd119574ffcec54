//! The GCV ladder's upper limit, h -> infinity: the local-linear fit with uniform
//! weights over every row, the same at every grid point (a global regression on
//! Z_t = (X_t, w_t X_t), w_t = (U_t - c)/s), so that f_m(u) = a_m + c_m (u - c)/s is
//! linear in the index.
//!
//! As h grows past the index values' range every window holds every row, and the
//! Biweight weights K((U_t - u_g)/h) = (1 - w^2)^2 tend to K(0) = 1 uniformly (their
//! spread is 2 (range/h)^2 at most): the local-linear fit at u_g tends to the
//! least-squares fit of y_t on (X_t, (U_t - u_g) X_t), which is one regression whatever
//! u_g (the columns span the same space as Z_t's). Its value at u_g is the global
//! line's (Fan and Gijbels 1996, sec. 3.2: a local-linear smoother with an infinite
//! bandwidth is the linear fit). The smoother then evaluates f as everywhere: linearly
//! between grid points (exact for a line) and constant beyond the outer grid points, so
//! its fitted values are Z^c_t beta, Z^c_t = (X_t, w^c_t X_t) with U_t clamped to the
//! grid, and with beta = S^-1 T (S = sum Z Z', T = sum Z y):
//!
//! - RSS = y'y - 2 beta' (sum Z^c y) + beta' (sum Z^c Z^c') beta,
//! - trace = sum_t Z^c_t' S^-1 Z_t = tr(S^-1 sum_t Z_t Z^c_t') (2p when no row lies
//!   beyond the grid; a little less otherwise),
//! - the standard error of f_m(u_g): sigma sqrt(v' S^-1 v), v = e_m + w_g e_(p+m) (the
//!   sandwich S^-1 S2 S^-1 of the local fits with K^2 = K = 1).
//!
//! One pass over the rows gives the design's sums ([`GlobalDesign`], kept for the
//! whole fit: X and U do not change) and one more each response's. [`GlobalFit::grid_fit`] writes the fit in
//! the local fits' form (bandwidth +inf): each grid point's inverse is S^-1 carried to
//! the parametrisation centred at u_g, (X, (U - u_g)/s X), as the local fits keep
//! theirs centred at u_g.

use rayon::prelude::*;

use crate::estimator::linalg::spd_solve_inverse;
use crate::estimator::problem::{GridFit, PointStatus, VcProblem};

/// Rows summed per parallel block.
const BLOCK: usize = 1 << 15;

/// Sums `add(s0, s1, acc)` over blocks of the rows `start..end` in parallel, block
/// order fixed (the same bits at any thread count).
fn blocks<A: Send>(
    (start, end): (usize, usize),
    zero: impl Fn() -> A + Sync + Send,
    add: impl Fn(usize, usize, &mut A) + Sync + Send,
    merge: impl Fn(A, A) -> A + Sync + Send,
) -> A {
    let starts: Vec<usize> = (start..end).step_by(BLOCK).collect();
    let parts: Vec<A> = starts
        .par_iter()
        .map(|&s0| {
            let mut acc = zero();
            add(s0, (s0 + BLOCK).min(end), &mut acc);
            acc
        })
        .collect();
    parts.into_iter().fold(zero(), merge)
}

fn add_into(mut a: Vec<f64>, b: Vec<f64>) -> Vec<f64> {
    a.iter_mut().zip(&b).for_each(|(a, b)| *a += b);
    a
}

/// What the global fit needs of the design (X and U, the same for every response of
/// one fit): S^-1, its condition number, sum Z Z^c' and sum Z^c Z^c', the trace.
#[derive(Clone, Debug)]
pub(super) struct GlobalDesign {
    p: usize,
    centre: f64,
    scale: f64,
    /// The outer grid points, where U is clamped.
    clamp: (f64, f64),
    s_inv: Vec<f64>,
    cond: f64,
    /// sum Z^c Z^c' (n x n).
    cc: Vec<f64>,
    rows: u64,
    trace: f64,
}

impl GlobalDesign {
    /// The design's sums of `prob` with f evaluated on `grid` (constant beyond its
    /// ends), w = (U - centre)/scale: one pass; None when S is singular (collinear
    /// regressors).
    pub(super) fn new(prob: &VcProblem, grid: &[f64], (centre, scale): (f64, f64)) -> Option<Self> {
        let p = prob.p;
        let n = 2 * p;
        let clamp = (grid[0], grid[grid.len() - 1]);
        // (sum Z Z' upper triangle, sum Z Z^c', sum Z^c Z^c' upper triangle, rows) in one
        // vector: n*n + n*n + n*n + 1
        let sums = blocks(
            (prob.start, prob.x.len()),
            || vec![0.0; 3 * n * n + 1],
            |s0, s1, acc| {
                let (mut z, mut zc) = ([0.0f64; 12], [0.0f64; 12]);
                let (s, rest) = acc.split_at_mut(n * n);
                let (zcs, rest) = rest.split_at_mut(n * n);
                let (cc, rows) = rest.split_at_mut(n * n);
                for t in s0..s1 {
                    let u = prob.u(t);
                    let w = (u - centre) / scale;
                    let wc = (u.clamp(clamp.0, clamp.1) - centre) / scale;
                    for m in 0..p {
                        let xm = prob.xr(t, m);
                        z[m] = xm;
                        z[p + m] = w * xm;
                        zc[m] = xm;
                        zc[p + m] = wc * xm;
                    }
                    for a in 0..n {
                        for b in a..n {
                            s[a * n + b] += z[a] * z[b];
                            cc[a * n + b] += zc[a] * zc[b];
                        }
                        for b in 0..n {
                            zcs[a * n + b] += z[a] * zc[b];
                        }
                    }
                }
                rows[0] += (s1 - s0) as f64;
            },
            add_into,
        );
        let sym = |m: &[f64]| -> Vec<f64> {
            let mut out = m.to_vec();
            for a in 0..n {
                for b in 0..a {
                    out[a * n + b] = m[b * n + a];
                }
            }
            out
        };
        let s = sym(&sums[..n * n]);
        let zc = &sums[n * n..2 * n * n];
        let cc = sym(&sums[2 * n * n..3 * n * n]);
        let (_, s_inv, cond) = spd_solve_inverse(&s, &vec![0.0; n], n)?;
        // tr(S^-1 sum Z Z^c') = sum_ab S^-1[a][b] (sum Z Z^c')[b][a]
        let trace = (0..n)
            .map(|a| {
                (0..n)
                    .map(|b| s_inv[a * n + b] * zc[b * n + a])
                    .sum::<f64>()
            })
            .sum();
        Some(GlobalDesign {
            p,
            centre,
            scale,
            clamp,
            s_inv,
            cond,
            cc,
            rows: sums[3 * n * n] as u64,
            trace,
        })
    }

    /// The global fit of `prob`'s response (its design this one's): one pass for sum
    /// Z y, sum Z^c y and y'y.
    pub(super) fn fit(&self, prob: &VcProblem) -> GlobalFit {
        let (p, n) = (self.p, 2 * self.p);
        let (centre, scale, clamp) = (self.centre, self.scale, self.clamp);
        // (sum Z y, sum Z^c y, y'y)
        let sums = blocks(
            (prob.start, prob.x.len()),
            || vec![0.0; 2 * n + 1],
            |s0, s1, acc| {
                let mut v = [0.0f64; 7];
                for t in s0..s1 {
                    prob.row(t, &mut v[..p + 1]);
                    let y = v[p];
                    let u = prob.u(t);
                    let w = (u - centre) / scale;
                    let wc = (u.clamp(clamp.0, clamp.1) - centre) / scale;
                    for m in 0..p {
                        let xy = v[m] * y;
                        acc[m] += xy;
                        acc[p + m] += w * xy;
                        acc[n + m] += xy;
                        acc[n + p + m] += wc * xy;
                    }
                    acc[2 * n] += y * y;
                }
            },
            add_into,
        );
        let (t, cy, yy) = (&sums[..n], &sums[n..2 * n], sums[2 * n]);
        let beta: Vec<f64> = (0..n)
            .map(|a| (0..n).map(|b| self.s_inv[a * n + b] * t[b]).sum())
            .collect();
        let quad: f64 = (0..n)
            .map(|a| beta[a] * (0..n).map(|b| self.cc[a * n + b] * beta[b]).sum::<f64>())
            .sum();
        let cross: f64 = beta.iter().zip(cy).map(|(b, c)| b * c).sum();
        GlobalFit {
            p,
            centre,
            scale,
            beta,
            s_inv: self.s_inv.clone(),
            cond: self.cond,
            rows: self.rows,
            rss: (yy - 2.0 * cross + quad).max(0.0),
            trace: self.trace,
        }
    }
}

/// The global fit of one response: beta in the parametrisation (X, w X), w = (U -
/// centre)/scale, S^-1, its condition number, and the smoother's RSS and trace.
#[derive(Clone, Debug)]
pub(super) struct GlobalFit {
    pub(super) p: usize,
    pub(super) centre: f64,
    pub(super) scale: f64,
    pub(super) beta: Vec<f64>,
    pub(super) s_inv: Vec<f64>,
    pub(super) cond: f64,
    pub(super) rows: u64,
    pub(super) rss: f64,
    pub(super) trace: f64,
}

impl GlobalFit {
    /// The global fit of `prob` with f evaluated on `grid` (constant beyond its ends),
    /// w = (U - centre)/scale ([`GlobalDesign::new`], then [`GlobalDesign::fit`]);
    /// None when S is singular.
    #[cfg(test)]
    pub(super) fn fit(prob: &VcProblem, grid: &[f64], cs: (f64, f64)) -> Option<Self> {
        Some(GlobalDesign::new(prob, grid, cs)?.fit(prob))
    }

    /// The fit in the local fits' form at `grid` (bandwidth +inf): f_m(u_g) = beta_m +
    /// w_g beta_(p+m), slope beta_(p+m)/scale, and S^-1 carried to the parametrisation
    /// centred at u_g: B S^-1 B', B = [I, w_g I; 0, I] (module doc).
    pub(super) fn grid_fit(&self, grid: &[f64]) -> GridFit {
        let p = self.p;
        let n = 2 * p;
        let mut fit = GridFit::new(grid.len(), p, f64::INFINITY);
        for (g, &ug) in grid.iter().enumerate() {
            let wg = (ug - self.centre) / self.scale;
            fit.status[g] = PointStatus::Ok;
            fit.n_support[g] = self.rows;
            fit.kernel_mass[g] = self.rows as f64;
            fit.cond[g] = self.cond;
            for m in 0..p {
                fit.f[g * p + m] = self.beta[m] + wg * self.beta[p + m];
                fit.slope[g * p + m] = self.beta[p + m] / self.scale;
            }
            // B S^-1 B': rows m < p of B are e_m + w_g e_(p+m), rows p + m are e_(p+m)
            let b_row = |r: usize, k: usize| -> f64 {
                let mut v = if r == k { 1.0 } else { 0.0 };
                if r < p && k == r + p {
                    v = wg;
                }
                v
            };
            let inv = &mut fit.s_inv[g * n * n..(g + 1) * n * n];
            for r in 0..n {
                for c in 0..n {
                    let mut acc = 0.0;
                    for a in 0..n {
                        let bra = b_row(r, a);
                        if bra == 0.0 {
                            continue;
                        }
                        for b in 0..n {
                            let bcb = b_row(c, b);
                            if bcb != 0.0 {
                                acc += bra * self.s_inv[a * n + b] * bcb;
                            }
                        }
                    }
                    inv[r * n + c] = acc;
                }
            }
        }
        fit
    }

    /// The standard-error factors sqrt([S_g^-1]_mm) at every grid point (G x p), so
    /// that se = sigma * factor (module doc).
    pub(super) fn se_factors(fit: &GridFit) -> Vec<f64> {
        let (p, n) = (fit.p, 2 * fit.p);
        (0..fit.n_grid())
            .flat_map(|g| (0..p).map(move |m| (g, m)))
            .map(|(g, m)| fit.s_inv[g * n * n + m * n + m].max(0.0).sqrt())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::direct;

    /// A FARMA-ish series with a mild state dependence, and an MA response.
    fn series(n: usize) -> (Vec<f64>, Vec<f64>) {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut normal = move || {
            let mut u = || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64
            };
            let (a, b) = (u().max(1e-300), u());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let mut x = vec![0.0f64; n];
        let mut e = vec![0.0f64; n];
        for t in 2..n {
            e[t] = normal();
            let u = x[t - 1];
            x[t] = (0.4 + 0.1 * u.tanh()) * x[t - 1] - 0.2 * x[t - 2] + e[t] + 0.3 * e[t - 1];
        }
        (x, e)
    }

    fn grid_of(x: &[f64], k: usize) -> Vec<f64> {
        let mut v = x.to_vec();
        v.sort_by(f64::total_cmp);
        let (lo, hi) = (v[v.len() / 50], v[v.len() - v.len() / 50]);
        (0..k)
            .map(|i| lo + (hi - lo) * i as f64 / (k - 1) as f64)
            .collect()
    }

    /// The one-pass RSS and trace against the smoother's own definitions (f evaluated
    /// row by row; the hat matrix's diagonal Z^c_t' S^-1 Z_t summed), and the grid
    /// values against the global line.
    #[test]
    fn the_global_fits_rss_and_trace_are_those_of_its_smoother_row_by_row() {
        let (x, e) = series(20_000);
        let b = [0.3];
        let prob = VcProblem::new(&x, &e, &b, 2, 1);
        let grid = grid_of(&x, 31);
        let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| {
            (a.0.min(*v), a.1.max(*v))
        });
        let cs = ((lo + hi) / 2.0, (hi - lo) / 2.0);
        let gf = GlobalFit::fit(&prob, &grid, cs).expect("a regular design");
        let fit = gf.grid_fit(&grid);
        let (p, n) = (2, 4);
        let (mut rss, mut trace) = (0.0, 0.0);
        let mut f = vec![0.0; p];
        for t in prob.start..x.len() {
            let u = prob.u(t);
            fit.eval(&grid, u, &mut f);
            let xs = [prob.xr(t, 0), prob.xr(t, 1)];
            let r = prob.y(t) - xs[0] * f[0] - xs[1] * f[1];
            rss += r * r;
            let w = (u - cs.0) / cs.1;
            let wc = (u.clamp(grid[0], grid[grid.len() - 1]) - cs.0) / cs.1;
            let z = [xs[0], xs[1], w * xs[0], w * xs[1]];
            let zc = [xs[0], xs[1], wc * xs[0], wc * xs[1]];
            for a in 0..n {
                for c in 0..n {
                    trace += zc[a] * gf.s_inv[a * n + c] * z[c];
                }
            }
        }
        assert!((gf.rss - rss).abs() <= 1e-9 * rss, "{} vs {rss}", gf.rss);
        assert!((gf.trace - trace).abs() <= 1e-9, "{} vs {trace}", gf.trace);
        assert!(gf.trace < 4.0 && gf.trace > 3.5, "{}", gf.trace);
        // f linear on the grid, with the slope it reports
        for m in 0..p {
            let s = fit.slope[m];
            for g in 1..grid.len() {
                let df = fit.f[g * p + m] - fit.f[(g - 1) * p + m];
                assert!((df - s * (grid[g] - grid[g - 1])).abs() < 1e-12);
            }
        }
    }

    /// The limit: the local-linear Biweight fits (the direct path's, an independent
    /// computation) at bandwidths far above the range approach the global fit, its
    /// values, RSS, trace and standard-error factors.
    #[test]
    fn local_fits_tend_to_the_global_fit_as_the_bandwidth_grows() {
        let (x, e) = series(20_000);
        let b = [0.3];
        let prob = VcProblem::new(&x, &e, &b, 2, 1);
        let grid = grid_of(&x, 21);
        let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| {
            (a.0.min(*v), a.1.max(*v))
        });
        let range = hi - lo;
        let gf = GlobalFit::fit(&prob, &grid, ((lo + hi) / 2.0, range / 2.0)).unwrap();
        let global = gf.grid_fit(&grid);
        let index = direct::DirectIndex::build(&prob);
        let mut last_gap = f64::INFINITY;
        for k in [10.0, 100.0, 1000.0] {
            let local = direct::fit_grid(&prob, &index, &grid, k * range);
            let gap = local
                .f
                .iter()
                .zip(&global.f)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(gap < last_gap, "k = {k}: {gap} not below {last_gap}");
            last_gap = gap;
            let (rss, trace) = direct::rss_trace(&prob, &grid, &local);
            // the Biweight's weights differ from 1 by 2 (range/h)^2 at most
            let tol = 10.0 / (k * k);
            assert!(
                (rss - gf.rss).abs() <= tol * gf.rss,
                "k = {k}: rss {rss} vs {}",
                gf.rss
            );
            assert!(
                (trace - gf.trace).abs() <= tol * 4.0,
                "k = {k}: trace {trace} vs {}",
                gf.trace
            );
            let se_local = direct::se_factors(&prob, &index, &grid, &local);
            let se_global = GlobalFit::se_factors(&global);
            for (a, b) in se_local.iter().zip(&se_global) {
                assert!((a - b).abs() <= tol * b, "k = {k}: se {a} vs {b}");
            }
        }
        assert!(last_gap < 1e-5, "{last_gap}");
    }
}
