//! The integration tests, one binary: each former `tests/NAME.rs` is the module
//! `NAME` here (`tests/suite/NAME.rs`), so `cargo test` links farma, arrow, parquet
//! and faer into one test executable rather than one per file. Run one file's tests
//! with `cargo test --test suite NAME::`.

mod common;

mod absurd_sizes;
mod adev;
mod analyze_channels;
mod arrow_formats;
mod bad_input;
mod batch;
mod csv_wide;
mod deterministic_outputs;
mod disk_full;
mod doc_tables;
mod estimator_multivariate;
mod estimator_paths;
mod estimator_recovery;
mod estimator_reference;
mod estimator_update;
mod fit_cli;
mod fit_index_cli;
mod fixtures;
mod fuzz_regressions;
mod gap;
mod gcv_limit;
mod ingest;
mod input_kinds;
mod noise_terms;
mod output_commit;
mod output_path;
mod parquet_checksums;
mod psd_acf;
mod reports;
mod simulate;
mod simulate_blocks;
mod spec;
mod spec_examples;
mod store_checksums;
mod temp_stores;
mod unit_root;
mod update_cli;
mod workflow_cli;
mod workflow_golden;
mod workflow_prep;
mod workflow_select;
