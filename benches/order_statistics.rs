//! Benchmark of the gap features' order statistics and distinct-value count
//! (`diagnosis::features`) against their peers from the standard library: the radix
//! selection against `select_nth_unstable_by(f64::total_cmp)` (the selection the
//! features used before), on the absolute increments of 5e5 samples (the
//! `distribution` ranks 0.5, 0.999, 0.9999) and on the samples themselves (the `state`
//! quintiles), continuous and on a grid; the distinct cells against the former LSD
//! radix sort, and the largest finite magnitude against one running `f64::max`; best
//! of `FARMA_BENCH_REPS` runs each.
//!
//!     cargo bench --bench order_statistics        (FARMA_BENCH_REPS=20)

use farma::diagnosis::features::{
    distinct_count_by_sort, distinct_count_on_grid, largest_finite_magnitude, order_statistics,
};
use rand::{Rng, SeedableRng};

/// The peer: successive `select_nth_unstable_by` on what is left above the last rank.
fn by_select_nth(v: &mut [f64], ranks: &[usize]) -> Vec<f64> {
    let mut out = Vec::with_capacity(ranks.len());
    let mut lo = 0;
    for &k in ranks {
        if k < lo {
            out.push(v[k]);
            continue;
        }
        let (_, at, _) = v[lo..].select_nth_unstable_by(k - lo, f64::total_cmp);
        out.push(*at);
        lo = k + 1;
    }
    out
}

/// The peer of the distinct count: the cells sorted by an LSD radix sort of 8-bit
/// digits and their runs counted (the count the features used before; finite cells,
/// a span below 2^32, as in the bench's series).
fn by_lsd_radix(x: &[f64], cell: f64) -> usize {
    let keys: Vec<i64> = x
        .iter()
        .map(|v| farma::num::round_half_away(v / cell) as i64)
        .collect();
    let lo = *keys.iter().min().unwrap();
    let hi = *keys.iter().max().unwrap();
    let mut a: Vec<u32> = keys.iter().map(|&k| (k - lo) as u32).collect();
    let mut b = vec![0u32; a.len()];
    let passes = (32 - ((hi - lo) as u32).leading_zeros()).div_ceil(8) as usize;
    let mut count = [[0usize; 256]; 4];
    for &k in &a {
        for (p, c) in count.iter_mut().enumerate().take(passes) {
            c[((k >> (8 * p)) & 0xff) as usize] += 1;
        }
    }
    for (p, c) in count.iter_mut().enumerate().take(passes) {
        let mut at = 0;
        for v in c.iter_mut() {
            let here = *v;
            *v = at;
            at += here;
        }
        for &k in &a {
            let d = ((k >> (8 * p)) & 0xff) as usize;
            b[c[d]] = k;
            c[d] += 1;
        }
        std::mem::swap(&mut a, &mut b);
    }
    1 + a.windows(2).filter(|w| w[0] != w[1]).count()
}

/// One line of the report: `what`, ours and the peer in ms, the peer's time over ours.
fn report(what: &str, ours: (&str, f64), peer: (&str, f64)) {
    println!(
        "{what}: {} {:.3} ms, {} {:.3} ms, ratio {:.2}",
        ours.0,
        1e3 * ours.1,
        peer.0,
        1e3 * peer.1,
        peer.1 / ours.1
    );
}

/// Best seconds of `reps` runs of `f`.
fn best(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let t = std::time::Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let reps = std::env::var("FARMA_BENCH_REPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20usize);
    let n = 500_000;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let white: Vec<f64> = (0..n)
        .map(|_| rng.random::<f64>() - 0.5 + rng.random::<f64>() - 0.5)
        .collect();
    let grid: Vec<f64> = white
        .iter()
        .map(|w| (w * 4.0 / 0.05).round() * 0.05)
        .collect();
    for (name, x) in [("continuous", &white), ("on a 0.05 grid", &grid)] {
        let d: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        let len = d.len();
        let rank = |p: f64| ((p * (len - 1) as f64).round() as usize).min(len - 1);
        let d_ranks = [rank(0.5), rank(0.999), rank(0.9999)];
        let q_ranks: Vec<usize> = (1..5).map(|k| (k * (n - 1)) / 5).collect();
        for (what, v, ranks) in [
            ("|d| 3 ranks", &d, &d_ranks[..]),
            ("x quintiles", x, &q_ranks[..]),
        ] {
            let mut scratch = v.clone();
            let mut peer = Vec::new();
            let t_peer = best(reps, || {
                scratch.copy_from_slice(v);
                peer = by_select_nth(&mut scratch, ranks);
            });
            let mut ours = Vec::new();
            let t_ours = best(reps, || ours = order_statistics(v, ranks));
            assert_eq!(peer, ours);
            report(
                &format!("{name}, {what}"),
                ("radix", t_ours),
                ("select_nth_unstable (the copy it needs included)", t_peer),
            );
        }
        let mut largest = 0.0;
        let t_ours = best(reps, || {
            largest = largest_finite_magnitude(std::hint::black_box(x))
        });
        let mut peer = 0.0;
        let t_peer = best(reps, || {
            peer = std::hint::black_box(x)
                .iter()
                .filter(|v| v.is_finite())
                .fold(0.0f64, |m, v| m.max(v.abs()))
        });
        assert_eq!(largest, peer);
        report(
            &format!("{name}, largest finite |x|"),
            ("8 lanes", t_ours),
            ("one running f64::max", t_peer),
        );
        let cell = 1e-9 * largest;
        let mut ours = 0;
        let t_ours = best(reps, || {
            ours = distinct_count_on_grid(x.iter().copied(), cell, n)
        });
        let mut slow = 0;
        best(1, || {
            slow = distinct_count_by_sort(x.iter().map(|v| farma::num::round_half_away(v / cell)))
        });
        assert_eq!(ours, slow);
        if name == "continuous" {
            let mut peer = 0;
            let t_peer = best(reps, || peer = by_lsd_radix(x, cell));
            assert_eq!(ours, peer);
            report(
                &format!("{name}, distinct cells ({ours})"),
                ("bitmap", t_ours),
                ("LSD radix sort", t_peer),
            );
        } else {
            // few cells: counted in a small hash set, as before
            println!("{name}, distinct cells ({ours}): {:.2} ms", 1e3 * t_ours);
        }
    }
}
