//! The state file of a model folder (`state.parquet`): one row per channel of
//! [`ChannelState`], with the file metadata `farma_state_version`; written by `fit
//! --save-state` and `update`, read by `update` (every field checked, the message
//! naming the file, channel and field).

use std::path::Path;
use std::sync::Arc;

use arrow_array::builder::{Float64Builder, ListBuilder, UInt64Builder};
use arrow_array::{
    Array, ArrayRef, BooleanArray, Float64Array, Int64Array, ListArray, RecordBatch, StringArray,
    UInt64Array,
};

use crate::error::{Error, Result};
use crate::model::state::{ChannelState, LastTime, STATE_VERSION};
use crate::output::batch;

fn lf(builder: &mut ListBuilder<Float64Builder>, v: &[f64]) {
    builder.values().append_slice(v);
    builder.append(true);
}

/// The state table: one row per channel (see the README for the columns).
pub fn state_table(states: &[&ChannelState]) -> Result<RecordBatch> {
    let names = [
        "grid",
        "gram",
        "cross",
        "gram2",
        "kernel_mass",
        "b",
        "b_gram",
        "b_rhs",
        "x_tail",
        "e_tail",
    ];
    let mut lists: Vec<ListBuilder<Float64Builder>> = names
        .iter()
        .map(|_| ListBuilder::new(Float64Builder::new()))
        .collect();
    let mut nsup = ListBuilder::new(UInt64Builder::new());
    for s in states {
        let vals: [&[f64]; 10] = [
            &s.grid,
            &s.gram,
            &s.cross,
            &s.gram2,
            &s.kernel_mass,
            &s.b,
            &s.b_gram,
            &s.b_rhs,
            &s.x_tail,
            &s.e_tail,
        ];
        for (l, v) in lists.iter_mut().zip(vals) {
            lf(l, v);
        }
        nsup.values().append_slice(&s.n_support);
        nsup.append(true);
    }
    let f = |g: &dyn Fn(&ChannelState) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from(
            states.iter().map(|s| g(s)).collect::<Vec<_>>(),
        ))
    };
    let i = |g: &dyn Fn(&ChannelState) -> i64| -> ArrayRef {
        Arc::new(Int64Array::from(
            states.iter().map(|s| g(s)).collect::<Vec<_>>(),
        ))
    };
    let mut cols: Vec<(&str, ArrayRef)> = vec![
        (
            "channel",
            Arc::new(StringArray::from(
                states.iter().map(|s| s.channel.clone()).collect::<Vec<_>>(),
            )),
        ),
        ("p", i(&|s| s.p as i64)),
        ("q", i(&|s| s.q as i64)),
        ("d", i(&|s| s.d as i64)),
        ("mean", f(&|s| s.mean)),
        ("bandwidth", f(&|s| s.bandwidth)),
        (
            "n",
            Arc::new(UInt64Array::from(
                states.iter().map(|s| s.n).collect::<Vec<_>>(),
            )),
        ),
        ("rss", f(&|s| s.rss)),
        ("rows", f(&|s| s.rows)),
        ("forgetting", f(&|s| s.forgetting)),
        (
            "linear_start",
            Arc::new(BooleanArray::from(
                states.iter().map(|s| s.linear_start).collect::<Vec<_>>(),
            )),
        ),
        (
            "t_last_s",
            Arc::new(Float64Array::from(
                states
                    .iter()
                    .map(|s| match s.t_last {
                        LastTime::At(t) => Some(t),
                        LastTime::NotRecorded | LastTime::NoTimeColumn => None,
                    })
                    .collect::<Vec<_>>(),
            )),
        ),
        ("n_support", Arc::new(nsup.finish())),
    ];
    for (name, mut l) in names.iter().zip(lists) {
        cols.push((name, Arc::new(l.finish())));
    }
    batch(cols)
}

/// Writes the state file atomically (file metadata: `farma_state_version` and `md`).
pub fn write_state(path: &Path, states: &[&ChannelState], md: &[(&str, String)]) -> Result<()> {
    crate::output::write_parquet(path, &state_table(states)?, &state_metadata(md))
}

/// The key-value metadata of a state file: `md` and the state format's version.
pub fn state_metadata<'a>(md: &[(&'a str, String)]) -> Vec<(&'a str, String)> {
    let mut md = md.to_vec();
    md.push(("farma_state_version", STATE_VERSION.to_string()));
    md
}

/// Key-value metadata of a Parquet file.
pub type Metadata = Vec<(String, String)>;

