//! Simulator throughput: samples per second of `farma::simulator::simulate` for the
//! every-component spec (fixtures/specs/every_component.toml, its fitted FARMA replaced
//! by an inline one so that no fit output is needed), per component, beside two floors
//! and a peer measured in the same run:
//! - floor: one parallel pass that writes a fresh Vec<f64> of the same length (the
//!   least any generator that returns a Vec must pay);
//! - peer: numpy (default_rng, PCG64) white noise + a random walk (`standard_normal`
//!   twice, `cumsum`, scale, add), timed in a fresh python3 process around the
//!   generation only, beside farma simulating the same two components
//!   (white_noise + rate_random_walk) on one channel.
//!
//! Run: `cargo bench --bench simulate` (numpy for the peer: `python3 -m pip install
//! numpy`; without it the peer is reported as missing). `FARMA_BENCH_N` sets the
//! number of samples per channel (default 1e7). Best of 3 for every farma figure.

#[path = "common/mod.rs"]
mod common;

use std::process::Command;
use std::time::Instant;

use farma::simulator::{SimRequest, Simulator, parse_spec, simulate};
use rayon::prelude::*;

const FS: f64 = 10.0;

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..runs {
        let t = Instant::now();
        let v = f();
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(v);
    }
    (best, last.unwrap())
}

const PEER: &str = r#"
import sys, time, json
import numpy as np
n = int(sys.argv[1])
rng = np.random.default_rng(7)
t0 = time.perf_counter()
y = 0.005 * np.sqrt(10.0) * rng.standard_normal(n)
y += np.cumsum(rng.standard_normal(n)) * (0.0002 / np.sqrt(10.0))
t1 = time.perf_counter()
print(json.dumps({"secs": t1 - t0, "version": np.__version__, "check": float(y[-1])}))
"#;

fn main() {
    let n: usize = std::env::var("FARMA_BENCH_N")
        .ok()
        .map(|s| s.parse::<f64>().expect("FARMA_BENCH_N") as usize)
        .unwrap_or(10_000_000);
    println!("machine: {}", common::machine());
    println!(
        "samples per channel: {n} at {FS} Hz, threads: {}",
        rayon::current_num_threads()
    );

    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/specs/every_component.toml"
    );
    let text = std::fs::read_to_string(path).unwrap().replace(
        "model = \"fits/gyro_y\"            # an output folder of `farma fit`\nchannel = \"gyro_y\"               # optional: which fitted channel",
        "p = 1\nq = 0\nd = 1\nf = [[0.3, 0.05]]\nma = []\nsigma = 0.002",
    );
    let spec = parse_spec(&text, std::path::Path::new(path)).unwrap();
    let temp: Vec<f64> = (0..n)
        .map(|k| 25.0 + 3.0 * (k as f64 / FS / 3600.0).sin())
        .collect();
    let mut req = SimRequest::new(n, FS);
    req.temperature_c = Some(&temp);

    // Floor: one pass writing a fresh Vec<f64>.
    let (floor_s, v) = best_of(3, || {
        let mut v = vec![0.0f64; n];
        v.par_chunks_mut(1 << 16).enumerate().for_each(|(c, s)| {
            for (j, x) in s.iter_mut().enumerate() {
                *x = ((c << 16) + j) as f64;
            }
        });
        v
    });
    drop(v);
    println!(
        "floor (write a Vec<f64>): {floor_s:.3} s, {:.1} M samples/s",
        n as f64 / floor_s / 1e6
    );

    let n_ch = spec.channels.len();
    let (all_s, out) = best_of(3, || simulate(&spec, &req).unwrap());
    assert!(
        out.channels
            .iter()
            .all(|(_, v)| v.iter().all(|x| x.is_finite()))
    );
    drop(out);
    println!(
        "every component, {n_ch} channels: {all_s:.3} s, {:.2} M samples/s per channel, {:.2} M channel-samples/s",
        n as f64 / all_s / 1e6,
        (n * n_ch) as f64 / all_s / 1e6
    );

    let sim = Simulator::new(&spec, req.clone()).unwrap();
    for (ci, ch) in spec.channels.iter().enumerate() {
        for (k, c) in ch.components.iter().enumerate() {
            let (s, v) = best_of(3, || sim.component_signal(ci, k).unwrap());
            drop(v);
            println!(
                "  {:<8} {:>2} {:<18} {:>8.3} s  {:>8.1} M samples/s",
                ch.name,
                k + 1,
                c.kind().as_str(),
                s,
                n as f64 / s / 1e6
            );
        }
    }

    // White noise + random walk beside numpy.
    let wr = parse_spec(
        "sample_rate_hz = 10.0\nseed = 7\n[[channel]]\nname = \"x\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.005\n[[channel.component]]\nkind = \"rate_random_walk\"\nk = 0.0002\n",
        std::path::Path::new("wr.toml"),
    )
    .unwrap();
    let (wr_s, v) = best_of(3, || simulate(&wr, &SimRequest::new(n, FS)).unwrap());
    drop(v);
    println!(
        "farma white_noise + rate_random_walk: {wr_s:.3} s, {:.1} M samples/s",
        n as f64 / wr_s / 1e6
    );
    let peer = Command::new("python3")
        .args(["-c", PEER, &n.to_string()])
        .output();
    match peer {
        Ok(o) if o.status.success() => {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("peer JSON");
            let secs = v["secs"].as_f64().unwrap();
            println!(
                "numpy {} white + cumsum random walk: {secs:.3} s, {:.1} M samples/s; farma / numpy speed: {:.2}x",
                v["version"].as_str().unwrap_or("?"),
                n as f64 / secs / 1e6,
                secs / wr_s
            );
        }
        Ok(o) => println!("peer numpy: failed: {}", String::from_utf8_lossy(&o.stderr)),
        Err(e) => println!("peer numpy: missing ({e})"),
    }
}
