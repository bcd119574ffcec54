//! The fit job (`farma fit` on the lag index): every selected channel of one log
//! fitted with the same parameters, in parallel; the model folder written
//! (coef.parquet, params.parquet, gcv.parquet, residuals.parquet with `residuals`,
//! state.parquet with `save_state`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::estimator::fit::fit_then_release;
use crate::estimator::update::state_from_fit;
use crate::estimator::{FarmaParams, FitPath};
use crate::log::Progress;
use crate::model::folder::state_file::{state_metadata, state_table};
use crate::model::folder::tables::{
    ModelRow, ResidualRows, coef_table, gcv_table, params_table, stage_residuals,
};
use crate::model::folder::{COEF_FILE, FIT_OUTPUTS, GCV_FILE, PARAMS_FILE, STATE_FILE};
use crate::model::state::LastTime;
use crate::model::{ChannelState, Farma, FitReport, Report};
use crate::output::OutputSet;
use crate::store::Store;

/// What to do when several channels of a fit fail ([`super::every_channel`]).
pub const FIT_CHANNELS_HINT: &str = "leave the failing ones out of --channel";

/// The grid size of a 1-D fit when none is given.
pub const DEFAULT_GRID: usize = 201;

/// Grid points x samples x channels of a direct-path fit with GCV above which it gets
/// a warning. The direct path gathers and sums every grid point's support at every
/// rung of its two GCV ladders (and the ladder's upward extensions, whose windows hold
/// every sample), so its cost grows as G N. Measured on a 2-core machine (AMD EPYC,
/// 2026-11-26, `farma fit --method direct`): 1.2 us per grid point and sample for the
/// bench's FARMA(2,1,1) at N = 1e5, G = 201 (23.7 s), and 1.8, 2.4 and 3.7 us at
/// N = 5,000, G = 2,000 for orders 1,0,1, 2,1,1 and 3,3,3 (an ARMA series whose GCV
/// extends the ladder upwards); so this threshold is about half a minute or more there.
pub const DIRECT_COST_WARN: f64 = 2e7;

/// The warning for a direct-path fit of `channels` channels of `n` samples on `grid`
/// points, when G N channels exceeds [`DIRECT_COST_WARN`] (none on the fast path, nor
/// with a fixed bandwidth: one rung per f-step).
pub fn direct_cost_warning(
    path: FitPath,
    grid: usize,
    n: usize,
    channels: usize,
    fixed_bandwidth: bool,
) -> Option<String> {
    if path != FitPath::Direct || fixed_bandwidth {
        return None;
    }
    let cost = grid as f64 * n as f64 * channels as f64;
    (cost > DIRECT_COST_WARN).then(|| {
        format!(
            "--method direct gathers every grid point's support at every rung of its GCV ladders: {grid} grid points x {n} samples x {channels} channel(s) = {cost:.1e}, about 1.2-3.7 us each on 2 cores (measured for orders 1,0,1 to 3,3,3): {:.1}-{:.1} min on such a machine; the fast path (the default, --method fast) gives the same fit to 1e-9 in far less, as do a coarser --grid or a fixed --bandwidth H",
            cost * 1.2e-6 / 60.0,
            cost * 3.7e-6 / 60.0
        )
    })
}

/// The time of a log's last sample, from its time column (the state's `t_last_s`).
pub fn last_time(store: &Store) -> Result<LastTime> {
    Ok(match &store.meta().time_col {
        Some(tc) => match store.column(tc)?.last() {
            Some(t) => LastTime::At(*t),
            None => LastTime::NoTimeColumn,
        },
        None => LastTime::NoTimeColumn,
    })
}

/// A fit of channels of one log.
#[derive(Clone, Debug)]
pub struct FitJob {
    /// The log (for messages and the tables' metadata).
    pub log: PathBuf,
    /// The model folder to write.
    pub output: PathBuf,
    /// The channels to fit.
    pub channels: Vec<String>,
    /// The fit's parameters (checked against the log's length by [`FitJob::run`]).
    pub params: FarmaParams,
    /// Also write residuals.parquet.
    pub residuals: bool,
    /// Also write state.parquet.
    pub save_state: bool,
}

/// One fitted channel.
#[derive(Clone, Debug)]
pub struct ChannelFit {
    pub channel: String,
    pub model: Farma,
    pub report: FitReport,
}

/// What a fit job did.
#[derive(Clone, Debug)]
pub struct FitDone {
    /// Every channel, in the order of [`FitJob::channels`].
    pub fits: Vec<ChannelFit>,
    /// coef.parquet in the committed folder.
    pub coef_path: PathBuf,
    /// Wall-clock seconds of the fits.
    pub secs: f64,
}

