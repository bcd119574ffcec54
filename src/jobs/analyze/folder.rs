//! The channel folders of `farma analyze`: each channel's tables are committed in
//! `OUT/channels/<channel>/` as soon as that channel is done, with a marker written
//! last; a rerun keeps a channel whose marker matches its log and options; at the end
//! the folder-level tables are the concatenation of the channels' tables.
//!
//! Commit of a channel: its old marker is removed first, then its files are staged
//! and renamed into place as one [`OutputSet`], then the marker is written
//! (atomically). A run stopped at any point (SIGINT, `kill -9`) leaves each channel
//! folder either with a marker and all its files of one run, or without a marker
//! (redone by the next run). No file is ever partial.

use std::path::{Path, PathBuf};

use arrow_array::{ArrayRef, RecordBatch};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use serde_json::json;

use crate::batch::units::Fingerprint;
use crate::error::{Error, Result};
use crate::output::{OutputSet, batch};

/// The folder of the channel folders under the output folder.
pub const CHANNELS_DIR: &str = "channels";
/// A channel folder's marker: the channel is done (JSON: channel, options hash, data
/// hash, log fingerprint, farma version; no time, so that two identical runs write
/// identical folders).
pub const MARKER: &str = "done.json";
/// A channel folder's summary text.
pub const SUMMARY: &str = "summary.txt";
/// A channel folder's `--json` line.
pub const JSON_LINE: &str = "channel.json";
/// A channel folder's report (its plots; the folder-level `report.html` takes in its
/// body).
pub const REPORT: &str = crate::report::REPORT;
/// The tables (file stems) each channel folder holds and the folder-level files
/// concatenate, in the order they are written.
pub const TABLES: &[&str] = &[
    "select",
    "ftests",
    "constancy",
    "coef",
    "params",
    "gcv",
    "acf",
    "ljung_box",
    "prediction",
    "poly",
    "verdict",
];

/// The files of a channel folder but the marker.
pub fn channel_files() -> Vec<String> {
    let mut v: Vec<String> = TABLES.iter().map(|t| format!("{t}.parquet")).collect();
    v.push(SUMMARY.into());
    v.push(JSON_LINE.into());
    v.push(REPORT.into());
    v
}

/// The folder name of a channel: the name itself when it is made of letters, digits,
/// `_`, `-` and `.` (not starting with `.`); otherwise those characters kept, the
/// others as `_`, and `-` with 8 hex digits of the name's hash appended (two names
/// never share a folder).
pub fn folder_name(channel: &str) -> String {
    let ok = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.';
    if !channel.is_empty() && !channel.starts_with('.') && channel.chars().all(ok) {
        return channel.to_string();
    }
    let clean: String = channel
        .chars()
        .map(|c| if ok(c) { c } else { '_' })
        .collect();
    format!(
        "{}-{:08x}",
        clean.trim_start_matches('.'),
        crate::batch::units::hash64(channel.as_bytes()) >> 32
    )
}

/// The folder of `channel` under the output folder `out`.
pub fn channel_dir(out: &Path, channel: &str) -> PathBuf {
    out.join(CHANNELS_DIR).join(folder_name(channel))
}

/// What a channel's marker records: the results are those of this channel, these
/// options, these prepared values and this log.
#[derive(Clone, Debug, PartialEq)]
pub struct Marker {
    pub channel: String,
    pub options_hash: String,
    /// xxHash64 of the prepared values the analysis ran on.
    pub data_hash: String,
    pub log: Fingerprint,
}

impl Marker {
    /// The marker's JSON: what [`Marker::read`] compares, no time (two identical runs
    /// write identical markers; the timings go to stderr).
    fn to_json(&self) -> String {
        json!({
            "channel": self.channel,
            "options_hash": self.options_hash,
            "data_hash": self.data_hash,
            "log_size": self.log.size,
            "log_mtime_ns": self.log.mtime_ns,
            "log_hash": self.log.head_tail_hash,
            "farma_version": env!("CARGO_PKG_VERSION"),
        })
        .to_string()
            + "\n"
    }

    fn read(path: &Path) -> Option<Marker> {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
        let s = |k: &str| v.get(k)?.as_str().map(str::to_string);
        Some(Marker {
            channel: s("channel")?,
            options_hash: s("options_hash")?,
            data_hash: s("data_hash")?,
            log: Fingerprint {
                size: v.get("log_size")?.as_u64()?,
                mtime_ns: v.get("log_mtime_ns")?.as_i64()?,
                head_tail_hash: s("log_hash")?,
            },
        })
    }

