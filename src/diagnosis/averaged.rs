//! Long logs diagnosed at a lower rate: a channel of more than `max_samples` samples is
//! averaged over consecutive blocks of K samples (K the least factor that leaves
//! `max_samples` or fewer) and diagnosed at rate / K, so that the ensemble's memory is
//! bounded whatever the log's length (about 260 MB at the default 2^17 samples and 20
//! replicas, 2 GB at 2^20; BENCHMARKS.md). What acts on each sample is diagnosed
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
//! taken out of the spec for the averaged diagnosis, stand-ins for their block means
//! put in their place (`stand_in`: the same angle rounding at the averaged rate, the
//! filter's block-mean FIR of [`block_filter`], ...), and put back, unchanged, in
//! `spec_after` (a note says so); they are not candidates but for the outliers (nor is
//! the distinct-value share a feature, nor the log's printed precision read: a block
//! mean of a rounded output lies on a grid of its own). A spec with an ARMA or FARMA
//! component, or with a per-sample component nothing stands in for, is diagnosed at
//! the log's own rate up to [`MODEL_MAX_SAMPLES`]; above, the first is refused (the
//! averaged log cannot be simulated from it) and the second averaged without it.

use std::f64::consts::PI;

use indicatif::ProgressBar;

use super::{Diagnosis, GapParams, RealLog, block_filter};
use crate::error::{Error, Result};
use crate::simulator::generate::output::{Fir, LowPass};
use crate::simulator::spec::MAX_FIR_TAPS;
use crate::simulator::{Component, Discretization, Kind, Spec};

/// The longest channel diagnosed at its own rate, by default: 2^17 samples. The
/// ADIS16405 runs' 1e6 samples are averaged by 8: ADIS run 1 is diagnosed in 8.5-8.7 s
/// and 262 MB on 2 cores, against 53 s and 2.0 GB at its own rate (2^20); on the bank's four
/// development parts it got 97 of 114 cases right against 96 at 2^20 and 94 at 2^16
/// (BENCHMARKS.md, the twenty-seventh session).
pub const MAX_SAMPLES: usize = 1 << 17;

/// The longest channel diagnosed at its own rate when the spec holds a model at that
/// rate (ARMA, FARMA: [`rate_model`]), which cannot simulate an averaged log (a longer
/// one is refused, [`spec_at`]), or a per-sample component that nothing stands in for
/// ([`TakenOut::unmatched`]; a longer one is averaged without it).
pub const MODEL_MAX_SAMPLES: usize = 1 << 20;

/// An error when a channel of `spec` holds an ARMA or FARMA model ([`rate_model`]),
/// which cannot simulate the log averaged over blocks of `k` samples.
pub fn refuse_rate_model(spec: &Spec, k: usize) -> Result<()> {
    for ch in &spec.channels {
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
    }
    Ok(())
}

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
    acts_on_each_sample_kind(c.kind())
}

/// [`acts_on_each_sample`] of a kind.
fn acts_on_each_sample_kind(k: Kind) -> bool {
    k.is_output_path() || k == Kind::Outliers
}

/// What [`spec_at`] took out of a spec: the per-sample components, and the stand-ins it
/// put in their place.
#[derive(Clone, Debug, Default)]
pub struct TakenOut {
    /// The per-sample components taken out: (channel, component), in order.
    pub removed: Vec<(usize, Component)>,
    /// Per channel: the index of its first stand-in and how many there are (they
    /// follow the channel's kept components; the averaged diagnosis adds after them).
    stand_ins: Vec<(usize, usize)>,
    /// The block length K.
    k: usize,
    /// The per-sample components taken out that nothing stands in for (a rounding of
    /// the rate coarser than 1.5 sd of the white noise, a saturation, a FIR too slow for
    /// a short one at the averaged rate): (channel, component).
    pub unmatched: Vec<(usize, Component)>,
    /// Per component taken out, in order: what stands in for it, in words.
    pub said: Vec<String>,
}

