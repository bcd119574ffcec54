//! `farma batch JOB.toml [-o ROOT] [--shard i/n] [--status] [--json]`: a job file's
//! tasks over many logs into one dataset ([`crate::batch`]).

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use crate::batch::jobfile::JobFile;
use crate::batch::{BatchRun, manifest};
use crate::error::{Error, Result};
use crate::log::{CachePolicy, Progress};

#[derive(Args, Debug)]
pub struct BatchArgs {
    /// The job file (TOML; see the README, "farma batch").
    pub job: PathBuf,
    /// The dataset root (default: the job file's `output`).
    #[arg(short, long, value_name = "ROOT")]
    pub output: Option<PathBuf>,
    /// Run shard I of N (1-based, e.g. 2/4): a fixed share of the units. Default: from
    /// SLURM_ARRAY_TASK_ID / SLURM_ARRAY_TASK_COUNT or JOB_COMPLETION_INDEX /
    /// FARMA_SHARD_COUNT when set, else every unit.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Print the progress of the job from its manifest (every shard's units) and exit.
    #[arg(long)]
    pub status: bool,
    /// One JSON object on stdout: the run's summary.
    #[arg(long)]
    pub json: bool,
    /// Folder for converted stores (default: $FARMA_CACHE_DIR, else ~/.cache/farma).
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
}

/// `i/n` (1-based on the command line) as (i - 1, n).
fn parse_shard(s: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::Usage(format!(
            "--shard: '{s}' is not I/N with 1 <= I <= N (e.g. 2/4)"
        ))
    };
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n): (usize, usize) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i == 0 || i > n {
        return Err(bad());
    }
    Ok((i - 1, n))
}

/// The shard from the scheduler's environment: Slurm array jobs
/// (SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT; the ID taken 0-based from
/// SLURM_ARRAY_TASK_MIN) or a Kubernetes Indexed Job (JOB_COMPLETION_INDEX, with the
/// count in FARMA_SHARD_COUNT).
fn shard_from_env() -> Result<Option<(usize, usize)>> {
    let var = |k: &str| std::env::var(k).ok().filter(|v| !v.trim().is_empty());
    let num = |k: &str, v: String| -> Result<usize> {
        v.trim()
            .parse()
            .map_err(|_| Error::Usage(format!("{k} = '{v}' is not a non-negative integer")))
    };
    if let (Some(id), Some(count)) = (var("SLURM_ARRAY_TASK_ID"), var("SLURM_ARRAY_TASK_COUNT")) {
        let min = match var("SLURM_ARRAY_TASK_MIN") {
            Some(m) => num("SLURM_ARRAY_TASK_MIN", m)?,
            None => 0,
        };
        let (id, n) = (
            num("SLURM_ARRAY_TASK_ID", id)?,
            num("SLURM_ARRAY_TASK_COUNT", count)?,
        );
        if n == 0 || id < min || id - min >= n {
            return Err(Error::Usage(format!(
                "SLURM_ARRAY_TASK_ID = {id} is outside the array (min {min}, count {n})"
            )));
        }
        return Ok(Some((id - min, n)));
    }
    if let Some(idx) = var("JOB_COMPLETION_INDEX") {
        let idx = num("JOB_COMPLETION_INDEX", idx)?;
        let n = match var("FARMA_SHARD_COUNT") {
            Some(c) => num("FARMA_SHARD_COUNT", c)?,
            None => {
                return Err(Error::Usage(
                    "JOB_COMPLETION_INDEX is set but FARMA_SHARD_COUNT is not: set it to the Job's completions".into(),
                ));
            }
        };
        if n == 0 || idx >= n {
            return Err(Error::Usage(format!(
                "JOB_COMPLETION_INDEX = {idx} is not below FARMA_SHARD_COUNT = {n}"
            )));
        }
        return Ok(Some((idx, n)));
    }
    Ok(None)
}

pub fn run(a: BatchArgs, progress: &Progress) -> Result<()> {
    let job = JobFile::load(&a.job)?;
    let root = a.output.clone().or(job.output.clone()).ok_or_else(|| {
        Error::Usage(format!(
            "{}: no output root: give -o ROOT or `output = \"...\"` in the job file",
            a.job.display()
        ))
    })?;
    if a.status {
        return status(&job, &root, a.json);
    }
    let shard = match &a.shard {
        Some(s) => parse_shard(s)?,
        None => shard_from_env()?.unwrap_or((0, 1)),
    };
    let cache = match &a.cache_dir {
        Some(d) => CachePolicy::Dir(d.clone()),
        None => CachePolicy::Default,
    };
    let (_, units) = crate::batch::units::plan(&job)?;
    let mine = units
        .iter()
        .filter(|u| crate::batch::units::in_shard(&u.key, shard))
        .count();
    let bar = progress.count_bar("units", mine as u64);
    let plain = !progress.enabled();
    eprintln!(
        "farma batch: {} unit(s) of {} in shard {}/{}; dataset {}",
        mine,
        units.len(),
        shard.0 + 1,
        shard.1,
        root.display()
    );
    let run = BatchRun {
        job,
        root: root.clone(),
        shard,
        cache,
    };
    let report = |unit: &str, st: &str, msg: &str| {
        bar.inc(1);
        if plain || st == "failed" {
            let msg = if msg.is_empty() {
                String::new()
            } else {
                format!(": {msg}")
            };
            crate::log::progress_line("batch", &format!("{unit}: {st}{msg}"));
        }
    };
    let s = run.run(&report)?;
    bar.finish_and_clear();
    eprintln!(
        "farma batch: {} done, {} failed, {} skipped of {} unit(s) in {:.1} s; manifest {}",
        s.done,
        s.failed,
        s.skipped,
        s.units,
        s.secs,
        root.join(manifest::MANIFEST_FILE).display()
    );
    if a.json {
        outln!(
            "{}",
            json!({
                "output": root.display().to_string(),
                "units": s.units, "done": s.done, "failed": s.failed, "skipped": s.skipped,
                "failures": s.errors.iter().map(|(u, e)| json!({"unit": u, "error": e})).collect::<Vec<_>>(),
                "shard": [shard.0 + 1, shard.1],
                "secs": s.secs,
            })
        );
    }
    if s.failed > 0 {
        for (u, e) in &s.errors {
            eprintln!("farma: error: {u}: {e}");
        }
        return Err(Error::BatchFailed {
            failed: s.failed,
            of: s.units,
        });
    }
    Ok(())
}

/// `--status`: the units of the job and their state in the manifest.
fn status(job: &JobFile, root: &std::path::Path, as_json: bool) -> Result<()> {
    let (_, units) = crate::batch::units::plan(job)?;
    let rows = manifest::read_rows(root)?;
    let count = |st: &str| {
        rows.iter()
            .filter(|r| r.status == st && units.iter().any(|u| u.key == r.unit))
            .count()
    };
    let (done, failed, skipped) = (
        count(manifest::DONE),
        count(manifest::FAILED),
        count(manifest::SKIPPED),
    );
    let pending = units.len() - done - failed - skipped;
    if as_json {
        outln!(
            "{}",
            json!({"output": root.display().to_string(), "units": units.len(), "done": done,
                   "failed": failed, "skipped": skipped, "pending": pending})
        );
    } else {
        outln!(
            "{}: {} unit(s): {done} done, {failed} failed, {skipped} skipped, {pending} not run",
            root.display(),
            units.len()
        );
        for r in rows.iter().filter(|r| r.status == manifest::FAILED) {
            outln!("  failed {}: {}", r.unit, r.error);
        }
    }
    Ok(())
}
