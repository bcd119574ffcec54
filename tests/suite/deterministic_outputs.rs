//! Two identical runs write byte-identical folders (issue 29, item 11): no timing or
//! clock time in any file (timings go to stderr), so that a scheduled job can compare
//! two nights' outputs with `cmp`.

use std::path::Path;

use crate::common::{farma, fixture, stderr};

/// Every file under `root` (relative path, bytes), sorted.
fn tree(root: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().to_string();
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

/// `farma analyze` twice (`--fresh`, so the second run redoes every channel) into one
/// folder: every file, summary.txt and the channels' markers included, is the same.
#[test]
fn two_identical_analyze_runs_write_identical_folders() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("m.csv");
    std::fs::copy(fixture("multiaxis.csv"), &log).unwrap();
    let out = dir.path().join("a");
    let args = |fresh: bool| {
        let mut v = vec![
            "analyze".to_string(),
            log.display().to_string(),
            "-o".into(),
            out.display().to_string(),
            "--channel".into(),
            "gyro_x,gyro_y".into(),
            "--quiet".into(),
        ];
        if fresh {
            v.push("--fresh".into());
        }
        v
    };
    let run = |fresh: bool| {
        let a = args(fresh);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let o = farma(&a, dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        // the timing is on stderr
        assert!(stderr(&o).contains(" s"), "{}", stderr(&o));
        tree(&out)
    };
    let first = run(false);
    std::thread::sleep(std::time::Duration::from_millis(1100));
    let second = run(true);
    let names = |t: &[(String, Vec<u8>)]| t.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(&first), names(&second));
    assert!(names(&first).iter().any(|n| n == "summary.txt"));
    assert!(names(&first).iter().any(|n| n.ends_with("done.json")));
    for ((name, a), (_, b)) in first.iter().zip(&second) {
        assert!(a == b, "{name} differs between two identical runs");
    }
}
