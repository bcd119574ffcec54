//! The output filter fitted by simulation beside a coarse output resolution: the
//! low-pass filter and the form of the rounding (on the rate or on the angle) read
//! together, when the spec already rounds its output: a filter to add when it has
//! none, a filter in place of its own when it has one.
//!
//! Why a second fit: [`super::output_path::output_filter`] reads the filter off the
//! PSD's roll-off and takes the rounding as additive white noise (q^2 / 12 per sample),
//! which holds while the quantum is small against the noise. A log with a few levels
//! (a quantum of the order of the sample's standard deviation) has a rounding error
//! that depends on the signal, and the roll-off it shows is no longer that model's. Here
//! every trial path is applied, exactly as the simulator applies it
//! ([`crate::diagnosis::path::PathStage`]), to the pre-path sums of the first
//! [`FIT_REPLICAS`] replicas of the fold's ensemble, and the trial whose statistics of
//! the training part lie nearest the real log's is kept (the method of simulated
//! moments: McFadden 1989, "A method of simulated moments for estimation of discrete
//! response models without numerical integration", Econometrica 57; Gourieroux,
//! Monfort and Renault 1993, "Indirect inference", J. Appl. Econometrics 8).
//!
//! The statistics, on the training blocks (at most [`FIT_SAMPLES`] samples, the first
//! ones) joined end to end without steps:
//! - the log of the Welch PSD (Hann segments of [`SEGMENT`] samples, the mean removed
//!   from each) averaged over [`N_BANDS`] bands of bins equally spaced in ln(bin);
//! - the log of the shares of first differences of 0, 1, 2 and 3 or more quanta (each
//!   share plus one over the count, so that an empty class stays finite).
//!
//! The cost is the mean squared difference of the real log's values from the replicas'
//! mean, per family, the two families' means added. The trials: order 1 and order 2
//! (Butterworth), each discretized by zero-order hold and by the bilinear transform,
//! the rounding on the rate and on the angle, the bandwidth over a log grid of
//! [`GRID_POINTS`] from f_s / 500 to 0.45 f_s; for each filter form (order and
//! discretization) the best trial is refined by a golden-section search between its
//! grid neighbours, and each form's best is a candidate. A best bandwidth at an end of
//! the grid is a bound, not an estimate ([`PathFit::at_edge`]). The fit runs only when
//! the rounding is coarse against the log's short-term noise ([`coarse`]).

use std::ops::Range;

use rayon::prelude::*;

use super::Context;
use super::lsq::golden_argmin;
use crate::diagnosis::path::PathStage;
use crate::simulator::{Component, Discretization};
use crate::stats::psd::{Detrend, welch};

/// The most training samples the fit reads (the first ones of the training blocks).
pub const FIT_SAMPLES: usize = 1 << 17;
/// Replicas each trial path is applied to.
pub const FIT_REPLICAS: usize = 4;
/// Welch segment length of the PSD statistic.
pub const SEGMENT: usize = 256;
/// Bands of the PSD statistic.
pub const N_BANDS: usize = 16;
/// Bandwidths on the search grid of each form.
pub const GRID_POINTS: usize = 20;

/// The least quantum, in units of the training log's short-term noise level
/// sigma = sqrt(mean (x_t - x_{t-1})^2 / 2), at which the fit runs ([`coarse`]).
pub const COARSE_QUANTUM_SIGMAS: f64 = 0.5;

/// Whether the rounding to `quantum` is coarse against the short-term noise of `x` on
/// `ranges`: quantum > [`COARSE_QUANTUM_SIGMAS`] sigma, sigma the root mean square
/// first difference over sqrt(2) (the sample's sd for white noise). Below that the
/// rounding error is close to independent uniform noise of variance q^2 / 12, the
/// model of the PSD fit (Widrow's quantization theorems hold approximately once the
/// quantum is below the input's standard deviation: Widrow and Kollar 2008,
/// "Quantization Noise", ch. 4-5), and the fit by simulation is not run.
pub fn coarse(x: &[f64], ranges: &[Range<usize>], quantum: f64) -> bool {
    let (mut ss, mut n) = (0.0, 0usize);
    for r in ranges {
        for w in x[r.clone()].windows(2) {
            let d = w[1] - w[0];
            if d.is_finite() {
                ss += d * d;
                n += 1;
            }
        }
    }
    n > 0 && quantum > COARSE_QUANTUM_SIGMAS * (ss / n as f64 / 2.0).sqrt()
}

/// The best trial path of one filter form.
#[derive(Clone, Debug, PartialEq)]
pub struct PathFit {
    /// The filter (an `output_filter` component).
    pub filter: Component,
    /// The rounding of the best trial is on the integrated angle.
    pub on_angle: bool,
    /// Its cost.
    pub cost: f64,
    /// The cost of the fold's path as it is (its filter, if any, and the rounding in
    /// the spec's form).
    pub cost_now: f64,
    /// The bandwidth stopped at an end of its grid.
    pub at_edge: bool,
}

