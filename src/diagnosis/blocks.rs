//! The training and withheld parts of a log: interleaved time blocks, scored in two
//! folds with swapped roles so that every sample of the log is withheld once.
//!
//! The log's N samples are cut into `n_blocks` contiguous main blocks of (nearly) equal
//! length L = N / n_blocks. Main block i goes to the training part of fold 1 when
//! floor((i+1) f + c) > floor(i f + c) for the training fraction f and c = 1 - f/2, so
//! the two parts alternate as evenly as f allows and block 0 is training in fold 1.
//! Fold 2 swaps the roles (its training share is 1 - f): every block is withheld in
//! exactly one fold, and the withheld score of a diagnosis combines both folds, each
//! scored with the parameters estimated on its own training part (cross-fitting), so
//! no part of the log goes unscored and no sample is scored by an estimate that saw it.
//!
//! The start of a log is where a warm-up lives, often shorter than L (a 120 s warm-up
//! in a 900 s block). Block 0 is therefore cut into pieces by halving from the end,
//! [0, L/2^k), [L/2^k, L/2^(k-1)), ..., [L/2, L), k the most halvings that keep the
//! first piece at least [`MIN_PIECE`] samples (at most [`MAX_START_HALVINGS`]), and
//! the pieces alternate between the parts (the last piece keeps block 0's role), so
//! that both folds train on, and withhold, a share of the first minutes: each fold's
//! training part starts within two pieces of the log's start, and a warm-up is fitted
//! from its first seconds in both folds, not extrapolated back to t = 0 from its tail
//! by the fold whose training part begins later. The main blocks
//! stay long for the Allan deviation at long averaging times, which is pooled over the
//! blocks long enough for each averaging factor (contracts.md section 3). Statistics
//! never cross a block boundary.

use std::ops::Range;

use crate::error::{Error, Result};

/// Most halvings of block 0 (it is cut into at most this many + 1 pieces): a bound
/// that only a block 0 of more than 2^24 samples reaches; [`MIN_PIECE`] sets where
/// the halving stops.
pub const MAX_START_HALVINGS: usize = 16;

/// Fewest samples in a piece of block 0 (four time windows of 64 samples).
pub const MIN_PIECE: usize = 256;

/// The block layout of a log.
#[derive(Clone, Debug, PartialEq)]
pub struct Blocks {
    /// Samples in the log.
    pub n: usize,
    /// The blocks, in time order, covering 0..n: the pieces of block 0, then main
    /// blocks 1.. n_blocks - 1.
    pub ranges: Vec<Range<usize>>,
    /// Whether each block is in the training part of fold 1.
    pub train: Vec<bool>,
}

impl Blocks {
    /// `n_blocks` interleaved blocks over `n` samples, a share `train_fraction` of them
    /// for training. Needs at least one block in each part and 64 samples per block.
    pub fn interleaved(n: usize, n_blocks: usize, train_fraction: f64) -> Result<Blocks> {
        Self::interleaved_with(n, n_blocks, train_fraction, MIN_PIECE)
    }

    /// [`Blocks::interleaved`] with block 0's pieces at least `min_piece` samples (at
    /// least 64) instead of [`MIN_PIECE`]: a log averaged over blocks of K samples
    /// takes MIN_PIECE / K, so that its pieces span the time they span in the log at
    /// its own rate.
    pub fn interleaved_with(
        n: usize,
        n_blocks: usize,
        train_fraction: f64,
        min_piece: usize,
    ) -> Result<Blocks> {
        let min_piece = min_piece.max(64);
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
        let f = train_fraction;
        let main_train: Vec<bool> = (0..n_blocks)
            .map(|i| {
                let c = 1.0 - 0.5 * f;
                ((i + 1) as f64 * f + c).floor() > (i as f64 * f + c).floor()
            })
            .collect();
        if main_train.iter().all(|t| *t) || !main_train.iter().any(|t| *t) {
            return Err(Error::Usage(format!(
                "--train-fraction {f} with {n_blocks} blocks leaves one part empty"
            )));
        }
        // block 0 cut into pieces by halving from its end, alternating roles
        let l0 = n / n_blocks;
        let mut k = 0;
        while k < MAX_START_HALVINGS && (l0 >> (k + 1)) >= min_piece {
            k += 1;
        }
        let mut ranges = Vec::with_capacity(n_blocks + k);
        let mut train = Vec::with_capacity(n_blocks + k);
        let mut start = 0;
        for j in (0..=k).rev() {
            let end = if j == 0 { l0 } else { l0 >> j };
            ranges.push(start..end);
            // the last piece (j = 0) keeps block 0's role, the others alternate
            train.push(main_train[0] == (j % 2 == 0));
            start = end;
        }
        for (i, t) in main_train.iter().enumerate().skip(1) {
            ranges.push((i * n / n_blocks)..((i + 1) * n / n_blocks));
            train.push(*t);
        }
        Ok(Blocks { n, ranges, train })
    }

