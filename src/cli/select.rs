//! `farma select LOG --channel C`: the order table (RSS, sigma^2, effective degrees of
//! freedom, GCV, AICc) beside the linear ARMA baseline, F-tests between nested orders,
//! the bootstrap test of constant coefficients, and the chosen order with its reasons.

use std::path::PathBuf;

use super::LogArgs;
use super::choices::FitPathArg;
use crate::error::{Error, Result};
use crate::estimator::FarmaParams;
use crate::estimator::fit::MAX_GRID;
use crate::jobs::select::{SelectJob, select_json, select_text};
use crate::log::Progress;
use crate::model::Order;
use crate::output::OutputSet;
use crate::workflow::constancy::ConstancyTest;
use crate::workflow::select::PAPER_ORDERS;
use clap::Args;

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
    #[arg(long, value_enum, default_value_t = FitPathArg::Fast)]
    pub method: FitPathArg,
    /// The constancy test at the selected order: chi2 (GLR at a fixed bandwidth, 0.5 sd,
    /// against chi2 on the smoother's degrees of freedom: one more fit; the default),
    /// bootstrap (GLR with GCV on B simulated series: B + 1 fits), none.
    #[arg(long, value_name = "TEST", value_parser = ["chi2", "bootstrap", "none"])]
    pub constancy: Option<String>,
    /// Bootstrap replicates of the constancy test (implies --constancy bootstrap; 0: no
    /// test; default 99 with --constancy bootstrap).
    #[arg(long, value_name = "B")]
    pub bootstrap: Option<usize>,
    /// Seed of the bootstrap.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl SelectFlags {
    pub fn orders(&self) -> Result<Vec<Order>> {
        match &self.orders {
            Some(s) => Order::parse_list(s),
            None => Ok(PAPER_ORDERS
                .iter()
                .map(|&(p, q, d)| Order::new(p, q, d))
                .collect()),
        }
    }

    /// The orders and the grid checked before any log is read: a bad flag is a
    /// usage error naming it, not an error of the log's first channel, and comes
    /// before the log is read and, in `farma analyze`, prepared.
    pub fn check(&self) -> Result<Vec<Order>> {
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
            path: self.method.into(),
            ..FarmaParams::default()
        }
    }

    /// The select job of these flags on `log` (orders and grid checked).
    pub fn job(&self, log: &std::path::Path, output: Option<PathBuf>) -> Result<SelectJob> {
        Ok(SelectJob {
            log: log.to_path_buf(),
            output,
            orders: self.check()?,
            farma: self.farma(),
            constancy: ConstancyTest::from_flags(self.constancy.as_deref(), self.bootstrap)?,
            seed: self.seed,
        })
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

pub fn run(a: SelectArgs, progress: &Progress) -> Result<()> {
    if let Some(dir) = &a.output {
        OutputSet::check(dir)?;
    }
    let job = a.select.job(&a.log, a.output.clone())?;
    let store = a.log_args.open(&a.log, progress)?;
    let names = store.select_channels(&a.channel)?;
    for c in job.run(&store, &names)? {
        if a.json {
            outln!(
                "{}",
                select_json(&c.channel, &c.selection, c.constancy.as_ref())
            );
        } else {
            out!(
                "{}",
                select_text(&c.channel, &c.selection, c.constancy.as_ref())
            );
        }
    }
    Ok(())
}
