//! `farma analyze` on multi-axis logs: channels by role (`--channel all` takes the
//! gyro axes, skips and names the accelerometer, offers the temperature), results
//! kept per channel and resumed, verdict.parquet, plain progress lines.

use std::path::Path;

use arrow_array::{Array, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray};

use crate::common::{farma, fixture, stderr, stdout};

use crate::common::parquet_table as table;

fn strings(b: &RecordBatch, name: &str) -> Vec<String> {
    let c = b.column_by_name(name).unwrap();
    let s = c.as_any().downcast_ref::<StringArray>().unwrap();
    (0..s.len()).map(|i| s.value(i).to_string()).collect()
}

fn floats(b: &RecordBatch, name: &str) -> Vec<Option<f64>> {
    let c = b.column_by_name(name).unwrap();
    let s = c.as_any().downcast_ref::<Float64Array>().unwrap();
    (0..s.len())
        .map(|i| (!s.is_null(i)).then(|| s.value(i)))
        .collect()
}

fn ints(b: &RecordBatch, name: &str) -> Vec<Option<i64>> {
    let c = b.column_by_name(name).unwrap();
    let s = c.as_any().downcast_ref::<Int64Array>().unwrap();
    (0..s.len())
        .map(|i| (!s.is_null(i)).then(|| s.value(i)))
        .collect()
}

fn bools(b: &RecordBatch, name: &str) -> Vec<Option<bool>> {
    let c = b.column_by_name(name).unwrap();
    let s = c.as_any().downcast_ref::<BooleanArray>().unwrap();
    (0..s.len())
        .map(|i| (!s.is_null(i)).then(|| s.value(i)))
        .collect()
}

/// A 10 Hz log of `n` rows with the named columns: AR(1) noise in each (its own
/// stream), the temperature a slow ramp.
fn write_log(path: &Path, names: &[&str], n: usize) {
    let mut s: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut state = vec![0.0; names.len()];
    let mut csv = format!("time_s,{}\n", names.join(","));
    for i in 0..n {
        csv += &format!("{}", i as f64 / 10.0);
        for (k, name) in names.iter().enumerate() {
            let v = if name.starts_with("temp") {
                25.0 + i as f64 * 1e-3 + 0.01 * next()
            } else {
                state[k] = 0.6 * state[k] + next();
                state[k]
            };
            csv += &format!(",{v}");
        }
        csv += "\n";
    }
    std::fs::write(path, csv).unwrap();
}

/// The quick analysis flags of these tests.
const QUICK: [&str; 6] = ["--orders", "1,1,1", "--grid", "21", "--holdout-s", "5"];

fn analyze(log: &Path, out: &Path, extra: &[&str], dir: &Path) -> std::process::Output {
    let mut args = vec!["analyze", log.to_str().unwrap()];
    args.extend(QUICK);
    args.extend(extra);
    args.extend(["-o", out.to_str().unwrap()]);
    farma(&args, dir)
}

