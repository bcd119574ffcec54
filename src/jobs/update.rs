//! The update job (`farma update`): every selected channel of a model folder continued
//! by recursive least squares over the samples of a new log ([`crate::estimator::update`]),
//! and the updated model folder written (coef, params, gcv, state[, residuals]).

use std::path::PathBuf;
use std::time::Instant;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::estimator::update::update;
use crate::model::folder::state_file::{Metadata, read_state, state_metadata, state_table};
use crate::model::folder::tables::{ModelRow, ResidualRows, stage_residuals};
use crate::model::folder::tables::{coef_table, gcv_table, params_table};
use crate::model::folder::{COEF_FILE, FIT_OUTPUTS, GCV_FILE, ModelDir, PARAMS_FILE, STATE_FILE};
use crate::model::state::{ChannelState, LastTime};
use crate::model::{Farma, Report, UpdateReport};
use crate::output::OutputSet;
use crate::store::Store;

/// An update of a model folder over a new log.
#[derive(Clone, Debug)]
pub struct UpdateJob {
    /// The folder of a fit with its state (`fit --save-state`) or of an earlier update.
    pub model_dir: PathBuf,
    /// The new log.
    pub new_log: PathBuf,
    /// The folder to write.
    pub output: PathBuf,
    /// The model's channels to update: `all` or a comma-separated list.
    pub channel: String,
    /// Forgetting factor lambda in (0, 1].
    pub forgetting: f64,
    /// Also write residuals.parquet.
    pub residuals: bool,
    /// Take a new log whose time stamps do not come after the fitted log's as its
    /// continuation (with a warning) instead of refusing it.
    pub no_time_check: bool,
    /// Relative tolerance of a sample interval (the log options' `time_tol`): a gap
    /// between the fitted log and the new one beyond it is warned about.
    pub time_tol: f64,
}

/// The model folder's state, read and checked ([`UpdateJob::read_model`]).
#[derive(Clone, Debug)]
pub struct ModelState {
    pub states: Vec<ChannelState>,
    /// The state file's metadata.
    pub md: Metadata,
    /// The rate the model was fitted at, if recorded.
    pub model_rate: Option<f64>,
}

/// One updated channel.
#[derive(Clone, Debug)]
pub struct ChannelUpdate {
    pub channel: String,
    pub model: Farma,
    pub state: ChannelState,
    pub report: UpdateReport,
}

/// What an update job did.
#[derive(Clone, Debug)]
pub struct UpdateDone {
    pub channels: Vec<ChannelUpdate>,
    /// coef.parquet in the committed folder.
    pub coef_path: PathBuf,
    /// Wall-clock seconds of the updates.
    pub secs: f64,
}

impl UpdateJob {
    /// Reads and checks the model folder's state (before the new log is opened): the
    /// folder, its state file, the selected channels, the rate it was fitted at.
    pub fn read_model(&self) -> Result<ModelState> {
        if !self.model_dir.is_dir() {
            return Err(Error::Usage(format!(
                "{}: MODEL_DIR is not a folder (the output folder of farma fit --save-state)",
                self.model_dir.display()
            )));
        }
        let state_path = self.model_dir.join(STATE_FILE);
        if !state_path.is_file() {
            // a 2-D fit writes no state, and refuses --save-state
            if let Some(index) = ModelDir::new(&self.model_dir).index2() {
                return Err(Error::Usage(format!(
                    "{}: no {STATE_FILE}: the model was fitted with a 2-D index (--index {index}), and online updates support the 1-D index only; fit the concatenated log instead",
                    self.model_dir.display()
                )));
            }
            return Err(Error::Usage(format!(
                "{}: no {STATE_FILE} in the model folder: run farma fit with --save-state",
                self.model_dir.display()
            )));
        }
        let (states, md) = read_state(&state_path)?;
        let states = select_states(states, &self.channel, &state_path)?;
        // the rate the model was fitted at: a value that is not a positive number is an
        // edited or corrupt state, refused rather than skipped so that the new log's rate
        // is always checked against it
        let model_rate: Option<f64> = match md.iter().find(|(k, _)| k == "sample_rate_hz") {
            None => None,
            Some((_, v)) => match v.trim().parse::<f64>() {
                Ok(r) if r.is_finite() && r > 0.0 => Some(r),
                _ => {
                    return Err(Error::format(
                        &state_path,
                        format!("metadata sample_rate_hz = '{v}' is not a positive number of Hz"),
                    ));
                }
            },
        };
        Ok(ModelState {
            states,
            md,
            model_rate,
        })
    }

