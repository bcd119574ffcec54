//! Temperature-driven additions (temperature_bias, thermal_rate, heteroskedastic), tried
//! when the log has the spec's temperature channel; Tm is the log's mean temperature.
//! - temperature_bias: least squares of the training residual on T - Tm and (T - Tm)^2
//!   with an intercept, which sets the reference temperature;
//! - thermal_rate: least squares on dT/dt for each smoothing and first-order lag of a
//!   grid, the best by residual sum of squares, its lag refined;
//! - heteroskedastic: the regression of d_t^2 (d the first difference) on T - Tm and
//!   (T - Tm)^2 gives E[d^2] = v_other + v_mod (1 + k (T - Tm))^2 exactly for the
//!   simulator's scale 1 + k (T - Tm), v_other being the other components' variance
//!   of d (from the ensemble): the slope k and the modulated component's level v_mod,
//!   which the proposal sets along with the scale; where the squared differences level
//!   off on one side, the clamped scale max(floor, 1 + k (T - Tm)) by maximum
//!   likelihood in its level and slope, profiled over the temperature of the clamp's
//!   kink ([`heteroskedastic_floor_form`]). The log's spikes are left out of the d_t^2
//!   ([`spike_free`]) and the spec's outliers out of v_other: where the scale is on its
//!   floor, a few spikes' squares (a Student-t's above all, whose mean square the
//!   spikes of one log mostly fall short of) would outweigh the noise and set the floor.

use super::lsq::{
    clearly_better, golden_argmin, ls_full, ls_weighted, refine_on_log_grid, rss_by_range,
    shrink_ranges,
};
use super::params::{flag_edge, flag_undetermined, params_json, scaled};
use super::{Context, Delta, Found, Proposal, Training};
use crate::diagnosis::features::Temperature;
use crate::error::Result;
use crate::simulator::Component;
use rayon::prelude::*;

/// temperature_bias: coefficients of T - Tm and (T - Tm)^2 with an intercept c0, by
/// least squares of the training residual, written in the simulator's form
/// b1' (T - R) + b2 (T - R)^2 with no constant: the reference R = Tm - delta carries
/// the intercept. Matching the constant and linear terms in T - Tm gives
/// b2 delta^2 - b1 delta + c0 = 0 and b1' = b1 - 2 b2 delta; the root of smaller
/// |delta| is delta = 2 c0 / (b1 + sign(b1) sqrt(b1^2 - 4 b2 c0)) (the form without
/// cancellation; Press et al., Numerical Recipes, 3rd ed., section 5.6), c0 / b1 when
/// b2 = 0. A bias of c (T - 22 degC) on a log whose mean temperature is 30 degC thus
/// comes back with R = 22 degC, not as c (T - 30 degC) short of its 8 c offset. When
/// the quadratic has no real root, the linear fit with its intercept is used.
pub(super) fn temperature_bias(
    cx: &Context,
    tr: &Training,
    tm: f64,
    out: &mut Found,
) -> Result<()> {
    let (res, ranges) = (&tr.res, &tr.ranges);
    let u1 = cx.unit(Component::TemperatureBias {
        coeffs: vec![1.0],
        reference_c: Some(tm),
    })?;
    let u2 = cx.unit(Component::TemperatureBias {
        coeffs: vec![0.0, 1.0],
        reference_c: Some(tm),
    })?;
    let quadratic = ls_weighted(res, &tr.regs(&[&u1, &u2]), true, ranges, tr.w())
        .and_then(|(b, _)| with_reference(b[0], b[1], b[2]));
    let form = match quadratic {
        Some(f) => Some(f),
        None => ls_weighted(res, &tr.regs(&[&u1]), true, ranges, tr.w())
            .and_then(|(b, _)| with_reference(b[0], b[1], 0.0)),
    };
    let Some((coeffs, delta)) = form else {
        return Ok(());
    };
    let reference_c = tm - delta;
    let comp = Component::TemperatureBias {
        coeffs: coeffs.clone(),
        reference_c: Some(reference_c),
    };
    let sig = cx.unit(comp.clone())?;
    out.same(
        "temperature_bias",
        comp,
        sig,
        format!(
            "least squares on T - Tm and (T - Tm)^2 with an intercept; the intercept puts the reference temperature at {reference_c:.3} degC"
        ),
    );
    Ok(())
}

/// The simulator's form of c0 + b1 (T - Tm) + b2 (T - Tm)^2: (coefficients of T - R
/// and (T - R)^2, delta = Tm - R), or None when no real R exists or the fit is
/// degenerate (see [`temperature_bias`]).
fn with_reference(c0: f64, b1: f64, b2: f64) -> Option<(Vec<f64>, f64)> {
    let disc = b1 * b1 - 4.0 * b2 * c0;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let den = b1 + b1.signum() * disc.sqrt();
    let delta = if c0 == 0.0 { 0.0 } else { 2.0 * c0 / den };
    if !delta.is_finite() {
        return None;
    }
    let coeffs = if b2 == 0.0 {
        vec![b1]
    } else {
        vec![b1 - 2.0 * b2 * delta, b2]
    };
    Some((coeffs, delta))
}

/// The smoothings (s) [`thermal_rate`] tries, up to a quarter of the log.
const THERMAL_SMOOTHINGS_S: [f64; 6] = [0.0, 10.0, 30.0, 100.0, 300.0, 1000.0];

/// The lags (s) [`thermal_rate`] tries before refining: none, then a log grid of 7 from
/// 10 s to the largest of its range.
const THERMAL_LAGS: usize = 7;

/// One least-squares fit of [`thermal_rate`]: every coefficient (the intercept first),
/// the smoothing and lag of its unit signal, the RSS and the unit signal.
struct ThermalFit {
    beta: Vec<f64>,
    smoothing_s: f64,
    lag_s: f64,
    rss: f64,
    unit: Vec<f64>,
}

