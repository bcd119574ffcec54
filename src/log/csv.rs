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
//! blank lines anywhere; RFC 4180 double quotes around names and cells (fields are
//! split by the `csv-core` crate; a quoted field may not span lines); CRLF or LF;
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

/// Splits lines into fields: csv-core (RFC 4180 quoting) for a delimiter byte, runs of
/// blanks for whitespace.
struct Splitter {
    delim: Delimiter,
    rdr: csv_core::Reader,
    /// The current field, unquoted.
    buf: Vec<u8>,
}

/// What a field longer than [`Splitter`]'s buffer is reported as.
const OVERLONG: &[u8] = b"(a field longer than 256 bytes)";

impl Splitter {
    fn new(delim: Delimiter) -> Splitter {
        let d = match delim {
            Delimiter::Byte(d) => d,
            Delimiter::Whitespace => b' ',
        };
        Splitter {
            delim,
            rdr: csv_core::ReaderBuilder::new().delimiter(d).build(),
            buf: vec![0; 256],
        }
    }

    /// Calls `f(index, field)` for each field of `line` (no line terminator); returns
    /// the field count.
    #[inline]
    fn split(&mut self, line: &[u8], mut f: impl FnMut(usize, &[u8])) -> usize {
        if self.delim == Delimiter::Whitespace {
            let mut i = 0;
            for field in line
                .split(|b| *b == b' ' || *b == b'\t')
                .filter(|s| !s.is_empty())
            {
                f(i, field);
                i += 1;
            }
            return i;
        }
        if let Delimiter::Byte(d) = self.delim
            && memchr::memchr(b'"', line).is_none()
        {
            return split_unquoted(line, d, f);
        }
        self.split_csv_core(line, f)
    }

    /// The general path: csv-core's state machine.
    fn split_csv_core(&mut self, line: &[u8], mut f: impl FnMut(usize, &[u8])) -> usize {
        use csv_core::ReadFieldResult as R;
        let mut input = line;
        let (mut fed_newline, mut fed_eof, mut overlong) = (false, false, false);
        let (mut i, mut len) = (0, 0);
        loop {
            let (res, nin, nout) = self.rdr.read_field(input, &mut self.buf[len..]);
            input = &input[nin..];
            len += nout;
            match res {
                R::InputEmpty if !fed_newline => {
                    input = b"\n";
                    fed_newline = true;
                }
                // An open quote swallowed the newline: end the record at end of input.
                R::InputEmpty => fed_eof = true,
                R::OutputFull => {
                    overlong = true;
                    len = 0;
                }
                R::Field { record_end } => {
                    f(i, if overlong { OVERLONG } else { &self.buf[..len] });
                    i += 1;
                    len = 0;
                    overlong = false;
                    if record_end {
                        break;
                    }
                }
                R::End => break,
            }
        }
        if fed_eof {
            self.rdr.reset();
        }
        i
    }
}

