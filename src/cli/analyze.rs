//! `farma analyze LOG -o OUTDIR`: prep -> select -> fit -> check for every channel, in
//! parallel; every table in one folder (Parquet) and a readable summary. The
//! arguments turned into an [`AnalyzeJob`], its result printed.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::LogArgs;
use super::prep::PrepFlags;
use super::select::SelectFlags;
use crate::error::{Error, Result};
use crate::jobs::analyze::AnalyzeJob;
use crate::jobs::select::select_json;
use crate::log::Progress;
use crate::output::OutputSet;

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

pub fn run(a: AnalyzeArgs, progress: &Progress) -> Result<()> {
    OutputSet::check(&a.output)?;
    if !(a.holdout_s.is_finite() && a.holdout_s >= 0.0) {
        return Err(Error::Usage(format!(
            "--holdout-s: {} is not a non-negative number",
            a.holdout_s
        )));
    }
    let select = a.select.job(&a.log, None)?;
    let store = a.log_args.open(&a.log, progress)?;
    let job = AnalyzeJob {
        log: a.log.clone(),
        output: a.output.clone(),
        channels: store.select_channels(&a.channel)?,
        prep: a.prep.params(),
        select,
        holdout_s: a.holdout_s,
        maxlag: a.maxlag,
        max_degree: a.max_degree,
    };
    let done = job.run(&store, progress)?;
    for r in &done.results {
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
        out!("{}", done.text);
    }
    eprintln!(
        "farma: {} channel(s) analysed in {:.2} s; tables and summary.txt in {}",
        done.results.len(),
        done.secs,
        a.output.display()
    );
    Ok(())
}
