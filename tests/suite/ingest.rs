//! Round trips (CSV, Parquet, real data) and the ingest policies.

use std::path::Path;

use crate::common::{self, farma, fixture, reference_parse_csv, stderr, stdout};
use arrow_array::{Array, Float64Array};
use farma::log::{CachePolicy, GapPolicy, LogOptions, NanPolicy, Progress, ingest, open_log};
use farma::store::Store;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

/// Reads every Float64 column of a Parquet file with the parquet crate directly.
fn reference_parquet(path: &Path) -> Vec<(String, Vec<f64>)> {
    let r = ParquetRecordBatchReaderBuilder::try_new(std::fs::File::open(path).unwrap())
        .unwrap()
        .build()
        .unwrap();
    let mut out: Vec<(String, Vec<f64>)> = Vec::new();
    for b in r {
        let b = b.unwrap();
        for (i, f) in b.schema().fields().iter().enumerate() {
            let a = b.column(i).as_any().downcast_ref::<Float64Array>().unwrap();
            assert_eq!(a.null_count(), 0);
            match out.iter_mut().find(|(n, _)| n == f.name()) {
                Some((_, v)) => v.extend_from_slice(a.values()),
                None => out.push((f.name().clone(), a.values().to_vec())),
            }
        }
    }
    out
}

fn ingest_default(input: &Path, dir: &Path) -> Store {
    let out = dir.join("s.arrow");
    ingest(input, &out, &LogOptions::default(), &Progress::hidden()).unwrap();
    Store::open(&out).unwrap()
}

#[test]
fn csv_round_trip_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let csv = fixture("multiaxis.csv");
    let s = ingest_default(&csv, dir.path());
    let (names, cols) = reference_parse_csv(&csv);
    assert_eq!(
        s.column_names(),
        names.iter().map(String::as_str).collect::<Vec<_>>()
    );
    assert_eq!(
        s.channel_names(),
        vec!["gyro_x", "gyro_y", "gyro_z", "temp_c"]
    );
    for (n, c) in names.iter().zip(&cols) {
        assert_eq!(bits(s.column(n).unwrap()), bits(c), "column {n}");
    }
    assert_eq!(s.n_samples(), 4000);
    assert!((s.sample_rate_hz() - 10.0).abs() < 1e-9);
    assert_eq!(s.meta().time_source, "column:time_s");
}

#[test]
fn parquet_round_trip_is_bit_identical_with_rate_from_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let pq = fixture("multiaxis.parquet");
    let s = ingest_default(&pq, dir.path());
    for (n, v) in reference_parquet(&pq) {
        assert_eq!(bits(s.column(&n).unwrap()), bits(&v), "column {n}");
    }
    assert_eq!(s.sample_rate_hz(), 10.0);
    assert_eq!(s.meta().time_source, "metadata");
    // Same values as the CSV fixture.
    let (_, cols) = reference_parse_csv(&fixture("multiaxis.csv"));
    assert_eq!(bits(s.column("gyro_x").unwrap()), bits(&cols[1]));
}

