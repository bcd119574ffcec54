//! `farma fit --save-state` then `farma update`: outputs, identical bytes with 1 and 2
//! threads, and bad model folders / logs exit 2 naming the problem.

mod common;

use std::path::{Path, PathBuf};

use common::{farma, fixture, stderr, stdout};

/// Writes rows [from, to) of multiaxis.csv (header kept), optionally without a column.
fn slice_log(dir: &Path, name: &str, from: usize, to: usize, drop: Option<&str>) -> PathBuf {
    let text = std::fs::read_to_string(fixture("multiaxis.csv")).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|i| Some(header[*i]) != drop)
        .collect();
    let pick = |l: &str| {
        let f: Vec<&str> = l.split(',').collect();
        keep.iter().map(|i| f[*i]).collect::<Vec<_>>().join(",")
    };
    let mut out = pick(&header.join(","));
    out.push('\n');
    for l in lines.skip(from).take(to - from) {
        out.push_str(&pick(l));
        out.push('\n');
    }
    let p = dir.join(name);
    std::fs::write(&p, out).unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `farma fit OLD --channel gyro_x,gyro_y --order ORDER --grid GRID --save-state -o
/// MODEL` in `d`, which must succeed; returns MODEL.
fn fit_state(d: &Path, old: &Path, order: &str, grid: &str) -> PathBuf {
    let model = d.join("model");
    let o = farma(
        &[
            "fit",
            s(old),
            "--channel",
            "gyro_x,gyro_y",
            "--order",
            order,
            "--grid",
            grid,
            "--save-state",
            "-o",
            s(&model),
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    model
}

#[test]
fn fit_save_state_then_update_writes_tables_independent_of_threads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let old = slice_log(d, "old.csv", 0, 3000, None);
    let new = slice_log(d, "new.csv", 3000, 4000, None);
    let model = fit_state(d, &old, "2,1,1", "31");
    assert!(model.join("state.parquet").exists());
    let run = |threads: &str, out: &str, extra: &[&str]| {
        let mut args = vec!["--threads", threads, "update", s(&model), s(&new), "-o"];
        let target = d.join(out);
        let target = target.to_str().unwrap().to_string();
        args.push(&target);
        args.extend_from_slice(&["--residuals", "--json"]);
        args.extend_from_slice(extra);
        let o = farma(&args, d);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        o
    };
    let one = run("1", "u1", &[]);
    let two = run("2", "u2", &[]);
    for f in [
        "coef.parquet",
        "params.parquet",
        "gcv.parquet",
        "residuals.parquet",
        "state.parquet",
    ] {
        let a = std::fs::read(d.join("u1").join(f)).unwrap();
        let b = std::fs::read(d.join("u2").join(f)).unwrap();
        assert!(a == b, "{f} differs between 1 and 2 threads");
    }
    let lines: Vec<serde_json::Value> = stdout(&one)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2);
    for v in &lines {
        for k in [
            "channel",
            "order",
            "b",
            "sigma2",
            "bandwidth",
            "rss",
            "coef",
            "n_new",
            "forgetting",
        ] {
            assert!(v.get(k).is_some(), "missing key {k}");
        }
        assert_eq!(v["n"], serde_json::json!(4000));
        assert_eq!(v["n_new"], serde_json::json!(1000));
        assert_eq!(v["method"], serde_json::json!("rls"));
    }
    assert_eq!(stdout(&one), stdout(&two).replace("/u2/", "/u1/"));
    // an update can be updated again, with forgetting
    let o = farma(
        &[
            "update",
            s(&d.join("u1")),
            s(&new),
            "-o",
            s(&d.join("u3")),
            "--forgetting",
            "0.99",
            "--json",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(stdout(&o).lines().next().unwrap()).unwrap();
    assert_eq!(v["n"], serde_json::json!(5000));
}

#[test]
fn update_rejects_bad_model_folders_and_logs_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let old = slice_log(d, "old.csv", 0, 2000, None);
    let new = slice_log(d, "new.csv", 2000, 2500, None);
    let no_y = slice_log(d, "no_y.csv", 2000, 2500, Some("gyro_y"));
    let model = fit_state(d, &old, "1,1,1", "21");
    let no_state = d.join("no_state");
    std::fs::create_dir(&no_state).unwrap();
    let corrupt = d.join("corrupt");
    std::fs::create_dir(&corrupt).unwrap();
    std::fs::write(corrupt.join("state.parquet"), b"not parquet at all").unwrap();
    let plain = d.join("plain"); // a fit without --save-state: coef.parquet is no state
    std::fs::create_dir(&plain).unwrap();
    std::fs::copy(model.join("coef.parquet"), plain.join("state.parquet")).unwrap();
    let out = d.join("out");
    let (missing, nope) = (d.join("missing"), d.join("nope.csv"));
    // the new samples at 5 Hz: the model was fitted at 10 Hz
    let slow = d.join("slow.csv");
    let text: Vec<String> = std::fs::read_to_string(&new)
        .unwrap()
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                return l.to_string();
            }
            let (t, rest) = l.split_once(',').unwrap();
            format!("{},{rest}", t.parse::<f64>().unwrap() * 2.0)
        })
        .collect();
    std::fs::write(&slow, text.join("\n")).unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["update", s(&missing), s(&new), "-o", s(&out)],
            "missing",
        ),
        (
            vec!["update", s(&no_state), s(&new), "-o", s(&out)],
            "--save-state",
        ),
        (
            vec!["update", s(&corrupt), s(&new), "-o", s(&out)],
            "not a readable Parquet",
        ),
        (
            vec!["update", s(&plain), s(&new), "-o", s(&out)],
            "not a farma state file",
        ),
        (
            vec!["update", s(&model), s(&no_y), "-o", s(&out)],
            "no channel 'gyro_y'",
        ),
        (
            vec!["update", s(&model), s(&nope), "-o", s(&out)],
            "nope.csv",
        ),
        (
            vec![
                "update",
                s(&model),
                s(&new),
                "-o",
                s(&out),
                "--forgetting",
                "1.5",
            ],
            "--forgetting",
        ),
        (
            vec!["update", s(&model), s(&slow), "-o", s(&out)],
            "sampled at 5.000000 Hz",
        ),
    ];
    for (args, needle) in cases {
        let r = farma(&args, d);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {}", stderr(&r));
        assert!(stderr(&r).contains(needle), "{args:?}: {}", stderr(&r));
    }
    assert!(!out.join("coef.parquet").exists());
    assert!(!out.join("state.parquet").exists());
}

