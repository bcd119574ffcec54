//! Long logs diagnosed at a lower rate: a channel of more than `max_samples` samples is
//! averaged over consecutive blocks of K samples (K the least factor that leaves
//! `max_samples` or fewer) and diagnosed at rate / K, so that the ensemble's memory is
//! bounded whatever the log's length (about 2 GB at the default 2^20 samples and 20
//! replicas; BENCHMARKS.md).
//!
//! What the averaged diagnosis sees: every effect whose block means of K samples are,
//! in distribution, the samples of the same component simulated at rate / K. That
//! holds exactly for the noises, whose samples the simulator draws as means of the
//! continuous-time rate over the sampling interval (`simulator::generate::markov`): the
//! mean of K consecutive interval means is the mean over their joint interval, the
//! sample at rate / K (white noise, quantization, random walk, Gauss-Markov, the
//! bias-instability bank). It holds to second order in K / (rate T) for the
//! deterministic and temperature effects of time scale T (a block mean of a slow
//! signal is its value at the block's centre, plus T''-terms of order (K dt)^2). It does not hold
//! for what acts on each sample: the output path (filter, resolution, saturation), the
//! outliers, and an ARMA or FARMA model fitted at the log's own rate. The first two are
//! taken out of the spec for the averaged diagnosis and put back, unchanged, in
//! `spec_after` (a note says so), and are not candidates (nor is the distinct-value
//! share a feature, nor the log's printed precision read: a block mean of a rounded
//! output lies on a grid of its own); a spec with an ARMA or FARMA
//! component is refused (the averaged log cannot be simulated from it).

use crate::error::{Error, Result};
use crate::simulator::{Component, Kind, Spec};

/// The longest channel diagnosed at its own rate, by default (2^20 samples: the ADIS16405
/// runs' 1e6 are not averaged).
pub const MAX_SAMPLES: usize = 1 << 20;

/// The least K with ceil(n / K) <= max (1 when n <= max or max is 0: never averaged).
pub fn factor(n: usize, max: usize) -> usize {
    if max == 0 || n <= max {
        1
    } else {
        n.div_ceil(max)
    }
}

/// The means of the consecutive blocks of `k` samples of `v`; a last block of fewer than
/// `k` samples is dropped (every averaged sample is a mean of `k`). The sum runs in
/// order, so a block of non-finite values gives a non-finite mean, as the samples would.
pub fn block_means(v: &[f64], k: usize) -> Vec<f64> {
    debug_assert!(k >= 1);
    v.chunks_exact(k)
        .map(|c| c.iter().sum::<f64>() / k as f64)
        .collect()
}

/// Whether a component acts on each sample of the output and is left out of the
/// averaged diagnosis (module doc).
fn per_sample(c: &Component) -> bool {
    c.kind().is_output_path() || c.kind() == Kind::Outliers
}

/// The components of `spec` that [`spec_at`] takes out: (channel, component) in order.
pub type Removed = Vec<(usize, Component)>;

/// `spec` at `rate_hz` (the averaged rate) with the per-sample components of every
/// channel taken out, and what was taken out; an error when a channel holds an ARMA or
/// FARMA model (fitted at the log's own rate: it cannot simulate the averaged log).
pub fn spec_at(spec: &Spec, rate_hz: f64, k: usize) -> Result<(Spec, Removed)> {
    let mut out = spec.clone();
    out.sample_rate_hz = rate_hz;
    let mut removed = Vec::new();
    for (j, ch) in out.channels.iter_mut().enumerate() {
        if let Some(c) = ch
            .components
            .iter()
            .find(|c| matches!(c.kind(), Kind::Arma | Kind::Farma))
        {
            return Err(Error::Usage(format!(
                "channel '{}' of the spec has a component of kind {}, a model at the log's own rate: the log is averaged over blocks of {k} samples for the diagnosis (--max-samples), and that model cannot simulate the averaged log; raise --max-samples (0: never average) or diagnose a shorter log",
                ch.name,
                c.kind().as_str()
            )));
        }
        let (keep, out_j): (Vec<Component>, Vec<Component>) =
            ch.components.drain(..).partition(|c| !per_sample(c));
        ch.components = keep;
        removed.extend(out_j.into_iter().map(|c| (j, c)));
    }
    Ok((out, removed))
}

