//! The workflow's results as Parquet tables (one row per channel and item) and the
//! writer of a prepared log as a store.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, Int64Array, RecordBatch, StringArray};

use super::prep::ChannelPrep;
use crate::error::Result;
use crate::output::batch;
use crate::store::{Repair, Segment, Store, StoreWriter};

pub(crate) fn s(v: Vec<String>) -> ArrayRef {
    Arc::new(StringArray::from(v))
}
pub(crate) fn f(v: Vec<f64>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}
pub(crate) fn fo(v: Vec<Option<f64>>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}
pub(crate) fn i(v: Vec<i64>) -> ArrayRef {
    Arc::new(Int64Array::from(v))
}
pub(crate) fn io(v: Vec<Option<i64>>) -> ArrayRef {
    Arc::new(Int64Array::from(v))
}

/// prep.parquet: channel, step, count, statistic, z, p_value, value, detail.
pub fn prep_table(chans: &[ChannelPrep]) -> Result<RecordBatch> {
    let (mut ch, mut st, mut cnt, mut stat, mut z, mut p, mut val, mut det) = (
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
        vec![],
    );
    for c in chans {
        for x in &c.steps {
            ch.push(c.name.clone());
            st.push(x.step.clone());
            cnt.push(x.count.map(|v| v as i64));
            stat.push(x.statistic);
            z.push(x.z);
            p.push(x.p_value);
            val.push(x.value);
            det.push(x.detail.clone());
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("step", s(st)),
        ("count", io(cnt)),
        ("statistic", fo(stat)),
        ("z", fo(z)),
        ("p_value", fo(p)),
        ("value", fo(val)),
        ("detail", s(det)),
    ])
}

/// replaced.parquet: channel, index (row of the input), t_s (seconds from the start),
/// original, replacement, pass.
pub fn replaced_table(chans: &[ChannelPrep], rate_hz: f64) -> Result<RecordBatch> {
    let (mut ch, mut idx, mut t, mut o, mut r, mut pass) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for c in chans {
        for x in &c.replaced {
            ch.push(c.name.clone());
            idx.push(x.index as i64);
            t.push(x.index as f64 / rate_hz);
            o.push(x.original);
            r.push(x.replacement);
            pass.push(x.pass as i64);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("index", i(idx)),
        ("t_s", f(t)),
        ("original", f(o)),
        ("replacement", f(r)),
        ("pass", i(pass)),
    ])
}

/// Writes the prepared channels (aligned, see [`super::prep::align`]) as a store
/// beside the source's time column, with the source's metadata plus one repair per
/// step that changed values. `dropped` rows were removed at the start.
pub fn write_prepared_store(
    target: &Path,
    source: &Store,
    chans: &[ChannelPrep],
    dropped: usize,
) -> Result<()> {
    let meta0 = source.meta();
    let n = chans.first().map(|c| c.values.len()).unwrap_or(0);
    let mut names: Vec<String> = Vec::new();
    if let Some(tc) = &meta0.time_col {
        names.push(tc.clone());
    }
    names.extend(chans.iter().map(|c| c.name.clone()));
    let mut w = StoreWriter::create(target, &names, n)?;
    {
        let mut cols = w.columns_mut();
        let mut k = 0;
        if let Some(tc) = &meta0.time_col {
            let t = source.column(tc)?;
            cols[0].copy_from_slice(&t[dropped..dropped + n]);
            k = 1;
        }
        for (c, col) in chans.iter().zip(cols.iter_mut().skip(k)) {
            col.copy_from_slice(&c.values);
        }
    }
    let mut meta = meta0.clone();
    if dropped > 0 {
        let rate = meta.sample_rate_hz;
        let mut segs: Vec<Segment> = Vec::new();
        let mut removed = dropped as u64;
        for sgm in &meta0.segments {
            let cut = removed.min(sgm.len);
            removed -= cut;
            if sgm.len > cut {
                segs.push(Segment {
                    start: (sgm.start + cut).saturating_sub(dropped as u64),
                    len: sgm.len - cut,
                    t0_s: sgm.t0_s + cut as f64 / rate,
                });
            }
        }
        meta.segments = segs;
    }
    for c in chans {
        for st in &c.steps {
            let changed = match st.step.as_str() {
                "pauta" => st.count.unwrap_or(0) > 0,
                "stationarity" | "stationarity_after" | "nonstationary_kept" => false,
                _ => true,
            };
            if changed {
                meta.repairs.push(Repair {
                    kind: format!("prep_{}", st.step),
                    channel: c.name.clone(),
                    count: st.count.unwrap_or(0),
                    detail: st.detail.clone(),
                });
            }
        }
    }
    w.finish(&meta)
}

