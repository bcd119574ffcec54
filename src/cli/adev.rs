//! `farma adev LOG`: overlapping Allan deviation (and modified Allan, overlapping
//! Hadamard) of channels, with confidence intervals; text, JSON Lines or Parquet.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use serde_json::{Map, Value, json};

use super::LogArgs;
use crate::error::{Error, Result};
use crate::jobs::adev::{AdevJob, ChannelAdev, allan_table, noise_terms_table};
use crate::log::Progress;
use crate::output::{write_parquet, write_text};
use crate::stats::adev::{CiOptions, Curve, Kind, ONE_SIGMA, TauGrid};
use crate::stats::noise_terms::{Identification, MinimumReading, to_spec};
use crate::stats::rate_unit::{RateUnit, datasheet, gyroparams};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum KindArg {
    /// Overlapping Allan deviation.
    Adev,
    /// Modified Allan deviation.
    Mdev,
    /// Overlapping Hadamard deviation.
    Hdev,
    /// All three.
    All,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TausArg {
    /// m = 1, 2, 4, 8, ... samples.
    Octave,
    /// About --per-decade distinct m per decade.
    Dense,
}

#[derive(Args, Debug)]
pub struct AdevArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC. Channels are rates (deg/s, g, ...).
    pub log: PathBuf,
    /// Channels (comma-separated, or all).
    #[arg(long, default_value = "all")]
    pub channel: String,
    /// Which deviation.
    #[arg(long, value_enum, default_value_t = KindArg::Adev)]
    pub kind: KindArg,
    /// Averaging times.
    #[arg(long, value_enum, default_value_t = TausArg::Octave)]
    pub taus: TausArg,
    /// Averaging factors per decade with --taus dense.
    #[arg(long, default_value_t = 10, value_name = "N")]
    pub per_decade: usize,
    /// Confidence level of the intervals (default: one sigma, 0.683).
    #[arg(long, default_value_t = ONE_SIGMA, value_name = "P")]
    pub confidence: f64,
    /// Noise type assumed for the degrees of freedom: exponent alpha of the frequency
    /// PSD f^alpha (2 white PM, 1 flicker PM, 0 white FM = angle random walk, -1
    /// flicker FM = bias instability, -2 random-walk FM = rate random walk).
    #[arg(
        long,
        default_value_t = 0,
        value_name = "ALPHA",
        allow_hyphen_values = true
    )]
    pub alpha: i32,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the curves as a Parquet table (one row per channel, kind and tau);
    /// a folder (a path that is a folder, or one without an extension that does not
    /// exist) gets allan.parquet, noise_terms.parquet and report.html (the Allan plot
    /// with the noise terms, the PSD; open it in a browser).
    #[arg(long, short, value_name = "OUT.parquet|OUTDIR")]
    pub output: Option<PathBuf>,
    /// Fit the noise terms to taus >= this only (seconds). Default: chosen from the
    /// data, the first octave tau from which the fit is not poor (dispersion <= 3;
    /// every tau when the whole curve fits), which leaves out a real sensor's short-tau
    /// region (output filter, quantization); a note on stderr says which and why.
    #[arg(long, value_name = "SECONDS")]
    pub fit_tau_min: Option<f64>,
    /// Write the identified noise terms as a simulation spec (TOML, contracts.md section 2).
    #[arg(long, value_name = "FILE.toml")]
    pub spec_out: Option<PathBuf>,
    /// The channels' rate unit, for the noise terms in datasheet units (deg/sqrt(h),
    /// deg/h, deg/h/sqrt(h)) and MATLAB gyroparams' SI ones: deg/s, rad/s or deg/h
    /// (default: from each channel's name, `_dps`, `_rps`, `_dph`; none otherwise).
    #[arg(long, value_name = "UNIT")]
    pub unit: Option<String>,
    /// Also write the noise terms as a Parquet table (one row per channel and term: the
    /// IEEE 952 coefficient with its uncertainty and unit, the taus fitted, and the
    /// datasheet and gyroparams forms; the table of the batch task `adev`).
    #[arg(long, value_name = "TERMS.parquet")]
    pub terms_out: Option<PathBuf>,
}

