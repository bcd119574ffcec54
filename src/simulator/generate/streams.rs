//! Random streams and chunked generation: what makes a simulation deterministic for a
//! seed and independent of the thread count.
//!
//! Every random draw comes from a ChaCha8 stream keyed by (seed, replica) and numbered
//! by (channel index, component index, sub-process, chunk index):
//! - the 256-bit ChaCha key is four 64-bit words `mix64(seed)`, `mix64(seed ^ C1)`,
//!   `mix64(replica)`, `mix64(replica ^ C2)`, where `mix64` is the SplitMix64 finaliser
//!   (a bijection of u64, Steele, Lea and Flood 2014), so distinct (seed, replica) pairs
//!   give distinct keys;
//! - the 64-bit ChaCha stream number is `channel << 48 | component << 32 | sub << 24 |
//!   chunk` (16, 16, 8 and 24 bits), so every (channel, component, sub-process, chunk)
//!   draws from its own stream of 2^64 words;
//! - the chunk `INIT_CHUNK` (all 24 bits set) is reserved for initial states and
//!   burn-ins.
//!
//! Samples are generated in fixed chunks of [`CHUNK`] samples: chunk c of a component
//! always covers samples c*CHUNK .. (c+1)*CHUNK and draws from its own stream, whoever
//! computes it, so rayon may run the chunks in any order on any number of threads and
//! the output is bit-identical. Linear first-order recursions (Gauss-Markov, random
//! walk, the Gauss-Markov bank of bias instability) run by chunks from a zero state
//! and are then fixed up with the carried state ([`ar1_bank`]); the carry scan is a
//! sequential pass over chunk ends in a fixed order.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Samples per chunk (fixed: changing it changes every simulated value).
pub const CHUNK: usize = 1 << 16;
/// The chunk index reserved for initial states and burn-ins.
pub const INIT_CHUNK: u64 = (1 << 24) - 1;
/// Most samples one component can simulate (chunk indices below `INIT_CHUNK`).
pub const MAX_SAMPLES: usize = (INIT_CHUNK as usize) * CHUNK;

/// SplitMix64's finaliser (Steele, Lea, Flood, "Fast splittable pseudorandom number
/// generators", OOPSLA 2014): a bijection of u64 with good avalanche.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Where a component's draws come from: (seed, replica, channel, component).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamKey {
    pub seed: u64,
    pub replica: u64,
    pub channel: usize,
    pub component: usize,
}

impl StreamKey {
    /// The generator of sub-process `sub` (0 for components with one) for `chunk`.
    pub fn rng(&self, sub: usize, chunk: u64) -> ChaCha8Rng {
        debug_assert!(self.channel < 1 << 16 && self.component < 1 << 16 && sub < 1 << 8);
        debug_assert!(chunk <= INIT_CHUNK);
        let words = [
            mix64(self.seed),
            mix64(self.seed ^ 0x5851_F42D_4C95_7F2D),
            mix64(self.replica),
            mix64(self.replica ^ 0x1405_7B7E_F767_814F),
        ];
        let mut key = [0u8; 32];
        for (i, w) in words.iter().enumerate() {
            key[8 * i..8 * i + 8].copy_from_slice(&w.to_le_bytes());
        }
        let mut rng = ChaCha8Rng::from_seed(key);
        rng.set_stream(
            (self.channel as u64) << 48
                | (self.component as u64) << 32
                | (sub as u64) << 24
                | chunk,
        );
        rng
    }

    /// The generator for initial states and burn-ins of sub-process `sub`.
    pub fn init_rng(&self, sub: usize) -> ChaCha8Rng {
        self.rng(sub, INIT_CHUNK)
    }
}

/// Calls `f(chunk_index, chunk)` for every fixed-size chunk of `out`, in parallel.
pub fn for_chunks(out: &mut [f64], f: impl Fn(u64, &mut [f64]) + Sync) {
    for_chunks_from(out, 0, f)
}

/// [`for_chunks`] for a block of a longer series whose first sample is sample
/// `c0 * CHUNK`: the chunk indices given to `f` are the series' (`c0` and on).
pub fn for_chunks_from(out: &mut [f64], c0: u64, f: impl Fn(u64, &mut [f64]) + Sync) {
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, s)| f(c0 + c as u64, s));
}

/// One first-order recursion x_t = phi x_{t-1} + gain w_t (w_t standard normal) of a
/// bank, started from x_{-1} = `x_init`; it adds x_t + prev x_{t-1} to sample t (prev
/// 0: the process itself; prev 1: the sum of two neighbouring values, which the
/// interval averages of [`super::markov`] need).
#[derive(Debug, Clone, Copy)]
pub struct Ar1 {
    pub phi: f64,
    pub gain: f64,
    pub x_init: f64,
    pub prev: f64,
}

