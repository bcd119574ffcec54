//! The units of a batch: every log the inputs name (files, globs, folders), its
//! `log_id`, and one unit per (log, task); a deterministic share of them per shard; the
//! fingerprint of a log and the hash of a task's options that decide whether a done
//! unit can be skipped.

use std::collections::BTreeMap;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::jobfile::{JobFile, Task};
use crate::error::{Error, Result};

/// Extensions a folder input takes.
pub const LOG_EXTENSIONS: [&str; 4] = ["csv", "parquet", "arrow", "ipc"];

/// One log of the batch.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Log {
    pub path: PathBuf,
    /// The partition key: the file stem with characters other than letters, digits,
    /// `_`, `-` and `.` replaced by `_`; when two logs share it, each gets `-` and the
    /// first 8 hex digits of its path's hash appended.
    pub id: String,
    /// The channels the inputs name for it (`None`: the gyro role).
    pub channels: Option<Vec<String>>,
    /// Its input's gyro patterns, overriding the job's (`None`: the job's).
    pub gyro: Option<Vec<String>>,
}

/// One unit of work: a task on a log.
#[derive(Clone, Debug)]
pub struct Unit {
    /// Index of the log in [`plan`]'s logs.
    pub log: usize,
    /// Index of the task in the job file.
    pub task: usize,
    /// `<log_id>.<task name>`: unique, stable across runs.
    pub key: String,
}

/// The logs and units of `job`, in a stable order (logs sorted by path, tasks in the
/// job file's order). A pattern that matches nothing, or a path that does not exist, is
/// an error naming it.
pub fn plan(job: &JobFile) -> Result<(Vec<Log>, Vec<Unit>)> {
    type Choice = (Option<Vec<String>>, Option<Vec<String>>);
    let mut found: BTreeMap<PathBuf, Choice> = BTreeMap::new();
    for inp in &job.inputs {
        for p in &inp.paths {
            let files = match expand(p, &job.path) {
                Ok(f) => f,
                Err(e) if inp.optional => {
                    eprintln!("farma: warning: {e} (an optional input: skipped)");
                    continue;
                }
                Err(e) => return Err(e),
            };
            for f in files {
                found
                    .entry(f)
                    .or_insert_with(|| (inp.channels.clone(), inp.gyro.clone()));
            }
        }
    }
    let stems: Vec<(PathBuf, String, Choice)> = found
        .into_iter()
        .map(|(p, c)| {
            let stem = p
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_default();
            let id: String = stem
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            (p, id, c)
        })
        .collect();
    let mut logs = Vec::new();
    for (p, id, (channels, gyro)) in &stems {
        let shared = stems.iter().filter(|o| o.1 == *id).count() > 1;
        let id = if shared {
            format!("{id}-{:08x}", hash64(p.to_string_lossy().as_bytes()) >> 32)
        } else {
            id.clone()
        };
        logs.push(Log {
            path: p.clone(),
            id,
            channels: channels.clone(),
            gyro: gyro.clone(),
        });
    }
    let mut units = Vec::new();
    for (li, l) in logs.iter().enumerate() {
        for (ti, t) in job.tasks.iter().enumerate() {
            units.push(Unit {
                log: li,
                task: ti,
                key: format!("{}.{}", l.id, t.name),
            });
        }
    }
    Ok((logs, units))
}

