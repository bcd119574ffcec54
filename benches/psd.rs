//! Welch PSD (Hann window, 50 % overlap, segments of 65536 samples, mean removed per
//! segment, one-sided density): farma beside scipy.signal.welch on the same data in
//! the same run.
//!
//! Run: `cargo bench --bench psd` (needs `python3 -m pip install scipy numpy` for the
//! peer; without it the peer is reported as missing). `FARMA_BENCH_N` sets the number of
//! samples (default 1e7), `FARMA_BENCH_SEGMENT` the segment length, `FARMA_BENCH_DIR`
//! where the raw data file for the peer lives (default target/bench-data). farma: best
//! of 3 in this process (data in memory); scipy: best of 3 in one fresh python3
//! process, timed around the `welch` call only (data already loaded). Also reports the
//! largest difference between the two spectra, relative to each bin.

#[path = "common/mod.rs"]
mod common;

use std::io::Write;
use std::process::Command;
use std::time::Instant;

use farma::stats::psd::{Detrend, welch};

/// White noise plus a random walk, from a fixed xorshift64* stream (as benches/adev.rs).
fn series(n: usize) -> Vec<f64> {
    let mut state: u64 = 0x9E3779B97F4A7C15;
    let mut next = || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545F4914F6CDD1D) >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut walk = 0.0;
    (0..n)
        .map(|_| {
            walk += 1e-3 * next();
            0.01 + walk + next()
        })
        .collect()
}

const PEER: &str = r#"
import sys, time, json
import numpy as np
import scipy, scipy.signal
y = np.fromfile(sys.argv[1], dtype='<f8')
fs = float(sys.argv[2]); L = int(sys.argv[3])
best = float('inf')
for _ in range(3):
    t0 = time.perf_counter()
    f, p = scipy.signal.welch(y, fs=fs, window='hann', nperseg=L, noverlap=L // 2,
                              detrend='constant', scaling='density')
    best = min(best, time.perf_counter() - t0)
np.asarray(p, dtype='<f8').tofile(sys.argv[1] + '.psd')
print(json.dumps({"secs": best, "version": scipy.__version__, "numpy": np.__version__}))
"#;

fn main() {
    let n: usize = std::env::var("FARMA_BENCH_N")
        .ok()
        .map(|s| s.parse::<f64>().expect("FARMA_BENCH_N") as usize)
        .unwrap_or(10_000_000);
    let l: usize = std::env::var("FARMA_BENCH_SEGMENT")
        .ok()
        .map(|s| s.parse().expect("FARMA_BENCH_SEGMENT"))
        .unwrap_or(65_536);
    let rate_hz = 100.0;
    println!("machine: {}", common::machine());
    println!("samples: {n}, rate {rate_hz} Hz, Welch PSD, segments of {l}, 50 % overlap");
    let y = series(n);

    let mut best = f64::INFINITY;
    let mut ours = None;
    for _ in 0..3 {
        let t = Instant::now();
        ours = Some(welch("bench", &y, rate_hz, l, Detrend::Constant).unwrap());
        best = best.min(t.elapsed().as_secs_f64());
    }
    let ours = ours.unwrap();
    println!(
        "farma: best of 3 {best:.3} s ({} segments)",
        ours.n_segments
    );

    let path = common::bench_dir().join(format!("psd_{n}.f64"));
    {
        let f = std::fs::File::create(&path).unwrap();
        let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
        for v in &y {
            w.write_all(&v.to_le_bytes()).unwrap();
        }
        w.flush().unwrap();
    }
    drop(y);
    let out = Command::new("python3")
        .args([
            "-c",
            PEER,
            path.to_str().unwrap(),
            &rate_hz.to_string(),
            &l.to_string(),
        ])
        .output();
    let _ = std::fs::remove_file(&path);
    let psd_path = path.with_extension("f64.psd");
    let peer = match out {
        Ok(o) if o.status.success() => {
            serde_json::from_slice::<serde_json::Value>(&o.stdout).expect("peer output")
        }
        Ok(o) => {
            println!(
                "scipy: missing or failed ({})",
                String::from_utf8_lossy(&o.stderr)
                    .lines()
                    .last()
                    .unwrap_or("")
            );
            return;
        }
        Err(e) => {
            println!("scipy: python3 not runnable ({e})");
            return;
        }
    };
    let theirs: Vec<f64> = std::fs::read(&psd_path)
        .unwrap()
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let _ = std::fs::remove_file(&psd_path);
    assert_eq!(theirs.len(), ours.psd.len(), "same number of bins");
    let worst = ours
        .psd
        .iter()
        .zip(&theirs)
        .skip(1) // DC: the mean removal leaves rounding noise only
        .map(|(a, b)| (a - b).abs() / b.abs())
        .fold(0.0f64, f64::max);
    let secs = peer["secs"].as_f64().unwrap();
    println!(
        "scipy {} (numpy {}): best of 3 {secs:.3} s",
        peer["version"].as_str().unwrap_or("?"),
        peer["numpy"].as_str().unwrap_or("?")
    );
    println!("farma is {:.1}x faster", secs / best);
    println!("largest relative difference farma vs scipy (bins 1..): {worst:.2e}");
}