/// thermal_rate: the coefficient by least squares of the training residual on the unit
/// signal (with an intercept) for each smoothing of [`THERMAL_SMOOTHINGS_S`] and each
/// lag of none and a log grid of [`THERMAL_LAGS`] from 10 s to min(3000 s, an eighth of
/// the log: a lag near the log's length turns dT/dt into a high-passed T, a stand-in
/// for a temperature bias), the best by residual sum of squares; a lag found on the
/// grid is refined by a golden-section search of ln lag_s between its grid neighbours.
/// A lag or a smoothing at the top of its range is flagged (`at_search_edge`), but a
/// top smoothing that a lesser one fits as well, the lower RSS within one standard
/// error of its spread over the training ranges ([`clearly_better`]; the
/// one-standard-error rule of Breiman et al. 1984, sec. 3.4.3), is marked
/// `undetermined` instead: the range does not bind it.
pub(super) fn thermal_rate(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let (res, ranges) = (&tr.res, &tr.ranges);
    let top_s = (0.25 * tr.duration_s).min(3000.0);
    let lag_top_s = (0.125 * tr.duration_s).min(3000.0);
    let smoothings: Vec<f64> = THERMAL_SMOOTHINGS_S
        .iter()
        .copied()
        .filter(|&s| s <= top_s)
        .collect();
    let lag_top = lag_top_s.max(20.0);
    let lags: Vec<f64> = std::iter::once(0.0)
        .chain(super::lsq::log_grid(10.0, lag_top, THERMAL_LAGS))
        .collect();
    let unit = |sm: f64, lag: f64| {
        cx.unit(Component::ThermalRate {
            coeff: 1.0,
            smoothing_s: sm,
            lag_s: lag,
        })
    };
    // the fit at one (smoothing, lag)
    let fit = |sm: f64, lag: f64| -> Result<Option<ThermalFit>> {
        let u = unit(sm, lag)?;
        Ok(
            ls_weighted(res, &tr.regs(&[&u]), true, ranges, tr.w()).map(|(beta, rss)| ThermalFit {
                beta,
                smoothing_s: sm,
                lag_s: lag,
                rss,
                unit: u,
            }),
        )
    };
    // each smoothing's best lag
    let mut by_smoothing: Vec<ThermalFit> = Vec::new();
    for &sm in &smoothings {
        let mut best: Option<ThermalFit> = None;
        for &lag in &lags {
            if let Some(f) = fit(sm, lag)?
                && best.as_ref().is_none_or(|x| f.rss < x.rss)
            {
                best = Some(f);
            }
        }
        by_smoothing.extend(best);
    }
    let Some(k) = (0..by_smoothing.len())
        .min_by(|&a, &b| by_smoothing[a].rss.total_cmp(&by_smoothing[b].rss))
    else {
        return Ok(());
    };
    // a smoothing at the top of its range that does not clearly beat a lesser one (on a
    // smooth temperature the smoothing trades off against the coefficient and the lag)
    // is not bound by the range: the data do not determine it
    let top_sm = smoothings[smoothings.len() - 1];
    let undetermined_from = if by_smoothing[k].smoothing_s == top_sm && top_sm > 0.0 {
        let lens: Vec<usize> = ranges.iter().map(|r| r.len()).collect();
        let by_range =
            |f: &ThermalFit| rss_by_range(res, &tr.regs(&[&f.unit]), &f.beta, true, ranges, tr.w());
        let top = by_range(&by_smoothing[k]);
        (0..k)
            .find(|&i| !clearly_better(&by_range(&by_smoothing[i]), &top, &lens))
            .map(|i| by_smoothing[i].smoothing_s)
    } else {
        None
    };
    let chosen = by_smoothing.swap_remove(k);
    let (sm, mut lag, rss, mut u) = (chosen.smoothing_s, chosen.lag_s, chosen.rss, chosen.unit);
    let mut cf = chosen.beta[1];
    if lag > 0.0 {
        // the lag's log grid (none left out), refined between its grid neighbours
        let grid = &lags[1..];
        let i = grid.iter().position(|&l| l == lag).unwrap_or(0);
        let rss_at = |v: f64| match fit(sm, v) {
            Ok(Some(f)) => f.rss,
            _ => f64::INFINITY,
        };
        let refined = refine_on_log_grid(grid, i, rss, 30, [10.0, lag_top], rss_at);
        if refined != lag
            && let Some(f) = fit(sm, refined)?
        {
            (cf, lag, u) = (f.beta[1], refined, f.unit);
        }
    }
    let sig: Vec<f64> = u.iter().map(|v| v * cf).collect();
    let mut p = super::same(
        "thermal_rate",
        Component::ThermalRate {
            coeff: cf,
            smoothing_s: sm,
            lag_s: lag,
        },
        sig,
        format!(
            "least squares on dT/dt, smoothing chosen over {:?} s, lag over 0 and 10 .. {} s (golden section)",
            smoothings,
            crate::fmt::num(lag_top)
        ),
    );
    if lag > 0.0 {
        flag_edge(&mut p.params, &mut p.note, "lag_s", lag, 10.0, lag_top);
    }
    // no smoothing (the bottom of its range) is a value, not a bound
    if let Some(from) = undetermined_from {
        flag_undetermined(&mut p.params, &mut p.note, "smoothing_s", [sm, from], " s");
    } else if sm > 0.0 {
        flag_edge(&mut p.params, &mut p.note, "smoothing_s", sm, 0.0, top_sm);
    }
    out.push(p);
    Ok(())
}

/// heteroskedastic: [`estimate_heteroskedastic`]; not tried when the channel has no
/// noise component to modulate.
pub(super) fn heteroskedastic(
    cx: &Context,
    tp: &Temperature,
    tm: f64,
    out: &mut Found,
) -> Result<()> {
    match estimate_heteroskedastic(cx, tp, tm)? {
        Ok(p) => out.push(p),
        Err(why) => out.skip("heteroskedastic", why),
    }
    Ok(())
}

