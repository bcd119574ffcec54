//! The b-step: with f fixed, b minimises the RSS of the MA filter of w, by Gauss-Newton
//! with step halving (one pass for q <= 2, [`gn_b_step`]; [`ma_step`] otherwise).

use super::passes::{SpanFill, ma_filter_gn, ma_filter_rss};
use crate::estimator::arma::PassSums;
use crate::estimator::arma::arma_pass;
use crate::estimator::arma::ma_invertible;
use crate::estimator::linalg::normal_equations;

/// The alternation's b-step in one pass ([`ma_filter_gn`]; w written by `fill` chunk
/// by chunk, or already in `buf` when `fill` is None): `buf` becomes the residuals at
/// `b0`, and the Gauss-Newton step from `b0` is taken. Returns (RSS at b0, the
/// stepped b, the step's predicted RSS decrease), or None for q other than 1 and 2
/// (`buf` untouched).
pub(super) fn gn_b_step(
    buf: &mut [f64],
    start: usize,
    b0: &[f64],
    fill: Option<&SpanFill<'_>>,
    refill: impl FnOnce(&mut [f64]),
) -> Option<(f64, Vec<f64>, f64)> {
    pub(super) fn solve<const Q: usize>(s: PassSums<Q>, b0: &[f64]) -> (f64, Vec<f64>, f64) {
        let jtj: Vec<f64> = s.jtj.iter().flatten().copied().collect();
        match normal_equations(&jtj, &s.jte, Q) {
            Some(step) => (
                s.rss,
                b0.iter().zip(&step).map(|(b, d)| b + d).collect(),
                predicted_decrease(&step, &s.jte),
            ),
            None => (s.rss, b0.to_vec(), 0.0),
        }
    }
    match *b0 {
        [b1] => Some(solve(ma_filter_gn(buf, &[b1], start, fill, refill), b0)),
        [b1, b2] => Some(solve(ma_filter_gn(buf, &[b1, b2], start, fill, refill), b0)),
        _ => None,
    }
}

/// A Gauss-Newton step's predicted RSS decrease, step . (-J'e): with
/// step = (J'J)^-1 (-J'e), ||e + J step||^2 = RSS - step . (-J'e).
pub(super) fn predicted_decrease(step: &[f64], neg_jte: &[f64]) -> f64 {
    step.iter().zip(neg_jte).map(|(s, g)| s * g).sum()
}

/// Relative RSS decrease below which a Gauss-Newton step is taken without a line
/// search: a sum of N squares is resolved to about 1e-16 sqrt(N) relative, so for
/// N up to 1e8 a decrease below 1e-12 of the RSS cannot be told from rounding.
pub(super) const FLAT_RSS: f64 = 1e-12;

/// Gauss-Newton for b minimising sum_{t >= start} e_t^2, e_t = w_t - sum b_m e_{t-m}
/// (`arma_pass` with p = 0), with step halving. Each trial point's pass also gives
/// the normal equations there, so an accepted step costs one pass in all.
pub fn ma_cls(w: &[f64], start: usize, b0: &[f64]) -> Vec<f64> {
    let q = b0.len();
    let mut b = b0.to_vec();
    let (mut rss, mut jtj, mut jte) = arma_pass(w, start, &[], &b);
    for _ in 0..30 {
        let Some(step) = normal_equations(&jtj, &jte, q) else {
            break;
        };
        // Stop on the size of the step, not on the RSS: near the optimum the RSS is
        // flat to rounding while b is still determined to ~1e-12.
        if step.iter().all(|s| s.abs() < 1e-12) {
            break;
        }
        // A step this small is inside the quadratic basin: the RSS cannot tell the
        // trial from b any more, so the line search would only halve the step 30
        // times, a pass each, and give up. Take the Gauss-Newton step and stop.
        if step
            .iter()
            .zip(&b)
            .all(|(s, bi)| s.abs() < 1e-9 * (1.0 + bi.abs()))
        {
            let bt: Vec<f64> = (0..q).map(|i| b[i] + step[i]).collect();
            if ma_invertible(&bt) {
                b = bt;
            }
            break;
        }
        // The same when the model predicts a decrease below the RSS's resolution, but
        // such a step need not be small (a flat direction of a badly conditioned J'J):
        // one pass checks that the RSS did not rise beyond rounding, else b stays.
        if predicted_decrease(&step, &jte) < FLAT_RSS * rss {
            let bt: Vec<f64> = (0..q).map(|i| b[i] + step[i]).collect();
            if ma_invertible(&bt) && arma_pass(w, start, &[], &bt).0 <= rss * (1.0 + FLAT_RSS) {
                b = bt;
            }
            break;
        }
        let mut scale = 1.0;
        let mut moved = false;
        for _ in 0..30 {
            let bt: Vec<f64> = (0..q).map(|i| b[i] + scale * step[i]).collect();
            if ma_invertible(&bt) {
                let (r, jt, je) = arma_pass(w, start, &[], &bt);
                if r <= rss * (1.0 + 1e-14) {
                    moved = true;
                    (b, rss, jtj, jte) = (bt, r, jt, je);
                    break;
                }
            }
            scale *= 0.5;
        }
        if !moved {
            break;
        }
    }
    b
}

