//! Long logs diagnosed at a lower rate: a channel of more than `max_samples` samples is
//! averaged over consecutive blocks of K samples (K the least factor that leaves
//! `max_samples` or fewer) and diagnosed at rate / K, so that the ensemble's memory is
//! bounded whatever the log's length (about 2 GB at the default 2^20 samples and 20
//! replicas, about 200 MB at 2^16; BENCHMARKS.md). What acts on each sample is diagnosed
//! on the log's first samples at its own rate ([`per_sample`]).
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

use indicatif::ProgressBar;

use super::{Diagnosis, GapParams, RealLog};
use crate::error::{Error, Result};
use crate::simulator::{Component, Kind, Spec};

/// The longest channel diagnosed at its own rate, by default (2^20 samples: the
/// ADIS16405 runs' 1e6 are not averaged; at 2^16 they are averaged by 16 and
/// diagnosed about 7x faster in a tenth of the memory, at a cost in accuracy on the
/// per-sample effects that BENCHMARKS.md gives, the twenty-fifth session).
pub const MAX_SAMPLES: usize = 1 << 20;

/// The longest channel diagnosed at its own rate when the spec holds a model at that
/// rate (ARMA, FARMA: [`rate_model`]), which cannot simulate an averaged log; a longer
/// one is refused ([`spec_at`]).
pub const MODEL_MAX_SAMPLES: usize = 1 << 20;

/// Whether a channel of `spec` holds an ARMA or FARMA model, fitted at the log's own
/// rate.
pub fn rate_model(spec: &Spec) -> bool {
    spec.channels.iter().any(|ch| {
        ch.components
            .iter()
            .any(|c| matches!(c.kind(), Kind::Arma | Kind::Farma))
    })
}

/// The samples of an averaged log diagnosed at its own rate for the per-sample
/// components, by default ([`per_sample`]; 2^16: 655 s at 100 Hz, 65.5 s at 1 kHz).
pub const EXCERPT_SAMPLES: usize = 1 << 16;

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
fn acts_on_each_sample(c: &Component) -> bool {
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
                "channel '{}' of the spec has a component of kind {}, a model at the log's own rate: the log is averaged over blocks of {k} samples for the diagnosis (it is longer than {MODEL_MAX_SAMPLES} samples, the most diagnosed at its own rate with such a model), and that model cannot simulate the averaged log; raise --max-samples (0: never average) or diagnose a shorter log",
                ch.name,
                c.kind().as_str()
            )));
        }
        let (keep, out_j): (Vec<Component>, Vec<Component>) = ch
            .components
            .drain(..)
            .partition(|c| !acts_on_each_sample(c));
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

/// The candidate kinds of the per-sample part ([`per_sample`]): the output path's, the
/// outliers', the models at the log's own rate (ARMA, FARMA), their recalibrations, and
/// the white noise's recalibration: the averaged part sees the noise a rounding or
/// outliers add as white noise and raises its level, which the per-sample part then
/// takes back beside them.
pub fn per_sample_kinds() -> Vec<String> {
    Kind::ALL
        .into_iter()
        .filter(|k| k.is_output_path() || matches!(k, Kind::Outliers | Kind::Arma | Kind::Farma))
        .flat_map(|k| {
            [
                k.as_str().to_string(),
                format!("recalibrate:{}", k.as_str()),
            ]
        })
        .chain(std::iter::once(format!(
            "recalibrate:{}",
            Kind::WhiteNoise.as_str()
        )))
        .collect()
}

/// The per-sample part of the averaged diagnosis `d` of `real`: the log's first
/// `prm.excerpt_samples` samples (at most `prm.max_samples`), every channel cut alike,
/// diagnosed at the log's own rate against `d.spec_after` (the slow effects found on
/// the averaged log in it, the per-sample components put back), with the output path
/// and outliers as the only candidates ([`per_sample_kinds`]). The excerpt is the log's
/// start, so that the spec after simulates it from the same time 0 (a warm-up, a ramp,
/// a temperature profile line up).
///
/// Merged into `d`: `significant` when either part is, `explained` when both are, the
/// spec after the per-sample part's, a note with its gaps; the part itself in
/// `d.per_sample`. A per-sample part that adds nothing leaves the verdict to the
/// averaged part: its threshold is that of the spec after's own simulations, which
/// do not hold the error of the slow effects estimated on the averaged log, so a gap
/// that no per-sample candidate shrinks is not taken as a per-sample effect (a note
/// gives it). A per-sample part that cannot be diagnosed (an excerpt too short for
/// the block layout) leaves `d` as it was, with a note saying why.
pub fn per_sample<'a>(real: &RealLog<'a>, prm: &GapParams, pb: &ProgressBar, d: &mut Diagnosis) {
    let n = prm.excerpt_samples.min(prm.max_samples).min(real.x.len());
    if n == 0 {
        return;
    }
    let cut = |v: &[(String, &'a [f64])]| -> Vec<(String, &'a [f64])> {
        v.iter()
            .map(|(s, v)| (s.clone(), &v[..n.min(v.len())]))
            .collect()
    };
    let log = RealLog {
        channel: real.channel.clone(),
        x: &real.x[..n],
        rate_hz: real.rate_hz,
        temperature_c: real.temperature_c.map(|t| &t[..n.min(t.len())]),
        others: cut(&real.others),
        spec_dir: real.spec_dir.clone(),
        scan: cut(&real.scan),
    };
    let kinds = per_sample_kinds();
    let only = match &prm.only_kinds {
        Some(o) => o.iter().filter(|s| kinds.contains(s)).cloned().collect(),
        None => kinds,
    };
    let p = GapParams {
        only_kinds: Some(only),
        max_samples: 0,
        averaged: false,
        ..prm.clone()
    };
    let seconds = n as f64 / real.rate_hz;
    match super::diagnose_with_progress(&log, &d.spec_after, &p, pb) {
        Ok(e) => {
            d.own_explained = d.explained;
            if !e.added.is_empty() {
                d.significant |= e.significant;
                d.explained &= e.explained;
            } else if e.gap_before > e.gap_threshold {
                d.notes.push(format!(
                    "the per-sample part's gap {:.3} is above its threshold {:.3}, and no per-sample candidate shrinks it: it is left to the averaged part's verdict (the slow effects are simulated on the excerpt as estimated on the averaged log, an estimation error that threshold does not hold)",
                    e.gap_before, e.gap_threshold
                ));
            }
            d.spec_after = e.spec_after.clone();
            d.notes.push(format!(
                "the per-sample part (per_sample): the log's first {n} samples ({seconds:.1} s) were diagnosed at {} Hz against the spec after the averaged diagnosis, the output path and outliers the only candidates: gap {:.3} -> {:.3} (threshold {:.3}{}), added: {}",
                real.rate_hz,
                e.gap_before,
                e.gap_after,
                e.gap_threshold,
                if e.significant { "" } else { ", not significant" },
                if e.added.is_empty() {
                    "nothing".to_string()
                } else {
                    e.added
                        .iter()
                        .map(|a| a.kind.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            ));
            d.per_sample = Some(Box::new(e));
        }
        Err(e) => d.notes.push(format!(
            "the per-sample part was not diagnosed (the log's first {n} samples, {seconds:.1} s; --excerpt-samples): {e}"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_factor_is_the_least_that_fits() {
        assert_eq!(factor(1_000_000, MAX_SAMPLES), 1);
        assert_eq!(factor(1_000_000, 1 << 16), 16);
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
