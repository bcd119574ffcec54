//! `farma select LOG --channel C`: the order table (RSS, sigma^2, effective degrees of
//! freedom, GCV, AICc) beside the linear ARMA baseline, F-tests between nested orders,
//! the bootstrap test of constant coefficients, and the chosen order with its reasons.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::LogArgs;
use crate::error::{Error, Result};
use crate::estimator::fit::MAX_GRID;
use crate::estimator::{FarmaParams, FitPath};
use crate::log::Progress;
use crate::output::OutputSet;
use crate::workflow::analyze::select_with_constancy;
use crate::workflow::constancy::Constancy;
use crate::workflow::select::{PAPER_ORDERS, Selection, order_name, parse_orders};
use crate::workflow::tables::{constancy_table, ftest_table, select_table};
use crate::workflow::{ALPHA, rejects};

/// The selection flags (shared with `farma analyze`).
#[derive(Args, Debug, Clone)]
pub struct SelectFlags {
    /// Orders to compare, `p,q,d;p,q,d;...` (default: the paper's eight).
    #[arg(long, value_name = "P,Q,D;..")]
    pub orders: Option<String>,
    /// Grid points of every FARMA fit.
    #[arg(long, default_value_t = 201, value_name = "N")]
    pub grid: usize,
    /// Computation of the local fits.
    #[arg(long, value_enum, default_value_t = FitPath::Fast)]
    pub method: FitPath,
    /// Bootstrap replicates of the constancy test (0: no test).
    #[arg(long, default_value_t = 99, value_name = "B")]
    pub bootstrap: usize,
    /// Seed of the bootstrap.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl SelectFlags {
    pub fn orders(&self) -> Result<Vec<(usize, usize, usize)>> {
        match &self.orders {
            Some(s) => parse_orders(s),
            None => Ok(PAPER_ORDERS.to_vec()),
        }
    }

    /// The orders and the grid checked before any log is read: a bad flag is a
    /// usage error naming it, not an error of the log's first channel, and comes
    /// before the log is read and, in `farma analyze`, prepared.
    pub fn check(&self) -> Result<Vec<(usize, usize, usize)>> {
        let orders = self.orders()?;
        if self.grid < 3 || self.grid > MAX_GRID {
            return Err(Error::Usage(format!(
                "--grid: 3 to {MAX_GRID} points (got {})",
                self.grid
            )));
        }
        Ok(orders)
    }

    pub fn farma(&self) -> FarmaParams {
        FarmaParams {
            grid_size: self.grid,
            path: self.method,
            ..FarmaParams::default()
        }
    }

    /// Selection and (B > 0) the constancy test at the selected order, for one series.
    pub fn run_on(&self, x: &[f64]) -> Result<(Selection, Option<Constancy>)> {
        select_with_constancy(x, &self.orders()?, &self.farma(), self.bootstrap, self.seed)
    }
}

#[derive(Args, Debug)]
pub struct SelectArgs {
    /// The log: a store, CSV, Parquet or Arrow IPC.
    pub log: PathBuf,
    /// Channels (comma-separated, or all); each gets its own table.
    #[arg(long, required = true)]
    pub channel: String,
    #[command(flatten)]
    pub select: SelectFlags,
    /// Also write select.parquet, ftests.parquet and constancy.parquet here.
    #[arg(short, long, value_name = "OUTDIR")]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub log_args: LogArgs,
    /// One JSON object per channel on stdout (JSON Lines).
    #[arg(long)]
    pub json: bool,
}

/// The `--json` object (contracts.md section 4).
pub fn select_json(name: &str, s: &Selection, c: Option<&Constancy>) -> serde_json::Value {
    let r = &s.rows[s.selected];
    json!({
        "channel": name,
        "selected": [r.order.0, r.order.1, r.order.2],
        "table": s.rows.iter().map(|r| json!({
            "order": [r.order.0, r.order.1, r.order.2],
            "rss": r.rss, "sigma2": r.sigma2, "trace": r.trace, "df": r.df,
            "gcv": r.gcv, "aicc": r.aicc, "bandwidth": r.bandwidth,
            "converged": r.converged, "arma_rss": r.arma_rss,
            "arma_sigma2": r.arma_sigma2, "arma_aicc": r.arma_aicc,
            "arma_ar": r.arma_ar, "arma_ma": r.arma_ma,
            "f_vs_arma": r.f_vs_arma, "p_vs_arma": r.p_vs_arma,
        })).collect::<Vec<_>>(),
        "ftests": s.ftests.iter().map(|t| json!({"small": t.small, "large": t.large,
            "f": t.f, "df1": t.df1, "df2": t.df2, "p_value": t.p_value})).collect::<Vec<_>>(),
        "constancy_p": c.map(|c| c.p_value),
        "constancy_statistic": c.map(|c| c.statistic),
        "constancy_bootstrap": c.map(|c| c.bootstrap),
        "reason": s.reason,
    })
}

