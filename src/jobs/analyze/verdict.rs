//! The verdict of `farma analyze` on one channel, for a test engineer: the selected
//! order, whether the nonlinearity is real (the constancy test), whether the residuals
//! are white (Ljung-Box), and whether the FARMA predicts the hold-out better than the
//! linear ARMA; one line of summary.txt and one row of verdict.parquet per channel.
//!
//! - nonlinear: the constancy test (`chi2` or `bootstrap`) rejects constant
//!   coefficients, p <= [`ALPHA`] ([`crate::workflow::rejects`]); null (not tested)
//!   with `--constancy none`. What the test can resolve: its smallest p-value, 1 / (B
//!   + 1) for a bootstrap of B replicates, 0 for the chi2 test.
//! - residuals white: the Ljung-Box test at the largest lag it was run at (20 with
//!   the default `--maxlag 40`, ln n when that is larger and within `--maxlag`) does
//!   not reject at [`ALPHA`]; null when no lag was tested (every lag at or below p + q).
//! - hold-out: the 1-step RMSE of the FARMA and of the ARMA baseline on the hold-out
//!   (null without one, `--holdout-s 0`).

use std::sync::Arc;

use arrow_array::{
    Array, ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray,
};

use crate::error::{Error, Result};
use crate::output::batch;
use crate::workflow::analyze::ChannelAnalysis;
use crate::workflow::select::order_name;
use crate::workflow::{ALPHA, rejects};

/// One channel's verdict.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    pub channel: String,
    /// The selected order (p, q, d).
    pub order: (usize, usize, usize),
    /// The constancy test (None: not run).
    pub constancy: Option<ConstancyVerdict>,
    /// The Ljung-Box test the whiteness verdict is taken from (None: no lag tested).
    pub ljung_box: Option<(usize, f64)>,
    /// 1-step hold-out RMSE of the FARMA and of the ARMA (None: no hold-out).
    pub rmse_k1: Option<(f64, f64)>,
    pub n_train: usize,
    /// Samples held out.
    pub holdout: usize,
}

/// The constancy test's part of a verdict.
#[derive(Clone, Debug, PartialEq)]
pub struct ConstancyVerdict {
    pub p_value: f64,
    /// The smallest p-value the test can return (1 / (B + 1); 0 for chi2).
    pub min_p: f64,
    /// B (0 for the chi2 test).
    pub bootstrap: usize,
    /// `chi2` or `bootstrap`.
    pub method: String,
}

impl Verdict {
    /// The verdict of an analysis.
    pub fn of(a: &ChannelAnalysis) -> Verdict {
        let sel = &a.selection;
        Verdict {
            channel: a.name.clone(),
            order: sel.rows[sel.selected].order,
            constancy: a.constancy.as_ref().map(|c| ConstancyVerdict {
                p_value: c.p_value,
                min_p: c.min_p(),
                bootstrap: c.bootstrap,
                method: c.method.to_string(),
            }),
            ljung_box: a
                .check
                .whiteness
                .ljung_box
                .iter()
                .max_by_key(|b| b.lag)
                .map(|b| (b.lag, b.p_value)),
            rmse_k1: a.check.prediction.as_ref().and_then(|p| {
                p.horizons
                    .iter()
                    .find(|h| h.k == 1)
                    .map(|h| (h.rmse_farma, h.rmse_arma))
            }),
            n_train: a.n_train,
            holdout: a.check.prediction.as_ref().map_or(0, |p| p.holdout),
        }
    }

    /// Whether the coefficient functions vary (None: not tested).
    pub fn nonlinear(&self) -> Option<bool> {
        self.constancy.as_ref().map(|c| rejects(c.p_value, ALPHA))
    }

    /// Whether the residuals are white (None: not tested).
    pub fn residuals_white(&self) -> Option<bool> {
        self.ljung_box.map(|(_, p)| !rejects(p, ALPHA))
    }

