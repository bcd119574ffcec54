//! The stores' per-column checksums: written by every conversion, checked when a cached
//! store is used again (a damaged or truncated one is converted again, with a note) and
//! on request for a store the user names ([`Store::verify`]); concurrent conversions of
//! one log into one cache.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{farma, fixture, stderr, stdout};
use arrow_array::{Array, Float64Array};
use farma::error::Error;
use farma::log::{LogOptions, Progress, ingest};
use farma::store::{CHECKSUM_KEY, Store};

/// The one store in a cache folder.
fn cached_store(cache: &Path) -> PathBuf {
    let stores: Vec<PathBuf> = std::fs::read_dir(cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "arrow"))
        .collect();
    assert_eq!(stores.len(), 1, "{stores:?}");
    stores.into_iter().next().unwrap()
}

/// Byte offset in the file of the values of column `name`.
fn column_offset(store: &Path, name: &str) -> usize {
    let first: Vec<u8> = {
        let s = Store::open(store).unwrap();
        s.column_with_nonfinite(name).unwrap()[..8]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect()
    };
    let bytes = std::fs::read(store).unwrap();
    let at: Vec<usize> = bytes
        .windows(first.len())
        .enumerate()
        .filter(|(_, w)| *w == first.as_slice())
        .map(|(i, _)| i)
        .collect();
    assert_eq!(
        at.len(),
        1,
        "column {name}'s first values found {} times",
        at.len()
    );
    at[0]
}

/// Flips (xor 0xff) 64 bytes from `offset` on.
fn flip_64(path: &Path, offset: usize) {
    let mut bytes = std::fs::read(path).unwrap();
    for b in &mut bytes[offset..offset + 64] {
        *b ^= 0xff;
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn damaged_cached_store_is_reconverted() {
    let cache = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.parquet");
    let log = log.to_str().unwrap();
    let first = farma(&["info", log, "--json"], cache.path());
    assert_eq!(first.status.code(), Some(0), "{}", stderr(&first));
    assert!(!stderr(&first).contains("note"), "{}", stderr(&first));
    let store = cached_store(cache.path());
    flip_64(&store, column_offset(&store, "gyro_y") + 800);

    let again = farma(&["info", log, "--json"], cache.path());
    assert_eq!(again.status.code(), Some(0), "{}", stderr(&again));
    assert_eq!(stdout(&again), stdout(&first), "the damaged store was used");
    let err = stderr(&again);
    assert!(
        err.contains("farma: note:") && err.contains("damaged") && err.contains("reconverted"),
        "{err}"
    );
    assert!(err.contains("gyro_y"), "the note names the column: {err}");
    // the entry was replaced by a good one: the next run uses it without a note
    Store::open(&cached_store(cache.path()))
        .unwrap()
        .verify()
        .unwrap();
    let third = farma(&["info", log, "--json"], cache.path());
    assert_eq!(stdout(&third), stdout(&first));
    assert!(!stderr(&third).contains("note"), "{}", stderr(&third));
}

#[test]
fn truncated_cached_store_is_reconverted() {
    let cache = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let log = log.to_str().unwrap();
    let first = farma(&["info", log, "--json"], cache.path());
    assert_eq!(first.status.code(), Some(0), "{}", stderr(&first));
    let store = cached_store(cache.path());
    let len = std::fs::metadata(&store).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&store)
        .unwrap()
        .set_len(len / 2)
        .unwrap();

    let again = farma(&["info", log, "--json"], cache.path());
    assert_eq!(again.status.code(), Some(0), "{}", stderr(&again));
    assert_eq!(stdout(&again), stdout(&first));
    let err = stderr(&again);
    assert!(
        err.contains("farma: note:") && err.contains("reconverted"),
        "{err}"
    );
    assert_eq!(
        std::fs::metadata(cached_store(cache.path())).unwrap().len(),
        len
    );
}

#[test]
fn verify_of_a_damaged_ingested_store_names_the_column() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.arrow");
    ingest(
        &fixture("multiaxis.csv"),
        &path,
        &LogOptions::default(),
        &Progress::hidden(),
    )
    .unwrap();
    Store::open(&path).unwrap().verify().unwrap();
    flip_64(&path, column_offset(&path, "gyro_z") + 1000);

    // opening a store the user names does not read it: today's behaviour stays
    let s = Store::open(&path).unwrap();
    assert_eq!(s.column("gyro_z").unwrap().len(), 4000);
    s.verify_columns(&["gyro_x", "temp_c"]).unwrap();
    let e = s.verify().unwrap_err();
    assert!(matches!(e, Error::Column { .. }), "{e:?}");
    assert_eq!(e.exit_code(), 2);
    let msg = e.to_string();
    assert!(msg.contains("'gyro_z'"), "{msg}");
    assert!(msg.contains(path.to_str().unwrap()), "{msg}");
    assert!(msg.contains("damaged"), "{msg}");
    let e = s.verify_columns(&["gyro_z"]).unwrap_err();
    assert!(e.to_string().contains("'gyro_z'"), "{e}");
}

