//! `farma analyze LOG -o OUTDIR`: prep -> select -> fit -> check for every channel, in
//! parallel; every table in one folder (Parquet) and a readable summary.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use rayon::prelude::*;
use serde_json::json;

use super::LogArgs;
use super::prep::{PrepFlags, prep_store};
use super::select::{SelectFlags, select_json, select_text};
use crate::error::{Error, Result};
use crate::estimator::tables::{ModelRow, coef_table, gcv_table, params_table};
use crate::log::Progress;
use crate::model::Report;
use crate::output::OutputSet;
use crate::workflow::analyze::{AnalyzeParams, ChannelAnalysis, analyze_channel};
use crate::workflow::select::{Selection, order_name};
use crate::workflow::tables::{
    acf_table, constancy_table, ftest_table, ljung_box_table, poly_table, prediction_table,
    select_table,
};

#[derive(Args, Debug)]
pub struct AnalyzeArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC.
    pub log: PathBuf,
    /// Channels (comma-separated, or all), analysed in parallel.
    #[arg(long, default_value = "all")]
    pub channel: String,
    /// Output folder for every table and summary.txt.
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: PathBuf,
    /// Seconds at the end held out from every fit and predicted (the paper: 50 s).
    #[arg(long, default_value_t = 50.0, value_name = "S")]
    pub holdout_s: f64,
    /// Largest lag of the residual autocorrelation.
    #[arg(long, default_value_t = 40)]
    pub maxlag: usize,
    /// Largest degree of the polynomial fits of the f_m.
    #[arg(long, default_value_t = 6)]
    pub max_degree: usize,
    #[command(flatten)]
    pub prep: PrepFlags,
    #[command(flatten)]
    pub select: SelectFlags,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines) instead of the summary.
    #[arg(long)]
    pub json: bool,
}

fn summary(a: &ChannelAnalysis, rate: f64) -> String {
    let s: &Selection = &a.selection;
    let mut o = String::new();
    o += "== preparation\n";
    for st in &a.prep.steps {
        o += &format!("  {:<20} {}\n", st.step, st.detail);
    }
    o += &format!(
        "== order selection on the first {} samples ({:.1} s)\n",
        a.n_train,
        a.n_train as f64 / rate
    );
    o += &select_text(&a.name, s, a.constancy.as_ref());
    let r = &s.rows[s.selected];
    let w = &a.check.whiteness;
    o += &format!(
        "== check of {}\n  residual ACF: {} of {} lags outside +-{:.4}\n",
        order_name(r.order),
        w.outside,
        w.acf.len(),
        w.band
    );
    for lb in &w.ljung_box {
        o += &format!(
            "  Ljung-Box lag {:>3}: Q = {:>10.3} on {} df, p = {:.4}\n",
            lb.lag, lb.q, lb.df, lb.p_value
        );
    }
    if let Some(pr) = &a.check.prediction {
        o += &format!(
            "  hold-out prediction of the last {} samples ({:.1} s; hold-out std {:.4e}):\n",
            pr.holdout,
            pr.holdout as f64 / rate,
            pr.holdout_std
        );
        o += "      k     rmse FARMA      rmse ARMA  FARMA/ARMA\n";
        for h in &pr.horizons {
            o += &format!(
                "  {:>5} {:>14.6e} {:>14.6e} {:>11.4}\n",
                h.k,
                h.rmse_farma,
                h.rmse_arma,
                h.rmse_farma / h.rmse_arma
            );
        }
    }
    for pf in &a.check.poly {
        o += &format!(
            "  f_{} ~ polynomial of degree {} in u = x - mean (BIC on the pointwise se): coef {:?}, rms {:.3e}\n",
            pf.m,
            pf.degree,
            pf.coef
                .iter()
                .map(|c| format!("{c:.4e}"))
                .collect::<Vec<_>>(),
            pf.wrms
        );
    }
    o
}

/// The files `farma analyze` writes into its output folder (a run removes those of
/// an earlier run that it does not write).
pub(super) const ANALYZE_OUTPUTS: &[&str] = &[
    "clean.arrow",
    "prep.parquet",
    "replaced.parquet",
    "select.parquet",
    "ftests.parquet",
    "constancy.parquet",
    "coef.parquet",
    "params.parquet",
    "gcv.parquet",
    "acf.parquet",
    "ljung_box.parquet",
    "prediction.parquet",
    "poly.parquet",
    "summary.txt",
];

