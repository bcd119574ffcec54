//! Reports a person opens in a browser: plots drawn with `plotters` (SVG backend, no
//! fonts rendered: the browser draws the text) and self-contained HTML pages
//! (`report.html`: inline SVG and a small inline style, no network, no script), the
//! verdict first and the detail below.
//!
//! One file per plot family: [`allan`] (Allan / modified / Hadamard deviation with the
//! IEEE 952 noise terms, the PSD with the terms' slopes), [`analysis`] (the analyze
//! workflow: f_m with +-2 SE, the order table, the hold-out prediction, the residual
//! ACF and histogram), [`gap`] (the sim-to-real gap); [`html`] builds the pages.
//!
//! Every plot carries axis titles with units (`tau [s]`); the rate unit is read from
//! the channel's name ([`unit_of`]).

pub mod allan;
pub mod analysis;
pub mod gap;
pub mod html;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{Ranged, ValueFormatter};
use plotters::prelude::*;

use crate::error::{Error, Result};

/// The file name of a command's report.
pub const REPORT: &str = "report.html";

/// What a drawing function returns (plotters' errors boxed).
pub(crate) type Drawn = std::result::Result<(), Box<dyn std::error::Error>>;

/// The SVG text of a `w` x `h` plot drawn by `draw` on a white background.
pub(crate) fn svg(
    w: u32,
    h: u32,
    what: &str,
    draw: impl FnOnce(&DrawingArea<SVGBackend, Shift>) -> Drawn,
) -> Result<String> {
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (w, h)).into_drawing_area();
        let r = root
            .fill(&WHITE)
            .map_err(|e| e.into())
            .and_then(|_| draw(&root))
            .and_then(|_| root.present().map_err(|e| e.into()));
        r.map_err(|e| {
            Error::Internal(format!("report: the plot '{what}' could not be drawn: {e}"))
        })?;
    }
    Ok(buf)
}

/// The unit of a channel read from its name, for axis titles: a rate unit as
/// [`crate::stats::rate_unit::RateUnit::from_channel_name`] reads it (`_dps` deg/s,
/// `_rps` rad/s, `_dph` deg/h, ...; the one list of suffixes), else `_mps2` m/s^2 (an
/// accelerometer), else `u` (the channel's unit).
pub fn unit_of(channel: &str) -> &'static str {
    if let Some(u) = crate::stats::rate_unit::RateUnit::from_channel_name(channel) {
        return u.name();
    }
    if channel.to_ascii_lowercase().ends_with("_mps2") {
        return "m/s^2";
    }
    "u"
}

/// Colours of the series, in order.
pub(crate) const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

pub(crate) fn color(i: usize) -> RGBColor {
    COLORS[i % COLORS.len()]
}

/// A tick label: plain for 1e-3 <= |v| < 1e4, else `2e-5`.
pub(crate) fn tick(v: &f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-3..1e4).contains(&a) {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.1e}").replace(".0e", "e")
    }
}

/// The range of the finite positive values of `v` for a log axis, widened by
/// `pad` (a factor) on both sides; None when there is none.
pub(crate) fn log_range(
    v: impl IntoIterator<Item = f64>,
    pad: f64,
) -> Option<std::ops::Range<f64>> {
    let (lo, hi) = v
        .into_iter()
        .filter(|x| x.is_finite() && *x > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(x), b.max(x)));
    if !lo.is_finite() {
        return None;
    }
    let (lo, hi) = if hi / lo < 1.0001 {
        (lo / 2.0, hi * 2.0)
    } else {
        (lo, hi)
    };
    Some(lo / pad..hi * pad)
}

/// The range of the finite values of `v` for a linear axis, widened by `pad` of its
/// span on both sides; None when there is none.
pub(crate) fn lin_range(
    v: impl IntoIterator<Item = f64>,
    pad: f64,
) -> Option<std::ops::Range<f64>> {
    let (lo, hi) = v
        .into_iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if !lo.is_finite() {
        return None;
    }
    let span = if hi > lo {
        hi - lo
    } else {
        lo.abs().max(1e-12)
    };
    Some(lo - pad * span..hi + pad * span)
}

/// At most `max` points of `v`, evenly strided (the last kept).
pub(crate) fn thin<T: Copy>(v: &[T], max: usize) -> Vec<T> {
    if v.len() <= max || max < 2 {
        return v.to_vec();
    }
    let step = v.len().div_ceil(max);
    let mut out: Vec<T> = v.iter().step_by(step).copied().collect();
    if let Some(last) = v.last() {
        out.push(*last);
    }
    out
}

/// The house style of a chart's mesh: axis titles `x_desc` and `y_desc`, both axes'
/// tick labels by [`tick`], a light grid.
pub(crate) fn draw_mesh<X, Y>(
    chart: &mut ChartContext<'_, SVGBackend<'_>, Cartesian2d<X, Y>>,
    x_desc: impl Into<String>,
    y_desc: impl Into<String>,
) -> Drawn
where
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .axis_desc_style(("sans-serif", 15))
        .label_style(("sans-serif", 12))
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    Ok(())
}

/// The house style of a chart's legend, at `position`.
pub(crate) fn draw_legend<'a, 'b: 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, SVGBackend<'b>, CT>,
    position: SeriesLabelPosition,
) -> Drawn {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .label_font(("sans-serif", 12))
        .draw()?;
    Ok(())
}

/// A legend entry's sample: a short line of `c`.
pub(crate) fn legend_line(
    c: RGBColor,
    width: u32,
) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(width))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_come_from_the_channel_name() {
        assert_eq!(unit_of("gyro_x_dps"), "deg/s");
        assert_eq!(unit_of("GYRO_X_RPS"), "rad/s");
        assert_eq!(unit_of("gyro_x"), "u");
        // the rate unit's own suffixes (one list), and an accelerometer's
        assert_eq!(unit_of("gyro_x_deg_h"), "deg/h");
        assert_eq!(unit_of("acc_x_mps2"), "m/s^2");
    }

    #[test]
    fn ticks_read_well() {
        assert_eq!(tick(&0.01), "0.01");
        assert_eq!(tick(&100.0), "100");
        assert_eq!(tick(&2e-5), "2e-5");
        assert_eq!(tick(&0.0), "0");
    }

    #[test]
    fn ranges_skip_what_cannot_be_drawn() {
        assert!(log_range([f64::NAN, -1.0, 0.0], 1.1).is_none());
        let r = log_range([1.0, 100.0, f64::INFINITY], 1.0).unwrap();
        assert_eq!((r.start, r.end), (1.0, 100.0));
        assert!(lin_range([f64::NAN], 0.1).is_none());
        assert_eq!(thin(&[1, 2, 3, 4, 5], 2), vec![1, 4, 5]);
    }
}
