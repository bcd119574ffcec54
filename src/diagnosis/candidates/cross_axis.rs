//! cross_axis: gain = cov(d_x, d_o) / var(d_o) over the training part (d the first
//! difference of the residual and of the other channel), for each other channel o of
//! the spec present in the log.

use super::lsq::{diff, ls, shrink_ranges};
use super::params::params_json;
use super::{Context, Delta, Found, Proposal, Training};
use crate::error::Result;
use crate::simulator::Component;

/// One cross_axis proposal per other channel of the spec in the log; not tried when
/// there is none.
pub(super) fn cross_axis(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let (res, ranges) = (&tr.res, &tr.ranges);
    if cx.others.is_empty() {
        out.skip("cross_axis", "no other channel of the spec in the log");
    }
    for (name, o) in cx.others {
        let dx: Vec<f64> = diff(res);
        let dob: Vec<f64> = diff(o);
        if let Some((b, _)) = ls(&dx, &[&dob], true, &shrink_ranges(ranges)) {
            let comp = Component::CrossAxis {
                from: name.clone(),
                gain: b[0],
            };
            let u = cx.sim.extra_signal(cx.spec, cx.channel, &comp)?;
            out.push(Proposal {
                kind: "cross_axis".into(),
                params: params_json(&comp),
                component: comp,
                replaces: None,
                delta: Delta::Each(u),
                note: format!("regression of the differences on those of '{name}'"),
            });
        }
    }
    Ok(())
}