/// `--channel all` takes the gyro axes only: the accelerometer is skipped and named
/// (with how to ask for it), the temperature named as the index of later tools, on
/// stderr and in summary.txt; `--role` and `--channel` take what they name; a log
/// without any gyro falls back to every channel but the temperature, with a warning.
#[test]
fn channel_all_takes_the_gyros_and_names_what_it_skips() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("imu.csv");
    write_log(&log, &["gyro_x_dps", "accel_x_g", "temp_c", "rate_y"], 800);
    let out = dir.path().join("a");
    let o = analyze(&log, &out, &["--bootstrap", "0"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v = table(&out.join("verdict.parquet"));
    assert_eq!(strings(&v, "channel"), ["gyro_x_dps", "rate_y"]);
    assert_eq!(
        strings(&table(&out.join("params.parquet")), "channel"),
        ["gyro_x_dps", "rate_y"]
    );
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    let err = stderr(&o);
    for text in [&summary, &err] {
        assert!(
            text.contains("gyro_x_dps: gyro (name ends in _dps)"),
            "{text}"
        );
        assert!(
            text.contains("rate_y: gyro (name starts with rate)"),
            "{text}"
        );
        assert!(
            text.contains(
                "accel_x_g: skipped, accelerometer (name ends in _g); ask with --channel accel_x_g"
            ),
            "{text}"
        );
        assert!(text.contains("temp_c: temperature"), "{text}");
    }
    assert!(
        summary.contains("temperature channel: temp_c (offered to farma fit --index lag,temp_c"),
        "{summary}"
    );
    assert!(!summary.contains("######## accel_x_g") && !summary.contains("######## temp_c"));
    assert!(out.join("channels/gyro_x_dps/done.json").is_file());
    assert!(!out.join("channels/accel_x_g").exists());
    // --role takes the accelerometer as a gyro, and drops rate_y
    let o = analyze(
        &log,
        &out,
        &[
            "--bootstrap",
            "0",
            "--role",
            "accel_x_g=gyro",
            "--role",
            "rate_*=other",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(
        strings(&table(&out.join("verdict.parquet")), "channel"),
        ["gyro_x_dps", "accel_x_g"]
    );
    assert!(stderr(&o).contains("accel_x_g: gyro (set by --role accel_x_g=gyro)"));
    // the channel rate_y of the earlier run is no longer this folder's
    assert!(!out.join("channels/rate_y").exists(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("an earlier run's channel"),
        "{}",
        stderr(&o)
    );
    let o = analyze(
        &log,
        &out,
        &["--bootstrap", "0", "--role", "x=magnet"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--role x=magnet"), "{}", stderr(&o));
    // an explicit list takes exactly those, temperature included
    let o = analyze(
        &log,
        &out,
        &["--bootstrap", "0", "--channel", "temp_c,accel_x_g"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(
        strings(&table(&out.join("verdict.parquet")), "channel"),
        ["temp_c", "accel_x_g"]
    );
    // a bad value in the skipped accelerometer does not block the gyros; in a taken
    // channel it is refused, naming it
    let log3 = dir.path().join("bad_accel.csv");
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let cells: Vec<&str> = lines[10].split(',').collect();
    lines[10] = format!("{},{},,{},{}", cells[0], cells[1], cells[3], cells[4]);
    std::fs::write(&log3, lines.join("\n") + "\n").unwrap();
    let out3 = dir.path().join("c");
    let o = analyze(&log3, &out3, &["--bootstrap", "0"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = analyze(
        &log3,
        &out3,
        &["--bootstrap", "0", "--role", "accel_x_g=gyro"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("accel_x_g"), "{}", stderr(&o));
    // no gyro: every channel but the temperature, with a warning
    let log2 = dir.path().join("aux.csv");
    write_log(&log2, &["aux_a", "aux_b", "temp_c"], 800);
    let out2 = dir.path().join("b");
    let o = analyze(&log2, &out2, &["--bootstrap", "0"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning:") && stderr(&o).contains("no channel is a gyro"),
        "{}",
        stderr(&o)
    );
    assert_eq!(
        strings(&table(&out2.join("verdict.parquet")), "channel"),
        ["aux_a", "aux_b"]
    );
}

/// Every file of a folder tree but the markers (their times differ), with its bytes.
fn files(root: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(root).unwrap().to_string_lossy().to_string();
            if p.is_dir() {
                stack.push(p);
            } else if !rel.ends_with("done.json") && rel != "summary.txt" {
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

/// summary.txt without its first line (the run's wall-clock time).
fn summary_body(out: &Path) -> String {
    let s = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    s.split_once('\n').unwrap().1.to_string()
}

/// A channel whose marker is gone (a run stopped while it was being written) is
/// analysed again by the rerun, the finished one is kept (a note says so); the
/// folder then equals a fresh run's. Changed options or a changed log redo every
/// channel; `--fresh` too.
#[test]
fn a_rerun_keeps_finished_channels_and_redoes_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("m.csv");
    std::fs::copy(fixture("multiaxis.csv"), &log).unwrap();
    let (out, fresh) = (dir.path().join("a"), dir.path().join("fresh"));
    let flags = ["--channel", "gyro_x,gyro_y", "--bootstrap", "4"];
    let o = analyze(&log, &out, &flags, dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("kept"), "{}", stderr(&o));
    // the run was stopped before gyro_y's marker was written
    std::fs::remove_file(out.join("channels/gyro_y/done.json")).unwrap();
    std::fs::remove_file(out.join("channels/gyro_y/coef.parquet")).unwrap();
    let o = analyze(&log, &out, &flags, dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("farma: note: gyro_x: done in an earlier run (same log and options), kept"),
        "{err}"
    );
    assert!(!err.contains("gyro_y: done in an earlier run"), "{err}");
    assert!(err.contains("analyze gyro_y: started") && !err.contains("analyze gyro_x: started"));
    assert!(out.join("channels/gyro_y/coef.parquet").is_file());
    let o = analyze(&log, &fresh, &flags, dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(files(&out), files(&fresh));
    assert_eq!(summary_body(&out), summary_body(&fresh));
    // all kept: nothing analysed, the same folder
    let o = analyze(&log, &out, &flags, dir.path());
    assert!(
        stderr(&o).contains("2 kept from an earlier run"),
        "{}",
        stderr(&o)
    );
    assert!(!stderr(&o).contains("started"), "{}", stderr(&o));
    assert_eq!(files(&out), files(&fresh));
    // other options: both again
    let o = analyze(
        &log,
        &out,
        &[&flags[..], &["--seed", "2"]].concat(),
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("kept"), "{}", stderr(&o));
    // a changed log (another modification time): both again
    let o = analyze(&log, &out, &flags, dir.path());
    assert!(!stderr(&o).contains("kept"), "{}", stderr(&o));
    let f = std::fs::File::options().write(true).open(&log).unwrap();
    f.set_modified(std::time::SystemTime::now() + std::time::Duration::from_secs(5))
        .unwrap();
    drop(f);
    let o = analyze(&log, &out, &flags, dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("kept"), "{}", stderr(&o));
    // --fresh: both again
    let o = analyze(&log, &out, &[&flags[..], &["--fresh"]].concat(), dir.path());
    assert!(!stderr(&o).contains("kept"), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("analyze gyro_x: started"),
        "{}",
        stderr(&o)
    );
}

/// verdict.parquet on the bundled log: one row per channel, each column what the
/// detailed tables say; the summary's first lines are the verdicts; without a
/// bootstrap the nonlinearity is not tested (null).
#[test]
fn the_verdict_table_agrees_with_the_detail() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let out = dir.path().join("a");
    let o = farma(
        &[
            "analyze",
            log.to_str().unwrap(),
            "--orders",
            "1,1,1;2,1,1",
            "--grid",
            "21",
            "--bootstrap",
            "9",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v = table(&out.join("verdict.parquet"));
    let chans = ["gyro_x", "gyro_y", "gyro_z"];
    assert_eq!(strings(&v, "channel"), chans);
    let sel = table(&out.join("select.parquet"));
    let lb = table(&out.join("ljung_box.parquet"));
    let pred = table(&out.join("prediction.parquet"));
    let con = table(&out.join("constancy.parquet"));
    for (k, ch) in chans.iter().enumerate() {
        // the selected order
        let s = (0..sel.num_rows())
            .find(|&r| {
                strings(&sel, "channel")[r] == *ch && bools(&sel, "selected")[r] == Some(true)
            })
            .unwrap();
        let order = (
            ints(&sel, "p")[s].unwrap(),
            ints(&sel, "q")[s].unwrap(),
            ints(&sel, "d")[s].unwrap(),
        );
        assert_eq!(
            (ints(&v, "p")[k], ints(&v, "q")[k], ints(&v, "d")[k]),
            (Some(order.0), Some(order.1), Some(order.2))
        );
        assert_eq!(
            strings(&v, "order")[k],
            format!("FARMA({},{},{})", order.0, order.1, order.2)
        );
        // the constancy test: p, what B = 9 resolves, the rejection rule
        let cp = floats(&con, "p_value")[k].unwrap();
        assert_eq!(floats(&v, "constancy_p")[k], Some(cp));
        assert_eq!(floats(&v, "constancy_min_p")[k], Some(0.1));
        assert_eq!(ints(&v, "constancy_bootstrap")[k], Some(9));
        assert_eq!(strings(&v, "constancy_method")[k], "bootstrap");
        assert_eq!(bools(&v, "nonlinear")[k], Some(cp <= 0.05));
        // whiteness: Ljung-Box at the largest lag
        let rows: Vec<usize> = (0..lb.num_rows())
            .filter(|&r| strings(&lb, "channel")[r] == *ch)
            .collect();
        let last = *rows.iter().max_by_key(|&&r| ints(&lb, "lag")[r]).unwrap();
        let p = floats(&lb, "p_value")[last].unwrap();
        assert_eq!(ints(&v, "ljung_box_lag")[k], ints(&lb, "lag")[last]);
        assert_eq!(ints(&v, "ljung_box_lag")[k], Some(20));
        assert_eq!(floats(&v, "ljung_box_p")[k], Some(p));
        assert_eq!(bools(&v, "residuals_white")[k], Some(p > 0.05));
        // the 1-step hold-out RMSE
        let r1 = (0..pred.num_rows())
            .find(|&r| strings(&pred, "channel")[r] == *ch && ints(&pred, "k")[r] == Some(1))
            .unwrap();
        let (f, a) = (
            floats(&pred, "rmse_farma")[r1].unwrap(),
            floats(&pred, "rmse_arma")[r1].unwrap(),
        );
        assert_eq!(floats(&v, "rmse_farma_k1")[k], Some(f));
        assert_eq!(floats(&v, "rmse_arma_k1")[k], Some(a));
        assert_eq!(floats(&v, "rmse_ratio_k1")[k], Some(f / a));
        assert_eq!(ints(&v, "n_train")[k], Some(3500));
        assert_eq!(ints(&v, "holdout")[k], Some(500));
    }
    // the summary opens with one verdict line per channel, before the detail
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    let lines: Vec<&str> = summary.lines().collect();
    assert_eq!(lines[2], "== verdict (alpha 0.05)");
    for (k, ch) in chans.iter().enumerate() {
        let l = lines[3 + k].trim_start();
        assert!(l.starts_with(ch) && l.contains("nonlinear: "), "{l}");
        assert!(l.contains("B = 9 resolves p >= 0.100"), "{l}");
        assert!(l.contains("residuals white: ") && l.contains("hold-out 1-step RMSE FARMA/ARMA"));
    }
    assert!(summary.find("== verdict") < summary.find("######## gyro_x"));
    // --json carries the verdict too
    let o = farma(
        &[
            "analyze",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "--orders",
            "1,1,1",
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
    let j: serde_json::Value = serde_json::from_str(stdout(&o).trim()).unwrap();
    assert_eq!(j["verdict"]["nonlinear"], serde_json::Value::Null);
    assert_eq!(j["verdict"]["order"], "FARMA(1,1,1)");
    let v = table(&out.join("verdict.parquet"));
    assert_eq!(bools(&v, "nonlinear"), [None]);
    assert_eq!(floats(&v, "constancy_p"), [None]);
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(summary.contains("nonlinear: not tested"), "{summary}");
    // the default test, chi2: its method, p resolved down to 0
    let o = farma(
        &[
            "analyze",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "--orders",
            "1,1,1",
            "--grid",
            "21",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v = table(&out.join("verdict.parquet"));
    assert_eq!(strings(&v, "constancy_method"), ["chi2"]);
    assert_eq!(floats(&v, "constancy_min_p"), [Some(0.0)]);
    let cp = floats(&v, "constancy_p")[0].unwrap();
    assert_eq!(bools(&v, "nonlinear"), [Some(cp <= 0.05)]);
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(summary.contains(", chi2 test)"), "{summary}");
}

/// stderr not a terminal: one timestamped line when a channel starts and when it is
/// done (order and constancy p) or fails; none with --quiet.
#[test]
fn plain_progress_lines_when_stderr_is_not_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("imu.csv");
    write_log(&log, &["gyro_x", "gyro_y"], 600);
    let out = dir.path().join("a");
    let o = analyze(&log, &out, &["--bootstrap", "4"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let err = stderr(&o);
    // 2026-11-27T07:30:01Z analyze gyro_x: started
    let stamped = |l: &str| {
        let b = l.as_bytes();
        l.len() > 21
            && b[4] == b'-'
            && b[7] == b'-'
            && b[10] == b'T'
            && b[13] == b':'
            && b[16] == b':'
            && b[19] == b'Z'
            && l[..4].chars().all(|c| c.is_ascii_digit())
            && l[20..].starts_with(" analyze ")
    };
    for ch in ["gyro_x", "gyro_y"] {
        let started: Vec<&str> = err
            .lines()
            .filter(|l| l.ends_with(&format!("analyze {ch}: started")))
            .collect();
        assert_eq!(started.len(), 1, "{err}");
        assert!(stamped(started[0]), "{err}");
        let done: Vec<&str> = err
            .lines()
            .filter(|l| l.contains(&format!("analyze {ch}: done in ")))
            .collect();
        assert_eq!(done.len(), 1, "{err}");
        assert!(stamped(done[0]), "{err}");
        assert!(
            done[0].contains("s (FARMA(1,1,1), nonlinear p = "),
            "{}",
            done[0]
        );
    }
    let o = analyze(
        &log,
        &out,
        &["--bootstrap", "4", "--fresh", "--quiet"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("started"), "{}", stderr(&o));
}
