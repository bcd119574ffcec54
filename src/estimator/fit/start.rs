//! The linear start: the ARMA(p,q) by conditional least squares, streamed over every
//! sample and refined on growing prefixes.

use super::bstep::{FLAT_RSS, predicted_decrease};
use super::passes::{FILTER_CHUNK, ma_filter_rss};
use crate::estimator::arma::arma_pass;
use crate::estimator::arma::arma_pass_into;
use crate::estimator::arma::fit_arma;
use crate::estimator::arma::lagged_normal;
use crate::estimator::arma::ma_invertible;
use crate::estimator::buffers;
use crate::estimator::linalg::normal_equations;
use crate::estimator::linalg::spd_solve_inverse;
use crate::estimator::series::Centred;

/// Gauss-Newton for the linear ARMA(p,q) on every sample, from (a0, b0): (a, b)
/// minimise sum_{t >= start} e_t^2 (`arma_pass`), with step halving and the MA part
/// kept invertible: the conditional least squares of [`crate::estimator::arma::fit_arma`] from a
/// given start. Streaming (one pass per iteration, the trial's pass giving the next
/// normal equations), nothing N-long allocated, so it runs on series of any length.
/// Returns (a, b, RSS).
pub fn arma_cls(
    x: &[f64],
    start: usize,
    a0: &[f64],
    b0: &[f64],
    max_iter: usize,
) -> (Vec<f64>, Vec<f64>, f64) {
    arma_cls_within(x, start, (a0, b0), max_iter, 0.0)
}

/// [`arma_cls`], stopping where it is, without a pass for the step, once the
/// Gauss-Newton model predicts a further RSS decrease below `enough` times the RSS
/// (0: never; [`arma_cls`]). Returns (a, b, RSS).
pub fn arma_cls_within(
    x: &[f64],
    start: usize,
    ab0: (&[f64], &[f64]),
    max_iter: usize,
    enough: f64,
) -> (Vec<f64>, Vec<f64>, f64) {
    let (a, b, rss, _) = arma_cls_residuals(Centred::plain(x), start, ab0, max_iter, enough, None);
    (a, b, rss)
}

/// [`arma_cls_within`], each pass writing its residuals to `e` (when given, and the
/// order has a kernel of its own, [`arma_pass_into`]). The last value is true when
/// `e` then holds the residuals at the returned (a, b) (the pass that evaluated them
/// was the last to write), false when it must be filled again (a rejected trial
/// step wrote last, or nothing was written).
pub(super) fn arma_cls_residuals(
    x: Centred,
    start: usize,
    (a0, b0): (&[f64], &[f64]),
    max_iter: usize,
    enough: f64,
    mut e: Option<&mut [f64]>,
) -> (Vec<f64>, Vec<f64>, f64, bool) {
    let (p, q) = (a0.len(), b0.len());
    let k = p + q;
    // the (a, b) whose residuals `e` holds
    let mut written: Option<(Vec<f64>, Vec<f64>)> = None;
    let mut pass = |x: Centred, start: usize, a: &[f64], b: &[f64]| {
        let into = e
            .as_deref_mut()
            .and_then(|e| arma_pass_into(x, start, a, b, e));
        match into {
            Some(out) => {
                written = Some((a.to_vec(), b.to_vec()));
                out
            }
            None => arma_pass(x, start, a, b),
        }
    };
    let (mut a, mut b) = (a0.to_vec(), b0.to_vec());
    let (mut rss, mut jtj, mut jte) = pass(x, start, &a, &b);
    for _ in 0..max_iter {
        let Some(step) = normal_equations(&jtj, &jte, k) else {
            break;
        };
        let theta: Vec<f64> = a.iter().chain(&b).copied().collect();
        if step
            .iter()
            .zip(&theta)
            .all(|(s, v)| s.abs() < 1e-9 * (1.0 + v.abs()))
        {
            break;
        }
        if enough > 0.0 && predicted_decrease(&step, &jte) < enough * rss {
            break;
        }
        // below the RSS's resolution (see ma_cls): take the step if the RSS did not
        // rise beyond rounding, and stop
        if predicted_decrease(&step, &jte) < FLAT_RSS * rss {
            let at: Vec<f64> = (0..p).map(|i| a[i] + step[i]).collect();
            let bt: Vec<f64> = (0..q).map(|i| b[i] + step[p + i]).collect();
            if ma_invertible(&bt) {
                let r = pass(x, start, &at, &bt).0;
                if r <= rss * (1.0 + FLAT_RSS) {
                    (a, b, rss) = (at, bt, r);
                }
            }
            break;
        }
        let mut scale = 1.0;
        let mut moved = false;
        for _ in 0..30 {
            let at: Vec<f64> = (0..p).map(|i| a[i] + scale * step[i]).collect();
            let bt: Vec<f64> = (0..q).map(|i| b[i] + scale * step[p + i]).collect();
            if ma_invertible(&bt) {
                let (r, jt, je) = pass(x, start, &at, &bt);
                if r <= rss {
                    moved = rss - r > 1e-12 * rss;
                    (a, b, rss, jtj, jte) = (at, bt, r, jt, je);
                    break;
                }
            }
            scale *= 0.5;
        }
        if !moved {
            break;
        }
    }
    let holds = written.is_some_and(|(wa, wb)| same_bits(&wa, &a) && same_bits(&wb, &b));
    (a, b, rss, holds)
}

/// Whether two slices hold the same values bit for bit.
pub(super) fn same_bits(u: &[f64], v: &[f64]) -> bool {
    u.len() == v.len() && u.iter().zip(v).all(|(a, b)| a.to_bits() == b.to_bits())
}

