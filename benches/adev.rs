//! Overlapping Allan deviation at octave taus on 1e8 samples: farma beside allantools'
//! `oadev` (data_type="freq", taus="octave") on the same data in the same run.
//!
//! Run: `cargo bench --bench adev` (needs `python3 -m pip install allantools numpy` for
//! the peer; without it the peer is reported as missing). `FARMA_BENCH_N` sets the
//! number of samples (default 1e8), `FARMA_BENCH_DIR` where the raw data file for the
//! peer lives (default target/bench-data). farma: best of 3 in this process (phase and
//! all taus, data in memory); allantools: one run in a fresh python3 process, timed
//! around the `oadev` call only (data already loaded). Also reports the largest
//! relative difference between the two curves.

#[path = "common/mod.rs"]
mod common;

use std::io::Write;
use std::process::Command;
use std::time::Instant;

use farma::stats::adev::{Kind, deviations, octave};

/// White noise plus a random walk (a gyro's angle random walk and rate random walk),
/// from a fixed xorshift64* stream: deterministic, no dependency.
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
import allantools
y = np.fromfile(sys.argv[1], dtype='<f8')
t0 = time.perf_counter()
taus, dev, err, ns = allantools.oadev(y, rate=float(sys.argv[2]), data_type='freq', taus='octave')
t1 = time.perf_counter()
print(json.dumps({"secs": t1 - t0, "version": allantools.__version__,
                  "m": [int(round(t * float(sys.argv[2]))) for t in taus], "dev": [float(d) for d in dev]}))
"#;

fn main() {
    let n: usize = std::env::var("FARMA_BENCH_N")
        .ok()
        .map(|s| s.parse::<f64>().expect("FARMA_BENCH_N") as usize)
        .unwrap_or(100_000_000);
    let rate_hz = 100.0;
    println!("machine: {}", common::machine());
    println!("samples: {n}, rate {rate_hz} Hz, overlapping ADEV, octave taus");
    let y = series(n);
    let ms = octave(Kind::Adev, n);
    println!("taus: {} (m = 1 .. {})", ms.len(), ms.last().unwrap());

    let mut best = f64::INFINITY;
    let mut ours = Vec::new();
    for _ in 0..3 {
        let t = Instant::now();
        ours = deviations(&y, Kind::Adev, &ms);
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!("farma: best of 3 {best:.3} s");
    {
        // Where the time goes: the phase alone, then the sums from it.
        let t = Instant::now();
        let x = farma::stats::adev::phase(&y);
        let t_phase = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let _ = farma::stats::adev::deviations_from_phase(&x, Kind::Adev, &ms);
        let t_sums = t.elapsed().as_secs_f64();
        println!("  of which phase {t_phase:.3} s, sums over all taus {t_sums:.3} s");
    }

    let path = common::bench_dir().join(format!("adev_{n}.f64"));
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
        .args(["-c", PEER, path.to_str().unwrap(), &rate_hz.to_string()])
        .output();
    let _ = std::fs::remove_file(&path);
    let peer = match out {
        Ok(o) if o.status.success() => {
            serde_json::from_slice::<serde_json::Value>(&o.stdout).expect("peer output")
        }
        Ok(o) => {
            println!(
                "allantools: missing or failed ({})",
                String::from_utf8_lossy(&o.stderr)
                    .lines()
                    .last()
                    .unwrap_or("")
            );
            return;
        }
        Err(e) => {
            println!("allantools: python3 not runnable ({e})");
            return;
        }
    };
    let secs = peer["secs"].as_f64().unwrap();
    let their_m: Vec<usize> = serde_json::from_value(peer["m"].clone()).unwrap();
    let their_dev: Vec<f64> = serde_json::from_value(peer["dev"].clone()).unwrap();
    assert_eq!(their_m, ms, "same averaging factors");
    let worst = ours
        .iter()
        .zip(&their_dev)
        .map(|(a, b)| (a - b).abs() / b.abs())
        .fold(0.0f64, f64::max);
    println!(
        "allantools {}: {secs:.3} s",
        peer["version"].as_str().unwrap_or("?")
    );
    println!("farma is {:.1}x faster", secs / best);
    println!("largest relative difference farma vs allantools: {worst:.2e}");
}
