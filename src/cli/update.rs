//! `farma update MODEL_DIR NEW_LOG -o OUTDIR [--forgetting LAMBDA]`: online update of
//! fitted models by recursive least squares over the samples of a new log; the
//! arguments turned into an [`UpdateJob`], its result printed.

use std::path::PathBuf;

use clap::Args;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::jobs::update::UpdateJob;
use crate::log::Progress;
use crate::model::Report;
use crate::model::folder::tables::fit_json;
use crate::output::OutputSet;

#[derive(Args, Debug)]
pub struct UpdateArgs {
    /// Folder of a fit (`farma fit --save-state`) or of an earlier update: reads its state.parquet.
    pub model_dir: PathBuf,
    /// The new samples: a log with every channel of the model (CSV, Parquet, Arrow IPC or a store).
    pub new_log: PathBuf,
    /// Output folder (coef.parquet, params.parquet, gcv.parquet, state.parquet[, residuals.parquet]).
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: PathBuf,
    /// The model's channels to update (comma-separated, or all); the output folder's
    /// model holds these only.
    #[arg(long, default_value = "all")]
    pub channel: String,
    /// Forgetting factor lambda in (0, 1]: a sample k steps old weighs lambda^k (1: none).
    #[arg(long, default_value_t = 1.0, value_name = "LAMBDA")]
    pub forgetting: f64,
    /// Also write residuals.parquet (the new samples' residuals).
    #[arg(long)]
    pub residuals: bool,
    /// Do not refuse a NEW_LOG whose time stamps do not come after the fitted log's
    /// last one (a log whose clock restarts at 0): it is taken as the continuation.
    #[arg(long)]
    pub no_time_check: bool,
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
    let job = UpdateJob {
        model_dir: a.model_dir.clone(),
        new_log: a.new_log.clone(),
        output: a.output.clone(),
        channel: a.channel.clone(),
        forgetting: a.forgetting,
        residuals: a.residuals,
        no_time_check: a.no_time_check,
        time_tol: a.log_args.time_tol,
    };
    let model = job.read_model()?;
    let store = a.log_args.open(&a.new_log, progress)?;
    let done = job.run(model, &store)?;
    for c in &done.channels {
        let (n, m, r) = (&c.channel, &c.model, &c.report);
        eprintln!(
            "farma: update {n}: {} new sample(s), n = {}, b = {:?} sigma2 = {:.6e} h = {:.6e} (held)",
            r.w.len(),
            r.n,
            m.b,
            m.sigma2,
            m.bandwidth
        );
        for note in &r.notes {
            eprintln!("farma: note: {n}: {note}");
        }
        if a.json {
            let v = fit_json(
                n,
                m,
                Report::Update(r),
                &done.coef_path.display().to_string(),
            );
            outln!("{v}");
        }
    }
    eprintln!(
        "farma: {} channel(s) updated in {:.2} s; tables in {}",
        done.channels.len(),
        done.secs,
        a.output.display()
    );
    Ok(())
}
