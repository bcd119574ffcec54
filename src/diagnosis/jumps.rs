//! Level jumps: whether a log's slow changes come in jumps that the simulations of the
//! spec after do not make. A bias step at one moment or a random telegraph bias moves
//! the level in a few large steps; a rate random walk, a Gauss-Markov or a flicker
//! noise moves it by many small Gaussian ones, and with the right size can match the
//! log's Allan variance and spectrum. Their difference is in the law of the changes of
//! the level: the differences of consecutive window means d_j = m_{j+1} - m_j are
//! heavy-tailed for jumps (a few of them carry most of the variance) and Gaussian for
//! the noises. The statistic is their kurtosis, K = N sum (d_j - dbar)^4 /
//! (sum (d_j - dbar)^2)^2 (3 for a Gaussian sample, about N for a single jump among N
//! windows; Pearson's beta_2), at a few window lengths, compared with the kurtosis of
//! each simulation of the spec after, read through its output path (a rounding coarse
//! against the noise holds a slowly wandering level on one step of its grid and then
//! moves it by a whole step: jumps of the path's own, which the real log shows too).
//! A tail shorter than a window is left out.

/// The numbers of windows the log is cut into: each window length is the log's length
/// over one of them.
pub const WINDOW_COUNTS: [usize; 3] = [32, 128, 512];

/// The fewest samples in a window.
pub const MIN_WINDOW: usize = 10;

/// How far the real log's kurtosis must lie above the simulations': above the largest
/// of them and above their mean by this many of their standard deviations.
pub const JUMP_SD: f64 = 5.0;

/// The kurtosis of the differences of consecutive means of windows of `window`
/// samples of `x` (module doc); NaN with fewer than 8 windows or no spread.
pub fn mean_step_kurtosis(x: &[f64], window: usize) -> f64 {
    if window == 0 {
        return f64::NAN;
    }
    let means: Vec<f64> = x
        .chunks_exact(window)
        .map(|c| c.iter().sum::<f64>() / window as f64)
        .collect();
    if means.len() < 8 {
        return f64::NAN;
    }
    let d: Vec<f64> = means.windows(2).map(|w| w[1] - w[0]).collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let (s2, s4) = d.iter().fold((0.0, 0.0), |(a, b), v| {
        let e = (v - mean) * (v - mean);
        (a + e, b + e * e)
    });
    if s2 > 0.0 {
        n * s4 / (s2 * s2)
    } else {
        f64::NAN
    }
}

/// What [`level_jumps`] found at one window length.
#[derive(Clone, Debug, PartialEq)]
pub struct Jumps {
    /// The window length, s.
    pub window_s: f64,
    /// The real log's kurtosis.
    pub real: f64,
    /// The simulations' largest kurtosis and their mean and standard deviation.
    pub sims_max: f64,
    pub sims_mean: f64,
    pub sims_sd: f64,
}

impl Jumps {
    /// The note of a verdict that this finding turns.
    pub fn note(&self) -> String {
        format!(
            "not explained: the changes of the level between windows of {} s come in jumps: the kurtosis of the differences of consecutive window means is {:.1} in the log against at most {:.1} (mean {:.1}, sd {:.2}) in the simulations of the spec after, which the added effects do not make: a bias step or a telegraph signal is as likely",
            crate::fmt::num(self.window_s),
            self.real,
            self.sims_max,
            self.sims_mean,
            self.sims_sd
        )
    }
}

/// The kurtosis of [`mean_step_kurtosis`] of `x` at each window count of
/// [`WINDOW_COUNTS`] (windows of `n / count` samples, `n` the real log's length; NaN
/// where a window would hold fewer than [`MIN_WINDOW`]).
pub fn kurtoses(x: &[f64], n: usize) -> [f64; WINDOW_COUNTS.len()] {
    WINDOW_COUNTS.map(|count| {
        let window = n / count;
        if window < MIN_WINDOW {
            f64::NAN
        } else {
            mean_step_kurtosis(x, window)
        }
    })
}