    /// The line of summary.txt, the channel's name padded to `width`.
    pub fn line(&self, width: usize) -> String {
        let yes = |b: bool| if b { "yes" } else { "no" };
        let nonlinear = match (&self.constancy, self.nonlinear()) {
            (Some(c), Some(n)) if c.method == "bootstrap" => format!(
                "nonlinear: {} (p = {}, bootstrap B = {} resolves p >= {})",
                yes(n),
                fmt_p(c.p_value),
                c.bootstrap,
                fmt_p(c.min_p)
            ),
            (Some(c), Some(n)) => format!(
                "nonlinear: {} (p = {}, {} test)",
                yes(n),
                fmt_p(c.p_value),
                c.method
            ),
            _ => "nonlinear: not tested (--constancy none)".into(),
        };
        let white = match (self.ljung_box, self.residuals_white()) {
            (Some((lag, p)), Some(w)) => format!(
                "residuals white: {} (Ljung-Box lag {lag} p = {})",
                yes(w),
                fmt_p(p)
            ),
            _ => "residuals white: not tested (no Ljung-Box lag)".into(),
        };
        let pred = match self.rmse_k1 {
            Some((f, a)) => format!("hold-out 1-step RMSE FARMA/ARMA {:.3}", f / a),
            None => "hold-out: none".into(),
        };
        format!(
            "{:<width$}  {}  {nonlinear}  {white}  {pred}",
            self.channel,
            order_name(self.order)
        )
    }
}

/// A p-value in summary lines: 3 decimals, or 2 significant digits below 0.001 (0 as
/// `0 (below 1e-300)`: the tail underflowed).
pub fn fmt_p(p: f64) -> String {
    if p == 0.0 {
        "0 (below 1e-300)".into()
    } else if p.is_finite() && p < 1e-3 {
        format!("{p:.1e}")
    } else {
        format!("{p:.3}")
    }
}

/// verdict.parquet: one row per channel (see the README for the columns).
pub fn verdict_table(rows: &[Verdict]) -> Result<RecordBatch> {
    let s = |f: &dyn Fn(&Verdict) -> String| -> ArrayRef {
        Arc::new(StringArray::from(rows.iter().map(f).collect::<Vec<_>>()))
    };
    let so = |f: &dyn Fn(&Verdict) -> Option<String>| -> ArrayRef {
        Arc::new(StringArray::from(rows.iter().map(f).collect::<Vec<_>>()))
    };
    let i = |f: &dyn Fn(&Verdict) -> i64| -> ArrayRef {
        Arc::new(Int64Array::from(rows.iter().map(f).collect::<Vec<_>>()))
    };
    let io = |f: &dyn Fn(&Verdict) -> Option<i64>| -> ArrayRef {
        Arc::new(Int64Array::from(rows.iter().map(f).collect::<Vec<_>>()))
    };
    let fo = |f: &dyn Fn(&Verdict) -> Option<f64>| -> ArrayRef {
        Arc::new(Float64Array::from(rows.iter().map(f).collect::<Vec<_>>()))
    };
    let bo = |f: &dyn Fn(&Verdict) -> Option<bool>| -> ArrayRef {
        Arc::new(BooleanArray::from(rows.iter().map(f).collect::<Vec<_>>()))
    };
    batch(vec![
        ("channel", s(&|v| v.channel.clone())),
        ("order", s(&|v| order_name(v.order))),
        ("p", i(&|v| v.order.0 as i64)),
        ("q", i(&|v| v.order.1 as i64)),
        ("d", i(&|v| v.order.2 as i64)),
        ("alpha", fo(&|_| Some(ALPHA))),
        ("nonlinear", bo(&|v| v.nonlinear())),
        (
            "constancy_p",
            fo(&|v| v.constancy.as_ref().map(|c| c.p_value)),
        ),
        (
            "constancy_min_p",
            fo(&|v| v.constancy.as_ref().map(|c| c.min_p)),
        ),
        (
            "constancy_bootstrap",
            io(&|v| v.constancy.as_ref().map(|c| c.bootstrap as i64)),
        ),
        (
            "constancy_method",
            so(&|v| v.constancy.as_ref().map(|c| c.method.clone())),
        ),
        ("residuals_white", bo(&|v| v.residuals_white())),
        ("ljung_box_lag", io(&|v| v.ljung_box.map(|(l, _)| l as i64))),
        ("ljung_box_p", fo(&|v| v.ljung_box.map(|(_, p)| p))),
        ("rmse_farma_k1", fo(&|v| v.rmse_k1.map(|(f, _)| f))),
        ("rmse_arma_k1", fo(&|v| v.rmse_k1.map(|(_, a)| a))),
        ("rmse_ratio_k1", fo(&|v| v.rmse_k1.map(|(f, a)| f / a))),
        ("n_train", i(&|v| v.n_train as i64)),
        ("holdout", i(&|v| v.holdout as i64)),
    ])
}

