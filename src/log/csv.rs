//! Parallel, streaming CSV reader: fills a store's columns straight from a memory map.
//!
//! Two passes over the mapped text, both split into newline-aligned chunks and run in
//! parallel: the first counts data rows per chunk (so every chunk knows the row it
//! starts at), the second parses each chunk into its own slice of every column of the
//! [`StoreWriter`]. Memory stays bounded whatever the file size: the input and the
//! output are both file-backed maps. Errors are reported for the earliest chunk, so
//! the message is the same whatever the thread count.
//!
//! Accepted text: a header row of names; comma, semicolon, tab or whitespace
//! separated (detected from the header, or `--delimiter`); `#` comment lines and
//! blank lines anywhere; optional double quotes around names and cells; CRLF or LF;
//! a UTF-8 byte-order mark. Empty cells and `NA`, `null`, `NaN` are missing values;
//! `inf` is infinite; both are handled by the NaN policy afterwards.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use memmap2::Mmap;
use rayon::prelude::*;

use super::{LogOptions, NonFinite, Parsed, Progress};
use crate::error::{Error, Result};
use crate::store::StoreWriter;

/// Field separator of a text log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delimiter {
    Byte(u8),
    /// One or more spaces or tabs.
    Whitespace,
}

impl Delimiter {
    /// Parses a `--delimiter` value: `,` `;` `tab` `\t` `space` `whitespace`.
    pub fn parse(s: &str) -> Result<Delimiter> {
        match s {
            "," | "comma" => Ok(Delimiter::Byte(b',')),
            ";" | "semicolon" => Ok(Delimiter::Byte(b';')),
            "\t" | "\\t" | "tab" => Ok(Delimiter::Byte(b'\t')),
            " " | "space" | "whitespace" => Ok(Delimiter::Whitespace),
            _ => Err(Error::Usage(format!(
                "--delimiter: '{s}' is not one of , ; tab whitespace"
            ))),
        }
    }

    fn detect(header: &[u8]) -> Delimiter {
        for b in [b',', b';', b'\t'] {
            if header.contains(&b) {
                return Delimiter::Byte(b);
            }
        }
        Delimiter::Whitespace
    }
}

/// Target chunk size for the parallel passes.
const CHUNK_BYTES: usize = 4 << 20;

/// A newline-aligned piece of the body.
#[derive(Clone, Debug)]
struct Chunk {
    start: usize,
    end: usize,
    /// Data rows in the chunk (pass 1).
    rows: usize,
    /// All lines in the chunk, including comments and blanks (pass 1).
    lines: usize,
    first_row: usize,
    first_line: u64,
}

fn is_skipped(line: &[u8]) -> bool {
    let t = line.trim_ascii_start();
    t.is_empty() || t[0] == b'#'
}

fn strip_cr(line: &[u8]) -> &[u8] {
    line.strip_suffix(b"\r").unwrap_or(line)
}

/// Calls `f(line)` for every line of `bytes` (without the newline).
fn for_each_line(bytes: &[u8], mut f: impl FnMut(&[u8]) -> bool) {
    let mut pos = 0;
    while pos < bytes.len() {
        let end = memchr::memchr(b'\n', &bytes[pos..]).map_or(bytes.len(), |i| pos + i);
        if !f(&bytes[pos..end]) {
            return;
        }
        pos = end + 1;
    }
}

fn unquote(cell: &[u8]) -> &[u8] {
    let c = cell.trim_ascii();
    if c.len() >= 2 && c[0] == b'"' && c[c.len() - 1] == b'"' {
        c[1..c.len() - 1].trim_ascii()
    } else {
        c
    }
}

