//! The temporary stores of `--no-cache` runs: named like every output temporary
//! (`.farma-HOST-PID-XXXXXX.tmp`) directly in `$TMPDIR`, so that the store of a killed
//! run (which cannot remove it) is swept by the next run there when its process is
//! gone; a live process's is kept. Before, each run converted into a private folder
//! `$TMPDIR/.tmpXXXXXX/`, which nothing swept (an 88 MB leak per killed run).

use std::process::Command;

use crate::common::{fixture, stderr};

/// This machine's name as farma writes it in temporary files' names.
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

fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_killed_no_cache_runs_store_is_swept_and_a_live_ones_kept() {
    if !std::path::Path::new("/proc/self").exists() {
        eprintln!("skipped: no /proc (the sweep needs it)");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let host = host();
    // pid_max is at most 2^22: this process cannot exist.
    let dead = tmp
        .path()
        .join(format!(".farma-{host}-999999999-a1B2c3.tmp"));
    let live = tmp
        .path()
        .join(format!(".farma-{host}-{}-z9Y8x7.tmp", std::process::id()));
    let other_host = tmp.path().join(".farma-elsewhere-999999999-a1B2c3.tmp");
    for p in [&dead, &live, &other_host] {
        std::fs::write(p, vec![0u8; 4096]).unwrap();
    }
    let o = Command::new(env!("CARGO_BIN_EXE_farma"))
        .args([
            "info",
            fixture("multiaxis.csv").to_str().unwrap(),
            "--no-cache",
        ])
        .env("TMPDIR", tmp.path())
        .env("FARMA_CACHE_DIR", tmp.path().join("unused-cache"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!dead.exists(), "the dead run's store was not swept");
    assert!(live.exists(), "a live process's temporary was removed");
    assert!(other_host.exists(), "another host's temporary was removed");
    assert!(
        stderr(&o).contains("removed 1 temporary file(s)"),
        "{}",
        stderr(&o)
    );
    // and the run left nothing of its own behind
    let mut want = vec![
        live.file_name().unwrap().to_string_lossy().into_owned(),
        other_host
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned(),
    ];
    want.sort();
    assert_eq!(entries(tmp.path()), want);
}

#[test]
fn a_no_cache_run_killed_mid_conversion_leaves_only_what_the_next_run_sweeps() {
    if !std::path::Path::new("/proc/self").exists() {
        eprintln!("skipped: no /proc (the sweep needs it)");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let big = tmp.path().join("big.csv");
    let mut text = String::from("time,gyro_x\n");
    for i in 0..1_000_000 {
        text.push_str(&format!("{},{}\n", i as f64 * 0.01, (i % 13) as f64 * 0.5));
    }
    std::fs::write(&big, text).unwrap();
    let work = tmp.path().join("t");
    std::fs::create_dir(&work).unwrap();
    let run = || {
        Command::new(env!("CARGO_BIN_EXE_farma"))
            .args(["info", big.to_str().unwrap(), "--no-cache"])
            .env("TMPDIR", &work)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    // Kill the first run as soon as its temporary store shows in $TMPDIR.
    let mut child = run();
    let t0 = std::time::Instant::now();
    let seen = loop {
        let e = entries(&work);
        if !e.is_empty() {
            break e;
        }
        if child.try_wait().unwrap().is_some() || t0.elapsed().as_secs() > 60 {
            eprintln!("skipped: the run ended before its temporary store was seen");
            return;
        }
        std::thread::sleep(std::time::Duration::from_micros(200));
    };
    child.kill().unwrap();
    child.wait().unwrap();
    let prefix = format!(".farma-{}-{}-", host(), child.id());
    for name in entries(&work) {
        assert!(
            name.starts_with(&prefix) && name.ends_with(".tmp"),
            "{name} (first seen {seen:?}) is not named for the sweep"
        );
        assert!(work.join(&name).is_file(), "{name} is not a file");
    }
    // The next run removes them and leaves nothing of its own.
    let o = run().wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(entries(&work), Vec::<String>::new(), "left behind");
}