/// The verdicts of a verdict.parquet table read back.
pub fn verdicts_of(b: &RecordBatch) -> Result<Vec<Verdict>> {
    let bad = |m: String| Error::Internal(format!("verdict.parquet: {m}"));
    let col = |n: &str| {
        b.column_by_name(n)
            .cloned()
            .ok_or_else(|| bad(format!("no column '{n}'")))
    };
    macro_rules! typed {
        ($name:expr, $ty:ty) => {
            col($name)?
                .as_any()
                .downcast_ref::<$ty>()
                .cloned()
                .ok_or_else(|| bad(format!("column '{}' has another type", $name)))?
        };
    }
    let ch = typed!("channel", StringArray);
    let (p, q, d) = (
        typed!("p", Int64Array),
        typed!("q", Int64Array),
        typed!("d", Int64Array),
    );
    let cp = typed!("constancy_p", Float64Array);
    let cmin = typed!("constancy_min_p", Float64Array);
    let cb = typed!("constancy_bootstrap", Int64Array);
    let cm = typed!("constancy_method", StringArray);
    let lag = typed!("ljung_box_lag", Int64Array);
    let lbp = typed!("ljung_box_p", Float64Array);
    let rf = typed!("rmse_farma_k1", Float64Array);
    let ra = typed!("rmse_arma_k1", Float64Array);
    let nt = typed!("n_train", Int64Array);
    let ho = typed!("holdout", Int64Array);
    Ok((0..b.num_rows())
        .map(|k| Verdict {
            channel: ch.value(k).to_string(),
            order: (
                p.value(k) as usize,
                q.value(k) as usize,
                d.value(k) as usize,
            ),
            constancy: (!cp.is_null(k)).then(|| ConstancyVerdict {
                p_value: cp.value(k),
                min_p: cmin.value(k),
                bootstrap: cb.value(k) as usize,
                method: cm.value(k).to_string(),
            }),
            ljung_box: (!lag.is_null(k)).then(|| (lag.value(k) as usize, lbp.value(k))),
            rmse_k1: (!rf.is_null(k)).then(|| (rf.value(k), ra.value(k))),
            n_train: nt.value(k) as usize,
            holdout: ho.value(k) as usize,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_verdict_reads_back_and_says_what_was_not_tested() {
        let a = Verdict {
            channel: "gyro_x_dps".into(),
            order: (3, 2, 1),
            constancy: Some(ConstancyVerdict {
                p_value: 0.31,
                min_p: 0.01,
                bootstrap: 99,
                method: "bootstrap".into(),
            }),
            ljung_box: Some((20, 0.42)),
            rmse_k1: Some((0.998, 1.0)),
            n_train: 3500,
            holdout: 500,
        };
        let b = Verdict {
            channel: "g".into(),
            constancy: None,
            ljung_box: None,
            rmse_k1: None,
            ..a.clone()
        };
        let t = verdict_table(&[a.clone(), b.clone()]).unwrap();
        assert_eq!(verdicts_of(&t).unwrap(), vec![a.clone(), b.clone()]);
        assert_eq!(
            a.line(10),
            "gyro_x_dps  FARMA(3,2,1)  nonlinear: no (p = 0.310, bootstrap B = 99 resolves p >= 0.010)  residuals white: yes (Ljung-Box lag 20 p = 0.420)  hold-out 1-step RMSE FARMA/ARMA 0.998"
        );
        assert!(b.line(10).contains("nonlinear: not tested"));
        assert_eq!(b.nonlinear(), None);
        let nl = t
            .column_by_name("nonlinear")
            .unwrap()
            .as_any()
            .downcast_ref::<BooleanArray>()
            .unwrap()
            .clone();
        assert!(!nl.value(0) && nl.is_null(1));
        // p = alpha rejects (the bootstrap's rule)
        let c = Verdict {
            constancy: Some(ConstancyVerdict {
                p_value: 0.05,
                min_p: 0.05,
                bootstrap: 19,
                method: "bootstrap".into(),
            }),
            ..a
        };
        assert_eq!(c.nonlinear(), Some(true));
        let chi2 = Verdict {
            constancy: Some(ConstancyVerdict {
                p_value: 0.003,
                min_p: 0.0,
                bootstrap: 0,
                method: "chi2".into(),
            }),
            ..c
        };
        assert!(
            chi2.line(0)
                .contains("nonlinear: yes (p = 0.003, chi2 test)"),
            "{}",
            chi2.line(0)
        );
    }
}
