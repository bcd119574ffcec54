//! Absurd sizes and values (issue 29, items 1, 3, 6 and 9): memory is planned before
//! it is taken (a flag asking for more than `--memory-limit` is refused with exit 2,
//! naming the flag and the bytes, where it aborted in the allocator), a spec whose
//! values overflow is refused naming the component and the value, `adev` and `psd`
//! refuse a series holding Inf (or overflowing) instead of writing NaN, and messages
//! name the real cause with a bounded number of digits.

use std::path::Path;

use farma::simulator::{SimRequest, Simulator, parse_spec};
use farma::store::{Store, StoreWriter};

use crate::common::{farma, fixture, stderr};

fn run(args: &[&str], dir: &Path) -> (Option<i32>, String) {
    let o = farma(args, dir);
    (o.status.code(), stderr(&o))
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

/// The longest line of a message: values print with a bounded number of digits.
fn longest_word(s: &str) -> usize {
    s.split_whitespace().map(str::len).max().unwrap_or(0)
}

#[test]
fn oversized_flags_are_refused_before_the_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let spec = fixture("specs/adis16405_datasheet.toml");
    let spec = spec.to_str().unwrap();
    let log = fixture("multiaxis.csv");
    let log = log.to_str().unwrap();
    let out = d.join("x.arrow");
    let out_s = out.to_str().unwrap();
    // simulate: blocks of 1M samples x 3 channels need more than 0.01 GB
    let (code, err) = run(
        &[
            "simulate",
            spec,
            "--duration",
            "1e9",
            "-o",
            out_s,
            "--memory-limit",
            "0.01",
        ],
        d,
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--duration 1e9 s") && err.contains("bytes") && err.contains("--memory-limit"),
        "{err}"
    );
    assert!(!out.exists());
    // the bootstrap's replicates
    let (code, err) = run(
        &[
            "select",
            log,
            "--channel",
            "gyro_x",
            "--bootstrap",
            "1000000000",
            "--memory-limit",
            "1",
        ],
        d,
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--bootstrap 1000000000") && err.contains("bytes"),
        "{err}"
    );
    // the gap ensemble's replicas
    let gspec = write(
        d,
        "g.toml",
        "sample_rate_hz = 10.0\n[[channel]]\nname = \"gyro_x\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.01\n",
    );
    let (code, err) = run(
        &[
            "gap",
            "--real",
            log,
            "--sim",
            &gspec,
            "--channel",
            "gyro_x",
            "--replicas",
            "1000000000",
            "-o",
            d.join("gap").to_str().unwrap(),
            "--memory-limit",
            "1",
        ],
        d,
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--replicas 1000000000") && err.contains("bytes"),
        "{err}"
    );
    // an inline farma model with d = 1e12 (its state: 8e12 bytes)
    let fspec = write(
        d,
        "f.toml",
        "sample_rate_hz = 10.0\n[[channel]]\nname = \"g\"\n[[channel.component]]\nkind = \"farma\"\np = 1\nq = 0\nd = 1000000000000\nf = [[0.5]]\nma = []\nsigma = 1.0\n",
    );
    let (code, err) = run(&["simulate", &fspec, "--duration", "10", "-o", out_s], d);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("'d' = 1000000000000") && err.contains("8e12 bytes"),
        "{err}"
    );
    // a bad --memory-limit
    let (code, err) = run(
        &[
            "simulate",
            spec,
            "--duration",
            "1",
            "-o",
            out_s,
            "--memory-limit=0",
        ],
        d,
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--memory-limit"), "{err}");
}

#[test]
fn overflowing_specs_are_refused_naming_the_component_and_the_value() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("x.arrow");
    let cases = [
        (
            "kind = \"gauss_markov\"\nsigma = 1e300\ntau_s = 1e300",
            "component 1 (gauss_markov): 'sigma' = 1e300",
        ),
        (
            "kind = \"bias_instability\"\nb = 1e300",
            "component 1 (bias_instability): 'b' = 1e300",
        ),
        (
            "kind = \"rate_ramp\"\nr = 1e307",
            "component 1 (rate_ramp): 'r' = 1e307",
        ),
    ];
    for (comp, want) in cases {
        let spec = write(
            d,
            "s.toml",
            &format!(
                "sample_rate_hz = 10.0\n[[channel]]\nname = \"g\"\n[[channel.component]]\n{comp}\n"
            ),
        );
        let (code, err) = run(
            &[
                "simulate",
                &spec,
                "--duration",
                "100",
                "-o",
                out.to_str().unwrap(),
            ],
            d,
        );
        assert_eq!(code, Some(2), "{comp}: {err}");
        assert!(err.contains(want), "{comp}: {err}");
        assert!(longest_word(&err) < 40, "{err}");
        assert!(!out.exists());
    }
    // a rate out of range is named as such (it was "--duration 10 s is too long")
    let text = std::fs::read_to_string(fixture("specs/adis16405_datasheet.toml")).unwrap();
    let text = text.replace("sample_rate_hz = 100.0", "sample_rate_hz = 1e300");
    let spec = write(d, "r.toml", &text);
    let (code, err) = run(
        &[
            "simulate",
            &spec,
            "--duration",
            "10",
            "-o",
            out.to_str().unwrap(),
        ],
        d,
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("sample rate 1e300 Hz") && err.contains("out of range"),
        "{err}"
    );
    assert!(!err.contains("too long"), "{err}");
}

