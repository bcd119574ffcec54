//! Deterministic additions (constant_bias, rate_ramp, warmup, sinusoid): least squares
//! of the training residual r_t = x_t - xbar_t on the effect's own signal, simulated
//! with a unit parameter, plus an intercept.

use std::ops::Range;

use rayon::prelude::*;

use super::lsq::{golden_min, log_grid, ls_w};
use super::params::flag_edge;
use super::{Context, Found, Training};
use crate::error::Result;
use crate::simulator::Component;

/// constant_bias: the mean of the training residual.
pub(super) fn constant_bias(cx: &Context, tr: &Training, out: &mut Found) {
    let (res, ranges, n) = (&tr.res, &tr.ranges, tr.n);
    let v = match tr.w() {
        None => {
            let s: f64 = ranges
                .iter()
                .map(|r| res[r.clone()].iter().sum::<f64>())
                .sum();
            s / cx.n_train() as f64
        }
        // the weighted mean, sum w r / sum w
        Some(w) => {
            let (swr, sw) = ranges
                .iter()
                .flat_map(|r| r.clone())
                .fold((0.0, 0.0), |(a, b), t| (a + w[t] * res[t], b + w[t]));
            if sw > 0.0 { swr / sw } else { 0.0 }
        }
    };
    let c = Component::ConstantBias { value: v };
    out.same(
        "constant_bias",
        c,
        vec![v; n],
        "mean of the training residual".into(),
    );
}

/// rate_ramp: the least-squares slope of the training residual on time.
pub(super) fn rate_ramp(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let (res, ranges) = (&tr.res, &tr.ranges);
    let u = cx.unit(Component::RateRamp { r: 1.0 })?;
    if let Some((b, _)) = ls_w(res, &tr.regs(&[&u]), true, ranges, tr.w()) {
        let sig: Vec<f64> = u.iter().map(|v| v * b[0]).collect();
        out.same(
            "rate_ramp",
            Component::RateRamp { r: b[0] },
            sig,
            "least-squares slope of the training residual on time".into(),
        );
    }
    Ok(())
}

/// warmup: the amplitude by least squares for each of a log grid of 24 time constants,
/// the best by residual sum of squares, refined by golden-section search on ln(tau)
/// between its grid neighbours.
pub(super) fn warmup(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let (res, ranges, fs, duration_s) = (&tr.res, &tr.ranges, tr.fs, tr.duration_s);
    let rss_at = |tau: f64| -> Result<Option<(f64, f64, Vec<f64>)>> {
        let u = cx.unit(Component::Warmup {
            amplitude: 1.0,
            tau_s: tau,
        })?;
        Ok(ls_w(res, &tr.regs(&[&u]), true, ranges, tr.w()).map(|(b, rss)| (b[0], rss, u)))
    };
    let grid = log_grid(5.0 / fs.min(1.0), duration_s / 2.0, 24);
    // the grid's fits in parallel (each keeps only its RSS), the best chosen in order
    let rss: Vec<Option<f64>> = grid
        .par_iter()
        .map(|&tau| Ok(rss_at(tau)?.map(|(_, rss, _)| rss)))
        .collect::<Result<_>>()?;
    let mut best: Option<(usize, f64)> = None;
    for (i, rss) in rss.into_iter().enumerate() {
        if let Some(rss) = rss
            && best.is_none_or(|x| rss < x.1)
        {
            best = Some((i, rss));
        }
    }
    // refine ln(tau) between the grid neighbours of the best point
    let refined = match best {
        Some((i, _)) => {
            let lo = grid[i.saturating_sub(1)].ln();
            let hi = grid[(i + 1).min(grid.len() - 1)].ln();
            let ln_tau = golden_min(lo, hi, 30, |v| {
                rss_at(v.exp())
                    .ok()
                    .flatten()
                    .map_or(f64::INFINITY, |x| x.1)
            });
            let tau = ln_tau.exp();
            rss_at(tau)?.map(|(a, _, u)| (a, tau, u))
        }
        None => None,
    };
    if let Some((a, tau, u)) = refined {
        let sig: Vec<f64> = u.iter().map(|v| v * a).collect();
        let mut p = super::same(
            "warmup",
            Component::Warmup {
                amplitude: a,
                tau_s: tau,
            },
            sig,
            "least squares over a log grid of 24 time constants, refined by golden section".into(),
        );
        flag_edge(
            &mut p.params,
            &mut p.note,
            "tau_s",
            tau,
            grid[0],
            grid[grid.len() - 1],
        );
        out.push(p);
    }
    Ok(())
}

