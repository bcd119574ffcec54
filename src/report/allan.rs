//! The Allan plot (each deviation curve the adev job computed with its confidence
//! band, each identified IEEE 952 noise term's line and their sum, the tau range of
//! the fit marked) and the PSD with the noise terms' slopes.

use plotters::prelude::*;

use super::{Drawn, color, draw_legend, draw_mesh, legend_line, log_range, svg, thin, tick};
use crate::error::Result;
use crate::stats::adev::{Curve, Kind};
use crate::stats::noise_terms::{Identification, Term};
use crate::stats::psd::Psd;

/// The long name of a deviation kind.
pub fn kind_title(k: Kind) -> &'static str {
    match k {
        Kind::Adev => "Allan deviation",
        Kind::Mdev => "modified Allan deviation",
        Kind::Hdev => "Hadamard deviation",
    }
}

/// A noise term's name as the Allan plot's legend writes it.
pub fn term_title(t: Term) -> &'static str {
    match t {
        Term::Quantization => "quantization Q",
        Term::WhiteNoise => "angle random walk N",
        Term::BiasInstability => "bias instability B",
        Term::RateRandomWalk => "rate random walk K",
        Term::RateRamp => "rate ramp R",
        Term::GaussMarkov => "Gauss-Markov",
    }
}

/// The deviation of term `t` of `id` at tau \[s\] (sqrt of its AVAR).
fn term_dev(id: &Identification, t: Term, tau_s: f64) -> f64 {
    id.get(t).map_or(f64::NAN, |e| {
        let ct = e.corr_time_s.map_or(1.0, |c| c.value);
        (e.coef_sq.value * t.basis(tau_s, ct)).sqrt()
    })
}

/// `n` log-spaced taus from `a` to `b`.
fn log_taus(a: f64, b: f64, n: usize) -> Vec<f64> {
    let (la, lb) = (a.ln(), b.ln());
    (0..n)
        .map(|i| (la + (lb - la) * i as f64 / (n - 1) as f64).exp())
        .collect()
}

/// The Allan plot of one channel: every curve of `curves` with its band, and the
/// noise terms of `id` (fitted to the Allan variance) with their sum.
pub fn allan_svg(
    channel: &str,
    unit: &str,
    curves: &[Curve],
    id: Option<&Identification>,
) -> Result<String> {
    let title = format!("{channel}: deviations with their confidence intervals");
    svg(900, 560, &title, |root| {
        draw_allan(root, &title, unit, curves, id)
    })
}