/// Adds the sum of the bank's outputs x_t + prev x_{t-1} to `out`; recursion k draws
/// w from sub-stream k of `key`.
///
/// By chunks: each chunk runs every recursion from a zero state (in parallel), the
/// true state at each chunk start is carried by one sequential pass over the chunk
/// ends (x_end(c) = y_end(c) + phi^L x_end(c-1)), and each chunk then adds
/// phi^(j+1) x_start + prev phi^j x_start for its j-th sample (in parallel).
/// Linearity makes the sum exactly the sequential recursion up to rounding, and the
/// fixed chunking makes the rounding independent of the thread count.
pub fn ar1_bank(out: &mut [f64], bank: &[Ar1], key: &StreamKey) {
    let mut x: Vec<f64> = bank.iter().map(|ar| ar.x_init).collect();
    ar1_bank_from(out, bank, key, 0, &mut x);
}

/// [`ar1_bank`] for a block of a longer series whose first sample is sample
/// `c0 * CHUNK`: `x` holds each recursion's state before the block (its `x_init` for
/// the first block; the `x_init` of `bank` is not used) and is left holding the state
/// after it. Blocks of whole chunks give the whole series' values bit for bit: the
/// chunks draw from the same streams and the carry runs through the same sequence
/// of operations.
pub fn ar1_bank_from(out: &mut [f64], bank: &[Ar1], key: &StreamKey, c0: u64, x: &mut [f64]) {
    use rand_distr::{Distribution, StandardNormal};
    let n_chunks = out.len().div_ceil(CHUNK);
    let k = bank.len();
    // Phase 1: zero-state runs, the bank's recursions interleaved sample by sample
    // (added to each sample in bank order); ends[c * k + i] = y_i at the end of chunk c.
    let mut ends = vec![0.0; n_chunks * k];
    out.par_chunks_mut(CHUNK)
        .zip(ends.par_chunks_mut(k.max(1)))
        .enumerate()
        .for_each(|(c, (s, end))| {
            let mut rngs: Vec<ChaCha8Rng> = (0..k).map(|i| key.rng(i, c0 + c as u64)).collect();
            let y = end;
            y.iter_mut().for_each(|v| *v = 0.0);
            // each recursion's draws for a stretch of DRAWS samples taken at once (the
            // same draws in the same order as one per sample), then the recursions run
            let mut w = vec![0.0f64; k * DRAWS];
            for piece in s.chunks_mut(DRAWS) {
                let len = piece.len();
                for (wi, rng) in w.chunks_mut(DRAWS).zip(rngs.iter_mut()) {
                    for v in &mut wi[..len] {
                        *v = StandardNormal.sample(rng);
                    }
                }
                for (j, v) in piece.iter_mut().enumerate() {
                    let mut acc = *v;
                    for (i, (ar, yi)) in bank.iter().zip(y.iter_mut()).enumerate() {
                        let before = *yi;
                        *yi = ar.phi * before + ar.gain * w[i * DRAWS + j];
                        acc += *yi + ar.prev * before;
                    }
                    *v = acc;
                }
            }
        });
    // Phase 2: the state before each chunk, sequentially.
    let mut starts = vec![0.0; n_chunks * k];
    for (i, ar) in bank.iter().enumerate() {
        let mut xi = x[i];
        for c in 0..n_chunks {
            starts[c * k + i] = xi;
            let len = CHUNK.min(out.len() - c * CHUNK);
            xi = ar.phi.powi(len as i32) * xi + ends[c * k + i];
        }
        x[i] = xi;
    }
    // Phase 3: add the homogeneous part phi^(j+1) x_start + prev phi^j x_start (bank
    // order, zero starts skipped).
    out.par_chunks_mut(CHUNK)
        .zip(starts.par_chunks(k.max(1)))
        .for_each(|(s, start)| {
            let live: Vec<(f64, f64, f64)> = bank
                .iter()
                .zip(start)
                .filter(|(_, x)| **x != 0.0)
                .map(|(ar, x)| (ar.phi, ar.prev, *x))
                .collect();
            homogeneous(s, live);
        });
}

/// Samples of each recursion's draws that [`ar1_bank_from`] takes at once.
const DRAWS: usize = 1024;

/// Samples between two looks for recursions of [`homogeneous`] that have settled.
const DROP_CHECK: usize = 256;

/// 2^-960: a sample of at least this magnitude is left exactly as it is by adding a
/// term below f64::MIN_POSITIVE = 2^-1022 (its half-ulp is at least 2^-1013).
const SETTLED_SAFE: f64 = f64::from_bits((1023 - 960) << 52);