impl TakenOut {
    /// The indices of channel `j`'s stand-ins in the averaged spec (empty when it has
    /// none).
    pub fn stand_ins_of(&self, j: usize) -> std::ops::Range<usize> {
        self.stand_ins.get(j).map_or(0..0, |&(at, n)| at..at + n)
    }
}

/// What stands in for the per-sample component `c` (averaged over blocks of `k`), in
/// words: `s` is its stand-in, None when nothing does.
fn said(c: &Component, s: Option<&Component>, k: usize) -> String {
    let what = match (c, s) {
        (_, None) => "nothing stands in".to_string(),
        (Component::Outliers { .. }, _) => format!("outliers of 1/{k} of their size"),
        (Component::OutputResolution { on_angle: true, .. }, _) => {
            "the same angle step at the averaged rate".into()
        }
        (Component::OutputResolution { .. }, _) => "white noise of its variance q^2/12".into(),
        (_, Some(Component::OutputFir { taps })) => format!(
            "a FIR of {} taps at the averaged rate that gives the block means' spectrum",
            taps.len()
        ),
        (_, Some(_)) => "itself at the averaged rate (zero-order hold)".into(),
    };
    format!("{}: {what}", c.kind())
}

/// The component that stands in, in the averaged spec, for the per-sample component
/// `c` of a channel at `rate_hz` averaged over blocks of `k` samples whose white noise,
/// through the channel's output filter, has sample standard deviation `sd` (None:
/// nothing stands in).
/// - A rounding of the rate to `quantum` q adds an error uniform over +-q/2 to each
///   sample, independent of the others while q is at most 1.5 `sd` (Sheppard's
///   correction): white noise of density n = q / sqrt(12 rate_hz) (its sample variance
///   n^2 rate_hz = q^2 / 12). A normal sample of sd 1 rounded to q at a fixed offset has
///   the variance 1 + q^2 / 12 to 0.1 % at q = 1.5, to 2.5 % at q = 2, 13 % at q = 2.5
///   and 31 % at q = 3 (numpy, 4e6 draws, the worst of 8 offsets), an error that moves
///   with the offset (a slow drift) and reads as a noise level changing in time:
///   coarser than 1.5, the error follows the signal and nothing stands in.
/// - A rounding of the angle to steps of q / rate_hz: the same rounding at the averaged
///   rate, of the rate quantum q / k (the same angle step). The block mean of the rate
///   read from a rounded angle is (R(A_end) - R(A_start)) / (k dt), R the rounding and
///   A the angle at the block's ends, and the angle at the end of each block is the
///   integral of the block means: the stand-in is exact, at any quantum.
/// - Outliers at `rate_hz` r of size s: the same outliers at the averaged rate, of
///   size s / k (an outlier's share of its block mean), at r (at most the averaged
///   rate); exact while two outliers in one block are rare (r k / rate_hz small).
/// - A low-pass filter, or a FIR: [`filter_stand_in`].
/// - Saturation: nothing.
fn stand_in(c: &Component, rate_hz: f64, k: usize, sd: f64) -> Option<Component> {
    match c {
        Component::Outliers {
            rate_hz: r,
            scale,
            dof,
        } => Some(Component::Outliers {
            rate_hz: r.min(rate_hz / k as f64),
            scale: scale / k as f64,
            dof: *dof,
        }),
        Component::OutputResolution {
            quantum,
            on_angle: false,
        } if *quantum <= 1.5 * sd => Some(Component::WhiteNoise {
            n: quantum / (12.0 * rate_hz).sqrt(),
        }),
        Component::OutputResolution {
            quantum,
            on_angle: true,
        } => Some(Component::OutputResolution {
            quantum: quantum / k as f64,
            on_angle: true,
        }),
        _ => None,
    }
}

