//! Outliers from spikes: the local second difference s_t = x_t - (x_{t-1} + x_{t+1})/2,
//! spikes where |s_t| exceeds 6 robust standard deviations (1.4826 MAD; on a series
//! whose median |s_t| is 0, a rate on a grid coarser than its noise, the root mean
//! square of the smallest 99 % of |s_t| made consistent for a normal) and is a local
//! maximum; the excess count over the ensemble's gives the rate, and the spikes' sizes
//! give the amplitude distribution and the share detected. Where the noise is higher
//! than the whole training part's, the threshold is its own: each window of
//! [`WINDOW`] samples whose robust sd is more than [`LOUDER`] times the whole's compares
//! |s_t| with 6 (and 4) times its own, so that a noise whose level changes over the log
//! (with temperature, in bursts) is not counted as spikes where it is high. Spikes
//! there between the two thresholds go uncounted, and the fits below read each spike's
//! size as truncated at the threshold it passed, the band's count and the rate's
//! detection share as the means over the samples of each window's thresholds (the
//! exposure); on level noise every threshold is the whole's:
//! - normal amplitudes: the mean square of the spikes, read as a normal sample truncated
//!   at the threshold (E[Z^2 | |Z| > c] = 1 + c phi(c) / Q(c)), gives the scale;
//! - heavy-tailed amplitudes (a Student-t of `dof` degrees of freedom, what spikes of a
//!   test stand mostly are): scale and dof by maximum likelihood of the spikes' sizes
//!   as a sample of |scale T_dof| truncated at the threshold,
//!   sum_i [ln f_dof(a_i / scale) - ln scale] - n ln P(|T_dof| > thr / scale),
//!   profiled over ln dof in [1, 50] and ln scale in [thr / 6, 10 max a_i] by golden
//!   section, tells the forms apart; the t proposed takes its scale and dof from that
//!   likelihood times the Poisson likelihood of the count of smaller local maxima of
//!   |s_t| between 4 and 6 robust sd (the simulations' count there plus the spikes
//!   the fit puts in that band), which pins a scale well below the threshold that the
//!   sizes above it leave open. The t alone is proposed when its likelihood beats the
//!   truncated normal's
//!   (the same likelihood at the moment scale) by the 1 % point of chi2(1), 6.63 in
//!   -2 ln L; below that, too few spikes tell the forms apart by their sizes, and when
//!   the t's dof is inside its range both forms are proposed, for the withheld part's
//!   statistics to choose (16-17 spikes of a t(3) per training part gave 0.5-2.2 in
//!   the bank's two such cases, BENCHMARKS.md).

use std::ops::Range;

use super::lsq::golden_argmin;
use super::params::flag_edge;
use super::{Context, Delta, Found, Proposal, added};
use crate::error::Result;
use crate::simulator::Component;
use crate::stats::special::{normal_cdf, student_t_ln_pdf, student_t_two_sided_tail};

/// How far (in -2 ln L) the Student-t fit of the spikes' sizes must beat the truncated
/// normal's to be kept: the 1 % point of chi2 with one degree of freedom (the t's one
/// extra parameter).
pub const HEAVY_TAIL_MIN_DEVIANCE: f64 = 6.63;

/// outliers: [`estimate_outliers`]; not tried when the training part has fewer than 3
/// spikes more than the simulations (the reason gives both counts).
pub(super) fn outliers(cx: &Context, out: &mut Found) -> Result<()> {
    match estimate_outliers(cx)? {
        Ok(ps) => ps.into_iter().for_each(|p| out.push(p)),
        Err(why) => out.skip("outliers", &why),
    }
    Ok(())
}

/// The spikes' threshold, in robust sd of the second difference.
const THRESHOLD_SD: f64 = 6.0;

/// Robust sd of the second difference below which a local maximum of |s_t| counts in
/// the band that [`student_fit`] reads besides the spikes' sizes: [4, 6) robust sd.
const BAND_SD: f64 = 4.0;

/// The spikes found on a part of a log ([`spikes_at`]).
#[derive(Clone, Debug, Default)]
struct Spikes {
    /// Their sizes |s_t|.
    sizes: Vec<f64>,
    /// The threshold each size passed, as (threshold, count of spikes), each threshold
    /// once.
    passed: Vec<(f64, usize)>,
    /// Local maxima of |s_t| in the band below the threshold.
    band: usize,
    /// Where spikes were looked for: (threshold, samples compared with it), each
    /// threshold once.
    exposure: Vec<(f64, f64)>,
}

