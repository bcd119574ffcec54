//! The sensor's output path (issue 27): output_filter, saturation and output_resolution
//! as spec components that `farma simulate` applies, block by block, to the sum of the
//! other components, and their estimates from a log (the value grid, the PSD's
//! roll-off, the pile at the extremes), on simulated data with known values and on the
//! real ADIS16405 run 1 (its 0.05 deg/s output step).

use std::path::Path;

use farma::diagnosis::candidates::output_path::{output_filter, saturation, value_grid};
use farma::simulator::generate::streams::CHUNK;
use farma::simulator::{SimRequest, Simulator, parse_spec};

use crate::common::{farma, fixture, realdata, stderr};

const SPEC: &str = r#"
sample_rate_hz = 100.0
seed = 3

[[channel]]
name = "x"

[[channel.component]]
kind = "output_resolution"     # listed first: the path's order does not follow the spec's
quantum = 0.05
on_angle = true

[[channel.component]]
kind = "white_noise"
n = 0.035

[[channel.component]]
kind = "constant_bias"
value = 0.3

[[channel.component]]
kind = "gauss_markov"
sigma = 0.2
tau_s = 20.0

[[channel.component]]
kind = "cross_axis"
from = "y"
gain = 0.5

[[channel.component]]
kind = "output_filter"
order = 2
bandwidth_hz = 15.0
damping = 0.8

[[channel.component]]
kind = "saturation"
limit = 1.0

[[channel]]
name = "y"

[[channel.component]]
kind = "white_noise"
n = 0.02
"#;

/// Whole series, blocks of any size, and the sum of the component signals (what the
/// gap diagnosis's ensemble adds up) give the same channel; its values sit on the grid
/// and within the range, and the integrated angle of the grid's rate stays within half
/// an angle quantum of the unrounded one.
#[test]
fn the_output_path_is_applied_in_order_and_carried_across_blocks() {
    let spec = parse_spec(SPEC, Path::new("spec.toml")).unwrap();
    let n = 2 * CHUNK + 777;
    let sim = Simulator::new(&spec, SimRequest::new(n, 100.0)).unwrap();
    let whole = sim.run().unwrap();
    let x = whole.channel("x").unwrap();
    for block in [CHUNK, CHUNK + 1, 5 * CHUNK] {
        let mut blocks = sim.blocks(block).unwrap();
        let mut got = Vec::new();
        while let Some((_, cols)) = blocks.next_block().unwrap() {
            got.extend_from_slice(&cols[0]);
        }
        assert!(got == x, "blocks of {block} differ from the whole series");
    }
    assert!(
        x.iter()
            .all(|v| (v / 0.05 - (v / 0.05).round()).abs() < 1e-9)
    );
    // saturation at 1.0 then rounding: never beyond the limit's grid value
    assert!(x.iter().all(|v| v.abs() <= 1.0 + 1e-9));
    assert!(x.iter().filter(|v| (v.abs() - 1.0).abs() < 1e-9).count() > 10);
    // the sum of the component signals is the channel
    let ch = sim.channel_index("x").unwrap();
    let mut sum = vec![0.0; n];
    for k in 0..spec.channels[0].components.len() {
        for (s, v) in sum.iter_mut().zip(sim.component_signal(ch, k).unwrap()) {
            *s += v;
        }
    }
    let worst = sum
        .iter()
        .zip(x)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "sum of parts off by {worst}");
    // the output resolution's signal alone is what the rounding changed; on the angle
    // its running sum (the angle's rounding error, in quanta) stays within half a quantum
    let q_part = sim.component_signal(ch, 0).unwrap();
    let mut angle = 0.0f64;
    for v in &q_part {
        angle += v / 0.05;
        assert!(angle.abs() <= 0.5 + 1e-6, "angle error {angle} quanta");
    }
}

/// The FIR form against scipy.signal.lfilter (fixtures/golden/fir_golden.csv, made by
/// make_fir_golden.py): the output path run on the whole input and in blocks of 1, 7
/// and 64 samples (the history carried across) gives lfilter's values within 1e-12.
#[test]
fn the_fir_output_filter_is_scipys_lfilter_across_blocks() {
    use farma::simulator::Component;
    use farma::simulator::generate::output::OutputPath;
    let text = std::fs::read_to_string(fixture("golden/fir_golden.csv")).unwrap();
    let taps: Vec<Vec<f64>> = text
        .lines()
        .filter_map(|l| l.strip_prefix("# taps "))
        .map(|l| {
            let (_, v) = l.split_once(" = ").unwrap();
            v.split(' ').map(|t| t.parse().unwrap()).collect()
        })
        .collect();
    assert_eq!(taps.len(), 3);
    let mut rows: Vec<Vec<(f64, f64)>> = vec![Vec::new(); taps.len()];
    for l in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        let set: usize = f[0].parse().unwrap();
        rows[set].push((f[2].parse().unwrap(), f[3].parse().unwrap()));
    }
    for (h, r) in taps.iter().zip(&rows) {
        assert_eq!(r.len(), 300);
        let comps = vec![Component::OutputFir { taps: h.clone() }];
        for block in [300, 1, 7, 64] {
            let mut path = OutputPath::of(&comps, 100.0, None);
            let mut y: Vec<f64> = r.iter().map(|p| p.0).collect();
            for c in y.chunks_mut(block) {
                path.apply(c);
            }
            let worst = y
                .iter()
                .zip(r)
                .map(|(a, p)| (a - p.1).abs())
                .fold(0.0, f64::max);
            assert!(
                worst < 1e-12,
                "taps {h:?}, blocks of {block}: off by {worst}"
            );
        }
    }
}

