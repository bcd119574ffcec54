//! Chi-squared quantiles, for confidence intervals from equivalent degrees of freedom.
//!
//! The chi-squared distribution with k degrees of freedom has CDF P(k/2, x/2), P the
//! regularized lower incomplete gamma function. P is computed as in Numerical Recipes
//! (Press et al., 3rd ed., section 6.2): the series
//! P(a, x) = e^-x x^a / Gamma(a+1) sum_n x^n / ((a+1)...(a+n)) for x < a + 1, else
//! 1 - Q(a, x) with Q from Legendre's continued fraction evaluated by the modified
//! Lentz method; ln Gamma from Lanczos' approximation (g = 607/128, 15 terms, as in
//! Boost/Godfrey: about 1e-15 relative). The quantile is found by Newton's method on
//! P(a, x) = p, from the Wilson-Hilferty starting point, safeguarded by bisection.

/// ln Gamma(z) for z > 0 (Lanczos, Godfrey's coefficients, g = 607/128).
pub fn ln_gamma(z: f64) -> f64 {
    const G: f64 = 607.0 / 128.0;
    const C: [f64; 15] = [
        0.999_999_999_999_997_1,
        57.156_235_665_862_92,
        -59.597_960_355_475_49,
        14.136_097_974_741_746,
        -0.491_913_816_097_620_2,
        0.339_946_499_848_118_9e-4,
        0.465_236_289_270_485_8e-4,
        -0.983_744_753_048_795_6e-4,
        0.158_088_703_224_912_5e-3,
        -0.210_264_441_724_104_9e-3,
        0.217_439_618_115_212_6e-3,
        -0.164_318_106_536_763_9e-3,
        0.844_182_239_838_527_4e-4,
        -0.261_908_384_015_814_1e-4,
        0.368_991_826_595_316_2e-5,
    ];
    if z < 0.5 {
        // Reflection: Gamma(z) Gamma(1 - z) = pi / sin(pi z).
        let pi = std::f64::consts::PI;
        return (pi / (pi * z).sin()).ln() - ln_gamma(1.0 - z);
    }
    let z = z - 1.0;
    let mut a = C[0];
    let t = z + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (z + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (z + 0.5) * t.ln() - t + a.ln()
}

/// ln(x^a e^-x / Gamma(a)), the prefactor of P and Q. For a >= 10 it is written as
/// -a (u - ln(1 + u)) + (ln a - ln 2 pi) / 2 - S(a), u = (x - a) / a, with S the
/// Stirling series of ln Gamma (Abramowitz & Stegun 6.1.41), so that the large,
/// cancelling terms a ln x, x and ln Gamma(a) never meet: accurate for a of 1e6 and more.
fn ln_prefix(a: f64, x: f64) -> f64 {
    if a < 10.0 {
        return a * x.ln() - x - ln_gamma(a);
    }
    let u = (x - a) / a;
    let u_minus_ln1p = if u.abs() < 0.01 {
        // u - ln(1 + u) = u^2/2 - u^3/3 + u^4/4 - ...
        let mut term = u * u;
        let mut s = 0.0;
        for k in 2..40 {
            let t = term / k as f64;
            s += if k % 2 == 0 { t } else { -t };
            term *= u;
            if t.abs() < 1e-18 * s.abs() {
                break;
            }
        }
        s
    } else {
        u - u.ln_1p()
    };
    let a2 = a * a;
    let stirling =
        (1.0 / 12.0 - (1.0 / 360.0 - (1.0 / 1260.0 - 1.0 / (1680.0 * a2)) / a2) / a2) / a;
    -a * u_minus_ln1p + 0.5 * (a.ln() - (2.0 * std::f64::consts::PI).ln()) - stirling
}

/// Regularized lower incomplete gamma P(a, x), a > 0, x >= 0.
pub fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let ln_pre = ln_prefix(a, x);
    if x < a + 1.0 {
        let mut ap = a;
        let mut del = 1.0 / a;
        let mut sum = del;
        for _ in 0..100_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-17 {
                break;
            }
        }
        (sum * ln_pre.exp()).min(1.0)
    } else {
        // Modified Lentz for the continued fraction of Q(a, x).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..100_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-17 {
                break;
            }
        }
        1.0 - (ln_pre.exp() * h)
    }
}

/// The chi-squared CDF with `dof` degrees of freedom.
pub fn chi2_cdf(x: f64, dof: f64) -> f64 {
    gamma_p(dof / 2.0, x / 2.0)
}

/// The chi-squared quantile: x with chi2_cdf(x, dof) = p, for 0 < p < 1, dof > 0.
pub fn chi2_quantile(p: f64, dof: f64) -> f64 {
    assert!(p > 0.0 && p < 1.0 && dof > 0.0, "chi2_quantile({p}, {dof})");
    let a = dof / 2.0;
    // Wilson-Hilferty start: chi2 ~ k (1 - 2/(9k) + z sqrt(2/(9k)))^3.
    let z = normal_quantile(p);
    let h = 2.0 / (9.0 * dof);
    let mut x = (dof * (1.0 - h + z * h.sqrt()).powi(3)).max(1e-300);
    // Bracket, then Newton with bisection fallback, on g(x) = P(a, x/2) - p.
    let (mut lo, mut hi) = (0.0f64, x.max(1.0));
    while chi2_cdf(hi, dof) < p {
        lo = hi;
        hi *= 2.0;
    }
    if !(x > lo && x < hi) {
        x = 0.5 * (lo + hi);
    }
    for _ in 0..200 {
        let g = chi2_cdf(x, dof) - p;
        if g == 0.0 {
            return x;
        }
        if g < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        // Density of chi2: (x/2)^a e^(-x/2) / (Gamma(a) x).
        let pdf = ln_prefix(a, x / 2.0).exp() / x;
        let mut next = x - g / pdf;
        if !(next > lo && next < hi && next.is_finite()) {
            next = 0.5 * (lo + hi);
        }
        if (next - x).abs() <= 1e-15 * x.abs() || hi - lo <= 1e-15 * hi {
            return next;
        }
        x = next;
    }
    x
}

/// The standard normal quantile by Acklam's rational approximation (about 1e-9
/// relative): only the starting point of [`chi2_quantile`], which Newton then refines.
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let pl = 0.02425;
    if p < pl {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - pl {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -normal_quantile(1.0 - p)
    }
}
