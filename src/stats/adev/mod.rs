//! Allan deviation and its relatives for a rate series (a gyro channel in deg/s, say):
//! overlapping Allan deviation, modified Allan deviation and overlapping Hadamard
//! deviation, at octave or dense averaging times, with confidence intervals from
//! equivalent degrees of freedom.
//!
//! Definitions (IEEE Std 1139-2008; W. J. Riley, "Handbook of Frequency Stability
//! Analysis", NIST Special Publication 1065, 2008, "SP 1065" below), for N rate samples
//! y_0..y_{N-1} at rate_hz, averaging factor m, tau_s = m / rate_hz, and the phase
//! X_k = sum_{i<k} y_i (k = 0..=N, in units of one sample):
//! - overlapping ADEV (SP 1065 eq. (10)/(11)):
//!   sigma^2(tau) = 1 / (2 m^2 (N - 2m + 1)) sum_{j=0}^{N-2m} (X_{j+2m} - 2 X_{j+m} + X_j)^2,
//!   the mean square difference of adjacent m-sample averages, halved;
//! - MDEV (SP 1065 eq. (14)/(15)):
//!   Mod sigma^2(tau) = 1 / (2 m^4 (N - 3m + 2)) sum_{j=0}^{N-3m+1}
//!   [ sum_{i=j}^{j+m-1} (X_{i+2m} - 2 X_{i+m} + X_i) ]^2;
//! - overlapping HDEV (SP 1065 eq. (20)):
//!   H sigma^2(tau) = 1 / (6 m^2 (N - 3m + 1)) sum_{j=0}^{N-3m}
//!   (X_{j+3m} - 3 X_{j+2m} + 3 X_{j+m} - X_j)^2.
//!
//! These are allantools' `oadev`, `mdev` and `ohdev` with `data_type="freq"`,
//! `rate=rate_hz` (its phase is X / rate_hz after removing the mean; the deviations are
//! unchanged by a constant), checked against it to 1e-10 relative on fixtures
//! (`fixtures/golden/`). allantools' `hdev` is the *non*-overlapping Hadamard
//! deviation; farma's `hdev` is the overlapping one (`ohdev`), which has better
//! confidence. Deviations come out in the units of the rate series.
//!
//! Speed: the fast path ([`fast`]) forms the phase once with a compensated parallel scan
//! ([`phase`](mod@phase)) and evaluates each tau in O(N), in parallel over fixed blocks (results
//! independent of the thread count). [`slow`] holds the definitions summed directly, the
//! twins the fast path is tested against. [`avar`] reproduces the R package avar's
//! estimator, which differs slightly (see there).

pub mod avar;
pub mod edf;
pub mod fast;
pub mod phase;
pub mod slow;
pub mod taus;

pub use edf::{ONE_SIGMA, confidence_interval, edf_greenhall};
pub use fast::deviations_from_phase;
pub use phase::phase;
pub use slow::deviation_slow;
pub use taus::{dense, max_m, octave};

use crate::error::{Error, Result};

/// Which deviation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    /// Overlapping Allan deviation (allantools `oadev`).
    Adev,
    /// Modified Allan deviation (allantools `mdev`).
    Mdev,
    /// Overlapping Hadamard deviation (allantools `ohdev`).
    Hdev,
}

impl Kind {
    /// All kinds, in output order.
    pub const ALL: [Kind; 3] = [Kind::Adev, Kind::Mdev, Kind::Hdev];

