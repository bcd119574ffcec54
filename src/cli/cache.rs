//! `farma cache list|prune`: the converted stores kept between runs
//! ([`crate::log::cache`]): what is there, and trimming it.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use serde_json::json;

use crate::error::{Error, Result};
use crate::log::CachePolicy;
use crate::log::cache::{dir_of, entries, limit_bytes, prune};

#[derive(Args, Debug)]
pub struct CacheArgs {
    #[command(subcommand)]
    pub action: CacheAction,
    /// The cache folder (default: $FARMA_CACHE_DIR, else ~/.cache/farma).
    #[arg(long, value_name = "DIR", global = true)]
    pub cache_dir: Option<PathBuf>,
    /// One JSON object on stdout.
    #[arg(long, global = true)]
    pub json: bool,
}

#[derive(Subcommand, Debug)]
pub enum CacheAction {
    /// The cached stores, least recently used first, with their sizes and the total.
    List,
    /// Remove the least recently used stores until the cache holds at most the limit
    /// (--max-gb, else FARMA_CACHE_LIMIT_GB, else 20 GB); --all removes every one.
    Prune {
        /// The size to trim to, GB (10^9 bytes).
        #[arg(long, value_name = "GB", conflicts_with = "all")]
        max_gb: Option<f64>,
        /// Remove every cached store.
        #[arg(long)]
        all: bool,
    },
}

fn secs_ago(t: std::time::SystemTime) -> f64 {
    std::time::SystemTime::now()
        .duration_since(t)
        .map_or(0.0, |d| d.as_secs_f64())
}

pub fn run(a: CacheArgs) -> Result<()> {
    let policy = match &a.cache_dir {
        Some(d) => CachePolicy::Dir(d.clone()),
        None => CachePolicy::Default,
    };
    let dir = dir_of(&policy).expect("a cache folder");
    match a.action {
        CacheAction::List => {
            let e = entries(&dir)?;
            let total: u64 = e.iter().map(|e| e.bytes).sum();
            if a.json {
                outln!(
                    "{}",
                    json!({
                        "dir": dir.display().to_string(),
                        "bytes": total,
                        "limit_bytes": limit_bytes()?,
                        "entries": e.iter().map(|e| json!({
                            "path": e.path.display().to_string(),
                            "bytes": e.bytes,
                            "last_used_s_ago": secs_ago(e.last_used),
                        })).collect::<Vec<_>>(),
                    })
                );
            } else {
                outln!(
                    "{}: {} store(s), {:.1} MB (limit {:.1} GB)",
                    dir.display(),
                    e.len(),
                    total as f64 / 1e6,
                    limit_bytes()? as f64 / 1e9
                );
                for x in &e {
                    outln!(
                        "  {:>10.1} MB  used {:>10.0} s ago  {}",
                        x.bytes as f64 / 1e6,
                        secs_ago(x.last_used),
                        x.path.display()
                    );
                }
            }
        }
        CacheAction::Prune { max_gb, all } => {
            let max = if all {
                0
            } else {
                match max_gb {
                    Some(g) if g.is_finite() && g >= 0.0 => (g * 1e9) as u64,
                    Some(g) => {
                        return Err(Error::Usage(format!(
                            "--max-gb: {g} is not a non-negative number of GB"
                        )));
                    }
                    None => limit_bytes()?,
                }
            };
            let removed = prune(&dir, max, None)?;
            let freed: u64 = removed.iter().map(|e| e.bytes).sum();
            if a.json {
                outln!(
                    "{}",
                    json!({"dir": dir.display().to_string(), "removed": removed.len(), "freed_bytes": freed})
                );
            } else {
                outln!(
                    "{}: removed {} store(s), {:.1} MB",
                    dir.display(),
                    removed.len(),
                    freed as f64 / 1e6
                );
            }
        }
    }
    Ok(())
}
