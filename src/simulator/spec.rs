//! The simulation spec: `../shared/design/contracts.md` section 2.
//!
//! A spec is a TOML file: top-level `sample_rate_hz`, optional `temperature_channel` and
//! `seed`, then one `[[channel]]` table per simulated channel, each with a `name` and
//! its `[[channel.component]]` tables. Every component has a `kind` and that kind's
//! parameters ([`Component`] lists them with their units). `u` is the rate unit of the
//! log (deg/h, deg/s, rad/s ...); times are in seconds.
//!
//! Noise coefficients follow IEEE Std 952, so that each is read off an Allan deviation
//! plot: white_noise `n` gives ADEV(tau) = n / sqrt(tau) (angle random walk);
//! quantization `q` gives sqrt(3) q / tau; rate_random_walk `k` gives k sqrt(tau / 3);
//! rate_ramp `r` gives r tau / sqrt(2); bias_instability `b` gives a flat floor of about
//! 0.664 b.
//!
//! Decisions the contract leaves open, taken here:
//! - `sample_rate_hz` is **required**: the contract marks only `temperature_channel` and
//!   `seed` optional. (A `--like REAL_LOG` run may still take the rate from the log;
//!   that is the simulate command's business.) Having the rate lets the spec check
//!   sinusoid frequencies against the Nyquist frequency and outlier rates against the
//!   sample rate.
//! - Every parameter the contract lists is required, except those it marks optional or
//!   gives a default: bias_instability `tau_min_s`/`tau_max_s` and temperature_bias
//!   `reference_c`. A farma component with `model` may also name the `channel` of the
//!   fitted model (default: the spec channel's name, or the only channel fitted).
//! - Which values may be negative: coefficients that are a size (n, q, b, k, sigma,
//!   scale, a sinusoid's amplitude, rates, times) must be >= 0 (time constants > 0);
//!   signed effects (constant_bias `value`, rate_ramp `r`, warmup `amplitude`,
//!   temperature_bias `coeffs`, thermal_rate `coeff`, heteroskedastic `slope`,
//!   cross_axis `gain`, ARMA/FARMA coefficients, phases) may have either sign. Every
//!   number must be finite.
//! - ARMA: the AR part must be stationary (all roots of 1 - sum a_m z^m outside the unit
//!   circle, checked exactly by the Schur-Cohn step-down recursion), since a simulation
//!   of a non-stationary AR diverges. The MA part need not be invertible: every finite
//!   MA is stationary, so nothing is wrong with simulating one. The inline FARMA f_m
//!   are nonlinear and are not checked for stability.
//! - Inline FARMA `f`: `f[m-1]` holds the polynomial coefficients of f_m in ascending
//!   powers, f_m(u) = f[m-1]\[0\] + f[m-1]\[1\] u + f[m-1]\[2\] u^2 + ...
//! - `cross_axis` adds `gain` times the `from` channel's own signal (its components
//!   other than cross_axis), so couplings in both directions are allowed (a
//!   misalignment matrix); one cross_axis per source channel.
//! - Temperature-driven components (temperature_bias, thermal_rate, heteroskedastic)
//!   need the top-level `temperature_channel`, which must not also be a simulated
//!   channel. `heteroskedastic.of` must be a noise kind (white_noise, quantization,
//!   bias_instability, rate_random_walk, gauss_markov, arma, farma, outliers) present in
//!   the same channel, at most one heteroskedastic per kind.
//! - A farma `model` path is kept as written (relative paths are for the generator to
//!   resolve against the spec's folder); its existence is checked when it is loaded.
//!
//! Parsing is a walk over the TOML table rather than serde derive, so that every error
//! names its place in the spec the same way (`channel 'rate' component 2
//! (white_noise): missing parameter 'n'`) and unknown keys are caught for every kind.
//! Errors are [`Error::Format`] (exit code 2) naming the spec file; TOML syntax errors
//! are [`Error::Malformed`] with the line and column the parser reports.

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use toml::{Table, Value};

use crate::error::{Error, Result};

/// A whole simulation spec (contracts.md section 2).
#[derive(Debug, Clone, PartialEq)]
pub struct Spec {
    /// Sample rate of the simulated log, Hz (> 0). Required (see the module doc).
    pub sample_rate_hz: f64,
    /// A channel of the real log whose temperature (degC) drives temperature effects.
    pub temperature_channel: Option<String>,
    /// Seed of the random generator (0 ..= i64::MAX, TOML integers are signed 64-bit).
    pub seed: Option<u64>,
    /// The simulated channels, in the order of the spec (`[[channel]]`).
    pub channels: Vec<ChannelSpec>,
}