/// The slope k of the simulator's scale 1 + k (T - Tm) (`thermal::scale`) and the
/// variance `v_mod` of the modulated component's differences at scale 1 (at T = Tm),
/// from the squared differences `d2` and `dt` = T - Tm over `ranges`, the other
/// components' differences having the variance `v_other` (from the ensemble): with the
/// scale on the modulated component, E[d^2] = v_other + v_mod (1 + k dT)^2
/// = a + 2 v_mod k dT + v_mod k^2 dT^2 exactly (a = v_other + v_mod), so least squares
/// of d^2 on 1, dT and dT^2 gives the intercept a and the linear coefficient c1, and
/// v_mod = a - v_other, k = c1 / (2 v_mod). Leaving the dT^2 term out puts
/// v_mod k^2 mean(dT^2) into the intercept and biases k low (by about 10 % for k = 0.06
/// over +-10 degC). v_mod is not the spec's: a spec whose level is the noise's RMS over
/// the log (sqrt(mean s^2) times its level at Tm) would otherwise be simulated louder
/// than the log by that factor once the scale is added. None when the regression is
/// singular or v_mod <= 0.
#[cfg(test)]
fn heteroskedastic_form(
    d2: &[f64],
    dt: &[f64],
    v_other: f64,
    ranges: &[std::ops::Range<usize>],
) -> Option<(f64, f64)> {
    let dt2: Vec<f64> = dt.iter().map(|v| v * v).collect();
    let (b, _) = ls_full(d2, &[dt, &dt2], true, ranges)?;
    let v_mod = b[0] - v_other;
    (v_mod > 0.0).then(|| (b[1] / (2.0 * v_mod), v_mod))
}

/// Smallest fall of -2 ln L (the Gaussian likelihood of the differences, see
/// [`heteroskedastic_floor_form`]) for the clamped scale to be taken over the
/// unclamped one. The kink is searched over about fifty temperatures and the squared
/// differences of neighbouring samples are correlated; a chi-square of one degree of
/// freedom exceeds 25 with probability 6e-7, and on the unclamped logs of the tests
/// the best clamp lowers -2 ln L by under 7.
pub(super) const FLOOR_MIN_DEVIANCE: f64 = 25.0;

/// Shares of the samples (in temperature order, from the clamped side) beyond the
/// kinks searched by [`heteroskedastic_floor_form`]: 1 %, then 2 % to 94 % by 2 %.
fn floor_shares() -> impl Iterator<Item = f64> {
    std::iter::once(0.01).chain((1..=47).map(|p| p as f64 / 50.0))
}

/// The heteroskedastic form with a floor on the scale.
#[derive(Debug, Clone, Copy, PartialEq)]
struct HeteroFit {
    /// k of max(floor, 1 + k (T - Tm)) [1/degC]
    slope: f64,
    /// the modulated component's variance of the differences at scale 1
    v_mod: f64,
    /// 0 when no clamp is seen
    floor: f64,
    /// the kink stopped at the first or last temperature searched: not an estimate
    at_edge: bool,
    /// the fall of -2 ln L against no clamp (0 when no clamp is taken)
    deviance: f64,
}

/// Maximum (Gaussian) likelihood of the scale model var(d_t) = v_other + (s + g u_t)^2
/// given the squared differences d2 over `ranges`, the model's own two parameters:
/// with s = sqrt(v_mod) and g = s k it is v_other + v_mod (1 + k u)^2, the form
/// [`heteroskedastic_form`] expands into a + b u + e u^2 with e = b^2 / (4 v_mod) tied
/// to the others (a free e would let the curvature take what the slope and the floor
/// should). d_t^2 / var(d_t) is chi-square of one degree of freedom; Fisher scoring
/// minimizes -2 ln L = sum (ln v_t + d_t^2 / v_t) by the weighted least squares of
/// d^2 - v on the gradient (2 m, 2 m u), m = s + g u, weights 1 / v^2 (McCullagh and
/// Nelder, Generalized Linear Models, 2nd ed., 1989, sections 2.5 and 9.2), the step
/// halved until -2 ln L falls. From `start`, at most 30 steps (to a relative change of
/// 1e-9); the variance is held at `min_var` or above. ((s, g) with s >= 0, -2 ln L up
/// to its constant); None when a system is singular or -2 ln L is not finite.
fn scale_ml(
    d2: &[f64],
    u: &[f64],
    ranges: &[std::ops::Range<usize>],
    v_other: f64,
    start: [f64; 2],
    min_var: f64,
) -> Option<([f64; 2], f64)> {
    // -2 ln L at c, with the scoring system's sums there (J'WJ, J'W (d^2 - v))
    let pass = |c: &[f64; 2]| -> (f64, [f64; 3], [f64; 2]) {
        let (mut f, mut ata, mut aty) = (0.0, [0.0; 3], [0.0; 2]);
        for r in ranges {
            for t in r.clone() {
                let x = u[t];
                let m = c[0] + c[1] * x;
                if m <= 0.0 {
                    f = f64::INFINITY;
                }
                let v = (v_other + m * m).max(min_var);
                f += v.ln() + d2[t] / v;
                let w = 4.0 * m * m / (v * v);
                let g = 2.0 * m * (d2[t] - v) / (v * v);
                ata[0] += w;
                ata[1] += w * x;
                ata[2] += w * x * x;
                aty[0] += g;
                aty[1] += g * x;
            }
        }
        (f, ata, aty)
    };
    let mut c = start;
    let (mut f, mut ata, mut aty) = pass(&c);
    if !f.is_finite() {
        return None;
    }
    for _ in 0..30 {
        let step =
            crate::estimator::linalg::normal_equations(&[ata[0], ata[1], ata[1], ata[2]], &aty, 2)?;
        let mut h = 1.0;
        let mut taken = None;
        for _ in 0..10 {
            let next = [c[0] + h * step[0], c[1] + h * step[1]];
            let p = pass(&next);
            if p.0.is_finite() && p.0 <= f {
                taken = Some((next, p));
                break;
            }
            h *= 0.5;
        }
        let Some((next, p)) = taken else { break };
        let change = (0..2)
            .map(|i| (next[i] - c[i]).abs() / (next[i].abs() + c[i].abs()).max(f64::MIN_POSITIVE))
            .fold(0.0, f64::max);
        let fall = f - p.0;
        c = next;
        (f, ata, aty) = p;
        if change < 1e-9 || fall < 1e-6 {
            break;
        }
    }
    // (s, g) and (-s, -g) are one model
    if c[0] < 0.0 {
        c = [-c[0], -c[1]];
    }
    Some((c, f))
}

