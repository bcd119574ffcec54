//! The select job (`farma select`): for every selected channel of a log, the order
//! table (FARMA fits of every order and the linear ARMA baseline, AICc, F-tests) and
//! the constancy test at the selected order; the tables written when asked.

use std::path::PathBuf;

use serde_json::json;

use crate::error::Result;
use crate::estimator::FarmaParams;
use crate::model::Order;
use crate::output::OutputSet;
use crate::store::Store;
use crate::workflow::analyze::select_with_constancy;
use crate::workflow::constancy::{Constancy, ConstancyTest};
use crate::workflow::select::{Selection, order_name};
use crate::workflow::tables::{constancy_table, ftest_table, select_table};
use crate::workflow::{ALPHA, rejects};

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
            "returned_start_reason": r.returned_start_reason.map(|w| w.as_str()),
        })).collect::<Vec<_>>(),
        "ftests": s.ftests.iter().map(|t| json!({"small": t.small, "large": t.large,
            "f": t.f, "df1": t.df1, "df2": t.df2, "p_value": t.p_value})).collect::<Vec<_>>(),
        "untested": s.untested.iter().map(|t| json!({"small": t.small, "large": t.large,
            "reason": t.reason})).collect::<Vec<_>>(),
        "constancy_method": c.map(|c| c.method),
        "constancy_p": c.map(|c| c.p_value),
        "constancy_statistic": c.map(|c| c.statistic),
        "constancy_df": c.map(|c| c.df).filter(|d| d.is_finite()),
        "constancy_bandwidth": c.map(|c| c.bandwidth),
        "constancy_bootstrap": c.map(|c| c.bootstrap),
        "constancy_min_p": c.map(|c| c.min_p()),
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
            if k == s.selected {
                "  <- selected"
            } else if r.returned_start_reason.is_some() {
                "  (linear start)"
            } else {
                ""
            }
        );
    }
    o += "F-tests between nested models (effective degrees of freedom):\n";
    for t in &s.ftests {
        o += &format!(
            "  {:<14} in {:<15} F = {:>9.3} on ({:.2}, {:.1}) df, p = {:.3e}\n",
            t.small, t.large, t.f, t.df1, t.df2, t.p_value
        );
    }
    if !s.untested.is_empty() {
        o += "not tested (the test is not defined):\n";
        for t in &s.untested {
            o += &format!("  {:<14} in {:<15} {}\n", t.small, t.large, t.reason);
        }
    }
    for r in s.rows.iter() {
        if let Some(w) = r.returned_start_reason {
            o += &format!(
                "{} returned its linear start: {}\n",
                order_name(r.order),
                w.words()
            );
        }
    }
    if let Some(c) = c {
        let how = if c.method == "bootstrap" {
            format!(
                "bootstrap GLR, B = {}: p resolves down to {:.4}",
                c.bootstrap,
                c.min_p()
            )
        } else if c.df > 0.0 {
            format!(
                "GLR at fixed bandwidth {:.4e}, 2T against chi2 on {:.2} df",
                c.bandwidth, c.df
            )
        } else {
            format!(
                "GLR at fixed bandwidth {:.4e}: the FARMA fit there returned its linear start, the null model itself",
                c.bandwidth
            )
        };
        o += &format!(
            "constancy ({how}): T = {:.3}, p = {:.4}: {}\n",
            c.statistic,
            c.p_value,
            if rejects(c.p_value, ALPHA) {
                format!("constant coefficients rejected at {ALPHA}: the coefficient functions vary")
            } else {
                format!(
                    "constant coefficients not rejected at {ALPHA}: the linear ARMA is adequate"
                )
            }
        );
    }
    o += &format!("selected: {}\n", s.reason);
    o
}

/// The files `farma select -o` can write into its output folder: a run removes those
/// of an earlier run that it does not write.
pub const SELECT_OUTPUTS: &[&str] = &["select.parquet", "ftests.parquet", "constancy.parquet"];