/// One `[[channel]]`: the name of the log channel it models and its components.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelSpec {
    /// The channel this models (a column name of the real log).
    pub name: String,
    /// The `[[channel.component]]` tables, summed, in the order of the spec.
    pub components: Vec<Component>,
}

/// One noise or error component (`[[channel.component]]`), by `kind`.
///
/// Units: `u` is the rate unit of the log; IEEE Std 952 meanings in the module doc.
#[derive(Debug, Clone, PartialEq)]
pub enum Component {
    /// A constant bias `value` \[u\] (any sign).
    ConstantBias { value: f64 },
    /// Angle random walk: white rate noise with ADEV(tau) = n / sqrt(tau); `n` [u sqrt(s)] >= 0.
    WhiteNoise { n: f64 },
    /// Angle quantization noise: ADEV(tau) = sqrt(3) q / tau; `q` [u s] >= 0; the angle
    /// quantum is sqrt(12) q.
    Quantization { q: f64 },
    /// Bias instability (flicker): a flat ADEV floor of about 0.664 b; `b` \[u\] >= 0.
    /// `tau_min_s`, `tau_max_s` (> 0, min < max) bound the flicker approximation.
    BiasInstability {
        b: f64,
        tau_min_s: Option<f64>,
        tau_max_s: Option<f64>,
    },
    /// Rate random walk: ADEV(tau) = k sqrt(tau / 3); `k` [u / sqrt(s)] >= 0.
    RateRandomWalk { k: f64 },
    /// Rate ramp: ADEV(tau) = r tau / sqrt(2); `r` [u / s] (any sign).
    RateRamp { r: f64 },
    /// First-order Gauss-Markov (exponentially correlated) noise: stationary standard
    /// deviation `sigma` \[u\] >= 0, correlation time `tau_s` \[s\] > 0.
    GaussMarkov { sigma: f64, tau_s: f64 },
    /// amplitude sin(2 pi freq_hz t + phase_rad): `amplitude` \[u\] >= 0,
    /// 0 <= `freq_hz` < sample_rate_hz / 2, `phase_rad` \[rad\].
    Sinusoid {
        amplitude: f64,
        freq_hz: f64,
        phase_rad: f64,
    },
    /// Linear ARMA x_t = sum_m ar[m-1] x_{t-m} + e_t + sum_m ma[m-1] e_{t-m}, with
    /// innovation standard deviation `sigma` \[u\] >= 0; the AR part must be stationary.
    Arma {
        ar: Vec<f64>,
        ma: Vec<f64>,
        sigma: f64,
    },
    /// A FARMA(p,q,d) model: fitted by `farma fit`, or inline.
    Farma(FarmaModel),
    /// Bias sum_j coeffs[j-1] (T - reference_c)^j; `coeffs` [u/degC, u/degC^2, ...]
    /// (non-empty), `reference_c` \[degC\] (default: the mean temperature).
    TemperatureBias {
        coeffs: Vec<f64>,
        reference_c: Option<f64>,
    },
    /// Bias proportional to dT/dt (the Shupe effect): `coeff` [u per degC/s], the
    /// temperature smoothed over `smoothing_s` \[s\] >= 0 before differencing.
    ThermalRate { coeff: f64, smoothing_s: f64 },
    /// Warm-up bias amplitude exp(-t / tau_s): `amplitude` \[u\] (any sign), `tau_s` \[s\] > 0.
    Warmup { amplitude: f64, tau_s: f64 },
    /// Outliers at `rate_hz` [1/s] (0 ..= sample_rate_hz) with size `scale` \[u\] >= 0.
    Outliers { rate_hz: f64, scale: f64 },
    /// The scale of the channel's `of` noise component varies with temperature:
    /// scale = 1 + slope (T - T_ref); `slope` [1/degC].
    Heteroskedastic { of: Kind, slope: f64 },
    /// Cross-axis coupling: `gain` (any sign) times the signal of channel `from`.
    CrossAxis { from: String, gain: f64 },
}

/// A farma component: a model written by `farma fit`, or an inline FARMA(p,q,d).
#[derive(Debug, Clone, PartialEq)]
pub enum FarmaModel {
    /// `model`: the output folder of `farma fit`; `channel`: which fitted channel.
    Fitted {
        model: PathBuf,
        channel: Option<String>,
    },
    /// Inline x_t = sum_m f_m(x_{t-d}) x_{t-m} + e_t + sum_m ma[m-1] e_{t-m}, with
    /// f_m(u) = sum_j f[m-1]\[j\] u^j (ascending powers), innovation standard deviation
    /// `sigma` \[u\] >= 0. `f` has p entries (each non-empty), `ma` has q, d >= 1.
    Inline {
        p: usize,
        q: usize,
        d: usize,
        f: Vec<Vec<f64>>,
        ma: Vec<f64>,
        sigma: f64,
    },
}