/// Splits a line into fields, calling `f(index, field)`. Returns the field count.
#[inline]
fn split_fields<'a>(line: &'a [u8], delim: Delimiter, mut f: impl FnMut(usize, &'a [u8])) -> usize {
    match delim {
        Delimiter::Byte(d) => {
            let mut i = 0;
            let mut start = 0;
            for pos in memchr::memchr_iter(d, line) {
                f(i, &line[start..pos]);
                i += 1;
                start = pos + 1;
            }
            f(i, &line[start..]);
            i + 1
        }
        Delimiter::Whitespace => {
            let mut i = 0;
            for field in line
                .split(|b| *b == b' ' || *b == b'\t')
                .filter(|s| !s.is_empty())
            {
                f(i, field);
                i += 1;
            }
            i
        }
    }
}

/// Parses one cell. `Ok(None)` is a missing value.
#[inline]
fn parse_cell(cell: &[u8]) -> std::result::Result<f64, ()> {
    let c = unquote(cell);
    if c.is_empty() {
        return Ok(f64::NAN);
    }
    // Fast path: plain ASCII number.
    let s = std::str::from_utf8(c).map_err(|_| ())?;
    match s.parse::<f64>() {
        Ok(v) => Ok(v),
        Err(_) => {
            if s.eq_ignore_ascii_case("na") || s.eq_ignore_ascii_case("null") {
                Ok(f64::NAN)
            } else {
                Err(())
            }
        }
    }
}

/// The header: names, the line it is on (1-based), and where the body starts.
struct Header {
    names: Vec<String>,
    line: u64,
    body_start: usize,
    delim: Delimiter,
}

fn read_header(path: &Path, text: &[u8], opts: &LogOptions) -> Result<Header> {
    let mut pos = 0;
    let mut line_no = 0u64;
    while pos < text.len() {
        let end = memchr::memchr(b'\n', &text[pos..]).map_or(text.len(), |i| pos + i);
        line_no += 1;
        let line = strip_cr(&text[pos..end]);
        if !is_skipped(line) {
            let delim = opts.delimiter.unwrap_or_else(|| Delimiter::detect(line));
            let mut names = Vec::new();
            let mut bad_utf8 = false;
            split_fields(line, delim, |_, f| match std::str::from_utf8(unquote(f)) {
                Ok(s) => names.push(s.to_string()),
                Err(_) => bad_utf8 = true,
            });
            if bad_utf8 {
                return Err(Error::Malformed {
                    path: path.to_path_buf(),
                    line: line_no,
                    msg: "header is not valid UTF-8".into(),
                });
            }
            if names.iter().all(|n| n.parse::<f64>().is_ok()) {
                return Err(Error::Malformed {
                    path: path.to_path_buf(),
                    line: line_no,
                    msg: "expected a header row of column names, found numbers".into(),
                });
            }
            for (i, n) in names.iter().enumerate() {
                if n.is_empty() {
                    return Err(Error::column(
                        path,
                        format!("header (line {line_no}): column {} has no name", i + 1),
                    ));
                }
                if names[..i].contains(n) {
                    return Err(Error::column(
                        path,
                        format!("header (line {line_no}): column name '{n}' appears twice"),
                    ));
                }
            }
            return Ok(Header {
                names,
                line: line_no,
                body_start: (end + 1).min(text.len()),
                delim,
            });
        }
        pos = end + 1;
    }
    if text.trim_ascii().is_empty() {
        Err(Error::empty(path, "the file is empty"))
    } else {
        Err(Error::empty(
            path,
            "no header row: the file holds only comments",
        ))
    }
}

/// Splits `body` into newline-aligned chunks of about [`CHUNK_BYTES`].
fn make_chunks(text: &[u8], body_start: usize) -> Vec<Chunk> {
    let mut chunks = Vec::new();
    let mut start = body_start;
    while start < text.len() {
        let mut end = (start + CHUNK_BYTES).min(text.len());
        if end < text.len() {
            end = memchr::memchr(b'\n', &text[end..]).map_or(text.len(), |i| end + i + 1);
        }
        chunks.push(Chunk {
            start,
            end,
            rows: 0,
            lines: 0,
            first_row: 0,
            first_line: 0,
        });
        start = end;
    }
    chunks
}

