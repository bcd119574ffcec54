//! Logs: reading a uniformly sampled multi-channel series from CSV, Parquet or Arrow IPC
//! into a [`Store`], with its time base, and the policies for bad
//! values and irregular sampling.
//!
//! [`ingest`] converts a file into a store; [`open_log`] gives any command a store for
//! any input, converting CSV / Parquet / foreign Arrow files through a cache so that a
//! user never has to ingest by hand. The input contract is section 1 of
//! `docs/contracts.md`.

pub mod cache;
mod columnar;
pub mod csv;
mod repair;
pub mod roles;
mod timebase;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressStyle};

pub(crate) use columnar::{check_ipc_bytes, no_panic};
pub use csv::Delimiter;

use crate::error::{Error, Result};
use crate::store::{
    NonFiniteColumn, Repair, STORE_FORMAT_VERSION, Segment, Store, StoreMeta, StoreWriter,
};

/// Names recognised as the time column (seconds) when `--time-col` is not given.
pub const TIME_COLUMN_NAMES: [&str; 4] = ["time", "time_s", "t", "timestamp"];

/// What to do with NaN, infinite or missing values in a channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NanPolicy {
    /// Fail with exit code 2, naming the column, the count and the first positions.
    #[default]
    Reject,
    /// Replace each by linear interpolation between its finite neighbours (in time).
    Interpolate,
}

/// What to do when the time column shows gaps or irregular sampling.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum GapPolicy {
    /// Fail with exit code 2, listing the first irregular intervals.
    #[default]
    Reject,
    /// Keep the samples; record uniformly sampled segments between the irregular intervals.
    Split,
    /// Resample every channel onto a uniform grid by linear interpolation.
    Interpolate,
}

/// How to read a log: time base, format details, policies.
#[derive(Clone, Debug, PartialEq)]
pub struct LogOptions {
    /// Name of the time column (seconds); default: one of [`TIME_COLUMN_NAMES`].
    pub time_col: Option<String>,
    /// Sample rate in Hz, used when there is no time column and no rate metadata.
    pub rate_hz: Option<f64>,
    /// CSV separator; default: detected from the header.
    pub delimiter: Option<Delimiter>,
    pub nan_policy: NanPolicy,
    pub gap_policy: GapPolicy,
    /// Relative tolerance on the sampling interval: an interval is regular when
    /// `|dt - dt_nominal| <= time_tol * dt_nominal`.
    pub time_tol: f64,
    /// Keep only these columns (plus the time column); default: all.
    pub columns: Option<Vec<String>>,
}

impl Default for LogOptions {
    fn default() -> Self {
        LogOptions {
            time_col: None,
            rate_hz: None,
            delimiter: None,
            nan_policy: NanPolicy::Reject,
            gap_policy: GapPolicy::Reject,
            time_tol: 0.05,
            columns: None,
        }
    }
}

impl LogOptions {
    fn validate(&self) -> Result<()> {
        if let Some(r) = self.rate_hz
            && !(r.is_finite() && r > 0.0)
        {
            return Err(Error::Usage(format!(
                "--rate: {r} is not a positive number of Hz"
            )));
        }
        if !(self.time_tol.is_finite() && self.time_tol > 0.0 && self.time_tol < 0.5) {
            return Err(Error::Usage(format!(
                "--time-tol: {} must lie in (0, 0.5)",
                self.time_tol
            )));
        }
        Ok(())
    }
}

/// Progress on stderr: bars when stderr is a terminal, plain timestamped lines
/// ([`Progress::line`]) when it is not (a log file, a scheduler's output), nothing
/// when quiet.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    enabled: bool,
    plain: bool,
}

impl Progress {
    /// Bars when stderr is a terminal, plain lines when it is not; neither when
    /// `quiet`.
    pub fn auto(quiet: bool) -> Self {
        let terminal = std::io::stderr().is_terminal();
        Progress {
            enabled: !quiet && terminal,
            plain: !quiet && !terminal,
        }
    }

    /// No bars and no lines.
    pub fn hidden() -> Self {
        Progress {
            enabled: false,
            plain: false,
        }
    }