/// The component kinds of contracts.md section 2, as written in `kind = "..."`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    ConstantBias,
    WhiteNoise,
    Quantization,
    BiasInstability,
    RateRandomWalk,
    RateRamp,
    GaussMarkov,
    Sinusoid,
    Arma,
    Farma,
    TemperatureBias,
    ThermalRate,
    Warmup,
    Outliers,
    Heteroskedastic,
    CrossAxis,
}

impl Kind {
    /// Every kind, in the order of the contract's table.
    pub const ALL: [Kind; 16] = [
        Kind::ConstantBias,
        Kind::WhiteNoise,
        Kind::Quantization,
        Kind::BiasInstability,
        Kind::RateRandomWalk,
        Kind::RateRamp,
        Kind::GaussMarkov,
        Kind::Sinusoid,
        Kind::Arma,
        Kind::Farma,
        Kind::TemperatureBias,
        Kind::ThermalRate,
        Kind::Warmup,
        Kind::Outliers,
        Kind::Heteroskedastic,
        Kind::CrossAxis,
    ];

    /// The name used in the spec.
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::ConstantBias => "constant_bias",
            Kind::WhiteNoise => "white_noise",
            Kind::Quantization => "quantization",
            Kind::BiasInstability => "bias_instability",
            Kind::RateRandomWalk => "rate_random_walk",
            Kind::RateRamp => "rate_ramp",
            Kind::GaussMarkov => "gauss_markov",
            Kind::Sinusoid => "sinusoid",
            Kind::Arma => "arma",
            Kind::Farma => "farma",
            Kind::TemperatureBias => "temperature_bias",
            Kind::ThermalRate => "thermal_rate",
            Kind::Warmup => "warmup",
            Kind::Outliers => "outliers",
            Kind::Heteroskedastic => "heteroskedastic",
            Kind::CrossAxis => "cross_axis",
        }
    }

    /// The kind named `name`, if any.
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.as_str() == name)
    }

    /// Random noise whose scale `heteroskedastic` can modulate.
    pub fn is_noise(self) -> bool {
        matches!(
            self,
            Kind::WhiteNoise
                | Kind::Quantization
                | Kind::BiasInstability
                | Kind::RateRandomWalk
                | Kind::GaussMarkov
                | Kind::Arma
                | Kind::Farma
                | Kind::Outliers
        )
    }

    /// Driven by the temperature channel.
    pub fn needs_temperature(self) -> bool {
        matches!(
            self,
            Kind::TemperatureBias | Kind::ThermalRate | Kind::Heteroskedastic
        )
    }

    /// The keys a component of this kind may hold, besides `kind`.
    fn keys(self) -> &'static [&'static str] {
        match self {
            Kind::ConstantBias => &["value"],
            Kind::WhiteNoise => &["n"],
            Kind::Quantization => &["q"],
            Kind::BiasInstability => &["b", "tau_min_s", "tau_max_s"],
            Kind::RateRandomWalk => &["k"],
            Kind::RateRamp => &["r"],
            Kind::GaussMarkov => &["sigma", "tau_s"],
            Kind::Sinusoid => &["amplitude", "freq_hz", "phase_rad"],
            Kind::Arma => &["ar", "ma", "sigma"],
            Kind::Farma => &["model", "channel", "p", "q", "d", "f", "ma", "sigma"],
            Kind::TemperatureBias => &["coeffs", "reference_c"],
            Kind::ThermalRate => &["coeff", "smoothing_s"],
            Kind::Warmup => &["amplitude", "tau_s"],
            Kind::Outliers => &["rate_hz", "scale"],
            Kind::Heteroskedastic => &["of", "slope"],
            Kind::CrossAxis => &["from", "gain"],
        }
    }
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Component {
    /// This component's kind.
    pub fn kind(&self) -> Kind {
        match self {
            Component::ConstantBias { .. } => Kind::ConstantBias,
            Component::WhiteNoise { .. } => Kind::WhiteNoise,
            Component::Quantization { .. } => Kind::Quantization,
            Component::BiasInstability { .. } => Kind::BiasInstability,
            Component::RateRandomWalk { .. } => Kind::RateRandomWalk,
            Component::RateRamp { .. } => Kind::RateRamp,
            Component::GaussMarkov { .. } => Kind::GaussMarkov,
            Component::Sinusoid { .. } => Kind::Sinusoid,
            Component::Arma { .. } => Kind::Arma,
            Component::Farma(_) => Kind::Farma,
            Component::TemperatureBias { .. } => Kind::TemperatureBias,
            Component::ThermalRate { .. } => Kind::ThermalRate,
            Component::Warmup { .. } => Kind::Warmup,
            Component::Outliers { .. } => Kind::Outliers,
            Component::Heteroskedastic { .. } => Kind::Heteroskedastic,
            Component::CrossAxis { .. } => Kind::CrossAxis,
        }
    }
}

