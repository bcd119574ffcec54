//! Allan deviation: allantools' golden values (fixtures/golden/), the R package avar's
//! curve of a real ADIS16405 run (../shared/realdata), and the `farma adev` command.

use std::path::Path;

use crate::common::{self, farma, fixture, realdata, stderr, stdout};
use farma::stats::adev::{
    self, CiOptions, Kind, TauGrid, avar, confidence_interval, curves, phase,
};

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Non-comment lines of a small CSV, split on commas: (header, rows).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty());
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

fn rate_from_header(path: &Path) -> f64 {
    let text = std::fs::read_to_string(path).unwrap();
    let line = text.lines().find(|l| l.contains("rate_hz=")).unwrap();
    let v = line.split("rate_hz=").nth(1).unwrap();
    v.split_whitespace().next().unwrap().parse().unwrap()
}

struct Golden {
    kind: Kind,
    grid: String,
    m: usize,
    tau_s: f64,
    dev: f64,
    edf: f64,
    lo: f64,
    hi: f64,
    n: usize,
}

fn golden(name: &str) -> (Vec<f64>, f64, Vec<Golden>) {
    let input = fixture(&format!("golden/adev_input_{name}.csv"));
    let (_, rows) = read_csv(&input);
    let y: Vec<f64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    let rate_hz = rate_from_header(&input);
    let (header, rows) = read_csv(&fixture(&format!("golden/adev_golden_{name}.csv")));
    assert_eq!(
        header,
        [
            "kind", "grid", "m", "tau_s", "dev", "edf", "dev_lo", "dev_hi", "n"
        ]
    );
    let g = rows
        .iter()
        .map(|r| Golden {
            kind: match r[0].as_str() {
                "oadev" => Kind::Adev,
                "mdev" => Kind::Mdev,
                "ohdev" => Kind::Hdev,
                k => panic!("unknown kind {k}"),
            },
            grid: r[1].clone(),
            m: r[2].parse().unwrap(),
            tau_s: r[3].parse().unwrap(),
            dev: r[4].parse().unwrap(),
            edf: r[5].parse().unwrap(),
            lo: r[6].parse().unwrap(),
            hi: r[7].parse().unwrap(),
            n: r[8].parse().unwrap(),
        })
        .collect();
    (y, rate_hz, g)
}

fn check_golden(name: &str) {
    let (y, rate_hz, g) = golden(name);
    let mut worst = [0.0f64; 4];
    for grid in ["octave", "dense"] {
        let tau_grid = match grid {
            "octave" => TauGrid::Octave,
            _ => TauGrid::Dense { per_decade: 10 },
        };
        let ours = curves(
            "golden",
            &y,
            rate_hz,
            &Kind::ALL,
            tau_grid,
            CiOptions::default(),
        )
        .unwrap();
        for c in &ours {
            let theirs: Vec<&Golden> = g
                .iter()
                .filter(|r| r.kind == c.kind && r.grid == grid)
                .collect();
            let ms: Vec<usize> = c.points.iter().map(|p| p.m).collect();
            let their_ms: Vec<usize> = theirs.iter().map(|r| r.m).collect();
            assert_eq!(
                ms, their_ms,
                "{name} {:?} {grid}: averaging factors",
                c.kind
            );
            for (p, r) in c.points.iter().zip(&theirs) {
                let what = format!("{name} {:?} {grid} m={}", c.kind, p.m);
                assert!(rel(p.tau_s, r.tau_s) < 1e-15, "{what}: tau");
                assert_eq!(p.n_terms, r.n, "{what}: terms");
                let e = [
                    rel(p.dev, r.dev),
                    rel(p.edf, r.edf),
                    rel(p.lo, r.lo),
                    rel(p.hi, r.hi),
                ];
                for (w, v) in worst.iter_mut().zip(e) {
                    *w = w.max(v);
                }
                assert!(
                    e[0] < 1e-10,
                    "{what}: dev {} vs allantools {}",
                    p.dev,
                    r.dev
                );
                assert!(
                    e[1] < 1e-10,
                    "{what}: edf {} vs allantools {}",
                    p.edf,
                    r.edf
                );
                assert!(e[2] < 1e-10, "{what}: lo {} vs allantools {}", p.lo, r.lo);
                assert!(e[3] < 1e-10, "{what}: hi {} vs allantools {}", p.hi, r.hi);
            }
        }
    }
    println!(
        "{name}: worst relative difference to allantools: dev {:.1e}, edf {:.1e}, lo {:.1e}, hi {:.1e}",
        worst[0], worst[1], worst[2], worst[3]
    );
}

#[test]
fn matches_allantools_white_plus_random_walk() {
    check_golden("wn_rw");
}

#[test]
fn matches_allantools_short_series() {
    check_golden("short");
}

#[test]
fn interval_brackets_and_narrows_with_edf() {
    let (lo1, hi1) = confidence_interval(1.0, 10.0, adev::ONE_SIGMA);
    let (lo2, hi2) = confidence_interval(1.0, 1000.0, adev::ONE_SIGMA);
    assert!(lo1 < lo2 && lo2 < 1.0 && 1.0 < hi2 && hi2 < hi1);
}