pub fn run(a: AnalyzeArgs, progress: &Progress) -> Result<()> {
    let t0 = Instant::now();
    OutputSet::check(&a.output)?;
    if !(a.holdout_s.is_finite() && a.holdout_s >= 0.0) {
        return Err(Error::Usage(format!(
            "--holdout-s: {} is not a non-negative number",
            a.holdout_s
        )));
    }
    let orders = a.select.check()?;
    let store = a.log_args.open(&a.log, progress)?;
    let names = store.select_channels(&a.channel)?;
    let rate = store.sample_rate_hz();
    let (chans, dropped) = prep_store(&store, &names, &a.prep.params())?;
    let prm = AnalyzeParams {
        orders,
        farma: a.select.farma(),
        bootstrap: a.select.bootstrap,
        seed: a.select.seed,
        holdout: (a.holdout_s * rate).round() as usize,
        maxlag: a.maxlag,
        max_degree: a.max_degree,
    };
    // every failing channel is named at once, in channel order, as `farma fit` does
    // (the first error rayon meets is any one of them: each rerun would find the next)
    let bar = progress.count_bar("channels done", chans.len() as u64);
    let results: Vec<ChannelAnalysis> = super::every_channel(
        chans
            .clone()
            .into_par_iter()
            .map(|c| {
                let name = c.name.clone();
                let r = analyze_channel(c, &prm).map_err(|e| super::on_channel(&a.log, &name, e));
                bar.inc(1);
                r
            })
            .collect(),
        super::fit::FIT_CHANNELS_HINT,
    )?;
    bar.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let dir = &a.output;
    let mut set = OutputSet::new(dir)?;
    let (size, mtime) = crate::log::source_identity(&a.log)?;
    let md = vec![
        ("source", a.log.display().to_string()),
        ("source_size", size.to_string()),
        ("source_mtime_ns", mtime.to_string()),
        ("sample_rate_hz", rate.to_string()),
    ];
    super::prep::stage_prep(&mut set, &store, (&chans, dropped), &md)?;
    let sels: Vec<(String, &Selection)> = results
        .iter()
        .map(|r| (r.name.clone(), &r.selection))
        .collect();
    set.parquet("select.parquet", &select_table(&sels)?, &md)?;
    set.parquet("ftests.parquet", &ftest_table(&sels)?, &md)?;
    let cons: Vec<_> = results
        .iter()
        .filter_map(|r| {
            r.constancy.as_ref().map(|c| {
                (
                    r.name.clone(),
                    r.selection.rows[r.selection.selected].order,
                    c,
                )
            })
        })
        .collect();
    set.parquet("constancy.parquet", &constancy_table(&cons)?, &md)?;
    let models: Vec<ModelRow> = results
        .iter()
        .map(|r| {
            let (m, rep) = &r.selection.fits[r.selection.selected];
            (r.name.clone(), m, Report::Fit(rep))
        })
        .collect();
    set.parquet("coef.parquet", &coef_table(&models)?, &md)?;
    set.parquet("params.parquet", &params_table(&models)?, &md)?;
    set.parquet("gcv.parquet", &gcv_table(&models)?, &md)?;
    let ws: Vec<_> = results
        .iter()
        .map(|r| (r.name.clone(), &r.check.whiteness))
        .collect();
    set.parquet("acf.parquet", &acf_table(&ws)?, &md)?;
    set.parquet("ljung_box.parquet", &ljung_box_table(&ws)?, &md)?;
    let ps: Vec<_> = results
        .iter()
        .filter_map(|r| r.check.prediction.as_ref().map(|p| (r.name.clone(), p)))
        .collect();
    set.parquet("prediction.parquet", &prediction_table(&ps)?, &md)?;
    let polys: Vec<_> = results
        .iter()
        .map(|r| (r.name.clone(), r.check.poly.as_slice()))
        .collect();
    set.parquet("poly.parquet", &poly_table(&polys)?, &md)?;
    let mut text = format!(
        "farma analyze {} ({} channel(s), {} samples at {} Hz; {:.2} s)\n",
        a.log.display(),
        results.len(),
        store.n_samples(),
        rate,
        secs
    );
    for r in &results {
        text += &format!("\n######## {}\n", r.name);
        text += &summary(r, rate);
    }
    set.file("summary.txt", |p| crate::output::write_text(p, &text))?;
    super::commit_outputs(set, ANALYZE_OUTPUTS)?;
    for r in &results {
        if a.json {
            let mut v = select_json(&r.name, &r.selection, r.constancy.as_ref());
            let w = &r.check.whiteness;
            v["n_train"] = json!(r.n_train);
            v["ljung_box"] = json!(
                w.ljung_box
                    .iter()
                    .map(|b| json!({"lag": b.lag, "q": b.q,
                "df": b.df, "p_value": b.p_value}))
                    .collect::<Vec<_>>()
            );
            v["acf_outside"] = json!(w.outside);
            v["prediction"] = json!(r.check.prediction.as_ref().map(|p| {
                p.horizons
                    .iter()
                    .map(|h| {
                        json!({"k": h.k, "n": h.n, "rmse_farma": h.rmse_farma,
                    "rmse_arma": h.rmse_arma})
                    })
                    .collect::<Vec<_>>()
            }));
            v["poly"] = json!(
                r.check
                    .poly
                    .iter()
                    .map(|p| json!({"m": p.m,
                "degree": p.degree, "coef": p.coef, "wrms": p.wrms}))
                    .collect::<Vec<_>>()
            );
            v["replaced"] = json!(r.prep.replaced.len());
            v["stationary"] = json!(r.prep.stationary(a.prep.alpha));
            outln!("{v}");
        }
    }
    if !a.json {
        out!("{text}");
    }
    eprintln!(
        "farma: {} channel(s) analysed in {secs:.2} s; tables and summary.txt in {}",
        results.len(),
        dir.display()
    );
    Ok(())
}
