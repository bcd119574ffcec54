//! Fitted models as tables (Parquet) and JSON: the coefficient functions, the
//! parameters, the GCV table and the residuals, one row per channel and item, for the
//! lag index and the 2-D index (whose tables add the second coordinate's columns:
//! models of one table share their index).
//! Column names are the contract of `docs/contracts.md` section 4.

use std::sync::Arc;

use arrow_array::builder::{Float64Builder, ListBuilder};
use arrow_array::{
    ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray, UInt64Array,
};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use serde_json::{Value, json};

use crate::error::Result;
use crate::estimator::problem::{GridFit, PointStatus};
use crate::model::{Farma, Report};
use crate::output::{OutputSet, batch};

fn s(v: Vec<String>) -> ArrayRef {
    Arc::new(StringArray::from(v))
}
fn f(v: Vec<f64>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}
fn i(v: Vec<i64>) -> ArrayRef {
    Arc::new(Int64Array::from(v))
}

/// One channel's model with the report of how it was made, as the tables take it.
pub type ModelRow<'a> = (String, &'a Farma, Report<'a>);

/// Whether the models are on a 2-D index (the tables' extra columns).
fn on_2d_index(models: &[ModelRow]) -> bool {
    let two_d = models.first().is_some_and(|(_, m, _)| m.second().is_some());
    debug_assert!(models.iter().all(|(_, m, _)| m.second().is_some() == two_d));
    two_d
}

/// The local fits' values coef.parquet writes: df/du (df/du_1 on a 2-D index), df/du_2
/// on a 2-D index, supports, kernel masses, condition numbers, statuses.
struct LocalColumns<'a> {
    slope: &'a [f64],
    slope2: Option<&'a [f64]>,
    n_support: &'a [u64],
    kernel_mass: &'a [f64],
    cond: &'a [f64],
    status: &'a [PointStatus],
}

impl<'a> LocalColumns<'a> {
    fn of(r: &Report<'a>) -> Self {
        let lag = |l: &'a GridFit| LocalColumns {
            slope: &l.slope,
            slope2: None,
            n_support: &l.n_support,
            kernel_mass: &l.kernel_mass,
            cond: &l.cond,
            status: &l.status,
        };
        match *r {
            Report::Fit(r) => lag(&r.local),
            Report::Update(r) => lag(&r.local),
            Report::Fit2(r) => LocalColumns {
                slope: &r.local.slope1,
                slope2: Some(&r.local.slope2),
                n_support: &r.local.n_support,
                kernel_mass: &r.local.kernel_mass,
                cond: &r.local.cond,
                status: &r.local.status,
            },
        }
    }
}

/// Coefficient functions: channel, m, grid, f, slope, se, n_support, kernel_mass,
/// cond, status, filled. The grid is in the units of the channel (mean added back).
/// On a 2-D index `grid` and `slope` are the lag coordinate's (df/du_1), and `grid2`
/// (the second index value) and `slope2` (df/du_2) follow them.
pub fn coef_table(models: &[ModelRow]) -> Result<RecordBatch> {
    let (mut ch, mut m_, mut grid, mut grid2, mut fv, mut slope, mut slope2, mut se) = (
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
    );
    let (mut nsup, mut mass, mut cond, mut status, mut filled) =
        (vec![], vec![], vec![], vec![], vec![]);
    for (name, m, r) in models {
        let p = m.p();
        let (c, local) = (&m.coef, LocalColumns::of(r));
        let n2 = c.n_grid() / c.grid.len();
        for g in 0..c.n_grid() {
            for k in 0..p {
                ch.push(name.clone());
                m_.push(k as i64 + 1);
                grid.push(c.grid[g / n2] + m.mean);
                grid2.extend(c.second_grid(g));
                fv.push(c.f[g * p + k]);
                slope.push(local.slope[g * p + k]);
                slope2.extend(local.slope2.map(|s| s[g * p + k]));
                se.push(c.se[g * p + k]);
                nsup.push(local.n_support[g]);
                mass.push(local.kernel_mass[g]);
                cond.push(local.cond[g]);
                status.push(local.status[g].as_str().to_string());
                filled.push(c.filled[g]);
            }
        }
    }
    let two_d = on_2d_index(models);
    let mut cols = vec![("channel", s(ch)), ("m", i(m_)), ("grid", f(grid))];
    if two_d {
        cols.push(("grid2", f(grid2)));
    }
    cols.extend([("f", f(fv)), ("slope", f(slope))]);
    if two_d {
        cols.push(("slope2", f(slope2)));
    }
    cols.extend([
        ("se", f(se)),
        ("n_support", Arc::new(UInt64Array::from(nsup))),
        ("kernel_mass", f(mass)),
        ("cond", f(cond)),
        ("status", s(status)),
        ("filled", Arc::new(BooleanArray::from(filled)) as ArrayRef),
    ]);
    batch(cols)
}

