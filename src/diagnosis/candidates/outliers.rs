//! Outliers from spikes: the local second difference s_t = x_t - (x_{t-1} + x_{t+1})/2,
//! spikes where |s_t| exceeds 6 robust standard deviations (1.4826 MAD) and is a local
//! maximum; the excess count over the ensemble's gives the rate, and the mean square of
//! the spikes, read as a normal sample truncated at the threshold
//! (E[Z^2 | |Z| > c] = 1 + c phi(c) / Q(c)), gives the scale and the share detected.

use std::ops::Range;

use super::params::params_json;
use super::{Context, Delta, Found, Proposal};
use crate::error::Result;
use crate::simulator::Component;
use crate::stats::special::normal_cdf;

/// outliers: [`estimate_outliers`]; not tried when the training part has fewer than 3
/// spikes more than the simulations (the reason gives both counts).
pub(super) fn outliers(cx: &Context, out: &mut Found) -> Result<()> {
    match estimate_outliers(cx)? {
        Ok(p) => out.push(p),
        Err(why) => out.skip("outliers", &why),
    }
    Ok(())
}

/// The spikes of `x` on `ranges`: (count, sum of their squares, threshold).
fn spikes(x: &[f64], ranges: &[Range<usize>]) -> (usize, f64, f64) {
    let s_at = |t: usize| x[t] - 0.5 * (x[t - 1] + x[t + 1]);
    let mut all: Vec<f64> = ranges
        .iter()
        .flat_map(|r| {
            (r.start + 1..r.end - 1).map(move |t| (x[t] - 0.5 * (x[t - 1] + x[t + 1])).abs())
        })
        .collect();
    if all.is_empty() {
        return (0, 0.0, 0.0);
    }
    let mid = all.len() / 2;
    all.select_nth_unstable_by(mid, f64::total_cmp);
    let sd = 1.4826 * all[mid];
    let thr = 6.0 * sd;
    let (mut count, mut sum_sq) = (0usize, 0.0);
    for r in ranges {
        for t in r.start + 2..r.end.saturating_sub(2) {
            let s = s_at(t).abs();
            if s > thr && s >= s_at(t - 1).abs() && s >= s_at(t + 1).abs() {
                count += 1;
                sum_sq += s * s;
            }
        }
    }
    (count, sum_sq, thr)
}

/// Upper tail of the standard normal, Q(c) = 1 - Phi(c) = Phi(-c).
fn normal_tail(c: f64) -> f64 {
    normal_cdf(-c)
}

/// The outliers proposal, or why there is none (fewer than 3 spikes more than the
/// simulations': the two counts).
fn estimate_outliers(cx: &Context) -> Result<std::result::Result<Proposal, String>> {
    let ranges = cx.ranges();
    let (c_real, ss_real, thr) = spikes(cx.real, ranges);
    let c_ens = cx
        .target
        .iter()
        .map(|t| spikes(t, ranges).0 as f64)
        .sum::<f64>()
        / cx.target.len() as f64;
    let excess = c_real as f64 - c_ens;
    if excess < 3.0 || c_real == 0 || thr <= 0.0 {
        return Ok(Err(format!(
            "no more spikes in the training part than in the simulations ({c_real} above 6 \
             robust sd against {c_ens:.1})"
        )));
    }
    let m2 = ss_real / c_real as f64;
    // solve m2 = scale^2 (1 + c phi(c) / Q(c)), c = thr / scale, by bisection on ln scale
    let f = |scale: f64| {
        let c = thr / scale;
        let phi = (-0.5 * c * c).exp() / (2.0 * std::f64::consts::PI).sqrt();
        let q = normal_tail(c).max(1e-300);
        scale * scale * (1.0 + c * phi / q) - m2
    };
    let (mut lo, mut hi) = ((thr * 1e-3).ln(), (m2.sqrt() * 10.0).max(thr).ln());
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f(mid.exp()) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let scale = (0.5 * (lo + hi)).exp();
    let p_detect = (2.0 * normal_tail(thr / scale)).max(1e-6);
    let t_train = cx.n_train() as f64 / cx.rate_hz();
    let rate_hz = (excess / (t_train * p_detect)).min(cx.rate_hz());
    let comp = Component::Outliers { rate_hz, scale };
    let u = cx.sim.extra_signal(cx.spec, cx.channel, &comp)?;
    Ok(Ok(Proposal {
        also: None,
        kind: "outliers".into(),
        params: params_json(&comp),
        component: comp,
        replaces: None,
        rescales: None,
        delta: Delta::Each(u),
        note: format!(
            "{c_real} spikes above 6 robust sd in the training part against {c_ens:.1} in the simulations"
        ),
    }))
}
