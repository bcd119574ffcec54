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
    if n <= SMALL_N {
        small_spd_solve_inverse(s, rhs, n)
    } else {
        faer_spd_solve_inverse(s, rhs, n)
    }
}

/// Largest order solved by the fixed-size kernel [`small_spd_solve_inverse`] (the
/// local systems of p <= 4 and the MA / ARMA normal equations); larger ones go to faer.
pub const SMALL_N: usize = 8;

/// [`spd_solve_inverse`] through faer (Cholesky, inverse, and the eigenvalues for the
/// condition number): the general path, and the twin the fixed-size kernel is tested
/// against.
pub fn faer_spd_solve_inverse(
    s: &[f64],
    rhs: &[f64],
    n: usize,
) -> Option<(Vec<f64>, Vec<f64>, f64)> {
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

/// [`spd_solve_inverse`] for n <= [`SMALL_N`] on the stack, without allocation or
/// dispatch (a GCV ladder solves G x J systems of order 2p, 201 x 31 = 6,231 with
/// the defaults at 1e6 samples, and a fit has two ladders; faer's general
/// path costs microseconds each there).
/// - Cholesky S = L L' (Golub and Van Loan, 4th ed., alg. 4.2.1, the gaxpy form); not
///   positive definite when a pivot is not positive.
/// - z by forward and back substitution; S^-1 = L'^-1 L^-1 from the inverse of L.
/// - The condition number lambda_max / lambda_min from the eigenvalues by the cyclic
///   Jacobi method (Golub and Van Loan, alg. 8.5.3; each rotated entry set to zero, as
///   in Rutishauser's form), run until every off-diagonal entry is below 1e-18 of the
///   geometric mean of its two diagonal entries, at most 60 sweeps. Near
///   [`MAX_COND`] the eigenvalues of either path carry errors of about eps lambda_max,
///   so the two may disagree on systems right at the limit.
/// - The Cholesky factor is computed first: a matrix that is not numerically positive
///   definite (or holds NaN) returns None before the eigenvalues.
pub fn small_spd_solve_inverse(
    s: &[f64],
    rhs: &[f64],
    n: usize,
) -> Option<(Vec<f64>, Vec<f64>, f64)> {
    assert!(n <= SMALL_N && s.len() == n * n && rhs.len() == n);
    let f = small_spd_factor(s, n)?;
    Some((f.solve(rhs), f.inv, f.cond))
}

/// A symmetric positive definite system of order n <= [`SMALL_N`] factored once by
/// [`small_spd_factor`]: its Cholesky factor, inverse and condition number, so that
/// systems with the same left-hand side and other right-hand sides (a local system
/// whose response changed) are solved by substitution alone, with the bits
/// [`small_spd_solve_inverse`] gives.
#[derive(Clone, Debug)]
pub struct SpdFactor {
    n: usize,
    /// Lower Cholesky factor.
    l: [[f64; SMALL_N]; SMALL_N],
    /// S^-1, row-major n x n.
    pub inv: Vec<f64>,
    /// lambda_max / lambda_min.
    pub cond: f64,
}

impl SpdFactor {
    /// z with S z = rhs: L y = rhs, L' z = y.
    pub fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        let (n, l) = (self.n, &self.l);
        assert_eq!(rhs.len(), n);
        let mut z = [0.0f64; SMALL_N];
        for i in 0..n {
            let mut v = rhs[i];
            for k in 0..i {
                v -= l[i][k] * z[k];
            }
            z[i] = v / l[i][i];
        }
        for i in (0..n).rev() {
            let mut v = z[i];
            for k in i + 1..n {
                v -= l[k][i] * z[k];
            }
            z[i] = v / l[i][i];
        }
        z[..n].to_vec()
    }
}

