//! `farma fit --index lag,CHANNEL`: the 2-D index from the command line: tables with
//! `grid2` and the second index named in the file metadata, identical bytes with 1 and
//! 2 threads, bad requests exit 2.

use std::fs::File;

use crate::common::{farma, fixture, stderr, stdout};
use arrow_array::{Array, Float64Array};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

#[test]
fn fit_with_a_temperature_index_writes_grid2_and_is_thread_independent() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let run = |threads: &str, out: &str| {
        let o = farma(
            &[
                "--threads",
                threads,
                "fit",
                log.to_str().unwrap(),
                "--channel",
                "gyro_x",
                "--order",
                "2,0,1",
                "--index",
                "lag,temp_c",
                "--index-grid",
                "7,5",
                "--residuals",
                "--json",
                "-o",
                dir.path().join(out).to_str().unwrap(),
            ],
            dir.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        o
    };
    let one = run("1", "t1");
    let two = run("2", "t2");
    for f in [
        "coef.parquet",
        "params.parquet",
        "gcv.parquet",
        "residuals.parquet",
    ] {
        let a = std::fs::read(dir.path().join("t1").join(f)).unwrap();
        let b = std::fs::read(dir.path().join("t2").join(f)).unwrap();
        assert!(a == b, "{f} differs between 1 and 2 threads");
    }
    assert_eq!(stdout(&one), stdout(&two).replace("/t2/", "/t1/"));
    let v: serde_json::Value = serde_json::from_str(stdout(&one).lines().next().unwrap()).unwrap();
    assert_eq!(v["index2"], serde_json::json!("temp_c"));
    assert!(v["bandwidth2"].as_f64().unwrap() > 0.0);

    let file = File::open(dir.path().join("t1").join("coef.parquet")).unwrap();
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).unwrap();
    let kv = builder
        .metadata()
        .file_metadata()
        .key_value_metadata()
        .unwrap()
        .clone();
    let meta = |k: &str| kv.iter().find(|e| e.key == k).and_then(|e| e.value.clone());
    assert_eq!(meta("index2").as_deref(), Some("temp_c"));
    assert_eq!(meta("index2_lag").as_deref(), Some("1"));
    let batches: Vec<_> = builder.build().unwrap().map(|b| b.unwrap()).collect();
    let rows: usize = batches.iter().map(|b| b.num_rows()).sum();
    assert_eq!(rows, 70);
    let g2 = batches[0]
        .column_by_name("grid2")
        .unwrap()
        .as_any()
        .downcast_ref::<Float64Array>()
        .unwrap()
        .clone();
    // the temperature grid spans the central quantiles of temp_c (about 25..30 degC)
    let (lo, hi) = (g2.value(0), g2.value(8));
    assert!(lo > 24.0 && hi < 31.0 && hi > lo, "{lo} {hi}");
    assert!(batches[0].column_by_name("slope2").is_some());
    assert_eq!(g2.len(), 70);
}

/// A 2-D index has the direct path only: an explicit `--method fast` says so on
/// stderr (not silently the direct path) and fits what `--method direct` and no
/// `--method` fit, byte for byte; the other two give no such warning.
#[test]
fn an_explicit_method_fast_with_a_2d_index_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let run = |method: Option<&str>, out: &str| {
        let o_dir = dir.path().join(out);
        let mut args = vec![
            "fit",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "--order",
            "1,0,1",
            "--index",
            "lag,temp_c",
            "--index-grid",
            "5,5",
            "-o",
            o_dir.to_str().unwrap(),
        ];
        if let Some(m) = method {
            args.extend(["--method", m]);
        }
        let o = farma(&args, dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        stderr(&o).to_string()
    };
    let fast = run(Some("fast"), "fast");
    assert!(
        fast.contains("warning: --method fast: a 2-D index") && fast.contains("direct path"),
        "{fast}"
    );
    for (m, out) in [(Some("direct"), "direct"), (None, "default")] {
        let err = run(m, out);
        assert!(!err.contains("--method fast"), "{m:?}: {err}");
        for f in ["coef.parquet", "params.parquet", "gcv.parquet"] {
            let a = std::fs::read(dir.path().join("fast").join(f)).unwrap();
            let b = std::fs::read(dir.path().join(out).join(f)).unwrap();
            assert!(a == b, "{f}: --method fast differs from {m:?}");
        }
    }
}