impl AdevArgs {
    fn kinds(&self) -> Vec<Kind> {
        match self.kind {
            KindArg::Adev => vec![Kind::Adev],
            KindArg::Mdev => vec![Kind::Mdev],
            KindArg::Hdev => vec![Kind::Hdev],
            KindArg::All => Kind::ALL.to_vec(),
        }
    }

    fn grid(&self) -> Result<TauGrid> {
        Ok(match self.taus {
            TausArg::Octave => TauGrid::Octave,
            TausArg::Dense => {
                if self.per_decade == 0 {
                    return Err(Error::Usage("--per-decade must be at least 1".into()));
                }
                TauGrid::Dense {
                    per_decade: self.per_decade,
                }
            }
        })
    }
}

pub fn run(a: AdevArgs, progress: &Progress) -> Result<()> {
    if !(a.confidence > 0.0 && a.confidence < 1.0) {
        return Err(Error::Usage(format!(
            "--confidence must be between 0 and 1, got {}",
            a.confidence
        )));
    }
    if !(-4..=2).contains(&a.alpha) {
        return Err(Error::Usage(format!(
            "--alpha must be an integer from -4 to 2, got {}",
            a.alpha
        )));
    }
    if let Some(t) = a.fit_tau_min
        && !(t.is_finite() && t >= 0.0)
    {
        return Err(Error::Usage(format!(
            "--fit-tau-min must be a non-negative number of seconds, got {t}"
        )));
    }
    let grid = a.grid()?;
    let kinds = a.kinds();
    let ci = CiOptions {
        confidence: a.confidence,
        alpha: a.alpha,
    };
    let store = a.log_args.open(&a.log, progress)?;
    let names = store.select_channels(&a.channel)?;
    let rate_hz = store.sample_rate_hz();
    let (start, len) = crate::jobs::longest_segment(&store, &a.log);
    let job = AdevJob {
        log: a.log.clone(),
        channels: names,
        kinds,
        grid,
        ci,
        fit_tau_min: a.fit_tau_min,
        unit: a.unit.as_deref().map(RateUnit::from_flag).transpose()?,
    };
    let done = job.run(&store, (start, len))?;
    for r in &done {
        if let Err(e) = &r.terms {
            if a.spec_out.is_some() {
                return Err(Error::Usage(format!("--spec-out: {e}")));
            }
            eprintln!("farma: warning: no noise terms: {e}");
        }
        if let Ok(id) = &r.terms {
            eprintln!("farma: note: {}: {}", r.channel, id.tau_min.explain());
            for w in fit_warnings(id, a.fit_tau_min) {
                eprintln!("farma: warning: {}: {w}", r.channel);
            }
        }
    }
    let results: Vec<(&str, &[Curve])> = done
        .iter()
        .map(|r| (r.channel.as_str(), r.curves.as_slice()))
        .collect();
    if let Some(path) = &a.spec_out {
        let chans: Vec<(String, &Identification, f64)> = done
            .iter()
            .filter_map(|r| {
                r.terms
                    .as_ref()
                    .ok()
                    .map(|id| (r.channel.clone(), id, r.mean))
            })
            .collect();
        let spec = to_spec(rate_hz, &chans);
        let text = format!(
            "# identified by farma adev from {} (IEEE Std 952 terms fitted to the octave Allan variance)\n{}",
            a.log.display(),
            spec.to_toml()?
        );
        write_text(path, &text)?;
    }

    if let Some(out) = a.output.as_ref().filter(|o| is_folder_output(o)) {
        job.write(out, &store, &done)?;
        eprintln!(
            "farma: wrote {} (open {} in a browser)",
            crate::jobs::adev::ADEV_OUTPUTS.join(", "),
            out.join(crate::report::REPORT).display()
        );
    } else if let Some(out) = &a.output {
        write_parquet(
            out,
            &allan_table(&done)?,
            &[
                ("log", a.log.display().to_string()),
                ("sample_rate_hz", rate_hz.to_string()),
                ("confidence", a.confidence.to_string()),
                ("alpha", a.alpha.to_string()),
                ("farma.command", "adev".to_string()),
            ],
        )?;
    }
    if let Some(out) = &a.terms_out {
        write_parquet(
            out,
            &noise_terms_table(&done)?,
            &[
                ("log", a.log.display().to_string()),
                ("sample_rate_hz", rate_hz.to_string()),
                ("farma.command", "adev".to_string()),
            ],
        )?;
    }
    let n = len;
    if a.json {
        for (name, cs) in &results {
            let mut o = Map::new();
            o.insert("channel".into(), json!(name));
            o.insert("log".into(), json!(a.log.display().to_string()));
            o.insert("sample_rate_hz".into(), json!(rate_hz));
            o.insert("n_samples".into(), json!(n));
            o.insert("taus".into(), json!(grid_name(grid)));
            o.insert("confidence".into(), json!(a.confidence));
            o.insert("alpha".into(), json!(a.alpha));
            for c in cs.iter() {
                let k = c.kind.name();
                let col = |f: &dyn Fn(&crate::stats::adev::Point) -> Value| -> Value {
                    Value::Array(c.points.iter().map(f).collect())
                };
                if c.kind == Kind::Adev {
                    o.insert("tau_s".into(), col(&|p| json!(p.tau_s)));
                }
                o.insert(format!("{k}_tau_s"), col(&|p| json!(p.tau_s)));
                o.insert(format!("{k}_m"), col(&|p| json!(p.m)));
                o.insert(k.into(), col(&|p| json!(p.dev)));
                o.insert(format!("{k}_lo"), col(&|p| json!(p.lo)));
                o.insert(format!("{k}_hi"), col(&|p| json!(p.hi)));
                o.insert(format!("{k}_edf"), col(&|p| json!(p.edf)));
            }
            if let Some(out) = &a.output {
                o.insert("output".into(), json!(out.display().to_string()));
            }
            let done_ch = done.iter().find(|r| r.channel == *name);
            let unit = done_ch.and_then(|r| r.unit);
            let id = done_ch.map(|r| &r.terms);
            match id {
                Some(Ok(id)) => {
                    o.insert("terms".into(), terms_json(id, unit));
                    o.insert("terms_fit".into(), terms_fit_json(id));
                    o.insert(
                        "bias_instability_reading".into(),
                        reading_json(id.minimum.as_ref(), unit),
                    );
                }
                Some(Err(e)) => {
                    o.insert("terms".into(), Value::Null);
                    o.insert("terms_error".into(), json!(e.to_string()));
                }
                None => {}
            }
            if let Some(p) = &a.spec_out {
                o.insert("spec_out".into(), json!(p.display().to_string()));
            }
            outln!("{}", Value::Object(o));
        }
        return Ok(());
    }
    outln!(
        "log       {} ({} samples at {} Hz, {} taus)",
        a.log.display(),
        n,
        rate_hz,
        grid_name(grid)
    );
    outln!(
        "interval  {:.1} % from Greenhall's EDF, noise alpha = {}",
        100.0 * a.confidence,
        a.alpha
    );
    for (name, cs) in &results {
        for c in cs.iter() {
            outln!();
            outln!(
                "{:<16} {:<5} {:>14} {:>10} {:>14} {:>14} {:>14} {:>12}",
                "channel",
                "kind",
                "tau_s",
                "m",
                "dev",
                "lo",
                "hi",
                "edf"
            );
            for p in &c.points {
                outln!(
                    "{:<16} {:<5} {:>14.6e} {:>10} {:>14.6e} {:>14.6e} {:>14.6e} {:>12.4e}",
                    name,
                    c.kind.name(),
                    p.tau_s,
                    p.m,
                    p.dev,
                    p.lo,
                    p.hi,
                    p.edf
                );
            }
        }
    }
    print_terms(&done)?;
    Ok(())
}