/// `spec_after` of an averaged diagnosis at the log's own rate `rate_hz`, with the
/// components [`spec_at`] took out put back after each channel's others (the output
/// path's components keep their order among themselves, which is all the simulator
/// reads of it).
pub fn restore(spec_after: &Spec, rate_hz: f64, removed: &Removed) -> Spec {
    let mut out = spec_after.clone();
    out.sample_rate_hz = rate_hz;
    for (j, c) in removed {
        out.channels[*j].components.push(c.clone());
    }
    out
}

/// The candidate kinds of an averaged diagnosis: every kind and its recalibration but
/// the per-sample ones and the models at the log's own rate.
pub fn candidate_kinds() -> Vec<String> {
    Kind::ALL
        .into_iter()
        .filter(|k| !(k.is_output_path() || matches!(k, Kind::Outliers | Kind::Arma | Kind::Farma)))
        .flat_map(|k| {
            [
                k.as_str().to_string(),
                format!("recalibrate:{}", k.as_str()),
            ]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factor_is_the_least_that_fits() {
        assert_eq!(factor(1_000_000, MAX_SAMPLES), 1);
        assert_eq!(factor(100, 0), 1);
        assert_eq!(factor(100_000_000, MAX_SAMPLES), 96);
        assert!(100_000_000usize.div_ceil(96) <= MAX_SAMPLES);
        assert!(100_000_000usize.div_ceil(95) > MAX_SAMPLES);
        assert_eq!(factor(11, 5), 3);
    }

    #[test]
    fn block_means_are_the_means_of_full_blocks() {
        let v: Vec<f64> = (0..10).map(|i| i as f64).collect();
        assert_eq!(block_means(&v, 3), vec![1.0, 4.0, 7.0]);
        assert_eq!(block_means(&v, 1), v);
        assert!(block_means(&[1.0, f64::NAN, 2.0, 3.0], 2)[0].is_nan());
    }

    #[test]
    fn the_output_path_is_taken_out_and_put_back_and_a_model_at_the_rate_refused() {
        let spec = crate::simulator::parse_spec(
            r#"
sample_rate_hz = 100.0
[[channel]]
name = "x"
[[channel.component]]
kind = "white_noise"
n = 0.1
[[channel.component]]
kind = "output_resolution"
quantum = 0.05
[[channel.component]]
kind = "rate_random_walk"
k = 0.001
"#,
            std::path::Path::new("test.toml"),
        )
        .unwrap();
        let (avg, removed) = spec_at(&spec, 1.0, 100).unwrap();
        assert_eq!(avg.sample_rate_hz, 1.0);
        let kinds: Vec<Kind> = avg.channels[0]
            .components
            .iter()
            .map(|c| c.kind())
            .collect();
        assert_eq!(kinds, [Kind::WhiteNoise, Kind::RateRandomWalk]);
        let back = restore(&avg, 100.0, &removed);
        assert_eq!(back.sample_rate_hz, 100.0);
        assert_eq!(back.channels[0].components.len(), 3);
        assert_eq!(
            back.channels[0].components[2].kind(),
            Kind::OutputResolution
        );
        let mut arma = spec.clone();
        arma.channels[0].components.push(Component::Arma {
            ar: vec![0.5],
            ma: vec![],
            sigma: 0.1,
        });
        let e = spec_at(&arma, 1.0, 100).unwrap_err().to_string();
        assert!(e.contains("arma") && e.contains("--max-samples"), "{e}");
        let kinds = candidate_kinds();
        assert!(kinds.contains(&"rate_random_walk".to_string()));
        assert!(kinds.contains(&"recalibrate:white_noise".to_string()));
        assert!(
            !kinds
                .iter()
                .any(|k| k.contains("output_") || k.contains("farma"))
        );
    }
}
