//! Inputs that are not what farma reads, named for what they are: a FIFO (was "the
//! file is empty (0 bytes)": the format sniffing ate its first bytes and the CSV reader
//! saw a length of 0), UTF-16 text with or without a byte-order mark (showed NUL bytes in
//! column names) and binary data in a text log.

use std::process::Command;

use crate::common::{farma, fixture, stderr};

#[test]
fn a_fifo_is_not_a_regular_file() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("log.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("skipped: no mkfifo");
        return;
    }
    // A writer that feeds the FIFO, so that an open for reading does not block (and the
    // old reader's failure shows); it is killed at the end.
    let mut feeder = Command::new("sh")
        .args([
            "-c",
            &format!(
                "cat {} > {} 2>/dev/null",
                fixture("multiaxis.csv").display(),
                fifo.display()
            ),
        ])
        .spawn()
        .unwrap();
    let o = farma(
        &["info", fifo.to_str().unwrap(), "--no-cache"],
        &dir.path().join("c"),
    );
    let _ = feeder.kill();
    let _ = feeder.wait();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("log.fifo"), "{e}");
    assert!(e.contains("not a regular file (a FIFO)"), "{e}");
    assert!(!e.contains("empty"), "{e}");
}

fn utf16(text: &str, big_endian: bool, bom: bool) -> Vec<u8> {
    let mut out = Vec::new();
    if bom {
        out.extend_from_slice(if big_endian {
            &[0xFE, 0xFF]
        } else {
            &[0xFF, 0xFE]
        });
    }
    for u in text.encode_utf16() {
        out.extend_from_slice(&if big_endian {
            u.to_be_bytes()
        } else {
            u.to_le_bytes()
        });
    }
    out
}

#[test]
fn utf16_text_is_named_with_or_without_a_byte_order_mark() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(fixture("multiaxis.csv")).unwrap();
    for (be, bom, want) in [
        (
            false,
            false,
            "looks like UTF-16LE text without a byte-order mark",
        ),
        (
            true,
            false,
            "looks like UTF-16BE text without a byte-order mark",
        ),
        (false, true, "UTF-16LE text (byte-order mark)"),
        (true, true, "UTF-16BE text (byte-order mark)"),
    ] {
        let p = dir.path().join(format!("u16_{be}_{bom}.csv"));
        std::fs::write(&p, utf16(&text, be, bom)).unwrap();
        let o = farma(&["info", p.to_str().unwrap(), "--no-cache"], dir.path());
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(
            e.contains(&*p.file_name().unwrap().to_string_lossy()),
            "{e}"
        );
        assert!(e.contains(want), "{want}: {e}");
        assert!(e.contains("convert it to UTF-8"), "{e}");
        assert!(!e.contains('\0'), "NUL bytes in the message: {e:?}");
    }
}

#[test]
fn nul_bytes_in_a_text_log_are_binary_data_with_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nul.csv");
    std::fs::write(&p, b"time,gyro_x\n0,1\n0.1,\x002\n0.2,3\n").unwrap();
    let o = farma(&["info", p.to_str().unwrap(), "--no-cache"], dir.path());
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("nul.csv:3:"), "{e}");
    assert!(e.contains("a NUL byte"), "{e}");
}
