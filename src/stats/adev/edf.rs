//! Equivalent degrees of freedom (EDF) of the deviations, by Greenhall's algorithm,
//! and the chi-squared confidence interval built on them.
//!
//! Source: C. A. Greenhall and W. J. Riley, "Uncertainty of stability variances based
//! on finite differences", 35th PTTI meeting, 2003 (also NIST SP 1065 section 5.3 and
//! W. J. Riley, "Confidence intervals and bias corrections for the Stable32 variance
//! functions"). This is a line-by-line port of allantools' `edf_greenhall` (ci.py,
//! allantools 2024.6) and checked against it on fixtures: equations (7)-(10) and (13)
//! and Tables 1-3 of the paper. Parameters: alpha the exponent of the frequency noise
//! PSD S_y(f) ~ f^alpha (2 white PM, 1 flicker PM, 0 white FM, -1 flicker FM,
//! -2 random-walk FM, down to -4), d the difference order (2 Allan, 3 Hadamard), m the
//! averaging factor, N the number of *phase* points (rate samples + 1), overlapping
//! (stride 1) or not, modified (MDEV) or not. farma assumes white FM (alpha = 0) unless
//! told otherwise: the rate noise of a gyro at short tau (angle random walk).
//!
//! The interval (SP 1065 eq. (45)): with edf = nu and confidence c, the variance lies
//! in [nu s^2 / chi2_{1-(1-c)/2}(nu), nu s^2 / chi2_{(1-c)/2}(nu)], so the deviation in
//! the square roots of those; c = 0.683 (erf(1/sqrt 2)) gives the one-sigma interval.

use crate::stats::special::chi2_quantile;

/// erf(1/sqrt(2)): the probability inside one standard deviation of a normal law.
pub const ONE_SIGMA: f64 = 0.682_689_492_137_085_9;

/// Greenhall's equation (7): the "sw" function for integer alpha in -4..=2.
fn sw(t: f64, alpha: i32) -> f64 {
    let log_term = |p: i32| {
        if t == 0.0 {
            0.0
        } else {
            t.powi(p) * t.abs().ln()
        }
    };
    match alpha {
        2 => -t.abs(),
        1 => log_term(2),
        0 => t.abs().powi(3),
        -1 => log_term(4),
        -2 => t.abs().powi(5),
        -3 => log_term(6),
        -4 => t.abs().powi(7),
        _ => unreachable!("alpha {alpha}"),
    }
}

/// Equation (8); `f == None` stands for F = infinity.
fn sx(t: f64, f: Option<f64>, alpha: i32) -> f64 {
    match f {
        None => sw(t, alpha + 2),
        Some(f) => f * f * (2.0 * sw(t, alpha) - sw(t - 1.0 / f, alpha) - sw(t + 1.0 / f, alpha)),
    }
}

/// Equation (9).
fn sz(t: f64, f: Option<f64>, alpha: i32, d: u32) -> f64 {
    let x = |dt: f64| sx(t + dt, f, alpha);
    match d {
        1 => 2.0 * x(0.0) - x(-1.0) - x(1.0),
        2 => 6.0 * x(0.0) - 4.0 * x(-1.0) - 4.0 * x(1.0) + x(-2.0) + x(2.0),
        3 => {
            20.0 * x(0.0) - 15.0 * x(-1.0) - 15.0 * x(1.0) + 6.0 * x(-2.0) + 6.0 * x(2.0)
                - x(-3.0)
                - x(3.0)
        }
        _ => unreachable!("d {d}"),
    }
}

/// Equation (10), the basic sum.
fn basic_sum(j: f64, m_big: f64, s: f64, f: Option<f64>, alpha: i32, d: u32) -> f64 {
    let first = sz(0.0, f, alpha, d).powi(2);
    let second = (1.0 - j / m_big) * sz(j / s, f, alpha, d).powi(2);
    let mut third = 0.0;
    for jj in 1..(j as i64) {
        let jj = jj as f64;
        third += 2.0 * (1.0 - jj / m_big) * sz(jj / s, f, alpha, d).powi(2);
    }
    first + second + third
}

/// Table 1 (a0, a1) of the paper: modified variances.
fn table1(alpha: i32, d: u32) -> (f64, f64) {
    const T: [[(f64, f64); 3]; 7] = [
        [
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
            (22.0 / 25.0, 2.0 / 3.0),
        ],
        [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
        [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
        [(-1.0, -1.0), (1.048, 0.534), (1.180, 0.816)],
        [(-1.0, -1.0), (1.302, 0.535), (1.175, 0.777)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.194, 0.703)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.489, 0.702)],
    ];
    T[(2 - alpha) as usize][(d - 1) as usize]
}

