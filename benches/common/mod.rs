//! Helpers shared by the benchmarks (plain `main` programs, `harness = false`).
#![allow(dead_code)]

use std::path::PathBuf;

/// Folder for large benchmark inputs: `$FARMA_BENCH_DIR`, else `target/bench-data`.
pub fn bench_dir() -> PathBuf {
    let d = std::env::var_os("FARMA_BENCH_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("target")
                .join("bench-data")
        });
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A `/proc/self/status` field in KiB (VmRSS, VmHWM, RssAnon, RssFile), Linux only.
pub fn proc_status_kib(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines()
        .find(|l| l.starts_with(field) && l[field.len()..].starts_with(':'))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
}

/// The machine, for BENCHMARKS.md.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown cpu".into());
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    format!("{cpu}, {cores} cores")
}
