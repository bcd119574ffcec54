//! Level and power of the constancy tests over repeated simulations.
//!
//! Run: `cargo bench --bench constancy`. R series of N samples each from a linear
//! ARMA(2,1) (a = 0.5, -0.3; b = 0.4) and from the FARMA(2,1,1) of
//! tests/suite/workflow_select.rs (f_1 = 0.2 + 0.6 exp(-z^2), f_2 = -0.25 + 0.15 tanh z,
//! b = 0.4), unit Gaussian innovations; on each, the test of FARMA(2,1,1) (grid
//! FARMA_BENCH_GRID, default 201 as `farma analyze`): `FARMA_BENCH_TEST=chi2` (the
//! default test of `farma select` and `analyze`: fixed bandwidth 0.5 sd, 2T against
//! chi2 on tr(S) - p df) or `bootstrap` with B replicates, the bandwidth by GCV on the
//! series and on every replicate (`FARMA_BENCH_H=gcv`, default), or chosen by GCV
//! on the series and held fixed in the replicates (`FARMA_BENCH_H=fixed`, the invalid
//! use, for comparison). Reports the rejection rate at 5 % with its binomial standard
//! error and the seconds per series. Environment: FARMA_BENCH_REPS (R, default 100),
//! FARMA_BENCH_N (default 2000), FARMA_BENCH_B (default 99), FARMA_BENCH_H,
//! FARMA_BENCH_TEST (default bootstrap), FARMA_BENCH_ONLY (level or power: one half).

#[path = "common/mod.rs"]
mod common;

use std::time::Instant;

use farma::estimator::{FarmaParams, fit};
use farma::workflow::constancy::{ConstancyParams, chi2_test, constancy_test};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The bench's series: the FARMA(2,1,1) of [`common::farma211`], or the ARMA(2,1)
/// a = (0.5, -0.3), b = 0.4 from the same innovations.
fn simulate(n: usize, seed: u64, nonlinear: bool) -> Vec<f64> {
    if nonlinear {
        return common::farma211(n, seed);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let burn = 500;
    let (mut x, mut e) = (vec![0.0; n + burn], vec![0.0; n + burn]);
    for t in 0..n + burn {
        e[t] = StandardNormal.sample(&mut rng);
        let mut s = e[t];
        if t >= 2 {
            s += 0.5 * x[t - 1] - 0.3 * x[t - 2] + 0.4 * e[t - 1];
        }
        x[t] = s;
    }
    x.split_off(burn)
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
    let b = env("FARMA_BENCH_B", 99);
    let grid = env("FARMA_BENCH_GRID", 201);
    let chi2 = std::env::var("FARMA_BENCH_TEST").is_ok_and(|v| v == "chi2");
    let only = std::env::var("FARMA_BENCH_ONLY").ok();
    println!("machine: {}", common::machine());
    let fixed = std::env::var("FARMA_BENCH_H").is_ok_and(|v| v == "fixed");
    if chi2 {
        println!(
            "R = {reps}, N = {n}, chi2 test (fixed bandwidth 0.5 sd), FARMA(2,1,1), grid {grid}, level 5 %"
        );
    } else {
        println!(
            "R = {reps}, N = {n}, B = {b}, FARMA(2,1,1), grid {grid}, level 5 %, bandwidth {}",
            if fixed {
                "by GCV on the series, fixed in the replicates"
            } else {
                "by GCV on the series and on every replicate"
            }
        );
    }
    for (label, nonlinear) in [
        ("ARMA(2,1) data (level)", false),
        ("FARMA(2,1,1) data (power)", true),
    ] {
        if only.as_deref().is_some_and(|o| (o == "power") != nonlinear) {
            continue;
        }
        let t0 = Instant::now();
        let mut rejected = 0;
        let mut ps = Vec::new();
        for r in 0..reps {
            let x = simulate(
                n,
                1000 + r as u64 + if nonlinear { 50_000 } else { 0 },
                nonlinear,
            );
            let base = FarmaParams {
                p: 2,
                q: 1,
                d: 1,
                grid_size: grid,
                ..FarmaParams::default()
            };
            let h = fixed.then(|| {
                fit(&x, &base.clone().validate(n).unwrap())
                    .unwrap()
                    .0
                    .bandwidth
            });
            let c = if chi2 {
                chi2_test(&x, &base).unwrap()
            } else {
                constancy_test(
                    &x,
                    &ConstancyParams {
                        bootstrap: b,
                        seed: r as u64,
                        farma: FarmaParams {
                            bandwidth: h,
                            ..base
                        },
                    },
                )
                .unwrap()
            };
            if farma::workflow::rejects(c.p_value, farma::workflow::ALPHA) {
                rejected += 1;
            }
            ps.push(c.p_value);
        }
        let rate = rejected as f64 / reps as f64;
        let se = (rate * (1.0 - rate) / reps as f64).sqrt();
        ps.sort_by(f64::total_cmp);
        println!(
            "{label}: rejected {rejected}/{reps} = {:.3} (se {:.3}); median p {:.3}; {:.1} s ({:.3} s per series)",
            rate,
            se,
            ps[reps / 2],
            t0.elapsed().as_secs_f64(),
            t0.elapsed().as_secs_f64() / reps as f64
        );
    }
}
