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
//! and half-width s_e, M_e[ab][i] = sum_{t in e} V_a V_b v^i with v = (U_t - c_e)/s_e
//! (|v| <= 1, no cancellation), i = 0..deg. Moments about any point u follow exactly
//! from the binomial theorem: sum V_a V_b (U - u)^s = sum_i C(s,i) s_e^i (c_e - u)^(s-i) M_e[ab][i].
//! For one grid point the windows of all bandwidths are nested, so they are summed
//! from the narrowest outwards, each interval recentred once: no prefix-sum
//! differences, hence no cancellation between far intervals.
//!
//! The pass runs over fixed blocks of rows (their size depends on N only), blocks in
//! parallel, block tables added in block order: the result does not depend on the
//! number of threads. The interval of a sample is found through a uniform bucket
//! table over the breakpoints (a guess, corrected by stepping to the exact interval),
//! not by a binary search.

use rayon::prelude::*;

use super::kernel::{BIWEIGHT, binomial_table, poly_mul};
use super::problem::{GridFit, VcProblem};

/// Moment tables over the elementary intervals of `breaks`.
pub struct MomentTable {
    /// Sorted, distinct breakpoints; interval e covers [breaks[e-1], breaks[e]).
    pub breaks: Vec<f64>,
    centre: Vec<f64>,
    half: Vec<f64>,
    pub p: usize,
    /// Families: pairs a <= b of V = (X_1..X_p, y), then the constant 1.
    nfam: usize,
    fam_of: Vec<usize>,
    /// Highest power of v kept.
    pub deg: usize,
    /// E x nfam x (deg + 1).
    m: Vec<f64>,
    /// Samples per interval.
    count: Vec<u64>,
}

/// Adds moments `src` (nfam rows of deg + 1, powers of (U - c_src)/s_src) to `acc` as
/// powers 0..=smax of (U - c_dst)/s_dst: with a = s_src/s_dst, b = (c_src - c_dst)/s_dst,
/// ((U - c_dst)/s_dst)^s = sum_i C(s,i) a^i b^(s-i) ((U - c_src)/s_src)^i.
/// With `s_dst = None` the powers are unscaled, (U - c_dst)^s.
#[allow(clippy::too_many_arguments)]
#[inline]
fn recentre_into(
    src: &[f64],
    (c_src, s_src): (f64, f64),
    (c_dst, s_dst): (f64, Option<f64>),
    nfam: usize,
    d1: usize,
    smax: usize,
    binom: &[[f64; 13]; 13],
    acc: &mut [f64],
) {
    let (a, b) = match s_dst {
        None => (s_src, c_src - c_dst),
        Some(sd) => (s_src / sd, (c_src - c_dst) / sd),
    };
    let mut sp = [1.0f64; 13];
    let mut dp = [1.0f64; 13];
    for k in 1..=smax {
        sp[k] = sp[k - 1] * a;
        dp[k] = dp[k - 1] * b;
    }
    // coefficient table C(s,i) a^i b^(s-i), shared by every family
    let mut coef = [[0.0f64; 13]; 13];
    for s in 0..=smax {
        for i in 0..=s {
            coef[s][i] = binom[s][i] * sp[i] * dp[s - i];
        }
    }
    for f in 0..nfam {
        let mrow = &src[f * d1..(f + 1) * d1];
        let arow = &mut acc[f * d1..(f + 1) * d1];
        for s in 0..=smax {
            let mut sum = 0.0;
            for i in 0..=s {
                sum += coef[s][i] * mrow[i];
            }
            arow[s] += sum;
        }
    }
}

impl MomentTable {
    fn n_intervals(&self) -> usize {
        self.breaks.len() + 1
    }

    fn fam(&self, a: usize, b: usize) -> usize {
        let nv = self.p + 1;
        self.fam_of[a.min(b) * nv + a.max(b)]
    }

    fn one_fam(&self) -> usize {
        self.nfam - 1
    }

    /// Index of an exact breakpoint value.
    fn break_index(&self, value: f64) -> usize {
        self.breaks
            .binary_search_by(|b| b.total_cmp(&value))
            .unwrap_or_else(|_| panic!("{value} is not a breakpoint"))
    }

