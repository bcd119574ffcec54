//! The simulation spec: `docs/contracts.md` section 2.
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
//! - The sensor's output path (output_filter, saturation, output_resolution) is not a
//!   term of the sum: it acts on the sum of the channel's other components, cross_axis
//!   included, in the order filter -> saturation -> resolution (the order of a
//!   sensor's output chain) whatever their order in the spec; at most one of each per
//!   channel, and a channel needs at least one component besides them. cross_axis
//!   couples the `from` channel's signal before its output path (the rate the other
//!   axis senses, not what it outputs).
//! - A farma `model` path is kept as written (relative paths are for the generator to
//!   resolve against the spec's folder); its existence is checked when it is loaded.
//!
//! Parsing is a walk over the TOML table rather than serde derive, so that every error
//! names its place in the spec the same way (`channel 'rate' component 2
//! (white_noise): missing parameter 'n'`) and unknown keys are caught for every kind.
//! Errors are [`Error::Format`](crate::error::Error::Format) (exit code 2) naming the
//! spec file; TOML syntax errors are [`Error::Malformed`](crate::error::Error::Malformed)
//! with the line and column the parser reports.
//!
//! The spec's types and kinds are here; `parse.rs` reads the TOML into them
//! ([`load_spec`], [`parse_spec`]), `validate.rs` checks ranges and cross-references on
//! the typed spec ([`Spec::validate`], [`ar_is_stationary`]), and `to_toml.rs` writes a
//! spec back out ([`Spec::to_toml`]).

mod parse;
mod to_toml;
mod validate;

use std::path::PathBuf;

pub use parse::{load_spec, parse_spec};
pub use validate::ar_is_stationary;

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
    /// temperature passed through a first-order lag of `lag_s` \[s\] >= 0 (the sensing
    /// element's temperature behind the logged one; 0: none), then smoothed over
    /// `smoothing_s` \[s\] >= 0 before differencing.
    ThermalRate {
        coeff: f64,
        smoothing_s: f64,
        lag_s: f64,
    },
    /// Warm-up bias amplitude exp(-t / tau_s): `amplitude` \[u\] (any sign), `tau_s` \[s\] > 0.
    Warmup { amplitude: f64, tau_s: f64 },
    /// Outliers at `rate_hz` [1/s] (0 ..= sample_rate_hz) with size `scale` \[u\] >= 0:
    /// each amplitude `scale` times a standard normal draw, or with `dof` (>= 1) a
    /// Student-t draw of `dof` degrees of freedom (heavy-tailed spikes; `scale` is then
    /// the t's scale, not its standard deviation).
    Outliers {
        rate_hz: f64,
        scale: f64,
        dof: Option<f64>,
    },
    /// The scale of the channel's `of` noise component varies with temperature:
    /// scale = max(floor, 1 + slope (T - T_ref)); `slope` [1/degC], `floor` (unitless,
    /// 0 <= floor < 1, default 0) the level the scale does not fall below, T_ref =
    /// `reference_c` \[degC\] (default: the log's mean temperature), where the
    /// unclamped scale is 1.
    Heteroskedastic {
        of: Kind,
        slope: f64,
        floor: f64,
        reference_c: Option<f64>,
    },
    /// Cross-axis coupling: `gain` (any sign) times the signal of channel `from`.
    CrossAxis { from: String, gain: f64 },
    /// Output resolution: every output sample rounded to a multiple of `quantum` \[u\]
    /// (> 0, the LSB in the rate unit). With `on_angle` (default false) the angle is
    /// quantized instead, to steps of `quantum` / sample_rate_hz \[u s\], and the rate
    /// is its first difference divided by the sample interval (as FOG outputs are):
    /// the rate values still sit on the grid of `quantum`, and the rounding error is
    /// carried from sample to sample instead of lost. Last stage of the output path.
    OutputResolution { quantum: f64, on_angle: bool },
    /// The sensor's low-pass output filter, of `order` 1 or 2, with natural frequency
    /// `bandwidth_hz` \[Hz\] > 0 (the -3 dB frequency of order 1, and of order 2 at
    /// damping 1/sqrt(2)) and, for order 2, `damping` ratio > 0 (default 1/sqrt(2),
    /// Butterworth), discretized as `discretization` says ([`Discretization`]).
    /// First stage of the output path.
    OutputFilter {
        order: usize,
        bandwidth_hz: f64,
        damping: Option<f64>,
        discretization: Discretization,
    },
    /// The sensor's output filter as a finite impulse response (`form = "fir"`):
    /// y_t = sum_k taps\[k\] x_{t-k}, `taps` unitless, 1 ..= [`MAX_FIR_TAPS`] finite
    /// values, the history before the first sample zero. Its DC gain is the sum of the
    /// taps (no normalization). Kind `output_filter`, first stage of the output path.
    OutputFir { taps: Vec<f64> },
    /// Saturation at the measurement range: every sample clamped to \[-limit, limit\],
    /// `limit` \[u\] > 0. Between the filter and the output resolution.
    Saturation { limit: f64 },
}

