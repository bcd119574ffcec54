//! What a store knows about its log besides the values: time base, segments, repairs.

use serde::{Deserialize, Serialize};

/// Schema-metadata key holding the JSON of [`StoreMeta`].
pub const META_KEY: &str = "farma.meta";
/// Schema-metadata key holding the sample rate in Hz (plain number, for any Arrow tool).
pub const RATE_KEY: &str = "sample_rate_hz";
/// Schema-metadata key holding the checksum of every column: a JSON object from column
/// name to the XXH64 hash (seed 0) of the column's values, its `8 * rows` little-endian
/// bytes without the padding, as 16 lowercase hex digits.
pub const CHECKSUM_KEY: &str = "farma.xxh64";
/// Version of the store layout and metadata; bumped when either changes (2: the
/// `nonfinite` list; 3: the per-column checksums under [`CHECKSUM_KEY`]).
pub const STORE_FORMAT_VERSION: u32 = 3;

/// A run of rows sampled uniformly at the store's rate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// First row of the segment.
    pub start: u64,
    /// Number of rows.
    pub len: u64,
    /// Time of the first row, seconds.
    pub t0_s: f64,
}

/// One change ingest made to the input's values or time base.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Repair {
    /// `nan_interpolated`, `gap_interpolated`, `gap_split`, `irregular_resampled`.
    pub kind: String,
    /// Channel affected, or `*` for all.
    pub channel: String,
    /// Number of values (or gaps) affected.
    pub count: u64,
    /// Human-readable detail (first positions, sizes).
    pub detail: String,
}

/// A channel that holds NaN, infinite or missing values, kept as they are: a cached
/// conversion under `--nan reject` checks only the columns a command uses, so a bad
/// column that is not used does not block the others; reading this one is an error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NonFiniteColumn {
    pub column: String,
    /// Number of non-finite or missing values.
    pub count: u64,
    /// The first positions in the source ("line 12, line 40").
    pub first: String,
}

/// Everything about a store that is not a channel value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StoreMeta {
    pub format_version: u32,
    pub farma_version: String,
    /// Sampling rate of the rows, Hz.
    pub sample_rate_hz: f64,
    /// Where the rate came from: `column:NAME`, `metadata` or `flag`.
    pub time_source: String,
    /// The time column kept in the store (not a channel), if the input had one.
    pub time_col: Option<String>,
    /// Uniformly sampled runs; one segment unless ingest split the log at gaps.
    pub segments: Vec<Segment>,
    /// Every repair ingest made.
    pub repairs: Vec<Repair>,
    /// The input file this store was made from.
    pub source: String,
    /// `csv`, `parquet` or `arrow`.
    pub source_format: String,
    /// Size in bytes and modification time (ns since the epoch) of the source.
    pub source_size: u64,
    pub source_mtime_ns: u128,
    /// Channels whose non-finite values were left in place (see [`NonFiniteColumn`]);
    /// absent (empty) in stores written before format version 2.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub nonfinite: Vec<NonFiniteColumn>,
}
