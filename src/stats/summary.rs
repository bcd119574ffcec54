//! Per-channel summary: count, mean, sample standard deviation, min, max.
//!
//! Non-finite values (NaN, infinities: a channel that holds missing values, see
//! `Store::nonfinite`) are left out and counted apart; every statistic is over the
//! finite values.
//!
//! Formula: the series is cut into fixed blocks of 65,536 values; each block's mean and
//! sum of squared deviations are computed in two passes over the block, and blocks are
//! combined in order with the pairwise update of Chan, Golub and LeVeque (1979),
//! `M2 = M2_a + M2_b + delta^2 n_a n_b / n`. Blocks run in parallel and merge in a fixed
//! order, so the result does not depend on the thread count. std uses `n - 1`.

use rayon::prelude::*;
use serde::Serialize;

const BLOCK: usize = 1 << 16;

/// Summary of one channel.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChannelSummary {
    pub name: String,
    /// Number of finite values, those the statistics are over.
    pub n: u64,
    /// Number of non-finite values (NaN, infinities), left out.
    pub n_nonfinite: u64,
    pub mean: f64,
    /// Sample standard deviation (divisor n - 1); NaN when n < 2.
    pub std: f64,
    pub min: f64,
    pub max: f64,
}

#[derive(Clone, Copy)]
struct Moments {
    n: f64,
    mean: f64,
    m2: f64,
    min: f64,
    max: f64,
}

impl Moments {
    /// The moments of the block's finite values (n = 0, mean and min/max NaN or
    /// infinite when it has none).
    fn of_block(x: &[f64]) -> Moments {
        let finite = || x.iter().copied().filter(|v| v.is_finite());
        let n = finite().count() as f64;
        let mean = finite().sum::<f64>() / n;
        let m2 = finite().map(|v| (v - mean) * (v - mean)).sum::<f64>();
        let (min, max) = finite().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        Moments {
            n,
            mean,
            m2,
            min,
            max,
        }
    }

    fn merge(self, o: Moments) -> Moments {
        // a block without finite values adds nothing (its mean is NaN)
        if o.n == 0.0 {
            return self;
        }
        if self.n == 0.0 {
            return o;
        }
        let n = self.n + o.n;
        let delta = o.mean - self.mean;
        Moments {
            n,
            mean: self.mean + delta * o.n / n,
            m2: self.m2 + o.m2 + delta * delta * self.n * o.n / n,
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }
}

/// Summarizes `x` (non-empty); its non-finite values are counted and left out.
pub fn summarize(name: &str, x: &[f64]) -> ChannelSummary {
    assert!(!x.is_empty(), "summarize needs at least one value");
    let blocks: Vec<Moments> = x.par_chunks(BLOCK).map(Moments::of_block).collect();
    let m = blocks
        .into_iter()
        .reduce(Moments::merge)
        .expect("non-empty");
    summary_of(name, m, x.len())
}

/// [`summarize`] of a series given piece by piece ([`Summarizer::push`]): the same
/// summary, bit for bit, when every piece but the last is a multiple of 65536 values.
pub struct Summarizer {
    name: String,
    len: usize,
    m: Option<Moments>,
}

impl Summarizer {
    pub fn new(name: &str) -> Self {
        Summarizer {
            name: name.to_string(),
            len: 0,
            m: None,
        }
    }

    /// The next values of the series.
    pub fn push(&mut self, x: &[f64]) {
        let blocks: Vec<Moments> = x.par_chunks(BLOCK).map(Moments::of_block).collect();
        for b in blocks {
            self.m = Some(match self.m.take() {
                None => b,
                Some(a) => a.merge(b),
            });
        }
        self.len += x.len();
    }

    /// The summary of every value pushed (at least one).
    pub fn finish(self) -> ChannelSummary {
        let m = self.m.unwrap_or(Moments {
            n: 0.0,
            mean: f64::NAN,
            m2: f64::NAN,
            min: f64::NAN,
            max: f64::NAN,
        });
        summary_of(&self.name, m, self.len)
    }
}

fn summary_of(name: &str, m: Moments, len: usize) -> ChannelSummary {
    let n = m.n as u64;
    ChannelSummary {
        name: name.to_string(),
        n,
        n_nonfinite: len as u64 - n,
        mean: if n > 0 { m.mean } else { f64::NAN },
        std: if n > 1 {
            (m.m2 / (m.n - 1.0)).sqrt()
        } else {
            f64::NAN
        },
        min: if n > 0 { m.min } else { f64::NAN },
        max: if n > 0 { m.max } else { f64::NAN },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_direct_two_pass_across_blocks() {
        // 3 blocks and a bit, with a large offset that breaks naive sum-of-squares.
        let x: Vec<f64> = (0..(3 * BLOCK + 123))
            .map(|i| 1e6 + ((i * 7919) % 1000) as f64 * 1e-3)
            .collect();
        let s = summarize("x", &x);
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        assert!((s.mean - mean).abs() <= 1e-12 * mean.abs());
        assert!((s.std - var.sqrt()).abs() <= 1e-9 * var.sqrt());
        assert_eq!(s.min, x.iter().cloned().fold(f64::INFINITY, f64::min));
        assert_eq!(s.max, x.iter().cloned().fold(f64::NEG_INFINITY, f64::max));
        assert_eq!(s.n_nonfinite, 0);
    }

    #[test]
    fn non_finite_values_are_counted_and_left_out() {
        // NaN and infinities in the first and third blocks, and a block of NaN only
        let mut x: Vec<f64> = (0..(4 * BLOCK + 5))
            .map(|i| ((i * 7919) % 1000) as f64 * 1e-3 - 0.3)
            .collect();
        for i in [3, 70, 2 * BLOCK + 1, 2 * BLOCK + 9] {
            x[i] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][i % 3];
        }
        x[BLOCK..2 * BLOCK].fill(f64::NAN);
        let s = summarize("x", &x);
        let kept: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
        let direct = summarize("x", &kept);
        assert_eq!(s.n, kept.len() as u64);
        assert_eq!(s.n_nonfinite, (BLOCK + 4) as u64);
        assert!((s.mean - direct.mean).abs() <= 1e-12);
        assert!((s.std - direct.std).abs() <= 1e-12);
        assert_eq!((s.min, s.max), (direct.min, direct.max));
        let none = summarize("x", &[f64::NAN, f64::NAN]);
        assert_eq!((none.n, none.n_nonfinite), (0, 2));
        assert!(none.mean.is_nan() && none.std.is_nan() && none.min.is_nan());
    }
}
