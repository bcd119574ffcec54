//! The manifest of a batch dataset: one row per unit (log, task) with the log's path
//! and fingerprint, the task, the options hash, the status (`done`, `failed`,
//! `skipped`), the error, the start and end times, the farma version and commit and the dataset
//! files the unit wrote.
//!
//! Each unit's row is its own file, `ROOT/_manifest/<unit>.parquet`, written
//! atomically when the unit ends: shards sharing one root never write the same file,
//! and a row exists only for a unit that ended. `ROOT/manifest.parquet` is the union
//! of those rows, rewritten (atomically) at the end of every run.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, Int64Array, RecordBatch, StringArray, UInt64Array};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use crate::error::{Error, Result};
use crate::output::{batch, write_parquet};

/// The folder of the per-unit rows.
pub const MANIFEST_DIR: &str = "_manifest";
/// The union of the rows.
pub const MANIFEST_FILE: &str = "manifest.parquet";

/// A unit's status.
pub const DONE: &str = "done";
pub const FAILED: &str = "failed";
pub const SKIPPED: &str = "skipped";

/// One row of the manifest.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub unit: String,
    pub log_id: String,
    pub log_path: String,
    pub task: String,
    pub kind: String,
    pub log_size: u64,
    pub log_mtime_ns: i64,
    /// xxHash64 of the log's first and last MiB.
    pub log_hash: String,
    pub options_hash: String,
    pub status: String,
    /// The error of a failed unit, the reason of a skipped one; empty when done.
    pub error: String,
    /// Unix seconds.
    pub started_unix_s: f64,
    pub finished_unix_s: f64,
    pub farma_version: String,
    /// The git commit the binary was built from ("unknown" outside a checkout).
    pub farma_commit: String,
    /// The dataset files the unit wrote, relative to the root, `;`-separated.
    pub files: String,
}

/// The path of `unit`'s row under `root`.
pub fn row_path(root: &Path, unit: &str) -> PathBuf {
    root.join(MANIFEST_DIR).join(format!("{unit}.parquet"))
}

/// The rows as one table.
pub fn table(rows: &[&Row]) -> Result<RecordBatch> {
    let s = |f: &dyn Fn(&Row) -> &str| -> ArrayRef {
        Arc::new(StringArray::from(
            rows.iter().map(|r| f(r)).collect::<Vec<_>>(),
        ))
    };
    let f = |g: &dyn Fn(&Row) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from(
            rows.iter().map(|r| g(r)).collect::<Vec<_>>(),
        ))
    };
    batch(vec![
        ("unit", s(&|r| &r.unit)),
        ("log_id", s(&|r| &r.log_id)),
        ("log_path", s(&|r| &r.log_path)),
        ("task", s(&|r| &r.task)),
        ("kind", s(&|r| &r.kind)),
        (
            "log_size",
            Arc::new(UInt64Array::from(
                rows.iter().map(|r| r.log_size).collect::<Vec<_>>(),
            )),
        ),
        (
            "log_mtime_ns",
            Arc::new(Int64Array::from(
                rows.iter().map(|r| r.log_mtime_ns).collect::<Vec<_>>(),
            )),
        ),
        ("log_hash", s(&|r| &r.log_hash)),
        ("options_hash", s(&|r| &r.options_hash)),
        ("status", s(&|r| &r.status)),
        ("error", s(&|r| &r.error)),
        ("started_unix_s", f(&|r| r.started_unix_s)),
        ("finished_unix_s", f(&|r| r.finished_unix_s)),
        ("farma_version", s(&|r| &r.farma_version)),
        ("farma_commit", s(&|r| &r.farma_commit)),
        ("files", s(&|r| &r.files)),
    ])
}

/// Writes `row` as its unit's manifest file (atomically).
pub fn write_row(root: &Path, row: &Row) -> Result<()> {
    let path = row_path(root, &row.unit);
    std::fs::create_dir_all(path.parent().expect("a folder"))
        .map_err(|e| Error::output_io(&path, e))?;
    write_parquet(&path, &table(&[row])?, &[])
}

/// Every unit's row under `root` (none when there is no manifest yet), by unit. A row
/// file that cannot be read is an error naming it.
pub fn read_rows(root: &Path) -> Result<Vec<Row>> {
    let dir = root.join(MANIFEST_DIR);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Ok(Vec::new());
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "parquet"))
        .collect();
    paths.sort();
    let mut rows = Vec::new();
    for p in paths {
        rows.extend(read_file(&p)?);
    }
    rows.sort_by(|a, b| a.unit.cmp(&b.unit));
    Ok(rows)
}

