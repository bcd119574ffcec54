//! farma: state-dependent dynamics as an effect. When the spec's channel carries a
//! linear `arma` component, a FARMA(p, q, 1) of the same orders is fitted (the
//! estimator of `farma fit`, GCV bandwidth) to the training blocks of the training
//! residual, joined (real minus the ensemble mean, its own mean removed), each f_m
//! reduced to the weighted polynomial of `farma check` (degree up to
//! [`MAX_DEGREE`], the criterion's choice), and proposed in place of the ARMA as an
//! inline `farma` component (contracts.md section 2), simulated on every replica
//! like any other component. The innovation sigma is the fit's; when the spec has
//! other noise components besides the ARMA, the fit's residual also holds theirs, and
//! the spread term of the scoring charges for the excess.

use super::params::params_json;
use super::{Context, Delta, Found, Proposal, Training};
use crate::error::Result;
use crate::estimator::fit::{FarmaParams, fit};
use crate::simulator::{Component, FarmaModel};
use crate::workflow::check::poly_fits;

/// Highest polynomial degree of an f_m.
pub const MAX_DEGREE: usize = 3;

/// Fewest training samples for a FARMA fit.
const MIN_SAMPLES: usize = 2000;

/// The farma proposal, or a reason it was not tried.
pub(super) fn farma(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let comps = &cx.spec.channels[cx.channel].components;
    let Some((k, p, q)) = comps.iter().enumerate().find_map(|(k, c)| match c {
        Component::Arma { ar, ma, .. } if !ar.is_empty() => Some((k, ar.len(), ma.len())),
        _ => None,
    }) else {
        out.skip(
            "farma",
            "the spec's channel has no arma component with an AR part for a FARMA to replace",
        );
        return Ok(());
    };
    // the training blocks joined: the recursion crosses a join at only as many
    // samples as there are blocks
    let y: Vec<f64> = tr
        .ranges
        .iter()
        .flat_map(|r| tr.res[r.clone()].iter().copied())
        .collect();
    if y.len() < MIN_SAMPLES {
        out.skip(
            "farma",
            &format!(
                "the training part has {} samples, fewer than {MIN_SAMPLES} for a FARMA fit",
                y.len()
            ),
        );
        return Ok(());
    }
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let y: Vec<f64> = y.iter().map(|v| v - mean).collect();
    let prm = FarmaParams {
        p: p.min(6),
        q: q.min(6),
        d: 1,
        ..FarmaParams::default()
    }
    .validate(y.len());
    let Ok(prm) = prm else {
        out.skip(
            "farma",
            "the ARMA's orders are beyond the estimator's (p, q <= 6)",
        );
        return Ok(());
    };
    let Ok((model, _)) = fit(&y, &prm) else {
        out.skip("farma", "the FARMA fit of the training residual failed");
        return Ok(());
    };
    let polys = poly_fits(&model, MAX_DEGREE);
    if polys.iter().any(|f| f.coef.iter().any(|c| !c.is_finite())) {
        out.skip(
            "farma",
            "a coefficient function has too few grid points for its polynomial",
        );
        return Ok(());
    }
    let comp = Component::Farma(FarmaModel::Inline {
        p: model.p(),
        q: model.b.len(),
        d: 1,
        f: polys.iter().map(|f| f.coef.clone()).collect(),
        ma: model.b.clone(),
        sigma: model.sigma2.max(0.0).sqrt(),
    });
    // a polynomial f_m can make the recursion explode where the data never went
    let new = match cx.sim.extra_signal(cx.spec, cx.channel, &comp) {
        Ok(v) if v.iter().all(|s| s.iter().all(|x| x.is_finite())) => v,
        _ => {
            out.skip(
                "farma",
                "the fitted FARMA's polynomial coefficient functions make the simulated recursion diverge",
            );
            return Ok(());
        }
    };
    let delta: Vec<Vec<f64>> = new
        .into_iter()
        .enumerate()
        .map(|(r, s)| {
            s.iter()
                .zip(cx.parts[r][k].iter())
                .map(|(a, b)| a - b)
                .collect()
        })
        .collect();
    out.push(Proposal {
        also: None,
        kind: "farma".into(),
        params: params_json(&comp),
        component: comp,
        replaces: Some(k),
        rescales: None,
        delta: Delta::Each(delta),
        note: format!(
            "FARMA({p},{q},1) fitted to the training blocks of the training residual, f_m as polynomials of degree <= {MAX_DEGREE}, in place of the arma component"
        ),
    });
    Ok(())
}