    /// Updates every selected channel over the new log `store` (all channels or
    /// none; every failing channel named at once) and writes the output folder.
    pub fn run(&self, model: ModelState, store: &Store) -> Result<UpdateDone> {
        let ModelState {
            states,
            md,
            model_rate,
        } = model;
        let state_path = self.model_dir.join(STATE_FILE);
        if let Some(r) = model_rate
            && (store.sample_rate_hz() - r).abs() > 1e-6 * r.abs()
        {
            return Err(Error::Timestamps {
                path: self.new_log.clone(),
                msg: format!(
                    "sampled at {:.6} Hz, but the model in {} was fitted at {r:.6} Hz",
                    store.sample_rate_hz(),
                    self.model_dir.display()
                ),
            });
        }
        for s in &states {
            store.column(&s.channel)?;
        }
        check_continuation(self, &states, store)?;
        crate::jobs::warn_gaps(store, &self.new_log);
        let t_last = crate::jobs::fit::last_time(store)?;
        let t0 = Instant::now();
        // a channel whose fit returned its linear start is the model's problem, not the
        // new log's: named with the state file, not NEW_LOG
        let others: Vec<&str> = states
            .iter()
            .filter(|s| !s.linear_start)
            .map(|s| s.channel.as_str())
            .collect();
        let instead = if others.is_empty() {
            String::new()
        } else {
            format!(" (or --channel {} updates the others)", others.join(","))
        };
        crate::jobs::every_channel(
            states
                .iter()
                .map(|s| -> Result<()> {
                    if !s.linear_start {
                        return Ok(());
                    }
                    Err(Error::format(
                        &state_path,
                        format!(
                            "channel '{}': its fit returned the linear ARMA start (the local fits ended above it in RSS), so the state holds no fitted local model to continue; fit the concatenated log instead{instead}",
                            s.channel
                        ),
                    ))
                })
                .collect(),
            "an update continues every channel of the model together",
        )?;
        let mut ups: Vec<(String, Farma, ChannelState, UpdateReport)> = crate::jobs::every_channel(
            states
                .par_iter()
                .map(|s| {
                    let x = store.column(&s.channel)?;
                    let (m, st, mut r) = update(s, x, self.forgetting)
                        .map_err(|e| crate::jobs::on_channel(&self.new_log, &s.channel, e))?;
                    // the new samples' residuals: kept only for residuals.parquet (as
                    // `farma fit`)
                    if !self.residuals {
                        r.residuals = Vec::new();
                    }
                    Ok((s.channel.clone(), m, st, r))
                })
                .collect(),
            "an update continues every channel of the model together",
        )?;
        let secs = t0.elapsed().as_secs_f64();
        for (_, _, st, _) in &mut ups {
            st.t_last = t_last;
        }
        let mut out = OutputSet::new(&self.output)?;
        let models: Vec<ModelRow> = ups
            .iter()
            .map(|(n, m, _, r)| (n.clone(), m, Report::Update(r)))
            .collect();
        let order = md
            .iter()
            .find(|(k, _)| k == "order")
            .map(|(_, v)| v.clone())
            .unwrap_or_default();
        let (size, mtime) = crate::log::source_identity(&self.new_log)?;
        let out_md = vec![
            ("order", order),
            ("source", self.new_log.display().to_string()),
            ("source_size", size.to_string()),
            ("source_mtime_ns", mtime.to_string()),
            ("sample_rate_hz", store.sample_rate_hz().to_string()),
            ("model", self.model_dir.display().to_string()),
            ("forgetting", self.forgetting.to_string()),
        ];
        let coef_path = out.path(COEF_FILE);
        out.parquet(COEF_FILE, &coef_table(&models)?, &out_md)?;
        out.parquet(PARAMS_FILE, &params_table(&models)?, &out_md)?;
        out.parquet(GCV_FILE, &gcv_table(&models)?, &out_md)?;
        if self.residuals {
            // every new sample is a residual of the model (its lags in the state): in_fit
            // true throughout; t counts from the first sample of the whole series
            let rows: Vec<ResidualRows> = ups
                .iter()
                .map(|(n, _, _, r)| ResidualRows {
                    channel: n,
                    values: &r.residuals,
                    first_t: r.first_t as i64,
                    in_fit_from: 0,
                })
                .collect();
            stage_residuals(&mut out, &rows, &out_md)?;
        }
        let refs: Vec<_> = ups.iter().map(|(_, _, st, _)| st).collect();
        out.parquet(STATE_FILE, &state_table(&refs)?, &state_metadata(&out_md))?;
        crate::jobs::commit_outputs(out, &FIT_OUTPUTS)?;
        Ok(UpdateDone {
            channels: ups
                .into_iter()
                .map(|(channel, model, state, report)| ChannelUpdate {
                    channel,
                    model,
                    state,
                    report,
                })
                .collect(),
            coef_path,
            secs,
        })
    }
}

