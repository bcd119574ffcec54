//! Weighted linear least squares for the few columns of an Allan-variance model:
//! Householder QR of the row- and column-scaled design, and the covariance
//! (A^T W A)^{-1} of the estimate.
//!
//! Minimises sum_i w_i (b_i - sum_j A_ij c_j)^2. Rows are scaled by sqrt(w_i) and
//! columns to unit norm before the QR (the bases span many decades over the taus), so
//! the factorisation sees a well-scaled matrix; the covariance is R^{-1} R^{-T} scaled
//! back. Source: G. H. Golub, C. F. Van Loan, "Matrix Computations", 4th ed., 5.3
//! (least squares by Householder QR) (the covariance (R^T R)^{-1} from the same factor).

/// The solution of a weighted least-squares problem.
#[derive(Clone, Debug)]
pub struct Wls {
    /// The coefficients c.
    pub coef: Vec<f64>,
    /// (A^T W A)^{-1}, row-major k x k.
    pub cov: Vec<f64>,
}

/// Solves min sum_i w\[i\] (b\[i\] - a\[i\] . c)^2 for `a` with rows of equal length k >= 1,
/// n >= k rows. None when the scaled design is rank deficient (a column of zeros, or
/// columns dependent to within 1e-12 relative).
pub fn solve(a: &[Vec<f64>], b: &[f64], w: &[f64]) -> Option<Wls> {
    let n = a.len();
    let k = a.first()?.len();
    if k == 0 || n < k {
        return None;
    }
    // Scaled design, column-major: s[j][i] = sqrt(w_i) a_ij / norm_j.
    let sw: Vec<f64> = w.iter().map(|&x| x.sqrt()).collect();
    let mut s: Vec<Vec<f64>> = (0..k)
        .map(|j| (0..n).map(|i| sw[i] * a[i][j]).collect())
        .collect();
    let mut norms = vec![0.0; k];
    for j in 0..k {
        let nrm = s[j].iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(nrm > 0.0 && nrm.is_finite()) {
            return None;
        }
        norms[j] = nrm;
        for v in &mut s[j] {
            *v /= nrm;
        }
    }
    let mut rhs: Vec<f64> = (0..n).map(|i| sw[i] * b[i]).collect();
    // Householder QR in place: R in the upper triangle of s.
    for j in 0..k {
        let x = &s[j][j..];
        let alpha = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        if alpha < 1e-12 {
            return None;
        }
        let sign = if x[0] >= 0.0 { 1.0 } else { -1.0 };
        let mut v: Vec<f64> = x.to_vec();
        v[0] += sign * alpha;
        let vnorm2: f64 = v.iter().map(|t| t * t).sum();
        let apply = |col: &mut [f64]| {
            let dot: f64 = v.iter().zip(col.iter()).map(|(a, b)| a * b).sum();
            let f = 2.0 * dot / vnorm2;
            for (c, vi) in col.iter_mut().zip(&v) {
                *c -= f * vi;
            }
        };
        for col in s.iter_mut().skip(j) {
            apply(&mut col[j..]);
        }
        apply(&mut rhs[j..]);
    }
    // R is s[j][i] for i <= j. Back substitution for the scaled coefficients.
    let r = |i: usize, j: usize| s[j][i];
    let mut x = vec![0.0; k];
    for i in (0..k).rev() {
        let mut acc = rhs[i];
        for (j, xj) in x.iter().enumerate().skip(i + 1) {
            acc -= r(i, j) * xj;
        }
        x[i] = acc / r(i, i);
    }
    // R^{-1} (upper triangular), then cov_scaled = R^{-1} R^{-T}.
    let mut rinv = vec![0.0; k * k];
    for col in 0..k {
        for i in (0..=col).rev() {
            let mut acc = if i == col { 1.0 } else { 0.0 };
            for j in i + 1..=col {
                acc -= r(i, j) * rinv[j * k + col];
            }
            rinv[i * k + col] = acc / r(i, i);
        }
    }
    let mut cov = vec![0.0; k * k];
    for i in 0..k {
        for j in 0..k {
            let mut acc = 0.0;
            for l in i.max(j)..k {
                acc += rinv[i * k + l] * rinv[j * k + l];
            }
            cov[i * k + j] = acc / (norms[i] * norms[j]);
        }
    }
    let coef = (0..k).map(|j| x[j] / norms[j]).collect();
    Some(Wls { coef, cov })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The twin: normal equations solved by Gauss-Jordan with partial pivoting.
    fn normal_equations(a: &[Vec<f64>], b: &[f64], w: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let k = a[0].len();
        let mut m = vec![vec![0.0; 2 * k + 1]; k];
        for (i, row) in a.iter().enumerate() {
            for p in 0..k {
                for q in 0..k {
                    m[p][q] += w[i] * row[p] * row[q];
                }
                m[p][2 * k] += w[i] * row[p] * b[i];
            }
        }
        for (p, row) in m.iter_mut().enumerate() {
            row[k + p] = 1.0;
        }
        for c in 0..k {
            let piv = (c..k)
                .max_by(|&x, &y| m[x][c].abs().total_cmp(&m[y][c].abs()))
                .unwrap();
            m.swap(c, piv);
            let d = m[c][c];
            for v in m[c].iter_mut() {
                *v /= d;
            }
            for r in 0..k {
                if r != c {
                    let f = m[r][c];
                    let rowc = m[c].clone();
                    for (v, rc) in m[r].iter_mut().zip(rowc) {
                        *v -= f * rc;
                    }
                }
            }
        }
        let coef = (0..k).map(|p| m[p][2 * k]).collect();
        let cov = (0..k * k).map(|i| m[i / k][k + i % k]).collect();
        (coef, cov)
    }

    #[test]
    fn matches_normal_equations() {
        let taus: Vec<f64> = (0..12).map(|i| 2f64.powi(i) * 0.01).collect();
        let a: Vec<Vec<f64>> = taus.iter().map(|&t| vec![1.0 / t, 0.44, t / 3.0]).collect();
        let b: Vec<f64> = taus
            .iter()
            .enumerate()
            .map(|(i, &t)| (0.5 / t + 0.2 + 0.01 * t) * (1.0 + 0.03 * ((i * 7 % 5) as f64 - 2.0)))
            .collect();
        let w: Vec<f64> = b.iter().map(|v| 100.0 / (v * v)).collect();
        let got = solve(&a, &b, &w).unwrap();
        let (coef, cov) = normal_equations(&a, &b, &w);
        for (g, c) in got.coef.iter().zip(&coef) {
            assert!((g - c).abs() < 1e-9 * c.abs(), "{g} {c}");
        }
        for (g, c) in got.cov.iter().zip(&cov) {
            assert!((g - c).abs() < 1e-7 * c.abs().max(1e-30), "{g} {c}");
        }
    }

    #[test]
    fn rank_deficient_is_none() {
        let a = vec![vec![1.0, 2.0], vec![2.0, 4.0], vec![3.0, 6.0]];
        assert!(solve(&a, &[1.0, 2.0, 3.0], &[1.0, 1.0, 1.0]).is_none());
        let z = vec![vec![1.0, 0.0], vec![2.0, 0.0]];
        assert!(solve(&z, &[1.0, 2.0], &[1.0, 1.0]).is_none());
    }
}
