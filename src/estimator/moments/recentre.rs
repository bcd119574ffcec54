//! Moving moments between anchors and scales: the binomial shift of a block of moments
//! in powers of (U - c_src)/s_src to powers of (U - c_dst)/s_dst, the general case and
//! the fixed-degree ones the fits use (the same products in the same order, so the
//! same bits), and the pure rescaling about one anchor.

/// Adds moments `src` (nfam rows of deg + 1, powers of (U - c_src)/s_src) to `acc` as
/// powers 0..=smax of (U - c_dst)/s_dst: with a = s_src/s_dst, b = (c_src - c_dst)/s_dst,
/// ((U - c_dst)/s_dst)^s = sum_i C(s,i) a^i b^(s-i) ((U - c_src)/s_src)^i.
/// With `s_dst = 1` the powers are unscaled, (U - c_dst)^s.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn recentre_into(
    src: &[f64],
    (c_src, s_src): (f64, f64),
    (c_dst, s_dst): (f64, f64),
    nfam: usize,
    d1: usize,
    smax: usize,
    binom: &[[f64; 13]; 13],
    acc: &mut [f64],
) {
    let (a, b) = (s_src / s_dst, (c_src - c_dst) / s_dst);
    match smax {
        2 => recentre_fixed::<3>(src, a, b, recentre_all(nfam), d1, binom, acc),
        5 => recentre_fixed::<6>(src, a, b, recentre_all(nfam), d1, binom, acc),
        6 => recentre_fixed::<7>(src, a, b, recentre_all(nfam), d1, binom, acc),
        10 => recentre_fixed::<11>(src, a, b, recentre_all(nfam), d1, binom, acc),
        _ => {
            let mut sp = [1.0f64; 13];
            let mut dp = [1.0f64; 13];
            for k in 1..=smax {
                sp[k] = sp[k - 1] * a;
                dp[k] = dp[k - 1] * b;
            }
            for f in 0..nfam {
                let mrow = &src[f * d1..(f + 1) * d1];
                let arow = &mut acc[f * d1..(f + 1) * d1];
                for s in 0..=smax {
                    let mut sum = 0.0;
                    for i in 0..=s {
                        sum += binom[s][i] * sp[i] * dp[s - i] * mrow[i];
                    }
                    arow[s] += sum;
                }
            }
        }
    }
}

/// [`recentre_into`] for powers 0..S-1: the coefficient table C(s,i) a^i b^(s-i) built
/// once (same products in the same order as the general case) and shared by every
/// family. `rows` gives (family of `src`, row of `acc`): every family into its own row
/// ([`recentre_all`]), or a subset packed into the first rows of `acc`; a family's
/// sums have the same bits either way.
#[inline]
pub(super) fn recentre_fixed<const S: usize>(
    src: &[f64],
    a: f64,
    b: f64,
    rows: impl Iterator<Item = (usize, usize)>,
    d1: usize,
    binom: &[[f64; 13]; 13],
    acc: &mut [f64],
) {
    let mut sp = [1.0f64; S];
    let mut dp = [1.0f64; S];
    for k in 1..S {
        sp[k] = sp[k - 1] * a;
        dp[k] = dp[k - 1] * b;
    }
    let mut coef = [[0.0f64; S]; S];
    for s in 0..S {
        for i in 0..=s {
            coef[s][i] = binom[s][i] * sp[i] * dp[s - i];
        }
    }
    for (f, r) in rows {
        let mrow: &[f64; S] = src[f * d1..f * d1 + S].try_into().unwrap();
        let arow: &mut [f64; S] = (&mut acc[r * d1..r * d1 + S]).try_into().unwrap();
        for s in 0..S {
            let mut sum = 0.0;
            for i in 0..=s {
                sum += coef[s][i] * mrow[i];
            }
            arow[s] += sum;
        }
    }
}

/// Every family of `nfam` into its own row: the `rows` of [`recentre_fixed`].
fn recentre_all(nfam: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..nfam).map(|f| (f, f))
}

/// Adds `ratio^s` times moments `src` to `acc`: the same samples about the same anchor,
/// powers of (U - c)/s_src rewritten as powers of (U - c)/s_dst, ratio = s_src/s_dst.
#[inline]
pub(super) fn rescale_into(src: &[f64], ratio: f64, nfam: usize, d1: usize, acc: &mut [f64]) {
    let mut rp = [1.0f64; 13];
    for k in 1..d1 {
        rp[k] = rp[k - 1] * ratio;
    }
    for f in 0..nfam {
        for s in 0..d1 {
            acc[f * d1 + s] += rp[s] * src[f * d1 + s];
        }
    }
}