#[test]
fn real_adis_runs_round_trip_with_rate_from_metadata() {
    let Some(dir_real) = common::realdata("imudata-adis16405") else {
        eprintln!("SKIPPED: ../shared/realdata/imudata-adis16405 not present");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for run in 1..=4 {
        let pq = dir_real.join(format!("adis_16405_imu{run}.parquet"));
        let s = ingest_default(&pq, dir.path());
        assert_eq!(s.sample_rate_hz(), 100.0);
        assert_eq!(s.n_samples(), 1_000_000);
        for (n, v) in reference_parquet(&pq) {
            assert_eq!(
                bits(s.column(&n).unwrap()),
                bits(&v),
                "run {run} column {n}"
            );
        }
    }
}

/// A CSV of several parser chunks (4 MiB each), with awkward formatting throughout.
fn write_big_csv(
    path: &Path,
    rows: usize,
    delim: &str,
    crlf: bool,
    bad_line: Option<usize>,
) -> Vec<Vec<f64>> {
    let nl = if crlf { "\r\n" } else { "\n" };
    let mut s = String::from("\u{feff}# big test file");
    s.push_str(nl);
    s.push_str(&format!("\"time\"{delim}a{delim}b{nl}"));
    let mut cols = vec![Vec::new(), Vec::new(), Vec::new()];
    let mut line = 3;
    for i in 0..rows {
        if i % 10_000 == 7 {
            s.push_str(&format!("# comment at row {i}{nl}{nl}"));
            line += 2;
        }
        let t = i as f64 * 0.01;
        let a = ((i * 2654435761) % 1_000_003) as f64 / 7.0 - 70_000.0;
        let b = -1.0 / (i as f64 + 3.0);
        if Some(line) == bad_line {
            s.push_str(&format!("{t}{delim}x1{delim}{b:e}{nl}"));
        } else {
            s.push_str(&format!("{t}{delim} {a} {delim}\"{b:e}\"{nl}"));
        }
        line += 1;
        for (c, v) in cols.iter_mut().zip([t, a, b]) {
            c.push(v);
        }
    }
    std::fs::write(path, s).unwrap();
    cols
}

#[test]
fn multi_chunk_csv_with_bom_quotes_comments_crlf_and_delimiters() {
    let dir = tempfile::tempdir().unwrap();
    for (delim, crlf) in [(",", false), (";", true), ("\t", false), ("  ", true)] {
        let p = dir.path().join("big.csv");
        let cols = write_big_csv(&p, 300_000, delim, crlf, None);
        assert!(
            std::fs::metadata(&p).unwrap().len() > 9 << 20,
            "want several chunks"
        );
        let out = dir.path().join("big.arrow");
        let opts = LogOptions {
            time_tol: 0.01,
            ..LogOptions::default()
        };
        ingest(&p, &out, &opts, &Progress::hidden()).unwrap();
        let s = Store::open(&out).unwrap();
        for (n, c) in ["time", "a", "b"].iter().zip(&cols) {
            assert_eq!(
                bits(s.column(n).unwrap()),
                bits(c),
                "delim {delim:?} column {n}"
            );
        }
    }
}

#[test]
fn line_numbers_are_exact_in_late_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad_big.csv");
    write_big_csv(&p, 300_000, ",", false, Some(287_654));
    let o = farma(
        &[
            "ingest",
            p.to_str().unwrap(),
            "-o",
            dir.path().join("x.arrow").to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("bad_big.csv:287654: column 'a': cannot parse 'x1'"),
        "{}",
        stderr(&o)
    );
    // Same message with one thread.
    let o1 = farma(
        &[
            "--threads",
            "1",
            "ingest",
            p.to_str().unwrap(),
            "-o",
            dir.path().join("x.arrow").to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(stderr(&o1), stderr(&o));
}

#[test]
fn nan_policy_interpolate_fills_linearly_and_records_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.arrow");
    let opts = LogOptions {
        nan_policy: NanPolicy::Interpolate,
        ..LogOptions::default()
    };
    let meta = ingest(
        &fixture("bad/nan_inf.csv"),
        &out,
        &opts,
        &Progress::hidden(),
    )
    .unwrap();
    let s = Store::open(&out).unwrap();
    let x = s.column("gyro_x").unwrap();
    // rows 0..4 are 0.01 i; rows 5,6,7 were NaN, inf, empty; row 8 is 0.08.
    let want = [
        0.04 + (0.08 - 0.04) * 0.25,
        0.04 + (0.08 - 0.04) * 0.5,
        0.04 + (0.08 - 0.04) * 0.75,
    ];
    for (k, w) in want.iter().enumerate() {
        assert!((x[5 + k] - w).abs() < 1e-12, "row {} = {}", 5 + k, x[5 + k]);
    }
    assert_eq!(meta.repairs.len(), 1);
    assert_eq!(meta.repairs[0].kind, "nan_interpolated");
    assert_eq!(meta.repairs[0].count, 3);
    assert!(meta.repairs[0].detail.contains("line 7"));
}

#[test]
fn gap_policies_split_and_interpolate() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.arrow");
    let gap = fixture("bad/gap.csv"); // t = 0 .1 .2 | .6 .7 .8, x = 10 t
    let opts = LogOptions {
        gap_policy: GapPolicy::Split,
        ..LogOptions::default()
    };
    let meta = ingest(&gap, &out, &opts, &Progress::hidden()).unwrap();
    assert_eq!(meta.segments.len(), 2);
    assert_eq!(
        (
            meta.segments[1].start,
            meta.segments[1].len,
            meta.segments[1].t0_s
        ),
        (3, 3, 0.6)
    );
    assert_eq!(Store::open(&out).unwrap().n_samples(), 6);

    let opts = LogOptions {
        gap_policy: GapPolicy::Interpolate,
        ..LogOptions::default()
    };
    let meta = ingest(&gap, &out, &opts, &Progress::hidden()).unwrap();
    let s = Store::open(&out).unwrap();
    assert_eq!(s.n_samples(), 9);
    assert_eq!(meta.segments.len(), 1);
    let x = s.column("gyro_x").unwrap();
    let t = s.column("time").unwrap();
    for k in 0..9 {
        assert!((t[k] - 0.1 * k as f64).abs() < 1e-12);
        assert!((x[k] - k as f64).abs() < 1e-9, "x[{k}] = {}", x[k]);
    }
}

#[test]
fn rate_flag_is_the_last_resort_and_columns_select() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("norate.csv");
    std::fs::write(&p, "a b\n1 2\n3 4\n5 6\n").unwrap();
    let out = dir.path().join("s.arrow");
    let opts = LogOptions {
        rate_hz: Some(50.0),
        columns: Some(vec!["b".into()]),
        ..LogOptions::default()
    };
    let meta = ingest(&p, &out, &opts, &Progress::hidden()).unwrap();
    assert_eq!(meta.time_source, "flag");
    let s = Store::open(&out).unwrap();
    assert_eq!(s.channel_names(), vec!["b"]);
    assert_eq!(s.column("b").unwrap(), &[2.0, 4.0, 6.0]);
    assert!((s.duration_s() - 0.06).abs() < 1e-12);
}