/// `ranges` cut to at most `max` samples in all, in order.
fn first_samples(ranges: &[Range<usize>], max: usize) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut left = max;
    for r in ranges {
        if left == 0 {
            break;
        }
        let len = r.len().min(left);
        if len >= 2 {
            out.push(r.start..r.start + len);
        }
        left -= len;
    }
    out
}

/// The statistics of the module doc of `y` on `ranges`, for the grid step `quantum`;
/// None when the joined samples are fewer than one PSD segment.
fn moments(y: &[f64], ranges: &[Range<usize>], rate_hz: f64, quantum: f64) -> Option<Vec<f64>> {
    let joined = super::output_path::joined_without_steps(y, ranges);
    let mut steps = [0usize; 4];
    for r in ranges {
        for w in y[r.clone()].windows(2) {
            let k = ((w[1] - w[0]).abs() / quantum).round();
            steps[(k as usize).min(3)] += 1;
        }
    }
    if joined.len() < SEGMENT {
        return None;
    }
    let psd = welch("path fit", &joined, rate_hz, SEGMENT, Detrend::Constant).ok()?;
    let nk = psd.psd.len();
    let ln_top = ((nk - 1) as f64).ln();
    let mut sums = [0.0; N_BANDS];
    let mut counts = [0usize; N_BANDS];
    for (k, p) in psd.psd.iter().enumerate().skip(1) {
        let b = (((k as f64).ln() / ln_top) * N_BANDS as f64).floor() as usize;
        let b = b.min(N_BANDS - 1);
        sums[b] += p;
        counts[b] += 1;
    }
    let mut out: Vec<f64> = sums
        .iter()
        .zip(&counts)
        .filter(|(_, c)| **c > 0)
        .map(|(s, c)| (s / *c as f64).max(f64::MIN_POSITIVE).ln())
        .collect();
    let total: usize = steps.iter().sum();
    let tf = total.max(1) as f64;
    out.extend(steps.iter().map(|c| ((*c as f64 + 1.0) / tf).ln()));
    Some(out)
}

/// The cost of the module doc: the real log's statistics `real` against the replicas'
/// `sims` (the last four of each are the step shares, the rest the PSD bands).
fn cost(real: &[f64], sims: &[Vec<f64>]) -> f64 {
    if sims.is_empty() || sims.iter().any(|s| s.len() != real.len()) {
        return f64::INFINITY;
    }
    let m = sims.len() as f64;
    let n_psd = real.len() - 4;
    let sq = |k: usize| {
        let mean = sims.iter().map(|s| s[k]).sum::<f64>() / m;
        (real[k] - mean).powi(2)
    };
    let psd = (0..n_psd).map(sq).sum::<f64>() / n_psd.max(1) as f64;
    let shares = (n_psd..real.len()).map(sq).sum::<f64>() / 4.0;
    psd + shares
}

/// A low-pass filter of `order` (Butterworth for order 2), `disc`, at `bandwidth_hz`.
fn filter(order: usize, disc: Discretization, bandwidth_hz: f64) -> Component {
    Component::OutputFilter {
        order,
        bandwidth_hz,
        damping: None,
        discretization: disc,
    }
}

