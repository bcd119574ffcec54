//! Noise additions from the Allan variance, which adds over independent processes: with
//! A(m) the pooled training AVAR of the real log, E(m) the ensemble's mean and U(m) the
//! candidate simulated with a unit coefficient (mean over replicas),
//! c^2 = argmin sum_m w_m (A - E - c^2 U)^2, w_m = 1 / (m A(m)^2) (the relative variance
//! of an AVAR estimate grows like m / N), c^2 >= 0: white_noise, quantization,
//! bias_instability, rate_random_walk, and gauss_markov (tau_s by the best fit over a
//! log grid).

use super::lsq::{fit_nonneg, log_grid};
use super::params::{flag_edge, params_json, scaled};
use super::{Context, Delta, Found, Proposal, Training, mean_in_order};
use crate::error::Result;
use crate::simulator::{Component, Kind};

/// The power-law noise kinds, each with its component of unit coefficient, in the order
/// they are tried.
pub(super) fn unit_components() -> [(Kind, Component); 4] {
    [
        (Kind::WhiteNoise, Component::WhiteNoise { n: 1.0 }),
        (Kind::Quantization, Component::Quantization { q: 1.0 }),
        (
            Kind::BiasInstability,
            Component::BiasInstability {
                b: 1.0,
                tau_min_s: None,
                tau_max_s: None,
            },
        ),
        (Kind::RateRandomWalk, Component::RateRandomWalk { k: 1.0 }),
    ]
}

/// The fit of a unit component to the excess training Allan variance, given G(m), the
/// unit component's mean training AVAR: (coefficient c, weighted RSS of the fit).
fn allan_fit(tr: &Training, g: &[f64]) -> (f64, f64) {
    let (c2, wrss) = fit_nonneg(&tr.excess, g, &tr.a_real, &tr.ms);
    (c2.sqrt(), wrss)
}

/// The mean training AVAR of `unit_c` over the replicas, its signals simulated and
/// dropped one by one (none is kept).
fn unit_mean_avar(cx: &Context, unit_c: &Component) -> Result<Vec<f64>> {
    let avars = cx
        .sim
        .extra_map(cx.spec, cx.channel, unit_c, |u| cx.avar(u))?;
    Ok(mean_in_order(avars))
}

/// The signal of `unit_c` in every replica, times `c` (in place).
fn scaled_signals(cx: &Context, unit_c: &Component, c: f64) -> Result<Vec<Vec<f64>>> {
    let mut u = cx.sim.extra_signal(cx.spec, cx.channel, unit_c)?;
    for e in u.iter_mut().flatten() {
        *e *= c;
    }
    Ok(u)
}

/// One power-law noise kind of [`unit_components`]: its coefficient from the excess
/// training Allan variance; not tried when there is no excess where it shows.
pub(super) fn power_law(
    cx: &Context,
    tr: &Training,
    kind: Kind,
    unit_c: Component,
    out: &mut Found,
) -> Result<()> {
    let mut u = cx.sim.extra_signal(cx.spec, cx.channel, &unit_c)?;
    let (c, _) = allan_fit(tr, &cx.mean_avar(u.iter().map(|v| v.as_slice())));
    if c <= 0.0 {
        out.skip(
            kind.as_str(),
            "no excess Allan variance where this term shows",
        );
        return Ok(());
    }
    let comp = scaled(&unit_c, c).expect("noise kinds scale");
    out.push(Proposal {
        also: None,
        kind: kind.as_str().into(),
        params: params_json(&comp),
        component: comp,
        replaces: None,
        rescales: None,
        delta: Delta::Each({
            for e in u.iter_mut().flatten() {
                *e *= c;
            }
            u
        }),
        note: "weighted least squares on the excess training Allan variance".into(),
    });
    Ok(())
}

/// gauss_markov: sigma from the excess training Allan variance for each tau_s of a log
/// grid of 8 (from 2 samples to the longest Allan cluster), the best by weighted RSS.
pub(super) fn gauss_markov(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let fs = tr.fs;
    let max_tau = cx.train.adev_factors().last().copied().unwrap_or(1) as f64 / fs;
    let mut best: Option<(f64, f64, f64)> = None;
    let grid = log_grid(2.0 / fs, max_tau.max(4.0 / fs), 8);
    for &tau in &grid {
        let unit_c = Component::GaussMarkov {
            sigma: 1.0,
            tau_s: tau,
        };
        let (c, wrss) = allan_fit(tr, &unit_mean_avar(cx, &unit_c)?);
        if c > 0.0 && best.as_ref().is_none_or(|b| wrss < b.2) {
            best = Some((c, tau, wrss));
        }
    }
    match best {
        Some((c, tau, _)) => {
            // the best tau's unit signals again (the same streams), scaled
            let unit_c = Component::GaussMarkov {
                sigma: 1.0,
                tau_s: tau,
            };
            let u = scaled_signals(cx, &unit_c, c)?;
            let comp = Component::GaussMarkov {
                sigma: c,
                tau_s: tau,
            };
            let mut params = params_json(&comp);
            let mut note = "excess training Allan variance, tau_s over a log grid of 8".to_string();
            flag_edge(
                &mut params,
                &mut note,
                "tau_s",
                tau,
                grid[0],
                grid[grid.len() - 1],
            );
            out.push(Proposal {
                also: None,
                kind: "gauss_markov".into(),
                params,
                component: comp,
                replaces: None,
                rescales: None,
                delta: Delta::Each(u),
                note,
            });
        }
        None => out.skip(
            "gauss_markov",
            "no excess Allan variance where this term shows",
        ),
    }
    Ok(())
}
