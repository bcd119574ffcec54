//! Benchmark of the gap diagnosis (`farma gap`): one diagnosis of a 4-hour 10 Hz channel
//! with M = 20 replicas and every candidate, timed; then the project's bank
//! (src/diagnosis/bank.rs) over several seeds, at one hour and four hours, with and
//! without the temperature channel where a case allows it: top-1 attribution and the
//! withheld-part gap after the right effect against the noise floor.
//!
//!     cargo bench --bench gap               (FARMA_BENCH_SEEDS=3 by default)
//!
//! Knobs for a partial run: FARMA_BENCH_CASES=kind,kind (only those hidden effects),
//! FARMA_BENCH_HOURS=1 or 4 (one size), FARMA_BENCH_TIMED=0 (skip the timed runs),
//! FARMA_BENCH_VERBOSE=1 (the three best effects of each case with their family gaps).

use std::time::Instant;

use farma::diagnosis::bank::{self, CHANNEL};
use farma::diagnosis::{GapParams, RealLog, diagnose};

fn main() {
    let seeds: u64 = std::env::var("FARMA_BENCH_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let env = |k: &str| std::env::var(k).ok();
    let only: Option<Vec<String>> =
        env("FARMA_BENCH_CASES").map(|s| s.split(',').map(|x| x.trim().to_string()).collect());
    let hours: Option<u32> = env("FARMA_BENCH_HOURS").and_then(|s| s.parse().ok());
    let timed = env("FARMA_BENCH_TIMED").as_deref() != Some("0");
    let verbose = env("FARMA_BENCH_VERBOSE").as_deref() == Some("1");
    let rate_hz = 10.0;
    let threads = rayon::current_num_threads();
    println!("farma gap benchmark: {threads} threads");

    // one timed diagnosis: 4 hours at 10 Hz, M = 20, every candidate (temperature case)
    let n4h = 144_000;
    let cases4 = bank::cases(rate_hz, 14_400.0);
    let case = cases4
        .iter()
        .find(|c| c.expect == "temperature_bias")
        .unwrap();
    let (x, temp) = bank::real_log(case, n4h, 42).unwrap();
    let real = RealLog {
        channel: CHANNEL.into(),
        x: &x,
        rate_hz,
        temperature_c: temp.as_deref(),
        others: vec![],
        spec_dir: None,
        scan: Vec::new(),
        beyond: &[],
    };
    let prm = GapParams {
        replicas: 20,
        ..GapParams::default()
    };
    for run in 0..if timed { 2 } else { 0 } {
        let t0 = Instant::now();
        let d = diagnose(&real, &case.spec, &prm).unwrap();
        println!(
            "run {run}: 4 h at 10 Hz (144,000 samples), M = 20, {} candidates scored in round 1, {} effects added: {:.2} s (gap {:.2} -> {:.2}, floor {:.2})",
            d.effects.len(),
            d.added.len(),
            t0.elapsed().as_secs_f64(),
            d.gap_before,
            d.gap_after,
            d.noise_floor
        );
    }

    println!(
        "\nbank: case, size, seed -> first-ranked effect, gap before -> after the first effect (floor)"
    );
    let mut total = 0;
    let mut top1 = 0;
    let mut closed = 0;
    let mut by_size = Vec::new();
    for (label, n) in [("1 h", 36_000usize), ("4 h", 144_000)] {
        if hours.is_some_and(|h| (h == 1) != (n == 36_000)) {
            continue;
        }
        let (mut t, mut ok, mut cl) = (0, 0, 0);
        // cases that do not need the temperature run both without and with it (then the
        // temperature candidates compete too)
        let cases = bank::cases(rate_hz, n as f64 / rate_hz);
        let variants: Vec<bank::Case> = cases
            .iter()
            .flat_map(|c| {
                let mut v = vec![c.clone()];
                if c.spec.temperature_channel.is_none() {
                    let mut w = c.clone();
                    w.spec.temperature_channel = Some(bank::TEMP.into());
                    w.truth.temperature_channel = Some(bank::TEMP.into());
                    v.push(w);
                }
                v
            })
            .collect();
        for (i, case) in variants.iter().enumerate() {
            // the seed follows the case's place in the whole bank, so that a partial run
            // (FARMA_BENCH_CASES) reproduces the same logs
            if only.as_ref().is_some_and(|o| !o.contains(&case.expect)) {
                continue;
            }
            for s in 0..seeds {
                let seed = 10_000 + 100 * i as u64 + s;
                let (x, temp) = bank::real_log(case, n, seed).unwrap();
                let real = RealLog {
                    channel: CHANNEL.into(),
                    x: &x,
                    rate_hz,
                    temperature_c: temp.as_deref(),
                    others: vec![],
                    spec_dir: None,
                    scan: Vec::new(),
                    beyond: &[],
                };
                let d = diagnose(
                    &real,
                    &case.spec,
                    &GapParams {
                        replicas: 20,
                        ..GapParams::default()
                    },
                )
                .unwrap();
                let first = d
                    .effects
                    .first()
                    .map(|e| e.kind.clone())
                    .unwrap_or_default();
                let after = d.effects.first().map(|e| e.gap_after).unwrap_or(f64::NAN);
                let hit = first == case.expect;
                let near = hit && after <= 2.0 * d.noise_floor;
                t += 1;
                ok += usize::from(hit);
                cl += usize::from(near);
                println!(
                    "  {:<24} {label} temp={} seed {seed}: {:<24} {:>7.2} -> {:>5.2} ({:.2}){}",
                    case.expect,
                    case.spec.temperature_channel.is_some(),
                    first,
                    d.gap_before,
                    after,
                    d.noise_floor,
                    if hit { "" } else { "   <- miss" }
                );
                if verbose {
                    let fams = |f: &[(farma::diagnosis::Statistic, f64)]| {
                        f.iter()
                            .map(|(s, g)| format!("{s:?} {g:.2}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    };
                    for e in d.effects.iter().take(3) {
                        println!(
                            "      {:<28} {:>6.2}  {}  {}",
                            e.kind,
                            e.gap_after,
                            fams(&e.families),
                            e.params
                        );
                    }
                    let before = fams(&d.family_before);
                    println!("      {:<28} {:>6.2}  {before}", "(before)", d.gap_before);
                }
            }
        }
        by_size.push((label, t, ok, cl));
        total += t;
        top1 += ok;
        closed += cl;
    }
    println!();
    for (label, t, ok, cl) in &by_size {
        println!("{label}: top-1 {ok}/{t}, gap within 2x floor after the right effect {cl}/{t}");
    }
    println!("all: top-1 {top1}/{total}, within 2x floor {closed}/{total}");
}
