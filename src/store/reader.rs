//! Opens a store without reading it: maps the file, decodes footer and batch metadata,
//! and hands out channels as `&[f64]` borrowed from the map; checks the columns against
//! their recorded checksums on request ([`Store::verify`]).

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{Array, Float64Array, RecordBatch};
use arrow_buffer::Buffer;
use arrow_schema::DataType;
use memmap2::Mmap;
use rayon::prelude::*;

use super::meta::{CHECKSUM_KEY, META_KEY, NonFiniteColumn, StoreMeta};
use super::writer::column_checksum;
use crate::error::{Error, Result};

/// A memory-mapped store. Cheap to open; channel slices borrow the map.
pub struct Store {
    path: PathBuf,
    /// The file the user named (the log a cached store came from); used in messages.
    label: PathBuf,
    batch: RecordBatch,
    meta: StoreMeta,
    /// The checksum recorded for each column (see [`CHECKSUM_KEY`]), in file order;
    /// None for a store written before format version 3.
    checksums: Option<Vec<u64>>,
    /// The map the columns borrow (for [`Store::release`]).
    map: Arc<Mmap>,
    /// Column name to its index: a lookup per channel in constant time (a log of 100k
    /// columns would otherwise scan the schema once per name).
    index: std::collections::HashMap<String, usize>,
}

impl std::fmt::Debug for Store {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Store")
            .field("path", &self.path)
            .field("rows", &self.batch.num_rows())
            .field("meta", &self.meta)
            .finish()
    }
}

impl Store {
    /// Opens a store written by [`super::StoreWriter`]. Fails with [`Error::Format`] for
    /// anything else (including Arrow IPC files of other layouts: convert those with
    /// `farma ingest`, or let [`crate::log::open_log`] do it).
    pub fn open(path: &Path) -> Result<Store> {
        let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
        // SAFETY: stores are written once to a temporary file and renamed into place;
        // nothing writes to a store after that. A user truncating the file while we read
        // it is outside what any mmap-based reader can guard against.
        let map = unsafe { Mmap::map(&file) }.map_err(|e| Error::input_io(path, e))?;
        let len = map.len();
        let bad = |m: &str| Error::format(path, format!("not a farma store: {m}"));
        if len < 6 + 10 || &map[..6] != b"ARROW1" || &map[len - 6..] != b"ARROW1" {
            return Err(bad("no Arrow IPC file magic at both ends (truncated?)"));
        }
        let mut tail = [0u8; 10];
        tail.copy_from_slice(&map[len - 10..]);
        let footer_len =
            arrow_ipc::reader::read_footer_length(tail).map_err(|e| bad(&e.to_string()))?;
        if footer_len + 10 > len {
            return Err(bad("footer length past the start of the file"));
        }
        let map = Arc::new(map);
        let footer_bytes = &map[len - 10 - footer_len..len - 10];
        let footer = arrow_ipc::root_as_footer(footer_bytes).map_err(|e| bad(&e.to_string()))?;
        let fb_schema = footer.schema().ok_or_else(|| bad("footer has no schema"))?;
        let schema =
            arrow_ipc::convert::try_fb_to_schema(fb_schema).map_err(|e| bad(&e.to_string()))?;
        let meta_json = schema
            .metadata()
            .get(META_KEY)
            .ok_or_else(|| bad("no farma.meta in the schema metadata"))?;
        let meta: StoreMeta =
            serde_json::from_str(meta_json).map_err(|e| bad(&format!("farma.meta: {e}")))?;
        if schema
            .fields()
            .iter()
            .any(|f| f.data_type() != &DataType::Float64)
        {
            return Err(bad("a column is not Float64"));
        }
        let checksums = match schema.metadata().get(CHECKSUM_KEY) {
            None => None,
            Some(json) => Some(parse_checksums(json, &schema).map_err(|m| bad(&m))?),
        };
        let blocks = footer
            .recordBatches()
            .ok_or_else(|| bad("no record batches"))?;
        if blocks.len() != 1 {
            return Err(bad(&format!("{} record batches, expected 1", blocks.len())));
        }
        let block = blocks.get(0);
        let version = footer.version();

        let ptr = std::ptr::NonNull::new(map.as_ptr() as *mut u8).expect("mmap is non-null");
        // SAFETY: `ptr` points to `len` initialised bytes owned by `map`, which the Buffer
        // keeps alive through its owner Arc.
        let buffer = unsafe { Buffer::from_custom_allocation(ptr, len, map.clone()) };
        let start = block.offset() as usize;
        let block_len = block.metaDataLength() as usize + block.bodyLength() as usize;
        if start.checked_add(block_len).is_none_or(|end| end > len) {
            return Err(bad("record batch block past the end of the file"));
        }
        // arrow-ipc's decoder trusts the buffers' stated offsets and lengths (a damaged
        // one panicked it: the store fuzz target): check the framing first, and decode
        // under no_panic as a net
        crate::log::check_ipc_bytes(&map, false).map_err(|m| bad(&format!("damaged: {m}")))?;
        let decoder = arrow_ipc::reader::FileDecoder::new(Arc::new(schema), version)
            .with_require_alignment(true);
        let batch = crate::log::no_panic(|| {
            decoder.read_record_batch(block, &buffer.slice_with_length(start, block_len))
        })
        .map_err(|()| bad("damaged: the Arrow decoder failed on its record batch"))?
        .map_err(|e| bad(&e.to_string()))?
        .ok_or_else(|| bad("empty record batch message"))?;
        for col in batch.columns() {
            if col.null_count() != 0 {
                return Err(bad("a column has nulls"));
            }
        }
        let index = batch
            .schema_ref()
            .fields()
            .iter()
            .enumerate()
            .map(|(i, f)| (f.name().clone(), i))
            .collect();
        Ok(Store {
            index,
            path: path.to_path_buf(),
            label: path.to_path_buf(),
            batch,
            meta,
            checksums,
            map,
        })
    }

