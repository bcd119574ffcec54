//! Per-channel summary: count, mean, sample standard deviation, min, max.
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
    pub n: u64,
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
    fn of_block(x: &[f64]) -> Moments {
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let m2 = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>();
        let (min, max) = x
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
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

/// Summarizes `x` (non-empty).
pub fn summarize(name: &str, x: &[f64]) -> ChannelSummary {
    assert!(!x.is_empty(), "summarize needs at least one value");
    let blocks: Vec<Moments> = x.par_chunks(BLOCK).map(Moments::of_block).collect();
    let m = blocks
        .into_iter()
        .reduce(Moments::merge)
        .expect("non-empty");
    ChannelSummary {
        name: name.to_string(),
        n: x.len() as u64,
        mean: m.mean,
        std: if x.len() > 1 {
            (m.m2 / (m.n - 1.0)).sqrt()
        } else {
            f64::NAN
        },
        min: m.min,
        max: m.max,
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
    }
}
