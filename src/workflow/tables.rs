//! The workflow's results as Parquet tables (one row per channel and item) and the
//! writer of a prepared log as a store.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, Int64Array, RecordBatch, StringArray};

use super::prep::ChannelPrep;
use crate::error::Result;
use crate::output::batch;
use crate::store::{Repair, Segment, Store, StoreWriter};

pub(crate) fn s(v: Vec<String>) -> ArrayRef {
    Arc::new(StringArray::from(v))
}
pub(crate) fn f(v: Vec<f64>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}
pub(crate) fn fo(v: Vec<Option<f64>>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}
pub(crate) fn i(v: Vec<i64>) -> ArrayRef {
    Arc::new(Int64Array::from(v))
}
pub(crate) fn io(v: Vec<Option<i64>>) -> ArrayRef {
    Arc::new(Int64Array::from(v))
}

/// prep.parquet: channel, step, count, statistic, z, p_value, value, detail.
pub fn prep_table(chans: &[ChannelPrep]) -> Result<RecordBatch> {
    let (mut ch, mut st, mut cnt, mut stat, mut z, mut p, mut val, mut det) = (
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
    );
    for c in chans {
        for x in &c.steps {
            ch.push(c.name.clone());
            st.push(x.step.clone());
            cnt.push(x.count.map(|v| v as i64));
            stat.push(x.statistic);
            z.push(x.z);
            p.push(x.p_value);
            val.push(x.value);
            det.push(x.detail.clone());
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("step", s(st)),
        ("count", io(cnt)),
        ("statistic", fo(stat)),
        ("z", fo(z)),
        ("p_value", fo(p)),
        ("value", fo(val)),
        ("detail", s(det)),
    ])
}

/// replaced.parquet: channel, index (row of the input), t_s (seconds from the start),
/// original, replacement, pass.
pub fn replaced_table(chans: &[ChannelPrep], rate_hz: f64) -> Result<RecordBatch> {
    let (mut ch, mut idx, mut t, mut o, mut r, mut pass) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for c in chans {
        for x in &c.replaced {
            ch.push(c.name.clone());
            idx.push(x.index as i64);
            t.push(x.index as f64 / rate_hz);
            o.push(x.original);
            r.push(x.replacement);
            pass.push(x.pass as i64);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("index", i(idx)),
        ("t_s", f(t)),
        ("original", f(o)),
        ("replacement", f(r)),
        ("pass", i(pass)),
    ])
}

/// Writes the prepared channels (aligned, see [`super::prep::align`]) as a store
/// beside the source's time column, with the source's metadata plus one repair per
/// step that changed values. `dropped` rows were removed at the start.
pub fn write_prepared_store(
    target: &Path,
    source: &Store,
    chans: &[ChannelPrep],
    dropped: usize,
) -> Result<()> {
    let meta0 = source.meta();
    let n = chans.first().map(|c| c.values.len()).unwrap_or(0);
    let mut names: Vec<String> = Vec::new();
    if let Some(tc) = &meta0.time_col {
        names.push(tc.clone());
    }
    names.extend(chans.iter().map(|c| c.name.clone()));
    let mut w = StoreWriter::create(target, &names, n)?;
    {
        let mut cols = w.columns_mut();
        let mut k = 0;
        if let Some(tc) = &meta0.time_col {
            let t = source.column(tc)?;
            cols[0].copy_from_slice(&t[dropped..dropped + n]);
            k = 1;
        }
        for (c, col) in chans.iter().zip(cols.iter_mut().skip(k)) {
            col.copy_from_slice(&c.values);
        }
    }
    let mut meta = meta0.clone();
    if dropped > 0 {
        let rate = meta.sample_rate_hz;
        let mut segs: Vec<Segment> = Vec::new();
        let mut removed = dropped as u64;
        for sgm in &meta0.segments {
            let cut = removed.min(sgm.len);
            removed -= cut;
            if sgm.len > cut {
                segs.push(Segment {
                    start: (sgm.start + cut).saturating_sub(dropped as u64),
                    len: sgm.len - cut,
                    t0_s: sgm.t0_s + cut as f64 / rate,
                });
            }
        }
        meta.segments = segs;
    }
    for c in chans {
        for st in &c.steps {
            let changed = match st.step.as_str() {
                "pauta" => st.count.unwrap_or(0) > 0,
                "stationarity" | "stationarity_after" | "nonstationary_kept" => false,
                _ => true,
            };
            if changed {
                meta.repairs.push(Repair {
                    kind: format!("prep_{}", st.step),
                    channel: c.name.clone(),
                    count: st.count.unwrap_or(0),
                    detail: st.detail.clone(),
                });
            }
        }
    }
    w.finish(&meta)
}
