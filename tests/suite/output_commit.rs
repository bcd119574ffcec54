//! An output folder never holds files of two runs (issue 29, item 8): a set is
//! committed through a journal written before the first rename, which the next reader
//! or writer completes when a run was killed between two renames; a lock file refuses
//! a second writer of one folder.

use std::path::Path;

use crate::common::{farma, fixture, stderr};

/// Every file under `root` (relative path, bytes), sorted.
fn tree(root: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(root).unwrap() {
        let p = e.unwrap().path();
        let rel = p.strip_prefix(root).unwrap().to_string_lossy().to_string();
        out.push((rel, std::fs::read(&p).unwrap()));
    }
    out.sort();
    out
}

fn names(t: &[(String, Vec<u8>)]) -> Vec<String> {
    t.iter().map(|f| f.0.clone()).collect()
}

fn fit_args<'a>(log: &'a str, out: &'a str, second: bool) -> Vec<&'a str> {
    let mut v = vec!["fit", log, "--channel", "gyro_x", "--grid", "41", "-o", out];
    if second {
        v.extend(["--order", "2,1,1"]);
    } else {
        v.extend(["--order", "1,0,1", "--residuals"]);
    }
    v
}

/// This machine's name as farma writes it in lock files.
fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .unwrap()
        .trim()
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// A run killed after 0, 1, 2 and 3 (all, before the removal of the first run's extra file) of the renames of its commit: the folder then
/// holds the commit journal, and the next reader (`farma check` loading the model)
/// completes it: the folder equals the second run's, never a mix of the two runs.
#[test]
fn a_commit_killed_between_renames_is_completed_by_the_next_reader() {
    if !cfg!(debug_assertions) {
        return; // the kill seam is compiled into debug builds only
    }
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let log = log.to_str().unwrap();
    let (first, second) = (dir.path().join("first"), dir.path().join("second"));
    for (out, which) in [(&first, false), (&second, true)] {
        let o = farma(&fit_args(log, out.to_str().unwrap(), which), dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    let (a, b) = (tree(&first), tree(&second));
    assert!(names(&a).contains(&"residuals.parquet".to_string()));
    assert!(!names(&b).contains(&"residuals.parquet".to_string()));
    for n in 0..=3 {
        let out = dir.path().join(format!("k{n}"));
        std::fs::create_dir(&out).unwrap();
        for (name, bytes) in &a {
            std::fs::write(out.join(name), bytes).unwrap();
        }
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_farma"))
            .args(fit_args(log, out.to_str().unwrap(), true))
            .env("FARMA_CACHE_DIR", dir.path())
            .env("FARMA_TEST_KILL_AFTER_RENAMES", n.to_string())
            .output()
            .unwrap();
        assert!(!o.status.success(), "kill after {n} renames: not killed");
        // killed mid-commit: the journal names the set
        assert!(
            out.join(".farma-commit.json").is_file(),
            "after {n} renames"
        );
        let o = farma(&["check", out.to_str().unwrap(), log], dir.path());
        assert_eq!(
            o.status.code(),
            Some(0),
            "after {n} renames: {}",
            stderr(&o)
        );
        assert!(
            stderr(&o).contains("completed the commit"),
            "{}",
            stderr(&o)
        );
        // the killed run's lock stays until the next writer takes it over
        let now: Vec<_> = tree(&out)
            .into_iter()
            .filter(|f| f.0 != ".farma.lock")
            .collect();
        assert_eq!(names(&now), names(&b), "after {n} renames");
        for ((name, x), (_, y)) in now.iter().zip(&b) {
            assert!(x == y, "after {n} renames: {name} is not the second run's");
        }
    }
}

/// A second writer of a folder whose lock a live process holds is refused (exit 2,
/// naming the lock), and the folder is unchanged; a lock left by a process that is
/// gone is taken over with a note.
#[test]
fn a_second_writer_is_refused_and_a_stale_lock_taken_over() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let log = log.to_str().unwrap();
    let out = dir.path().join("o");
    let o = farma(&fit_args(log, out.to_str().unwrap(), false), dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let before = tree(&out);
    assert!(
        !names(&before).iter().any(|n| n.starts_with('.')),
        "{:?}",
        names(&before)
    );
    // a live writer: this test process
    let lock = out.join(".farma.lock");
    std::fs::write(&lock, format!("{} {}\n", host(), std::process::id())).unwrap();
    let o = farma(&fit_args(log, out.to_str().unwrap(), true), dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("another farma run") && err.contains(".farma.lock"),
        "{err}"
    );
    std::fs::remove_file(&lock).unwrap();
    assert_eq!(tree(&out), before);
    // analyze holds its folder for the whole run: refused too
    std::fs::write(&lock, format!("{} {}\n", host(), std::process::id())).unwrap();
    let o = farma(
        &[
            "analyze",
            log,
            "-o",
            out.to_str().unwrap(),
            "--channel",
            "gyro_x",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("another farma run"), "{}", stderr(&o));
    // a lock of a process that is gone (pids never reach 2^22 + 12345 on Linux)
    std::fs::write(&lock, format!("{} {}\n", host(), (1u32 << 22) + 12345)).unwrap();
    let o = farma(&fit_args(log, out.to_str().unwrap(), true), dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("taken over"), "{}", stderr(&o));
    assert!(!lock.exists());
}
