//! Every file of the bad-input bank fails with exit code 2, a message naming the
//! problem, and no output left behind.

use crate::common::{farma, fixture, stderr};

/// (fixture, extra flags, substrings the message must contain).
const CASES: &[(&str, &[&str], &[&str])] = &[
    ("bad/empty.csv", &[], &["empty.csv", "the file is empty"]),
    (
        "bad/comments_only.csv",
        &[],
        &["comments_only.csv", "no header row"],
    ),
    (
        "bad/header_only.csv",
        &[],
        &["header_only.csv", "no data rows after the header (line 1)"],
    ),
    (
        "bad/wrong_field_count.csv",
        &[],
        &["wrong_field_count.csv:7:", "2 field(s), expected 3"],
    ),
    (
        "bad/truncated.csv",
        &[],
        &["truncated.csv:7:", "2 field(s), expected 3", "truncated?"],
    ),
    (
        "bad/non_numeric.csv",
        &[],
        &["non_numeric.csv:7:", "column 'gyro_x'", "'abc'"],
    ),
    (
        "bad/nan_inf.csv",
        &[],
        &[
            "nan_inf.csv",
            "column 'gyro_x'",
            "3 non-finite",
            "line 7, line 8, line 9",
            "--nan interpolate",
        ],
    ),
    (
        "bad/non_monotonic_time.csv",
        &[],
        &[
            "non_monotonic_time.csv",
            "not increasing",
            "line 5",
            "0.2 after 0.3",
        ],
    ),
    (
        "bad/duplicate_time.csv",
        &[],
        &["duplicate_time.csv", "repeats the timestamp 0.2 at line 5"],
    ),
    (
        "bad/gap.csv",
        &[],
        &[
            "gap.csv",
            "irregular sampling",
            "1 gap(s)",
            "3 missing",
            "line 5",
            "--gaps split",
        ],
    ),
    (
        "bad/irregular.csv",
        &[],
        &[
            "irregular.csv",
            "irregular sampling",
            "2 irregular interval(s)",
            "line 4",
        ],
    ),
    (
        "bad/no_time_base.csv",
        &[],
        &["no_time_base.csv", "no time base", "--rate"],
    ),
    (
        "bad/duplicate_column.csv",
        &[],
        &["duplicate_column.csv", "'gyro_x' appears twice"],
    ),
    (
        "bad/empty_column_name.csv",
        &[],
        &["empty_column_name.csv", "column 2 has no name"],
    ),
    (
        "bad/no_header.csv",
        &[],
        &["no_header.csv:1:", "expected a header row"],
    ),
    (
        "bad/one_row.csv",
        &[],
        &["one_row.csv", "too short", "1 sample(s), need at least 2"],
    ),
    (
        "bad/nan_time.csv",
        &[],
        &["nan_time.csv", "time column 'time'", "non-finite", "line 3"],
    ),
    (
        "bad/truncated.parquet",
        &[],
        &["truncated.parquet", "not a readable Parquet file"],
    ),
    (
        "bad/text_column.parquet",
        &[],
        &[
            "text_column.parquet",
            "column 'label'",
            "not a number",
            "--columns",
        ],
    ),
    (
        "bad/not_a_log.arrow",
        &[],
        &["not_a_log.arrow", "not a readable Arrow IPC file"],
    ),
    (
        "multiaxis.csv",
        &["--channel", "gyro_w"],
        &[
            "multiaxis.csv",
            "no channel 'gyro_w'",
            "gyro_x, gyro_y, gyro_z, temp_c",
        ],
    ),
    (
        "multiaxis.csv",
        &["--time-col", "clock"],
        &["multiaxis.csv", "--time-col: no column 'clock'"],
    ),
    (
        "multiaxis.csv",
        &["--columns", "gyro_q"],
        &["multiaxis.csv", "no column 'gyro_q'"],
    ),
    (
        "multiaxis.csv",
        &["--rate=-5"],
        &["--rate", "not a positive number"],
    ),
    (
        "missing_file.csv",
        &[],
        &["cannot read", "missing_file.csv"],
    ),
];

/// The cases whose problem is in a channel's values, run with `adev` instead of `info`.
const VALUE_PROBLEMS: &[&str] = &["bad/nan_inf.csv"];

#[test]
fn every_bad_input_exits_2_with_a_named_problem() {
    let cache = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for (file, flags, needles) in CASES {
        let path = fixture(file);
        let p = path.to_str().unwrap();
        // a problem in a channel's values: `info` describes it (its count of
        // non-finite values), a command that reads the values refuses it
        let command = if VALUE_PROBLEMS.contains(file) {
            "adev"
        } else {
            "info"
        };
        let mut args = vec![command, p];
        args.extend_from_slice(flags);
        let out = farma(&args, cache.path());
        let err = stderr(&out);
        if out.status.code() != Some(2) {
            failures.push(format!(
                "{file} {flags:?}: exit {:?}, stderr: {err}",
                out.status.code()
            ));
            continue;
        }
        for n in *needles {
            if !err.contains(n) {
                failures.push(format!("{file} {flags:?}: message lacks '{n}': {err}"));
            }
        }
        assert!(!err.contains("panicked"), "{file}: {err}");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn failed_ingest_leaves_no_output_and_keeps_an_existing_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("store.arrow");
    for (file, flags, _) in CASES {
        if !flags.is_empty() {
            continue;
        }
        let path = fixture(file);
        let o = farma(
            &[
                "ingest",
                path.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ],
            dir.path(),
        );
        assert_eq!(o.status.code(), Some(2), "{file}: {}", stderr(&o));
        assert!(!out.exists(), "{file} left an output behind");
    }
    // An existing output survives a failed ingest untouched.
    std::fs::write(&out, b"previous").unwrap();
    let o = farma(
        &[
            "ingest",
            fixture("bad/non_numeric.csv").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(&out).unwrap(), b"previous");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

#[test]
fn usage_errors_exit_2() {
    let cache = tempfile::tempdir().unwrap();
    let o = farma(&["info"], cache.path());
    assert_eq!(o.status.code(), Some(2));
    let o = farma(&["frobnicate"], cache.path());
    assert_eq!(o.status.code(), Some(2));
    let p = fixture("multiaxis.csv");
    let o = farma(
        &["info", p.to_str().unwrap(), "--delimiter", "|"],
        cache.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--delimiter"));
}
