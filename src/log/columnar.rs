//! Parquet and Arrow IPC logs: streams record batches into a store's columns.
//!
//! Numeric columns of any width are converted to `f64` exactly (every integer up to
//! 2^53 and every `f32` is representable); nulls become missing values for the NaN
//! policy; `Timestamp` time columns become seconds. The sample rate may come from the
//! `sample_rate_hz` key of the file's key-value or Arrow schema metadata.

use std::collections::HashMap;
use std::fs::File;
use std::path::{Path, PathBuf};

use arrow_array::cast::AsArray;
use arrow_array::types::*;
use arrow_array::{Array, ArrowPrimitiveType, RecordBatch};
use arrow_schema::{DataType, Schema, TimeUnit};
use parquet::arrow::ProjectionMask;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use super::{LogOptions, NonFinite, Parsed, Progress};
use crate::error::{Error, Result};
use crate::store::{RATE_KEY, StoreWriter};

fn is_supported(dt: &DataType) -> bool {
    matches!(
        dt,
        DataType::Float64
            | DataType::Float32
            | DataType::Int8
            | DataType::Int16
            | DataType::Int32
            | DataType::Int64
            | DataType::UInt8
            | DataType::UInt16
            | DataType::UInt32
            | DataType::UInt64
            | DataType::Timestamp(_, _)
    )
}

/// Picks the columns to keep (time column first if selected), checks their types.
fn plan(path: &Path, schema: &Schema, opts: &LogOptions) -> Result<(Vec<String>, Option<String>)> {
    let names: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
    let time_col = super::find_time_column(path, &names, opts)?;
    let keep: Vec<String> = match &opts.columns {
        None => names.clone(),
        Some(sel) => {
            let all: std::collections::HashSet<&String> = names.iter().collect();
            for s in sel {
                if !all.contains(s) {
                    return Err(Error::column(
                        path,
                        format!("no column '{s}'; columns are: {}", names.join(", ")),
                    ));
                }
            }
            let sel: std::collections::HashSet<&String> = sel.iter().collect();
            names
                .iter()
                .filter(|n| sel.contains(n) || Some(*n) == time_col.as_ref())
                .cloned()
                .collect()
        }
    };
    // By index, not `field_with_name` (a scan per name): linear at any width.
    let keep_set: std::collections::HashSet<&str> = keep.iter().map(String::as_str).collect();
    for f in schema.fields() {
        let (n, dt) = (f.name(), f.data_type());
        if !keep_set.contains(n.as_str()) {
            continue;
        }
        if !is_supported(dt) {
            return Err(Error::column(
                path,
                format!(
                    "column '{n}' has type {dt}, not a number; choose the channels with --columns"
                ),
            ));
        }
    }
    if keep.is_empty() {
        return Err(Error::column(path, "the file has no columns"));
    }
    Ok((keep, time_col))
}

fn rate_from(md: &HashMap<String, String>, path: &Path) -> Result<Option<f64>> {
    match md.get(RATE_KEY) {
        None => Ok(None),
        Some(s) => match s.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(Some(v)),
            _ => Err(Error::format(
                path,
                format!("metadata {RATE_KEY} = '{s}' is not a positive number"),
            )),
        },
    }
}

fn copy_primitive<T: ArrowPrimitiveType>(
    arr: &dyn Array,
    out: &mut [f64],
    row0: u64,
    nf: &mut NonFinite,
    conv: impl Fn(T::Native) -> f64,
) {
    let a = arr.as_primitive::<T>();
    for (i, (o, v)) in out.iter_mut().zip(a.values().iter()).enumerate() {
        let x = if a.is_null(i) { f64::NAN } else { conv(*v) };
        if !x.is_finite() {
            nf.add(row0 + i as u64);
        }
        *o = x;
    }
}

/// Copies one column of a batch into `out` as f64.
fn copy_column(arr: &dyn Array, out: &mut [f64], row0: u64, nf: &mut NonFinite) {
    match arr.data_type() {
        DataType::Float64 => copy_primitive::<Float64Type>(arr, out, row0, nf, |v| v),
        DataType::Float32 => copy_primitive::<Float32Type>(arr, out, row0, nf, f64::from),
        DataType::Int8 => copy_primitive::<Int8Type>(arr, out, row0, nf, f64::from),
        DataType::Int16 => copy_primitive::<Int16Type>(arr, out, row0, nf, f64::from),
        DataType::Int32 => copy_primitive::<Int32Type>(arr, out, row0, nf, f64::from),
        DataType::Int64 => copy_primitive::<Int64Type>(arr, out, row0, nf, |v| v as f64),
        DataType::UInt8 => copy_primitive::<UInt8Type>(arr, out, row0, nf, f64::from),
        DataType::UInt16 => copy_primitive::<UInt16Type>(arr, out, row0, nf, f64::from),
        DataType::UInt32 => copy_primitive::<UInt32Type>(arr, out, row0, nf, f64::from),
        DataType::UInt64 => copy_primitive::<UInt64Type>(arr, out, row0, nf, |v| v as f64),
        DataType::Timestamp(unit, _) => {
            let scale = match unit {
                TimeUnit::Second => 1.0,
                TimeUnit::Millisecond => 1e-3,
                TimeUnit::Microsecond => 1e-6,
                TimeUnit::Nanosecond => 1e-9,
            };
            // Timestamps of every unit share the i64 representation.
            let data = arr.to_data();
            let a = arrow_array::Int64Array::from(
                data.into_builder()
                    .data_type(DataType::Int64)
                    .build()
                    .expect("same layout"),
            );
            copy_primitive::<Int64Type>(&a, out, row0, nf, |v| v as f64 * scale)
        }
        other => unreachable!("type {other} rejected by plan()"),
    }
}