#[test]
fn other_commands_read_csv_through_the_cache_once() {
    let cache = tempfile::tempdir().unwrap();
    let csv = fixture("multiaxis.csv");
    let a = farma(&["info", csv.to_str().unwrap(), "--json"], cache.path());
    assert_eq!(a.status.code(), Some(0), "{}", stderr(&a));
    let entries: Vec<_> = std::fs::read_dir(cache.path()).unwrap().collect();
    assert_eq!(entries.len(), 1);
    let b = farma(&["info", csv.to_str().unwrap(), "--json"], cache.path());
    assert_eq!(stdout(&a), stdout(&b));
    assert_eq!(std::fs::read_dir(cache.path()).unwrap().count(), 1);
    // And the store opened directly says the same.
    let s = open_log(
        &csv,
        &LogOptions::default(),
        &CachePolicy::Off,
        &Progress::hidden(),
    )
    .unwrap();
    assert_eq!(s.n_samples(), 4000);
}

/// An edit that keeps the file's size and modification time (`cp -p`, `rsync -t`, an
/// editor that restores the mtime) is not served from the stale cached store: the
/// cache key holds the inode and ctime as well, so the new values are read.
#[cfg(unix)]
#[test]
fn an_edit_keeping_size_and_mtime_is_not_read_from_a_stale_cache() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let log = dir.path().join("log.csv");
    let write = |digit: char| {
        let mut text = String::from("time,x\n");
        for i in 0..100 {
            text.push_str(&format!("{}.{i:02},{digit}.{}\n", i / 100, i % 10));
        }
        std::fs::write(&log, text).unwrap();
    };
    let mean = || {
        let o = farma(&["info", log.to_str().unwrap(), "--json"], &cache);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        v["channels"][0]["mean"].as_f64().unwrap()
    };
    write('1');
    let before = std::fs::metadata(&log).unwrap();
    let first = mean();
    assert!((first - 1.45).abs() < 1e-12, "{first}");
    // let the clock move on (the kernel's ctime ticks every few ms)
    std::thread::sleep(std::time::Duration::from_millis(50));
    write('7'); // same length: every value 1.x becomes 7.x
    std::fs::OpenOptions::new()
        .write(true)
        .open(&log)
        .unwrap()
        .set_modified(before.modified().unwrap())
        .unwrap();
    let after = std::fs::metadata(&log).unwrap();
    assert_eq!(after.len(), before.len());
    assert_eq!(after.modified().unwrap(), before.modified().unwrap());
    let second = mean();
    assert!((second - 7.45).abs() < 1e-12, "stale cache: mean {second}");
}

