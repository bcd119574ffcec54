//! The sensor's output path read off a log: the output resolution (the value grid), the
//! low-pass output filter (the PSD's roll-off) and saturation (clipped values piling at
//! the extremes), each estimated in the form the simulator uses
//! ([`crate::simulator::generate::output`]) and each able to say "absent".
//!
//! - [`value_grid`]: the greatest common step of the distinct values. Values closer
//!   than 1e-9 of the largest magnitude are merged first (a float printed as
//!   0.15000000000000002 is 0.15), the gaps g_j between neighbouring distinct values are
//!   taken, and the quantum is the largest q = g_min / m (m = 1, 2, ..., 16) of which
//!   every gap is an integer multiple to 0.02 q (a tolerance that also absorbs a
//!   quantum printed with few decimals, 1/3 as 0.3333). Evidence that the grid is no
//!   coincidence: with k gaps each within 0.02 q of a multiple by chance with
//!   probability 0.04 (the gaps of continuous values are spread over many quanta),
//!   at least 6 distinct values (0.04^5 = 1e-7) or, with fewer, at most one distinct
//!   value per 10 samples (values repeat, which continuous values never do). The grid's
//!   offset (the distinct values minus their nearest multiple of q, averaged) is
//!   reported, and whether q is a power of ten (then it may be the precision the log
//!   was printed with rather than the sensor's LSB). At most [`GRID_SAMPLE`] values are
//!   read (a stride over the log: a grid holds on any subset).
//! - [`output_filter`]: a low-pass magnitude response times a white level, fitted to
//!   Welch's PSD (segments of 1024 samples, bins from 1 % of the Nyquist frequency
//!   up): the model is S(f) = (W + R / f^2) |H(f)|^2 + S_q(f), R >= 0 a red part
//!   (drift) that keeps the low bins from being read as a roll-off, with
//!   |H|^2 the simulator's own power response ([`LowPass::power_response`]) and S_q the
//!   rounding noise of a known grid (q^2 / 12 per sample: 2 (q^2 / 12) / f_s flat when
//!   the rate is rounded, times 4 sin^2(pi f / f_s) when the angle is, the error being
//!   then the first difference of a white angle error). The fit minimizes
//!   sum (ln P_k - ln S(f_k))^2 (the log of a Welch average has nearly constant
//!   variance, about 1 / segments): W and R by weighted least squares for each
//!   shape (see `fit_level`), order 1 over a log grid of bandwidths from f_s / 500 to 5 f_s, order 2 over
//!   that grid times a log grid of damping from 0.2 to 5, then refined by golden-section
//!   searches. "absent" unless the best filter lowers the cost against the flat model
//!   (no filter) by at least [`FILTER_MIN_DEVIANCE`] times the residual variance per
//!   bin, and attenuates the PSD at the Nyquist frequency by at least 10 % (a bandwidth
//!   far above the Nyquist frequency changes nothing measurable); order 2 is chosen
//!   over order 1 when it lowers the cost by a further [`ORDER2_MIN_DEVIANCE`] residual
//!   variances. A bandwidth or damping at the end of its search range is flagged
//!   (`at_edge`), not reported as an estimate. Whether the rounding is on the angle is
//!   decided by the same fit: both forms of S_q are tried and the angle form kept when
//!   it lowers the cost by [`ORDER2_MIN_DEVIANCE`] residual variances.
//! - [`saturation`]: the count of samples at the largest value (within a quarter of
//!   the quantum, or 1e-9 of the magnitude) against the count at the next level below
//!   (the next distinct value): a clipped tail piles at the limit, an unclipped one
//!   thins out, so a side is clipped when its extreme holds at least 5 samples and at
//!   least twice as many as the next level (continuous values never repeat: any pile
//!   of 5 equal values at the extreme is a clip). The limit is the largest magnitude
//!   of a clipped extreme; both sides are reported.
//! - [`proposals`]: the three as candidates of the diagnosis, read off the training
//!   blocks (joined end to end): `output_resolution` at the grid's quantum, on the
//!   rate and on the angle (two candidates: the scoring tells them apart), when the
//!   withheld statistics show a value grid the simulations lack and the grid is no
//!   printed precision; `output_filter`: the best fit of each order on each of two
//!   [`Band`]s (every bin; the bins up to 0.6 of the Nyquist frequency weighted by
//!   1 / f), each that is present and not at the edge of its search range, up to four
//!   candidates (a filter of another form than the simulator's is approximated
//!   differently by each; the withheld scoring chooses); `saturation` at the
//!   clipped limit, only when the log piles at an extreme.

use super::lsq::golden_argmin;
use super::{Also, Context, Delta, NotTried, Proposal, params_json};
use crate::diagnosis::path::PathStage;
use crate::error::Result;
use crate::simulator::generate::output::LowPass;
use crate::simulator::{Component, Discretization, Kind};
use crate::stats::psd::{Detrend, welch};

/// The most values [`value_grid`] reads (a stride over longer logs).
pub const GRID_SAMPLE: usize = 2_000_000;
/// Smallest cost reduction of a filter against no filter, in residual variances per
/// PSD bin, for the filter to be present.
pub const FILTER_MIN_DEVIANCE: f64 = 50.0;
/// Smallest further cost reduction for order 2 over order 1 (and for the angle form of
/// the rounding noise over the rate form).
pub const ORDER2_MIN_DEVIANCE: f64 = 10.0;

/// The most the cost of the filter fitted by simulation ([`super::path_fit`]) may be, as
/// a share of the cost of the fold's path as it is, for it to be proposed.
pub const PATH_FIT_MAX_COST_RATIO: f64 = 0.8;

/// Smallest relative change of the white noise's n for the joint candidate (output
/// filter with the white noise refitted) to be offered beside the filter alone.
pub const JOINT_MIN_CHANGE: f64 = 0.05;

/// The highest PSD bin a bilinear filter's fit reads, as a share of the Nyquist
/// frequency (see [`filter_fits`]).
pub const BILINEAR_TOP_SHARE: f64 = 0.9;

/// An estimate, or why the effect is absent.
#[derive(Clone, Debug, PartialEq)]
pub enum Finding<T> {
    Present(T),
    Absent(String),
}

impl<T> Finding<T> {
    /// The estimate, if present.
    pub fn present(self) -> Option<T> {
        match self {
            Finding::Present(t) => Some(t),
            Finding::Absent(_) => None,
        }
    }
    /// Whether the effect was found.
    pub fn is_present(&self) -> bool {
        matches!(self, Finding::Present(_))
    }
}

/// A value grid: the values of the log are offset + k quantum.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// The step, in the rate unit of the log.
    pub quantum: f64,
    /// The mean distance of the values from the nearest multiple of the quantum, in
    /// \[-quantum/2, quantum/2\] (0 for a grid through zero, as the simulator's).
    pub offset: f64,
    /// Distinct values read.
    pub levels: usize,
    /// The quantum is a power of ten: maybe the precision the log was printed with.
    pub decimal: bool,
}

