//! cross_axis: gain = cov(d_x, d_o) / var(d_o) over the training part (d the first
//! difference of the residual and of the other channel), for each other channel o of
//! the spec present in the log. Its signal is gain times the other channel's
//! simulation, which every replica of the ensemble holds: a proposal comes shed
//! ([`Proposal::shed`]) and is scored from those simulations ([`Proposal::change`]),
//! built ([`Proposal::restore`]) only when it is added.

use super::lsq::{diff, ls, shrink_ranges};
use super::params::params_json;
use super::{Context, Delta, Found, Proposal, Training};
use crate::error::Result;
use crate::simulator::Component;

/// One cross_axis proposal per other channel of the spec in the log that the target
/// channel is not coupled to yet (a gyro can pick up two others); not tried when there
/// is none.
pub(super) fn cross_axis(cx: &Context, tr: &Training, out: &mut Found) -> Result<()> {
    let (res, ranges) = (&tr.res, &tr.ranges);
    if cx.others.is_empty() {
        out.skip("cross_axis", "no other channel of the spec in the log");
    }
    let coupled = |name: &str| {
        cx.spec.channels[cx.channel]
            .components
            .iter()
            .any(|c| matches!(c, Component::CrossAxis { from, .. } if from == name))
    };
    for (j, (name, o)) in cx.others.iter().enumerate() {
        if coupled(name) {
            continue;
        }
        let dx: Vec<f64> = diff(res);
        let dob: Vec<f64> = diff(o);
        if let Some((b, _)) = ls(&dx, &[&dob], true, &shrink_ranges(ranges)) {
            let comp = Component::CrossAxis {
                from: name.clone(),
                gain: b[0],
            };
            // a signal the state rebuilds is not built (Proposal::shed, ::change)
            let u = if cacheable(cx, j, name) {
                Vec::new()
            } else {
                cx.sim.extra_signal(cx.spec, cx.channel, &comp)?
            };
            out.push(Proposal {
                also: None,
                kind: "cross_axis".into(),
                params: params_json(&comp),
                component: comp,
                replaces: None,
                rescales: None,
                delta: Delta::Each(u),
                note: format!("regression of the differences on those of '{name}'"),
            });
        }
    }
    Ok(())
}

/// The signal of a cross_axis component of gain `gain` from other channel `j` (named
/// `name`) in every replica, from the ensemble's simulations of that channel: gain
/// times the source's own signal, as the simulator adds it to a zero buffer
/// (0 + gain v), when the simulated channel is that own signal (it has no cross-axis
/// coupling and no output-path stage of its own); None otherwise, and the component
/// is simulated. [`super::super::ensemble::SimBase::extra_signal`] is its slow twin.
pub(super) fn cached_signal(
    cx: &Context,
    j: usize,
    name: &str,
    gain: f64,
) -> Option<Vec<Vec<f64>>> {
    cacheable(cx, j, name).then(|| {
        cx.sim_others
            .iter()
            .map(|chs| chs[j].iter().map(|v| 0.0 + gain * v).collect())
            .collect()
    })
}

/// Whether [`cached_signal`] reads other channel `j` (named `name`) from the
/// ensemble's simulations: the source has no cross-axis coupling and no output-path
/// stage of its own, and every replica holds its whole simulation.
fn cacheable(cx: &Context, j: usize, name: &str) -> bool {
    let Some(src) = cx.spec.channels.iter().find(|c| c.name == name) else {
        return false;
    };
    let plain = src
        .components
        .iter()
        .all(|c| !matches!(c, Component::CrossAxis { .. }) && !c.kind().is_output_path());
    plain
        && cx.sim_others.len() == cx.sim.replicas
        && cx
            .sim_others
            .iter()
            .all(|chs| chs.get(j).is_some_and(|v| v.len() == cx.sim.n_samples))
}

/// For a cross_axis proposal of the state `cx` whose delta [`cross_axis`] took from
/// the ensemble's simulations ([`cached_signal`]): what rebuilds that delta bit for
/// bit, (the other channel's index, its name, the gain); None for any other proposal.
pub(super) fn rebuild_source<'p>(cx: &Context, p: &'p Proposal) -> Option<(usize, &'p str, f64)> {
    let Component::CrossAxis { from, gain } = &p.component else {
        return None;
    };
    if p.kind != "cross_axis" || p.replaces.is_some() {
        return None;
    }
    let j = cx.others.iter().position(|(name, _)| name == from)?;
    cacheable(cx, j, from).then_some((j, from.as_str(), *gain))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnosis::blocks::Blocks;
    use crate::diagnosis::ensemble::SimBase;
    use crate::diagnosis::features::Layout;
    use crate::simulator::{ChannelSpec, Spec};

    fn spec(extra_on_y: Option<Component>) -> Spec {
        let noise = vec![
            Component::WhiteNoise { n: 0.03 },
            Component::BiasInstability {
                b: 0.007,
                tau_min_s: None,
                tau_max_s: None,
            },
            Component::GaussMarkov {
                sigma: 0.1,
                tau_s: 0.5,
            },
        ];
        let mut y = noise.clone();
        y.extend(extra_on_y);
        Spec {
            sample_rate_hz: 100.0,
            temperature_channel: None,
            seed: Some(5),
            channels: vec![
                ChannelSpec {
                    name: "x".into(),
                    components: noise,
                },
                ChannelSpec {
                    name: "y".into(),
                    components: y,
                },
            ],
        }
    }

    #[test]
    fn the_cached_cross_axis_signal_is_the_simulated_one_bit_for_bit() {
        let n = 50_000;
        let sim = SimBase {
            n_samples: n,
            rate_hz: 100.0,
            temperature_c: None,
            seed: 5,
            replicas: 3,
            base_dir: None,
        };
        let names = vec!["y".to_string()];
        let blocks = Blocks::interleaved(n, 8, 0.5).unwrap();
        let train = Layout::new(&blocks, true, 100.0, None, &names);
        let real = vec![0.0; n];
        for (extra, cached) in [
            (None, true),
            (
                Some(Component::CrossAxis {
                    from: "x".into(),
                    gain: 0.1,
                }),
                false,
            ),
        ] {
            let sp = spec(extra);
            let sim_others = sim.channels(&sp, &names).unwrap();
            let others = vec![("y".to_string(), real.as_slice())];
            let cx = Context {
                spec: &sp,
                channel: 0,
                sim: &sim,
                train: &train,
                real: &real,
                beyond: &[],
                temperature: None,
                others: &others,
                sim_others: &sim_others,
                target: &[],
                parts: &[],
            };
            let gain = -0.0371;
            let got = cached_signal(&cx, 0, "y", gain);
            assert_eq!(got.is_some(), cached);
            if let Some(got) = got {
                let comp = Component::CrossAxis {
                    from: "y".into(),
                    gain,
                };
                let want = sim.extra_signal(&sp, 0, &comp).unwrap();
                assert_eq!(got.len(), want.len());
                for (g, w) in got.iter().zip(&want) {
                    assert!(g.iter().zip(w).all(|(a, b)| a.to_bits() == b.to_bits()));
                }
            }
        }
    }
}