    /// Whether bars are drawn (stderr a terminal, not quiet): otherwise a long job
    /// prints plain lines.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// Whether plain progress lines are printed (stderr not a terminal, not quiet).
    pub fn plain(&self) -> bool {
        self.plain
    }

    /// A plain progress line of command `cmd` on stderr when [`Progress::plain`]:
    /// `2026-11-27T07:30:01Z analyze gyro_x_dps: started`.
    pub fn line(&self, cmd: &str, msg: &str) {
        if self.plain {
            progress_line(cmd, msg);
        }
    }

    pub(crate) fn bar(&self, msg: &'static str, len: u64) -> ProgressBar {
        self.styled(
            msg,
            len,
            "{msg:>14} [{bar:30}] {percent:>3}% {elapsed_precise} eta {eta}",
        )
    }

    /// A bar that counts `len` items (channels fitted, say) under the label `msg`:
    /// "3/6", with the time since it started; hidden unless bars are on.
    pub(crate) fn count_bar(&self, msg: &'static str, len: u64) -> ProgressBar {
        let pb = self.styled(
            msg,
            len,
            "{msg:>14} [{bar:30}] {pos}/{len} {elapsed_precise}",
        );
        pb.tick();
        pb
    }

    /// A bar of `len` steps drawn by `template`; hidden unless bars are on.
    fn styled(&self, msg: &'static str, len: u64, template: &str) -> ProgressBar {
        if !self.enabled {
            return ProgressBar::hidden();
        }
        let pb = ProgressBar::new(len);
        pb.set_style(
            ProgressStyle::with_template(template)
                .expect("valid template")
                .progress_chars("=> "),
        );
        pb.set_message(msg);
        pb
    }
}

/// Prints `STAMP CMD MSG` on stderr, STAMP the UTC time ([`utc_stamp`]): the one form
/// of the plain progress lines of `farma analyze` and `farma batch`.
pub fn progress_line(cmd: &str, msg: &str) {
    eprintln!("{} {cmd} {msg}", utc_stamp(std::time::SystemTime::now()));
}

/// `t` as an ISO 8601 UTC time to the second: `2026-11-27T07:30:01Z`.
pub fn utc_stamp(t: std::time::SystemTime) -> String {
    let s = t
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, sod) = (s.div_euclid(86_400), s.rem_euclid(86_400));
    // civil date from days since 1970-01-01 (H. Hinnant's days_from_civil inverse)
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        sod / 3600,
        (sod / 60) % 60,
        sod % 60
    )
}

/// Count and first positions (rows) of non-finite values in one column.
#[derive(Clone, Debug, Default)]
pub(crate) struct NonFinite {
    pub count: u64,
    pub first_rows: Vec<u64>,
}

impl NonFinite {
    const KEEP: usize = 5;

    pub fn add(&mut self, row: u64) {
        self.count += 1;
        if self.first_rows.len() < Self::KEEP {
            self.first_rows.push(row);
        }
    }

    /// Adds `other`, whose rows all come after ours.
    pub fn merge(&mut self, other: NonFinite) {
        self.count += other.count;
        for r in other.first_rows {
            if self.first_rows.len() < Self::KEEP {
                self.first_rows.push(r);
            }
        }
    }
}

/// A store filled with the input's values, not yet checked or finished.
pub(crate) struct Parsed {
    pub writer: StoreWriter,
    pub format: &'static str,
    /// Name of the time column, if the input has one.
    pub time_col: Option<String>,
    /// `sample_rate_hz` from the file metadata.
    pub rate_meta_hz: Option<f64>,
    /// Non-finite values per store column.
    pub nonfinite: Vec<NonFinite>,
    /// Describes data row `r` (0-based) for messages: "line 17" or "row 3".
    pub locate: Box<dyn Fn(u64) -> String + Send + Sync>,
    pub path: PathBuf,
}

