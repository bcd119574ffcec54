//! A component's size parameter and its parameters as JSON: scaling a component (what a
//! recalibration proposes), whether its size acts through the Allan variance or the
//! mean, and the parameter keys of contracts.md section 2 that a proposal reports.

use serde_json::{Value, json};

use crate::simulator::Component;

/// The size parameter of a component scaled by `s` (None: no such parameter).
pub fn scaled(c: &Component, s: f64) -> Option<Component> {
    use Component as C;
    let s_pos = s.max(0.0);
    Some(match c {
        C::ConstantBias { value } => C::ConstantBias { value: value * s },
        C::WhiteNoise { n } => C::WhiteNoise { n: n * s_pos },
        C::Quantization { q } => C::Quantization { q: q * s_pos },
        C::BiasInstability {
            b,
            tau_min_s,
            tau_max_s,
        } => C::BiasInstability {
            b: b * s_pos,
            tau_min_s: *tau_min_s,
            tau_max_s: *tau_max_s,
        },
        C::RateRandomWalk { k } => C::RateRandomWalk { k: k * s_pos },
        C::RateRamp { r } => C::RateRamp { r: r * s },
        C::GaussMarkov { sigma, tau_s } => C::GaussMarkov {
            sigma: sigma * s_pos,
            tau_s: *tau_s,
        },
        C::Sinusoid {
            amplitude,
            freq_hz,
            phase_rad,
        } => C::Sinusoid {
            amplitude: amplitude * s_pos,
            freq_hz: *freq_hz,
            phase_rad: *phase_rad,
        },
        C::Arma { ar, ma, sigma } => C::Arma {
            ar: ar.clone(),
            ma: ma.clone(),
            sigma: sigma * s_pos,
        },
        C::TemperatureBias {
            coeffs,
            reference_c,
        } => C::TemperatureBias {
            coeffs: coeffs.iter().map(|v| v * s).collect(),
            reference_c: *reference_c,
        },
        C::ThermalRate { coeff, smoothing_s } => C::ThermalRate {
            coeff: coeff * s,
            smoothing_s: *smoothing_s,
        },
        C::Warmup { amplitude, tau_s } => C::Warmup {
            amplitude: amplitude * s,
            tau_s: *tau_s,
        },
        C::Outliers { rate_hz, scale } => C::Outliers {
            rate_hz: *rate_hz,
            scale: scale * s_pos,
        },
        C::CrossAxis { from, gain } => C::CrossAxis {
            from: from.clone(),
            gain: gain * s,
        },
        C::Farma(_)
        | C::Heteroskedastic { .. }
        | C::OutputFilter { .. }
        | C::Saturation { .. }
        | C::OutputResolution { .. } => return None,
    })
}

/// Whether the size of a component acts through the Allan variance (noise) or through
/// the mean (deterministic).
pub(super) fn is_noise(c: &Component) -> bool {
    matches!(
        c,
        Component::WhiteNoise { .. }
            | Component::Quantization { .. }
            | Component::BiasInstability { .. }
            | Component::RateRandomWalk { .. }
            | Component::GaussMarkov { .. }
            | Component::Arma { .. }
    )
}

/// The parameters of a component as JSON (the keys of contracts.md section 2).
pub fn params_json(c: &Component) -> Value {
    use Component as C;
    match c {
        C::ConstantBias { value } => json!({ "value": value }),
        C::WhiteNoise { n } => json!({ "n": n }),
        C::Quantization { q } => json!({ "q": q }),
        C::BiasInstability {
            b,
            tau_min_s,
            tau_max_s,
        } => json!({ "b": b, "tau_min_s": tau_min_s, "tau_max_s": tau_max_s }),
        C::RateRandomWalk { k } => json!({ "k": k }),
        C::RateRamp { r } => json!({ "r": r }),
        C::GaussMarkov { sigma, tau_s } => json!({ "sigma": sigma, "tau_s": tau_s }),
        C::Sinusoid {
            amplitude,
            freq_hz,
            phase_rad,
        } => json!({ "amplitude": amplitude, "freq_hz": freq_hz, "phase_rad": phase_rad }),
        C::Arma { ar, ma, sigma } => json!({ "ar": ar, "ma": ma, "sigma": sigma }),
        C::Farma(_) => json!({}),
        C::TemperatureBias {
            coeffs,
            reference_c,
        } => json!({ "coeffs": coeffs, "reference_c": reference_c }),
        C::ThermalRate { coeff, smoothing_s } => {
            json!({ "coeff": coeff, "smoothing_s": smoothing_s })
        }
        C::Warmup { amplitude, tau_s } => json!({ "amplitude": amplitude, "tau_s": tau_s }),
        C::Outliers { rate_hz, scale } => json!({ "rate_hz": rate_hz, "scale": scale }),
        C::Heteroskedastic { of, slope } => json!({ "of": of.as_str(), "slope": slope }),
        C::CrossAxis { from, gain } => json!({ "from": from, "gain": gain }),
        C::OutputFilter {
            order,
            bandwidth_hz,
            damping,
        } => json!({ "order": order, "bandwidth_hz": bandwidth_hz, "damping": damping }),
        C::Saturation { limit } => json!({ "limit": limit }),
        C::OutputResolution { quantum, on_angle } => {
            json!({ "quantum": quantum, "on_angle": on_angle })
        }
    }
}
