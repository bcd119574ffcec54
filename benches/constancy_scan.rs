//! Level and power of the asymptotic (Wilks) constancy test at several bandwidths.
//!
//! Run: `cargo bench --bench constancy_scan`. R series of N samples from the linear
//! ARMA(2,1) and the FARMA(2,1,1) of `benches/constancy.rs`; on each, the GLR statistic T
//! of FARMA(2,1,1) against ARMA(2,1) at GCV's bandwidth and at fixed bandwidths
//! h = c sd(x) for c in FARMA_SCAN_C (default 0.25,0.5,1,2), its asymptotic p-value
//! P(chi2(r_K mu) >= r_K T) with mu from the smoother's trace
//! ([`farma::workflow::constancy::wilks_p`]), and the rejection rate at 5 %.
//! Environment: FARMA_BENCH_REPS (default 100), FARMA_BENCH_N (default 2000),
//! FARMA_SCAN_C, FARMA_BENCH_GRID (default 31).

#[path = "common/mod.rs"]
mod common;

use std::time::Instant;

use farma::estimator::FarmaParams;
use farma::workflow::constancy::glr_at;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The null models: (AR, MA) of a linear ARMA. FARMA_SCAN_NULL picks one: arma21 (the
/// bench's own, the default), ar1 (0.9), arma11 (0.7; -0.3), ma_edge (0.3; -0.95, an
/// MA part near the unit root, what differencing gives), ar3 (0.4, 0.2, -0.3; 0.5).
fn null_model() -> (Vec<f64>, Vec<f64>) {
    match std::env::var("FARMA_SCAN_NULL")
        .as_deref()
        .unwrap_or("arma21")
    {
        "ar1" => (vec![0.9], vec![]),
        "arma11" => (vec![0.7], vec![-0.3]),
        "ma_edge" => (vec![0.3], vec![-0.95]),
        "ar3" => (vec![0.4, 0.2, -0.3], vec![0.5]),
        _ => (vec![0.5, -0.3], vec![0.4]),
    }
}

fn simulate(n: usize, seed: u64, nonlinear: bool) -> Vec<f64> {
    if nonlinear {
        return common::farma211(n, seed);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let burn = 500;
    {
        let (ar, ma) = null_model();
        let (mut x, mut e) = (vec![0.0; n + burn], vec![0.0; n + burn]);
        for t in 0..n + burn {
            e[t] = StandardNormal.sample(&mut rng);
            let mut s = e[t];
            for (k, a) in ar.iter().enumerate() {
                if t > k {
                    s += a * x[t - k - 1];
                }
            }
            for (k, b) in ma.iter().enumerate() {
                if t > k {
                    s += b * e[t - k - 1];
                }
            }
            x[t] = s;
        }
        x.split_off(burn)
    }
}

fn env(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let reps = env("FARMA_BENCH_REPS", 100);
    let n = env("FARMA_BENCH_N", 2000);
    let grid = env("FARMA_BENCH_GRID", 31);
    let cs: Vec<f64> = std::env::var("FARMA_SCAN_C")
        .unwrap_or_else(|_| "0.25,0.5,1,2".into())
        .split(',')
        .map(|v| v.parse().expect("FARMA_SCAN_C: numbers"))
        .collect();
    println!("machine: {}", common::machine());
    println!("R = {reps}, N = {n}, FARMA(2,1,1), grid {grid}, level 5 %, Wilks p");
    let only: Option<bool> = std::env::var("FARMA_SCAN_ONLY").ok().map(|v| v == "power");
    for (label, nonlinear) in [("level", false), ("power", true)] {
        if only.is_some_and(|o| o != nonlinear) {
            continue;
        }
        let t0 = Instant::now();
        // per bandwidth label: rejections, sum of T, sum of mu
        let mut labels: Vec<String> = vec!["gcv".into()];
        labels.extend(cs.iter().map(|c| format!("{c}sd")));
        let mut rej = vec![0usize; labels.len()];
        let mut sum_t = vec![0.0; labels.len()];
        let mut sum_mu = vec![0.0; labels.len()];
        let mut sum_t2 = vec![0.0; labels.len()];
        // the other references: mu = (trace - p) / 2 with the r_K scale, and
        // 2T ~ chi2(trace - p)
        let mut rej_proj = vec![0usize; labels.len()];
        let mut rej_f = vec![0usize; labels.len()];
        for r in 0..reps {
            let x = simulate(
                n,
                1000 + r as u64 + if nonlinear { 50_000 } else { 0 },
                nonlinear,
            );
            let mean = x.iter().sum::<f64>() / n as f64;
            let xc: Vec<f64> = x.iter().map(|v| v - mean).collect();
            let sd = (xc.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
            let base = FarmaParams {
                p: 2,
                q: 1,
                d: 1,
                grid_size: grid,
                ..FarmaParams::default()
            };
            let mut hs = vec![None];
            hs.extend(cs.iter().map(|c| Some(c * sd)));
            for (k, h) in hs.into_iter().enumerate() {
                let g = glr_at(
                    &xc,
                    &FarmaParams {
                        bandwidth: h,
                        ..base.clone()
                    },
                )
                .unwrap();
                if farma::workflow::rejects(g.p_wilks, 0.05) {
                    rej[k] += 1;
                }
                let dfx = (g.trace - 2.0).max(1e-9);
                let pp = farma::workflow::constancy::wilks_p(g.t, dfx / 2.0);
                if farma::workflow::rejects(pp, 0.05) {
                    rej_proj[k] += 1;
                }
                let pf = if g.t > 0.0 {
                    farma::stats::special::chi2_sf(2.0 * g.t, dfx)
                } else {
                    1.0
                };
                if farma::workflow::rejects(pf, 0.05) {
                    rej_f[k] += 1;
                }
                sum_t[k] += g.t;
                sum_t2[k] += g.t * g.t;
                sum_mu[k] += g.mu;
            }
        }
        println!("{label} ({:.1} s):", t0.elapsed().as_secs_f64());
        for k in 0..labels.len() {
            let rate = rej[k] as f64 / reps as f64;
            let mt = sum_t[k] / reps as f64;
            let vt = sum_t2[k] / reps as f64 - mt * mt;
            let mu = sum_mu[k] / reps as f64;
            println!(
                "  h {:>8}: rejected {:>3}/{reps} = {rate:.3} (se {:.3}) [(tr-p)/2: {:.3}; chi2(tr-p): {:.3}]; mean T {mt:.2} var T {vt:.2}; mean mu {mu:.2} (Wilks var {:.2})",
                labels[k],
                rej[k],
                rej_proj[k] as f64 / reps as f64,
                rej_f[k] as f64 / reps as f64,
                (rate * (1.0 - rate) / reps as f64).sqrt(),
                2.0 * mu / farma::workflow::constancy::R_K
            );
        }
    }
}