/// The readable table.
pub fn select_text(name: &str, s: &Selection, c: Option<&Constancy>) -> String {
    let mut o = format!("channel {name}\n");
    o += &format!(
        "{:<15} {:>13} {:>12} {:>8} {:>12} {:>10} {:>13} {:>10} {:>9} {:>9}\n",
        "order", "rss", "sigma2", "df", "gcv", "aicc", "arma_rss", "arma_aicc", "F(arma)", "p"
    );
    for (k, r) in s.rows.iter().enumerate() {
        o += &format!(
            "{:<15} {:>13.6e} {:>12.5e} {:>8.2} {:>12.5e} {:>10.4} {:>13.6e} {:>10.4} {:>9.3} {:>9.2e}{}\n",
            order_name(r.order),
            r.rss,
            r.sigma2,
            r.df,
            r.gcv,
            r.aicc,
            r.arma_rss,
            r.arma_aicc,
            r.f_vs_arma,
            r.p_vs_arma,
            if k == s.selected { "  <- selected" } else { "" }
        );
    }
    o += "F-tests between nested models (effective degrees of freedom):\n";
    for t in &s.ftests {
        o += &format!(
            "  {:<14} in {:<15} F = {:>9.3} on ({:.2}, {:.1}) df, p = {:.3e}\n",
            t.small, t.large, t.f, t.df1, t.df2, t.p_value
        );
    }
    if let Some(c) = c {
        o += &format!(
            "constancy (bootstrap GLR, B = {}): T = {:.3}, p = {:.4}: {}\n",
            c.bootstrap,
            c.statistic,
            c.p_value,
            if rejects(c.p_value, ALPHA) {
                "the coefficient functions vary: the nonlinearity is real"
            } else {
                "constant coefficients not rejected: the linear ARMA is adequate"
            }
        );
    }
    o += &format!("selected: {}\n", s.reason);
    o
}

/// The files `farma select -o` can write into its output folder: a run removes those
/// of an earlier run that it does not write.
pub(super) const SELECT_OUTPUTS: &[&str] =
    &["select.parquet", "ftests.parquet", "constancy.parquet"];

pub fn run(a: SelectArgs, progress: &Progress) -> Result<()> {
    if let Some(dir) = &a.output {
        OutputSet::check(dir)?;
    }
    a.select.check()?;
    let store = a.log_args.open(&a.log, progress)?;
    let names = store.select_channels(&a.channel)?;
    let mut done = Vec::new();
    for n in &names {
        let x = store.column(n)?;
        let (sel, con) = a
            .select
            .run_on(x)
            .map_err(|e| super::on_channel(&a.log, n, e))?;
        if a.json {
            outln!("{}", select_json(n, &sel, con.as_ref()));
        } else {
            out!("{}", select_text(n, &sel, con.as_ref()));
        }
        done.push((n.clone(), sel, con));
    }
    if let Some(dir) = &a.output {
        let mut set = OutputSet::new(dir)?;
        let md = vec![
            ("source", a.log.display().to_string()),
            ("sample_rate_hz", store.sample_rate_hz().to_string()),
        ];
        let sels: Vec<(String, &Selection)> = done.iter().map(|(n, s, _)| (n.clone(), s)).collect();
        set.parquet("select.parquet", &select_table(&sels)?, &md)?;
        set.parquet("ftests.parquet", &ftest_table(&sels)?, &md)?;
        let cons: Vec<_> = done
            .iter()
            .filter_map(|(n, s, c)| c.as_ref().map(|c| (n.clone(), s.rows[s.selected].order, c)))
            .collect();
        set.parquet("constancy.parquet", &constancy_table(&cons)?, &md)?;
        super::commit_outputs(set, SELECT_OUTPUTS)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constancy(p_value: f64) -> Constancy {
        Constancy {
            statistic: 10.0,
            p_value,
            bootstrap: 19,
            bandwidth: 1.0,
            rss0: 2.0,
            rss1: 1.0,
            t_boot: vec![],
        }
    }

    /// The text reads the constancy p-value with the workflow's one rule, p <= alpha:
    /// at B = 19 the smallest p, 0.05, rejects.
    #[test]
    fn constancy_text_rejects_at_the_level() {
        let s = Selection {
            rows: vec![],
            ftests: vec![],
            selected: 0,
            reason: "none".into(),
            fits: vec![],
        };
        let at = select_text("x", &s, Some(&constancy(1.0 / 20.0)));
        assert!(at.contains("the nonlinearity is real"), "{at}");
        let above = select_text("x", &s, Some(&constancy(2.0 / 20.0)));
        assert!(
            above.contains("constant coefficients not rejected"),
            "{above}"
        );
    }
}