    /// Checks every column's values against the checksum the writer recorded (XXH64
    /// under [`CHECKSUM_KEY`]), reading the whole file once, the columns in parallel.
    /// A column whose bytes changed is an [`Error::Column`] naming the store file and
    /// the column; a store without checksums (written before format version 3) is an
    /// [`Error::Format`]. Opening a store does not verify it; the cache of converted
    /// logs does, and so can any caller that must not compute on damaged data.
    pub fn verify(&self) -> Result<()> {
        let names: Vec<&str> = self.column_names();
        self.verify_columns(&names)
    }

    /// [`Store::verify`] for the named columns only (channels or the time column).
    pub fn verify_columns(&self, names: &[&str]) -> Result<()> {
        let Some(sums) = &self.checksums else {
            return Err(Error::format(
                &self.path,
                format!(
                    "no column checksums ({CHECKSUM_KEY}): written by a farma older than store format 3; convert the log again"
                ),
            ));
        };
        let idx: Vec<usize> = names
            .iter()
            .map(|name| {
                self.index.get(*name).copied().ok_or_else(|| {
                    Error::column(
                        &self.path,
                        format!(
                            "no column '{name}'; columns are: {}",
                            self.column_names().join(", ")
                        ),
                    )
                })
            })
            .collect::<Result<_>>()?;
        let bad: Vec<(usize, u64)> = idx
            .into_par_iter()
            .filter_map(|i| {
                let values = self
                    .batch
                    .column(i)
                    .as_any()
                    .downcast_ref::<Float64Array>()?;
                let got = column_checksum(values.values());
                self.release(values.values());
                (got != sums[i]).then_some((i, got))
            })
            .collect();
        let Some(&(i, got)) = bad.iter().min_by_key(|(i, _)| *i) else {
            return Ok(());
        };
        let others = match bad.len() {
            1 => String::new(),
            k => format!(" ({} more column(s) damaged too)", k - 1),
        };
        Err(Error::column(
            &self.path,
            format!(
                "column '{}': damaged: its values do not match the checksum the store records (xxh64 {:016x}, computed {got:016x}){others}; convert the log again",
                self.batch.schema_ref().field(i).name(),
                sums[i]
            ),
        ))
    }

