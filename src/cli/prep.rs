//! `farma prep LOG -o OUTDIR`: Pauta outlier rejection, the reverse-arrangement test,
//! trend removal or differencing, mean removal; the cleaned log and a report.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::LogArgs;
use super::choices::{NonstationaryArg, ReplaceArg, SegmentStatArg};
use crate::error::Result;
use crate::jobs::prep::PrepJob;
use crate::log::Progress;
use crate::output::OutputSet;
use crate::workflow::prep::{ChannelPrep, PrepParams};

/// The preparation flags (shared with `farma analyze`).
#[derive(Args, Debug, Clone)]
pub struct PrepFlags {
    /// Pauta threshold in standard deviations.
    #[arg(long = "sigma", default_value_t = 3.0, value_name = "C")]
    pub sigma_c: f64,
    /// Replacement of rejected samples (the time base is kept).
    #[arg(long, value_enum, default_value_t = ReplaceArg::Interpolate)]
    pub replace: ReplaceArg,
    /// Segments of the reverse-arrangement test.
    #[arg(long, default_value_t = 20, value_name = "K")]
    pub segments: usize,
    /// Statistic of each segment in the reverse-arrangement test.
    #[arg(long, value_enum, default_value_t = SegmentStatArg::Mean)]
    pub segment_stat: SegmentStatArg,
    /// Level of the stationarity test (rejected when p <= alpha).
    #[arg(long, default_value_t = crate::workflow::ALPHA)]
    pub alpha: f64,
    /// What to do when stationarity is rejected.
    #[arg(long, value_enum, default_value_t = NonstationaryArg::Trend)]
    pub nonstationary: NonstationaryArg,
    /// Keep the mean (default: subtract it).
    #[arg(long)]
    pub keep_mean: bool,
}

impl PrepFlags {
    pub fn params(&self) -> PrepParams {
        PrepParams {
            sigma_c: self.sigma_c,
            replace: self.replace.into(),
            segments: self.segments,
            segment_stat: self.segment_stat.into(),
            alpha: self.alpha,
            nonstationary: self.nonstationary.into(),
            keep_mean: self.keep_mean,
            ..PrepParams::default()
        }
    }
}

#[derive(Args, Debug)]
pub struct PrepArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC.
    pub log: PathBuf,
    /// Channels to prepare (comma-separated, or all).
    #[arg(long, default_value = "all")]
    pub channel: String,
    /// Output folder: clean.arrow (the prepared log, a store), prep.parquet (every
    /// step), replaced.parquet (every replaced sample).
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: PathBuf,
    #[command(flatten)]
    pub prep: PrepFlags,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines).
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: PrepArgs, progress: &Progress) -> Result<()> {
    OutputSet::check(&a.output)?;
    let store = a.log_args.open(&a.log, progress)?;
    let prm = a.prep.params();
    let job = PrepJob {
        log: a.log.clone(),
        output: a.output.clone(),
        channels: store.select_channels(&a.channel)?,
        params: prm.clone(),
    };
    let chans = job.run(&store)?;
    for c in &chans {
        if a.json {
            outln!("{}", prep_json(c, prm.alpha));
        } else {
            outln!("channel {}", c.name);
            for s in &c.steps {
                outln!("  {:<20} {}", s.step, s.detail);
            }
        }
    }
    eprintln!(
        "farma: {} channel(s) prepared; clean.arrow, prep.parquet, replaced.parquet in {}",
        chans.len(),
        a.output.display()
    );
    Ok(())
}

/// The `--json` object of one prepared channel.
pub fn prep_json(c: &ChannelPrep, alpha: f64) -> serde_json::Value {
    let ra = |r: &crate::workflow::stationarity::ReverseArrangement| {
        json!({"segments": r.segments, "statistic": r.statistic, "mean": r.mean,
               "variance": r.variance, "z": r.z, "p_value": r.p_value})
    };
    json!({
        "channel": c.name,
        "n": c.values.len(),
        "replaced": c.replaced.len(),
        "replaced_index": c.replaced.iter().map(|r| r.index).collect::<Vec<_>>(),
        "stationarity": ra(&c.before),
        "stationarity_after": c.after.as_ref().map(ra),
        "stationary": c.stationary(alpha),
        "differenced": c.differenced,
        "steps": c.steps.iter().map(|s| json!({"step": s.step, "count": s.count,
            "statistic": s.statistic, "z": s.z, "p_value": s.p_value, "value": s.value,
            "detail": s.detail})).collect::<Vec<_>>(),
    })
}
