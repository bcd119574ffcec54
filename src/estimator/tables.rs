//! Fitted models as tables (Parquet) and JSON: the coefficient functions, the
//! parameters, the GCV table and the residuals, one row per channel and item.
//! Column names are the contract of `shared/design/contracts.md` section 4.

use std::sync::Arc;

use arrow_array::builder::{Float64Builder, ListBuilder};
use arrow_array::{
    ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray, UInt64Array,
};
use serde_json::{Value, json};

use super::fit::{FitPath, FittedFarma, Init};
use crate::error::Result;
use crate::output::batch;

fn s(v: Vec<String>) -> ArrayRef {
    Arc::new(StringArray::from(v))
}
fn f(v: Vec<f64>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}
fn i(v: Vec<i64>) -> ArrayRef {
    Arc::new(Int64Array::from(v))
}

pub fn init_name(i: Init) -> &'static str {
    match i {
        Init::Arma => "arma",
        Init::Literal => "literal",
    }
}

pub fn path_name(p: FitPath) -> &'static str {
    match p {
        FitPath::Fast => "fast",
        FitPath::Direct => "direct",
    }
}

/// Coefficient functions: channel, m, grid, f, slope, se, n_support, kernel_mass,
/// cond, status, filled. The grid is in the units of the channel (mean added back).
pub fn coef_table(models: &[(String, &FittedFarma)]) -> Result<RecordBatch> {
    let (mut ch, mut m_, mut grid, mut fv, mut slope, mut se) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    let (mut nsup, mut mass, mut cond, mut status, mut filled) =
        (vec![], vec![], vec![], vec![], vec![]);
    for (name, m) in models {
        let p = m.p;
        for g in 0..m.grid.len() {
            for k in 0..p {
                ch.push(name.clone());
                m_.push(k as i64 + 1);
                grid.push(m.grid[g] + m.mean);
                fv.push(m.coef.f[g * p + k]);
                slope.push(m.coef.slope[g * p + k]);
                se.push(m.se[g * p + k]);
                nsup.push(m.coef.n_support[g]);
                mass.push(m.coef.kernel_mass[g]);
                cond.push(m.coef.cond[g]);
                status.push(m.coef.status[g].as_str().to_string());
                filled.push(m.filled[g]);
            }
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("m", i(m_)),
        ("grid", f(grid)),
        ("f", f(fv)),
        ("slope", f(slope)),
        ("se", f(se)),
        ("n_support", Arc::new(UInt64Array::from(nsup))),
        ("kernel_mass", f(mass)),
        ("cond", f(cond)),
        ("status", s(status)),
        ("filled", Arc::new(BooleanArray::from(filled))),
    ])
}

/// One row per channel: order, b, sigma2, bandwidth, RSS, trace, GCV, iterations...
pub fn params_table(models: &[(String, &FittedFarma)]) -> Result<RecordBatch> {
    let mut b = ListBuilder::new(Float64Builder::new());
    for (_, m) in models {
        for v in &m.b {
            b.values().append_value(*v);
        }
        b.append(true);
    }
    let col = |g: &dyn Fn(&FittedFarma) -> f64| f(models.iter().map(|(_, m)| g(m)).collect());
    let coli = |g: &dyn Fn(&FittedFarma) -> i64| i(models.iter().map(|(_, m)| g(m)).collect());
    batch(vec![
        (
            "channel",
            s(models.iter().map(|(n, _)| n.clone()).collect()),
        ),
        ("p", coli(&|m| m.p as i64)),
        ("q", coli(&|m| m.q as i64)),
        ("d", coli(&|m| m.d as i64)),
        ("b", Arc::new(b.finish())),
        ("mean", col(&|m| m.mean)),
        ("sigma2", col(&|m| m.sigma2)),
        ("bandwidth", col(&|m| m.bandwidth)),
        ("rss", col(&|m| m.rss)),
        ("trace", col(&|m| m.trace)),
        ("gcv", col(&|m| m.gcv)),
        ("iterations", coli(&|m| m.iterations as i64)),
        (
            "converged",
            Arc::new(BooleanArray::from(
                models.iter().map(|(_, m)| m.converged).collect::<Vec<_>>(),
            )),
        ),
        (
            "ladder_extended",
            Arc::new(BooleanArray::from(
                models
                    .iter()
                    .map(|(_, m)| m.ladder_extended)
                    .collect::<Vec<_>>(),
            )),
        ),
        (
            "init",
            s(models
                .iter()
                .map(|(_, m)| init_name(m.init).to_string())
                .collect()),
        ),
        (
            "method",
            s(models
                .iter()
                .map(|(_, m)| path_name(m.path).to_string())
                .collect()),
        ),
        ("n", coli(&|m| m.n as i64)),
        ("n_rows", coli(&|m| m.n_rows as i64)),
    ])
}

/// The GCV ladder: channel, j (the rung, h_j = 1.1^-j range/2), bandwidth, rss, trace, gcv, n_failed, chosen.
pub fn gcv_table(models: &[(String, &FittedFarma)]) -> Result<RecordBatch> {
    let (mut ch, mut j, mut h, mut rss, mut tr, mut gcv, mut nf, mut chosen) = (
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
    );
    for (name, m) in models {
        for r in &m.gcv_table {
            ch.push(name.clone());
            j.push(r.j as i64);
            h.push(r.bandwidth);
            rss.push(r.rss);
            tr.push(r.trace);
            gcv.push(r.gcv);
            nf.push(r.n_failed as i64);
            chosen.push(r.bandwidth == m.bandwidth);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("j", i(j)),
        ("bandwidth", f(h)),
        ("rss", f(rss)),
        ("trace", f(tr)),
        ("gcv", f(gcv)),
        ("n_failed", i(nf)),
        ("chosen", Arc::new(BooleanArray::from(chosen))),
    ])
}

/// Residuals: channel, t (sample index), residual, in_fit (false for the first
/// max(p,q,d) samples, whose lags reach before the series: the recursion's warm-up,
/// not residuals of the model, and not in its RSS).
pub fn residual_table(models: &[(String, &FittedFarma)]) -> Result<RecordBatch> {
    let (mut ch, mut t, mut r, mut in_fit) = (vec![], vec![], vec![], vec![]);
    for (name, m) in models {
        let warm_up = m.n - m.n_rows;
        for (k, v) in m.residuals.iter().enumerate() {
            ch.push(name.clone());
            t.push(k as i64);
            r.push(*v);
            in_fit.push(k >= warm_up);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("t", i(t)),
        ("residual", f(r)),
        ("in_fit", Arc::new(BooleanArray::from(in_fit))),
    ])
}

/// The `--json` object of one channel (contract keys plus more).
pub fn fit_json(name: &str, m: &FittedFarma, coef_path: &str) -> Value {
    json!({
        "channel": name,
        "order": [m.p, m.q, m.d],
        "b": m.b,
        "sigma2": m.sigma2,
        "bandwidth": m.bandwidth,
        "rss": m.rss,
        "trace": m.trace,
        "gcv": m.gcv,
        "iterations": m.iterations,
        "converged": m.converged,
        "coef": coef_path,
        "mean": m.mean,
        "init": init_name(m.init),
        "method": path_name(m.path),
        "ladder_extended": m.ladder_extended,
        "n": m.n,
        "notes": m.notes,
    })
}
