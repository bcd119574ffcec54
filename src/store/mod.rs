//! The store: a log as one uncompressed Arrow IPC file that every command memory-maps.
//!
//! Layout (written by [`StoreWriter`], read by [`Store`]): the Arrow IPC *file* format
//! with exactly one record batch, every column `Float64` without nulls, each column's
//! values one contiguous, 64-byte aligned run of little-endian `f64`. Opening a store
//! maps the file and decodes the footer and the batch's metadata only, so a channel is
//! a `&[f64]` that borrows the map: constant-time open, no copy, pages read on touch.
//!
//! The file's schema metadata carries `sample_rate_hz` (readable by any Arrow tool) and
//! `farma.meta`, the JSON of [`StoreMeta`]: time base, segments, what ingest repaired
//! and where the data came from; and [`CHECKSUM_KEY`] (`farma.xxh64`), a checksum of
//! every column: a JSON object from column name to the XXH64 hash (seed 0) of the
//! column's values (its `8 * rows` bytes, without padding), 16 lowercase hex digits.
//! [`Store::verify`] checks them; opening a store does not.

mod meta;
mod reader;
mod writer;

pub use meta::{
    CHECKSUM_KEY, META_KEY, NonFiniteColumn, RATE_KEY, Repair, STORE_FORMAT_VERSION, Segment,
    StoreMeta,
};
pub use reader::Store;
pub use writer::{StoreWriter, output_permissions};