    /// The name used in outputs: `adev`, `mdev`, `hdev`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Adev => "adev",
            Kind::Mdev => "mdev",
            Kind::Hdev => "hdev",
        }
    }

    /// Order of the phase difference: 2 (Allan, modified Allan) or 3 (Hadamard).
    pub fn order(self) -> usize {
        match self {
            Kind::Adev | Kind::Mdev => 2,
            Kind::Hdev => 3,
        }
    }

    /// Terms in the estimator at averaging factor m for N rate samples (0 if none):
    /// N - 2m + 1 (ADEV), N - 3m + 2 (MDEV), N - 3m + 1 (HDEV).
    pub fn n_terms(self, n_samples: usize, m: usize) -> usize {
        let (k, c) = match self {
            Kind::Adev => (2, 1),
            Kind::Mdev => (3, 2),
            Kind::Hdev => (3, 1),
        };
        (n_samples + c).saturating_sub(k * m)
    }

    /// The deviation from the sum of squared phase differences `s` over `n` terms.
    fn normalize(self, s: f64, m: usize, n: usize) -> f64 {
        let mf = m as f64;
        let nf = n as f64;
        match self {
            Kind::Adev => (s / (2.0 * nf)).sqrt() / mf,
            Kind::Mdev => (s / (2.0 * nf)).sqrt() / (mf * mf),
            Kind::Hdev => (s / (6.0 * nf)).sqrt() / mf,
        }
    }

    /// Greenhall's EDF for this kind at m with N rate samples, noise PSD exponent alpha.
    pub fn edf(self, alpha: i32, m: usize, n_samples: usize) -> Option<f64> {
        let (d, modified) = match self {
            Kind::Adev => (2, false),
            Kind::Mdev => (2, true),
            Kind::Hdev => (3, false),
        };
        edf_greenhall(alpha, d, m, n_samples + 1, true, modified)
    }
}

/// Which averaging times.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TauGrid {
    /// m = 1, 2, 4, 8, ...
    Octave,
    /// About `per_decade` distinct integer m per decade.
    Dense { per_decade: usize },
}

impl TauGrid {
    /// The averaging factors for `kind` and N rate samples.
    pub fn factors(self, kind: Kind, n_samples: usize) -> Vec<usize> {
        match self {
            TauGrid::Octave => octave(kind, n_samples),
            TauGrid::Dense { per_decade } => dense(kind, n_samples, per_decade),
        }
    }
}

/// Confidence-interval settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CiOptions {
    /// Confidence level of the interval (default one sigma, 0.683).
    pub confidence: f64,
    /// Exponent alpha of the assumed frequency-noise PSD f^alpha (default 0, white FM).
    pub alpha: i32,
}

impl Default for CiOptions {
    fn default() -> Self {
        CiOptions {
            confidence: ONE_SIGMA,
            alpha: 0,
        }
    }
}

/// One point of a deviation curve.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Point {
    /// Averaging factor (samples per average).
    pub m: usize,
    /// Averaging time, seconds: m / rate_hz.
    pub tau_s: f64,
    /// The deviation, in the units of the rate series.
    pub dev: f64,
    /// Lower and upper bounds of the confidence interval.
    pub lo: f64,
    pub hi: f64,
    /// Equivalent degrees of freedom behind the interval (NaN where Greenhall's
    /// algorithm has no case; the bounds are then NaN too).
    pub edf: f64,
    /// Terms in the estimator's sum.
    pub n_terms: usize,
}

/// A deviation curve of one kind.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    pub kind: Kind,
    pub points: Vec<Point>,
}