/// What to do when several channels of a selection fail.
const SELECT_CHANNELS_HINT: &str = "leave the failing ones out of --channel";

/// An order selection for channels of one log.
#[derive(Clone, Debug)]
pub struct SelectJob {
    pub log: PathBuf,
    /// The folder for select.parquet, ftests.parquet, constancy.parquet, if any.
    pub output: Option<PathBuf>,
    /// The orders compared.
    pub orders: Vec<Order>,
    /// The parameters of every FARMA fit (the order replaced by each of `orders`).
    pub farma: FarmaParams,
    /// The constancy test at the selected order.
    pub constancy: ConstancyTest,
    pub seed: u64,
}

/// One channel's selection.
#[derive(Clone, Debug)]
pub struct ChannelSelection {
    pub channel: String,
    pub selection: Selection,
    pub constancy: Option<Constancy>,
}

impl SelectJob {
    /// The orders as the workflow takes them.
    pub fn order_tuples(&self) -> Vec<(usize, usize, usize)> {
        self.orders.iter().map(|o| (o.p, o.q, o.d)).collect()
    }

    /// Selection and (B > 0) the constancy test at the selected order, for one series.
    pub fn run_on(&self, x: &[f64]) -> Result<(Selection, Option<Constancy>)> {
        select_with_constancy(
            x,
            &self.order_tuples(),
            &self.farma,
            self.constancy,
            self.seed,
        )
    }

    /// Selects every channel of `names` in turn (each selection fits its orders in
    /// parallel), every failing channel named at once, and writes the tables when
    /// [`SelectJob::output`] is set.
    pub fn run(&self, store: &Store, names: &[String]) -> Result<Vec<ChannelSelection>> {
        let done = super::every_channel(
            names
                .iter()
                .map(|n| {
                    let x = store.column(n)?;
                    let (selection, constancy) = self
                        .run_on(x)
                        .map_err(|e| super::on_channel(&self.log, n, e))?;
                    Ok(ChannelSelection {
                        channel: n.clone(),
                        selection,
                        constancy,
                    })
                })
                .collect(),
            SELECT_CHANNELS_HINT,
        )?;
        if let Some(dir) = &self.output {
            let mut set = OutputSet::new(dir)?;
            let md = vec![
                ("source", self.log.display().to_string()),
                ("sample_rate_hz", store.sample_rate_hz().to_string()),
            ];
            let sels: Vec<(String, &Selection)> = done
                .iter()
                .map(|c| (c.channel.clone(), &c.selection))
                .collect();
            set.parquet("select.parquet", &select_table(&sels)?, &md)?;
            set.parquet("ftests.parquet", &ftest_table(&sels)?, &md)?;
            let cons: Vec<_> = done
                .iter()
                .filter_map(|c| {
                    c.constancy.as_ref().map(|k| {
                        (
                            c.channel.clone(),
                            c.selection.rows[c.selection.selected].order,
                            k,
                        )
                    })
                })
                .collect();
            set.parquet("constancy.parquet", &constancy_table(&cons)?, &md)?;
            crate::jobs::commit_outputs(set, SELECT_OUTPUTS)?;
        }
        Ok(done)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constancy(p_value: f64) -> Constancy {
        Constancy {
            method: "bootstrap",
            statistic: 10.0,
            p_value,
            bootstrap: 19,
            df: f64::NAN,
            trace: 5.0,
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
            untested: vec![],
            selected: 0,
            reason: "none".into(),
            fits: vec![],
        };
        let at = select_text("x", &s, Some(&constancy(1.0 / 20.0)));
        assert!(
            at.contains("constant coefficients rejected at 0.05"),
            "{at}"
        );
        let above = select_text("x", &s, Some(&constancy(2.0 / 20.0)));
        assert!(
            above.contains("constant coefficients not rejected"),
            "{above}"
        );
    }
}
