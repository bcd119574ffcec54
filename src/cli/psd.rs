//! `farma psd LOG`: one-sided power spectral density of channels by Welch's method
//! (Hann window, 50 % overlap); text, JSON Lines or Parquet.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use serde_json::json;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::jobs::psd::{PsdJob, psd_table};
use crate::log::Progress;
use crate::output::write_parquet;
use crate::stats::psd::Detrend;

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
    if let Some(l) = a.segment {
        crate::workflow::budget::check_memory(
            &format!("--segment {l}"),
            "the Welch segments' FFT buffers",
            crate::stats::psd::planned_bytes(len, l, rayon::current_num_threads()),
        )?;
    }
    let machine = a.json || a.output.is_some();
    let bands = a.bands_per_decade.unwrap_or(if machine { 0 } else { 10 });
    let job = PsdJob {
        log: a.log.clone(),
        channels: names,
        segment_len: a.segment,
        detrend,
        bands_per_decade: bands,
    };
    let rows = job.run(&store, (start, len))?;
    if let Some(out) = &a.output {
        write_parquet(out, &psd_table(&rows)?, &job.metadata(rate_hz, &rows[0]))?;
    }
    if a.json {
        for r in &rows {
            let o = json!({
                "channel": r.channel,
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
            r.channel,
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
