//! `farma batch`: a job file's tasks run over many logs into one dataset.
//!
//! A unit of work is (log, task) ([`units`]). Each unit runs the task's job
//! ([`crate::jobs`]) on the log's channels (those its input names, else the channels
//! of the gyro role, [`jobfile::Roles`]) into a staging folder under the root, then its
//! tables are moved, each by one atomic rename, into the dataset:
//!
//! ```text
//! ROOT/<table>/task=<task name>/log_id=<log id>/part-0.parquet   (hive partitions)
//! ROOT/_files/task=<task name>/log_id=<log id>/<file>            (summary.txt, stores)
//! ROOT/_manifest/<log id>.<task name>.parquet                    (the unit's row)
//! ROOT/manifest.parquet                                          (all rows)
//! ROOT/index.html                      (every unit, its status, report and verdict)
//! ```
//!
//! `<table>` is the file stem a job writes (`coef`, `params`, `gcv`, `select`,
//! `ftests`, `ljung_box`, ...); every table has a `channel` column, and `task` and
//! `log_id` come from the partitions (DuckDB `hive_partitioning = true`, pyarrow
//! `partitioning="hive"`).
//!
//! A unit's manifest row is written last, when its tables are in place: a rerun skips
//! a unit whose row says `done` with the same log fingerprint and options hash and
//! whose files are all there, and redoes every other (its old files replaced, those it
//! no longer writes removed). A run killed at any moment loses at most the units in
//! flight: no file in the dataset is ever partial (each is renamed into place whole).
//! Units are run longest log first, in parallel over the machine's threads; a failing
//! unit records its error in the manifest and the others go on. Every store a unit
//! reads is verified against its per-column checksums first ([`crate::store`]): a
//! damaged ingested store fails its units, naming the column.

pub mod index;
pub mod jobfile;
pub mod manifest;
pub mod units;

use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use rayon::prelude::*;

use crate::diagnosis::GapParams;
use crate::error::{Error, Result};
use crate::estimator::{FarmaParams, FitPath};
use crate::jobs::adev::AdevJob;
use crate::jobs::analyze::AnalyzeJob;
use crate::jobs::analyze::choice::ChannelChoice;
use crate::jobs::check::CheckJob;
use crate::jobs::fit::{DEFAULT_GRID, FitJob};
use crate::jobs::gap::GapJob;
use crate::jobs::prep::PrepJob;
use crate::jobs::psd::PsdJob;
use crate::jobs::select::SelectJob;
use crate::log::{CachePolicy, LogOptions, Progress};
use crate::model::Order;
use crate::stats::adev::{CiOptions, Kind, ONE_SIGMA, TauGrid};
use crate::stats::psd::Detrend;
use crate::workflow::constancy::ConstancyTest;
use crate::workflow::prep::PrepParams;
use crate::workflow::select::PAPER_ORDERS;
use jobfile::{JobFile, Task, TaskKind, opt_bool, opt_f64, opt_str, opt_usize};
use manifest::Row;
use units::{Log, Unit};

/// The staging folder under the root (removed units' leftovers are swept at start).
pub const STAGING_DIR: &str = ".staging";
/// The folder of the files that are not tables.
pub const FILES_DIR: &str = "_files";

/// How to run a batch.
#[derive(Clone, Debug)]
pub struct BatchRun {
    pub job: JobFile,
    /// The dataset root.
    pub root: PathBuf,
    /// (i, n): this process runs shard i of n (0-based); (0, 1) runs every unit.
    pub shard: (usize, usize),
    pub cache: CachePolicy,
}

/// What a batch run did.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// Units of this shard.
    pub units: usize,
    pub done: usize,
    pub failed: usize,
    /// Units skipped: done before with the same inputs and options, or with no
    /// channel to run on.
    pub skipped: usize,
    /// (unit, error) of the failed units.
    pub errors: Vec<(String, String)>,
    pub secs: f64,
}

fn unix_now() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

