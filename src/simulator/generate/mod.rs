//! The generator: turns a [`Spec`] into simulated channels.
//!
//! [`simulate`] runs a whole spec; [`Simulator`] holds a prepared spec (fitted models
//! loaded, the request checked) so that a caller can simulate many replicas, or one
//! component at a time ([`Simulator::component_signal`]) and add it to a cached sum:
//! a channel is the sum of its components' signals (up to rounding), where
//! - heteroskedastic's signal is (scale_k - 1) times the signal of the channel's
//!   component(s) of kind `of` (so adding it turns their scale from 1 into scale_k),
//! - cross_axis's signal is `gain` times the `from` channel's own signal (its
//!   components other than cross_axis).
//!
//! Determinism: every draw comes from a stream keyed by (seed, replica, channel index,
//! component index, sub-process, chunk) ([`streams`]); a component's values depend only
//! on those and on its parameters, not on the thread count, on the other components,
//! or on which channels are requested. Which parts run in parallel: all draws, every
//! deterministic and temperature-driven component, and the first-order recursions
//! (gauss_markov, rate_random_walk, bias_instability: chunks + carry fix-up); ARMA and
//! FARMA recursions run sequentially after parallel draws ([`recursion`]).
//!
//! One file per component family: [`deterministic`], [`noise`], [`markov`],
//! [`recursion`], [`thermal`].

pub mod deterministic;
pub mod markov;
pub mod noise;
pub mod recursion;
pub mod streams;
pub mod thermal;

use std::collections::HashMap;
use std::path::PathBuf;

use super::spec::{Component, FarmaModel, Kind, Spec};
use crate::error::{Error, Result};
use crate::model::Farma;
use crate::model::folder::ModelDir;
use recursion::{Coefs, FARMA_BURN_IN, Recursion, add_recursion, arma_burn_in};
use streams::{MAX_SAMPLES, StreamKey};

/// Seed used when neither the request nor the spec gives one.
pub const DEFAULT_SEED: u64 = 0;

/// What to simulate: length, rate, temperature, seed, replica and channels.
#[derive(Debug, Clone)]
pub struct SimRequest<'a> {
    /// Samples per channel (>= 1).
    pub n_samples: usize,
    /// Sample rate, Hz (> 0); normally the spec's `sample_rate_hz`.
    pub sample_rate_hz: f64,
    /// Temperature, degC, one value per sample; needed by temperature_bias,
    /// thermal_rate and heteroskedastic.
    pub temperature_c: Option<&'a [f64]>,
    /// Overrides the spec's seed.
    pub seed: Option<u64>,
    /// Replica r of the seed: replicas are independent realisations.
    pub replica: u64,
    /// Channels to return (by name); `None`: every channel of the spec.
    pub channels: Option<Vec<String>>,
    /// Folder that relative farma `model` paths are resolved against (the spec's
    /// folder); `None`: the current directory.
    pub base_dir: Option<PathBuf>,
}

impl<'a> SimRequest<'a> {
    /// `n_samples` at `sample_rate_hz`, the spec's seed, replica 0, every channel.
    pub fn new(n_samples: usize, sample_rate_hz: f64) -> Self {
        SimRequest {
            n_samples,
            sample_rate_hz,
            temperature_c: None,
            seed: None,
            replica: 0,
            channels: None,
            base_dir: None,
        }
    }
}

/// Simulated channels.
#[derive(Debug, Clone, PartialEq)]
pub struct Simulated {
    pub sample_rate_hz: f64,
    /// The seed used (the request's, else the spec's, else [`DEFAULT_SEED`]).
    pub seed: u64,
    pub replica: u64,
    /// (name, values), in spec order.
    pub channels: Vec<(String, Vec<f64>)>,
}

impl Simulated {
    /// The values of channel `name`.
    pub fn channel(&self, name: &str) -> Option<&[f64]> {
        self.channels
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
}

/// Simulates `spec` as `req` asks.
pub fn simulate(spec: &Spec, req: &SimRequest) -> Result<Simulated> {
    Simulator::new(spec, req.clone())?.run()
}

/// A spec prepared for a request: checked, fitted models loaded.
pub struct Simulator<'a> {
    spec: &'a Spec,
    req: SimRequest<'a>,
    seed: u64,
    /// Fitted farma models by (channel index, component index).
    saved: HashMap<(usize, usize), Farma>,
    /// Mean temperature of the request, if it has one.
    temp_mean_c: Option<f64>,
}

