//! Writes a store: lays out the Arrow IPC file for a known row count, lets the caller
//! fill the columns in place through a writable memory map, then appends the footer
//! and renames the temporary file into place.
//!
//! Because the layout is fixed before any value is written, producers (the parallel
//! CSV parser, the Parquet reader) write straight into the final file in bounded
//! memory: the map is file-backed, so dirty pages go to disk instead of the heap.
//!
//! File layout (Arrow IPC file format, metadata version 5, alignment 64):
//! `ARROW1` + padding to 64 | schema message | record-batch message (metadata only)
//! | body: column 0 values, padded to 64, column 1, ... | end-of-stream marker
//! | footer (schema with full metadata, one record block) | footer length | `ARROW1`.
//! The footer is written last, so metadata that is known only after the values
//! (segments, repairs, the columns' checksums) goes there; readers of the file format
//! use the footer's schema.
//!
//! Checksums: [`StoreWriter::finish`] hashes each column's values (its `8 * rows`
//! bytes, not the padding) with XXH64, seed 0, in one pass over the map, the columns in
//! parallel, and records them under [`CHECKSUM_KEY`] as a JSON object from column name
//! to 16 lowercase hex digits; [`super::Store::verify`] checks them.

use std::collections::HashMap;
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use arrow_ipc::writer::{DictionaryTracker, IpcDataGenerator, IpcWriteOptions};
use arrow_schema::{DataType, Field, Schema};
use flatbuffers::FlatBufferBuilder;
use memmap2::MmapMut;
use rayon::prelude::*;

use super::meta::{CHECKSUM_KEY, META_KEY, RATE_KEY, StoreMeta};
use crate::error::{Error, Result};

const ALIGN: usize = 64;
const MAGIC: &[u8; 6] = b"ARROW1";
const CONTINUATION: [u8; 4] = [0xff; 4];

fn pad_to(len: usize) -> usize {
    len.div_ceil(ALIGN) * ALIGN
}

/// A store being written. Fill [`StoreWriter::columns_mut`], then call
/// [`StoreWriter::finish`]; dropping it without `finish` removes the temporary file.
pub struct StoreWriter {
    target: PathBuf,
    tmp: tempfile::NamedTempFile,
    map: MmapMut,
    names: Vec<String>,
    n_rows: usize,
    /// Byte offset of the record-batch message and its padded metadata length.
    batch_offset: usize,
    batch_meta_len: usize,
    body_offset: usize,
    col_stride: usize,
}

impl StoreWriter {
    /// Creates a temporary file beside `target` laid out for `names.len()` columns of
    /// `n_rows` rows each. Values start as zero.
    pub fn create(target: &Path, names: &[String], n_rows: usize) -> Result<Self> {
        Self::create_with(target, names, n_rows, reserve_space)
    }

    /// [`StoreWriter::create`] with `reserve(file, len)` to give the file its `len`
    /// bytes before it is mapped: the seam through which the tests inject a full disk.
    fn create_with(
        target: &Path,
        names: &[String],
        n_rows: usize,
        reserve: impl FnOnce(&std::fs::File, u64) -> std::io::Result<()>,
    ) -> Result<Self> {
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let tmp = crate::output::temp_in(&dir, target)?;
        let opts = IpcWriteOptions::default();
        let schema = schema_for(names, None);

        let mut head: Vec<u8> = Vec::new();
        head.extend_from_slice(MAGIC);
        head.resize(pad_to(MAGIC.len()), 0);
        let encoded = IpcDataGenerator::default().schema_to_bytes_with_dictionary_tracker(
            &schema,
            &mut DictionaryTracker::new(true),
            &opts,
        );
        write_framed(&mut head, &encoded.ipc_message);

        let col_stride = pad_to(n_rows * 8);
        let body_len = col_stride * names.len();
        let batch_offset = head.len();
        let batch_msg = record_batch_message(names.len(), n_rows, col_stride, body_len);
        write_framed(&mut head, &batch_msg);
        let batch_meta_len = head.len() - batch_offset;
        let body_offset = head.len();

        let file = tmp.as_file();
        let map_err = |e| Error::output_io(target, e);
        (&*file).write_all(&head).map_err(map_err)?;
        // The space is reserved before the map: a page of a map that the file system
        // cannot back is a SIGBUS when it is written, not an error we could report.
        let total = (body_offset + body_len) as u64;
        reserve(file, total).map_err(|e| no_space(target, &dir, total, e))?;
        // SAFETY: the file is ours (a fresh temporary file), nobody else maps or truncates it.
        let map = unsafe { MmapMut::map_mut(file) }.map_err(map_err)?;
        Ok(StoreWriter {
            target: target.to_path_buf(),
            tmp,
            map,
            names: names.to_vec(),
            n_rows,
            batch_offset,
            batch_meta_len,
            body_offset,
            col_stride,
        })
    }