/// Deviation curves of `kinds` for the rate series `y` at `rate_hz`, on `grid`, with
/// confidence intervals. Fails with [`Error::TooShort`] (naming `what`) when the series
/// allows no averaging factor for a kind.
pub fn curves(
    what: &str,
    y: &[f64],
    rate_hz: f64,
    kinds: &[Kind],
    grid: TauGrid,
    ci: CiOptions,
) -> Result<Vec<Curve>> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(Error::Usage(format!(
            "{what}: sample rate {} Hz",
            crate::fmt::num(rate_hz)
        )));
    }
    crate::stats::require_finite(what, y, rate_hz)?;
    for &k in kinds {
        if max_m(k, y.len()) == 0 {
            let need = match k {
                Kind::Adev => 3,
                Kind::Mdev => 3,
                Kind::Hdev => 4,
            };
            return Err(Error::TooShort {
                what: format!("{what}: {}", k.name()),
                need,
                have: y.len() as u64,
            });
        }
    }
    let x = phase(y);
    let out: Vec<Curve> = kinds
        .iter()
        .map(|&kind| {
            let ms = grid.factors(kind, y.len());
            let devs = deviations_from_phase(&x, kind, &ms);
            let points = ms
                .iter()
                .zip(devs)
                .map(|(&m, dev)| {
                    let edf = kind.edf(ci.alpha, m, y.len()).unwrap_or(f64::NAN);
                    let (lo, hi) = if edf.is_finite() && edf > 0.0 {
                        confidence_interval(dev, edf, ci.confidence)
                    } else {
                        (f64::NAN, f64::NAN)
                    };
                    Point {
                        m,
                        tau_s: m as f64 / rate_hz,
                        dev,
                        lo,
                        hi,
                        edf,
                        n_terms: kind.n_terms(y.len(), m),
                    }
                })
                .collect();
            Curve { kind, points }
        })
        .collect();
    for c in &out {
        if let Some(p) = c.points.iter().find(|p| !p.dev.is_finite()) {
            return Err(crate::stats::overflow_error(
                what,
                c.kind.name(),
                &format!("tau = {} s", crate::fmt::num(p.tau_s)),
                y,
            ));
        }
    }
    Ok(out)
}