/// The power response |H(e^(i v))|^2 of the output filter `c` (a low-pass or a FIR) at
/// `rate_hz`, v in radians per sample; None for another component.
fn filter_power(c: &Component, rate_hz: f64) -> Option<Box<dyn Fn(f64) -> f64>> {
    let to_hz = rate_hz / (2.0 * PI);
    match c {
        Component::OutputFilter {
            order,
            bandwidth_hz,
            damping,
            discretization,
        } => {
            let f = LowPass::with(*order, *bandwidth_hz, *damping, *discretization, rate_hz);
            Some(Box::new(move |v| f.power_response(v * to_hz, rate_hz)))
        }
        Component::OutputFir { taps } => {
            let f = Fir::new(taps);
            Some(Box::new(move |v| f.power_response(v * to_hz, rate_hz)))
        }
        _ => None,
    }
}

/// The variance gain of a white noise through the output filters among `comps`:
/// (1 / 2 pi) the integral of the power response over a period (the mean of 4096
/// equally spaced values; 1 without a filter).
fn noise_gain(comps: &[Component], rate_hz: f64) -> f64 {
    comps
        .iter()
        .filter_map(|c| filter_power(c, rate_hz))
        .map(|p| {
            let n = 4096;
            (0..n)
                .map(|m| p(2.0 * PI * (m as f64 + 0.5) / n as f64))
                .sum::<f64>()
                / n as f64
        })
        .product()
}

/// The component that stands in, in the averaged spec, for the output filter `c` (a
/// low-pass or a FIR) of a channel at `rate_hz` averaged over blocks of `k` samples,
/// whose white noise has sample variance `white_var` and whose other stand-ins are
/// `others` ([`stand_in`]):
/// - the FIR at the averaged rate of [`block_filter::block_mean_fir`]: the averaged
///   white noise and the roundings' stand-ins through it have the spectrum of the block
///   means of the white noise filtered and the roundings after it (the filter at the
///   averaged rate would not: the block means of a filtered white noise are not the
///   filter's output on the block means unless the filter is slow against a block);
/// - when that FIR is longer than [`MAX_FIR_TAPS`] taps (a filter slow against a
///   block, which then nearly commutes with the block mean) or the channel has no
///   white noise: a low-pass as itself at the averaged rate, discretized by the
///   zero-order hold; a FIR, nothing.
fn filter_stand_in(
    c: &Component,
    rate_hz: f64,
    k: usize,
    white_var: f64,
    others: &[Component],
) -> Option<Component> {
    let power = filter_power(c, rate_hz)?;
    let avg_hz = rate_hz / k as f64;
    // the rate roundings' stand-ins: white noise, its variance per averaged sample
    let round_var: f64 = others
        .iter()
        .map(|o| match o {
            Component::WhiteNoise { n } => n * n * avg_hz,
            _ => 0.0,
        })
        .sum();
    if let Some(taps) = block_filter::block_mean_fir(power, k, white_var, round_var, MAX_FIR_TAPS) {
        return Some(Component::OutputFir { taps });
    }
    match c {
        Component::OutputFilter {
            order,
            bandwidth_hz,
            damping,
            ..
        } => Some(Component::OutputFilter {
            order: *order,
            bandwidth_hz: *bandwidth_hz,
            damping: *damping,
            discretization: Discretization::Zoh,
        }),
        _ => None,
    }
}