fn read_file(path: &Path) -> Result<Vec<Row>> {
    let bad = |m: String| Error::format(path, format!("not a farma batch manifest row: {m}"));
    let file = std::fs::File::open(path).map_err(|e| Error::input_io(path, e))?;
    let reader = ParquetRecordBatchReaderBuilder::try_new(file)
        .map_err(|e| bad(e.to_string()))?
        .build()
        .map_err(|e| bad(e.to_string()))?;
    let mut out = Vec::new();
    for b in reader {
        let b = b.map_err(|e| bad(e.to_string()))?;
        let col = |name: &str| {
            b.column_by_name(name)
                .ok_or_else(|| bad(format!("no column '{name}'")))
        };
        let st = |name: &str| -> Result<StringArray> {
            col(name)?
                .as_any()
                .downcast_ref::<StringArray>()
                .cloned()
                .ok_or_else(|| bad(format!("column '{name}' is not text")))
        };
        let fl = |name: &str| -> Result<Float64Array> {
            col(name)?
                .as_any()
                .downcast_ref::<Float64Array>()
                .cloned()
                .ok_or_else(|| bad(format!("column '{name}' is not float64")))
        };
        let (unit, log_id, log_path, task, kind) = (
            st("unit")?,
            st("log_id")?,
            st("log_path")?,
            st("task")?,
            st("kind")?,
        );
        let size = col("log_size")?
            .as_any()
            .downcast_ref::<UInt64Array>()
            .cloned()
            .ok_or_else(|| bad("column 'log_size' is not uint64".into()))?;
        let mtime = col("log_mtime_ns")?
            .as_any()
            .downcast_ref::<Int64Array>()
            .cloned()
            .ok_or_else(|| bad("column 'log_mtime_ns' is not int64".into()))?;
        let (hash, opts, status, error, version, files) = (
            st("log_hash")?,
            st("options_hash")?,
            st("status")?,
            st("error")?,
            st("farma_version")?,
            st("files")?,
        );
        let (t0, t1) = (fl("started_unix_s")?, fl("finished_unix_s")?);
        // (rows written before the column existed have none)
        let commit = b
            .column_by_name("farma_commit")
            .and_then(|c| c.as_any().downcast_ref::<StringArray>().cloned());
        for i in 0..b.num_rows() {
            out.push(Row {
                unit: unit.value(i).into(),
                log_id: log_id.value(i).into(),
                log_path: log_path.value(i).into(),
                task: task.value(i).into(),
                kind: kind.value(i).into(),
                log_size: size.value(i),
                log_mtime_ns: mtime.value(i),
                log_hash: hash.value(i).into(),
                options_hash: opts.value(i).into(),
                status: status.value(i).into(),
                error: error.value(i).into(),
                started_unix_s: t0.value(i),
                finished_unix_s: t1.value(i),
                farma_version: version.value(i).into(),
                farma_commit: commit
                    .as_ref()
                    .map_or_else(String::new, |c| c.value(i).to_string()),
                files: files.value(i).into(),
            });
        }
    }
    Ok(out)
}

/// Rewrites `ROOT/manifest.parquet` as the union of the unit rows (atomically).
pub fn write_union(root: &Path) -> Result<usize> {
    let rows = read_rows(root)?;
    let refs: Vec<&Row> = rows.iter().collect();
    write_parquet(&root.join(MANIFEST_FILE), &table(&refs)?, &[])?;
    Ok(rows.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let row = Row {
            unit: "a.fit".into(),
            log_id: "a".into(),
            log_path: "/x/a.csv".into(),
            task: "fit".into(),
            kind: "fit".into(),
            log_size: 12,
            log_mtime_ns: -3,
            log_hash: "00ff".into(),
            options_hash: "abcd".into(),
            status: DONE.into(),
            error: String::new(),
            started_unix_s: 1.5,
            finished_unix_s: 2.5,
            farma_version: "0".into(),
            farma_commit: "abc".into(),
            files: "coef/task=fit/log_id=a/part-0.parquet".into(),
        };
        write_row(dir.path(), &row).unwrap();
        assert_eq!(read_rows(dir.path()).unwrap(), vec![row]);
        assert_eq!(write_union(dir.path()).unwrap(), 1);
    }
}
