//! Outputs: tables written atomically as Parquet for analytics tools (DuckDB, pandas,
//! Spark), and small helpers for the `--json` lines on stdout.
//!
//! Every file is written to a temporary file in the target's folder and renamed into
//! place, so a reader never sees half a file and a failed run leaves nothing behind.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{ArrayRef, RecordBatch};
use arrow_schema::{Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;

use crate::error::{Error, Result};

/// Creates `dir` (and parents) for outputs.
pub fn ensure_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::output_io(dir, e))
}

/// Builds a batch from named columns (all of equal length).
pub fn batch(columns: Vec<(&str, ArrayRef)>) -> Result<RecordBatch> {
    let fields: Vec<Field> = columns
        .iter()
        .map(|(n, a)| Field::new(*n, a.data_type().clone(), a.null_count() > 0))
        .collect();
    let arrays: Vec<ArrayRef> = columns.into_iter().map(|(_, a)| a).collect();
    RecordBatch::try_new(Arc::new(Schema::new(fields)), arrays)
        .map_err(|e| Error::Internal(format!("output table: {e}")))
}

/// A temporary file in `path`'s folder (removed unless renamed), so that a rename puts
/// it in place atomically: [`temp_in`] there.
fn temp_beside(path: &Path) -> Result<tempfile::NamedTempFile> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    temp_in(&dir, path)
}

/// A temporary file in folder `dir` for output `target` (named in errors), removed
/// unless renamed: `.farma-HOST-PID-XXXXXX.tmp`, HOST this machine's name and PID this
/// process's. A run killed while it writes (SIGKILL, a scheduler's time limit) cannot
/// remove its temporary files; so before the first one in a folder, the files of that
/// pattern whose HOST is this machine and whose process is gone are removed, with a
/// note on stderr ([`sweep_stale_temps`]). Files of another machine (a shared folder),
/// of a live process, or of the older `.farma-XXXXXX.tmp` pattern are left alone.
pub(crate) fn temp_in(dir: &Path, target: &Path) -> Result<tempfile::NamedTempFile> {
    sweep_stale_temps(dir);
    let prefix = match host_name() {
        Some(host) => format!(".farma-{host}-{}-", std::process::id()),
        None => ".farma-".to_string(),
    };
    tempfile::Builder::new()
        .prefix(&prefix)
        .suffix(".tmp")
        .permissions(crate::store::output_permissions())
        .tempfile_in(dir)
        .map_err(|e| Error::output_io(target, e))
}

/// This machine's name for temporary files' names (letters, digits, `.` and `_`; any
/// other character as `_`), from `/proc/sys/kernel/hostname`; None where that cannot
/// be read (not Linux): temporary files are then named `.farma-XXXXXX.tmp` and never
/// swept.
fn host_name() -> Option<String> {
    static HOST: std::sync::OnceLock<Option<String>> = std::sync::OnceLock::new();
    HOST.get_or_init(|| {
        let raw = std::fs::read_to_string("/proc/sys/kernel/hostname").ok()?;
        let name: String = raw
            .trim()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '.' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        (!name.is_empty()).then_some(name)
    })
    .clone()
}

/// Removes from `dir` (once per folder and process) the temporary files
/// `.farma-HOST-PID-XXXXXX.tmp` left by killed runs: HOST this machine (`host_name`),
/// PID a process that no longer exists (`/proc/PID` absent). Says how many on stderr.
/// Errors are ignored: a file that cannot be removed stays.
pub fn sweep_stale_temps(dir: &Path) {
    static SWEPT: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let Some(host) = host_name() else { return };
    if !Path::new("/proc/self").exists() {
        return;
    }
    let key = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    {
        let mut swept = SWEPT.lock().unwrap_or_else(|e| e.into_inner());
        if swept.contains(&key) {
            return;
        }
        swept.push(key);
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let me = std::process::id();
    let mut removed = 0usize;
    let committing = journal_temps(dir);
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        if committing.iter().any(|c| c == name) {
            continue;
        }
        let Some(pid) = stale_temp_pid(name, &host) else {
            continue;
        };
        if pid == me || Path::new("/proc").join(pid.to_string()).exists() {
            continue;
        }
        if entry.file_type().is_ok_and(|t| t.is_file())
            && std::fs::remove_file(entry.path()).is_ok()
        {
            removed += 1;
        }
    }
    if removed > 0 {
        eprintln!(
            "farma: note: removed {removed} temporary file(s) .farma-{host}-PID-*.tmp left in {} by killed runs",
            dir.display()
        );
    }
}