/// The clamped form E[d^2] = v_other + v_mod max(floor, 1 + k dT)^2 (dT = T - Tm): for
/// k > 0 the clamp acts below the kink temperature c = (floor - 1) / k, and
/// max(floor, 1 + k dT) = 1 + k max(dT, c), so for a given c the form is
/// [`heteroskedastic_form`]'s, exact, on u = max(dT, c) (u = min(dT, c) and c > 0 for
/// k < 0, the clamp on the warm side), with floor = 1 + k c. The squared differences'
/// spread grows with their mean (a chi-square's), so where the scale levels off the
/// ordinary least squares of [`heteroskedastic_form`] hardly sees the clamp; each form
/// is fitted by maximum likelihood instead, in the model's own two parameters
/// ([`scale_ml`]: the level and the slope, the curvature tied to them), and the kink
/// profiled out (the change-point fit of a segmented regression; Hudson, J. Am. Stat.
/// Assoc. 61, 1966) over the temperatures beyond which [`floor_shares`] of the samples
/// lie, on each side of Tm, each kink's fit starting from its neighbour's (or from a
/// constant scale where that start would put the scale at or below 0), keeping fits
/// with k of the side's sign and 0 <= floor < 1. The best is taken when it lowers
/// -2 ln L by [`FLOOR_MIN_DEVIANCE`] against the unclamped form's maximum likelihood
/// (the better of the two starts: the ordinary least squares and a constant scale);
/// otherwise the unclamped ordinary least squares is returned (floor 0, the same slope
/// and level as [`heteroskedastic_form`]). A kink at the first or last temperature
/// searched on its side is flagged `at_edge`. None when the unclamped regression is
/// singular or its v_mod <= 0.
fn heteroskedastic_floor_form(
    d2: &[f64],
    dt: &[f64],
    v_other: f64,
    ranges: &[std::ops::Range<usize>],
) -> Option<HeteroFit> {
    let dt2: Vec<f64> = dt.iter().map(|v| v * v).collect();
    let (b0, _) = ls_full(d2, &[dt, &dt2], true, ranges)?;
    let v_mod0 = b0[0] - v_other;
    if v_mod0 <= 0.0 {
        return None;
    }
    let unclamped = HeteroFit {
        slope: b0[1] / (2.0 * v_mod0),
        v_mod: v_mod0,
        floor: 0.0,
        at_edge: false,
        deviance: 0.0,
    };
    let mut sorted: Vec<f64> = ranges
        .iter()
        .flat_map(|r| dt[r.clone()].iter().copied())
        .collect();
    let n = sorted.len();
    if n < 10 {
        return Some(unclamped);
    }
    let mean_d2 = ranges
        .iter()
        .flat_map(|r| d2[r.clone()].iter())
        .sum::<f64>()
        / n as f64;
    let min_var = 1e-6 * mean_d2;
    if min_var.is_nan() || min_var <= 0.0 {
        return Some(unclamped);
    }
    // the starts of the two-parameter fits: the unclamped least squares, a constant
    // scale (m = s > 0 everywhere: always a valid start)
    let s0 = v_mod0.sqrt();
    let flat = [(mean_d2 - v_other).max(min_var).sqrt(), 0.0];
    // a start is valid when m = s + g u > 0 over u's range [lo, hi]
    let valid = |c: &[f64; 2], lo: f64, hi: f64| c[0] + c[1] * lo > 0.0 && c[0] + c[1] * hi > 0.0;
    sorted.sort_by(f64::total_cmp);
    let (lo_all, hi_all) = (sorted[0], sorted[n - 1]);
    let Some(nll0) = [[s0, s0 * unclamped.slope], flat]
        .iter()
        .filter(|c| valid(c, lo_all, hi_all))
        .filter_map(|c| scale_ml(d2, dt, ranges, v_other, *c, min_var))
        .map(|(_, f)| f)
        .reduce(f64::min)
    else {
        return Some(unclamped);
    };
    // the clamped form's fit at kink c on the low (k > 0) or high side, from `from`
    // when it is a valid start there, else from a constant scale: (-2 ln L, fit, (s, g)),
    // None when singular or out of the form's range
    let fit_at = |low: bool, c: f64, from: [f64; 2]| -> Option<(f64, HeteroFit, [f64; 2])> {
        let u: Vec<f64> = dt
            .iter()
            .map(|&v| if low { v.max(c) } else { v.min(c) })
            .collect();
        let (lo, hi) = if low {
            (c, hi_all.max(c))
        } else {
            (lo_all.min(c), c)
        };
        let start = if valid(&from, lo, hi) { from } else { flat };
        let (b, nll) = scale_ml(d2, &u, ranges, v_other, start, min_var)?;
        let v_mod = b[0] * b[0];
        let k = b[1] / b[0];
        let floor = 1.0 + k * c;
        let fit = HeteroFit {
            slope: k,
            v_mod,
            floor,
            at_edge: false,
            deviance: 0.0,
        };
        (v_mod > 0.0 && (k > 0.0) == low && (0.0..1.0).contains(&floor)).then_some((nll, fit, b))
    };
    // (-2 ln L, fit, coefficients, side, kinks searched on it, index of the best)
    type Best = (f64, HeteroFit, [f64; 2], bool, Vec<f64>, usize);
    let mut best: Option<Best> = None;
    for low in [true, false] {
        let mut kinks: Vec<f64> = floor_shares()
            .map(|p| {
                let i = ((p * n as f64) as usize).min(n - 1);
                if low { sorted[i] } else { sorted[n - 1 - i] }
            })
            .filter(|&c| if low { c < 0.0 } else { c > 0.0 })
            .collect();
        kinks.dedup();
        let mut from = [s0, s0 * unclamped.slope];
        let mut side: Option<(f64, HeteroFit, [f64; 2], usize)> = None;
        for (i, &c) in kinks.iter().enumerate() {
            let Some((nll, fit, b)) = fit_at(low, c, from) else {
                continue;
            };
            from = b;
            if side.as_ref().is_none_or(|s| nll < s.0) {
                side = Some((nll, fit, b, i));
            }
        }
        if let Some((nll, fit, b, i)) = side
            && best.as_ref().is_none_or(|s| nll < s.0)
        {
            best = Some((nll, fit, b, low, kinks, i));
        }
    }
    let Some((mut nll, mut fit, b, low, kinks, i)) = best else {
        return Some(unclamped);
    };
    // the kink refined between the grid's neighbours of the best by golden-section search
    let (lo, hi) = (
        kinks[i.saturating_sub(1)],
        kinks[(i + 1).min(kinks.len() - 1)],
    );
    let (c, _) = golden_argmin(lo.min(hi), lo.max(hi), 16, |c| {
        fit_at(low, c, b).map_or(f64::INFINITY, |f| f.0)
    });
    if let Some((nll_c, fit_c, _)) = fit_at(low, c, b)
        && nll_c < nll
    {
        (nll, fit) = (nll_c, fit_c);
    }
    let deviance = nll0 - nll;
    Some(if deviance >= FLOOR_MIN_DEVIANCE {
        HeteroFit {
            at_edge: i == 0 || i + 1 == kinks.len(),
            deviance,
            ..fit
        }
    } else {
        unclamped
    })
}