/// Reads and validates the spec at `path` (errors exit with code 2).
pub fn load_spec(path: &Path) -> Result<Spec> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input_io(path, e))?;
    parse_spec(&text, path)
}

/// Parses and validates spec `text`; `source` names the file in errors.
pub fn parse_spec(text: &str, source: &Path) -> Result<Spec> {
    let table: Table = text.parse().map_err(|e| syntax_error(text, source, &e))?;
    let spec = decode_spec(&table).map_err(|msg| Error::format(source, msg))?;
    spec.validate().map_err(|msg| Error::format(source, msg))?;
    Ok(spec)
}

/// A TOML syntax error as `FILE:LINE: column C: message`.
fn syntax_error(text: &str, source: &Path, e: &toml::de::Error) -> Error {
    let message = e.message().trim().replace('\n', "; ");
    match e.span() {
        Some(span) => {
            let start = span.start.min(text.len());
            let before = &text[..start];
            let line = before.matches('\n').count() as u64 + 1;
            let line_start = before.rfind('\n').map_or(0, |i| i + 1);
            let column = before[line_start..].chars().count() + 1;
            Error::Malformed {
                path: source.to_path_buf(),
                line,
                msg: format!("column {column}: invalid TOML: {message}"),
            }
        }
        None => Error::format(source, format!("invalid TOML: {message}")),
    }
}

// ---------------------------------------------------------------------------------
// Decoding: types, missing and unknown keys.

/// The keys of one table, read with their place in the spec for messages.
struct Fields<'t> {
    table: &'t Table,
    /// "channel 'rate' component 2 (white_noise)", "channel 'rate'", "the top level".
    place: String,
    /// "parameter" in components, "key" elsewhere.
    noun: &'static str,
}

impl<'t> Fields<'t> {
    /// Checks that `table` holds only `allowed` keys.
    fn new(
        table: &'t Table,
        place: String,
        noun: &'static str,
        allowed: &[&str],
    ) -> Result<Self, String> {
        for key in table.keys() {
            if !allowed.contains(&key.as_str()) {
                let at = if place == "the top level" {
                    "at the top level".to_string()
                } else {
                    format!("in {place}")
                };
                let hint = match closest(key, allowed) {
                    Some(near) => format!("; did you mean '{near}'?"),
                    None => String::new(),
                };
                return Err(format!(
                    "unknown key '{key}' {at} (expected {}){hint}",
                    one_of(allowed)
                ));
            }
        }
        Ok(Fields { table, place, noun })
    }

    fn has(&self, key: &str) -> bool {
        self.table.contains_key(key)
    }

    fn get(&self, key: &str) -> Result<&'t Value, String> {
        self.table
            .get(key)
            .ok_or_else(|| format!("{}: missing {} '{key}'", self.place, self.noun))
    }

    fn wrong(&self, key: &str, want: &str, found: &Value) -> String {
        format!(
            "{}: '{key}' must be {want}, found {}",
            self.place,
            describe(found)
        )
    }

    fn f64(&self, key: &str) -> Result<f64, String> {
        let v = self.get(key)?;
        number(v).ok_or_else(|| self.wrong(key, "a number", v))
    }

    fn opt_f64(&self, key: &str) -> Result<Option<f64>, String> {
        if self.has(key) {
            self.f64(key).map(Some)
        } else {
            Ok(None)
        }
    }

    fn string(&self, key: &str) -> Result<String, String> {
        let v = self.get(key)?;
        v.as_str()
            .map(str::to_string)
            .ok_or_else(|| self.wrong(key, "a string", v))
    }

    fn opt_string(&self, key: &str) -> Result<Option<String>, String> {
        if self.has(key) {
            self.string(key).map(Some)
        } else {
            Ok(None)
        }
    }

    /// A non-negative integer.
    fn uint(&self, key: &str) -> Result<u64, String> {
        let v = self.get(key)?;
        match v.as_integer() {
            Some(i) if i >= 0 => Ok(i as u64),
            _ => Err(self.wrong(key, "an integer >= 0", v)),
        }
    }

    fn list(&self, key: &str) -> Result<Vec<f64>, String> {
        let v = self.get(key)?;
        numbers(v).ok_or_else(|| self.wrong(key, "an array of numbers", v))
    }

    fn matrix(&self, key: &str) -> Result<Vec<Vec<f64>>, String> {
        let v = self.get(key)?;
        v.as_array()
            .and_then(|rows| rows.iter().map(numbers).collect::<Option<Vec<_>>>())
            .ok_or_else(|| self.wrong(key, "an array of arrays of numbers", v))
    }
}