/// Table 2 (a0, a1): unmodified variances.
fn table2(alpha: i32, d: u32) -> (f64, f64) {
    const T: [[(f64, f64); 3]; 7] = [
        [
            (3.0 / 2.0, 1.0 / 2.0),
            (35.0 / 18.0, 1.0),
            (231.0 / 100.0, 3.0 / 2.0),
        ],
        [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
        [
            (2.0 / 3.0, 1.0 / 6.0),
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
        ],
        [(-1.0, -1.0), (0.852, 0.375), (0.997, 0.617)],
        [(-1.0, -1.0), (1.079, 0.368), (1.033, 0.607)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.053, 0.553)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.302, 0.535)],
    ];
    T[(2 - alpha) as usize][(d - 1) as usize]
}

/// Table 3 (b0, b1): alpha = 1.
fn table3(d: u32) -> (f64, f64) {
    [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)][(d - 1) as usize]
}

/// Binomial coefficient as f64 (small arguments only).
fn binom(n: u32, k: u32) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// Greenhall's EDF. `n_phase` is the number of phase points (rate samples + 1).
/// Returns None where the algorithm has no case (alpha + 2d <= 1, or alpha = 2
/// unmodified with ceil(r) <= d, which allantools also leaves unimplemented).
pub fn edf_greenhall(
    alpha: i32,
    d: u32,
    m: usize,
    n_phase: usize,
    overlapping: bool,
    modified: bool,
) -> Option<f64> {
    if !(-4..=2).contains(&alpha) || !(1..=3).contains(&d) || alpha + 2 * d as i32 <= 1 {
        return None;
    }
    let mf = m as f64;
    let n = n_phase as f64;
    let f = if modified { 1.0 } else { mf };
    let s = if overlapping { mf } else { 1.0 };
    let l = mf / f + mf * d as f64;
    let m_big = 1.0 + (s * (n - l) / mf).floor();
    let j = m_big.min((d as f64 + 1.0) * s);
    let j_max = 100.0;
    let r = m_big / s;
    let df = d as f64;
    let inv = if modified {
        if j <= j_max {
            basic_sum(j, m_big, s, Some(1.0), alpha, d)
                / (sz(0.0, Some(1.0), alpha, d).powi(2) * m_big)
        } else if r > df + 1.0 {
            let (a0, a1) = table1(alpha, d);
            (a0 - a1 / r) / r
        } else {
            let m_prime = j_max / r;
            basic_sum(j_max, j_max, m_prime, Some(1.0), alpha, d)
                / (sz(0.0, Some(f), alpha, d).powi(2) * j_max)
        }
    } else if alpha <= 0 {
        if j <= j_max {
            let m_prime = if mf * (df + 1.0) <= j_max {
                Some(mf)
            } else {
                None
            };
            basic_sum(j, m_big, s, m_prime, alpha, d) / (sz(0.0, m_prime, alpha, d).powi(2) * m_big)
        } else if r > df + 1.0 {
            let (a0, a1) = table2(alpha, d);
            (a0 - a1 / r) / r
        } else {
            let m_prime = j_max / r;
            basic_sum(j_max, j_max, m_prime, None, alpha, d)
                / (sz(0.0, None, alpha, d).powi(2) * j_max)
        }
    } else if alpha == 1 {
        if j <= j_max {
            basic_sum(j, m_big, s, Some(mf), 1, d) / (sz(0.0, Some(mf), 1, d).powi(2) * m_big)
        } else if r > df + 1.0 {
            let (a0, a1) = table2(alpha, d);
            let (b0, b1) = table3(d);
            (a0 - a1 / r) / ((b0 + b1 * mf.ln()).powi(2) * r)
        } else {
            let m_prime = j_max / r;
            let (b0, b1) = table3(d);
            basic_sum(j_max, j_max, m_prime, Some(m_prime), 1, d)
                / ((b0 + b1 * mf.ln()).powi(2) * j_max)
        }
    } else {
        // alpha = 2, unmodified.
        if r.ceil() <= df {
            return None;
        }
        let a0 = binom(4 * d, 2 * d) / binom(2 * d, d).powi(2);
        let a1 = df / 2.0;
        (a0 - a1 / r) / m_big
    };
    Some(1.0 / inv)
}

/// The confidence interval (lo, hi) of a deviation `dev` with `edf` degrees of freedom
/// at confidence `confidence` (SP 1065 eq. (45)).
pub fn confidence_interval(dev: f64, edf: f64, confidence: f64) -> (f64, f64) {
    let p_lo = confidence.abs().min((confidence - 1.0).abs()) / 2.0;
    let p_hi = 1.0 - p_lo;
    let chi2_lo = chi2_quantile(p_lo, edf);
    let chi2_hi = chi2_quantile(p_hi, edf);
    let var = dev * dev;
    ((edf * var / chi2_hi).sqrt(), (edf * var / chi2_lo).sqrt())
}