    /// Drops this process's resident pages of `values`, a slice of this store's map
    /// (a column), with madvise(MADV_DONTNEED) over the whole pages it covers: the
    /// resident set no longer counts them once a column has been copied or checksummed.
    /// The map is read-only and backed by the file, so a later read faults the same
    /// bytes back in (from the page cache, or the file). A slice outside the map is
    /// left alone.
    pub fn release(&self, values: &[f64]) {
        const PAGE: usize = 4096;
        let base = self.map.as_ptr() as usize;
        let (lo, hi) = (
            values.as_ptr() as usize,
            values.as_ptr() as usize + std::mem::size_of_val(values),
        );
        if lo < base || hi > base + self.map.len() {
            return;
        }
        // whole pages inside the slice only: its neighbours' bytes stay resident
        let start = (lo - base).div_ceil(PAGE) * PAGE;
        let end = (hi - base) / PAGE * PAGE;
        if end > start {
            // SAFETY: MADV_DONTNEED discards a private or anonymous mapping's data; this
            // map is a read-only mapping of the store file, never written, so the pages
            // read back after it hold the file's bytes unchanged. Failure only leaves the
            // pages resident.
            let _ = unsafe {
                self.map.unchecked_advise_range(
                    memmap2::UncheckedAdvice::DontNeed,
                    start,
                    end - start,
                )
            };
        }
    }

    /// The file this store was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The log the user named (for a converted log, the original file).
    pub fn label(&self) -> &Path {
        &self.label
    }

    /// Names `label` as the log in messages (used when opened through the cache).
    pub fn with_label(mut self, label: &Path) -> Store {
        self.label = label.to_path_buf();
        self
    }

    /// Store metadata: time base, segments, repairs, source.
    pub fn meta(&self) -> &StoreMeta {
        &self.meta
    }

    /// Rows (samples per channel).
    pub fn n_samples(&self) -> usize {
        self.batch.num_rows()
    }