fn draw_allan(
    root: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    title: &str,
    unit: &str,
    curves: &[Curve],
    id: Option<&Identification>,
) -> Drawn {
    let taus = || curves.iter().flat_map(|c| c.points.iter().map(|p| p.tau_s));
    let devs = || {
        curves
            .iter()
            .flat_map(|c| c.points.iter().flat_map(|p| [p.dev, p.lo, p.hi]))
    };
    let (Some(xr), Some(yr)) = (log_range(taus(), 1.3), log_range(devs(), 1.5)) else {
        return Ok(());
    };
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d(xr.clone().log_scale(), yr.clone().log_scale())?;
    draw_mesh(
        &mut chart,
        "averaging time tau [s]",
        format!("deviation [{unit}]"),
    )?;
    // the tau range the noise terms were fitted to
    if let Some(id) = id
        && let (Some(a), Some(b)) = (id.points.first(), id.points.last())
    {
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(a.tau_s, yr.start), (b.tau_s, yr.end)],
                RGBColor(250, 250, 234).filled(),
            )))?
            .label(format!(
                "tau range of the noise-term fit ({} to {} s)",
                tick(&a.tau_s),
                tick(&b.tau_s)
            ))
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 5), (x + 18, y + 5)],
                    RGBColor(236, 236, 190).filled(),
                )
            });
    }
    for (i, c) in curves.iter().enumerate() {
        let col = color(i);
        let band: Vec<(f64, f64)> = c
            .points
            .iter()
            .filter(|p| p.lo.is_finite() && p.hi.is_finite() && p.lo > 0.0)
            .map(|p| (p.tau_s, p.hi))
            .chain(
                c.points
                    .iter()
                    .rev()
                    .filter(|p| p.lo.is_finite() && p.hi.is_finite() && p.lo > 0.0)
                    .map(|p| (p.tau_s, p.lo)),
            )
            .collect();
        if band.len() >= 4 {
            chart.draw_series(std::iter::once(Polygon::new(band, col.mix(0.18).filled())))?;
        }
        let pts: Vec<(f64, f64)> = c
            .points
            .iter()
            .filter(|p| p.dev.is_finite() && p.dev > 0.0)
            .map(|p| (p.tau_s, p.dev))
            .collect();
        let pts = thin(&pts, 2000);
        chart
            .draw_series(LineSeries::new(pts.clone(), col.stroke_width(2)))?
            .label(format!(
                "{} (band: confidence interval)",
                kind_title(c.kind)
            ))
            .legend(legend_line(col, 2));
        if pts.len() <= 80 {
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 2, col.filled())))?;
        }
    }
    if let Some(id) = id {
        let grid = log_taus(xr.start, xr.end, 120);
        for (k, t) in id.terms.iter().enumerate() {
            let col = color(k + 3);
            let line: Vec<(f64, f64)> = grid
                .iter()
                .map(|&tau| (tau, term_dev(id, t.term, tau)))
                .filter(|(_, v)| v.is_finite() && *v >= yr.start && *v <= yr.end)
                .collect();
            if line.len() < 2 {
                continue;
            }
            chart
                .draw_series(DashedLineSeries::new(line, 6, 4, col.stroke_width(2)))?
                .label(format!(
                    "{} = {} +- {} {}",
                    term_title(t.term),
                    fmt_sig(t.coef.value),
                    fmt_sig(t.coef.unc),
                    t.term.coef_unit().replace('u', unit)
                ))
                .legend(legend_line(col, 2));
        }
        if !id.terms.is_empty() {
            let sum: Vec<(f64, f64)> = grid
                .iter()
                .map(|&tau| (tau, id.model_avar(tau).sqrt()))
                .filter(|(_, v)| v.is_finite() && *v >= yr.start && *v <= yr.end)
                .collect();
            chart
                .draw_series(LineSeries::new(sum, BLACK.stroke_width(1)))?
                .label("sum of the noise terms (IEEE 952 model)")
                .legend(legend_line(BLACK, 1));
        }
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    Ok(())
}

/// A value with 3 significant digits.
pub fn fmt_sig(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e4).contains(&a) {
        format!("{v:.2e}")
    } else {
        let digits = if a == 0.0 {
            3
        } else {
            (2 - a.log10().floor() as i32).max(0) as usize
        };
        format!("{v:.digits$}")
    }
}

/// The one-sided rate PSD \[u^2/Hz\] of noise term `t` at f \[Hz\] (IEEE 952 writes
/// its PSDs two-sided: one-sided is twice that), for a log at `rate_hz`.
pub fn term_psd(id: &Identification, t: Term, f: f64) -> f64 {
    let Some(e) = id.get(t) else { return f64::NAN };
    let c2 = e.coef_sq.value;
    let pi = std::f64::consts::PI;
    match t {
        Term::Quantization => 2.0 * (2.0 * pi * f).powi(2) * c2 / id.rate_hz,
        Term::WhiteNoise => 2.0 * c2,
        Term::BiasInstability => c2 / (pi * f),
        Term::RateRandomWalk => c2 / (2.0 * pi * pi * f * f),
        Term::RateRamp => f64::NAN,
        Term::GaussMarkov => {
            let tc = e.corr_time_s.map_or(f64::NAN, |c| c.value);
            4.0 * c2 * tc / (1.0 + (2.0 * pi * f * tc).powi(2))
        }
    }
}

