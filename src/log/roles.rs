//! Channel roles: which channels of a log are gyro axes, temperatures, accelerometer
//! axes, or something else, from their names (and the units written into them:
//! `gyro_x_dps`, `temp_degc`, `accel_z_g`). One classifier, used by `farma analyze`
//! (what `--channel all` takes) and `farma batch` (the `[roles]` of a job file).
//!
//! A role is a list of case-insensitive glob patterns (`*` any run of characters, `?`
//! one, `[xyz]` one of). A channel takes the first role whose patterns match, in the
//! order: explicit overrides (`farma analyze --role NAME=ROLE`, an input's own `gyro`
//! patterns in a job file; the last given first), temperature, accelerometer, gyro;
//! otherwise it is `other`. Temperature and accelerometer come before gyro so that a
//! gyro's own temperature sensor (`gyro_temp`) or an accelerometer's rate-of-change
//! column is not taken for a rate axis. Every classification carries its reason in
//! words ("name ends in _dps"), for the summaries that say why a channel was taken.

use crate::error::{Error, Result};

/// The default patterns of the gyro role (angular rate: deg/s, rad/s, rev/s, deg/h):
/// the units first, so that the reason a channel gives is its unit when it has one.
pub const GYRO_PATTERNS: &[&str] = &[
    "*_dps", "*_rps", "*_rad_s", "*_rads", "*_degps", "*_deg_s", "*_degph", "*_deg_h", "*_dph",
    "*gyro*", "rate*", "*_rate", "*_rate_*", "omega*", "g[xyz]", "g[xyz]_*", "w[xyz]",
];
/// The default patterns of the temperature role (units first).
pub const TEMPERATURE_PATTERNS: &[&str] = &[
    "*_degc",
    "*_degf",
    "*_celsius",
    "temp*",
    "*_temp",
    "*_temp_*",
    "*temperature*",
];
/// The default patterns of the accelerometer role (g, mg, m/s^2; units first).
pub const ACCEL_PATTERNS: &[&str] = &[
    "*_g", "*_mg", "*_mps2", "*_m_s2", "*_ms2", "*accel*", "acc_*", "acc[xyz]", "*_acc", "*_acc_*",
    "a[xyz]", "a[xyz]_*",
];

/// What a channel is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Role {
    Gyro,
    Temperature,
    Accel,
    Other,
}

impl Role {
    pub fn as_str(&self) -> &'static str {
        match self {
            Role::Gyro => "gyro",
            Role::Temperature => "temperature",
            Role::Accel => "accel",
            Role::Other => "other",
        }
    }

    /// The role a word names: `gyro`, `temperature` (or `temp`), `accel` (or
    /// `accelerometer`), `other`.
    pub fn parse(s: &str) -> Option<Role> {
        match s.trim().to_ascii_lowercase().as_str() {
            "gyro" => Some(Role::Gyro),
            "temperature" | "temp" => Some(Role::Temperature),
            "accel" | "accelerometer" => Some(Role::Accel),
            "other" => Some(Role::Other),
            _ => None,
        }
    }

    /// The role in words, for summaries ("accelerometer").
    pub fn words(&self) -> &'static str {
        match self {
            Role::Gyro => "gyro",
            Role::Temperature => "temperature",
            Role::Accel => "accelerometer",
            Role::Other => "other",
        }
    }
}

/// Where an override came from, for the reason it gives.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Override {
    /// A channel name or pattern.
    pub pattern: String,
    pub role: Role,
    /// How it was given, quoted in the reason (`--role gyro_x=accel`).
    pub source: String,
}

/// Channel-name patterns per role, and explicit overrides.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Roles {
    pub gyro: Vec<String>,
    pub temperature: Vec<String>,
    pub accel: Vec<String>,
    /// Checked first, the last one first.
    pub overrides: Vec<Override>,
}

/// A channel's role and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Classified {
    pub role: Role,
    /// In words: "name ends in _dps", "set by --role gyro_x=accel", "no role pattern
    /// matches".
    pub reason: String,
}

fn owned(p: &[&str]) -> Vec<String> {
    p.iter().map(|s| s.to_string()).collect()
}

impl Default for Roles {
    fn default() -> Self {
        Roles {
            gyro: owned(GYRO_PATTERNS),
            temperature: owned(TEMPERATURE_PATTERNS),
            accel: owned(ACCEL_PATTERNS),
            overrides: Vec::new(),
        }
    }
}

impl Roles {
    /// The role of `channel` and the reason.
    pub fn classify(&self, channel: &str) -> Classified {
        for o in self.overrides.iter().rev() {
            if name_matches(&o.pattern, channel) {
                return Classified {
                    role: o.role,
                    reason: format!("set by {}", o.source),
                };
            }
        }
        for (role, patterns) in [
            (Role::Temperature, &self.temperature),
            (Role::Accel, &self.accel),
            (Role::Gyro, &self.gyro),
        ] {
            if let Some(p) = patterns.iter().find(|p| name_matches(p, channel)) {
                return Classified {
                    role,
                    reason: describe(p),
                };
            }
        }
        Classified {
            role: Role::Other,
            reason: "no role pattern matches".into(),
        }
    }

    /// The role of `channel`.
    pub fn role(&self, channel: &str) -> Role {
        self.classify(channel).role
    }

