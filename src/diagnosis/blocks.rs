//! The training and withheld parts of a log: interleaved time blocks.
//!
//! The log's N samples are cut into `n_blocks` contiguous blocks of (nearly) equal
//! length. Block i goes to the training part when floor((i+1) f + c) > floor(i f + c)
//! for the training fraction f and c = 1 - f/2, so the two parts alternate as evenly as f allows and
//! block 0 (the start of the log, where a warm-up is strongest) is training. Effects
//! localised in time and every temperature condition of a long run thus appear in both
//! parts (contracts.md section 3), while each block stays long enough for the Allan
//! deviation at long averaging times. Statistics never cross a block boundary.

use std::ops::Range;

use crate::error::{Error, Result};

/// The block layout of a log.
#[derive(Clone, Debug, PartialEq)]
pub struct Blocks {
    /// Samples in the log.
    pub n: usize,
    /// The blocks, in time order, covering 0..n.
    pub ranges: Vec<Range<usize>>,
    /// Whether each block is in the training part.
    pub train: Vec<bool>,
}

impl Blocks {
    /// `n_blocks` interleaved blocks over `n` samples, a share `train_fraction` of them
    /// for training. Needs at least one block in each part and 64 samples per block.
    pub fn interleaved(n: usize, n_blocks: usize, train_fraction: f64) -> Result<Blocks> {
        if !(train_fraction > 0.0 && train_fraction < 1.0) {
            return Err(Error::Usage(format!(
                "--train-fraction must lie strictly between 0 and 1 (got {train_fraction})"
            )));
        }
        if n_blocks < 2 {
            return Err(Error::Usage(format!(
                "--blocks must be at least 2 (got {n_blocks})"
            )));
        }
        let need = 64 * n_blocks;
        if n < need {
            return Err(Error::TooShort {
                what: format!("gap diagnosis with {n_blocks} blocks"),
                need: need as u64,
                have: n as u64,
            });
        }
        let ranges: Vec<Range<usize>> = (0..n_blocks)
            .map(|i| (i * n / n_blocks)..((i + 1) * n / n_blocks))
            .collect();
        let f = train_fraction;
        let train: Vec<bool> = (0..n_blocks)
            .map(|i| {
                let c = 1.0 - 0.5 * f;
                ((i + 1) as f64 * f + c).floor() > (i as f64 * f + c).floor()
            })
            .collect();
        if train.iter().all(|t| *t) || !train.iter().any(|t| *t) {
            return Err(Error::Usage(format!(
                "--train-fraction {f} with {n_blocks} blocks leaves one part empty"
            )));
        }
        Ok(Blocks { n, ranges, train })
    }

    /// The blocks of the training part (`true`) or of the withheld part (`false`).
    pub fn part(&self, training: bool) -> Vec<Range<usize>> {
        self.ranges
            .iter()
            .zip(&self.train)
            .filter(|(_, t)| **t == training)
            .map(|(r, _)| r.clone())
            .collect()
    }

    /// Length of the shortest block.
    pub fn min_len(&self) -> usize {
        self.ranges.iter().map(|r| r.len()).min().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_alternate_starting_with_training() {
        let b = Blocks::interleaved(1000, 8, 0.5).unwrap();
        assert_eq!(
            b.train,
            vec![true, false, true, false, true, false, true, false]
        );
        assert_eq!(b.ranges.first().unwrap().start, 0);
        assert_eq!(b.ranges.last().unwrap().end, 1000);
        for w in b.ranges.windows(2) {
            assert_eq!(w[0].end, w[1].start);
        }
    }

    #[test]
    fn fraction_sets_the_share() {
        for (k, f) in [(10, 0.7), (10, 0.3), (20, 0.25), (9, 0.5)] {
            let b = Blocks::interleaved(100_000, k, f).unwrap();
            let n_train = b.train.iter().filter(|t| **t).count();
            assert!(
                (n_train as f64 - f * k as f64).abs() <= 1.0,
                "{k} {f} {n_train}"
            );
            assert!(b.train[0]);
        }
    }

    #[test]
    fn bad_requests_are_refused() {
        assert!(Blocks::interleaved(1000, 8, 1.0).is_err());
        assert!(Blocks::interleaved(1000, 8, 0.0).is_err());
        assert!(Blocks::interleaved(1000, 1, 0.5).is_err());
        assert!(Blocks::interleaved(100, 8, 0.5).is_err());
        assert!(Blocks::interleaved(1000, 2, 0.9).is_err());
    }
}
