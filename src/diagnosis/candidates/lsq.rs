//! Least squares and searches shared by the estimates of the candidate effects: the
//! weighted non-negative fit on Allan variances, ordinary least squares over the
//! training ranges, log grids, golden-section search, and first differences that do
//! not cross a block edge.

use std::ops::Range;

use crate::estimator::linalg::normal_equations;

/// Weighted least squares of y on u with the coefficient >= 0: (c, weighted RSS).
pub(super) fn fit_nonneg(y: &[f64], u: &[f64], a: &[f64], ms: &[usize]) -> (f64, f64) {
    let w: Vec<f64> = ms
        .iter()
        .zip(a)
        .map(|(m, a)| 1.0 / (*m as f64 * a * a).max(f64::MIN_POSITIVE))
        .collect();
    let suu: f64 = (0..y.len()).map(|i| w[i] * u[i] * u[i]).sum();
    let suy: f64 = (0..y.len()).map(|i| w[i] * u[i] * y[i]).sum();
    let c = if suu > 0.0 { (suy / suu).max(0.0) } else { 0.0 };
    let rss = (0..y.len()).map(|i| w[i] * (y[i] - c * u[i]).powi(2)).sum();
    (c, rss)
}

/// Least squares of y on the regressors (and an intercept) over `ranges`:
/// (coefficients of the regressors, RSS).
pub(super) fn ls(
    y: &[f64],
    regs: &[&[f64]],
    intercept: bool,
    ranges: &[Range<usize>],
) -> Option<(Vec<f64>, f64)> {
    ls_w(y, regs, intercept, ranges, None)
}

/// [`ls`] with every coefficient: the intercept first (when fitted), then the
/// regressors'.
pub(super) fn ls_full(
    y: &[f64],
    regs: &[&[f64]],
    intercept: bool,
    ranges: &[Range<usize>],
) -> Option<(Vec<f64>, f64)> {
    ls_weighted(y, regs, intercept, ranges, None)
}

/// [`ls`] weighted by `w` (None: every sample alike): with the noise's variance v_t
/// known up to a factor, w_t = 1 / v_t gives the best linear unbiased estimate
/// (Aitken 1935); the RSS returned is the weighted one, sum w_t (y_t - f_t)^2.
pub(super) fn ls_w(
    y: &[f64],
    regs: &[&[f64]],
    intercept: bool,
    ranges: &[Range<usize>],
    w: Option<&[f64]>,
) -> Option<(Vec<f64>, f64)> {
    ls_weighted(y, regs, intercept, ranges, w).map(|(mut beta, rss)| {
        if intercept {
            beta.remove(0);
        }
        (beta, rss)
    })
}

/// [`ls_w`] with every coefficient: the intercept first (when fitted), then the
/// regressors'.
pub(super) fn ls_weighted(
    y: &[f64],
    regs: &[&[f64]],
    intercept: bool,
    ranges: &[Range<usize>],
    w: Option<&[f64]>,
) -> Option<(Vec<f64>, f64)> {
    let k = regs.len() + usize::from(intercept);
    let mut ata = vec![0.0; k * k];
    let mut aty = vec![0.0; k];
    let mut row = vec![0.0; k];
    for r in ranges {
        for t in r.clone() {
            let mut j = 0;
            if intercept {
                row[0] = 1.0;
                j = 1;
            }
            for g in regs {
                row[j] = g[t];
                j += 1;
            }
            let wt = w.map_or(1.0, |w| w[t]);
            for a in 0..k {
                aty[a] += wt * row[a] * y[t];
                for b in 0..k {
                    ata[a * k + b] += wt * row[a] * row[b];
                }
            }
        }
    }
    let beta = normal_equations(&ata, &aty, k)?;
    let mut rss = 0.0;
    for r in ranges {
        for t in r.clone() {
            rss += weighted_sq_residual(y, regs, &beta, intercept, w, t);
        }
    }
    Some((beta, rss))
}

/// w_t (y_t - f_t)^2 for the fit f = `beta` (the intercept first when fitted) at
/// sample t; w_t = 1 without weights.
fn weighted_sq_residual(
    y: &[f64],
    regs: &[&[f64]],
    beta: &[f64],
    intercept: bool,
    w: Option<&[f64]>,
    t: usize,
) -> f64 {
    let mut f = if intercept { beta[0] } else { 0.0 };
    for (j, g) in regs.iter().enumerate() {
        f += beta[j + usize::from(intercept)] * g[t];
    }
    w.map_or(1.0, |w| w[t]) * (y[t] - f).powi(2)
}

/// The weighted RSS of each of `ranges` for the fit `beta` (every coefficient, the
/// intercept first when fitted, as [`ls_weighted`] returns them).
pub(super) fn rss_by_range(
    y: &[f64],
    regs: &[&[f64]],
    beta: &[f64],
    intercept: bool,
    ranges: &[Range<usize>],
    w: Option<&[f64]>,
) -> Vec<f64> {
    ranges
        .iter()
        .map(|r| {
            r.clone()
                .map(|t| weighted_sq_residual(y, regs, beta, intercept, w, t))
                .sum()
        })
        .collect()
}

