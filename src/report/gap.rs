//! The gap report redrawn with plotters: the Allan deviation and the PSD of the real
//! log's withheld part against the simulations of the spec (mean +- 2 sd of the
//! ensemble), before and after the added effects, the out-of-band regions shaded; the
//! candidate effects ranked by how much of the gap they remove; and the page.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::html::Page;
use super::{
    Drawn, color, draw_legend, draw_mesh, legend_line, lin_range, log_range, svg, tick, unit_of,
};
use crate::diagnosis::{Diagnosis, EnsembleStats, Region, Statistic};
use crate::error::Result;

/// The report's SVG of one diagnosis (`report.svg`, and the plot of `report.html`):
/// the Allan panels, the PSD panels and the effects.
pub fn gap_svg(d: &Diagnosis) -> Result<String> {
    let unit = unit_of(&d.channel);
    let title = format!("farma gap: channel {}", d.channel);
    svg(1000, 1500, &title, |root| {
        let (top, rest) = root.split_vertically(760);
        let (psd, eff) = rest.split_vertically(420);
        let (a1, a2) = top.split_vertically(380);
        panel(
            &a1,
            d,
            Statistic::Adev,
            &d.ens_before,
            &d.where_before,
            "before",
            unit,
        )?;
        panel(
            &a2,
            d,
            Statistic::Adev,
            &d.ens_after,
            &d.where_after,
            "after the added effects",
            unit,
        )?;
        let (p1, p2) = psd.split_horizontally(500);
        panel(
            &p1,
            d,
            Statistic::Psd,
            &d.ens_before,
            &d.where_before,
            "before",
            unit,
        )?;
        panel(
            &p2,
            d,
            Statistic::Psd,
            &d.ens_after,
            &d.where_after,
            "after",
            unit,
        )?;
        effects(&eff, d)
    })
}

/// Real value and ensemble band of feature `i` in plot units: ADEV = exp(ln AVAR / 2),
/// PSD = exp(ln PSD).
fn to_plot(stat: Statistic, v: f64) -> f64 {
    match stat {
        Statistic::Adev => (0.5 * v).exp(),
        _ => v.exp(),
    }
}

#[allow(clippy::too_many_arguments)]
fn panel(
    area: &DrawingArea<SVGBackend, Shift>,
    d: &Diagnosis,
    stat: Statistic,
    e: &EnsembleStats,
    regions: &[Region],
    when: &str,
    unit: &str,
) -> Drawn {
    let mut idx: Vec<usize> = (0..d.defs.len())
        .filter(|&i| d.defs[i].statistic == stat && d.defs[i].lo > 0.0)
        .collect();
    // fold 1's withheld part: the features up to where fold 2's start again
    if let Some(k) = idx
        .windows(2)
        .position(|w| d.defs[w[1]].lo < d.defs[w[0]].lo)
    {
        idx.truncate(k + 1);
    }
    if idx.len() < 2 {
        return Ok(());
    }
    // tau for the Allan features; the band's centre (geometric) for the PSD's
    let x = |i: usize| (d.defs[i].lo * d.defs[i].hi.max(d.defs[i].lo)).sqrt();
    let band = |i: usize, s: f64| to_plot(stat, e.mean[i] + s * 2.0 * e.sd[i]);
    let ys = idx
        .iter()
        .flat_map(|&i| [band(i, -1.0), band(i, 1.0), to_plot(stat, d.real[i])]);
    let (Some(xr), Some(yr)) = (
        log_range(idx.iter().map(|&i| x(i)), 1.2),
        log_range(ys, 1.5),
    ) else {
        return Ok(());
    };
    let (name, xdesc, ydesc) = match stat {
        Statistic::Adev => (
            "Allan deviation",
            "averaging time tau [s]".to_string(),
            format!("Allan deviation [{unit}]"),
        ),
        _ => (
            "PSD",
            "frequency f [Hz]".to_string(),
            format!("PSD [({unit})^2/Hz]"),
        ),
    };
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "{name} of fold 1's withheld part, {when} (gap {})",
                gap_of(d, when)
            ),
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(44)
        .y_label_area_size(78)
        .build_cartesian_2d(xr.clone().log_scale(), yr.clone().log_scale())?;
    draw_mesh(&mut chart, xdesc, ydesc)?;
    let shaded: Vec<&Region> = regions.iter().filter(|r| r.statistic == stat).collect();
    for (k, r) in shaded.iter().enumerate() {
        let (a, b) = (r.lo.max(xr.start) / 1.08, r.hi.min(xr.end) * 1.08);
        let s = chart.draw_series(std::iter::once(Rectangle::new(
            [(a, yr.start), (b, yr.end)],
            RGBColor(244, 199, 195).mix(0.6).filled(),
        )))?;
        if k == 0 {
            s.label("out of the band (real differs)").legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 5), (x + 18, y + 5)],
                    RGBColor(244, 199, 195).filled(),
                )
            });
        }
    }
    let poly: Vec<(f64, f64)> = idx
        .iter()
        .map(|&i| (x(i), band(i, 1.0)))
        .chain(idx.iter().rev().map(|&i| (x(i), band(i, -1.0))))
        .filter(|(_, y)| y.is_finite() && *y > 0.0)
        .collect();
    chart
        .draw_series(std::iter::once(Polygon::new(
            poly,
            RGBColor(158, 202, 225).mix(0.6).filled(),
        )))?
        .label("simulations of the spec (mean +- 2 sd)")
        .legend(|(x, y)| {
            Rectangle::new(
                [(x, y - 5), (x + 18, y + 5)],
                RGBColor(158, 202, 225).filled(),
            )
        });
    let real: Vec<(f64, f64)> = idx
        .iter()
        .map(|&i| (x(i), to_plot(stat, d.real[i])))
        .filter(|(_, y)| y.is_finite() && *y > 0.0)
        .collect();
    chart
        .draw_series(LineSeries::new(real.clone(), color(1).stroke_width(2)))?
        .label("real log")
        .legend(legend_line(color(1), 2));
    chart.draw_series(real.iter().map(|&p| Circle::new(p, 2, color(1).filled())))?;
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    Ok(())
}