    /// Builds the tables in one pass. `umin`, `umax` bound the index values (they
    /// centre the two unbounded end intervals).
    pub fn build(
        prob: &VcProblem,
        mut breaks: Vec<f64>,
        umin: f64,
        umax: f64,
        deg: usize,
    ) -> MomentTable {
        breaks.sort_by(f64::total_cmp);
        breaks.dedup();
        let p = prob.p;
        let nv = p + 1;
        let mut fam_of = vec![usize::MAX; nv * nv];
        let mut nfam = 0;
        for a in 0..nv {
            for b in a..nv {
                fam_of[a * nv + b] = nfam;
                nfam += 1;
            }
        }
        nfam += 1; // the constant
        let e_count = breaks.len() + 1;
        let mut centre = vec![0.0; e_count];
        let mut half = vec![0.0; e_count];
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
        }
        let mut t = MomentTable {
            breaks,
            centre,
            half,
            p,
            nfam,
            fam_of,
            deg,
            m: vec![0.0; e_count * nfam * (deg + 1)],
            count: vec![0; e_count],
        };
        t.accumulate(prob);
        t
    }

    /// Adds the moments of intervals lo..=hi about `u` (unscaled powers 0..=smax) to
    /// `acc` in ascending or descending order of the intervals, and returns their
    /// sample count. (Summing from the intervals nearest u outwards keeps the small
    /// terms first; the order is part of the result to the last bit.)
    #[allow(clippy::too_many_arguments)]
    fn add_range(
        &self,
        lo: usize,
        hi: usize,
        u: f64,
        smax: usize,
        binom: &[[f64; 13]; 13],
        acc: &mut [f64],
        descending: bool,
    ) -> u64 {
        let hi = hi.min(self.n_intervals() - 1);
        if lo > hi {
            return 0;
        }
        let d1 = self.deg + 1;
        let width = self.nfam * d1;
        let mut count = 0;
        let mut one = |e: usize| {
            recentre_into(
                &self.m[e * width..(e + 1) * width],
                (self.centre[e], self.half[e]),
                (u, None),
                self.nfam,
                d1,
                smax,
                binom,
                acc,
            );
            count += self.count[e];
        };
        if descending {
            (lo..=hi).rev().for_each(&mut one);
        } else {
            (lo..=hi).for_each(&mut one);
        }
        count
    }

    fn accumulate(&mut self, prob: &VcProblem) {
        let n_rows = prob.n_rows();
        let block = (n_rows / 64).clamp(1 << 16, 1 << 22);
        let starts: Vec<usize> = (prob.start..prob.x.len()).step_by(block).collect();
        let wave = rayon::current_num_threads().max(1);
        let width = self.nfam * (self.deg + 1);
        let lookup = IntervalLookup::new(&self.breaks);
        for group in starts.chunks(wave) {
            let parts: Vec<(Vec<f64>, Vec<u64>)> = group
                .par_iter()
                .map(|&s| {
                    let end = (s + block).min(prob.x.len());
                    let mut m = vec![0.0; self.m.len()];
                    let mut count = vec![0u64; self.count.len()];
                    let mut v = vec![0.0; self.p + 2];
                    let mut pw = vec![0.0; self.deg + 1];
                    let nv = self.p + 1;
                    for t in s..end {
                        let u = prob.u(t);
                        let e = lookup.find(u);
                        count[e] += 1;
                        let z = (u - self.centre[e]) / self.half[e];
                        pw[0] = 1.0;
                        for k in 1..=self.deg {
                            pw[k] = pw[k - 1] * z;
                        }
                        prob.row(t, &mut v[..nv]);
                        v[nv] = 1.0;
                        let base = e * width;
                        let mut f = 0;
                        for a in 0..nv {
                            for b in a..nv {
                                let val = v[a] * v[b];
                                let row = &mut m
                                    [base + f * (self.deg + 1)..base + (f + 1) * (self.deg + 1)];
                                for (r, pk) in row.iter_mut().zip(&pw) {
                                    *r += val * pk;
                                }
                                f += 1;
                            }
                        }
                        let row =
                            &mut m[base + f * (self.deg + 1)..base + (f + 1) * (self.deg + 1)];
                        for (r, pk) in row.iter_mut().zip(&pw) {
                            *r += pk;
                        }
                    }
                    (m, count)
                })
                .collect();
            for (m, count) in parts {
                for (a, b) in self.m.iter_mut().zip(&m) {
                    *a += b;
                }
                for (a, b) in self.count.iter_mut().zip(&count) {
                    *a += b;
                }
            }
        }
    }

    /// Local-linear fits at every grid point for every bandwidth in `hs`. Every
    /// `u_g`, `u_g - h` and `u_g + h` must be a breakpoint.
    pub fn fit_ladder(&self, grid: &[f64], hs: &[f64]) -> Vec<GridFit> {
        assert!(self.deg >= 6, "local fits need moments up to degree 6");
        let p = self.p;
        let n = 2 * p;
        let d1 = self.deg + 1;
        let binom = binomial_table();
        let mut order: Vec<usize> = (0..hs.len()).collect();
        order.sort_by(|a, b| hs[*a].total_cmp(&hs[*b]));
        // per grid point: for each h, (S, T, count, mass)
        type Point = (Vec<f64>, Vec<f64>, u64, f64);
        let per_g: Vec<Vec<Point>> = grid
            .par_iter()
            .map(|&ug| {
                let mut acc = vec![0.0; self.nfam * d1];
                let mut count = 0u64;
                let mut out: Vec<Option<Point>> = vec![None; hs.len()];
                let gi = self.break_index(ug);
                // current window: intervals lo..=hi (empty: lo = gi + 1, hi = gi)
                let (mut lo, mut hi) = (gi + 1, gi);
                for &j in &order {
                    let h = hs[j];
                    let new_lo = self.break_index(ug - h) + 1;
                    let new_hi = self.break_index(ug + h);
                    if new_lo < lo {
                        count += self.add_range(new_lo, lo - 1, ug, 6, &binom, &mut acc, true);
                    }
                    if new_hi > hi {
                        count += self.add_range(hi + 1, new_hi, ug, 6, &binom, &mut acc, false);
                    }
                    lo = lo.min(new_lo);
                    hi = hi.max(new_hi);
                    // W[f][s] = acc[f][s] / h^s; A(r) = sum_k kappa_k W(k + r)
                    let mut hp = [1.0f64; 7];
                    for k in 1..7 {
                        hp[k] = hp[k - 1] / h;
                    }
                    let a_of = |f: usize, r: usize| -> f64 {
                        BIWEIGHT
                            .iter()
                            .enumerate()
                            .filter(|(_, c)| **c != 0.0)
                            .map(|(k, c)| c * acc[f * d1 + k + r] * hp[k + r])
                            .sum()
                    };
                    let mut s = vec![0.0; n * n];
                    let mut rhs = vec![0.0; n];
                    for a in 0..p {
                        for b in 0..p {
                            let f = self.fam(a, b);
                            let (m0, m1, m2) = (a_of(f, 0), a_of(f, 1), a_of(f, 2));
                            s[a * n + b] = m0;
                            s[a * n + p + b] = m1;
                            s[(p + a) * n + b] = m1;
                            s[(p + a) * n + p + b] = m2;
                        }
                        let fy = self.fam(a, p);
                        rhs[a] = a_of(fy, 0);
                        rhs[p + a] = a_of(fy, 1);
                    }
                    let mass = a_of(self.one_fam(), 0);
                    out[j] = Some((s, rhs, count, mass));
                }
                out.into_iter()
                    .map(|o| o.expect("every h visited"))
                    .collect()
            })
            .collect();
        hs.iter()
            .enumerate()
            .map(|(j, &h)| {
                let mut fit = GridFit::new(grid.len(), p, h);
                for (g, pts) in per_g.iter().enumerate() {
                    let (s, rhs, count, mass) = &pts[j];
                    fit.set_point(g, s, rhs, *count, *mass);
                }
                fit
            })
            .collect()
    }

    /// Sum over intervals lo..=hi of moments about u, powers 0..=smax.
    fn range_moments(
        &self,
        lo: usize,
        hi: usize,
        u: f64,
        smax: usize,
        binom: &[[f64; 13]; 13],
    ) -> Vec<f64> {
        let mut acc = vec![0.0; self.nfam * (self.deg + 1)];
        self.add_range(lo, hi, u, smax, binom, &mut acc, false);
        acc
    }

    /// Exact RSS and trace of the smoother (f between grid points by linear
    /// interpolation, constant beyond the ends) for a fit whose points are all Ok.
    pub fn rss_trace(&self, grid: &[f64], fit: &GridFit) -> (f64, f64) {
        let p = self.p;
        let n = 2 * p;
        let d1 = self.deg + 1;
        let h = fit.bandwidth;
        let gl = grid.len();
        let binom = binomial_table();
        let gidx: Vec<usize> = grid.iter().map(|g| self.break_index(*g)).collect();
        let e_last = self.n_intervals() - 1;
        // cells: (first interval, last interval, left grid index, right grid index)
        let mut cells: Vec<(usize, usize, usize, Option<usize>)> = vec![(0, gidx[0], 0, None)];
        for k in 0..gl - 1 {
            cells.push((gidx[k] + 1, gidx[k + 1], k, Some(k + 1)));
        }
        cells.push((gidx[gl - 1] + 1, e_last, gl - 1, None));
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
        let parts: Vec<(f64, f64)> = cells
            .par_iter()
            .map(|&(lo, hi, k, k1)| {
                if lo > hi {
                    return (0.0, 0.0);
                }
                // RSS
                let r = self.range_moments(lo, hi, grid[k], 2, &binom);
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
                // trace
                let targets: Vec<(usize, Vec<f64>)> = match k1 {
                    None => vec![(k, vec![1.0])],
                    Some(k1) => {
                        let dlt = grid[k1] - grid[k];
                        vec![(k, vec![1.0, -1.0 / dlt]), (k1, vec![1.0, 1.0 / dlt])]
                    }
                };
                let mut tr = 0.0;
                for (g, omega) in targets {
                    let ug = grid[g];
                    let wlo = self.break_index(ug - h) + 1;
                    let whi = self.break_index(ug + h);
                    let (a0, b0) = (lo.max(wlo), hi.min(whi));
                    if a0 > b0 {
                        continue;
                    }
                    let r = self.range_moments(a0, b0, ug, 6, &binom);
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
}

impl MomentTable {
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
        let k2 = poly_mul(&BIWEIGHT, &BIWEIGHT);
        let per_g: Vec<Vec<f64>> = grid
            .par_iter()
            .enumerate()
            .map(|(g, &ug)| {
                if fit.status[g] != super::problem::PointStatus::Ok {
                    return vec![f64::NAN; p];
                }
                let lo = self.break_index(ug - h) + 1;
                let hi = self.break_index(ug + h);
                let acc = self.range_moments(lo, hi, ug, 10, &binom);
                let mut hp = [1.0f64; 11];
                for k in 1..11 {
                    hp[k] = hp[k - 1] / h;
                }
                let a2 = |f: usize, r: usize| -> f64 {
                    k2.iter()
                        .enumerate()
                        .map(|(k, c)| c * acc[f * d1 + k + r] * hp[k + r])
                        .sum()
                };
                let mut s2 = vec![0.0; n * n];
                for a in 0..p {
                    for b in 0..p {
                        let f = self.fam(a, b);
                        let (m0, m1, m2) = (a2(f, 0), a2(f, 1), a2(f, 2));
                        s2[a * n + b] = m0;
                        s2[a * n + p + b] = m1;
                        s2[(p + a) * n + b] = m1;
                        s2[(p + a) * n + p + b] = m2;
                    }
                }
                sandwich_diag(&fit.s_inv[g * n * n..(g + 1) * n * n], &s2, n, p)
            })
            .collect();
        per_g.concat()
    }
}

/// The interval of a value among sorted distinct breakpoints: exactly
/// `breaks.partition_point(|b| *b <= u)`, found from a guess out of a uniform bucket
/// table (4 buckets per breakpoint) corrected by stepping, instead of a binary search.
pub struct IntervalLookup<'a> {
    breaks: &'a [f64],
    lo: f64,
    scale: f64,
    first: Vec<u32>,
}

impl<'a> IntervalLookup<'a> {
    pub fn new(breaks: &'a [f64]) -> Self {
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
        IntervalLookup {
            breaks,
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
        let mut e = self.first[k] as usize;
        let b = self.breaks;
        while e < b.len() && b[e] <= u {
            e += 1;
        }
        while e > 0 && b[e - 1] > u {
            e -= 1;
        }
        e
    }
}

/// sqrt of the first p diagonal entries of Q S2 Q (Q symmetric, row-major n x n).
pub fn sandwich_diag(q: &[f64], s2: &[f64], n: usize, p: usize) -> Vec<f64> {
    (0..p)
        .map(|m| {
            let mut v = 0.0;
            for i in 0..n {
                for j in 0..n {
                    v += q[m * n + i] * s2[i * n + j] * q[j * n + m];
                }
            }
            v.max(0.0).sqrt()
        })
        .collect()
}

/// The breakpoints for grid `grid` and bandwidths `hs`: every u_g, u_g - h, u_g + h.
pub fn breakpoints(grid: &[f64], hs: &[f64]) -> Vec<f64> {
    let mut b = Vec::with_capacity(grid.len() * (2 * hs.len() + 1));
    for &g in grid {
        b.push(g);
        for &h in hs {
            b.push(g - h);
            b.push(g + h);
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interval_lookup_equals_binary_search() {
        // uneven breakpoints (a grid and its windows), values inside, outside, on breaks
        let grid: Vec<f64> = (0..21).map(|k| -1.3 + 0.13 * k as f64).collect();
        let hs: Vec<f64> = (0..21).map(|j| 1.1f64.powi(-j) * 1.7).collect();
        let mut b = breakpoints(&grid, &hs);
        b.sort_by(f64::total_cmp);
        b.dedup();
        let lk = IntervalLookup::new(&b);
        let mut us: Vec<f64> = b.clone();
        us.extend(b.iter().map(|v| v.next_up()));
        us.extend(b.iter().map(|v| v.next_down()));
        us.extend((0..20_001).map(|i| -6.0 + 12.0 * i as f64 / 20_000.0));
        us.extend([f64::MAX, f64::MIN, 0.0, -0.0]);
        for u in us {
            assert_eq!(lk.find(u), b.partition_point(|v| *v <= u), "u = {u}");
        }
        let one = [0.5];
        let lk = IntervalLookup::new(&one);
        for u in [0.0, 0.5, 1.0] {
            assert_eq!(lk.find(u), one.partition_point(|v| *v <= u));
        }
    }
}