/// `spec` at the averaged rate `rate_hz / k` (the log's own rate `rate_hz`) with the
/// per-sample components of every channel taken out and their stand-ins
/// (`stand_in`) after each channel's kept components; an error when a channel holds
/// an ARMA or FARMA model (fitted at the log's own rate: it cannot simulate the
/// averaged log).
pub fn spec_at(spec: &Spec, rate_hz: f64, k: usize) -> Result<(Spec, TakenOut)> {
    refuse_rate_model(spec, k)?;
    let mut out = spec.clone();
    out.sample_rate_hz = rate_hz / k as f64;
    let mut taken = TakenOut {
        k,
        ..TakenOut::default()
    };
    for (j, ch) in out.channels.iter_mut().enumerate() {
        let sd = (ch
            .components
            .iter()
            .map(|c| match c {
                Component::WhiteNoise { n } => n * n,
                _ => 0.0,
            })
            .sum::<f64>()
            * rate_hz)
            .sqrt();
        let (keep, out_j): (Vec<Component>, Vec<Component>) = ch
            .components
            .drain(..)
            .partition(|c| !acts_on_each_sample(c));
        ch.components = keep;
        // the rounding comes after the filter: its condition reads the filtered noise
        let sd_out = sd * noise_gain(&out_j, rate_hz).sqrt();
        // the roundings' and outliers' stand-ins first; the filter's reads them and
        // follows them, as the output path orders it
        let mut stand: Vec<Component> = Vec::new();
        let mut pending: Vec<&Component> = Vec::new();
        for c in &out_j {
            match stand_in(c, rate_hz, k, sd_out) {
                Some(s) => {
                    taken.said.push(said(c, Some(&s), k));
                    stand.push(s)
                }
                None => pending.push(c),
            }
        }
        let mut filters = Vec::new();
        for c in pending {
            let f = filter_stand_in(c, rate_hz, k, sd * sd, &stand);
            taken.said.push(said(c, f.as_ref(), k));
            match f {
                Some(f) => filters.push(f),
                None => taken.unmatched.push((j, c.clone())),
            }
        }
        stand.extend(filters);
        taken.stand_ins.push((ch.components.len(), stand.len()));
        ch.components.extend(stand);
        taken.removed.extend(out_j.into_iter().map(|c| (j, c)));
    }
    Ok((out, taken))
}

/// `spec_after` of an averaged diagnosis at the log's own rate `rate_hz`, with the
/// stand-ins [`spec_at`] put in taken out and the components it took out put back
/// after each channel's others (the output path's components keep their order among
/// themselves, which is all the simulator reads of it). Outliers the averaged
/// diagnosis added (in the form of their block means, as `stand_in` puts them) are put at the
/// log's rate: their size times K.
pub fn restore(spec_after: &Spec, rate_hz: f64, taken: &TakenOut) -> Spec {
    let mut out = spec_after.clone();
    out.sample_rate_hz = rate_hz;
    for (j, &(at, n)) in taken.stand_ins.iter().enumerate() {
        let comps = &mut out.channels[j].components;
        for c in comps.iter_mut().skip(at + n) {
            if let Component::Outliers { scale, .. } = c {
                *scale *= taken.k.max(1) as f64;
            }
        }
        if n > 0 && at + n <= comps.len() {
            comps.drain(at..at + n);
        }
    }
    for (j, c) in &taken.removed {
        out.channels[*j].components.push(c.clone());
    }
    out
}

/// An outliers effect of the averaged diagnosis, whose size is that of their block
/// means of `k` samples (as `stand_in` puts them), put at the log's rate (its size times `k`), as
/// [`restore`] puts it in `spec_after`.
pub fn outliers_at_log_rate(e: &mut super::Effect, k: usize) {
    if let Component::Outliers { scale, .. } = &mut e.component {
        *scale *= k as f64;
        if let Some(v) = e.params.get_mut("scale")
            && let Some(x) = v.as_f64()
        {
            *v = serde_json::json!(x * k as f64);
        }
    }
}

/// The candidate kinds of an averaged diagnosis: every kind and its recalibration but
/// the per-sample ones and the models at the log's own rate, and the outliers (their
/// block means are outliers too, as `stand_in` puts them; not recalibrated: a stand-in's
/// recalibration would not reach `spec_after`).
pub fn candidate_kinds() -> Vec<String> {
    let mut v =
        kinds_where(|k| !(acts_on_each_sample_kind(k) || matches!(k, Kind::Arma | Kind::Farma)));
    v.push(Kind::Outliers.as_str().to_string());
    v
}

/// The candidate kinds of the per-sample part ([`per_sample`]): the output path's, the
/// outliers', the models at the log's own rate (ARMA, FARMA), their recalibrations, and
/// the white noise's recalibration: the averaged part sees the noise a rounding or
/// outliers add as white noise and raises its level, which the per-sample part then
/// takes back beside them.
pub fn per_sample_kinds() -> Vec<String> {
    let mut v =
        kinds_where(|k| acts_on_each_sample_kind(k) || matches!(k, Kind::Arma | Kind::Farma));
    v.push(format!("recalibrate:{}", Kind::WhiteNoise.as_str()));
    v
}

