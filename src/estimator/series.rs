//! A series read with its mean taken out on the fly: x_t = raw_t - mean, the value a
//! centred copy of `raw` would hold, bit for bit (the same subtraction), without the
//! copy. The fit reads a store's mapped column through it, so that it holds no
//! N-long copy of the series (`fit::fit_then_release`); a series already centred
//! (or not to be) is read with mean 0, which leaves every value as it is
//! (v - 0 = v for every f64, -0 included).

use std::ops::Range;

/// The values raw_t - mean, t = 0 .. raw.len() (borrowed; nothing is copied).
#[derive(Clone, Copy, Debug)]
pub struct Centred<'a> {
    raw: &'a [f64],
    mean: f64,
}

impl<'a> Centred<'a> {
    /// `raw` less `mean`.
    pub fn new(raw: &'a [f64], mean: f64) -> Self {
        Centred { raw, mean }
    }

    /// `x` as it is (mean 0).
    pub fn plain(x: &'a [f64]) -> Self {
        Centred { raw: x, mean: 0.0 }
    }

    /// x_t.
    #[inline(always)]
    pub fn at(&self, t: usize) -> f64 {
        self.raw[t] - self.mean
    }

    /// N.
    #[inline]
    pub fn len(&self) -> usize {
        self.raw.len()
    }

    /// Whether the series is empty.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.raw.is_empty()
    }

    /// The values at `r`, as a series of their own (index 0 = row r.start).
    #[inline]
    pub fn range(&self, r: Range<usize>) -> Centred<'a> {
        Centred {
            raw: &self.raw[r],
            mean: self.mean,
        }
    }

    /// The first `len` values.
    #[inline]
    pub fn prefix(&self, len: usize) -> Centred<'a> {
        self.range(0..len)
    }

    /// The values, copied (for short prefixes).
    pub fn to_vec(&self) -> Vec<f64> {
        self.raw.iter().map(|v| v - self.mean).collect()
    }

    /// The mean taken out.
    pub fn mean(&self) -> f64 {
        self.mean
    }

    /// The series the values are read from, before the mean is taken out.
    pub fn raw(&self) -> &'a [f64] {
        self.raw
    }
}

impl<'a> From<&'a [f64]> for Centred<'a> {
    fn from(x: &'a [f64]) -> Self {
        Centred::plain(x)
    }
}

impl<'a> From<&'a Vec<f64>> for Centred<'a> {
    fn from(x: &'a Vec<f64>) -> Self {
        Centred::plain(x)
    }
}

impl<'a, const N: usize> From<&'a [f64; N]> for Centred<'a> {
    fn from(x: &'a [f64; N]) -> Self {
        Centred::plain(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_those_of_a_centred_copy_and_mean_zero_leaves_them() {
        let raw = [1.5, -0.0, 0.0, 3.25e300, -7.0, 1e-310];
        let mean = raw.iter().sum::<f64>() / raw.len() as f64;
        let copy: Vec<f64> = raw.iter().map(|v| v - mean).collect();
        let c = Centred::new(&raw, mean);
        for (t, v) in copy.iter().enumerate() {
            assert_eq!(c.at(t).to_bits(), v.to_bits());
            assert_eq!(Centred::plain(&copy).at(t).to_bits(), v.to_bits());
        }
        assert_eq!(c.range(2..5).at(1).to_bits(), copy[3].to_bits());
        assert_eq!(c.prefix(4).to_vec(), copy[..4].to_vec());
        assert_eq!(Centred::plain(&[-0.0]).at(0).to_bits(), (-0.0f64).to_bits());
    }
}