/// The value grid of `x` (module doc), or why there is none.
pub fn value_grid(x: &[f64]) -> Finding<Grid> {
    let stride = x.len().div_ceil(GRID_SAMPLE).max(1);
    let mut v: Vec<f64> = x
        .iter()
        .step_by(stride)
        .copied()
        .filter(|a| a.is_finite())
        .collect();
    let n = v.len();
    if n < 3 {
        return Finding::Absent(format!("{n} finite values: too few to tell a grid"));
    }
    v.sort_by(f64::total_cmp);
    let scale = v[0].abs().max(v[n - 1].abs());
    let merge = 1e-9 * scale;
    let mut d: Vec<f64> = Vec::new();
    for a in v {
        match d.last() {
            Some(&b) if a - b <= merge => {}
            _ => d.push(a),
        }
    }
    let levels = d.len();
    if levels < 2 {
        return Finding::Absent("the values are all equal: a constant, no grid to read".into());
    }
    let gaps: Vec<f64> = d.windows(2).map(|w| w[1] - w[0]).collect();
    let repeat = levels * 10 <= n;
    if levels < 6 && !repeat {
        return Finding::Absent(format!(
            "{levels} distinct values in {n} samples: too few to tell a grid from chance"
        ));
    }
    let g_min = gaps.iter().copied().fold(f64::INFINITY, f64::min);
    if g_min <= 0.0 {
        return Finding::Absent("no positive gap between distinct values".into());
    }
    let quantum = (1..=16).map(|m| g_min / m as f64).find(|&q| {
        gaps.iter().all(|&g| {
            let k = g / q;
            (k - k.round()).abs() <= 0.02
        })
    });
    let Some(q) = quantum else {
        return Finding::Absent(format!(
            "the gaps between the {levels} distinct values are not multiples of one step (the smallest is {})",
            crate::fmt::num(g_min)
        ));
    };
    // refine: the least-squares step through the levels' integer indices from d[0]
    let ks: Vec<f64> = d.iter().map(|a| ((a - d[0]) / q).round()).collect();
    let kk: f64 = ks.iter().map(|k| k * k).sum();
    let q = if kk > 0.0 {
        ks.iter().zip(&d).map(|(k, a)| k * (a - d[0])).sum::<f64>() / kk
    } else {
        q
    };
    let offset = d.iter().map(|a| a - (a / q).round() * q).sum::<f64>() / levels as f64;
    let decade = q.log10();
    let decimal = (decade - decade.round()).abs() < 1e-6;
    Finding::Present(Grid {
        quantum: q,
        offset,
        levels,
        decimal,
    })
}

/// A fitted output filter.
#[derive(Clone, Debug, PartialEq)]
pub struct FilterFit {
    /// 1 or 2.
    pub order: usize,
    /// The natural frequency, Hz (the -3 dB frequency of order 1).
    pub bandwidth_hz: f64,
    /// The damping ratio (order 2).
    pub damping: Option<f64>,
    /// W: the one-sided PSD of the input before the filter, u^2/Hz.
    pub white_psd: f64,
    /// A parameter stopped at the end of its search range: not an estimate.
    pub at_edge: bool,
    /// Cost reduction against no filter, in residual variances per PSD bin.
    pub deviance: f64,
    /// The rounding noise was fitted as that of an angle quantizer.
    pub on_angle: bool,
    /// The discretization fitted.
    pub discretization: Discretization,
}

/// What [`output_filter`] fits to: the log's PSD bins above 10 % of the Nyquist
/// frequency, their logarithms and frequencies.
struct Spectrum {
    f_hz: Vec<f64>,
    ln_p: Vec<f64>,
    rate_hz: f64,
    /// Each bin's weight in the cost (mean 1).
    wt: Vec<f64>,
    /// The discretization of the filters fitted.
    disc: Discretization,
}

/// Which PSD bins a filter fit reads and how it weighs them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Band {
    /// The highest frequency read, as a share of the Nyquist frequency.
    pub top_share: f64,
    /// Each bin weighted by 1 / f (every decade counts alike, as in the diagnosis's
    /// PSD bands) instead of equally (every bin counts alike).
    pub log_weight: bool,
}

impl Band {
    /// Every bin up to the Nyquist frequency, weighted equally ([`output_filter`]).
    pub const ALL: Band = Band {
        top_share: 1.0,
        log_weight: false,
    };
    /// The bins up to 0.6 of the Nyquist frequency, weighted by 1 / f: a filter of
    /// another discretization (the bilinear transform puts a zero at the Nyquist
    /// frequency) differs from the simulator's most near the Nyquist frequency, where
    /// equally weighted bins are densest.
    pub const LOW: Band = Band {
        top_share: 0.6,
        log_weight: true,
    };
}

/// The cost of shape `g` (|H|^2 per bin) plus rounding noise `sq` (u^2/Hz per bin):
/// sum (ln P - ln S)^2 with S = (W + R / f^2) g + sq, minimized over W > 0 and R >= 0
/// (the red part: drift below the roll-off, itself filtered), and W. Two starts: the
/// least squares of the relative residual (P - S) / P (the first-order expansion of
/// ln P - ln S, a 2x2 system, R dropped when it comes out negative) and the median of
/// (P - sq) / g with R = 0; the better one is then refined by Gauss-Newton steps on
/// the log residual (Jacobian d ln S / dW = g / S, d ln S / dR = g / (f^2 S)), each
/// step halved until the cost falls (R held at 0 when the step would make it
/// negative). The expansion alone is weighted by 1 / P, so a few bins of a roll-off
/// deeper than the shape can follow (a filter with a zero at the Nyquist frequency)
/// would decide W; the log cost weighs every bin alike.
fn fit_level(sp: &Spectrum, g: &[f64], sq: &[f64]) -> (f64, f64) {
    let cost = |w: f64, r: f64| -> f64 {
        sp.ln_p
            .iter()
            .zip(g)
            .zip(sq)
            .zip(&sp.f_hz)
            .zip(&sp.wt)
            .map(|((((lp, gi), s), f), k)| {
                let d = lp - ((w + r / (f * f)) * gi + s).max(1e-300).ln();
                k * d * d
            })
            .sum()
    };
    // start 1: columns a = g / P, b = g / (f^2 P), target y = (P - sq) / P
    let rows = sp.ln_p.iter().zip(g).zip(sq).zip(&sp.f_hz).zip(&sp.wt);
    let n = normal2(rows.map(|((((lp, gi), s), f), k)| {
        let p = lp.exp();
        let a = k.sqrt() * gi / p;
        (a, k.sqrt() * gi / (f * f * p), k.sqrt() * (p - s) / p)
    }));
    let (mut w, mut r) = solve2(n);
    if r < 0.0 {
        (w, r) = (n.ay / n.aa, 0.0);
    }
    if w.is_nan() || w <= 0.0 {
        w = 1e-300;
    }
    let mut c = cost(w, r);
    // start 2: the median level
    let mut ratios: Vec<f64> = sp
        .ln_p
        .iter()
        .zip(g)
        .zip(sq)
        .filter(|(_, gi)| **gi > 0.0)
        .map(|((lp, gi), s)| (lp.exp() - s) / gi)
        .filter(|v| *v > 0.0 && v.is_finite())
        .collect();
    if !ratios.is_empty() {
        ratios.sort_by(f64::total_cmp);
        let w2 = ratios[ratios.len() / 2];
        let c2 = cost(w2, 0.0);
        if c2 < c {
            (w, r, c) = (w2, 0.0, c2);
        }
    }
    // Gauss-Newton on the log residual
    for _ in 0..20 {
        let rows = sp.ln_p.iter().zip(g).zip(sq).zip(&sp.f_hz).zip(&sp.wt);
        let j = normal2(rows.map(|((((lp, gi), s), f), k)| {
            let sm = ((w + r / (f * f)) * gi + s).max(1e-300);
            let e = k.sqrt() * (lp - sm.ln());
            (k.sqrt() * gi / sm, k.sqrt() * gi / (f * f * sm), e)
        }));
        let (mut dw, mut dr) = solve2(j);
        if r + dr < 0.0 {
            (dw, dr) = (j.ay / j.aa, -r);
        }
        if !(dw.is_finite() && dr.is_finite()) {
            break;
        }
        let mut step = 1.0;
        let mut improved = false;
        for _ in 0..30 {
            let w1 = (w + step * dw).max(w * 1e-3);
            let r1 = (r + step * dr).max(0.0);
            let c1 = cost(w1, r1);
            if c1 < c {
                improved = c - c1 > 1e-12 * c;
                (w, r, c) = (w1, r1, c1);
                break;
            }
            step *= 0.5;
        }
        if !improved {
            break;
        }
    }
    (c, w)
}