/// The heteroskedastic proposal for the noise component with the largest share of the
/// variance of the differences (None: no such component, no regression, or a
/// non-positive level): the scale's slope and, with it, that component's level
/// rescaled by f = sqrt(v_mod / its variance of the differences in the ensemble)
/// ([`heteroskedastic_form`]); the signal added is (f s_t - 1) times the component's.
/// The quantiles of the training temperature at which [`estimate_heteroskedastic`] also
/// puts the reference of the scale (besides the log's mean): one on each side, so that
/// a scale clamped over most of the log (the mean temperature on its floor, where no
/// line through 1 fits) is fitted about a temperature where it is not clamped.
const REFERENCE_QUANTILES: [f64; 2] = [0.02, 0.98];

/// How much more a fit about another reference must lower -2 ln L than the fit about
/// the mean to be taken: two references that reach the same kink are one model, and
/// their likelihoods differ by rounding only; the mean is kept then.
const REFERENCE_MIN_GAIN: f64 = 1.0;

/// Differences in a window of [`spike_free`]: its robust sd of the differences holds
/// within about 2.6 % (the sample median's standard error at 2048 half-normal values).
const SPIKE_WINDOW: usize = 2048;

/// How many robust sd of its window a difference must exceed for [`spike_free`] to
/// leave it out: the outliers' threshold (candidates/outliers.rs), beyond which a
/// normal difference falls once in 5e8.
const SPIKE_SD: f64 = 6.0;

/// The samples t of `ranges` (each t with t - 1 in its range) whose difference
/// d_t = x_t - x_{t-1} is not a spike's, as runs of t: |d_t| at most [`SPIKE_SD`] times
/// the robust sd (1.4826 times the median |d|) of its window of [`SPIKE_WINDOW`]
/// differences (the last window of a range taking a rest shorter than half a window;
/// a window whose median |d| is 0, a series of few levels, keeps all).
fn spike_free(x: &[f64], ranges: &[std::ops::Range<usize>]) -> Vec<std::ops::Range<usize>> {
    let mut out: Vec<std::ops::Range<usize>> = Vec::new();
    let mut abs_d: Vec<f64> = Vec::with_capacity(SPIKE_WINDOW + SPIKE_WINDOW / 2);
    for r in ranges {
        let mut a = r.start;
        while a < r.end {
            let mut b = (a + SPIKE_WINDOW).min(r.end);
            if r.end - b < SPIKE_WINDOW / 2 {
                b = r.end;
            }
            abs_d.clear();
            abs_d.extend((a..b).map(|t| (x[t] - x[t - 1]).abs()));
            let mid = abs_d.len() / 2;
            abs_d.select_nth_unstable_by(mid, f64::total_cmp);
            let thr = SPIKE_SD * 1.4826 * abs_d[mid];
            // runs of kept samples, one that goes on from the last window's joined to it
            let mut push = |run: std::ops::Range<usize>| match out.last_mut() {
                Some(last) if last.end == run.start => last.end = run.end,
                _ => out.push(run),
            };
            let mut run = a;
            for t in a..b {
                if thr > 0.0 && (x[t] - x[t - 1]).abs() > thr {
                    if run < t {
                        push(run..t);
                    }
                    run = t + 1;
                }
            }
            if run < b {
                push(run..b);
            }
            a = b;
        }
    }
    out
}