/// The R package avar's curve for run 1 of the ADIS16405 data.
#[test]
fn matches_avar_on_adis16405_run1() {
    let (Some(parquet), Some(curve)) = (
        realdata("imudata-adis16405/adis_16405_imu1.parquet"),
        realdata("avar-allan-curves/adis_av.csv"),
    ) else {
        println!("SKIPPED: ../shared/realdata (ADIS16405 run 1 and avar's curve) not present");
        return;
    };
    let (_cache, store) = crate::common::open_store(&parquet);
    let rate_hz = store.sample_rate_hz();
    assert_eq!(rate_hz, 100.0);
    let (header, rows) = read_csv(&curve);
    let col = |n: &str| header.iter().position(|h| h == n).unwrap();
    let (c_chan, c_tau, c_adev) = (col("channel"), col("tau_s"), col("adev"));
    let channels = [
        ("Gyro. X", "gyro_x_dps"),
        ("Gyro. Y", "gyro_y_dps"),
        ("Gyro. Z", "gyro_z_dps"),
        ("Accel. X", "accel_x_g"),
        ("Accel. Y", "accel_y_g"),
        ("Accel. Z", "accel_z_g"),
    ];
    for (theirs, ours) in channels {
        let y = store.column(ours).unwrap();
        let x = phase(y);
        let ref_rows: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r[c_chan] == theirs)
            .map(|r| (r[c_tau].parse().unwrap(), r[c_adev].parse().unwrap()))
            .collect();
        let levels = avar::avar_levels(y.len());
        assert_eq!(ref_rows.len(), levels.len(), "{theirs}: number of taus");
        let ms: Vec<usize> = levels.clone();
        let oadev = adev::deviations_from_phase(&x, Kind::Adev, &ms);
        let (mut worst_std, mut worst_avar) = (0.0f64, 0.0f64);
        let mut worst_std_tau = 0.0;
        for ((&m, &(tau_s, ref_adev)), std_adev) in levels.iter().zip(&ref_rows).zip(oadev) {
            assert!(
                rel(m as f64 / rate_hz, tau_s) < 1e-12,
                "{theirs}: tau {tau_s}"
            );
            // avar's own estimator (one difference short in the sum, see
            // farma::stats::adev::avar): must agree to rounding.
            let a = avar::avar_mo_deviation(&x, m);
            worst_avar = worst_avar.max(rel(a, ref_adev));
            assert!(
                rel(a, ref_adev) < 1e-9,
                "{theirs} tau={tau_s}: avar estimator {a} vs avar {ref_adev}"
            );
            // farma's standard overlapping ADEV (allantools' oadev): the bar is 1e-5.
            let e = rel(std_adev, ref_adev);
            if e > worst_std {
                worst_std = e;
                worst_std_tau = tau_s;
            }
            assert!(
                e < 1e-5,
                "{theirs} tau={tau_s}: overlapping ADEV {std_adev} vs avar {ref_adev} ({e:.2e})"
            );
        }
        println!(
            "{theirs} ({ours}): overlapping ADEV vs avar worst {worst_std:.2e} (tau {worst_std_tau} s); \
             avar's estimator vs avar worst {worst_avar:.2e}"
        );
    }
}

#[test]
fn cli_json_text_parquet_and_errors() {
    let cache = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let log = log.to_str().unwrap();
    let o = farma(
        &["adev", log, "--channel", "gyro_x,gyro_y", "--json"],
        cache.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let lines: Vec<serde_json::Value> = stdout(&o)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2);
    // The same numbers as the library on the same column.
    let (_, cols) = common::reference_parse_csv(&fixture("multiaxis.csv"));
    let y = &cols[1];
    let lib = curves(
        "t",
        y,
        10.0,
        &[Kind::Adev],
        TauGrid::Octave,
        CiOptions::default(),
    )
    .unwrap();
    let v = &lines[0];
    assert_eq!(v["channel"], "gyro_x");
    let tau: Vec<f64> = serde_json::from_value(v["tau_s"].clone()).unwrap();
    let dev: Vec<f64> = serde_json::from_value(v["adev"].clone()).unwrap();
    let lo: Vec<f64> = serde_json::from_value(v["adev_lo"].clone()).unwrap();
    let hi: Vec<f64> = serde_json::from_value(v["adev_hi"].clone()).unwrap();
    assert_eq!(tau.len(), lib[0].points.len());
    // serde_json's float parsing is within an ulp or so, not always exact.
    for (i, p) in lib[0].points.iter().enumerate() {
        assert!(
            rel(tau[i], p.tau_s) < 1e-15,
            "tau {} vs {}",
            tau[i],
            p.tau_s
        );
        assert!(rel(dev[i], p.dev) < 1e-15, "adev {} vs {}", dev[i], p.dev);
        assert!(rel(lo[i], p.lo) < 1e-15, "lo {} vs {}", lo[i], p.lo);
        assert!(rel(hi[i], p.hi) < 1e-15, "hi {} vs {}", hi[i], p.hi);
    }

    // Text table.
    let o = farma(
        &["adev", log, "--channel", "gyro_z", "--kind", "all"],
        cache.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("mdev") && out.contains("hdev") && out.contains("gyro_z"),
        "{out}"
    );

    // Parquet.
    let dir = tempfile::tempdir().unwrap();
    let pq = dir.path().join("a.parquet");
    let o = farma(
        &[
            "adev",
            log,
            "--channel",
            "all",
            "--kind",
            "all",
            "--taus",
            "dense",
            "-o",
            pq.to_str().unwrap(),
        ],
        cache.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let r = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(
        std::fs::File::open(&pq).unwrap(),
    )
    .unwrap()
    .build()
    .unwrap();
    let rows: usize = r.map(|b| b.unwrap().num_rows()).sum();
    assert!(rows > 4 * 3 * 20, "{rows} rows");

    // Unknown channel and a log too short: exit 2 with a message naming the problem.
    let o = farma(&["adev", log, "--channel", "nope"], cache.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("nope"), "{}", stderr(&o));
    let short = dir.path().join("short.csv");
    std::fs::write(&short, "time_s,g\n0,1\n0.1,2\n").unwrap();
    let o = farma(
        &["adev", short.to_str().unwrap(), "--channel", "g"],
        cache.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("too short"), "{}", stderr(&o));
}
