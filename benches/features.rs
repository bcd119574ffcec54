//! Benchmark of the gap diagnosis' statistics (`diagnosis::features`): seconds per
//! family on one withheld part of a 1e6-sample series (white noise plus a random walk,
//! 100 Hz, a temperature channel), the cost each candidate's replicas pay.
//!
//!     cargo bench --bench features        (FARMA_BENCH_N=1000000 FARMA_BENCH_REPS=5 FARMA_BENCH_GRID=0
//!                                          FARMA_BENCH_OTHERS=2)
//!
//! FARMA_BENCH_OTHERS other channels (white noise, each partly correlated with the
//! series) give the cross-axis features; their cost is the whole computation with them
//! less the one without.

use farma::diagnosis::{Blocks, Layout, Temperature};
use rand::{Rng, SeedableRng};

fn main() {
    let env = |k: &str, d: usize| {
        std::env::var(k)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let n = env("FARMA_BENCH_N", 1_000_000);
    let reps = env("FARMA_BENCH_REPS", 5);
    let rate_hz = 100.0;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut walk = 0.0;
    let x: Vec<f64> = (0..n)
        .map(|_| {
            walk += 1e-3 * (rng.random::<f64>() - 0.5);
            walk + (rng.random::<f64>() - 0.5)
        })
        .collect();
    // FARMA_BENCH_GRID=Q: the series rounded to multiples of Q (a printed or quantized
    // log, as ADIS16405's 0.01 deg/s text output)
    let grid: f64 = std::env::var("FARMA_BENCH_GRID")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.0);
    let x: Vec<f64> = if grid > 0.0 {
        x.iter().map(|v| (v / grid).round() * grid).collect()
    } else {
        x
    };
    let t_c: Vec<f64> = (0..n)
        .map(|i| 25.0 + 10.0 * (i as f64 / n as f64 * 6.0).sin())
        .collect();
    let temp = Temperature::new(t_c, rate_hz);
    let blocks = Blocks::interleaved(n, 8, 0.5).unwrap();
    let layout = Layout::new(&blocks, false, rate_hz, Some(&temp), &[]);
    let t0 = std::time::Instant::now();
    for _ in 0..reps {
        std::hint::black_box(layout.compute(&x, Some(&temp), &[]));
    }
    let all = t0.elapsed().as_secs_f64() / reps as f64;
    println!(
        "features of one withheld part of {n} samples ({} features): {:.1} ms",
        layout.defs.len(),
        1e3 * all
    );
    for (family, s) in layout.family_seconds(&x, Some(&temp), reps) {
        println!("  {family:>12}: {:7.1} ms", 1e3 * s / reps as f64);
    }
    let n_others = env("FARMA_BENCH_OTHERS", 2);
    if n_others > 0 {
        let others: Vec<Vec<f64>> = (0..n_others)
            .map(|_| {
                x.iter()
                    .map(|v| 0.3 * v + (rng.random::<f64>() - 0.5))
                    .collect()
            })
            .collect();
        let names: Vec<String> = (0..n_others).map(|k| format!("other{k}")).collect();
        let with = Layout::new(&blocks, false, rate_hz, Some(&temp), &names);
        let refs: Vec<&[f64]> = others.iter().map(|o| o.as_slice()).collect();
        let sides = with.others(&refs);
        let t0 = std::time::Instant::now();
        for _ in 0..reps {
            std::hint::black_box(with.compute_with(&x, Some(&temp), &sides));
        }
        let with_s = t0.elapsed().as_secs_f64() / reps as f64;
        println!(
            "  {:>12}: {:7.1} ms ({n_others} other channels: {:.1} ms in all)",
            "cross_axis",
            1e3 * (with_s - all),
            1e3 * with_s
        );
    }
}