/// The sums of the normal equations of y on two columns a and b.
#[derive(Clone, Copy)]
struct Normal2 {
    aa: f64,
    ab: f64,
    bb: f64,
    ay: f64,
    by: f64,
}

/// [`Normal2`] over the rows (a, b, y), summed in their order.
fn normal2(rows: impl Iterator<Item = (f64, f64, f64)>) -> Normal2 {
    let mut n = Normal2 {
        aa: 0.0,
        ab: 0.0,
        bb: 0.0,
        ay: 0.0,
        by: 0.0,
    };
    for (a, b, y) in rows {
        n.aa += a * a;
        n.ab += a * b;
        n.bb += b * b;
        n.ay += a * y;
        n.by += b * y;
    }
    n
}

/// The least-squares coefficients of y on (a, b) by Cramer's rule on the 2x2 normal
/// equations; when they are near singular (det <= 1e-12 aa bb), a alone (b's 0).
fn solve2(n: Normal2) -> (f64, f64) {
    let det = n.aa * n.bb - n.ab * n.ab;
    if det > 1e-12 * n.aa * n.bb {
        (
            (n.ay * n.bb - n.by * n.ab) / det,
            (n.aa * n.by - n.ab * n.ay) / det,
        )
    } else {
        (n.ay / n.aa, 0.0)
    }
}

/// The shape |H|^2 at the spectrum's bins.
fn shape(sp: &Spectrum, order: usize, bandwidth_hz: f64, damping: Option<f64>) -> Vec<f64> {
    let h = LowPass::with(order, bandwidth_hz, damping, sp.disc, sp.rate_hz);
    sp.f_hz
        .iter()
        .map(|&f| h.power_response(f, sp.rate_hz))
        .collect()
}

/// The low-pass output filter of `x` sampled at `rate_hz` (module doc); `grid`: the
/// log's value grid, whose rounding noise is part of the model.
pub fn output_filter(x: &[f64], rate_hz: f64, grid: Option<&Grid>) -> Result<Finding<FilterFit>> {
    Ok(
        match filter_fits(x, rate_hz, grid, Band::ALL, Discretization::Zoh)? {
            Ok(f) => f.chosen,
            Err(why) => Finding::Absent(why),
        },
    )
}

/// The filter fits of one [`Band`]: the order chosen (as [`output_filter`] reports
/// it) and the best fit of each order, each present only when it passes the tests of
/// presence on its own.
pub struct FilterFits {
    pub chosen: Finding<FilterFit>,
    pub by_order: Vec<FilterFit>,
}

