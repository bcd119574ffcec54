//! The Allan-deviation job (`farma adev`, the batch task `adev`): every selected
//! channel's deviation curves with their confidence intervals
//! ([`crate::stats::adev`]) on the log's longest uniform segment, and the IEEE Std 952
//! noise terms fitted to the octave Allan variance ([`crate::stats::noise_terms`]);
//! as a folder, `allan.parquet` and `noise_terms.parquet`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, Int64Array, StringArray};
use rayon::prelude::*;

use crate::error::Result;
use crate::output::{OutputSet, batch};
use crate::stats::adev::{CiOptions, Curve, Kind, TauGrid, curves, phase};
use crate::stats::noise_terms::{AvarPoint, Identification, Options, identify_from, octave_avar};
use crate::stats::rate_unit::{RateUnit, datasheet, gyroparams};
use crate::store::Store;

/// A noise-term fit whose dispersion (the Pearson X^2 per degree of freedom) is above
/// this is warned about (the command's stderr and its report): the selected terms miss
/// the curve's shape somewhere. The automatic tau range uses the same bound.
pub use crate::stats::noise_terms::POOR_DISPERSION;

/// The files an Allan-deviation folder holds.
pub const ADEV_OUTPUTS: &[&str] = &["allan.parquet", "noise_terms.parquet", "report.html"];

/// Deviation curves and noise terms of channels of one log.
#[derive(Clone, Debug)]
pub struct AdevJob {
    pub log: PathBuf,
    pub channels: Vec<String>,
    pub kinds: Vec<Kind>,
    pub grid: TauGrid,
    pub ci: CiOptions,
    /// Fit the noise terms to taus >= this only (seconds).
    pub fit_tau_min: Option<f64>,
    /// The channels' rate unit (`--unit`); None: each from its name (`_dps`, ...), the
    /// datasheet figures left out where that finds none.
    pub unit: Option<RateUnit>,
}

/// One channel's curves and noise terms.
#[derive(Debug)]
pub struct ChannelAdev {
    pub channel: String,
    pub curves: Vec<Curve>,
    /// The noise terms, or why none could be fitted.
    pub terms: Result<Identification>,
    /// The channel's mean over the segment (the spec's bias when written as one).
    pub mean: f64,
    /// Its rate unit: `--unit`, else from its name; None when neither gives one.
    pub unit: Option<RateUnit>,
    /// Welch's PSD of the segment (for the report), None where it cannot be had.
    pub psd: Option<crate::stats::psd::Psd>,
    /// The segment's autocorrelation to [`REPORT_ACF_LAGS`] lags (for the report), None
    /// where it cannot be had (a constant channel).
    pub acf: Option<crate::stats::acf::Acf>,
}

/// Lags of the autocorrelation in adev's report (fewer on a shorter segment).
pub const REPORT_ACF_LAGS: usize = 500;

impl AdevJob {
    /// The curves and terms of every channel, in parallel, on the rows `(start, len)`
    /// (the longest uniform segment); every channel whose curves fail is named at once.
    pub fn run(&self, store: &Store, (start, len): (usize, usize)) -> Result<Vec<ChannelAdev>> {
        let rate_hz = store.sample_rate_hz();
        super::every_channel(
            self.channels
                .par_iter()
                .map(|name| {
                    let y = &store.column(name)?[start..start + len];
                    let what = format!("{}: channel '{name}'", self.log.display());
                    let c = curves(&what, y, rate_hz, &self.kinds, self.grid, self.ci)?;
                    // the identification fits the octave AVAR: the curve's when it is one
                    let octave: Vec<AvarPoint> = match c.iter().find(|c| c.kind == Kind::Adev) {
                        Some(c) if self.grid == TauGrid::Octave => c
                            .points
                            .iter()
                            .map(|p| AvarPoint {
                                m: p.m,
                                tau_s: p.tau_s,
                                avar: p.dev * p.dev,
                            })
                            .collect(),
                        _ => octave_avar(y, rate_hz),
                    };
                    let opts = Options {
                        tau_min_s: self.fit_tau_min,
                        ..Options::default()
                    };
                    let terms = identify_from(&what, y, rate_hz, &octave, &opts);
                    let psd = crate::stats::psd::welch(
                        &what,
                        y,
                        rate_hz,
                        crate::stats::psd::default_segment_len(y.len()),
                        crate::stats::psd::Detrend::Constant,
                    )
                    .ok();
                    let acf = crate::stats::acf::acf(
                        &what,
                        y,
                        REPORT_ACF_LAGS.min(crate::stats::acf::default_max_lag(y.len())),
                    )
                    .ok();
                    Ok(ChannelAdev {
                        channel: name.clone(),
                        curves: c,
                        terms,
                        mean: phase::mean(y),
                        unit: self.unit.or_else(|| RateUnit::from_channel_name(name)),
                        psd,
                        acf,
                    })
                })
                .collect(),
            "leave the failing ones out of --channel",
        )
    }