/// A TOML number (an integer reads as a float) as f64.
fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Float(x) => Some(*x),
        Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

fn numbers(v: &Value) -> Option<Vec<f64>> {
    v.as_array()?.iter().map(number).collect()
}

fn describe(v: &Value) -> String {
    let what = match v {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a float",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a datetime",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    };
    match v {
        Value::Array(_) | Value::Table(_) => what.to_string(),
        _ => format!("{what} ({v})"),
    }
}

fn one_of(names: &[&str]) -> String {
    match names {
        [] => "no keys".to_string(),
        [one] => format!("'{one}'"),
        _ => {
            let quoted: Vec<String> = names.iter().map(|n| format!("'{n}'")).collect();
            format!("one of {}", quoted.join(", "))
        }
    }
}

/// The allowed name nearest to `key` by edit distance, if it is a plausible typo.
fn closest<'a>(key: &str, allowed: &[&'a str]) -> Option<&'a str> {
    fn distance(a: &str, b: &str) -> usize {
        let b: Vec<char> = b.chars().collect();
        let mut row: Vec<usize> = (0..=b.len()).collect();
        for (i, ca) in a.chars().enumerate() {
            let mut prev = row[0];
            row[0] = i + 1;
            for (j, cb) in b.iter().enumerate() {
                let cur = row[j + 1];
                row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
                prev = cur;
            }
        }
        row[b.len()]
    }
    allowed
        .iter()
        .map(|&name| (distance(key, name), name))
        .filter(|&(d, name)| d <= 2 && d < name.chars().count().max(2))
        .min_by_key(|&(d, _)| d)
        .map(|(_, name)| name)
}

const TOP_KEYS: &[&str] = &["sample_rate_hz", "temperature_channel", "seed", "channel"];
const CHANNEL_KEYS: &[&str] = &["name", "component"];

fn decode_spec(table: &Table) -> Result<Spec, String> {
    let top = Fields::new(table, "the top level".into(), "key", TOP_KEYS)?;
    let sample_rate_hz = top.f64("sample_rate_hz")?;
    let temperature_channel = top.opt_string("temperature_channel")?;
    let seed = if top.has("seed") {
        Some(top.uint("seed")?)
    } else {
        None
    };
    let channels = match table.get("channel") {
        None => {
            return Err(
                "the top level: missing key 'channel' (at least one [[channel]] table)".into(),
            );
        }
        Some(v) => tables_of(v, "the top level", "channel", "[[channel]]")?
            .into_iter()
            .enumerate()
            .map(|(i, t)| decode_channel(t, i + 1))
            .collect::<Result<Vec<_>, _>>()?,
    };
    Ok(Spec {
        sample_rate_hz,
        temperature_channel,
        seed,
        channels,
    })
}

/// `v` as an array of tables (`[[key]]`).
fn tables_of<'v>(
    v: &'v Value,
    place: &str,
    key: &str,
    syntax: &str,
) -> Result<Vec<&'v Table>, String> {
    let bad = || {
        format!(
            "{place}: '{key}' must be an array of tables ({syntax}), found {}",
            describe(v)
        )
    };
    v.as_array()
        .ok_or_else(bad)?
        .iter()
        .map(|item| item.as_table().ok_or_else(bad))
        .collect()
}

fn decode_channel(table: &Table, index: usize) -> Result<ChannelSpec, String> {
    // The name first, so that every later message can use it.
    let unnamed = format!("channel {index}");
    let name = match table.get("name") {
        Some(Value::String(s)) => s.clone(),
        Some(other) => {
            return Err(format!(
                "{unnamed}: 'name' must be a string, found {}",
                describe(other)
            ));
        }
        None => return Err(format!("{unnamed}: missing key 'name'")),
    };
    let place = format!("channel '{name}'");
    Fields::new(table, place.clone(), "key", CHANNEL_KEYS)?;
    let components = match table.get("component") {
        None => Vec::new(),
        Some(v) => tables_of(v, &place, "component", "[[channel.component]]")?
            .into_iter()
            .enumerate()
            .map(|(i, t)| decode_component(t, &place, i + 1))
            .collect::<Result<Vec<_>, _>>()?,
    };
    Ok(ChannelSpec { name, components })
}