impl BatchRun {
    /// Runs this shard's units and rewrites the manifest; `report` is told of each
    /// unit as it ends (unit key, status, message).
    pub fn run(&self, report: &(dyn Fn(&str, &str, &str) + Sync)) -> Result<Summary> {
        let t0 = Instant::now();
        let (logs, units) = units::plan(&self.job)?;
        std::fs::create_dir_all(&self.root).map_err(|e| Error::output_io(&self.root, e))?;
        let previous = manifest::read_rows(&self.root)?;
        let mut mine: Vec<&Unit> = units
            .iter()
            .filter(|u| units::in_shard(&u.key, self.shard))
            .collect();
        // longest first: the log's size stands for the unit's length
        let size = |u: &Unit| std::fs::metadata(&logs[u.log].path).map_or(0, |m| m.len());
        mine.sort_by(|a, b| size(b).cmp(&size(a)).then(a.key.cmp(&b.key)));
        let outcomes: Vec<(String, String)> = mine
            .par_iter()
            .map(|u| {
                let prev = previous.iter().find(|r| r.unit == u.key);
                let status = self.run_unit(u, &logs[u.log], &self.job.tasks[u.task], prev);
                let (st, msg) = match &status {
                    Ok(Ran::Done) => (manifest::DONE, String::new()),
                    Ok(Ran::Unchanged) => ("unchanged", String::new()),
                    Ok(Ran::Skipped(why)) => (manifest::SKIPPED, why.clone()),
                    Err(e) => (manifest::FAILED, e.to_string()),
                };
                report(&u.key, st, &msg);
                (st.to_string(), msg)
            })
            .collect();
        manifest::write_union(&self.root)?;
        index::write(&self.root)?;
        let mut s = Summary {
            units: mine.len(),
            ..Summary::default()
        };
        for (u, (st, msg)) in mine.iter().zip(outcomes) {
            match st.as_str() {
                manifest::DONE => s.done += 1,
                manifest::FAILED => {
                    s.failed += 1;
                    s.errors.push((u.key.clone(), msg));
                }
                _ => s.skipped += 1,
            }
        }
        s.secs = t0.elapsed().as_secs_f64();
        Ok(s)
    }

