//! `farma check MODEL LOG`: residual whiteness, hold-out prediction against the linear
//! ARMA baseline, and polynomial fits of the f_m, for a model written by `farma fit`
//! (or `farma analyze`) and a log.
//!
//! The hold-out is the last `--holdout-s` seconds of LOG. The ARMA(p,q) baseline is
//! fitted by conditional least squares on LOG before the hold-out. Whiteness is that of
//! the model's residuals on LOG before the hold-out (rows t >= max(p,q,d)). When the
//! model was fitted on the same log including its end, the hold-out is not unseen by
//! it: `farma analyze` fits on the log without the hold-out.

use std::path::{Path, PathBuf};

use arrow_array::{Array, Float64Array, Int64Array, RecordBatch, StringArray};
use clap::Args;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use serde_json::json;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::estimator::arma::fit_arma;
use crate::estimator::saved::{SavedFarma, load_saved};
use crate::log::Progress;
use crate::output::OutputSet;
use crate::workflow::check::{
    HORIZONS, Linear, PolyFit, Predictor, poly_fit_curve, predict_holdout, residuals_of,
};
use crate::workflow::ljung_box::{Whiteness, whiteness};
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

/// A saved model as a predictor on centred values (u + mean is the channel value).
struct Saved<'a>(&'a SavedFarma);

impl Predictor for Saved<'_> {
    fn p(&self) -> usize {
        self.0.p
    }
    fn d(&self) -> usize {
        self.0.d
    }
    fn b(&self) -> &[f64] {
        &self.0.b
    }
    fn f(&self, u: f64, out: &mut [f64]) {
        self.0.eval(u + self.0.mean, out)
    }
}

fn read(path: &Path) -> Result<Vec<RecordBatch>> {
    let file = std::fs::File::open(path).map_err(|e| Error::input_io(path, e))?;
    let bad = |e: parquet::errors::ParquetError| {
        Error::format(path, format!("not a farma fit table: {e}"))
    };
    ParquetRecordBatchReaderBuilder::try_new(file)
        .map_err(bad)?
        .build()
        .map_err(bad)?
        .map(|b| b.map_err(|e| Error::format(path, format!("not a farma fit table: {e}"))))
        .collect()
}