/// The PID of a temporary file's name `.farma-HOST-PID-XXXXXX.tmp` when HOST is `host`
/// (XXXXXX: letters and digits).
fn stale_temp_pid(name: &str, host: &str) -> Option<u32> {
    let rest = name
        .strip_prefix(".farma-")?
        .strip_suffix(".tmp")?
        .strip_prefix(host)?
        .strip_prefix('-')?;
    let (pid, random) = rest.split_once('-')?;
    if random.is_empty() || !random.chars().all(|c| c.is_ascii_alphanumeric()) {
        return None;
    }
    if pid.is_empty() || !pid.chars().all(|c| c.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// Writes `text` to `path` atomically (a temporary file beside it, then a rename).
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    use std::io::Write;
    let mut tmp = temp_beside(path)?;
    tmp.write_all(text.as_bytes())
        .and_then(|_| tmp.flush())
        .map_err(|e| Error::output_io(path, e))?;
    tmp.persist(path)
        .map_err(|e| Error::output_io(path, e.error))?;
    Ok(())
}

/// Writes `batch` to `path` as zstd Parquet with key-value metadata, atomically.
pub fn write_parquet(path: &Path, batch: &RecordBatch, metadata: &[(&str, String)]) -> Result<()> {
    let tmp = stage_parquet(path, batch, metadata)?;
    tmp.persist(path)
        .map_err(|e| Error::output_io(path, e.error))?;
    Ok(())
}

/// `batch` written as zstd Parquet with key-value metadata (and `farma_version`) to a
/// temporary file in `path`'s folder, for a rename to `path`.
fn stage_parquet(
    path: &Path,
    batch: &RecordBatch,
    metadata: &[(&str, String)],
) -> Result<tempfile::TempPath> {
    stage_parquet_batches(path, batch.schema(), [Ok(batch.clone())], metadata)
}

/// [`stage_parquet`] for a table given batch by batch (each of `schema`): the writer
/// holds one row group at a time, never the whole table.
fn stage_parquet_batches(
    path: &Path,
    schema: arrow_schema::SchemaRef,
    batches: impl IntoIterator<Item = Result<RecordBatch>>,
    metadata: &[(&str, String)],
) -> Result<tempfile::TempPath> {
    let tmp = temp_beside(path)?;
    let mut kv: Vec<KeyValue> = metadata
        .iter()
        .map(|(k, v)| KeyValue::new(k.to_string(), v.clone()))
        .collect();
    kv.push(KeyValue::new(
        "farma_version".into(),
        env!("CARGO_PKG_VERSION").to_string(),
    ));
    let props = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::default()))
        .set_key_value_metadata(Some(kv))
        .build();
    let file = tmp.reopen().map_err(|e| Error::output_io(path, e))?;
    let mut w = ArrowWriter::try_new(file, schema, Some(props))
        .map_err(|e| Error::output_io(path, std::io::Error::other(e)))?;
    for batch in batches {
        w.write(&batch?)
            .map_err(|e| Error::output_io(path, std::io::Error::other(e)))?;
    }
    w.close()
        .map_err(|e| Error::output_io(path, std::io::Error::other(e)))?;
    Ok(tmp.into_temp_path())
}

/// The lock file of an output folder ([`lock_dir`]).
pub const LOCK_FILE: &str = ".farma.lock";
/// The commit journal of an output folder ([`OutputSet::commit`]).
pub const JOURNAL_FILE: &str = ".farma-commit.json";

/// Output folders this process holds the lock of, with how many guards hold each.
static HELD: std::sync::Mutex<Vec<(PathBuf, usize)>> = std::sync::Mutex::new(Vec::new());

/// This process's lock on an output folder; released (the lock file removed) when the
/// last guard of the folder is dropped.
#[derive(Debug)]
pub struct DirLock {
    key: PathBuf,
    file: PathBuf,
}

impl Drop for DirLock {
    fn drop(&mut self) {
        let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(i) = held.iter().position(|(k, _)| *k == self.key) {
            held[i].1 -= 1;
            if held[i].1 == 0 {
                held.remove(i);
                let _ = std::fs::remove_file(&self.file);
            }
        }
    }
}