    /// Runs one unit unless it is done and unchanged; writes its manifest row.
    fn run_unit(&self, u: &Unit, log: &Log, task: &Task, prev: Option<&Row>) -> Result<Ran> {
        let started = unix_now();
        let opts = units::options_hash(task, log, &self.job.roles);
        let mut row = Row {
            unit: u.key.clone(),
            log_id: log.id.clone(),
            log_path: log.path.display().to_string(),
            task: task.name.clone(),
            kind: task.kind.as_str().to_string(),
            log_size: 0,
            log_mtime_ns: 0,
            log_hash: String::new(),
            options_hash: opts.clone(),
            status: manifest::FAILED.into(),
            error: String::new(),
            started_unix_s: started,
            finished_unix_s: started,
            farma_version: env!("CARGO_PKG_VERSION").into(),
            farma_commit: env!("FARMA_COMMIT").into(),
            files: String::new(),
        };
        let result = (|| -> Result<Ran> {
            let fp = units::fingerprint(&log.path)?;
            row.log_size = fp.size;
            row.log_mtime_ns = fp.mtime_ns;
            row.log_hash = fp.head_tail_hash.clone();
            if let Some(p) = prev
                && p.status == manifest::DONE
                && p.options_hash == opts
                && p.log_size == fp.size
                && p.log_mtime_ns == fp.mtime_ns
                && p.log_hash == fp.head_tail_hash
                && p.files
                    .split(';')
                    .filter(|f| !f.is_empty())
                    .all(|f| self.root.join(f).is_file())
            {
                return Ok(Ran::Unchanged);
            }
            let store = crate::log::open_log(
                &log.path,
                &LogOptions::default(),
                &self.cache,
                &Progress::hidden(),
            )?;
            // every store a batch reads is checked against its column checksums (a
            // cached conversion was checked when reused; an ingested store named as an
            // input is refused here, naming the damaged column)
            store.verify()?;
            let roles = self.job.roles.for_input(&log.gyro);
            let channels: Vec<String> = match &log.channels {
                Some(c) => c.clone(),
                None => store
                    .channel_names()
                    .into_iter()
                    .filter(|c| roles.is_gyro(c))
                    .map(str::to_string)
                    .collect(),
            };
            if channels.is_empty() {
                return Ok(Ran::Skipped(format!(
                    "no channel of the gyro role ({}) among {}; name the channels in the input",
                    roles.gyro.join(", "),
                    store.channel_names().join(", ")
                )));
            }
            for c in &channels {
                store.column(c)?;
            }
            let staging =
                self.root
                    .join(STAGING_DIR)
                    .join(format!("{}.{}", u.key, std::process::id()));
            let _ = std::fs::remove_dir_all(&staging);
            let out = staging.join("out");
            // the log's first channel of the temperature role, offered to the tasks
            // that read one (gap)
            let temperature = store
                .channel_names()
                .into_iter()
                .find(|c| roles.is_temperature(c))
                .map(str::to_string);
            let run = run_task(task, &log.path, &out, &store, channels, temperature, &roles);
            let placed = run.and_then(|()| self.place(&out, log, task));
            let _ = std::fs::remove_dir_all(&staging);
            let files = placed?;
            // the files of an earlier run of this unit that this one did not write
            if let Some(p) = prev {
                for f in p.files.split(';').filter(|f| !f.is_empty()) {
                    if !files.iter().any(|n| n == f) {
                        let _ = std::fs::remove_file(self.root.join(f));
                    }
                }
            }
            row.files = files.join(";");
            Ok(Ran::Done)
        })();
        match &result {
            Ok(Ran::Unchanged) => return result,
            Ok(Ran::Done) => row.status = manifest::DONE.into(),
            Ok(Ran::Skipped(why)) => {
                row.status = manifest::SKIPPED.into();
                row.error = why.clone();
            }
            Err(e) => row.error = e.to_string(),
        }
        row.finished_unix_s = unix_now();
        manifest::write_row(&self.root, &row)?;
        result
    }

