//! A full disk under a memory-mapped store writer: the space is reserved before the map
//! (`posix_fallocate`), so a writer that cannot get it fails with exit 1, naming the
//! file, the bytes it needs and the file system's folder, and removes its temporary
//! file. Before, every writer (`ingest`, the cache conversion of a CSV or Parquet log,
//! `simulate -o x.arrow`) died of SIGBUS (exit 135, nothing printed) on the first page
//! the file system could not back, and left the temporary file.
//!
//! The file system is a real 2 MB tmpfs, mounted in a private mount namespace of the
//! test (`unshare --map-root-user --mount`: no root needed where user namespaces are
//! allowed); where that is not possible the test says so and passes. The writer's
//! handling is also unit-tested through an injected `ENOSPC` (src/store/writer.rs).

use std::path::Path;
use std::process::Command;

use crate::common::fixture;

/// Runs `farma ARGS` with a 2 MB tmpfs mounted at `mnt` (in a private mount namespace),
/// then lists `mnt`. Returns (exit code, stderr, entries of `mnt` after the run), or
/// None when no tmpfs can be mounted here.
fn on_small_tmpfs(mnt: &Path, args: &[&str]) -> Option<(i32, String, String)> {
    let script = r#"mount -t tmpfs -o size=2m farma-test "$MNT" || exit 99
"$FARMA" "$@" 2>"$MNT.err"; rc=$?
echo "rc=$rc"; ls -A "$MNT""#;
    let out = Command::new("unshare")
        .args(["--map-root-user", "--mount", "sh", "-c", script, "sh"])
        .args(args)
        .env("MNT", mnt)
        .env("FARMA", env!("CARGO_BIN_EXE_farma"))
        .output()
        .ok()?;
    if out.status.code() == Some(99) || !out.status.success() {
        eprintln!(
            "skipped: cannot mount a tmpfs in a user namespace here: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        return None;
    }
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let (rc_line, ls) = text.split_once('\n').unwrap_or((&text, ""));
    let rc: i32 = rc_line.trim().strip_prefix("rc=").unwrap().parse().unwrap();
    let err = std::fs::read_to_string(format!("{}.err", mnt.display())).unwrap();
    Some((rc, err, ls.trim().to_string()))
}

fn big_csv(dir: &Path) -> std::path::PathBuf {
    // 200k rows of two columns: a 3.2 MB store
    let mut text = String::from("time,gyro_x\n");
    for i in 0..200_000 {
        text.push_str(&format!("{},{}\n", i as f64 * 0.01, (i % 17) as f64 * 0.25));
    }
    let p = dir.join("big.csv");
    std::fs::write(&p, text).unwrap();
    p
}

fn assert_refused(rc: i32, err: &str, ls: &str, what: &str) {
    assert_eq!(rc, 1, "{what}: exit {rc} (135 is SIGBUS): {err}");
    assert!(err.contains("No space left on device"), "{what}: {err}");
    assert!(err.contains("the store needs"), "{what}: {err}");
    assert!(err.contains(") free"), "{what}: {err}");
    assert!(!ls.contains(".tmp"), "{what}: temporary file left: {ls}");
}

#[test]
fn ingest_into_a_full_file_system_is_exit_1_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let csv = big_csv(dir.path());
    let mnt = dir.path().join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    let out = mnt.join("x.arrow");
    let Some((rc, err, ls)) = on_small_tmpfs(
        &mnt,
        &["ingest", csv.to_str().unwrap(), "-o", out.to_str().unwrap()],
    ) else {
        return;
    };
    assert_refused(rc, &err, &ls, "ingest");
    assert!(err.contains("x.arrow"), "{err}");
    assert_eq!(ls, "", "{ls}");
}

#[test]
fn the_cache_conversion_on_a_full_file_system_is_exit_1_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let csv = big_csv(dir.path());
    let mnt = dir.path().join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    let Some((rc, err, ls)) = on_small_tmpfs(
        &mnt,
        &[
            "info",
            csv.to_str().unwrap(),
            "--cache-dir",
            mnt.to_str().unwrap(),
        ],
    ) else {
        return;
    };
    assert_refused(rc, &err, &ls, "info (cache conversion)");
}

#[test]
fn simulate_into_a_full_file_system_is_exit_1_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mnt = dir.path().join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    let out = mnt.join("sim.arrow");
    let spec = fixture("specs/adis16405_datasheet.toml");
    let Some((rc, err, ls)) = on_small_tmpfs(
        &mnt,
        &[
            "simulate",
            spec.to_str().unwrap(),
            "--duration",
            "2000",
            "-o",
            out.to_str().unwrap(),
        ],
    ) else {
        return;
    };
    assert_refused(rc, &err, &ls, "simulate");
    assert_eq!(ls, "", "{ls}");
}

#[test]
fn a_store_that_fits_is_written_on_the_small_file_system() {
    // the reservation itself does not refuse what fits
    let dir = tempfile::tempdir().unwrap();
    let mnt = dir.path().join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    let out = mnt.join("small.arrow");
    let Some((rc, err, ls)) = on_small_tmpfs(
        &mnt,
        &[
            "ingest",
            fixture("multiaxis.csv").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
    ) else {
        return;
    };
    assert_eq!(rc, 0, "{err}");
    assert_eq!(ls, "small.arrow");
}