fn decode_component(table: &Table, channel: &str, index: usize) -> Result<Component, String> {
    let unnamed = format!("{channel} component {index}");
    let kind = match table.get("kind") {
        Some(Value::String(s)) => match Kind::from_name(s) {
            Some(kind) => kind,
            None => {
                let names: Vec<&str> = Kind::ALL.iter().map(|k| k.as_str()).collect();
                let hint = match closest(s, &names) {
                    Some(near) => format!("; did you mean '{near}'?"),
                    None => String::new(),
                };
                return Err(format!(
                    "{unnamed}: unknown kind '{s}' (expected {}){hint}",
                    one_of(&names)
                ));
            }
        },
        Some(other) => {
            return Err(format!(
                "{unnamed}: 'kind' must be a string, found {}",
                describe(other)
            ));
        }
        None => return Err(format!("{unnamed}: missing key 'kind'")),
    };
    let place = format!("{unnamed} ({kind})");
    let mut allowed = vec!["kind"];
    allowed.extend_from_slice(kind.keys());
    let p = Fields::new(table, place, "parameter", &allowed)?;
    Ok(match kind {
        Kind::ConstantBias => Component::ConstantBias {
            value: p.f64("value")?,
        },
        Kind::WhiteNoise => Component::WhiteNoise { n: p.f64("n")? },
        Kind::Quantization => Component::Quantization { q: p.f64("q")? },
        Kind::BiasInstability => Component::BiasInstability {
            b: p.f64("b")?,
            tau_min_s: p.opt_f64("tau_min_s")?,
            tau_max_s: p.opt_f64("tau_max_s")?,
        },
        Kind::RateRandomWalk => Component::RateRandomWalk { k: p.f64("k")? },
        Kind::RateRamp => Component::RateRamp { r: p.f64("r")? },
        Kind::GaussMarkov => Component::GaussMarkov {
            sigma: p.f64("sigma")?,
            tau_s: p.f64("tau_s")?,
        },
        Kind::Sinusoid => Component::Sinusoid {
            amplitude: p.f64("amplitude")?,
            freq_hz: p.f64("freq_hz")?,
            phase_rad: p.f64("phase_rad")?,
        },
        Kind::Arma => Component::Arma {
            ar: p.list("ar")?,
            ma: p.list("ma")?,
            sigma: p.f64("sigma")?,
        },
        Kind::Farma => Component::Farma(decode_farma(&p)?),
        Kind::TemperatureBias => Component::TemperatureBias {
            coeffs: p.list("coeffs")?,
            reference_c: p.opt_f64("reference_c")?,
        },
        Kind::ThermalRate => Component::ThermalRate {
            coeff: p.f64("coeff")?,
            smoothing_s: p.f64("smoothing_s")?,
        },
        Kind::Warmup => Component::Warmup {
            amplitude: p.f64("amplitude")?,
            tau_s: p.f64("tau_s")?,
        },
        Kind::Outliers => Component::Outliers {
            rate_hz: p.f64("rate_hz")?,
            scale: p.f64("scale")?,
        },
        Kind::Heteroskedastic => {
            let of = p.string("of")?;
            let of = Kind::from_name(&of).ok_or_else(|| {
                format!(
                    "{}: 'of' = '{of}' is not a component kind (expected a noise kind: {})",
                    p.place,
                    noise_kinds()
                )
            })?;
            Component::Heteroskedastic {
                of,
                slope: p.f64("slope")?,
            }
        }
        Kind::CrossAxis => Component::CrossAxis {
            from: p.string("from")?,
            gain: p.f64("gain")?,
        },
    })
}

const FARMA_INLINE_KEYS: &[&str] = &["p", "q", "d", "f", "ma", "sigma"];

fn decode_farma(p: &Fields<'_>) -> Result<FarmaModel, String> {
    let inline: Vec<&str> = FARMA_INLINE_KEYS
        .iter()
        .copied()
        .filter(|k| p.has(k))
        .collect();
    if p.has("model") {
        if let Some(first) = inline.first() {
            return Err(format!(
                "{}: give either 'model' (a fitted model) or the inline parameters p, q, d, f, ma, sigma, not both (found 'model' and '{first}')",
                p.place
            ));
        }
        return Ok(FarmaModel::Fitted {
            model: PathBuf::from(p.string("model")?),
            channel: p.opt_string("channel")?,
        });
    }
    if p.has("channel") {
        return Err(format!(
            "{}: 'channel' names a channel of a fitted model and needs 'model'",
            p.place
        ));
    }
    if inline.is_empty() {
        return Err(format!(
            "{}: missing parameter 'model' (a model written by farma fit) or the inline parameters p, q, d, f, ma, sigma",
            p.place
        ));
    }
    let size = |key: &str| -> Result<usize, String> {
        let v = p.uint(key)?;
        usize::try_from(v).map_err(|_| format!("{}: '{key}' = {v} is too large", p.place))
    };
    Ok(FarmaModel::Inline {
        p: size("p")?,
        q: size("q")?,
        d: size("d")?,
        f: p.matrix("f")?,
        ma: p.list("ma")?,
        sigma: p.f64("sigma")?,
    })
}

