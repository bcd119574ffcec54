//! Opening a store is constant time and reads nothing: a 1e8-row store (two channels,
//! 1.6 GB) is opened and one channel's slice of 1,000 values is read, in a fresh
//! process; we report the time and the RSS it adds, beside a full sequential pass
//! over the same channel (which does read the file).
//!
//! Run: `cargo bench --bench store_open` (`FARMA_BENCH_ROWS` overrides 1e8).

#[path = "common/mod.rs"]
mod common;

use std::process::Command;
use std::time::Instant;

use farma::store::{Segment, StoreMeta, StoreWriter};

fn make_store(path: &std::path::Path, rows: usize) {
    let names = vec!["gyro_x".to_string(), "gyro_y".to_string()];
    let mut w = StoreWriter::create(path, &names, rows).unwrap();
    for (c, col) in w.columns_mut().into_iter().enumerate() {
        for (i, v) in col.iter_mut().enumerate() {
            *v = (i % 1000) as f64 * 1e-3 + c as f64;
        }
    }
    let meta = StoreMeta {
        format_version: farma::store::STORE_FORMAT_VERSION,
        farma_version: env!("CARGO_PKG_VERSION").into(),
        sample_rate_hz: 100.0,
        time_source: "flag".into(),
        time_col: None,
        segments: vec![Segment {
            start: 0,
            len: rows as u64,
            t0_s: 0.0,
        }],
        repairs: vec![],
        source: "benchmark".into(),
        source_format: "generated".into(),
        source_size: 0,
        source_mtime_ns: 0,
        nonfinite: vec![],
    };
    w.finish(&meta).unwrap();
}

/// Child: open, read 1,000 values from the middle of one channel; print timings and RSS.
fn child(path: &str, full_pass: bool) {
    let rss0 = common::proc_status_kib("VmRSS").unwrap_or(0);
    let t = Instant::now();
    let s = farma::store::Store::open(path.as_ref()).unwrap();
    let open_s = t.elapsed().as_secs_f64();
    let x = s.column("gyro_y").unwrap();
    let mid = x.len() / 2;
    let t = Instant::now();
    let sum: f64 = x[mid..mid + 1000].iter().sum();
    let slice_s = t.elapsed().as_secs_f64();
    let rss1 = common::proc_status_kib("VmRSS").unwrap_or(0);
    let (pass_s, total) = if full_pass {
        let t = Instant::now();
        let total: f64 = x.iter().sum();
        (t.elapsed().as_secs_f64(), total)
    } else {
        (0.0, 0.0)
    };
    println!(
        "{open_s} {slice_s} {} {pass_s} {sum} {total} {}",
        rss1 as i64 - rss0 as i64,
        s.n_samples()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() == 4 && args[1] == "--child" {
        child(&args[2], args[3] == "full");
        return;
    }
    let rows: usize = std::env::var("FARMA_BENCH_ROWS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100_000_000);
    let path = common::bench_dir().join(format!("store_{rows}.arrow"));
    if !path.exists() {
        eprintln!("writing {} ...", path.display());
        make_store(&path, rows);
    }
    let size = std::fs::metadata(&path).unwrap().len();
    let run = |mode: &str| -> Vec<f64> {
        let o = Command::new(std::env::current_exe().unwrap())
            .args(["--child", path.to_str().unwrap(), mode])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8(o.stdout)
            .unwrap()
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let mut best = [f64::INFINITY; 2];
    let mut rss_added = 0.0f64;
    for _ in 0..5 {
        let v = run("slice");
        best[0] = best[0].min(v[0]);
        best[1] = best[1].min(v[1]);
        rss_added = rss_added.max(v[2]);
    }
    let full = run("full");
    println!("machine: {}", common::machine());
    println!(
        "store: {} rows x 2 channels, {:.2} GB",
        full[6],
        size as f64 / 1e9
    );
    println!(
        "open (map + footer + batch metadata): {:.1} us (best of 5)",
        best[0] * 1e6
    );
    println!(
        "read 1,000 values of one channel:     {:.1} us",
        best[1] * 1e6
    );
    println!(
        "RSS added by open + slice read:       {rss_added:.0} KiB (the channel is {:.0} MiB)",
        rows as f64 * 8.0 / 1048576.0
    );
    println!(
        "floor, one full pass over the channel (sum from the map): {:.3} s",
        full[3]
    );
}