/// The least z of [`clearly_better`]: the better fit's lower RSS must be this many
/// standard errors of its spread over the ranges.
pub(super) const BETTER_Z: f64 = 1.0;

/// Whether the fit whose RSS by range is `better` lowers the RSS of the fit `worse` by
/// more than its spread over the ranges, whose lengths are `lens`. With D_r the
/// difference on range r (n_r samples, D and N their sums), the differences are taken
/// as independent with variance s^2 n_r: s^2 = sum_r (D_r - n_r D / N)^2 / n_r / (R - 1)
/// and z = D / sqrt(s^2 N), a block (batch-means) standard error that holds for
/// residuals correlated within a range (Carlstein 1986). True when z > [`BETTER_Z`];
/// with fewer than 4 ranges the spread is not estimated and any lower RSS counts.
pub(super) fn clearly_better(worse: &[f64], better: &[f64], lens: &[usize]) -> bool {
    let d: Vec<f64> = worse.iter().zip(better).map(|(a, b)| a - b).collect();
    let total: f64 = d.iter().sum();
    if d.len() < 4 {
        return total > 0.0;
    }
    let n: f64 = lens.iter().map(|&l| l as f64).sum();
    let s2 = d
        .iter()
        .zip(lens)
        .filter(|(_, l)| **l > 0)
        .map(|(dr, &l)| {
            let l = l as f64;
            (dr - l * total / n).powi(2) / l
        })
        .sum::<f64>()
        / (d.len() - 1) as f64;
    total > BETTER_Z * (s2 * n).sqrt()
}

/// `n` points from `lo` to `hi`, evenly spaced in ln.
pub(super) fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1).max(1) as f64))
        .collect()
}

/// Golden-section search for the minimum of a unimodal `f` on [lo, hi] (`iters`
/// steps, each shrinking the bracket by 0.618; Kiefer 1953): the last two interior
/// points with their values and the final bracket. At equal values the left point is
/// kept when `left_on_tie`.
fn golden_search(
    mut lo: f64,
    mut hi: f64,
    iters: usize,
    left_on_tie: bool,
    f: impl Fn(f64) -> f64,
) -> ((f64, f64), (f64, f64), (f64, f64)) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut a = hi - g * (hi - lo);
    let mut b = lo + g * (hi - lo);
    let (mut fa, mut fb) = (f(a), f(b));
    for _ in 0..iters {
        if fa < fb || (left_on_tie && fa == fb) {
            hi = b;
            b = a;
            fb = fa;
            a = hi - g * (hi - lo);
            fa = f(a);
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + g * (hi - lo);
            fb = f(b);
        }
    }
    ((a, fa), (b, fb), (lo, hi))
}

/// The minimiser of a unimodal `f` on [lo, hi] by golden-section search
/// ([`golden_search`]): the middle of the final bracket.
pub(super) fn golden_min(lo: f64, hi: f64, iters: usize, f: impl Fn(f64) -> f64) -> f64 {
    let (_, _, (lo, hi)) = golden_search(lo, hi, iters, false, f);
    0.5 * (lo + hi)
}

/// [`golden_search`] returning the better of its last two points and its value
/// (argmin, min), the left one at a tie.
pub(super) fn golden_argmin(lo: f64, hi: f64, iters: usize, f: impl Fn(f64) -> f64) -> (f64, f64) {
    let ((a, fa), (b, fb), _) = golden_search(lo, hi, iters, true, f);
    if fa <= fb { (a, fa) } else { (b, fb) }
}

/// The best point `grid[i]` of a log grid (`f_i` = f there) refined by a golden-section
/// search of ln x between its grid neighbours (`iters` steps, [`golden_argmin`]): the
/// refined point when it improves on the grid's, else the grid point; a point within
/// 1e-3 in ln of an end of the search range `ends` is put on that end (a bound, which
/// `flag_edge` then reports as such).
pub(super) fn refine_on_log_grid(
    grid: &[f64],
    i: usize,
    f_i: f64,
    iters: usize,
    ends: [f64; 2],
    f: impl Fn(f64) -> f64,
) -> f64 {
    let (a, b) = (grid[i.saturating_sub(1)], grid[(i + 1).min(grid.len() - 1)]);
    let (u, f_u) = golden_argmin(a.ln(), b.ln(), iters, |u| f(u.exp()));
    let mut x = if f_u < f_i { u.exp() } else { grid[i] };
    for end in ends {
        if (x / end).ln().abs() <= 1e-3 {
            x = end;
        }
    }
    x
}

