//! Reading a spec: the TOML text walked into a typed [`Spec`], each error naming its
//! place (`channel 'rate' component 2 (white_noise): missing parameter 'n'`), unknown
//! keys caught for every kind with the nearest allowed name suggested; then
//! [`Spec::validate`].

use std::path::{Path, PathBuf};

use toml::{Table, Value};

use super::{ChannelSpec, Component, Discretization, FarmaModel, Kind, Spec, noise_kinds};
use crate::error::{Error, Result};

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

    fn opt_bool(&self, key: &str) -> Result<Option<bool>, String> {
        match self.table.get(key) {
            None => Ok(None),
            Some(Value::Boolean(b)) => Ok(Some(*b)),
            Some(v) => Err(self.wrong(key, "a boolean (true or false)", v)),
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
            lag_s: p.opt_f64("lag_s")?.unwrap_or(0.0),
        },
        Kind::Warmup => Component::Warmup {
            amplitude: p.f64("amplitude")?,
            tau_s: p.f64("tau_s")?,
        },
        Kind::Outliers => Component::Outliers {
            rate_hz: p.f64("rate_hz")?,
            scale: p.f64("scale")?,
            dof: p.opt_f64("dof")?,
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
                floor: p.opt_f64("floor")?.unwrap_or(0.0),
                reference_c: p.opt_f64("reference_c")?,
            }
        }
        Kind::CrossAxis => Component::CrossAxis {
            from: p.string("from")?,
            gain: p.f64("gain")?,
        },
        Kind::OutputFilter => {
            match p.opt_string("form")?.as_deref() {
                None | Some("lowpass") => {
                    if p.has("taps") {
                        return Err(format!(
                            "{}: 'taps' belongs to form = \"fir\"; a low-pass (form = \"lowpass\", the default) takes order, bandwidth_hz, damping, discretization",
                            p.place
                        ));
                    }
                }
                Some("fir") => {
                    if let Some(k) = ["order", "bandwidth_hz", "damping", "discretization"]
                        .into_iter()
                        .find(|k| p.has(k))
                    {
                        return Err(format!(
                            "{}: '{k}' belongs to the low-pass form; form = \"fir\" takes only 'taps'",
                            p.place
                        ));
                    }
                    return Ok(Component::OutputFir {
                        taps: p.list("taps")?,
                    });
                }
                Some(_) => {
                    let v = p.get("form")?;
                    return Err(p.wrong("form", "\"lowpass\" or \"fir\"", v));
                }
            }
            let v = p.get("order")?;
            let order = match v.as_integer() {
                Some(o @ (1 | 2)) => o as usize,
                _ => return Err(p.wrong("order", "1 or 2", v)),
            };
            let discretization = match p.opt_string("discretization")?.as_deref() {
                None | Some("zoh") => Discretization::Zoh,
                Some("bilinear") => Discretization::Bilinear,
                Some(_) => {
                    let v = p.get("discretization")?;
                    return Err(p.wrong("discretization", "\"zoh\" or \"bilinear\"", v));
                }
            };
            Component::OutputFilter {
                order,
                bandwidth_hz: p.f64("bandwidth_hz")?,
                damping: p.opt_f64("damping")?,
                discretization,
            }
        }
        Kind::Saturation => Component::Saturation {
            limit: p.f64("limit")?,
        },
        Kind::OutputResolution => Component::OutputResolution {
            quantum: p.f64("quantum")?,
            on_angle: p.opt_bool("on_angle")?.unwrap_or(false),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_suggests_typos_only() {
        assert_eq!(closest("nn", &["kind", "n"]), Some("n"));
        assert_eq!(closest("sigm", &["sigma", "tau_s"]), Some("sigma"));
        assert_eq!(closest("zzzzzz", &["sigma", "tau_s"]), None);
    }
}