/// The fast path for a line without quotes: fields are the bytes between delimiters,
/// exactly what csv-core yields for such a line (tested against it).
#[inline]
fn split_unquoted(line: &[u8], d: u8, mut f: impl FnMut(usize, &[u8])) -> usize {
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

/// Parses one cell: a decimal number, `inf`/`nan` in any case (via `fast-float2`, an
/// Eisel-Lemire parser; checked against `str::parse::<f64>` in the tests), or a missing
/// value (empty, `NA`, `null`) as NaN. `Err` for anything else.
#[inline]
fn parse_cell(cell: &[u8]) -> std::result::Result<f64, ()> {
    let c = unquote(cell);
    if c.is_empty() {
        return Ok(f64::NAN);
    }
    match fast_float2::parse::<f64, _>(c) {
        Ok(v) => Ok(v),
        Err(_) if c.eq_ignore_ascii_case(b"na") || c.eq_ignore_ascii_case(b"null") => Ok(f64::NAN),
        Err(_) => Err(()),
    }
}

/// Refuses text that is not UTF-8 or ASCII where that shows in the first bytes: UTF-16
/// or UTF-32 (with a byte-order mark, or ASCII text as UTF-16 without one: every other
/// byte NUL), or binary data (NUL bytes) before the end of the first lines. Such input
/// would otherwise show NUL bytes in column names or fail on a cell far from the cause.
fn check_text_encoding(path: &Path, text: &[u8]) -> Result<()> {
    let convert = "convert it to UTF-8 (e.g. iconv -f UTF-16 -t UTF-8)";
    let bom = if text.starts_with(b"\xFF\xFE\0\0") {
        Some("UTF-32LE")
    } else if text.starts_with(b"\0\0\xFE\xFF") {
        Some("UTF-32BE")
    } else if text.starts_with(b"\xFF\xFE") {
        Some("UTF-16LE")
    } else if text.starts_with(b"\xFE\xFF") {
        Some("UTF-16BE")
    } else {
        None
    };
    if let Some(enc) = bom {
        return Err(Error::format(
            path,
            format!("{enc} text (byte-order mark); farma reads UTF-8 text: {convert}"),
        ));
    }
    let sample = &text[..text.len().min(4096)];
    let Some(first_nul) = memchr::memchr(0, sample) else {
        return Ok(());
    };
    let (mut even, mut odd) = (0usize, 0usize);
    for (i, b) in sample.iter().enumerate() {
        if *b == 0 {
            if i % 2 == 0 {
                even += 1;
            } else {
                odd += 1;
            }
        }
    }
    // ASCII as UTF-16: the high byte of every code unit is 0
    let units = sample.len() / 2;
    let utf16 = if odd * 10 >= units * 8 && even * 10 < units {
        Some("UTF-16LE")
    } else if even * 10 >= units * 8 && odd * 10 < units {
        Some("UTF-16BE")
    } else {
        None
    };
    let line = 1 + memchr::memchr_iter(b'\n', &sample[..first_nul]).count();
    Err(match utf16 {
        Some(enc) => Error::format(
            path,
            format!(
                "looks like {enc} text without a byte-order mark (every other byte is NUL); farma reads UTF-8 text: {convert}"
            ),
        ),
        None => Error::Malformed {
            path: path.to_path_buf(),
            line: line as u64,
            msg: format!(
                "a NUL byte (at byte {}): binary data, not a text log",
                first_nul
            ),
        },
    })
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
            Splitter::new(delim).split(line, |_, f| match std::str::from_utf8(unquote(f)) {
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
            let mut seen = std::collections::HashSet::with_capacity(names.len());
            for (i, n) in names.iter().enumerate() {
                if n.is_empty() {
                    return Err(Error::column(
                        path,
                        format!("header (line {line_no}): column {} has no name", i + 1),
                    ));
                }
                if !seen.insert(n.as_str()) {
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
    check_text_encoding(path, text)?;

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
    // Hash sets, not `Vec::contains`: a header of 100k names is checked in linear time.
    let keep: Option<std::collections::HashSet<&str>> = match &opts.columns {
        None => None,
        Some(sel) => {
            let all: std::collections::HashSet<&str> = names.iter().map(String::as_str).collect();
            let mut k: std::collections::HashSet<&str> = time_col.into_iter().collect();
            for s in sel {
                if !all.contains(s.as_str()) {
                    return Err(Error::column(
                        path,
                        format!("no column '{s}'; columns are: {}", names.join(", ")),
                    ));
                }
                k.insert(s.as_str());
            }
            Some(k)
        }
    };
    // Store order follows the file's column order.
    let mut store_names: Vec<String> = Vec::new();
    let target = names
        .iter()
        .map(|n| {
            keep.as_ref()
                .is_none_or(|k| k.contains(n.as_str()))
                .then(|| {
                    store_names.push(n.clone());
                    store_names.len() - 1
                })
        })
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
    let mut splitter = Splitter::new(header.delim);
    let body = &text[c.start..c.end];
    let ends_file = c.end == text.len();
    for_each_line(body, |raw| {
        let l = strip_cr(raw);
        if is_skipped(l) {
            line += 1;
            return true;
        }
        let mut bad: Option<(usize, String)> = None;
        let count = splitter.split(l, |i, field| {
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
                    Err(()) => {
                        bad = Some((i, String::from_utf8_lossy(unquote(field)).into_owned()))
                    }
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
                text: field,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn fields_fast(line: &[u8], d: u8) -> Vec<Vec<u8>> {
        let mut v = Vec::new();
        split_unquoted(line, d, |_, f| v.push(f.to_vec()));
        v
    }

    fn fields_csv_core(line: &[u8], d: u8) -> Vec<Vec<u8>> {
        let mut v = Vec::new();
        Splitter::new(Delimiter::Byte(d)).split_csv_core(line, |_, f| v.push(f.to_vec()));
        v
    }

    #[test]
    fn fast_split_equals_csv_core_on_unquoted_lines() {
        let alphabet = b"0123456789.-+eE ,;\tabcNn";
        let mut state = 12345u64;
        for _ in 0..20_000 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let len = (state >> 58) as usize;
            let line: Vec<u8> = (0..len)
                .map(|k| {
                    let r = state.rotate_left(7 * k as u32 + 3);
                    alphabet[(r % alphabet.len() as u64) as usize]
                })
                .collect();
            if is_skipped(&line) {
                continue; // blank and comment lines never reach the splitter
            }
            for d in [b',', b';', b'\t'] {
                assert_eq!(
                    fields_fast(&line, d),
                    fields_csv_core(&line, d),
                    "{:?}",
                    String::from_utf8_lossy(&line)
                );
            }
        }
    }

    #[test]
    fn parse_cell_agrees_with_std_parse() {
        let mut state = 99u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut cases: Vec<String> = vec![
            "0".into(), "-0".into(), "1e308".into(), "1e309".into(), "-1e-320".into(), "4.9e-324".into(),
            "inf".into(), "-Infinity".into(), "NaN".into(), "+1.5".into(), ".5".into(), "5.".into(),
            "1_0".into(), "0x10".into(), "1e".into(), "--1".into(), "1.2.3".into(), "e5".into(),
            "179769313486231570000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000".into(),
        ];
        for _ in 0..200_000 {
            let bits = next();
            let x = f64::from_bits(bits);
            cases.push(format!("{x}"));
            cases.push(format!("{x:e}"));
            cases.push(format!(
                "{:.9e}",
                (next() as f64 / u64::MAX as f64 - 0.5) * 0.1
            ));
            cases.push(format!("{:.4}", next() % 100_000));
        }
        for c in &cases {
            let want = c.parse::<f64>().map_err(|_| ());
            let got = parse_cell(c.as_bytes());
            match (want, got) {
                (Ok(a), Ok(b)) => assert!(
                    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                    "{c}: {a} vs {b}"
                ),
                (Err(()), Err(())) => {}
                (w, g) => panic!("{c}: std {w:?}, parse_cell {g:?}"),
            }
        }
    }

    #[test]
    fn csv_core_path_unquotes_and_resets_after_an_open_quote() {
        let mut sp = Splitter::new(Delimiter::Byte(b','));
        let mut v = Vec::new();
        sp.split(b"\"a,b\",\"x\"\"y\",3", |_, f| v.push(f.to_vec()));
        assert_eq!(v, vec![b"a,b".to_vec(), b"x\"y".to_vec(), b"3".to_vec()]);
        let mut w = Vec::new();
        assert_eq!(sp.split(b"\"open,1", |_, f| w.push(f.to_vec())), 1);
        let mut u = Vec::new();
        assert_eq!(
            sp.split(b"1,2", |_, f| u.push(f.to_vec())),
            2,
            "reader was reset"
        );
    }
}