/// The linear ARMA(p,q) the FARMA fit starts from (and nests): conditional least
/// squares ([`fit_arma`]) on the first [`START_MAX`] samples of `x`, refined on longer
/// prefixes and then on every sample by [`arma_cls_within`] (rows t >= `start`, to
/// [`START_ENOUGH`]) when the series is longer. The workflow's
/// ARMA baseline is this same fit, so a FARMA RSS can be compared with it. None when
/// the design is singular.
///
/// The refinement runs on prefixes of N / [`REFINE_RATIO`]^k samples, k = ..., 1, 0
/// (those longer than [`START_MAX`]), shortest first: each prefix's optimum is within
/// about 1/sqrt(its length) of the next one's, so the passes over every sample start
/// close to their optimum and need fewer steps, while all the prefixes' passes
/// together cost less than one over every sample. On the bench's FARMA(2,1,1) series
/// at 1e7 samples (timing prints, BENCHMARKS.md): 5 passes over every sample from a
/// fit on the first 2^16, 4 from the prefixes, 2 with [`START_ENOUGH`] as well.
pub fn linear_start(x: &[f64], p: usize, q: usize, start: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    linear_start_into(Centred::plain(x), p, q, start, None).map(|(a, b, _)| (a, b))
}

/// [`linear_start`], the passes over every sample writing their residuals to `e`
/// (when given); the last value says whether `e` holds the residuals at the
/// returned (a, b) ([`arma_cls_residuals`]).
pub(super) fn linear_start_into(
    x: Centred,
    p: usize,
    q: usize,
    start: usize,
    mut e: Option<&mut [f64]>,
) -> Option<(Vec<f64>, Vec<f64>, bool)> {
    // (a copy of the first START_MAX values: the same values)
    let m = fit_arma(&x.prefix(x.len().min(START_MAX)).to_vec(), p, q)?;
    let (mut a, mut b) = (m.ar, m.ma);
    // N / RATIO^k for k = ..., 2, 1, 0, those longer than the first fit's
    let mut lens: Vec<usize> = std::iter::successors(Some(x.len()), |l| Some(l / REFINE_RATIO))
        .take_while(|l| *l > START_MAX)
        .collect();
    lens.reverse();
    let mut holds = false;
    for len in lens {
        let out = if len == x.len() {
            e.as_deref_mut()
        } else {
            None
        };
        (a, b, _, holds) =
            arma_cls_residuals(x.prefix(len), start, (&a, &b), 30, START_ENOUGH, out);
    }
    Some((a, b, holds))
}

/// The linear ARMA (a, b)'s residuals, e_t = x_t - sum a_m x_{t-m} -
/// sum b_m e_{t-m} with zeros before the first sample (the values of
/// [`super::arma::arma_residuals`], in the same operations), and their RSS over t >= `start` in
/// [`rss_from`]'s order: w_t = x_t - sum a_m x_{t-m} in parallel, then the MA filter
/// ([`ma_filter_rss`], in parallel chunks for q = 1, 2).
pub(super) fn arma_residuals_rss(
    x: Centred,
    a: &[f64],
    b: &[f64],
    start: usize,
) -> (Vec<f64>, f64) {
    use rayon::prelude::*;
    let w_rows = |t0: usize, rows: &mut [f64]| {
        for (i, v) in rows.iter_mut().enumerate() {
            let t = t0 + i;
            let mut s = x.at(t);
            for (m, am) in a.iter().enumerate() {
                if t > m {
                    s -= am * x.at(t - m - 1);
                }
            }
            *v = s;
        }
    };
    let fill = |buf: &mut [f64]| {
        buf.par_chunks_mut(FILTER_CHUNK)
            .enumerate()
            .for_each(|(c, rows)| w_rows(c * FILTER_CHUNK, rows))
    };
    // w written straight into a new buffer (its first write), then filtered in place
    let (mut e, _) = buffers::filled(x.len(), w_rows);
    let rss = ma_filter_rss(&mut e, b, start, fill);
    (e, rss)
}

/// [`linear_start`] stops refining once the Gauss-Newton model predicts less than
/// this relative RSS decrease ([`arma_cls_within`]): its RSS is then within about
/// 1e-10 of the linear ARMA's least one, far below the alternation's tolerance
/// (1e-6 by default) and any test's resolution, and a pass over every sample is saved
/// on long series (the step that would check a decrease of that size).
pub const START_ENOUGH: f64 = 1e-10;

/// Growth of the prefixes [`linear_start`] refines the linear ARMA on.
pub const REFINE_RATIO: usize = 16;

/// Samples the linear ARMA start is first fitted on (the first ones); on longer series
/// it is then refined on longer prefixes and on every sample by the streaming
/// [`arma_cls_within`] ([`linear_start`]).
pub const START_MAX: usize = 1 << 14;

/// The least-squares standard-error factors of the linear model's constant
/// coefficients a_m, sqrt([(X'X)^-1]_mm) with X the lagged values x_{t-1}..x_{t-p}
/// over the rows from `start` on: the linear model with constant f_m has trace p (the
/// least-squares hat matrix on X_1..X_p) and Var(a) = sigma^2 (X'X)^-1 with the MA
/// part sum b_m e_{t-m} taken as a known offset. NaN where X'X is singular.
pub(super) fn linear_se_factors(x: Centred, p: usize, start: usize) -> Vec<f64> {
    let lags: Vec<(usize, usize)> = (1..=p).map(|m| (0, m)).collect();
    let (xtx, _) = lagged_normal(x, &[x], &lags, start..x.len());
    let rhs = vec![0.0; p];
    match spd_solve_inverse(&xtx, &rhs, p) {
        Some((_, inv, _)) => (0..p).map(|i| inv[i * p + i].sqrt()).collect(),
        None => vec![f64::NAN; p],
    }
}