/// Reads a state file; returns the channels' states and the file's key-value metadata.
pub fn read_state(path: &Path) -> Result<(Vec<ChannelState>, Metadata)> {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let file = std::fs::File::open(path).map_err(|e| Error::input_io(path, e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file)
        .map_err(|e| Error::format(path, format!("not a readable Parquet file: {e}")))?;
    let md: Metadata = builder
        .metadata()
        .file_metadata()
        .key_value_metadata()
        .map(|kv| {
            kv.iter()
                .map(|e| (e.key.clone(), e.value.clone().unwrap_or_default()))
                .collect()
        })
        .unwrap_or_default();
    match md.iter().find(|(k, _)| k == "farma_state_version") {
        Some((_, v)) if v == STATE_VERSION => {}
        Some((_, v)) => {
            return Err(Error::format(
                path,
                format!("state version {v}, this farma reads version {STATE_VERSION}"),
            ));
        }
        None => {
            return Err(Error::format(
                path,
                "not a farma state file (no 'farma_state_version' metadata)",
            ));
        }
    }
    let reader = builder
        .build()
        .map_err(|e| Error::format(path, format!("cannot read: {e}")))?;
    let mut out = Vec::new();
    for b in reader {
        let b = b.map_err(|e| Error::format(path, format!("cannot read: {e}")))?;
        let col = |name: &str| {
            b.column_by_name(name)
                .ok_or_else(|| Error::format(path, format!("column '{name}' is missing")))
        };
        let wrong = |name: &str| Error::format(path, format!("column '{name}' has the wrong type"));
        macro_rules! get {
            ($name:expr, $ty:ty) => {
                col($name)?
                    .as_any()
                    .downcast_ref::<$ty>()
                    .ok_or_else(|| wrong($name))?
            };
        }
        let channel = get!("channel", StringArray);
        let (p, q, d) = (
            get!("p", Int64Array),
            get!("q", Int64Array),
            get!("d", Int64Array),
        );
        let (mean, bw, n, rss, rows, lam) = (
            get!("mean", Float64Array),
            get!("bandwidth", Float64Array),
            get!("n", UInt64Array),
            get!("rss", Float64Array),
            get!("rows", Float64Array),
            get!("forgetting", Float64Array),
        );
        let nsup = get!("n_support", ListArray);
        // absent in state files written before it: false
        let linear_start = match b.column_by_name("linear_start") {
            None => None,
            Some(c) => Some(
                c.as_any()
                    .downcast_ref::<BooleanArray>()
                    .ok_or_else(|| wrong("linear_start"))?,
            ),
        };
        // absent in state files written before it: not recorded; null: no time column
        let t_last = match b.column_by_name("t_last_s") {
            None => None,
            Some(c) => Some(
                c.as_any()
                    .downcast_ref::<Float64Array>()
                    .ok_or_else(|| wrong("t_last_s"))?,
            ),
        };
        // a list field with a missing value (its own or one of its entries)
        let null_in = |name: &str, row: usize| {
            Error::format(
                path,
                format!(
                    "channel '{}': field '{name}' holds a missing (null) value",
                    channel.value(row)
                ),
            )
        };
        let list = |name: &str, row: usize| -> Result<Vec<f64>> {
            let l = col(name)?
                .as_any()
                .downcast_ref::<ListArray>()
                .ok_or_else(|| wrong(name))?;
            let v = l.value(row);
            let v = v
                .as_any()
                .downcast_ref::<Float64Array>()
                .ok_or_else(|| wrong(name))?;
            if l.is_null(row) || v.null_count() > 0 {
                return Err(null_in(name, row));
            }
            Ok(v.values().to_vec())
        };
        for row in 0..b.num_rows() {
            let scalars: [(&str, &dyn Array); 10] = [
                ("channel", channel),
                ("p", p),
                ("q", q),
                ("d", d),
                ("mean", mean),
                ("bandwidth", bw),
                ("n", n),
                ("rss", rss),
                ("rows", rows),
                ("forgetting", lam),
            ];
            if let Some((name, _)) = scalars.iter().find(|(_, a)| a.is_null(row)) {
                return Err(Error::format(
                    path,
                    format!(
                        "channel '{}' (row {row}): field '{name}' is missing (null)",
                        channel.value(row)
                    ),
                ));
            }
            let usz =
                |a: &Int64Array, name: &str| usize::try_from(a.value(row)).map_err(|_| wrong(name));
            let ns = nsup.value(row);
            let ns = ns
                .as_any()
                .downcast_ref::<UInt64Array>()
                .ok_or_else(|| wrong("n_support"))?;
            if nsup.is_null(row) || ns.null_count() > 0 {
                return Err(null_in("n_support", row));
            }
            let s = ChannelState {
                channel: channel.value(row).to_string(),
                p: usz(p, "p")?,
                q: usz(q, "q")?,
                d: usz(d, "d")?,
                mean: mean.value(row),
                bandwidth: bw.value(row),
                grid: list("grid", row)?,
                gram: list("gram", row)?,
                cross: list("cross", row)?,
                gram2: list("gram2", row)?,
                kernel_mass: list("kernel_mass", row)?,
                n_support: ns.values().to_vec(),
                b: list("b", row)?,
                b_gram: list("b_gram", row)?,
                b_rhs: list("b_rhs", row)?,
                x_tail: list("x_tail", row)?,
                e_tail: list("e_tail", row)?,
                n: n.value(row),
                rss: rss.value(row),
                rows: rows.value(row),
                forgetting: lam.value(row),
                linear_start: match linear_start {
                    None => false,
                    Some(c) if c.is_null(row) => return Err(null_in("linear_start", row)),
                    Some(c) => c.value(row),
                },
                t_last: match t_last {
                    None => LastTime::NotRecorded,
                    Some(c) if c.is_null(row) => LastTime::NoTimeColumn,
                    Some(c) => LastTime::At(c.value(row)),
                },
            };
            s.check()
                .and_then(|()| s.check_invertible())
                .and_then(|()| s.check_solvable())
                .map_err(|m| Error::format(path, format!("channel '{}': {m}", s.channel)))?;
            if out.iter().any(|o: &ChannelState| o.channel == s.channel) {
                return Err(Error::format(
                    path,
                    format!(
                        "channel '{}': field 'channel': the channel has more than one state row",
                        s.channel
                    ),
                ));
            }
            out.push(s);
        }
    }
    if out.is_empty() {
        return Err(Error::format(path, "the state file holds no channel"));
    }
    Ok((out, md))
}
