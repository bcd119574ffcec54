//! The analyze job (`farma analyze`): the paper's workflow for every selected channel
//! of a log, in parallel: prep, order selection with the constancy test, the selected
//! fit's check (whiteness, hold-out prediction, polynomial f_m); a verdict per channel
//! ([`verdict`]); every table in one folder (Parquet) and a readable summary.txt.
//!
//! Each channel's tables are committed in its own folder as soon as it is done
//! ([`folder`]): a stopped run keeps the finished channels, and a rerun with the same
//! log and options keeps them instead of analysing them again. The folder-level tables,
//! written as one set at the end, are the concatenation of the channels' tables. Which
//! channels `--channel all` takes comes from their roles ([`choice`]).

pub mod choice;
pub mod folder;
pub mod verdict;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde_json::json;

use super::select::{SelectJob, select_json, select_text};
use crate::error::{Error, Result};
use crate::log::Progress;
use crate::model::Report;
use crate::model::folder::tables::{ModelRow, coef_table, gcv_table, params_table};
use crate::output::OutputSet;
use crate::store::Store;
use crate::workflow::analyze::{AnalyzeParams, ChannelAnalysis, analyze_channel};
use crate::workflow::prep::{ChannelPrep, PrepParams};
use crate::workflow::select::{Selection, order_name};
use crate::workflow::tables::{
    acf_table, constancy_table, ftest_table, ljung_box_table, poly_table, prediction_table,
    select_table,
};
use choice::ChannelChoice;
use folder::{ChannelFiles, Marker};
use verdict::{Verdict, verdict_table, verdicts_of};

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
/// an earlier run that it does not write), besides the channel folders
/// (`channels/<channel>/`, [`folder`]).
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
    "verdict.parquet",
    "summary.txt",
    "report.html",
];

/// The workflow on channels of one log.
#[derive(Clone, Debug)]
pub struct AnalyzeJob {
    pub log: PathBuf,
    /// The folder to write.
    pub output: PathBuf,
    /// The channels and why they were taken.
    pub choice: ChannelChoice,
    pub prep: PrepParams,
    /// The orders, fit parameters and constancy test (its `log` and `output` unused).
    pub select: SelectJob,
    /// Seconds at the end of each channel held out of the fits and predicted.
    pub holdout_s: f64,
    pub maxlag: usize,
    pub max_degree: usize,
    /// Analyse every channel again, also those an earlier run finished with the same
    /// log and options.
    pub fresh: bool,
}

/// What an analyze job did.
#[derive(Clone, Debug)]
pub struct AnalyzeDone {
    /// The channels, in order.
    pub channels: Vec<String>,
    /// Each channel's `--json` line.
    pub json_lines: Vec<String>,
    /// The channels kept from an earlier run.
    pub kept: Vec<String>,
    pub verdicts: Vec<Verdict>,
    /// summary.txt's text.
    pub text: String,
    /// Wall-clock seconds.
    pub secs: f64,
}

/// The `--json` object of one channel's analysis: the keys of `farma select --json`
/// and the check's, and the verdict.
pub fn channel_json(r: &ChannelAnalysis, v: &Verdict, alpha: f64) -> serde_json::Value {
    let mut o = select_json(&r.name, &r.selection, r.constancy.as_ref());
    let w = &r.check.whiteness;
    o["n_train"] = json!(r.n_train);
    o["ljung_box"] = json!(
        w.ljung_box
            .iter()
            .map(|b| json!({"lag": b.lag, "q": b.q, "df": b.df, "p_value": b.p_value}))
            .collect::<Vec<_>>()
    );
    o["acf_outside"] = json!(w.outside);
    o["prediction"] = json!(r.check.prediction.as_ref().map(|p| {
        p.horizons
            .iter()
            .map(|h| {
                json!({"k": h.k, "n": h.n, "rmse_farma": h.rmse_farma, "rmse_arma": h.rmse_arma})
            })
            .collect::<Vec<_>>()
    }));
    o["poly"] = json!(
        r.check
            .poly
            .iter()
            .map(|p| json!({"m": p.m, "degree": p.degree, "coef": p.coef, "wrms": p.wrms}))
            .collect::<Vec<_>>()
    );
    o["replaced"] = json!(r.prep.replaced.len());
    o["stationary"] = json!(r.prep.stationary(alpha));
    o["verdict"] = json!({
        "order": order_name(v.order),
        "nonlinear": v.nonlinear(),
        "constancy_method": v.constancy.as_ref().map(|c| c.method.clone()),
        "constancy_p": v.constancy.as_ref().map(|c| c.p_value),
        "constancy_min_p": v.constancy.as_ref().map(|c| c.min_p),
        "residuals_white": v.residuals_white(),
        "ljung_box_lag": v.ljung_box.map(|(l, _)| l),
        "ljung_box_p": v.ljung_box.map(|(_, p)| p),
        "rmse_ratio_k1": v.rmse_k1.map(|(f, a)| f / a),
    });
    o
}

