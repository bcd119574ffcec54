//! Validating a typed spec: value ranges (finite numbers, non-negative sizes, positive
//! time constants), the stationarity of ARMA parts, and the cross-references between
//! channels (temperature channel, cross_axis sources, heteroskedastic targets), with
//! messages that name the key (module doc of [`super`]).

use std::collections::HashSet;

use super::{
    ChannelSpec, Component, Discretization, FarmaModel, Kind, MAX_FIR_TAPS, Spec, noise_kinds,
};
use crate::fmt::num;

/// The highest sample rate a simulation may run at, Hz (no gyro log comes near; above
/// it a second of simulation is beyond the simulator's samples).
pub const MAX_RATE_HZ: f64 = 1e9;
/// The largest magnitude of a number of a spec that is simulated: the simulation squares
/// and sums them (variances, sums of components and of recursions), which overflows
/// f64 (1.8e308) long before 1e300. A spec as data (parsed, written back) may hold any
/// finite value; [`Spec::check_simulable`] refuses those beyond.
pub const MAX_MAGNITUDE: f64 = 1e100;
/// The largest damping ratio of a second-order output filter: far beyond critical
/// damping (1) a second-order low-pass is a first-order one (its slow pole at about
/// bandwidth_hz / (2 damping)) and its fast pole only a numerical hazard.
pub const MAX_DAMPING: f64 = 1e3;