/// A state.parquet with a NaN mean exits 2 naming the file, the channel and the field
/// (it panicked); new samples 1e20 times the model's scale exit 2 and write nothing
/// (they wrote NaN coefficients with exit 0).
#[test]
fn update_rejects_a_nan_state_and_samples_off_the_models_scale() {
    use farma::estimator::update::{read_state, write_state};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let old = slice_log(d, "old.csv", 0, 2000, None);
    let new = slice_log(d, "new.csv", 2000, 2500, None);
    let model = fit_state(d, &old, "1,1,1", "21");
    // the state with a NaN mean for gyro_x
    let (mut states, md) = read_state(&model.join("state.parquet")).unwrap();
    states[0].mean = f64::NAN;
    let bad = d.join("bad");
    std::fs::create_dir(&bad).unwrap();
    let md: Vec<(&str, String)> = md
        .iter()
        .filter(|(k, _)| k != "farma_state_version")
        .map(|(k, v)| (k.as_str(), v.clone()))
        .collect();
    let refs: Vec<_> = states.iter().collect();
    write_state(&bad.join("state.parquet"), &refs, &md).unwrap();
    let out = d.join("out");
    let r = farma(&["update", s(&bad), s(&new), "-o", s(&out)], d);
    let err = stderr(&r);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("state.parquet") && err.contains("'gyro_x'") && err.contains("'mean'"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    // this 1,1,1 fit of gyro_x returned its linear ARMA start: the state holds no fitted
    // local model, and update refuses it (it had solved the rejected local fits)
    let r = farma(&["update", s(&model), s(&new), "-o", s(&out)], d);
    let err = stderr(&r);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("'gyro_x'") && err.contains("linear ARMA start"),
        "{err}"
    );
    assert!(!out.join("state.parquet").exists());
    // a model with local fits (2,1,1 on 31 points, as the first test)
    let model = fit_state(d, &old, "2,1,1", "31");
    // gyro_x times 1e20
    let text = std::fs::read_to_string(&new).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let col = header.split(',').position(|c| c == "gyro_x").unwrap();
    let mut scaled = format!("{header}\n");
    for l in lines {
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        f[col] = format!("{:e}", f[col].parse::<f64>().unwrap() * 1e20);
        scaled.push_str(&f.join(","));
        scaled.push('\n');
    }
    let big = d.join("big.csv");
    std::fs::write(&big, scaled).unwrap();
    let r = farma(&["update", s(&model), s(&big), "-o", s(&out)], d);
    let err = stderr(&r);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("'gyro_x'") && err.contains("non-finite") && err.contains("scale"),
        "{err}"
    );
    assert!(!out.join("state.parquet").exists());
    assert!(!out.join("coef.parquet").exists());
}
