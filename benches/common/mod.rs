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

/// The FARMA(2,1,1) of tests/suite/workflow_select.rs: f_1(z) = 0.2 + 0.6 exp(-z^2),
/// f_2(z) = -0.25 + 0.15 tanh z, b = 0.4, z = x_{t-1}, unit Gaussian innovations
/// (ChaCha8, `seed`), 500 samples of burn-in dropped.
pub fn farma211(n: usize, seed: u64) -> Vec<f64> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let burn = 500;
    let (mut x, mut e) = (vec![0.0; n + burn], vec![0.0; n + burn]);
    for t in 0..n + burn {
        e[t] = StandardNormal.sample(&mut rng);
        let mut s = e[t];
        if t >= 2 {
            let z = x[t - 1];
            s += (0.2 + 0.6 * f64::exp(-z * z)) * x[t - 1]
                + (-0.25 + 0.15 * z.tanh()) * x[t - 2]
                + 0.4 * e[t - 1];
        }
        x[t] = s;
    }
    x.split_off(burn)
}
