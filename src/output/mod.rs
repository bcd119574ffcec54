//! Outputs: tables written atomically as Parquet for analytics tools (DuckDB, pandas,
//! Spark), and small helpers for the `--json` lines on stdout.
//!
//! Every file is written to a temporary file in the target's folder and renamed into
//! place, so a reader never sees half a file and a failed run leaves nothing behind.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{ArrayRef, RecordBatch};
use arrow_schema::{Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;

use crate::error::{Error, Result};

/// Creates `dir` (and parents) for outputs.
pub fn ensure_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::output_io(dir, e))
}

/// Builds a batch from named columns (all of equal length).
pub fn batch(columns: Vec<(&str, ArrayRef)>) -> Result<RecordBatch> {
    let fields: Vec<Field> = columns
        .iter()
        .map(|(n, a)| Field::new(*n, a.data_type().clone(), a.null_count() > 0))
        .collect();
    let arrays: Vec<ArrayRef> = columns.into_iter().map(|(_, a)| a).collect();
    RecordBatch::try_new(Arc::new(Schema::new(fields)), arrays)
        .map_err(|e| Error::Internal(format!("output table: {e}")))
}

/// Writes `text` to `path` atomically (a temporary file beside it, then a rename).
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    use std::io::Write;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".farma-")
        .suffix(".tmp")
        .permissions(crate::store::output_permissions())
        .tempfile_in(&dir)
        .map_err(|e| Error::output_io(path, e))?;
    tmp.write_all(text.as_bytes())
        .and_then(|_| tmp.flush())
        .map_err(|e| Error::output_io(path, e))?;
    tmp.persist(path)
        .map_err(|e| Error::output_io(path, e.error))?;
    Ok(())
}

/// Writes `batch` to `path` as zstd Parquet with key-value metadata, atomically.
pub fn write_parquet(path: &Path, batch: &RecordBatch, metadata: &[(&str, String)]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".farma-")
        .suffix(".tmp")
        .permissions(crate::store::output_permissions())
        .tempfile_in(&dir)
        .map_err(|e| Error::output_io(path, e))?;
    let mut kv: Vec<KeyValue> = metadata
        .iter()
        .map(|(k, v)| KeyValue::new(k.to_string(), v.clone()))
        .collect();
    kv.push(KeyValue::new(
        "farma_version".into(),
        env!("CARGO_PKG_VERSION").to_string(),
    ));
    let props = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::default()))
        .set_key_value_metadata(Some(kv))
        .build();
    let file = tmp.reopen().map_err(|e| Error::output_io(path, e))?;
    let mut w = ArrowWriter::try_new(file, batch.schema(), Some(props))
        .map_err(|e| Error::output_io(path, std::io::Error::other(e)))?;
    w.write(batch)
        .map_err(|e| Error::output_io(path, std::io::Error::other(e)))?;
    w.close()
        .map_err(|e| Error::output_io(path, std::io::Error::other(e)))?;
    tmp.persist(path)
        .map_err(|e| Error::output_io(path, e.error))?;
    Ok(())
}