/// One row per channel: order, b, sigma2, bandwidth, RSS, trace, GCV, iterations...;
/// an update's rows add the forgetting factor and the count of new samples; on a 2-D
/// index `bandwidth` is h_1, and `bandwidth2`, `d2` and `index2` (the second index
/// channel) follow the rest.
pub fn params_table(models: &[ModelRow]) -> Result<RecordBatch> {
    let mut b = ListBuilder::new(Float64Builder::new());
    for (_, m, _) in models {
        for v in &m.b {
            b.values().append_value(*v);
        }
        b.append(true);
    }
    let col =
        |g: &dyn Fn(&Farma, &Report) -> f64| f(models.iter().map(|(_, m, r)| g(m, r)).collect());
    let coli =
        |g: &dyn Fn(&Farma, &Report) -> i64| i(models.iter().map(|(_, m, r)| g(m, r)).collect());
    let flag = |g: &dyn Fn(&Report) -> bool| -> ArrayRef {
        Arc::new(BooleanArray::from(
            models.iter().map(|(_, _, r)| g(r)).collect::<Vec<_>>(),
        ))
    };
    let name = |g: &dyn Fn(&Report) -> &'static str| {
        s(models.iter().map(|(_, _, r)| g(r).to_string()).collect())
    };
    let mut cols = vec![
        (
            "channel",
            s(models.iter().map(|(n, _, _)| n.clone()).collect()),
        ),
        ("p", coli(&|m, _| m.p() as i64)),
        ("q", coli(&|m, _| m.q() as i64)),
        ("d", coli(&|m, _| m.d() as i64)),
        ("b", Arc::new(b.finish()) as ArrayRef),
        ("mean", col(&|m, _| m.mean)),
        ("sigma2", col(&|m, _| m.sigma2)),
        ("bandwidth", col(&|m, _| m.bandwidth)),
        ("rss", col(&|_, r| r.rss())),
        ("trace", col(&|_, r| r.trace())),
        ("gcv", col(&|_, r| r.gcv())),
        ("iterations", coli(&|_, r| r.iterations() as i64)),
        ("converged", flag(&|r| r.converged())),
        ("ladder_extended", flag(&|r| r.ladder_extended())),
        ("init", name(&|r| r.init_name())),
        ("method", name(&|r| r.method_name())),
        ("n", coli(&|_, r| r.n() as i64)),
        ("n_rows", coli(&|_, r| r.n_rows() as i64)),
    ];
    if on_2d_index(models) {
        let second = |m: &Farma| m.second().expect("a 2-D index").clone();
        cols.extend([
            ("bandwidth2", col(&|m, _| second(m).bandwidth)),
            ("d2", coli(&|m, _| second(m).lag as i64)),
            (
                "index2",
                s(models.iter().map(|(_, m, _)| second(m).channel).collect()),
            ),
        ]);
    }
    if models
        .iter()
        .any(|(_, _, r)| matches!(r, Report::Update(_)))
    {
        let upd = |g: &dyn Fn(&crate::model::UpdateReport) -> f64| -> Vec<f64> {
            models
                .iter()
                .map(|(_, _, r)| match r {
                    Report::Update(u) => g(u),
                    Report::Fit(_) | Report::Fit2(_) => f64::NAN,
                })
                .collect()
        };
        cols.push(("forgetting", f(upd(&|u| u.forgetting))));
        let n_new: Vec<i64> = upd(&|u| u.w.len() as f64)
            .iter()
            .map(|v| *v as i64)
            .collect();
        cols.push(("n_new", i(n_new)));
    }
    batch(cols)
}