/// Finds the 1-based line of data row `row`, rescanning its chunk (error paths only).
struct LineLocator {
    text: Arc<Mmap>,
    /// Length of the byte-order mark the chunk offsets do not count.
    bom: usize,
    chunks: Vec<Chunk>,
}

impl LineLocator {
    fn line_of_row(&self, row: u64) -> u64 {
        let row = row as usize;
        let ci = self
            .chunks
            .partition_point(|c| c.first_row + c.rows <= row)
            .min(self.chunks.len().saturating_sub(1));
        let c = &self.chunks[ci];
        let mut line = c.first_line;
        let mut r = c.first_row;
        let mut found = line;
        for_each_line(&self.text[self.bom + c.start..self.bom + c.end], |l| {
            if !is_skipped(strip_cr(l)) {
                if r == row {
                    found = line;
                    return false;
                }
                r += 1;
            }
            line += 1;
            true
        });
        found
    }
}

/// Which input column feeds which store column.
struct ColumnPlan {
    /// For each input field index, the store column it fills (None: not kept).
    target: Vec<Option<usize>>,
    /// Store column names, in store order.
    names: Vec<String>,
}

/// Reads a CSV log into a new store at `target` (not yet finished).
pub(crate) fn read_csv(
    path: &Path,
    target: &Path,
    opts: &LogOptions,
    progress: &Progress,
) -> Result<Parsed> {
    let file = File::open(path).map_err(|e| Error::input_io(path, e))?;
    let len = file.metadata().map_err(|e| Error::input_io(path, e))?.len();
    if len == 0 {
        return Err(Error::empty(path, "the file is empty (0 bytes)"));
    }
    // SAFETY: the input is only read; a concurrent writer could change what we parse,
    // as with any reader, but cannot make us read out of bounds of the map.
    let map = Arc::new(unsafe { Mmap::map(&file) }.map_err(|e| Error::input_io(path, e))?);
    let mut text: &[u8] = &map[..];
    let bom = if text.starts_with(b"\xEF\xBB\xBF") {
        3
    } else {
        0
    };
    text = &text[bom..];

    let header = read_header(path, text, opts)?;
    let time_col = super::find_time_column(path, &header.names, opts)?;
    let plan = plan_columns(path, &header.names, time_col.as_deref(), opts)?;

    let mut chunks = make_chunks(text, header.body_start);
    let pb = progress.bar("counting rows", (text.len() - header.body_start) as u64);
    chunks.par_iter_mut().for_each(|c| {
        let mut rows = 0;
        let mut lines = 0;
        for_each_line(&text[c.start..c.end], |l| {
            lines += 1;
            if !is_skipped(strip_cr(l)) {
                rows += 1;
            }
            true
        });
        c.rows = rows;
        c.lines = lines;
        pb.inc((c.end - c.start) as u64);
    });
    pb.finish_and_clear();
    let mut row = 0;
    let mut line = header.line + 1;
    for c in chunks.iter_mut() {
        c.first_row = row;
        c.first_line = line;
        row += c.rows;
        line += c.lines as u64;
    }
    let n_rows = row;
    if n_rows == 0 {
        return Err(Error::empty(
            path,
            format!("no data rows after the header (line {})", header.line),
        ));
    }

    let mut writer = StoreWriter::create(target, &plan.names, n_rows)?;
    let n_cols = plan.names.len();
    let n_fields = header.names.len();
    // Hand each chunk its own slice of every column.
    let mut per_chunk: Vec<Vec<&mut [f64]>> =
        chunks.iter().map(|_| Vec::with_capacity(n_cols)).collect();
    for mut col in writer.columns_mut() {
        for (ci, c) in chunks.iter().enumerate() {
            let (head, tail) = col.split_at_mut(c.rows);
            per_chunk[ci].push(head);
            col = tail;
        }
    }

    let pb = progress.bar("parsing", (text.len() - header.body_start) as u64);
    let results: Vec<Result<Vec<NonFinite>>> = chunks
        .par_iter()
        .zip(per_chunk.into_par_iter())
        .map(|(c, mut cols)| {
            let r = parse_chunk(path, text, c, &mut cols, &plan, &header, n_fields);
            pb.inc((c.end - c.start) as u64);
            r
        })
        .collect();
    pb.finish_and_clear();

    let mut nonfinite: Vec<NonFinite> = (0..n_cols).map(|_| NonFinite::default()).collect();
    for r in results {
        for (acc, nf) in nonfinite.iter_mut().zip(r?) {
            acc.merge(nf);
        }
    }
    let locator = LineLocator {
        text: map.clone(),
        bom,
        chunks,
    };
    let locate = Box::new(move |row: u64| format!("line {}", locator.line_of_row(row)));
    Ok(Parsed {
        writer,
        format: "csv",
        time_col,
        rate_meta_hz: None,
        nonfinite,
        locate,
        path: PathBuf::from(path),
    })
}

