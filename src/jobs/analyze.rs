//! The analyze job (`farma analyze`): the paper's workflow for every selected channel
//! of a log, in parallel: prep, order selection with the constancy test, the selected
//! fit's check (whiteness, hold-out prediction, polynomial f_m); every table in one
//! folder (Parquet) and a readable summary.txt.

use std::path::PathBuf;
use std::time::Instant;

use rayon::prelude::*;

use super::select::{SelectJob, select_text};
use crate::error::Result;
use crate::log::Progress;
use crate::model::Report;
use crate::model::folder::tables::{ModelRow, coef_table, gcv_table, params_table};
use crate::output::OutputSet;
use crate::store::Store;
use crate::workflow::analyze::{AnalyzeParams, ChannelAnalysis, analyze_channel};
use crate::workflow::prep::PrepParams;
use crate::workflow::select::{Selection, order_name};
use crate::workflow::tables::{
    acf_table, constancy_table, ftest_table, ljung_box_table, poly_table, prediction_table,
    select_table,
};

pub fn summary(a: &ChannelAnalysis, rate: f64) -> String {
    let s: &Selection = &a.selection;
    let mut o = String::new();
    o += "== preparation\n";
    for st in &a.prep.steps {
        o += &format!("  {:<20} {}\n", st.step, st.detail);
    }
    o += &format!(
        "== order selection on the first {} samples ({:.1} s)\n",
        a.n_train,
        a.n_train as f64 / rate
    );
    o += &select_text(&a.name, s, a.constancy.as_ref());
    let r = &s.rows[s.selected];
    let w = &a.check.whiteness;
    o += &format!(
        "== check of {}\n  residual ACF: {} of {} lags outside +-{:.4}\n",
        order_name(r.order),
        w.outside,
        w.acf.len(),
        w.band
    );
    for lb in &w.ljung_box {
        o += &format!(
            "  Ljung-Box lag {:>3}: Q = {:>10.3} on {} df, p = {:.4}\n",
            lb.lag, lb.q, lb.df, lb.p_value
        );
    }
    if let Some(pr) = &a.check.prediction {
        o += &format!(
            "  hold-out prediction of the last {} samples ({:.1} s; hold-out std {:.4e}):\n",
            pr.holdout,
            pr.holdout as f64 / rate,
            pr.holdout_std
        );
        o += "      k     rmse FARMA      rmse ARMA  FARMA/ARMA\n";
        for h in &pr.horizons {
            o += &format!(
                "  {:>5} {:>14.6e} {:>14.6e} {:>11.4}\n",
                h.k,
                h.rmse_farma,
                h.rmse_arma,
                h.rmse_farma / h.rmse_arma
            );
        }
    }
    for pf in &a.check.poly {
        o += &format!(
            "  f_{} ~ polynomial of degree {} in u = x - mean (BIC on the pointwise se): coef {:?}, rms {:.3e}\n",
            pf.m,
            pf.degree,
            pf.coef
                .iter()
                .map(|c| format!("{c:.4e}"))
                .collect::<Vec<_>>(),
            pf.wrms
        );
    }
    o
}

/// The files `farma analyze` writes into its output folder (a run removes those of
/// an earlier run that it does not write).
pub const ANALYZE_OUTPUTS: &[&str] = &[
    "clean.arrow",
    "prep.parquet",
    "replaced.parquet",
    "select.parquet",
    "ftests.parquet",
    "constancy.parquet",
    "coef.parquet",
    "params.parquet",
    "gcv.parquet",
    "acf.parquet",
    "ljung_box.parquet",
    "prediction.parquet",
    "poly.parquet",
    "summary.txt",
];

/// The workflow on channels of one log.
#[derive(Clone, Debug)]
pub struct AnalyzeJob {
    pub log: PathBuf,
    /// The folder to write.
    pub output: PathBuf,
    pub channels: Vec<String>,
    pub prep: PrepParams,
    /// The orders, fit parameters and constancy test (its `log` and `output` unused).
    pub select: SelectJob,
    /// Seconds at the end of each channel held out of the fits and predicted.
    pub holdout_s: f64,
    pub maxlag: usize,
    pub max_degree: usize,
}