/// The kinds of the [`first_pass`]: the output path's and the outliers', with their
/// recalibrations.
fn first_pass_kinds() -> Vec<String> {
    kinds_where(acts_on_each_sample_kind)
}

/// Each kind that `keep` holds, and its recalibration (`recalibrate:<kind>`).
fn kinds_where(keep: impl Fn(Kind) -> bool) -> Vec<String> {
    Kind::ALL
        .into_iter()
        .filter(|k| keep(*k))
        .flat_map(|k| {
            [
                k.as_str().to_string(),
                format!("recalibrate:{}", k.as_str()),
            ]
        })
        .collect()
}

/// `prm` for one part of an averaged log's diagnosis, run at its own rate
/// (`max_samples` 0): `kinds` the only candidates (those of them `prm.only_kinds`
/// allows), `averaged` whether the part's log is the averaged one.
pub fn params_for(prm: &GapParams, kinds: Vec<String>, averaged: bool) -> GapParams {
    let only = match &prm.only_kinds {
        Some(o) => o.iter().filter(|s| kinds.contains(s)).cloned().collect(),
        None => kinds,
    };
    GapParams {
        only_kinds: Some(only),
        max_samples: 0,
        averaged,
        ..prm.clone()
    }
}

/// The samples after the per-sample part's excerpt that its estimators read as
/// training data ([`RealLog::beyond`]), at most: 2^20 (16 excerpts of the default
/// 2^16), a bound on the passes' time whatever the log's length.
pub const BEYOND_SAMPLES: usize = 1 << 20;

/// The log's first `n` samples, every channel and the temperature cut alike; the
/// diagnosed channel's next [`BEYOND_SAMPLES`] (at most) are the excerpt's `beyond`.
fn excerpt<'a>(real: &RealLog<'a>, n: usize) -> RealLog<'a> {
    let cut = |v: &[(String, &'a [f64])]| -> Vec<(String, &'a [f64])> {
        v.iter()
            .map(|(s, v)| (s.clone(), &v[..n.min(v.len())]))
            .collect()
    };
    RealLog {
        channel: real.channel.clone(),
        x: &real.x[..n],
        rate_hz: real.rate_hz,
        temperature_c: real.temperature_c.map(|t| &t[..n.min(t.len())]),
        others: cut(&real.others),
        spec_dir: real.spec_dir.clone(),
        scan: cut(&real.scan),
        beyond: &real.x[n..real.x.len().min(n.saturating_add(BEYOND_SAMPLES))],
    }
}

/// The samples of the per-sample part: `prm.excerpt_samples`, at most
/// `prm.max_samples` and the log's length.
fn excerpt_len(real: &RealLog, prm: &GapParams) -> usize {
    prm.excerpt_samples.min(prm.max_samples).min(real.x.len())
}

/// The diagnosis of the log's first samples ([`excerpt_len`]) at its own rate against
/// `spec`, with `kinds` (those of them `prm.only_kinds` allows) the only candidates.
/// The test-stand events of the samples after the excerpt (`beyond`) are replaced as
/// the diagnosis replaces those of the excerpt ([`super::events`]; not with
/// `--keep-events`): a knock there is no outlier of the sensor.
fn diagnose_excerpt(
    real: &RealLog,
    spec: &Spec,
    prm: &GapParams,
    pb: &ProgressBar,
    kinds: Vec<String>,
    explain_replicas: usize,
) -> Result<Diagnosis> {
    let n = excerpt_len(real, prm);
    let cleaned: Vec<f64>;
    let mut log = excerpt(real, n);
    if !prm.keep_events && !log.beyond.is_empty() {
        let end = n + log.beyond.len();
        let scan: Vec<(String, &[f64])> = real
            .scan
            .iter()
            .map(|(s, v)| (s.clone(), &v[n.min(v.len())..end.min(v.len())]))
            .collect();
        let found = super::events::detect(&real.channel, log.beyond, &scan, real.rate_hz);
        if !found.is_empty() {
            cleaned = super::events::replaced(log.beyond, &found)?;
            log.beyond = &cleaned;
        }
    }
    let p = GapParams {
        explain_replicas,
        ..params_for(prm, kinds, false)
    };
    super::diagnose_with_progress(&log, spec, &p, pb)
}

