//! What a diagnosis leaves behind: the JSON object of contracts.md section 3, Parquet
//! tables for analytics tools, the amended spec, and an SVG report a person can read.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray};
use serde_json::{Value, json};

use super::{Diagnosis, Region, Statistic};
use crate::error::Result;
use crate::output::{OutputSet, batch, write_text};

/// The JSON object of contracts.md section 3 (with extra keys).
pub fn to_json(d: &Diagnosis) -> Value {
    let region = |r: &Region| {
        json!({
            "statistic": r.statistic.as_str(),
            "feature": r.feature,
            "lo": finite(r.lo),
            "hi": finite(r.hi),
            "unit": r.unit,
            "excess": r.excess,
            "ratio_or_delta": finite(r.ratio_or_delta),
            "fold": r.fold,
        })
    };
    let fam = |f: &[(Statistic, f64)]| -> Value {
        f.iter()
            .map(|(s, g)| (s.as_str().to_string(), json!(g)))
            .collect::<serde_json::Map<_, _>>()
            .into()
    };
    json!({
        "channel": d.channel,
        "gap_before": d.gap_before,
        "gap_after": d.gap_after,
        "noise_floor": d.noise_floor,
        "gap_threshold": d.gap_threshold,
        "significant": d.significant,
        "averaged_by": d.averaged_by,
        "explained": d.explained,
        "explained_threshold": d.explained_threshold,
        "explained_replica_gaps": d.explained_replica_gaps,
        "unexplained": unexplained(d).into_iter().map(region).collect::<Vec<_>>(),
        "where": d.where_before.iter().map(region).collect::<Vec<_>>(),
        "where_after": d.where_after.iter().map(region).collect::<Vec<_>>(),
        "effects": d.effects.iter().map(|e| json!({
            "kind": e.kind,
            "shrink": e.shrink,
            "gap_after": e.gap_after,
            "params": e.params,
            "note": e.note,
        })).collect::<Vec<_>>(),
        "added": d.all_added().iter().map(|(_, e)| e.kind.clone()).collect::<Vec<_>>(),
        "added_effects": d.all_added().iter().map(|(part, e)| json!({
            "kind": e.kind, "shrink": e.shrink, "gap_after": e.gap_after, "params": e.params,
            "contribution": e.contribution.map(finite), "step": e.step, "part": part,
        })).collect::<Vec<_>>(),
        "steps": d.steps.iter().map(|s| json!({
            "action": s.action,
            "kind": s.kind,
            "gap_before": finite(s.gap_before),
            "gap_after": finite(s.gap_after),
            "runner_up": s.runner_up,
            "runner_up_gap_after": s.runner_up_gap_after.map(finite),
            "difference_sd": s.difference_sd.map(finite),
            "tie": s.tie,
        })).collect::<Vec<_>>(),
        "not_tried": d.not_tried,
        "joint_pairs": d.joint_pairs.iter().map(|j| json!({
            "kinds": j.kinds,
            "gap_after": finite(j.gap_after),
            "best_single": j.best_single,
            "best_single_gap_after": finite(j.best_single_gap_after),
            "added": j.added,
            "reason": j.reason,
        })).collect::<Vec<_>>(),
        "families_before": fam(&d.family_before),
        "families_after": fam(&d.family_after),
        "replicas": d.replicas,
        "seed": d.seed,
        "blocks": d.blocks.ranges.len(),
        "train_blocks": d.blocks.train.iter().filter(|t| **t).count(),
        "notes": d.notes,
        "events_excluded": d.events_excluded.iter().map(|e| json!({
            "start_s": e.start_s,
            "end_s": e.end_s,
            "channels": e.channels,
            "peak_sd": finite(e.peak_sd),
        })).collect::<Vec<_>>(),
        "per_sample": d.per_sample.as_deref().map(to_json),
        "per_sample_first": d.per_sample_first.as_deref().map(to_json),
    })
}

/// The regions that remain when `d` is not explained: its own out-of-band regions after
/// the added effects when its gap after is above its threshold, and its per-sample
/// part's when that part is not explained.
fn unexplained(d: &Diagnosis) -> Vec<&Region> {
    if d.explained {
        return Vec::new();
    }
    let mut v: Vec<&Region> = if d.per_sample.is_some() && d.own_explained {
        Vec::new()
    } else {
        d.where_after.iter().collect()
    };
    if let Some(p) = d.per_sample.as_deref().filter(|p| !p.added.is_empty()) {
        v.extend(unexplained(p));
    }
    v
}