    /// Whether `dir` holds this channel's results: its marker equals this one and
    /// every file of the folder is there.
    pub fn matches(&self, dir: &Path) -> bool {
        // a commit stopped half way is completed first (a folder that cannot be
        // settled is redone)
        if crate::output::settle(dir).is_err() {
            return false;
        }
        Marker::read(&dir.join(MARKER)).is_some_and(|m| m == *self)
            && channel_files().iter().all(|f| dir.join(f).is_file())
    }
}

/// A channel's files, ready to commit.
pub struct ChannelFiles<'a> {
    pub tables: Vec<(&'static str, RecordBatch)>,
    pub summary: String,
    pub json_line: String,
    /// The channel's `report.html`.
    pub report: String,
    pub metadata: &'a [(&'a str, String)],
}

/// Commits a channel's files into `dir`: the old marker removed, the files renamed
/// into place as one set, the marker written last.
pub fn commit_channel(dir: &Path, files: ChannelFiles, marker: &Marker) -> Result<()> {
    let m = dir.join(MARKER);
    if m.exists() {
        std::fs::remove_file(&m).map_err(|e| Error::output_io(&m, e))?;
    }
    let mut set = OutputSet::new(dir)?;
    for (t, b) in &files.tables {
        set.parquet(&format!("{t}.parquet"), b, files.metadata)?;
    }
    set.file(SUMMARY, |p| crate::output::write_text(p, &files.summary))?;
    set.file(JSON_LINE, |p| {
        crate::output::write_text(p, &files.json_line)
    })?;
    set.file(REPORT, |p| crate::output::write_text(p, &files.report))?;
    let names = channel_files();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    super::super::commit_outputs(set, &names)?;
    crate::output::write_text(&m, &marker.to_json())
}

/// Reads the Parquet file at `path` as one batch.
fn read_table(path: &Path) -> Result<RecordBatch> {
    let f = std::fs::File::open(path).map_err(|e| Error::input_io(path, e))?;
    let bad = |e: String| Error::format(path, format!("a channel table that cannot be read: {e}"));
    let builder = ParquetRecordBatchReaderBuilder::try_new(f).map_err(|e| bad(e.to_string()))?;
    let schema = builder.schema().clone();
    let batches: Vec<RecordBatch> = builder
        .with_batch_size(1 << 16)
        .build()
        .map_err(|e| bad(e.to_string()))?
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| bad(e.to_string()))?;
    arrow_select::concat::concat_batches(&schema, &batches).map_err(|e| bad(e.to_string()))
}

/// Table `table` of every channel folder of `dirs`, in their order, as one table (the
/// columns of the first; nullable where any value is null, as [`batch`] builds them).
pub fn concat_table(dirs: &[PathBuf], table: &str) -> Result<RecordBatch> {
    let parts: Vec<RecordBatch> = dirs
        .iter()
        .map(|d| read_table(&d.join(format!("{table}.parquet"))))
        .collect::<Result<_>>()?;
    let first = parts
        .first()
        .ok_or_else(|| Error::Internal(format!("{table}: no channel to concatenate")))?;
    let schema = first.schema();
    let mut columns: Vec<(&str, ArrayRef)> = Vec::new();
    for (k, field) in schema.fields().iter().enumerate() {
        let arrays: Vec<&dyn arrow_array::Array> = parts
            .iter()
            .map(|p| {
                p.column_by_name(field.name())
                    .map(|c| c.as_ref())
                    .ok_or_else(|| {
                        Error::Internal(format!(
                            "{table}.parquet: a channel's table has no column '{}'",
                            field.name()
                        ))
                    })
            })
            .collect::<Result<_>>()?;
        let joined = arrow_select::concat::concat(&arrays)
            .map_err(|e| Error::Internal(format!("{table}.parquet: {e}")))?;
        debug_assert_eq!(schema.field(k).name(), field.name());
        columns.push((field.name().as_str(), joined));
    }
    batch(columns)
}

/// Reads a text file of a channel folder.
pub fn read_text(dir: &Path, name: &str) -> Result<String> {
    let p = dir.join(name);
    std::fs::read_to_string(&p).map_err(|e| Error::input_io(&p, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channel_folders_are_safe_names() {
        assert_eq!(folder_name("gyro_x_dps"), "gyro_x_dps");
        let odd = folder_name("rate x/dps");
        assert!(odd.starts_with("rate_x_dps-") && odd.len() == "rate_x_dps-".len() + 8);
        assert_ne!(folder_name("a/b"), folder_name("a b"));
        assert!(!folder_name("..").starts_with('.'));
        assert!(!folder_name(".hidden").starts_with('.'));
    }
}
