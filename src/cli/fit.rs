//! `farma fit LOG --channel C --order p,q,d -o OUTDIR`: the arguments of a fit,
//! turned into a [`FitJob`] (or, with `--index lag,CHANNEL`, a 2-D fit); the job's
//! result printed (stderr lines, `--json` on stdout).

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::LogArgs;
use super::choices::{FitPathArg, InitArg};
use crate::error::{Error, Result};
use crate::estimator::multivariate::{Farma2Params, check_grid2};
use crate::estimator::{FarmaParams, FitPath, Init};
use crate::jobs::fit::{DEFAULT_GRID, FitJob};
use crate::jobs::fit2::Fit2Job;
use crate::log::Progress;
use crate::model::folder::tables::fit_json;
use crate::model::{Order, Report};
use crate::output::OutputSet;

#[derive(Args, Debug)]
pub struct FitArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC.
    pub log: PathBuf,
    /// Channels to fit (comma-separated, or all); fitted in parallel.
    #[arg(long, required = true)]
    pub channel: String,
    /// Model order p,q,d.
    #[arg(long, default_value = "2,1,1", value_name = "P,Q,D")]
    pub order: String,
    /// Output folder (coef.parquet, params.parquet, gcv.parquet[, residuals.parquet]).
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: PathBuf,
    /// A fixed bandwidth instead of GCV.
    #[arg(long, value_name = "H")]
    pub bandwidth: Option<f64>,
    /// Grid points over the central 98 % of the index values [default: 201] (a 2-D
    /// index takes --index-grid instead).
    #[arg(long, value_name = "N")]
    pub grid: Option<usize>,
    /// Computation of the local fits [default: fast] (a 2-D index, --index
    /// lag,CHANNEL, always takes the direct path: KD-tree gather per grid point; an
    /// explicit --method fast there is warned about).
    #[arg(long, value_enum)]
    pub method: Option<FitPathArg>,
    /// Start of the alternation (`literal`: the paper's scheme, for comparison).
    #[arg(long, value_enum, default_value_t = InitArg::Arma)]
    pub init: InitArg,
    #[arg(long, default_value_t = 50)]
    pub max_iter: usize,
    /// Relative RSS change that ends the alternation.
    #[arg(long, default_value_t = 1e-6)]
    pub tol: f64,
    /// Fit the raw values (default: the mean is subtracted and recorded).
    #[arg(long)]
    pub no_demean: bool,
    /// Also write residuals.parquet.
    #[arg(long)]
    pub residuals: bool,
    /// Also write state.parquet, what `farma update` needs to continue the fit (GCV then
    /// keeps a finite bandwidth: the ladder's limit h -> infinity has no kernel windows
    /// to update).
    #[arg(long)]
    pub save_state: bool,
    /// Index of the coefficient functions: `lag` (x_(t-d), default) or `lag,CHANNEL`
    /// (x_(t-d) and another channel of the log, e.g. lag,temp_c).
    #[arg(long, value_name = "lag[,CHANNEL]")]
    pub index: Option<String>,
    /// Lag of the second index channel (default: d).
    #[arg(long, value_name = "D2")]
    pub index_lag: Option<usize>,
    /// Grid points per coordinate of a 2-D index [default: 21,21].
    #[arg(long, value_name = "N1,N2")]
    pub index_grid: Option<String>,
    /// With a 2-D index and --bandwidth: the bandwidth of the second coordinate.
    #[arg(long, value_name = "H2")]
    pub bandwidth2: Option<f64>,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines).
    #[arg(long)]
    pub json: bool,
}

/// The options of a 2-D index are a usage error with the 1-D index (they would be
/// silently ignored, and the user would read a 1-D model as the one asked for).
fn reject_index2_options(a: &FitArgs) -> Result<()> {
    let given: Vec<&str> = [
        ("--index-lag", a.index_lag.is_some()),
        ("--index-grid", a.index_grid.is_some()),
        ("--bandwidth2", a.bandwidth2.is_some()),
    ]
    .into_iter()
    .filter_map(|(name, set)| set.then_some(name))
    .collect();
    if given.is_empty() {
        return Ok(());
    }
    Err(Error::Usage(format!(
        "{} only apply to a 2-D index (--index lag,CHANNEL); the index here is x_(t-d) alone",
        given.join(", ")
    )))
}