fn finite(v: f64) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}

fn f64s(v: Vec<f64>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}
fn strs(v: Vec<String>) -> ArrayRef {
    Arc::new(StringArray::from(v))
}

/// The three tables of a diagnosis: gap_features, gap_regions and gap_effects (each row
/// with the channel).
pub fn tables(d: &Diagnosis) -> Result<[RecordBatch; 3]> {
    let ch = |n: usize| strs(vec![d.channel.clone(); n]);
    let k = d.defs.len();
    let zb = d.ens_before.z(&d.real);
    let za = d.ens_after.z(&d.real);
    let feats = batch(vec![
        ("channel", ch(k)),
        (
            "statistic",
            strs(d.defs.iter().map(|f| f.statistic.as_str().into()).collect()),
        ),
        (
            "feature",
            strs(d.defs.iter().map(|f| f.name.clone()).collect()),
        ),
        ("lo", f64s(d.defs.iter().map(|f| f.lo).collect())),
        ("hi", f64s(d.defs.iter().map(|f| f.hi).collect())),
        (
            "unit",
            strs(d.defs.iter().map(|f| f.unit.clone()).collect()),
        ),
        ("real", f64s(d.real.clone())),
        ("sim_mean_before", f64s(d.ens_before.mean.clone())),
        ("sim_sd_before", f64s(d.ens_before.sd.clone())),
        ("z_before", f64s(zb)),
        ("sim_mean_after", f64s(d.ens_after.mean.clone())),
        ("sim_sd_after", f64s(d.ens_after.sd.clone())),
        ("z_after", f64s(za)),
        (
            "fold",
            Arc::new(Int64Array::from(
                d.defs.iter().map(|f| f.fold as i64).collect::<Vec<_>>(),
            )) as ArrayRef,
        ),
    ])?;
    let mut regions: Vec<(&str, &Region)> = d
        .where_before
        .iter()
        .map(|r| ("before", r))
        .chain(d.where_after.iter().map(|r| ("after", r)))
        .collect();
    if let Some(p) = &d.per_sample {
        regions.extend(p.where_before.iter().map(|r| ("per_sample_before", r)));
        regions.extend(p.where_after.iter().map(|r| ("per_sample_after", r)));
    }
    let nr = regions.len();
    let reg = batch(vec![
        ("channel", ch(nr)),
        ("phase", strs(regions.iter().map(|r| r.0.into()).collect())),
        (
            "statistic",
            strs(
                regions
                    .iter()
                    .map(|r| r.1.statistic.as_str().into())
                    .collect(),
            ),
        ),
        (
            "feature",
            strs(regions.iter().map(|r| r.1.feature.clone()).collect()),
        ),
        ("lo", f64s(regions.iter().map(|r| r.1.lo).collect())),
        ("hi", f64s(regions.iter().map(|r| r.1.hi).collect())),
        (
            "unit",
            strs(regions.iter().map(|r| r.1.unit.clone()).collect()),
        ),
        ("excess", f64s(regions.iter().map(|r| r.1.excess).collect())),
        (
            "ratio_or_delta",
            f64s(regions.iter().map(|r| r.1.ratio_or_delta).collect()),
        ),
        (
            "fold",
            Arc::new(Int64Array::from(
                regions.iter().map(|r| r.1.fold as i64).collect::<Vec<_>>(),
            )) as ArrayRef,
        ),
    ])?;
    let mut rows: Vec<(&str, i64, &super::Effect)> = d
        .effects
        .iter()
        .enumerate()
        .map(|(i, e)| ("ranked", i as i64 + 1, e))
        .chain(
            d.added
                .iter()
                .enumerate()
                .map(|(i, e)| ("added", i as i64 + 1, e)),
        )
        .collect();
    if let Some(p) = &d.per_sample {
        rows.extend(
            p.effects
                .iter()
                .enumerate()
                .map(|(i, e)| ("per_sample_ranked", i as i64 + 1, e)),
        );
        let first = d.per_sample_first.iter().flat_map(|f| f.added.iter());
        rows.extend(
            first
                .chain(p.added.iter())
                .enumerate()
                .map(|(i, e)| ("per_sample_added", i as i64 + 1, e)),
        );
    }
    let ne = rows.len();
    let eff = batch(vec![
        ("channel", ch(ne)),
        ("list", strs(rows.iter().map(|r| r.0.into()).collect())),
        (
            "rank",
            Arc::new(Int64Array::from(
                rows.iter().map(|r| r.1).collect::<Vec<_>>(),
            )) as ArrayRef,
        ),
        (
            "kind",
            strs(rows.iter().map(|r| r.2.kind.clone()).collect()),
        ),
        (
            "gap_after",
            f64s(rows.iter().map(|r| r.2.gap_after).collect()),
        ),
        ("shrink", f64s(rows.iter().map(|r| r.2.shrink).collect())),
        (
            "contribution",
            Arc::new(Float64Array::from(
                rows.iter()
                    .map(|r| r.2.contribution.filter(|c| c.is_finite()))
                    .collect::<Vec<_>>(),
            )) as ArrayRef,
        ),
        (
            "params",
            strs(rows.iter().map(|r| r.2.params.to_string()).collect()),
        ),
        (
            "note",
            strs(rows.iter().map(|r| r.2.note.clone()).collect()),
        ),
        (
            "added",
            Arc::new(BooleanArray::from(
                rows.iter()
                    .map(|r| {
                        r.0.ends_with("added")
                            || match r.0 {
                                "ranked" => was_added(d, r.2),
                                _ => d.per_sample.as_deref().is_some_and(|p| was_added(p, r.2)),
                            }
                    })
                    .collect::<Vec<_>>(),
            )) as ArrayRef,
        ),
    ])?;
    Ok([feats, reg, eff])
}

