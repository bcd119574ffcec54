//! `farma check MODEL LOG`: residual whiteness, hold-out prediction against the linear
//! ARMA baseline, and polynomial fits of the f_m, for a model written by `farma fit`
//! (or `farma analyze`) and a log; the arguments turned into a [`CheckJob`], its
//! result printed.
//!
//! The hold-out is the last `--holdout-s` seconds of LOG. The ARMA(p,q) baseline is
//! fitted by conditional least squares on LOG before the hold-out. Whiteness is that of
//! the model's residuals on LOG before the hold-out (rows t >= max(p,q,d)). When the
//! model was fitted on the same log including its end, the hold-out is not unseen by
//! it: `farma analyze` fits on the log without the hold-out.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::jobs::check::CheckJob;
use crate::log::Progress;
use crate::output::OutputSet;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// The output folder of `farma fit` (params.parquet, coef.parquet).
    pub model: PathBuf,
    /// The log: a store, CSV, Parquet or Arrow IPC.
    pub log: PathBuf,
    /// Channels to check (comma-separated; default: every channel of the model).
    #[arg(long)]
    pub channel: Option<String>,
    /// Seconds at the end of LOG predicted (the paper: 50 s).
    #[arg(long, default_value_t = 50.0, value_name = "S")]
    pub holdout_s: f64,
    /// Largest lag of the residual autocorrelation.
    #[arg(long, default_value_t = 40)]
    pub maxlag: usize,
    /// Largest degree of the polynomial fits of the f_m.
    #[arg(long, default_value_t = 6)]
    pub max_degree: usize,
    /// Also write acf.parquet, ljung_box.parquet, prediction.parquet, poly.parquet here.
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines).
    #[arg(long)]
    pub json: bool,
}

/// A warning when the model folder records LOG itself as the log it was fitted on (the
/// same file: size and modification time equal, and the same path once resolved, or
/// the same name when a path no longer resolves): its hold-out was in the fit.
fn fitted_on_this_log(dir: &crate::model::folder::ModelDir, a: &CheckArgs) -> Option<String> {
    let (source, size, mtime) = dir.source()?;
    let (log_size, log_mtime) = crate::log::source_identity(&a.log).ok()?;
    let same_path = match (
        std::fs::canonicalize(&source),
        std::fs::canonicalize(&a.log),
    ) {
        (Ok(x), Ok(y)) => x == y,
        _ => std::path::Path::new(&source).file_name() == a.log.file_name(),
    };
    (same_path && size == log_size && mtime == log_mtime).then(|| {
        format!(
            "{} was fitted on {} itself (the same file: path, size and modification time), so the hold-out's last {} s were in the fit: the FARMA prediction there is in-sample while the ARMA baseline is fitted before the hold-out; check on a log the model has not seen, or run `farma analyze`, which fits without the hold-out",
            a.model.display(),
            a.log.display(),
            a.holdout_s
        )
    })
}

pub fn run(a: CheckArgs, progress: &Progress) -> Result<()> {
    if let Some(dir) = &a.output {
        OutputSet::check(dir)?;
    }
    let job = CheckJob {
        model: a.model.clone(),
        log: a.log.clone(),
        output: a.output.clone(),
        holdout_s: a.holdout_s,
        maxlag: a.maxlag,
        max_degree: a.max_degree,
    };
    let dir = job.model_dir()?;
    let store = a.log_args.open(&a.log, progress)?;
    let names = match &a.channel {
        // (blank names dropped and repeats taken once, as `--channel` of the other commands)
        Some(c) => {
            let mut v: Vec<String> = Vec::new();
            for s in c.split(',').map(str::trim).filter(|s| !s.is_empty()) {
                if !v.iter().any(|o| o == s) {
                    v.push(s.to_string());
                }
            }
            if v.is_empty() {
                return Err(Error::Usage("--channel: no channel named".into()));
            }
            v
        }
        None => dir.channels()?,
    };
    if !(a.holdout_s.is_finite() && a.holdout_s >= 0.0) {
        return Err(Error::Usage(format!(
            "--holdout-s: {} is not a non-negative number",
            a.holdout_s
        )));
    }
    if let Some(warning) = fitted_on_this_log(&dir, &a) {
        eprintln!("farma: warning: {warning}");
    }
    for c in job.run(&dir, &store, &names)? {
        let (name, model, holdout, report) = (&c.channel, &c.model, c.holdout, &c.report);
        let (w, prediction, poly) = (&report.whiteness, &report.prediction, &report.poly);
        let (p, q, d) = (model.p(), model.q(), model.d());
        if a.json {
            outln!(
                "{}",
                json!({
                    "channel": name,
                    "order": [p, q, d],
                    "holdout": holdout,
                    "acf_outside": w.outside, "acf_band": w.band,
                    "ljung_box": w.ljung_box.iter().map(|b| json!({"lag": b.lag, "q": b.q, "df": b.df, "p_value": b.p_value})).collect::<Vec<_>>(),
                    "prediction": prediction.as_ref().map(|p| p.horizons.iter().map(|h| json!({"k": h.k, "n": h.n, "rmse_farma": h.rmse_farma, "rmse_arma": h.rmse_arma})).collect::<Vec<_>>()),
                    "arma_ar": c.arma_ar, "arma_ma": c.arma_ma,
                    "poly": poly.iter().map(|p| json!({"m": p.m, "degree": p.degree, "coef": p.coef, "wrms": p.wrms})).collect::<Vec<_>>(),
                })
            );
        } else {
            outln!("channel {name}: FARMA({p},{q},{d})");
            outln!(
                "  residual ACF: {} of {} lags outside +-{:.4}",
                w.outside,
                w.acf.len(),
                w.band
            );
            for b in &w.ljung_box {
                outln!(
                    "  Ljung-Box lag {:>3}: Q = {:>10.3} on {} df, p = {:.4}",
                    b.lag,
                    b.q,
                    b.df,
                    b.p_value
                );
            }
            if let Some(pr) = &prediction {
                outln!(
                    "  hold-out: last {} samples; ARMA({},{}) baseline fitted before it",
                    pr.holdout,
                    p,
                    q
                );
                outln!("      k     rmse FARMA      rmse ARMA");
                for h in &pr.horizons {
                    outln!(
                        "  {:>5} {:>14.6e} {:>14.6e}",
                        h.k,
                        h.rmse_farma,
                        h.rmse_arma
                    );
                }
            }
            for pf in poly {
                outln!(
                    "  f_{} ~ degree {} in u = x - mean: {:?}",
                    pf.m,
                    pf.degree,
                    pf.coef
                );
            }
        }
    }
    Ok(())
}