/// How an output filter's continuous low-pass becomes a digital one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Discretization {
    /// Zero-order hold (`"zoh"`, the default): each input sample held over its
    /// interval, the output the continuous filter's state at the interval's end; exact
    /// for any bandwidth, even above the Nyquist frequency (an analog filter sampled).
    #[default]
    Zoh,
    /// The bilinear transform with the bandwidth prewarped (`"bilinear"`): the digital
    /// Butterworth of a sensor's DSP as filter-design tools give it (scipy.signal.butter
    /// with fs, MATLAB butter), exact -3 dB point at bandwidth_hz (order 1, and order 2
    /// at damping 1/sqrt(2)) and a zero at the Nyquist frequency; the bandwidth must be
    /// below the Nyquist frequency.
    Bilinear,
}

impl Discretization {
    /// The name in a spec.
    pub fn as_str(self) -> &'static str {
        match self {
            Discretization::Zoh => "zoh",
            Discretization::Bilinear => "bilinear",
        }
    }
}

/// The most taps of an `output_filter` of form "fir".
pub const MAX_FIR_TAPS: usize = 64;

/// The default damping ratio of a second-order output filter (Butterworth).
pub const DEFAULT_DAMPING: f64 = std::f64::consts::FRAC_1_SQRT_2;

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
    OutputFilter,
    Saturation,
    OutputResolution,
}

impl Kind {
    /// Every kind, in the order of the contract's table.
    pub const ALL: [Kind; 19] = [
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
        Kind::OutputFilter,
        Kind::Saturation,
        Kind::OutputResolution,
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
            Kind::OutputFilter => "output_filter",
            Kind::Saturation => "saturation",
            Kind::OutputResolution => "output_resolution",
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

    /// A stage of the sensor's output path (output_filter, saturation,
    /// output_resolution): applied to the sum of the channel's other components (its
    /// cross_axis couplings included), in the fixed order filter -> saturation ->
    /// resolution whatever their order in the spec; not a term of the sum.
    pub fn is_output_path(self) -> bool {
        matches!(
            self,
            Kind::OutputFilter | Kind::Saturation | Kind::OutputResolution
        )
    }

    /// The position of an output-path stage in the output path (0 first), else None.
    pub fn output_stage(self) -> Option<usize> {
        match self {
            Kind::OutputFilter => Some(0),
            Kind::Saturation => Some(1),
            Kind::OutputResolution => Some(2),
            _ => None,
        }
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
            Kind::ThermalRate => &["coeff", "smoothing_s", "lag_s"],
            Kind::Warmup => &["amplitude", "tau_s"],
            Kind::Outliers => &["rate_hz", "scale", "dof"],
            Kind::Heteroskedastic => &["of", "slope", "floor", "reference_c"],
            Kind::CrossAxis => &["from", "gain"],
            Kind::OutputFilter => &[
                "form",
                "order",
                "bandwidth_hz",
                "damping",
                "discretization",
                "taps",
            ],
            Kind::Saturation => &["limit"],
            Kind::OutputResolution => &["quantum", "on_angle"],
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
            Component::OutputFilter { .. } | Component::OutputFir { .. } => Kind::OutputFilter,
            Component::Saturation { .. } => Kind::Saturation,
            Component::OutputResolution { .. } => Kind::OutputResolution,
        }
    }
}

/// The noise kinds' names, as a list for messages.
fn noise_kinds() -> String {
    let names: Vec<&str> = Kind::ALL
        .iter()
        .filter(|k| k.is_noise())
        .map(|k| k.as_str())
        .collect();
    names.join(", ")
}