/// Takes the lock of output folder `dir` (which exists) for this process: the file
/// `.farma.lock` created exclusively in it, holding `HOST PID`. A folder locked by
/// another live process is refused (a usage error, exit 2, naming the lock and its
/// holder): two runs never write one folder at once. A lock left by a killed run (this
/// machine, a process that no longer exists) is taken over with a note. Locks nest
/// within a process (`analyze` holds its folder for the whole run and commits sets in
/// it). Then completes a commit that a killed run left half done ([`settle`]).
pub fn lock_dir(dir: &Path) -> Result<DirLock> {
    let key = dir.canonicalize().map_err(|e| Error::output_io(dir, e))?;
    let file = key.join(LOCK_FILE);
    {
        let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(h) = held.iter_mut().find(|(k, _)| *k == key) {
            h.1 += 1;
            return Ok(DirLock { key, file });
        }
    }
    let me = std::process::id();
    let host = host_name().unwrap_or_else(|| "unknown".into());
    let mut tries = 0;
    loop {
        use std::io::Write;
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&file)
        {
            Ok(mut f) => {
                f.write_all(format!("{host} {me}\n").as_bytes())
                    .map_err(|e| Error::output_io(&file, e))?;
                break;
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && tries < 3 => {
                tries += 1;
                let text = std::fs::read_to_string(&file).unwrap_or_default();
                let mut words = text.split_whitespace();
                let (h, pid) = (
                    words.next(),
                    words.next().and_then(|p| p.parse::<u32>().ok()),
                );
                let stale = match (h, pid) {
                    (Some(h), Some(pid)) => {
                        h == host
                            && Path::new("/proc/self").exists()
                            && (pid == me || !Path::new("/proc").join(pid.to_string()).exists())
                    }
                    // written but not yet filled by its taker, or not ours: not stale
                    _ => false,
                };
                if stale {
                    eprintln!(
                        "farma: note: {}: lock of a run that is gone (process {} on {host}) taken over",
                        file.display(),
                        pid.unwrap_or(0)
                    );
                    let _ = std::fs::remove_file(&file);
                    continue;
                }
                if h.is_none() && tries < 3 {
                    // its taker has not written it yet
                    std::thread::sleep(std::time::Duration::from_millis(50));
                    continue;
                }
                return Err(Error::Usage(format!(
                    "-o {}: another farma run is writing this folder (process {} on host {}, lock file {}); wait for it to end, or remove the lock file if that run is gone",
                    dir.display(),
                    pid.map_or_else(|| "?".to_string(), |p| p.to_string()),
                    h.unwrap_or("?"),
                    file.display()
                )));
            }
            Err(e) => return Err(Error::output_io(&file, e)),
        }
    }
    HELD.lock()
        .unwrap_or_else(|e| e.into_inner())
        .push((key.clone(), 1));
    let lock = DirLock { key, file };
    settle(dir)?;
    Ok(lock)
}

/// The commit journal: the renames (temporary name, final name) and removals of a set
/// being committed, names relative to the folder.
#[derive(serde::Serialize, serde::Deserialize)]
struct Journal {
    renames: Vec<(String, String)>,
    remove: Vec<String>,
}

/// Completes the commit of a set that a run killed while it committed left half done
/// in `dir`: when the journal `.farma-commit.json` is there, its renames not yet done
/// are done, its removals too, and the journal is removed (every step can be repeated,
/// so two processes settling one folder agree). Every reader of an output folder
/// (model folders, analyze's channel folders) and every writer (at [`lock_dir`])
/// calls it first, so none sees a folder holding files of two runs.
pub fn settle(dir: &Path) -> Result<()> {
    let jpath = dir.join(JOURNAL_FILE);
    let text = match std::fs::read_to_string(&jpath) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::input_io(&jpath, e)),
    };
    let j: Journal = serde_json::from_str(&text).map_err(|e| {
        Error::format(
            &jpath,
            format!("an output folder's commit journal that cannot be read ({e}); remove it and run again"),
        )
    })?;
    let unfinished = |e: std::io::Error| {
        Error::output_io(
            dir,
            std::io::Error::new(
                e.kind(),
                format!(
                    "cannot complete the commit of a run that was stopped while committing ({}): {e}",
                    jpath.display()
                ),
            ),
        )
    };
    let safe = |n: &str| !n.is_empty() && !n.contains('/') && n != "." && n != "..";
    if !j.renames.iter().all(|(a, b)| safe(a) && safe(b)) || !j.remove.iter().all(|n| safe(n)) {
        return Err(Error::format(
            &jpath,
            "a commit journal naming files outside its folder",
        ));
    }
    let mut done = 0usize;
    for (from, to) in &j.renames {
        match std::fs::rename(dir.join(from), dir.join(to)) {
            Ok(()) => done += 1,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(unfinished(e)),
        }
    }
    for name in &j.remove {
        match std::fs::remove_file(dir.join(name)) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(unfinished(e)),
        }
    }
    match std::fs::remove_file(&jpath) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(unfinished(e)),
    }
    eprintln!(
        "farma: note: {}: completed the commit of a run that was stopped while committing ({done} file(s) put in place)",
        dir.display()
    );
    Ok(())
}

