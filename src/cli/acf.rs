//! `farma acf LOG`: sample autocorrelation of channels up to a maximum lag, with the
//! +-1.96/sqrt(N) band of a white series; text, JSON Lines or Parquet.

use std::path::PathBuf;
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, Int64Array, StringArray};
use clap::Args;
use serde_json::json;

use super::LogArgs;
use crate::error::Result;
use crate::log::Progress;
use crate::output::{batch, write_parquet};
use crate::stats::acf::{Acf, acf, default_max_lag};

#[derive(Args, Debug)]
pub struct AcfArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC.
    pub log: PathBuf,
    /// Channels (comma-separated, or all).
    #[arg(long, default_value = "all")]
    pub channel: String,
    /// Largest lag in samples (default: 1000, or N - 1 for shorter logs).
    #[arg(long, value_name = "SAMPLES")]
    pub max_lag: Option<usize>,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the autocorrelation as a Parquet table (one row per channel and lag).
    #[arg(long, short, value_name = "OUT.parquet")]
    pub output: Option<PathBuf>,
}

pub fn run(a: AcfArgs, progress: &Progress) -> Result<()> {
    let store = a.log_args.open(&a.log, progress)?;
    let names = store.select_channels(&a.channel)?;
    let rate_hz = store.sample_rate_hz();
    let (start, len) = crate::jobs::longest_segment(&store, &a.log);
    let max_lag = a.max_lag.unwrap_or_else(|| default_max_lag(len));
    if let Some(flag) = a.max_lag {
        crate::workflow::budget::check_memory(
            &format!("--max-lag {flag}"),
            "the autocorrelation's FFT blocks",
            crate::stats::acf::planned_bytes(len, max_lag, rayon::current_num_threads()),
        )?;
    }
    let mut results: Vec<(String, Acf)> = Vec::new();
    for name in &names {
        let y = &store.column(name)?[start..start + len];
        let what = format!("{}: channel '{name}'", a.log.display());
        results.push((name.clone(), acf(&what, y, max_lag)?));
    }
    let lag_s = |k: usize| k as f64 / rate_hz;
    if let Some(out) = &a.output {
        let (mut ch, mut lag, mut ls, mut r, mut band) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (name, c) in &results {
            for (k, &v) in c.acf.iter().enumerate() {
                ch.push(name.as_str());
                lag.push(k as i64);
                ls.push(lag_s(k));
                r.push(v);
                band.push(c.band);
            }
        }
        let b = batch(vec![
            ("channel", Arc::new(StringArray::from(ch)) as ArrayRef),
            ("lag", Arc::new(Int64Array::from(lag)) as ArrayRef),
            ("lag_s", Arc::new(Float64Array::from(ls)) as ArrayRef),
            ("acf", Arc::new(Float64Array::from(r)) as ArrayRef),
            ("band", Arc::new(Float64Array::from(band)) as ArrayRef),
        ])?;
        write_parquet(
            out,
            &b,
            &[
                ("log", a.log.display().to_string()),
                ("sample_rate_hz", rate_hz.to_string()),
                ("n_samples", len.to_string()),
                ("max_lag", max_lag.to_string()),
                ("farma.command", "acf".to_string()),
            ],
        )?;
    }
    if a.json {
        for (name, c) in &results {
            let o = json!({
                "channel": name,
                "log": a.log.display().to_string(),
                "sample_rate_hz": rate_hz,
                "n_samples": c.n,
                "max_lag": max_lag,
                "lag": (0..c.acf.len()).collect::<Vec<usize>>(),
                "lag_s": (0..c.acf.len()).map(lag_s).collect::<Vec<f64>>(),
                "acf": c.acf,
                "band": c.band,
                "variance": c.variance,
                "output": a.output.as_ref().map(|p| p.display().to_string()),
            });
            outln!("{o}");
        }
        return Ok(());
    }
    outln!(
        "log       {} ({} samples at {} Hz)",
        a.log.display(),
        len,
        rate_hz
    );
    for (name, c) in &results {
        outln!();
        outln!(
            "channel {name}: autocorrelation, band +-{:.4e} (1.96/sqrt(N); * outside)",
            c.band
        );
        outln!("{:>10} {:>14} {:>14}", "lag", "lag_s", "acf");
        for (k, &v) in c.acf.iter().enumerate() {
            let mark = if k > 0 && v.abs() > c.band { " *" } else { "" };
            outln!("{:>10} {:>14.6e} {:>14.6e}{mark}", k, lag_s(k), v);
        }
    }
    Ok(())
}