/// The GCV ladder: channel, j (the rung, h_j = 1.1^-j range/2; null for the ladder's
/// limit h -> infinity, whose bandwidth is +inf: the global fit), bandwidth, rss,
/// trace, gcv, n_failed, chosen; on a 2-D index `bandwidth` is h_1 and `bandwidth2`
/// follows it (h_j = 1.1^-j (range_1/2, range_2/2)).
pub fn gcv_table(models: &[ModelRow]) -> Result<RecordBatch> {
    let (mut ch, mut j, mut h, mut h2, mut rss, mut tr, mut gcv, mut nf, mut chosen) = (
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
    );
    for (name, m, rep) in models {
        for r in rep.gcv_table() {
            ch.push(name.clone());
            j.push(r.bandwidth.is_finite().then_some(r.j as i64));
            h.push(r.bandwidth);
            h2.extend(r.bandwidth2);
            rss.push(r.rss);
            tr.push(r.trace);
            gcv.push(r.gcv);
            nf.push(r.n_failed as i64);
            chosen.push((r.bandwidth, r.bandwidth2) == m.bandwidths());
        }
    }
    let j = Arc::new(Int64Array::from(j)) as ArrayRef;
    let mut cols = vec![("channel", s(ch)), ("j", j), ("bandwidth", f(h))];
    if on_2d_index(models) {
        cols.push(("bandwidth2", f(h2)));
    }
    cols.extend([
        ("rss", f(rss)),
        ("trace", f(tr)),
        ("gcv", f(gcv)),
        ("n_failed", i(nf)),
        ("chosen", Arc::new(BooleanArray::from(chosen)) as ArrayRef),
    ]);
    batch(cols)
}

/// One channel's rows of residuals.parquet: its residuals, the sample index t of the
/// first, and the first row that is a residual of the model (`in_fit` true from it
/// on: the rows before are the recursion's warm-up, their lags reaching before the
/// series, not in the RSS).
pub struct ResidualRows<'a> {
    pub channel: &'a str,
    pub values: &'a [f64],
    pub first_t: i64,
    pub in_fit_from: usize,
}

impl<'a> ResidualRows<'a> {
    /// The rows of a fit over a whole series of `n` samples of which `n_rows` are
    /// residuals of the model: t from 0, in the fit from n - n_rows (max(p, q, d), or
    /// with a 2-D index max(p, q, d, d2)) on.
    pub fn of_series(channel: &'a str, values: &'a [f64], n: usize, n_rows: usize) -> Self {
        ResidualRows {
            channel,
            values,
            first_t: 0,
            in_fit_from: n - n_rows,
        }
    }

    /// The rows of a fit ([`ResidualRows::of_series`]), on either index.
    pub fn of_fit<L>(channel: &'a str, r: &'a crate::model::FitReport<L>) -> Self {
        Self::of_series(channel, &r.residuals, r.n, r.n_rows)
    }
}

/// Stages residuals.parquet in `out`: the rows of `rows`, channel after channel, in
/// batches ([`residual_batches`]), with file metadata `md`.
pub fn stage_residuals(
    out: &mut OutputSet,
    rows: &[ResidualRows],
    md: &[(&str, String)],
) -> Result<()> {
    out.parquet_batches(
        "residuals.parquet",
        residual_schema(),
        residual_batches(rows),
        md,
    )
}

/// Rows per batch of [`residual_batches`].
pub const RESIDUAL_BATCH_ROWS: usize = 1 << 20;

/// The schema of residuals.parquet: channel, t (sample index), residual, in_fit.
pub fn residual_schema() -> SchemaRef {
    Arc::new(Schema::new(vec![
        Field::new("channel", DataType::Utf8, false),
        Field::new("t", DataType::Int64, false),
        Field::new("residual", DataType::Float64, false),
        Field::new("in_fit", DataType::Boolean, false),
    ]))
}

/// residuals.parquet's rows, channel after channel, in batches of at most
/// [`RESIDUAL_BATCH_ROWS`] rows ([`residual_schema`]): written one by one
/// ([`crate::output::OutputSet::parquet_batches`]), so that a table of 1e8 rows is
/// never held whole in memory.
pub fn residual_batches<'a>(
    rows: &'a [ResidualRows<'a>],
) -> impl Iterator<Item = Result<RecordBatch>> + 'a {
    residual_batches_of(rows, RESIDUAL_BATCH_ROWS)
}