/// select.parquet: channel, p, q, d, m, rss, sigma2, trace, df, gcv, aicc, bandwidth,
/// converged, arma_rss, arma_sigma2, arma_aicc, f_vs_arma, p_vs_arma, selected,
/// returned_start_reason (null for a local fit; `no_descent` or `ended_above` when the
/// fit returned its linear start, [`crate::model::StartReason`]).
pub fn select_table(sels: &[(String, &super::select::Selection)]) -> Result<RecordBatch> {
    let mut ch = vec![];
    let (mut p, mut q, mut d, mut m) = (vec![], vec![], vec![], vec![]);
    let (mut rss, mut s2, mut tr, mut df, mut gcv, mut aicc, mut h) =
        (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    let (mut conv, mut arss, mut as2, mut aaicc, mut fv, mut pv, mut sel) =
        (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    let mut why: Vec<Option<&'static str>> = vec![];
    for (name, s) in sels {
        for (k, r) in s.rows.iter().enumerate() {
            ch.push(name.clone());
            p.push(r.order.0 as i64);
            q.push(r.order.1 as i64);
            d.push(r.order.2 as i64);
            m.push(r.m as i64);
            rss.push(r.rss);
            s2.push(r.sigma2);
            tr.push(r.trace);
            df.push(r.df);
            gcv.push(r.gcv);
            aicc.push(r.aicc);
            h.push(r.bandwidth);
            conv.push(r.converged);
            arss.push(r.arma_rss);
            as2.push(r.arma_sigma2);
            aaicc.push(r.arma_aicc);
            fv.push(r.f_vs_arma);
            pv.push(r.p_vs_arma);
            sel.push(k == s.selected);
            why.push(r.returned_start_reason.map(|w| w.as_str()));
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("p", i(p)),
        ("q", i(q)),
        ("d", i(d)),
        ("m", i(m)),
        ("rss", f(rss)),
        ("sigma2", f(s2)),
        ("trace", f(tr)),
        ("df", f(df)),
        ("gcv", f(gcv)),
        ("aicc", f(aicc)),
        ("bandwidth", f(h)),
        ("converged", Arc::new(arrow_array::BooleanArray::from(conv))),
        ("arma_rss", f(arss)),
        ("arma_sigma2", f(as2)),
        ("arma_aicc", f(aaicc)),
        ("f_vs_arma", f(fv)),
        ("p_vs_arma", f(pv)),
        ("selected", Arc::new(arrow_array::BooleanArray::from(sel))),
        (
            "returned_start_reason",
            Arc::new(arrow_array::StringArray::from(why)),
        ),
    ])
}

/// ftests.parquet: channel, small, large, f, df1, df2, p_value: the F-tests that are
/// defined; the nested pairs left untested (`Selection::untested`: df_1 <= df_0, or
/// the FARMA returned its linear start) are not written here (the `--json` output
/// and the text list them with the reason).
pub fn ftest_table(sels: &[(String, &super::select::Selection)]) -> Result<RecordBatch> {
    let (mut ch, mut a, mut b, mut fv, mut d1, mut d2, mut pv) =
        (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    for (name, sl) in sels {
        for t in &sl.ftests {
            ch.push(name.clone());
            a.push(t.small.clone());
            b.push(t.large.clone());
            fv.push(t.f);
            d1.push(t.df1);
            d2.push(t.df2);
            pv.push(t.p_value);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("small", s(a)),
        ("large", s(b)),
        ("f", f(fv)),
        ("df1", f(d1)),
        ("df2", f(d2)),
        ("p_value", f(pv)),
    ])
}

/// constancy.parquet: channel, p, q, d, method (chi2, bootstrap), statistic, p_value,
/// min_p (the smallest p the test can give: 1 / (B + 1), 0 for chi2), bootstrap (B, 0
/// for chi2), df (chi2's tr(S) - p, NaN for the bootstrap), trace, bandwidth, rss0,
/// rss1.
pub fn constancy_table(
    rows: &[(String, (usize, usize, usize), &super::constancy::Constancy)],
) -> Result<RecordBatch> {
    let mut ch = vec![];
    let (mut p, mut q, mut d, mut t, mut pv, mut b, mut h, mut r0, mut r1) = (
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
    let (mut meth, mut minp, mut df, mut tr) = (vec![], vec![], vec![], vec![]);
    for (name, o, c) in rows {
        meth.push(c.method.to_string());
        minp.push(c.min_p());
        df.push(c.df);
        tr.push(c.trace);
        ch.push(name.clone());
        p.push(o.0 as i64);
        q.push(o.1 as i64);
        d.push(o.2 as i64);
        t.push(c.statistic);
        pv.push(c.p_value);
        b.push(c.bootstrap as i64);
        h.push(c.bandwidth);
        r0.push(c.rss0);
        r1.push(c.rss1);
    }
    batch(vec![
        ("channel", s(ch)),
        ("p", i(p)),
        ("q", i(q)),
        ("d", i(d)),
        ("method", s(meth)),
        ("statistic", f(t)),
        ("p_value", f(pv)),
        ("min_p", f(minp)),
        ("bootstrap", i(b)),
        ("df", f(df)),
        ("trace", f(tr)),
        ("bandwidth", f(h)),
        ("rss0", f(r0)),
        ("rss1", f(r1)),
    ])
}

/// acf.parquet: channel, lag, acf, band.
pub fn acf_table(rows: &[(String, &super::ljung_box::Whiteness)]) -> Result<RecordBatch> {
    let (mut ch, mut lag, mut r, mut band) = (vec![], vec![], vec![], vec![]);
    for (name, w) in rows {
        for (k, v) in w.acf.iter().enumerate() {
            ch.push(name.clone());
            lag.push(k as i64 + 1);
            r.push(*v);
            band.push(w.band);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("lag", i(lag)),
        ("acf", f(r)),
        ("band", f(band)),
    ])
}

/// ljung_box.parquet: channel, lag, q, df, p_value.
pub fn ljung_box_table(rows: &[(String, &super::ljung_box::Whiteness)]) -> Result<RecordBatch> {
    let (mut ch, mut lag, mut q, mut df, mut p) = (vec![], vec![], vec![], vec![], vec![]);
    for (name, w) in rows {
        for b in &w.ljung_box {
            ch.push(name.clone());
            lag.push(b.lag as i64);
            q.push(b.q);
            df.push(b.df as i64);
            p.push(b.p_value);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("lag", i(lag)),
        ("q", f(q)),
        ("df", i(df)),
        ("p_value", f(p)),
    ])
}

/// prediction.parquet: channel, k (steps ahead), n, rmse_farma, rmse_arma,
/// holdout_std, holdout.
pub fn prediction_table(rows: &[(String, &super::check::Prediction)]) -> Result<RecordBatch> {
    let (mut ch, mut k, mut n, mut rf, mut ra, mut sd, mut ho) =
        (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    for (name, pr) in rows {
        for h in &pr.horizons {
            ch.push(name.clone());
            k.push(h.k as i64);
            n.push(h.n as i64);
            rf.push(h.rmse_farma);
            ra.push(h.rmse_arma);
            sd.push(pr.holdout_std);
            ho.push(pr.holdout as i64);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("k", i(k)),
        ("n", i(n)),
        ("rmse_farma", f(rf)),
        ("rmse_arma", f(ra)),
        ("holdout_std", f(sd)),
        ("holdout", i(ho)),
    ])
}

/// poly.parquet: channel, m, degree, coef (list: 1, u, u^2, ...), wrms, criterion
/// (list by degree).
pub fn poly_table(rows: &[(String, &[super::check::PolyFit])]) -> Result<RecordBatch> {
    use arrow_array::builder::{Float64Builder, ListBuilder};
    let (mut ch, mut m, mut deg, mut w) = (vec![], vec![], vec![], vec![]);
    let mut coef = ListBuilder::new(Float64Builder::new());
    let mut bic = ListBuilder::new(Float64Builder::new());
    for (name, fits) in rows {
        for pf in fits.iter() {
            ch.push(name.clone());
            m.push(pf.m as i64);
            deg.push(pf.degree as i64);
            w.push(pf.wrms);
            coef.values().append_slice(&pf.coef);
            coef.append(true);
            bic.values().append_slice(&pf.criterion);
            bic.append(true);
        }
    }
    batch(vec![
        ("channel", s(ch)),
        ("m", i(m)),
        ("degree", i(deg)),
        ("coef", Arc::new(coef.finish())),
        ("wrms", f(w)),
        ("criterion", Arc::new(bic.finish())),
    ])
}