impl Spikes {
    /// `other`'s spikes, band and exposure added to these.
    fn extend(&mut self, other: Spikes) {
        self.sizes.extend(other.sizes);
        for (c, k) in other.passed {
            add_to(&mut self.passed, c, k);
        }
        self.band += other.band;
        for (c, n) in other.exposure {
            add_to(&mut self.exposure, c, n);
        }
    }
}

/// `n` added to the entry of threshold `c` in `v`, or a new entry.
fn add_to<N: std::ops::AddAssign>(v: &mut Vec<(f64, N)>, c: f64, n: N) {
    match v.iter_mut().find(|e| e.0 == c) {
        Some(e) => e.1 += n,
        None => v.push((c, n)),
    }
}

/// The spikes of `x` on `ranges` (module doc; [`spikes_at`] at the robust sd of the
/// whole, 1.4826 times the median |s_t|, 0 with no s_t) and that sd.
fn spikes(x: &[f64], ranges: &[Range<usize>]) -> (Spikes, f64) {
    let mut all: Vec<f64> = ranges
        .iter()
        .flat_map(|r| {
            (r.start + 1..r.end.saturating_sub(1))
                .map(move |t| (x[t] - 0.5 * (x[t - 1] + x[t + 1])).abs())
        })
        .collect();
    if all.is_empty() {
        return (Spikes::default(), 0.0);
    }
    let mid = all.len() / 2;
    all.select_nth_unstable_by(mid, f64::total_cmp);
    let mut sd = 1.4826 * all[mid];
    if sd == 0.0 {
        sd = trimmed_sd(&mut all);
    }
    (spikes_at(x, ranges, sd), sd)
}

/// The share of the |s_t| that [`trimmed_sd`] keeps.
const TRIM_KEEP: f64 = 0.99;

/// The root mean square of a normal sample's central [`TRIM_KEEP`] (|z| below its
/// 0.995 quantile 2.5758), over its sd: sqrt((p - 2 z phi(z)) / p) at p = 0.99,
/// z = 2.5758, phi(z) = 0.014460.
const TRIMMED_RMS_OF_NORMAL: f64 = 0.961_642;

/// The sd of the s_t from the smallest [`TRIM_KEEP`] of their sizes `abs_s` (reordered),
/// made consistent for normal s_t ([`TRIMMED_RMS_OF_NORMAL`]), for a series whose median
/// |s_t| is 0: the samples of a rate on a grid coarser than its noise mostly repeat their
/// neighbours, so that the median reads 0 and every step would pass 6 times it. 0 when
/// they are all 0.
fn trimmed_sd(abs_s: &mut [f64]) -> f64 {
    let keep = ((TRIM_KEEP * abs_s.len() as f64).ceil() as usize).clamp(1, abs_s.len());
    if keep < abs_s.len() {
        abs_s.select_nth_unstable_by(keep, f64::total_cmp);
    }
    let ms = abs_s[..keep].iter().map(|a| a * a).sum::<f64>() / keep as f64;
    ms.sqrt() / TRIMMED_RMS_OF_NORMAL
}

/// Samples of the windows whose own robust sd can set the thresholds ([`spikes_at`]):
/// the median of 2048 |s_t| estimates their sd within about 2.6 % (the sample median's
/// standard error, 1.166 / sqrt(n) of the half-normal's median).
const WINDOW: usize = 2048;

/// How much louder than the whole training part's a window's robust sd must be for
/// [`spikes_at`] to take it: 4 of its standard errors (2.6 % each at [`WINDOW`]
/// samples) above, so that on level noise no window moves the thresholds.
const LOUDER: f64 = 1.1;

/// The windows of range `r` whose second differences [`spikes_at`] reads: `WINDOW`
/// samples each from `r.start`, the last one taking a rest shorter than half a window.
fn windows(r: &Range<usize>) -> Vec<Range<usize>> {
    let mut w: Vec<Range<usize>> = (r.start..r.end)
        .step_by(WINDOW)
        .map(|a| a..(a + WINDOW).min(r.end))
        .collect();
    if w.len() > 1 && w[w.len() - 1].len() < WINDOW / 2 {
        let last = w.pop().map_or(0, |l| l.end);
        if let Some(prev) = w.last_mut() {
            prev.end = last;
        }
    }
    w
}