    /// Moves the files of a unit's job folder `out` into the dataset; returns their
    /// paths relative to the root.
    fn place(&self, out: &Path, log: &Log, task: &Task) -> Result<Vec<String>> {
        let mut names: Vec<PathBuf> = std::fs::read_dir(out)
            .map_err(|e| Error::output_io(out, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file())
            .collect();
        names.sort();
        let mut rel = Vec::new();
        for src in names {
            let file = src
                .file_name()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_default();
            let part = format!("task={}/log_id={}", task.name, log.id);
            let dest_rel = match file.strip_suffix(".parquet") {
                Some(table) => format!("{table}/{part}/part-0.parquet"),
                None => format!("{FILES_DIR}/{part}/{file}"),
            };
            let dest = self.root.join(&dest_rel);
            std::fs::create_dir_all(dest.parent().expect("a folder"))
                .map_err(|e| Error::output_io(&dest, e))?;
            std::fs::rename(&src, &dest).map_err(|e| Error::output_io(&dest, e))?;
            rel.push(dest_rel);
        }
        Ok(rel)
    }
}

/// What a unit did.
#[derive(Clone, Debug)]
enum Ran {
    Done,
    /// Done before, with the same log and options: not run again.
    Unchanged,
    /// Nothing to run on (the reason).
    Skipped(String),
}

/// Runs `task` on `channels` of `store` (the log `log`), writing its folder `out`.
fn run_task(
    task: &Task,
    log: &Path,
    out: &Path,
    store: &crate::store::Store,
    channels: Vec<String>,
    temperature: Option<String>,
    roles: &jobfile::Roles,
) -> Result<()> {
    let path = |t: &Task| -> Result<FitPath> {
        Ok(match opt_str(t, "method")? {
            None | Some("fast") => FitPath::Fast,
            Some("direct") => FitPath::Direct,
            Some(m) => {
                return Err(Error::Usage(format!(
                    "task '{}': method = '{m}' is not fast or direct",
                    t.name
                )));
            }
        })
    };
    let select = |t: &Task| -> Result<SelectJob> {
        let orders = match opt_str(t, "orders")? {
            Some(s) => Order::parse_list(s)?,
            None => PAPER_ORDERS
                .iter()
                .map(|&(p, q, d)| Order::new(p, q, d))
                .collect(),
        };
        Ok(SelectJob {
            log: log.to_path_buf(),
            output: Some(out.to_path_buf()),
            orders,
            farma: FarmaParams {
                grid_size: opt_usize(t, "grid")?.unwrap_or(DEFAULT_GRID),
                path: path(t)?,
                ..FarmaParams::default()
            },
            constancy: ConstancyTest::from_flags(
                opt_str(t, "constancy")?,
                opt_usize(t, "bootstrap")?,
            )
            .map_err(|e| Error::Usage(format!("task '{}': {e}", t.name)))?,
            seed: opt_usize(t, "seed")?.unwrap_or(1) as u64,
        })
    };
    match task.kind {
        TaskKind::Adev => {
            let job = AdevJob {
                log: log.to_path_buf(),
                channels,
                kinds: vec![Kind::Adev],
                grid: TauGrid::Octave,
                ci: CiOptions {
                    confidence: ONE_SIGMA,
                    alpha: 0,
                },
                fit_tau_min: opt_f64(task, "fit_tau_min")?,
                unit: None,
            };
            let segment = crate::jobs::longest_segment(store, log);
            let done = job.run(store, segment)?;
            job.write(out, store, &done)
        }
        TaskKind::Check => {
            let model = PathBuf::from(opt_str(task, "model")?.unwrap_or_default());
            let job = CheckJob {
                model: model.clone(),
                log: log.to_path_buf(),
                output: Some(out.to_path_buf()),
                holdout_s: opt_f64(task, "holdout_s")?.unwrap_or(50.0),
                maxlag: opt_usize(task, "maxlag")?.unwrap_or(40),
                max_degree: opt_usize(task, "max_degree")?.unwrap_or(6),
            };
            if !(job.holdout_s.is_finite() && job.holdout_s >= 0.0) {
                return Err(Error::Usage(format!(
                    "task '{}': holdout_s = {} is not a non-negative number",
                    task.name, job.holdout_s
                )));
            }
            // the unit's channels that the model holds
            let dir = job.model_dir()?;
            let fitted = dir.channels()?;
            let names: Vec<String> = channels
                .into_iter()
                .filter(|c| fitted.contains(c))
                .collect();
            if names.is_empty() {
                return Err(Error::Usage(format!(
                    "task '{}': the model {} holds none of the log's channels (it has {})",
                    task.name,
                    model.display(),
                    fitted.join(", ")
                )));
            }
            job.run(&dir, store, &names).map(|_| ())
        }
        TaskKind::Psd => {
            let detrend = match opt_str(task, "detrend")? {
                None | Some("constant") => Detrend::Constant,
                Some("none") => Detrend::None,
                Some(d) => {
                    return Err(Error::Usage(format!(
                        "task '{}': detrend = '{d}' is not constant or none",
                        task.name
                    )));
                }
            };
            let segment_len = opt_usize(task, "segment")?;
            if segment_len.is_some_and(|s| s < 2) {
                return Err(Error::Usage(format!(
                    "task '{}': segment must be at least 2 samples",
                    task.name
                )));
            }
            let job = PsdJob {
                log: log.to_path_buf(),
                channels,
                segment_len,
                detrend,
                bands_per_decade: opt_usize(task, "bands_per_decade")?.unwrap_or(0),
            };
            let segment = crate::jobs::longest_segment(store, log);
            let done = job.run(store, segment)?;
            job.write(out, store, &done)
        }
        TaskKind::Fit => {
            let o = Order::parse_flag(opt_str(task, "order")?.unwrap_or("2,1,1"))?;
            let job = FitJob {
                log: log.to_path_buf(),
                output: out.to_path_buf(),
                channels,
                params: FarmaParams {
                    p: o.p,
                    q: o.q,
                    d: o.d,
                    grid_size: opt_usize(task, "grid")?.unwrap_or(DEFAULT_GRID),
                    bandwidth: opt_f64(task, "bandwidth")?,
                    path: path(task)?,
                    max_iter: opt_usize(task, "max_iter")?.unwrap_or(50),
                    tol: opt_f64(task, "tol")?.unwrap_or(1e-6),
                    ..FarmaParams::default()
                },
                residuals: opt_bool(task, "residuals")?.unwrap_or(false),
                save_state: false,
            };
            job.run(store, &Progress::hidden()).map(|_| ())
        }
        TaskKind::Select => select(task)?.run(store, &channels).map(|_| ()),
        TaskKind::Analyze => {
            let job = AnalyzeJob {
                log: log.to_path_buf(),
                output: out.to_path_buf(),
                choice: ChannelChoice::given(
                    &store.channel_names(),
                    channels,
                    roles,
                    "a channel of the unit",
                ),
                prep: PrepParams::default(),
                select: select(task)?,
                holdout_s: opt_f64(task, "holdout_s")?.unwrap_or(50.0),
                maxlag: opt_usize(task, "maxlag")?.unwrap_or(40),
                max_degree: opt_usize(task, "max_degree")?.unwrap_or(6),
                fresh: true,
            };
            job.run(store, &Progress::hidden()).map(|_| ())
        }
        TaskKind::Gap => {
            let spec_path = PathBuf::from(opt_str(task, "spec")?.unwrap_or_default());
            let spec = crate::simulator::load_spec(&spec_path)?;
            // the unit's channels that the spec simulates
            let names: Vec<String> = channels
                .into_iter()
                .filter(|c| spec.channels.iter().any(|s| &s.name == c))
                .collect();
            if names.is_empty() {
                return Err(Error::Usage(format!(
                    "task '{}': the spec {} simulates none of the log's channels (it has {})",
                    task.name,
                    spec_path.display(),
                    spec.channels
                        .iter()
                        .map(|c| c.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            }
            let d = GapParams::default();
            let job = GapJob {
                log: log.to_path_buf(),
                spec_path,
                spec,
                channels: names,
                temperature,
                params: GapParams {
                    train_fraction: opt_f64(task, "train_fraction")?.unwrap_or(d.train_fraction),
                    replicas: opt_usize(task, "replicas")?.unwrap_or(d.replicas),
                    n_blocks: opt_usize(task, "blocks")?.unwrap_or(d.n_blocks),
                    seed: opt_usize(task, "seed")?.map(|s| s as u64),
                    max_added: opt_usize(task, "max_effects")?.unwrap_or(d.max_added),
                    reestimate: opt_bool(task, "reestimate")?.unwrap_or(d.reestimate),
                    screen: opt_bool(task, "screen")?.unwrap_or(d.screen),
                    joint_pairs: opt_bool(task, "joint_pairs")?.unwrap_or(d.joint_pairs),
                    keep_events: opt_bool(task, "keep_events")?.unwrap_or(d.keep_events),
                    explain_replicas: opt_usize(task, "explain_replicas")?
                        .unwrap_or(d.explain_replicas),
                    max_samples: opt_usize(task, "max_samples")?.unwrap_or(d.max_samples),
                    excerpt_samples: opt_usize(task, "excerpt_samples")?
                        .unwrap_or(d.excerpt_samples),
                    ..d
                },
            };
            let done = job.run(store)?;
            job.write(out, &done).map(|_| ())
        }
        TaskKind::Prep => PrepJob {
            log: log.to_path_buf(),
            output: out.to_path_buf(),
            channels,
            params: PrepParams::default(),
        }
        .run(store)
        .map(|_| ()),
    }
}
