//! `farma fit ... --index lag,CHANNEL`: the FARMA fit with a 2-D index (the model's
//! lagged value and another channel of the log); see `estimator::multivariate`.

use std::time::Instant;

use rayon::prelude::*;
use serde_json::json;

use super::fit::FitArgs;
use crate::error::{Error, Result};
use crate::estimator::multivariate::{Farma2Params, check_fit2, check_grid2, fit2};
use crate::estimator::tables::{
    ModelRow, ResidualRows, coef_table, gcv_table, params_table, stage_residuals,
};
use crate::estimator::{FarmaParams, FitPath, Init};
use crate::log::Progress;
use crate::model::report::FitReport2;
use crate::model::{Farma, Order, Report};
use crate::output::OutputSet;

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

pub fn run(a: FitArgs, index2: String, progress: &Progress) -> Result<()> {
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
    if a.init == super::choices::InitArg::Literal {
        return Err(Error::Usage(
            "--init literal: a 2-D index starts from the linear ARMA only".into(),
        ));
    }
    // a 2-D index has the direct path only (KD-tree gather): an explicit --method
    // fast is not what runs, and says so (--method direct is what runs anyway)
    if a.method == Some(super::choices::FitPathArg::Fast) {
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
    crate::jobs::warn_gaps(&store, &a.log);
    if store.meta().time_col.as_deref() == Some(index2.as_str()) {
        return Err(Error::column(
            &a.log,
            format!(
                "--index lag,{index2}: '{index2}' is the log's time column, not a channel (f_m that change with time are a trend: `farma prep` removes one); channels are: {}",
                store.channel_names().join(", ")
            ),
        ));
    }
    let mut names = store.select_channels(&a.channel)?;
    // `all` means every channel the index channel indexes: not the index itself (its
    // model on itself at the same lag is refused below; name it to fit it)
    if a.channel.trim() == "all" && names.contains(&index2) {
        names.retain(|n| *n != index2);
        if names.is_empty() {
            return Err(Error::column(
                &a.log,
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
    let params = Farma2Params {
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
    };
    if p == 0 || d == 0 || p > 6 || q > 6 || d > 1000 {
        return Err(Error::Usage(format!(
            "--order: p and d at least 1, p, q at most 6 and d at most 1000 (got {p},{q},{d})"
        )));
    }
    if a.tol.is_nan() || a.tol <= 0.0 || a.max_iter == 0 {
        return Err(Error::Usage(
            "--tol must be positive and --max-iter at least 1".into(),
        ));
    }
    if let Some(w) = cost_warning(grid, store.n_samples(), names.len(), bandwidth.is_some()) {
        eprintln!("farma: warning: {w}");
    }
    // what does not depend on the fitted channel is checked once, not per channel
    check_fit2(store.n_samples(), z, &params).map_err(|e| match e {
        Error::Usage(msg) | Error::Data(msg) => Error::column(&a.log, msg),
        Error::TooShort { what, need, have } => Error::TooShort {
            what: format!("{}: {what}", a.log.display()),
            need,
            have,
        },
        other => other,
    })?;
    let t0 = Instant::now();
    let bar = progress.count_bar("channels fitted", names.len() as u64);
    let fits: Vec<(String, (Farma, FitReport2))> = crate::jobs::every_channel(
        names
            .par_iter()
            .map(|n| {
                let x = store.column(n)?;
                let mut m =
                    fit2(x, z, &params).map_err(|e| crate::jobs::on_channel(&a.log, n, e))?;
                // N values per channel: kept only for residuals.parquet (as `farma fit`)
                if !a.residuals {
                    m.1.residuals = Vec::new();
                }
                bar.inc(1);
                Ok((n.clone(), m))
            })
            .collect(),
        crate::jobs::fit::FIT_CHANNELS_HINT,
    )?;
    bar.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let mut out = OutputSet::new(&a.output)?;
    let refs: Vec<ModelRow> = fits
        .iter()
        .map(|(n, (m, r))| (n.clone(), m, Report::Fit2(r)))
        .collect();
    let (size, mtime) = crate::log::source_identity(&a.log)?;
    let md = vec![
        ("order", format!("{p},{q},{d}")),
        ("source", a.log.display().to_string()),
        ("source_size", size.to_string()),
        ("source_mtime_ns", mtime.to_string()),
        ("sample_rate_hz", store.sample_rate_hz().to_string()),
        ("index", format!("lag,{index2}")),
        ("index2", index2.clone()),
        ("index2_lag", d2.to_string()),
    ];
    let coef_path = out.path("coef.parquet");
    out.parquet("coef.parquet", &coef_table(&refs)?, &md)?;
    out.parquet("params.parquet", &params_table(&refs)?, &md)?;
    out.parquet("gcv.parquet", &gcv_table(&refs)?, &md)?;
    if a.residuals {
        // in_fit: false for the first max(p,q,d,d2) samples (the warm-up, as in 1-D)
        let rows: Vec<ResidualRows> = fits
            .iter()
            .map(|(n, (_, r))| ResidualRows::of_fit(n, r))
            .collect();
        stage_residuals(&mut out, &rows, &md)?;
    }
    crate::jobs::commit_outputs(out, &crate::model::folder::FIT_OUTPUTS)?;
    for (n, (m, r)) in &fits {
        let second = m.second().expect("a 2-D index");
        eprintln!(
            "farma: fit {n}: FARMA({p},{q},{d}) on (x_(t-{d}), {index2}_(t-{d2})): b = {:?} sigma2 = {:.6e} h = ({:.6e}, {:.6e}) trace = {:.2} iterations {} {}",
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
