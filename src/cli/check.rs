//! `farma check MODEL LOG`: residual whiteness, hold-out prediction against the linear
//! ARMA baseline, and polynomial fits of the f_m, for a model written by `farma fit`
//! (or `farma analyze`) and a log.
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
use crate::estimator::arma::fit_arma;
use crate::log::Progress;
use crate::model::Farma;
use crate::model::folder::{ModelDir, PARAMS_FILE};
use crate::output::OutputSet;
use crate::workflow::check::{CheckReport, check_model};
use crate::workflow::tables::{acf_table, ljung_box_table, poly_table, prediction_table};

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

/// The files `farma check -o` can write into its output folder: a run removes those
/// of an earlier run that it does not write.
pub(super) const CHECK_OUTPUTS: &[&str] = &[
    "acf.parquet",
    "ljung_box.parquet",
    "prediction.parquet",
    "poly.parquet",
];

pub fn run(a: CheckArgs, progress: &Progress) -> Result<()> {
    if let Some(dir) = &a.output {
        OutputSet::check(dir)?;
    }
    // a 2-D fit's folder is refused naming its index (its coef.parquet repeats every
    // grid point of the lag index, once per point of the second, which the 1-D
    // reader would report as 'f_1 has a repeated grid point')
    let dir = ModelDir::new(&a.model);
    if let Some(index) = dir.index2() {
        return Err(Error::format(
            &dir.params_path(),
            format!(
                "the model was fitted with a 2-D index (--index {index}); farma check takes a fit on the lag index x_(t-d) alone"
            ),
        ));
    }
    let store = a.log_args.open(&a.log, progress)?;
    let rate = store.sample_rate_hz();
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
    let mut out: Vec<(String, CheckReport)> = Vec::new();
    for name in &names {
        let (_, model) = dir.load(Some(name))?;
        if let Some(what) = crate::estimator::arma::not_invertible(&model.b) {
            // (an update can leave one, with a note, and a folder can be edited)
            return Err(Error::format(
                &a.model.join(PARAMS_FILE),
                format!(
                    "channel '{name}': {what}: the model's residuals on the log would grow without bound; refit the channel"
                ),
            ));
        }
        let x = store.column(name)?;
        let n = x.len();
        let holdout = (a.holdout_s * rate).round() as usize;
        let start = model.order.lag();
        // (saturating: a --holdout-s beyond the log's length in samples must reach the
        // refusal below, not wrap around and cut the slice after it out of range)
        let need = holdout.saturating_add(start).saturating_add(100);
        if need > n {
            return Err(Error::TooShort {
                what: format!(
                    "{}: channel {name}: check with a {holdout}-sample hold-out",
                    a.log.display()
                ),
                need: need as u64,
                have: n as u64,
            });
        }
        let y: Vec<f64> = x.iter().map(|v| v - model.mean).collect();
        let e = model.residuals(&y);
        let train = &x[..n - holdout];
        let tm = train.iter().sum::<f64>() / train.len() as f64;
        let tc: Vec<f64> = train.iter().map(|v| v - tm).collect();
        let arma = fit_arma(&tc, model.p(), model.q()).ok_or_else(|| {
            Error::column(
                &a.log,
                format!(
                    "channel '{name}': the linear ARMA({},{}) baseline on the log before the hold-out failed (singular design: a constant or too regular channel)",
                    model.p(),
                    model.q()
                ),
            )
        })?;
        let baseline = Farma::linear(&arma.ar, &arma.ma, tm, f64::NAN);
        let report = check_model(
            &model,
            &e[..n - holdout],
            &baseline,
            x,
            holdout,
            a.maxlag,
            a.max_degree,
        );
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
                    "arma_ar": arma.ar, "arma_ma": arma.ma,
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
        out.push((name.clone(), report));
    }
    if let Some(dir) = &a.output {
        let mut set = OutputSet::new(dir)?;
        let md = vec![
            ("source", a.log.display().to_string()),
            ("model", a.model.display().to_string()),
        ];
        let ws: Vec<_> = out.iter().map(|o| (o.0.clone(), &o.1.whiteness)).collect();
        set.parquet("acf.parquet", &acf_table(&ws)?, &md)?;
        set.parquet("ljung_box.parquet", &ljung_box_table(&ws)?, &md)?;
        let ps: Vec<_> = out
            .iter()
            .filter_map(|o| o.1.prediction.as_ref().map(|p| (o.0.clone(), p)))
            .collect();
        set.parquet("prediction.parquet", &prediction_table(&ps)?, &md)?;
        let pf: Vec<_> = out
            .iter()
            .map(|o| (o.0.clone(), o.1.poly.as_slice()))
            .collect();
        set.parquet("poly.parquet", &poly_table(&pf)?, &md)?;
        super::commit_outputs(set, CHECK_OUTPUTS)?;
    }
    Ok(())
}