/// The factor of [`small_spd_solve_inverse`] (its steps but the substitution), or
/// None where that returns None.
pub fn small_spd_factor(s: &[f64], n: usize) -> Option<SpdFactor> {
    assert!(n <= SMALL_N && s.len() == n * n);
    if (0..n).any(|i| !(s[i * n + i].is_finite() && s[i * n + i] > 0.0)) {
        return None;
    }
    const M: usize = SMALL_N;
    // Cholesky, lower triangle
    let mut l = [[0.0f64; M]; M];
    for j in 0..n {
        let mut d = s[j * n + j];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let djj = d.sqrt();
        l[j][j] = djj;
        for i in j + 1..n {
            let mut v = s[i * n + j];
            for k in 0..j {
                v -= l[i][k] * l[j][k];
            }
            l[i][j] = v / djj;
        }
    }
    // eigenvalues (Jacobi on a copy of the lower triangle made symmetric)
    let mut a = [[0.0f64; M]; M];
    for i in 0..n {
        for j in 0..=i {
            a[i][j] = s[i * n + j];
            a[j][i] = s[i * n + j];
        }
    }
    let mut sweeps = 0;
    loop {
        let mut rotated = false;
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p][q];
                if apq == 0.0 || apq.abs() <= 1e-18 * a[p][p].abs().sqrt() * a[q][q].abs().sqrt() {
                    continue;
                }
                rotated = true;
                // the rotation that zeroes a_pq (Golub and Van Loan, alg. 8.5.1)
                let tau = (a[q][q] - a[p][p]) / (2.0 * apq);
                let t = if tau >= 0.0 {
                    1.0 / (tau + (1.0 + tau * tau).sqrt())
                } else {
                    -1.0 / (-tau + (1.0 + tau * tau).sqrt())
                };
                let c = 1.0 / (1.0 + t * t).sqrt();
                let sn = t * c;
                for k in 0..n {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = c * akp - sn * akq;
                    a[k][q] = sn * akp + c * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = c * apk - sn * aqk;
                    a[q][k] = sn * apk + c * aqk;
                }
                a[p][q] = 0.0;
                a[q][p] = 0.0;
            }
        }
        sweeps += 1;
        if !rotated || sweeps >= 60 {
            break;
        }
    }
    let (lo, hi) = (0..n).fold((f64::INFINITY, 0.0f64), |(l, h), i| {
        (l.min(a[i][i]), h.max(a[i][i]))
    });
    let cond = if lo > 0.0 { hi / lo } else { f64::INFINITY };
    if cond.is_nan() || cond > MAX_COND {
        return None;
    }
    // W = L^-1 (lower), then S^-1 = W' W
    let mut w = [[0.0f64; M]; M];
    for j in 0..n {
        w[j][j] = 1.0 / l[j][j];
        for i in j + 1..n {
            let mut v = 0.0;
            for k in j..i {
                v -= l[i][k] * w[k][j];
            }
            w[i][j] = v / l[i][i];
        }
    }
    let mut inv = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut v = 0.0;
            for k in i..n {
                v += w[k][i] * w[k][j];
            }
            inv[i * n + j] = v;
            inv[j * n + i] = v;
        }
    }
    Some(SpdFactor { n, l, inv, cond })
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

    /// A random symmetric positive definite matrix Q diag(lambda) Q' with eigenvalues
    /// spread over `decades`, and its eigenvalues.
    fn spd(n: usize, decades: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut st = seed;
        let mut rnd = move || {
            st = st
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((st >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let q = Mat::<f64>::from_fn(n, n, |_, _| rnd()).qr().compute_Q();
        let lam: Vec<f64> = (0..n)
            .map(|i| 10f64.powf(-decades * i as f64 / (n.max(2) - 1) as f64) * (1.0 + rnd()))
            .collect();
        let s = (0..n * n)
            .map(|k| (0..n).map(|m| q[(k / n, m)] * lam[m] * q[(k % n, m)]).sum())
            .collect();
        (s, lam)
    }

    #[test]
    fn the_fixed_size_kernel_equals_faer() {
        for n in 1..=SMALL_N {
            for (seed, decades) in [(1, 0.5), (2, 3.0), (3, 6.0), (4, 9.0)] {
                let (s, lam) = spd(n, decades, seed * 31 + n as u64);
                let rhs: Vec<f64> = (0..n).map(|i| 1.0 - 0.3 * i as f64).collect();
                let (z1, i1, c1) = small_spd_solve_inverse(&s, &rhs, n).unwrap();
                let (z2, i2, c2) = faer_spd_solve_inverse(&s, &rhs, n).unwrap();
                let c_true = lam.iter().cloned().fold(0.0, f64::max)
                    / lam.iter().cloned().fold(f64::INFINITY, f64::min);
                // the solution and inverse to the accuracy a backward-stable solve
                // has, eps times the condition number; the condition numbers to each
                // other and to the one the matrix was made with
                let tol = 1e-14 * c_true;
                let zmax = z2.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let imax = i2.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                for (a, b) in z1.iter().zip(&z2) {
                    assert!((a - b).abs() <= tol * zmax, "n {n} z {a} vs {b}");
                }
                for (a, b) in i1.iter().zip(&i2) {
                    assert!((a - b).abs() <= tol * imax, "n {n} inverse {a} vs {b}");
                }
                assert!((c1 / c2 - 1.0).abs() <= 1e-6, "n {n} cond {c1} vs {c2}");
                assert!(
                    (c1 / c_true - 1.0).abs() <= 1e-6,
                    "n {n} cond {c1} vs {c_true}"
                );
            }
        }
        // not positive definite, or above MAX_COND: None from both
        let (mut s, _) = spd(4, 16.0, 9);
        assert!(small_spd_solve_inverse(&s, &[1.0; 4], 4).is_none());
        assert!(faer_spd_solve_inverse(&s, &[1.0; 4], 4).is_none());
        s[0] = -1.0;
        assert!(small_spd_solve_inverse(&s, &[1.0; 4], 4).is_none());
        // indefinite with a positive diagonal; NaN off the diagonal; huge entries of
        // a singular matrix (its condition must not be lost to overflow)
        let indefinite = [1.0, 2.0, 2.0, 1.0];
        assert!(small_spd_solve_inverse(&indefinite, &[1.0; 2], 2).is_none());
        assert!(faer_spd_solve_inverse(&indefinite, &[1.0; 2], 2).is_none());
        let nan = [1.0, f64::NAN, f64::NAN, 1.0];
        assert!(small_spd_solve_inverse(&nan, &[1.0; 2], 2).is_none());
        let big = [1e200, 1e200 * (1.0 - 1e-15), 1e200 * (1.0 - 1e-15), 1e200];
        assert!(small_spd_solve_inverse(&big, &[1.0; 2], 2).is_none());
        assert!(faer_spd_solve_inverse(&big, &[1.0; 2], 2).is_none());
    }
}