fn noise_kinds() -> String {
    let names: Vec<&str> = Kind::ALL
        .iter()
        .filter(|k| k.is_noise())
        .map(|k| k.as_str())
        .collect();
    names.join(", ")
}

// ---------------------------------------------------------------------------------
// Validation: ranges and cross-references, on the typed spec.

impl Spec {
    /// Checks values and cross-references (module doc); the message names the key.
    ///
    /// [`parse_spec`] runs this; a spec built in code (the noise-term identification)
    /// is checked by [`Spec::to_toml`].
    pub fn validate(&self) -> Result<(), String> {
        let rate = self.sample_rate_hz;
        if !(rate.is_finite() && rate > 0.0) {
            return Err(format!(
                "the top level: 'sample_rate_hz' must be > 0, found {rate}"
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

    fn validate_channel(&self, channel: &ChannelSpec) -> Result<(), String> {
        let name = &channel.name;
        if channel.components.is_empty() {
            return Err(format!(
                "channel '{name}' has no components (add [[channel.component]] tables)"
            ));
        }
        let kinds: HashSet<Kind> = channel.components.iter().map(Component::kind).collect();
        let mut modulated = HashSet::new();
        let mut sources = HashSet::new();
        for (i, component) in channel.components.iter().enumerate() {
            let place = format!(
                "channel '{name}' component {} ({})",
                i + 1,
                component.kind()
            );
            let check = Check { place: &place };
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
                            "{place}: 'tau_min_s' ({lo}) must be below 'tau_max_s' ({hi})"
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
                            "{place}: 'amplitude' must be >= 0, found {amplitude} (use 'phase_rad' to flip the sign)"
                        ));
                    }
                    check.non_negative("amplitude", *amplitude)?;
                    check.non_negative("freq_hz", *freq_hz)?;
                    check.finite("phase_rad", *phase_rad)?;
                    let nyquist = self.sample_rate_hz / 2.0;
                    if *freq_hz >= nyquist {
                        return Err(format!(
                            "{place}: 'freq_hz' = {freq_hz} must be below the Nyquist frequency {nyquist} Hz (sample_rate_hz / 2)"
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
                Component::ThermalRate { coeff, smoothing_s } => {
                    check.finite("coeff", *coeff)?;
                    check.non_negative("smoothing_s", *smoothing_s)?;
                }
                Component::Warmup { amplitude, tau_s } => {
                    check.finite("amplitude", *amplitude)?;
                    check.positive("tau_s", *tau_s)?;
                }
                Component::Outliers { rate_hz, scale } => {
                    check.non_negative("rate_hz", *rate_hz)?;
                    check.non_negative("scale", *scale)?;
                    if *rate_hz > self.sample_rate_hz {
                        return Err(format!(
                            "{place}: 'rate_hz' = {rate_hz} exceeds sample_rate_hz = {} (at most one outlier per sample)",
                            self.sample_rate_hz
                        ));
                    }
                }
                Component::Heteroskedastic { of, slope } => {
                    check.finite("slope", *slope)?;
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
            Err(format!("{}: '{key}' must be >= 0, found {x}", self.place))
        }
    }

    fn positive(&self, key: &str, x: f64) -> Result<(), String> {
        self.finite(key, x)?;
        if x > 0.0 {
            Ok(())
        } else {
            Err(format!("{}: '{key}' must be > 0, found {x}", self.place))
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

// ---------------------------------------------------------------------------------
// Writing.

impl Spec {
    /// The spec as TOML text that [`parse_spec`] reads back to an equal spec.
    ///
    /// The spec is validated first: a spec that farma builds and cannot write is a bug
    /// ([`Error::Internal`], exit code 1).
    pub fn to_toml(&self) -> Result<String> {
        self.validate()
            .map_err(|msg| Error::Internal(format!("writing a simulation spec: {msg}")))?;
        let mut out = String::new();
        out.push_str("# farma simulation spec (contracts.md section 2)\n");
        line(&mut out, "sample_rate_hz", float(self.sample_rate_hz));
        if let Some(t) = &self.temperature_channel {
            line(&mut out, "temperature_channel", string(t));
        }
        if let Some(seed) = self.seed {
            line(&mut out, "seed", seed.to_string());
        }
        for channel in &self.channels {
            out.push_str("\n[[channel]]\n");
            line(&mut out, "name", string(&channel.name));
            for component in &channel.components {
                out.push_str("\n[[channel.component]]\n");
                write_component(&mut out, component)?;
            }
        }
        Ok(out)
    }
}

fn line(out: &mut String, key: &str, value: String) {
    let _ = writeln!(out, "{key} = {value}");
}

fn float(x: f64) -> String {
    Value::Float(x).to_string()
}

fn string(s: &str) -> String {
    Value::String(s.to_string()).to_string()
}

fn floats(xs: &[f64]) -> String {
    let items: Vec<String> = xs.iter().map(|&x| float(x)).collect();
    format!("[{}]", items.join(", "))
}

fn write_component(out: &mut String, c: &Component) -> Result<()> {
    line(out, "kind", string(c.kind().as_str()));
    match c {
        Component::ConstantBias { value } => line(out, "value", float(*value)),
        Component::WhiteNoise { n } => line(out, "n", float(*n)),
        Component::Quantization { q } => line(out, "q", float(*q)),
        Component::BiasInstability {
            b,
            tau_min_s,
            tau_max_s,
        } => {
            line(out, "b", float(*b));
            if let Some(x) = tau_min_s {
                line(out, "tau_min_s", float(*x));
            }
            if let Some(x) = tau_max_s {
                line(out, "tau_max_s", float(*x));
            }
        }
        Component::RateRandomWalk { k } => line(out, "k", float(*k)),
        Component::RateRamp { r } => line(out, "r", float(*r)),
        Component::GaussMarkov { sigma, tau_s } => {
            line(out, "sigma", float(*sigma));
            line(out, "tau_s", float(*tau_s));
        }
        Component::Sinusoid {
            amplitude,
            freq_hz,
            phase_rad,
        } => {
            line(out, "amplitude", float(*amplitude));
            line(out, "freq_hz", float(*freq_hz));
            line(out, "phase_rad", float(*phase_rad));
        }
        Component::Arma { ar, ma, sigma } => {
            line(out, "ar", floats(ar));
            line(out, "ma", floats(ma));
            line(out, "sigma", float(*sigma));
        }
        Component::Farma(FarmaModel::Fitted { model, channel }) => {
            let path = model.to_str().ok_or_else(|| {
                Error::Internal(format!(
                    "writing a simulation spec: model path {} is not UTF-8",
                    model.display()
                ))
            })?;
            line(out, "model", string(path));
            if let Some(ch) = channel {
                line(out, "channel", string(ch));
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
            line(out, "p", p.to_string());
            line(out, "q", q.to_string());
            line(out, "d", d.to_string());
            let rows: Vec<String> = f.iter().map(|row| floats(row)).collect();
            line(out, "f", format!("[{}]", rows.join(", ")));
            line(out, "ma", floats(ma));
            line(out, "sigma", float(*sigma));
        }
        Component::TemperatureBias {
            coeffs,
            reference_c,
        } => {
            line(out, "coeffs", floats(coeffs));
            if let Some(t) = reference_c {
                line(out, "reference_c", float(*t));
            }
        }
        Component::ThermalRate { coeff, smoothing_s } => {
            line(out, "coeff", float(*coeff));
            line(out, "smoothing_s", float(*smoothing_s));
        }
        Component::Warmup { amplitude, tau_s } => {
            line(out, "amplitude", float(*amplitude));
            line(out, "tau_s", float(*tau_s));
        }
        Component::Outliers { rate_hz, scale } => {
            line(out, "rate_hz", float(*rate_hz));
            line(out, "scale", float(*scale));
        }
        Component::Heteroskedastic { of, slope } => {
            line(out, "of", string(of.as_str()));
            line(out, "slope", float(*slope));
        }
        Component::CrossAxis { from, gain } => {
            line(out, "from", string(from));
            line(out, "gain", float(*gain));
        }
    }
    Ok(())
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

    #[test]
    fn closest_suggests_typos_only() {
        assert_eq!(closest("nn", &["kind", "n"]), Some("n"));
        assert_eq!(closest("sigm", &["sigma", "tau_s"]), Some("sigma"));
        assert_eq!(closest("zzzzzz", &["sigma", "tau_s"]), None);
    }
}