/// The per-sample part's first pass, before the averaged part: the log's first
/// samples (`excerpt_len`) at its own rate against `spec` as given, with the output
/// path's kinds and the outliers' (and their recalibrations) the only candidates. What
/// it adds is in the spec the averaged part starts from, where each stands in by its
/// block means ([`spec_at`]), so that the averaged part does not take the noise a
/// rounding adds for white noise (nor a slow filter for a Gauss-Markov). None when
/// there is no excerpt or it cannot be diagnosed ([`per_sample`] then says why).
pub fn first_pass(
    real: &RealLog,
    spec: &Spec,
    prm: &GapParams,
    pb: &ProgressBar,
) -> Option<Diagnosis> {
    if excerpt_len(real, prm) == 0 {
        return None;
    }
    diagnose_excerpt(real, spec, prm, pb, first_pass_kinds(), 0).ok()
}

/// The per-sample part of the averaged diagnosis `d` of `real`: the log's first
/// `prm.excerpt_samples` samples (at most `prm.max_samples`), every channel cut alike,
/// diagnosed at the log's own rate against `d.spec_after` (the slow effects found on
/// the averaged log in it, the per-sample components put back), with the per-sample
/// kinds as the only candidates ([`per_sample_kinds`]). The excerpt is the log's
/// start, so that the spec after simulates it from the same time 0 (a warm-up, a ramp,
/// a temperature profile line up). `first` is the [`first_pass`], whose added effects
/// are in `d.spec_after` already.
///
/// Merged into `d`: `significant` when either part is, `explained` when both are, the
/// spec after the per-sample part's, a note with its gaps; the part itself in
/// `d.per_sample` (and the first pass in `d.per_sample_first`). A per-sample part
/// whose passes add nothing leaves the verdict to the averaged part: its threshold is
/// that of the spec after's own simulations, which do not hold the error of the slow
/// effects estimated on the averaged log, so a gap that no per-sample candidate
/// shrinks is not taken as a per-sample effect (a note gives it). A per-sample part
/// that cannot be diagnosed (an excerpt too short for the block layout) leaves `d` as
/// it was, with a note saying why.
pub fn per_sample(
    real: &RealLog,
    prm: &GapParams,
    pb: &ProgressBar,
    d: &mut Diagnosis,
    first: Option<Diagnosis>,
) {
    let n = excerpt_len(real, prm);
    if n == 0 {
        return;
    }
    let seconds = n as f64 / real.rate_hz;
    let first_added: Vec<String> = first
        .iter()
        .flat_map(|f| f.added.iter().map(|a| a.kind.clone()))
        .collect();
    d.per_sample_first = first.map(Box::new);
    match diagnose_excerpt(
        real,
        &d.spec_after,
        prm,
        pb,
        per_sample_kinds(),
        prm.explain_replicas,
    ) {
        Ok(e) => {
            d.own_explained = d.explained;
            if !e.added.is_empty() || !first_added.is_empty() {
                d.significant |= e.significant
                    || d.per_sample_first.as_ref().is_some_and(|f| f.significant);
                d.explained &= e.explained;
            } else if e.gap_before > e.gap_threshold {
                d.notes.push(format!(
                    "the per-sample part's gap {:.3} is above its threshold {:.3}, and no per-sample candidate shrinks it: it is left to the averaged part's verdict (the slow effects are simulated on the excerpt as estimated on the averaged log, an estimation error that threshold does not hold)",
                    e.gap_before, e.gap_threshold
                ));
            }
            d.spec_after = e.spec_after.clone();
            let list = |v: Vec<String>| {
                if v.is_empty() {
                    "nothing".to_string()
                } else {
                    v.join(", ")
                }
            };
            d.notes.push(format!(
                "the per-sample part (per_sample): the log's first {n} samples ({seconds:.1} s) at {} Hz, first against the spec as given with the output path and outliers as candidates (added: {}; per_sample_first), then against the spec after the averaged diagnosis with the per-sample kinds as candidates: gap {:.3} -> {:.3} (threshold {:.3}{}), added: {}",
                crate::fmt::num(real.rate_hz),
                list(first_added),
                e.gap_before,
                e.gap_after,
                e.gap_threshold,
                if e.significant { "" } else { ", not significant" },
                list(e.added.iter().map(|a| a.kind.clone()).collect())
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
        assert_eq!(factor(1_000_000, 1 << 20), 1);
        assert_eq!(factor(1_000_000, MAX_SAMPLES), 8);
        assert_eq!(factor(1_000_000, 1 << 16), 16);
        assert_eq!(factor(100, 0), 1);
        assert_eq!(factor(100_000_000, 1 << 20), 96);
        assert_eq!(factor(100_000_000, MAX_SAMPLES), 763);
        assert!(100_000_000usize.div_ceil(763) <= MAX_SAMPLES);
        assert!(100_000_000usize.div_ceil(762) > MAX_SAMPLES);
        assert_eq!(factor(11, 5), 3);
    }

    /// The block means of a rounded white noise have the variance and lag-1
    /// autocorrelation of the rounding's stand-in (the rate rounded to 1 sd; the angle
    /// rounded to 1 and 3 sd, its stand-in the same angle step at the averaged rate; the
    /// noise alone is 8 % below it on the rate): 4e6 samples at 100 Hz, averaged by 100
    /// (the estimates' relative sd about sqrt(2 / 4e4) = 0.7 %, the correlations' sd
    /// about 0.005).
    #[test]
    fn a_rounding_s_stand_in_gives_its_block_means_variance() {
        use crate::simulator::{SimRequest, simulate};
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let var = |v: &[f64]| {
            let m = mean(v);
            v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len() as f64
        };
        let lag1 = |v: &[f64]| {
            let m = mean(v);
            v.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum::<f64>() / v.len() as f64 / var(v)
        };
        for (on_angle, quantum) in [(false, 1.0), (true, 1.0), (true, 3.0)] {
            let spec = Spec {
                sample_rate_hz: 100.0,
                temperature_channel: None,
                seed: Some(3),
                channels: vec![crate::simulator::ChannelSpec {
                    name: "x".into(),
                    components: vec![
                        Component::ConstantBias { value: 0.3 },
                        Component::WhiteNoise { n: 0.1 },
                        Component::OutputResolution { quantum, on_angle },
                    ],
                }],
            };
            let (avg, _) = spec_at(&spec, 100.0, 100).unwrap();
            assert_eq!(avg.channels[0].components.len(), 3);
            let mut req = SimRequest::new(4_000_000, 100.0);
            req.seed = Some(5);
            let full = simulate(&spec, &req).unwrap();
            let means = block_means(full.channel("x").unwrap(), 100);
            let mut req = SimRequest::new(40_000, 1.0);
            req.seed = Some(6);
            let at = simulate(&avg, &req).unwrap();
            let at = at.channel("x").unwrap();
            let (want, got) = (var(&means), var(at));
            assert!(
                (got / want - 1.0).abs() < 0.03,
                "on_angle {on_angle} quantum {quantum}: block means {want}, stand-in {got}"
            );
            let (want1, got1) = (lag1(&means), lag1(at));
            assert!(
                (got1 - want1).abs() < 0.025,
                "on_angle {on_angle} quantum {quantum}: lag-1 {want1} against {got1}"
            );
            assert!(
                (mean(at) - mean(&means)).abs() < 0.01,
                "{} {}",
                mean(at),
                mean(&means)
            );
            if !on_angle {
                assert!(want > 1.05 * 0.01, "{want}");
            }
        }
    }

    /// The rounding's condition reads the noise after the filter: a rounding to 1.2 sd
    /// of the white noise stands in alone, but behind a 5 Hz low-pass at 100 Hz (which
    /// keeps about a sixth of the noise's variance) it is 3 sd of what it rounds.
    #[test]
    fn a_rounding_behind_a_filter_is_judged_on_the_filtered_noise() {
        let spec = |filter: bool| {
            let mut components = vec![
                Component::WhiteNoise { n: 0.1 },
                Component::OutputResolution {
                    quantum: 1.2,
                    on_angle: false,
                },
            ];
            if filter {
                components.push(Component::OutputFilter {
                    order: 1,
                    bandwidth_hz: 5.0,
                    damping: None,
                    discretization: Discretization::Zoh,
                });
            }
            Spec {
                sample_rate_hz: 100.0,
                temperature_channel: None,
                seed: Some(3),
                channels: vec![crate::simulator::ChannelSpec {
                    name: "x".into(),
                    components,
                }],
            }
        };
        let gain = noise_gain(&spec(true).channels[0].components, 100.0);
        // order 1, a = exp(-2 pi 5 / 100): (1 - a)^2 / (1 - a^2) = (1 - a) / (1 + a)
        let a = (-2.0 * PI * 5.0 / 100.0).exp();
        assert!((gain - (1.0 - a) / (1.0 + a)).abs() < 1e-6, "{gain}");
        let (_, alone) = spec_at(&spec(false), 100.0, 10).unwrap();
        assert!(alone.unmatched.is_empty());
        let (avg, behind) = spec_at(&spec(true), 100.0, 10).unwrap();
        assert_eq!(behind.unmatched.len(), 1);
        assert_eq!(behind.unmatched[0].1.kind(), Kind::OutputResolution);
        // the filter still stands in, as a FIR
        assert!(
            avg.channels[0]
                .components
                .iter()
                .any(|c| matches!(c, Component::OutputFir { .. }))
        );
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
        let kinds_of =
            |s: &Spec| -> Vec<Kind> { s.channels[0].components.iter().map(|c| c.kind()).collect() };
        let (mut avg, taken) = spec_at(&spec, 100.0, 100).unwrap();
        assert_eq!(avg.sample_rate_hz, 1.0);
        let kinds = kinds_of(&avg);
        // the rounding's stand-in: white noise of density q / sqrt(12 rate)
        assert_eq!(
            kinds,
            [Kind::WhiteNoise, Kind::RateRandomWalk, Kind::WhiteNoise]
        );
        assert_eq!(
            avg.channels[0].components[2],
            Component::WhiteNoise {
                n: 0.05 / 1200f64.sqrt()
            }
        );
        // an effect the averaged diagnosis adds follows the stand-ins and stays; an
        // outliers' size goes back to the log's rate
        avg.channels[0]
            .components
            .push(Component::ConstantBias { value: 1.0 });
        avg.channels[0].components.push(Component::Outliers {
            rate_hz: 0.1,
            scale: 0.5,
            dof: None,
        });
        let back = restore(&avg, 100.0, &taken);
        assert_eq!(back.sample_rate_hz, 100.0);
        assert_eq!(
            kinds_of(&back),
            [
                Kind::WhiteNoise,
                Kind::RateRandomWalk,
                Kind::ConstantBias,
                Kind::Outliers,
                Kind::OutputResolution
            ]
        );
        assert_eq!(
            back.channels[0].components[3],
            Component::Outliers {
                rate_hz: 0.1,
                scale: 50.0,
                dof: None
            }
        );
        let mut arma = spec.clone();
        arma.channels[0].components.push(Component::Arma {
            ar: vec![0.5],
            ma: vec![],
            sigma: 0.1,
        });
        let e = spec_at(&arma, 100.0, 100).unwrap_err().to_string();
        assert!(e.contains("arma") && e.contains("--max-samples"), "{e}");
        let kinds = candidate_kinds();
        assert!(kinds.contains(&"rate_random_walk".to_string()));
        assert!(kinds.contains(&"recalibrate:white_noise".to_string()));
        assert!(kinds.contains(&"outliers".to_string()));
        assert!(!kinds.contains(&"recalibrate:outliers".to_string()));
        assert!(
            !kinds
                .iter()
                .any(|k| k.contains("output_") || k.contains("farma"))
        );
    }
}
