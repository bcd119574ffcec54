//! The gap job (`farma gap`, the batch task `gap`): the sim-to-real gap diagnosis of
//! channels of one log against one simulation spec. One channel writes the files of
//! `farma gap -o` ([`report::GAP_OUTPUTS`]); several write the three tables with every
//! channel's rows, a `spec_after` and an SVG report per channel, and one
//! `report.html` over the channels.

use std::path::{Path, PathBuf};

use crate::diagnosis::{Diagnosis, GapParams, RealLog, diagnose, report};
use crate::error::{Error, Result};
use crate::output::{OutputSet, write_text};
use crate::simulator::Spec;
use crate::store::Store;

/// A diagnosis of channels of one log against one spec.
#[derive(Clone, Debug)]
pub struct GapJob {
    pub log: PathBuf,
    /// The spec file (its folder resolves the spec's relative model paths).
    pub spec_path: PathBuf,
    pub spec: Spec,
    /// The channels to diagnose (channels of the spec and of the log).
    pub channels: Vec<String>,
    /// A temperature channel of the log, used when the spec names none (the log's
    /// temperature role, offered by `farma batch`).
    pub temperature: Option<String>,
    pub params: GapParams,
}

impl GapJob {
    /// The temperature channel the diagnosis reads: the spec's `temperature_channel`,
    /// else [`GapJob::temperature`] when the log has it.
    pub fn temperature_channel(&self, store: &Store) -> Option<String> {
        match &self.spec.temperature_channel {
            Some(t) => Some(t.clone()),
            None => self
                .temperature
                .clone()
                .filter(|t| store.channel_names().contains(&t.as_str())),
        }
    }

    /// The real log's side of the diagnosis of `channel`.
    pub fn real_log<'a>(&self, store: &'a Store, channel: &str) -> Result<RealLog<'a>> {
        let x = store.column(channel)?;
        let temperature_c = match self.temperature_channel(store) {
            Some(t) => Some(store.column(&t).map_err(|e| match e {
                Error::Column { .. } => Error::Usage(format!(
                    "{}: the spec's temperature_channel '{t}' is not a column of the real log {}",
                    self.spec_path.display(),
                    self.log.display()
                )),
                other => other,
            })?),
            None => None,
        };
        let log_names = store.channel_names();
        let others: Vec<(String, &[f64])> = self
            .spec
            .channels
            .iter()
            .filter(|c| c.name != channel && log_names.contains(&c.name.as_str()))
            .map(|c| Ok((c.name.clone(), store.column(&c.name)?)))
            .collect::<Result<_>>()?;
        // every other numeric channel is scanned for test-stand events, the
        // accelerometers included; the temperature and a channel with gaps are not
        let temp = self.temperature_channel(store);
        let scan: Vec<(String, &[f64])> = log_names
            .iter()
            .filter(|n| **n != channel && Some(**n) != temp.as_deref())
            .filter(|n| store.nonfinite(n).is_none())
            .map(|n| Ok((n.to_string(), store.column(n)?)))
            .collect::<Result<_>>()?;
        Ok(RealLog {
            channel: channel.to_string(),
            x,
            rate_hz: store.sample_rate_hz(),
            temperature_c,
            others,
            spec_dir: self.spec_path.parent().map(|p| p.to_path_buf()),
            scan,
            beyond: &[],
        })
    }

    /// Diagnoses every channel in turn (each diagnosis runs its ensemble in parallel).
    /// An offered temperature channel becomes the spec's `temperature_channel` (the
    /// effects it lets the diagnosis add need it in `spec_after`).
    pub fn run(&self, store: &Store) -> Result<Vec<Diagnosis>> {
        let mut spec = self.spec.clone();
        if spec.temperature_channel.is_none() {
            spec.temperature_channel = self.temperature_channel(store);
        }
        self.channels
            .iter()
            .map(|c| {
                let real = self.real_log(store, c)?;
                diagnose(&real, &spec, &self.params).map_err(|e| super::on_channel(&self.log, c, e))
            })
            .collect()
    }

    /// The file-level metadata of the tables.
    fn meta(&self) -> Vec<(&'static str, String)> {
        vec![
            ("real", self.log.display().to_string()),
            ("spec", self.spec_path.display().to_string()),
        ]
    }

    /// Writes the diagnoses `done` into `dir` as one set; returns the files' paths.
    pub fn write(&self, dir: &Path, done: &[Diagnosis]) -> Result<Vec<String>> {
        if let [d] = done {
            let mut meta = self.meta();
            meta.push(("channel", d.channel.clone()));
            return report::write_outputs(d, dir, &meta);
        }
        let mut out = OutputSet::new(dir)?;
        let mut names: Vec<String> = Vec::new();
        let per: Vec<[arrow_array::RecordBatch; 3]> =
            done.iter().map(report::tables).collect::<Result<_>>()?;
        for (k, table) in ["gap_features", "gap_regions", "gap_effects"]
            .iter()
            .enumerate()
        {
            let parts: Vec<&arrow_array::RecordBatch> = per.iter().map(|t| &t[k]).collect();
            let all =
                arrow_select::concat::concat_batches(&parts[0].schema(), parts).map_err(|e| {
                    Error::Data(format!("gap: the {table} tables do not concatenate: {e}"))
                })?;
            let name = format!("{table}.parquet");
            out.parquet(&name, &all, &self.meta())?;
            names.push(name);
        }
        for d in done {
            let toml = d.spec_after.to_toml()?;
            let spec_name = format!("spec_after_{}.toml", d.channel);
            out.file(&spec_name, |p| write_text(p, &toml))?;
            let svg = report::svg(d)?;
            let svg_name = format!("report_{}.svg", d.channel);
            out.file(&svg_name, |p| write_text(p, &svg))?;
            names.push(spec_name);
            names.push(svg_name);
        }
        let page = crate::report::gap::gap_page(
            &self.log.display().to_string(),
            &self.spec_path.display().to_string(),
            done,
        )?;
        out.file(crate::report::REPORT, |p| write_text(p, &page))?;
        names.push(crate::report::REPORT.to_string());
        let written = names
            .iter()
            .map(|n| out.path(n).display().to_string())
            .collect();
        let refs: Vec<&str> = names
            .iter()
            .map(String::as_str)
            .chain(report::GAP_OUTPUTS)
            .collect();
        out.commit(&refs)?;
        Ok(written)
    }
}
