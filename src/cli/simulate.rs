//! `farma simulate SPEC --duration S -o LOG`: simulate a gyro log from a spec.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use serde_json::json;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::log::Progress;
use crate::simulator::generate::streams::MAX_SAMPLES;
use crate::simulator::write::{BLOCK_ROWS, LogFormat, LogWriter, TIME_COL};
use crate::simulator::{Component, SimRequest, Simulator, load_spec};
use crate::stats::Summarizer;

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
    // a rate or a spec value out of range is named before any size is derived from it
    spec.check_simulable(rate_hz).map_err(Error::Usage)?;
    let n_samples = match (a.duration, &real) {
        (Some(d), _) => {
            if !(d.is_finite() && d > 0.0) {
                return Err(Error::Usage(format!(
                    "--duration must be > 0 seconds, found {}",
                    crate::fmt::num(d)
                )));
            }
            let n = (d * rate_hz).round();
            let (d_s, rate_s) = (crate::fmt::num(d), crate::fmt::num(rate_hz));
            if n < 1.0 {
                return Err(Error::Usage(format!(
                    "--duration {d_s} s is less than one sample at {rate_s} Hz"
                )));
            }
            if n > MAX_SAMPLES as f64 {
                return Err(Error::Usage(format!(
                    "--duration {d_s} s is too long: {} samples at {rate_s} Hz, more than the simulator's limit of {MAX_SAMPLES} samples per channel",
                    crate::fmt::num(n)
                )));
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
    // memory planned before it is taken: the log is generated and written by
    // blocks, so what is held is a few blocks per channel (and thermal_rate's
    // smoothed temperature, 3 values per sample while it is computed), not the series
    let n_channels = spec.channels.len() as f64;
    let thermal = spec
        .channels
        .iter()
        .flat_map(|c| &c.components)
        .filter(|c| matches!(c, Component::ThermalRate { .. }))
        .count() as f64;
    let block = BLOCK_ROWS.min(n_samples) as f64;
    let planned = 8.0 * block * (4.0 * n_channels + 4.0) + 24.0 * thermal * n_samples as f64;
    crate::workflow::budget::check_memory(
        &format!(
            "--duration {} s",
            crate::fmt::num(n_samples as f64 / rate_hz)
        ),
        &format!(
            "simulating {n_samples} samples of {} channel(s) by blocks of {} samples",
            spec.channels.len(),
            block
        ),
        planned,
    )?;
    let sim = Simulator::new(&spec, req)?;
    let names = sim.channel_names()?;
    let mut columns: Vec<&str> = names.iter().map(String::as_str).collect();
    let temp_col = match temperature {
        Some((name, t)) if !columns.contains(&name) => Some((name, t)),
        _ => None,
    };
    if let Some((name, _)) = temp_col {
        columns.push(name);
    }
    for name in &columns {
        if ["time", "time_s", "t", "timestamp"].contains(name) {
            return Err(Error::Usage(format!(
                "{}: channel '{name}' would be read as the time column of the simulated log; rename it",
                a.spec.display()
            )));
        }
    }
    let seed = sim.seed();
    let provenance = vec![
        ("source", a.spec.display().to_string()),
        ("farma_simulate_seed", seed.to_string()),
        ("farma_simulate_replica", a.replica.to_string()),
        (
            "farma_simulate_like",
            a.like
                .as_ref()
                .map_or_else(String::new, |p| p.display().to_string()),
        ),
    ];
    let mut w = LogWriter::create(&a.output, format, &columns, n_samples, rate_hz, &provenance)?;
    let mut acc: Vec<Summarizer> = names.iter().map(|n| Summarizer::new(n)).collect();
    let mut blocks = sim.blocks(BLOCK_ROWS)?;
    while let Some((start, cols)) = blocks.next_block()? {
        let mut block: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
        if let Some((_, t)) = temp_col {
            block.push(&t[start..start + cols[0].len()]);
        }
        w.write_block(&block)?;
        for (s, c) in acc.iter_mut().zip(&cols) {
            s.push(c);
        }
    }
    w.finish()?;
    let out = Simulated {
        seed,
        replica: a.replica,
        n_channels: names.len(),
    };
    let elapsed_s = started.elapsed().as_secs_f64();

    let summaries: Vec<_> = acc.into_iter().map(Summarizer::finish).collect();
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
            out.n_channels,
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

/// What the summary line says of the simulation.
struct Simulated {
    seed: u64,
    replica: u64,
    n_channels: usize,
}
