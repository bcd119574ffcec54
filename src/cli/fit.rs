//! `farma fit LOG --channel C --order p,q,d -o OUTDIR`.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use rayon::prelude::*;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::estimator::tables::ModelRow;
use crate::estimator::tables::{
    ResidualRows, coef_table, fit_json, gcv_table, params_table, stage_residuals,
};
use crate::estimator::{FarmaParams, FitPath, Init, fit, update};
use crate::log::Progress;
use crate::model::folder::state_file::{state_metadata, state_table};
use crate::model::folder::{COEF_FILE, FIT_OUTPUTS, GCV_FILE, PARAMS_FILE, STATE_FILE};
use crate::model::{ChannelState, Farma, FitReport, Report};
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
    pub method: Option<FitPath>,
    /// Start of the alternation (`literal`: the paper's scheme, for comparison).
    #[arg(long, value_enum, default_value_t = Init::Arma)]
    pub init: Init,
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
    /// Also write state.parquet, what `farma update` needs to continue the fit.
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

/// What to do when several channels of a fit fail ([`super::every_channel`]).
pub(super) const FIT_CHANNELS_HINT: &str = "leave the failing ones out of --channel";

/// The grid size of a 1-D fit when `--grid` is not given.
pub const DEFAULT_GRID: usize = 201;

/// A log of several uniform segments (`--gaps split`) is fitted as one series: the
/// lags and residuals of the first samples after a gap reach across it. Said on
/// stderr (`adev`, `psd` and `acf` use the longest segment instead).
pub(super) fn warn_gaps(store: &crate::store::Store, log: &std::path::Path) {
    let segments = &store.meta().segments;
    if segments.len() > 1 {
        eprintln!(
            "farma: warning: {}: {} segments (gaps): fitted as one series, the lags x_(t-m) and residuals of the first samples after each gap reach across it; for a fit without, cut the log at its gaps or use --gaps interpolate",
            log.display(),
            segments.len()
        );
    }
}

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

pub(super) fn parse_order(s: &str) -> Result<(usize, usize, usize)> {
    let v: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || {
        Error::Usage(format!(
            "--order: '{s}' is not p,q,d (three non-negative integers, e.g. 2,1,1)"
        ))
    };
    if v.len() != 3 {
        return Err(bad());
    }
    let n: Vec<usize> = v
        .iter()
        .map(|x| x.parse::<usize>().map_err(|_| bad()))
        .collect::<Result<_>>()?;
    Ok((n[0], n[1], n[2]))
}