    /// Number of rows of every column.
    pub fn n_rows(&self) -> usize {
        self.n_rows
    }

    /// Column names in file order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The columns' values, writable, in file order.
    pub fn columns_mut(&mut self) -> Vec<&mut [f64]> {
        let body = &mut self.map[self.body_offset..];
        let mut out = Vec::with_capacity(self.names.len());
        let mut rest: &mut [u8] = body;
        for _ in 0..self.names.len() {
            let (col, tail) = rest.split_at_mut(self.col_stride);
            rest = tail;
            let bytes = &mut col[..self.n_rows * 8];
            assert_eq!(bytes.as_ptr() as usize % std::mem::align_of::<f64>(), 0);
            // SAFETY: the map is page aligned and every column starts at a multiple of 64
            // bytes from it, so the pointer is aligned for f64 (asserted); every bit pattern
            // is a valid f64; the length is a whole number of f64s; the slice borrows the map.
            let values = unsafe {
                std::slice::from_raw_parts_mut(bytes.as_mut_ptr() as *mut f64, self.n_rows)
            };
            out.push(values);
        }
        out
    }

    /// Releases rows `rows` of every column from this process's memory: the pages
    /// already written stay in the file (and the page cache) but leave the process's
    /// resident set, so that a producer writing block by block (`farma simulate` of
    /// 1e8 samples) holds one block, not the file. Advice only: a failure is ignored.
    pub fn release_rows(&self, rows: std::ops::Range<usize>) {
        for i in 0..self.names.len() {
            let start = self.body_offset + i * self.col_stride + rows.start * 8;
            let len = (rows.end.min(self.n_rows) - rows.start.min(rows.end)) * 8;
            if len == 0 {
                continue;
            }
            // SAFETY: the map is a shared file mapping (MmapMut::map_mut), for which
            // MADV_DONTNEED drops the pages from this process only: dirty pages go to
            // the page cache and the file keeps every value (a private mapping would
            // lose them). No slice into the range is alive (`&self` excludes
            // `columns_mut`'s borrows).
            let _ = unsafe {
                self.map
                    .unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, start, len)
            };
        }
    }

    /// Column `i`'s values, as written so far.
    pub fn column(&self, i: usize) -> &[f64] {
        let start = self.body_offset + i * self.col_stride;
        let bytes = &self.map[start..start + self.n_rows * 8];
        assert_eq!(bytes.as_ptr() as usize % std::mem::align_of::<f64>(), 0);
        // SAFETY: as in `columns_mut`: aligned (asserted), any bits are an f64, borrows the map.
        unsafe { std::slice::from_raw_parts(bytes.as_ptr() as *const f64, self.n_rows) }
    }

    /// Writes the footer with `meta` and the columns' checksums, and renames the file
    /// onto the target.
    ///
    /// The data is not fsync'ed: a killed process loses nothing (the page cache holds
    /// it and the rename is atomic), only a machine crash could.
    pub fn finish(self, meta: &StoreMeta) -> Result<()> {
        // by pieces, each released after it is hashed: the resident set stays bounded
        // however long the columns are
        const PIECE: usize = 1 << 20;
        let checksums: Vec<u64> = (0..self.names.len())
            .into_par_iter()
            .map(|i| {
                let col = self.column(i);
                let mut h = twox_hash::XxHash64::with_seed(0);
                for (k, piece) in col.chunks(PIECE).enumerate() {
                    std::hash::Hasher::write(&mut h, as_bytes(piece));
                    let start = self.body_offset + i * self.col_stride + k * PIECE * 8;
                    // SAFETY: as in `release_rows`: a shared file mapping; the piece
                    // is read again from the page cache if needed.
                    let _ = unsafe {
                        self.map.unchecked_advise_range(
                            memmap2::UncheckedAdvice::DontNeed,
                            start,
                            piece.len() * 8,
                        )
                    };
                }
                std::hash::Hasher::finish(&h)
            })
            .collect();
        let StoreWriter {
            target,
            tmp,
            map,
            names,
            batch_offset,
            batch_meta_len,
            col_stride,
            ..
        } = self;
        let map_err = |e| Error::output_io(&target, e);
        map.flush_async().map_err(map_err)?;
        drop(map);

        let schema = schema_for(&names, Some((meta, &checksums)));
        let mut fbb = FlatBufferBuilder::new();
        let body_len = (col_stride * names.len()) as i64;
        let blocks = [arrow_ipc::Block::new(
            batch_offset as i64,
            batch_meta_len as i32,
            body_len,
        )];
        let record_batches = fbb.create_vector(&blocks);
        let dictionaries = fbb.create_vector::<arrow_ipc::Block>(&[]);
        let fb_schema =
            arrow_ipc::convert::IpcSchemaEncoder::new().schema_to_fb_offset(&mut fbb, &schema);
        let root = {
            let mut fb = arrow_ipc::FooterBuilder::new(&mut fbb);
            fb.add_version(arrow_ipc::MetadataVersion::V5);
            fb.add_schema(fb_schema);
            fb.add_dictionaries(dictionaries);
            fb.add_recordBatches(record_batches);
            fb.finish()
        };
        fbb.finish(root, None);
        let footer = fbb.finished_data();

        let mut file = tmp.as_file();
        file.seek(SeekFrom::End(0)).map_err(map_err)?;
        let mut tail = Vec::with_capacity(footer.len() + 32);
        tail.extend_from_slice(&CONTINUATION);
        tail.extend_from_slice(&0i32.to_le_bytes());
        tail.extend_from_slice(footer);
        tail.extend_from_slice(&(footer.len() as i32).to_le_bytes());
        tail.extend_from_slice(MAGIC);
        file.write_all(&tail).map_err(map_err)?;
        file.flush().map_err(map_err)?;
        tmp.persist(&target)
            .map_err(|e| Error::output_io(&target, e.error))?;
        Ok(())
    }
}