/// The first window length (of [`WINDOW_COUNTS`], windows of at least [`MIN_WINDOW`]
/// samples) at which the real log `x`'s kurtosis lies above every simulation's in
/// `sims` and above their mean by [`JUMP_SD`] of their sd; None when there is none.
pub fn level_jumps(x: &[f64], sims: &[&[f64]], rate_hz: f64) -> Option<Jumps> {
    let ks: Vec<_> = sims.iter().map(|s| kurtoses(s, x.len())).collect();
    level_jumps_of(x, &ks, rate_hz)
}

/// [`level_jumps`] from each simulation's [`kurtoses`] (`sims`), computed by the
/// caller (through the simulation's output path, one at a time).
pub fn level_jumps_of(
    x: &[f64],
    sims: &[[f64; WINDOW_COUNTS.len()]],
    rate_hz: f64,
) -> Option<Jumps> {
    if sims.len() < 2 {
        return None;
    }
    for (i, count) in WINDOW_COUNTS.into_iter().enumerate() {
        let window = x.len() / count;
        if window < MIN_WINDOW {
            continue;
        }
        let real = mean_step_kurtosis(x, window);
        let ks: Vec<f64> = sims
            .iter()
            .map(|s| s[i])
            .filter(|k| k.is_finite())
            .collect();
        if !real.is_finite() || ks.len() < 2 {
            continue;
        }
        let m = ks.len() as f64;
        let mean = ks.iter().sum::<f64>() / m;
        let sd = (ks.iter().map(|k| (k - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt();
        let max = ks.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if real > max && real > mean + JUMP_SD * sd {
            return Some(Jumps {
                window_s: window as f64 / rate_hz,
                real,
                sims_max: max,
                sims_mean: mean,
                sims_sd: sd,
            });
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    use super::*;

    fn white(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
    }

    fn walk(n: usize, k: f64, seed: u64) -> Vec<f64> {
        let mut acc = 0.0;
        white(n, seed)
            .into_iter()
            .zip(white(n, seed + 1000))
            .map(|(e, w)| {
                acc += k * w;
                acc + e
            })
            .collect()
    }

    #[test]
    fn kurtosis_of_one_jump_is_about_the_window_count_and_of_noise_about_three() {
        // a step alone: one nonzero difference among N - 1
        let n = 64 * 100;
        let step: Vec<f64> = (0..n).map(|t| if t < n / 2 { 0.0 } else { 1.0 }).collect();
        let k = mean_step_kurtosis(&step, 100);
        // N s4 / s2^2 of one value v among N: (N - 1)^2 / N ... about N - 3
        assert!((k - 61.0).abs() < 1.0, "{k}");
        let kw = mean_step_kurtosis(&white(400_000, 1), 400);
        assert!((kw - 3.0).abs() < 0.5, "{kw}");
    }

    #[test]
    fn a_telegraph_signal_is_found_and_a_random_walk_of_its_size_is_not() {
        let n = 72_000;
        let sims: Vec<Vec<f64>> = (0..20).map(|r| walk(n, 0.02, 10 + r)).collect();
        let sim_refs: Vec<&[f64]> = sims.iter().map(|v| v.as_slice()).collect();
        // another draw of the simulations' own process: not jumps
        assert_eq!(level_jumps(&walk(n, 0.02, 99), &sim_refs, 10.0), None);
        // ten switches between two levels, on white noise
        let mut level = 0.0;
        let tele: Vec<f64> = white(n, 7)
            .into_iter()
            .enumerate()
            .map(|(t, e)| {
                if t > 0 && t % 7_200 == 0 {
                    level = if level == 0.0 { 3.0 } else { 0.0 };
                }
                level + e
            })
            .collect();
        let j = level_jumps(&tele, &sim_refs, 10.0).expect("jumps");
        assert!(j.real > j.sims_max && j.real > 5.0, "{j:?}");
    }
}
