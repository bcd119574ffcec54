//! Benchmark of the gap diagnosis (`farma gap`): one diagnosis of a 4-hour 10 Hz channel
//! with M = 20 replicas and every candidate, timed; then the project's bank
//! (src/diagnosis/bank.rs) over several seeds, at one hour and four hours, with and
//! without the temperature channel where a case allows it: top-1 attribution and the
//! withheld-part gap after the right effect against the noise floor.
//!
//!     cargo bench --bench gap               (FARMA_BENCH_SEEDS=3 by default)

use std::time::Instant;

use farma::diagnosis::bank::{self, CHANNEL};
use farma::diagnosis::{GapParams, RealLog, diagnose};

fn main() {
    let seeds: u64 = std::env::var("FARMA_BENCH_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let rate_hz = 10.0;
    let threads = rayon::current_num_threads();
    println!("farma gap benchmark: {threads} threads");

    // one timed diagnosis: 4 hours at 10 Hz, M = 20, every candidate (temperature case)
    let cases = bank::cases(rate_hz);
    let case = cases
        .iter()
        .find(|c| c.expect == "temperature_bias")
        .unwrap();
    let n4h = 144_000;
    let (x, temp) = bank::real_log(case, n4h, 42).unwrap();
    let real = RealLog {
        channel: CHANNEL.into(),
        x: &x,
        rate_hz,
        temperature_c: temp.as_deref(),
        others: vec![],
        spec_dir: None,
    };
    let prm = GapParams {
        replicas: 20,
        ..GapParams::default()
    };
    for run in 0..2 {
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
        let (mut t, mut ok, mut cl) = (0, 0, 0);
        // cases that do not need the temperature run both without and with it (then the
        // temperature candidates compete too)
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