/// The filter and rounding form fitted by simulation (module doc) for the fold of
/// `cx`, whose output path `now` rounds to `quantum`, with or without a filter; each
/// trial is `now` with the trial's filter and rounding in place of its own. One fit
/// per filter form (order 1 and 2, each discretization), with the rounding form and
/// bandwidth best for it: as with the PSD fit's forms, the withheld scoring chooses
/// among them (half a log may not tell them apart). None when the training part is
/// shorter than a PSD segment.
pub fn fit(cx: &Context, now: &PathStage, quantum: f64) -> Option<Vec<PathFit>> {
    let fs = cx.rate_hz();
    let ranges = first_samples(cx.ranges(), FIT_SAMPLES);
    let end = ranges.last()?.end;
    let real = moments(cx.real, &ranges, fs, quantum)?;
    let reps: Vec<&[f64]> = cx
        .target
        .iter()
        .take(FIT_REPLICAS)
        .map(|t| &t[..end])
        .collect();
    let resolution = |on_angle: bool| Component::OutputResolution { quantum, on_angle };
    // the cost of `path` (the replicas' outputs from a path at rest, as the
    // simulator's)
    let cost_of = |path: &PathStage| -> f64 {
        let sims: Vec<Vec<f64>> = reps
            .iter()
            .filter_map(|x| {
                let mut y = x.to_vec();
                path.apply(&mut y);
                moments(&y, &ranges, fs, quantum)
            })
            .collect();
        cost(&real, &sims)
    };
    let trial = |on_angle: bool, order: usize, disc: Discretization, bandwidth_hz: f64| {
        now.with(&filter(order, disc, bandwidth_hz))
            .with(&resolution(on_angle))
    };
    let cost_now = cost_of(now);
    let (lo, hi) = ((fs / 500.0).ln(), (0.45 * fs).ln());
    let bw = |i: usize| (lo + (hi - lo) * i as f64 / (GRID_POINTS - 1) as f64).exp();
    let forms: Vec<(bool, usize, Discretization)> = [false, true]
        .into_iter()
        .flat_map(|a| {
            [1, 2].into_iter().flat_map(move |o| {
                [Discretization::Zoh, Discretization::Bilinear]
                    .into_iter()
                    .map(move |d| (a, o, d))
            })
        })
        .collect();
    let trials: Vec<(usize, usize)> = (0..forms.len())
        .flat_map(|f| (0..GRID_POINTS).map(move |i| (f, i)))
        .collect();
    let costs: Vec<f64> = trials
        .par_iter()
        .map(|&(f, i)| {
            let (a, o, d) = forms[f];
            cost_of(&trial(a, o, d, bw(i)))
        })
        .collect();
    // per filter form (order, discretization): its best rounding form and bandwidth
    let mut fits = Vec::new();
    for (order, disc) in [
        (1, Discretization::Zoh),
        (1, Discretization::Bilinear),
        (2, Discretization::Zoh),
        (2, Discretization::Bilinear),
    ] {
        let Some((best, &best_cost)) = costs
            .iter()
            .enumerate()
            .filter(|(t, c)| {
                let (_, o, d) = forms[trials[*t].0];
                o == order && d == disc && c.is_finite()
            })
            .min_by(|a, b| a.1.total_cmp(b.1))
        else {
            continue;
        };
        let (f, i) = trials[best];
        let on_angle = forms[f].0;
        let at_edge = i == 0 || i == GRID_POINTS - 1;
        let (bandwidth_hz, cost) = if at_edge {
            (bw(i), best_cost)
        } else {
            let step = (hi - lo) / (GRID_POINTS - 1) as f64;
            let u0 = bw(i).ln();
            let (u, c) = golden_argmin(u0 - step, u0 + step, 12, |u| {
                cost_of(&trial(on_angle, order, disc, u.exp()))
            });
            if c < best_cost {
                (u.exp(), c)
            } else {
                (bw(i), best_cost)
            }
        };
        fits.push(PathFit {
            filter: filter(order, disc, bandwidth_hz),
            on_angle,
            cost,
            cost_now,
            at_edge,
        });
    }
    Some(fits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_samples_of_the_ranges_are_kept_in_order() {
        let r = vec![0..10, 20..30, 40..50];
        assert_eq!(first_samples(&r, 15), vec![0..10, 20..25]);
        assert_eq!(first_samples(&r, 100), r);
        // a remainder of one sample has no difference: left out
        assert_eq!(first_samples(&r, 11), vec![0..10]);
    }

    #[test]
    fn the_step_shares_count_quanta_of_the_first_differences() {
        // 300 samples on a 0.5 grid: differences of 0, 1, 2 and 3 quanta in turn
        let pattern = [0.0, 0.0, 0.5, 1.5, 0.0];
        let y: Vec<f64> = (0..300).map(|t| pattern[t % 5]).collect();
        let whole = std::iter::once(0..300).collect::<Vec<_>>();
        let m = moments(&y, &whole, 10.0, 0.5).unwrap();
        let shares: Vec<f64> = m[m.len() - 4..].iter().map(|v| v.exp()).collect();
        // 299 differences: 0 (60), +1 (60), +2 (60), -3 (60), 0 (59)
        let n = 299.0;
        let want = [119.0, 60.0, 60.0, 60.0].map(|c: f64| (c + 1.0) / n);
        for (s, w) in shares.iter().zip(want) {
            assert!((s - w).abs() < 1e-12, "{shares:?} against {want:?}");
        }
        // a range shorter than a PSD segment: no statistics
        let short = std::iter::once(0..100).collect::<Vec<_>>();
        assert!(moments(&y, &short, 10.0, 0.5).is_none());
    }

    #[test]
    fn a_quantum_is_coarse_above_half_the_short_term_noise_level() {
        // alternating +-1: differences of 2, sigma = sqrt(4 / 2) = sqrt(2)
        let x: Vec<f64> = (0..100)
            .map(|t| if t % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let r = std::iter::once(0..100).collect::<Vec<_>>();
        let sigma = 2f64.sqrt();
        assert!(coarse(&x, &r, 0.51 * sigma));
        assert!(!coarse(&x, &r, 0.49 * sigma));
        // a constant: no short-term noise, every quantum is coarse
        let r10 = std::iter::once(0..10).collect::<Vec<_>>();
        assert!(coarse(&[3.0; 10], &r10, 1e-9));
        assert!(!coarse(&[3.0; 10], &[], 1.0));
    }

    #[test]
    fn the_cost_is_zero_for_the_real_statistics_and_grows_with_distance() {
        let real = vec![1.0, 2.0, 3.0, 0.1, 0.2, 0.3, 0.4];
        assert_eq!(cost(&real, &[real.clone(), real.clone()]), 0.0);
        let mut off = real.clone();
        off[0] += 0.3;
        let mut far = real.clone();
        far[0] += 0.6;
        assert!(cost(&real, &[off]) < cost(&real, &[far]));
        assert!(cost(&real, &[vec![1.0]]).is_infinite());
    }
}
