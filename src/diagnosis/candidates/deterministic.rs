//! Deterministic additions (constant_bias, rate_ramp, warmup, sinusoid): least squares
//! of the training residual r_t = x_t - xbar_t on the effect's own signal, simulated
//! with a unit parameter, plus an intercept.

use std::ops::Range;

use rayon::prelude::*;

use super::lsq::{golden_min, log_grid, ls};
use super::params::flag_edge;
use super::{Context, Found, Training};
use crate::error::Result;
use crate::simulator::Component;

/// constant_bias: the mean of the training residual.
pub(super) fn constant_bias(cx: &Context, tr: &Training, out: &mut Found) {
    let (res, ranges, n) = (&tr.res, &tr.ranges, tr.n);
    let s: f64 = ranges
        .iter()
        .map(|r| res[r.clone()].iter().sum::<f64>())
        .sum();
    let v = s / cx.n_train() as f64;
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
    if let Some((b, _)) = ls(res, &[&u], true, ranges) {
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
        Ok(ls(res, &[&u], true, ranges).map(|(b, rss)| (b[0], rss, u)))
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
    if let Some((amp, f, ph)) = find_sinusoid(&tr.res, &tr.ranges, tr.fs) {
        let c = Component::Sinusoid {
            amplitude: amp,
            freq_hz: f,
            phase_rad: ph,
        };
        let sig = cx.unit(c.clone())?;
        out.same(
            "sinusoid",
            c,
            sig,
            "largest peak of the training periodogram, refined by least squares".into(),
        );
    } else {
        out.skip("sinusoid", "no periodogram peak in the training residual");
    }
    Ok(())
}

/// The sinusoid that best explains `res` on `ranges`: (amplitude, freq_hz, phase_rad).
fn find_sinusoid(res: &[f64], ranges: &[Range<usize>], fs: f64) -> Option<(f64, f64, f64)> {
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
    for r in ranges {
        for t in r.clone() {
            masked[t] = res[t] - mean;
        }
    }
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    fft.process(&mut masked, &mut spec).ok()?;
    // skip the lowest bins: a few cycles per log are drift, not a sinusoid
    let k0 = 8.min(spec.len() - 1);
    let (kbest, _) = spec
        .iter()
        .enumerate()
        .skip(k0)
        .take(spec.len().saturating_sub(k0 + 1))
        .max_by(|a, b| a.1.norm_sqr().total_cmp(&b.1.norm_sqr()))?;
    let df = fs / n as f64;
    let power = |f: f64| -> (f64, f64, f64) {
        // least squares of res on sin, cos at f over ranges
        let w = 2.0 * std::f64::consts::PI * f / fs;
        let (mut ss, mut sc, mut cc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for r in ranges {
            for t in r.clone() {
                let (s, c) = (w * t as f64).sin_cos();
                let y = res[t] - mean;
                ss += s * s;
                sc += s * c;
                cc += c * c;
                ys += y * s;
                yc += y * c;
            }
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
    Some((a.hypot(b), f, b.atan2(a)))
}