    /// Sample rate, Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        self.meta.sample_rate_hz
    }

    /// Duration covered by the samples, seconds: rows / rate (segments summed).
    pub fn duration_s(&self) -> f64 {
        self.n_samples() as f64 / self.meta.sample_rate_hz
    }

    /// Names of all columns in file order, the time column included.
    pub fn column_names(&self) -> Vec<&str> {
        self.batch
            .schema_ref()
            .fields()
            .iter()
            .map(|f| f.name().as_str())
            .collect()
    }

    /// Names of the channels (every column but the time column), in file order.
    pub fn channel_names(&self) -> Vec<&str> {
        let time = self.meta.time_col.as_deref();
        self.column_names()
            .into_iter()
            .filter(|n| Some(*n) != time)
            .collect()
    }

    /// The values of a column (channel or time column), borrowed from the map. A
    /// channel that holds non-finite values (left in place by a conversion under
    /// `--nan reject`, see [`super::NonFiniteColumn`]) is an [`Error::NonFinite`].
    pub fn column(&self, name: &str) -> Result<&[f64]> {
        if let Some(nf) = self.nonfinite(name) {
            return Err(Error::NonFinite {
                path: self.label.clone(),
                column: nf.column.clone(),
                count: nf.count,
                first: nf.first.clone(),
                hint: "use --nan interpolate to replace them".into(),
            });
        }
        self.column_with_nonfinite(name)
    }

    /// The non-finite or missing values a channel holds (left in place by a conversion
    /// under `--nan reject`), None for a channel without.
    pub fn nonfinite(&self, name: &str) -> Option<&NonFiniteColumn> {
        self.meta.nonfinite.iter().find(|c| c.column == name)
    }

    /// The values of a column as [`Store::column`], but a channel that holds
    /// non-finite values is returned with them (NaN for a missing value; see
    /// [`Store::nonfinite`]): for `farma info`, which describes such a channel instead
    /// of refusing it.
    pub fn column_with_nonfinite(&self, name: &str) -> Result<&[f64]> {
        let idx = self.index.get(name).copied().ok_or_else(|| {
            Error::column(
                &self.label,
                format!(
                    "no channel '{name}'; channels are: {}",
                    self.channel_names().join(", ")
                ),
            )
        })?;
        let arr = self
            .batch
            .column(idx)
            .as_any()
            .downcast_ref::<Float64Array>()
            .ok_or_else(|| Error::Internal(format!("column {name} is not Float64")))?;
        Ok(arr.values().as_ref())
    }

    /// Resolves a channel selection: `all`, or a comma-separated list of names. `all`
    /// with a channel that holds non-finite values (see [`Store::nonfinite`]) is an
    /// [`Error::NonFinite`] naming it and the channels without; a named one is refused
    /// when it is read ([`Store::column`]).
    pub fn select_channels(&self, selection: &str) -> Result<Vec<String>> {
        self.select(selection, true)
    }

    /// [`Store::select_channels`], but `all` keeps the channels that hold non-finite
    /// values (`farma info`, which describes them).
    pub fn select_channels_with_nonfinite(&self, selection: &str) -> Result<Vec<String>> {
        self.select(selection, false)
    }

    fn select(&self, selection: &str, refuse_nonfinite: bool) -> Result<Vec<String>> {
        let all = self.channel_names();
        if selection.trim() == "all" {
            if all.is_empty() {
                return Err(Error::column(
                    &self.label,
                    "--channel all: the log has no data channels (only a time column)",
                ));
            }
            // a channel with non-finite values is refused here, before any work,
            // naming the channels that could be taken instead
            let bad: Vec<&NonFiniteColumn> = all
                .iter()
                .filter(|_| refuse_nonfinite)
                .filter_map(|name| self.nonfinite(name))
                .collect();
            if let Some(first) = bad.first() {
                let good: Vec<&str> = all
                    .iter()
                    .copied()
                    .filter(|name| self.nonfinite(name).is_none())
                    .collect();
                let others = match bad.len() {
                    1 => String::new(),
                    k => format!(
                        " (and {} more: {})",
                        k - 1,
                        bad[1..]
                            .iter()
                            .map(|c| format!("'{}'", c.column))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                };
                let instead = if good.is_empty() {
                    "no channel of the log is without them".to_string()
                } else {
                    format!("--channel {} takes the others", good.join(","))
                };
                return Err(Error::NonFinite {
                    path: self.label.clone(),
                    column: first.column.clone(),
                    count: first.count,
                    first: first.first.clone(),
                    hint: format!(
                        "--channel all includes it{others}; {instead}, or --nan interpolate replaces them"
                    ),
                });
            }
            return Ok(all.iter().map(|s| s.to_string()).collect());
        }
        let mut out = Vec::new();
        for name in selection
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
        {
            if !all.contains(&name) {
                return Err(Error::column(
                    &self.label,
                    format!("no channel '{name}'; channels are: {}", all.join(", ")),
                ));
            }
            if !out.iter().any(|o| o == name) {
                out.push(name.to_string());
            }
        }
        if out.is_empty() {
            return Err(Error::Usage("--channel: no channel named".into()));
        }
        Ok(out)
    }
}

/// The checksums under [`CHECKSUM_KEY`], one per field of `schema` in its order.
fn parse_checksums(json: &str, schema: &arrow_schema::Schema) -> Result<Vec<u64>, String> {
    let map: std::collections::HashMap<String, String> =
        serde_json::from_str(json).map_err(|e| format!("{CHECKSUM_KEY}: {e}"))?;
    schema
        .fields()
        .iter()
        .map(|f| {
            let hex = map
                .get(f.name())
                .ok_or_else(|| format!("{CHECKSUM_KEY}: no checksum for column '{}'", f.name()))?;
            u64::from_str_radix(hex, 16).map_err(|_| {
                format!(
                    "{CHECKSUM_KEY}: column '{}': '{hex}' is not a hex checksum",
                    f.name()
                )
            })
        })
        .collect()
}
