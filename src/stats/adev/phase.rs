//! The phase series (running sum of the rate series), computed with care for
//! precision and in parallel, with results independent of the thread count.
//!
//! Every deviation here is a sum of squared finite differences of the phase
//! X_k = sum_{i<k} (y_i - mean(y)), k = 0..=N (the time integral of the rate series in
//! units of one sample; allantools' `frequency2phase` is X times tau0 = 1 / rate_hz).
//! Two precautions keep X as exact as an f64 can hold it:
//! - the mean is removed first (as allantools does), so X does not grow like N * mean;
//! - the running sum is compensated: sub-blocks of samples are summed with the rounding
//!   error of every addition recovered exactly (Knuth's TwoSum) and summed apart, the
//!   sub-block offsets are accumulated in double-double (an unevaluated sum hi + lo of
//!   two f64), and each sub-block is then scanned from its double-double offset
//!   carrying the same compensation term. Each X_k is the
//!   correctly rounded running sum up to a few units in the last place, where a plain
//!   `cumsum` (allantools) drifts by about sqrt(k) units of |X| rounding.
//!
//! The block layout is fixed by the index alone, so the result is bit-for-bit the same
//! on any number of threads.

use rayon::prelude::*;

/// Samples per block of the parallel scans (fixed: results do not depend on threads).
pub const BLOCK: usize = 1 << 15;

/// An unevaluated sum hi + lo (double-double), enough for offsets of a running sum.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DoubleDouble {
    pub hi: f64,
    pub lo: f64,
}

/// Knuth's TwoSum: s + e == a + b exactly.
#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

impl DoubleDouble {
    /// Adds a double-double (Dekker/Knuth, "sloppy" add: error about 2^-104 relative).
    #[inline]
    pub fn plus(self, o: DoubleDouble) -> DoubleDouble {
        let (s, e) = two_sum(self.hi, o.hi);
        let e = e + self.lo + o.lo;
        let (hi, lo) = two_sum(s, e);
        DoubleDouble { hi, lo }
    }

    /// Adds an f64.
    #[inline]
    pub fn plus_f64(self, v: f64) -> DoubleDouble {
        self.plus(DoubleDouble { hi: v, lo: 0.0 })
    }

    /// The nearest f64.
    #[inline]
    pub fn value(self) -> f64 {
        self.hi + self.lo
    }
}

/// Compensated sum of `f(i)` for i in `range` as a double-double: four interleaved
/// lanes, each a running f64 sum whose rounding errors (TwoSum, exact) are summed
/// separately; branch-free, so the lanes run in parallel in the pipeline.
fn block_sum(range: std::ops::Range<usize>, f: &(impl Fn(usize) -> f64 + Sync)) -> DoubleDouble {
    let mut s = [0.0f64; 4];
    let mut c = [0.0f64; 4];
    let start = range.start;
    let len = range.len();
    let quads = len / 4;
    for q in 0..quads {
        let i = start + 4 * q;
        for l in 0..4 {
            let (t, e) = two_sum(s[l], f(i + l));
            s[l] = t;
            c[l] += e;
        }
    }
    for i in start + 4 * quads..range.end {
        let (t, e) = two_sum(s[0], f(i));
        s[0] = t;
        c[0] += e;
    }
    let mut acc = DoubleDouble::default();
    for l in 0..4 {
        acc = acc.plus(DoubleDouble { hi: s[l], lo: c[l] });
    }
    acc
}

/// Compensated sum of `f(i)` for i in 0..len, in parallel over fixed blocks.
pub fn compensated_sum(len: usize, f: impl Fn(usize) -> f64 + Sync) -> DoubleDouble {
    let n_blocks = len.div_ceil(BLOCK);
    let sums: Vec<DoubleDouble> = (0..n_blocks)
        .into_par_iter()
        .map(|b| block_sum(b * BLOCK..((b + 1) * BLOCK).min(len), &f))
        .collect();
    sums.into_iter()
        .fold(DoubleDouble::default(), DoubleDouble::plus)
}