    /// Writes `allan.parquet`, `noise_terms.parquet` and `report.html` into the
    /// folder `dir`.
    pub fn write(&self, dir: &Path, store: &Store, done: &[ChannelAdev]) -> Result<()> {
        let mut set = OutputSet::new(dir)?;
        let md = super::source_metadata(&self.log, store)?;
        set.parquet("allan.parquet", &allan_table(done)?, &md)?;
        set.parquet("noise_terms.parquet", &noise_terms_table(done)?, &md)?;
        let page = crate::report::allan::adev_page(
            &self.log.display().to_string(),
            store.sample_rate_hz(),
            done,
        )?;
        set.file(crate::report::REPORT, |p| {
            crate::output::write_text(p, &page)
        })?;
        super::commit_outputs(set, ADEV_OUTPUTS)
    }
}

/// `term` of the row of `noise_terms.parquet` that holds the bias instability read off
/// the curve's minimum ([`crate::stats::noise_terms::reading`]): its `fit_tau_min_s`
/// and `fit_tau_max_s` are the tau of the minimum, `n_taus` 1, `deviance` and
/// `dispersion` NaN.
pub const READING_TERM: &str = "bias_instability_reading";

/// The curves: channel, kind, tau_s, m, dev, dev_lo, dev_hi, edf, n_terms (one row per
/// channel, kind and tau).
pub fn allan_table(done: &[ChannelAdev]) -> Result<arrow_array::RecordBatch> {
    let mut channel = Vec::new();
    let mut kind = Vec::new();
    let (mut m, mut n_terms) = (Vec::new(), Vec::new());
    let (mut tau, mut dev, mut lo, mut hi, mut edf) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for r in done {
        for c in &r.curves {
            for p in &c.points {
                channel.push(r.channel.as_str());
                kind.push(c.kind.name());
                m.push(p.m as i64);
                n_terms.push(p.n_terms as i64);
                tau.push(p.tau_s);
                dev.push(p.dev);
                lo.push(p.lo);
                hi.push(p.hi);
                edf.push(p.edf);
            }
        }
    }
    let f = |v: Vec<f64>| Arc::new(Float64Array::from(v)) as ArrayRef;
    batch(vec![
        ("channel", Arc::new(StringArray::from(channel)) as ArrayRef),
        ("kind", Arc::new(StringArray::from(kind)) as ArrayRef),
        ("tau_s", f(tau)),
        ("m", Arc::new(Int64Array::from(m)) as ArrayRef),
        ("dev", f(dev)),
        ("dev_lo", f(lo)),
        ("dev_hi", f(hi)),
        ("edf", f(edf)),
        ("n_terms", Arc::new(Int64Array::from(n_terms)) as ArrayRef),
    ])
}

