//! `farma ingest INPUT -o STORE.arrow`.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use super::LogArgs;
use crate::error::Result;
use crate::log::{Progress, ingest};

#[derive(Args, Debug)]
pub struct IngestArgs {
    /// Input log: CSV, Parquet or Arrow IPC.
    pub input: PathBuf,
    /// Output store (Arrow IPC file, uncompressed, memory-mappable).
    #[arg(short, long, value_name = "STORE.arrow")]
    pub output: PathBuf,
    #[command(flatten)]
    pub log: LogArgs,
    /// Print the store's metadata as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: IngestArgs, progress: &Progress) -> Result<()> {
    let opts = a.log.options()?;
    let t = Instant::now();
    let meta = ingest(&a.input, &a.output, &opts, progress)?;
    let rows: u64 = meta.segments.iter().map(|s| s.len).sum();
    eprintln!(
        "farma: ingested {} ({}): {rows} rows at {} Hz into {} in {:.2} s",
        a.input.display(),
        meta.source_format,
        meta.sample_rate_hz,
        a.output.display(),
        t.elapsed().as_secs_f64()
    );
    for r in &meta.repairs {
        eprintln!(
            "farma: repaired: {} {} x{}: {}",
            r.kind, r.channel, r.count, r.detail
        );
    }
    if a.json {
        outln!("{}", serde_json::to_string(&meta).expect("serializable"));
    }
    Ok(())
}
