//! Temperature-driven additions (temperature_bias, thermal_rate, heteroskedastic), tried
//! when the log has the spec's temperature channel; Tm is the log's mean temperature.
//! - temperature_bias: least squares of the training residual on T - Tm and (T - Tm)^2
//!   with an intercept, which sets the reference temperature;
//! - thermal_rate: least squares on dT/dt for each smoothing of a grid, the best by
//!   residual sum of squares;
//! - heteroskedastic: the regression of d_t^2 (d the first difference) on T - Tm and
//!   (T - Tm)^2 gives E[d^2] = v_other + v_mod (1 + k (T - Tm))^2 exactly for the
//!   simulator's scale 1 + k (T - Tm), v_other being the other components' variance
//!   of d (from the ensemble): the slope k and the modulated component's level v_mod,
//!   which the proposal sets along with the scale.

use super::lsq::{ls, ls_full, shrink_ranges};
use super::params::{params_json, scaled};
use super::{Context, Delta, Found, Proposal, Training};
use crate::diagnosis::features::Temperature;
use crate::error::Result;
use crate::simulator::Component;

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
    let quadratic =
        ls_full(res, &[&u1, &u2], true, ranges).and_then(|(b, _)| with_reference(b[0], b[1], b[2]));
    let form = match quadratic {
        Some(f) => Some(f),
        None => {
            ls_full(res, &[&u1], true, ranges).and_then(|(b, _)| with_reference(b[0], b[1], 0.0))
        }
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
        Some(p) => out.push(p),
        None => out.skip(
            "heteroskedastic",
            "the spec's channel has no noise component to modulate",
        ),
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

/// The heteroskedastic proposal for the noise component with the largest share of the
/// variance of the differences (None: no such component, no regression, or a
/// non-positive level): the scale's slope and, with it, that component's level
/// rescaled by f = sqrt(v_mod / its variance of the differences in the ensemble)
/// ([`heteroskedastic_form`]); the signal added is (f s_t - 1) times the component's.
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
    let m = cx.target.len().max(1) as f64;
    let total: f64 = cx.target.iter().map(|t| var_d(t)).sum::<f64>() / m;
    let mut best: Option<(usize, f64)> = None;
    for (k, c) in comps.iter().enumerate() {
        if !c.kind().is_noise() || matches!(c, Component::Farma(_)) {
            continue;
        }
        let v: f64 = cx.parts.iter().map(|p| var_d(&p[k])).sum::<f64>() / m;
        if best.is_none_or(|b| v > b.1) {
            best = Some((k, v));
        }
    }
    let Some((k, v)) = best else { return Ok(None) };
    if v <= 0.0 {
        return Ok(None);
    }
    let of = comps[k].kind();
    let d2: Vec<f64> = {
        let mut d = vec![0.0; cx.real.len()];
        for (t, v) in d.iter_mut().enumerate().skip(1) {
            *v = (cx.real[t] - cx.real[t - 1]).powi(2);
        }
        d
    };
    let dt: Vec<f64> = tp.t_c.iter().map(|t| t - tm).collect();
    let Some((slope, v_mod)) = heteroskedastic_form(&d2, &dt, (total - v).max(0.0), &ranges) else {
        return Ok(None);
    };
    let f = (v_mod / v).sqrt();
    let comp = Component::Heteroskedastic { of, slope };
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
    Ok(Some(Proposal {
        also: None,
        kind: "heteroskedastic".into(),
        params,
        component: comp,
        replaces: None,
        rescales: Some((k, level)),
        delta: Delta::Each(u),
        note: format!(
            "regression of the squared differences on temperature; {} carries {:.0} % of their variance in the ensemble, its level at the mean temperature rescaled by {f:.3}",
            of.as_str(),
            100.0 * v / total.max(f64::MIN_POSITIVE)
        ),
    }))
}

#[cfg(test)]
mod tests {
    use super::{heteroskedastic_form, with_reference};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

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
            let (b, _) = super::ls(&d2, &[&dt], true, &ranges).unwrap();
            let mean = |v: &[f64]| v[1..].iter().sum::<f64>() / (n - 1) as f64;
            let a = mean(&d2) - b[0] * mean(&dt);
            let first_order = b[0] / (2.0 * (a - 2.0 * (1.0 - phi)));
            assert!(
                first_order < 0.95 * k,
                "phi {phi} g {g}: first order {first_order}"
            );
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
