//! `farma simulate` by blocks (issue 29, items 1 and 9): the generator carries every
//! component's state (recursions, random walks, Gauss-Markov banks, quantization's
//! last angle error, the random streams' chunk numbers) from block to block, so that a
//! log written block by block in bounded memory is bit for bit the whole-series
//! simulation, whatever the block size.

use std::path::Path;

use farma::simulator::generate::streams::CHUNK;
use farma::simulator::{SimRequest, Simulator, load_spec, parse_spec};
use farma::store::Store;

use crate::common::{farma, fixture, stderr};

/// FNV-1a 64 of the values' little-endian bytes.
fn fnv(values: &[f64]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in values {
        for b in v.to_le_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x100_0000_01b3);
        }
    }
    h
}

/// The adis16405 datasheet spec at 100 Hz, 700000 samples (10.7 chunks), seed 5: the
/// hashes of the channels written by the whole-series generator before it worked by
/// blocks (farma 78d43cd, `simulate --duration 7000 -o x.csv`, hashed from the CSV).
const GOLDEN: [(&str, u64); 3] = [
    ("gyro_x_dps", 0x45fd_c94a_e276_8c16),
    ("gyro_y_dps", 0x5504_8f31_ed62_02b3),
    ("gyro_z_dps", 0x737e_490d_eee3_a4e3),
];

/// Every channel's values of `sim` by blocks of `block` samples.
fn by_blocks(sim: &Simulator, block: usize) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = Vec::new();
    let mut blocks = sim.blocks(block).unwrap();
    let mut next = 0;
    while let Some((start, cols)) = blocks.next_block().unwrap() {
        assert_eq!(start, next);
        next += cols[0].len();
        if out.is_empty() {
            out = vec![Vec::new(); cols.len()];
        }
        for (o, c) in out.iter_mut().zip(cols) {
            o.extend_from_slice(&c);
        }
    }
    out
}

#[test]
fn blocks_give_the_whole_series_generators_values() {
    let spec = load_spec(&fixture("specs/adis16405_datasheet.toml")).unwrap();
    let sim = Simulator::new(&spec, SimRequest::new(700_000, 100.0)).unwrap();
    let whole = sim.run().unwrap();
    for ((name, want), (got_name, v)) in GOLDEN.iter().zip(&whole.channels) {
        assert_eq!(name, got_name);
        assert_eq!(
            fnv(v),
            *want,
            "{name}: not the whole-series generator's values"
        );
    }
    for block in [CHUNK, 3 * CHUNK, 1 << 20] {
        let b = by_blocks(&sim, block);
        for ((name, v), w) in whole.channels.iter().zip(&b) {
            assert!(
                v == w,
                "{name}: blocks of {block} differ from the whole series"
            );
        }
    }
}

/// Every component kind (the fitted farma model aside: inline farma and arma carry the
/// same recursion state), with a temperature series: blocks of 1 and 2 chunks and of
/// a size that is not a multiple of a chunk (rounded up to one) give the whole series.
#[test]
fn blocks_of_every_component_kind_give_the_whole_series() {
    let text = std::fs::read_to_string(fixture("specs/every_component.toml")).unwrap();
    let i = text
        .find("[[channel.component]]\nkind = \"farma\"\nmodel")
        .unwrap();
    let j = i + text[i + 5..].find("[[channel.component]]").unwrap() + 5;
    let text = format!("{}{}", &text[..i], &text[j..]);
    let spec = parse_spec(&text, Path::new("every.toml")).unwrap();
    let n = 3 * CHUNK + 1234;
    let temp: Vec<f64> = (0..n)
        .map(|k| 25.0 + 3.0 * (k as f64 * 1e-4).sin() + 0.01 * (k as f64 * 0.37).cos())
        .collect();
    let mut req = SimRequest::new(n, 10.0);
    req.temperature_c = Some(&temp);
    let sim = Simulator::new(&spec, req).unwrap();
    let whole = sim.run().unwrap();
    assert_eq!(whole.channels.len(), 3);
    for block in [CHUNK, 2 * CHUNK, CHUNK + 1] {
        let b = by_blocks(&sim, block);
        for ((name, v), w) in whole.channels.iter().zip(&b) {
            assert_eq!(v.len(), n);
            assert!(
                v == w,
                "{name}: blocks of {block} differ from the whole series"
            );
        }
    }
}

/// The CLI writes by blocks (1M rows) into a store and a CSV: the golden values.
#[test]
fn the_written_logs_hold_the_golden_values() {
    let dir = tempfile::tempdir().unwrap();
    let spec = fixture("specs/adis16405_datasheet.toml");
    let store = dir.path().join("s.arrow");
    let csv = dir.path().join("s.csv");
    for out in [&store, &csv] {
        let o = farma(
            &[
                "simulate",
                spec.to_str().unwrap(),
                "--duration",
                "7000",
                "-o",
                out.to_str().unwrap(),
            ],
            dir.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    let s = Store::open(&store).unwrap();
    for (name, want) in GOLDEN {
        assert_eq!(fnv(s.column(name).unwrap()), want, "{name} in the store");
    }
    s.verify().unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); 3];
    for line in text.lines().skip(2) {
        for (c, v) in cols.iter_mut().zip(line.split(',').skip(1)) {
            c.push(v.parse().unwrap());
        }
    }
    for ((name, want), c) in GOLDEN.iter().zip(&cols) {
        assert_eq!(fnv(c), *want, "{name} in the CSV");
    }
}