fn estimate_heteroskedastic(
    cx: &Context,
    tp: &Temperature,
    tm: f64,
) -> Result<std::result::Result<Proposal, &'static str>> {
    let comps = &cx.spec.channels[cx.channel].components;
    let ranges = shrink_ranges(cx.ranges());
    // the noise component with the largest share of the variance of the differences
    let var_d = |x: &[f64]| -> f64 {
        let mut s = 0.0;
        let mut c = 0.0f64;
        for r in &ranges {
            for t in r.clone() {
                let d = x[t] - x[t - 1];
                s += d * d;
                c += 1.0;
            }
        }
        s / c.max(1.0)
    };
    // the mean over the replicas of `of(r)` (in parallel, summed in the replicas' order)
    let m = cx.target.len().max(1) as f64;
    let mean_of = |of: &(dyn Fn(usize) -> f64 + Sync)| -> f64 {
        (0..cx.target.len())
            .into_par_iter()
            .map(of)
            .collect::<Vec<f64>>()
            .iter()
            .sum::<f64>()
            / m
    };
    // the ensemble's outputs' (through the output path), as the log's differences are
    let total = mean_of(&|r| var_d(&cx.target_as_output(r)));
    let mut best: Option<(usize, f64)> = None;
    for (k, c) in comps.iter().enumerate() {
        if !c.kind().is_noise() || matches!(c, Component::Farma(_)) {
            continue;
        }
        // as the output shows it (through the channel's output filter)
        let v = mean_of(&|r| var_d(&cx.part_as_output(r, k)));
        if best.is_none_or(|b| v > b.1) {
            best = Some((k, v));
        }
    }
    let no_noise = "the spec's channel has no noise component to modulate";
    let Some((k, v)) = best else {
        return Ok(Err(no_noise));
    };
    if v <= 0.0 {
        return Ok(Err(no_noise));
    }
    // the spec's outliers, whose share of the squared differences the real log's
    // spikes, left out of its fit ([`spike_free`]), do not carry
    let spikes: f64 = comps
        .iter()
        .enumerate()
        .filter(|(_, c)| matches!(c, Component::Outliers { .. }))
        .map(|(j, _)| {
            mean_of(&|r| {
                let x = cx.part_as_output(r, j);
                if x.is_empty() { 0.0 } else { var_d(&x) }
            })
        })
        .sum();
    let v_other = (total - v - spikes).max(0.0);
    let of = comps[k].kind();
    let d2: Vec<f64> = {
        let mut d = vec![0.0; cx.real.len()];
        for (t, v) in d.iter_mut().enumerate().skip(1) {
            *v = (cx.real[t] - cx.real[t - 1]).powi(2);
        }
        d
    };
    // the form about the mean temperature, and about a cold and a warm quantile of the
    // training temperature, which are the same model wherever the scale is not clamped
    // at the reference (the level v_mod and the slope k rescale by 1 + k (r' - r)): a
    // clamped fit about another reference replaces the mean's when its deviance is
    // larger by REFERENCE_MIN_GAIN
    // the real log's squared differences without its spikes', whose squares (a
    // Student-t amplitude's above all) are no part of the noise level: where the
    // scale is on its floor they would outweigh it
    let fit_ranges = spike_free(cx.real, &ranges);
    let fit_about = |r: f64| {
        let dt: Vec<f64> = tp.t_c.iter().map(|t| t - r).collect();
        heteroskedastic_floor_form(&d2, &dt, v_other, &fit_ranges)
    };
    let mut chosen: Option<(Option<f64>, HeteroFit)> = fit_about(tm).map(|f| (None, f));
    let train_t: Vec<f64> = ranges
        .iter()
        .flat_map(|r| tp.t_c[r.clone()].iter().copied())
        .collect();
    if !train_t.is_empty() {
        let n_t = train_t.len();
        let ranks: Vec<usize> = REFERENCE_QUANTILES
            .iter()
            .map(|q| ((q * (n_t - 1) as f64).round() as usize).min(n_t - 1))
            .collect();
        for r in crate::diagnosis::features::order_statistics(&train_t, &ranks) {
            let Some(f) = fit_about(r) else { continue };
            let better = match &chosen {
                None => f.floor > 0.0,
                Some((_, c)) => f.floor > 0.0 && f.deviance > c.deviance + REFERENCE_MIN_GAIN,
            };
            if better {
                chosen = Some((Some(r), f));
            }
        }
    }
    let Some((reference_c, fit)) = chosen else {
        return Ok(Err(
            "the squared differences' regression on temperature gives no positive level about the mean temperature or its 2 % and 98 % quantiles",
        ));
    };
    let HeteroFit {
        slope,
        v_mod,
        floor,
        ..
    } = fit;
    let f = (v_mod / v).sqrt();
    // the reference written out, the mean temperature included: the simulator's default
    // is the mean of whatever temperature it is given, which for the log's first
    // samples (the per-sample part of a long log) or another profile is not this log's
    let comp = Component::Heteroskedastic {
        of,
        slope,
        floor,
        reference_c: Some(reference_c.unwrap_or(tm)),
    };
    let level = scaled(&comps[k], f).expect("noise kinds scale");
    // (s - 1) x times f, plus (f - 1) x: (f s - 1) x
    let mut u = cx.sim.extra_signal(cx.spec, cx.channel, &comp)?;
    for (r, ur) in u.iter_mut().enumerate() {
        let x = if r > 0 && cx.parts[r][k].is_empty() {
            &cx.parts[0][k]
        } else {
            &cx.parts[r][k]
        };
        for (a, b) in ur.iter_mut().zip(x.iter()) {
            *a = f * *a + (f - 1.0) * b;
        }
    }
    let mut params = params_json(&comp);
    params["level_factor"] = serde_json::json!(f);
    let mut floor_note = String::new();
    if let Some(r) = reference_c {
        floor_note = format!(
            "; about {r:.2} degC (the scale is 1 there): the fit about the mean temperature {tm:.2} degC does not reach this clamp"
        );
    }
    if floor > 0.0 {
        let kink_c = reference_c.unwrap_or(tm) + (floor - 1.0) / slope;
        floor_note += &format!(
            "; the squared differences level off {} {kink_c:.2} degC: scale floor {floor:.3} (the clamp lowers the residual sum of squares by {:.0} residual variances)",
            if slope > 0.0 { "below" } else { "above" },
            fit.deviance
        );
        if fit.at_edge {
            params["floor_at_edge"] = serde_json::json!(true);
            floor_note.push_str(
                "; the kink stopped at the end of its search range (0.5 % to 95 % of the samples clamped): the floor is not an estimate",
            );
        }
    }
    let at = if reference_c.is_some() {
        "reference"
    } else {
        "mean"
    };
    Ok(Ok(Proposal {
        also: None,
        kind: "heteroskedastic".into(),
        params,
        component: comp,
        replaces: None,
        rescales: Some((k, level)),
        delta: Delta::Each(u),
        note: format!(
            "regression of the squared differences on temperature; {} carries {:.0} % of their variance in the ensemble, its level at the {at} temperature rescaled by {f:.3}{floor_note}",
            of.as_str(),
            100.0 * v / total.max(f64::MIN_POSITIVE)
        ),
    }))
}

