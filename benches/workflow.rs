//! The whole analysis of one 1e6-sample channel beside the estimator's single fit.
//!
//! Run: `cargo bench --bench workflow`. A FARMA(2,1,1) series (the model of
//! tests/suite/workflow_select.rs) of FARMA_BENCH_N samples (default 1e6): the estimator's
//! single FARMA(2,1,1) fit with GCV (default parameters, grid 201), then the workflow
//! of `farma analyze` on the same series: preparation (Pauta, reverse arrangements,
//! mean), the eight orders of the paper with GCV and the ARMA baselines, F-tests, the
//! constancy test (FARMA_BENCH_TEST: chi2, the default, or bootstrap with FARMA_BENCH_B
//! replicates, default 19), and the check (whiteness, prediction of the last 5000
//! samples, polynomial fits); and the constancy test alone at FARMA(2,1,1), in single
//! fits. Each once, in this process, all cores.

#[path = "common/mod.rs"]
mod common;

use std::time::Instant;

use farma::estimator::{FarmaParams, fit};
use farma::workflow::analyze::{AnalyzeParams, analyze_channel};
use farma::workflow::constancy::{ConstancyTest, run_test};
use farma::workflow::prep::{PrepParams, prep_channel};
use farma::workflow::select::PAPER_ORDERS;

fn main() {
    let n: usize = std::env::var("FARMA_BENCH_N")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .map(|v| v as usize)
        .unwrap_or(1_000_000);
    let b: usize = std::env::var("FARMA_BENCH_B")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(19);
    let test = match std::env::var("FARMA_BENCH_TEST").as_deref() {
        Ok("bootstrap") => ConstancyTest::Bootstrap(b),
        _ => ConstancyTest::Chi2,
    };
    println!("machine: {}", common::machine());
    let x = common::farma211(n, 77);
    let t0 = Instant::now();
    let m = fit(&x, &FarmaParams::default().validate(n).unwrap()).unwrap();
    let single = t0.elapsed().as_secs_f64();
    println!(
        "single FARMA(2,1,1) fit (GCV, grid 201), N = {n}: {single:.2} s (h = {:.4}, {} iterations)",
        m.0.bandwidth, m.1.iterations
    );
    let t0 = Instant::now();
    let c = run_test(&x, test, &FarmaParams::default(), 1)
        .unwrap()
        .unwrap();
    let tc = t0.elapsed().as_secs_f64();
    println!(
        "constancy test alone ({}): {tc:.2} s = {:.2} single fits (T = {:.3}, p = {:.3e})",
        c.method,
        tc / single,
        c.statistic,
        c.p_value
    );
    let t0 = Instant::now();
    let prep = prep_channel("x", &x, &PrepParams::default());
    let tp = t0.elapsed().as_secs_f64();
    let prm = AnalyzeParams {
        orders: PAPER_ORDERS.to_vec(),
        farma: FarmaParams::default(),
        constancy: test,
        seed: 1,
        holdout: 5000,
        maxlag: 40,
        max_degree: 6,
    };
    let a = analyze_channel(prep, &prm).unwrap();
    let total = t0.elapsed().as_secs_f64();
    let r = &a.selection.rows[a.selection.selected];
    println!(
        "whole analysis (prep {tp:.2} s; 8 orders + ARMA baselines + F-tests + constancy {} + check): {total:.2} s = {:.1} single fits",
        test.name(),
        total / single
    );
    println!(
        "selected {:?}, constancy p = {:?}, one-step rmse FARMA {:.4} vs ARMA {:.4}",
        r.order,
        a.constancy.as_ref().map(|c| c.p_value),
        a.check.prediction.as_ref().unwrap().horizons[0].rmse_farma,
        a.check.prediction.as_ref().unwrap().horizons[0].rmse_arma
    );
}