impl FitJob {
    /// Fits every channel of `store` (the log [`FitJob::log`]) in parallel and writes
    /// the model folder: all channels or none; every failing channel named at once.
    pub fn run(&self, store: &Store, progress: &Progress) -> Result<FitDone> {
        let prm = &self.params;
        super::warn_gaps(store, &self.log);
        if let Some(w) = direct_cost_warning(
            prm.path,
            prm.grid_size,
            store.n_samples(),
            self.channels.len(),
            prm.bandwidth.is_some(),
        ) {
            eprintln!("farma: warning: {w}");
        }
        // the parameters and the length are those of every channel: checked once
        let valid = prm
            .clone()
            .validate(store.n_samples())
            .map_err(|e| in_log(&self.log, e))?;
        let t_last = match self.save_state {
            true => Some(last_time(store)?),
            false => None,
        };
        let t0 = Instant::now();
        let bar = progress.count_bar("channels fitted", self.channels.len() as u64);
        // Each channel's state is taken from its fit as soon as the fit ends, and its
        // residuals (N values) are then dropped unless residuals.parquet is written: a
        // log of many long channels holds the residuals of the fits in flight, not one
        // series per channel (measured on 6 channels of 1e7 samples: 0.98 GB maxrss,
        // against 1.29 GB with every channel's residuals held to the end; BENCHMARKS.md).
        let fitted: Vec<(ChannelFit, Option<ChannelState>)> =
            super::map_channels(&self.log, &self.channels, FIT_CHANNELS_HINT, |n| {
                let x = store.column(n)?;
                let (model, mut report) = fit_then_release(x, &valid, || store.release(x))?;
                let state = t_last.map(|t| {
                    let mut s = state_from_fit(n, x, &model, &report);
                    s.t_last = t;
                    s
                });
                if !self.residuals {
                    report.residuals = Vec::new();
                }
                bar.inc(1);
                let channel = n.to_string();
                Ok((
                    ChannelFit {
                        channel,
                        model,
                        report,
                    },
                    state,
                ))
            })?;
        bar.finish_and_clear();
        let (fits, states): (Vec<ChannelFit>, Vec<Option<ChannelState>>) =
            fitted.into_iter().unzip();
        let states: Vec<ChannelState> = states.into_iter().flatten().collect();
        let secs = t0.elapsed().as_secs_f64();
        let coef_path = self.write(store, &fits, &states)?;
        Ok(FitDone {
            fits,
            coef_path,
            secs,
        })
    }

    /// Stages and commits the model folder; returns the path of its coef.parquet.
    fn write(
        &self,
        store: &Store,
        fits: &[ChannelFit],
        states: &[ChannelState],
    ) -> Result<PathBuf> {
        let mut out = OutputSet::new(&self.output)?;
        let refs: Vec<ModelRow> = fits
            .iter()
            .map(|c| (c.channel.clone(), &c.model, Report::Fit(&c.report)))
            .collect();
        let prm = &self.params;
        let mut md = vec![("order", format!("{},{},{}", prm.p, prm.q, prm.d))];
        md.extend(super::source_metadata(&self.log, store)?);
        let coef_path = out.path(COEF_FILE);
        out.parquet(COEF_FILE, &coef_table(&refs)?, &md)?;
        out.parquet(PARAMS_FILE, &params_table(&refs)?, &md)?;
        out.parquet(GCV_FILE, &gcv_table(&refs)?, &md)?;
        if self.residuals {
            let rows: Vec<ResidualRows> = fits
                .iter()
                .map(|c| ResidualRows::of_fit(&c.channel, &c.report))
                .collect();
            stage_residuals(&mut out, &rows, &md)?;
        }
        if self.save_state {
            for s in states.iter().filter(|s| s.linear_start) {
                eprintln!(
                    "farma: warning: {}: the fit returned its linear ARMA start; its state is written, but `farma update` refuses it (no fitted local model to continue): fit the concatenated log instead",
                    s.channel
                );
            }
            let refs: Vec<_> = states.iter().collect();
            out.parquet(STATE_FILE, &state_table(&refs)?, &state_metadata(&md))?;
        }
        super::commit_outputs(out, &FIT_OUTPUTS)?;
        Ok(coef_path)
    }
}

/// A too-short log named with its path.
fn in_log(log: &Path, e: Error) -> Error {
    match e {
        Error::TooShort { what, need, have } => Error::TooShort {
            what: format!("{}: {what}", log.display()),
            need,
            have,
        },
        other => other,
    }
}