/// The spikes of `x` on `ranges` and the count of local maxima in the band below them
/// ([`spikes`]) at the robust sd `sd` of the whole: in each window of a range
/// ([`windows`]), |s_t| is compared with 6 and 4 times sd, or times sd_w where sd_w >
/// [`LOUDER`] sd, sd_w the window's robust sd (of its s_t with both neighbours inside
/// the range). A local maximum is one of |s_t| among its neighbours; the sizes are
/// |s_t|, each with the threshold it passed, and each window's samples count in the
/// exposure at its threshold.
fn spikes_at(x: &[f64], ranges: &[Range<usize>], sd: f64) -> Spikes {
    let s_at = |t: usize| x[t] - 0.5 * (x[t - 1] + x[t + 1]);
    let mut found = Spikes::default();
    let mut abs_s: Vec<f64> = Vec::with_capacity(WINDOW + WINDOW / 2);
    for r in ranges {
        for w in windows(r) {
            abs_s.clear();
            abs_s.extend(
                (w.start.max(r.start + 1)..w.end.min(r.end.saturating_sub(1)))
                    .map(|t| s_at(t).abs()),
            );
            let sd_w = if abs_s.is_empty() {
                0.0
            } else {
                let mid = abs_s.len() / 2;
                abs_s.select_nth_unstable_by(mid, f64::total_cmp);
                1.4826 * abs_s[mid]
            };
            // the window's own sd only where its noise is louder than its sampling
            // error allows: on level noise the thresholds stay the whole's
            let sd_here = if sd_w > LOUDER * sd { sd_w } else { sd };
            let thr = THRESHOLD_SD * sd_here;
            let band_lo = BAND_SD * sd_here;
            let (mut above, mut seen) = (0, 0.0);
            for t in w.start.max(r.start + 2)..w.end.min(r.end.saturating_sub(2)) {
                seen += 1.0;
                let a = s_at(t).abs();
                if a > band_lo && a >= s_at(t - 1).abs() && a >= s_at(t + 1).abs() {
                    if a > thr {
                        found.sizes.push(a);
                        above += 1;
                    } else {
                        found.band += 1;
                    }
                }
            }
            if above > 0 {
                add_to(&mut found.passed, thr, above);
            }
            if seen > 0.0 {
                add_to(&mut found.exposure, thr, seen);
            }
        }
    }
    found
}

/// The number of spikes of `x` on `ranges` and of local maxima in the band below
/// them ([`spikes`]).
fn spike_count(x: &[f64], ranges: &[Range<usize>]) -> (usize, usize) {
    let (found, _) = spikes(x, ranges);
    (found.sizes.len(), found.band)
}

/// P(|W| > c), W a Student-t of `dof` degrees of freedom (None: standard normal).
fn two_sided_tail(c: f64, dof: Option<f64>) -> f64 {
    match dof {
        Some(nu) => student_t_two_sided_tail(c, nu),
        None => 2.0 * normal_tail(c),
    }
}

/// The share of spikes |scale W| that pass the thresholds of `exposure` (each times
/// `factor`), over its samples: sum_w n_w P(|W| > factor c_w / scale) / sum_w n_w.
fn share_above(exposure: &[(f64, f64)], factor: f64, scale: f64, dof: Option<f64>) -> f64 {
    let n: f64 = exposure.iter().map(|e| e.1).sum();
    exposure
        .iter()
        .map(|&(c, k)| k * two_sided_tail(factor * c / scale, dof))
        .sum::<f64>()
        / n.max(f64::MIN_POSITIVE)
}

/// ln L of the sizes `a` as |scale W| each truncated at the threshold it passed
/// (`passed`: (threshold, count of sizes) pairs), W a Student-t of `dof` degrees of
/// freedom (None: standard normal):
/// sum_i [ln 2 f(a_i / scale) - ln scale - ln P(|W| > c_i / scale)].
fn truncated_ln_l(a: &[f64], passed: &[(f64, usize)], scale: f64, dof: Option<f64>) -> f64 {
    let n = a.len() as f64;
    // ln W's density at each a_i / scale, less its value at 0 (the normalising
    // constant, taken once)
    let (sum_shape, ln_f0) = match dof {
        Some(nu) => (
            a.iter()
                .map(|&v| -0.5 * (nu + 1.0) * ((v / scale).powi(2) / nu).ln_1p())
                .sum::<f64>(),
            student_t_ln_pdf(0.0, nu),
        ),
        None => (
            a.iter().map(|&v| -0.5 * (v / scale).powi(2)).sum::<f64>(),
            -0.5 * (2.0 * std::f64::consts::PI).ln(),
        ),
    };
    let ln_tails: f64 = passed
        .iter()
        .map(|&(c, k)| k as f64 * two_sided_tail(c / scale, dof).max(1e-300).ln())
        .sum();
    // |W| has twice W's density on a > 0
    n * (std::f64::consts::LN_2 + ln_f0 - scale.ln()) + sum_shape - ln_tails
}

/// The ends of the search range of [`student_fit`]'s dof.
const DOF_RANGE: [f64; 2] = [1.0, 50.0];

