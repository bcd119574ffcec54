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
    let names: Vec<&str> = columns.iter().map(|c| c.0).collect();
    let mut w = LogWriter::create(path, format, &names, n, sample_rate_hz, provenance)?;
    let mut start = 0;
    while start < n {
        let end = (start + ROW_GROUP).min(n);
        let block: Vec<&[f64]> = columns.iter().map(|c| &c.1[start..end]).collect();
        w.write_block(&block)?;
        start = end;
    }
    w.finish()
}

/// Rows per block that [`LogWriter`] writes best: a Parquet row group.
pub const BLOCK_ROWS: usize = ROW_GROUP;

/// A simulated log written block by block, in bounded memory: the blocks of the
/// channels' values are given in order ([`LogWriter::write_block`]), each goes to the
/// temporary file (a Parquet row group or CSV lines; in a store, into the mapped file,
/// whose pages are then released), and [`LogWriter::finish`] renames it into place.
/// Dropped unfinished, the temporary file is removed. Blocks of [`BLOCK_ROWS`] rows
/// give the same file as one call with the whole columns.
pub struct LogWriter {
    path: PathBuf,
    n: usize,
    written: usize,
    rate: f64,
    sink: Sink,
}

enum Sink {
    Parquet {
        tmp: tempfile::NamedTempFile,
        w: Box<ArrowWriter<std::fs::File>>,
        schema: Arc<Schema>,
    },
    Store {
        w: Box<StoreWriter>,
        meta: Box<StoreMeta>,
    },
    Csv {
        w: std::io::BufWriter<tempfile::NamedTempFile>,
    },
}

impl LogWriter {
    /// Starts `path` (in `format`) for channels `names` of `n` rows each, with a time
    /// column, the rate and the provenance metadata.
    pub fn create(
        path: &Path,
        format: LogFormat,
        names: &[&str],
        n: usize,
        rate: f64,
        provenance: &[(&str, String)],
    ) -> Result<LogWriter> {
        let sink = match format {
            LogFormat::Parquet => {
                let tmp = temp_beside(path)?;
                let mut fields = vec![Field::new(TIME_COL, DataType::Float64, false)];
                fields.extend(
                    names
                        .iter()
                        .map(|n| Field::new(*n, DataType::Float64, false)),
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
                let file = tmp.reopen().map_err(|e| Error::output_io(path, e))?;
                let w = ArrowWriter::try_new(file, schema.clone(), Some(props))
                    .map_err(|e| parquet_io(path, e))?;
                Sink::Parquet {
                    tmp,
                    w: Box::new(w),
                    schema,
                }
            }
            LogFormat::Arrow => {
                let mut cols = vec![TIME_COL.to_string()];
                cols.extend(names.iter().map(|n| n.to_string()));
                let w = StoreWriter::create(path, &cols, n)?;
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
                Sink::Store {
                    w: Box::new(w),
                    meta: Box::new(meta),
                }
            }
            LogFormat::Csv => {
                let tmp = temp_beside(path)?;
                let io = |e: std::io::Error| Error::output_io(path, e);
                let mut w = std::io::BufWriter::with_capacity(1 << 20, tmp);
                write!(w, "# farma simulate: sample_rate_hz={rate}").map_err(io)?;
                for (k, v) in provenance {
                    write!(w, " {k}={}", v.replace('\n', " ")).map_err(io)?;
                }
                writeln!(w).map_err(io)?;
                write!(w, "{TIME_COL}").map_err(io)?;
                for name in names {
                    write!(w, ",{name}").map_err(io)?;
                }
                writeln!(w).map_err(io)?;
                Sink::Csv { w }
            }
        };
        Ok(LogWriter {
            path: path.to_path_buf(),
            n,
            written: 0,
            rate,
            sink,
        })
    }

    /// Writes the next rows: one slice per channel, all of one length.
    pub fn write_block(&mut self, block: &[&[f64]]) -> Result<()> {
        let len = block.first().map_or(0, |c| c.len());
        let start = self.written;
        if block.iter().any(|c| c.len() != len) || start + len > self.n {
            return Err(Error::Internal("simulated block of a wrong length".into()));
        }
        let rate = self.rate;
        let time = |k: usize| k as f64 / rate;
        let path = &self.path;
        match &mut self.sink {
            Sink::Parquet { w, schema, .. } => {
                let mut arrays: Vec<ArrayRef> = vec![Arc::new(Float64Array::from_iter_values(
                    (start..start + len).map(time),
                ))];
                arrays.extend(
                    block
                        .iter()
                        .map(|v| Arc::new(Float64Array::from(v.to_vec())) as ArrayRef),
                );
                let batch = RecordBatch::try_new(schema.clone(), arrays)
                    .map_err(|e| Error::Internal(format!("simulated table: {e}")))?;
                w.write(&batch).map_err(|e| parquet_io(path, e))?;
            }
            Sink::Store { w, .. } => {
                {
                    let mut cols = w.columns_mut();
                    for (k, v) in cols[0][start..start + len].iter_mut().enumerate() {
                        *v = time(start + k);
                    }
                    for (dst, src) in cols.iter_mut().skip(1).zip(block) {
                        dst[start..start + len].copy_from_slice(src);
                    }
                }
                // the written pages go to the file, not the process's memory
                w.release_rows(start..start + len);
            }
            Sink::Csv { w } => {
                let io = |e: std::io::Error| Error::output_io(path, e);
                for j in 0..len {
                    write!(w, "{:?}", time(start + j)).map_err(io)?;
                    for v in block {
                        write!(w, ",{:?}", v[j]).map_err(io)?;
                    }
                    writeln!(w).map_err(io)?;
                }
            }
        }
        self.written += len;
        Ok(())
    }

    /// Completes the file (after every row is written) and renames it into place.
    pub fn finish(self) -> Result<()> {
        if self.written != self.n {
            return Err(Error::Internal(format!(
                "simulated log of {} rows finished after {}",
                self.n, self.written
            )));
        }
        let path = &self.path;
        match self.sink {
            Sink::Parquet { tmp, w, .. } => {
                w.close().map_err(|e| parquet_io(path, e))?;
                tmp.persist(path)
                    .map_err(|e| Error::output_io(path, e.error))?;
            }
            Sink::Store { w, meta } => w.finish(&meta)?,
            Sink::Csv { w } => {
                let tmp = w
                    .into_inner()
                    .map_err(|e| Error::output_io(path, e.into_error()))?;
                tmp.persist(path)
                    .map_err(|e| Error::output_io(path, e.error))?;
            }
        }
        Ok(())
    }
}

fn parquet_io(path: &Path, e: parquet::errors::ParquetError) -> Error {
    Error::output_io(path, std::io::Error::other(e))
}