impl<'a> Simulator<'a> {
    /// Checks `req` against `spec` and loads fitted models. Errors (exit code 2): a
    /// rate or length out of range, an unknown channel, a temperature series missing
    /// or of the wrong length, a sinusoid at or above the Nyquist frequency or an
    /// outlier rate above the sample rate of the request, a fitted model that cannot be
    /// read.
    pub fn new(spec: &'a Spec, req: SimRequest<'a>) -> Result<Self> {
        let fs = req.sample_rate_hz;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(Error::Usage(format!(
                "sample rate must be > 0 Hz, found {fs}"
            )));
        }
        if req.n_samples == 0 {
            return Err(Error::Usage("nothing to simulate: 0 samples".into()));
        }
        if req.n_samples > MAX_SAMPLES {
            return Err(Error::Usage(format!(
                "{} samples exceed the simulator's limit of {MAX_SAMPLES} per channel",
                req.n_samples
            )));
        }
        if spec.channels.len() >= 1 << 16 {
            return Err(Error::Usage("more than 65535 channels in the spec".into()));
        }
        if let Some(names) = &req.channels {
            for n in names {
                if !spec.channels.iter().any(|c| &c.name == n) {
                    let all: Vec<&str> = spec.channels.iter().map(|c| c.name.as_str()).collect();
                    return Err(Error::Usage(format!(
                        "no channel '{n}' in the spec; channels are: {}",
                        all.join(", ")
                    )));
                }
            }
        }
        // Channels simulated: the requested ones and the sources of their cross_axis.
        let mut used: Vec<bool> = spec
            .channels
            .iter()
            .map(|c| req.channels.as_ref().is_none_or(|w| w.contains(&c.name)))
            .collect();
        for (ci, c) in spec.channels.iter().enumerate() {
            if used[ci] {
                for comp in &c.components {
                    if let Component::CrossAxis { from, .. } = comp
                        && let Some(j) = spec.channels.iter().position(|x| &x.name == from)
                    {
                        used[j] = true;
                    }
                }
            }
        }
        let needs_temp: Vec<String> = spec
            .channels
            .iter()
            .zip(&used)
            .filter(|(_, u)| **u)
            .map(|(c, _)| c)
            .flat_map(|c| {
                c.components
                    .iter()
                    .enumerate()
                    .filter(|(_, k)| k.kind().needs_temperature())
                    .map(move |(i, k)| {
                        format!("channel '{}' component {} ({})", c.name, i + 1, k.kind())
                    })
            })
            .collect();
        match (req.temperature_c, needs_temp.first()) {
            (None, Some(first)) => {
                return Err(Error::Usage(format!(
                    "{first} needs a temperature series, and none was given (hint: --like REAL_LOG takes it from the spec's temperature_channel '{}' of a real log)",
                    spec.temperature_channel.as_deref().unwrap_or("?")
                )));
            }
            (Some(t), _) if t.len() != req.n_samples => {
                return Err(Error::Usage(format!(
                    "the temperature series has {} values but {} samples are simulated",
                    t.len(),
                    req.n_samples
                )));
            }
            (Some(t), _) => {
                if let Some(i) = t.iter().position(|v| !v.is_finite()) {
                    return Err(Error::Usage(format!(
                        "the temperature series has a non-finite value at sample {i}"
                    )));
                }
            }
            _ => {}
        }
        let temp_mean_c = req.temperature_c.map(thermal::mean_c);
        let mut saved = HashMap::new();
        for (ci, ch) in spec.channels.iter().enumerate() {
            if ch.components.len() >= 1 << 16 {
                return Err(Error::Usage(format!(
                    "channel '{}': more than 65535 components",
                    ch.name
                )));
            }
            for (k, comp) in ch.components.iter().enumerate() {
                let place = format!(
                    "channel '{}' component {} ({})",
                    ch.name,
                    k + 1,
                    comp.kind()
                );
                match comp {
                    Component::Sinusoid { freq_hz, .. } if *freq_hz >= fs / 2.0 => {
                        return Err(Error::Usage(format!(
                            "{place}: freq_hz = {freq_hz} is not below the Nyquist frequency {} Hz of the {fs} Hz simulation",
                            fs / 2.0
                        )));
                    }
                    Component::Outliers { rate_hz, .. } if *rate_hz > fs => {
                        return Err(Error::Usage(format!(
                            "{place}: rate_hz = {rate_hz} exceeds the sample rate {fs} Hz"
                        )));
                    }
                    Component::BiasInstability { .. } => {
                        let (lo, hi) = bi_bounds(comp, req.n_samples, fs);
                        if !(lo > 0.0 && hi > lo) {
                            return Err(Error::Usage(format!(
                                "{place}: the flicker bounds tau_min_s = {lo} s, tau_max_s = {hi} s are not 0 < min < max (the defaults are 1 / sample rate and the duration)"
                            )));
                        }
                        let k = markov::bias_instability_bank(1.0, lo, hi).processes.len();
                        if k >= markov::WHITE_SUB {
                            return Err(Error::Usage(format!(
                                "{place}: the flicker bank would need {k} Gauss-Markov processes (2 per decade of correlation time from tau_min_s / 100 to 100 tau_max_s), more than the {} the simulator has streams for: tau_max_s / tau_min_s spans more than 123 decades",
                                markov::WHITE_SUB - 1
                            )));
                        }
                    }
                    Component::Farma(FarmaModel::Fitted { model, channel }) => {
                        let dir = match &req.base_dir {
                            Some(b) if model.is_relative() => b.join(model),
                            _ => model.clone(),
                        };
                        let name = channel.as_deref().unwrap_or(&ch.name);
                        // Default: the spec channel's name, or the only channel fitted.
                        let folder = ModelDir::new(&dir);
                        let m = match folder.load(Some(name)) {
                            Ok((_, m)) => Ok(m),
                            Err(e) if channel.is_none() => {
                                folder.load(None).map(|(_, m)| m).map_err(|_| e)
                            }
                            Err(e) => Err(e),
                        }
                        .map_err(|e| {
                            Error::Usage(format!(
                                "{place}: cannot load the fitted model '{}' (an output folder of `farma fit`): {e}",
                                dir.display()
                            ))
                        })?;
                        saved.insert((ci, k), m);
                    }
                    _ => {}
                }
            }
        }
        let seed = req.seed.or(spec.seed).unwrap_or(DEFAULT_SEED);
        Ok(Simulator {
            spec,
            req,
            seed,
            saved,
            temp_mean_c,
        })
    }

    /// The seed in use.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Switches to replica `r` (nothing else changes).
    pub fn set_replica(&mut self, r: u64) {
        self.req.replica = r;
    }

    /// The index of channel `name` in the spec.
    pub fn channel_index(&self, name: &str) -> Result<usize> {
        self.spec
            .channels
            .iter()
            .position(|c| c.name == name)
            .ok_or_else(|| Error::Usage(format!("no channel '{name}' in the spec")))
    }

    fn key(&self, channel: usize, component: usize) -> StreamKey {
        StreamKey {
            seed: self.seed,
            replica: self.req.replica,
            channel,
            component,
        }
    }

    /// The signal of component `component` of channel `channel` (indices in the spec)
    /// alone, `n_samples` long.
    pub fn component_signal(&self, channel: usize, component: usize) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.req.n_samples];
        self.add_component(channel, component, &mut out)?;
        Ok(out)
    }

    /// Adds the signal of one component to `out` (`n_samples` long).
    pub fn add_component(&self, channel: usize, component: usize, out: &mut [f64]) -> Result<()> {
        let ch = self
            .spec
            .channels
            .get(channel)
            .ok_or_else(|| Error::Usage(format!("no channel {channel} in the spec")))?;
        let comp = ch.components.get(component).ok_or_else(|| {
            Error::Usage(format!(
                "channel '{}' has no component {}",
                ch.name,
                component + 1
            ))
        })?;
        if out.len() != self.req.n_samples {
            return Err(Error::Internal(format!(
                "component buffer of {} samples for a {}-sample simulation",
                out.len(),
                self.req.n_samples
            )));
        }
        match comp {
            Component::Heteroskedastic { of, slope } => {
                let mut base = vec![0.0; out.len()];
                for (k, c) in ch.components.iter().enumerate() {
                    if c.kind() == *of {
                        self.add_plain(channel, k, &mut base)?;
                    }
                }
                let (t, tref) = self.temperature()?;
                let s = thermal::scale(*slope, tref, t);
                for ((o, b), s) in out.iter_mut().zip(&base).zip(&s) {
                    *o += (s - 1.0) * b;
                }
                Ok(())
            }
            Component::CrossAxis { from, gain } => {
                let src = self.channel_index(from)?;
                let own = self.own_signal(src)?;
                for (o, v) in out.iter_mut().zip(&own) {
                    *o += gain * v;
                }
                Ok(())
            }
            _ => self.add_plain(channel, component, out),
        }
    }

    fn temperature(&self) -> Result<(&[f64], f64)> {
        match (self.req.temperature_c, self.temp_mean_c) {
            (Some(t), Some(m)) => Ok((t, m)),
            _ => Err(Error::Usage(
                "a temperature-driven component needs a temperature series".into(),
            )),
        }
    }

    /// A component that is neither heteroskedastic nor cross_axis.
    fn add_plain(&self, channel: usize, component: usize, out: &mut [f64]) -> Result<()> {
        let ch = &self.spec.channels[channel];
        let comp = &ch.components[component];
        let fs = self.req.sample_rate_hz;
        let key = self.key(channel, component);
        let what = format!(
            "channel '{}' component {} ({})",
            ch.name,
            component + 1,
            comp.kind()
        );
        match comp {
            Component::ConstantBias { value } => deterministic::constant_bias(out, *value),
            Component::WhiteNoise { n } => noise::white_noise(out, *n, fs, &key),
            Component::Quantization { q } => noise::quantization(out, *q, fs, &key),
            Component::BiasInstability { b, .. } => {
                let (lo, hi) = bi_bounds(comp, self.req.n_samples, fs);
                markov::bias_instability(out, *b, lo, hi, fs, &key)
            }
            Component::RateRandomWalk { k } => markov::rate_random_walk(out, *k, fs, &key),
            Component::RateRamp { r } => deterministic::rate_ramp(out, *r, fs),
            Component::GaussMarkov { sigma, tau_s } => {
                markov::gauss_markov(out, *sigma, *tau_s, fs, &key)
            }
            Component::Sinusoid {
                amplitude,
                freq_hz,
                phase_rad,
            } => deterministic::sinusoid(out, *amplitude, *freq_hz, *phase_rad, fs),
            Component::Arma { ar, ma, sigma } => {
                let r = Recursion {
                    p: ar.len(),
                    d: 1,
                    coefs: Coefs::Constant(ar),
                    ma,
                    sigma: *sigma,
                };
                add_recursion(out, &r, arma_burn_in(ar, ma.len()), 0.0, &key, &what)?
            }
            Component::Farma(FarmaModel::Inline {
                p, d, f, ma, sigma, ..
            }) => {
                let r = Recursion {
                    p: *p,
                    d: *d,
                    coefs: Coefs::Poly(f),
                    ma,
                    sigma: *sigma,
                };
                add_recursion(out, &r, FARMA_BURN_IN, 0.0, &key, &what)?
            }
            Component::Farma(FarmaModel::Fitted { .. }) => {
                let m = self
                    .saved
                    .get(&(channel, component))
                    .ok_or_else(|| Error::Internal(format!("{what}: model not loaded")))?;
                let r = Recursion {
                    p: m.p(),
                    d: m.d(),
                    coefs: Coefs::Fitted(m),
                    ma: &m.b,
                    sigma: m.sigma2.sqrt(),
                };
                add_recursion(out, &r, FARMA_BURN_IN, m.mean, &key, &what)?
            }
            Component::TemperatureBias {
                coeffs,
                reference_c,
            } => {
                let (t, mean) = self.temperature()?;
                thermal::temperature_bias(out, coeffs, reference_c.unwrap_or(mean), t)
            }
            Component::ThermalRate { coeff, smoothing_s } => {
                let (t, _) = self.temperature()?;
                thermal::thermal_rate(out, *coeff, *smoothing_s, fs, t)
            }
            Component::Warmup { amplitude, tau_s } => {
                deterministic::warmup(out, *amplitude, *tau_s, fs)
            }
            Component::Outliers { rate_hz, scale } => {
                noise::outliers(out, *rate_hz, *scale, fs, &key)
            }
            Component::Heteroskedastic { .. } | Component::CrossAxis { .. } => {
                return Err(Error::Internal(format!("{what}: not a plain component")));
            }
        }
        Ok(())
    }

    /// A channel's own signal: the sum of its components other than cross_axis
    /// (heteroskedastic terms added last, after the signals they modulate).
    pub fn own_signal(&self, channel: usize) -> Result<Vec<f64>> {
        let ch = &self.spec.channels[channel];
        let mut out = vec![0.0; self.req.n_samples];
        let modulated: Vec<Kind> = ch
            .components
            .iter()
            .filter_map(|c| match c {
                Component::Heteroskedastic { of, .. } => Some(*of),
                _ => None,
            })
            .collect();
        // Signals of modulated kinds are kept once and reused by heteroskedastic.
        let mut bases: HashMap<Kind, Vec<f64>> = HashMap::new();
        for (k, comp) in ch.components.iter().enumerate() {
            match comp {
                Component::CrossAxis { .. } | Component::Heteroskedastic { .. } => {}
                c if modulated.contains(&c.kind()) => {
                    let base = bases
                        .entry(c.kind())
                        .or_insert_with(|| vec![0.0; out.len()]);
                    self.add_plain(channel, k, base)?;
                }
                _ => self.add_plain(channel, k, &mut out)?,
            }
        }
        for comp in &ch.components {
            if let Component::Heteroskedastic { of, slope } = comp {
                let (t, tref) = self.temperature()?;
                let s = thermal::scale(*slope, tref, t);
                let base = &bases[of];
                for ((o, b), s) in out.iter_mut().zip(base).zip(&s) {
                    *o += s * b;
                }
            }
        }
        Ok(out)
    }

    /// Simulates the requested channels (own signal plus cross-axis couplings).
    pub fn run(&self) -> Result<Simulated> {
        let wanted: Vec<usize> = match &self.req.channels {
            None => (0..self.spec.channels.len()).collect(),
            Some(names) => {
                let mut idx: Vec<usize> = names
                    .iter()
                    .map(|n| self.channel_index(n))
                    .collect::<Result<_>>()?;
                idx.sort_unstable();
                idx.dedup();
                idx
            }
        };
        // Own signals of every channel needed (wanted ones and cross-axis sources).
        let mut needed: Vec<usize> = wanted.clone();
        for &ci in &wanted {
            for c in &self.spec.channels[ci].components {
                if let Component::CrossAxis { from, .. } = c {
                    needed.push(self.channel_index(from)?);
                }
            }
        }
        needed.sort_unstable();
        needed.dedup();
        let mut own: HashMap<usize, Vec<f64>> = HashMap::new();
        for &ci in &needed {
            own.insert(ci, self.own_signal(ci)?);
        }
        let mut channels = Vec::with_capacity(wanted.len());
        for &ci in &wanted {
            let ch = &self.spec.channels[ci];
            let mut v = own[&ci].clone();
            for c in &ch.components {
                if let Component::CrossAxis { from, gain } = c {
                    let src = &own[&self.channel_index(from)?];
                    for (o, s) in v.iter_mut().zip(src) {
                        *o += gain * s;
                    }
                }
            }
            channels.push((ch.name.clone(), v));
        }
        Ok(Simulated {
            sample_rate_hz: self.req.sample_rate_hz,
            seed: self.seed,
            replica: self.req.replica,
            channels,
        })
    }
}

/// The flicker bounds of a bias_instability component: its tau_min_s / tau_max_s, or
/// the defaults 1 / rate_hz (one sample interval) and the simulated duration.
pub fn bi_bounds(comp: &Component, n_samples: usize, rate_hz: f64) -> (f64, f64) {
    match comp {
        Component::BiasInstability {
            tau_min_s,
            tau_max_s,
            ..
        } => (
            tau_min_s.unwrap_or(1.0 / rate_hz),
            tau_max_s.unwrap_or(n_samples as f64 / rate_hz),
        ),
        _ => (f64::NAN, f64::NAN),
    }
}

/// The signal of component `component` (index in the channel) of channel `channel`
/// (by name) alone: a one-off convenience over [`Simulator::component_signal`] (which
/// a caller that simulates many components should keep, to load fitted models once).
pub fn component_signal(
    spec: &Spec,
    channel: &str,
    component: usize,
    req: &SimRequest,
) -> Result<Vec<f64>> {
    let sim = Simulator::new(spec, req.clone())?;
    let ci = sim.channel_index(channel)?;
    sim.component_signal(ci, component)
}