/// [`output_filter`]'s fit on the bins of `band`; Err: why no fit could be made.
pub fn filter_fits(
    x: &[f64],
    rate_hz: f64,
    grid: Option<&Grid>,
    band: Band,
    disc: Discretization,
) -> Result<std::result::Result<FilterFits, String>> {
    let l = 1024usize.min(crate::stats::psd::default_segment_len(x.len()));
    if x.len() < 4 * 256 || l < 256 {
        return Ok(Err(format!(
            "{} samples: too few for a PSD with 256-sample segments",
            x.len()
        )));
    }
    let psd = welch("output filter", x, rate_hz, l, Detrend::Constant)?;
    let nyq = rate_hz / 2.0;
    // near the bilinear transform's zero at the Nyquist frequency the Welch estimate is
    // the Hann window's leakage from the bins below, not the filter's response (its
    // log falls without bound): those fits read the bins up to 0.9 of the Nyquist
    // frequency, where the leakage of a 1024-sample segment is negligible
    let top = match disc {
        Discretization::Zoh => band.top_share,
        Discretization::Bilinear => band.top_share.min(BILINEAR_TOP_SHARE),
    };
    let (mut f_hz, mut ln_p) = (Vec::new(), Vec::new());
    for (f, p) in psd.freq_hz.iter().zip(&psd.psd) {
        if *f >= 0.01 * nyq && *f <= top * nyq && *p > 0.0 {
            f_hz.push(*f);
            ln_p.push(p.ln());
        }
    }
    if f_hz.len() < 20 {
        return Ok(Err(
            "the PSD has too few positive bins above 1 % of the Nyquist frequency".into(),
        ));
    }
    let wt: Vec<f64> = if band.log_weight {
        let inv: Vec<f64> = f_hz.iter().map(|f| 1.0 / f).collect();
        let mean = inv.iter().sum::<f64>() / inv.len() as f64;
        inv.iter().map(|v| v / mean).collect()
    } else {
        vec![1.0; f_hz.len()]
    };
    let sp = Spectrum {
        f_hz,
        ln_p,
        rate_hz,
        wt,
        disc,
    };
    let nb = sp.f_hz.len();
    // rounding noise of the grid, on the rate and on the angle
    let v_q = grid.map_or(0.0, |g| g.quantum * g.quantum / 12.0);
    let sq_rate: Vec<f64> = vec![2.0 * v_q / rate_hz; nb];
    let sq_angle: Vec<f64> = sp
        .f_hz
        .iter()
        .map(|f| {
            let s = (std::f64::consts::PI * f / rate_hz).sin();
            2.0 * v_q / rate_hz * 4.0 * s * s
        })
        .collect();
    let ones = vec![1.0; nb];

    // a bilinear filter's bandwidth is below the Nyquist frequency
    let hi = match disc {
        Discretization::Zoh => 5.0 * rate_hz,
        Discretization::Bilinear => 0.49 * rate_hz,
    };
    let lo = rate_hz / 500.0;
    let grid_bw: Vec<f64> = (0..=60)
        .map(|i| lo * (hi / lo).powf(i as f64 / 60.0))
        .collect();
    let grid_z: Vec<f64> = (0..=14)
        .map(|i| 0.2 * (25.0f64).powf(i as f64 / 14.0))
        .collect();

    struct Best {
        cost: f64,
        w: f64,
        bw: f64,
        z: Option<f64>,
        edge: bool,
    }
    let fit_order = |order: usize, sq: &[f64]| -> Best {
        let mut best = (f64::INFINITY, 0usize, 0usize);
        let zs: &[f64] = if order == 1 { &[f64::NAN] } else { &grid_z };
        for (i, &bw) in grid_bw.iter().enumerate() {
            for (j, &z) in zs.iter().enumerate() {
                let zo = (order == 2).then_some(z);
                let (c, _) = fit_level(&sp, &shape(&sp, order, bw, zo), sq);
                if c < best.0 {
                    best = (c, i, j);
                }
            }
        }
        let (_, i, j) = best;
        let edge_bw = i == 0 || i == grid_bw.len() - 1;
        let edge_z = order == 2 && (j == 0 || j == grid_z.len() - 1);
        let mut bw = grid_bw[i];
        let mut z = (order == 2).then(|| grid_z[j]);
        let step = (hi / lo).powf(1.0 / 60.0);
        let zstep = 25f64.powf(1.0 / 14.0);
        // refine: alternate golden searches on ln bandwidth and ln damping
        for _ in 0..if order == 2 { 3 } else { 1 } {
            let (u, _) = golden_argmin(
                (bw / step).max(lo).ln(),
                (bw * step).min(hi).ln(),
                30,
                |u| fit_level(&sp, &shape(&sp, order, u.exp(), z), sq).0,
            );
            bw = u.exp();
            if let Some(zz) = z {
                let (u, _) = golden_argmin(
                    (zz / zstep).max(0.2).ln(),
                    (zz * zstep).min(5.0).ln(),
                    30,
                    |u| fit_level(&sp, &shape(&sp, order, bw, Some(u.exp())), sq).0,
                );
                z = Some(u.exp());
            }
        }
        let (cost, w) = fit_level(&sp, &shape(&sp, order, bw, z), sq);
        Best {
            cost,
            w,
            bw,
            z,
            edge: edge_bw || edge_z,
        }
    };

    // the rounding noise's form: angle or rate (only with a grid)
    let (sq, on_angle) = if v_q > 0.0 {
        let (c_rate, _) = fit_level(&sp, &ones, &sq_rate);
        let (c_angle, _) = fit_level(&sp, &ones, &sq_angle);
        let r1 = fit_order(1, &sq_rate);
        let a1 = fit_order(1, &sq_angle);
        let var = r1.cost.min(a1.cost).min(c_rate).min(c_angle) / (nb as f64 - 3.0);
        if r1.cost.min(c_rate) - a1.cost.min(c_angle) > ORDER2_MIN_DEVIANCE * var {
            (sq_angle, true)
        } else {
            (sq_rate, false)
        }
    } else {
        (vec![0.0; nb], false)
    };
    let (c_flat, _) = fit_level(&sp, &ones, &sq);
    let b1 = fit_order(1, &sq);
    let b2 = fit_order(2, &sq);
    let var = b2.cost.min(b1.cost) / (nb as f64 - 3.0);
    let var = var.max(1e-12);
    let (best, order) = if b1.cost - b2.cost > ORDER2_MIN_DEVIANCE * var {
        (&b2, 2)
    } else {
        (&b1, 1)
    };
    // a fit of `order` as a filter, if it passes the tests of presence
    let as_fit = |b: &Best, order: usize| -> std::result::Result<FilterFit, String> {
        let deviance = (c_flat - b.cost) / var;
        let h = LowPass::with(order, b.bw, b.z, disc, rate_hz);
        let at_nyquist = h.power_response(nyq, rate_hz);
        if deviance < FILTER_MIN_DEVIANCE || at_nyquist > 0.9 || b.bw >= hi * 0.999 {
            return Err(format!(
                "the PSD's high-frequency part is flat: the best filter ({} order, {} Hz) lowers the cost by {} residual variances (needs {}) and keeps {} of the power at the Nyquist frequency",
                if order == 1 { "first" } else { "second" },
                crate::fmt::num(b.bw),
                crate::fmt::num(deviance),
                crate::fmt::num(FILTER_MIN_DEVIANCE),
                crate::fmt::num(at_nyquist)
            ));
        }
        Ok(FilterFit {
            order,
            bandwidth_hz: b.bw,
            damping: b.z,
            white_psd: b.w,
            at_edge: b.edge,
            deviance,
            on_angle,
            discretization: disc,
        })
    };
    let chosen = match as_fit(best, order) {
        Ok(f) => Finding::Present(f),
        Err(why) => Finding::Absent(why),
    };
    // a digital filter designed by the bilinear transform is most often a Butterworth:
    // order 2 at damping 1/sqrt(2) too, its bandwidth alone fitted (damping None, the
    // spec's default), which a short log's PSD pins better than bandwidth and damping
    // together
    let butterworth = (disc == Discretization::Bilinear).then(|| {
        let z = Some(crate::simulator::spec::DEFAULT_DAMPING);
        let cost = |bw: f64| fit_level(&sp, &shape(&sp, 2, bw, z), &sq).0;
        let i = (0..grid_bw.len())
            .min_by(|a, b| cost(grid_bw[*a]).total_cmp(&cost(grid_bw[*b])))
            .unwrap_or(0);
        let step = (hi / lo).powf(1.0 / 60.0);
        let (u, _) = golden_argmin(
            (grid_bw[i] / step).max(lo).ln(),
            (grid_bw[i] * step).min(hi).ln(),
            30,
            |u| cost(u.exp()),
        );
        let (cost, w) = fit_level(&sp, &shape(&sp, 2, u.exp(), z), &sq);
        Best {
            cost,
            w,
            bw: u.exp(),
            z: None,
            edge: i == 0 || i == grid_bw.len() - 1,
        }
    });
    let by_order = [(&b1, 1), (&b2, 2)]
        .into_iter()
        .chain(butterworth.as_ref().map(|b| (b, 2)))
        .filter_map(|(b, o)| as_fit(b, o).ok())
        .collect();
    Ok(Ok(FilterFits { chosen, by_order }))
}

/// Saturation found in a log.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    /// The measurement range: the largest magnitude of a clipped extreme, u.
    pub limit: f64,
    /// Samples at the largest value when that side is clipped.
    pub n_high: Option<usize>,
    /// Samples at the smallest value when that side is clipped.
    pub n_low: Option<usize>,
}

/// Saturation of `x` (module doc); `quantum`: the value grid's step, if any.
pub fn saturation(x: &[f64], quantum: Option<f64>) -> Finding<Clip> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &a in x.iter().filter(|a| a.is_finite()) {
        lo = lo.min(a);
        hi = hi.max(a);
    }
    if hi <= lo {
        return Finding::Absent("fewer than two distinct finite values".into());
    }
    let tol = quantum.map_or(1e-9 * lo.abs().max(hi.abs()), |q| q / 4.0);
    // (count at the extreme, the next distinct value inwards, count at that value)
    let side = |ext: f64, sign: f64| -> (usize, usize) {
        let at = x.iter().filter(|a| (**a - ext).abs() <= tol).count();
        // the next level: the extreme-most value more than tol inside
        let next = x
            .iter()
            .copied()
            .filter(|a| a.is_finite() && sign * (ext - a) > tol)
            .fold(f64::NAN, |m, a| {
                if m.is_nan() || sign * (a - m) > 0.0 {
                    a
                } else {
                    m
                }
            });
        let n_next = if next.is_nan() {
            0
        } else {
            x.iter().filter(|a| (**a - next).abs() <= tol).count()
        };
        (at, n_next)
    };
    let clipped = |(at, next): (usize, usize)| at >= 5 && at >= 2 * next;
    let (h, l) = (side(hi, 1.0), side(lo, -1.0));
    let n_high = clipped(h).then_some(h.0);
    let n_low = clipped(l).then_some(l.0);
    let limit = match (n_high, n_low) {
        (Some(_), Some(_)) => hi.abs().max(lo.abs()),
        (Some(_), None) => hi.abs(),
        (None, Some(_)) => lo.abs(),
        (None, None) => {
            return Finding::Absent(format!(
                "no pile at the extremes: {} sample(s) at the largest value against {} at the next level, {} at the smallest against {}",
                h.0, h.1, l.0, l.1
            ));
        }
    };
    Finding::Present(Clip {
        limit,
        n_high,
        n_low,
    })
}