/// Every number of a component, by key (the elements of a list under one key).
fn numbers(c: &Component) -> Vec<(&'static str, f64)> {
    let mut v: Vec<(&'static str, f64)> = Vec::new();
    match c {
        Component::ConstantBias { value } => v.push(("value", *value)),
        Component::WhiteNoise { n } => v.push(("n", *n)),
        Component::Quantization { q } => v.push(("q", *q)),
        Component::BiasInstability {
            b,
            tau_min_s,
            tau_max_s,
        } => {
            v.push(("b", *b));
            v.extend(tau_min_s.map(|t| ("tau_min_s", t)));
            v.extend(tau_max_s.map(|t| ("tau_max_s", t)));
        }
        Component::RateRandomWalk { k } => v.push(("k", *k)),
        Component::RateRamp { r } => v.push(("r", *r)),
        Component::GaussMarkov { sigma, tau_s } => {
            v.extend([("sigma", *sigma), ("tau_s", *tau_s)]);
        }
        Component::Sinusoid {
            amplitude,
            freq_hz,
            phase_rad,
        } => v.extend([
            ("amplitude", *amplitude),
            ("freq_hz", *freq_hz),
            ("phase_rad", *phase_rad),
        ]),
        Component::Arma { ar, ma, sigma } => {
            v.extend(ar.iter().map(|x| ("ar", *x)));
            v.extend(ma.iter().map(|x| ("ma", *x)));
            v.push(("sigma", *sigma));
        }
        Component::Farma(FarmaModel::Inline { f, ma, sigma, .. }) => {
            v.extend(f.iter().flatten().map(|x| ("f", *x)));
            v.extend(ma.iter().map(|x| ("ma", *x)));
            v.push(("sigma", *sigma));
        }
        Component::Farma(FarmaModel::Fitted { .. }) => {}
        Component::TemperatureBias {
            coeffs,
            reference_c,
        } => {
            v.extend(coeffs.iter().map(|x| ("coeffs", *x)));
            v.extend(reference_c.map(|t| ("reference_c", t)));
        }
        Component::ThermalRate {
            coeff,
            smoothing_s,
            lag_s,
        } => {
            v.extend([
                ("coeff", *coeff),
                ("smoothing_s", *smoothing_s),
                ("lag_s", *lag_s),
            ]);
        }
        Component::Warmup { amplitude, tau_s } => {
            v.extend([("amplitude", *amplitude), ("tau_s", *tau_s)]);
        }
        Component::Outliers {
            rate_hz,
            scale,
            dof,
        } => {
            v.extend([("rate_hz", *rate_hz), ("scale", *scale)]);
            v.extend(dof.map(|d| ("dof", d)));
        }
        Component::Heteroskedastic {
            slope,
            floor,
            reference_c,
            ..
        } => {
            v.extend([("slope", *slope), ("floor", *floor)]);
            v.extend(reference_c.map(|r| ("reference_c", r)));
        }
        Component::CrossAxis { gain, .. } => v.push(("gain", *gain)),
        Component::OutputFilter {
            bandwidth_hz,
            damping,
            ..
        } => {
            v.push(("bandwidth_hz", *bandwidth_hz));
            v.extend(damping.map(|z| ("damping", z)));
        }
        Component::OutputFir { taps } => v.extend(taps.iter().map(|x| ("taps", *x))),
        Component::Saturation { limit } => v.push(("limit", *limit)),
        Component::OutputResolution { quantum, .. } => v.push(("quantum", *quantum)),
    }
    v
}

impl Spec {
    /// Checks values and cross-references (module doc); the message names the key.
    ///
    /// [`parse_spec`](super::parse_spec) runs this; a spec built in code (the noise-term
    /// identification) is checked by [`Spec::to_toml`].
    pub fn validate(&self) -> Result<(), String> {
        let rate = self.sample_rate_hz;
        if !(rate.is_finite() && rate > 0.0) {
            return Err(format!(
                "the top level: 'sample_rate_hz' must be > 0, found {}",
                num(rate)
            ));
        }

        if let Some(seed) = self.seed
            && seed > i64::MAX as u64
        {
            return Err(format!(
                "the top level: 'seed' must be at most {} (TOML integers are signed 64-bit), found {seed}",
                i64::MAX
            ));
        }
        if let Some(t) = &self.temperature_channel {
            if t.is_empty() {
                return Err("the top level: 'temperature_channel' must not be empty".into());
            }
            if self.channels.iter().any(|c| &c.name == t) {
                return Err(format!(
                    "the top level: 'temperature_channel' = '{t}' is also a simulated channel; the temperature channel is read from the real log"
                ));
            }
        }
        if self.channels.is_empty() {
            return Err("the spec has no [[channel]] table".into());
        }
        let mut names = HashSet::new();
        for (i, channel) in self.channels.iter().enumerate() {
            if channel.name.is_empty() {
                return Err(format!("channel {}: 'name' must not be empty", i + 1));
            }
            if !names.insert(channel.name.as_str()) {
                return Err(format!(
                    "channel '{}' appears twice (channel {}); channel names must be unique",
                    channel.name,
                    i + 1
                ));
            }
        }
        for channel in &self.channels {
            self.validate_channel(channel)?;
        }
        Ok(())
    }

    /// What a simulation of the spec at `rate_hz` needs beyond [`Spec::validate`]:
    /// the rate at most `MAX_RATE_HZ` and every number at most `MAX_MAGNITUDE` in
    /// magnitude (beyond, the simulated values overflow f64); the message names the
    /// component, the key and the value.
    pub fn check_simulable(&self, rate_hz: f64) -> Result<(), String> {
        if rate_hz > MAX_RATE_HZ {
            return Err(format!(
                "the sample rate {} Hz (the spec's 'sample_rate_hz' or the --like log's) is out of range: at most {} Hz",
                num(rate_hz),
                num(MAX_RATE_HZ)
            ));
        }
        for ch in &self.channels {
            for (i, c) in ch.components.iter().enumerate() {
                if let Component::OutputFilter {
                    bandwidth_hz,
                    discretization: Discretization::Bilinear,
                    ..
                } = c
                    && *bandwidth_hz >= rate_hz / 2.0
                {
                    return Err(format!(
                        "channel '{}' component {} (output_filter): 'bandwidth_hz' = {} must be below the Nyquist frequency {} Hz of the simulation's rate with discretization = \"bilinear\"",
                        ch.name,
                        i + 1,
                        num(*bandwidth_hz),
                        num(rate_hz / 2.0)
                    ));
                }
                if let Some((key, x)) = numbers(c)
                    .into_iter()
                    .find(|(_, x)| x.abs() > MAX_MAGNITUDE)
                {
                    return Err(format!(
                        "channel '{}' component {} ({}): '{key}' = {} is out of range: beyond {} the simulated values overflow f64 (they are squared and summed)",
                        ch.name,
                        i + 1,
                        c.kind(),
                        num(x),
                        num(MAX_MAGNITUDE)
                    ));
                }
            }
        }
        Ok(())
    }

    fn validate_channel(&self, channel: &ChannelSpec) -> Result<(), String> {
        let name = &channel.name;
        if channel.components.is_empty() {
            return Err(format!(
                "channel '{name}' has no components (add [[channel.component]] tables)"
            ));
        }
        let kinds: HashSet<Kind> = channel.components.iter().map(Component::kind).collect();
        if channel.components.iter().all(|c| c.kind().is_output_path()) {
            return Err(format!(
                "channel '{name}' has only output-path components (output_filter, saturation, output_resolution), which act on the sum of the others: add a noise or bias component"
            ));
        }
        let mut stages = HashSet::new();
        let mut modulated = HashSet::new();
        let mut sources = HashSet::new();
        for (i, component) in channel.components.iter().enumerate() {
            let place = format!(
                "channel '{name}' component {} ({})",
                i + 1,
                component.kind()
            );
            let check = Check { place: &place };
            if component.kind().is_output_path() && !stages.insert(component.kind()) {
                return Err(format!(
                    "{place}: a second {} in channel '{name}' (the output path has one of each stage)",
                    component.kind()
                ));
            }
            if component.kind().needs_temperature() && self.temperature_channel.is_none() {
                return Err(format!(
                    "{place}: needs a temperature: set 'temperature_channel' at the top level"
                ));
            }
            match component {
                Component::ConstantBias { value } => check.finite("value", *value)?,
                Component::WhiteNoise { n } => check.non_negative("n", *n)?,
                Component::Quantization { q } => check.non_negative("q", *q)?,
                Component::BiasInstability {
                    b,
                    tau_min_s,
                    tau_max_s,
                } => {
                    check.non_negative("b", *b)?;
                    if let Some(lo) = tau_min_s {
                        check.positive("tau_min_s", *lo)?;
                    }
                    if let Some(hi) = tau_max_s {
                        check.positive("tau_max_s", *hi)?;
                    }
                    if let (Some(lo), Some(hi)) = (tau_min_s, tau_max_s)
                        && lo >= hi
                    {
                        return Err(format!(
                            "{place}: 'tau_min_s' ({}) must be below 'tau_max_s' ({})",
                            num(*lo),
                            num(*hi)
                        ));
                    }
                }
                Component::RateRandomWalk { k } => check.non_negative("k", *k)?,
                Component::RateRamp { r } => check.finite("r", *r)?,
                Component::GaussMarkov { sigma, tau_s } => {
                    check.non_negative("sigma", *sigma)?;
                    check.positive("tau_s", *tau_s)?;
                }
                Component::Sinusoid {
                    amplitude,
                    freq_hz,
                    phase_rad,
                } => {
                    if amplitude.is_finite() && *amplitude < 0.0 {
                        return Err(format!(
                            "{place}: 'amplitude' must be >= 0, found {} (use 'phase_rad' to flip the sign)",
                            num(*amplitude)
                        ));
                    }
                    check.non_negative("amplitude", *amplitude)?;
                    check.non_negative("freq_hz", *freq_hz)?;
                    check.finite("phase_rad", *phase_rad)?;
                    let nyquist = self.sample_rate_hz / 2.0;
                    if *freq_hz >= nyquist {
                        return Err(format!(
                            "{place}: 'freq_hz' = {} must be below the Nyquist frequency {} Hz (sample_rate_hz / 2)",
                            num(*freq_hz),
                            num(nyquist)
                        ));
                    }
                }
                Component::Arma { ar, ma, sigma } => {
                    check.all_finite("ar", ar)?;
                    check.all_finite("ma", ma)?;
                    check.non_negative("sigma", *sigma)?;
                    if !ar_is_stationary(ar) {
                        return Err(format!(
                            "{place}: 'ar' = {ar:?} is not stationary (a root of 1 - sum ar[m] z^m lies on or inside the unit circle); a simulation would diverge"
                        ));
                    }
                }
                Component::Farma(FarmaModel::Fitted { model, channel }) => {
                    if model.as_os_str().is_empty() {
                        return Err(format!("{place}: 'model' must not be empty"));
                    }
                    if channel.as_deref() == Some("") {
                        return Err(format!("{place}: 'channel' must not be empty"));
                    }
                }
                Component::Farma(FarmaModel::Inline {
                    p,
                    q,
                    d,
                    f,
                    ma,
                    sigma,
                }) => {
                    if *d == 0 {
                        return Err(format!("{place}: 'd' must be >= 1 (the index is x_(t-d))"));
                    }
                    if f.len() != *p {
                        return Err(format!(
                            "{place}: 'f' has {} polynomial(s) but p = {p}",
                            f.len()
                        ));
                    }
                    if ma.len() != *q {
                        return Err(format!(
                            "{place}: 'ma' has {} coefficient(s) but q = {q}",
                            ma.len()
                        ));
                    }
                    for (m, poly) in f.iter().enumerate() {
                        if poly.is_empty() {
                            return Err(format!(
                                "{place}: 'f' entry {} (f_{}) has no coefficients",
                                m + 1,
                                m + 1
                            ));
                        }
                        check.all_finite("f", poly)?;
                    }
                    check.all_finite("ma", ma)?;
                    check.non_negative("sigma", *sigma)?;
                }
                Component::TemperatureBias {
                    coeffs,
                    reference_c,
                } => {
                    if coeffs.is_empty() {
                        return Err(format!(
                            "{place}: 'coeffs' must hold at least one coefficient [u/degC, u/degC^2, ...]"
                        ));
                    }
                    check.all_finite("coeffs", coeffs)?;
                    if let Some(t) = reference_c {
                        check.finite("reference_c", *t)?;
                    }
                }
                Component::ThermalRate {
                    coeff,
                    smoothing_s,
                    lag_s,
                } => {
                    check.finite("coeff", *coeff)?;
                    check.non_negative("smoothing_s", *smoothing_s)?;
                    check.non_negative("lag_s", *lag_s)?;
                }
                Component::Warmup { amplitude, tau_s } => {
                    check.finite("amplitude", *amplitude)?;
                    check.positive("tau_s", *tau_s)?;
                }
                Component::Outliers {
                    rate_hz,
                    scale,
                    dof,
                } => {
                    check.non_negative("rate_hz", *rate_hz)?;
                    check.non_negative("scale", *scale)?;
                    if let Some(d) = dof
                        && !(d.is_finite() && *d >= 1.0)
                    {
                        return Err(format!(
                            "{place}: 'dof' = {} must be a finite number >= 1 (the Student-t's degrees of freedom; leave it out for normal amplitudes)",
                            num(*d)
                        ));
                    }
                    if *rate_hz > self.sample_rate_hz {
                        return Err(format!(
                            "{place}: 'rate_hz' = {} exceeds sample_rate_hz = {} (at most one outlier per sample)",
                            num(*rate_hz),
                            num(self.sample_rate_hz)
                        ));
                    }
                }
                Component::Heteroskedastic {
                    of,
                    slope,
                    floor,
                    reference_c,
                } => {
                    check.finite("slope", *slope)?;
                    if let Some(r) = reference_c {
                        check.finite("reference_c", *r)?;
                    }
                    check.non_negative("floor", *floor)?;
                    if *floor >= 1.0 {
                        return Err(format!(
                            "{place}: 'floor' must be < 1 (the scale at the reference temperature is 1), found {}",
                            num(*floor)
                        ));
                    }
                    if !of.is_noise() {
                        return Err(format!(
                            "{place}: 'of' = '{of}' is not a noise kind (expected one of: {})",
                            noise_kinds()
                        ));
                    }
                    if !kinds.contains(of) {
                        return Err(format!(
                            "{place}: 'of' = '{of}' but channel '{name}' has no {of} component"
                        ));
                    }
                    if !modulated.insert(*of) {
                        return Err(format!(
                            "{place}: a second heteroskedastic component for '{of}' in channel '{name}'"
                        ));
                    }
                }
                Component::OutputFilter {
                    order,
                    bandwidth_hz,
                    damping,
                    discretization,
                } => {
                    if !(1..=2).contains(order) {
                        return Err(format!("{place}: 'order' must be 1 or 2, found {order}"));
                    }
                    check.positive("bandwidth_hz", *bandwidth_hz)?;
                    let nyquist = self.sample_rate_hz / 2.0;
                    if *discretization == Discretization::Bilinear && *bandwidth_hz >= nyquist {
                        return Err(format!(
                            "{place}: 'bandwidth_hz' = {} must be below the Nyquist frequency {} Hz (sample_rate_hz / 2) with discretization = \"bilinear\" (the prewarping maps the Nyquist frequency to an infinite analog one)",
                            num(*bandwidth_hz),
                            num(nyquist)
                        ));
                    }
                    if let Some(z) = damping {
                        if *order == 1 {
                            return Err(format!(
                                "{place}: 'damping' is a parameter of a second-order filter (order = 2), found with order = 1"
                            ));
                        }
                        check.positive("damping", *z)?;
                        if *z > MAX_DAMPING {
                            return Err(format!(
                                "{place}: 'damping' = {} is out of range: at most {} (beyond, the filter is a first-order one of bandwidth bandwidth_hz / (2 damping))",
                                num(*z),
                                num(MAX_DAMPING)
                            ));
                        }
                    }
                }
                Component::OutputFir { taps } => {
                    if taps.is_empty() || taps.len() > MAX_FIR_TAPS {
                        return Err(format!(
                            "{place}: 'taps' must hold 1 to {MAX_FIR_TAPS} numbers, found {}",
                            taps.len()
                        ));
                    }
                    check.all_finite("taps", taps)?;
                }
                Component::Saturation { limit } => check.positive("limit", *limit)?,
                Component::OutputResolution { quantum, .. } => {
                    check.positive("quantum", *quantum)?
                }
                Component::CrossAxis { from, gain } => {
                    check.finite("gain", *gain)?;
                    if from == name {
                        return Err(format!(
                            "{place}: 'from' = '{from}' is this channel; cross_axis couples another channel"
                        ));
                    }
                    if !self.channels.iter().any(|c| &c.name == from) {
                        let names: Vec<&str> =
                            self.channels.iter().map(|c| c.name.as_str()).collect();
                        return Err(format!(
                            "{place}: 'from' = '{from}' is not a channel of the spec (channels: {})",
                            names.join(", ")
                        ));
                    }
                    if !sources.insert(from.as_str()) {
                        return Err(format!(
                            "{place}: a second cross_axis from '{from}' in channel '{name}' (give one with the total gain)"
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

/// Range checks for one component's parameters.
struct Check<'a> {
    place: &'a str,
}

impl Check<'_> {
    fn finite(&self, key: &str, x: f64) -> Result<(), String> {
        if x.is_finite() {
            Ok(())
        } else {
            Err(format!("{}: '{key}' must be finite, found {x}", self.place))
        }
    }

    fn all_finite(&self, key: &str, xs: &[f64]) -> Result<(), String> {
        match xs.iter().find(|x| !x.is_finite()) {
            None => Ok(()),
            Some(x) => Err(format!(
                "{}: '{key}' must hold finite numbers, found {x}",
                self.place
            )),
        }
    }

    fn non_negative(&self, key: &str, x: f64) -> Result<(), String> {
        self.finite(key, x)?;
        if x >= 0.0 {
            Ok(())
        } else {
            Err(format!(
                "{}: '{key}' must be >= 0, found {}",
                self.place,
                num(x)
            ))
        }
    }

    fn positive(&self, key: &str, x: f64) -> Result<(), String> {
        self.finite(key, x)?;
        if x > 0.0 {
            Ok(())
        } else {
            Err(format!(
                "{}: '{key}' must be > 0, found {}",
                self.place,
                num(x)
            ))
        }
    }
}

/// Whether x_t = sum_m ar[m-1] x_{t-m} + e_t is stationary: every root of
/// 1 - sum_m ar[m-1] z^m outside the unit circle. The Schur-Cohn step-down (reverse
/// Levinson-Durbin) recursion turns the coefficients into partial autocorrelations,
/// which all lie strictly inside (-1, 1) exactly when the process is stationary.
pub fn ar_is_stationary(ar: &[f64]) -> bool {
    let mut a: Vec<f64> = ar.to_vec();
    while let Some(&last) = a.last() {
        if last == 0.0 {
            a.pop();
        } else {
            break;
        }
    }
    while let Some(&k) = a.last() {
        if k.is_nan() || k.abs() >= 1.0 {
            return false;
        }
        let order = a.len();
        let denom = 1.0 - k * k;
        let prev: Vec<f64> = (0..order - 1)
            .map(|j| (a[j] + k * a[order - 2 - j]) / denom)
            .collect();
        a = prev;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ar_stationarity_matches_known_cases() {
        assert!(ar_is_stationary(&[]));
        assert!(ar_is_stationary(&[0.9]));
        assert!(!ar_is_stationary(&[1.0]));
        assert!(!ar_is_stationary(&[-1.01]));
        // AR(2): stationary iff a2 + a1 < 1, a2 - a1 < 1, |a2| < 1.
        assert!(ar_is_stationary(&[0.5, 0.3]));
        assert!(!ar_is_stationary(&[0.5, 0.6]));
        assert!(ar_is_stationary(&[1.8, -0.9]));
        assert!(!ar_is_stationary(&[0.2, -1.0]));
        // (1 - 0.5 z)(1 - 0.5 z)(1 - 2 z): one root inside.
        assert!(!ar_is_stationary(&[3.0, -2.25, 0.5]));
        // (1 - 0.5 z)^3 = 1 - 1.5 z + 0.75 z^2 - 0.125 z^3.
        assert!(ar_is_stationary(&[1.5, -0.75, 0.125]));
        // Trailing zeros do not change the answer.
        assert!(ar_is_stationary(&[0.5, 0.0, 0.0]));
    }
}
