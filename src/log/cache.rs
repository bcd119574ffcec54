//! Where converted stores of CSV / Parquet / foreign Arrow logs are kept between runs.
//!
//! The file name is a 64-bit FNV-1a hash of the input's canonical path, size,
//! modification time, on Unix also its device, inode and status-change time (ctime),
//! the read options and the store format version, so an edited input or other options
//! give a new entry. Size and mtime alone miss an edit that keeps both (`cp -p`, `rsync
//! -t`, `touch -r` after an edit of the same length): such a copy writes into the file
//! (a new ctime, which no one can set back) or replaces it (a new inode). Entries are
//! written to a unique temporary file in the cache folder and renamed into place, so
//! concurrent jobs never read half a store and two that convert one log at the same
//! moment both end with a whole one. An entry used again is first checked against its
//! column checksums ([`crate::store::Store::verify`], in [`super::open_log`]); a damaged
//! one is converted again.
//!
//! The cache is kept under a size limit (`FARMA_CACHE_LIMIT_GB`, default
//! [`DEFAULT_LIMIT_GB`] GB): after each conversion the least recently used entries are
//! removed ([`prune`]; an entry's modification time is its last use, set when it is
//! reused). `farma cache list` and `farma cache prune` show and trim it.

use std::path::{Path, PathBuf};

use super::{CachePolicy, LogOptions, source_identity};
use crate::error::{Error, Result};
use crate::store::STORE_FORMAT_VERSION;

/// FNV-1a, 64 bit (Fowler, Noll, Vo): stable across platforms and Rust versions.
fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf29ce484222325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x100000001b3);
    }
    h
}

fn default_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("FARMA_CACHE_DIR") {
        return PathBuf::from(d);
    }
    if let Some(d) = std::env::var_os("XDG_CACHE_HOME") {
        return PathBuf::from(d).join("farma");
    }
    if let Some(h) = std::env::var_os("HOME") {
        return PathBuf::from(h).join(".cache").join("farma");
    }
    std::env::temp_dir().join("farma-cache")
}

/// What changes with every write to a file besides its size and mtime: on Unix its
/// device and inode (a file replaced by a rename) and its status-change time (a write
/// into it, or a changed mtime: the kernel sets ctime, no user can set it back).
#[cfg(unix)]
fn file_version(path: &Path) -> Result<String> {
    use std::os::unix::fs::MetadataExt;
    let md = std::fs::metadata(path).map_err(|e| Error::input_io(path, e))?;
    Ok(format!(
        "{}:{}:{}.{:09}",
        md.dev(),
        md.ino(),
        md.ctime(),
        md.ctime_nsec()
    ))
}

/// Elsewhere only size and modification time identify the version of a file.
#[cfg(not(unix))]
fn file_version(_path: &Path) -> Result<String> {
    Ok(String::new())
}

/// The cached store for `input` under `opts`, or `None` when caching is off.
pub(crate) fn store_path(
    input: &Path,
    opts: &LogOptions,
    policy: &CachePolicy,
) -> Result<Option<PathBuf>> {
    let Some(dir) = dir_of(policy) else {
        return Ok(None);
    };
    std::fs::create_dir_all(&dir).map_err(|e| Error::output_io(&dir, e))?;
    let canon = input
        .canonicalize()
        .map_err(|e| Error::input_io(input, e))?;
    let (size, mtime) = source_identity(input)?;
    let key = format!(
        "{}\0{size}\0{mtime}\0{}\0{opts:?}\0{STORE_FORMAT_VERSION}\0{}",
        canon.display(),
        file_version(input)?,
        env!("CARGO_PKG_VERSION")
    );
    let stem = input
        .file_stem()
        .map_or("log".into(), |s| s.to_string_lossy().into_owned());
    Ok(Some(dir.join(format!(
        "{stem}-{:016x}.arrow",
        fnv1a64(key.as_bytes())
    ))))
}

/// The cache's default size limit, GB (10^9 bytes): `FARMA_CACHE_LIMIT_GB` sets another.
pub const DEFAULT_LIMIT_GB: f64 = 20.0;

/// The cache folder of `policy` (`None` when caching is off).
pub fn dir_of(policy: &CachePolicy) -> Option<PathBuf> {
    match policy {
        CachePolicy::Off => None,
        CachePolicy::Dir(d) => Some(d.clone()),
        CachePolicy::Default => Some(default_dir()),
    }
}

