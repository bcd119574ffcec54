//! Small dense solves with faer: symmetric positive definite systems by Cholesky.

use faer::Mat;
use faer::linalg::solvers::{DenseSolveCore, Solve};

/// Condition number above which a local system counts as singular.
pub const MAX_COND: f64 = 1e14;

/// Solves S z = rhs for symmetric positive definite S (row-major n x n) and returns
/// (z, S^{-1} row-major, condition number), or None when S is not numerically positive
/// definite. The condition number is the 2-norm one, lambda_max / lambda_min of S: it
/// bounds the relative error of z caused by errors in S relative to its largest entries
/// (Golub and Van Loan, 4th ed., 2.6.2). It is not equilibrated on purpose: in a local
/// design [X, w X] a block made only of samples with vanishing kernel weight would be
/// scaled up by equilibration and look well determined. Above [`MAX_COND`] the system
/// counts as singular.
pub fn spd_solve_inverse(s: &[f64], rhs: &[f64], n: usize) -> Option<(Vec<f64>, Vec<f64>, f64)> {
    let diag: Vec<f64> = (0..n).map(|i| s[i * n + i]).collect();
    if diag.iter().any(|d| !(d.is_finite() && *d > 0.0)) {
        return None;
    }
    let a = Mat::<f64>::from_fn(n, n, |i, j| s[i * n + j]);
    let eig = a.self_adjoint_eigenvalues(faer::Side::Lower).ok()?;
    let (lo, hi) = eig
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(*v), b.max(*v)));
    let cond = if lo > 0.0 { hi / lo } else { f64::INFINITY };
    if cond.is_nan() || cond > MAX_COND {
        return None;
    }
    let llt = a.llt(faer::Side::Lower).ok()?;
    let b = Mat::<f64>::from_fn(n, 1, |i, _| rhs[i]);
    let z = llt.solve(&b);
    let inv = llt.inverse();
    let sol = (0..n).map(|i| z[(i, 0)]).collect();
    let inv_rm = (0..n * n).map(|k| inv[(k / n, k % n)]).collect();
    Some((sol, inv_rm, cond))
}

/// Ordinary least squares by the normal equations: minimises |y - A beta|^2 given
/// A'A (row-major k x k) and A'y. None when A'A is singular.
pub fn normal_equations(ata: &[f64], aty: &[f64], k: usize) -> Option<Vec<f64>> {
    spd_solve_inverse(ata, aty, k).map(|(z, _, _)| z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_and_inverts_and_flags_singular() {
        let s = [4.0, 2.0, 2.0, 3.0];
        let (z, inv, cond) = spd_solve_inverse(&s, &[2.0, 1.0], 2).unwrap();
        assert!(cond > 1.0 && cond < 10.0);
        // exact: det 8, inverse [3 -2; -2 4]/8, z = inv * (2,1) = (0.5, 0)
        assert!((z[0] - 0.5).abs() < 1e-15 && z[1].abs() < 1e-15);
        assert!((inv[0] - 0.375).abs() < 1e-15 && (inv[1] + 0.25).abs() < 1e-15);
        assert!(spd_solve_inverse(&[1.0, 1.0, 1.0, 1.0], &[1.0, 1.0], 2).is_none());
        assert!(spd_solve_inverse(&[0.0; 4], &[0.0; 2], 2).is_none());
    }
}
