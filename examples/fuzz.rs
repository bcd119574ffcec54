//! A mutation fuzzer on stable Rust (no nightly here, so no cargo-fuzz): the readers of
//! every input farma takes, fed mutated copies of the seeds in `fixtures/`.
//!
//!     cargo run --release --example fuzz -- TARGET SECONDS [OUT_DIR]
//!     bash benches/fuzz.sh TARGET SECONDS      # the same, restarted after an abort
//!
//! TARGET: `csv`, `parquet`, `arrow` (ingest of a log: format sniffing, the reader, the
//! time base and NaN policies, the store writer), `spec` (the simulation spec parser and
//! validator), `store` (opening, verifying and reading a farma store). Each input runs
//! in-process under `catch_unwind`, on a worker thread watched by a per-input timeout
//! (10 s). A panic is saved as `OUT_DIR/crash-N.bin`, a hang as `OUT_DIR/hang.bin` (and
//! the fuzzer exits 3); the input being run is always in `OUT_DIR/current.bin`, so an
//! abort (which no Rust code can catch) leaves it behind for benches/fuzz.sh to keep.
//! Mutations: bit flips, random bytes, inserted and deleted runs, duplicated runs,
//! splices of two seeds, truncation, and tokens (delimiters, newlines, `NaN`, numbers
//! at the limits of f64, 0xFF runs, Arrow and Parquet magic).

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const TOKENS: &[&[u8]] = &[
    b",",
    b";",
    b"\t",
    b"\n",
    b"\r\n",
    b"\"",
    b"#",
    b"NaN",
    b"inf",
    b"-",
    b"1e308",
    b"1e-320",
    b"1e309",
    b"0",
    b"9007199254740993",
    b"time",
    b"PAR1",
    b"ARROW1",
    b"\xff\xff\xff\xff",
    b"\x00",
    b"\xef\xbb\xbf",
    b"=",
    b"[",
    b"]",
    b"[[channel]]",
    b"1e300",
];

fn seeds(target: &str, root: &Path) -> Vec<Vec<u8>> {
    let f = root.join("fixtures");
    let mut files: Vec<PathBuf> = match target {
        "csv" => vec![f.join("multiaxis.csv")],
        "parquet" => vec![
            f.join("multiaxis.parquet"),
            f.join("foreign/crc.parquet"),
            f.join("foreign/int64_big.parquet"),
        ],
        "arrow" => vec![
            f.join("foreign/lz4.arrow"),
            f.join("foreign/zstd.arrow"),
            f.join("foreign/stream.arrows"),
            f.join("foreign/int64_2p53.arrow"),
            f.join("foreign/v1.feather"),
        ],
        "spec" => vec![
            f.join("specs/adis16405_datasheet.toml"),
            f.join("specs/every_component.toml"),
        ],
        "store" => vec![],
        _ => panic!("unknown target {target}: csv, parquet, arrow, spec or store"),
    };
    let dir_seeds = |d: &Path, ext: &str| -> Vec<PathBuf> {
        std::fs::read_dir(d)
            .map(|rd| {
                rd.flatten()
                    .map(|e| e.path())
                    .filter(|p| p.extension().is_some_and(|x| x == ext))
                    .collect()
            })
            .unwrap_or_default()
    };
    match target {
        "csv" => files.extend(dir_seeds(&f.join("bad"), "csv")),
        "spec" => files.extend(dir_seeds(&f.join("specs/bad"), "toml")),
        _ => {}
    }
    let mut out: Vec<Vec<u8>> = files.iter().filter_map(|p| std::fs::read(p).ok()).collect();
    if target == "store" {
        // a store of the bundled log, written once
        let dir = tempfile::tempdir().unwrap();
        let s = dir.path().join("s.arrow");
        farma::log::ingest(
            &f.join("multiaxis.csv"),
            &s,
            &Default::default(),
            &farma::log::Progress::hidden(),
        )
        .expect("ingest the seed store");
        out.push(std::fs::read(&s).unwrap());
    }
    // CSV seeds are cut to their first 60 lines: small inputs mutate faster
    if target == "csv" {
        for s in &mut out {
            let cut = s
                .iter()
                .enumerate()
                .filter(|(_, b)| **b == b'\n')
                .nth(60)
                .map_or(s.len(), |(i, _)| i + 1);
            s.truncate(cut);
        }
    }
    assert!(!out.is_empty(), "no seeds for {target}");
    out
}