/// The size limit, bytes: `FARMA_CACHE_LIMIT_GB` (a non-negative number of GB), else
/// [`DEFAULT_LIMIT_GB`]. A value that is not a number is an error naming the variable.
pub fn limit_bytes() -> Result<u64> {
    match std::env::var("FARMA_CACHE_LIMIT_GB") {
        Err(_) => Ok((DEFAULT_LIMIT_GB * 1e9) as u64),
        Ok(v) => match v.trim().parse::<f64>() {
            Ok(g) if g.is_finite() && g >= 0.0 => Ok((g * 1e9) as u64),
            _ => Err(Error::Usage(format!(
                "FARMA_CACHE_LIMIT_GB = '{v}' is not a non-negative number of GB"
            ))),
        },
    }
}

/// One cached store.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    pub path: PathBuf,
    pub bytes: u64,
    /// When it was last written or used (its modification time, which a reuse sets).
    pub last_used: std::time::SystemTime,
}

/// The cached stores in `dir` (files named `<stem>-<16 hex digits>.arrow`), least
/// recently used first.
pub fn entries(dir: &Path) -> Result<Vec<Entry>> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for e in rd.filter_map(|e| e.ok()) {
        let path = e.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let Some(stem) = name.strip_suffix(".arrow") else {
            continue;
        };
        let is_entry = stem.len() > 17
            && stem.as_bytes()[stem.len() - 17] == b'-'
            && stem[stem.len() - 16..]
                .bytes()
                .all(|b| b.is_ascii_hexdigit());
        if !is_entry {
            continue;
        }
        let Ok(md) = e.metadata() else { continue };
        if !md.is_file() {
            continue;
        }
        out.push(Entry {
            path,
            bytes: md.len(),
            last_used: md.modified().unwrap_or(std::time::UNIX_EPOCH),
        });
    }
    out.sort_by(|a, b| a.last_used.cmp(&b.last_used).then(a.path.cmp(&b.path)));
    Ok(out)
}

/// Marks `entry` as used now (its modification time), for [`prune`]'s order.
pub(crate) fn touch(entry: &Path) {
    if let Ok(f) = std::fs::File::options().append(true).open(entry) {
        let _ = f.set_modified(std::time::SystemTime::now());
    }
}

/// Removes the least recently used entries of `dir` until the others hold at most
/// `max_bytes`, never `keep` (the entry in use); returns the removed ones. A store
/// removed while another process has it mapped stays readable by that process (Unix).
pub fn prune(dir: &Path, max_bytes: u64, keep: Option<&Path>) -> Result<Vec<Entry>> {
    let all = entries(dir)?;
    let mut total: u64 = all.iter().map(|e| e.bytes).sum();
    let mut removed = Vec::new();
    for e in all {
        if total <= max_bytes {
            break;
        }
        if keep.is_some_and(|k| k == e.path) {
            continue;
        }
        match std::fs::remove_file(&e.path) {
            Ok(()) => {
                total -= e.bytes;
                removed.push(e);
            }
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => total -= e.bytes,
            Err(err) => return Err(Error::output_io(&e.path, err)),
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    #[test]
    fn pruning_removes_the_least_recently_used_first() {
        use std::time::{Duration, SystemTime};
        let dir = tempfile::tempdir().unwrap();
        let mk = |name: &str, n: usize, age_s: u64| {
            let p = dir.path().join(name);
            std::fs::write(&p, vec![0u8; n]).unwrap();
            let f = std::fs::File::options().append(true).open(&p).unwrap();
            f.set_modified(SystemTime::now() - Duration::from_secs(age_s))
                .unwrap();
            p
        };
        let old = mk("a-0123456789abcdef.arrow", 100, 300);
        let mid = mk("b-0123456789abcdef.arrow", 100, 200);
        let new = mk("c-0123456789abcdef.arrow", 100, 100);
        let other = mk("notes.arrow", 1000, 1000);
        let e = super::entries(dir.path()).unwrap();
        assert_eq!(
            e.iter().map(|e| &e.path).collect::<Vec<_>>(),
            [&old, &mid, &new]
        );
        // keep the oldest (in use): the next oldest goes
        let r = super::prune(dir.path(), 200, Some(&old)).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].path, mid);
        assert!(old.exists() && new.exists() && other.exists() && !mid.exists());
        super::touch(&old);
        let r = super::prune(dir.path(), 100, None).unwrap();
        assert_eq!(r[0].path, new);
        assert!(old.exists());
    }

    #[test]
    fn fnv_known_values() {
        // Test vectors from the FNV reference (isthe.com/chongo/tech/comp/fnv).
        assert_eq!(super::fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(super::fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
    }
}
