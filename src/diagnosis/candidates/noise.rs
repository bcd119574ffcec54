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

/// The tau_s grid of gauss_markov for the state `cx`: 8 log-spaced values from 2
/// samples to the longest Allan cluster of its training part.
fn gm_grid(cx: &Context, tr: &Training) -> Vec<f64> {
    let fs = tr.fs;
    let max_tau = cx.train.adev_factors().last().copied().unwrap_or(1) as f64 / fs;
    log_grid(2.0 / fs, max_tau.max(4.0 / fs), 8)
}

/// The unit gauss_markov component of correlation time `tau`.
fn gm_unit(tau: f64) -> Component {
    Component::GaussMarkov {
        sigma: 1.0,
        tau_s: tau,
    }
}

/// gauss_markov: sigma from the excess training Allan variance for each tau_s of a log
/// grid of 8 (from 2 samples to the longest Allan cluster), the best by weighted RSS.
pub(super) fn gauss_markov(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let grid = gm_grid(cx, tr);
    let g = grid
        .iter()
        .map(|&tau| unit_mean_avar(cx, &gm_unit(tau)))
        .collect::<Result<Vec<_>>>()?;
    gm_propose(cx, tr, &grid, &g, out)
}

/// [`gauss_markov`] for two states whose unit signals are the same: each unit signal
/// of the grid simulated once and read by both states' training parts. The signal of
/// a component appended to the target channel depends on the seed, the replica, the
/// channel, the component's index and its own parameters only (its random streams are
/// keyed by these), so two states on one ensemble base whose target channels have as
/// many components, with the same grid, get the same unit signals; otherwise each state
/// simulates its own. [`gauss_markov`] on each state is its slow twin.
pub(super) fn gauss_markov_folds(
    cxs: [&Context; 2],
    trs: [&Training; 2],
    outs: [&mut Found; 2],
) -> Result<()> {
    let grids = [gm_grid(cxs[0], trs[0]), gm_grid(cxs[1], trs[1])];
    let n_comps = |cx: &Context| cx.spec.channels[cx.channel].components.len();
    let same_signals = std::ptr::eq(cxs[0].sim, cxs[1].sim)
        && cxs[0].channel == cxs[1].channel
        && n_comps(cxs[0]) == n_comps(cxs[1])
        && grids[0] == grids[1];
    let [o0, o1] = outs;
    if !same_signals {
        gauss_markov(cxs[0], trs[0], o0)?;
        return gauss_markov(cxs[1], trs[1], o1);
    }
    let mut g: [Vec<Vec<f64>>; 2] = Default::default();
    for &tau in &grids[0] {
        let (a0, a1): (Vec<_>, Vec<_>) = cxs[0]
            .sim
            .extra_map(cxs[0].spec, cxs[0].channel, &gm_unit(tau), |u| {
                (cxs[0].avar(u), cxs[1].avar(u))
            })?
            .into_iter()
            .unzip();
        g[0].push(mean_in_order(a0));
        g[1].push(mean_in_order(a1));
    }
    gm_propose(cxs[0], trs[0], &grids[0], &g[0], o0)?;
    gm_propose(cxs[1], trs[1], &grids[1], &g[1], o1)
}

/// The gauss_markov proposal of the state `cx` from `g[i]`, the mean training AVAR of
/// the unit component of tau_s `grid[i]`: the tau of the best fit, its unit signals
/// simulated again (the same streams) and scaled.
fn gm_propose(
    cx: &Context,
    tr: &Training,
    grid: &[f64],
    g: &[Vec<f64>],
    out: &mut Found,
) -> Result<()> {
    let mut best: Option<(f64, f64, f64)> = None;
    for (&tau, g) in grid.iter().zip(g) {
        let (c, wrss) = allan_fit(tr, g);
        if c > 0.0 && best.as_ref().is_none_or(|b| wrss < b.2) {
            best = Some((c, tau, wrss));
        }
    }
    match best {
        Some((c, tau, _)) => {
            let u = scaled_signals(cx, &gm_unit(tau), c)?;
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