/// The time column among `names`: `--time-col`, else the first of [`TIME_COLUMN_NAMES`]
/// (case-insensitive).
pub(crate) fn find_time_column(
    path: &Path,
    names: &[String],
    opts: &LogOptions,
) -> Result<Option<String>> {
    if let Some(t) = &opts.time_col {
        return if names.contains(t) {
            Ok(Some(t.clone()))
        } else {
            Err(Error::column(
                path,
                format!(
                    "--time-col: no column '{t}'; columns are: {}",
                    names.join(", ")
                ),
            ))
        };
    }
    for cand in TIME_COLUMN_NAMES {
        if let Some(n) = names.iter().find(|n| n.eq_ignore_ascii_case(cand)) {
            return Ok(Some(n.clone()));
        }
    }
    Ok(None)
}

/// File formats farma reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Csv,
    Parquet,
    /// The Arrow IPC file format (Feather v2): `ARROW1` at both ends.
    Arrow,
    /// The Arrow IPC stream format: encapsulated messages from the first byte (the
    /// continuation marker `FF FF FF FF`), no footer.
    ArrowStream,
    /// Feather v1 (`FEA1`), the format before Arrow IPC files: refused with a message.
    FeatherV1,
}

/// Tells the format from the file's first bytes (`PAR1`, `ARROW1`, an Arrow stream's
/// continuation marker `FF FF FF FF`, `FEA1`), else CSV. Only regular files are read:
/// a FIFO, socket or device is refused (the sniffing would eat a FIFO's first bytes, and
/// the readers map or re-read the file).
pub fn detect_format(path: &Path) -> Result<Format> {
    use std::io::Read;
    // stat first: opening a FIFO for reading would block until a writer comes
    let md = std::fs::metadata(path).map_err(|e| Error::input_io(path, e))?;
    if md.is_dir() {
        return Err(Error::format(path, "is a directory, not a log file"));
    }
    if !md.is_file() {
        return Err(Error::format(
            path,
            format!(
                "not a regular file ({}); farma needs a file it can map or re-read: save the data to a file first",
                file_kind(&md)
            ),
        ));
    }
    let mut f = std::fs::File::open(path).map_err(|e| Error::input_io(path, e))?;
    let mut head = [0u8; 8];
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) => return Err(Error::input_io(path, e)),
        }
    }
    let head = &head[..n];
    Ok(if head.starts_with(b"PAR1") {
        Format::Parquet
    } else if head.starts_with(b"ARROW1") {
        Format::Arrow
    } else if head.starts_with(b"FEA1") {
        Format::FeatherV1
    } else if head.len() == 8
        && head.starts_with(&[0xff; 4])
        && i32::from_le_bytes(head[4..8].try_into().expect("4 bytes")) > 0
    {
        // a continuation marker and a positive metadata length: no text log starts so
        // (0xFF is not UTF-8)
        Format::ArrowStream
    } else {
        Format::Csv
    })
}

/// What kind of non-regular file `md` describes, for messages.
fn file_kind(md: &std::fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = md.file_type();
        if t.is_fifo() {
            return "a FIFO";
        } else if t.is_socket() {
            return "a socket";
        } else if t.is_char_device() {
            return "a character device";
        } else if t.is_block_device() {
            return "a block device";
        }
    }
    let _ = md;
    "not a plain file"
}

/// Converts `input` into a store at `output` (written to a temporary file, then
/// renamed). Returns the store's metadata. Under `--nan reject` a channel with
/// non-finite values is an error (the whole file is converted, for any reader).
pub fn ingest(
    input: &Path,
    output: &Path,
    opts: &LogOptions,
    progress: &Progress,
) -> Result<StoreMeta> {
    convert(input, output, opts, progress, NanCheck::Now)
}

/// When `--nan reject` checks a channel's values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum NanCheck {
    /// At conversion: any channel with non-finite values is an error (`farma ingest`).
    Now,
    /// When a command reads the channel ([`Store::column`]): the values stay, listed in
    /// the store's `nonfinite`, so a bad column that a command does not use does not
    /// block it (the cached conversions of [`open_log`]).
    OnRead,
}