/// The count of local maxima of |s_t| in the band [`BAND_SD`] .. 6 robust sd below
/// the spikes: `observed` in the real log's training part, `noise` the simulations'
/// mean, `excess` the spikes above the threshold less the simulations' mean.
#[derive(Clone, Copy, Debug)]
struct Band {
    observed: f64,
    noise: f64,
    excess: f64,
}

impl Band {
    /// ln L of the band's count (a Poisson count, constants dropped) when the spikes
    /// are |scale T_dof|, `excess` of them lie above their thresholds, and `exposure`
    /// says where they were looked for: at r spikes per sample,
    /// r sum_w n_w P(|T| > c_w / scale) = excess, and those in the band add
    /// excess (sum_w n_w P(|T| > b_w / scale) / sum_w n_w P(|T| > c_w / scale) - 1),
    /// b_w = c_w BAND_SD / 6, to the simulations' count: lambda = noise + that,
    /// ln L = observed ln lambda - lambda.
    fn ln_l(&self, exposure: &[(f64, f64)], scale: f64, nu: f64) -> f64 {
        let p_thr = share_above(exposure, 1.0, scale, Some(nu)).max(1e-300);
        let p_band = share_above(exposure, BAND_SD / THRESHOLD_SD, scale, Some(nu));
        let lambda = (self.noise + self.excess * (p_band / p_thr - 1.0)).max(1e-9);
        self.observed * lambda.ln() - lambda
    }
}

/// The Student-t fit of the sizes `a`, each above the threshold it passed (`passed`,
/// [`truncated_ln_l`]), looked for over `exposure` (module doc): (scale, dof, ln L of
/// the sizes, the scale's search range, from a sixth of the lowest threshold). With
/// `band`, the likelihood maximized is the
/// sizes' times the band count's ([`Band::ln_l`]): the sizes above the threshold alone
/// say little about a scale well below it (their law tends to a Pareto's of index dof
/// as the scale falls, so a few spikes can fit a tiny scale and a count of undetected
/// spikes many times theirs), the count of smaller spikes in the band does.
fn student_fit(
    a: &[f64],
    passed: &[(f64, usize)],
    exposure: &[(f64, f64)],
    band: Option<Band>,
) -> (f64, f64, f64, [f64; 2]) {
    let thr = passed
        .iter()
        .map(|e| e.0)
        .chain(exposure.iter().map(|e| e.0))
        .fold(f64::INFINITY, f64::min);
    let a_max = a.iter().copied().fold(thr, f64::max);
    let (s_lo, s_hi) = ((thr / 6.0).ln(), (10.0 * a_max).ln());
    let neg_ln_l = |scale: f64, nu: f64| {
        -truncated_ln_l(a, passed, scale, Some(nu))
            - band.map_or(0.0, |b| b.ln_l(exposure, scale, nu))
    };
    let best_scale = |nu: f64| golden_argmin(s_lo, s_hi, 60, |u| neg_ln_l(u.exp(), nu));
    let (v, _) = golden_argmin(DOF_RANGE[0].ln(), DOF_RANGE[1].ln(), 40, |v| {
        best_scale(v.exp()).1
    });
    let nu = v.exp();
    let (u, _) = best_scale(nu);
    let ln_l = truncated_ln_l(a, passed, u.exp(), Some(nu));
    (u.exp(), nu, ln_l, [s_lo.exp(), s_hi.exp()])
}

/// The scale of the sizes `a` as |scale Z|, Z standard normal, each truncated at the
/// threshold it passed (`passed`, [`truncated_ln_l`]), by maximum likelihood: the
/// score equation of [`truncated_ln_l`] in the scale is
/// mean_i a_i^2 = scale^2 (1 + mean_i c_i phi(c_i) / Q(c_i)), c_i = thr_i / scale
/// (E[Z^2 | |Z| > c] = 1 + c phi(c) / Q(c) for one threshold), solved by bisection on
/// ln scale.
fn normal_fit(a: &[f64], passed: &[(f64, usize)]) -> f64 {
    let n = a.len().max(1) as f64;
    let m2 = a.iter().map(|s| s * s).sum::<f64>() / n;
    let (thr_lo, thr_hi) = passed.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), e| {
        (lo.min(e.0), hi.max(e.0))
    });
    let f = |scale: f64| {
        let mills = passed
            .iter()
            .map(|&(c, k)| {
                let c = c / scale;
                let phi = (-0.5 * c * c).exp() / (2.0 * std::f64::consts::PI).sqrt();
                k as f64 * c * phi / normal_tail(c).max(1e-300)
            })
            .sum::<f64>()
            / n;
        scale * scale * (1.0 + mills) - m2
    };
    let (mut lo, mut hi) = ((thr_lo * 1e-3).ln(), (m2.sqrt() * 10.0).max(thr_hi).ln());
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f(mid.exp()) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    (0.5 * (lo + hi)).exp()
}

