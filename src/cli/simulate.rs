//! `farma simulate SPEC --duration S -o LOG`: simulate a gyro log from a spec.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use serde_json::json;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::log::Progress;
use crate::simulator::write::{LogFormat, TIME_COL, write_log};
use crate::simulator::{SimRequest, Simulator, load_spec};
use crate::stats::summarize;

#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// The simulation spec (TOML, contracts.md section 2).
    pub spec: PathBuf,
    /// Length of the simulated log, seconds (optional with --like: the real log's length).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// The simulated log: .parquet, .arrow (a farma store) or .csv.
    #[arg(short, long, value_name = "LOG")]
    pub output: PathBuf,
    /// A real log to take the length, the sample rate and the temperature channel from.
    #[arg(long, value_name = "REAL_LOG")]
    pub like: Option<PathBuf>,
    /// Seed of the random streams (default: the spec's seed, else 0).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Replica of the seed (independent realisations of one seed).
    #[arg(long, default_value_t = 0)]
    pub replica: u64,
    /// Channels of the spec to simulate (comma-separated, or all).
    #[arg(long, default_value = "all")]
    pub channel: String,
    /// How to read the --like log.
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON summary object on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: SimulateArgs, progress: &Progress) -> Result<()> {
    let started = Instant::now();
    let format = LogFormat::from_path(&a.output)?;
    let spec = load_spec(&a.spec)?;
    let real = match &a.like {
        Some(path) => Some(a.log_args.open(path, progress)?),
        None => None,
    };
    let rate_hz = match &real {
        Some(s) => {
            let r = s.sample_rate_hz();
            if (r - spec.sample_rate_hz).abs() > 1e-9 * r {
                eprintln!(
                    "farma: warning: --like log is sampled at {r} Hz, the spec says {} Hz; simulating at {r} Hz",
                    spec.sample_rate_hz
                );
            }
            r
        }
        None => spec.sample_rate_hz,
    };
    let n_samples = match (a.duration, &real) {
        (Some(d), _) => {
            if !(d.is_finite() && d > 0.0) {
                return Err(Error::Usage(format!(
                    "--duration must be > 0 seconds, found {d}"
                )));
            }
            let n = (d * rate_hz).round();
            if n < 1.0 {
                return Err(Error::Usage(format!(
                    "--duration {d} s is less than one sample at {rate_hz} Hz"
                )));
            }
            if n > usize::MAX as f64 / 2.0 {
                return Err(Error::Usage(format!("--duration {d} s is too long")));
            }
            n as usize
        }
        (None, Some(s)) => s.n_samples(),
        (None, None) => {
            return Err(Error::Usage(
                "give --duration SECONDS, or --like REAL_LOG to take the length from a real log"
                    .into(),
            ));
        }
    };
    let temperature: Option<(&str, &[f64])> = match (&real, &spec.temperature_channel) {
        (Some(s), Some(name)) => {
            let needed = spec
                .channels
                .iter()
                .flat_map(|c| &c.components)
                .any(|c| c.kind().needs_temperature());
            match s.column(name) {
                Ok(t) => {
                    if t.len() < n_samples {
                        return Err(Error::Usage(format!(
                            "--duration asks for {n_samples} samples but the temperature channel '{name}' of {} has {}",
                            s.label().display(),
                            t.len()
                        )));
                    }
                    Some((name.as_str(), &t[..n_samples]))
                }
                // a temperature column with NaN: the same error as for a channel
                Err(e @ Error::NonFinite { .. }) => return Err(e),
                Err(_) if needed => {
                    return Err(Error::Usage(format!(
                        "{}: no channel '{name}', the spec's temperature_channel; channels are: {} (hint: set the spec's temperature_channel to the log's temperature column)",
                        s.label().display(),
                        s.channel_names().join(", ")
                    )));
                }
                Err(_) => None,
            }
        }
        _ => None,
    };
    let channels = if a.channel.trim() == "all" {
        None
    } else {
        Some(
            a.channel
                .split(',')
                .map(|s| s.trim().to_string())
                .filter(|s| !s.is_empty())
                .collect::<Vec<_>>(),
        )
    };
    let req = SimRequest {
        n_samples,
        sample_rate_hz: rate_hz,
        temperature_c: temperature.map(|t| t.1),
        seed: a.seed,
        replica: a.replica,
        channels,
        base_dir: a.spec.parent().map(|p| p.to_path_buf()),
    };
    let sim = Simulator::new(&spec, req)?;
    let out = sim.run()?;

    let mut columns: Vec<(&str, &[f64])> = out
        .channels
        .iter()
        .map(|(n, v)| (n.as_str(), v.as_slice()))
        .collect();
    if let Some((name, t)) = temperature
        && !columns.iter().any(|c| c.0 == name)
    {
        columns.push((name, t));
    }
    for (name, _) in &columns {
        if ["time", "time_s", "t", "timestamp"].contains(name) {
            return Err(Error::Usage(format!(
                "{}: channel '{name}' would be read as the time column of the simulated log; rename it",
                a.spec.display()
            )));
        }
    }
    let provenance = vec![
        ("source", a.spec.display().to_string()),
        ("farma_simulate_seed", out.seed.to_string()),
        ("farma_simulate_replica", out.replica.to_string()),
        (
            "farma_simulate_like",
            a.like
                .as_ref()
                .map_or_else(String::new, |p| p.display().to_string()),
        ),
    ];
    write_log(&a.output, format, &columns, rate_hz, &provenance)?;
    let elapsed_s = started.elapsed().as_secs_f64();

    let summaries: Vec<_> = out.channels.iter().map(|(n, v)| summarize(n, v)).collect();
    if a.json {
        let v = json!({
            "output": a.output.display().to_string(),
            "format": format.as_str(),
            "spec": a.spec.display().to_string(),
            "like": a.like.as_ref().map(|p| p.display().to_string()),
            "n_samples": n_samples,
            "sample_rate_hz": rate_hz,
            "duration_s": n_samples as f64 / rate_hz,
            "seed": out.seed,
            "replica": out.replica,
            "time_col": TIME_COL,
            "temperature_channel": temperature.map(|t| t.0),
            "channels": summaries,
            "elapsed_s": elapsed_s,
        });
        outln!("{v}");
    } else {
        outln!(
            "wrote {} ({}): {} channel(s), {} samples at {} Hz ({} s), seed {} replica {}",
            a.output.display(),
            format.as_str(),
            out.channels.len(),
            n_samples,
            rate_hz,
            n_samples as f64 / rate_hz,
            out.seed,
            out.replica
        );
        for s in &summaries {
            outln!(
                "  {:<16} mean {:>14.6e}  std {:>14.6e}",
                s.name,
                s.mean,
                s.std
            );
        }
    }
    Ok(())
}
