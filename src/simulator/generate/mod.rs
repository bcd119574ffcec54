//! The generator: turns a [`Spec`] into simulated channels.
//!
//! [`simulate`] runs a whole spec; [`Simulator`] holds a prepared spec (fitted models
//! loaded, the request checked) so that a caller can simulate many replicas, or one
//! component at a time ([`Simulator::component_signal`]) and add it to a cached sum:
//! a channel is the sum of its components' signals (up to rounding), where
//! - heteroskedastic's signal is (scale_k - 1) times the signal of the channel's
//!   component(s) of kind `of` (so adding it turns their scale from 1 into scale_k),
//! - cross_axis's signal is `gain` times the `from` channel's own signal (its
//!   components other than cross_axis and the output path),
//! - an output-path stage's signal (output_filter, saturation, output_resolution) is
//!   what it changes: the sum of the other components (cross_axis included) passed
//!   through the stages up to and including it, minus that sum passed through the
//!   stages before it ([`output`]; the stages run in the order filter -> saturation ->
//!   resolution). The channel is the sum of the other components passed through the
//!   whole output path.
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
pub mod output;
pub mod recursion;
pub mod streams;
pub mod thermal;

use std::collections::HashMap;
use std::path::PathBuf;

use super::spec::{Component, FarmaModel, Kind, Spec};
use crate::error::{Error, Result};
use crate::model::Farma;
use crate::model::folder::ModelDir;
use recursion::{Coefs, FARMA_BURN_IN, RecState, Recursion, add_recursion_from, arma_burn_in};
use streams::{CHUNK, MAX_SAMPLES, StreamKey};

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
                "sample rate must be > 0 Hz, found {}",
                crate::fmt::num(fs)
            )));
        }
        spec.check_simulable(fs).map_err(Error::Usage)?;
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
                    Component::Farma(FarmaModel::Inline { p, d, q, .. }) => {
                        // the recursion keeps max(p, d) past values and q innovations
                        crate::workflow::budget::check_memory(
                            &format!("{place}: 'd' = {d}"),
                            "the recursion's state of max(p, d) + q past values",
                            8.0 * ((*p).max(*d) as f64 + *q as f64),
                        )?;
                    }
                    Component::Sinusoid { freq_hz, .. } if *freq_hz >= fs / 2.0 => {
                        return Err(Error::Usage(format!(
                            "{place}: freq_hz = {} is not below the Nyquist frequency {} Hz of the {} Hz simulation",
                            crate::fmt::num(*freq_hz),
                            crate::fmt::num(fs / 2.0),
                            crate::fmt::num(fs)
                        )));
                    }
                    Component::Outliers { rate_hz, .. } if *rate_hz > fs => {
                        return Err(Error::Usage(format!(
                            "{place}: rate_hz = {} exceeds the sample rate {} Hz",
                            crate::fmt::num(*rate_hz),
                            crate::fmt::num(fs)
                        )));
                    }
                    Component::BiasInstability { .. } => {
                        let (lo, hi) = bi_bounds(comp, req.n_samples, fs);
                        if !(lo > 0.0 && hi > lo) {
                            return Err(Error::Usage(format!(
                                "{place}: the flicker bounds tau_min_s = {} s, tau_max_s = {} s are not 0 < min < max (the defaults are 1 / sample rate and the duration)",
                                crate::fmt::num(lo),
                                crate::fmt::num(hi)
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
            Component::Heteroskedastic {
                of,
                slope,
                floor,
                reference_c,
            } => {
                let mut base = vec![0.0; out.len()];
                for (k, c) in ch.components.iter().enumerate() {
                    if c.kind() == *of {
                        self.add_plain(channel, k, &mut base)?;
                    }
                }
                let (t, mean_c) = self.temperature()?;
                let tref = reference_c.unwrap_or(mean_c);
                let s = thermal::scale(*slope, *floor, tref, t);
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
            c if c.kind().is_output_path() => {
                let fs = self.req.sample_rate_hz;
                let mut before = self.own_signal(channel)?;
                for c in &ch.components {
                    if let Component::CrossAxis { from, gain } = c {
                        let own = self.own_signal(self.channel_index(from)?)?;
                        for (o, v) in before.iter_mut().zip(&own) {
                            *o += gain * v;
                        }
                    }
                }
                let mut after = before.clone();
                output::OutputPath::of(&ch.components, fs, Some((c.kind(), false)))
                    .apply(&mut before);
                output::OutputPath::of(&ch.components, fs, Some((c.kind(), true)))
                    .apply(&mut after);
                for ((o, a), b) in out.iter_mut().zip(&after).zip(&before) {
                    *o += a - b;
                }
                self.finite(out, 0, &self.what(channel, component))
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
        let mut st = self.new_state(channel, component);
        self.add_plain_block(channel, component, out, 0, &mut st)
    }

    /// "channel 'NAME' component K (KIND)".
    fn what(&self, channel: usize, component: usize) -> String {
        let ch = &self.spec.channels[channel];
        format!(
            "channel '{}' component {} ({})",
            ch.name,
            component + 1,
            ch.components[component].kind()
        )
    }

    /// The state of a plain component before its first block.
    fn new_state(&self, channel: usize, component: usize) -> CompState {
        let comp = &self.spec.channels[channel].components[component];
        let fs = self.req.sample_rate_hz;
        let key = self.key(channel, component);
        match comp {
            Component::Quantization { q } => {
                CompState::Quantization(noise::quantization_init(*q, &key))
            }
            Component::BiasInstability { b, .. } => {
                let (lo, hi) = bi_bounds(comp, self.req.n_samples, fs);
                CompState::Ar1(markov::bias_instability_comp(*b, lo, hi, fs, &key))
            }
            Component::RateRandomWalk { k } => {
                CompState::Ar1(markov::rate_random_walk_comp(*k, fs))
            }
            Component::GaussMarkov { sigma, tau_s } => {
                CompState::Ar1(markov::gauss_markov_comp(*sigma, *tau_s, fs, &key))
            }
            Component::Arma { .. } | Component::Farma(_) => {
                CompState::Recursion(RecState::default())
            }
            Component::ThermalRate {
                smoothing_s, lag_s, ..
            } => match self.req.temperature_c {
                Some(t) => CompState::Thermal(thermal::smooth(
                    &thermal::lagged(t, *lag_s, fs),
                    thermal::smoothing_half_width(*smoothing_s, fs),
                )),
                None => CompState::Stateless,
            },
            _ => CompState::Stateless,
        }
    }

    /// Adds the block of `out.len()` samples from sample `start` (a multiple of
    /// [`CHUNK`]) of a plain component to `out`, its state carried in `st`; the
    /// sum is then checked: a non-finite value is an error naming the component.
    fn add_plain_block(
        &self,
        channel: usize,
        component: usize,
        out: &mut [f64],
        start: usize,
        st: &mut CompState,
    ) -> Result<()> {
        let ch = &self.spec.channels[channel];
        let comp = &ch.components[component];
        let fs = self.req.sample_rate_hz;
        let key = self.key(channel, component);
        let what = self.what(channel, component);
        debug_assert_eq!(start % CHUNK, 0);
        let c0 = (start / CHUNK) as u64;
        let len = out.len();
        match (comp, st) {
            (Component::ConstantBias { value }, _) => deterministic::constant_bias(out, *value),
            (Component::WhiteNoise { n }, _) => noise::white_noise_from(out, *n, fs, &key, c0),
            (Component::Quantization { q }, CompState::Quantization(prev)) => {
                noise::quantization_from(out, *q, fs, &key, c0, prev)
            }
            (
                Component::BiasInstability { .. }
                | Component::RateRandomWalk { .. }
                | Component::GaussMarkov { .. },
                CompState::Ar1(a),
            ) => a.add_block(out, &key, c0),
            (Component::RateRamp { r }, _) => deterministic::rate_ramp(out, *r, fs, start),
            (
                Component::Sinusoid {
                    amplitude,
                    freq_hz,
                    phase_rad,
                },
                _,
            ) => deterministic::sinusoid(out, *amplitude, *freq_hz, *phase_rad, fs, start),
            (Component::Arma { ar, ma, sigma }, CompState::Recursion(rs)) => {
                let r = Recursion {
                    p: ar.len(),
                    d: 1,
                    coefs: Coefs::Constant(ar),
                    ma,
                    sigma: *sigma,
                };
                let burn = arma_burn_in(ar, ma.len());
                add_recursion_from(out, &r, burn, 0.0, &key, &what, c0, rs)?
            }
            (
                Component::Farma(FarmaModel::Inline {
                    p, d, f, ma, sigma, ..
                }),
                CompState::Recursion(rs),
            ) => {
                let r = Recursion {
                    p: *p,
                    d: *d,
                    coefs: Coefs::Poly(f),
                    ma,
                    sigma: *sigma,
                };
                add_recursion_from(out, &r, FARMA_BURN_IN, 0.0, &key, &what, c0, rs)?
            }
            (Component::Farma(FarmaModel::Fitted { .. }), CompState::Recursion(rs)) => {
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
                add_recursion_from(out, &r, FARMA_BURN_IN, m.mean, &key, &what, c0, rs)?
            }
            (
                Component::TemperatureBias {
                    coeffs,
                    reference_c,
                },
                _,
            ) => {
                let (t, mean) = self.temperature()?;
                let t = &t[start..start + len];
                thermal::temperature_bias(out, coeffs, reference_c.unwrap_or(mean), t)
            }
            (Component::ThermalRate { coeff, .. }, CompState::Thermal(smoothed)) => {
                thermal::thermal_rate_from(out, *coeff, fs, smoothed, start)
            }
            (Component::ThermalRate { .. }, _) => {
                self.temperature()?;
            }
            (Component::Warmup { amplitude, tau_s }, _) => {
                deterministic::warmup(out, *amplitude, *tau_s, fs, start)
            }
            (
                Component::Outliers {
                    rate_hz,
                    scale,
                    dof,
                },
                _,
            ) => noise::outliers_from(out, *rate_hz, *scale, *dof, fs, &key, c0),
            (
                Component::Heteroskedastic { .. }
                | Component::CrossAxis { .. }
                | Component::OutputFilter { .. }
                | Component::OutputFir { .. }
                | Component::Saturation { .. }
                | Component::OutputResolution { .. },
                _,
            ) => {
                return Err(Error::Internal(format!("{what}: not a plain component")));
            }
            _ => return Err(Error::Internal(format!("{what}: state of another kind"))),
        }
        self.finite(out, start, &what)
    }

    /// An error naming `what` (the component, or the sum it was added to) when `out`
    /// (samples from `start`) holds a non-finite value: no NaN or Inf is written.
    fn finite(&self, out: &[f64], start: usize, what: &str) -> Result<()> {
        match out.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(j) => Err(Error::Usage(format!(
                "{what} gives a non-finite value ({}) at sample {} (t = {} s): its parameters are beyond the range of f64 for this sample rate and duration",
                out[j],
                start + j,
                crate::fmt::num((start + j) as f64 / self.req.sample_rate_hz)
            ))),
        }
    }

    /// A channel's own signal: the sum of its components other than cross_axis and the
    /// output path (heteroskedastic terms added last, after the signals they modulate).
    pub fn own_signal(&self, channel: usize) -> Result<Vec<f64>> {
        let mut states = HashMap::new();
        self.own_signal_block(channel, 0, self.req.n_samples, &mut states)
    }

    /// The block of `len` samples from sample `start` of [`Simulator::own_signal`],
    /// the components' states carried in `states` (by component index).
    fn own_signal_block(
        &self,
        channel: usize,
        start: usize,
        len: usize,
        states: &mut HashMap<(usize, usize), CompState>,
    ) -> Result<Vec<f64>> {
        let ch = &self.spec.channels[channel];
        let mut out = vec![0.0; len];
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
                c if c.kind().is_output_path() => {}
                c => {
                    let st = states
                        .entry((channel, k))
                        .or_insert_with(|| self.new_state(channel, k));
                    if modulated.contains(&c.kind()) {
                        let base = bases.entry(c.kind()).or_insert_with(|| vec![0.0; len]);
                        self.add_plain_block(channel, k, base, start, st)?;
                    } else {
                        self.add_plain_block(channel, k, &mut out, start, st)?;
                    }
                }
            }
        }
        for (k, comp) in ch.components.iter().enumerate() {
            if let Component::Heteroskedastic {
                of,
                slope,
                floor,
                reference_c,
            } = comp
            {
                let (t, mean_c) = self.temperature()?;
                let tref = reference_c.unwrap_or(mean_c);
                let s = thermal::scale(*slope, *floor, tref, &t[start..start + len]);
                let base = &bases[of];
                for ((o, b), s) in out.iter_mut().zip(base).zip(&s) {
                    *o += s * b;
                }
                self.finite(&out, start, &self.what(channel, k))?;
            }
        }
        Ok(out)
    }

    /// The channels simulated (spec indices, in spec order).
    fn wanted(&self) -> Result<Vec<usize>> {
        Ok(match &self.req.channels {
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
        })
    }

    /// The names of the channels simulated, in the order of [`Simulated::channels`]
    /// and of [`Blocks::next_block`]'s columns.
    pub fn channel_names(&self) -> Result<Vec<String>> {
        Ok(self
            .wanted()?
            .into_iter()
            .map(|ci| self.spec.channels[ci].name.clone())
            .collect())
    }

    /// The simulation by blocks of `block` samples (rounded up to a whole number of
    /// [`CHUNK`]s): each block is what [`Simulator::run`] gives for those samples, bit
    /// for bit, and the memory held is that of a block (and of thermal_rate's smoothed
    /// temperature), not of the whole series.
    pub fn blocks(&self, block: usize) -> Result<Blocks<'_, 'a>> {
        let wanted = self.wanted()?;
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
        Ok(Blocks {
            sim: self,
            block: block.max(1).div_ceil(CHUNK) * CHUNK,
            next: 0,
            wanted,
            needed,
            states: HashMap::new(),
            paths: HashMap::new(),
        })
    }

    /// Simulates the requested channels (own signal plus cross-axis couplings).
    pub fn run(&self) -> Result<Simulated> {
        let mut blocks = self.blocks(self.req.n_samples)?;
        let mut channels: Vec<(String, Vec<f64>)> = self
            .channel_names()?
            .into_iter()
            .map(|n| (n, Vec::new()))
            .collect();
        while let Some((_, cols)) = blocks.next_block()? {
            for ((_, v), c) in channels.iter_mut().zip(cols) {
                if v.is_empty() {
                    *v = c;
                } else {
                    v.extend_from_slice(&c);
                }
            }
        }
        Ok(Simulated {
            sample_rate_hz: self.req.sample_rate_hz,
            seed: self.seed,
            replica: self.req.replica,
            channels,
        })
    }
}

/// The state a plain component carries from one block to the next.
pub enum CompState {
    Stateless,
    /// quantization: the angle error before the block.
    Quantization(f64),
    /// gauss_markov, rate_random_walk, bias_instability.
    Ar1(markov::Ar1Comp),
    /// arma, farma.
    Recursion(RecState),
    /// thermal_rate: the whole smoothed temperature.
    Thermal(Vec<f64>),
}

/// A simulation generated block by block ([`Simulator::blocks`]).
pub struct Blocks<'s, 'a> {
    sim: &'s Simulator<'a>,
    block: usize,
    next: usize,
    wanted: Vec<usize>,
    needed: Vec<usize>,
    states: HashMap<(usize, usize), CompState>,
    /// The output path of each channel that has one, with its stages' states.
    paths: HashMap<usize, output::OutputPath>,
}

impl Blocks<'_, '_> {
    /// Samples per block (a multiple of [`CHUNK`]).
    pub fn block_len(&self) -> usize {
        self.block
    }

    /// The next block: its first sample and the values of every simulated channel
    /// ([`Simulator::channel_names`]' order); `None` after the last.
    pub fn next_block(&mut self) -> Result<Option<(usize, Vec<Vec<f64>>)>> {
        let sim = self.sim;
        let n = sim.req.n_samples;
        if self.next >= n {
            return Ok(None);
        }
        let start = self.next;
        let len = self.block.min(n - start);
        let mut own: HashMap<usize, Vec<f64>> = HashMap::new();
        for &ci in &self.needed {
            own.insert(ci, sim.own_signal_block(ci, start, len, &mut self.states)?);
        }
        let mut cols = Vec::with_capacity(self.wanted.len());
        for &ci in &self.wanted {
            let ch = &sim.spec.channels[ci];
            let mut v = own[&ci].clone();
            for (k, c) in ch.components.iter().enumerate() {
                if let Component::CrossAxis { from, gain } = c {
                    let src = &own[&sim.channel_index(from)?];
                    for (o, s) in v.iter_mut().zip(src) {
                        *o += gain * s;
                    }
                    sim.finite(&v, start, &sim.what(ci, k))?;
                }
            }
            let path = self.paths.entry(ci).or_insert_with(|| {
                output::OutputPath::of(&ch.components, sim.req.sample_rate_hz, None)
            });
            if !path.is_empty() {
                path.apply(&mut v);
                sim.finite(&v, start, &format!("channel '{}' output path", ch.name))?;
            }
            cols.push(v);
        }
        self.next = start + len;
        Ok(Some((start, cols)))
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