/// The blocks `ranges` of `x` joined end to end, each shifted by a constant so that its
/// first sample repeats the previous block's last: a junction then adds no step, whose
/// 1/f^2 spectrum would fill a filter's roll-off at high frequencies (the shifts are a
/// random walk at the blocks' scale, which the fit's red part takes).
pub(super) fn joined_without_steps(x: &[f64], ranges: &[std::ops::Range<usize>]) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(ranges.iter().map(|r| r.len()).sum());
    for r in ranges {
        let block = &x[r.clone()];
        let shift = match (out.last(), block.first()) {
            (Some(a), Some(b)) => a - b,
            _ => 0.0,
        };
        out.extend(block.iter().map(|v| v + shift));
    }
    out
}

/// The joint candidate's second change: the spec's white noise component `k` (level
/// `n` [u sqrt(s)]) rescaled by `s`, as its new component and each replica's change
/// (s - 1) times its signal; None when `s` is not finite or moves n by no more than
/// JOINT_MIN_CHANGE.
fn white_refit(cx: &Context, k: usize, n: f64, s: f64) -> Option<Also> {
    if !s.is_finite() || (s - 1.0).abs() <= JOINT_MIN_CHANGE {
        return None;
    }
    Some(Also::new(
        k,
        Component::WhiteNoise { n: n * s },
        s - 1.0,
        cx.parts,
    ))
}

/// Which of [`proposals`]' candidates are asked for: all of them (a round, and the
/// filters of the pair move `Refit::path_pair`), or only the output resolution (the
/// pair move's first step); the others' fits are then not run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Asked {
    All,
    Resolution,
}

/// The output-path candidates for the state `cx` (module doc), each handed to `sink`
/// with an empty delta (an output-path component changes the path, not the sum);
/// `grid_seen`: the withheld statistics show a value grid the simulations lack.
/// Returns the candidates found but not proposed, and why.
pub fn proposals(
    cx: &Context,
    grid_seen: bool,
    asked: Asked,
    sink: &mut dyn FnMut(Proposal),
) -> Result<Vec<NotTried>> {
    let comps = &cx.spec.channels[cx.channel].components;
    let has = |k: Kind| comps.iter().any(|c| c.kind() == k);
    let mut skipped = Vec::new();
    let x: Vec<f64> = cx
        .ranges()
        .iter()
        .flat_map(|r| cx.real[r.clone()].iter().copied())
        .collect();
    let fs = cx.rate_hz();
    let grid = value_grid(&x).present();
    let lsb = grid
        .as_ref()
        .filter(|g| !g.decimal && g.levels as f64 <= 0.01 * x.len() as f64);
    // the spec's white noise, which a joint candidate refits before the filter
    let white = comps.iter().enumerate().find_map(|(k, c)| match c {
        Component::WhiteNoise { n } if *n > 0.0 => Some((k, *n)),
        _ => None,
    });
    let mut offer_also = |c: Component, note: String, also: Option<Also>| {
        let mut params = params_json(&c);
        if let (
            Some(Also {
                comp: k,
                component: Component::WhiteNoise { n },
                ..
            }),
            serde_json::Value::Object(m),
        ) = (&also, &mut params)
        {
            m.insert("white_noise_n".into(), serde_json::json!(n));
            m.insert("white_noise_component".into(), serde_json::json!(k + 1));
        }
        sink(Proposal {
            also,
            kind: c.kind().as_str().into(),
            params,
            component: c,
            replaces: None,
            rescales: None,
            delta: Delta::Same(Vec::new()),
            note,
        })
    };
    if let (Some(g), true, false) = (lsb, grid_seen, has(Kind::OutputResolution)) {
        for on_angle in [false, true] {
            offer_also(
                Component::OutputResolution {
                    quantum: g.quantum,
                    on_angle,
                },
                format!(
                    "the training values sit on a grid of {:.6e} u ({} levels): every simulation's {} rounded to it",
                    g.quantum,
                    g.levels,
                    if on_angle { "integrated angle" } else { "rate" }
                ),
                None,
            );
        }
    }
    // the filters fitted by simulation with the rounding, proposed last
    let mut by_simulation: Vec<Proposal> = Vec::new();
    if !has(Kind::OutputFilter) && asked == Asked::All {
        let mut at_edge = None;
        let mut found = 0;
        // the zero-order hold on both bands; the bilinear transform (whose zero at the
        // Nyquist frequency the LOW band exists to discount) on every bin
        let tries = [
            (Band::ALL, Discretization::Zoh),
            (Band::LOW, Discretization::Zoh),
            (Band::ALL, Discretization::Bilinear),
        ];
        let joined = joined_without_steps(cx.real, cx.ranges());
        for (band, disc) in tries {
            let Ok(fits) = filter_fits(&joined, fs, grid.as_ref(), band, disc)? else {
                continue;
            };
            for f in fits.by_order {
                if f.at_edge {
                    at_edge.get_or_insert(f.bandwidth_hz);
                    continue;
                }
                found += 1;
                let filter = Component::OutputFilter {
                    order: f.order,
                    bandwidth_hz: f.bandwidth_hz,
                    damping: f.damping,
                    discretization: disc,
                };
                let fitted = format!(
                    "order {} ({}) fitted to the training PSD's roll-off up to {} % of the Nyquist frequency{}",
                    f.order,
                    disc.as_str(),
                    (100.0 * band.top_share).round(),
                    if band.log_weight {
                        ", bins weighted by 1 / f"
                    } else {
                        ""
                    },
                );
                // the joint candidate: the white noise refitted to the fit's level W
                // before the filter, n = sqrt(W / 2) (white noise n [u sqrt(s)] has the
                // one-sided PSD 2 n^2 whatever the rate; the spec's other components
                // are taken as red, their part of the bins above the roll-off's start
                // being the fit's red part), when it moves n by more than
                // JOINT_MIN_CHANGE: a datasheet's ARW is read on the filtered output,
                // so the filter alone would lower the output's level
                if let Some((k, n)) = white {
                    let s = (f.white_psd / 2.0).sqrt() / n;
                    if let Some(also) = white_refit(cx, k, n, s) {
                        offer_also(
                            filter.clone(),
                            format!(
                                "{fitted}, with the white noise before it refitted to the fitted level: n = {} (factor {})",
                                crate::fmt::num(n * s),
                                crate::fmt::num(s)
                            ),
                            Some(also),
                        );
                    }
                }
                offer_also(
                    filter,
                    format!(
                        "{fitted} (the cost falls by {} residual variances against no filter)",
                        crate::fmt::num(f.deviance)
                    ),
                    None,
                );
            }
        }
        // absent (an Err): the low-pass candidates above speak for the filter
        if let Ok(m) = ma1_filter(cx, white.map(|(k, _)| k)) {
            let theta = m.theta;
            let fir = Component::OutputFir {
                taps: vec![1.0 / (1.0 + theta), theta / (1.0 + theta)],
            };
            let fitted = format!(
                "MA(1) FIR (1, theta) / (1 + theta), theta = {}: the training rate's lag-1 autocorrelation (after a {}-sample moving mean) exceeds the simulations' by {} (lags 2, 3 by {}, {}; ensemble sd {})",
                crate::fmt::num(theta),
                2 * m.half + 1,
                crate::fmt::num(m.excess[0]),
                crate::fmt::num(m.excess[1]),
                crate::fmt::num(m.excess[2]),
                crate::fmt::num(m.sd_lag1),
            );
            if let (Some((k, n)), Some(s)) = (white, m.white_factor)
                && let Some(also) = white_refit(cx, k, n, s)
            {
                offer_also(
                    fir.clone(),
                    format!(
                        "{fitted}, with the white noise before it refitted to the training rate's short-term variance: n = {} (factor {})",
                        crate::fmt::num(n * s),
                        crate::fmt::num(s)
                    ),
                    Some(also),
                );
            }
            offer_also(fir, fitted, None);
        }
        if let (0, Some(bw)) = (found, at_edge) {
            skipped.push(NotTried {
                kind: "output_filter".into(),
                reason: format!(
                    "the PSD's roll-off fits a filter whose bandwidth ({} Hz) or damping stopped at the end of its search range: not an estimate",
                    crate::fmt::num(bw)
                ),
            });
        }
    }
    // a spec that rounds its output: the filters fitted by simulation with the
    // rounding (path_fit.rs), added, or in place of the spec's filter
    if let Some((k, quantum, on_angle)) = comps.iter().enumerate().find_map(|(k, c)| match c {
        Component::OutputResolution { quantum, on_angle } => Some((k, *quantum, *on_angle)),
        _ => None,
    }) && asked != Asked::Resolution
        && super::path_fit::coarse(cx.real, cx.ranges(), quantum)
        && let Some(fits) = super::path_fit::fit(cx, &PathStage::of(comps, fs), quantum)
    {
        let filter_now = comps.iter().position(|c| c.kind() == Kind::OutputFilter);
        by_simulation.extend(
            fits.into_iter()
                .filter(|f| !f.at_edge && f.cost < PATH_FIT_MAX_COST_RATIO * f.cost_now)
                .map(|f| path_fit_proposal(f, (k, quantum, on_angle), filter_now)),
        );
    }
    if !has(Kind::Saturation)
        && asked == Asked::All
        && let Some(c) = saturation(&x, grid.as_ref().map(|g| g.quantum)).present()
    {
        offer_also(
            Component::Saturation { limit: c.limit },
            format!(
                "the training values pile at the extreme(s) {}: clipped there",
                crate::fmt::num(c.limit)
            ),
            None,
        );
    }
    for p in by_simulation {
        sink(p);
    }
    Ok(skipped)
}