/// First differences x_t - x_{t-1}, 0 at t = 0.
pub(super) fn diff(x: &[f64]) -> Vec<f64> {
    let mut d = vec![0.0; x.len()];
    for (t, v) in d.iter_mut().enumerate().skip(1) {
        *v = x[t] - x[t - 1];
    }
    d
}

/// Ranges without their first sample (where a difference would cross a block edge).
pub(super) fn shrink_ranges(r: &[Range<usize>]) -> Vec<Range<usize>> {
    r.iter().map(|r| (r.start + 1)..r.end).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_section_finds_the_minimum() {
        // near a quadratic minimum f changes by (dx)^2, below rounding once dx is under
        // sqrt(eps) ~ 1.5e-8: that is as close as any comparison search can get
        let x = golden_min(0.0, 4.0, 60, |v| (v - 1.3).powi(2) + 2.0);
        assert!((x - 1.3).abs() < 1e-7, "{x}");
        // at an end of the bracket it converges to that end
        let y = golden_min(0.0, 1.0, 60, |v| v);
        assert!(y < 1e-9, "{y}");
    }

    #[test]
    fn rss_by_range_sums_to_the_fits_rss() {
        let n = 300;
        let u: Vec<f64> = (0..n).map(|t| (t as f64 * 0.03).cos()).collect();
        let y: Vec<f64> = (0..n)
            .map(|t| -0.2 + 1.5 * u[t] + ((t * 104729) % 17) as f64 * 0.02)
            .collect();
        let ranges = [0..80, 100..190, 190..300];
        let (b, rss) = ls_full(&y, &[&u], true, &ranges).unwrap();
        let parts = rss_by_range(&y, &[&u], &b, true, &ranges, None);
        assert_eq!(parts.len(), 3);
        let sum: f64 = parts.iter().sum();
        assert!((sum - rss).abs() < 1e-12 * rss, "{sum} {rss}");
        // one range by hand
        let r1: f64 = (100..190)
            .map(|t| (y[t] - b[0] - b[1] * u[t]).powi(2))
            .sum();
        assert!((parts[1] - r1).abs() < 1e-12 * r1);
    }

    #[test]
    fn a_lower_rss_counts_only_beyond_its_spread_over_the_ranges() {
        let lens = [1000usize; 8];
        let worse = [10.0; 8];
        // the same lowering on every range: clearly better
        assert!(clearly_better(&worse, &[9.9; 8], &lens));
        // a lowering on one range and rises elsewhere: a total of +0.1 within the spread
        let mixed = [8.0, 10.3, 10.2, 10.3, 10.3, 10.2, 10.3, 10.3];
        let total: f64 = worse.iter().zip(&mixed).map(|(a, b)| a - b).sum();
        assert!(total > 0.0, "{total}");
        assert!(!clearly_better(&worse, &mixed, &lens));
        // no lowering at all
        assert!(!clearly_better(&worse, &worse, &lens));
        // with fewer than 4 ranges any lowering counts
        assert!(clearly_better(&[1.0, 1.0], &[0.99, 1.005], &[10, 10]));
    }

    #[test]
    fn weighted_least_squares_is_ordinary_least_squares_on_rows_scaled_by_root_weights() {
        let n = 400;
        let u: Vec<f64> = (0..n).map(|t| (t as f64 * 0.01).sin()).collect();
        let y: Vec<f64> = (0..n)
            .map(|t| 0.3 + 2.0 * u[t] + ((t * 7919) % 13) as f64 * 0.01)
            .collect();
        let w: Vec<f64> = (0..n).map(|t| 0.5 + (t % 5) as f64).collect();
        let ranges = [0..150, 200..400];
        // no weights: the unweighted fit, bit for bit
        assert_eq!(
            ls_weighted(&y, &[&u], true, &ranges, None),
            ls_full(&y, &[&u], true, &ranges)
        );
        // the twin: every row (the intercept's column too) times sqrt(w), no intercept
        let r: Vec<f64> = w.iter().map(|v| v.sqrt()).collect();
        let ys: Vec<f64> = (0..n).map(|t| r[t] * y[t]).collect();
        let us: Vec<f64> = (0..n).map(|t| r[t] * u[t]).collect();
        let (b_twin, rss_twin) = ls_full(&ys, &[&r, &us], false, &ranges).unwrap();
        let (b, rss) = ls_weighted(&y, &[&u], true, &ranges, Some(&w)).unwrap();
        for (a, b) in b.iter().zip(&b_twin) {
            assert!((a - b).abs() < 1e-10 * b.abs().max(1.0), "{a} {b}");
        }
        assert!((rss - rss_twin).abs() < 1e-9 * rss_twin, "{rss} {rss_twin}");
        // ls_w drops the intercept as ls does
        let (b1, _) = ls_w(&y, &[&u], true, &ranges, Some(&w)).unwrap();
        assert_eq!(b1, vec![b[1]]);
    }
}