/// The temporary files a commit journal in `dir` names (kept by the sweep of stale
/// temporary files: they are the set being committed).
fn journal_temps(dir: &Path) -> Vec<String> {
    std::fs::read_to_string(dir.join(JOURNAL_FILE))
        .ok()
        .and_then(|t| serde_json::from_str::<Journal>(&t).ok())
        .map(|j| j.renames.into_iter().map(|(a, _)| a).collect())
        .unwrap_or_default()
}

/// Debug builds only: `FARMA_TEST_KILL_AFTER_RENAMES=N` kills the process (SIGKILL)
/// once N renames of a commit are done (N = 0: right after the journal is written),
/// the test seam of an interrupted commit.
fn test_kill_point(renames_done: usize) {
    if !cfg!(debug_assertions) {
        return;
    }
    let Some(n) = std::env::var("FARMA_TEST_KILL_AFTER_RENAMES")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
    else {
        return;
    };
    if n == renames_done {
        let _ = std::process::Command::new("kill")
            .args(["-KILL", &std::process::id().to_string()])
            .status();
        std::thread::sleep(std::time::Duration::from_secs(5));
        std::process::exit(137);
    }
}

/// The files of one run, written together into one folder: each is first written
/// to a temporary file there, and only once every one is written are they renamed
/// into place ([`OutputSet::commit`]). A run that fails before leaves the folder as
/// it was (the temporary files are removed when the set is dropped); the files of
/// an earlier run that this one does not write are removed at the commit, so the
/// folder never holds files of two runs.
///
/// The set holds the folder's lock ([`lock_dir`]) from its creation to its drop, and
/// commits through a journal: once every file is staged, `.farma-commit.json` (the
/// renames and removals to do) is put in place by one rename, which is the commit
/// point; then the files are renamed and the journal removed. A run killed before
/// the journal leaves the earlier set (and temporary files that the next run sweeps);
/// one killed after it leaves the journal, which the next reader or writer of the
/// folder completes ([`settle`]): either set complete, never a mix.
pub struct OutputSet {
    dir: PathBuf,
    staged: Vec<(PathBuf, tempfile::TempPath)>,
    _lock: DirLock,
}

impl OutputSet {
    /// A set writing into `dir` (created with its parents). Fails (a usage error)
    /// when `dir` is a file.
    pub fn new(dir: &Path) -> Result<Self> {
        Self::check(dir)?;
        ensure_dir(dir)?;
        let lock = lock_dir(dir)?;
        Ok(OutputSet {
            dir: dir.to_path_buf(),
            staged: Vec::new(),
            _lock: lock,
        })
    }

    /// A usage error when `dir` exists and is not a folder, or when the nearest of
    /// its parents that exists is not a folder (`-o FILE/sub`, which would otherwise
    /// fail only when the outputs are written, after the work, exit 1): for a run to
    /// check before its work (nothing is created).
    pub fn check(dir: &Path) -> Result<()> {
        if dir.exists() && !dir.is_dir() {
            return Err(Error::Usage(format!(
                "-o {}: exists and is not a folder",
                dir.display()
            )));
        }
        let existing = dir
            .ancestors()
            .skip(1)
            .filter(|a| !a.as_os_str().is_empty())
            .find(|a| a.exists());
        if let Some(parent) = existing
            && !parent.is_dir()
        {
            return Err(Error::Usage(format!(
                "-o {}: {} exists and is not a folder",
                dir.display(),
                parent.display()
            )));
        }
        Ok(())
    }

    /// The path of file `name` in the set's folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Writes `batch` as Parquet file `name` of the set (see [`write_parquet`]), in
    /// place only at the commit.
    pub fn parquet(
        &mut self,
        name: &str,
        batch: &RecordBatch,
        metadata: &[(&str, String)],
    ) -> Result<()> {
        let path = self.path(name);
        let tmp = stage_parquet(&path, batch, metadata)?;
        self.staged.push((path, tmp));
        Ok(())
    }