/// Deviations of `kind` at averaging factors `ms` of the rate series `y` (fast path).
pub fn deviations(y: &[f64], kind: Kind, ms: &[usize]) -> Vec<f64> {
    deviations_from_phase(&phase(y), kind, ms)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
    }

    fn noise(n: usize, seed: u64, mean: f64, rw: f64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut walk = 0.0;
        (0..n)
            .map(|_| {
                walk += rw * (rng.random::<f64>() - 0.5);
                mean + walk + (rng.random::<f64>() - 0.5)
            })
            .collect()
    }

    #[test]
    fn fast_matches_slow_twin_on_random_data() {
        for (seed, n) in [(1u64, 700usize), (2, 1001), (3, 1500), (4, 64), (5, 5)] {
            let y = noise(n, seed, 3.0, 0.05);
            for kind in Kind::ALL {
                let mut ms = octave(kind, n);
                ms.extend(dense(kind, n, 10));
                ms.sort_unstable();
                ms.dedup();
                let fast = deviations(&y, kind, &ms);
                for (&m, f) in ms.iter().zip(fast) {
                    let s = deviation_slow(&y, kind, m);
                    assert!(rel(f, s) < 1e-10, "{kind:?} n={n} m={m}: fast {f} slow {s}");
                }
            }
        }
    }

    #[test]
    fn results_do_not_depend_on_thread_count() {
        // Longer than a block of each parallel loop, so there are several.
        let y = noise(3 * phase::BLOCK + 123, 9, -1.0, 0.01);
        let ms = octave(Kind::Adev, y.len());
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| Kind::ALL.map(|k| deviations(&y, k, &ms[..ms.len().min(12)])));
        let three = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap()
            .install(|| Kind::ALL.map(|k| deviations(&y, k, &ms[..ms.len().min(12)])));
        for (a, b) in one.iter().zip(three.iter()) {
            let ab: Vec<u64> = a.iter().map(|v| v.to_bits()).collect();
            let bb: Vec<u64> = b.iter().map(|v| v.to_bits()).collect();
            assert_eq!(ab, bb);
        }
    }

    #[test]
    fn fast_matches_slow_twin_across_blocks() {
        // Several phase blocks and summation blocks; a few taus (the twin is O(N m)).
        let y = noise(2 * phase::BLOCK + 77, 11, 100.0, 0.02);
        for kind in [Kind::Adev, Kind::Hdev] {
            for m in [1usize, 3, 16, 1000] {
                let f = deviations(&y, kind, &[m])[0];
                let s = deviation_slow(&y, kind, m);
                assert!(rel(f, s) < 1e-10, "{kind:?} m={m}: fast {f} slow {s}");
            }
        }
        for m in [1usize, 2, 7] {
            let f = deviations(&y, Kind::Mdev, &[m])[0];
            let s = deviation_slow(&y, Kind::Mdev, m);
            assert!(rel(f, s) < 1e-10, "mdev m={m}: fast {f} slow {s}");
        }
    }

    #[test]
    fn compensated_phase_beats_plain_cumsum() {
        // y = 0.1 repeated: every running sum k * 0.1 in exact arithmetic. The phase
        // removes the mean (all zeros); so test the scan itself on f(i) = 0.1.
        let n = 1_000_000;
        let mut out = vec![0.0; n + 1];
        phase::compensated_prefix(&mut out, |_| 0.1);
        let mut plain = 0.0f64;
        let mut worst_plain = 0.0f64;
        let mut worst = 0.0f64;
        for (k, &o) in out.iter().enumerate().skip(1) {
            plain += 0.1;
            // 0.1 as an f64 times k, correctly rounded, via f64 of the exact product.
            let exact = (k as f64) * 0.1f64; // one rounding: within 0.5 ulp
            worst = worst.max((o - exact).abs() / exact);
            worst_plain = worst_plain.max((plain - exact).abs() / exact);
        }
        assert!(worst < 3e-16, "compensated scan drifts: {worst}");
        assert!(
            worst_plain > 1e-13,
            "plain sum unexpectedly exact: {worst_plain}"
        );
    }

    #[test]
    fn white_noise_adev_follows_one_over_sqrt_tau() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let sigma = 2.0f64;
        let y: Vec<f64> = (0..200_000)
            .map(|_| {
                // Sum of 12 uniforms - 6: unit variance, close to normal.
                let u: f64 = (0..12).map(|_| rng.random::<f64>()).sum::<f64>() - 6.0;
                sigma * u
            })
            .collect();
        let c = curves(
            "t",
            &y,
            100.0,
            &Kind::ALL,
            TauGrid::Octave,
            CiOptions::default(),
        )
        .unwrap();
        for p in &c[0].points[..8] {
            let expect = sigma / (p.m as f64).sqrt();
            assert!(
                rel(p.dev, expect) < 0.05,
                "m={} {} vs {}",
                p.m,
                p.dev,
                expect
            );
            assert!(p.lo < p.dev && p.dev < p.hi);
            assert!(p.lo <= expect * 1.02 && expect * 0.98 <= p.hi);
        }
    }

    #[test]
    fn avar_variant_matches_its_twin() {
        let y = noise(5000, 3, 0.5, 0.1);
        let x = phase(&y);
        for m in avar::avar_levels(y.len()) {
            let f = avar::avar_mo_deviation(&x, m);
            let s = avar::avar_mo_deviation_slow(&y, m);
            assert!(rel(f, s) < 1e-10, "m={m}: {f} vs {s}");
        }
        assert_eq!(avar::avar_levels(1_000_000).len(), 18);
        assert_eq!(avar::avar_levels(1_000_000)[0], 2);
    }

    #[test]
    fn too_short_is_an_error() {
        let e = curves(
            "x.csv: gyro",
            &[1.0, 2.0],
            1.0,
            &[Kind::Adev],
            TauGrid::Octave,
            CiOptions::default(),
        )
        .unwrap_err();
        assert!(matches!(e, Error::TooShort { .. }), "{e}");
        let c = curves(
            "x",
            &[1.0, 2.0, 4.0],
            1.0,
            &[Kind::Adev],
            TauGrid::Octave,
            CiOptions::default(),
        )
        .unwrap();
        assert_eq!(c[0].points.len(), 1);
    }
}