/// The proposal of a filter fitted by simulation ([`super::path_fit`]): `f` beside the
/// spec's output resolution `(index, quantum, on_angle)`, which it sets to its own
/// rounding form (`Proposal::rescales`), as an `output_filter`, or as
/// `recalibrate:output_filter` in place of the spec's filter at `filter_now`.
fn path_fit_proposal(
    f: super::path_fit::PathFit,
    (k, quantum, on_angle_now): (usize, f64, bool),
    filter_now: Option<usize>,
) -> Proposal {
    let mut params = params_json(&f.filter);
    if let serde_json::Value::Object(m) = &mut params {
        m.insert("resolution_on_angle".into(), serde_json::json!(f.on_angle));
    }
    let form = |a: bool| {
        if a {
            "the integrated angle"
        } else {
            "the rate"
        }
    };
    let note = format!(
        "fitted by simulation with the output resolution, the rounding on {}{}: the training PSD in bands and the shares of steps of 0-3 quanta, cost {} against {} with the path as it is{}",
        form(f.on_angle),
        if f.on_angle == on_angle_now {
            String::new()
        } else {
            format!(" (the spec's on {})", form(on_angle_now))
        },
        crate::fmt::num(f.cost),
        crate::fmt::num(f.cost_now),
        if filter_now.is_some() {
            ", in place of the spec's filter"
        } else {
            ""
        }
    );
    Proposal {
        also: None,
        kind: match filter_now {
            Some(_) => format!("recalibrate:{}", f.filter.kind()),
            None => f.filter.kind().as_str().into(),
        },
        params,
        component: f.filter,
        replaces: filter_now,
        rescales: Some((
            k,
            Component::OutputResolution {
                quantum,
                on_angle: f.on_angle,
            },
        )),
        delta: Delta::Same(Vec::new()),
        note,
    }
}

/// The half width of the moving mean [`hp_lags`] removes (samples).
pub const MA1_HALF_WINDOW: usize = 500;
/// How many ensemble standard deviations the lag-1 excess must pass for the MA(1)
/// filter to be proposed.
pub const MA1_MIN_SDS: f64 = 4.0;

/// The short-term autocorrelation of `x` on the blocks `ranges`: d_t = x_t minus the
/// centred moving mean of 2 `half` + 1 samples (the slow drift removed), samples with
/// |d_t| above 6 robust sd (1.4826 median |d|) left out (a knock or an outlier would
/// otherwise dominate), then rho_k = sum d_t d_{t+k} / sum d_t^2 over the pairs within
/// one block (k = 1, 2, 3), the variance sum d_t^2 / count and the count. None when
/// no block is longer than 2 `half` + 4 samples.
pub fn hp_lags(x: &[f64], ranges: &[std::ops::Range<usize>], half: usize) -> Option<HpLags> {
    let w = 2 * half + 1;
    let mut ds: Vec<Vec<f64>> = Vec::new();
    for r in ranges {
        let b = &x[r.clone()];
        if b.len() < w + 4 {
            continue;
        }
        let mut c = Vec::with_capacity(b.len() + 1);
        c.push(0.0);
        let mut acc = 0.0;
        for v in b {
            acc += v;
            c.push(acc);
        }
        ds.push(
            (half..b.len() - half)
                .map(|t| b[t] - (c[t + half + 1] - c[t - half]) / w as f64)
                .collect(),
        );
    }
    let mut abs: Vec<f64> = ds.iter().flatten().map(|d| d.abs()).collect();
    if abs.is_empty() {
        return None;
    }
    let mid = abs.len() / 2;
    let med = *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
    let thr = 6.0 * 1.4826 * med;
    let ok = |d: f64| d.abs() <= thr || thr == 0.0;
    let (mut c0, mut c, mut n) = (0.0, [0.0; 3], 0usize);
    for d in &ds {
        for (t, &a) in d.iter().enumerate() {
            if !ok(a) {
                continue;
            }
            c0 += a * a;
            n += 1;
            for (k, ck) in c.iter_mut().enumerate() {
                if let Some(&b) = d.get(t + k + 1)
                    && ok(b)
                {
                    *ck += a * b;
                }
            }
        }
    }
    if n == 0 || c0 <= 0.0 {
        return None;
    }
    Some(HpLags {
        rho: c.map(|ck| ck / c0),
        var: c0 / n as f64,
        count: n,
    })
}