/// xxHash64 of a series' values (little-endian bytes), 16 hex digits.
fn values_hash(x: &[f64]) -> String {
    use std::hash::Hasher;
    let mut h = twox_hash::XxHash64::with_seed(0);
    let mut buf = Vec::with_capacity(8 * 4096);
    for chunk in x.chunks(4096) {
        buf.clear();
        for v in chunk {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        h.write(&buf);
    }
    format!("{:016x}", h.finish())
}

impl AnalyzeJob {
    /// The hash of everything a channel's results depend on besides its prepared
    /// values: the channel, the preparation's parameters and steps, the rows dropped
    /// to align, the analysis parameters, the rate and the farma version.
    fn options_hash(
        &self,
        c: &ChannelPrep,
        dropped: usize,
        prm: &AnalyzeParams,
        rate: f64,
    ) -> String {
        let text = format!(
            "farma analyze channel 1\n{}\n{:?}\n{:?}\n{}\n{dropped}\n{:?}\n{:?}\n{:?}\n{}\n{}\n{}\n{}\n{rate}\n{}",
            c.name,
            self.prep,
            c.steps,
            c.replaced.len(),
            prm.orders,
            prm.farma,
            prm.constancy,
            prm.seed,
            prm.holdout,
            prm.maxlag,
            prm.max_degree,
            env!("CARGO_PKG_VERSION")
        );
        format!("{:016x}", crate::batch::units::hash64(text.as_bytes()))
    }

    /// One channel's tables, summary and JSON line.
    fn channel_files<'a>(
        &self,
        a: &ChannelAnalysis,
        v: &Verdict,
        store: &Store,
        md: &'a [(&'a str, String)],
    ) -> Result<ChannelFiles<'a>> {
        let rate = store.sample_rate_hz();
        let name = a.name.clone();
        let sels = [(name.clone(), &a.selection)];
        let sel = &a.selection;
        let order = sel.rows[sel.selected].order;
        let cons: Vec<_> = a
            .constancy
            .as_ref()
            .map(|c| (name.clone(), order, c))
            .into_iter()
            .collect();
        let (m, rep) = &sel.fits[sel.selected];
        let models: Vec<ModelRow> = vec![(name.clone(), m, Report::Fit(rep))];
        let ws = [(name.clone(), &a.check.whiteness)];
        let ps: Vec<_> = a
            .check
            .prediction
            .as_ref()
            .map(|p| (name.clone(), p))
            .into_iter()
            .collect();
        let polys = [(name.clone(), a.check.poly.as_slice())];
        let tables = vec![
            ("select", select_table(&sels)?),
            ("ftests", ftest_table(&sels)?),
            ("constancy", constancy_table(&cons)?),
            ("coef", coef_table(&models)?),
            ("params", params_table(&models)?),
            ("gcv", gcv_table(&models)?),
            ("acf", acf_table(&ws)?),
            ("ljung_box", ljung_box_table(&ws)?),
            ("prediction", prediction_table(&ps)?),
            ("poly", poly_table(&polys)?),
            ("verdict", verdict_table(std::slice::from_ref(v))?),
        ];
        debug_assert!(
            tables
                .iter()
                .map(|t| t.0)
                .eq(folder::TABLES.iter().copied())
        );
        let summary_text = format!(
            "farma analyze {}: channel {name} ({} samples at {rate} Hz)\nverdict: {}\n\n######## {name}\n{}",
            self.log.display(),
            a.prep.values.len(),
            v.line(0),
            summary(a, rate)
        );
        let report = crate::report::analysis::channel_section(
            a,
            &v.line(0),
            rate,
            crate::report::unit_of(&name),
        )?
        .finish(&format!("farma analyze {}: {name}", self.log.display()));
        Ok(ChannelFiles {
            tables,
            summary: summary_text,
            json_line: format!("{}\n", channel_json(a, v, self.prep.alpha)),
            report,
            metadata: md,
        })
    }

    /// Analyses every channel in parallel, committing each channel's folder when it is
    /// done (channels an earlier run finished with the same log and options are kept,
    /// unless `fresh`); then, when every channel is done, writes the folder-level
    /// tables and summary.txt as one set. A failing channel fails the run (every
    /// failing channel named at once) after the others are committed.
    pub fn run(&self, store: &Store, progress: &Progress) -> Result<AnalyzeDone> {
        let t0 = Instant::now();
        let rate = store.sample_rate_hz();
        let (chans, dropped) = super::prep::prep_store(store, &self.choice.channels, &self.prep)?;
        let prm = AnalyzeParams {
            orders: self.select.order_tuples(),
            farma: self.select.farma.clone(),
            constancy: self.select.constancy,
            seed: self.select.seed,
            holdout: (self.holdout_s * rate).round() as usize,
            maxlag: self.maxlag,
            max_degree: self.max_degree,
        };
        let fp = crate::batch::units::fingerprint(&self.log)?;
        let md = super::source_metadata(&self.log, store)?;
        OutputSet::check(&self.output)?;
        // the folder is this run's until it ends: a second run into it is refused
        crate::output::ensure_dir(&self.output)?;
        let _lock = crate::output::lock_dir(&self.output)?;
        // each channel's marker, and whether an earlier run's folder is kept (said in
        // channel order, before the work)
        let markers: Vec<(Marker, bool)> = chans
            .iter()
            .map(|c| {
                let m = Marker {
                    channel: c.name.clone(),
                    options_hash: self.options_hash(c, dropped, &prm, rate),
                    data_hash: values_hash(&c.values),
                    log: fp.clone(),
                };
                let keep = !self.fresh && m.matches(&folder::channel_dir(&self.output, &c.name));
                if keep {
                    eprintln!(
                        "farma: note: {}: done in an earlier run (same log and options), kept",
                        c.name
                    );
                }
                (m, keep)
            })
            .collect();
        let bar = progress.count_bar("channels done", chans.len() as u64);
        bar.inc(markers.iter().filter(|m| m.1).count() as u64);
        // every failing channel is named at once, in channel order, as `farma fit` does
        // (the first error rayon meets is any one of them: each rerun would find the next)
        // the channels at once within the memory budget: each runs its order table's
        // fits in parallel (as many as the threads, or the budget, allow)
        let todo: Vec<_> = chans
            .iter()
            .zip(&markers)
            .filter(|(_, (_, keep))| !keep)
            .map(|(c, (m, _))| (c, m))
            .collect();
        let n = chans.iter().map(|c| c.values.len()).max().unwrap_or(0);
        let per_channel = prm.orders.len().min(rayon::current_num_threads()).max(1);
        let at_once = (crate::workflow::budget::fits_in_flight(n) / per_channel).max(1);
        super::every_channel(
            crate::workflow::budget::par_map_waves(&todo, at_once, |&(c, m)| {
                let r = self.run_channel(c, m, &prm, store, &md, progress);
                bar.inc(1);
                r.map_err(|e| super::on_channel(&self.log, &c.name, e))
            }),
            super::fit::FIT_CHANNELS_HINT,
        )?;
        bar.finish_and_clear();
        let kept: Vec<bool> = markers.iter().map(|m| m.1).collect();
        let dirs: Vec<PathBuf> = chans
            .iter()
            .map(|c| folder::channel_dir(&self.output, &c.name))
            .collect();
        let mut set = OutputSet::new(&self.output)?;
        super::prep::stage_prep(&mut set, store, (&chans, dropped), &md)?;
        let mut verdicts = Vec::new();
        for t in folder::TABLES {
            let table = folder::concat_table(&dirs, t)?;
            if *t == "verdict" {
                verdicts = verdicts_of(&table)?;
            }
            set.parquet(&format!("{t}.parquet"), &table, &md)?;
        }
        // no timing in the files: two identical runs write byte-identical folders
        // (the elapsed time goes to stderr, `AnalyzeDone::secs`)
        let mut text = format!(
            "farma analyze {} ({} channel(s), {} samples at {} Hz)\n",
            self.log.display(),
            chans.len(),
            store.n_samples(),
            rate,
        );
        let width = verdicts.iter().map(|v| v.channel.len()).max().unwrap_or(0);
        text += &format!("\n== verdict (alpha {})\n", crate::workflow::ALPHA);
        for v in &verdicts {
            text += &format!("  {}\n", v.line(width));
        }
        text += "\n";
        text += &self.choice.text();
        let mut json_lines = Vec::new();
        for d in &dirs {
            let s = folder::read_text(d, folder::SUMMARY)?;
            let detail = s.find("\n######## ").map_or(s.as_str(), |k| &s[k..]);
            text += detail;
            json_lines.push(folder::read_text(d, folder::JSON_LINE)?);
        }
        set.file("summary.txt", |p| crate::output::write_text(p, &text))?;
        let page = self.report_page(&verdicts, &dirs, width)?;
        set.file(crate::report::REPORT, |p| {
            crate::output::write_text(p, &page)
        })?;
        super::commit_outputs(set, ANALYZE_OUTPUTS)?;
        remove_other_channel_folders(&self.output, &dirs);
        Ok(AnalyzeDone {
            channels: chans.iter().map(|c| c.name.clone()).collect(),
            json_lines,
            kept: chans
                .iter()
                .zip(&kept)
                .filter(|(_, k)| **k)
                .map(|(c, _)| c.name.clone())
                .collect(),
            verdicts,
            text,
            secs: t0.elapsed().as_secs_f64(),
        })
    }

    /// The folder's `report.html`: the verdict of every channel first, then each
    /// channel's plots (the body of its folder's report).
    fn report_page(&self, verdicts: &[Verdict], dirs: &[PathBuf], width: usize) -> Result<String> {
        use crate::report::html::{Page, body_of};
        let log = self.log.display().to_string();
        let mut p = Page::new(&format!("farma analyze: {log}"));
        let lines: Vec<String> = verdicts.iter().map(|v| v.line(width)).collect();
        p.verdict(&lines);
        p.pre(&self.choice.text());
        for d in dirs {
            let page = folder::read_text(d, folder::REPORT)?;
            match body_of(&page) {
                Some(body) => {
                    p.raw(body);
                }
                None => {
                    p.p("warn", &format!("{}: its report has no body", d.display()));
                }
            }
        }
        Ok(p.finish(&format!("farma analyze: {log}")))
    }

    /// Analyses one channel and commits its folder with `marker`.
    fn run_channel(
        &self,
        c: &ChannelPrep,
        marker: &Marker,
        prm: &AnalyzeParams,
        store: &Store,
        md: &[(&str, String)],
        progress: &Progress,
    ) -> Result<()> {
        let dir = folder::channel_dir(&self.output, &c.name);
        progress.line("analyze", &format!("{}: started", c.name));
        let t = Instant::now();
        let r = analyze_channel(c.clone(), prm).and_then(|a| {
            let v = Verdict::of(&a);
            let files = self.channel_files(&a, &v, store, md)?;
            folder::commit_channel(&dir, files, marker)?;
            Ok(v)
        });
        match &r {
            Ok(v) => progress.line(
                "analyze",
                &format!(
                    "{}: done in {:.1} s ({}, nonlinear {})",
                    c.name,
                    t.elapsed().as_secs_f64(),
                    order_name(v.order),
                    match &v.constancy {
                        Some(k) => format!("p = {}", verdict::fmt_p(k.p_value)),
                        None => "not tested".into(),
                    }
                ),
            ),
            Err(e) => progress.line(
                "analyze",
                &format!(
                    "{}: failed: {}",
                    c.name,
                    e.to_string().lines().next().unwrap_or("")
                ),
            ),
        }
        r.map(|_| ())
    }
}

/// Removes the channel folders under `out` that are not `dirs` (an earlier run's
/// channels that this run does not analyse), with a note: the folder holds one run.
fn remove_other_channel_folders(out: &Path, dirs: &[PathBuf]) {
    let Ok(entries) = std::fs::read_dir(out.join(folder::CHANNELS_DIR)) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() && !dirs.contains(&p) {
            match std::fs::remove_dir_all(&p) {
                Ok(()) => eprintln!(
                    "farma: removed {} (an earlier run's channel; this run does not analyse it)",
                    p.display()
                ),
                Err(err) => eprintln!(
                    "farma: warning: could not remove {} (an earlier run's channel): {}",
                    p.display(),
                    Error::output_io(&p, err)
                ),
            }
        }
    }
}