fn convert(
    input: &Path,
    output: &Path,
    opts: &LogOptions,
    progress: &Progress,
    nan_check: NanCheck,
) -> Result<StoreMeta> {
    opts.validate()?;
    let parsed = match detect_format(input)? {
        Format::Csv => csv::read_csv(input, output, opts, progress)?,
        Format::Parquet => columnar::read_parquet(input, output, opts, progress)?,
        Format::Arrow => columnar::read_arrow(input, output, opts, progress)?,
        Format::ArrowStream => columnar::read_arrow_stream(input, output, opts, progress)?,
        Format::FeatherV1 => {
            return Err(Error::format(
                input,
                "a Feather v1 file (the format before Arrow IPC, deprecated since 2020): farma reads Feather v2 / Arrow IPC; convert it, e.g. in Python: pyarrow.feather.write_feather(pyarrow.feather.read_table(IN), OUT)",
            ));
        }
    };
    finalize(parsed, input, output, opts, nan_check)
}

/// Time base, NaN policy, gap policy, metadata; then renames the store into place.
fn finalize(
    parsed: Parsed,
    input: &Path,
    output: &Path,
    opts: &LogOptions,
    nan_check: NanCheck,
) -> Result<StoreMeta> {
    let Parsed {
        mut writer,
        format,
        time_col,
        rate_meta_hz,
        nonfinite,
        locate,
        path,
    } = parsed;
    let names = writer.names().to_vec();
    let n_rows = writer.n_rows();
    let time_idx = time_col
        .as_ref()
        .map(|t| names.iter().position(|n| n == t).expect("time column kept"));
    let mut repairs = Vec::new();
    let mut left_nonfinite = Vec::new();

    // Non-finite values: the time column never; channels by policy.
    if let Some(ti) = time_idx
        && nonfinite[ti].count > 0
    {
        let nf = &nonfinite[ti];
        return Err(Error::timestamps(
            &path,
            format!(
                "time column '{}' has {} missing or non-finite value(s), first at {}",
                names[ti],
                nf.count,
                nf.first_rows
                    .iter()
                    .map(|r| locate(*r))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    for (ci, nf) in nonfinite.iter().enumerate() {
        if Some(ci) == time_idx || nf.count == 0 {
            continue;
        }
        let first = nf
            .first_rows
            .iter()
            .map(|r| locate(*r))
            .collect::<Vec<_>>()
            .join(", ");
        match opts.nan_policy {
            NanPolicy::Reject if nan_check == NanCheck::OnRead => {
                left_nonfinite.push(NonFiniteColumn {
                    column: names[ci].clone(),
                    count: nf.count,
                    first,
                });
            }
            NanPolicy::Reject => {
                return Err(Error::NonFinite {
                    path: path.clone(),
                    column: names[ci].clone(),
                    count: nf.count,
                    first,
                    hint: "use --nan interpolate to replace them, or --columns to convert only the columns you need".into(),
                });
            }
            NanPolicy::Interpolate => {
                if nf.count as usize == n_rows {
                    return Err(Error::column(
                        &path,
                        format!(
                            "column '{}' has no finite value to interpolate from",
                            names[ci]
                        ),
                    ));
                }
                repairs.push(Repair {
                    kind: "nan_interpolated".into(),
                    channel: names[ci].clone(),
                    count: nf.count,
                    detail: format!("first at {first}"),
                });
            }
        }
    }
    if opts.nan_policy == NanPolicy::Interpolate
        && repairs.iter().any(|r| r.kind == "nan_interpolated")
    {
        let mut cols = writer.columns_mut();
        let times: Option<&[f64]> = time_idx.map(|ti| &*std::mem::take(&mut cols[ti]));
        for (ci, col) in cols.iter_mut().enumerate() {
            if Some(ci) != time_idx && nonfinite[ci].count > 0 {
                repair::interpolate_nonfinite(col, times);
            }
        }
    }

    // Time base.
    let mut segments = vec![];
    let (rate_hz, time_source) = if let Some(ti) = time_idx
        && n_rows < 2
    {
        // one row has no sample interval: the rate from the file's metadata or
        // --rate (as without a time column), the time of the row from the column
        let rate = rate_meta_hz
            .map(|r| (r, "metadata"))
            .or(opts.rate_hz.map(|r| (r, "flag")));
        match rate {
            Some((r, source)) if n_rows == 1 => {
                segments.push(Segment {
                    start: 0,
                    len: 1,
                    t0_s: writer.column(ti)[0],
                });
                (r, source.to_string())
            }
            _ => {
                return Err(Error::TooShort {
                    what: format!(
                        "{}: sample interval from time column '{}' (a single row has none: give the rate with --rate HZ)",
                        path.display(),
                        names[ti]
                    ),
                    need: 2,
                    have: n_rows as u64,
                });
            }
        }
    } else if let Some(ti) = time_idx {
        let t = writer.column(ti);
        let t0_s = t[0];
        let check = timebase::check_times(t, opts.time_tol)
            .map_err(|p| p.into_error(&path, &names[ti], &*locate))?;
        if let Some(flag) = opts.rate_hz {
            let from_time = 1.0 / check.dt_s;
            if (flag - from_time).abs() > 0.01 * from_time {
                eprintln!(
                    "farma: warning: --rate {flag} Hz disagrees with the time column '{}' ({from_time:.6} Hz); using the time column",
                    names[ti]
                );
            }
        }
        if check.irregular_count == 0 {
            segments.push(Segment {
                start: 0,
                len: n_rows as u64,
                t0_s,
            });
            (check.rate_hz_regular(t), format!("column:{}", names[ti]))
        } else {
            let summary = check.describe(&*locate);
            match opts.gap_policy {
                GapPolicy::Reject => {
                    return Err(Error::timestamps(
                        &path,
                        format!(
                            "irregular sampling in time column '{}': {summary}; use --gaps split or --gaps interpolate (or widen --time-tol)",
                            names[ti]
                        ),
                    ));
                }
                GapPolicy::Split => {
                    segments = check.segments(t).map_err(|m| Error::timestamps(&path, m))?;
                    repairs.push(Repair {
                        kind: "gap_split".into(),
                        channel: "*".into(),
                        count: check.irregular_count,
                        detail: format!("{} segments; {summary}", segments.len()),
                    });
                    (1.0 / check.dt_s, format!("column:{}", names[ti]))
                }
                GapPolicy::Interpolate => {
                    let resampled = repair::resample_uniform(&mut writer, output, ti, check.dt_s)?;
                    repairs.push(Repair {
                        kind: "gap_interpolated".into(),
                        channel: "*".into(),
                        count: check.irregular_count,
                        detail: format!(
                            "{n_rows} rows resampled to {} at {} Hz; {summary}",
                            resampled.n_rows(),
                            1.0 / check.dt_s
                        ),
                    });
                    segments.push(Segment {
                        start: 0,
                        len: resampled.n_rows() as u64,
                        t0_s,
                    });
                    writer = resampled;
                    (1.0 / check.dt_s, format!("column:{}", names[ti]))
                }
            }
        }
    } else if let Some(r) = rate_meta_hz {
        if let Some(flag) = opts.rate_hz
            && (flag - r).abs() > 1e-9 * r
        {
            eprintln!(
                "farma: warning: --rate {flag} Hz ignored: the file metadata says sample_rate_hz = {r}"
            );
        }
        segments.push(Segment {
            start: 0,
            len: n_rows as u64,
            t0_s: 0.0,
        });
        (r, "metadata".to_string())
    } else if let Some(r) = opts.rate_hz {
        segments.push(Segment {
            start: 0,
            len: n_rows as u64,
            t0_s: 0.0,
        });
        (r, "flag".to_string())
    } else {
        return Err(Error::NoTimeBase { path });
    };

    let (source_size, source_mtime_ns) = source_identity(input)?;
    let meta = StoreMeta {
        format_version: STORE_FORMAT_VERSION,
        farma_version: env!("CARGO_PKG_VERSION").to_string(),
        sample_rate_hz: rate_hz,
        time_source,
        time_col,
        segments,
        repairs,
        source: input.display().to_string(),
        source_format: format.to_string(),
        source_size,
        source_mtime_ns,
        nonfinite: left_nonfinite,
    };
    writer.finish(&meta)?;
    Ok(meta)
}

/// Size and modification time (ns) of a file: its identity for caches and metadata.
pub(crate) fn source_identity(path: &Path) -> Result<(u64, u128)> {
    let md = std::fs::metadata(path).map_err(|e| Error::input_io(path, e))?;
    let mtime = md
        .modified()
        .ok()
        .and_then(|m| m.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    Ok((md.len(), mtime))
}

/// Where [`open_log`] keeps converted stores.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CachePolicy {
    /// `$FARMA_CACHE_DIR`, else `$XDG_CACHE_HOME/farma`, else `~/.cache/farma`.
    Default,
    /// A given folder.
    Dir(PathBuf),
    /// Convert into a temporary store, deleted when the store is dropped.
    Off,
}

/// Opens any log as a store: a farma store directly (not verified: see
/// [`Store::verify`]); anything else through the cache, whose entry is verified against
/// its checksums when it is reused and converted again, with a note on stderr, when it
/// is damaged, truncated, unreadable or has none.
pub fn open_log(
    path: &Path,
    opts: &LogOptions,
    cache: &CachePolicy,
    progress: &Progress,
) -> Result<Store> {
    opts.validate()?;
    if detect_format(path)? == Format::Arrow {
        match Store::open(path) {
            Ok(s) => return Ok(s),
            Err(Error::Format { .. }) => {} // a foreign Arrow file: convert it
            Err(e) => return Err(e),
        }
    }
    match cache::store_path(path, opts, cache)? {
        Some(cached) => {
            let damaged = if cached.exists() {
                match Store::open(&cached).and_then(|s| s.verify().map(|()| s)) {
                    Ok(s) => {
                        cache::touch(&cached);
                        return Ok(s.with_label(path));
                    }
                    Err(e) => Some(e),
                }
            } else {
                None
            };
            let limit = cache::limit_bytes()?;
            convert(path, &cached, opts, progress, NanCheck::OnRead)?;
            if let Some(dir) = cached.parent() {
                for e in cache::prune(dir, limit, Some(&cached))? {
                    eprintln!(
                        "farma: note: removed the least recently used cached store {} ({:.1} MB) to keep the cache under {:.1} GB (FARMA_CACHE_LIMIT_GB)",
                        e.path.display(),
                        e.bytes as f64 / 1e6,
                        limit as f64 / 1e9
                    );
                }
            }
            if let Some(e) = damaged {
                eprintln!(
                    "farma: note: the cached conversion of {} was damaged or unreadable ({e}); reconverted",
                    path.display()
                );
            }
            Ok(Store::open(&cached)?.with_label(path))
        }
        None => {
            // Named like every output temporary (`.farma-HOST-PID-XXXXXX.tmp`) straight in
            // the temporary folder, so a killed run's store is swept by the next run there
            // (`output::sweep_stale_temps`); the name is reserved by an empty file that the
            // conversion's rename replaces, and removed when `tmp` drops.
            let dir = std::env::temp_dir();
            let tmp = crate::output::temp_in(&dir, &dir)?.into_temp_path();
            convert(path, &tmp, opts, progress, NanCheck::OnRead)?;
            // The map keeps the data alive after the file is removed.
            let store = Store::open(&tmp)?.with_label(path);
            drop(tmp);
            Ok(store)
        }
    }
}

#[cfg(test)]
mod stamp_tests {
    use super::utc_stamp;
    use std::time::{Duration, UNIX_EPOCH};

    #[test]
    fn utc_stamps_are_iso_8601() {
        let at = |s: u64| utc_stamp(UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "1970-01-01T00:00:00Z");
        // 2026-11-27T07:30:01Z
        assert_eq!(at(1_795_764_601), "2026-11-27T07:30:01Z");
        // a leap day
        assert_eq!(at(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(at(4_107_542_399), "2100-02-28T23:59:59Z");
    }
}
