//! Online update (`farma update`, recursive least squares) beside its peer, refitting
//! the local fits on the concatenated data at the same bandwidth, in the same run.
//!
//! A FARMA(2,1,1) of N_OLD samples is fitted (fixed bandwidth, fast path), its state
//! built (what `--save-state` costs), then N_NEW new samples are added by
//! `update::update` (lambda = 1) and, as the peer, by the batch computation the update
//! replaces: `direct::fit_grid` on the concatenated series with the update's residuals
//! and b, and the full `fit` on the concatenated series (same fixed bandwidth).
//!
//!     cargo bench --bench update            (FARMA_BENCH_N_OLD, FARMA_BENCH_N_NEW)

#[path = "common/mod.rs"]
mod common;

use std::time::Instant;

use farma::estimator::direct::{DirectIndex, fit_grid};
use farma::estimator::update::{state_from_fit, update};
use farma::estimator::{FarmaParams, FitPath, VcProblem, fit};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

fn simulate(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut x = vec![0.0; n];
    let mut e = vec![0.0; n];
    for t in 0..n {
        e[t] = StandardNormal.sample(&mut rng);
        let z = if t >= 1 { x[t - 1] } else { 0.0 };
        let mut s = e[t];
        if t >= 1 {
            s += (0.3 + 0.4 * f64::exp(-z * z)) * x[t - 1] - 0.5 * e[t - 1];
        }
        if t >= 2 {
            s += (-0.2 + 0.1 * z.tanh()) * x[t - 2];
        }
        x[t] = s;
    }
    x
}

fn env(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .map(|v| v as usize)
        .unwrap_or(default)
}

fn main() {
    let n_old = env("FARMA_BENCH_N_OLD", 1_000_000);
    let n_new = env("FARMA_BENCH_N_NEW", 100_000);
    println!("machine: {}", common::machine());
    println!("threads: {}", rayon::current_num_threads());
    let x = simulate(n_old + n_new, 7);
    let params = FarmaParams {
        p: 2,
        q: 1,
        d: 1,
        bandwidth: Some(0.25),
        path: FitPath::Fast,
        ..FarmaParams::default()
    };
    let t = Instant::now();
    let m = fit(&x[..n_old], &params.clone().validate(n_old).unwrap()).unwrap();
    println!(
        "fit on {n_old} samples (G = {}, h = 0.25, {} iterations): {:.3} s",
        m.0.coef.grid.len(),
        m.1.iterations,
        t.elapsed().as_secs_f64()
    );
    let t = Instant::now();
    let st = state_from_fit("x", &x[..n_old], &m.0, &m.1);
    println!("state (--save-state): {:.3} s", t.elapsed().as_secs_f64());
    let mut best_up = f64::INFINITY;
    let mut up = None;
    for _ in 0..3 {
        let t = Instant::now();
        let u = update(&st, &x[n_old..], 1.0).unwrap();
        best_up = best_up.min(t.elapsed().as_secs_f64());
        up = Some(u);
    }
    let up = up.unwrap();
    println!(
        "update, {n_new} new samples: {best_up:.3} s ({:.2} us per sample, {:.3e} samples/s)",
        best_up / n_new as f64 * 1e6,
        n_new as f64 / best_up
    );
    let xa: Vec<f64> = x.iter().map(|v| v - m.0.mean).collect();
    let mut ea = m.1.residuals.clone();
    ea.extend(&up.2.residuals);
    let prob = VcProblem::new(&xa, &ea, &up.0.b, 2, 1);
    let mut best_direct = f64::INFINITY;
    let mut worst = 0.0f64;
    for _ in 0..3 {
        let t = Instant::now();
        let index = DirectIndex::build(&prob);
        let batch = fit_grid(&prob, &index, &m.0.coef.grid, m.0.bandwidth);
        best_direct = best_direct.min(t.elapsed().as_secs_f64());
        for (a, b) in batch.f.iter().zip(&up.2.local.f) {
            if a.is_finite() {
                worst = worst.max((a - b).abs());
            }
        }
    }
    println!(
        "peer: direct local fits on the concatenated {} samples: {best_direct:.3} s (max |f_update - f_batch| = {worst:.2e})",
        n_old + n_new
    );
    let t = Instant::now();
    let all = fit(&x, &params.validate(x.len()).unwrap()).unwrap();
    let refit = t.elapsed().as_secs_f64();
    println!(
        "peer: full fit on the concatenated samples (fast path, {} iterations): {refit:.3} s",
        all.1.iterations
    );
    println!(
        "ratios: direct refit / update = {:.1}, full refit / update = {:.1}",
        best_direct / best_up,
        refit / best_up
    );
}