    /// The blocks of the training part (`true`) or of the withheld part (`false`) of
    /// fold 1; fold 2's training part is fold 1's withheld part and the reverse.
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

    /// Length of the longest block.
    pub fn max_len(&self) -> usize {
        self.ranges.iter().map(|r| r.len()).max().unwrap_or(0)
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
            // the main blocks 1..k keep the share; block 0's pieces split it
            let n_pieces = b.ranges.len() - (k - 1);
            let n_train = b.train[n_pieces..].iter().filter(|t| **t).count()
                + usize::from(*b.train.get(n_pieces - 1).unwrap());
            assert!(
                (n_train as f64 - f * k as f64).abs() <= 1.0,
                "{k} {f} {n_train}"
            );
            let train_samples: usize = b.part(true).iter().map(|r| r.len()).sum();
            assert!(
                (train_samples as f64 / 1e5 - f).abs() <= 1.5 / k as f64,
                "{k} {f} {train_samples}"
            );
        }
    }

    #[test]
    fn block_0_is_cut_into_alternating_pieces_that_both_folds_train_on() {
        // 7200 s at 10 Hz in 8 blocks: block 0 is 900 s = 9000 samples, halved 5 times
        // (a sixth would leave 140 < MIN_PIECE samples)
        let b = Blocks::interleaved(72_000, 8, 0.5).unwrap();
        let ends: Vec<usize> = b.ranges.iter().take(6).map(|r| r.end).collect();
        assert_eq!(ends, vec![281, 562, 1125, 2250, 4500, 9000]);
        assert_eq!(b.ranges[6], 9000..18_000);
        assert_eq!(
            b.train[..8],
            [false, true, false, true, false, true, false, true]
        );
        // the last piece keeps block 0's role
        assert!(b.train[5]);
        // at least a quarter of the first minute (600 samples) and of the first 2
        // minutes is in each part
        for (span, least) in [(600, 150), (1200, 300)] {
            for training in [true, false] {
                let early: usize = b
                    .part(training)
                    .iter()
                    .map(|r| r.end.min(span).saturating_sub(r.start))
                    .sum();
                assert!(early >= least, "{span} {training} {early}");
            }
        }
        // each part starts within two pieces of the log's start
        for training in [true, false] {
            assert!(b.part(training)[0].start <= 281, "{training}");
        }
        // a long block 0 is halved until its first piece would fall below MIN_PIECE
        let b = Blocks::interleaved(12_000_000, 12, 0.5).unwrap();
        let first = b.ranges[0].len();
        assert!((MIN_PIECE..2 * MIN_PIECE).contains(&first), "{first}");
        assert_eq!(b.ranges.len(), 12 + 11);
        // an averaged log's pieces span the same time as at the log's own rate: 216 000
        // samples (8 blocks) and their means over blocks of 4 have the same piece ends
        // in time
        let full = Blocks::interleaved(216_000, 8, 0.5).unwrap();
        let avg = Blocks::interleaved_with(54_000, 8, 0.5, MIN_PIECE / 4).unwrap();
        assert_eq!(full.ranges.len(), avg.ranges.len());
        for (f, a) in full.ranges.iter().zip(&avg.ranges) {
            assert!(f.end.abs_diff(4 * a.end) < 4, "{f:?} {a:?}");
        }
        assert_eq!(full.train, avg.train);
        // never below 64 samples
        let b = Blocks::interleaved_with(54_000, 8, 0.5, 1).unwrap();
        assert!(b.min_len() >= 64);
        // a short log: no piece below MIN_PIECE samples
        let b = Blocks::interleaved(12_000, 8, 0.5).unwrap();
        assert_eq!(b.ranges[0], 0..375);
        assert_eq!(b.ranges[1], 375..750);
        assert_eq!(b.ranges[2], 750..1500);
        assert_eq!(b.train[..4], [true, false, true, false]);
        assert!(b.min_len() >= MIN_PIECE);
    }

    #[test]
    fn the_two_folds_withhold_every_sample_exactly_once() {
        for (n, k, f) in [(72_000, 8, 0.5), (12_345, 5, 0.3), (1_000_000, 8, 0.7)] {
            let b = Blocks::interleaved(n, k, f).unwrap();
            // fold 1 withholds part(false), fold 2 part(true)
            let mut seen = vec![0u8; n];
            for training in [false, true] {
                for r in b.part(training) {
                    for s in &mut seen[r] {
                        *s += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&c| c == 1), "{n} {k} {f}");
            for w in b.ranges.windows(2) {
                assert_eq!(w[0].end, w[1].start);
            }
            assert!(b.max_len() >= n / k && b.min_len() >= MIN_PIECE.min(n / k));
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