/// Streams `batches` into a new store.
fn fill(
    path: &Path,
    target: &Path,
    names: &[String],
    n_rows: usize,
    batches: impl Iterator<Item = Result<RecordBatch>>,
    progress: &Progress,
) -> Result<(StoreWriter, Vec<NonFinite>)> {
    if n_rows == 0 {
        return Err(Error::empty(path, "the file holds no rows"));
    }
    let mut writer = StoreWriter::create(target, names, n_rows)?;
    let mut nonfinite: Vec<NonFinite> = names.iter().map(|_| NonFinite::default()).collect();
    let pb = progress.bar("reading", n_rows as u64);
    let mut row = 0usize;
    {
        let mut cols = writer.columns_mut();
        for batch in batches {
            let batch = batch?;
            let k = batch.num_rows();
            if row + k > n_rows {
                return Err(Error::format(path, "more rows than the file metadata says"));
            }
            for (ci, name) in names.iter().enumerate() {
                let arr = batch
                    .column_by_name(name)
                    .ok_or_else(|| Error::Internal(format!("batch lacks column {name}")))?;
                copy_column(
                    arr.as_ref(),
                    &mut cols[ci][row..row + k],
                    row as u64,
                    &mut nonfinite[ci],
                );
            }
            row += k;
            pb.inc(k as u64);
        }
    }
    pb.finish_and_clear();
    if row != n_rows {
        return Err(Error::format(
            path,
            format!("read {row} rows, the file metadata says {n_rows} (truncated?)"),
        ));
    }
    Ok((writer, nonfinite))
}

/// Reads a Parquet log into a new store at `target` (not yet finished).
pub(crate) fn read_parquet(
    path: &Path,
    target: &Path,
    opts: &LogOptions,
    progress: &Progress,
) -> Result<Parsed> {
    let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file)
        .map_err(|e| Error::format(path, format!("not a readable Parquet file: {e}")))?;
    let schema = builder.schema().clone();
    let mut md: HashMap<String, String> = schema
        .metadata()
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    if let Some(kv) = builder.metadata().file_metadata().key_value_metadata() {
        for e in kv {
            if let Some(v) = &e.value {
                md.entry(e.key.clone()).or_insert_with(|| v.clone());
            }
        }
    }
    let rate_meta_hz = rate_from(&md, path)?;
    let (names, time_col) = plan(path, &schema, opts)?;
    let n_rows = usize::try_from(builder.metadata().file_metadata().num_rows())
        .map_err(|_| Error::format(path, "negative row count in the metadata"))?;
    let indices: Vec<usize> = names
        .iter()
        .map(|n| schema.index_of(n).expect("planned"))
        .collect();
    let mask = ProjectionMask::roots(builder.parquet_schema(), indices);
    let reader = builder
        .with_projection(mask)
        .with_batch_size(64 * 1024)
        .build()
        .map_err(|e| Error::format(path, format!("cannot read Parquet: {e}")))?;
    let batches = reader
        .map(|b| b.map_err(|e| Error::format(path, format!("cannot decode Parquet data: {e}"))));
    let (writer, nonfinite) = fill(path, target, &names, n_rows, batches, progress)?;
    Ok(Parsed {
        writer,
        format: "parquet",
        time_col,
        rate_meta_hz,
        nonfinite,
        locate: Box::new(|row| format!("row {}", row + 1)),
        path: PathBuf::from(path),
    })
}

/// Reads an Arrow IPC file (of any layout) into a new store at `target`.
pub(crate) fn read_arrow(
    path: &Path,
    target: &Path,
    opts: &LogOptions,
    progress: &Progress,
) -> Result<Parsed> {
    let open = || -> Result<arrow_ipc::reader::FileReader<File>> {
        let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
        arrow_ipc::reader::FileReader::try_new(file, None)
            .map_err(|e| Error::format(path, format!("not a readable Arrow IPC file: {e}")))
    };
    let reader = open()?;
    let schema = reader.schema();
    let md: HashMap<String, String> = schema
        .metadata()
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let rate_meta_hz = rate_from(&md, path)?;
    let (names, time_col) = plan(path, &schema, opts)?;
    // First pass: count rows (decodes one column per batch).
    let first = schema.index_of(&names[0]).expect("planned");
    let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
    let mut counter = arrow_ipc::reader::FileReaderBuilder::new()
        .with_projection(vec![first])
        .build(file)
        .map_err(|e| Error::format(path, format!("not a readable Arrow IPC file: {e}")))?;
    let mut n_rows = 0usize;
    for b in &mut counter {
        n_rows += b
            .map_err(|e| Error::format(path, format!("cannot decode Arrow data: {e}")))?
            .num_rows();
    }
    let batches = reader
        .map(|b| b.map_err(|e| Error::format(path, format!("cannot decode Arrow data: {e}"))));
    let (writer, nonfinite) = fill(path, target, &names, n_rows, batches, progress)?;
    Ok(Parsed {
        writer,
        format: "arrow",
        time_col,
        rate_meta_hz,
        nonfinite,
        locate: Box::new(|row| format!("row {}", row + 1)),
        path: PathBuf::from(path),
    })
}
