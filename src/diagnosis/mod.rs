//! Sim-to-real gap diagnosis: where a gyro simulator (a spec) differs from a real log,
//! which unmodelled effect causes it, and how far the gap shrinks once the effect is
//! added, judged on withheld data (contracts.md section 3).
//!
//! The steps, one file each:
//! - [`blocks`]: the log cut into interleaved training and withheld time blocks;
//! - [`features`]: the statistics that localise a difference (Allan variance per tau,
//!   PSD per band, windows over time, the marginal distribution, dependence on
//!   temperature and dT/dt, state-dependent dynamics, cross-axis coupling);
//! - [`ensemble`]: M simulations of the spec on the log's time base and temperature,
//!   kept per component so that a candidate is one more signal added to a cached sum;
//! - [`distance`]: the scalar gap (family-balanced RMS of ensemble z-scores, with a
//!   charge for widening the band), the noise
//!   floor and significance from leave-one-out simulations, the regions out of band;
//! - [`candidates`]: each candidate effect's parameters, estimated on the training part;
//! - this file: scoring on the withheld part and the greedy loop ([`diagnose`]);
//! - [`report`]: Parquet tables and the SVG report.

pub mod bank;
pub mod blocks;
pub mod candidates;
pub mod distance;
pub mod ensemble;
pub mod features;
pub mod report;

use rayon::prelude::*;
use serde_json::Value;

use crate::error::{Error, Result};
use crate::simulator::{Component, Spec};
pub use blocks::Blocks;
pub use candidates::{NotTried, Proposal};
pub use distance::{Calibration, EnsembleStats, Region};
pub use features::{FeatureDef, Layout, Statistic, Temperature};

/// Settings of a diagnosis.
#[derive(Clone, Debug)]
pub struct GapParams {
    /// Share of the blocks used for estimation (the rest is withheld for scoring).
    pub train_fraction: f64,
    /// Simulations in the ensemble (M).
    pub replicas: usize,
    /// Time blocks the log is cut into.
    pub n_blocks: usize,
    /// Seed of the ensemble (default: the spec's, else 1).
    pub seed: Option<u64>,
    /// Most effects the greedy search adds.
    pub max_added: usize,
    /// Smallest relative shrink of the gap for an effect to be added.
    pub min_shrink: f64,
}

impl Default for GapParams {
    fn default() -> Self {
        GapParams {
            train_fraction: 0.5,
            replicas: 20,
            n_blocks: 8,
            seed: None,
            max_added: 4,
            min_shrink: 0.05,
        }
    }
}

/// The real log's side of a diagnosis.
#[derive(Clone, Debug)]
pub struct RealLog<'a> {
    /// The diagnosed channel (a channel of the spec and of the log).
    pub channel: String,
    pub x: &'a [f64],
    pub rate_hz: f64,
    /// The spec's temperature channel, from the log.
    pub temperature_c: Option<&'a [f64]>,
    /// Other channels of the spec present in the log, for cross-axis statistics.
    pub others: Vec<(String, &'a [f64])>,
    /// Folder of the spec (relative model paths).
    pub spec_dir: Option<std::path::PathBuf>,
}

/// One candidate effect, scored.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Effect {
    /// A component kind of contracts.md section 2, or `recalibrate:<kind>`.
    pub kind: String,
    /// The gap on the withheld part with the effect added.
    pub gap_after: f64,
    /// 1 - gap_after / gap before the effect.
    pub shrink: f64,
    pub params: Value,
    /// How the parameters were estimated.
    pub note: String,
    /// The gap of each statistic family with the effect added.
    pub families: Vec<(Statistic, f64)>,
    #[serde(skip)]
    pub component: Component,
    #[serde(skip)]
    pub replaces: Option<usize>,
}

/// The outcome of a diagnosis.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    pub channel: String,
    pub gap_before: f64,
    pub gap_after: f64,
    /// Mean leave-one-out gap of the spec's own simulations.
    pub noise_floor: f64,
    /// A gap above this is significant.
    pub gap_threshold: f64,
    /// Regions out of the band before and after the added effects.
    pub where_before: Vec<Region>,
    pub where_after: Vec<Region>,
    /// The first round's candidates, best first (shrink relative to gap_before).
    pub effects: Vec<Effect>,
    /// Effects added by the greedy search, in order (shrink relative to the gap before
    /// each was added).
    pub added: Vec<Effect>,
    pub not_tried: Vec<NotTried>,
    /// The spec with the added effects.
    pub spec_after: Spec,
    /// Feature layout of the withheld part, the real log's features there, and the
    /// ensemble's statistics before and after.
    pub defs: Vec<FeatureDef>,
    pub real: Vec<f64>,
    pub ens_before: EnsembleStats,
    pub ens_after: EnsembleStats,
    pub family_before: Vec<(Statistic, f64)>,
    pub family_after: Vec<(Statistic, f64)>,
    pub blocks: Blocks,
    pub replicas: usize,
    pub seed: u64,
    pub notes: Vec<String>,
}

