//! Ingest throughput: `farma ingest` on a >= 1 GB CSV beside pyarrow's
//! `pyarrow.csv.read_csv` on the same file in the same run.
//!
//! Run: `cargo bench --bench ingest` (needs `python3 -m pip install pyarrow` for the
//! peer; without it the peer is reported as missing). `FARMA_BENCH_GB` sets the size
//! (default 1.05), `FARMA_BENCH_DIR` where the file lives (default target/bench-data).
//! Each tool runs 3 times in a fresh process, best time reported, file in page cache.

#[path = "common/mod.rs"]
mod common;

use std::io::Write;
use std::process::Command;
use std::time::Instant;

fn write_csv(path: &std::path::Path, target_bytes: u64) {
    let f = std::fs::File::create(path).unwrap();
    let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
    writeln!(w, "time_s,gyro_x,gyro_y,gyro_z,temp_c").unwrap();
    let mut state: u64 = 0x9E3779B97F4A7C15;
    let mut next = || {
        // xorshift64*: a fast deterministic stream of doubles in [-1, 1).
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545F4914F6CDD1D) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    };
    let mut written = 0u64;
    let mut k = 0u64;
    let mut line = String::new();
    while written < target_bytes {
        line.clear();
        use std::fmt::Write as _;
        let t = k as f64 * 0.01;
        writeln!(
            line,
            "{t:.2},{:.9e},{:.9e},{:.9e},{:.4}",
            next() * 0.05,
            next() * 0.05,
            next() * 0.05,
            25.0 + next()
        )
        .unwrap();
        w.write_all(line.as_bytes()).unwrap();
        written += line.len() as u64;
        k += 1;
    }
    w.flush().unwrap();
}

fn child_ingest(input: &str, output: &str) {
    // Sample the anonymous (heap) memory while ingest runs: file-backed map pages are
    // in VmHWM too, but the kernel can drop them at will; RssAnon is what is held.
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let d2 = done.clone();
    let sampler = std::thread::spawn(move || {
        let mut peak = 0;
        while !d2.load(std::sync::atomic::Ordering::Relaxed) {
            peak = peak.max(common::proc_status_kib("RssAnon").unwrap_or(0));
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        peak
    });
    let t = Instant::now();
    let meta = farma::log::ingest(
        input.as_ref(),
        output.as_ref(),
        &farma::log::LogOptions::default(),
        &farma::log::Progress::hidden(),
    )
    .unwrap();
    let secs = t.elapsed().as_secs_f64();
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    let anon_peak = sampler.join().unwrap();
    let rows: u64 = meta.segments.iter().map(|s| s.len).sum();
    println!(
        "{secs} {rows} {} {anon_peak}",
        common::proc_status_kib("VmHWM").unwrap_or(0)
    );
}

fn run_child(input: &str, output: &str) -> (f64, u64, u64, u64) {
    let o = Command::new(std::env::current_exe().unwrap())
        .args(["--child-ingest", input, output])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = String::from_utf8(o.stdout).unwrap();
    let v: Vec<&str> = s.split_whitespace().collect();
    (
        v[0].parse().unwrap(),
        v[1].parse().unwrap(),
        v[2].parse().unwrap(),
        v[3].parse().unwrap(),
    )
}

fn run_pyarrow(input: &str) -> Option<(f64, u64, u64)> {
    let code = r#"
import sys, time, resource
import pyarrow.csv as pc
t = time.perf_counter()
tab = pc.read_csv(sys.argv[1])
dt = time.perf_counter() - t
print(dt, tab.num_rows, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"#;
    let o = Command::new("python3")
        .args(["-c", code, input])
        .output()
        .ok()?;
    if !o.status.success() {
        eprintln!(
            "pyarrow peer failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        return None;
    }
    let s = String::from_utf8(o.stdout).ok()?;
    let v: Vec<&str> = s.split_whitespace().collect();
    Some((v[0].parse().ok()?, v[1].parse().ok()?, v[2].parse().ok()?))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() == 4 && args[1] == "--child-ingest" {
        child_ingest(&args[2], &args[3]);
        return;
    }
    let gb: f64 = std::env::var("FARMA_BENCH_GB")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.05);
    let target = (gb * 1e9) as u64;
    let dir = common::bench_dir();
    let csv = dir.join(format!("ingest_{target}.csv"));
    if std::fs::metadata(&csv)
        .map(|m| m.len() < target)
        .unwrap_or(true)
    {
        eprintln!("writing {} ...", csv.display());
        write_csv(&csv, target);
    }
    let bytes = std::fs::metadata(&csv).unwrap().len();
    let mb = bytes as f64 / 1e6;
    let out = dir.join("ingest_out.arrow");
    let (csv_s, out_s) = (csv.to_str().unwrap(), out.to_str().unwrap());
    // Warm the page cache once so both tools read from memory.
    let _ = std::fs::read(&csv).map(|v| v.len());

    let mut farma_best = f64::INFINITY;
    let mut farma_rows = 0;
    let mut farma_hwm = 0;
    let mut farma_anon = 0;
    let mut py_best = f64::INFINITY;
    let mut py_rows = 0;
    let mut py_hwm = 0;
    let mut have_py = true;
    for _ in 0..3 {
        let (s, rows, hwm, anon) = run_child(csv_s, out_s);
        farma_best = farma_best.min(s);
        farma_rows = rows;
        farma_hwm = farma_hwm.max(hwm);
        farma_anon = farma_anon.max(anon);
        if have_py {
            match run_pyarrow(csv_s) {
                Some((s, rows, hwm)) => {
                    py_best = py_best.min(s);
                    py_rows = rows;
                    py_hwm = py_hwm.max(hwm);
                }
                None => have_py = false,
            }
        }
    }
    let _ = std::fs::remove_file(&out);
    println!("machine: {}", common::machine());
    println!(
        "input: {} ({mb:.0} MB, {farma_rows} rows x 5 columns)",
        csv.display()
    );
    println!(
        "farma ingest:          {farma_best:.3} s  {:.0} MB/s  peak RSS {:.0} MiB, of which anonymous (heap) {:.1} MiB; the rest are file-backed map pages",
        mb / farma_best,
        farma_hwm as f64 / 1024.0,
        farma_anon as f64 / 1024.0
    );
    if have_py {
        assert_eq!(py_rows, farma_rows);
        println!(
            "pyarrow.csv.read_csv:  {py_best:.3} s  {:.0} MB/s  peak RSS {:.0} MiB (table in memory)",
            mb / py_best,
            py_hwm as f64 / 1024.0
        );
        println!(
            "ratio farma / pyarrow throughput: {:.2}",
            py_best / farma_best
        );
    } else {
        println!("pyarrow: not available (python3 -m pip install pyarrow)");
    }
}
