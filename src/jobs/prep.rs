//! The prep job (`farma prep`): the paper's preparation of every selected channel of a
//! log in parallel (Pauta outliers, the reverse-arrangement test, trend removal or
//! differencing, mean removal), aligned to a common length; the prepared log
//! (clean.arrow, a store) and its tables written.

use std::path::PathBuf;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::output::OutputSet;
use crate::store::Store;
use crate::workflow::prep::{ChannelPrep, PrepParams, align, prep_channel};
use crate::workflow::tables::{prep_table, replaced_table, write_prepared_store};

/// Prepares `names` of `store` in parallel, aligned to a common length.
pub fn prep_store(
    store: &Store,
    names: &[String],
    prm: &PrepParams,
) -> Result<(Vec<ChannelPrep>, usize)> {
    let mut chans: Vec<ChannelPrep> = super::every_channel(
        names
            .par_iter()
            .map(|n| {
                let x = store.column(n)?;
                prm.validate(x.len()).map_err(|e| match e {
                    Error::TooShort { what, need, have } => Error::TooShort {
                        what: format!("{}: channel {n}: {what}", store.label().display()),
                        need,
                        have,
                    },
                    o => o,
                })?;
                Ok(prep_channel(n, x, prm))
            })
            .collect(),
        "leave the failing ones out of --channel",
    )?;
    let dropped = align(&mut chans);
    Ok((chans, dropped))
}

/// The files `farma prep` can write into its output folder: a run removes those of an
/// earlier run that it does not write.
pub const PREP_OUTPUTS: &[&str] = &["clean.arrow", "prep.parquet", "replaced.parquet"];

/// Stages the prepared log (clean.arrow) and its two tables (prep.parquet,
/// replaced.parquet) in `set`: the part of its folder `farma analyze` shares with
/// `farma prep`.
pub fn stage_prep(
    set: &mut OutputSet,
    store: &Store,
    (chans, dropped): (&[ChannelPrep], usize),
    md: &[(&str, String)],
) -> Result<()> {
    set.file("clean.arrow", |p| {
        write_prepared_store(p, store, chans, dropped)
    })?;
    set.parquet("prep.parquet", &prep_table(chans)?, md)?;
    set.parquet(
        "replaced.parquet",
        &replaced_table(chans, store.sample_rate_hz())?,
        md,
    )
}

/// A preparation of channels of one log.
#[derive(Clone, Debug)]
pub struct PrepJob {
    pub log: PathBuf,
    /// The folder to write.
    pub output: PathBuf,
    pub channels: Vec<String>,
    pub params: PrepParams,
}

impl PrepJob {
    /// Prepares every channel (all or none; every failing channel named at once) and
    /// writes the folder; returns the prepared channels.
    pub fn run(&self, store: &Store) -> Result<Vec<ChannelPrep>> {
        let (chans, dropped) = prep_store(store, &self.channels, &self.params)?;
        let mut set = OutputSet::new(&self.output)?;
        let md = super::source_metadata(&self.log, store)?;
        stage_prep(&mut set, store, (&chans, dropped), &md)?;
        super::commit_outputs(set, PREP_OUTPUTS)?;
        Ok(chans)
    }
}
