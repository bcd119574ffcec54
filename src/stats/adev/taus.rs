//! Averaging factors m (tau_s = m / rate_hz) for which a deviation is computed.
//!
//! Both lists follow allantools' `tau_generator` on the *phase* series, which has one
//! more point than the rate series (N rate samples give N + 1 phase points), and then
//! drop every m whose estimator would have fewer than two terms (allantools'
//! `remove_small_ns`), so that a list here equals allantools' list for the same data.

use super::Kind;

/// Largest averaging factor with at least two terms in the estimator of `kind` for
/// `n_samples` rate samples (0 when there is none).
///
/// Terms per estimator (N = `n_samples`): overlapping ADEV N - 2m + 1, MDEV
/// N - 3m + 2, overlapping HDEV N - 3m + 1 (see [`Kind::n_terms`]).
pub fn max_m(kind: Kind, n_samples: usize) -> usize {
    let n = n_samples as i64;
    let m = match kind {
        Kind::Adev => (n - 1) / 2,
        Kind::Mdev => n / 3,
        Kind::Hdev => (n - 1) / 3,
    };
    m.max(0) as usize
}

/// Octave averaging factors 1, 2, 4, ... up to [`max_m`] (allantools `taus="octave"`).
pub fn octave(kind: Kind, n_samples: usize) -> Vec<usize> {
    let top = max_m(kind, n_samples);
    let mut out = Vec::new();
    let mut m = 1usize;
    while m <= top {
        out.push(m);
        m *= 2;
    }
    out
}

/// Dense averaging factors: `per_decade` points per decade, m_k = round(10^(k /
/// per_decade)) for k = 0, 1, ..., duplicates removed (so the small m are all the
/// integers 1, 2, 3, ... until the grid spreads out), up to [`max_m`].
pub fn dense(kind: Kind, n_samples: usize, per_decade: usize) -> Vec<usize> {
    let top = max_m(kind, n_samples);
    let per_decade = per_decade.max(1) as f64;
    let mut out: Vec<usize> = Vec::new();
    for k in 0.. {
        let m = 10f64.powf(k as f64 / per_decade).round() as usize;
        if m > top {
            break;
        }
        if out.last() != Some(&m) {
            out.push(m);
        }
    }
    out
}