/// What an analyze job did.
#[derive(Clone, Debug)]
pub struct AnalyzeDone {
    pub results: Vec<ChannelAnalysis>,
    /// summary.txt's text.
    pub text: String,
    /// Wall-clock seconds.
    pub secs: f64,
}

impl AnalyzeJob {
    /// Analyses every channel in parallel (all or none; every failing channel named
    /// at once) and writes the folder.
    pub fn run(&self, store: &Store, progress: &Progress) -> Result<AnalyzeDone> {
        let t0 = Instant::now();
        let rate = store.sample_rate_hz();
        let (chans, dropped) = super::prep::prep_store(store, &self.channels, &self.prep)?;
        let prm = AnalyzeParams {
            orders: self.select.order_tuples(),
            farma: self.select.farma.clone(),
            constancy: self.select.constancy,
            seed: self.select.seed,
            holdout: (self.holdout_s * rate).round() as usize,
            maxlag: self.maxlag,
            max_degree: self.max_degree,
        };
        // every failing channel is named at once, in channel order, as `farma fit` does
        // (the first error rayon meets is any one of them: each rerun would find the next)
        let bar = progress.count_bar("channels done", chans.len() as u64);
        let results: Vec<ChannelAnalysis> = super::every_channel(
            chans
                .clone()
                .into_par_iter()
                .map(|c| {
                    let name = c.name.clone();
                    let r = analyze_channel(c, &prm)
                        .map_err(|e| super::on_channel(&self.log, &name, e));
                    bar.inc(1);
                    r
                })
                .collect(),
            super::fit::FIT_CHANNELS_HINT,
        )?;
        bar.finish_and_clear();
        let secs = t0.elapsed().as_secs_f64();
        let dir = &self.output;
        let mut set = OutputSet::new(dir)?;
        let md = super::source_metadata(&self.log, store)?;
        super::prep::stage_prep(&mut set, store, (&chans, dropped), &md)?;
        let sels: Vec<(String, &Selection)> = results
            .iter()
            .map(|r| (r.name.clone(), &r.selection))
            .collect();
        set.parquet("select.parquet", &select_table(&sels)?, &md)?;
        set.parquet("ftests.parquet", &ftest_table(&sels)?, &md)?;
        let cons: Vec<_> = results
            .iter()
            .filter_map(|r| {
                r.constancy.as_ref().map(|c| {
                    (
                        r.name.clone(),
                        r.selection.rows[r.selection.selected].order,
                        c,
                    )
                })
            })
            .collect();
        set.parquet("constancy.parquet", &constancy_table(&cons)?, &md)?;
        let models: Vec<ModelRow> = results
            .iter()
            .map(|r| {
                let (m, rep) = &r.selection.fits[r.selection.selected];
                (r.name.clone(), m, Report::Fit(rep))
            })
            .collect();
        set.parquet("coef.parquet", &coef_table(&models)?, &md)?;
        set.parquet("params.parquet", &params_table(&models)?, &md)?;
        set.parquet("gcv.parquet", &gcv_table(&models)?, &md)?;
        let ws: Vec<_> = results
            .iter()
            .map(|r| (r.name.clone(), &r.check.whiteness))
            .collect();
        set.parquet("acf.parquet", &acf_table(&ws)?, &md)?;
        set.parquet("ljung_box.parquet", &ljung_box_table(&ws)?, &md)?;
        let ps: Vec<_> = results
            .iter()
            .filter_map(|r| r.check.prediction.as_ref().map(|p| (r.name.clone(), p)))
            .collect();
        set.parquet("prediction.parquet", &prediction_table(&ps)?, &md)?;
        let polys: Vec<_> = results
            .iter()
            .map(|r| (r.name.clone(), r.check.poly.as_slice()))
            .collect();
        set.parquet("poly.parquet", &poly_table(&polys)?, &md)?;
        let mut text = format!(
            "farma analyze {} ({} channel(s), {} samples at {} Hz; {:.2} s)\n",
            self.log.display(),
            results.len(),
            store.n_samples(),
            rate,
            secs
        );
        for r in &results {
            text += &format!("\n######## {}\n", r.name);
            text += &summary(r, rate);
        }
        set.file("summary.txt", |p| crate::output::write_text(p, &text))?;
        super::commit_outputs(set, ANALYZE_OUTPUTS)?;
        Ok(AnalyzeDone {
            results,
            text,
            secs,
        })
    }
}
