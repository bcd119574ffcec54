//! Parquet and Arrow IPC logs: streams record batches into a store's columns.
//!
//! Numeric columns of any width are converted to `f64` exactly (every integer up to
//! 2^53 and every `f32` is representable); a 64-bit integer that no `f64` holds
//! exactly (beyond 2^53) is refused, naming its column and row, rather than rounded;
//! nulls become missing values for the NaN policy; `Timestamp` time columns become
//! seconds. Arrow IPC is read in the file and the stream formats, with lz4 or zstd
//! compressed bodies (pyarrow's Feather default is lz4). Parquet page checksums (CRC32)
//! are verified where the writer recorded them. The sample rate may come from the
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

/// The first value of a 64-bit integer column that no `f64` holds exactly (beyond
/// 2^53 in magnitude), with its index in `arr`; None for other types.
fn inexact_integer(arr: &dyn Array) -> Option<(usize, String, f64)> {
    // 2^63 and 2^64 as f64: a conversion that saturates there is not exact
    const I64_END: f64 = 9_223_372_036_854_775_808.0;
    const U64_END: f64 = 18_446_744_073_709_551_616.0;
    match arr.data_type() {
        DataType::Int64 => {
            let a = arr.as_primitive::<Int64Type>();
            a.values().iter().enumerate().find_map(|(i, &v)| {
                let f = v as f64;
                (!a.is_null(i) && (f >= I64_END || f as i64 != v)).then(|| (i, v.to_string(), f))
            })
        }
        DataType::UInt64 => {
            let a = arr.as_primitive::<UInt64Type>();
            a.values().iter().enumerate().find_map(|(i, &v)| {
                let f = v as f64;
                (!a.is_null(i) && (f >= U64_END || f as u64 != v)).then(|| (i, v.to_string(), f))
            })
        }
        _ => None,
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
                if let Some((i, v, f)) = inexact_integer(arr.as_ref()) {
                    return Err(Error::column(
                        path,
                        format!(
                            "column '{name}', row {}: the integer {v} has no exact 64-bit float (it is beyond 2^53 = 9007199254740992; it would become {f:.0}); farma keeps every channel as f64: scale or offset the column, or convert it to float64 yourself if the rounding is acceptable",
                            row + i + 1
                        ),
                    ));
                }
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

/// The bytes of a Parquet file, memory-mapped, for the Parquet decoder. Read from
/// memory rather than through `File` reads: a damaged page header can state a field
/// of gigabytes, which the decoder skips (or loops over element by element) with one
/// `read` call per 8 KiB even past the end of the file; from memory each of those is
/// a bounds check.
fn map_bytes(path: &Path) -> Result<bytes::Bytes> {
    let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
    // SAFETY: read only, as every reader of the input; see csv.rs.
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::input_io(path, e))?;
    Ok(bytes::Bytes::from_owner(map))
}

/// Reads a Parquet log into a new store at `target` (not yet finished).
pub(crate) fn read_parquet(
    path: &Path,
    target: &Path,
    opts: &LogOptions,
    progress: &Progress,
) -> Result<Parsed> {
    let bytes = map_bytes(path)?;
    let damaged = |what: &str| {
        Error::format(
            path,
            format!("not a readable Parquet file: the Parquet decoder failed on damaged {what}"),
        )
    };
    let builder = no_panic(|| ParquetRecordBatchReaderBuilder::try_new(bytes))
        .map_err(|()| damaged("metadata"))?
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
    // The store's space is reserved for this count before a row is read: a damaged
    // count (the fuzzer's 'PAR1' splices) must not reserve gigabytes first.
    let in_groups: i64 = builder
        .metadata()
        .row_groups()
        .iter()
        .map(|g| g.num_rows())
        .fold(0i64, i64::saturating_add);
    if in_groups != n_rows as i64 {
        return Err(Error::format(
            path,
            format!("damaged metadata: the file says {n_rows} rows, its row groups {in_groups}"),
        ));
    }
    let index: HashMap<&str, usize> = schema
        .fields()
        .iter()
        .enumerate()
        .map(|(i, f)| (f.name().as_str(), i))
        .collect();
    let indices: Vec<usize> = names.iter().map(|n| index[n.as_str()]).collect();
    let mask = ProjectionMask::roots(builder.parquet_schema(), indices);
    let mut reader = no_panic(|| {
        builder
            .with_projection(mask)
            .with_batch_size(64 * 1024)
            .build()
    })
    .map_err(|()| damaged("metadata"))?
    .map_err(|e| Error::format(path, format!("cannot read Parquet: {e}")))?;
    let batches = std::iter::from_fn(move || match no_panic(|| reader.next()) {
        Ok(b) => b,
        Err(()) => Some(Err(arrow_schema::ArrowError::ParquetError(
            "the Parquet decoder failed on damaged data".into(),
        ))),
    })
    .map(|b| {
        b.map_err(|e| {
            let msg = e.to_string();
            if !msg.contains("CRC checksum mismatch") {
                return Error::format(path, format!("cannot decode Parquet data: {msg}"));
            }
            let at = match no_panic(|| bad_page(path)).ok().flatten() {
                Some((rg, n_rg, col)) => format!(
                    "in column '{col}', row group {rg} (numbered from 0; the file has {n_rg})"
                ),
                None => "in a data page".to_string(),
            };
            Error::format(
                path,
                format!("page checksum (CRC32) mismatch {at}: the file is damaged"),
            )
        })
    });
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

/// The first page of a Parquet file whose CRC32 does not match its header's: (row
/// group, 0-based, the number of row groups, column path). Reads every page of every
/// column (the error path only: the Arrow reader says only that some page failed).
fn bad_page(path: &Path) -> Option<(usize, usize, String)> {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    let r = SerializedFileReader::new(map_bytes(path).ok()?).ok()?;
    let n_rg = r.num_row_groups();
    for rg in 0..n_rg {
        let g = r.get_row_group(rg).ok()?;
        for c in 0..g.num_columns() {
            let Ok(mut pages) = g.get_column_page_reader(c) else {
                continue;
            };
            loop {
                match pages.get_next_page() {
                    Ok(Some(_)) => {}
                    Ok(None) => break,
                    Err(e) if e.to_string().contains("CRC checksum mismatch") => {
                        return Some((rg, n_rg, g.metadata().column(c).column_path().string()));
                    }
                    Err(_) => break,
                }
            }
        }
    }
    None
}

/// Checks the framing of every IPC message of an Arrow file (`stream == false`: the
/// blocks its footer lists) or stream (the messages from the first byte) before
/// arrow-ipc decodes them: arrow-ipc trusts the lengths a file states, so a damaged
/// file could panic it (a buffer past the end of its body) or abort the process (an
/// allocation of a stated length: a body, or a compressed buffer's uncompressed
/// length). Refused here, with exit 2: a message or body past the end of the file,
/// a buffer outside its message's body, an uncompressed length beyond the machine's
/// memory.
fn check_ipc_framing(path: &Path, stream: bool) -> Result<()> {
    let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
    // SAFETY: read only, as every reader of the input; see csv.rs.
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::input_io(path, e))?;
    let what = if stream { "stream" } else { "file" };
    check_ipc_bytes(&map, stream).map_err(|m| {
        Error::format(
            path,
            format!("not a readable Arrow IPC {what}: damaged: {m}"),
        )
    })
}

/// [`check_ipc_framing`] on the bytes of a file; `Err` says what is wrong. Also the
/// check of [`crate::store::Store::open`], whose decoder trusts the lengths as much.
pub(crate) fn check_ipc_bytes(bytes: &[u8], stream: bool) -> std::result::Result<(), String> {
    let bad = |m: String| m;
    let memory = physical_memory();
    // One message at `pos`: its framing, header, body; returns the end of its body.
    let message_at = |pos: usize, end: usize| -> std::result::Result<Option<usize>, String> {
        let word = |at: usize| -> std::result::Result<i32, String> {
            bytes
                .get(at..at + 4)
                .map(|b| i32::from_le_bytes(b.try_into().expect("4 bytes")))
                .ok_or_else(|| bad(format!("a message header at byte {at} runs past the end")))
        };
        let (len, meta_start) = match word(pos)? {
            -1 => (word(pos + 4)?, pos + 8),
            n => (n, pos + 4), // the format before the continuation marker
        };
        if len == 0 {
            return Ok(None); // end of stream
        }
        let len = usize::try_from(len)
            .map_err(|_| bad(format!("negative message length at byte {pos}")))?;
        let meta_end = meta_start
            .checked_add(len)
            .filter(|e| *e <= end)
            .ok_or_else(|| bad(format!("the message at byte {pos} runs past the end")))?;
        let msg = arrow_ipc::root_as_message(&bytes[meta_start..meta_end])
            .map_err(|e| bad(format!("the message at byte {pos}: {e}")))?;
        let body_len = usize::try_from(msg.bodyLength())
            .map_err(|_| bad(format!("negative body length at byte {pos}")))?;
        let body_end = meta_end
            .checked_add(body_len)
            .filter(|e| *e <= end)
            .ok_or_else(|| {
                bad(format!(
                    "the body of the message at byte {pos} ({body_len} bytes) runs past the end"
                ))
            })?;
        let batch = msg
            .header_as_record_batch()
            .or_else(|| msg.header_as_dictionary_batch().and_then(|d| d.data()));
        if let Some(batch) = batch {
            let compressed = batch.compression().is_some();
            for b in batch.buffers().iter().flatten() {
                let (off, blen) = (b.offset(), b.length());
                let inside = usize::try_from(off)
                    .ok()
                    .zip(usize::try_from(blen).ok())
                    .and_then(|(o, l)| o.checked_add(l).map(|e| (o, e)))
                    .filter(|(_, e)| *e <= body_len);
                let Some((o, e)) = inside else {
                    return Err(bad(format!(
                        "a buffer (offset {off}, length {blen}) lies outside the {body_len}-byte body of the message at byte {pos}"
                    )));
                };
                if compressed && e - o >= 8 {
                    let at = meta_end + o;
                    let n = i64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
                    if n < -1 || n as u64 > memory {
                        return Err(bad(format!(
                            "a compressed buffer at byte {at} states an uncompressed length of {n} bytes"
                        )));
                    }
                }
            }
        }
        Ok(Some(body_end))
    };
    if stream {
        let mut pos = 0;
        while pos < bytes.len() {
            match message_at(pos, bytes.len())? {
                Some(next) => pos = next,
                None => break,
            }
        }
        return Ok(());
    }
    // the file format: ARROW1, padding, messages..., footer, footer length, ARROW1
    let len = bytes.len();
    if len < 10 + 8 {
        return Err(bad(
            "shorter than an Arrow IPC file's magic and footer".into()
        ));
    }
    let footer_len = i32::from_le_bytes(bytes[len - 10..len - 6].try_into().expect("4 bytes"));
    let footer_start = usize::try_from(footer_len)
        .ok()
        .and_then(|f| (len - 10).checked_sub(f))
        .filter(|s| *s >= 8)
        .ok_or_else(|| {
            bad(format!(
                "footer length {footer_len} past the start of the file"
            ))
        })?;
    let footer = arrow_ipc::root_as_footer(&bytes[footer_start..len - 10])
        .map_err(|e| bad(format!("the footer: {e}")))?;
    let blocks = footer
        .recordBatches()
        .into_iter()
        .flatten()
        .chain(footer.dictionaries().into_iter().flatten());
    for b in blocks {
        let (off, meta, body) = (b.offset(), b.metaDataLength(), b.bodyLength());
        let end = usize::try_from(off)
            .ok()
            .zip(usize::try_from(meta).ok())
            .zip(usize::try_from(body).ok())
            .and_then(|((o, m), b)| o.checked_add(m)?.checked_add(b))
            .filter(|e| *e <= footer_start)
            .ok_or_else(|| {
                bad(format!(
                    "a block (offset {off}, metadata {meta}, body {body} bytes) past the footer at byte {footer_start}"
                ))
            })?;
        let body_end = message_at(off as usize, end)?
            .ok_or_else(|| bad(format!("an empty message at byte {off}")))?;
        if body_end != end {
            return Err(bad(format!(
                "the block at byte {off} says {body} body bytes, its message another length"
            )));
        }
    }
    Ok(())
}

/// The machine's physical memory in bytes (the bound on a stated uncompressed length);
/// `u64::MAX` where it cannot be told.
fn physical_memory() -> u64 {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: sysconf reads a constant of the system.
        let (pages, size) = unsafe {
            (
                libc::sysconf(libc::_SC_PHYS_PAGES),
                libc::sysconf(libc::_SC_PAGESIZE),
            )
        };
        if pages > 0 && size > 0 {
            return (pages as u64).saturating_mul(size as u64);
        }
    }
    u64::MAX
}