/// Seconds for a message: six decimals, trailing zeros dropped (1.0999999999999943 is
/// "1.1").
fn secs(t: f64) -> String {
    let s = format!("{t:.6}");
    let s = s.trim_end_matches('0');
    s.strip_suffix('.').unwrap_or(s).to_string()
}

/// Checks that `store` (NEW_LOG) continues the fitted series in time: its first time
/// stamp after the state's last one (an error, exit 2, unless `--no-time-check`),
/// about one sample interval after it (else a warning: the update bridges the gap);
/// a warning when there is nothing to check against.
fn check_continuation(job: &UpdateJob, states: &[ChannelState], store: &Store) -> Result<()> {
    let state_path = job.model_dir.join(STATE_FILE);
    let new = job.new_log.display();
    let cannot = |why: String| {
        eprintln!(
            "farma: warning: cannot check that {new} continues the fitted log in time: {why}"
        );
    };
    if states.iter().any(|s| s.t_last == LastTime::NotRecorded) {
        cannot(format!(
            "{} has no t_last_s column (written by an older farma; a fit or update now records it)",
            state_path.display()
        ));
        return Ok(());
    }
    let t_last = states
        .iter()
        .filter_map(|s| match s.t_last {
            LastTime::At(t) => Some(t),
            _ => None,
        })
        .reduce(f64::max);
    let Some(t_last) = t_last else {
        cannot("the fitted log had no time column".into());
        return Ok(());
    };
    let times = match &store.meta().time_col {
        Some(tc) => store.column(tc)?,
        None => &[],
    };
    let Some(&t0) = times.first() else {
        cannot(format!(
            "it has no time column (the fitted log's last sample is at t = {} s)",
            secs(t_last)
        ));
        return Ok(());
    };
    if t0 <= t_last {
        if job.no_time_check {
            eprintln!(
                "farma: warning: {new} starts at t = {} s, not after the fitted log's last sample (t = {} s); taken as its continuation (--no-time-check)",
                secs(t0),
                secs(t_last)
            );
            return Ok(());
        }
        return Err(Error::Timestamps {
            path: job.new_log.clone(),
            msg: format!(
                "starts at t = {} s, not after the last sample the model in {} has seen (t = {} s): an update continues the fitted series, so the new log must come after it in time (the fitted log itself, or one that overlaps it?); for a log whose clock restarts, --no-time-check",
                secs(t0),
                job.model_dir.display(),
                secs(t_last)
            ),
        });
    }
    let dt = 1.0 / store.sample_rate_hz();
    let gap = t0 - t_last;
    if (gap - dt).abs() > job.time_tol * dt {
        eprintln!(
            "farma: warning: {new} starts {} s after the last sample the model has seen (t = {} s), {:.2} sample intervals of {} s: updated as one series, the lags x_(t-m) and residuals of its first samples reach across the gap",
            secs(gap),
            secs(t_last),
            gap / dt,
            secs(dt)
        );
    }
    Ok(())
}

/// The states of the channels `selection` names (`all`, or a comma-separated list of
/// the model's channels, in the model's order); a name the model does not hold is a
/// usage error naming the model's channels.
fn select_states(
    states: Vec<ChannelState>,
    selection: &str,
    state_path: &std::path::Path,
) -> Result<Vec<ChannelState>> {
    if selection.trim() == "all" {
        return Ok(states);
    }
    let names: Vec<&str> = selection
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    if names.is_empty() {
        return Err(Error::Usage("--channel: no channel named".into()));
    }
    for name in &names {
        if !states.iter().any(|s| s.channel == *name) {
            return Err(Error::Usage(format!(
                "--channel {name}: the model in {} has no channel '{name}'; its channels are: {}",
                state_path.display(),
                states
                    .iter()
                    .map(|s| s.channel.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
    }
    Ok(states
        .into_iter()
        .filter(|s| names.contains(&s.channel.as_str()))
        .collect())
}