struct State {
    spec: Spec,
    target: Vec<Vec<f64>>,
    parts: Vec<Vec<Vec<f64>>>,
    ens: EnsembleStats,
    gap: f64,
}

/// Finds where `spec` differs from the real log, which effects explain it, and how far
/// the gap shrinks on the withheld part.
pub fn diagnose(real: &RealLog, spec: &Spec, prm: &GapParams) -> Result<Diagnosis> {
    if prm.replicas < 5 {
        return Err(Error::Usage(format!(
            "--replicas must be at least 5 (got {}): the ensemble's spread needs them",
            prm.replicas
        )));
    }
    let channel = spec
        .channels
        .iter()
        .position(|c| c.name == real.channel)
        .ok_or_else(|| {
            Error::Usage(format!(
                "the spec has no channel '{}' (it has: {})",
                real.channel,
                spec.channels
                    .iter()
                    .map(|c| c.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })?;
    let n = real.x.len();
    // the ensemble holds every replica's component signals and other channels at once
    let n_comp = spec.channels[channel].components.len();
    crate::workflow::budget::check_memory(
        &format!("--replicas {}", prm.replicas),
        &format!(
            "the ensemble of {} replicas x {} signals x {n} samples",
            prm.replicas,
            n_comp + real.others.len() + 1
        ),
        8.0 * n as f64 * prm.replicas as f64 * (n_comp + real.others.len() + 1) as f64,
    )?;
    let blocks = Blocks::interleaved(n, prm.n_blocks, prm.train_fraction)?;
    let rate_hz = real.rate_hz;
    let mut notes = Vec::new();
    if (spec.sample_rate_hz - rate_hz).abs() > 1e-9 * rate_hz {
        notes.push(format!(
            "the spec's sample_rate_hz {} differs from the log's {} Hz: simulated at the log's rate",
            spec.sample_rate_hz, rate_hz
        ));
    }
    let temperature = real
        .temperature_c
        .map(|t| Temperature::new(t.to_vec(), rate_hz));
    let seed = prm.seed.or(spec.seed).unwrap_or(1);
    let sim = ensemble::SimBase {
        n_samples: n,
        rate_hz,
        temperature_c: real.temperature_c,
        seed,
        replicas: prm.replicas,
        base_dir: real.spec_dir.clone(),
    };
    let other_names: Vec<String> = real.others.iter().map(|(s, _)| s.clone()).collect();
    let test = Layout::new(&blocks, false, rate_hz, temperature.as_ref(), &other_names);
    let train = Layout::new(&blocks, true, rate_hz, temperature.as_ref(), &other_names);
    let defs = test.defs.clone();
    let real_others: Vec<&[f64]> = real.others.iter().map(|(_, v)| *v).collect();
    let real_feats = test.compute(real.x, temperature.as_ref(), &real_others);

    let sim_others = sim.channels(spec, &other_names)?;
    let parts = sim.component_signals(spec, channel, &(0..n_comp).collect::<Vec<_>>())?;
    let target: Vec<Vec<f64>> = parts
        .iter()
        .map(|p| {
            let mut s = vec![0.0; n];
            for c in p {
                for (a, v) in s.iter_mut().zip(c) {
                    *a += v;
                }
            }
            s
        })
        .collect();
    let feats_of = |xs: &[Vec<f64>], delta: Option<&candidates::Delta>| -> Vec<Vec<f64>> {
        xs.par_iter()
            .enumerate()
            .map(|(r, x)| {
                let o: Vec<&[f64]> = sim_others[r].iter().map(|v| v.as_slice()).collect();
                match delta {
                    None => test.compute(x, temperature.as_ref(), &o),
                    Some(d) => {
                        let y: Vec<f64> = x.iter().zip(d.get(r)).map(|(a, b)| a + b).collect();
                        test.compute(&y, temperature.as_ref(), &o)
                    }
                }
            })
            .collect()
    };
    let feats = feats_of(&target, None);
    let cal = Calibration::new(&feats, &defs);
    let ens = EnsembleStats::new(&feats, &defs, None);
    let z0 = ens.z(&real_feats);
    let gap_before = distance::gap(&z0, None, &defs);
    let where_before = distance::regions(&z0, &real_feats, &ens, &defs, &cal);
    let family_before = distance::family_gaps(&z0, None, &defs);
    let ens_before = ens.clone();
    // a real log on a value grid that the simulations do not have: say so, with the step
    let resolution = where_before
        .iter()
        .any(|r| r.feature == "ln_distinct_share" && r.ratio_or_delta < 1.0)
        .then(|| candidates::output_resolution(real.x))
        .flatten();

    let mut st = State {
        spec: spec.clone(),
        target,
        parts,
        ens,
        gap: gap_before,
    };
    let mut first: Option<Vec<Effect>> = None;
    let mut added: Vec<Effect> = Vec::new();
    let mut not_tried = Vec::new();
    loop {
        let stop_floor = st.gap <= cal.gap_threshold;
        if stop_floor && first.is_some() {
            notes.push(format!(
                "the gap {:.3} is within the spread of the spec's own simulations (threshold {:.3}): nothing more to add",
                st.gap, cal.gap_threshold
            ));
            break;
        }
        let cx = candidates::Context {
            spec: &st.spec,
            channel,
            sim: &sim,
            train: &train,
            real: real.x,
            temperature: temperature.as_ref(),
            others: &real.others,
            target: &st.target,
            parts: &st.parts,
        };
        let (props, skipped) = candidates::propose(&cx)?;
        if first.is_none() {
            not_tried = skipped;
            if let Some(q) = resolution {
                not_tried.push(NotTried {
                    kind: "output_resolution".into(),
                    reason: format!(
                        "the real values sit on a grid of {q:.6e} u (the sensor's output resolution, an LSB in the rate): add an output_resolution component with quantum = {q:.6e} to the spec (the search does not add output-path components yet), else the distribution statistics keep this difference"
                    ),
                });
            }
        }
        let mut scored: Vec<(Effect, EnsembleStats, Proposal)> = props
            .into_iter()
            .map(|p| {
                let f = feats_of(&st.target, Some(&p.delta));
                let e = EnsembleStats::new(&f, &defs, None);
                let z = e.z(&real_feats);
                let pen = e.spread_penalty(&ens_before);
                let g = distance::gap(&z, Some(&pen), &defs);
                let eff = Effect {
                    kind: p.kind.clone(),
                    gap_after: g,
                    shrink: 1.0 - g / st.gap,
                    params: p.params.clone(),
                    note: p.note.clone(),
                    families: distance::family_gaps(&z, Some(&pen), &defs),
                    component: p.component.clone(),
                    replaces: p.replaces,
                };
                (eff, e, p)
            })
            .collect();
        scored.sort_by(|a, b| a.0.gap_after.total_cmp(&b.0.gap_after));
        if first.is_none() {
            first = Some(scored.iter().map(|s| s.0.clone()).collect());
        }
        if stop_floor {
            notes.push(format!(
                "the gap {:.3} is within the spread of the spec's own simulations (threshold {:.3}): the spec matches, nothing added",
                st.gap, cal.gap_threshold
            ));
            break;
        }
        let Some((eff, e, p)) = scored.into_iter().next() else {
            notes.push("no candidate effect could be estimated".into());
            break;
        };
        if eff.gap_after > st.gap * (1.0 - prm.min_shrink) {
            notes.push(format!(
                "the best remaining effect ({}) shrinks the gap by {:.1} %, less than {:.0} %: stopped",
                eff.kind,
                100.0 * eff.shrink,
                100.0 * prm.min_shrink
            ));
            break;
        }
        // apply
        for (r, t) in st.target.iter_mut().enumerate() {
            for (a, v) in t.iter_mut().zip(p.delta.get(r)) {
                *a += v;
            }
        }
        match p.replaces {
            Some(k) => {
                st.spec.channels[channel].components[k] = p.component.clone();
                for (r, parts) in st.parts.iter_mut().enumerate() {
                    for (a, v) in parts[k].iter_mut().zip(p.delta.get(r)) {
                        *a += v;
                    }
                }
            }
            None => {
                st.spec.channels[channel]
                    .components
                    .push(p.component.clone());
                for (r, parts) in st.parts.iter_mut().enumerate() {
                    parts.push(p.delta.get(r).to_vec());
                }
            }
        }
        st.ens = e;
        st.gap = eff.gap_after;
        added.push(eff);
        if added.len() >= prm.max_added {
            notes.push(format!(
                "stopped after {} effects (--max-effects)",
                added.len()
            ));
            break;
        }
    }
    let z1 = st.ens.z(&real_feats);
    let where_after = distance::regions(&z1, &real_feats, &st.ens, &defs, &cal);
    let pen1 = st.ens.spread_penalty(&ens_before);
    let family_after = distance::family_gaps(&z1, Some(&pen1), &defs);
    Ok(Diagnosis {
        channel: real.channel.clone(),
        gap_before,
        gap_after: st.gap,
        noise_floor: cal.noise_floor,
        gap_threshold: cal.gap_threshold,
        where_before,
        where_after,
        effects: first.unwrap_or_default(),
        added,
        not_tried,
        spec_after: st.spec,
        defs,
        real: real_feats,
        ens_before,
        ens_after: st.ens,
        family_before,
        family_after,
        blocks,
        replicas: prm.replicas,
        seed,
        notes,
    })
}