/// sinusoid: the largest peak of the training periodogram, refined by least squares
/// ([`find_sinusoid`]); not tried when there is no peak.
pub(super) fn sinusoid(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    if let Some(line) = tr.line() {
        // the line is the output's; the component goes in before the output filter,
        // whose gain and phase at the line's frequency it must undo
        let (gain, shift_rad) = cx
            .filter_response(line.freq_hz)
            .filter(|&(g, _)| g > MIN_FILTER_GAIN)
            .unwrap_or((1.0, 0.0));
        let c = Component::Sinusoid {
            amplitude: line.amplitude / gain,
            freq_hz: line.freq_hz,
            phase_rad: wrap_rad(line.phase_rad - shift_rad),
        };
        let sig = cx.unit(c.clone())?;
        let mut note =
            String::from("largest peak of the training periodogram, refined by least squares");
        if gain != 1.0 || shift_rad != 0.0 {
            note += &format!(
                "; before the output filter, whose gain {gain:.4} and phase {shift_rad:.4} rad at {:.6} Hz it undoes",
                line.freq_hz
            );
        }
        out.same("sinusoid", c, sig, note);
    } else {
        out.skip("sinusoid", "no periodogram peak in the training residual");
    }
    Ok(())
}

/// The least gain of the output filter at a line's frequency that [`sinusoid`] undoes:
/// below it the line the output shows would need an input more than 20 times its size.
const MIN_FILTER_GAIN: f64 = 0.05;

/// `phi` in (-pi, pi].
fn wrap_rad(phi: f64) -> f64 {
    use std::f64::consts::PI;
    let w = phi.rem_euclid(2.0 * PI);
    if w > PI { w - 2.0 * PI } else { w }
}

/// Bins of a group of the running median in [`whitened_peak`].
const MEDIAN_GROUP: usize = 32;