    /// [`OutputSet::parquet`] for a table given batch by batch, all of `schema`: a
    /// long table (residuals of 1e8 samples) is written without being held whole.
    pub fn parquet_batches(
        &mut self,
        name: &str,
        schema: arrow_schema::SchemaRef,
        batches: impl IntoIterator<Item = Result<RecordBatch>>,
        metadata: &[(&str, String)],
    ) -> Result<()> {
        let path = self.path(name);
        let tmp = stage_parquet_batches(&path, schema, batches, metadata)?;
        self.staged.push((path, tmp));
        Ok(())
    }

    /// Stages file `name` of the set written by `write`, which is given the path of a
    /// temporary file in the set's folder to write (or rename onto); in place only at
    /// the commit.
    pub fn file(&mut self, name: &str, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
        let path = self.path(name);
        let tmp = temp_beside(&path)?.into_temp_path();
        write(&tmp)?;
        self.staged.push((path, tmp));
        Ok(())
    }

    /// Renames every file of the set into place, after checking that none of their
    /// names is taken by a folder, then removes those of `outputs` (the names this
    /// kind of run can write) that the set does not hold. Returns the removed paths.
    /// Atomic for readers through the journal (see [`OutputSet`]).
    pub fn commit(self, outputs: &[&str]) -> Result<Vec<PathBuf>> {
        for (path, _) in &self.staged {
            if path.is_dir() {
                return Err(Error::output_io(
                    path,
                    std::io::Error::other("a folder of this name is in the way"),
                ));
            }
        }
        let name_of = |p: &Path| -> Result<String> {
            p.file_name()
                .and_then(|n| n.to_str())
                .map(str::to_string)
                .ok_or_else(|| Error::Internal(format!("output name {}", p.display())))
        };
        let written: Vec<PathBuf> = self.staged.iter().map(|(p, _)| p.clone()).collect();
        let mut journal = Journal {
            renames: Vec::new(),
            remove: Vec::new(),
        };
        for (path, tmp) in &self.staged {
            journal.renames.push((name_of(tmp)?, name_of(path)?));
        }
        let mut removed = Vec::new();
        for name in outputs {
            let path = self.dir.join(name);
            if !written.contains(&path) && path.is_file() {
                journal.remove.push(name_of(&path)?);
                removed.push(path);
            }
        }
        let jpath = self.dir.join(JOURNAL_FILE);
        let text = serde_json::to_string(&journal)
            .map_err(|e| Error::Internal(format!("commit journal: {e}")))?;
        // the commit point: after this rename the set is committed (the next reader
        // completes it if this process stops here)
        write_text(&jpath, &text)?;
        let mut staged = Vec::new();
        for (path, tmp) in self.staged {
            // kept from here on: the journal names them
            let tmp = tmp.keep().map_err(|e| Error::output_io(&path, e.error))?;
            staged.push((path, tmp));
        }
        test_kill_point(0);
        for (k, (path, tmp)) in staged.iter().enumerate() {
            std::fs::rename(tmp, path).map_err(|e| Error::output_io(path, e))?;
            test_kill_point(k + 1);
        }
        for path in &removed {
            match std::fs::remove_file(path) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(Error::output_io(path, e)),
            }
        }
        std::fs::remove_file(&jpath).map_err(|e| Error::output_io(&jpath, e))?;
        Ok(removed)
    }
}

#[cfg(test)]
mod temp_name_tests {
    use super::stale_temp_pid;

    #[test]
    fn a_temporary_files_pid_is_read_only_for_this_host_and_pattern() {
        assert_eq!(
            stale_temp_pid(".farma-box1-4242-aB3xYz.tmp", "box1"),
            Some(4242)
        );
        assert_eq!(stale_temp_pid(".farma-box1-4242-aB3xYz.tmp", "box2"), None);
        // a host whose name is this one's with more after it
        assert_eq!(stale_temp_pid(".farma-box1x-4242-aB3xYz.tmp", "box1"), None);
        // the older pattern, and other files
        assert_eq!(stale_temp_pid(".farma-aB3xYz.tmp", "box1"), None);
        assert_eq!(
            stale_temp_pid(".farma-box1-4242-aB3xYz.parquet", "box1"),
            None
        );
        assert_eq!(stale_temp_pid("farma-box1-4242-aB3xYz.tmp", "box1"), None);
        assert_eq!(stale_temp_pid(".farma-box1-42x2-aB3xYz.tmp", "box1"), None);
        assert_eq!(stale_temp_pid(".farma-box1-4242-.tmp", "box1"), None);
        assert_eq!(stale_temp_pid(".farma-box1-4242-a-b.tmp", "box1"), None);
    }
}