/// `terms` of the JSON line: {kind: {coef: value, coef_unc: u, unit: ...}} for each
/// selected term (contracts.md section 4); gauss_markov also has tau_s, tau_s_unc.
fn terms_json(id: &Identification, unit: Option<RateUnit>) -> Value {
    let mut o = Map::new();
    for t in &id.terms {
        let c = t.term.coef_name();
        let mut e = Map::new();
        e.insert(c.into(), json!(t.coef.value));
        e.insert(format!("{c}_unc"), json!(t.coef.unc));
        if let Some(ct) = t.corr_time_s {
            e.insert("tau_s".into(), json!(ct.value));
            e.insert("tau_s_unc".into(), json!(ct.unc));
        }
        e.insert("unit".into(), json!(t.term.coef_unit()));
        let kind = t.term.kind_name();
        let conv = |c: Option<crate::stats::rate_unit::Converted>| {
            c.map_or(
                Value::Null,
                |c| json!({"name": c.name, "value": c.value, "unc": c.unc, "unit": c.unit}),
            )
        };
        if let Some(u) = unit {
            e.insert("rate_unit".into(), json!(u.name()));
            e.insert(
                "datasheet".into(),
                conv(datasheet(kind, t.coef.value, t.coef.unc, u)),
            );
            e.insert(
                "gyroparams".into(),
                conv(gyroparams(kind, t.coef.value, t.coef.unc, u)),
            );
        }
        o.insert(kind.into(), Value::Object(e));
    }
    Value::Object(o)
}