/// The alternation's checked b-step for q > 2 (for q <= 2 the alternation runs
/// `ma_step_from` from `gn_b_step`'s step when that step is not small, see
/// [`SMALL_STEP`]): one Gauss-Newton step for b on w (in `buf`) from `b0`, then the
/// MA filter at the new b, turning w into the residuals in place, with their RSS: two
/// passes. Near the optimum (every alternation after the first few) one step
/// is about as good as [`ma_cls`]'s several (Gauss-Newton converges linearly here,
/// the residuals not being zero, but one step cuts the start's error about 200-fold:
/// see the test).
/// When the step does not lower the RSS below its value at `b0` (beyond rounding),
/// `refill` puts w back into `buf`, [`ma_cls`] runs with step halving, and the filter
/// runs at its b. Returns (b, RSS over t >= `start`).
pub fn ma_step(
    buf: &mut [f64],
    start: usize,
    b0: &[f64],
    refill: impl FnMut(&mut [f64]),
) -> (Vec<f64>, f64) {
    let q = b0.len();
    let (rss0, jtj, jte) = arma_pass(&*buf, start, &[], b0);
    let b1: Vec<f64> = match normal_equations(&jtj, &jte, q) {
        Some(step) => b0.iter().zip(&step).map(|(b, s)| b + s).collect(),
        None => b0.to_vec(),
    };
    ma_step_from(buf, start, b0, (rss0, b1), refill)
}

/// [`ma_step`] from its Gauss-Newton step already taken: `rss0` the RSS at `b0`, `b1`
/// the stepped b (from `gn_b_step`'s pass, which the alternation has run): the filter
/// at b1 and the check, without `arma_pass`'s pass again.
pub(super) fn ma_step_from(
    buf: &mut [f64],
    start: usize,
    b0: &[f64],
    (rss0, b1): (f64, Vec<f64>),
    mut refill: impl FnMut(&mut [f64]),
) -> (Vec<f64>, f64) {
    if ma_invertible(&b1) {
        let rss1 = ma_filter_rss(buf, &b1, start, &mut refill);
        if rss1 <= rss0 * (1.0 + FLAT_RSS) {
            return (b1, rss1);
        }
        refill(buf);
    }
    let b = ma_cls(buf, start, b0);
    let rss = ma_filter_rss(buf, &b, start, &mut refill);
    (b, rss)
}

/// Largest predicted RSS decrease, relative to the RSS, of a Gauss-Newton step for b
/// that the alternation takes without checking it (`gn_b_step`: the step goes into
/// the next f-step's response, and the next pass's RSS tells whether it helped); a
/// larger step is taken by [`ma_step`], which checks it with a pass of its own. On the
/// bench's FARMA(2,1,1) series (1e6-1e8 samples) the first alternation's step predicts
/// 1.1-1.5e-4 of the RSS (checked), the later ones 4e-6 down to 4e-7.
pub const SMALL_STEP: f64 = 1e-4;
