//! Shared test helpers: the fixture generator and a runner for the binary.

pub mod fixtures_gen;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The project root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A path under `fixtures/`.
pub fn fixture(rel: &str) -> PathBuf {
    root().join("fixtures").join(rel)
}

/// The real-data folder beside the project, if present.
pub fn realdata(rel: &str) -> Option<PathBuf> {
    let p = root().join("..").join("shared").join("realdata").join(rel);
    p.exists().then_some(p)
}

/// Runs the `farma` binary with `args`, a private cache folder and no terminal.
pub fn farma(args: &[&str], cache: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_farma"))
        .args(args)
        .env("FARMA_CACHE_DIR", cache)
        .output()
        .expect("run farma")
}

/// A run given `-o FILE` (a file, not a folder) was refused before its work: exit 2,
/// "not a folder" on stderr, nothing on stdout, the file still holding `kept`.
pub fn assert_refused_file_output(o: &Output, file: &Path, kept: &str) {
    assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
    assert!(stderr(o).contains("not a folder"), "{}", stderr(o));
    assert_eq!(stdout(o), "", "the work ran");
    assert_eq!(std::fs::read_to_string(file).unwrap(), kept);
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Parses a simple comma-separated numeric CSV the slow, obvious way: the reference
/// the parallel parser is checked against. Skips `#` lines; returns (names, columns).
pub fn reference_parse_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let names: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(|s| s.trim().to_string())
        .collect();
    let mut cols = vec![Vec::new(); names.len()];
    for l in lines {
        for (c, f) in cols.iter_mut().zip(l.split(',')) {
            c.push(f.trim().parse::<f64>().unwrap());
        }
    }
    (names, cols)
}

/// A log opened with the default options into a store cached in a fresh temporary
/// folder (returned too: the store lives while it does).
pub fn open_store(path: &Path) -> (tempfile::TempDir, farma::store::Store) {
    use farma::log::{CachePolicy, LogOptions, Progress, open_log};
    let cache = tempfile::tempdir().unwrap();
    let store = open_log(
        path,
        &LogOptions::default(),
        &CachePolicy::Dir(cache.path().to_path_buf()),
        &Progress::hidden(),
    )
    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (cache, store)
}

/// A whole Parquet file as one record batch (every batch the reader gives, concatenated).
pub fn parquet_table(path: &Path) -> arrow_array::RecordBatch {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let f = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let b = ParquetRecordBatchReaderBuilder::try_new(f).unwrap();
    let schema = b.schema().clone();
    let batches: Vec<arrow_array::RecordBatch> = b.build().unwrap().map(|r| r.unwrap()).collect();
    arrow_select::concat::concat_batches(&schema, &batches).unwrap()
}

/// The string column `col` of a Parquet file, every row.
pub fn parquet_strings(path: &Path, col: &str) -> Vec<String> {
    use arrow_array::{Array, StringArray};
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out = Vec::new();
    for b in ParquetRecordBatchReaderBuilder::try_new(file)
        .unwrap()
        .build()
        .unwrap()
    {
        let b = b.unwrap();
        let a = b
            .column_by_name(col)
            .unwrap_or_else(|| panic!("{}: no column {col}", path.display()));
        let s = a
            .as_any()
            .downcast_ref::<StringArray>()
            .expect("a string column");
        out.extend((0..s.len()).map(|i| s.value(i).to_string()));
    }
    out
}
