//! What one sample costs in the estimator's per-alternation moment pass, beside the
//! floor (one sum over the same values), on one thread: the interval lookup alone
//! (`IntervalLookup::find`, and a binary search over the same breakpoints for
//! comparison) and the whole f-step pass (`MomentTable::build_families` with the X_a y
//! families, the table every alternation rebuilds). Explains the fit bench's
//! "alternation / floor" ratio.
//!
//! Run: `cargo bench --bench moment_pass` (FARMA_BENCH_N, default 1e6). Best of 5.

#[path = "common/mod.rs"]
mod common;

use std::time::Instant;

use farma::estimator::arma::arma_pass;
use farma::estimator::moments::{
    Families, IntervalIndex, IntervalLookup, MomentTable, breakpoints,
};
use farma::estimator::problem::VcProblem;

fn best_of<T>(f: impl Fn() -> T) -> f64 {
    (0..5)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(f());
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let n = std::env::var("FARMA_BENCH_N")
        .ok()
        .map(|s| s.parse::<f64>().expect("FARMA_BENCH_N") as usize)
        .unwrap_or(1_000_000);
    // an AR(2) series with uniform innovations (LCG: no dependencies)
    let mut x = vec![0.0f64; n];
    let mut s: u64 = 1;
    for t in 2..n {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        x[t] = 0.5 * x[t - 1] - 0.2 * x[t - 2] + u;
    }
    let e = vec![0.1; n];
    let prob = VcProblem::new(&x, &e, &[-0.5], 2, 1);
    let grid: Vec<f64> = (0..201).map(|k| -0.8 + 1.6 * k as f64 / 200.0).collect();
    let h = 0.2;
    let mut breaks = breakpoints(&grid, &[h]);
    breaks.sort_by(f64::total_cmp);
    breaks.dedup();
    let lookup = IntervalLookup::new(&breaks);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let ns = |secs: f64| secs / n as f64 * 1e9;
    let floor = best_of(|| x.iter().sum::<f64>());
    let find = best_of(|| x.iter().map(|u| lookup.find(*u)).sum::<usize>());
    let bsearch = best_of(|| {
        x.iter()
            .map(|u| breaks.partition_point(|b| *b <= *u))
            .sum::<usize>()
    });
    let pass = pool.install(|| {
        best_of(|| {
            MomentTable::build_families(&prob, breaks.clone(), -3.0, 3.0, 6, Families::Response)
        })
    });
    let index = pool.install(|| IntervalIndex::build(&prob, breaks.clone()).unwrap());
    let indexed = pool.install(|| {
        best_of(|| MomentTable::build_indexed(&prob, &index, -3.0, 3.0, 6, Families::Response))
    });
    let full = pool.install(|| {
        best_of(|| MomentTable::build_indexed(&prob, &index, -3.0, 3.0, 6, Families::All))
    });
    // a GCV ladder's table: 301 grid points, 41 rungs (some 25,000 intervals, 9.8 MB
    // of moments hit at random: compare with the one-bandwidth table above)
    let lgrid: Vec<f64> = (0..301).map(|k| -0.8 + 1.6 * k as f64 / 300.0).collect();
    let lhs: Vec<f64> = (0..41).map(|j| 1.1f64.powi(-j) * 1.5).collect();
    let lbreaks = breakpoints(&lgrid, &lhs);
    let lindex = pool.install(|| IntervalIndex::build(&prob, lbreaks.clone()).unwrap());
    let ladder = |fam: Families| {
        pool.install(|| best_of(|| MomentTable::build_indexed(&prob, &lindex, -3.0, 3.0, 6, fam)))
    };
    let lad_all = ladder(Families::All);
    let lad_y = ladder(Families::ResponseAndSquare);
    // the Gauss-Newton pass (ARMA(2,1) and MA(1)): chunks in parallel on two threads
    // against one thread (the one-loop recursion's time, plus the leads)
    let pool2 = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let gn21_1 = pool.install(|| best_of(|| arma_pass(&x, 2, &[0.4, -0.2], &[-0.5])));
    let gn21_2 = pool2.install(|| best_of(|| arma_pass(&x, 2, &[0.4, -0.2], &[-0.5])));
    let gn01_1 = pool.install(|| best_of(|| arma_pass(&x, 2, &[], &[-0.5])));
    let gn01_2 = pool2.install(|| best_of(|| arma_pass(&x, 2, &[], &[-0.5])));
    println!("machine: {}, one thread, N = {n:.0e}", common::machine());
    println!("| step | ns per sample | / floor |");
    println!("|---|---|---|");
    for (what, t) in [
        ("floor: sum", floor),
        ("IntervalLookup::find", find),
        (
            &*format!("binary search over {} breakpoints", breaks.len()),
            bsearch,
        ),
        ("f-step pass (X_a y families, degree 6)", pass),
        ("the same, intervals read from an IntervalIndex", indexed),
        ("every family, degree 6, intervals read", full),
        (
            "GCV ladder table (41 rungs), every family, intervals read",
            lad_all,
        ),
        (
            "its y families alone (the re-check after convergence)",
            lad_y,
        ),
        ("Gauss-Newton pass, ARMA(2,1)", gn21_1),
        ("the same, two threads (chunks)", gn21_2),
        ("Gauss-Newton pass, MA(1)", gn01_1),
        ("the same, two threads (chunks)", gn01_2),
    ] {
        println!("| {what} | {:.1} | {:.1} |", ns(t), t / floor);
    }
}