/// `bias_instability_reading`: the curve's minimum / 0.664 as a datasheet reads it
/// ([`crate::stats::noise_terms::reading`]); null when the curve has no minimum.
fn reading_json(r: Option<&MinimumReading>, unit: Option<RateUnit>) -> Value {
    let Some(r) = r else { return Value::Null };
    let mut e = Map::new();
    e.insert("b".into(), json!(r.b));
    e.insert("b_unc".into(), json!(r.b_unc));
    e.insert("unit".into(), json!("u"));
    e.insert("tau_s".into(), json!(r.tau_s));
    e.insert("m".into(), json!(r.m));
    e.insert("adev".into(), json!(r.adev));
    e.insert("edf".into(), json!(r.edf));
    e.insert("at_last_tau".into(), json!(r.at_last_tau));
    if let Some(u) = unit {
        let conv = |c: Option<crate::stats::rate_unit::Converted>| {
            c.map_or(
                Value::Null,
                |c| json!({"name": c.name, "value": c.value, "unc": c.unc, "unit": c.unit}),
            )
        };
        e.insert("rate_unit".into(), json!(u.name()));
        e.insert(
            "datasheet".into(),
            conv(datasheet("bias_instability", r.b, r.b_unc, u)),
        );
        e.insert(
            "gyroparams".into(),
            conv(gyroparams("bias_instability", r.b, r.b_unc, u)),
        );
    }
    Value::Object(e)
}

/// Warnings on a poor noise-term fit, each with what to try: a dispersion above
/// [`crate::jobs::adev::POOR_DISPERSION`], and every term whose uncertainty exceeds its value.
fn fit_warnings(id: &Identification, fit_tau_min: Option<f64>) -> Vec<String> {
    let hint = match fit_tau_min {
        None => {
            "the automatic tau range found no first tau from which the terms fit (see the note); try a larger --fit-tau-min, or look at the curve for a feature the IEEE 952 terms do not model (a sinusoid, a temperature effect)"
        }
        Some(_) => "try a larger --fit-tau-min, or a longer log for the long-tau terms",
    };
    let mut out = Vec::new();
    if id.dispersion > crate::jobs::adev::POOR_DISPERSION {
        out.push(format!(
            "the noise-term fit is poor: dispersion {:.2} (X^2 per degree of freedom over {} taus; above {} the selected terms miss the curve's shape); {hint}",
            id.dispersion,
            id.points.len(),
            crate::jobs::adev::POOR_DISPERSION
        ));
    }
    for t in id.terms.iter().filter(|t| t.coef.unc > t.coef.value.abs()) {
        out.push(format!(
            "{} {} = {:.3e} +- {:.3e}: its uncertainty exceeds its value, so the log does not determine it; {hint}",
            t.term.kind_name(),
            t.term.coef_name(),
            t.coef.value,
            t.coef.unc
        ));
    }
    out
}

/// `terms_fit`: how the terms were chosen and how well they fit.
fn terms_fit_json(id: &Identification) -> Value {
    json!({
        "method": "Gamma maximum likelihood on the octave overlapping AVAR (Greenhall EDF), subsets ranked by deviance + penalty * parameters",
        "deviance": id.deviance,
        "pearson_chi2": id.pearson,
        "dof": id.dof,
        "dispersion": id.dispersion,
        "penalty": id.penalty,
        "tau_min_s": id.tau_min.tau_s,
        "tau_min_automatic": id.tau_min.automatic,
        "tau_min_tries": id.tau_min.tries,
        "tau_min_note": id.tau_min.explain(),
        "tau_s": id.points.iter().map(|p| p.tau_s).collect::<Vec<f64>>(),
        "avar": id.points.iter().map(|p| p.avar).collect::<Vec<f64>>(),
        "avar_model": id.points.iter().map(|p| p.model).collect::<Vec<f64>>(),
        "edf": id.points.iter().map(|p| p.edf).collect::<Vec<f64>>(),
        "candidates": id.candidates,
    })
}

