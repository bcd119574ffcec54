//! The check job (`farma check`): a saved model's channels checked on a log, the
//! check [`crate::workflow::check::check_model`] runs (residual whiteness, hold-out
//! prediction against the linear ARMA baseline fitted before the hold-out, polynomial
//! fits of the f_m), every channel in parallel; the tables written when asked.

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::estimator::arma::fit_arma;
use crate::model::Farma;
use crate::model::folder::{ModelDir, PARAMS_FILE};
use crate::output::OutputSet;
use crate::store::Store;
use crate::workflow::check::{CheckReport, check_model};
use crate::workflow::tables::{acf_table, ljung_box_table, poly_table, prediction_table};

/// The files `farma check -o` can write into its output folder: a run removes those
/// of an earlier run that it does not write.
pub const CHECK_OUTPUTS: &[&str] = &[
    "acf.parquet",
    "ljung_box.parquet",
    "prediction.parquet",
    "poly.parquet",
];

/// What to do when several channels of a check fail.
const CHECK_CHANNELS_HINT: &str = "name the others with --channel, or refit the failing ones";

/// A check of a model folder's channels on a log.
#[derive(Clone, Debug)]
pub struct CheckJob {
    /// The model folder (`farma fit -o`).
    pub model: PathBuf,
    /// The log.
    pub log: PathBuf,
    /// The folder for the tables (acf, ljung_box, prediction, poly), if any.
    pub output: Option<PathBuf>,
    /// Seconds at the end of the log predicted (0: no prediction).
    pub holdout_s: f64,
    /// Largest lag of the residual autocorrelation.
    pub maxlag: usize,
    /// Largest degree of the polynomial fits of the f_m.
    pub max_degree: usize,
}

/// One checked channel.
#[derive(Clone, Debug)]
pub struct ChannelCheck {
    pub channel: String,
    pub model: Farma,
    /// Samples held out.
    pub holdout: usize,
    /// The linear ARMA baseline fitted before the hold-out: AR and MA coefficients.
    pub arma_ar: Vec<f64>,
    pub arma_ma: Vec<f64>,
    pub report: CheckReport,
}

impl CheckJob {
    /// The model folder, refused when it holds a fit on a 2-D index (its coef.parquet
    /// repeats every grid point of the lag index, once per point of the second, which
    /// the 1-D reader would report as 'f_1 has a repeated grid point').
    pub fn model_dir(&self) -> Result<ModelDir> {
        let dir = ModelDir::new(&self.model);
        if let Some(index) = dir.index2() {
            return Err(Error::format(
                &dir.params_path(),
                format!(
                    "the model was fitted with a 2-D index (--index {index}); farma check takes a fit on the lag index x_(t-d) alone"
                ),
            ));
        }
        Ok(dir)
    }

    /// Checks the model's channels `names` in `dir` (from [`CheckJob::model_dir`]) on
    /// `store` (the log [`CheckJob::log`]) in parallel, every failing channel named at
    /// once, and writes the tables when [`CheckJob::output`] is set.
    pub fn run(
        &self,
        dir: &ModelDir,
        store: &Store,
        names: &[String],
    ) -> Result<Vec<ChannelCheck>> {
        let rate = store.sample_rate_hz();
        let done = super::map_channels(&self.log, names, CHECK_CHANNELS_HINT, |name| {
            let (_, model) = dir.load(Some(name))?;
            if let Some(what) = crate::estimator::arma::not_invertible(&model.b) {
                // (an update can leave one, with a note, and a folder can be edited)
                return Err(Error::format(
                    &self.model.join(PARAMS_FILE),
                    format!(
                        "channel '{name}': {what}: the model's residuals on the log would grow without bound; refit the channel"
                    ),
                ));
            }
            let x = store.column(name)?;
            let n = x.len();
            let holdout = (self.holdout_s * rate).round() as usize;
            let start = model.order.lag();
            // (saturating: a --holdout-s beyond the log's length in samples must reach the
            // refusal below, not wrap around and cut the slice after it out of range)
            let need = holdout.saturating_add(start).saturating_add(100);
            if need > n {
                return Err(Error::TooShort {
                    what: format!("check with a {holdout}-sample hold-out"),
                    need: need as u64,
                    have: n as u64,
                });
            }
            let y: Vec<f64> = x.iter().map(|v| v - model.mean).collect();
            let e = model.residuals(&y);
            let train = &x[..n - holdout];
            let tm = train.iter().sum::<f64>() / train.len() as f64;
            let tc: Vec<f64> = train.iter().map(|v| v - tm).collect();
            let arma = fit_arma(&tc, model.p(), model.q()).ok_or_else(|| {
                Error::column(
                    &self.log,
                    format!(
                        "channel '{name}': the linear ARMA({},{}) baseline on the log before the hold-out failed (singular design: a constant or too regular channel)",
                        model.p(),
                        model.q()
                    ),
                )
            })?;
            let baseline = Farma::linear(&arma.ar, &arma.ma, tm, f64::NAN);
            let report = check_model(
                &model,
                &e[..n - holdout],
                &baseline,
                x,
                holdout,
                self.maxlag,
                self.max_degree,
            );
            Ok(ChannelCheck {
                channel: name.to_string(),
                model,
                holdout,
                arma_ar: arma.ar,
                arma_ma: arma.ma,
                report,
            })
        })?;
        if let Some(dir) = &self.output {
            let mut set = OutputSet::new(dir)?;
            let md = vec![
                ("source", self.log.display().to_string()),
                ("model", self.model.display().to_string()),
            ];
            let ws: Vec<_> = done
                .iter()
                .map(|o| (o.channel.clone(), &o.report.whiteness))
                .collect();
            set.parquet("acf.parquet", &acf_table(&ws)?, &md)?;
            set.parquet("ljung_box.parquet", &ljung_box_table(&ws)?, &md)?;
            let ps: Vec<_> = done
                .iter()
                .filter_map(|o| o.report.prediction.as_ref().map(|p| (o.channel.clone(), p)))
                .collect();
            set.parquet("prediction.parquet", &prediction_table(&ps)?, &md)?;
            let pf: Vec<_> = done
                .iter()
                .map(|o| (o.channel.clone(), o.report.poly.as_slice()))
                .collect();
            set.parquet("poly.parquet", &poly_table(&pf)?, &md)?;
            crate::jobs::commit_outputs(set, CHECK_OUTPUTS)?;
        }
        Ok(done)
    }
}