/// Gives `file` a length of `len` bytes with every block allocated
/// (`posix_fallocate`), so that writing through a map of it cannot fail. Where the file
/// system cannot allocate ahead (EOPNOTSUPP, EINVAL: some network or FUSE file systems),
/// the file is only extended (`set_len`), as before.
fn reserve_space(file: &std::fs::File, len: u64) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        let len_off = libc::off_t::try_from(len)
            .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "file too large"))?;
        // SAFETY: a valid open file descriptor; posix_fallocate touches nothing else.
        let rc = unsafe { libc::posix_fallocate(file.as_raw_fd(), 0, len_off) };
        match rc {
            0 => return Ok(()),
            libc::EOPNOTSUPP | libc::EINVAL | libc::ENOSYS => {}
            e => return Err(std::io::Error::from_raw_os_error(e)),
        }
    }
    file.set_len(len)
}

/// The error of a store whose `need` bytes could not be reserved in folder `dir`: the
/// cause, the bytes, the folder and what its file system has free.
fn no_space(target: &Path, dir: &Path, need: u64, e: std::io::Error) -> Error {
    let free = free_bytes(dir)
        .map(|f| format!(", which has {f} bytes ({}) free", human_bytes(f)))
        .unwrap_or_default();
    let dir = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    Error::output_io(
        target,
        std::io::Error::new(
            e.kind(),
            format!(
                "{e}: the store needs {need} bytes ({}) on the file system of {}{free}; free space there or write elsewhere (--cache-dir, --no-cache with TMPDIR, -o)",
                human_bytes(need),
                dir.display()
            ),
        ),
    )
}

