//! `farma analyze LOG -o OUTDIR`: prep -> select -> fit -> check for every channel, in
//! parallel; every table in one folder (Parquet) and a readable summary. The
//! arguments turned into an [`AnalyzeJob`], its result printed.

use std::path::PathBuf;

use clap::Args;

use super::LogArgs;
use super::prep::PrepFlags;
use super::select::SelectFlags;
use crate::error::{Error, Result};
use crate::jobs::analyze::AnalyzeJob;
use crate::jobs::analyze::choice::ChannelChoice;
use crate::log::Progress;
use crate::log::roles::Roles;
use crate::output::OutputSet;

#[derive(Args, Debug)]
pub struct AnalyzeArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC.
    pub log: PathBuf,
    /// Channels (comma-separated), analysed in parallel; `all`: the gyro axes, by
    /// their names and units (gyro, rate, _dps, _rps, _rad_s, _degph, gx..; see
    /// --role); accelerometers (accel, _g, _mps2, ..) and other channels are skipped
    /// unless named, temperatures (temp, _degc, ..) are named in the summary as the
    /// 2-D index of later tools. No gyro at all: every channel but the temperatures,
    /// with a warning.
    #[arg(long, default_value = "all")]
    pub channel: String,
    /// Sets the role of channels for `--channel all`: NAME=ROLE, NAME a channel or a
    /// pattern (`*`, `?`), ROLE gyro, temperature, accel or other; repeatable, the
    /// last match wins (`--role imu_rx=gyro --role 'aux*=other'`).
    #[arg(long, value_name = "NAME=ROLE")]
    pub role: Vec<String>,
    /// Analyse every channel again: by default a channel that an earlier run into the
    /// same OUTDIR finished with the same log and options is kept (its folder
    /// OUTDIR/channels/NAME has a matching done.json).
    #[arg(long)]
    pub fresh: bool,
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
    let mut roles = Roles::default();
    for r in &a.role {
        roles.add_override("--role", r)?;
    }
    let select = a.select.job(&a.log, None)?;
    let store = a.log_args.open(&a.log, progress)?;
    let choice = ChannelChoice::choose(&store, &a.channel, &roles)?;
    if let Some(w) = &choice.warning {
        eprintln!("farma: warning: {w}");
    }
    for l in &choice.lines {
        eprintln!("farma: {l}");
    }
    let job = AnalyzeJob {
        log: a.log.clone(),
        output: a.output.clone(),
        choice,
        prep: a.prep.params(),
        select,
        holdout_s: a.holdout_s,
        maxlag: a.maxlag,
        max_degree: a.max_degree,
        fresh: a.fresh,
    };
    let done = job.run(&store, progress)?;
    if a.json {
        for l in &done.json_lines {
            out!("{l}");
        }
    } else {
        out!("{}", done.text);
    }
    let kept = if done.kept.is_empty() {
        String::new()
    } else {
        format!(
            " ({} kept from an earlier run: {})",
            done.kept.len(),
            done.kept.join(", ")
        )
    };
    eprintln!(
        "farma: {} channel(s) analysed in {:.2} s{kept}; tables, summary.txt and report.html in {}",
        done.channels.len(),
        done.secs,
        a.output.display()
    );
    Ok(())
}
