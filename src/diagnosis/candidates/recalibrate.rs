//! Recalibration of what the spec has: every component whose signal is linear in a size
//! parameter (`recalibrate:<kind>`, outliers excepted) gets a size factor s. A noise
//! component k: A - E + V_k against V_k, its own training Allan variance, gives s^2; a
//! deterministic one: least squares of the training residual on its signal gives
//! s - 1 (no intercept for constant_bias, whose signal is one).

use serde_json::{Value, json};

use super::lsq::{fit_nonneg, ls};
use super::params::{is_noise, params_json, scaled};
use super::{Context, Delta, Found, Proposal, Training};
use crate::diagnosis::ensemble::is_deterministic;
use crate::error::Result;
use crate::simulator::Component;

/// The `recalibrate:<kind>` proposal of component `k` of the target channel, when it
/// has a size factor (none when the channel has no component `k`).
pub(super) fn recalibrate(cx: &Context, tr: &Training, k: usize, out: &mut Found) -> Result<()> {
    let comps = &cx.spec.channels[cx.channel].components;
    let (res, ranges) = (&tr.res, &tr.ranges);
    if let Some(c) = comps.get(k) {
        let kind = format!("recalibrate:{}", c.kind());
        if scaled(c, 1.0).is_none() {
            return Ok(());
        }
        let s = if is_noise(c) {
            let na = tr.noise_avar(cx);
            // the component's Allan variance as the output shows it (through the
            // channel's output filter)
            let vk = cx.mean_avar_of(|r| cx.part_as_output(r, k));
            let y: Vec<f64> = na.excess.iter().zip(&vk).map(|(e, v)| e + v).collect();
            let (s2, _) = fit_nonneg(&y, &vk, &na.a_real, &tr.ms);
            s2.sqrt()
        } else if matches!(c, Component::Outliers { .. }) {
            return Ok(());
        } else {
            let sig: &[f64] = &cx.parts[0][k];
            let intercept = !matches!(c, Component::ConstantBias { .. });
            match ls(res, &[sig], intercept, ranges) {
                Some((b, _)) => 1.0 + b[0],
                None => return Ok(()),
            }
        };
        let Some(comp) = scaled(c, s) else {
            return Ok(());
        };
        let delta = if is_deterministic(c) {
            Delta::Same(cx.parts[0][k].iter().map(|v| v * (s - 1.0)).collect())
        } else {
            Delta::Each(
                cx.parts
                    .iter()
                    .map(|p| p[k].iter().map(|v| v * (s - 1.0)).collect())
                    .collect(),
            )
        };
        let mut params = params_json(&comp);
        if let Value::Object(m) = &mut params {
            m.insert("factor".into(), json!(s));
            m.insert("component".into(), json!(k + 1));
        }
        out.push(Proposal {
            also: None,
            kind,
            params,
            component: comp,
            replaces: Some(k),
            rescales: None,
            delta,
            note: if is_noise(c) {
                format!(
                    "size factor from the training Allan variance{}",
                    tr.noise_avar(cx).note()
                )
            } else {
                "size factor by least squares on the training residual".into()
            },
        });
    }
    Ok(())
}
