//! The analyze workflow's plots, for one channel: each f_m with +-2 SE and the linear
//! ARMA's constant a_m; the order table (RSS and AICc per order, FARMA beside the ARMA
//! baseline); the hold-out prediction against the data (one step ahead) and the RMSE
//! per horizon; the residual ACF with its band and the residuals' histogram.

use plotters::prelude::*;

use super::html::Page;
use super::{color, draw_legend, draw_mesh, legend_line, lin_range, log_range, svg, thin, tick};
use crate::error::Result;
use crate::model::Farma;
use crate::workflow::analyze::ChannelAnalysis;
use crate::workflow::select::order_name;

/// Samples of the hold-out drawn (its first ones) in the prediction plot.
const PREDICTION_SHOWN: usize = 400;
/// Samples before the hold-out over which the one-step residual recursion runs in
/// (the MA part's start-up).
const WARM_UP: usize = 5000;

/// The section of one channel's analysis: `verdict` (one line) first, then the plots.
pub fn channel_section(
    a: &ChannelAnalysis,
    verdict: &str,
    rate_hz: f64,
    unit: &str,
) -> Result<Page> {
    let mut p = Page::default();
    p.h2(&format!("channel {}", a.name));
    p.verdict(&[verdict.to_string()]);
    let sel = &a.selection;
    let (model, report) = &sel.fits[sel.selected];
    let row = &sel.rows[sel.selected];
    p.h3(&format!(
        "coefficient functions of the selected {} (band: +-2 SE; dashed: the linear ARMA's constant a_m)",
        order_name(row.order)
    ));
    for m in 1..=model.p() {
        p.plot(&coef_svg(
            a,
            model,
            m,
            row.arma_ar.get(m - 1).copied(),
            unit,
        )?);
    }
    p.h3("order table: FARMA beside the linear ARMA baseline (selected order ringed)");
    p.plot(&order_svg(a, false, unit)?);
    p.plot(&order_svg(a, true, unit)?);
    if let Some(pr) = &a.check.prediction {
        p.h3(&format!(
            "hold-out: the last {} samples ({:.1} s), not fitted",
            pr.holdout,
            pr.holdout as f64 / rate_hz
        ));
        let baseline = Farma::linear(&row.arma_ar, &row.arma_ma, model.mean, f64::NAN);
        p.plot(&prediction_svg(
            a, model, &baseline, pr.holdout, rate_hz, unit,
        )?);
        p.plot(&horizon_svg(a, unit)?);
    }
    p.h3("residuals of the selected fit");
    p.plot(&acf_svg(a)?);
    p.plot(&histogram_svg(&a.name, &report.residuals, unit)?);
    Ok(p)
}