/// What validation cannot predict (a temperature polynomial of degree 250 over a
/// 10 degC swing) is caught on the generated block, naming the component.
#[test]
fn a_non_finite_block_names_the_component_that_produced_it() {
    let coeffs: Vec<String> = (0..250)
        .map(|k| {
            if k == 249 {
                "1e90".into()
            } else {
                "0.0".to_string()
            }
        })
        .collect();
    let text = format!(
        "sample_rate_hz = 10.0\ntemperature_channel = \"t\"\n[[channel]]\nname = \"g\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.1\n[[channel.component]]\nkind = \"temperature_bias\"\ncoeffs = [{}]\nreference_c = 0.0\n",
        coeffs.join(", ")
    );
    let spec = parse_spec(&text, Path::new("t.toml")).unwrap();
    let temp: Vec<f64> = (0..1000).map(|k| 5.0 + k as f64 * 0.005).collect();
    let mut req = SimRequest::new(1000, 10.0);
    req.temperature_c = Some(&temp);
    let err = Simulator::new(&spec, req)
        .unwrap()
        .run()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("channel 'g' component 2 (temperature_bias) gives a non-finite value"),
        "{err}"
    );
}

/// A store with `values` as its channel `g` at 10 Hz (a store farma did not write
/// with its non-finite record: the simulator's output before it checked).
fn store_with(path: &Path, values: &[f64]) {
    let dir = path.parent().unwrap();
    let spec = write(
        dir,
        "w.toml",
        "sample_rate_hz = 10.0\n[[channel]]\nname = \"g\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.1\n",
    );
    let src = dir.join("src.arrow");
    let o = farma(
        &[
            "simulate",
            &spec,
            "--duration",
            &format!("{}", values.len() as f64 / 10.0),
            "-o",
            src.to_str().unwrap(),
        ],
        dir,
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = Store::open(&src).unwrap();
    let names: Vec<String> = vec!["time".into(), "g".into()];
    let mut w = StoreWriter::create(path, &names, values.len()).unwrap();
    {
        let mut cols = w.columns_mut();
        cols[0].copy_from_slice(s.column("time").unwrap());
        cols[1].copy_from_slice(values);
    }
    w.finish(s.meta()).unwrap();
}

#[test]
fn adev_and_psd_refuse_a_series_holding_inf_or_overflowing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut v: Vec<f64> = (0..4000)
        .map(|k| ((k * 7919) % 1000) as f64 * 1e-3)
        .collect();
    v[1234] = f64::INFINITY;
    let inf = d.join("inf.arrow");
    store_with(&inf, &v);
    for cmd in ["adev", "psd"] {
        let (code, err) = run(&[cmd, inf.to_str().unwrap(), "--channel", "g"], d);
        assert_eq!(code, Some(2), "{cmd}: {err}");
        assert!(
            err.contains("channel 'g'") && err.contains("sample 1234") && err.contains("inf"),
            "{cmd}: {err}"
        );
    }
    // finite values whose squares overflow: the cause, not "the log is too short"
    let big: Vec<f64> = (0..4000)
        .map(|k| if k % 2 == 0 { 1e200 } else { -1e200 })
        .collect();
    let huge = d.join("huge.arrow");
    store_with(&huge, &big);
    for cmd in ["adev", "psd"] {
        let (code, err) = run(&[cmd, huge.to_str().unwrap(), "--channel", "g"], d);
        assert_eq!(code, Some(2), "{cmd}: {err}");
        assert!(
            err.contains("overflows f64") && !err.contains("too short"),
            "{cmd}: {err}"
        );
        assert!(longest_word(&err) < 40, "{err}");
    }
}

/// `acf --max-lag` and `psd --segment` plan their FFT buffers against the limit: over it,
/// exit 2 naming the flag and the bytes; under it, the same request runs.
#[test]
fn acf_max_lag_and_psd_segment_are_planned_against_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let log = crate::common::fixture("multiaxis.csv");
    let log = log.to_str().unwrap();
    for (cmd, flag, value) in [("acf", "--max-lag", "3999"), ("psd", "--segment", "4000")] {
        let (code, err) = run(
            &[
                "--memory-limit",
                "0.00001",
                cmd,
                log,
                "--channel",
                "gyro_x",
                flag,
                value,
            ],
            dir.path(),
        );
        assert_eq!(code, Some(2), "{cmd}: {err}");
        assert!(
            err.contains(&format!("{flag} {value}"))
                && err.contains("bytes")
                && err.contains("--memory-limit"),
            "{err}"
        );
        let (code, err) = run(&[cmd, log, "--channel", "gyro_x", flag, value], dir.path());
        assert_eq!(code, Some(0), "{cmd}: {err}");
    }
}