/// The file-level metadata of a diagnosis's tables: `meta` and the gap before, after and
/// the noise floor.
pub fn table_meta<'a>(d: &Diagnosis, meta: &[(&'a str, String)]) -> Vec<(&'a str, String)> {
    let mut meta: Vec<(&str, String)> = meta.to_vec();
    meta.push(("gap_before", d.gap_before.to_string()));
    meta.push(("gap_after", d.gap_after.to_string()));
    meta.push(("noise_floor", d.noise_floor.to_string()));
    meta
}

/// Writes `gap_features.parquet`, `gap_regions.parquet`, `gap_effects.parquet`,
/// `spec_after.toml`, `report.svg` and `report.html` into `dir` (created when missing) as one set
/// ([`GAP_OUTPUTS`]).
pub fn write_outputs(d: &Diagnosis, dir: &Path, meta: &[(&str, String)]) -> Result<Vec<String>> {
    let mut out = OutputSet::new(dir)?;
    let [feats, reg, eff] = tables(d)?;
    let meta = table_meta(d, meta);
    // one set: every file staged beside its place, all renamed into place together
    for (name, b) in [
        ("gap_features.parquet", &feats),
        ("gap_regions.parquet", &reg),
        ("gap_effects.parquet", &eff),
    ] {
        out.parquet(name, b, &meta)?;
    }
    let toml = d.spec_after.to_toml()?;
    out.file("spec_after.toml", |p| write_text(p, &toml))?;
    let report = svg(d)?;
    out.file("report.svg", |p| write_text(p, &report))?;
    let value = |k: &str| {
        meta.iter()
            .find(|(n, _)| *n == k)
            .map_or(String::new(), |(_, v)| v.clone())
    };
    let page =
        crate::report::gap::gap_page(&value("real"), &value("spec"), std::slice::from_ref(d))?;
    out.file(crate::report::REPORT, |p| write_text(p, &page))?;
    let written = GAP_OUTPUTS
        .iter()
        .map(|n| out.path(n).display().to_string())
        .collect();
    out.commit(&GAP_OUTPUTS)?;
    Ok(written)
}

/// The files of `farma gap -o OUTDIR`, written as one set ([`OutputSet`]): each is
/// staged beside its place and they are renamed into place only once all are written,
/// so a run that fails before then leaves the folder's files as they were.
pub const GAP_OUTPUTS: [&str; 6] = [
    "gap_features.parquet",
    "gap_regions.parquet",
    "gap_effects.parquet",
    "spec_after.toml",
    "report.svg",
    "report.html",
];

/// Whether a first-round candidate is one the search kept (same kind and the
/// same estimated parameters: an effect added in a later round was re-estimated).
fn was_added(d: &Diagnosis, e: &super::Effect) -> bool {
    d.added
        .iter()
        .any(|a| a.kind == e.kind && a.params == e.params)
}

/// The report's SVG (drawn by [`crate::report::gap::gap_svg`]): the Allan deviation
/// and the PSD of the real log's withheld part against the simulation band (mean +- 2
/// sd) before and after the added effects, the out-of-band regions shaded, and the
/// ranked effects with their shrink.
pub fn svg(d: &Diagnosis) -> Result<String> {
    crate::report::gap::gap_svg(d)
}