/// The PSD plot of one channel: Welch's one-sided PSD and the noise terms' slopes.
pub fn psd_svg(
    channel: &str,
    unit: &str,
    psd: &Psd,
    id: Option<&Identification>,
) -> Result<String> {
    let title = format!("{channel}: power spectral density (Welch, one-sided)");
    svg(900, 480, &title, |root| {
        let pts: Vec<(f64, f64)> = psd
            .freq_hz
            .iter()
            .zip(&psd.psd)
            .filter(|(f, p)| **f > 0.0 && p.is_finite() && **p > 0.0)
            .map(|(f, p)| (*f, *p))
            .collect();
        let pts = thin(&pts, 3000);
        let (Some(xr), Some(yr)) = (
            log_range(pts.iter().map(|p| p.0), 1.1),
            log_range(pts.iter().map(|p| p.1), 3.0),
        ) else {
            return Ok(());
        };
        let mut chart = ChartBuilder::on(root)
            .caption(&title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(80)
            .build_cartesian_2d(xr.clone().log_scale(), yr.clone().log_scale())?;
        draw_mesh(
            &mut chart,
            "frequency f [Hz]",
            format!("PSD [({unit})^2/Hz]"),
        )?;
        chart
            .draw_series(LineSeries::new(pts, color(0).stroke_width(1)))?
            .label("PSD of the log")
            .legend(legend_line(color(0), 1));
        if let Some(id) = id {
            let grid = log_taus(xr.start, xr.end, 120);
            for (k, t) in id.terms.iter().enumerate() {
                let col = color(k + 3);
                let line: Vec<(f64, f64)> = grid
                    .iter()
                    .map(|&f| (f, term_psd(id, t.term, f)))
                    .filter(|(_, v)| v.is_finite() && *v >= yr.start && *v <= yr.end)
                    .collect();
                if line.len() < 2 {
                    continue;
                }
                chart
                    .draw_series(DashedLineSeries::new(line, 6, 4, col.stroke_width(2)))?
                    .label(format!("{} (slope of the term)", term_title(t.term)))
                    .legend(legend_line(col, 2));
            }
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// `report.html` of an adev run: per channel the verdict on its noise terms (each
/// term found, warnings where the fit is poor or a term's uncertainty exceeds its
/// value) first, then the Allan plot, the PSD, the autocorrelation with its band and
/// the table of the terms.
pub fn adev_page(
    log: &str,
    rate_hz: f64,
    done: &[crate::jobs::adev::ChannelAdev],
) -> Result<String> {
    use super::html::Page;
    let mut p = Page::new(&format!("farma adev: {log}"));
    let mut lines = Vec::new();
    for r in done {
        let unit = r
            .unit
            .map_or_else(|| super::unit_of(&r.channel), |u| u.name());
        match &r.terms {
            Err(e) => lines.push(format!(
                "!{}: no noise terms could be fitted: {e}",
                r.channel
            )),
            Ok(id) => {
                let found: Vec<String> = id
                    .terms
                    .iter()
                    .map(|t| {
                        format!(
                            "{} = {} +- {} {}",
                            t.term.coef_name(),
                            fmt_sig(t.coef.value),
                            fmt_sig(t.coef.unc),
                            t.term.coef_unit().replace('u', unit)
                        )
                    })
                    .collect();
                lines.push(format!(
                    "{}: {} (fitted to {} octave taus, dispersion {})",
                    r.channel,
                    if found.is_empty() {
                        "no noise term found".to_string()
                    } else {
                        found.join(", ")
                    },
                    id.points.len(),
                    fmt_sig(id.dispersion)
                ));
                if let Some(m) = &id.minimum {
                    lines.push(format!(
                        "{}: bias instability read off the curve's minimum as a datasheet does (adev {} {unit} at tau = {} s, / 0.664): {} +- {} {unit}{}",
                        r.channel,
                        fmt_sig(m.adev),
                        fmt_sig(m.tau_s),
                        fmt_sig(m.b),
                        fmt_sig(m.b_unc),
                        if m.at_last_tau {
                            " (the curve still falls at its last tau: an upper bound)"
                        } else {
                            ""
                        }
                    ));
                }
                lines.push(format!("{}: {}", r.channel, id.tau_min.explain()));
                if id.get(Term::BiasInstability).is_none() {
                    lines.push(format!(
                        "!{}: no bias instability found; where the sensor's output filter bends the shortest taus, try --fit-tau-min",
                        r.channel
                    ));
                }
                for t in &id.terms {
                    if t.coef.unc > t.coef.value.abs() {
                        lines.push(format!(
                            "!{}: the {} term's uncertainty ({}) exceeds its value ({}): the term is not determined by this log",
                            r.channel,
                            t.term.kind_name(),
                            fmt_sig(t.coef.unc),
                            fmt_sig(t.coef.value)
                        ));
                    }
                }
                if id.dispersion > crate::jobs::adev::POOR_DISPERSION {
                    lines.push(format!(
                        "!{}: the terms fit the Allan variance poorly (dispersion {} > {}: the model misses a feature of the curve); try --fit-tau-min",
                        r.channel,
                        fmt_sig(id.dispersion),
                        crate::jobs::adev::POOR_DISPERSION
                    ));
                }
            }
        }
    }
    p.verdict(&lines);
    for r in done {
        let unit = r
            .unit
            .map_or_else(|| super::unit_of(&r.channel), |u| u.name());
        let id = r.terms.as_ref().ok();
        p.h2(&format!("channel {}", r.channel));
        p.plot(&allan_svg(&r.channel, unit, &r.curves, id)?);
        if let Some(psd) = &r.psd {
            p.plot(&psd_svg(&r.channel, unit, psd, id)?);
        }
        if let Some(a) = &r.acf {
            let lags = &a.acf[1..];
            let outside = lags.iter().filter(|v| v.abs() > a.band).count();
            let title = format!(
                "{}: autocorrelation ({} of {} lags outside +-{})",
                r.channel,
                outside,
                lags.len(),
                tick(&a.band)
            );
            p.plot(&super::analysis::acf_bars_svg(
                &title,
                lags,
                a.band,
                Some(rate_hz),
            )?);
        }
        if let Some(id) = id {
            let rows: Vec<Vec<String>> = id
                .terms
                .iter()
                .map(|t| {
                    vec![
                        t.term.kind_name().to_string(),
                        t.term.coef_name().to_string(),
                        fmt_sig(t.coef.value),
                        fmt_sig(t.coef.unc),
                        t.term.coef_unit().replace('u', unit),
                        t.corr_time_s.map_or(String::new(), |c| {
                            format!("{} +- {}", fmt_sig(c.value), fmt_sig(c.unc))
                        }),
                    ]
                })
                .chain(id.minimum.iter().map(|m| {
                    vec![
                        format!(
                            "{} (curve minimum / 0.664)",
                            crate::jobs::adev::READING_TERM
                        ),
                        "b".to_string(),
                        fmt_sig(m.b),
                        fmt_sig(m.b_unc),
                        unit.to_string(),
                        String::new(),
                    ]
                }))
                .collect();
            p.table(
                &[
                    "term (IEEE 952)",
                    "coef",
                    "value",
                    "uncertainty (1 sd)",
                    "unit",
                    "correlation time [s]",
                ],
                &rows,
            );
        }
    }
    p.p(
        "note",
        &format!(
            "Sample rate {} Hz. Unit read from the channel name ({}); u: the channel's unit where the name does not say it.",
            tick(&rate_hz),
            "_dps deg/s, _rps rad/s"
        ),
    );
    Ok(p.finish(&format!("farma adev: {log}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits() {
        assert_eq!(fmt_sig(0.008123), "0.00812");
        assert_eq!(fmt_sig(12.345), "12.3");
        assert_eq!(fmt_sig(1.5e-6), "1.50e-6");
    }
}
