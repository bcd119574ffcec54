//! Which channels `farma analyze` runs on, and why, from the channels' roles
//! ([`crate::log::roles`]): `--channel all` takes the gyro axes; accelerometers and
//! other channels are skipped (ask for them by name); a temperature channel is not put
//! through the FARMA workflow but named in the summary as the 2-D index of later
//! tools. No gyro at all: every channel but the temperatures, with a warning. An
//! explicit `--channel a,b` takes exactly those.

use crate::error::Result;
use crate::log::roles::{Role, Roles};
use crate::store::Store;

/// The channels to analyse and the lines that say why.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChannelChoice {
    pub channels: Vec<String>,
    /// One line per channel of the log, in the log's order: taken and why, or skipped
    /// and why ("accel_x_g: skipped, accelerometer (name ends in _g); ask with
    /// --channel").
    pub lines: Vec<String>,
    /// The temperature channels of the log.
    pub temperature: Vec<String>,
    /// A warning for stderr and the summary (no gyro channel: the fallback).
    pub warning: Option<String>,
}

impl ChannelChoice {
    /// The choice of `--channel SELECTION` among the channels of `store`.
    pub fn choose(store: &Store, selection: &str, roles: &Roles) -> Result<ChannelChoice> {
        let names = store.channel_names();
        let classified: Vec<_> = names.iter().map(|n| (*n, roles.classify(n))).collect();
        let temperature: Vec<String> = classified
            .iter()
            .filter(|(_, c)| c.role == Role::Temperature)
            .map(|(n, _)| n.to_string())
            .collect();
        if selection.trim() != "all" || names.is_empty() {
            // names checked (and a log without channels refused) as every command does
            let channels = store.select_channels(selection)?;
            return Ok(Self::given(&names, channels, roles, "named in --channel"));
        }
        let gyros: Vec<String> = classified
            .iter()
            .filter(|(_, c)| c.role == Role::Gyro)
            .map(|(n, _)| n.to_string())
            .collect();
        let fallback = gyros.is_empty();
        let mut channels = Vec::new();
        let mut lines = Vec::new();
        for (n, c) in &classified {
            let take = match c.role {
                Role::Gyro => true,
                Role::Temperature => false,
                Role::Accel | Role::Other => fallback,
            };
            if take {
                channels.push(n.to_string());
                lines.push(if fallback {
                    format!(
                        "{n}: taken, {} ({}): no channel of the log is a gyro",
                        c.role.words(),
                        c.reason
                    )
                } else {
                    format!("{n}: gyro ({})", c.reason)
                });
            } else if c.role == Role::Temperature {
                lines.push(format!(
                    "{n}: temperature ({}): not put through the FARMA workflow; ask with --channel {n}",
                    c.reason
                ));
            } else {
                lines.push(format!(
                    "{n}: skipped, {} ({}); ask with --channel {n} or --role {n}=gyro",
                    c.role.words(),
                    c.reason
                ));
            }
        }
        let warning = fallback.then(|| {
            format!(
                "{}: no channel is a gyro by its name or unit (gyro patterns: {}); analysing every channel but the temperatures: {}; name them with --channel or --role NAME=gyro",
                store.label().display(),
                roles.gyro.join(", "),
                if channels.is_empty() {
                    "none".to_string()
                } else {
                    channels.join(", ")
                }
            )
        });
        if channels.is_empty() {
            return Err(crate::error::Error::column(
                store.label(),
                format!(
                    "--channel all: no channel to analyse (every channel is a temperature: {}); name one with --channel",
                    temperature.join(", ")
                ),
            ));
        }
        // a taken channel with non-finite values is refused when it is read (prep),
        // naming it; a skipped one no longer blocks the run
        Ok(ChannelChoice {
            channels,
            lines,
            temperature,
            warning,
        })
    }

    /// `channels` given by the caller (`why`: "named in --channel", a batch input's
    /// list or gyro role), among the log's `names`.
    pub fn given(names: &[&str], channels: Vec<String>, roles: &Roles, why: &str) -> Self {
        let temperature = names
            .iter()
            .filter(|n| roles.role(n) == Role::Temperature)
            .map(|n| n.to_string())
            .collect();
        let lines = names
            .iter()
            .map(|n| {
                let c = roles.classify(n);
                if channels.iter().any(|t| t == n) {
                    format!("{n}: {why} ({}: {})", c.role.words(), c.reason)
                } else {
                    format!("{n}: not named ({}: {})", c.role.words(), c.reason)
                }
            })
            .collect();
        ChannelChoice {
            channels,
            lines,
            temperature,
            warning: None,
        }
    }

    /// The lines of summary.txt's channel section.
    pub fn text(&self) -> String {
        let mut o = String::from("== channels\n");
        if let Some(w) = &self.warning {
            o += &format!("  warning: {w}\n");
        }
        for l in &self.lines {
            o += &format!("  {l}\n");
        }
        for t in &self.temperature {
            o += &format!(
                "  temperature channel: {t} (offered to farma fit --index lag,{t} and farma gap)\n"
            );
        }
        o
    }
}