fn mutate(rng: &mut ChaCha8Rng, seeds: &[Vec<u8>], base: &[u8]) -> Vec<u8> {
    let mut v = base.to_vec();
    let n = 1 + rng.random_range(0..4);
    for _ in 0..n {
        let len = v.len();
        match rng.random_range(0..9) {
            0 if len > 0 => {
                let i = rng.random_range(0..len);
                v[i] ^= 1 << rng.random_range(0..8);
            }
            1 if len > 0 => {
                let i = rng.random_range(0..len);
                v[i] = rng.random();
            }
            2 => {
                let i = rng.random_range(0..=len);
                let k = rng.random_range(1..16);
                let ins: Vec<u8> = (0..k).map(|_| rng.random()).collect();
                v.splice(i..i, ins);
            }
            3 if len > 0 => {
                let i = rng.random_range(0..len);
                let k = rng.random_range(1..=(len - i).min(256));
                v.drain(i..i + k);
            }
            4 if len > 0 => {
                let i = rng.random_range(0..len);
                let k = rng.random_range(1..=(len - i).min(512));
                let dup = v[i..i + k].to_vec();
                let j = rng.random_range(0..=len);
                v.splice(j..j, dup);
            }
            5 => {
                let other = &seeds[rng.random_range(0..seeds.len())];
                if !other.is_empty() && len > 0 {
                    let i = rng.random_range(0..len);
                    let j = rng.random_range(0..other.len());
                    v.truncate(i);
                    v.extend_from_slice(&other[j..]);
                }
            }
            6 if len > 0 => {
                let i = rng.random_range(0..len);
                v.truncate(i);
            }
            7 => {
                let t = TOKENS[rng.random_range(0..TOKENS.len())];
                let i = rng.random_range(0..=len);
                v.splice(i..i, t.iter().copied());
            }
            _ if len >= 4 => {
                // an interesting little-endian integer over 4 bytes
                let i = rng.random_range(0..len - 3);
                let x: u32 =
                    [0, 1, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, 64, 4096][rng.random_range(0..7)];
                v[i..i + 4].copy_from_slice(&x.to_le_bytes());
            }
            _ => {}
        }
    }
    v.truncate(1 << 20);
    v
}

/// Runs one input through `target` in `dir`; Err(message) on a panic.
fn run_one(target: &str, input: &[u8], dir: &Path) -> Result<(), String> {
    let ext = match target {
        "csv" => "csv",
        "parquet" => "parquet",
        "spec" => "toml",
        _ => "arrow",
    };
    let path = dir.join(format!("in.{ext}"));
    if std::fs::write(&path, input).is_err() {
        return Ok(()); // a full disk: not the target's failure
    }
    let out = dir.join("out.arrow");
    let r = std::panic::catch_unwind(AssertUnwindSafe(|| match target {
        "spec" => {
            if let Ok(text) = std::str::from_utf8(input) {
                let _ = farma::simulator::parse_spec(text, &path);
            }
        }
        "store" => {
            if let Ok(s) = farma::store::Store::open(&path) {
                let _ = s.verify();
                for n in s.column_names() {
                    if let Ok(c) = s.column_with_nonfinite(n) {
                        std::hint::black_box(c.iter().sum::<f64>());
                    }
                }
            }
        }
        _ => {
            let opts = farma::log::LogOptions {
                rate_hz: Some(10.0),
                ..Default::default()
            };
            let _ = farma::log::ingest(&path, &out, &opts, &farma::log::Progress::hidden());
            let _ = std::fs::remove_file(&out);
        }
    }));
    r.map_err(|p| {
        p.downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "panic".into())
    })
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: fuzz TARGET SECONDS [OUT_DIR]");
        std::process::exit(2);
    }
    let target = args[1].clone();
    let secs: f64 = args[2].parse().expect("SECONDS");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out_dir = args
        .get(3)
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target/fuzz").join(&target));
    std::fs::create_dir_all(&out_dir).unwrap();
    let seeds = seeds(&target, &root);
    std::panic::set_hook(Box::new(|_| {}));
    let seed: u64 = std::env::var("FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos() as u64
        });
    let mut rng = ChaCha8Rng::seed_from_u64(seed);

    // the worker: runs inputs sent to it, answers with the outcome
    let (tx_in, rx_in) = mpsc::channel::<Vec<u8>>();
    let (tx_out, rx_out) = mpsc::channel::<Result<(), String>>();
    let work = tempfile::tempdir().unwrap();
    let work_path = work.path().to_path_buf();
    let t = target.clone();
    std::thread::spawn(move || {
        for input in rx_in {
            let _ = tx_out.send(run_one(&t, &input, &work_path));
        }
    });

    let start = Instant::now();
    let (mut runs, mut crashes) = (0u64, 0u64);
    let mut corpus = seeds.clone();
    while start.elapsed().as_secs_f64() < secs {
        let base = &corpus[rng.random_range(0..corpus.len())];
        let input = if runs < seeds.len() as u64 {
            seeds[runs as usize].clone()
        } else {
            mutate(&mut rng, &seeds, base)
        };
        // (a full disk must not stop the fuzzer: the input is then only not kept)
        let _ = std::fs::write(out_dir.join("current.bin"), &input);
        tx_in.send(input.clone()).unwrap();
        match rx_out.recv_timeout(Duration::from_secs(10)) {
            Ok(Ok(())) => {}
            Ok(Err(msg)) => {
                crashes += 1;
                let p = out_dir.join(format!("crash-{crashes}.bin"));
                std::fs::write(&p, &input).unwrap();
                eprintln!(
                    "fuzz {target}: panic ({msg}); input saved as {}",
                    p.display()
                );
            }
            Err(_) => {
                let p = out_dir.join("hang.bin");
                std::fs::write(&p, &input).unwrap();
                eprintln!(
                    "fuzz {target}: an input ran over 10 s; saved as {}",
                    p.display()
                );
                std::process::exit(3);
            }
        }
        runs += 1;
        // keep some mutants as bases: the corpus drifts away from the seeds
        if runs % 50 == 0 && corpus.len() < 200 {
            corpus.push(mutate(&mut rng, &seeds, base));
        }
    }
    let _ = std::fs::remove_file(out_dir.join("current.bin"));
    println!(
        "fuzz {target}: {runs} inputs in {:.0} s, {crashes} panic(s), seed {seed}",
        start.elapsed().as_secs_f64()
    );
    std::process::exit(if crashes > 0 { 1 } else { 0 });
}