pub fn run(a: FitArgs, progress: &Progress) -> Result<()> {
    if let Some(second) = super::fit_index2::second_index(a.index.as_deref())? {
        return super::fit_index2::run(a, second, progress);
    }
    let (p, q, d) = parse_order(&a.order)?;
    reject_index2_options(&a)?;
    OutputSet::check(&a.output)?;
    let store = a.log_args.open(&a.log, progress)?;
    warn_gaps(&store, &a.log);
    let names = store.select_channels(&a.channel)?;
    let grid = a.grid.unwrap_or(DEFAULT_GRID);
    let method = a.method.unwrap_or(FitPath::Fast);
    if let Some(w) = direct_cost_warning(
        method,
        grid,
        store.n_samples(),
        names.len(),
        a.bandwidth.is_some(),
    ) {
        eprintln!("farma: warning: {w}");
    }
    let params = FarmaParams {
        p,
        q,
        d,
        grid_size: grid,
        bandwidth: a.bandwidth,
        init: a.init,
        path: method,
        max_iter: a.max_iter,
        tol: a.tol,
        demean: !a.no_demean,
        ..FarmaParams::default()
    };
    // the parameters and the length are those of every channel: checked once
    let valid = params
        .clone()
        .validate(store.n_samples())
        .map_err(|e| match e {
            Error::TooShort { what, need, have } => Error::TooShort {
                what: format!("{}: {what}", a.log.display()),
                need,
                have,
            },
            other => other,
        })?;
    let t_last = match a.save_state {
        true => Some(super::update::last_time(&store)?),
        false => None,
    };
    let t0 = Instant::now();
    let bar = progress.count_bar("channels fitted", names.len() as u64);
    // Each channel's state is taken from its fit as soon as the fit ends, and its
    // residuals (N values) are then dropped unless --residuals writes them: a log of
    // many long channels holds the residuals of the fits in flight, not one series per
    // channel (measured on 6 channels of 1e7 samples: 0.98 GB maxrss, against 1.29 GB
    // with every channel's residuals held to the end; BENCHMARKS.md).
    let fitted: Vec<(String, (Farma, FitReport), Option<ChannelState>)> = super::every_channel(
        names
            .par_iter()
            .map(|n| {
                let x = store.column(n)?;
                let (m, mut r) = fit(x, &valid).map_err(|e| super::on_channel(&a.log, n, e))?;
                let state = t_last.map(|t| {
                    let mut s = update::state_from_fit(n, x, &m, &r);
                    s.t_last = t;
                    s
                });
                if !a.residuals {
                    r.residuals = Vec::new();
                }
                bar.inc(1);
                Ok((n.clone(), (m, r), state))
            })
            .collect(),
        FIT_CHANNELS_HINT,
    )?;
    bar.finish_and_clear();
    let mut fits = Vec::with_capacity(fitted.len());
    let mut states = Vec::new();
    for (n, m, s) in fitted {
        fits.push((n, m));
        states.extend(s);
    }
    let secs = t0.elapsed().as_secs_f64();
    let mut out = OutputSet::new(&a.output)?;
    let refs: Vec<ModelRow> = fits
        .iter()
        .map(|(n, (m, r))| (n.clone(), m, Report::Fit(r)))
        .collect();
    let (size, mtime) = crate::log::source_identity(&a.log)?;
    let md = vec![
        ("order", format!("{p},{q},{d}")),
        ("source", a.log.display().to_string()),
        ("source_size", size.to_string()),
        ("source_mtime_ns", mtime.to_string()),
        ("sample_rate_hz", store.sample_rate_hz().to_string()),
    ];
    let coef_path = out.path(COEF_FILE);
    out.parquet(COEF_FILE, &coef_table(&refs)?, &md)?;
    out.parquet(PARAMS_FILE, &params_table(&refs)?, &md)?;
    out.parquet(GCV_FILE, &gcv_table(&refs)?, &md)?;
    if a.residuals {
        let rows: Vec<ResidualRows> = fits
            .iter()
            .map(|(n, (_, r))| ResidualRows::of_fit(n, r))
            .collect();
        stage_residuals(&mut out, &rows, &md)?;
    }
    if a.save_state {
        for s in states.iter().filter(|s| s.linear_start) {
            eprintln!(
                "farma: warning: {}: the fit returned its linear ARMA start; its state is written, but `farma update` refuses it (no fitted local model to continue): fit the concatenated log instead",
                s.channel
            );
        }
        let refs: Vec<_> = states.iter().collect();
        let table = state_table(&refs)?;
        out.parquet(STATE_FILE, &table, &state_metadata(&md))?;
    }
    super::commit_outputs(out, &FIT_OUTPUTS)?;
    for (n, (m, r)) in &fits {
        eprintln!(
            "farma: fit {n}: FARMA({p},{q},{d}) b = {:?} sigma2 = {:.6e} h = {:.6e} trace = {:.2} iterations {} {}",
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
        for note in &r.notes {
            eprintln!("farma: note: {n}: {note}");
        }
        if a.json {
            outln!(
                "{}",
                fit_json(n, m, Report::Fit(r), &coef_path.display().to_string())
            );
        }
    }
    eprintln!(
        "farma: {} channel(s) fitted in {secs:.2} s; tables in {}",
        fits.len(),
        a.output.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