/// `bytes` in kB, MB or GB with one decimal.
fn human_bytes(bytes: u64) -> String {
    let b = bytes as f64;
    if b < 1e6 {
        format!("{:.1} kB", b / 1e3)
    } else if b < 1e9 {
        format!("{:.1} MB", b / 1e6)
    } else {
        format!("{:.1} GB", b / 1e9)
    }
}

/// Bytes free to an unprivileged user on the file system holding `dir` (`statvfs`).
fn free_bytes(dir: &Path) -> Option<u64> {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
        // SAFETY: statvfs only writes the struct we hand it; `c` is NUL-terminated.
        let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
        if unsafe { libc::statvfs(c.as_ptr(), &mut st) } != 0 {
            return None;
        }
        #[allow(clippy::unnecessary_cast)] // the field types differ between targets
        Some(st.f_bavail as u64 * st.f_frsize as u64)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = dir;
        None
    }
}

/// Permissions of a finished output: readable by all (tempfile's default is 0600).
pub fn output_permissions() -> std::fs::Permissions {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::Permissions::from_mode(0o644)
    }
    #[cfg(not(unix))]
    {
        std::fs::metadata(".")
            .map(|m| m.permissions())
            .expect("cwd metadata")
    }
}

/// The XXH64 hash (seed 0) of a column's values as little-endian bytes: the checksum
/// recorded under [`CHECKSUM_KEY`].
pub(super) fn column_checksum(values: &[f64]) -> u64 {
    twox_hash::XxHash64::oneshot(0, as_bytes(values))
}

/// The bytes of `values`.
fn as_bytes(values: &[f64]) -> &[u8] {
    // SAFETY: any f64 is 8 initialised bytes; the byte slice borrows `values`. Stores
    // are little-endian (Arrow IPC), as are the machines farma runs on.
    unsafe {
        std::slice::from_raw_parts(values.as_ptr() as *const u8, std::mem::size_of_val(values))
    }
}

/// The JSON recorded under [`CHECKSUM_KEY`]: column name to 16 lowercase hex digits.
fn checksum_json(names: &[String], checksums: &[u64]) -> String {
    let map: serde_json::Map<String, serde_json::Value> = names
        .iter()
        .zip(checksums)
        .map(|(n, h)| (n.clone(), serde_json::Value::String(format!("{h:016x}"))))
        .collect();
    serde_json::Value::Object(map).to_string()
}

/// The store's schema: one non-nullable Float64 field per column, and, when given,
/// the metadata keys [`RATE_KEY`], [`META_KEY`] and [`CHECKSUM_KEY`].
fn schema_for(names: &[String], meta: Option<(&StoreMeta, &[u64])>) -> Schema {
    let fields: Vec<Field> = names
        .iter()
        .map(|n| Field::new(n, DataType::Float64, false))
        .collect();
    let mut md = HashMap::new();
    if let Some((meta, checksums)) = meta {
        md.insert(RATE_KEY.to_string(), format!("{}", meta.sample_rate_hz));
        md.insert(CHECKSUM_KEY.to_string(), checksum_json(names, checksums));
        md.insert(
            META_KEY.to_string(),
            serde_json::to_string(meta).expect("StoreMeta serializes"),
        );
    }
    Schema::new_with_metadata(fields, md)
}

/// Appends an encapsulated IPC message: continuation marker, padded metadata length,
/// the flatbuffer, zero padding so the whole frame is a multiple of 64 bytes.
fn write_framed(out: &mut Vec<u8>, message: &[u8]) {
    let framed = pad_to(message.len() + 8);
    let padded_meta = (framed - 8) as i32;
    out.extend_from_slice(&CONTINUATION);
    out.extend_from_slice(&padded_meta.to_le_bytes());
    out.extend_from_slice(message);
    out.resize(out.len() + framed - 8 - message.len(), 0);
}

