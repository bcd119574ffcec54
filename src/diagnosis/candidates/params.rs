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
        C::ThermalRate {
            coeff,
            smoothing_s,
            lag_s,
        } => C::ThermalRate {
            coeff: coeff * s,
            smoothing_s: *smoothing_s,
            lag_s: *lag_s,
        },
        C::Warmup { amplitude, tau_s } => C::Warmup {
            amplitude: amplitude * s,
            tau_s: *tau_s,
        },
        C::Outliers {
            rate_hz,
            scale,
            dof,
        } => C::Outliers {
            rate_hz: *rate_hz,
            scale: scale * s_pos,
            dof: *dof,
        },
        C::CrossAxis { from, gain } => C::CrossAxis {
            from: from.clone(),
            gain: gain * s,
        },
        C::Farma(_)
        | C::Heteroskedastic { .. }
        | C::OutputFilter { .. }
        | C::OutputFir { .. }
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

/// Marks parameter `name` of an estimate as stopped at an end of its search range
/// [lo, hi] (within 1e-6 relative): `at_search_edge` lists such parameters in the
/// params object, and the note says that the value is a bound, not an estimate.
/// Returns whether it was at an edge.
pub(super) fn flag_edge(
    params: &mut Value,
    note: &mut String,
    name: &str,
    value: f64,
    lo: f64,
    hi: f64,
) -> bool {
    let near = |a: f64, b: f64| (a - b).abs() <= 1e-6 * a.abs().max(b.abs());
    let side = if near(value, lo) {
        "lower"
    } else if near(value, hi) {
        "upper"
    } else {
        return false;
    };
    list_param(params, "at_search_edge", name);
    note.push_str(&format!(
        "; {name} = {value:.4e} is the {side} end of its search range [{lo:.4e}, {hi:.4e}]: a bound, not an estimate"
    ));
    true
}

/// Marks parameter `name` of an estimate as not determined by the data: its value
/// `value` is at an end of its search range, and the inner value `inner` fits as well
/// (both in `unit`, e.g. " s"). `undetermined` lists such parameters in the params
/// object, and the note says so.
pub(super) fn flag_undetermined(
    params: &mut Value,
    note: &mut String,
    name: &str,
    [value, inner]: [f64; 2],
    unit: &str,
) {
    list_param(params, "undetermined", name);
    note.push_str(&format!(
        "; {name}: {}{unit} fits no better than {}{unit} within one standard error over the training ranges, so the data do not determine it",
        crate::fmt::num(value),
        crate::fmt::num(inner)
    ));
}

/// Appends `name` to the array `key` of the params object (created when absent).
fn list_param(params: &mut Value, key: &str, name: &str) {
    if let Value::Object(m) = params {
        let list = m.entry(key).or_insert_with(|| Value::Array(Vec::new()));
        if let Value::Array(a) = list {
            a.push(Value::String(name.to_string()));
        }
    }
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
        C::Farma(crate::simulator::FarmaModel::Inline {
            p,
            q,
            d,
            f,
            ma,
            sigma,
        }) => json!({ "p": p, "q": q, "d": d, "f": f, "ma": ma, "sigma": sigma }),
        C::Farma(crate::simulator::FarmaModel::Fitted { model, channel }) => {
            json!({ "model": model.display().to_string(), "channel": channel })
        }
        C::TemperatureBias {
            coeffs,
            reference_c,
        } => json!({ "coeffs": coeffs, "reference_c": reference_c }),
        C::ThermalRate {
            coeff,
            smoothing_s,
            lag_s,
        } => {
            let mut p = json!({ "coeff": coeff, "smoothing_s": smoothing_s });
            if *lag_s > 0.0 {
                p["lag_s"] = json!(lag_s);
            }
            p
        }
        C::Warmup { amplitude, tau_s } => json!({ "amplitude": amplitude, "tau_s": tau_s }),
        C::Outliers {
            rate_hz,
            scale,
            dof,
        } => {
            let mut p = json!({ "rate_hz": rate_hz, "scale": scale });
            if let Some(d) = dof {
                p["dof"] = json!(d);
            }
            p
        }
        C::Heteroskedastic {
            of,
            slope,
            floor,
            reference_c,
        } => {
            let mut p = json!({ "of": of.as_str(), "slope": slope });
            if *floor > 0.0 {
                p["floor"] = json!(floor);
            }
            if let Some(r) = reference_c {
                p["reference_c"] = json!(r);
            }
            p
        }
        C::CrossAxis { from, gain } => json!({ "from": from, "gain": gain }),
        C::OutputFilter {
            order,
            bandwidth_hz,
            damping,
            discretization,
        } => json!({
            "order": order,
            "bandwidth_hz": bandwidth_hz,
            "damping": damping,
            "discretization": discretization.as_str()
        }),
        C::OutputFir { taps } => json!({ "form": "fir", "taps": taps }),
        C::Saturation { limit } => json!({ "limit": limit }),
        C::OutputResolution { quantum, on_angle } => {
            json!({ "quantum": quantum, "on_angle": on_angle })
        }
    }
}

#[cfg(test)]
mod edge_tests {
    use super::{flag_edge, flag_undetermined};
    use serde_json::json;

    #[test]
    fn a_value_at_an_end_of_its_range_is_flagged_and_one_inside_is_not() {
        let mut p = json!({"sigma": 1.0, "tau_s": 0.02});
        let mut note = String::from("grid");
        assert!(flag_edge(&mut p, &mut note, "tau_s", 0.02, 0.02, 400.0));
        assert_eq!(p["at_search_edge"], json!(["tau_s"]));
        assert!(
            note.contains("lower end") && note.contains("a bound, not an estimate"),
            "{note}"
        );
        let mut q = json!({"tau_s": 400.0});
        let mut note = String::new();
        assert!(flag_edge(
            &mut q,
            &mut note,
            "tau_s",
            400.0 * (1.0 + 1e-9),
            0.02,
            400.0
        ));
        assert!(note.contains("upper end"));
        let mut r = json!({"tau_s": 3.0});
        let mut note = String::new();
        assert!(!flag_edge(&mut r, &mut note, "tau_s", 3.0, 0.02, 400.0));
        assert!(r.get("at_search_edge").is_none() && note.is_empty());
    }

    #[test]
    fn an_undetermined_value_is_listed_beside_a_bound_and_named_in_the_note() {
        let mut p = json!({"lag_s": 10.0, "smoothing_s": 1000.0});
        let mut note = String::from("fold 1");
        assert!(flag_edge(&mut p, &mut note, "lag_s", 10.0, 10.0, 900.0));
        flag_undetermined(&mut p, &mut note, "smoothing_s", [1000.0, 30.0], " s");
        assert_eq!(p["at_search_edge"], json!(["lag_s"]));
        assert_eq!(p["undetermined"], json!(["smoothing_s"]));
        assert!(
            note.ends_with("; smoothing_s: 1000 s fits no better than 30 s within one standard error over the training ranges, so the data do not determine it"),
            "{note}"
        );
    }
}