/// A spec with the FIR form: `farma simulate`'s blocks give the whole series, and the
/// component signals (the gap diagnosis's ensemble) sum to it.
#[test]
fn the_fir_output_filter_is_carried_across_simulation_blocks() {
    let spec = parse_spec(
        "sample_rate_hz = 100.0\nseed = 4\n[[channel]]\nname = \"x\"\n\
         [[channel.component]]\nkind = \"white_noise\"\nn = 0.035\n\
         [[channel.component]]\nkind = \"gauss_markov\"\nsigma = 0.2\ntau_s = 20.0\n\
         [[channel.component]]\nkind = \"output_filter\"\nform = \"fir\"\ntaps = [0.5, 0.3, 0.2]\n",
        Path::new("fir.toml"),
    )
    .unwrap();
    let n = 2 * CHUNK + 777;
    let sim = Simulator::new(&spec, SimRequest::new(n, 100.0)).unwrap();
    let x = sim.run().unwrap().channel("x").unwrap().to_vec();
    for block in [CHUNK, CHUNK + 1, 5 * CHUNK] {
        let mut blocks = sim.blocks(block).unwrap();
        let mut got = Vec::new();
        while let Some((_, cols)) = blocks.next_block().unwrap() {
            got.extend_from_slice(&cols[0]);
        }
        assert!(got == x, "blocks of {block} differ from the whole series");
    }
    // the filter's own: the pre-path sum filtered by hand, zero history
    let ch = sim.channel_index("x").unwrap();
    let mut pre = vec![0.0; n];
    for k in 0..2 {
        for (s, v) in pre.iter_mut().zip(sim.component_signal(ch, k).unwrap()) {
            *s += v;
        }
    }
    let h = [0.5, 0.3, 0.2];
    for t in [0, 1, 2, CHUNK - 1, CHUNK, CHUNK + 1, n - 1] {
        let want: f64 = (0..3).filter(|k| *k <= t).map(|k| h[k] * pre[t - k]).sum();
        assert!(
            (x[t] - want).abs() < 1e-12,
            "t {t}: {} against {want}",
            x[t]
        );
    }
    let mut sum = pre;
    for (s, v) in sum.iter_mut().zip(sim.component_signal(ch, 2).unwrap()) {
        *s += v;
    }
    let worst = sum
        .iter()
        .zip(&x)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "sum of parts off by {worst}");
}

/// `farma simulate` writes the output path's values (a CSV on the grid).
#[test]
fn simulate_writes_values_on_the_grid() {
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("spec.toml");
    std::fs::write(&spec, SPEC).unwrap();
    let out = dir.path().join("sim.csv");
    let o = farma(
        &[
            "simulate",
            spec.to_str().unwrap(),
            "--duration",
            "60",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let header = text
        .lines()
        .find(|l| l.split(',').any(|h| h == "x"))
        .unwrap();
    let col = header.split(',').position(|h| h == "x").unwrap();
    let x: Vec<f64> = text
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(col)?.parse().ok())
        .collect();
    assert_eq!(x.len(), 6000);
    let g = value_grid(&x)
        .present()
        .expect("the written values sit on a grid");
    assert!((g.quantum - 0.05).abs() < 1e-9, "{g:?}");
}

/// The real ADIS16405 runs 1-4, gyro_x_dps at 100 Hz: the 0.05 deg/s output step is
/// found in each; the filter and saturation estimates are printed for the record.
#[test]
fn adis16405_runs_output_step() {
    for run in 1..=4 {
        let Some(parquet) = realdata(&format!("imudata-adis16405/adis_16405_imu{run}.parquet"))
        else {
            println!("SKIPPED: ../shared/realdata (ADIS16405 run {run}) not present");
            continue;
        };
        let (_cache, store) = crate::common::open_store(&parquet);
        let rate_hz = store.sample_rate_hz();
        let x = store.column("gyro_x_dps").unwrap();
        let g = value_grid(x).present().expect("the ADIS16405 output step");
        assert!((g.quantum - 0.05).abs() < 1e-6, "run {run}: {g:?}");
        assert!(g.offset.abs() < 1e-6 && !g.decimal, "run {run}: {g:?}");
        let f = output_filter(x, rate_hz, Some(&g)).unwrap();
        let s = saturation(x, Some(g.quantum));
        println!("ADIS16405 run {run} gyro_x_dps: grid {g:?}\nfilter {f:?}\nsaturation {s:?}");
        // a static gyro at +-0.35 deg/s rms is nowhere near its +-150 deg/s range
        assert!(!s.is_present(), "run {run}: {s:?}");
    }
}

/// The ADIS16405 datasheet spec (white noise and bias instability, no output path)
/// simulated as long as a run: no grid, no filter, no saturation.
#[test]
fn a_datasheet_simulation_has_no_output_path() {
    let spec =
        farma::simulator::load_spec(&crate::common::fixture("specs/adis16405_datasheet.toml"))
            .unwrap();
    let mut req = SimRequest::new(1_000_000, 100.0);
    req.channels = Some(vec!["gyro_x_dps".into()]);
    let out = Simulator::new(&spec, req).unwrap().run().unwrap();
    let x = out.channel("gyro_x_dps").unwrap();
    let g = value_grid(x);
    assert!(!g.is_present(), "{g:?}");
    let f = output_filter(x, 100.0, None).unwrap();
    assert!(!f.is_present(), "{f:?}");
    let s = saturation(x, None);
    assert!(!s.is_present(), "{s:?}");
}
