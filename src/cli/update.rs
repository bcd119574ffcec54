//! `farma update MODEL_DIR NEW_LOG -o OUTDIR [--forgetting LAMBDA]`: online update of
//! fitted models by recursive least squares over the samples of a new log.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use rayon::prelude::*;

use super::LogArgs;
use super::fit::FIT_OUTPUTS;
use crate::error::{Error, Result};
use crate::estimator::FittedFarma;
use crate::estimator::tables::{coef_table, fit_json, gcv_table};
use crate::estimator::update::{
    Updated, read_state, state_metadata, state_table, update, update_params_table,
    update_residual_table,
};
use crate::log::Progress;
use crate::output::OutputSet;

/// The state file in a model folder.
pub const STATE_FILE: &str = "state.parquet";

#[derive(Args, Debug)]
pub struct UpdateArgs {
    /// Folder of a fit (`farma fit --save-state`) or of an earlier update: reads its state.parquet.
    pub model_dir: PathBuf,
    /// The new samples: a log with every channel of the model (CSV, Parquet, Arrow IPC or a store).
    pub new_log: PathBuf,
    /// Output folder (coef.parquet, params.parquet, gcv.parquet, state.parquet[, residuals.parquet]).
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: PathBuf,
    /// Forgetting factor lambda in (0, 1]: a sample k steps old weighs lambda^k (1: none).
    #[arg(long, default_value_t = 1.0, value_name = "LAMBDA")]
    pub forgetting: f64,
    /// Also write residuals.parquet (the new samples' residuals).
    #[arg(long)]
    pub residuals: bool,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines).
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: UpdateArgs, progress: &Progress) -> Result<()> {
    if !(a.forgetting > 0.0 && a.forgetting <= 1.0) {
        return Err(Error::Usage(format!(
            "--forgetting: {} is not in (0, 1]",
            a.forgetting
        )));
    }
    OutputSet::check(&a.output)?;
    if !a.model_dir.is_dir() {
        return Err(Error::Usage(format!(
            "{}: MODEL_DIR is not a folder (the output folder of farma fit --save-state)",
            a.model_dir.display()
        )));
    }
    let state_path = a.model_dir.join(STATE_FILE);
    if !state_path.is_file() {
        return Err(Error::Usage(format!(
            "{}: no {STATE_FILE} in the model folder: run farma fit with --save-state",
            a.model_dir.display()
        )));
    }
    let (states, md) = read_state(&state_path)?;
    let model_rate: Option<f64> = md
        .iter()
        .find(|(k, _)| k == "sample_rate_hz")
        .and_then(|(_, v)| v.parse().ok());
    let store = a.log_args.open(&a.new_log, progress)?;
    if let Some(r) = model_rate
        && (store.sample_rate_hz() - r).abs() > 1e-6 * r.abs()
    {
        return Err(Error::Timestamps {
            path: a.new_log.clone(),
            msg: format!(
                "sampled at {:.6} Hz, but the model in {} was fitted at {r:.6} Hz",
                store.sample_rate_hz(),
                a.model_dir.display()
            ),
        });
    }
    for s in &states {
        store.column(&s.channel)?;
    }
    let t0 = Instant::now();
    let ups: Vec<(String, Updated)> = states
        .par_iter()
        .map(|s| {
            let x = store.column(&s.channel)?;
            let u = update(s, x, a.forgetting).map_err(|e| match e {
                Error::Usage(msg) => Error::Column {
                    path: a.new_log.clone(),
                    msg: format!("channel '{}': {msg}", s.channel),
                },
                other => other,
            })?;
            Ok((s.channel.clone(), u))
        })
        .collect::<Result<_>>()?;
    let secs = t0.elapsed().as_secs_f64();
    let mut out = OutputSet::new(&a.output)?;
    let items: Vec<(String, &Updated)> = ups.iter().map(|(n, u)| (n.clone(), u)).collect();
    let models: Vec<(String, &FittedFarma)> =
        ups.iter().map(|(n, u)| (n.clone(), &u.model)).collect();
    let order = md
        .iter()
        .find(|(k, _)| k == "order")
        .map(|(_, v)| v.clone())
        .unwrap_or_default();
    let (size, mtime) = crate::log::source_identity(&a.new_log)?;
    let out_md = vec![
        ("order", order),
        ("source", a.new_log.display().to_string()),
        ("source_size", size.to_string()),
        ("source_mtime_ns", mtime.to_string()),
        ("sample_rate_hz", store.sample_rate_hz().to_string()),
        ("model", a.model_dir.display().to_string()),
        ("forgetting", a.forgetting.to_string()),
    ];
    let coef_path = out.path("coef.parquet");
    out.parquet("coef.parquet", &coef_table(&models)?, &out_md)?;
    out.parquet("params.parquet", &update_params_table(&items)?, &out_md)?;
    out.parquet("gcv.parquet", &gcv_table(&models)?, &out_md)?;
    if a.residuals {
        out.parquet(
            "residuals.parquet",
            &update_residual_table(&items)?,
            &out_md,
        )?;
    }
    let refs: Vec<_> = ups.iter().map(|(_, u)| &u.state).collect();
    out.parquet(STATE_FILE, &state_table(&refs)?, &state_metadata(&out_md))?;
    super::commit_outputs(out, &FIT_OUTPUTS)?;
    for (n, u) in &ups {
        let m = &u.model;
        eprintln!(
            "farma: update {n}: {} new sample(s), n = {}, b = {:?} sigma2 = {:.6e} h = {:.6e} (held)",
            u.w.len(),
            m.n,
            m.b,
            m.sigma2,
            m.bandwidth
        );
        for note in &m.notes {
            eprintln!("farma: note: {n}: {note}");
        }
        if a.json {
            let mut v = fit_json(n, m, &coef_path.display().to_string());
            v["init"] = "state".into();
            v["method"] = "rls".into();
            v["forgetting"] = a.forgetting.into();
            v["n_new"] = u.w.len().into();
            outln!("{v}");
        }
    }
    eprintln!(
        "farma: {} channel(s) updated in {secs:.2} s; tables in {}",
        ups.len(),
        a.output.display()
    );
    Ok(())
}