/// f_m over the index x_{t-d} with +-2 SE, and the ARMA's a_m.
fn coef_svg(
    a: &ChannelAnalysis,
    model: &Farma,
    m: usize,
    arma: Option<f64>,
    unit: &str,
) -> Result<String> {
    let c = &model.coef;
    let p = c.p();
    let n2 = c.n_grid() / c.grid.len().max(1);
    let title = format!("{}: f_{m}", a.name);
    // the lag index only (on a 2-D index the first slice of the second axis)
    let pts: Vec<(f64, f64, f64)> = (0..c.grid.len())
        .map(|g1| g1 * n2)
        .filter(|&g| !c.filled[g])
        .map(|g| {
            (
                c.centred_grid(g) + model.mean,
                c.f[g * p + m - 1],
                c.se[g * p + m - 1],
            )
        })
        .filter(|t| t.0.is_finite() && t.1.is_finite())
        .collect();
    svg(560, 360, &title, |root| {
        let ys = pts
            .iter()
            .flat_map(|t| [t.1, t.1 - 2.0 * t.2, t.1 + 2.0 * t.2])
            .chain(arma);
        let (Some(xr), Some(yr)) = (
            lin_range(pts.iter().map(|t| t.0), 0.02),
            lin_range(ys, 0.08),
        ) else {
            return Ok(());
        };
        let mut chart = ChartBuilder::on(root)
            .caption(&title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(xr.clone(), yr)?;
        draw_mesh(
            &mut chart,
            format!("index x(t-{}) [{unit}]", model.d()),
            format!("f_{m} [-]"),
        )?;
        let band: Vec<(f64, f64)> = pts
            .iter()
            .filter(|t| t.2.is_finite())
            .map(|t| (t.0, t.1 + 2.0 * t.2))
            .chain(
                pts.iter()
                    .rev()
                    .filter(|t| t.2.is_finite())
                    .map(|t| (t.0, t.1 - 2.0 * t.2)),
            )
            .collect();
        if band.len() >= 4 {
            chart
                .draw_series(std::iter::once(Polygon::new(
                    band,
                    color(0).mix(0.2).filled(),
                )))?
                .label("+-2 SE")
                .legend(|(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 18, y + 5)], color(0).mix(0.3).filled())
                });
        }
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|t| (t.0, t.1)),
                color(0).stroke_width(2),
            ))?
            .label(format!("FARMA f_{m}"))
            .legend(legend_line(color(0), 2));
        if let Some(am) = arma.filter(|v| v.is_finite()) {
            chart
                .draw_series(DashedLineSeries::new(
                    [(xr.start, am), (xr.end, am)],
                    6,
                    4,
                    color(1).stroke_width(2),
                ))?
                .label(format!("ARMA a_{m} = {}", tick(&am)))
                .legend(legend_line(color(1), 2));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// The order table: AICc (`aicc`) or RSS per order, FARMA and ARMA.
fn order_svg(a: &ChannelAnalysis, aicc: bool, unit: &str) -> Result<String> {
    let rows = &a.selection.rows;
    let what = if aicc { "AICc" } else { "RSS" };
    let title = format!("{}: {what} per order", a.name);
    let farma: Vec<f64> = rows
        .iter()
        .map(|r| if aicc { r.aicc } else { r.rss })
        .collect();
    let arma: Vec<f64> = rows
        .iter()
        .map(|r| if aicc { r.arma_aicc } else { r.arma_rss })
        .collect();
    let names: Vec<String> = rows.iter().map(|r| order_name(r.order)).collect();
    let n = rows.len();
    svg(560, 380, &title, |root| {
        let Some(yr) = lin_range(farma.iter().chain(&arma).copied(), 0.08) else {
            return Ok(());
        };
        let label = |v: &f64| {
            let k = v.round();
            if (v - k).abs() < 0.01 && k >= 0.0 && (k as usize) < n {
                names[k as usize].clone()
            } else {
                String::new()
            }
        };
        let mut chart = ChartBuilder::on(root)
            .caption(&title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(70)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5f64..n as f64 - 0.5, yr)?;
        chart
            .configure_mesh()
            .axis_desc_style(("sans-serif", 15))
            .label_style(("sans-serif", 12))
            .x_desc("order FARMA(p,q,d) [-]")
            .y_desc(if aicc {
                "AICc [-]".to_string()
            } else {
                format!("RSS [({unit})^2]")
            })
            .x_labels(n.max(2) * 2 - 1)
            .x_label_formatter(&label)
            .x_label_style(
                ("sans-serif", 10)
                    .into_font()
                    .transform(FontTransform::Rotate90),
            )
            .y_label_formatter(&tick)
            .light_line_style(RGBColor(235, 235, 235))
            .draw()?;
        let series = |v: &[f64]| -> Vec<(f64, f64)> {
            v.iter()
                .enumerate()
                .filter(|(_, y)| y.is_finite())
                .map(|(i, y)| (i as f64, *y))
                .collect()
        };
        for (k, (v, name)) in [(&farma, "FARMA"), (&arma, "linear ARMA")]
            .into_iter()
            .enumerate()
        {
            let pts = series(v);
            let col = color(k);
            chart
                .draw_series(LineSeries::new(pts.clone(), col.stroke_width(1)))?
                .label(name)
                .legend(legend_line(col, 2));
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, col.filled())))?;
        }
        let s = a.selection.selected;
        if farma[s].is_finite() {
            chart.draw_series(std::iter::once(Circle::new(
                (s as f64, farma[s]),
                9,
                BLACK.stroke_width(2),
            )))?;
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// The one-step predictions of `model` and `baseline` at the first samples of the
/// hold-out: x_t - e_t, the residual recursion run in over the samples before.
fn one_step(model: &Farma, x: &[f64], from: usize, to: usize) -> Vec<f64> {
    let y: Vec<f64> = x[from..to].iter().map(|v| v - model.mean).collect();
    let e = model.residuals(&y);
    x[from..to].iter().zip(&e).map(|(v, e)| v - e).collect()
}

fn prediction_svg(
    a: &ChannelAnalysis,
    model: &Farma,
    baseline: &Farma,
    holdout: usize,
    rate_hz: f64,
    unit: &str,
) -> Result<String> {
    let x = &a.prep.values;
    let n = x.len();
    let h0 = n - holdout;
    let from = h0.saturating_sub(WARM_UP);
    let to = (h0 + PREDICTION_SHOWN.min(holdout)).min(n);
    let pf = one_step(model, x, from, to);
    let pa = one_step(baseline, x, from, to);
    let t = |i: usize| i as f64 / rate_hz;
    let data: Vec<(f64, f64)> = (h0..to).map(|i| (t(i), x[i])).collect();
    let farma: Vec<(f64, f64)> = (h0..to).map(|i| (t(i), pf[i - from])).collect();
    let arma: Vec<(f64, f64)> = (h0..to).map(|i| (t(i), pa[i - from])).collect();
    let title = format!(
        "{}: one step ahead over the first {} hold-out samples",
        a.name,
        to - h0
    );
    svg(1140, 380, &title, |root| {
        let ys = data.iter().chain(&farma).chain(&arma).map(|p| p.1);
        let (Some(xr), Some(yr)) = (
            lin_range(data.iter().map(|p| p.0), 0.0),
            lin_range(ys, 0.05),
        ) else {
            return Ok(());
        };
        let mut chart = ChartBuilder::on(root)
            .caption(&title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(44)
            .y_label_area_size(78)
            .build_cartesian_2d(xr, yr)?;
        draw_mesh(&mut chart, "time t [s]", format!("{} [{unit}]", a.name))?;
        for (k, (pts, name, w)) in [
            (&data, "data (not fitted)", 1u32),
            (&arma, "linear ARMA", 1),
            (&farma, "FARMA", 2),
        ]
        .into_iter()
        .enumerate()
        {
            let col = [RGBColor(120, 120, 120), color(1), color(0)][k];
            chart
                .draw_series(LineSeries::new(pts.clone(), col.stroke_width(w)))?
                .label(name)
                .legend(legend_line(col, 2));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// The hold-out RMSE per horizon k, FARMA and ARMA, beside the hold-out's std.
fn horizon_svg(a: &ChannelAnalysis, unit: &str) -> Result<String> {
    let Some(pr) = &a.check.prediction else {
        return Ok(String::new());
    };
    let title = format!("{}: hold-out RMSE per horizon", a.name);
    let h = &pr.horizons;
    svg(560, 360, &title, |root| {
        let ys = h
            .iter()
            .flat_map(|r| [r.rmse_farma, r.rmse_arma])
            .chain([pr.holdout_std]);
        let (Some(xr), Some(yr)) = (
            log_range(h.iter().map(|r| r.k as f64), 1.3),
            log_range(ys, 1.3),
        ) else {
            return Ok(());
        };
        let mut chart = ChartBuilder::on(root)
            .caption(&title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(44)
            .y_label_area_size(78)
            .build_cartesian_2d(xr.clone().log_scale(), yr.log_scale())?;
        draw_mesh(&mut chart, "horizon k [samples]", format!("RMSE [{unit}]"))?;
        for (k, name) in ["FARMA", "linear ARMA"].into_iter().enumerate() {
            let pts: Vec<(f64, f64)> = h
                .iter()
                .map(|r| (r.k as f64, if k == 0 { r.rmse_farma } else { r.rmse_arma }))
                .filter(|p| p.1.is_finite() && p.1 > 0.0)
                .collect();
            let col = color(k);
            chart
                .draw_series(LineSeries::new(pts.clone(), col.stroke_width(2)))?
                .label(name)
                .legend(legend_line(col, 2));
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, col.filled())))?;
        }
        if pr.holdout_std.is_finite() && pr.holdout_std > 0.0 {
            chart
                .draw_series(DashedLineSeries::new(
                    [(xr.start, pr.holdout_std), (xr.end, pr.holdout_std)],
                    6,
                    4,
                    BLACK.stroke_width(1),
                ))?
                .label("std of the hold-out")
                .legend(legend_line(BLACK, 1));
        }
        draw_legend(&mut chart, SeriesLabelPosition::LowerRight)?;
        Ok(())
    })
}

/// The residual ACF (lags 1..) with its +-band.
fn acf_svg(a: &ChannelAnalysis) -> Result<String> {
    let w = &a.check.whiteness;
    let title = format!(
        "{}: residual ACF ({} of {} lags outside +-{})",
        a.name,
        w.outside,
        w.acf.len(),
        tick(&w.band)
    );
    acf_bars_svg(&title, &w.acf, w.band, None)
}

/// An autocorrelation as bars at lags 1, 2, ... (`acf[k]` at lag k + 1; bars outside
/// +-`band` in the second colour) with the dashed white-noise band; the lag axis in
/// seconds when `rate_hz` is given, in samples otherwise.
pub fn acf_bars_svg(title: &str, acf: &[f64], band: f64, rate_hz: Option<f64>) -> Result<String> {
    svg(560, 360, title, |root| {
        let dt = rate_hz.map_or(1.0, |r| 1.0 / r);
        let n = acf.len();
        let Some(yr) = lin_range(acf.iter().copied().chain([band, -band]), 0.1) else {
            return Ok(());
        };
        let x_end = (n as f64 + 1.0) * dt;
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(0f64..x_end, yr)?;
        let x_label = if rate_hz.is_some() {
            "lag [s]"
        } else {
            "lag [samples]"
        };
        draw_mesh(&mut chart, x_label, "autocorrelation [-]")?;
        for (k, v) in acf.iter().enumerate() {
            if v.is_finite() {
                let lag = (k as f64 + 1.0) * dt;
                let col = if v.abs() > band { color(1) } else { color(0) };
                chart.draw_series(LineSeries::new(
                    [(lag, 0.0), (lag, *v)],
                    col.stroke_width(if n > 200 { 1 } else { 2 }),
                ))?;
            }
        }
        for s in [1.0, -1.0] {
            let r = chart.draw_series(DashedLineSeries::new(
                [(0.0, s * band), (x_end, s * band)],
                6,
                4,
                BLACK.stroke_width(1),
            ))?;
            if s > 0.0 {
                r.label("white-noise band +-1.96/sqrt(N)")
                    .legend(legend_line(BLACK, 1));
            }
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// The histogram of the residuals (density) with the normal density of their mean
/// and standard deviation.
pub fn histogram_svg(channel: &str, residuals: &[f64], unit: &str) -> Result<String> {
    let r: Vec<f64> = residuals
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    let n = r.len() as f64;
    let mean = r.iter().sum::<f64>() / n.max(1.0);
    let sd = (r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
    let title = format!("{channel}: histogram of the residuals ({} values)", r.len());
    svg(560, 360, &title, |root| {
        if r.len() < 2 || sd.is_nan() || sd <= 0.0 {
            return Ok(());
        }
        let (lo, hi) = (mean - 4.0 * sd, mean + 4.0 * sd);
        const BINS: usize = 50;
        let wbin = (hi - lo) / BINS as f64;
        let mut counts = [0usize; BINS];
        for v in &r {
            let k = ((v - lo) / wbin).floor();
            if k >= 0.0 && (k as usize) < BINS {
                counts[k as usize] += 1;
            }
        }
        let dens: Vec<f64> = counts.iter().map(|&c| c as f64 / (n * wbin)).collect();
        let pdf = |x: f64| {
            (-0.5 * ((x - mean) / sd).powi(2)).exp() / (sd * (2.0 * std::f64::consts::PI).sqrt())
        };
        let top = dens.iter().copied().fold(pdf(mean), f64::max) * 1.1;
        let mut chart = ChartBuilder::on(root)
            .caption(&title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(lo..hi, 0.0..top)?;
        draw_mesh(
            &mut chart,
            format!("residual [{unit}]"),
            format!("density [1/({unit})]"),
        )?;
        chart
            .draw_series(dens.iter().enumerate().map(|(k, d)| {
                let a = lo + k as f64 * wbin;
                Rectangle::new([(a, 0.0), (a + wbin, *d)], color(0).mix(0.5).filled())
            }))?
            .label("residuals")
            .legend(|(x, y)| {
                Rectangle::new([(x, y - 5), (x + 18, y + 5)], color(0).mix(0.5).filled())
            });
        let curve: Vec<(f64, f64)> = (0..=200)
            .map(|i| lo + (hi - lo) * i as f64 / 200.0)
            .map(|x| (x, pdf(x)))
            .collect();
        chart
            .draw_series(LineSeries::new(thin(&curve, 201), color(1).stroke_width(2)))?
            .label("normal density (same mean and sd)")
            .legend(legend_line(color(1), 2));
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}