thread_local! {
    /// Set while [`no_panic`] runs its closure: the panic hook stays quiet on this thread.
    static QUIET: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f`, a step of a foreign decoder (arrow-ipc, parquet) that may panic on damaged
/// data (the fuzzer found `Num of bytes exceed MAX_VLQ_BYTE_LEN` and `column start and
/// length should not be negative` in parquet, buffers past their body in arrow-ipc);
/// a panic becomes `Err(())` and prints nothing (the process's panic hook is wrapped
/// once to stay quiet on a thread inside `no_panic`).
pub(crate) fn no_panic<T>(f: impl FnOnce() -> T) -> std::result::Result<T, ()> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let prev = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(|q| q.get()) {
                prev(info);
            }
        }));
    });
    let was = QUIET.with(|q| q.replace(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET.with(|q| q.set(was));
    r.map_err(|_| ())
}

/// One step of arrow-ipc's decoder under [`no_panic`]: a panic (a case of damage that
/// [`check_ipc_framing`] does not catch) is an error naming the file.
fn guarded<T>(
    path: &Path,
    f: impl FnOnce() -> Option<std::result::Result<T, arrow_schema::ArrowError>>,
) -> Option<Result<T>> {
    match no_panic(f) {
        Ok(r) => {
            r.map(|r| r.map_err(|e| Error::format(path, format!("cannot decode Arrow data: {e}"))))
        }
        Err(()) => Some(Err(Error::format(
            path,
            "cannot decode Arrow data: the Arrow decoder failed on damaged data",
        ))),
    }
}

/// Reads an Arrow IPC file (of any layout) into a new store at `target`.
pub(crate) fn read_arrow(
    path: &Path,
    target: &Path,
    opts: &LogOptions,
    progress: &Progress,
) -> Result<Parsed> {
    let open = |projection: Option<Vec<usize>>| -> Result<arrow_ipc::reader::FileReader<File>> {
        let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
        let mut b = arrow_ipc::reader::FileReaderBuilder::new();
        if let Some(p) = projection {
            b = b.with_projection(p);
        }
        b.build(file)
            .map_err(|e| Error::format(path, format!("not a readable Arrow IPC file: {e}")))
    };
    check_ipc_framing(path, false)?;
    let reader = open(None)?;
    let schema = reader.schema();
    read_ipc(path, target, opts, progress, &schema, reader, |first| {
        open(Some(vec![first]))
    })
}

/// Reads an Arrow IPC stream (the format of `pyarrow.ipc.new_stream`, no footer) into a
/// new store at `target`: like [`read_arrow`], the rows counted in a first pass.
pub(crate) fn read_arrow_stream(
    path: &Path,
    target: &Path,
    opts: &LogOptions,
    progress: &Progress,
) -> Result<Parsed> {
    type Stream = arrow_ipc::reader::StreamReader<std::io::BufReader<File>>;
    let open = |projection: Option<Vec<usize>>| -> Result<Stream> {
        let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
        arrow_ipc::reader::StreamReader::try_new_buffered(file, projection)
            .map_err(|e| Error::format(path, format!("not a readable Arrow IPC stream: {e}")))
    };
    check_ipc_framing(path, true)?;
    let reader = open(None)?;
    let schema = reader.schema();
    read_ipc(path, target, opts, progress, &schema, reader, |first| {
        open(Some(vec![first]))
    })
}

/// The common part of [`read_arrow`] and [`read_arrow_stream`]: `reader` yields the
/// batches, `counter(i)` a reader of column `i` only, for the row count.
fn read_ipc<R, C>(
    path: &Path,
    target: &Path,
    opts: &LogOptions,
    progress: &Progress,
    schema: &Schema,
    reader: R,
    counter: impl FnOnce(usize) -> Result<C>,
) -> Result<Parsed>
where
    R: Iterator<Item = std::result::Result<RecordBatch, arrow_schema::ArrowError>>,
    C: Iterator<Item = std::result::Result<RecordBatch, arrow_schema::ArrowError>>,
{
    let md: HashMap<String, String> = schema
        .metadata()
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let rate_meta_hz = rate_from(&md, path)?;
    let (names, time_col) = plan(path, schema, opts)?;
    // First pass: count rows (decodes one column per batch).
    let first = schema.index_of(&names[0]).expect("planned");
    let mut n_rows = 0usize;
    let mut counter = counter(first)?;
    while let Some(b) = guarded(path, || counter.next()) {
        n_rows += b?.num_rows();
    }
    let mut reader = reader;
    let batches = std::iter::from_fn(move || guarded(path, || reader.next()));
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
