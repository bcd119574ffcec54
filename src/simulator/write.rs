//! Writes a simulated log: a time column `time` (t_k = k / sample_rate_hz, seconds)
//! and one column per channel, in the format named by the file's extension:
//! `.parquet` (zstd, row groups of 1M rows, `sample_rate_hz` and provenance in the
//! key-value metadata), `.arrow` (a farma store, memory-mapped by every command, rate
//! and provenance in the schema metadata), `.csv` (comma separated, a `#` provenance
//! line, then the header; numbers in Rust's shortest round-trip form, so they read
//! back exactly). Every format is written to a temporary file beside the
//! target and renamed into place, so a failed run leaves nothing behind.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;

use crate::error::{Error, Result};
use crate::store::{STORE_FORMAT_VERSION, Segment, StoreMeta, StoreWriter};

/// Name of the time column of a simulated log.
pub const TIME_COL: &str = "time";
/// Rows per Parquet row group (and per write batch).
const ROW_GROUP: usize = 1 << 20;

/// Output formats of a simulated log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    Parquet,
    Arrow,
    Csv,
}

impl LogFormat {
    /// The format named by `path`'s extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<LogFormat> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("parquet") => Ok(LogFormat::Parquet),
            Some("arrow") => Ok(LogFormat::Arrow),
            Some("csv") => Ok(LogFormat::Csv),
            _ => Err(Error::Usage(format!(
                "{}: cannot tell the output format from the extension; use .parquet, .arrow (a farma store) or .csv",
                path.display()
            ))),
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            LogFormat::Parquet => "parquet",
            LogFormat::Arrow => "arrow",
            LogFormat::Csv => "csv",
        }
    }
}

fn temp_beside(path: &Path) -> Result<tempfile::NamedTempFile> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    crate::output::temp_in(&dir, path)
}

/// Writes `columns` (name, values; all of one length) with a leading time column to
/// `path` in `format`, with `sample_rate_hz` and `provenance` (key, value) metadata.
pub fn write_log(
    path: &Path,
    format: LogFormat,
    columns: &[(&str, &[f64])],
    sample_rate_hz: f64,
    provenance: &[(&str, String)],
) -> Result<()> {
    let n = columns.first().map_or(0, |c| c.1.len());
    if columns.iter().any(|c| c.1.len() != n) {
        return Err(Error::Internal(
            "simulated columns of different lengths".into(),
        ));
    }
    let time = |k: usize| k as f64 / sample_rate_hz;
    match format {
        LogFormat::Parquet => write_parquet(path, columns, n, sample_rate_hz, provenance, &time),
        LogFormat::Arrow => write_store(path, columns, n, sample_rate_hz, provenance, &time),
        LogFormat::Csv => write_csv(path, columns, n, sample_rate_hz, provenance, &time),
    }
}

fn write_parquet(
    path: &Path,
    columns: &[(&str, &[f64])],
    n: usize,
    rate: f64,
    provenance: &[(&str, String)],
    time: &dyn Fn(usize) -> f64,
) -> Result<()> {
    let tmp = temp_beside(path)?;
    let mut fields = vec![Field::new(TIME_COL, DataType::Float64, false)];
    fields.extend(
        columns
            .iter()
            .map(|(n, _)| Field::new(*n, DataType::Float64, false)),
    );
    let schema = Arc::new(Schema::new(fields));
    let mut kv = vec![
        KeyValue::new("sample_rate_hz".into(), rate.to_string()),
        KeyValue::new(
            "farma_version".into(),
            env!("CARGO_PKG_VERSION").to_string(),
        ),
    ];
    kv.extend(
        provenance
            .iter()
            .map(|(k, v)| KeyValue::new(k.to_string(), v.clone())),
    );
    let props = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::default()))
        .set_max_row_group_row_count(Some(ROW_GROUP))
        .set_key_value_metadata(Some(kv))
        .build();
    let io = |e: parquet::errors::ParquetError| Error::output_io(path, std::io::Error::other(e));
    let file = tmp.reopen().map_err(|e| Error::output_io(path, e))?;
    let mut w = ArrowWriter::try_new(file, schema.clone(), Some(props)).map_err(io)?;
    let mut start = 0;
    while start < n {
        let end = (start + ROW_GROUP).min(n);
        let mut arrays: Vec<ArrayRef> = vec![Arc::new(Float64Array::from_iter_values(
            (start..end).map(time),
        ))];
        arrays.extend(
            columns
                .iter()
                .map(|(_, v)| Arc::new(Float64Array::from(v[start..end].to_vec())) as ArrayRef),
        );
        let batch = RecordBatch::try_new(schema.clone(), arrays)
            .map_err(|e| Error::Internal(format!("simulated table: {e}")))?;
        w.write(&batch).map_err(io)?;
        start = end;
    }
    w.close().map_err(io)?;
    tmp.persist(path)
        .map_err(|e| Error::output_io(path, e.error))?;
    Ok(())
}

fn write_store(
    path: &Path,
    columns: &[(&str, &[f64])],
    n: usize,
    rate: f64,
    provenance: &[(&str, String)],
    time: &dyn Fn(usize) -> f64,
) -> Result<()> {
    let mut names = vec![TIME_COL.to_string()];
    names.extend(columns.iter().map(|(n, _)| n.to_string()));
    let mut w = StoreWriter::create(path, &names, n)?;
    {
        let mut cols = w.columns_mut();
        for (k, v) in cols[0].iter_mut().enumerate() {
            *v = time(k);
        }
        for (dst, (_, src)) in cols.iter_mut().skip(1).zip(columns) {
            dst.copy_from_slice(src);
        }
    }
    let source = provenance
        .iter()
        .find(|(k, _)| *k == "source")
        .map_or_else(String::new, |(_, v)| v.clone());
    let meta = StoreMeta {
        format_version: STORE_FORMAT_VERSION,
        farma_version: env!("CARGO_PKG_VERSION").to_string(),
        sample_rate_hz: rate,
        time_source: format!("column:{TIME_COL}"),
        time_col: Some(TIME_COL.to_string()),
        segments: vec![Segment {
            start: 0,
            len: n as u64,
            t0_s: 0.0,
        }],
        repairs: vec![],
        source,
        source_format: "simulate".into(),
        source_size: 0,
        source_mtime_ns: 0,
        nonfinite: vec![],
    };
    w.finish(&meta)
}

fn write_csv(
    path: &Path,
    columns: &[(&str, &[f64])],
    n: usize,
    rate: f64,
    provenance: &[(&str, String)],
    time: &dyn Fn(usize) -> f64,
) -> Result<()> {
    let tmp = temp_beside(path)?;
    let io = |e: std::io::Error| Error::output_io(path, e);
    {
        let mut w = std::io::BufWriter::with_capacity(1 << 20, tmp.as_file());
        write!(w, "# farma simulate: sample_rate_hz={rate}").map_err(io)?;
        for (k, v) in provenance {
            write!(w, " {k}={}", v.replace('\n', " ")).map_err(io)?;
        }
        writeln!(w).map_err(io)?;
        write!(w, "{TIME_COL}").map_err(io)?;
        for (name, _) in columns {
            write!(w, ",{name}").map_err(io)?;
        }
        writeln!(w).map_err(io)?;
        for k in 0..n {
            write!(w, "{:?}", time(k)).map_err(io)?;
            for (_, v) in columns {
                write!(w, ",{:?}", v[k]).map_err(io)?;
            }
            writeln!(w).map_err(io)?;
        }
        w.flush().map_err(io)?;
    }
    tmp.persist(path)
        .map_err(|e| Error::output_io(path, e.error))?;
    Ok(())
}
