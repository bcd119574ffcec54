//! Parquet page checksums: a page whose CRC32 (written by pyarrow's
//! `write_page_checksum=True`, fixtures/foreign/crc.parquet) does not match its bytes is
//! refused with exit 2, naming the file, the column and the row group. Before, the
//! reader skipped the check (the parquet crate's `crc` feature was off) and a flipped
//! byte gave exit 0 with changed statistics.

use crate::common::{farma, fixture, stderr, stdout};

/// crc.parquet with one byte of `gyro_x`'s data flipped: the bytes of its value at
/// row 2 (plain encoding, no compression: verbatim in the page).
fn damaged(dir: &std::path::Path) -> std::path::PathBuf {
    let mut bytes = std::fs::read(fixture("foreign/crc.parquet")).unwrap();
    let want = gyro_x_row(2).to_le_bytes();
    let at: Vec<usize> = bytes
        .windows(8)
        .enumerate()
        .filter(|(_, w)| *w == want)
        .map(|(i, _)| i)
        .collect();
    assert_eq!(at.len(), 1, "gyro_x[2] found {} times", at.len());
    bytes[at[0] + 3] ^= 0x10;
    let p = dir.join("crc_bad.parquet");
    std::fs::write(&p, bytes).unwrap();
    p
}

/// gyro_x at `row` as fixtures/foreign/make_foreign.py wrote it.
fn gyro_x_row(row: usize) -> f64 {
    use arrow_array::{Array, Float64Array};
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let f = std::fs::File::open(fixture("foreign/crc.parquet")).unwrap();
    let b = ParquetRecordBatchReaderBuilder::try_new(f)
        .unwrap()
        .build()
        .unwrap()
        .next()
        .unwrap()
        .unwrap();
    let col = b.column_by_name("gyro_x").unwrap();
    let a = col.as_any().downcast_ref::<Float64Array>().unwrap();
    assert!(a.len() > row);
    a.value(row)
}

#[test]
fn the_intact_file_with_page_checksums_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let o = farma(
        &[
            "info",
            fixture("foreign/crc.parquet").to_str().unwrap(),
            "--no-cache",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("samples   200"), "{}", stdout(&o));
}

#[test]
fn a_flipped_byte_in_a_data_page_is_exit_2_naming_file_column_and_row_group() {
    let dir = tempfile::tempdir().unwrap();
    let bad = damaged(dir.path());
    for extra in [
        &["--no-cache"][..],
        &["--cache-dir", dir.path().join("c").to_str().unwrap()],
    ] {
        let mut args = vec!["info", bad.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = farma(&args, &dir.path().join("c"));
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains("crc_bad.parquet"), "{e}");
        assert!(e.contains("page checksum (CRC32) mismatch"), "{e}");
        assert!(e.contains("column 'gyro_x'"), "{e}");
        assert!(e.contains("row group 0"), "{e}");
        assert_eq!(stdout(&o), "");
    }
    // and `ingest` writes nothing
    let out = dir.path().join("x.arrow");
    let o = farma(
        &["ingest", bad.to_str().unwrap(), "-o", out.to_str().unwrap()],
        &dir.path().join("c"),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!out.exists());
}
