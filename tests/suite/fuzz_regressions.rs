//! Inputs the fuzzer (examples/fuzz.rs, benches/fuzz.sh) found, kept in fixtures/fuzz/:
//! each must be refused with exit 2 and a message naming the file, never a panic
//! (exit 101) or an abort (134).
//!
//! Found in the first runs of the `arrow` target: arrow-ipc trusts the lengths a file
//! states, so a buffer stated past its message's body panicked in
//! `Buffer::slice_with_length` (`arrow_buffer_past_body_*.arrows`, mutated streams) and a
//! stated length past the end of the file or a huge uncompressed length aborted on the
//! allocation (`arrow_huge_uncompressed_length.arrow`: "memory allocation of
//! 5558009288175124480 bytes failed"). The framing of every message is now checked
//! before arrow-ipc decodes it (`check_ipc_framing` in src/log/columnar.rs).

use crate::common::{farma, fixture, stderr, stdout};

fn assert_refused(path: &std::path::Path, want: &str) {
    let dir = tempfile::tempdir().unwrap();
    let o = farma(
        &["info", path.to_str().unwrap(), "--rate", "10", "--no-cache"],
        dir.path(),
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{}: {e}", path.display());
    assert!(!e.contains("panicked"), "{e}");
    assert_eq!(e.lines().count(), 1, "one line, the error: {e}");
    assert!(
        e.contains(&*path.file_name().unwrap().to_string_lossy()),
        "{e}"
    );
    assert!(e.contains(want), "{want}: {e}");
    assert_eq!(stdout(&o), "");
}

#[test]
fn fuzzed_arrow_inputs_are_refused_not_panics_or_aborts() {
    for (name, want) in [
        (
            "arrow_buffer_past_body_1.arrows",
            "lies outside the 1216-byte body",
        ),
        (
            "arrow_buffer_past_body_2.arrows",
            "lies outside the 1216-byte body",
        ),
        ("arrow_huge_uncompressed_length.arrow", "runs past the end"),
    ] {
        assert_refused(&fixture(&format!("fuzz/{name}")), want);
    }
}

#[test]
fn fuzzed_parquet_inputs_that_panicked_the_decoder_are_refused_quietly() {
    // Panics inside the parquet crate on damaged pages and metadata (the parquet
    // target, 600 s, 6 panics of two kinds): now caught, exit 2, nothing of the panic
    // on stderr.
    for (name, want) in [
        (
            "parquet_vlq_panic.parquet",
            "the Parquet decoder failed on damaged data",
        ),
        (
            "parquet_negative_column_start.parquet",
            "the Parquet decoder failed on damaged",
        ),
    ] {
        assert_refused(&fixture(&format!("fuzz/{name}")), want);
    }
}

#[test]
fn a_compressed_buffer_stating_a_huge_uncompressed_length_is_refused_before_the_allocation() {
    // lz4.arrow's first values buffer (200 f64 of `time`) states 1600 uncompressed
    // bytes in its 8-byte prefix: say 2^62 instead
    let mut bytes = std::fs::read(fixture("foreign/lz4.arrow")).unwrap();
    let at = bytes
        .windows(8)
        .position(|w| w == 1600i64.to_le_bytes())
        .expect("the prefix of a 1600-byte buffer");
    bytes[at..at + 8].copy_from_slice(&(1i64 << 62).to_le_bytes());
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge.arrow");
    std::fs::write(&p, bytes).unwrap();
    assert_refused(
        &p,
        "states an uncompressed length of 4611686018427387904 bytes",
    );
}

#[test]
fn a_parquet_row_count_that_its_row_groups_do_not_add_up_to_is_refused_before_reserving() {
    // Found by the parquet target: a spliced footer stated ~1e9 rows, and the store's
    // space (8 bytes per row and column) was reserved for them before the first row
    // was read: gigabytes of a shared disk, or a failure for the wrong cause.
    // FileMetaData field 3, num_rows, in the Thrift compact protocol: the field header
    // 0x16 (delta 1, i64) after the schema list, then zigzag(4000) = 8000 as a varint
    let bytes = std::fs::read(fixture("multiaxis.parquet")).unwrap();
    let n = bytes.len();
    let footer_len = u32::from_le_bytes(bytes[n - 8..n - 4].try_into().unwrap()) as usize;
    let start = n - 8 - footer_len;
    let footer = &bytes[start..n - 8];
    let pat = [0x16u8, 0xC0, 0x3E];
    let at: Vec<usize> = footer
        .windows(3)
        .enumerate()
        .filter(|(_, w)| *w == pat)
        .map(|(i, _)| i)
        .collect();
    // the first is the file's (fields 1-3 come before the row groups, whose own
    // num_rows and whose chunks' num_values follow)
    assert!(!at.is_empty(), "num_rows not found");
    let mut varint = Vec::new();
    let mut z: u64 = 2 * 1_000_000_000; // zigzag(1e9)
    while z >= 0x80 {
        varint.push((z as u8) | 0x80);
        z >>= 7;
    }
    varint.push(z as u8);
    let mut new_footer = footer[..at[0] + 1].to_vec();
    new_footer.extend_from_slice(&varint);
    new_footer.extend_from_slice(&footer[at[0] + 3..]);
    let mut out = bytes[..start].to_vec();
    out.extend_from_slice(&new_footer);
    out.extend_from_slice(&(new_footer.len() as u32).to_le_bytes());
    out.extend_from_slice(b"PAR1");
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rows_lie.parquet");
    std::fs::write(&p, out).unwrap();
    assert_refused(
        &p,
        "damaged metadata: the file says 1000000000 rows, its row groups 4000",
    );
}

#[test]
fn a_store_whose_buffer_lies_past_its_body_is_refused_by_the_opener() {
    // The store target (600 s, 521,985 inputs): 1,649 panics of one kind, a buffer
    // stated past the record batch's body ('slice offset=128000
    // length=66709569480457472 selflen=160000' in arrow-buffer), through
    // Store::open's FileDecoder. The opener now checks the framing first.
    let p = fixture("fuzz/store_buffer_past_body.arrow");
    match farma::store::Store::open(&p) {
        Err(farma::Error::Format { msg, .. }) => {
            assert!(msg.contains("lies outside"), "{msg}")
        }
        other => panic!("{other:?}"),
    }
    assert_refused(&p, "lies outside");
}

#[test]
fn a_parquet_page_header_stating_a_huge_field_is_refused_without_reading_past_the_end() {
    // Found by the parquet target (600 s): a damaged page header whose Thrift fields
    // state huge lengths and counts. The decoder skips them, and read through `File`
    // each skip was a `read` call per 8 KiB, also past the end of the file: 38-60 s,
    // mostly in the kernel, before the exit 2. The file is now read from a memory map
    // (`map_bytes` in src/log/columnar.rs), about 1 s. The bound below is a guard
    // against that hang coming back (30 times the time now), not a speed claim.
    let started = std::time::Instant::now();
    assert_refused(
        &fixture("fuzz/parquet_huge_field_skip.parquet"),
        "cannot decode Parquet data",
    );
    let took = started.elapsed().as_secs_f64();
    assert!(took < 30.0, "took {took:.1} s");
}
