//! The 2-D fit job (`farma fit --index lag,CHANNEL`): every selected channel of one
//! log fitted with f_m on the 2-D index (x_(t-d), z_(t-d2)), z another channel of the
//! log, in parallel; the model folder written (coef, params, gcv[, residuals]; the
//! metadata records the index).

use std::path::PathBuf;
use std::time::Instant;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::estimator::multivariate::{Farma2Params, check_fit2, fit2};
use crate::log::Progress;
use crate::model::folder::tables::{
    ModelRow, ResidualRows, coef_table, gcv_table, params_table, stage_residuals,
};
use crate::model::folder::{COEF_FILE, FIT_OUTPUTS, GCV_FILE, PARAMS_FILE};
use crate::model::order::{MAX_D, MAX_PQ};
use crate::model::report::FitReport2;
use crate::model::{Farma, Report};
use crate::output::OutputSet;
use crate::store::Store;

/// Estimated sample visits of a 2-D fit with GCV above which it gets a warning.
/// Each rung of a GCV ladder gathers every grid point's support (the box
/// [u_k - h_k, u_k + h_k) with h_j = 1.1^-j (range_k / 2)); over the rungs j = 0..20
/// the boxes' shares of the samples add up to about sum 1.1^-2j = 5.8 (less on
/// concentrated data), and a fit runs two ladders (the first f-step and the re-check),
/// so about 12 G1 G2 N visits. Measured on the 2-core bench machine (2026-11-25,
/// FARMA(1,0,1), N = 64,000): 4.8 s at 21,21, 10.3 s at 31,31 and 109.7 s at
/// 100,100 (7.7e9 estimated visits), about 14 ns per estimated visit (p = 1: each
/// visit adds to a 3p x 3p system, so larger p costs more per visit); so this
/// threshold is about a minute there.
pub const COST_WARN_VISITS: f64 = 4e9;

/// The warning for a 2-D fit of `channels` channels of `n` samples on a
/// `g1` x `g2` grid, when its GCV ladders' estimated visits exceed
/// [`COST_WARN_VISITS`] (none with fixed bandwidths: one rung per f-step).
pub fn cost_warning(
    (g1, g2): (usize, usize),
    n: usize,
    channels: usize,
    fixed_bandwidth: bool,
) -> Option<String> {
    if fixed_bandwidth {
        return None;
    }
    let visits = 12.0 * g1 as f64 * g2 as f64 * n as f64 * channels as f64;
    (visits > COST_WARN_VISITS).then(|| {
        format!(
            "a 2-D index fit gathers every grid point's support at every rung of its two GCV ladders: about 12 x {g1} x {g2} grid points x {n} samples x {channels} channel(s) = {visits:.1e} sample visits (about 14 ns each on 2 cores at p = 1, more for larger p: {:.0} min or more on such a machine); a coarser --index-grid, or fixed --bandwidth H1 --bandwidth2 H2 (one rung), costs less",
            (visits * 14e-9 / 60.0).max(1.0)
        )
    })
}

/// A fit of channels of one log on a 2-D index.
#[derive(Clone, Debug)]
pub struct Fit2Job {
    pub log: PathBuf,
    /// The model folder to write.
    pub output: PathBuf,
    /// The channels: `all` (every channel but the index channel) or a comma-separated
    /// list.
    pub channel: String,
    /// The fit's parameters, with the index channel and its delay.
    pub params: Farma2Params,
    /// Also write residuals.parquet.
    pub residuals: bool,
}

/// What a 2-D fit job did.
#[derive(Clone, Debug)]
pub struct Fit2Done {
    /// (channel, model, report), in channel order.
    pub fits: Vec<(String, (Farma, FitReport2))>,
    /// coef.parquet in the committed folder.
    pub coef_path: PathBuf,
    /// Wall-clock seconds of the fits.
    pub secs: f64,
}