/// Phase 3 of [`ar1_bank_from`] on one chunk `s`: adds to its j-th sample the terms
/// h_i(j) + prev_i h_i(j - 1), summed in bank order after the sample's value, where
/// h_i(-1) = x_i, h_i(j) = phi_i h_i(j - 1), and `live` holds (phi_i, prev_i, x_i) of
/// the recursions whose start x_i is not 0, in bank order.
///
/// A decaying recursion ends at a fixed point below f64::MIN_POSITIVE: 0, or, for
/// phi > 1/2, the smallest subnormals, which phi h rounds back to (arithmetic on them
/// is slow). From there it adds the same term z = h + prev h to every sample. Every
/// `DROP_CHECK` samples, the recursions that lead the bank order and have settled
/// with |z| < f64::MIN_POSITIVE are taken out of the loop: a sample v with
/// |v| >= 2^-960 ([`SETTLED_SAFE`]) is left exactly as it is by each of them (v + z = v, as |z| is below
/// half of v's ulp), so only the remaining ones are added; any other sample (zero,
/// tiny, NaN) gets the settled terms added first, in order, as constants. The result
/// is the sum over every term bit for bit; [`homogeneous_every_term`] is its slow twin.
/// Returns how many recursions settled.
fn homogeneous(s: &mut [f64], live: Vec<(f64, f64, f64)>) -> usize {
    let mut h: Vec<f64> = live.iter().map(|l| l.2).collect();
    // the terms of the settled recursions, in bank order
    let mut settled: Vec<f64> = Vec::new();
    let mut first = 0;
    for block in s.chunks_mut(DROP_CHECK) {
        let (hl, ll) = (&mut h[first..], &live[first..]);
        for v in block.iter_mut() {
            let mut acc = *v;
            if acc.is_nan() || acc.abs() < SETTLED_SAFE {
                for z in &settled {
                    acc += z;
                }
            }
            for (hi, l) in hl.iter_mut().zip(ll) {
                let before = *hi;
                *hi *= l.0;
                acc += *hi + l.1 * before;
            }
            *v = acc;
        }
        // the leading recursions at a fixed point with a term below MIN_POSITIVE
        while let (Some(&hi), Some(&(phi, prev, _))) = (h.get(first), live.get(first)) {
            let z = hi + prev * hi;
            let fixed = (hi * phi).to_bits() == hi.to_bits();
            if !(fixed && hi.abs() < f64::MIN_POSITIVE && z.abs() < f64::MIN_POSITIVE) {
                break;
            }
            settled.push(z);
            first += 1;
        }
    }
    settled.len()
}

/// The slow twin of [`homogeneous`]: every recursion's term added to every sample.
#[cfg(test)]
fn homogeneous_every_term(s: &mut [f64], live: &[(f64, f64, f64)]) {
    let mut h: Vec<f64> = live.iter().map(|l| l.2).collect();
    for v in s.iter_mut() {
        let mut acc = *v;
        for (hi, l) in h.iter_mut().zip(live) {
            let before = *hi;
            *hi *= l.0;
            acc += *hi + l.1 * before;
        }
        *v = acc;
    }
}