    /// Whether `channel` has the gyro role.
    pub fn is_gyro(&self, channel: &str) -> bool {
        self.role(channel) == Role::Gyro
    }

    /// Whether `channel` has the temperature role.
    pub fn is_temperature(&self, channel: &str) -> bool {
        self.role(channel) == Role::Temperature
    }

    /// These roles with the gyro patterns replaced by `gyro` (a batch input's own),
    /// which then also come before the temperature and accelerometer patterns.
    pub fn for_input(&self, gyro: &Option<Vec<String>>) -> Roles {
        match gyro {
            Some(g) => {
                let mut r = self.clone();
                r.gyro = g.clone();
                r.overrides.extend(g.iter().map(|p| Override {
                    pattern: p.clone(),
                    role: Role::Gyro,
                    source: format!("the input's gyro pattern {p}"),
                }));
                r
            }
            None => self.clone(),
        }
    }

    /// Adds an override from a `NAME=ROLE` flag value (`--role` of `flag`): NAME a
    /// channel name or pattern. A usage error names a bad value.
    pub fn add_override(&mut self, flag: &str, value: &str) -> Result<()> {
        let (name, role) = value.split_once('=').ok_or_else(|| {
            Error::Usage(format!(
                "{flag} {value}: not NAME=ROLE (ROLE one of gyro, temperature, accel, other)"
            ))
        })?;
        let name = name.trim();
        let role = Role::parse(role).ok_or_else(|| {
            Error::Usage(format!(
                "{flag} {value}: '{}' is not a role (gyro, temperature, accel, other)",
                role.trim()
            ))
        })?;
        if name.is_empty() {
            return Err(Error::Usage(format!("{flag} {value}: no channel name")));
        }
        self.overrides.push(Override {
            pattern: name.to_string(),
            role,
            source: format!("{flag} {name}={}", role.as_str()),
        });
        Ok(())
    }
}

/// A channel-name pattern: `*` any run of characters, `?` one, `[..]` one of,
/// case-insensitive.
pub fn name_matches(pattern: &str, name: &str) -> bool {
    glob::Pattern::new(&pattern.to_ascii_lowercase())
        .map(|p| p.matches(&name.to_ascii_lowercase()))
        .unwrap_or(false)
}

/// A pattern in words: `*_dps` "name ends in _dps", `temp*` "name starts with temp",
/// `*accel*` "name contains accel", `gx` "name is gx", else "name matches PATTERN".
pub fn describe(pattern: &str) -> String {
    let special = |s: &str| s.contains(['*', '?', '[']);
    if !special(pattern) {
        return format!("name is {pattern}");
    }
    if let Some(mid) = pattern
        .strip_prefix('*')
        .and_then(|s| s.strip_suffix('*'))
        .filter(|m| !m.is_empty() && !special(m))
    {
        return format!("name contains {mid}");
    }
    if let Some(end) = pattern.strip_prefix('*').filter(|e| !special(e)) {
        return format!("name ends in {end}");
    }
    if let Some(start) = pattern.strip_suffix('*').filter(|s| !special(s)) {
        return format!("name starts with {start}");
    }
    format!("name matches {pattern}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_units_give_roles_with_reasons() {
        let r = Roles::default();
        for (name, role) in [
            ("gyro_x", Role::Gyro),
            ("gyro_x_dps", Role::Gyro),
            ("Rate_X_DPS", Role::Gyro),
            ("x_rps", Role::Gyro),
            ("fog_degph", Role::Gyro),
            ("gz", Role::Gyro),
            ("temp_c", Role::Temperature),
            ("board_degc", Role::Temperature),
            ("gyro_temp", Role::Temperature),
            ("accel_x_g", Role::Accel),
            ("ay", Role::Accel),
            ("x_mps2", Role::Accel),
            ("mag_x", Role::Other),
            ("flat_a", Role::Other),
        ] {
            assert_eq!(r.role(name), role, "{name}");
        }
        assert_eq!(r.classify("gyro_x_dps").reason, "name ends in _dps");
        assert_eq!(r.classify("gyro_x").reason, "name contains gyro");
        assert_eq!(r.classify("accel_x_g").reason, "name ends in _g");
        assert_eq!(r.classify("accel_x").reason, "name contains accel");
        assert_eq!(r.classify("temp_c").reason, "name starts with temp");
        assert_eq!(r.classify("gz").reason, "name matches g[xyz]");
        assert_eq!(describe("gx"), "name is gx");
        let mut r = Roles::default();
        r.add_override("--role", "accel_x_g=gyro").unwrap();
        r.add_override("--role", "gyro_*=other").unwrap();
        r.add_override("--role", "gyro_y=gyro").unwrap();
        let c = r.classify("accel_x_g");
        assert_eq!(c.role, Role::Gyro);
        assert_eq!(c.reason, "set by --role accel_x_g=gyro");
        assert_eq!(r.role("gyro_x"), Role::Other);
        assert_eq!(r.role("gyro_y"), Role::Gyro, "the last override wins");
        assert!(r.add_override("--role", "gyro_x").is_err());
        assert!(r.add_override("--role", "gyro_x=magnet").is_err());
        // a batch input's own gyro patterns come before the temperature patterns
        let inp = Roles::default().for_input(&Some(vec!["temp_*".into()]));
        assert!(inp.is_gyro("temp_c") && !inp.is_gyro("gyro_x"));
    }
}