impl Fit2Job {
    /// Checks the index channel and the parameters against the log, fits every channel
    /// in parallel (all or none; every failing channel named at once) and writes the
    /// model folder.
    pub fn run(&self, store: &Store, progress: &Progress) -> Result<Fit2Done> {
        let params = &self.params;
        let base = &params.base;
        let (p, q, d) = (base.p, base.q, base.d);
        let (index2, d2) = (params.index2.clone(), params.d2);
        super::warn_gaps(store, &self.log);
        if store.meta().time_col.as_deref() == Some(index2.as_str()) {
            return Err(Error::column(
                &self.log,
                format!(
                    "--index lag,{index2}: '{index2}' is the log's time column, not a channel (f_m that change with time are a trend: `farma prep` removes one); channels are: {}",
                    store.channel_names().join(", ")
                ),
            ));
        }
        let mut names = store.select_channels(&self.channel)?;
        // `all` means every channel the index channel indexes: not the index itself (its
        // model on itself at the same lag is refused below; name it to fit it)
        if self.channel.trim() == "all" && names.contains(&index2) {
            names.retain(|n| *n != index2);
            if names.is_empty() {
                return Err(Error::column(
                    &self.log,
                    format!(
                        "--channel all --index lag,{index2}: the log's only channel is the index channel '{index2}'"
                    ),
                ));
            }
            eprintln!(
                "farma: note: --channel all --index lag,{index2}: '{index2}', the index channel, is not fitted (name it in --channel, with --index-lag, to fit it)"
            );
        }
        let z = store.column(&index2).map_err(|e| match e {
            Error::Column { path, msg } => Error::Column {
                path,
                msg: format!("--index: {msg}"),
            },
            other => other,
        })?;
        if names.contains(&index2) && d2 == 0 {
            return Err(Error::Usage(format!(
                "--index lag,{index2} --index-lag 0: the second index would be the fitted channel's own current value, the x_t the model predicts; use --index-lag 1 or more"
            )));
        }
        if names.contains(&index2) && d2 == d {
            return Err(Error::Usage(format!(
                "--index lag,{index2}: the second index is the fitted channel at the same lag; use --index-lag to pick another lag"
            )));
        }
        if crate::model::Order::new(p, q, d).bounds().is_some() {
            return Err(Error::Usage(format!(
                "--order: p and d at least 1, p, q at most {MAX_PQ} and d at most {MAX_D} (got {p},{q},{d})"
            )));
        }
        if base.tol.is_nan() || base.tol <= 0.0 || base.max_iter == 0 {
            return Err(Error::Usage(
                "--tol must be positive and --max-iter at least 1".into(),
            ));
        }
        if let Some(w) = cost_warning(
            params.grid,
            store.n_samples(),
            names.len(),
            params.bandwidth.is_some(),
        ) {
            eprintln!("farma: warning: {w}");
        }
        // what does not depend on the fitted channel is checked once, not per channel
        check_fit2(store.n_samples(), z, params).map_err(|e| match e {
            Error::Usage(msg) | Error::Data(msg) => Error::column(&self.log, msg),
            Error::TooShort { what, need, have } => Error::TooShort {
                what: format!("{}: {what}", self.log.display()),
                need,
                have,
            },
            other => other,
        })?;
        let t0 = Instant::now();
        let bar = progress.count_bar("channels fitted", names.len() as u64);
        let fits: Vec<(String, (Farma, FitReport2))> = super::every_channel(
            names
                .par_iter()
                .map(|n| {
                    let x = store.column(n)?;
                    let mut m =
                        fit2(x, z, params).map_err(|e| super::on_channel(&self.log, n, e))?;
                    // N values per channel: kept only for residuals.parquet (as `farma fit`)
                    if !self.residuals {
                        m.1.residuals = Vec::new();
                    }
                    bar.inc(1);
                    Ok((n.clone(), m))
                })
                .collect(),
            super::fit::FIT_CHANNELS_HINT,
        )?;
        bar.finish_and_clear();
        let secs = t0.elapsed().as_secs_f64();
        let mut out = OutputSet::new(&self.output)?;
        let refs: Vec<ModelRow> = fits
            .iter()
            .map(|(n, (m, r))| (n.clone(), m, Report::Fit2(r)))
            .collect();
        let mut md = vec![("order", format!("{p},{q},{d}"))];
        md.extend(super::source_metadata(&self.log, store)?);
        md.extend([
            ("index", format!("lag,{index2}")),
            ("index2", index2.clone()),
            ("index2_lag", d2.to_string()),
        ]);
        let coef_path = out.path(COEF_FILE);
        out.parquet(COEF_FILE, &coef_table(&refs)?, &md)?;
        out.parquet(PARAMS_FILE, &params_table(&refs)?, &md)?;
        out.parquet(GCV_FILE, &gcv_table(&refs)?, &md)?;
        if self.residuals {
            // in_fit: false for the first max(p,q,d,d2) samples (the warm-up, as in 1-D)
            let rows: Vec<ResidualRows> = fits
                .iter()
                .map(|(n, (_, r))| ResidualRows::of_fit(n, r))
                .collect();
            stage_residuals(&mut out, &rows, &md)?;
        }
        super::commit_outputs(out, &FIT_OUTPUTS)?;
        Ok(Fit2Done {
            fits,
            coef_path,
            secs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_costly_2d_fit_gets_a_warning_with_its_estimate() {
        // 21 x 21 on 64,000 samples (4.8 s measured): no warning
        assert!(cost_warning((21, 21), 64_000, 1, false).is_none());
        // 100 x 100 on 1e6 samples: 1.2e11 visits
        let w = cost_warning((100, 100), 1_000_000, 1, false).expect("a warning");
        assert!(w.contains("1.2e11") && w.contains("--index-grid"), "{w}");
        // the default grid on 1e6 samples of three channels: 1.6e10
        assert!(cost_warning((21, 21), 1_000_000, 3, false).is_some());
        // fixed bandwidths: no ladder
        assert!(cost_warning((100, 100), 1_000_000, 1, true).is_none());
    }
}