pub fn run(a: FitArgs, progress: &Progress) -> Result<()> {
    if let Some(second) = second_index(a.index.as_deref())? {
        return run_index2(a, second, progress);
    }
    let Order { p, q, d } = Order::parse_flag(&a.order)?;
    reject_index2_options(&a)?;
    OutputSet::check(&a.output)?;
    let store = a.log_args.open(&a.log, progress)?;
    let job = FitJob {
        log: a.log.clone(),
        output: a.output.clone(),
        channels: store.select_channels(&a.channel)?,
        params: FarmaParams {
            p,
            q,
            d,
            grid_size: a.grid.unwrap_or(DEFAULT_GRID),
            bandwidth: a.bandwidth,
            init: a.init.into(),
            path: a.method.map_or(FitPath::Fast, Into::into),
            max_iter: a.max_iter,
            tol: a.tol,
            demean: !a.no_demean,
            // the online state keeps kernel windows of a finite bandwidth
            bandwidth_limit: !a.save_state,
            ..FarmaParams::default()
        },
        residuals: a.residuals,
        save_state: a.save_state,
    };
    let done = job.run(&store, progress)?;
    for c in &done.fits {
        let (n, m, r) = (&c.channel, &c.model, &c.report);
        let line = format!(
            "fit {n}: FARMA({p},{q},{d}) b = {:?} sigma2 = {:.6e} h = {:.6e} trace = {:.2} iterations {} {}",
            m.b,
            m.sigma2,
            m.bandwidth,
            r.trace,
            r.iterations,
            if r.converged {
                "converged"
            } else {
                "NOT converged (raise --max-iter or --tol)"
            }
        );
        // the result on stdout; with --json stdout holds the JSON alone
        if a.json {
            eprintln!("farma: {line}");
        } else {
            outln!("{line}");
        }
        for note in &r.notes {
            eprintln!("farma: note: {n}: {note}");
        }
        if a.json {
            outln!(
                "{}",
                fit_json(n, m, Report::Fit(r), &done.coef_path.display().to_string())
            );
        }
    }
    eprintln!(
        "farma: {} channel(s) fitted in {:.2} s; tables in {}",
        done.fits.len(),
        done.secs,
        a.output.display()
    );
    Ok(())
}

/// The second index channel of `--index`, or None for the 1-D index (`lag`).
pub fn second_index(spec: Option<&str>) -> Result<Option<String>> {
    let Some(spec) = spec else { return Ok(None) };
    let parts: Vec<&str> = spec.split(',').map(str::trim).collect();
    match parts.as_slice() {
        ["lag"] => Ok(None),
        ["lag", c] if !c.is_empty() => Ok(Some(c.to_string())),
        _ => Err(Error::Usage(format!(
            "--index: '{spec}' is not 'lag' or 'lag,CHANNEL' (e.g. lag,temp_c)"
        ))),
    }
}

fn parse_pair(s: &str) -> Result<(usize, usize)> {
    let v: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || Error::Usage(format!("--index-grid: '{s}' is not N1,N2 (e.g. 21,21)"));
    if v.len() != 2 {
        return Err(bad());
    }
    Ok((
        v[0].parse().map_err(|_| bad())?,
        v[1].parse().map_err(|_| bad())?,
    ))
}

