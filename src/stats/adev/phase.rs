//! The phase series (running sum of the rate series), computed with care for
//! precision and in parallel, with results independent of the thread count.
//!
//! Every deviation here is a sum of squared finite differences of the phase
//! X_k = sum_{i<k} (y_i - mean(y)), k = 0..=N (the time integral of the rate series in
//! units of one sample; allantools' `frequency2phase` is X times tau0 = 1 / rate_hz).
//! Two precautions keep X as exact as an f64 can hold it:
//! - the mean is removed first (as allantools does), so X does not grow like N * mean;
//! - the running sum is compensated: blocks of [`BLOCK`] samples are summed with
//!   Neumaier's compensated sum, the block offsets are accumulated in double-double
//!   (an unevaluated sum hi + lo of two f64, Knuth's TwoSum), and each block is then
//!   scanned from its double-double offset carrying a compensation term. Each X_k is the
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

/// Neumaier's compensated sum of `f(i)` for i in `range`, as a double-double.
fn block_sum(range: std::ops::Range<usize>, f: &(impl Fn(usize) -> f64 + Sync)) -> DoubleDouble {
    let mut s = 0.0f64;
    let mut c = 0.0f64;
    for i in range {
        let v = f(i);
        let t = s + v;
        if s.abs() >= v.abs() {
            c += (s - t) + v;
        } else {
            c += (v - t) + s;
        }
        s = t;
    }
    let (hi, lo) = two_sum(s, c);
    DoubleDouble { hi, lo }
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

/// Writes the running sum out[0] = 0, out[k + 1] = out[k] + f(k) for k in
/// 0..out.len() - 1, compensated as described in the module documentation.
pub fn compensated_prefix(out: &mut [f64], f: impl Fn(usize) -> f64 + Sync) {
    if out.is_empty() {
        return;
    }
    let len = out.len() - 1; // terms
    out[0] = 0.0;
    let n_blocks = len.div_ceil(BLOCK);
    let sums: Vec<DoubleDouble> = (0..n_blocks)
        .into_par_iter()
        .map(|b| block_sum(b * BLOCK..((b + 1) * BLOCK).min(len), &f))
        .collect();
    let mut offsets = Vec::with_capacity(n_blocks);
    let mut acc = DoubleDouble::default();
    for s in &sums {
        offsets.push(acc);
        acc = acc.plus(*s);
    }
    out[1..]
        .par_chunks_mut(BLOCK)
        .zip(offsets.par_iter())
        .enumerate()
        .for_each(|(b, (chunk, off))| {
            // Running value hi + (lo + c): hi the f64 sum, the rest compensation.
            let mut s = off.hi;
            let mut c = off.lo;
            let start = b * BLOCK;
            for (k, o) in chunk.iter_mut().enumerate() {
                let v = f(start + k);
                let t = s + v;
                if s.abs() >= v.abs() {
                    c += (s - t) + v;
                } else {
                    c += (v - t) + s;
                }
                s = t;
                *o = s + c;
            }
        });
}

/// Mean of `y`, from a compensated sum.
pub fn mean(y: &[f64]) -> f64 {
    if y.is_empty() {
        return 0.0;
    }
    compensated_sum(y.len(), |i| y[i]).value() / y.len() as f64
}

/// The phase X_k = sum_{i<k} (y_i - mean(y)), k = 0..=N (N + 1 values, X_0 = 0), in
/// units of one sample (multiply by 1 / rate_hz for allantools' phase in seconds).
pub fn phase(y: &[f64]) -> Vec<f64> {
    let mu = mean(y);
    let mut x = vec![0.0; y.len() + 1];
    compensated_prefix(&mut x, |i| y[i] - mu);
    x
}