fn plan_columns(
    path: &Path,
    names: &[String],
    time_col: Option<&str>,
    opts: &LogOptions,
) -> Result<ColumnPlan> {
    let keep: Vec<String> = match &opts.columns {
        None => names.to_vec(),
        Some(sel) => {
            let mut k = Vec::new();
            if let Some(t) = time_col {
                k.push(t.to_string());
            }
            for s in sel {
                if !names.contains(s) {
                    return Err(Error::column(
                        path,
                        format!("no column '{s}'; columns are: {}", names.join(", ")),
                    ));
                }
                if !k.contains(s) {
                    k.push(s.clone());
                }
            }
            k
        }
    };
    // Store order follows the file's column order.
    let store_names: Vec<String> = names.iter().filter(|n| keep.contains(n)).cloned().collect();
    let target = names
        .iter()
        .map(|n| store_names.iter().position(|k| k == n))
        .collect();
    Ok(ColumnPlan {
        target,
        names: store_names,
    })
}

fn parse_chunk(
    path: &Path,
    text: &[u8],
    c: &Chunk,
    cols: &mut [&mut [f64]],
    plan: &ColumnPlan,
    header: &Header,
    n_fields: usize,
) -> Result<Vec<NonFinite>> {
    let mut nonfinite: Vec<NonFinite> = (0..cols.len()).map(|_| NonFinite::default()).collect();
    let mut row = 0usize;
    let mut line = c.first_line;
    let mut err: Option<Error> = None;
    let body = &text[c.start..c.end];
    let ends_file = c.end == text.len();
    for_each_line(body, |raw| {
        let l = strip_cr(raw);
        if is_skipped(l) {
            line += 1;
            return true;
        }
        let mut bad: Option<(usize, &[u8])> = None;
        let count = split_fields(l, header.delim, |i, field| {
            if bad.is_some() || i >= n_fields {
                return;
            }
            if let Some(col) = plan.target[i] {
                match parse_cell(field) {
                    Ok(v) => {
                        cols[col][row] = v;
                        if !v.is_finite() {
                            nonfinite[col].add((c.first_row + row) as u64);
                        }
                    }
                    Err(()) => bad = Some((i, field)),
                }
            }
        });
        if count != n_fields {
            let last = ends_file
                && !body.ends_with(b"\n")
                && std::ptr::eq(raw.as_ptr_range().end, body.as_ptr_range().end);
            let hint = if last && count < n_fields {
                ": the file ends mid-row (truncated?)"
            } else {
                ""
            };
            err = Some(Error::Malformed {
                path: path.to_path_buf(),
                line,
                msg: format!(
                    "{count} field(s), expected {n_fields} as in the header (line {}){hint}",
                    header.line
                ),
            });
            return false;
        }
        if let Some((i, field)) = bad {
            err = Some(Error::NonNumeric {
                path: path.to_path_buf(),
                line,
                column: header.names[i].clone(),
                text: String::from_utf8_lossy(unquote(field)).into_owned(),
            });
            return false;
        }
        row += 1;
        line += 1;
        true
    });
    match err {
        Some(e) => Err(e),
        None => Ok(nonfinite),
    }
}