fn col<'a, T: 'static>(b: &'a RecordBatch, name: &str, path: &Path) -> Result<&'a T> {
    b.column_by_name(name)
        .and_then(|c| c.as_any().downcast_ref::<T>())
        .ok_or_else(|| {
            Error::column(
                path,
                format!("no column '{name}' of the type farma fit writes"),
            )
        })
}

/// Channel names, bandwidths of params.parquet; (m, grid, se) of coef.parquet for `channel`.
/// (m, grid, se) of one coefficient row.
type CoefRow = (usize, f64, f64);

fn model_extras(dir: &Path, channel: &str) -> Result<(f64, Vec<CoefRow>)> {
    let pp = dir.join("params.parquet");
    let mut h = f64::NAN;
    for b in read(&pp)? {
        let ch: &StringArray = col(&b, "channel", &pp)?;
        let bw: &Float64Array = col(&b, "bandwidth", &pp)?;
        for i in 0..ch.len() {
            if ch.value(i) == channel {
                h = bw.value(i);
            }
        }
    }
    let cp = dir.join("coef.parquet");
    let mut out = Vec::new();
    for b in read(&cp)? {
        let ch: &StringArray = col(&b, "channel", &cp)?;
        let m: &Int64Array = col(&b, "m", &cp)?;
        let g: &Float64Array = col(&b, "grid", &cp)?;
        let se: &Float64Array = col(&b, "se", &cp)?;
        for i in 0..ch.len() {
            if ch.value(i) == channel {
                out.push((m.value(i) as usize, g.value(i), se.value(i)));
            }
        }
    }
    Ok((h, out))
}

/// Channels fitted in the model folder.
fn model_channels(dir: &Path) -> Result<Vec<String>> {
    let pp = dir.join("params.parquet");
    let mut out = Vec::new();
    for b in read(&pp)? {
        let ch: &StringArray = col(&b, "channel", &pp)?;
        out.extend((0..ch.len()).map(|i| ch.value(i).to_string()));
    }
    Ok(out)
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
    if let Some(index) = super::update::model_index2(&a.model) {
        return Err(Error::format(
            &a.model.join("params.parquet"),
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
        None => model_channels(&a.model)?,
    };
    if !(a.holdout_s.is_finite() && a.holdout_s >= 0.0) {
        return Err(Error::Usage(format!(
            "--holdout-s: {} is not a non-negative number",
            a.holdout_s
        )));
    }
    let mut out: Vec<(
        String,
        Whiteness,
        Option<crate::workflow::check::Prediction>,
        Vec<PolyFit>,
    )> = Vec::new();
    for name in &names {
        let model = load_saved(&a.model, Some(name))?;
        if let Some(what) = crate::estimator::arma::not_invertible(&model.b) {
            // (an update can leave one, with a note, and a folder can be edited)
            return Err(Error::format(
                &a.model.join("params.parquet"),
                format!(
                    "channel '{name}': {what}: the model's residuals on the log would grow without bound; refit the channel"
                ),
            ));
        }
        let x = store.column(name)?;
        let n = x.len();
        let holdout = (a.holdout_s * rate).round() as usize;
        let start = model.p.max(model.q).max(model.d);
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
        let pred = Saved(&model);
        let y: Vec<f64> = x.iter().map(|v| v - model.mean).collect();
        let e = residuals_of(&pred, &y);
        let ln = ((n - holdout - start) as f64).ln().round() as usize;
        let mut lags = vec![5, 10, 20, ln.max(1)];
        lags.retain(|l| *l <= a.maxlag);
        lags.sort_unstable();
        lags.dedup();
        let w = whiteness(&e[start..n - holdout], a.maxlag, &lags, model.p + model.q);
        let train = &x[..n - holdout];
        let tm = train.iter().sum::<f64>() / train.len() as f64;
        let tc: Vec<f64> = train.iter().map(|v| v - tm).collect();
        let arma = fit_arma(&tc, model.p, model.q).ok_or_else(|| {
            Error::column(
                &a.log,
                format!(
                    "channel '{name}': the linear ARMA({},{}) baseline on the log before the hold-out failed (singular design: a constant or too regular channel)",
                    model.p, model.q
                ),
            )
        })?;
        let lin = Linear {
            ar: &arma.ar,
            ma: &arma.ma,
        };
        let prediction = (holdout > 0)
            .then(|| predict_holdout(&pred, model.mean, &lin, tm, x, holdout, &HORIZONS));
        let (h, rows) = model_extras(&a.model, name)?;
        let mut poly = Vec::new();
        for m in 1..=model.p {
            let pts: Vec<&CoefRow> = rows.iter().filter(|r| r.0 == m).collect();
            let grid: Vec<f64> = pts.iter().map(|r| r.1 - model.mean).collect();
            let se: Vec<f64> = pts.iter().map(|r| r.2).collect();
            let f: Vec<f64> = pts
                .iter()
                .map(|r| crate::estimator::saved::interp(&model.grid[m - 1], &model.f[m - 1], r.1))
                .collect();
            poly.push(poly_fit_curve(m, &grid, &f, &se, h, a.max_degree));
        }
        if a.json {
            outln!(
                "{}",
                json!({
                    "channel": name,
                    "order": [model.p, model.q, model.d],
                    "holdout": holdout,
                    "acf_outside": w.outside, "acf_band": w.band,
                    "ljung_box": w.ljung_box.iter().map(|b| json!({"lag": b.lag, "q": b.q, "df": b.df, "p_value": b.p_value})).collect::<Vec<_>>(),
                    "prediction": prediction.as_ref().map(|p| p.horizons.iter().map(|h| json!({"k": h.k, "n": h.n, "rmse_farma": h.rmse_farma, "rmse_arma": h.rmse_arma})).collect::<Vec<_>>()),
                    "arma_ar": arma.ar, "arma_ma": arma.ma,
                    "poly": poly.iter().map(|p| json!({"m": p.m, "degree": p.degree, "coef": p.coef, "wrms": p.wrms})).collect::<Vec<_>>(),
                })
            );
        } else {
            outln!("channel {name}: FARMA({},{},{})", model.p, model.q, model.d);
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
                    model.p,
                    model.q
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
            for p in &poly {
                outln!(
                    "  f_{} ~ degree {} in u = x - mean: {:?}",
                    p.m,
                    p.degree,
                    p.coef
                );
            }
        }
        out.push((name.clone(), w, prediction, poly));
    }
    if let Some(dir) = &a.output {
        let mut set = OutputSet::new(dir)?;
        let md = vec![
            ("source", a.log.display().to_string()),
            ("model", a.model.display().to_string()),
        ];
        let ws: Vec<_> = out.iter().map(|o| (o.0.clone(), &o.1)).collect();
        set.parquet("acf.parquet", &acf_table(&ws)?, &md)?;
        set.parquet("ljung_box.parquet", &ljung_box_table(&ws)?, &md)?;
        let ps: Vec<_> = out
            .iter()
            .filter_map(|o| o.2.as_ref().map(|p| (o.0.clone(), p)))
            .collect();
        set.parquet("prediction.parquet", &prediction_table(&ps)?, &md)?;
        let pf: Vec<_> = out.iter().map(|o| (o.0.clone(), o.3.as_slice())).collect();
        set.parquet("poly.parquet", &poly_table(&pf)?, &md)?;
        super::commit_outputs(set, CHECK_OUTPUTS)?;
    }
    Ok(())
}
