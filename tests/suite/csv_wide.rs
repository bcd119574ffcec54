//! Wide CSV headers are read in linear time: a header of 100k names with 3 rows was
//! 49.6 s (a duplicate-name check by `Vec::contains`, a column plan by `Vec::position`,
//! a schema scan per channel), and is now well under a second in release
//! (BENCHMARKS.md). The bound here is generous, for debug builds on a busy machine; the
//! quadratic version took minutes at this width.

use std::time::{Duration, Instant};

use crate::common::{farma, stderr, stdout};

fn wide_csv(dir: &std::path::Path, cols: usize) -> std::path::PathBuf {
    let mut text = String::with_capacity(cols * 16);
    let names: Vec<String> = (0..cols).map(|i| format!("ch{i}")).collect();
    text.push_str(&names.join(","));
    text.push('\n');
    for r in 0..3 {
        let row: Vec<String> = (0..cols).map(|i| format!("{}", (i + r) % 7)).collect();
        text.push_str(&row.join(","));
        text.push('\n');
    }
    let p = dir.join("wide.csv");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_100k_column_header_is_read_in_linear_time() {
    let dir = tempfile::tempdir().unwrap();
    let csv = wide_csv(dir.path(), 100_000);
    let t = Instant::now();
    let o = farma(
        &[
            "info",
            csv.to_str().unwrap(),
            "--rate",
            "10",
            "--channel",
            "ch99999",
            "--no-cache",
        ],
        &dir.path().join("cache"),
    );
    let took = t.elapsed();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("ch99999"), "{}", stdout(&o));
    assert!(
        took < Duration::from_secs(10),
        "100k columns took {took:?} (quadratic?)"
    );
}

#[test]
fn a_duplicate_name_in_a_wide_header_is_still_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut names: Vec<String> = (0..50_000).map(|i| format!("ch{i}")).collect();
    names.push("ch123".into());
    let text = format!(
        "{}\n{}\n",
        names.join(","),
        vec!["1"; names.len()].join(",")
    );
    let csv = dir.path().join("dup.csv");
    std::fs::write(&csv, text).unwrap();
    let o = farma(
        &["info", csv.to_str().unwrap(), "--rate", "10", "--no-cache"],
        &dir.path().join("cache"),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("column name 'ch123' appears twice"),
        "{}",
        stderr(&o)
    );
}