/// Upper tail of the standard normal, Q(c) = 1 - Phi(c) = Phi(-c).
fn normal_tail(c: f64) -> f64 {
    normal_cdf(-c)
}

/// The outliers proposals (one per amplitude form offered), or why there is none
/// (fewer than 3 spikes more than the simulations': the two counts).
fn estimate_outliers(cx: &Context) -> Result<std::result::Result<Vec<Proposal>, String>> {
    let ranges = cx.ranges();
    let (mut found, sd) = spikes(cx.real, ranges);
    let thr = THRESHOLD_SD * sd;
    let (sum_spikes, sum_band) = cx
        .target
        .iter()
        .map(|t| spike_count(t, ranges))
        .fold((0, 0), |(a, b), (c, d)| (a + c, b + d));
    let m = cx.target.len() as f64;
    let (mut c_ens, mut band_ens) = (sum_spikes as f64 / m, sum_band as f64 / m);
    // the samples after the excerpt train too: their spikes at the training part's
    // robust sd, and the simulations' counts per training sample over their length
    let mut t_train = cx.n_train() as f64 / cx.rate_hz();
    let mut after = String::new();
    if cx.beyond.len() > 4 && sd > 0.0 && cx.n_train() > 0 {
        let whole = 0..cx.beyond.len();
        let b = spikes_at(cx.beyond, std::slice::from_ref(&whole), sd);
        let per = cx.beyond.len() as f64 / cx.n_train() as f64;
        after = format!(
            "; of these, {} spikes and {} local maxima in the band in the {} samples after the excerpt, which train only, against {:.1} and {:.1}",
            b.sizes.len(),
            b.band,
            cx.beyond.len(),
            c_ens * per,
            band_ens * per
        );
        c_ens *= 1.0 + per;
        band_ens *= 1.0 + per;
        found.extend(b);
        t_train += cx.beyond.len() as f64 / cx.rate_hz();
    }
    let Spikes {
        sizes,
        passed,
        band: band_real,
        exposure,
    } = found;
    let c_real = sizes.len();
    let excess = c_real as f64 - c_ens;
    if excess < 3.0 || c_real == 0 || thr <= 0.0 {
        return Ok(Err(format!(
            "no more spikes in the training part than in the simulations ({c_real} above 6 \
             robust sd against {c_ens:.1}{after})"
        )));
    }
    let scale_normal = normal_fit(&sizes, &passed);
    let ln_l_normal = truncated_ln_l(&sizes, &passed, scale_normal, None);
    // the form by the sizes alone, the t's scale and dof with the band's count
    let (_, _, ln_l_t, _) = student_fit(&sizes, &passed, &exposure, None);
    let deviance = 2.0 * (ln_l_t - ln_l_normal);
    let heavy = deviance > HEAVY_TAIL_MIN_DEVIANCE;
    let band = Band {
        observed: band_real as f64,
        noise: band_ens,
        excess,
    };
    let (scale_t, dof_t, _, scale_range) = student_fit(&sizes, &passed, &exposure, Some(band));
    let counts = format!(
        "{c_real} spikes above 6 robust sd in the training part against {c_ens:.1} in the \
         simulations ({band_real} against {band_ens:.1} local maxima between {BAND_SD} and 6 robust sd{after})"
    );
    // the proposal of one amplitude form: the rate from the excess count and the
    // share of spikes of that form above the threshold
    let make = |scale: f64, dof: Option<f64>, note: String| -> Result<Proposal> {
        let p_detect = share_above(&exposure, 1.0, scale, dof).max(1e-6);
        let rate_hz = (excess / (t_train * p_detect)).min(cx.rate_hz());
        let comp = Component::Outliers {
            rate_hz,
            scale,
            dof,
        };
        let u = cx.sim.extra_signal(cx.spec, cx.channel, &comp)?;
        let mut p = added("outliers", comp, Delta::Each(u), note);
        if dof.is_some() {
            let [lo, hi] = scale_range;
            flag_edge(&mut p.params, &mut p.note, "scale", scale_t, lo, hi);
            let [lo, hi] = DOF_RANGE;
            flag_edge(&mut p.params, &mut p.note, "dof", dof_t, lo, hi);
        }
        Ok(p)
    };
    let t_note = |how: &str| {
        format!(
            "{counts}; {how}: Student-t of {} degrees of freedom (-2 ln L {} below the truncated normal's)",
            crate::fmt::num(dof_t),
            crate::fmt::num(deviance)
        )
    };
    if heavy {
        return Ok(Ok(vec![make(
            scale_t,
            Some(dof_t),
            t_note("their sizes are heavy-tailed"),
        )?]));
    }
    let mut out = vec![make(
        scale_normal,
        None,
        format!("{counts}; their sizes fit a truncated normal"),
    )?];
    // too few spikes to tell the forms apart by their sizes, but a t inside its range
    // of dof: both are offered, and the withheld part's spikes choose
    if dof_t < 0.99 * DOF_RANGE[1] {
        out.push(make(
            scale_t,
            Some(dof_t),
            t_note("too few to tell a t from a normal by their sizes; the t offered beside it"),
        )?);
    }
    Ok(Ok(out))
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal, StudentT};

    use super::*;

    /// The sizes above `thr` of `n` draws of |scale W|.
    fn sizes(n: usize, scale: f64, thr: f64, w: impl Fn(&mut ChaCha8Rng) -> f64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        (0..n)
            .map(|_| (scale * w(&mut rng)).abs())
            .filter(|a| *a > thr)
            .collect()
    }

    /// White noise of sd 1 on the first half and `high` on the second, with a spike of
    /// `size` (sign alternating) every 997 samples from sample 500.
    fn noise_with_spikes(n: usize, high: f64, size: f64) -> (Vec<f64>, usize) {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut x: Vec<f64> = (0..n)
            .map(|t| {
                let w: f64 = StandardNormal.sample(&mut rng);
                if t < n / 2 { w } else { high * w }
            })
            .collect();
        let mut k = 0;
        for (i, t) in (500..n - 500).step_by(997).enumerate() {
            x[t] += if i % 2 == 0 { size } else { -size };
            k += 1;
        }
        (x, k)
    }

    /// The local maxima of |s_t| on `ranges` above `thr`, at every sample a window reads.
    fn above_whole(x: &[f64], ranges: &[Range<usize>], thr: f64) -> usize {
        let s = |t: usize| (x[t] - 0.5 * (x[t - 1] + x[t + 1])).abs();
        ranges
            .iter()
            .flat_map(|r| r.start + 2..r.end - 2)
            .filter(|&t| s(t) > thr && s(t) >= s(t - 1) && s(t) >= s(t + 1))
            .count()
    }

    #[test]
    fn a_noise_level_that_changes_over_the_log_is_not_counted_as_spikes() {
        // noise 4 times higher on the second half: 6 robust sd of the whole are about
        // 3 sd of the louder half's noise, which passes them hundreds of times; spikes
        // of 80 (16 sd of the louder half) are found in both halves and nothing else
        let n = 200_000;
        let (x, k) = noise_with_spikes(n, 4.0, 80.0);
        let ranges = [0..n / 3, n / 3..n];
        let (found, sd) = spikes(&x, &ranges);
        let sizes = found.sizes;
        assert!(sd > 1.0 && sd < 4.0, "robust sd of the whole {sd}");
        assert_eq!(sizes.len(), k);
        assert!(
            sizes.iter().all(|&a| a > 60.0),
            "a noise sample counted: {sizes:?}"
        );
        // the threshold of the whole alone counts the louder half's noise
        let whole = above_whole(&x, &ranges, THRESHOLD_SD * sd);
        assert!(
            whole > 2 * k,
            "{whole} above the whole's threshold, {k} spikes"
        );
    }

    #[test]
    fn on_level_noise_the_windows_thresholds_are_the_wholes() {
        // spikes of 8 (|s_t| near the threshold 6 x 1.22) on level noise: no window is
        // louder than its sampling error allows, so the spikes are exactly those above
        // the whole's threshold
        let n = 300_000;
        let (x, _) = noise_with_spikes(n, 1.0, 8.0);
        let whole_log = 0..n;
        let ranges = std::slice::from_ref(&whole_log);
        let (found, sd) = spikes(&x, ranges);
        let sizes = found.sizes;
        assert!((sd / 1.2247 - 1.0).abs() < 0.02, "robust sd {sd}");
        let whole = above_whole(&x, ranges, THRESHOLD_SD * sd);
        assert!(whole > 100, "{whole} spikes");
        assert_eq!(sizes.len(), whole);
    }

    #[test]
    fn the_windows_cover_a_range_and_the_last_takes_a_short_rest() {
        assert_eq!(
            windows(&(10..10 + 2 * WINDOW + 100)),
            vec![10..10 + WINDOW, 10 + WINDOW..10 + 2 * WINDOW + 100]
        );
        assert_eq!(
            windows(&(0..2 * WINDOW + WINDOW / 2)),
            vec![
                0..WINDOW,
                WINDOW..2 * WINDOW,
                2 * WINDOW..2 * WINDOW + WINDOW / 2
            ]
        );
        assert_eq!(windows(&(5..105)), vec![5..105]);
        assert!(windows(&(7..7)).is_empty());
    }

    #[test]
    fn heavy_tailed_spike_sizes_are_told_from_normal_ones_and_their_dof_found() {
        let thr = 1.0;
        // Student-t of 2 degrees of freedom, scale 1.5: about 600 of 1000 above thr
        let t2 = StudentT::new(2.0).unwrap();
        let a = sizes(1000, 1.5, thr, |r| t2.sample(r));
        let level = |a: &[f64]| [(thr, a.len())];
        let (scale, dof, ln_l_t, [s_lo, s_hi]) = student_fit(&a, &level(&a), &[(thr, 1.0)], None);
        // inside both search ranges
        assert!(scale > 1.01 * s_lo && scale < 0.99 * s_hi, "scale {scale}");
        assert!(dof > 1.01 && dof < 49.0, "dof {dof}");
        assert!((dof / 2.0).ln().abs() < 0.35, "dof {dof}");
        assert!((scale / 1.5).ln().abs() < 0.25, "scale {scale}");
        // the truncated normal at its best scale (a grid fine enough for the test) is far worse
        let ln_l_n = (1..400)
            .map(|i| truncated_ln_l(&a, &level(&a), 0.05 * i as f64, None))
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(2.0 * (ln_l_t - ln_l_n) > HEAVY_TAIL_MIN_DEVIANCE);
        // normal sizes: the t adds almost nothing (its dof runs to the top of the range)
        let b = sizes(2000, 1.5, thr, |r| StandardNormal.sample(r));
        let (_, dof_b, ln_l_tb, _) = student_fit(&b, &level(&b), &[(thr, 1.0)], None);
        let ln_l_nb = (1..400)
            .map(|i| truncated_ln_l(&b, &level(&b), 0.05 * i as f64, None))
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(
            2.0 * (ln_l_tb - ln_l_nb) < HEAVY_TAIL_MIN_DEVIANCE,
            "dof {dof_b}"
        );
        assert!(dof_b > 10.0, "dof {dof_b}");
    }

    #[test]
    fn the_band_below_the_threshold_pins_the_count_of_spikes_the_sizes_alone_leave_open() {
        // about 20 spikes of |8 T_3| above a threshold of 6 (noise sd 1) per draw, 45
        // draws: the number of spikes implied by each fit, (spikes above) / P(|scale
        // T_dof| > thr), against the truth
        let (thr, scale, n_true) = (6.0, 8.0, 40.0);
        let t3 = StudentT::new(3.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let poisson = rand_distr::Poisson::new(n_true).unwrap();
        let noise = rand_distr::Poisson::new(0.3).unwrap();
        let (mut err_sizes, mut err_band) = (Vec::new(), Vec::new());
        for _ in 0..45 {
            let k: f64 = poisson.sample(&mut rng);
            let k = k as usize;
            let amps: Vec<f64> = (0..k)
                .map(|_| {
                    let w: f64 = t3.sample(&mut rng);
                    (scale * w).abs()
                })
                .collect();
            let above: Vec<f64> = amps.iter().copied().filter(|&a| a > thr).collect();
            let in_band = amps
                .iter()
                .filter(|&&a| a > thr * BAND_SD / 6.0 && a <= thr)
                .count() as f64
                + {
                    let z: f64 = noise.sample(&mut rng);
                    z
                };
            let band = Band {
                observed: in_band,
                noise: 0.3,
                excess: above.len() as f64,
            };
            let implied =
                |(s, nu): (f64, f64)| above.len() as f64 / student_t_two_sided_tail(thr / s, nu);
            let passed = [(thr, above.len())];
            let (s0, nu0, _, _) = student_fit(&above, &passed, &[(thr, 1.0)], None);
            let (s1, nu1, _, _) = student_fit(&above, &passed, &[(thr, 1.0)], Some(band));
            err_sizes.push((implied((s0, nu0)) / n_true).ln().abs());
            err_band.push((implied((s1, nu1)) / n_true).ln().abs());
        }
        // the median error and the mean of the five largest (the fits that run off
        // to a small scale and many undetected spikes)
        let summary = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            (v[v.len() / 2], v[v.len() - 5..].iter().sum::<f64>() / 5.0)
        };
        let (m0, w0) = summary(&mut err_sizes);
        let (m1, w1) = summary(&mut err_band);
        assert!(
            m1 <= m0 && m1 < 0.25,
            "median |ln ratio|: band {m1}, sizes alone {m0}"
        );
        assert!(w1 < 0.75 * w0, "worst five: band {w1}, sizes alone {w0}");
    }

    #[test]
    fn sizes_each_truncated_at_their_own_threshold_give_the_scale_and_the_form() {
        // |8 Z| above 4 in quiet windows and above 12 in loud ones (a noise three
        // times louder there), 2000 draws in each: the likelihood with each size's own
        // threshold recovers the scale, and is the sum of the two groups' likelihoods;
        // read as one sample truncated at the lower threshold it does not
        let (scale, quiet, loud) = (8.0, 4.0, 12.0);
        let z = |r: &mut ChaCha8Rng| -> f64 { StandardNormal.sample(r) };
        let a_quiet = sizes(2000, scale, quiet, z);
        let mut rng = ChaCha8Rng::seed_from_u64(29);
        let a_loud: Vec<f64> = (0..2000)
            .map(|_| (scale * z(&mut rng)).abs())
            .filter(|&a| a > loud)
            .collect();
        let passed = [(quiet, a_quiet.len()), (loud, a_loud.len())];
        let all: Vec<f64> = a_quiet.iter().chain(&a_loud).copied().collect();
        let s = normal_fit(&all, &passed);
        assert!((s / scale - 1.0).abs() < 0.05, "scale {s} for {scale}");
        let one = normal_fit(&all, &[(quiet, all.len())]);
        assert!(one / scale > 1.1, "one threshold: scale {one} for {scale}");
        // the ML's score is 0 there: the likelihood is lower on either side
        let ln_l = |v: f64| truncated_ln_l(&all, &passed, v, None);
        assert!(ln_l(s) > ln_l(0.98 * s) && ln_l(s) > ln_l(1.02 * s));
        let split = truncated_ln_l(&a_quiet, &[(quiet, a_quiet.len())], s, Some(4.0))
            + truncated_ln_l(&a_loud, &[(loud, a_loud.len())], s, Some(4.0));
        let joint = truncated_ln_l(&all, &passed, s, Some(4.0));
        assert!(
            (joint - split).abs() < 1e-9 * split.abs(),
            "{joint} {split}"
        );
        // the share detected over the exposure is the samples' mean of the tails
        let exposure = [(quiet, 3.0), (loud, 1.0)];
        let share = share_above(&exposure, 1.0, scale, None);
        let want = 0.75 * 2.0 * normal_tail(0.5) + 0.25 * 2.0 * normal_tail(1.5);
        assert!((share - want).abs() < 1e-12, "{share} {want}");
    }

    #[test]
    fn a_rate_on_a_coarse_grid_has_a_threshold_and_its_spikes_are_found() {
        // noise of sd 0.3 rounded to a grid of 1: most samples repeat their neighbours,
        // the median |s_t| is 0, and spikes of 12 are the only |s_t| past 6 times the
        // trimmed sd (about 0.45 from the rounding's 1 / sqrt(12) and the noise)
        let n = 50_000;
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut x: Vec<f64> = (0..n)
            .map(|_| {
                let w: f64 = StandardNormal.sample(&mut rng);
                (0.3 * w).round()
            })
            .collect();
        let mut k = 0;
        for t in (300..n - 300).step_by(1231) {
            x[t] += 12.0;
            k += 1;
        }
        let whole = 0..n;
        let (found, sd) = spikes(&x, std::slice::from_ref(&whole));
        assert!(sd > 0.2 && sd < 1.0, "sd {sd}");
        assert_eq!(found.sizes.len(), k);
        // normal s_t: the trimmed sd is their sd
        let mut z: Vec<f64> = (0..200_000)
            .map(|_| {
                let w: f64 = StandardNormal.sample(&mut rng);
                (2.0 * w).abs()
            })
            .collect();
        let s = trimmed_sd(&mut z);
        assert!((s / 2.0 - 1.0).abs() < 0.01, "trimmed sd {s}");
    }

    #[test]
    fn the_truncated_likelihood_is_a_density_on_the_sizes_above_the_threshold() {
        // integral over a > thr of exp(ln L({a})) = 1, for the normal and a t
        for dof in [None, Some(3.0)] {
            let (thr, scale, h) = (0.8, 1.3, 1e-3);
            let area: f64 = (0..200_000)
                .map(|i| {
                    let a = thr + (i as f64 + 0.5) * h;
                    h * truncated_ln_l(&[a], &[(thr, 1)], scale, dof).exp()
                })
                .sum();
            let rest = dof.map_or(0.0, |nu| {
                student_t_two_sided_tail((thr + 200.0) / scale, nu)
                    / student_t_two_sided_tail(thr / scale, nu)
            });
            assert!((area + rest - 1.0).abs() < 1e-4, "{dof:?}: {area} + {rest}");
        }
    }
}