/// The flatbuffer `Message` of a record batch of `n_cols` non-null Float64 columns,
/// each `n_rows` long, stored `col_stride` bytes apart in the body.
fn record_batch_message(
    n_cols: usize,
    n_rows: usize,
    col_stride: usize,
    body_len: usize,
) -> Vec<u8> {
    let mut fbb = FlatBufferBuilder::new();
    let nodes: Vec<arrow_ipc::FieldNode> = (0..n_cols)
        .map(|_| arrow_ipc::FieldNode::new(n_rows as i64, 0))
        .collect();
    let buffers: Vec<arrow_ipc::Buffer> = (0..n_cols)
        .flat_map(|i| {
            let off = (i * col_stride) as i64;
            [
                arrow_ipc::Buffer::new(off, 0),
                arrow_ipc::Buffer::new(off, (n_rows * 8) as i64),
            ]
        })
        .collect();
    let nodes = fbb.create_vector(&nodes);
    let buffers = fbb.create_vector(&buffers);
    let batch = {
        let mut b = arrow_ipc::RecordBatchBuilder::new(&mut fbb);
        b.add_length(n_rows as i64);
        b.add_nodes(nodes);
        b.add_buffers(buffers);
        b.finish()
    };
    let root = {
        let mut m = arrow_ipc::MessageBuilder::new(&mut fbb);
        m.add_version(arrow_ipc::MetadataVersion::V5);
        m.add_header_type(arrow_ipc::MessageHeader::RecordBatch);
        m.add_header(batch.as_union_value());
        m.add_bodyLength(body_len as i64);
        m.finish()
    };
    fbb.finish(root, None);
    fbb.finished_data().to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_store_that_cannot_get_its_space_is_exit_1_naming_the_bytes_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("s.arrow");
        let names = vec!["a".to_string(), "b".to_string()];
        let mut asked = 0;
        let r = StoreWriter::create_with(&target, &names, 1000, |_, len| {
            asked = len;
            Err(std::io::Error::from_raw_os_error(libc::ENOSPC))
        });
        let e = r.err().expect("the reservation failed");
        assert_eq!(e.exit_code(), crate::error::EXIT_FAILURE, "{e}");
        let msg = e.to_string();
        assert!(asked >= 2 * 8000, "{asked}");
        assert!(msg.contains(&format!("needs {asked} bytes")), "{msg}");
        assert!(msg.contains("No space left on device"), "{msg}");
        assert!(msg.contains("s.arrow"), "{msg}");
        assert!(
            msg.contains(") free") && msg.contains("file system of"),
            "{msg}"
        );
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert!(left.is_empty(), "left behind: {left:?}");
    }

    #[test]
    fn the_reserved_file_is_fully_allocated_before_the_map() {
        // posix_fallocate, not a sparse set_len: the blocks are there before a value
        // is written through the map.
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("s.arrow");
        let names = vec!["a".to_string()];
        let w = StoreWriter::create(&target, &names, 1 << 20).unwrap();
        let tmp = std::fs::read_dir(dir.path())
            .unwrap()
            .next()
            .unwrap()
            .unwrap();
        #[cfg(target_os = "linux")]
        {
            use std::os::fd::AsRawFd;
            use std::os::unix::fs::MetadataExt;
            let md = tmp.metadata().unwrap();
            assert!(md.len() >= 8 << 20);
            // file systems that cannot allocate ahead keep a sparse file (set_len)
            let probe = std::fs::File::create(dir.path().join("probe")).unwrap();
            // SAFETY: a valid descriptor.
            let rc = unsafe { libc::posix_fallocate(probe.as_raw_fd(), 0, 1 << 16) };
            if rc == 0 {
                assert!(md.blocks() * 512 >= md.len(), "{} blocks", md.blocks());
            } else {
                eprintln!("skipped: no posix_fallocate here ({rc})");
            }
        }
        drop(w);
    }
}