#[test]
fn info_json_has_the_contract_keys_and_correct_statistics() {
    let cache = tempfile::tempdir().unwrap();
    let csv = fixture("multiaxis.csv");
    let o = farma(&["info", csv.to_str().unwrap(), "--json"], cache.path());
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!((v["sample_rate_hz"].as_f64().unwrap() - 10.0).abs() < 1e-9);
    assert!((v["duration_s"].as_f64().unwrap() - 400.0).abs() < 1e-6);
    let (_, cols) = reference_parse_csv(&csv);
    let chans = v["channels"].as_array().unwrap();
    assert_eq!(chans.len(), 4);
    for (c, x) in chans.iter().zip(&cols[1..]) {
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let std = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        assert_eq!(c["n"].as_u64().unwrap(), 4000);
        assert!((c["mean"].as_f64().unwrap() - mean).abs() <= 1e-12 * mean.abs().max(1e-3));
        assert!((c["std"].as_f64().unwrap() - std).abs() <= 1e-10 * std);
        assert_eq!(
            c["min"].as_f64().unwrap(),
            x.iter().cloned().fold(f64::INFINITY, f64::min)
        );
        assert_eq!(
            c["max"].as_f64().unwrap(),
            x.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        );
    }
}

#[test]
fn info_describes_a_channel_with_missing_values_instead_of_refusing_the_log() {
    let dir = tempfile::tempdir().unwrap();
    // `aux` empty at data row 4 (line 6) and NaN at row 9 (line 11)
    let mut text = String::from("time_s,gyro,aux\n");
    let mut kept = Vec::new();
    for i in 0..40 {
        let aux = match i {
            4 => String::new(),
            9 => "NaN".into(),
            _ => {
                let v = (i * i % 13) as f64 * 0.25;
                kept.push(v);
                format!("{v}")
            }
        };
        text += &format!("{},{},{aux}\n", i as f64 * 0.1, (i % 5) as f64);
    }
    let log = dir.path().join("holes.csv");
    std::fs::write(&log, text).unwrap();
    let l = log.to_str().unwrap();
    let o = farma(&["info", l, "--json"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let aux = &v["channels"][1];
    assert_eq!(aux["name"], "aux");
    assert_eq!(aux["n"].as_u64(), Some(38));
    assert_eq!(aux["n_nonfinite"].as_u64(), Some(2));
    let mean = kept.iter().sum::<f64>() / 38.0;
    assert!(
        (aux["mean"].as_f64().unwrap() - mean).abs() < 1e-12,
        "{aux}"
    );
    assert_eq!(aux["max"].as_f64(), Some(3.0));
    assert_eq!(v["channels"][0]["n_nonfinite"].as_u64(), Some(0));
    assert_eq!(v["nonfinite"][0]["column"], "aux");
    assert_eq!(v["nonfinite"][0]["first"], "line 6, line 11");
    // the text names the column, its count and lines
    let o = farma(&["info", l], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("nonfinite aux x2: first at line 6, line 11"),
        "{out}"
    );
    // a command that reads every channel is refused, naming the ones it could take
    let o = farma(&["adev", l, "--channel", "all", "--json"], dir.path());
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("column 'aux'") && err.contains("--channel gyro takes the others"),
        "{err}"
    );
    assert!(stdout(&o).is_empty());
}

#[test]
fn quoted_names_and_cells_follow_rfc4180() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("quoted.csv");
    std::fs::write(
        &p,
        "\"time\",\"gyro, x (deg/s)\",\"say \"\"hi\"\"\"\n0,\"1.5\",2\n0.5,\"-2.5e-3\",3\n",
    )
    .unwrap();
    let out = dir.path().join("s.arrow");
    ingest(&p, &out, &LogOptions::default(), &Progress::hidden()).unwrap();
    let s = Store::open(&out).unwrap();
    assert_eq!(s.channel_names(), vec!["gyro, x (deg/s)", "say \"hi\""]);
    assert_eq!(s.column("gyro, x (deg/s)").unwrap(), &[1.5, -2.5e-3]);
    assert_eq!(s.sample_rate_hz(), 2.0);
    // A quoted cell holding the delimiter is one field, and not a number.
    std::fs::write(&p, "time,x\n0,\"1,5\"\n").unwrap();
    let e = ingest(&p, &out, &LogOptions::default(), &Progress::hidden()).unwrap_err();
    assert!(e.to_string().contains("cannot parse '1,5'"), "{e}");
}
