//! Every Arrow IPC file a user's tools write (fixtures/foreign/, made by pyarrow 26 with
//! fixtures/foreign/make_foreign.py): the file format compressed with lz4 (pyarrow's
//! Feather default) or zstd, the stream format (was taken for CSV), Feather v1 (a clear
//! message; was taken for CSV), and 64-bit integers no f64 holds exactly (refused
//! naming the column and row; were rounded silently).

use crate::common::{farma, fixture, stderr, stdout};

fn info_json(name: &str) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let o = farma(
        &[
            "info",
            fixture(&format!("foreign/{name}")).to_str().unwrap(),
            "--json",
            "--no-cache",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
    serde_json::from_str(stdout(&o).trim()).unwrap()
}

/// The statistics of the uncompressed Parquet twin (crc.parquet holds the same table).
fn reference() -> serde_json::Value {
    info_json("crc.parquet")
}

#[test]
fn lz4_and_zstd_compressed_ipc_files_and_an_ipc_stream_read_as_the_same_log() {
    let want = reference();
    assert_eq!(want["n_samples"], 200);
    for name in ["lz4.arrow", "zstd.arrow", "stream.arrows"] {
        let got = info_json(name);
        assert_eq!(got["n_samples"], want["n_samples"], "{name}");
        assert_eq!(got["sample_rate_hz"], want["sample_rate_hz"], "{name}");
        assert_eq!(got["channels"], want["channels"], "{name}");
        assert_eq!(got["format"], "arrow", "{name}");
    }
}

#[test]
fn an_ipc_stream_converts_through_ingest() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.arrow");
    let o = farma(
        &[
            "ingest",
            fixture("foreign/stream.arrows").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = farma::store::Store::open(&out).unwrap();
    assert_eq!(s.n_samples(), 200);
}

#[test]
fn feather_v1_is_named_not_taken_for_csv() {
    let dir = tempfile::tempdir().unwrap();
    let o = farma(
        &[
            "info",
            fixture("foreign/v1.feather").to_str().unwrap(),
            "--no-cache",
        ],
        dir.path(),
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("v1.feather"), "{e}");
    assert!(e.contains("Feather v1"), "{e}");
    assert!(e.contains("write_feather"), "{e}");
    assert!(!e.contains("line"), "read as text: {e}");
}

#[test]
fn int64_beyond_2_pow_53_is_refused_naming_column_and_row() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["int64_big.arrow", "int64_big.parquet"] {
        let o = farma(
            &[
                "info",
                fixture(&format!("foreign/{name}")).to_str().unwrap(),
                "--no-cache",
            ],
            dir.path(),
        );
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {e}");
        assert!(e.contains(name), "{e}");
        assert!(e.contains("column 'counts', row 4"), "{e}");
        assert!(e.contains("9007199254740993"), "{e}");
        assert_eq!(stdout(&o), "");
    }
}

#[test]
fn int64_up_to_2_pow_53_is_read_exactly() {
    let v = info_json("int64_2p53.arrow");
    let ch = v["channels"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "counts")
        .unwrap_or_else(|| panic!("{v}"))
        .clone();
    assert_eq!(ch["max"].as_f64(), Some(9007199254740992.0), "{ch}");
    assert_eq!(ch["min"].as_f64(), Some(-9007199254740992.0), "{ch}");
}