#[cfg(test)]
mod tests {
    use super::super::lsq::ls;
    use super::{
        SPIKE_WINDOW, heteroskedastic_floor_form, heteroskedastic_form, spike_free, with_reference,
    };
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    /// White noise of sd 0.15 on the first half and 3 on the second (a scale on its
    /// floor, then far above it) with a spike of 40 every 1009 samples: the spikes'
    /// two differences are left out in both halves, and nothing else (a spike of 40 is
    /// 9 sd of the loud half's differences, 190 of the quiet half's); a constant
    /// series (median |d| of 0) keeps every sample.
    #[test]
    fn the_spikes_differences_are_left_out_at_each_windows_own_level() {
        let n = 40_000;
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let mut x: Vec<f64> = (0..n)
            .map(|t| {
                let w: f64 = rng.sample(StandardNormal);
                if t < n / 2 { 0.15 * w } else { 3.0 * w }
            })
            .collect();
        let spikes: Vec<usize> = (700..n - 700).step_by(1009).collect();
        for &t in &spikes {
            x[t] += 40.0;
        }
        let ranges = [1..n / 3, n / 3 + 1..n];
        let kept = spike_free(&x, &ranges);
        let out: Vec<usize> = ranges
            .iter()
            .flat_map(|r| r.clone())
            .filter(|t| !kept.iter().any(|k| k.contains(t)))
            .collect();
        let want: Vec<usize> = spikes
            .iter()
            .flat_map(|&t| [t, t + 1])
            .filter(|t| ranges.iter().any(|r| r.contains(t)))
            .collect();
        // every spike's two differences out; besides them only a few loud samples of
        // the window that holds the change of level, whose median reads part quiet
        let (spike_d, other): (Vec<usize>, Vec<usize>) = out.iter().partition(|t| want.contains(t));
        assert_eq!(spike_d, want);
        let start = n / 3 + 1 + (n / 2 - n / 3 - 1) / SPIKE_WINDOW * SPIKE_WINDOW;
        assert!(
            other.len() <= 4
                && other
                    .iter()
                    .all(|t| (start..start + SPIKE_WINDOW).contains(t)),
            "{other:?} (the window from {start})"
        );
        let flat = vec![1.0; 5000];
        let all = 1..5000;
        assert_eq!(
            spike_free(&flat, std::slice::from_ref(&all)),
            std::slice::from_ref(&all)
        );
    }

    /// White noise scaled by g (1 + k (T - Tm)) under a sinusoidal temperature of
    /// +-10 degC (the modulated component alone, phi = 1, and beside an unmodulated
    /// noise of the same variance, phi = 1/2; the level g at the spec's, 1, and below
    /// it, 0.6): k comes back within 2 % (5 % at g = 0.6, where the modulated noise
    /// carries a quarter of the variance), and the level's variance of the differences
    /// 2 phi g^2 within 2 %, where the first-order form without the dT^2 term is about
    /// 10 % low on k.
    #[test]
    fn the_heteroskedastic_slope_and_level_are_recovered_in_the_simulators_form() {
        let n = 400_000;
        let k = 0.06;
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut normal = move || -> f64 { rng.sample(StandardNormal) };
        let dt: Vec<f64> = (0..n)
            .map(|t| 10.0 * (std::f64::consts::TAU * t as f64 / 50_000.0).sin())
            .collect();
        for (phi, g) in [(1.0f64, 1.0f64), (0.5, 1.0), (0.5, 0.6)] {
            let other = (1.0 - phi).sqrt();
            let x: Vec<f64> = dt
                .iter()
                .map(|d| g * phi.sqrt() * (1.0 + k * d) * normal() + other * normal())
                .collect();
            let d2: Vec<f64> = (0..n)
                .map(|t| {
                    if t == 0 {
                        0.0
                    } else {
                        (x[t] - x[t - 1]).powi(2)
                    }
                })
                .collect();
            let ranges = vec![std::ops::Range { start: 1, end: n }];
            let (got, v_mod) = heteroskedastic_form(&d2, &dt, 2.0 * (1.0 - phi), &ranges).unwrap();
            // 2 %, 5 % where the modulated noise carries a quarter of the variance
            let tol = if g < 1.0 { 0.05 } else { 0.02 };
            assert!((got - k).abs() < tol * k, "phi {phi} g {g}: {got} vs {k}");
            let want = 2.0 * phi * g * g;
            assert!(
                (v_mod - want).abs() < 0.02 * want,
                "phi {phi} g {g}: level {v_mod} vs {want}"
            );
            // the first-order form: intercept = mean d^2 - c1 mean dT
            let (b, _) = ls(&d2, &[&dt], true, &ranges).unwrap();
            let mean = |v: &[f64]| v[1..].iter().sum::<f64>() / (n - 1) as f64;
            let a = mean(&d2) - b[0] * mean(&dt);
            let first_order = b[0] / (2.0 * (a - 2.0 * (1.0 - phi)));
            assert!(
                first_order < 0.95 * k,
                "phi {phi} g {g}: first order {first_order}"
            );
        }
    }