/// `n` standard normal draws from `rng` (burn-ins and initial states).
pub fn normals(rng: &mut ChaCha8Rng, n: usize) -> Vec<f64> {
    use rand_distr::{Distribution, StandardNormal};
    (0..n).map(|_| StandardNormal.sample(rng)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_distr::{Distribution, StandardNormal};

    /// The slow twin of [`ar1_bank`]: each recursion run sequentially over the whole
    /// series with the same draws (chunk c of recursion i from stream (i, c)).
    fn sequential(n: usize, bank: &[Ar1], key: &StreamKey) -> Vec<f64> {
        let mut out = vec![0.0; n];
        for (i, ar) in bank.iter().enumerate() {
            let mut x = ar.x_init;
            let mut rng = key.rng(i, 0);
            for (t, o) in out.iter_mut().enumerate() {
                if t % CHUNK == 0 {
                    rng = key.rng(i, (t / CHUNK) as u64);
                }
                let w: f64 = StandardNormal.sample(&mut rng);
                let before = x;
                x = ar.phi * x + ar.gain * w;
                *o += x + ar.prev * before;
            }
        }
        out
    }

    #[test]
    fn chunked_bank_matches_the_sequential_recursion() {
        let key = StreamKey {
            seed: 3,
            replica: 1,
            channel: 2,
            component: 5,
        };
        let bank = [
            Ar1 {
                phi: 0.999,
                gain: 0.1,
                x_init: 2.0,
                prev: 1.0,
            },
            Ar1 {
                phi: 1.0,
                gain: 0.01,
                x_init: 0.0,
                prev: 0.0,
            },
            Ar1 {
                phi: 0.5,
                gain: 1.0,
                x_init: -1.0,
                prev: 0.7,
            },
        ];
        let n = 2 * CHUNK + 777;
        let mut fast = vec![0.0; n];
        ar1_bank(&mut fast, &bank, &key);
        let slow = sequential(n, &bank, &key);
        // by blocks of 1 and 2 chunks with the carried state: the same bits
        for block in [CHUNK, 2 * CHUNK] {
            let mut blocks = vec![0.0; n];
            let mut x: Vec<f64> = bank.iter().map(|a| a.x_init).collect();
            for (b, s) in blocks.chunks_mut(block).enumerate() {
                ar1_bank_from(s, &bank, &key, (b * block / CHUNK) as u64, &mut x);
            }
            assert!(blocks == fast, "blocks of {block}");
        }
        for (t, (a, b)) in fast.iter().zip(&slow).enumerate() {
            assert!(
                (a - b).abs() <= 1e-11 * (1.0 + b.abs()),
                "sample {t}: {a} vs {b}"
            );
        }
    }

    #[test]
    fn settled_recursions_taken_out_keep_every_bit() {
        let key = StreamKey {
            seed: 4,
            replica: 2,
            channel: 0,
            component: 1,
        };
        // decays that settle within a chunk (at 0, -0 or the smallest subnormals, at
        // different samples), ones that do not, prev 0 and 1; the 1e-5 one settles but
        // does not lead the bank order
        let live: Vec<(f64, f64, f64)> = [
            (1e-30, 1.0, 0.7),
            (0.5, 0.0, -1.3),
            (0.9, 1.0, 2.1),
            (0.98, 1.0, -0.4),
            (0.9999, 0.0, 1.1),
            (1e-5, 0.3, -2e-300),
            (1.0, 1.0, 0.2),
        ]
        .to_vec();
        let mut rng = key.rng(0, 0);
        let base: Vec<f64> = (0..CHUNK)
            .map(|_| {
                let w: f64 = StandardNormal.sample(&mut rng);
                1e-3 * w
            })
            .collect();
        // samples about the threshold below which the settled terms are added
        let tiny = [
            1e-300,
            -1e-310,
            5e-324,
            SETTLED_SAFE,
            -SETTLED_SAFE / 2.0,
            f64::NAN,
            1.0,
        ];
        for (case, start) in [
            base.clone(),
            vec![0.0; CHUNK],
            // zero sums whose sign only the settled zeros decide
            vec![-0.0; CHUNK],
            (0..CHUNK).map(|t| tiny[t % tiny.len()]).collect(),
        ]
        .into_iter()
        .enumerate()
        {
            for bank in [live.clone(), live[..2].to_vec(), live[5..].to_vec()] {
                let mut fast = start.clone();
                let n_settled = homogeneous(&mut fast, bank.clone());
                if bank.len() == live.len() {
                    // 1e-30, 0.5 (to 0), 0.9 and 0.98 (to the smallest subnormal)
                    assert_eq!(n_settled, 4, "case {case}");
                }
                let mut slow = start.clone();
                homogeneous_every_term(&mut slow, &bank);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert!(bits(&fast) == bits(&slow), "case {case}, bank {bank:?}");
            }
        }
        // -0 samples: the +0 terms of a settled recursion make them +0, as the full sum
        // does, its -0 terms leave them -0
        for (x, want) in [(1e-20, 0.0f64), (-1e-20, -0.0)] {
            let mut fast = vec![-0.0; 1000];
            homogeneous(&mut fast, vec![(1e-300, 1.0, x)]);
            let mut slow = vec![-0.0; 1000];
            homogeneous_every_term(&mut slow, &[(1e-300, 1.0, x)]);
            assert!(
                fast.iter()
                    .zip(&slow)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
            assert_eq!(fast[500].to_bits(), want.to_bits());
        }
    }

    #[test]
    fn keys_give_distinct_streams() {
        let k = |seed, replica, channel, component| StreamKey {
            seed,
            replica,
            channel,
            component,
        };
        use rand::Rng;
        let first = |key: StreamKey, sub, chunk| key.rng(sub, chunk).random::<u64>();
        let base = first(k(1, 0, 0, 0), 0, 0);
        assert_ne!(base, first(k(2, 0, 0, 0), 0, 0));
        assert_ne!(base, first(k(1, 1, 0, 0), 0, 0));
        assert_ne!(base, first(k(1, 0, 1, 0), 0, 0));
        assert_ne!(base, first(k(1, 0, 0, 1), 0, 0));
        assert_ne!(base, first(k(1, 0, 0, 0), 1, 0));
        assert_ne!(base, first(k(1, 0, 0, 0), 0, 1));
        assert_eq!(base, first(k(1, 0, 0, 0), 0, 0));
        // seed and replica are not interchangeable
        assert_ne!(first(k(1, 2, 0, 0), 0, 0), first(k(2, 1, 0, 0), 0, 0));
    }
}