#[test]
fn checksums_are_xxh64_of_each_column_in_the_schema_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.arrow");
    ingest(
        &fixture("multiaxis.parquet"),
        &path,
        &LogOptions::default(),
        &Progress::hidden(),
    )
    .unwrap();
    // read with the arrow crate, as any Arrow tool would
    let reader =
        arrow_ipc::reader::FileReader::try_new(std::fs::File::open(&path).unwrap(), None).unwrap();
    let schema = reader.schema();
    let sums: std::collections::HashMap<String, String> =
        serde_json::from_str(schema.metadata().get(CHECKSUM_KEY).unwrap()).unwrap();
    let batch = reader.into_iter().next().unwrap().unwrap();
    assert_eq!(sums.len(), batch.num_columns());
    for (i, f) in schema.fields().iter().enumerate() {
        let a = batch
            .column(i)
            .as_any()
            .downcast_ref::<Float64Array>()
            .unwrap();
        assert_eq!(a.null_count(), 0);
        let bytes: Vec<u8> = a.values().iter().flat_map(|v| v.to_le_bytes()).collect();
        let want = format!("{:016x}", twox_hash::XxHash64::oneshot(0, &bytes));
        assert_eq!(sums[f.name()], want, "column {}", f.name());
    }
}

#[test]
fn concurrent_conversions_into_one_cache_both_end_good() {
    let log = fixture("multiaxis.csv");
    let log = log.to_str().unwrap();
    let alone = tempfile::tempdir().unwrap();
    let want = farma(&["info", log, "--json"], alone.path());
    assert_eq!(want.status.code(), Some(0), "{}", stderr(&want));
    for _round in 0..3 {
        let cache = tempfile::tempdir().unwrap();
        let spawn = || {
            Command::new(env!("CARGO_BIN_EXE_farma"))
                .args(["info", log, "--json"])
                .env("FARMA_CACHE_DIR", cache.path())
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (a, b) = (spawn(), spawn());
        for o in [a.wait_with_output().unwrap(), b.wait_with_output().unwrap()] {
            assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
            assert_eq!(stdout(&o), stdout(&want));
            assert!(!stderr(&o).contains("note"), "{}", stderr(&o));
        }
        // one good entry, no temporary file left
        let names: Vec<String> = std::fs::read_dir(cache.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        Store::open(&cached_store(cache.path()))
            .unwrap()
            .verify()
            .unwrap();
    }
}

/// `Store::release` drops a column's resident pages and nothing else: the column reads
/// back the same bytes, its neighbours and the checksums are untouched, and a slice
/// that is not the store's is left alone.
#[test]
fn a_released_column_reads_back_the_same_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.arrow");
    let n = 200_000;
    let x: Vec<f64> = (0..n).map(|i| ((i as f64) * 0.37).sin() * 1e3).collect();
    let t: Vec<f64> = (0..n).map(|i| i as f64 / 100.0).collect();
    let csv = dir.path().join("s.csv");
    let mut text = String::from("time_s,x\n");
    for i in 0..n {
        text.push_str(&format!("{},{}\n", t[i], x[i]));
    }
    std::fs::write(&csv, text).unwrap();
    let o = farma(
        &[
            "ingest",
            csv.to_str().unwrap(),
            "-o",
            path.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let store = Store::open(&path).unwrap();
    let col = store.column("x").unwrap();
    let before: Vec<f64> = col.to_vec();
    let time_before: Vec<f64> = store.column_with_nonfinite("time_s").unwrap().to_vec();
    store.release(col);
    store.release(&before); // not the store's: ignored
    assert!(
        col.iter()
            .zip(&before)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    assert_eq!(
        store.column_with_nonfinite("time_s").unwrap(),
        &time_before[..]
    );
    store.verify().unwrap();
    assert_eq!(before[12_345], x[12_345]);
}
