//! Welch PSD and autocorrelation (src/stats/psd.rs, acf.rs): scipy.signal.welch and
//! statsmodels acf golden values (fixtures/golden/make_psd_acf_golden.py), and the
//! `farma psd` / `farma acf` commands.

use crate::common::{self, farma, fixture, stderr, stdout};
use farma::stats::acf::acf;
use farma::stats::psd::{Detrend, welch};

fn data_lines(rel: &str) -> Vec<String> {
    std::fs::read_to_string(fixture(rel))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
        .map(str::to_string)
        .collect()
}

fn input() -> (Vec<f64>, f64) {
    let text = std::fs::read_to_string(fixture("golden/psd_acf_input.csv")).unwrap();
    let rate: f64 = text
        .lines()
        .find_map(|l| l.split("rate_hz=").nth(1))
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let lines = data_lines("golden/psd_acf_input.csv");
    assert_eq!(lines[0], "y");
    (
        lines[1..].iter().map(|l| l.parse().unwrap()).collect(),
        rate,
    )
}

#[test]
fn welch_matches_scipy() {
    let (y, rate) = input();
    let lines = data_lines("golden/psd_golden.csv");
    assert_eq!(lines[0], "nperseg,detrend,freq_hz,psd");
    let rows: Vec<Vec<String>> = lines[1..]
        .iter()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    let mut cases = 0;
    for (l, d) in [(256usize, "constant"), (500, "none"), (3000, "constant")] {
        let theirs: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r[0] == l.to_string() && r[1] == d)
            .map(|r| (r[2].parse().unwrap(), r[3].parse().unwrap()))
            .collect();
        let detrend = if d == "none" {
            Detrend::None
        } else {
            Detrend::Constant
        };
        let ours = welch("golden", &y, rate, l, detrend).unwrap();
        assert_eq!(ours.psd.len(), theirs.len(), "L={l}");
        let top = theirs.iter().map(|t| t.1).fold(0.0, f64::max);
        for (k, ((f, p), (tf, tp))) in ours.freq_hz.iter().zip(&ours.psd).zip(&theirs).enumerate() {
            assert!(
                (f - tf).abs() <= 1e-12 * tf.abs().max(1.0),
                "L={l} k={k}: f"
            );
            // Relative to the bin, with a floor at 1e-12 of the peak for bins that
            // detrending makes nearly zero (DC).
            assert!(
                (p - tp).abs() <= 1e-10 * tp.abs() + 1e-12 * top,
                "L={l} {d} k={k}: {p} vs scipy {tp}"
            );
        }
        cases += 1;
    }
    assert_eq!(cases, 3);
}

#[test]
fn acf_matches_statsmodels() {
    let (y, _) = input();
    let lines = data_lines("golden/acf_golden.csv");
    assert_eq!(lines[0], "lag,acf_fft,acf_direct");
    let ours = acf("golden", &y, 200).unwrap();
    assert_eq!(ours.acf.len(), lines.len() - 1);
    for (k, l) in lines[1..].iter().enumerate() {
        let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(f[0] as usize, k);
        assert!(
            (ours.acf[k] - f[1]).abs() < 1e-13,
            "lag {k}: {} vs {}",
            ours.acf[k],
            f[1]
        );
        assert!((ours.acf[k] - f[2]).abs() < 1e-13, "lag {k}: direct");
    }
    assert!((ours.band - 1.96 / 3000f64.sqrt()).abs() < 1e-16);
}

#[test]
fn cli_psd_and_acf() {
    let cache = tempfile::tempdir().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let log = log.to_str().unwrap();
    let (_, cols) = common::reference_parse_csv(&fixture("multiaxis.csv"));

    // PSD: JSON equals the library on the same column.
    let o = farma(
        &[
            "psd",
            log,
            "--channel",
            "gyro_x,gyro_y",
            "--segment",
            "256",
            "--json",
        ],
        cache.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Vec<serde_json::Value> = stdout(&o)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(v.len(), 2);
    assert_eq!(v[0]["channel"], "gyro_x");
    let lib = welch("t", &cols[1], 10.0, 256, Detrend::Constant).unwrap();
    let p: Vec<f64> = serde_json::from_value(v[0]["psd"].clone()).unwrap();
    assert_eq!(p.len(), 129);
    assert_eq!(v[0]["n_segments"], lib.n_segments);
    for (a, b) in p.iter().zip(&lib.psd) {
        assert!((a - b).abs() <= 1e-15 * b.abs(), "{a} vs {b}");
    }
    // Bands: every bin but DC counted once.
    let o = farma(
        &[
            "psd",
            log,
            "--channel",
            "gyro_x",
            "--segment",
            "256",
            "--bands-per-decade",
            "5",
            "--json",
        ],
        cache.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(stdout(&o).trim()).unwrap();
    let nb: Vec<usize> = serde_json::from_value(v["n_bins"].clone()).unwrap();
    assert_eq!(nb.iter().sum::<usize>(), 128);
    // Text and Parquet.
    let pq = dir.path().join("p.parquet");
    let o = farma(
        &["psd", log, "--channel", "all", "-o", pq.to_str().unwrap()],
        cache.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("Welch PSD"), "{}", stdout(&o));
    let rows: usize = parquet_rows(&pq);
    assert!(rows > 4 * 100, "{rows}");

    // ACF.
    let o = farma(
        &[
            "acf",
            log,
            "--channel",
            "gyro_z",
            "--max-lag",
            "50",
            "--json",
        ],
        cache.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(stdout(&o).trim()).unwrap();
    let r: Vec<f64> = serde_json::from_value(v["acf"].clone()).unwrap();
    let lib = acf("t", &cols[3], 50).unwrap();
    assert_eq!(r.len(), 51);
    for (a, b) in r.iter().zip(&lib.acf) {
        assert!((a - b).abs() <= 1e-15, "{a} vs {b}");
    }
    let pq = dir.path().join("a.parquet");
    let o = farma(
        &["acf", log, "--max-lag", "20", "-o", pq.to_str().unwrap()],
        cache.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("autocorrelation"));
    assert_eq!(parquet_rows(&pq), 4 * 21);

    // Bad input: exit code 2 and a message naming the problem; no output written.
    let bad = dir.path().join("bad.parquet");
    let o = farma(
        &["acf", log, "--max-lag", "4000", "-o", bad.to_str().unwrap()],
        cache.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--max-lag"), "{}", stderr(&o));
    assert!(!bad.exists());
    let o = farma(&["psd", log, "--segment", "5000"], cache.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("too short"), "{}", stderr(&o));
    let o = farma(&["psd", log, "--channel", "nope"], cache.path());
    assert_eq!(o.status.code(), Some(2));
}

fn parquet_rows(p: &std::path::Path) -> usize {
    parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(
        std::fs::File::open(p).unwrap(),
    )
    .unwrap()
    .build()
    .unwrap()
    .map(|b| b.unwrap().num_rows())
    .sum()
}
