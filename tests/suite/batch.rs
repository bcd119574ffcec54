//! `farma batch`: the nightly example job, resume, redo on a changed log or changed
//! options, failure isolation, and shards writing one dataset.

use std::path::{Path, PathBuf};

use crate::common::{farma, fixture, stderr, stdout};

/// Every file under `root` (relative path) with its bytes, but the manifest (its
/// times differ between runs) and the staging folder.
fn dataset(root: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(root).unwrap().to_string_lossy().to_string();
            if rel.starts_with("_manifest")
                || rel == "manifest.parquet"
                || rel.starts_with(".staging")
            {
                continue;
            }
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

/// `n` different logs `DIR/logs/log{k}.csv`: the fixture without its last k lines.
fn fixture_logs(dir: &Path, n: usize) {
    let logs = dir.join("logs");
    std::fs::create_dir(&logs).unwrap();
    let csv = std::fs::read_to_string(fixture("multiaxis.csv")).unwrap();
    for k in 0..n {
        let mut end = csv.len();
        for _ in 0..k {
            end = csv[..end - 1].rfind('\n').unwrap() + 1;
        }
        std::fs::write(logs.join(format!("log{k}.csv")), &csv[..end]).unwrap();
    }
}

fn json_of(o: &std::process::Output) -> serde_json::Value {
    serde_json::from_str(stdout(o).trim()).unwrap_or_else(|e| panic!("{e}: {}", stdout(o)))
}

fn job(dir: &Path, body: &str) -> PathBuf {
    let p = dir.join("job.toml");
    std::fs::write(&p, body).unwrap();
    p
}

/// The bundled nightly job: the good logs' units are done, the bad log's fail with
/// the reader's error (exit 2, named on stderr and in the manifest); every table is a
/// hive partition `task=..`/`log_id=..`; a rerun skips the done units and changes no
/// file; `--status` counts them.
#[test]
fn the_nightly_job_runs_isolates_a_bad_log_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("out");
    let nightly = fixture("jobs/nightly.toml");
    let (j, r) = (nightly.to_str().unwrap(), root.to_str().unwrap());
    // the real ADIS16405 run 1 is an optional input: there where ../shared is
    let real = crate::common::realdata("imudata-adis16405/adis_16405_imu1.parquet").is_some();
    let done = if real { 12 } else { 8 };
    let o = farma(&["batch", j, "-o", r, "--json"], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let s = json_of(&o);
    assert_eq!(
        (
            s["units"].as_u64(),
            s["done"].as_u64(),
            s["failed"].as_u64()
        ),
        (Some(done + 4), Some(done), Some(4)),
        "{s}"
    );
    let err = stderr(&o);
    for t in ["fit", "select-quick", "adev", "psd"] {
        assert!(
            err.contains(&format!("farma: error: nan_time.{t}: ")),
            "{err}"
        );
    }
    let files = dataset(&root);
    let names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
    for t in ["coef", "params", "gcv"] {
        assert_eq!(
            names
                .iter()
                .filter(|n| n.starts_with(&format!("{t}/task=fit/log_id=multiaxis-")))
                .count(),
            2,
            "{names:?}"
        );
    }
    assert_eq!(
        names
            .iter()
            .filter(|n| n.starts_with("select/task=select-quick/log_id=multiaxis-"))
            .count(),
        2
    );
    for (t, task) in [("allan", "adev"), ("noise_terms", "adev"), ("psd", "psd")] {
        let prefix = format!("{t}/task={task}/log_id=multiaxis-");
        assert_eq!(
            names.iter().filter(|n| n.starts_with(&prefix)).count(),
            2,
            "{names:?}"
        );
    }
    assert!(root.join("manifest.parquet").is_file());
    assert_eq!(
        std::fs::read_dir(root.join("_manifest")).unwrap().count() as u64,
        done + 4
    );

    let again = farma(&["batch", j, "-o", r, "--json"], dir.path());
    let s = json_of(&again);
    assert_eq!(
        (
            s["done"].as_u64(),
            s["skipped"].as_u64(),
            s["failed"].as_u64()
        ),
        (Some(0), Some(done), Some(4)),
        "{s}"
    );
    assert_eq!(dataset(&root), files, "a rerun changed the dataset");

    let st = farma(&["batch", j, "-o", r, "--status"], dir.path());
    assert_eq!(st.status.code(), Some(0), "{}", stderr(&st));
    assert!(
        stdout(&st).contains(&format!("{done} done, 4 failed, 0 skipped, 0 not run")),
        "{}",
        stdout(&st)
    );
}

/// A log that changed and a task whose options changed are redone; the others are
/// skipped.
#[test]
fn a_changed_log_or_changed_options_are_redone() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    std::fs::create_dir(&logs).unwrap();
    let csv = std::fs::read_to_string(fixture("multiaxis.csv")).unwrap();
    std::fs::write(logs.join("a.csv"), &csv).unwrap();
    std::fs::write(logs.join("b.csv"), &csv).unwrap();
    let body = |grid: u32| {
        format!(
            "output = \"out\"\n[[inputs]]\npaths = [\"logs/\"]\n[[tasks]]\nkind = \"fit\"\norder = \"1,1,1\"\ngrid = {grid}\n"
        )
    };
    let j = job(dir.path(), &body(31));
    let jj = j.to_str().unwrap();
    let o = farma(&["batch", jj, "--json"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(json_of(&o)["done"].as_u64(), Some(2));
    // a.csv loses its last line
    let cut = &csv[..csv.trim_end().rfind('\n').unwrap() + 1];
    std::fs::write(logs.join("a.csv"), cut).unwrap();
    let o = farma(&["batch", jj, "--json"], dir.path());
    let s = json_of(&o);
    assert_eq!(
        (s["done"].as_u64(), s["skipped"].as_u64()),
        (Some(1), Some(1)),
        "{s}"
    );
    // another grid: both redone
    job(dir.path(), &body(41));
    let o = farma(&["batch", jj, "--json"], dir.path());
    let s = json_of(&o);
    assert_eq!(
        (s["done"].as_u64(), s["skipped"].as_u64()),
        (Some(2), Some(0)),
        "{s}"
    );
}

/// Two shards into one root give the same dataset as one process, and each unit is
/// run by exactly one shard.
#[test]
fn two_shards_write_the_single_run_dataset() {
    let dir = tempfile::tempdir().unwrap();
    fixture_logs(dir.path(), 4);
    let j = job(
        dir.path(),
        "[[inputs]]\npaths = [\"logs/*.csv\"]\n[[tasks]]\nkind = \"fit\"\norder = \"1,1,1\"\ngrid = 31\n[[tasks]]\nkind = \"prep\"\n",
    );
    let jj = j.to_str().unwrap();
    let one = dir.path().join("one");
    let o = farma(&["batch", jj, "-o", one.to_str().unwrap()], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let two = dir.path().join("two");
    let t = two.to_str().unwrap();
    let mut units = 0;
    for s in ["1/2", "2/2"] {
        let o = farma(&["batch", jj, "-o", t, "--shard", s, "--json"], dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let v = json_of(&o);
        assert_eq!(v["done"], v["units"], "{v}");
        units += v["units"].as_u64().unwrap();
    }
    assert_eq!(units, 8);
    assert_eq!(dataset(&two), dataset(&one));
    let st = farma(&["batch", jj, "-o", t, "--status", "--json"], dir.path());
    let v = json_of(&st);
    assert_eq!(
        (v["done"].as_u64(), v["pending"].as_u64()),
        (Some(8), Some(0)),
        "{v}"
    );
    // a bad shard is a usage error
    let o = farma(&["batch", jj, "-o", t, "--shard", "3/2"], dir.path());
    assert_eq!(o.status.code(), Some(2));
}

/// The Slurm array script, run with bash as four array tasks at once (no scheduler),
/// and the Kubernetes Indexed Job's variables: the shards write the single run's
/// dataset into one root.
#[test]
fn the_slurm_script_and_the_indexed_job_variables_run_shards() {
    let dir = tempfile::tempdir().unwrap();
    fixture_logs(dir.path(), 3);
    let j = job(
        dir.path(),
        "[[inputs]]\npaths = [\"logs/\"]\n[[tasks]]\nkind = \"fit\"\norder = \"1,1,1\"\ngrid = 31\n[[tasks]]\nkind = \"prep\"\n",
    );
    let one = dir.path().join("one");
    let o = farma(
        &["batch", j.to_str().unwrap(), "-o", one.to_str().unwrap()],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let script = crate::common::root().join("examples/slurm/nightly.sbatch");
    let array = dir.path().join("array");
    let children: Vec<_> = (0..4)
        .map(|i| {
            std::process::Command::new("bash")
                .arg(&script)
                .env("FARMA", env!("CARGO_BIN_EXE_farma"))
                .env("JOB", &j)
                .env("OUT", &array)
                .env("FARMA_CACHE_DIR", dir.path())
                .env("SLURM_ARRAY_TASK_ID", (10 + i).to_string())
                .env("SLURM_ARRAY_TASK_MIN", "10")
                .env("SLURM_ARRAY_TASK_COUNT", "4")
                .env("SLURM_CPUS_PER_TASK", "1")
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .expect("bash")
        })
        .collect();
    let children: Vec<_> = children
        .into_iter()
        .map(|c| c.wait_with_output().unwrap())
        .collect();
    for c in &children {
        assert_eq!(c.status.code(), Some(0), "{}", stderr(c));
    }
    assert_eq!(dataset(&array), dataset(&one));
    let indexed = dir.path().join("indexed");
    for i in 0..3 {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_farma"))
            .args([
                "batch",
                j.to_str().unwrap(),
                "-o",
                indexed.to_str().unwrap(),
            ])
            .env("FARMA_CACHE_DIR", dir.path())
            .env("JOB_COMPLETION_INDEX", i.to_string())
            .env("FARMA_SHARD_COUNT", "3")
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    assert_eq!(dataset(&indexed), dataset(&one));
    let st = farma(
        &[
            "batch",
            j.to_str().unwrap(),
            "-o",
            indexed.to_str().unwrap(),
            "--status",
            "--json",
        ],
        dir.path(),
    );
    assert_eq!(json_of(&st)["done"].as_u64(), Some(6));
}

/// An ingested store with damaged bytes named as a batch input fails its units,
/// naming the column; the other logs' units are done.
#[test]
fn a_damaged_ingested_store_fails_its_units_naming_the_column() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    std::fs::create_dir(&logs).unwrap();
    let store = logs.join("stand.arrow");
    let o = farma(
        &[
            "ingest",
            fixture("multiaxis.csv").to_str().unwrap(),
            "-o",
            store.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    std::fs::copy(fixture("multiaxis.csv"), logs.join("good.csv")).unwrap();
    let j = job(
        dir.path(),
        "[[inputs]]\npaths = [\"logs/\"]\n[[tasks]]\nkind = \"fit\"\norder = \"1,1,1\"\ngrid = 31\n",
    );
    let jj = j.to_str().unwrap();
    let o = farma(
        &[
            "batch",
            jj,
            "-o",
            dir.path().join("ok").to_str().unwrap(),
            "--json",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(json_of(&o)["done"].as_u64(), Some(2));
    // flip 64 bytes in the middle of the store (inside a column's values)
    let mut bytes = std::fs::read(&store).unwrap();
    let mid = bytes.len() / 2;
    for b in &mut bytes[mid..mid + 64] {
        *b ^= 0x5a;
    }
    std::fs::write(&store, bytes).unwrap();
    let o = farma(
        &[
            "batch",
            jj,
            "-o",
            dir.path().join("bad").to_str().unwrap(),
            "--json",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let s = json_of(&o);
    assert_eq!(
        (s["done"].as_u64(), s["failed"].as_u64()),
        (Some(1), Some(1)),
        "{s}"
    );
    let err = s["failures"][0]["error"].as_str().unwrap().to_string();
    assert!(
        err.contains("stand.arrow") && err.contains("column '"),
        "{err}"
    );
}

/// The cache stays under FARMA_CACHE_LIMIT_GB (least recently used stores removed,
/// with a note; the one in use kept), and `farma cache list` / `prune` show and trim it.
#[test]
fn the_cache_keeps_under_its_limit_and_lists_and_prunes() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let csv = std::fs::read_to_string(fixture("multiaxis.csv")).unwrap();
    let run = |args: &[&str], limit: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_farma"))
            .args(args)
            .env("FARMA_CACHE_DIR", &cache)
            .env("FARMA_CACHE_LIMIT_GB", limit)
            .output()
            .unwrap()
    };
    // each store of the fixture is about 160 kB: a 0.0003 GB (300 kB) limit holds one
    let mut logs = Vec::new();
    for k in 0..3 {
        let p = dir.path().join(format!("log{k}.csv"));
        std::fs::write(&p, &csv).unwrap();
        let o = run(&["info", p.to_str().unwrap()], "0.0003");
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        if k > 0 {
            assert!(
                stderr(&o).contains("removed the least recently used cached store"),
                "{}",
                stderr(&o)
            );
        }
        logs.push(p);
    }
    let o = run(&["cache", "list", "--json"], "0.0003");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v = json_of(&o);
    let entries = v["entries"].as_array().unwrap();
    assert_eq!(entries.len(), 1, "{v}");
    assert!(
        entries[0]["path"].as_str().unwrap().contains("log2-"),
        "{v}"
    );
    // a generous limit keeps everything; prune --all empties the cache
    for p in &logs[..2] {
        assert_eq!(
            run(&["info", p.to_str().unwrap()], "20").status.code(),
            Some(0)
        );
    }
    let v = json_of(&run(&["cache", "list", "--json"], "20"));
    assert_eq!(v["entries"].as_array().unwrap().len(), 3, "{v}");
    let v = json_of(&run(
        &["cache", "prune", "--max-gb", "0.0003", "--json"],
        "20",
    ));
    assert_eq!(v["removed"].as_u64(), Some(2), "{v}");
    let v = json_of(&run(&["cache", "prune", "--all", "--json"], "20"));
    assert_eq!(v["removed"].as_u64(), Some(1), "{v}");
    let o = run(&["info", logs[0].to_str().unwrap()], "nonsense");
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("FARMA_CACHE_LIMIT_GB"),
        "{}",
        stderr(&o)
    );
}

/// An input's own gyro patterns override the job's: a log with no channel of the role
/// is skipped (with the reason in the manifest), another input's logs run.
#[test]
fn an_input_overrides_the_gyro_role() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(fixture("multiaxis.csv"), dir.path().join("a.csv")).unwrap();
    std::fs::copy(fixture("multiaxis.csv"), dir.path().join("b.csv")).unwrap();
    let j = job(
        dir.path(),
        "output = \"out\"\n[[inputs]]\npaths = [\"a.csv\"]\ngyro = [\"rate_*\"]\n[[inputs]]\npaths = [\"b.csv\"]\ngyro = [\"gyro_x\"]\n[[tasks]]\nkind = \"adev\"\n",
    );
    let o = farma(&["batch", j.to_str().unwrap(), "--json"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = json_of(&o);
    assert_eq!(
        (s["done"].as_u64(), s["skipped"].as_u64()),
        (Some(1), Some(1)),
        "{s}"
    );
    let st = farma(&["batch", j.to_str().unwrap(), "--status"], dir.path());
    assert!(
        stdout(&st).contains("1 done, 0 failed, 1 skipped"),
        "{}",
        stdout(&st)
    );
}

/// The check task checks a saved model on every log: its whiteness, prediction and
/// polynomial tables land in the dataset; a model without any of a log's channels
/// fails that unit, naming the model.
#[test]
fn the_check_task_checks_a_saved_model_on_every_log() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    std::fs::create_dir(&logs).unwrap();
    std::fs::copy(fixture("multiaxis.csv"), logs.join("a.csv")).unwrap();
    std::fs::copy(fixture("multiaxis.csv"), logs.join("b.csv")).unwrap();
    let model = dir.path().join("model");
    let o = farma(
        &[
            "fit",
            fixture("multiaxis.csv").to_str().unwrap(),
            "--channel",
            "gyro_x,gyro_y",
            "--order",
            "1,1,1",
            "--grid",
            "31",
            "-o",
            model.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let j = job(
        dir.path(),
        "output = \"out\"\n[[inputs]]\npaths = [\"logs/\"]\n[[tasks]]\nkind = \"check\"\nmodel = \"model\"\nholdout_s = 20\n",
    );
    let o = farma(&["batch", j.to_str().unwrap(), "--json"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(json_of(&o)["done"].as_u64(), Some(2));
    // unchanged: skipped; the model refitted into its folder: both redone
    let o = farma(&["batch", j.to_str().unwrap(), "--json"], dir.path());
    assert_eq!(json_of(&o)["skipped"].as_u64(), Some(2));
    std::thread::sleep(std::time::Duration::from_millis(20));
    let o = farma(
        &[
            "fit",
            fixture("multiaxis.csv").to_str().unwrap(),
            "--channel",
            "gyro_x,gyro_y",
            "--order",
            "2,1,1",
            "--grid",
            "31",
            "-o",
            model.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = farma(&["batch", j.to_str().unwrap(), "--json"], dir.path());
    assert_eq!(json_of(&o)["done"].as_u64(), Some(2));
    for t in ["acf", "ljung_box", "prediction", "poly"] {
        for l in ["a", "b"] {
            let p = dir
                .path()
                .join(format!("out/{t}/task=check/log_id={l}/part-0.parquet"));
            assert!(p.is_file(), "{}", p.display());
        }
    }
    // a model of other channels: the units fail naming it
    let j = job(
        dir.path(),
        "output = \"out2\"\n[[inputs]]\npaths = [\"logs/\"]\nchannels = [\"gyro_z\"]\n[[tasks]]\nkind = \"check\"\nmodel = \"model\"\n",
    );
    let o = farma(&["batch", j.to_str().unwrap(), "--json"], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let s = json_of(&o);
    assert_eq!(s["failed"].as_u64(), Some(2), "{s}");
    assert!(
        s["failures"][0]["error"]
            .as_str()
            .unwrap()
            .contains("holds none"),
        "{s}"
    );
}

/// The analyze task: its dataset holds every table of `farma analyze` with the
/// verdict among them (one row per gyro channel), its summary.txt under `_files`, and
/// none of the job's channel folders; its tables equal those of `farma analyze` on the
/// same channels; a rerun skips it.
#[test]
fn the_analyze_task_writes_the_verdict_table() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(fixture("multiaxis.csv"), dir.path().join("m.csv")).unwrap();
    let j = job(
        dir.path(),
        "output = \"out\"\n[[inputs]]\npaths = [\"m.csv\"]\n[[tasks]]\nkind = \"analyze\"\norders = \"1,1,1\"\ngrid = 21\nbootstrap = 4\n",
    );
    let o = farma(&["batch", j.to_str().unwrap(), "--json"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(json_of(&o)["done"].as_u64(), Some(1));
    let root = dir.path().join("out");
    let files: Vec<String> = dataset(&root).into_iter().map(|(f, _)| f).collect();
    for t in [
        "verdict",
        "select",
        "ftests",
        "constancy",
        "coef",
        "params",
        "gcv",
        "acf",
        "ljung_box",
        "prediction",
        "poly",
        "prep",
        "replaced",
    ] {
        let f = format!("{t}/task=analyze/log_id=m/part-0.parquet");
        assert!(files.contains(&f), "{f} missing: {files:?}");
    }
    assert!(files.contains(&"_files/task=analyze/log_id=m/summary.txt".to_string()));
    assert!(!files.iter().any(|f| f.contains("channels")), "{files:?}");
    // the same tables as farma analyze on the gyro channels
    let out = dir.path().join("a");
    let o = farma(
        &[
            "analyze",
            dir.path().join("m.csv").to_str().unwrap(),
            "--orders",
            "1,1,1",
            "--grid",
            "21",
            "--bootstrap",
            "4",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for t in ["verdict", "params", "select"] {
        assert_eq!(
            std::fs::read(root.join(format!("{t}/task=analyze/log_id=m/part-0.parquet"))).unwrap(),
            std::fs::read(out.join(format!("{t}.parquet"))).unwrap(),
            "{t}"
        );
    }
    let summary =
        std::fs::read_to_string(root.join("_files/task=analyze/log_id=m/summary.txt")).unwrap();
    assert!(summary.contains("== verdict") && summary.contains("gyro_z  FARMA(1,1,1)"));
    let o = farma(&["batch", j.to_str().unwrap(), "--json"], dir.path());
    assert_eq!(json_of(&o)["skipped"].as_u64(), Some(1), "{}", stderr(&o));
}

/// The gap task: the unit's channels that the spec simulates are diagnosed against it,
/// every table a hive partition with every channel's rows; the log's temperature
/// channel (the temperature role) is offered when the spec names none, and becomes the
/// `temperature_channel` of each channel's `spec_after`; an edited spec redoes the unit.
#[test]
fn the_gap_task_diagnoses_the_specs_channels_with_the_temperature_role() {
    let dir = tempfile::tempdir().unwrap();
    let spec = "sample_rate_hz = 10.0\nseed = 3\n[[channel]]\nname = \"gyro_x\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.01\n[[channel]]\nname = \"gyro_y\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.01\n";
    std::fs::write(dir.path().join("spec.toml"), spec).unwrap();
    let log = fixture("multiaxis.csv");
    let j = job(
        dir.path(),
        &format!(
            "[[inputs]]\npaths = [{:?}]\n[[tasks]]\nkind = \"gap\"\nspec = \"spec.toml\"\nreplicas = 6\n",
            log.to_str().unwrap()
        ),
    );
    let root = dir.path().join("out");
    let (j, r) = (j.to_str().unwrap(), root.to_str().unwrap());
    let o = farma(&["batch", j, "-o", r, "--json"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(json_of(&o)["done"].as_u64(), Some(1));
    let part = "task=gap/log_id=multiaxis";
    for t in ["gap_features", "gap_regions", "gap_effects"] {
        let f = root.join(t).join(part).join("part-0.parquet");
        let rows = crate::common::parquet_strings(&f, "channel");
        assert!(
            rows.iter().any(|c| c == "gyro_x") && rows.iter().any(|c| c == "gyro_y"),
            "{t}: {rows:?}"
        );
        assert!(!rows.iter().any(|c| c == "gyro_z" || c == "temp_c"), "{t}");
    }
    for c in ["gyro_x", "gyro_y"] {
        let after = std::fs::read_to_string(
            root.join("_files")
                .join(part)
                .join(format!("spec_after_{c}.toml")),
        )
        .unwrap();
        assert!(
            after.contains("temperature_channel = \"temp_c\""),
            "{after}"
        );
        assert!(
            root.join("_files")
                .join(part)
                .join(format!("report_{c}.svg"))
                .is_file()
        );
    }
    // the manifest names the binary's version and commit
    let commit = crate::common::parquet_strings(&root.join("manifest.parquet"), "farma_commit");
    assert!(commit.len() == 1 && !commit[0].is_empty(), "{commit:?}");
    // unchanged: skipped; an edited spec: redone
    let o = farma(&["batch", j, "-o", r, "--json"], dir.path());
    assert_eq!(json_of(&o)["done"].as_u64(), Some(0), "{}", stderr(&o));
    std::fs::write(dir.path().join("spec.toml"), spec.replace("0.01", "0.02")).unwrap();
    let o = farma(&["batch", j, "-o", r, "--json"], dir.path());
    assert_eq!(json_of(&o)["done"].as_u64(), Some(1), "{}", stderr(&o));
}

/// The gap task's `max_samples` and `excerpt_samples` reach the diagnosis: the 4000-sample
/// log averaged (over blocks of 2 for at most 2000) has its per-sample part's rows in
/// the effects table.
#[test]
fn the_gap_task_s_max_samples_and_excerpt_samples_reach_the_diagnosis() {
    let dir = tempfile::tempdir().unwrap();
    let spec = "sample_rate_hz = 10.0\nseed = 3\n[[channel]]\nname = \"gyro_x\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.01\n";
    std::fs::write(dir.path().join("spec.toml"), spec).unwrap();
    let log = fixture("multiaxis.csv");
    let j = job(
        dir.path(),
        &format!(
            "[[inputs]]\npaths = [{:?}]\n[[tasks]]\nkind = \"gap\"\nspec = \"spec.toml\"\nreplicas = 6\nmax_samples = 2000\nexcerpt_samples = 1500\n",
            log.to_str().unwrap()
        ),
    );
    let root = dir.path().join("out");
    let (j, r) = (j.to_str().unwrap(), root.to_str().unwrap());
    let o = farma(&["batch", j, "-o", r, "--json"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let f = root
        .join("gap_effects")
        .join("task=gap/log_id=multiaxis")
        .join("part-0.parquet");
    let lists = crate::common::parquet_strings(&f, "list");
    assert!(lists.iter().any(|l| l == "per_sample_ranked"), "{lists:?}");
    // excerpt_samples = 0: averaged, no per-sample part
    let j0 = job(
        dir.path(),
        &format!(
            "[[inputs]]\npaths = [{:?}]\n[[tasks]]\nkind = \"gap\"\nspec = \"spec.toml\"\nreplicas = 6\nmax_samples = 2000\nexcerpt_samples = 0\n",
            log.to_str().unwrap()
        ),
    );
    let root0 = dir.path().join("out0");
    let o = farma(
        &[
            "batch",
            j0.to_str().unwrap(),
            "-o",
            root0.to_str().unwrap(),
            "--json",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let f0 = root0
        .join("gap_effects")
        .join("task=gap/log_id=multiaxis")
        .join("part-0.parquet");
    let lists = crate::common::parquet_strings(&f0, "list");
    assert!(
        !lists.is_empty() && !lists.iter().any(|l| l.starts_with("per_sample")),
        "{lists:?}"
    );
}

/// The root's index.html: one row per unit, a relative link to each adev unit's
/// report.html (a file that is there) with that report's verdict, and the failed
/// unit's error; self-contained; a rerun writes the same bytes.
#[test]
fn the_root_index_links_every_report_with_its_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("out");
    let good = fixture("multiaxis.csv");
    let bad = fixture("bad/nan_time.csv");
    let j = job(
        dir.path(),
        &format!(
            "output = \"unused\"\n[[inputs]]\npaths = [{:?}, {:?}]\n[[tasks]]\nkind = \"adev\"\n",
            good.to_str().unwrap(),
            bad.to_str().unwrap()
        ),
    );
    let (j, r) = (j.to_str().unwrap(), root.to_str().unwrap());
    let o = farma(&["batch", j, "-o", r], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let index = std::fs::read_to_string(root.join("index.html")).unwrap();
    assert!(
        index.contains("2 units: 1 done, 1 failed, 0 skipped"),
        "{index}"
    );
    let link = "_files/task=adev/log_id=multiaxis/report.html";
    assert!(index.contains(&format!("<a href=\"{link}\">")), "{index}");
    let report = std::fs::read_to_string(root.join(link)).unwrap();
    // the report's verdict box, as it is in the report
    let verdict = farma::batch::index::verdict_of(&report).unwrap();
    assert!(verdict.contains("gyro_x"), "{verdict}");
    assert!(index.contains(verdict));
    // the failed unit, with its status and error
    assert!(
        index.contains(">nan_time</td>") && index.contains(">failed</span>"),
        "{index}"
    );
    assert!(!index.contains("<script") && !index.contains("http"));
    let o = farma(&["batch", j, "-o", r], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        std::fs::read_to_string(root.join("index.html")).unwrap(),
        index
    );
}