/// The files a path of an input names: the file, a folder's logs, or a glob's matches.
fn expand(p: &Path, job: &Path) -> Result<Vec<PathBuf>> {
    let s = p.to_string_lossy();
    if s.contains(['*', '?', '[']) {
        let paths = glob::glob(&s).map_err(|e| {
            Error::format(job, format!("inputs: '{s}' is not a valid pattern: {e}"))
        })?;
        let mut out: Vec<PathBuf> = paths
            .filter_map(|r| r.ok())
            .filter(|f| f.is_file())
            .collect();
        out.sort();
        if out.is_empty() {
            return Err(Error::format(job, format!("inputs: '{s}' matches no file")));
        }
        return Ok(out);
    }
    if p.is_dir() {
        let mut out: Vec<PathBuf> = std::fs::read_dir(p)
            .map_err(|e| Error::input_io(p, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|f| {
                f.is_file()
                    && f.extension()
                        .and_then(|e| e.to_str())
                        .is_some_and(|e| LOG_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
            })
            .collect();
        out.sort();
        if out.is_empty() {
            return Err(Error::format(
                job,
                format!("inputs: the folder '{s}' holds no .csv, .parquet, .arrow or .ipc file"),
            ));
        }
        return Ok(out);
    }
    if p.is_file() {
        return Ok(vec![p.to_path_buf()]);
    }
    Err(Error::format(job, format!("inputs: '{s}' does not exist")))
}

/// Whether unit `key` belongs to shard `i` of `n` (0-based): by the hash of its key,
/// so that a unit keeps its shard when other logs are added or removed.
pub fn in_shard(key: &str, (i, n): (usize, usize)) -> bool {
    n <= 1 || (hash64(key.as_bytes()) % n as u64) as usize == i
}

/// xxHash64 (seed 0) of `bytes`: the batch's one hash (log contents, options, ids).
pub fn hash64(bytes: &[u8]) -> u64 {
    twox_hash::XxHash64::oneshot(0, bytes)
}

/// What identifies a log's contents: its size, modification time and the hash of its
/// first and last MiB.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fingerprint {
    pub size: u64,
    pub mtime_ns: i64,
    /// xxHash64 of the first MiB followed by the last MiB (16 hex digits).
    pub head_tail_hash: String,
}

/// The bytes hashed at each end of a log.
const END_BYTES: u64 = 1 << 20;

/// The fingerprint of the log at `path`.
pub fn fingerprint(path: &Path) -> Result<Fingerprint> {
    let (size, mtime_ns) = crate::log::source_identity(path)?;
    let mut f = std::fs::File::open(path).map_err(|e| Error::input_io(path, e))?;
    let mut buf = Vec::new();
    let head = size.min(END_BYTES);
    (&mut f)
        .take(head)
        .read_to_end(&mut buf)
        .map_err(|e| Error::input_io(path, e))?;
    if size > head {
        let tail_from = (size - END_BYTES).max(head);
        f.seek(SeekFrom::Start(tail_from))
            .map_err(|e| Error::input_io(path, e))?;
        f.read_to_end(&mut buf)
            .map_err(|e| Error::input_io(path, e))?;
    }
    Ok(Fingerprint {
        size,
        mtime_ns: mtime_ns as i64,
        head_tail_hash: format!("{:016x}", hash64(&buf)),
    })
}

/// The hash of a task's kind and options, of the log's channel list and roles,
/// of a check's model files (size and modification time) and of the farma version (16
/// hex digits): what a rerun compares to know the unit's options unchanged.
pub fn options_hash(task: &Task, log: &Log, roles: &super::jobfile::Roles) -> String {
    // a check's model folder: a refit into the same folder is a change of options
    let model = match (
        &task.kind,
        task.options.get("model").and_then(|v| v.as_str()),
    ) {
        (super::jobfile::TaskKind::Check, Some(m)) => ["params.parquet", "coef.parquet"]
            .iter()
            .map(|f| {
                crate::log::source_identity(&Path::new(m).join(f))
                    .map_or_else(|_| "missing".to_string(), |(s, t)| format!("{s}:{t}"))
            })
            .collect::<Vec<_>>()
            .join(","),
        _ => String::new(),
    };
    // a gap's spec file: an edited spec is a change of options
    let model = match (
        &task.kind,
        task.options.get("spec").and_then(|v| v.as_str()),
    ) {
        (super::jobfile::TaskKind::Gap, Some(s)) => std::fs::read(s).map_or_else(
            |_| "missing".to_string(),
            |b| format!("{:016x}", hash64(&b)),
        ),
        _ => model,
    };
    let text = format!(
        "{}\n{}\n{:?}\n{:?}\n{model}\n{}",
        task.kind.as_str(),
        task.options,
        log.channels,
        roles.for_input(&log.gyro),
        env!("CARGO_PKG_VERSION")
    );
    format!("{:016x}", hash64(text.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_units() {
        let keys: Vec<String> = (0..200).map(|i| format!("log{i}.fit")).collect();
        let n = 4;
        let mut seen = vec![0; keys.len()];
        for i in 0..n {
            for (k, key) in keys.iter().enumerate() {
                if in_shard(key, (i, n)) {
                    seen[k] += 1;
                }
            }
        }
        assert!(seen.iter().all(|c| *c == 1));
        let share = keys.iter().filter(|k| in_shard(k, (0, n))).count();
        assert!(share > 30 && share < 70, "{share}");
    }
}
