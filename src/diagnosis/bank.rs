//! The project's own test bank for the diagnosis: each candidate effect hidden in turn
//! from a spec. A "real" log is simulated from the spec plus the hidden effect (with an
//! independent seed); the diagnosis gets the spec without it and must rank the hidden
//! effect first and bring the withheld-part gap near the noise floor.
//!
//! The base spec is a MEMS-like gyro at `rate_hz`: white noise n = 0.01 u sqrt(s) and
//! bias instability b = 0.002 u. The temperature, where a case uses one, warms by
//! 5 degC with a 30-minute time constant and cycles by +-1.5 degC with a one-hour
//! period (a climatic-chamber profile).

use crate::error::Result;
use crate::simulator::{ChannelSpec, Component, Kind, SimRequest, Spec, simulate};

/// One case of the bank.
#[derive(Clone, Debug)]
pub struct Case {
    /// The kind the diagnosis should find (`recalibrate:<kind>` for a wrong parameter).
    pub expect: String,
    /// The spec handed to the diagnosis.
    pub spec: Spec,
    /// The spec the "real" log was simulated from.
    pub truth: Spec,
}

/// The channel every case diagnoses.
pub const CHANNEL: &str = "rate";
/// The temperature channel of cases that use one.
pub const TEMP: &str = "temp_c";

/// The base spec.
pub fn base_spec(rate_hz: f64, with_temperature: bool) -> Spec {
    Spec {
        sample_rate_hz: rate_hz,
        temperature_channel: with_temperature.then(|| TEMP.to_string()),
        seed: Some(11),
        channels: vec![ChannelSpec {
            name: CHANNEL.into(),
            components: vec![
                Component::WhiteNoise { n: 0.01 },
                Component::BiasInstability {
                    b: 0.002,
                    tau_min_s: None,
                    tau_max_s: None,
                },
            ],
        }],
    }
}

/// The chamber temperature profile, degC.
pub fn temperature_profile(n: usize, rate_hz: f64) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let t = k as f64 / rate_hz;
            25.0 + 5.0 * (1.0 - (-t / 1800.0).exp())
                + 1.5 * (2.0 * std::f64::consts::PI * t / 3600.0).sin()
        })
        .collect()
}

/// Every case for a log of `duration_s`. Each hidden effect is sized to matter in an
/// hour of data (its gap several times the noise floor), not to sit at the edge of
/// detection. The warm-up's time constant is a sixth of the log (600 s in an hour);
/// warm-ups shorter than block 0 are tested in the suite (`tests/suite/gap.rs`).
pub fn cases(rate_hz: f64, duration_s: f64) -> Vec<Case> {
    let mut out = Vec::new();
    let mut add = |expect: &str,
                   comp: Option<Component>,
                   temp: bool,
                   truth_edit: Option<(usize, Component)>| {
        let spec = base_spec(rate_hz, temp);
        let mut truth = spec.clone();
        if let Some(c) = comp {
            truth.channels[0].components.push(c);
        }
        if let Some((k, c)) = truth_edit {
            truth.channels[0].components[k] = c;
        }
        out.push(Case {
            expect: expect.into(),
            spec,
            truth,
        });
    };
    use Component as C;
    add(
        "constant_bias",
        Some(C::ConstantBias { value: 0.03 }),
        false,
        None,
    );
    add("rate_ramp", Some(C::RateRamp { r: 6e-6 }), false, None);
    add(
        "warmup",
        Some(C::Warmup {
            amplitude: 0.08,
            tau_s: duration_s / 6.0,
        }),
        false,
        None,
    );
    add(
        "sinusoid",
        Some(C::Sinusoid {
            amplitude: 0.01,
            freq_hz: 0.05,
            phase_rad: 0.3,
        }),
        false,
        None,
    );
    add(
        "outliers",
        Some(C::Outliers {
            rate_hz: 0.01,
            scale: 0.3,
            dof: None,
        }),
        false,
        None,
    );
    add(
        "quantization",
        Some(C::Quantization { q: 0.003 }),
        false,
        None,
    );
    add(
        "rate_random_walk",
        Some(C::RateRandomWalk { k: 3e-4 }),
        false,
        None,
    );
    add(
        "gauss_markov",
        Some(C::GaussMarkov {
            sigma: 0.006,
            tau_s: 20.0,
        }),
        false,
        None,
    );
    add(
        "recalibrate:white_noise",
        None,
        false,
        Some((0, C::WhiteNoise { n: 0.02 })),
    );
    add(
        "temperature_bias",
        Some(C::TemperatureBias {
            coeffs: vec![0.01],
            reference_c: None,
        }),
        true,
        None,
    );
    add(
        "thermal_rate",
        Some(C::ThermalRate {
            coeff: 6.0,
            smoothing_s: 30.0,
            lag_s: 0.0,
        }),
        true,
        None,
    );
    add(
        "heteroskedastic",
        Some(C::Heteroskedastic {
            of: Kind::WhiteNoise,
            slope: 0.12,
            floor: 0.0,
            reference_c: None,
        }),
        true,
        None,
    );
    out
}

/// A "real" log for `case`: (rate channel, temperature if the case uses one).
pub fn real_log(case: &Case, n: usize, seed: u64) -> Result<(Vec<f64>, Option<Vec<f64>>)> {
    let rate_hz = case.truth.sample_rate_hz;
    let temp = case
        .truth
        .temperature_channel
        .as_ref()
        .map(|_| temperature_profile(n, rate_hz));
    let mut req = SimRequest::new(n, rate_hz);
    req.temperature_c = temp.as_deref();
    req.seed = Some(seed);
    let sim = simulate(&case.truth, &req)?;
    let x = sim.channel(CHANNEL).unwrap_or_default().to_vec();
    Ok((x, temp))
}