    /// Squared differences of white noise scaled by g max(floor, 1 + k dT) (beside an
    /// unmodulated noise of variance 1 - phi) under a sinusoidal dT of +-10 degC.
    fn clamped_d2(n: usize, k: f64, floor: f64, phi: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut normal = move || -> f64 { rng.sample(StandardNormal) };
        let dt: Vec<f64> = (0..n)
            .map(|t| 10.0 * (std::f64::consts::TAU * t as f64 / 50_000.0).sin())
            .collect();
        let other = (1.0 - phi).sqrt();
        let x: Vec<f64> = dt
            .iter()
            .map(|d| phi.sqrt() * (1.0 + k * d).max(floor) * normal() + other * normal())
            .collect();
        let d2 = (0..n)
            .map(|t| {
                if t == 0 {
                    0.0
                } else {
                    (x[t] - x[t - 1]).powi(2)
                }
            })
            .collect();
        (d2, dt)
    }

    /// A floor on the scale (0.3 at k = 0.15: clamped below dT = -4.7 degC, 35 % of the
    /// samples; 0.5 at k = -0.12 beside an unmodulated noise of the same variance,
    /// clamped above 4.2 degC, 29 %; 0.4 at k = 0.2, 40 %) comes back with the slope
    /// within 3 %, the floor within 0.02 and the level within 3 %, found (not at the
    /// edge of the kink's range). With 400 000 samples these seeds gave errors of at most
    /// 0.7 %, 0.004 and 0.8 %: the tolerances leave room for other seeds, not for a
    /// form that misses the clamp (the unclamped fit has no floor at all).
    #[test]
    fn a_floor_on_the_scale_is_recovered_with_the_slope() {
        let n = 400_000;
        for (k, floor, phi, seed) in [
            (0.15, 0.3, 1.0, 21u64),
            (-0.12, 0.5, 0.5, 22),
            (0.2, 0.4, 1.0, 23),
        ] {
            let (d2, dt) = clamped_d2(n, k, floor, phi, seed);
            let ranges = vec![std::ops::Range { start: 1, end: n }];
            let v_other = 2.0 * (1.0 - phi);
            let fit = heteroskedastic_floor_form(&d2, &dt, v_other, &ranges).unwrap();
            assert!(
                (fit.slope - k).abs() < 0.03 * k.abs(),
                "k {k} floor {floor}: {fit:?}"
            );
            assert!(
                (fit.floor - floor).abs() < 0.02,
                "k {k} floor {floor}: {fit:?}"
            );
            assert!(
                (fit.v_mod - 2.0 * phi).abs() < 0.03 * 2.0 * phi,
                "k {k} floor {floor}: {fit:?}"
            );
            assert!(!fit.at_edge && fit.deviance >= super::FLOOR_MIN_DEVIANCE);
        }
    }

    /// Without a floor (and with the scale never reaching 0) no clamp is taken: the fit
    /// is the unclamped closed form's, bit for bit, on five seeds and two slopes.
    #[test]
    fn no_floor_is_found_where_the_scale_is_not_clamped() {
        let n = 400_000;
        for seed in 31..36u64 {
            for (k, phi) in [(0.06, 1.0), (-0.04, 0.5)] {
                let (d2, dt) = clamped_d2(n, k, 0.0, phi, seed);
                let ranges = vec![std::ops::Range { start: 1, end: n }];
                let v_other = 2.0 * (1.0 - phi);
                let fit = heteroskedastic_floor_form(&d2, &dt, v_other, &ranges).unwrap();
                let (k0, v0) = heteroskedastic_form(&d2, &dt, v_other, &ranges).unwrap();
                assert_eq!(
                    (fit.floor, fit.slope, fit.v_mod, fit.at_edge),
                    (0.0, k0, v0, false),
                    "seed {seed} k {k}"
                );
            }
        }
    }

    #[test]
    fn the_reference_form_reproduces_the_polynomial_with_its_constant() {
        for (c0, b1, b2) in [
            (0.096, 0.012, 0.0),
            (0.096, 0.012, 1e-4),
            (-0.3, 0.05, -2e-3),
            (0.0, 0.02, 3e-4),
            (1e-6, -0.01, 1e-5),
        ] {
            let (coeffs, delta) = with_reference(c0, b1, b2).expect("a real root");
            for dt in [-7.0, -1.0, 0.0, 2.5, 11.0] {
                // T - Tm = dt, T - R = dt + delta
                let want = c0 + b1 * dt + b2 * dt * dt;
                let u = dt + delta;
                let got = coeffs[0] * u + coeffs.get(1).copied().unwrap_or(0.0) * u * u;
                assert!(
                    (got - want).abs() < 1e-12 * (1.0 + want.abs()),
                    "{c0} {b1} {b2} {dt}: {got} vs {want}"
                );
            }
        }
        // 0.012 (T - 22) on a log at a mean of 30 degC: the reference comes back
        let (coeffs, delta) = with_reference(0.012 * 8.0, 0.012, 0.0).unwrap();
        assert!((30.0 - delta - 22.0).abs() < 1e-12 && (coeffs[0] - 0.012).abs() < 1e-15);
        // no real reference: b2 (T - R)^2 + b1' (T - R) cannot reach this constant
        assert!(with_reference(1.0, 0.0, 1.0).is_none());
    }
}
