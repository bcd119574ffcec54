//! The Biweight (quartic) kernel K(w) = 15/16 (1 - w^2)^2 on |w| <= 1, zero outside
//! (Silverman 1986, Table 3.1; the kernel of the FARMA paper).

/// Coefficients of K(w) as a polynomial on |w| <= 1: K(w) = sum_r BIWEIGHT\[r\] w^r.
pub const BIWEIGHT: [f64; 5] = [15.0 / 16.0, 0.0, -30.0 / 16.0, 0.0, 15.0 / 16.0];

/// K(w).
#[inline]
pub fn biweight(w: f64) -> f64 {
    if w.abs() <= 1.0 {
        let a = 1.0 - w * w;
        15.0 / 16.0 * a * a
    } else {
        0.0
    }
}

/// Binomial coefficients C(n, k) for n <= 12 (exact in f64).
pub fn binomial_table() -> [[f64; 13]; 13] {
    let mut c = [[0.0; 13]; 13];
    for n in 0..13 {
        c[n][0] = 1.0;
        for k in 1..=n {
            c[n][k] = c[n - 1][k - 1] + if k < n { c[n - 1][k] } else { 0.0 };
        }
    }
    c
}

/// Product of two polynomials given by coefficients (lowest power first).
pub fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polynomial_form_equals_kernel_and_integrates_to_one() {
        for i in 0..=200 {
            let w = -1.0 + i as f64 / 100.0;
            let p: f64 = BIWEIGHT
                .iter()
                .enumerate()
                .map(|(r, c)| c * w.powi(r as i32))
                .sum();
            assert!((p - biweight(w)).abs() < 1e-15);
        }
        // int_{-1}^{1} K = sum_r c_r * 2/(r+1) over even r.
        let integral: f64 = BIWEIGHT
            .iter()
            .enumerate()
            .filter(|(r, _)| r % 2 == 0)
            .map(|(r, c)| c * 2.0 / (r as f64 + 1.0))
            .sum();
        assert!((integral - 1.0).abs() < 1e-15);
        assert_eq!(binomial_table()[6][3], 20.0);
    }
}