/// Sub-blocks scanned side by side in one task (independent dependency chains).
const LANES: usize = 4;
const SUB: usize = BLOCK / LANES;

/// Writes the running sum out\[0\] = 0, out[k + 1] = out\[k\] + f(k) for k in
/// 0..out.len() - 1, compensated as described in the module documentation: each value
/// is the double-double offset of its sub-block plus a TwoSum-compensated running sum,
/// rounded once. Sub-blocks of `SUB` terms are scanned `LANES` at a time.
pub fn compensated_prefix(out: &mut [f64], f: impl Fn(usize) -> f64 + Sync) {
    if out.is_empty() {
        return;
    }
    let len = out.len() - 1; // terms
    out[0] = 0.0;
    let n_sub = len.div_ceil(SUB);
    let sums: Vec<DoubleDouble> = (0..n_sub)
        .into_par_iter()
        .map(|b| block_sum(b * SUB..((b + 1) * SUB).min(len), &f))
        .collect();
    let mut offsets = Vec::with_capacity(n_sub);
    let mut acc = DoubleDouble::default();
    for s in &sums {
        offsets.push(acc);
        acc = acc.plus(*s);
    }
    out[1..]
        .par_chunks_mut(BLOCK)
        .enumerate()
        .for_each(|(b, chunk)| {
            let start = b * BLOCK;
            let full = chunk.len() == BLOCK;
            if full {
                // LANES sub-blocks at once: lane l covers chunk[l*SUB..(l+1)*SUB].
                let mut s = [0.0f64; LANES];
                let mut c = [0.0f64; LANES];
                for l in 0..LANES {
                    let off = offsets[b * LANES + l];
                    s[l] = off.hi;
                    c[l] = off.lo;
                }
                let (lanes, _) = chunk.as_chunks_mut::<SUB>();
                let [o0, o1, o2, o3] = lanes else {
                    unreachable!()
                };
                for k in 0..SUB {
                    let outs = [&mut o0[k], &mut o1[k], &mut o2[k], &mut o3[k]];
                    for (l, o) in outs.into_iter().enumerate() {
                        let (t, e) = two_sum(s[l], f(start + l * SUB + k));
                        s[l] = t;
                        c[l] += e;
                        *o = t + c[l];
                    }
                }
            } else {
                for (sb, sub) in chunk.chunks_mut(SUB).enumerate() {
                    let off = offsets[b * LANES + sb];
                    let (mut s, mut c) = (off.hi, off.lo);
                    let base = start + sb * SUB;
                    for (k, o) in sub.iter_mut().enumerate() {
                        let (t, e) = two_sum(s, f(base + k));
                        s = t;
                        c += e;
                        *o = s + c;
                    }
                }
            }
        });
}

/// Mean of `y`: a plain sum in eight lanes per block, blocks combined in
/// double-double. The mean only has to be near the true one (removing any constant
/// leaves every deviation unchanged; it only keeps the phase small), so this pass is
/// built for speed, not for the last bit.
pub fn mean(y: &[f64]) -> f64 {
    if y.is_empty() {
        return 0.0;
    }
    let sums: Vec<f64> = y
        .par_chunks(BLOCK)
        .map(|c| {
            let (q, r) = c.as_chunks::<8>();
            let mut acc = [0.0f64; 8];
            for v in q {
                for l in 0..8 {
                    acc[l] += v[l];
                }
            }
            acc.iter().sum::<f64>() + r.iter().sum::<f64>()
        })
        .collect();
    sums.into_iter()
        .fold(DoubleDouble::default(), DoubleDouble::plus_f64)
        .value()
        / y.len() as f64
}

/// The phase X_k = sum_{i<k} (y_i - mean(y)), k = 0..=N (N + 1 values, X_0 = 0), in
/// units of one sample (multiply by 1 / rate_hz for allantools' phase in seconds).
pub fn phase(y: &[f64]) -> Vec<f64> {
    let mu = mean(y);
    let mut x = vec![0.0; y.len() + 1];
    compensated_prefix(&mut x, |i| y[i] - mu);
    x
}