fn gap_of(d: &Diagnosis, when: &str) -> String {
    let g = if when == "before" {
        d.gap_before
    } else {
        d.gap_after
    };
    format!("{g:.2}")
}

/// The ranked candidate effects as bars of their shrink (the added ones dark).
fn effects(area: &DrawingArea<SVGBackend, Shift>, d: &Diagnosis) -> Drawn {
    let shown: Vec<_> = d.effects.iter().take(10).collect();
    let n = shown.len().max(1);
    let xr = lin_range(
        shown.iter().map(|e| 100.0 * e.shrink).chain([0.0, 100.0]),
        0.02,
    )
    .unwrap_or(0.0..100.0);
    let mut chart = ChartBuilder::on(area)
        .caption(
            "candidate effects, ranked by the shrink of the withheld-part gap (added: dark)",
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(44)
        .y_label_area_size(78)
        .build_cartesian_2d(xr.clone(), -0.5f64..n as f64 - 0.5)?;
    chart
        .configure_mesh()
        .axis_desc_style(("sans-serif", 15))
        .label_style(("sans-serif", 12))
        .x_desc("shrink of the gap [%]")
        .y_desc("candidate effect [rank]")
        .y_labels(n.min(10))
        .y_label_formatter(&|v| format!("{}", v.round() as i64 + 1))
        .x_label_formatter(&tick)
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    for (i, e) in shown.iter().enumerate() {
        let y = i as f64;
        let added = d
            .added
            .iter()
            .any(|a| a.kind == e.kind && a.params == e.params);
        let col = if added {
            RGBColor(31, 119, 60)
        } else {
            RGBColor(152, 223, 138)
        };
        let w = 100.0 * e.shrink;
        chart.draw_series(std::iter::once(Rectangle::new(
            [(0.0f64.max(xr.start), y - 0.35), (w, y + 0.35)],
            col.filled(),
        )))?;
        chart.draw_series(std::iter::once(Text::new(
            format!("{} ({:.1} %)", e.kind, w),
            (xr.start + 0.01 * (xr.end - xr.start), y + 0.1),
            ("sans-serif", 13).into_font().color(&BLACK),
        )))?;
    }
    Ok(())
}

/// `report.html` of one or more diagnoses: the verdict of each channel first, then its
/// plots and tables.
pub fn gap_page(real: &str, spec: &str, done: &[Diagnosis]) -> Result<String> {
    let mut p = Page::new(&format!("farma gap: {real} against {spec}"));
    let mut lines = Vec::new();
    for d in done {
        let sig = d.significant;
        let mut l = format!(
            "{}: gap {:.2} before, {:.2} after the added effects (noise floor {:.2}, significant above {:.2}): {}",
            d.channel,
            d.gap_before,
            d.gap_after,
            d.noise_floor,
            d.gap_threshold,
            if sig {
                "the simulator differs from the real sensor"
            } else {
                "no significant gap"
            }
        );
        if !d.added.is_empty() {
            l += &format!(
                "; added: {}",
                d.added
                    .iter()
                    .map(|e| e.kind.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        if let Some(ps) = &d.per_sample {
            l += &format!(
                "; the per-sample part (its first {} samples at its own rate): gap {:.2} -> {:.2} (significant above {:.2}){}",
                ps.blocks.n,
                ps.gap_before,
                ps.gap_after,
                ps.gap_threshold,
                if ps.added.is_empty() {
                    String::new()
                } else {
                    format!(
                        ", added: {}",
                        ps.added
                            .iter()
                            .map(|e| e.kind.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                }
            );
        }
        lines.push(if sig && !d.explained {
            format!("!{l} (not explained by the added effects)")
        } else {
            l
        });
    }
    p.verdict(&lines);
    let sections = done.iter().flat_map(|d| {
        let part = d.per_sample.as_deref().map(|ps| {
            (
                format!(
                    "channel {}: the per-sample part (the log's first {} samples at its own rate, against the spec after the averaged diagnosis)",
                    d.channel, ps.blocks.n
                ),
                ps,
            )
        });
        std::iter::once((format!("channel {}", d.channel), d)).chain(part)
    });
    for (title, d) in sections {
        p.h2(&title);
        p.plot(&gap_svg(d)?);
        if !d.events_excluded.is_empty() {
            p.h3("test-stand events excluded (replaced by the stretch before each)");
            let rows: Vec<Vec<String>> = d
                .events_excluded
                .iter()
                .map(|e| {
                    vec![
                        format!("{:.2} .. {:.2}", e.start_s, e.end_s),
                        format!("{:.1}", e.peak_sd),
                        e.channels.join(", "),
                    ]
                })
                .collect();
            p.table(&["span [s]", "peak [robust sd]", "seen on"], &rows);
        }
        p.h3("where the real log is out of the simulations' band (before)");
        let rows: Vec<Vec<String>> = d
            .where_before
            .iter()
            .map(|r| {
                vec![
                    r.fold.to_string(),
                    r.statistic.as_str().to_string(),
                    r.feature.clone(),
                    if r.is_whole_part() {
                        "whole withheld part".to_string()
                    } else {
                        format!("{} .. {} {}", tick(&r.lo), tick(&r.hi), r.unit)
                    },
                    format!("{:.2}", r.excess),
                    tick(&r.ratio_or_delta),
                ]
            })
            .collect();
        if rows.is_empty() {
            p.p("", "nowhere");
        } else {
            p.table(
                &[
                    "fold",
                    "statistic",
                    "feature",
                    "range",
                    "excess [sd]",
                    "real / sim (or real - sim)",
                ],
                &rows,
            );
        }
        p.h3("candidate effects");
        let rows: Vec<Vec<String>> = d
            .effects
            .iter()
            .enumerate()
            .map(|(i, e)| {
                vec![
                    (i + 1).to_string(),
                    e.kind.clone(),
                    format!("{:.1}", 100.0 * e.shrink),
                    format!("{:.3}", e.gap_after),
                    e.params.to_string(),
                    e.note.clone(),
                ]
            })
            .collect();
        p.table(
            &[
                "rank",
                "effect",
                "shrink [%]",
                "gap after",
                "params",
                "note",
            ],
            &rows,
        );
        for n in &d.not_tried {
            p.p("note", &format!("not tried: {}: {}", n.kind, n.reason));
        }
        for j in &d.joint_pairs {
            p.p(
                "note",
                &format!(
                    "joint pair {} + {}: gap after {:.3}, {}: {}",
                    j.kinds[0],
                    j.kinds[1],
                    j.gap_after,
                    if j.added { "added" } else { "not added" },
                    j.reason
                ),
            );
        }
        for n in &d.notes {
            p.p("note", &format!("note: {n}"));
        }
    }
    Ok(p.finish(&format!("farma gap: {real}")))
}
