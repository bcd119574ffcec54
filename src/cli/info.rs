//! `farma info LOG`: what a log holds. A channel with non-finite or missing values is
//! described, not refused: its statistics are over its finite values, and the count
//! and first lines of the others are listed.

use std::path::PathBuf;

use clap::Args;
use rayon::prelude::*;
use serde_json::json;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::log::Progress;
use crate::stats::{ChannelSummary, summarize};

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC.
    pub log: PathBuf,
    /// Channels to summarise (comma-separated, or all).
    #[arg(long, default_value = "all")]
    pub channel: String,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object on stdout instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: InfoArgs, progress: &Progress) -> Result<()> {
    let store = a.log_args.open(&a.log, progress)?;
    let names = store.select_channels_with_nonfinite(&a.channel)?;
    if store.n_samples() < 2 {
        return Err(Error::TooShort {
            what: format!("{}: info (standard deviation)", a.log.display()),
            need: 2,
            have: store.n_samples() as u64,
        });
    }
    let summaries: Vec<ChannelSummary> = crate::jobs::every_channel(
        names
            .par_iter()
            .map(|n| Ok(summarize(n, store.column_with_nonfinite(n)?)))
            .collect(),
        "leave the failing ones out of --channel",
    )?;
    let meta = store.meta();
    let nonfinite: Vec<_> = names.iter().filter_map(|n| store.nonfinite(n)).collect();
    if a.json {
        let v = json!({
            "log": a.log.display().to_string(),
            "format": meta.source_format,
            "channels": summaries,
            "n_samples": store.n_samples(),
            "sample_rate_hz": store.sample_rate_hz(),
            "duration_s": store.duration_s(),
            "time_source": meta.time_source,
            "time_col": meta.time_col,
            "segments": meta.segments,
            "gaps": meta.segments.len().saturating_sub(1),
            "repairs": meta.repairs,
            "nonfinite": nonfinite,
        });
        outln!("{v}");
        return Ok(());
    }
    outln!("log       {} ({})", a.log.display(), meta.source_format);
    outln!(
        "samples   {} in {} segment(s)",
        store.n_samples(),
        meta.segments.len()
    );
    outln!(
        "rate      {} Hz (from {})",
        store.sample_rate_hz(),
        meta.time_source
    );
    outln!("duration  {:.3} s", store.duration_s());
    if meta.repairs.is_empty() {
        outln!("repairs   none");
    }
    for r in &meta.repairs {
        outln!(
            "repair    {} {} x{}: {}",
            r.kind,
            r.channel,
            r.count,
            r.detail
        );
    }
    for c in &nonfinite {
        outln!(
            "nonfinite {} x{}: first at {} (left out of its statistics; commands that read it refuse it: --nan interpolate replaces them)",
            c.column,
            c.count,
            c.first
        );
    }
    if meta.segments.len() > 1 {
        for s in &meta.segments {
            outln!(
                "segment   rows {}..{} from t = {} s",
                s.start,
                s.start + s.len,
                s.t0_s
            );
        }
    }
    outln!();
    outln!(
        "{:<16} {:>12} {:>14} {:>14} {:>14} {:>14}",
        "channel",
        "n",
        "mean",
        "std",
        "min",
        "max"
    );
    for s in &summaries {
        outln!(
            "{:<16} {:>12} {:>14.6e} {:>14.6e} {:>14.6e} {:>14.6e}",
            s.name,
            s.n,
            s.mean,
            s.std,
            s.min,
            s.max
        );
    }
    Ok(())
}