/// What [`hp_lags`] reads off a series.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HpLags {
    /// Autocorrelation at lags 1, 2, 3.
    pub rho: [f64; 3],
    /// The variance of the high-passed samples kept.
    pub var: f64,
    /// The samples kept.
    pub count: usize,
}

/// The MA(1) output filter read off the training part (see [`ma1_filter`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Ma1 {
    /// The MA coefficient: the filter is (1, theta) / (1 + theta), unit DC gain.
    pub theta: f64,
    /// The real log's lag-1, 2, 3 autocorrelation minus the ensemble mean's.
    pub excess: [f64; 3],
    /// The spread used for lag 1: the ensemble's sd, at least 1 / sqrt(count).
    pub sd_lag1: f64,
    /// The factor on the white noise's n that keeps the short-term variance with the
    /// filter in (None without a white noise).
    pub white_factor: Option<f64>,
    /// The moving mean's half width used.
    pub half: usize,
}

/// The MA(1) output filter (a sensor's averaging decimation filter seen at the output
/// rate, whose autocorrelation is zero beyond lag 1) read off the training blocks of
/// `cx`: [`hp_lags`] of the real log and of each replica of the ensemble; the
/// excess e_k = rho_k(real) - mean rho_k(ensemble). Proposed only when e_1 is positive
/// and above [`MA1_MIN_SDS`] times its spread s_1 (the ensemble's sd of rho_1, at
/// least 1 / sqrt(count)) and e_2, e_3 are within [`MA1_MIN_SDS`] s_k or within a tenth
/// of e_1 (a low-pass has rho_2 = rho_1^2 or more: it is left to the low-pass
/// candidates), and e_1 < 0.5 (the largest lag-1 autocorrelation of an MA(1)). theta
/// solves e_1 = theta / (1 + theta^2): theta = (1 - sqrt(1 - 4 e_1^2)) / (2 e_1), the
/// invertible root. White noise added after the filter (the output rounding) dilutes
/// e_1, so theta reads the share of the filtered part low.
/// With the white noise (component `white`), the factor s on its n that keeps the
/// high-passed variance: the filter multiplies the white part's variance v_w by
/// g = (1 + theta^2) / (1 + theta)^2, and s^2 = (V_real - V_ens + v_w) / (g v_w), V the
/// high-passed variances (the ensemble's a mean over replicas), v_w the white part's
/// (mean over replicas).
pub fn ma1_filter(cx: &Context, white: Option<usize>) -> std::result::Result<Ma1, String> {
    let ranges = cx.ranges();
    let longest = ranges.iter().map(|r| r.len()).max().unwrap_or(0);
    let half = MA1_HALF_WINDOW.min(longest / 8).max(1);
    let real = hp_lags(cx.real, ranges, half).ok_or("training blocks too short")?;
    let ens: Vec<HpLags> = cx
        .target
        .iter()
        .filter_map(|t| hp_lags(t, ranges, half))
        .collect();
    if ens.len() < 2 {
        return Err("fewer than two replicas to compare with".into());
    }
    let m = ens.len() as f64;
    let floor = 1.0 / (real.count as f64).sqrt();
    let mut excess = [0.0; 3];
    let mut sd = [0.0; 3];
    for k in 0..3 {
        let mean = ens.iter().map(|e| e.rho[k]).sum::<f64>() / m;
        let var = ens.iter().map(|e| (e.rho[k] - mean).powi(2)).sum::<f64>() / (m - 1.0);
        excess[k] = real.rho[k] - mean;
        sd[k] = var.sqrt().max(floor);
    }
    let e1 = excess[0];
    if e1 <= MA1_MIN_SDS * sd[0] {
        return Err(format!(
            "the lag-1 autocorrelation's excess {} is within {MA1_MIN_SDS} sd ({}) of the simulations'",
            crate::fmt::num(e1),
            crate::fmt::num(sd[0])
        ));
    }
    if let Some(k) = (1..3).find(|&k| excess[k].abs() > (MA1_MIN_SDS * sd[k]).max(0.1 * e1)) {
        return Err(format!(
            "lags 2, 3 exceed the simulations' too (lag {}: {}): not an MA(1)",
            k + 1,
            crate::fmt::num(excess[k])
        ));
    }
    if e1 >= 0.5 {
        return Err(format!(
            "the lag-1 excess {} is beyond any MA(1)'s (0.5)",
            crate::fmt::num(e1)
        ));
    }
    let theta = (1.0 - (1.0 - 4.0 * e1 * e1).sqrt()) / (2.0 * e1);
    let white_factor = white.and_then(|k| {
        let vw: Vec<f64> = cx
            .parts
            .iter()
            .filter_map(|p| hp_lags(&p[k], ranges, half).map(|h| h.var))
            .collect();
        if vw.is_empty() {
            return None;
        }
        let v_w = vw.iter().sum::<f64>() / vw.len() as f64;
        let v_ens = ens.iter().map(|e| e.var).sum::<f64>() / m;
        let g = (1.0 + theta * theta) / (1.0 + theta).powi(2);
        let s2 = (real.var - v_ens + v_w) / (g * v_w);
        (s2 > 0.0 && v_w > 0.0).then(|| s2.sqrt())
    });
    Ok(Ma1 {
        theta,
        excess,
        sd_lag1: sd[0],
        white_factor,
        half,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulator::generate::{SimRequest, Simulator};
    use crate::simulator::{ChannelSpec, Component, Spec};

    /// `n` samples at `rate_hz` of white noise `sd` (u) plus a constant `bias` through
    /// the output path `path`.
    fn sim(
        n: usize,
        rate_hz: f64,
        sd: f64,
        bias: f64,
        path: Vec<Component>,
        seed: u64,
    ) -> Vec<f64> {
        let mut comps = vec![
            Component::ConstantBias { value: bias },
            Component::WhiteNoise {
                n: sd / rate_hz.sqrt(),
            },
        ];
        comps.extend(path);
        let spec = Spec {
            sample_rate_hz: rate_hz,
            temperature_channel: None,
            seed: Some(seed),
            channels: vec![ChannelSpec {
                name: "x".into(),
                components: comps,
            }],
        };
        spec.validate().unwrap();
        let out = Simulator::new(&spec, SimRequest::new(n, rate_hz))
            .unwrap()
            .run()
            .unwrap();
        out.channels[0].1.clone()
    }

    #[test]
    fn the_grid_is_found_through_print_noise_and_absent_on_continuous_values() {
        let q = 0.05;
        let x = sim(
            200_000,
            100.0,
            0.35,
            0.1,
            vec![Component::OutputResolution {
                quantum: q,
                on_angle: false,
            }],
            1,
        );
        // printed through text with float noise: 0.15000000000000002 and the like
        let printed: Vec<f64> = x.iter().map(|v| (v / q).round() * 0.05).collect();
        for v in [&x, &printed] {
            let g = value_grid(v).present().expect("a grid");
            assert!((g.quantum - q).abs() < 1e-9, "{g:?}");
            assert!(g.offset.abs() < 1e-9 && !g.decimal, "{g:?}");
        }
        // a quantum of 1/3 printed with 4 decimals
        let third: Vec<f64> = x
            .iter()
            .map(|v| (((v / q).round() / 3.0) * 1e4).round() / 1e4)
            .collect();
        let g = value_grid(&third).present().expect("a grid");
        assert!((g.quantum - 1.0 / 3.0).abs() < 1e-4, "{g:?}");
        // on the angle: the same grid
        let a = sim(
            200_000,
            100.0,
            0.35,
            0.1,
            vec![Component::OutputResolution {
                quantum: q,
                on_angle: true,
            }],
            2,
        );
        assert!((value_grid(&a).present().unwrap().quantum - q).abs() < 1e-9);
        // continuous values, and the same with a grid far finer than the values' spread
        let c = sim(200_000, 100.0, 0.35, 0.1, vec![], 3);
        assert!(!value_grid(&c).is_present(), "{:?}", value_grid(&c));
        // a log printed with 4 decimals sits on 1e-4: found, flagged as decimal
        let p4: Vec<f64> = c.iter().map(|v| (v * 1e4).round() / 1e4).collect();
        let g = value_grid(&p4).present().unwrap();
        assert!((g.quantum - 1e-4).abs() < 1e-12 && g.decimal, "{g:?}");
        // few values: no grid claimed
        assert!(!value_grid(&[0.1, 0.3, 0.7]).is_present());
    }

    #[test]
    fn the_filter_bandwidth_is_recovered_and_absent_without_a_filter() {
        let fs = 100.0;
        for (order, bw, z) in [(1, 8.0, None), (2, 12.0, Some(0.5)), (2, 6.0, Some(1.5))] {
            let x = sim(
                400_000,
                fs,
                1.0,
                0.0,
                vec![Component::OutputFilter {
                    order,
                    bandwidth_hz: bw,
                    damping: z,
                    discretization: Discretization::Zoh,
                }],
                4,
            );
            let f = output_filter(&x, fs, None)
                .unwrap()
                .present()
                .expect("a filter");
            assert_eq!(f.order, order, "{f:?}");
            assert!((f.bandwidth_hz / bw - 1.0).abs() < 0.05, "{f:?}");
            if let Some(z) = z {
                assert!((f.damping.unwrap() / z - 1.0).abs() < 0.1, "{f:?}");
            }
            assert!(!f.at_edge, "{f:?}");
            // W = 2 sd^2 / fs (less sharp: the red part R trades with W when the slow
            // pole of an overdamped filter is low)
            assert!((f.white_psd / (2.0 / fs) - 1.0).abs() < 0.15, "{f:?}");
        }
        // no filter: absent, with and without a grid
        let x = sim(400_000, fs, 1.0, 0.0, vec![], 5);
        let f = output_filter(&x, fs, None).unwrap();
        assert!(!f.is_present(), "{f:?}");
        let q = 0.5;
        let xq = sim(
            400_000,
            fs,
            1.0,
            0.0,
            vec![Component::OutputResolution {
                quantum: q,
                on_angle: true,
            }],
            6,
        );
        let g = value_grid(&xq).present().unwrap();
        let f = output_filter(&xq, fs, Some(&g)).unwrap();
        assert!(!f.is_present(), "{f:?}");
        // a filtered and angle-quantized log: both found, the angle form recognized
        let xf = sim(
            400_000,
            fs,
            1.0,
            0.0,
            vec![
                Component::OutputFilter {
                    order: 1,
                    bandwidth_hz: 10.0,
                    damping: None,
                    discretization: Default::default(),
                },
                Component::OutputResolution {
                    quantum: q,
                    on_angle: true,
                },
            ],
            7,
        );
        let g = value_grid(&xf).present().unwrap();
        assert!((g.quantum - q).abs() < 1e-9);
        let f = output_filter(&xf, fs, Some(&g))
            .unwrap()
            .present()
            .expect("a filter");
        assert!(f.on_angle && f.order == 1, "{f:?}");
        assert!((f.bandwidth_hz / 10.0 - 1.0).abs() < 0.1, "{f:?}");
    }

    #[test]
    fn a_bilinear_butterworth_is_recovered_in_its_own_discretization() {
        // the digital Butterworth of filter-design tools (scipy.signal.butter with fs):
        // its zero at the Nyquist frequency is outside the zero-order hold's family
        let fs = 100.0;
        for (order, bw) in [(1, 12.0), (2, 8.4)] {
            let x = sim(
                240_000,
                fs,
                1.0,
                0.0,
                vec![Component::OutputFilter {
                    order,
                    bandwidth_hz: bw,
                    damping: None,
                    discretization: Discretization::Bilinear,
                }],
                13,
            );
            let fits = filter_fits(&x, fs, None, Band::ALL, Discretization::Bilinear)
                .unwrap()
                .unwrap();
            let f = match fits.chosen {
                Finding::Present(f) => f,
                Finding::Absent(why) => panic!("{why}"),
            };
            assert_eq!(f.order, order, "{f:?}");
            assert!((f.bandwidth_hz / bw - 1.0).abs() < 0.03, "{f:?}");
            assert!(!f.at_edge && f.discretization == Discretization::Bilinear);
            assert!((f.white_psd / (2.0 / fs) - 1.0).abs() < 0.1, "{f:?}");
        }
        // no filter: the bilinear fit finds none
        let x = sim(240_000, fs, 1.0, 0.0, vec![], 14);
        let fits = filter_fits(&x, fs, None, Band::ALL, Discretization::Bilinear)
            .unwrap()
            .unwrap();
        assert!(
            fits.by_order.iter().all(|f| f.at_edge),
            "{:?}",
            fits.by_order
        );
    }

    #[test]
    fn saturation_is_found_at_the_pile_and_absent_otherwise() {
        let x = sim(
            100_000,
            100.0,
            1.0,
            0.2,
            vec![Component::Saturation { limit: 2.5 }],
            8,
        );
        let c = saturation(&x, None).present().expect("clipped");
        assert_eq!(c.limit, 2.5);
        assert!(c.n_high.unwrap() > 100 && c.n_low.unwrap() > 10, "{c:?}");
        // one side only
        let y = sim(
            100_000,
            100.0,
            1.0,
            1.5,
            vec![Component::Saturation { limit: 3.0 }],
            9,
        );
        let c = saturation(&y, None).present().expect("clipped");
        assert_eq!((c.limit, c.n_low), (3.0, None), "{c:?}");
        // with a grid: the pile is told from the grid's repeats
        let z = sim(
            100_000,
            100.0,
            1.0,
            0.0,
            vec![
                Component::Saturation { limit: 2.0 },
                Component::OutputResolution {
                    quantum: 0.1,
                    on_angle: false,
                },
            ],
            10,
        );
        let c = saturation(&z, Some(0.1)).present().expect("clipped");
        assert!((c.limit - 2.0).abs() < 1e-9, "{c:?}");
        // absent: continuous, and on a grid
        let w = sim(100_000, 100.0, 1.0, 0.0, vec![], 11);
        assert!(!saturation(&w, None).is_present());
        let wq = sim(
            100_000,
            100.0,
            1.0,
            0.0,
            vec![Component::OutputResolution {
                quantum: 0.1,
                on_angle: false,
            }],
            12,
        );
        let s = saturation(&wq, Some(0.1));
        assert!(!s.is_present(), "{s:?}");
    }
}
