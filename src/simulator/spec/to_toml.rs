//! Writing a spec back out: [`Spec::to_toml`], TOML text that [`super::parse_spec`]
//! reads back to an equal spec.

use std::fmt::Write as _;

use toml::Value;

use super::{Component, Discretization, FarmaModel, Spec};
use crate::error::{Error, Result};

impl Spec {
    /// The spec as TOML text that [`parse_spec`](super::parse_spec) reads back to an equal spec.
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
        Component::ThermalRate {
            coeff,
            smoothing_s,
            lag_s,
        } => {
            line(out, "coeff", float(*coeff));
            line(out, "smoothing_s", float(*smoothing_s));
            if *lag_s > 0.0 {
                line(out, "lag_s", float(*lag_s));
            }
        }
        Component::Warmup { amplitude, tau_s } => {
            line(out, "amplitude", float(*amplitude));
            line(out, "tau_s", float(*tau_s));
        }
        Component::Outliers {
            rate_hz,
            scale,
            dof,
        } => {
            line(out, "rate_hz", float(*rate_hz));
            line(out, "scale", float(*scale));
            if let Some(d) = dof {
                line(out, "dof", float(*d));
            }
        }
        Component::Heteroskedastic {
            of,
            slope,
            floor,
            reference_c,
        } => {
            line(out, "of", string(of.as_str()));
            line(out, "slope", float(*slope));
            if *floor > 0.0 {
                line(out, "floor", float(*floor));
            }
            if let Some(r) = reference_c {
                line(out, "reference_c", float(*r));
            }
        }
        Component::CrossAxis { from, gain } => {
            line(out, "from", string(from));
            line(out, "gain", float(*gain));
        }
        Component::OutputFilter {
            order,
            bandwidth_hz,
            damping,
            discretization,
        } => {
            line(out, "order", order.to_string());
            line(out, "bandwidth_hz", float(*bandwidth_hz));
            if let Some(z) = damping {
                line(out, "damping", float(*z));
            }
            if *discretization != Discretization::Zoh {
                line(out, "discretization", string(discretization.as_str()));
            }
        }
        Component::OutputFir { taps } => {
            line(out, "form", string("fir"));
            line(out, "taps", floats(taps));
        }
        Component::Saturation { limit } => line(out, "limit", float(*limit)),
        Component::OutputResolution { quantum, on_angle } => {
            line(out, "quantum", float(*quantum));
            line(out, "on_angle", on_angle.to_string());
        }
    }
    Ok(())
}