/// `farma fit --index lag,CHANNEL`: the arguments of a 2-D fit checked and turned
/// into a [`Fit2Job`]; its result printed.
fn run_index2(a: FitArgs, index2: String, progress: &Progress) -> Result<()> {
    let Order { p, q, d } = Order::parse_flag(&a.order)?;
    OutputSet::check(&a.output)?;
    if a.save_state {
        return Err(Error::Usage(
            "--save-state: online updates (farma update) support the 1-D index only; drop --save-state or the second --index channel".into(),
        ));
    }
    if let Some(g) = a.grid {
        return Err(Error::Usage(format!(
            "--grid {g}: the grid of a 1-D index; a 2-D index has a G1 x G2 grid, --index-grid N1,N2 (default 21,21)"
        )));
    }
    if a.init == InitArg::Literal {
        return Err(Error::Usage(
            "--init literal: a 2-D index starts from the linear ARMA only".into(),
        ));
    }
    // a 2-D index has the direct path only (KD-tree gather): an explicit --method
    // fast is not what runs, and says so (--method direct is what runs anyway)
    if a.method == Some(FitPathArg::Fast) {
        eprintln!(
            "farma: warning: --method fast: a 2-D index has no moment tables (a window in two variables is no union of 1-D intervals); the direct path fits it (a KD-tree gather per grid point), as --method direct would"
        );
    }
    let bandwidth = match (a.bandwidth, a.bandwidth2) {
        (None, None) => None,
        (Some(h1), Some(h2)) => Some((h1, h2)),
        _ => {
            return Err(Error::Usage(
                "with a 2-D index give both --bandwidth H1 and --bandwidth2 H2, or neither (GCV)"
                    .into(),
            ));
        }
    };
    let grid = parse_pair(a.index_grid.as_deref().unwrap_or("21,21"))?;
    check_grid2(grid)?;
    let d2 = a.index_lag.unwrap_or(d);
    let store = a.log_args.open(&a.log, progress)?;
    let job = Fit2Job {
        log: a.log.clone(),
        output: a.output.clone(),
        channel: a.channel.clone(),
        params: Farma2Params {
            base: FarmaParams {
                p,
                q,
                d,
                init: Init::Arma,
                path: FitPath::Direct,
                max_iter: a.max_iter,
                tol: a.tol,
                demean: !a.no_demean,
                ..FarmaParams::default()
            },
            index2: index2.clone(),
            d2,
            grid,
            bandwidth,
        },
        residuals: a.residuals,
    };
    let done = job.run(&store, progress)?;
    let (fits, coef_path, secs) = (&done.fits, &done.coef_path, done.secs);
    for (n, (m, r)) in fits {
        let second = m.second().expect("a 2-D index");
        let line = format!(
            "fit {n}: FARMA({p},{q},{d}) on (x_(t-{d}), {index2}_(t-{d2})): b = {:?} sigma2 = {:.6e} h = ({:.6e}, {:.6e}) trace = {:.2} iterations {} {}",
            m.b,
            m.sigma2,
            m.bandwidth,
            second.bandwidth,
            r.trace,
            r.iterations,
            if r.converged {
                "converged"
            } else {
                "NOT converged (raise --max-iter or --tol)"
            }
        );
        if a.json {
            eprintln!("farma: {line}");
        } else {
            outln!("{line}");
        }
        for note in &r.notes {
            eprintln!("farma: note: {n}: {note}");
        }
        if a.json {
            let v = json!({
                "channel": n,
                "order": [p, q, d],
                "b": m.b,
                "sigma2": m.sigma2,
                "bandwidth": m.bandwidth,
                "bandwidth2": second.bandwidth,
                "rss": r.rss,
                "trace": r.trace,
                "gcv": r.gcv,
                "iterations": r.iterations,
                "converged": r.converged,
                "coef": coef_path.display().to_string(),
                "mean": m.mean,
                "init": "arma",
                "method": "direct",
                "ladder_extended": r.ladder_extended,
                "n": r.n,
                "index2": index2,
                "d2": second.lag,
                "grid": [m.coef.grid.len(), second.grid.len()],
                "notes": r.notes,
            });
            let mut v = v;
            if let Some(w) = r.returned_start_reason {
                v["returned_start_reason"] = w.as_str().into();
            }
            outln!("{v}");
        }
    }
    eprintln!(
        "farma: {} channel(s) fitted on a 2-D index in {secs:.2} s; tables in {}",
        fits.len(),
        a.output.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::estimator::FitPath;
    use crate::jobs::fit::direct_cost_warning;

    #[test]
    fn a_costly_direct_fit_gets_a_warning_with_its_estimate() {
        // the bench's direct fit, 201 points on 1e5 samples (23.7 s measured): a warning
        let w = direct_cost_warning(FitPath::Direct, 201, 100_000, 1, false).expect("a warning");
        assert!(w.contains("2.0e7") && w.contains("--method fast"), "{w}");
        // the default grid on 20,000 samples: none
        assert!(direct_cost_warning(FitPath::Direct, 201, 20_000, 1, false).is_none());
        // three channels of 40,000 samples: 2.4e7, a warning
        assert!(direct_cost_warning(FitPath::Direct, 201, 40_000, 3, false).is_some());
        // the fast path, or a fixed bandwidth: none
        assert!(direct_cost_warning(FitPath::Fast, 5000, 1_000_000, 1, false).is_none());
        assert!(direct_cost_warning(FitPath::Direct, 5000, 1_000_000, 1, true).is_none());
    }
}
