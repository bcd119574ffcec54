//! Slow, obviously correct twins: each estimator summed straight from its definition
//! on the rate series y (no phase, no mean removal, no blocking), O(N m) or O(N m^2)
//! per tau. The fast path is tested against these on random data.

use super::Kind;

/// Mean of y[a..a + m], by a plain sum.
fn window_mean(y: &[f64], a: usize, m: usize) -> f64 {
    y[a..a + m].iter().sum::<f64>() / m as f64
}

/// The deviation of `kind` at averaging factor m, from the definitions in NIST SP 1065
/// (M = N rate samples y_1..y_M, ybar_j(m) the mean of y_j..y_{j+m-1}):
/// - overlapping ADEV, SP 1065 eq. (10):
///   sigma^2 = 1 / (2 (M - 2m + 1)) sum_{j=1}^{M-2m+1} (ybar_{j+m} - ybar_j)^2;
/// - MDEV, SP 1065 eq. (15):
///   sigma^2 = 1 / (2 m^4 (M - 3m + 2)) sum_{j=1}^{M-3m+2}
///   [ sum_{i=j}^{j+m-1} sum_{k=i}^{i+m-1} (y_{k+m} - y_k) ]^2;
/// - overlapping HDEV, SP 1065 eq. (19) with overlapping samples:
///   sigma^2 = 1 / (6 (M - 3m + 1)) sum_{j=1}^{M-3m+1}
///   (ybar_{j+2m} - 2 ybar_{j+m} + ybar_j)^2.
pub fn deviation_slow(y: &[f64], kind: Kind, m: usize) -> f64 {
    let n = y.len();
    assert!(m >= 1 && m <= super::max_m(kind, n), "m = {m} out of range");
    match kind {
        Kind::Adev => {
            let terms = n - 2 * m + 1;
            let mut s = 0.0;
            for j in 0..terms {
                let d = window_mean(y, j + m, m) - window_mean(y, j, m);
                s += d * d;
            }
            (s / (2.0 * terms as f64)).sqrt()
        }
        Kind::Mdev => {
            let terms = n + 2 - 3 * m;
            let mut s = 0.0;
            for j in 0..terms {
                let mut outer = 0.0;
                for i in j..j + m {
                    let mut inner = 0.0;
                    for k in i..i + m {
                        inner += y[k + m] - y[k];
                    }
                    outer += inner;
                }
                s += outer * outer;
            }
            let m4 = (m as f64).powi(4);
            (s / (2.0 * m4 * terms as f64)).sqrt()
        }
        Kind::Hdev => {
            let terms = n + 1 - 3 * m;
            let mut s = 0.0;
            for j in 0..terms {
                let d = window_mean(y, j + 2 * m, m) - 2.0 * window_mean(y, j + m, m)
                    + window_mean(y, j, m);
                s += d * d;
            }
            (s / (6.0 * terms as f64)).sqrt()
        }
    }
}
