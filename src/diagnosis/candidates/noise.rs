//! Noise additions from the Allan variance, which adds over independent processes: with
//! A(m) the pooled training AVAR of the real log, E(m) the ensemble's mean and U(m) the
//! candidate simulated with a unit coefficient (mean over replicas),
//! c^2 = argmin sum_m w_m (A - E - c^2 U)^2, w_m = 1 / (m A(m)^2) (the relative variance
//! of an AVAR estimate grows like m / N), c^2 >= 0: white_noise, quantization,
//! bias_instability, rate_random_walk, and gauss_markov (U in closed form, tau_s by the
//! best fit over a log grid refined by golden section). A(m) is of the log with a
//! significant line of the training residual taken out ([`Training::noise_avar`]).

use super::lsq::{fit_nonneg, log_grid, refine_on_log_grid};
use super::params::{flag_edge, params_json, scaled};
use super::{Context, Delta, Found, Proposal, Training, added};
use crate::error::Result;
use crate::simulator::{Component, Kind};
use crate::stats::noise_terms::gauss_markov_g;

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

/// The fit of a unit component to the excess training Allan variance (a significant
/// line of the residual taken out, [`Training::noise_avar`]), given G(m), the unit
/// component's mean training AVAR: (coefficient c, weighted RSS of the fit).
fn allan_fit(cx: &Context, tr: &Training, g: &[f64]) -> (f64, f64) {
    let na = tr.noise_avar(cx);
    let (c2, wrss) = fit_nonneg(&na.excess, g, &na.a_real, &tr.ms);
    (c2.sqrt(), wrss)
}

/// The mean training AVAR of `unit_c` over the replicas, its signals simulated and
/// dropped one by one (none is kept).
#[cfg(test)]
pub(super) fn unit_mean_avar(cx: &Context, unit_c: &Component) -> Result<Vec<f64>> {
    let avars = cx
        .sim
        .extra_map(cx.spec, cx.channel, unit_c, |u| cx.avar(u))?;
    Ok(super::mean_in_order(avars))
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
    let (c, _) = allan_fit(cx, tr, &cx.mean_avar(u.iter().map(|v| v.as_slice())));
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
        note: format!(
            "weighted least squares on the excess training Allan variance{}",
            tr.noise_avar(cx).note()
        ),
    });
    Ok(())
}

/// Points of the log grid of tau_s that [`gauss_markov`] scans before refining.
pub(super) const GM_GRID: usize = 48;

/// The tau_s range of gauss_markov for the state `cx`: from 2 samples to the longest
/// Allan cluster of its training part.
fn gm_range(cx: &Context, tr: &Training) -> (f64, f64) {
    let fs = tr.fs;
    let max_tau = cx.train.adev_factors().last().copied().unwrap_or(1) as f64 / fs;
    (2.0 / fs, max_tau.max(4.0 / fs))
}

/// The unit gauss_markov component of correlation time `tau`.
pub(super) fn gm_unit(tau: f64) -> Component {
    Component::GaussMarkov {
        sigma: 1.0,
        tau_s: tau,
    }
}

/// U(m) of the unit Gauss-Markov process of correlation time `tau_s` at the cluster
/// sizes `ms` (rate `fs`): g(m / (fs tau_s)), the IEEE Std 952 Allan variance per
/// sigma^2 ([`gauss_markov_g`]). It is exact, not an approximation, for what the
/// simulator draws (each sample the interval average of the continuous process, see
/// [`crate::simulator::generate`]'s `markov.rs`), and the pooled overlapping estimator
/// is unbiased for it on every block: the mean over the ensemble's replicas of their
/// simulated unit signals' training AVAR ([`gauss_markov_by_simulation`], its slow
/// twin) converges to it.
pub(super) fn gm_unit_avar(ms: &[usize], fs: f64, tau_s: f64) -> Vec<f64> {
    ms.iter()
        .map(|&m| gauss_markov_g(m as f64 / (fs * tau_s)))
        .collect()
}

/// gauss_markov: sigma from the excess training Allan variance for each tau_s of a
/// log grid of [`GM_GRID`] over [`gm_range`] with the unit AVAR in closed form
/// ([`gm_unit_avar`]), the best by weighted RSS refined by a golden-section search of
/// ln tau_s between its grid neighbours; a tau_s at an end of the range is flagged
/// (`at_search_edge`), a bound rather than an estimate.
pub(super) fn gauss_markov(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let (lo, hi) = gm_range(cx, tr);
    let fit = |tau: f64| allan_fit(cx, tr, &gm_unit_avar(&tr.ms, tr.fs, tau));
    // the weighted RSS of a fit with a positive coefficient (none: infinite)
    let wrss = |tau: f64| match fit(tau) {
        (c, w) if c > 0.0 => w,
        _ => f64::INFINITY,
    };
    let grid = log_grid(lo, hi, GM_GRID);
    let best = (0..grid.len())
        .map(|i| (i, wrss(grid[i])))
        .filter(|(_, w)| w.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let Some((i, w_grid)) = best else {
        out.skip(
            "gauss_markov",
            "no excess Allan variance where this term shows",
        );
        return Ok(());
    };
    let tau = refine_on_log_grid(&grid, i, w_grid, 40, [lo, hi], wrss);
    let (c, _) = fit(tau);
    gm_propose(cx, tr, tau, c, (lo, hi), out)
}

/// [`gauss_markov`] with U(m) the mean over the ensemble's replicas of the simulated
/// unit signal's training AVAR, on the grid alone (no refinement): the slow twin of
/// [`gm_unit_avar`], what the tests compare it with. (sigma, tau_s, weighted RSS) of
/// the best grid point.
#[cfg(test)]
pub(super) fn gauss_markov_by_simulation(
    cx: &Context,
    tr: &Training,
    grid: &[f64],
) -> Result<Option<(f64, f64, f64)>> {
    let mut best: Option<(f64, f64, f64)> = None;
    for &tau in grid {
        let g = unit_mean_avar(cx, &gm_unit(tau))?;
        let (c, wrss) = allan_fit(cx, tr, &g);
        if c > 0.0 && best.as_ref().is_none_or(|b| wrss < b.2) {
            best = Some((c, tau, wrss));
        }
    }
    Ok(best)
}

/// The gauss_markov proposal of the state `cx`: sigma `c` at correlation time `tau`
/// (searched over `range`), its unit signals simulated and scaled.
fn gm_propose(
    cx: &Context,
    tr: &Training,
    tau: f64,
    c: f64,
    range: (f64, f64),
    out: &mut Found,
) -> Result<()> {
    let u = scaled_signals(cx, &gm_unit(tau), c)?;
    let mut p = added(
        "gauss_markov",
        Component::GaussMarkov {
            sigma: c,
            tau_s: tau,
        },
        Delta::Each(u),
        format!(
            "excess training Allan variance against the closed-form unit AVAR, tau_s over a log grid of {GM_GRID} refined by golden section{}",
            tr.noise_avar(cx).note()
        ),
    );
    flag_edge(&mut p.params, &mut p.note, "tau_s", tau, range.0, range.1);
    out.push(p);
    Ok(())
}
