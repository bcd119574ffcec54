//! Temperature-driven additions (temperature_bias, thermal_rate, heteroskedastic), tried
//! when the log has the spec's temperature channel; Tm is the log's mean temperature.
//! - temperature_bias: least squares of the training residual on T - Tm and (T - Tm)^2;
//! - thermal_rate: least squares on dT/dt for each smoothing of a grid, the best by
//!   residual sum of squares;
//! - heteroskedastic: the regression of d_t^2 (d the first difference) on T - Tm gives
//!   E[d^2] = a (1 + 2 phi slope (T - Tm)) to first order, phi being the share of the
//!   modulated component in the variance of d (from the ensemble).

use super::lsq::{ls, shrink_ranges};
use super::params::params_json;
use super::{Context, Delta, Found, Proposal, Training};
use crate::diagnosis::features::Temperature;
use crate::error::Result;
use crate::simulator::Component;

/// temperature_bias: coefficients of T - Tm and (T - Tm)^2.
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
    if let Some((b, _)) = ls(res, &[&u1, &u2], true, ranges) {
        let sig: Vec<f64> = u1
            .iter()
            .zip(&u2)
            .map(|(a, c)| b[0] * a + b[1] * c)
            .collect();
        out.same(
            "temperature_bias",
            Component::TemperatureBias {
                coeffs: b.clone(),
                reference_c: Some(tm),
            },
            sig,
            "least squares on T - Tm and (T - Tm)^2".into(),
        );
    }
    Ok(())
}

/// thermal_rate: the coefficient for each smoothing of 0, 10, 30, 100, 300 s, the best
/// by residual sum of squares.
pub(super) fn thermal_rate(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let (res, ranges) = (&tr.res, &tr.ranges);
    let mut best: Option<(f64, f64, f64, Vec<f64>)> = None;
    for sm in [0.0, 10.0, 30.0, 100.0, 300.0] {
        let u = cx.unit(Component::ThermalRate {
            coeff: 1.0,
            smoothing_s: sm,
        })?;
        if let Some((b, rss)) = ls(res, &[&u], true, ranges)
            && best.as_ref().is_none_or(|x| rss < x.2)
        {
            best = Some((b[0], sm, rss, u));
        }
    }
    if let Some((cf, sm, _, u)) = best {
        let sig: Vec<f64> = u.iter().map(|v| v * cf).collect();
        out.same(
            "thermal_rate",
            Component::ThermalRate {
                coeff: cf,
                smoothing_s: sm,
            },
            sig,
            "least squares on dT/dt, smoothing chosen over 0, 10, 30, 100, 300 s".into(),
        );
    }
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
        Some(p) => out.props.push(p),
        None => out.skip(
            "heteroskedastic",
            "the spec's channel has no noise component to modulate",
        ),
    }
    Ok(())
}

/// The heteroskedastic proposal for the noise component with the largest share of the
/// variance of the differences (None: no such component, no regression, or a
/// non-positive intercept).
fn estimate_heteroskedastic(cx: &Context, tp: &Temperature, tm: f64) -> Result<Option<Proposal>> {
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
    let total: f64 = cx.target.iter().map(|t| var_d(t)).sum::<f64>();
    let mut best: Option<(usize, f64)> = None;
    for (k, c) in comps.iter().enumerate() {
        if !c.kind().is_noise() || matches!(c, Component::Farma(_)) {
            continue;
        }
        let v: f64 = cx.parts.iter().map(|p| var_d(&p[k])).sum::<f64>();
        if best.is_none_or(|b| v > b.1) {
            best = Some((k, v));
        }
    }
    let Some((k, v)) = best else { return Ok(None) };
    let of = comps[k].kind();
    let phi = (v / total.max(f64::MIN_POSITIVE)).clamp(1e-6, 1.0);
    let d2: Vec<f64> = {
        let mut d = vec![0.0; cx.real.len()];
        for (t, v) in d.iter_mut().enumerate().skip(1) {
            *v = (cx.real[t] - cx.real[t - 1]).powi(2);
        }
        d
    };
    let dt: Vec<f64> = tp.t_c.iter().map(|t| t - tm).collect();
    let Some((b, _)) = ls(&d2, &[&dt], true, &ranges) else {
        return Ok(None);
    };
    // intercept = mean of d2 where dT = 0: the regression's mean minus slope * mean dT
    let (mut sd2, mut sdt, mut c) = (0.0, 0.0, 0.0);
    for r in &ranges {
        for t in r.clone() {
            sd2 += d2[t];
            sdt += dt[t];
            c += 1.0;
        }
    }
    let a = (sd2 - b[0] * sdt) / c;
    if a <= 0.0 {
        return Ok(None);
    }
    let slope = b[0] / (2.0 * a * phi);
    let comp = Component::Heteroskedastic { of, slope };
    let u = cx.sim.extra_signal(cx.spec, cx.channel, &comp)?;
    Ok(Some(Proposal {
        kind: "heteroskedastic".into(),
        params: params_json(&comp),
        component: comp,
        replaces: None,
        delta: Delta::Each(u),
        note: format!(
            "regression of the squared differences on temperature; {} carries {:.0} % of their variance",
            of.as_str(),
            100.0 * phi
        ),
    }))
}