/// The bin in [k0, k1) of periodogram `pw` with the largest power relative to the
/// background around it, and that ratio: the median of the bins of its group of [`MEDIAN_GROUP`] and
/// of the two neighbouring groups (a running median, robust to the line itself and to
/// the side lobes of the training mask). A line stands out of a coloured background
/// this way, where the raw largest bin is the background's low-frequency end (a
/// Gauss-Markov's red spectrum beside a sinusoid). None when the range is empty.
fn whitened_peak(pw: &[f64], k0: usize, k1: usize) -> Option<(usize, f64)> {
    if k1 <= k0 {
        return None;
    }
    let n_groups = (k1 - k0).div_ceil(MEDIAN_GROUP);
    let group = |g: usize| k0 + g * MEDIAN_GROUP..(k0 + (g + 1) * MEDIAN_GROUP).min(k1);
    let medians: Vec<f64> = (0..n_groups)
        .map(|g| {
            let mut v: Vec<f64> = (g.saturating_sub(1)..(g + 2).min(n_groups))
                .flat_map(|h| pw[group(h)].iter().copied())
                .collect();
            let mid = v.len() / 2;
            v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
            v[mid]
        })
        .collect();
    (k0..k1)
        .map(|k| {
            let m = medians[(k - k0) / MEDIAN_GROUP];
            (k, pw[k] / m.max(f64::MIN_POSITIVE))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// A line of the training residual: the sinusoid amplitude sin(2 pi freq_hz t / fs +
/// phase_rad) at sample t ([`find_sinusoid`]), and how far its periodogram bin stands
/// out of the background.
#[derive(Clone, Debug)]
pub(super) struct Line {
    pub amplitude: f64,
    pub freq_hz: f64,
    pub phase_rad: f64,
    /// The line's bin over the running median of the bins around it
    /// ([`whitened_peak`]).
    pub ratio: f64,
    /// Bins searched for the largest ratio.
    pub bins: usize,
    /// The line's periodogram bin: cycles over the log's length.
    pub bin: usize,
}

/// Lowest bin of a line that [`Line::is_significant`] accepts: three groups of the
/// running median, so that the background around the bin is read on both sides of it
/// (below, the median of a steep red background, a drift's, lies on the bin's high
/// side and any low bin stands out of it).
const LINE_MIN_BIN: usize = 3 * MEDIAN_GROUP;

/// Chance, over all bins searched, that a line this far out of the background is
/// noise, below which [`Line::is_significant`] holds.
const LINE_FALSE_ALARM: f64 = 1e-3;

impl Line {
    /// Whether the line stands out of a background without lines: a periodogram
    /// ordinate of a continuous spectrum is S chi^2_2 / 2, so its ratio to the median
    /// of its neighbours (S ln 2) exceeds y with probability 2^-y, and the largest of
    /// K bins with probability at most K 2^-y (Bonferroni); significant when that is
    /// below [`LINE_FALSE_ALARM`]; and the line at [`LINE_MIN_BIN`] cycles over the
    /// log or more.
    pub fn is_significant(&self) -> bool {
        let k = self.bins.max(1) as f64;
        self.bin >= LINE_MIN_BIN && self.ratio > (k / LINE_FALSE_ALARM).log2()
    }

    /// The line's value at sample `t`.
    pub fn at(&self, t: usize, fs: f64) -> f64 {
        let w = std::f64::consts::TAU * self.freq_hz / fs;
        self.amplitude * (w * t as f64 + self.phase_rad).sin()
    }
}

/// The sinusoid that best explains `res` on `ranges` ([`Line`]).
pub(super) fn find_sinusoid(res: &[f64], ranges: &[Range<usize>], fs: f64) -> Option<Line> {
    let n = res.len();
    let mut masked = vec![0.0; n];
    let mut cnt = 0.0;
    let mut mean = 0.0;
    for r in ranges {
        for t in r.clone() {
            mean += res[t];
            cnt += 1.0;
        }
    }
    mean /= cnt;
    // each range less its own mean: a drift leaves the training blocks at different
    // levels, and the mask's square wave of them puts lines at the blocks' rate and its
    // odd harmonics
    for r in ranges {
        let m = r.clone().map(|t| res[t]).sum::<f64>() / r.len().max(1) as f64;
        for t in r.clone() {
            masked[t] = res[t] - m;
        }
    }
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    fft.process(&mut masked, &mut spec).ok()?;
    // skip the lowest bins: a few cycles per log are drift, not a sinusoid
    let k0 = 8.min(spec.len() - 1);
    let pw: Vec<f64> = spec.iter().map(|c| c.norm_sqr()).collect();
    let k1 = spec.len().saturating_sub(1);
    let (kbest, ratio) = whitened_peak(&pw, k0, k1)?;
    let df = fs / n as f64;
    let power = |f: f64| -> (f64, f64, f64) {
        // least squares of res on sin, cos at f over ranges
        let w = 2.0 * std::f64::consts::PI * f / fs;
        let (mut ss, mut sc, mut cc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for r in ranges {
            sin_cos_on(w, r.clone(), |t, s, c| {
                let y = res[t] - mean;
                ss += s * s;
                sc += s * c;
                cc += c * c;
                ys += y * s;
                yc += y * c;
            });
        }
        let det = ss * cc - sc * sc;
        if det <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let a = (ys * cc - yc * sc) / det;
        let b = (yc * ss - ys * sc) / det;
        (a * ys + b * yc, a, b)
    };
    let (mut lo, mut hi) = ((kbest as f64 - 1.0) * df, (kbest as f64 + 1.0) * df);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..40 {
        let a = hi - g * (hi - lo);
        let b = lo + g * (hi - lo);
        let (pa, pb) = rayon::join(|| power(a), || power(b));
        if pa.0 > pb.0 {
            hi = b;
        } else {
            lo = a;
        }
    }
    let f = 0.5 * (lo + hi);
    if !(f > 0.0 && f < fs / 2.0) {
        return None;
    }
    let (_, a, b) = power(f);
    // a sin + b cos = A sin(w t + phi)
    Some(Line {
        amplitude: a.hypot(b),
        freq_hz: f,
        phase_rad: b.atan2(a),
        ratio,
        bins: k1 - k0,
        bin: kbest,
    })
}

/// Samples between two exact evaluations in [`sin_cos_on`].
const ROTATION_RUN: usize = 1024;

/// Calls `f(t, sin(w t), cos(w t))` for each t of `r`: sin_cos exactly at the start of
/// each run of [`ROTATION_RUN`] samples, then the angle-addition rotation
/// sin(w (t + 1)) = sin(w t) cos w + cos(w t) sin w, cos(w (t + 1)) = cos(w t) cos w -
/// sin(w t) sin w (each step's rounding error adds up over a run; the twin
/// `(w t).sin_cos()` per sample is tested against it, within 1e-12 plus a few ulps of
/// the angle).
fn sin_cos_on(w: f64, r: Range<usize>, mut f: impl FnMut(usize, f64, f64)) {
    let (sw, cw) = w.sin_cos();
    let mut t = r.start;
    while t < r.end {
        let end = (t + ROTATION_RUN).min(r.end);
        let (mut s, mut c) = (w * t as f64).sin_cos();
        for u in t..end {
            f(u, s, c);
            (s, c) = (s * cw + c * sw, c * cw - s * sw);
        }
        t = end;
    }
}

#[cfg(test)]
mod tests {
    use super::{find_sinusoid, sin_cos_on};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    /// A sinusoid at 0.14 Hz (amplitude 0.17) over a Gauss-Markov of tau 15.6 s at
    /// 10 Hz (dev case 20 of the independent bank, its sigma 0.2 doubled), on
    /// alternating training blocks: the largest raw periodogram bin is in the
    /// Gauss-Markov's low-frequency plateau (in most seeds at sigma 0.3 already), the
    /// largest relative to its running median is the line.
    #[test]
    fn the_line_is_found_over_a_red_background() {
        let (n, fs) = (12_000usize, 10.0f64);
        let mut rng = ChaCha8Rng::seed_from_u64(20);
        let a = (-1.0 / (15.6 * fs)).exp();
        let mut g = 0.0f64;
        let res: Vec<f64> = (0..n)
            .map(|t| {
                let e: f64 = rng.sample(StandardNormal);
                g = a * g + 0.4 * (1.0 - a * a).sqrt() * e;
                let w: f64 = rng.sample(StandardNormal);
                g + 0.05 * w + 0.17 * (std::f64::consts::TAU * 0.14 * t as f64 / fs + 4.1).sin()
            })
            .collect();
        let ranges: Vec<std::ops::Range<usize>> =
            (0..8).map(|b| b * 1500..b * 1500 + 750).collect();
        let line = find_sinusoid(&res, &ranges, fs).unwrap();
        let (amp, f) = (line.amplitude, line.freq_hz);
        assert!(line.is_significant(), "ratio {}", line.ratio);
        assert!((f - 0.14).abs() < 2e-3, "freq {f}");
        assert!((amp - 0.17).abs() < 0.2 * 0.17, "amplitude {amp}");
    }

    /// No line is significant in white noise, nor in a random walk with a warm-up (a
    /// steep red background, whose lowest bins stand far out of their neighbours'
    /// median), over 20 seeds each; the same backgrounds with a line of 20 % of the
    /// white noise's sd at 1.3 Hz added (a ratio of about 260) make it significant.
    #[test]
    fn a_line_is_significant_over_white_and_red_backgrounds_and_a_drift_is_not() {
        let (n, fs) = (36_000usize, 10.0f64);
        let ranges: Vec<std::ops::Range<usize>> =
            (0..8).map(|b| b * 4500..b * 4500 + 2250).collect();
        for seed in 0..20u64 {
            for red in [false, true] {
                let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
                let mut walk = 0.0f64;
                let bg: Vec<f64> = (0..n)
                    .map(|t| {
                        let e: f64 = rng.sample(StandardNormal);
                        let w: f64 = rng.sample(StandardNormal);
                        walk += 0.02 * e;
                        let drift = if red {
                            walk + 3.0 * (-(t as f64) / (600.0 * fs)).exp()
                        } else {
                            0.0
                        };
                        w + drift
                    })
                    .collect();
                let line = find_sinusoid(&bg, &ranges, fs).unwrap();
                assert!(
                    !line.is_significant(),
                    "seed {seed}, red {red}: {} Hz, ratio {}",
                    line.freq_hz,
                    line.ratio
                );
                let with: Vec<f64> = bg
                    .iter()
                    .enumerate()
                    .map(|(t, v)| v + 0.2 * (std::f64::consts::TAU * 1.3 * t as f64 / fs).sin())
                    .collect();
                let line = find_sinusoid(&with, &ranges, fs).unwrap();
                assert!((line.freq_hz - 1.3).abs() < 1e-3, "{}", line.freq_hz);
                assert!(
                    line.is_significant(),
                    "seed {seed}, red {red}: ratio {}",
                    line.ratio
                );
            }
        }
    }

    #[test]
    fn the_rotation_gives_each_samples_sin_and_cos() {
        for (w, r) in [(0.0879, 0..5000), (2.9, 123_456..130_001), (1e-5, 7..8)] {
            let mut worst = 0.0f64;
            let mut seen = 0;
            sin_cos_on(w, r.clone(), |t, s, c| {
                let (s0, c0) = (w * t as f64).sin_cos();
                worst = worst.max((s - s0).abs()).max((c - c0).abs());
                assert_eq!(t, r.start + seen);
                seen += 1;
            });
            assert_eq!(seen, r.len());
            // both round the angle w t: a few of its ulps apart at most, besides the
            // rotation's own rounding
            let bound = 1e-12 + 4.0 * f64::EPSILON * w * r.end as f64;
            assert!(worst < bound, "w {w}: {worst} against {bound}");
        }
    }
}
