//! `farma select`, `farma analyze` and `farma check` on the bundled log: JSON keys of
//! contracts.md section 4, the output folder, bad input.

use crate::common::{assert_refused_file_output, farma, fixture, stderr, stdout};

/// Fits the fixture log's gyro_x with `flags` (order, grid, index) into `dir/name`,
/// checking that it succeeds; returns the model folder.
fn fit_gyro_x(
    dir: &std::path::Path,
    log: &std::path::Path,
    name: &str,
    flags: &[&str],
) -> std::path::PathBuf {
    let model = dir.join(name);
    let mut args = vec!["fit", log.to_str().unwrap(), "--channel", "gyro_x"];
    args.extend(flags);
    args.extend(["-o", model.to_str().unwrap()]);
    let o = farma(&args, dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    model
}

#[test]
fn select_json_has_the_contract_keys() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let o = farma(
        &[
            "select",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "--orders",
            "1,1,1;2,1,1",
            "--grid",
            "21",
            "--bootstrap",
            "4",
            "--json",
            "-o",
            dir.path().join("s").to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(stdout(&o).trim()).unwrap();
    assert_eq!(v["channel"], "gyro_x");
    let sel = v["selected"].as_array().unwrap();
    assert_eq!(sel.len(), 3);
    let table = v["table"].as_array().unwrap();
    assert_eq!(table.len(), 2);
    for r in table {
        for k in ["order", "rss", "sigma2", "trace", "arma_rss"] {
            assert!(r.get(k).is_some(), "{k} missing in {r}");
        }
    }
    // the selected order is the row of smallest AICc
    let best = table
        .iter()
        .min_by(|a, b| {
            a["aicc"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["aicc"].as_f64().unwrap())
        })
        .unwrap();
    assert_eq!(&best["order"], &v["selected"]);
    let p = v["constancy_p"].as_f64().unwrap();
    assert!(p > 0.0 && p <= 1.0);
    for f in ["select.parquet", "ftests.parquet", "constancy.parquet"] {
        assert!(dir.path().join("s").join(f).exists(), "{f}");
    }
    // bad grid of orders: exit 2 naming the flag
    let o = farma(
        &[
            "select",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "--orders",
            "2,1",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--orders"), "{}", stderr(&o));
}

#[test]
fn analyze_writes_every_table_and_a_summary() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let out = dir.path().join("a");
    let o = farma(
        &[
            "analyze",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x,gyro_z",
            "--orders",
            "2,1,1",
            "--grid",
            "21",
            "--bootstrap",
            "0",
            "--json",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let lines: Vec<serde_json::Value> = stdout(&o)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2);
    for v in &lines {
        // 50 s at 10 Hz held out
        assert_eq!(v["n_train"], 3500);
        assert_eq!(v["prediction"][0]["k"], 1);
        assert!(v["ljung_box"].as_array().unwrap().len() >= 2);
    }
    for f in [
        "clean.arrow",
        "prep.parquet",
        "replaced.parquet",
        "select.parquet",
        "ftests.parquet",
        "constancy.parquet",
        "coef.parquet",
        "params.parquet",
        "gcv.parquet",
        "acf.parquet",
        "ljung_box.parquet",
        "prediction.parquet",
        "poly.parquet",
        "summary.txt",
        "report.html",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(summary.contains("######## gyro_z") && summary.contains("Ljung-Box"));
    assert!(out.join("verdict.parquet").exists());
    // written as one set: the 16 files (report.html among them), the channel folders
    // and no temporary file left beside them
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 17);
    let mut chans: Vec<String> = std::fs::read_dir(out.join("channels"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    chans.sort();
    assert_eq!(chans, ["gyro_x", "gyro_z"]);
    // each channel folder: its 11 tables, summary, JSON line, report and marker
    assert_eq!(
        std::fs::read_dir(out.join("channels/gyro_z"))
            .unwrap()
            .count(),
        15
    );
    // -o naming a file: exit 2 before the work, the file untouched
    let taken = out.join("summary.txt");
    let o = farma(
        &[
            "analyze",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "-o",
            taken.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_refused_file_output(&o, &taken, &summary);
    // a hold-out longer than half the log: exit 2, names the flag
    let o = farma(
        &[
            "analyze",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "--holdout-s",
            "300",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--holdout-s"), "{}", stderr(&o));
}

#[test]
fn check_reads_a_fit_folder_and_scores_the_holdout() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let model = fit_gyro_x(dir.path(), &log, "m", &["--order", "2,1,1", "--grid", "21"]);
    let out = dir.path().join("c");
    let o = farma(
        &[
            "check",
            model.to_str().unwrap(),
            log.to_str().unwrap(),
            "--json",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(stdout(&o).trim()).unwrap();
    assert_eq!(v["channel"], "gyro_x");
    assert_eq!(v["holdout"], 500);
    let pred = v["prediction"].as_array().unwrap();
    assert_eq!(pred[0]["k"], 1);
    assert_eq!(pred[0]["n"], 500);
    // one-step errors are near the channel's innovation scale, far below its spread
    let r1 = pred[0]["rmse_farma"].as_f64().unwrap();
    assert!(r1 > 0.0 && r1 < 0.0103, "{r1}");
    assert_eq!(v["poly"].as_array().unwrap().len(), 2);
    for f in [
        "acf.parquet",
        "ljung_box.parquet",
        "prediction.parquet",
        "poly.parquet",
    ] {
        assert!(out.join(f).exists(), "{f}");
    }
    // a folder that is not a fit: exit 2
    let o = farma(
        &["check", dir.path().to_str().unwrap(), log.to_str().unwrap()],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // a model whose b is not invertible (an update can write one): exit 2, naming
    // the file, the channel and b, nothing written
    with_b(&model.join("params.parquet"), -1.5);
    let out2 = dir.path().join("c2");
    let o = farma(
        &[
            "check",
            model.to_str().unwrap(),
            log.to_str().unwrap(),
            "-o",
            out2.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("params.parquet") && err.contains("gyro_x") && err.contains("not invertible"),
        "{err}"
    );
    assert!(!out2.exists());
}

/// Rewrites a fit's params.parquet with every channel's b = [b1].
fn with_b(path: &std::path::Path, b1: f64) {
    use arrow_array::builder::{Float64Builder, ListBuilder};
    use arrow_array::{Array, RecordBatch};
    use std::sync::Arc;
    let file = std::fs::File::open(path).unwrap();
    let reader = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .unwrap()
        .build()
        .unwrap();
    let batches: Vec<RecordBatch> = reader.map(|b| b.unwrap()).collect();
    let schema = batches[0].schema();
    let k = schema.index_of("b").unwrap();
    let edited: Vec<RecordBatch> = batches
        .iter()
        .map(|batch| {
            let mut list = ListBuilder::new(Float64Builder::new());
            for _ in 0..batch.num_rows() {
                list.values().append_value(b1);
                list.append(true);
            }
            let mut cols: Vec<Arc<dyn Array>> = batch.columns().to_vec();
            cols[k] = Arc::new(list.finish());
            RecordBatch::try_new(schema.clone(), cols).unwrap()
        })
        .collect();
    let file = std::fs::File::create(path).unwrap();
    let mut w = parquet::arrow::ArrowWriter::try_new(file, schema.clone(), None).unwrap();
    for b in &edited {
        w.write(b).unwrap();
    }
    w.close().unwrap();
}

/// `-o` naming a file (not a folder) is a usage error found before the work: exit 2,
/// nothing on stdout, the file untouched.
#[test]
fn select_and_check_reject_an_output_that_is_a_file_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let file = dir.path().join("taken");
    std::fs::write(&file, "keep me").unwrap();
    let o = farma(
        &[
            "select",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "--orders",
            "1,1,1",
            "--grid",
            "21",
            "--bootstrap",
            "0",
            "-o",
            file.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_refused_file_output(&o, &file, "keep me");

    let model = fit_gyro_x(dir.path(), &log, "m", &["--order", "1,1,1", "--grid", "21"]);
    let o = farma(
        &[
            "check",
            model.to_str().unwrap(),
            log.to_str().unwrap(),
            "-o",
            file.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_refused_file_output(&o, &file, "keep me");
}

/// `farma check` on edge input: a --holdout-s beyond any log's length in samples is
/// refused with a message, not a wrap-around and a panic (exit 101); `--channel`
/// repeats are taken once (every row written once) and a trailing comma is no channel;
/// a constant channel's failing ARMA baseline names the log.
#[test]
fn check_refuses_a_huge_holdout_and_takes_each_channel_once() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let model = fit_gyro_x(dir.path(), &log, "m", &["--order", "1,1,1", "--grid", "21"]);
    let (m, l) = (model.to_str().unwrap(), log.to_str().unwrap());
    let o = farma(&["check", m, l, "--holdout-s", "1e300"], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("too short"), "{}", stderr(&o));

    let o = farma(
        &["check", m, l, "--channel", "gyro_x,gyro_x,", "--json"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 1, "{}", stdout(&o));

    let flat = dir.path().join("flat.csv");
    let mut csv = String::from("time_s,gyro_x\n");
    for i in 0..2000 {
        csv += &format!("{},0.5\n", i as f64 / 10.0);
    }
    std::fs::write(&flat, csv).unwrap();
    let o = farma(&["check", m, flat.to_str().unwrap()], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("flat.csv") && err.contains("gyro_x") && err.contains("ARMA"),
        "{err}"
    );
}

/// `--orders` and `--grid` of `farma select` and `farma analyze` are checked before
/// the log is read, naming the flag and not a channel (an order with p or d = 0, or a
/// bad grid, is not reported as `LOG: channel 'x': --order: ...` after the log is read
/// and prepared); an order given twice is fitted once (its rows and F-tests are not
/// repeated).
#[test]
fn select_and_analyze_check_orders_and_grid_before_the_log() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let l = log.to_str().unwrap();
    let out = dir.path().join("a");
    for (flag, value) in [
        ("--orders", "1,1,0"),
        ("--orders", "0,1,1"),
        ("--orders", "7,1,1"),
        ("--grid", "2"),
    ] {
        for cmd in ["select", "analyze"] {
            let mut args = vec![
                cmd,
                l,
                "--channel",
                "gyro_x",
                "--bootstrap",
                "0",
                "-o",
                out.to_str().unwrap(),
            ];
            args.extend([flag, value]);
            if flag == "--grid" {
                args.extend(["--orders", "1,1,1"]);
            }
            let o = farma(&args, dir.path());
            assert_eq!(o.status.code(), Some(2), "{cmd} {value}: {}", stderr(&o));
            let err = stderr(&o);
            assert!(
                err.contains(&format!("{flag}:")) && !err.contains("channel"),
                "{cmd} {flag} {value}: {err}"
            );
            assert!(!out.exists());
        }
    }
    let o = farma(
        &[
            "select",
            l,
            "--channel",
            "gyro_x",
            "--bootstrap",
            "0",
            "--grid",
            "21",
            "--orders",
            "1,1,1;1,1,1",
            "--json",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(stdout(&o).trim()).unwrap();
    assert_eq!(v["table"].as_array().unwrap().len(), 1, "{v}");
    assert_eq!(v["ftests"].as_array().unwrap().len(), 1, "{v}");
}

/// `farma analyze` names every failing channel at once, in channel order, as `farma
/// fit` does (not only the one error rayon meets first), and writes no folder-level
/// table; the channel that succeeded is kept in its folder for the rerun.
#[test]
fn analyze_names_every_failing_channel() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("two.csv");
    let mut csv = String::from("time_s,flat_a,flat_b,noise\n");
    let mut s: u64 = 12345;
    for i in 0..600 {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        csv += &format!("{},1.5,2.5,{u}\n", i as f64 / 10.0);
    }
    std::fs::write(&log, csv).unwrap();
    let out = dir.path().join("a");
    let o = farma(
        &[
            "analyze",
            log.to_str().unwrap(),
            "--grid",
            "21",
            "--bootstrap",
            "0",
            "--orders",
            "1,1,1",
            "--holdout-s",
            "5",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    let (a, b) = (err.find("flat_a"), err.find("flat_b"));
    assert!(a.is_some() && b.is_some() && a < b, "{err}");
    assert!(!err.contains("'noise'"), "{err}");
    // no gyro among them: every channel, with a warning; each failure's progress line
    assert!(err.contains("no channel is a gyro"), "{err}");
    assert!(err.contains("analyze flat_a: failed: "), "{err}");
    assert!(!out.join("summary.txt").exists() && !out.join("verdict.parquet").exists());
    assert!(out.join("channels/noise/done.json").is_file());
    assert!(!out.join("channels/flat_a").exists());
}

/// `farma check` on the folder of a fit on a 2-D index refuses it naming the index
/// (exit 2), not "f_1 has a repeated grid point" of coef.parquet (which repeats the lag
/// index's grid once per point of the second).
#[test]
fn check_refuses_a_2d_index_fit_naming_the_index() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let model = fit_gyro_x(
        dir.path(),
        &log,
        "m2",
        &["--order", "1,1,1", "--index", "lag,temp_c"],
    );
    let o = farma(
        &["check", model.to_str().unwrap(), log.to_str().unwrap()],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("params.parquet") && err.contains("2-D index") && err.contains("lag,temp_c"),
        "{err}"
    );
}

/// `farma check`, `farma select` and `farma prep` name every failing channel at once
/// (exit 2), in channel order, not the first one met: one rerun sees them all.
#[test]
fn check_select_and_prep_name_every_failing_channel() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let model = dir.path().join("m");
    let o = farma(
        &[
            "fit",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x,gyro_y",
            "--order",
            "1,1,1",
            "--grid",
            "21",
            "-o",
            model.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let (m, l) = (model.to_str().unwrap(), log.to_str().unwrap());
    let out = dir.path().join("c");
    let o = farma(
        &[
            "check",
            m,
            l,
            "--holdout-s",
            "1e300",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    let (a, b) = (err.find("channel gyro_x"), err.find("channel gyro_y"));
    assert!(a.is_some() && b.is_some() && a < b, "{err}");
    assert!(err.contains("2 of 2 channels failed"), "{err}");
    assert!(!out.exists());

    // two constant channels beside a noisy one
    let flat = dir.path().join("flat.csv");
    let mut csv = String::from("time_s,flat_a,noise,flat_b\n");
    let mut s: u64 = 99;
    for i in 0..600 {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        csv += &format!("{},1.5,{u},2.5\n", i as f64 / 10.0);
    }
    std::fs::write(&flat, csv).unwrap();
    let f = flat.to_str().unwrap();
    let o = farma(
        &[
            "select",
            f,
            "--channel",
            "all",
            "--grid",
            "21",
            "--bootstrap",
            "0",
            "--orders",
            "1,1,1",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    let (a, b) = (err.find("flat_a"), err.find("flat_b"));
    assert!(a.is_some() && b.is_some() && a < b, "{err}");
    assert!(!err.contains("'noise'"), "{err}");
    // prep of a log too short for the reverse-arrangement test's segments, every channel
    let short = dir.path().join("short.csv");
    std::fs::write(&short, "time_s,a,b\n0,1,2\n0.1,2,1\n0.2,1,3\n0.3,2,2\n").unwrap();
    let out = dir.path().join("p");
    let o = farma(
        &["prep", short.to_str().unwrap(), "-o", out.to_str().unwrap()],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("channel a") && err.contains("channel b"),
        "{err}"
    );
    assert!(!out.exists());
}