/// [`residual_batches`] in batches of at most `batch_rows` rows.
fn residual_batches_of<'a>(
    rows: &'a [ResidualRows<'a>],
    batch_rows: usize,
) -> impl Iterator<Item = Result<RecordBatch>> + 'a {
    let schema = residual_schema();
    rows.iter().flat_map(move |r| {
        let schema = schema.clone();
        (0..r.values.len()).step_by(batch_rows).map(move |from| {
            let to = (from + batch_rows).min(r.values.len());
            let cols: Vec<ArrayRef> = vec![
                Arc::new(StringArray::from_iter_values(std::iter::repeat_n(
                    r.channel,
                    to - from,
                ))),
                Arc::new(Int64Array::from_iter_values(
                    (from..to).map(|k| r.first_t + k as i64),
                )),
                Arc::new(Float64Array::from(r.values[from..to].to_vec())),
                Arc::new(BooleanArray::from(
                    (from..to)
                        .map(|k| k >= r.in_fit_from)
                        .collect::<Vec<bool>>(),
                )),
            ];
            RecordBatch::try_new(schema.clone(), cols)
                .map_err(|e| crate::error::Error::Internal(format!("output table: {e}")))
        })
    })
}

/// The `--json` object of one channel (contract keys plus more; an update's adds
/// `forgetting` and `n_new`).
pub fn fit_json(name: &str, m: &Farma, r: Report, coef_path: &str) -> Value {
    let mut v = json!({
        "channel": name,
        "order": [m.p(), m.q(), m.d()],
        "b": m.b,
        "sigma2": m.sigma2,
        "bandwidth": m.bandwidth,
        "rss": r.rss(),
        "trace": r.trace(),
        "gcv": r.gcv(),
        "iterations": r.iterations(),
        "converged": r.converged(),
        "coef": coef_path,
        "mean": m.mean,
        "init": r.init_name(),
        "method": r.method_name(),
        "ladder_extended": r.ladder_extended(),
        "n": r.n(),
        "notes": r.notes(),
    });
    // only where the fit returned its linear start (the other fits' JSON unchanged)
    if let Some(w) = r.returned_start_reason() {
        v["returned_start_reason"] = w.as_str().into();
    }
    if let Report::Update(u) = r {
        v["forgetting"] = u.forgetting.into();
        v["n_new"] = u.w.len().into();
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use arrow_array::Array;

    /// Batches of 3 rows over channels of 7, 0 and 4 rows (a boundary inside a
    /// channel, an empty channel, one at a channel's end) hold the rows written one
    /// by one: channel, t from first_t, the value, in_fit from in_fit_from.
    #[test]
    fn residual_batches_hold_the_rows_one_by_one() {
        let a: Vec<f64> = (0..7).map(|k| k as f64 * 0.5 - 1.0).collect();
        let c = [4.0, -3.0, 2.5, 1e-300];
        let rows = [
            ResidualRows {
                channel: "a",
                values: &a,
                first_t: 0,
                in_fit_from: 2,
            },
            ResidualRows {
                channel: "b",
                values: &[],
                first_t: 5,
                in_fit_from: 0,
            },
            ResidualRows {
                channel: "c",
                values: &c,
                first_t: 100,
                in_fit_from: 0,
            },
        ];
        let mut want = Vec::new();
        for r in &rows {
            for (k, v) in r.values.iter().enumerate() {
                want.push((
                    r.channel.to_string(),
                    r.first_t + k as i64,
                    v.to_bits(),
                    k >= r.in_fit_from,
                ));
            }
        }
        let mut got = Vec::new();
        let mut sizes = Vec::new();
        for b in residual_batches_of(&rows, 3) {
            let b = b.unwrap();
            assert_eq!(b.schema(), residual_schema());
            sizes.push(b.num_rows());
            let col = |i: usize| b.column(i).clone();
            let (ch, t, r, f) = (col(0), col(1), col(2), col(3));
            let ch = ch.as_any().downcast_ref::<StringArray>().unwrap();
            let t = t.as_any().downcast_ref::<Int64Array>().unwrap();
            let r = r.as_any().downcast_ref::<Float64Array>().unwrap();
            let f = f.as_any().downcast_ref::<BooleanArray>().unwrap();
            assert_eq!(f.null_count(), 0);
            for i in 0..b.num_rows() {
                got.push((
                    ch.value(i).to_string(),
                    t.value(i),
                    r.value(i).to_bits(),
                    f.value(i),
                ));
            }
        }
        assert_eq!(sizes, [3, 3, 1, 3, 1]);
        assert_eq!(got, want);
    }
}
