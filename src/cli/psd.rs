//! `farma psd LOG`: one-sided power spectral density of channels by Welch's method
//! (Hann window, 50 % overlap); text, JSON Lines or Parquet.

use std::path::PathBuf;
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, Int64Array, StringArray};
use clap::{Args, ValueEnum};
use serde_json::json;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::log::Progress;
use crate::output::{batch, write_parquet};
use crate::stats::psd::{Detrend, band_average, default_segment_len, welch};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DetrendArg {
    /// Remove each segment's mean (scipy's default).
    Constant,
    /// Use the segments as they are.
    None,
}

#[derive(Args, Debug)]
pub struct PsdArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC. Channels are rates (deg/s, g, ...).
    pub log: PathBuf,
    /// Channels (comma-separated, or all).
    #[arg(long, default_value = "all")]
    pub channel: String,
    /// Segment length in samples (default: the largest power of two <= N/8, at most 65536).
    #[arg(long, value_name = "SAMPLES")]
    pub segment: Option<usize>,
    /// What to remove from each segment before windowing.
    #[arg(long, value_enum, default_value_t = DetrendArg::Constant)]
    pub detrend: DetrendArg,
    /// Average the spectrum over log-spaced bands, this many per decade (for plots).
    /// 0: every frequency bin. Default: every bin for --json and -o, 10 per decade for
    /// the text table.
    #[arg(long, value_name = "K")]
    pub bands_per_decade: Option<usize>,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the spectrum as a Parquet table (one row per channel and frequency).
    #[arg(long, short, value_name = "OUT.parquet")]
    pub output: Option<PathBuf>,
}

/// One channel's output rows.
struct Rows {
    name: String,
    freq_hz: Vec<f64>,
    psd: Vec<f64>,
    n_bins: Vec<usize>,
    segment_len: usize,
    n_segments: usize,
}

pub fn run(a: PsdArgs, progress: &Progress) -> Result<()> {
    if a.segment == Some(0) || a.segment == Some(1) {
        return Err(Error::Usage("--segment must be at least 2 samples".into()));
    }
    let store = a.log_args.open(&a.log, progress)?;
    let names = store.select_channels(&a.channel)?;
    let rate_hz = store.sample_rate_hz();
    let (start, len) = crate::jobs::longest_segment(&store, &a.log);
    let detrend = match a.detrend {
        DetrendArg::Constant => Detrend::Constant,
        DetrendArg::None => Detrend::None,
    };
    let machine = a.json || a.output.is_some();
    let bands = a.bands_per_decade.unwrap_or(if machine { 0 } else { 10 });
    let segment_len = a.segment.unwrap_or_else(|| default_segment_len(len));
    let mut rows = Vec::new();
    for name in &names {
        let y = &store.column(name)?[start..start + len];
        let what = format!("{}: channel '{name}'", a.log.display());
        let p = welch(&what, y, rate_hz, segment_len, detrend)?;
        let (freq_hz, psd, n_bins) = if bands == 0 {
            let n = vec![1; p.psd.len()];
            (p.freq_hz.clone(), p.psd.clone(), n)
        } else {
            let b = band_average(&p, bands);
            (
                b.iter().map(|x| x.freq_hz).collect(),
                b.iter().map(|x| x.psd).collect(),
                b.iter().map(|x| x.n_bins).collect(),
            )
        };
        rows.push(Rows {
            name: name.clone(),
            freq_hz,
            psd,
            n_bins,
            segment_len: p.segment_len,
            n_segments: p.n_segments,
        });
    }
    let meta = |r: &Rows| {
        vec![
            ("log", a.log.display().to_string()),
            ("sample_rate_hz", rate_hz.to_string()),
            ("window", "hann".to_string()),
            ("overlap", "0.5".to_string()),
            ("segment_len", r.segment_len.to_string()),
            ("n_segments", r.n_segments.to_string()),
            ("detrend", format!("{:?}", a.detrend).to_lowercase()),
            ("bands_per_decade", bands.to_string()),
            ("unit", "u^2/Hz, one-sided".to_string()),
            ("farma.command", "psd".to_string()),
        ]
    };
    if let Some(out) = &a.output {
        let (mut ch, mut f, mut p, mut nb) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for r in &rows {
            for i in 0..r.psd.len() {
                ch.push(r.name.as_str());
                f.push(r.freq_hz[i]);
                p.push(r.psd[i]);
                nb.push(r.n_bins[i] as i64);
            }
        }
        let b = batch(vec![
            ("channel", Arc::new(StringArray::from(ch)) as ArrayRef),
            ("freq_hz", Arc::new(Float64Array::from(f)) as ArrayRef),
            ("psd", Arc::new(Float64Array::from(p)) as ArrayRef),
            ("n_bins", Arc::new(Int64Array::from(nb)) as ArrayRef),
        ])?;
        // Segment counts are the same for every channel (same length, same L).
        write_parquet(out, &b, &meta(&rows[0]))?;
    }
    if a.json {
        for r in &rows {
            let o = json!({
                "channel": r.name,
                "log": a.log.display().to_string(),
                "sample_rate_hz": rate_hz,
                "n_samples": len,
                "window": "hann",
                "overlap": 0.5,
                "detrend": format!("{:?}", a.detrend).to_lowercase(),
                "segment_len": r.segment_len,
                "n_segments": r.n_segments,
                "bands_per_decade": bands,
                "freq_hz": r.freq_hz,
                "psd": r.psd,
                "n_bins": r.n_bins,
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
    for r in &rows {
        outln!();
        outln!(
            "channel {}: Welch PSD, Hann window, {} segments of {} samples, 50 % overlap, one-sided [u^2/Hz]{}",
            r.name,
            r.n_segments,
            r.segment_len,
            if bands > 0 {
                format!(", averaged in {bands} bands per decade")
            } else {
                String::new()
            }
        );
        outln!("{:>14} {:>14} {:>8}", "freq_hz", "psd", "bins");
        for i in 0..r.psd.len() {
            outln!(
                "{:>14.6e} {:>14.6e} {:>8}",
                r.freq_hz[i],
                r.psd[i],
                r.n_bins[i]
            );
        }
    }
    Ok(())
}