#[test]
fn fit_with_a_bad_index_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let l = log.to_str().unwrap();
    let out = dir.path().join("o");
    let o = out.to_str().unwrap();
    for (args, needle) in [
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "lag,nope",
                "-o",
                o,
            ],
            "no channel 'nope'",
        ),
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "temp_c",
                "-o",
                o,
            ],
            "--index",
        ),
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "lag,temp_c",
                "--save-state",
                "-o",
                o,
            ],
            "--save-state",
        ),
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "lag,temp_c",
                "--bandwidth",
                "0.1",
                "-o",
                o,
            ],
            "--bandwidth2",
        ),
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "lag,temp_c",
                "--index-grid",
                "7",
                "-o",
                o,
            ],
            "--index-grid",
        ),
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "lag,gyro_x",
                "-o",
                o,
            ],
            "--index-lag",
        ),
        // the fitted channel's own current value x_t as an index of the model of x_t
        // (a fit on it gives sigma2 0.21 where honest fits give 0.99)
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "lag,gyro_x",
                "--index-lag",
                "0",
                "-o",
                o,
            ],
            "own current value",
        ),
        // --grid is the 1-D grid: with a 2-D index it is refused, not ignored silently
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "lag,temp_c",
                "--grid",
                "41",
                "-o",
                o,
            ],
            "--grid 41: the grid of a 1-D index; a 2-D index has a G1 x G2 grid, --index-grid N1,N2 (default 21,21)",
        ),
        // the time column is no channel, so no index
        (
            vec![
                "fit",
                l,
                "--channel",
                "gyro_x",
                "--index",
                "lag,time_s",
                "-o",
                o,
            ],
            "multiaxis.csv: --index lag,time_s: 'time_s' is the log's time column, not a channel",
        ),
    ] {
        let r = farma(&args, dir.path());
        assert_eq!(r.status.code(), Some(2), "{args:?}: {}", stderr(&r));
        assert!(stderr(&r).contains(needle), "{args:?}: {}", stderr(&r));
    }
    assert!(!out.join("coef.parquet").exists());
}

/// `--channel all` with a 2-D index fits every channel but the index channel (its
/// model on itself at the same lag is refused), with a note that says so; a log whose
/// only channel is the index channel is refused, exit 2. (`all` taking the index
/// channel in would fail the run on it.)
#[test]
fn channel_all_with_a_2d_index_leaves_the_index_channel_out() {
    use arrow_array::StringArray;
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let out = dir.path().join("o");
    let o = farma(
        &[
            "fit",
            log.to_str().unwrap(),
            "--channel",
            "all",
            "--order",
            "1,0,1",
            "--index",
            "lag,temp_c",
            "--index-grid",
            "5,5",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("'temp_c', the index channel, is not fitted"),
        "{err}"
    );
    let file = File::open(out.join("params.parquet")).unwrap();
    let mut fitted = vec![];
    for b in ParquetRecordBatchReaderBuilder::try_new(file)
        .unwrap()
        .build()
        .unwrap()
    {
        let b = b.unwrap();
        let c = b.column_by_name("channel").unwrap();
        let c = c.as_any().downcast_ref::<StringArray>().unwrap();
        fitted.extend((0..c.len()).map(|k| c.value(k).to_string()));
    }
    assert_eq!(fitted, ["gyro_x", "gyro_y", "gyro_z"]);
    // a log of the index channel alone
    let only = dir.path().join("only.csv");
    let text: String = (0..200)
        .map(|k| format!("{},{}\n", k as f64 * 0.1, 20.0 + (k % 7) as f64))
        .collect();
    std::fs::write(&only, format!("time_s,temp_c\n{text}")).unwrap();
    let out2 = dir.path().join("o2");
    let o = farma(
        &[
            "fit",
            only.to_str().unwrap(),
            "--channel",
            "all",
            "--index",
            "lag,temp_c",
            "-o",
            out2.to_str().unwrap(),
        ],
        dir.path(),
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("only.csv") && err.contains("only channel is the index channel 'temp_c'"),
        "{err}"
    );
    assert!(!out2.exists());
}

/// `--index-grid` has an upper bound: 100000,100000 would have the allocator abort the
/// process (exit 134) and 18446744073709551615,3 would panic on a capacity overflow
/// (exit 101) after the log is read. Both are refused,
/// exit 2, before the log is read (a missing log is not reached), as is one point
/// beyond the bound.
#[test]
fn an_index_grid_beyond_the_bound_is_refused_before_the_log_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for (log, grid) in [
        (fixture("multiaxis.csv"), "100000,100000"),
        (fixture("multiaxis.csv"), "18446744073709551615,3"),
        (fixture("multiaxis.csv"), "13334,3"),
        (dir.path().join("missing.csv"), "201,201"),
    ] {
        let args = [
            "fit",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "--order",
            "1,0,1",
            "--index",
            "lag,temp_c",
            "--index-grid",
            grid,
            "-o",
            out.to_str().unwrap(),
        ];
        let r = farma(&args, dir.path());
        assert_eq!(r.status.code(), Some(2), "{grid}: {}", stderr(&r));
        let err = stderr(&r);
        assert!(!err.contains("panicked"), "{grid}: {err}");
        assert!(
            err.contains("--index-grid")
                && (err.contains("at most 40000 grid points") || err.contains("at least 3")),
            "{grid}: {err}"
        );
        assert_eq!(stdout(&r), "");
        assert!(!out.exists(), "{grid}: the output folder was created");
    }
}
