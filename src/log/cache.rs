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
    let dir = match policy {
        CachePolicy::Off => return Ok(None),
        CachePolicy::Dir(d) => d.clone(),
        CachePolicy::Default => default_dir(),
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

#[cfg(test)]
mod tests {
    #[test]
    fn fnv_known_values() {
        // Test vectors from the FNV reference (isthe.com/chongo/tech/comp/fnv).
        assert_eq!(super::fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(super::fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
    }
}