fn print_terms(done: &[ChannelAdev]) -> Result<()> {
    outln!();
    outln!(
        "noise terms (IEEE Std 952) fitted to the octave Allan variance; uncertainty: one standard uncertainty; u = the channel's unit"
    );
    outln!(
        "{:<16} {:<18} {:<6} {:>14} {:>12} {:<10} datasheet (gyroparams)",
        "channel",
        "kind",
        "param",
        "value",
        "unc",
        "unit"
    );
    for r in done {
        let name = &r.channel;
        let Ok(id) = &r.terms else {
            outln!("{name:<16} (none: the log is too short)");
            continue;
        };
        for t in &id.terms {
            let kind = t.term.kind_name();
            let sheet = match r.unit {
                Some(u) => {
                    let ds = datasheet(kind, t.coef.value, t.coef.unc, u)
                        .map(|c| format!("{} {:.4e} +- {:.2e} {}", c.name, c.value, c.unc, c.unit));
                    let gp = gyroparams(kind, t.coef.value, t.coef.unc, u)
                        .map(|c| format!(" ({} {:.4e} {})", c.name, c.value, c.unit));
                    format!("{}{}", ds.unwrap_or_default(), gp.unwrap_or_default())
                }
                None => "(no rate unit: --unit deg/s|rad/s|deg/h)".into(),
            };
            outln!(
                "{:<16} {:<18} {:<6} {:>14.6e} {:>12.3e} {:<10} {}",
                name,
                kind,
                t.term.coef_name(),
                t.coef.value,
                t.coef.unc,
                t.term.coef_unit(),
                sheet
            );
            if let Some(ct) = t.corr_time_s {
                outln!(
                    "{:<16} {:<18} {:<6} {:>14.6e} {:>12.3e} {:<10}",
                    name,
                    t.term.kind_name(),
                    "tau_s",
                    ct.value,
                    ct.unc,
                    "s"
                );
            }
        }
        outln!(
            "{:<16} fit: {} taus, deviance {:.3}, dispersion {:.3}",
            name,
            id.points.len(),
            id.deviance,
            id.dispersion
        );
        if let Some(m) = &id.minimum {
            let sheet = r
                .unit
                .and_then(|u| datasheet("bias_instability", m.b, m.b_unc, u))
                .map(|c| format!(" = {:.4e} +- {:.2e} {}", c.value, c.unc, c.unit))
                .unwrap_or_default();
            outln!(
                "{:<16} bias instability read off the curve's minimum (as datasheets and MATLAB's allanvar example read it): adev {:.6e} at tau = {} s / 0.664 = {:.6e} +- {:.3e} u{}{}",
                name,
                m.adev,
                crate::fmt::num(m.tau_s),
                m.b,
                m.b_unc,
                sheet,
                if m.at_last_tau {
                    " (the curve still falls at its last tau: an upper bound)"
                } else {
                    ""
                }
            );
        }
        outln!(
            "{:<16} taus fitted: {} to {} s (first tau {})",
            name,
            crate::fmt::num(id.tau_min.tau_s),
            crate::fmt::num(id.points.last().map_or(f64::NAN, |p| p.tau_s)),
            if id.tau_min.automatic {
                "chosen automatically, see the note on stderr"
            } else {
                "from --fit-tau-min"
            }
        );
    }
    Ok(())
}

fn grid_name(g: TauGrid) -> String {
    match g {
        TauGrid::Octave => "octave".into(),
        TauGrid::Dense { per_decade } => format!("dense ({per_decade} per decade)"),
    }
}

/// Whether `-o PATH` names a folder: one that exists, or a path without an extension
/// that does not exist (`-o OUT.parquet` stays a table).
fn is_folder_output(path: &std::path::Path) -> bool {
    path.is_dir() || (!path.exists() && path.extension().is_none())
}