/// The noise terms: one row per channel and identified term: channel, term
/// (quantization, white_noise, bias_instability, rate_random_walk, rate_ramp,
/// gauss_markov), coef (q, n, b, k, r, sigma), value, unc (one standard uncertainty),
/// unit (u the channel's unit), corr_time_s and corr_time_s_unc (Gauss-Markov; NaN
/// otherwise), and the fit's n_taus, deviance and dispersion, the taus it used
/// (fit_tau_min_s, fit_tau_max_s) and whether the first was chosen from the data
/// (fit_tau_min_automatic; false: `--fit-tau-min`); rate_unit (the channel's, null when unknown) and the
/// term as a datasheet prints it (datasheet_name, datasheet_value, datasheet_unc,
/// datasheet_unit) and as MATLAB's gyroparams names it (gyroparams_name,
/// gyroparams_value, gyroparams_unc, gyroparams_unit, SI), null without a rate unit or
/// a gyroparams property ([`crate::stats::rate_unit`]). A channel whose terms could not
/// be fitted has no row.
pub fn noise_terms_table(done: &[ChannelAdev]) -> Result<arrow_array::RecordBatch> {
    /// One row: a fitted term, or the curve-minimum reading.
    struct Row<'a> {
        channel: &'a str,
        term: &'static str,
        coef: &'static str,
        unit: &'static str,
        value: f64,
        unc: f64,
        corr_time_s: Option<crate::stats::noise_terms::Estimate>,
        n_taus: i64,
        deviance: f64,
        dispersion: f64,
        tau_range_s: (f64, f64),
        tau_auto: bool,
        rate_unit: Option<RateUnit>,
        /// The kind the datasheet and gyroparams forms are those of.
        as_kind: &'static str,
    }
    let mut rows = Vec::new();
    for r in done {
        let Ok(id) = &r.terms else { continue };
        let taus = id.points.iter().map(|p| p.tau_s);
        let range = taus.fold((f64::INFINITY, f64::NEG_INFINITY), |a, t| {
            (a.0.min(t), a.1.max(t))
        });
        for t in &id.terms {
            rows.push(Row {
                channel: &r.channel,
                term: t.term.kind_name(),
                coef: t.term.coef_name(),
                unit: t.term.coef_unit(),
                value: t.coef.value,
                unc: t.coef.unc,
                corr_time_s: t.corr_time_s,
                n_taus: id.points.len() as i64,
                deviance: id.deviance,
                dispersion: id.dispersion,
                tau_range_s: range,
                tau_auto: id.tau_min.automatic,
                rate_unit: r.unit,
                as_kind: t.term.kind_name(),
            });
        }
        // the datasheet reading: one tau, no fit
        if let Some(m) = &id.minimum {
            rows.push(Row {
                channel: &r.channel,
                term: READING_TERM,
                coef: "b",
                unit: "u",
                value: m.b,
                unc: m.b_unc,
                corr_time_s: None,
                n_taus: 1,
                deviance: f64::NAN,
                dispersion: f64::NAN,
                tau_range_s: (m.tau_s, m.tau_s),
                tau_auto: false,
                rate_unit: r.unit,
                as_kind: "bias_instability",
            });
        }
    }
    let ds: Vec<_> = rows
        .iter()
        .map(|w| {
            w.rate_unit
                .and_then(|u| datasheet(w.as_kind, w.value, w.unc, u))
        })
        .collect();
    let gp: Vec<_> = rows
        .iter()
        .map(|w| {
            w.rate_unit
                .and_then(|u| gyroparams(w.as_kind, w.value, w.unc, u))
        })
        .collect();
    let col_f = |g: &dyn Fn(&Row) -> f64| rows.iter().map(g).collect::<Vec<f64>>();
    let col_s = |g: &dyn Fn(&Row) -> &'static str| rows.iter().map(g).collect::<Vec<&str>>();
    let channel: Vec<&str> = rows.iter().map(|w| w.channel).collect();
    let term = col_s(&|w| w.term);
    let coef = col_s(&|w| w.coef);
    let unit = col_s(&|w| w.unit);
    let value = col_f(&|w| w.value);
    let unc = col_f(&|w| w.unc);
    let ct = col_f(&|w| w.corr_time_s.map_or(f64::NAN, |c| c.value));
    let ct_unc = col_f(&|w| w.corr_time_s.map_or(f64::NAN, |c| c.unc));
    let n_taus: Vec<i64> = rows.iter().map(|w| w.n_taus).collect();
    let deviance = col_f(&|w| w.deviance);
    let dispersion = col_f(&|w| w.dispersion);
    let tau_lo = col_f(&|w| w.tau_range_s.0);
    let tau_hi = col_f(&|w| w.tau_range_s.1);
    let tau_auto: Vec<bool> = rows.iter().map(|w| w.tau_auto).collect();
    let rate_unit: Vec<Option<&str>> = rows
        .iter()
        .map(|w| w.rate_unit.map(RateUnit::name))
        .collect();
    let ds_name: Vec<_> = ds.iter().map(|c| c.as_ref().map(|c| c.name)).collect();
    let ds_value: Vec<_> = ds.iter().map(|c| c.as_ref().map(|c| c.value)).collect();
    let ds_unc: Vec<_> = ds.iter().map(|c| c.as_ref().map(|c| c.unc)).collect();
    let ds_unit: Vec<_> = ds.iter().map(|c| c.as_ref().map(|c| c.unit)).collect();
    let gp_name: Vec<_> = gp.iter().map(|c| c.as_ref().map(|c| c.name)).collect();
    let gp_value: Vec<_> = gp.iter().map(|c| c.as_ref().map(|c| c.value)).collect();
    let gp_unc: Vec<_> = gp.iter().map(|c| c.as_ref().map(|c| c.unc)).collect();
    let gp_unit: Vec<_> = gp.iter().map(|c| c.as_ref().map(|c| c.unit)).collect();
    let s = |v: Vec<&str>| Arc::new(StringArray::from(v)) as ArrayRef;
    let f = |v: Vec<f64>| Arc::new(Float64Array::from(v)) as ArrayRef;
    let os = |v: Vec<Option<&str>>| Arc::new(StringArray::from(v)) as ArrayRef;
    let of = |v: Vec<Option<f64>>| Arc::new(Float64Array::from(v)) as ArrayRef;
    batch(vec![
        ("channel", Arc::new(StringArray::from(channel)) as ArrayRef),
        ("term", s(term)),
        ("coef", s(coef)),
        ("value", f(value)),
        ("unc", f(unc)),
        ("unit", s(unit)),
        ("corr_time_s", f(ct)),
        ("corr_time_s_unc", f(ct_unc)),
        ("n_taus", Arc::new(Int64Array::from(n_taus)) as ArrayRef),
        ("deviance", f(deviance)),
        ("dispersion", f(dispersion)),
        ("fit_tau_min_s", f(tau_lo)),
        ("fit_tau_max_s", f(tau_hi)),
        (
            "fit_tau_min_automatic",
            Arc::new(arrow_array::BooleanArray::from(tau_auto)) as ArrayRef,
        ),
        ("rate_unit", os(rate_unit)),
        ("datasheet_name", os(ds_name)),
        ("datasheet_value", of(ds_value)),
        ("datasheet_unc", of(ds_unc)),
        ("datasheet_unit", os(ds_unit)),
        ("gyroparams_name", os(gp_name)),
        ("gyroparams_value", of(gp_value)),
        ("gyroparams_unc", of(gp_unc)),
        ("gyroparams_unit", os(gp_unit)),
    ])
}
