//! Noise-term identification: the IEEE Std 952 coefficients of a rate channel read off
//! its Allan variance (quantization Q, white noise / angle random walk N, bias
//! instability B, rate random walk K, rate ramp R, and a first-order Gauss-Markov hump
//! sigma, T), each with its standard uncertainty, and the simulation spec they make.
//!
//! - [`model`]: the AVAR of each term (IEEE Std 952-1997 Annex C; El-Sheimy, Hou, Niu
//!   2008), the Gauss-Markov formula included;
//! - [`fit`]: the Gamma maximum-likelihood fit over octave taus, every subset of the
//!   terms, selection by a penalised deviance (BIC by default), the uncertainties;
//! - [`reading`]: the bias instability as a datasheet reads it (the curve's minimum /
//!   0.664), beside the fitted one;
//! - [`wls`]: the small weighted least-squares solver under it.
//!
//! Units: u is the rate unit of the log (deg/s, deg/h, rad/s ...), tau in seconds; the
//! coefficients are those of contracts.md section 2 (white_noise n [u sqrt(s)],
//! quantization q [u s], bias_instability b \[u\], rate_random_walk k [u / sqrt(s)],
//! rate_ramp r [u / s], gauss_markov sigma \[u\] and tau_s \[s\]).
//!
//! Decisions:
//! - The fit always uses the overlapping AVAR at octave taus m = 1, 2, 4, ... up to
//!   the largest with two terms, whatever grid the user displays (see [`fit`] on the
//!   correlation of neighbouring taus).
//! - The Allan variance does not see the sign of a ramp: the identified `r` takes the
//!   sign of the least-squares slope of the channel against time.
//! - The spec written from an identification also holds a `constant_bias` equal to the
//!   channel's mean, so that a simulation sits where the log does; the bias
//!   instability's flicker band (`tau_min_s`, `tau_max_s`) is the tau range of the fit.

pub mod fit;
pub mod model;
pub mod reading;
pub mod wls;

pub use fit::AvarPoint;
pub use model::{BIAS_FLOOR, Term, gauss_markov_g};
pub use reading::{MinimumReading, minimum_reading};

use crate::error::{Error, Result};
use crate::simulator::{ChannelSpec, Component, Spec};
use crate::stats::adev::{self, Kind};

/// A term is kept only when its squared coefficient is at least this many standard
/// uncertainties above zero.
pub const MIN_Z: f64 = 2.0;

/// A fit whose dispersion (the Pearson X^2 per degree of freedom, [`Identification`])
/// is above this is poor: the selected terms miss the curve's shape somewhere. The
/// commands warn about it, and the automatic tau range ([`Options::tau_min_s`]) looks
/// for the first octave tau from which the fit is not poor.
pub const POOR_DISPERSION: f64 = 3.0;

/// The automatic tau range cuts at most this fraction of the octave taus from the
/// short end (a third: on 2^20 samples, 19 taus, the fit may start at m = 64 at most),
/// and always leaves at least [`AUTO_MIN_TAUS`] taus to fit.
pub const AUTO_MAX_CUT_FRACTION: f64 = 1.0 / 3.0;

/// The automatic tau range leaves at least this many octave taus to the fit.
pub const AUTO_MIN_TAUS: usize = 6;

/// What to identify.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// Candidate terms (default: all six).
    pub candidates: Vec<Term>,
    /// Penalty per parameter on the deviance (default None: ln(number of taus), BIC).
    pub penalty: Option<f64>,
    /// Fit only taus >= this \[s\]. Real sensors filter and decimate internally, which
    /// bends the Allan curve at the first few taus; with their very large EDF those
    /// points would otherwise dominate the fit. None (the default): chosen from the
    /// data, [`identify_curve`]'s automatic tau range (the first octave tau from which
    /// the fit is not poor; every tau when the whole curve fits).
    pub tau_min_s: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            candidates: Term::ALL.to_vec(),
            penalty: None,
            tau_min_s: None,
        }
    }
}

/// A value with its standard uncertainty (one sigma).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Estimate {
    pub value: f64,
    pub unc: f64,
}

/// One identified term.
#[derive(Clone, Debug, PartialEq)]
pub struct Identified {
    pub term: Term,
    /// The coefficient (Q, N, B, K, R or sigma) in the units of [`Term::coef_unit`];
    /// a ramp's R carries the sign of the channel's slope.
    pub coef: Estimate,
    /// The squared coefficient, the parameter the fit is linear in.
    pub coef_sq: Estimate,
    /// Gauss-Markov correlation time T \[s\] (the hump only).
    pub corr_time_s: Option<Estimate>,
}

/// One point of the fit: measurement, EDF and model.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FitPoint {
    pub m: usize,
    pub tau_s: f64,
    /// Measured overlapping AVAR.
    pub avar: f64,
    /// Greenhall's EDF for the noise type that dominates the model at this tau.
    pub edf: f64,
    /// The fitted model's AVAR.
    pub model: f64,
}

/// A candidate subset and its score, for the record of the selection.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Candidate {
    pub terms: Vec<&'static str>,
    pub deviance: f64,
    pub criterion: f64,
}

/// The identification of one channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Identification {
    /// The selected terms, in [`Term`] order.
    pub terms: Vec<Identified>,
    /// The octave points of the fit with the model's AVAR.
    pub points: Vec<FitPoint>,
    /// Gamma deviance of the selected model.
    pub deviance: f64,
    /// Pearson statistic X^2 of the selected model.
    pub pearson: f64,
    /// Number of taus minus number of parameters.
    pub dof: i64,
    /// max(1, X^2 / dof): the factor the covariance was multiplied by.
    pub dispersion: f64,
    /// Penalty per parameter used.
    pub penalty: f64,
    /// Every feasible subset, best criterion first (at most 10 kept).
    pub candidates: Vec<Candidate>,
    /// Number of rate samples, sample rate \[Hz\].
    pub n_samples: usize,
    pub rate_hz: f64,
    /// How the shortest fitted tau was chosen.
    pub tau_min: TauMinChoice,
    /// The bias instability read off the whole curve's minimum (every octave tau, the
    /// fitted range or not): [`reading`].
    pub minimum: Option<MinimumReading>,
}

/// How the fit's shortest tau was chosen: given ([`Options::tau_min_s`]) or by the
/// automatic tau range, with the fits it tried.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TauMinChoice {
    /// The shortest tau fitted \[s\].
    pub tau_s: f64,
    /// True when chosen from the data; false when given.
    pub automatic: bool,
    /// The automatic choice's tries, shortest first tau first, up to the one chosen
    /// (every one when none fits, `none_adequate`): each candidate first tau, the
    /// dispersion of the fit from there (None where no subset fitted) and the local
    /// log-log slope of the Allan deviation from that tau to the next octave. Empty
    /// when the tau was given.
    pub tries: Vec<TauMinTry>,
    /// True when no candidate first tau gave a fit that is not poor (the automatic
    /// choice then takes the one of the smallest dispersion).
    pub none_adequate: bool,
}

/// One candidate first tau of the automatic tau range.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TauMinTry {
    pub tau_s: f64,
    pub dispersion: Option<f64>,
    /// d ln ADEV / d ln tau between this octave tau and the next:
    /// ln(AVAR_{i+1} / AVAR_i) / (2 ln 2); IEEE 952 reads the terms off it (-1
    /// quantization, -1/2 white noise, 0 bias instability, +1/2 rate random walk,
    /// +1 ramp).
    pub adev_slope: f64,
}

impl TauMinChoice {
    /// One sentence on the choice, for a note on stderr and in the report: the tau
    /// chosen and why.
    pub fn explain(&self) -> String {
        let t = crate::fmt::num(self.tau_s);
        if !self.automatic {
            return format!("noise terms fitted from tau = {t} s (--fit-tau-min)");
        }
        let list = |tries: &[TauMinTry]| {
            tries
                .iter()
                .map(|x| {
                    format!(
                        "{} s: {} (ADEV slope {:.2})",
                        crate::fmt::num(x.tau_s),
                        x.dispersion
                            .map_or("no fit".to_string(), |d| format!("dispersion {d:.3}")),
                        x.adev_slope
                    )
                })
                .collect::<Vec<_>>()
                .join("; ")
        };
        if self.none_adequate {
            return format!(
                "noise terms fitted from tau = {t} s, chosen automatically: no first tau among the shortest third of the octave taus gave a fit with dispersion <= {POOR_DISPERSION}, and the fit from {t} s has the smallest (tries: {}); the curve has a feature the IEEE 952 terms do not model (see the dispersion warning)",
                list(&self.tries)
            );
        }
        if self.tries.len() <= 1 {
            return format!(
                "noise terms fitted from tau = {t} s (every octave tau: the whole curve fits, dispersion <= {POOR_DISPERSION})"
            );
        }
        let (cut, chosen) = self.tries.split_at(self.tries.len() - 1);
        format!(
            "noise terms fitted from tau = {t} s, chosen automatically: the fits from shorter taus were poor ({}; above {POOR_DISPERSION} the terms miss the curve's shape), from {t} s it fits ({}); the taus below are the sensor's short-tau region (output filter, quantization or decimation), left out; --fit-tau-min overrides",
            list(cut),
            list(chosen)
        )
    }
}

impl Identification {
    /// The identified term of this kind, if selected.
    pub fn get(&self, term: Term) -> Option<&Identified> {
        self.terms.iter().find(|t| t.term == term)
    }

    /// The model's AVAR at tau \[s\].
    pub fn model_avar(&self, tau_s: f64) -> f64 {
        self.terms
            .iter()
            .map(|t| {
                let ct = t.corr_time_s.map_or(1.0, |e| e.value);
                t.coef_sq.value * t.term.basis(tau_s, ct)
            })
            .sum()
    }

    /// The spec components of this identification (module doc: a constant bias at
    /// `mean`, then the terms in [`Term`] order).
    pub fn components(&self, mean: f64) -> Vec<Component> {
        let mut out = vec![Component::ConstantBias { value: mean }];
        let tau_lo = self.points.first().map(|p| p.tau_s);
        let tau_hi = self.points.last().map(|p| p.tau_s);
        for t in &self.terms {
            let c = t.coef.value;
            out.push(match t.term {
                Term::Quantization => Component::Quantization { q: c },
                Term::WhiteNoise => Component::WhiteNoise { n: c },
                Term::BiasInstability => Component::BiasInstability {
                    b: c,
                    tau_min_s: tau_lo,
                    tau_max_s: tau_hi,
                },
                Term::RateRandomWalk => Component::RateRandomWalk { k: c },
                Term::RateRamp => Component::RateRamp { r: c },
                Term::GaussMarkov => Component::GaussMarkov {
                    sigma: c,
                    tau_s: t.corr_time_s.map_or(f64::NAN, |e| e.value),
                },
            });
        }
        out
    }
}

/// A simulation spec (contracts.md section 2) from identified channels:
/// (channel name, identification, channel mean).
pub fn to_spec(rate_hz: f64, channels: &[(String, &Identification, f64)]) -> Spec {
    Spec {
        sample_rate_hz: rate_hz,
        temperature_channel: None,
        seed: None,
        channels: channels
            .iter()
            .map(|(name, id, mean)| ChannelSpec {
                name: name.clone(),
                components: id.components(*mean),
            })
            .collect(),
    }
}

/// The overlapping Allan variance of `y` at octave averaging factors (the fit's input).
pub fn octave_avar(y: &[f64], rate_hz: f64) -> Vec<AvarPoint> {
    let ms = adev::octave(Kind::Adev, y.len());
    let devs = adev::deviations(y, Kind::Adev, &ms);
    ms.iter()
        .zip(devs)
        .map(|(&m, d)| AvarPoint {
            m,
            tau_s: m as f64 / rate_hz,
            avar: d * d,
        })
        .collect()
}

/// Least-squares slope of `y` against time t_i = i / rate_hz, in u / s:
/// sum_i (i - c) y_i / sum_i (i - c)^2 * rate_hz, c = (N - 1) / 2, with
/// sum_i (i - c)^2 = N (N^2 - 1) / 12.
pub fn slope_per_s(y: &[f64], rate_hz: f64) -> f64 {
    use rayon::prelude::*;
    let n = y.len();
    if n < 2 {
        return 0.0;
    }
    let c = (n as f64 - 1.0) / 2.0;
    let num: f64 = y
        .par_chunks(1 << 16)
        .enumerate()
        .map(|(b, ch)| {
            let base = b << 16;
            ch.iter()
                .enumerate()
                .map(|(i, v)| ((base + i) as f64 - c) * v)
                .sum::<f64>()
        })
        .collect::<Vec<f64>>()
        .iter()
        .sum();
    let nf = n as f64;
    num / (nf * (nf * nf - 1.0) / 12.0) * rate_hz
}

/// Identifies the noise terms of the rate series `y` sampled at `rate_hz` (the octave
/// AVAR, then [`identify_curve`]; a ramp takes the sign of the series' slope).
pub fn identify(what: &str, y: &[f64], rate_hz: f64, opts: &Options) -> Result<Identification> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(Error::Usage(format!("{what}: sample rate {rate_hz} Hz")));
    }
    identify_from(what, y, rate_hz, &octave_avar(y, rate_hz), opts)
}

/// [`identify`] with the octave AVAR of `y` already computed (`points`, as
/// [`octave_avar`] makes them).
pub fn identify_from(
    what: &str,
    y: &[f64],
    rate_hz: f64,
    points: &[AvarPoint],
    opts: &Options,
) -> Result<Identification> {
    let mut id = identify_curve(what, points, y.len(), rate_hz, opts)?;
    if let Some(t) = id.terms.iter_mut().find(|t| t.term == Term::RateRamp)
        && slope_per_s(y, rate_hz) < 0.0
    {
        t.coef.value = -t.coef.value;
    }
    Ok(id)
}

/// Identifies the noise terms from octave points of an overlapping AVAR curve of a
/// series of `n_samples` rate samples (the points must be the octave factors
/// m = 1, 2, 4, ..., for the EDF to hold; zero or non-finite values are dropped).
///
/// The tau range: from [`Options::tau_min_s`] when given; otherwise automatic. The
/// fit is tried from the first octave tau, then from the second, and so on, and the
/// first whose dispersion is at most [`POOR_DISPERSION`] is taken: a curve that the
/// IEEE 952 terms describe everywhere (a simulation, a sensor without output filter)
/// keeps every tau, while a real sensor's short-tau region (its output filter and
/// decimation flatten the curve at the first taus, its quantization steepens it),
/// where the points have EDFs of 10^5 and more and any model error dominates the
/// fit, is left out. At most [`AUTO_MAX_CUT_FRACTION`] of the taus are cut, and
/// [`AUTO_MIN_TAUS`] are always left; when no first tau in that range fits, the one
/// whose fit has the smallest dispersion is taken (and the dispersion shows the
/// misfit that remains). The choice and its tries are in
/// [`Identification::tau_min`].
pub fn identify_curve(
    what: &str,
    points: &[AvarPoint],
    n_samples: usize,
    rate_hz: f64,
    opts: &Options,
) -> Result<Identification> {
    if let Some(p) = points.iter().find(|p| p.avar.is_infinite()) {
        // not a short log: the variance overflowed
        return Err(Error::Data(format!(
            "{what}: the Allan variance at tau = {} s overflows f64: the values are too large (their squares pass 1.8e308); rescale the channel (other units)",
            crate::fmt::num(p.tau_s)
        )));
    }
    let pts: Vec<AvarPoint> = points
        .iter()
        .copied()
        .filter(|p| p.avar.is_finite() && p.avar > 0.0)
        .filter(|p| opts.tau_min_s.is_none_or(|t| p.tau_s >= t * (1.0 - 1e-12)))
        .collect();
    if pts.len() < 3 {
        return Err(Error::TooShort {
            what: format!(
                "{what}: noise-term identification needs at least 3 octave taus with a non-zero Allan variance, got {}",
                pts.len()
            ),
            need: 8,
            have: n_samples as u64,
        });
    }
    let minimum = minimum_reading(points, n_samples);
    if opts.tau_min_s.is_some() {
        let mut id = fit_range(what, &pts, n_samples, rate_hz, opts)?;
        id.tau_min.automatic = false;
        id.minimum = minimum;
        return Ok(id);
    }
    let max_cut = ((pts.len() as f64 * AUTO_MAX_CUT_FRACTION).floor() as usize)
        .min(pts.len().saturating_sub(AUTO_MIN_TAUS));
    let slope = |i: usize| match pts.get(i + 1) {
        Some(q) => (q.avar / pts[i].avar).ln() / (2.0 * (q.tau_s / pts[i].tau_s).ln()),
        None => f64::NAN,
    };
    let mut tries = Vec::new();
    let mut fits = Vec::new();
    for cut in 0..=max_cut {
        let fit = fit_range(what, &pts[cut..], n_samples, rate_hz, opts);
        let dispersion = fit.as_ref().ok().map(|id| id.dispersion);
        tries.push(TauMinTry {
            tau_s: pts[cut].tau_s,
            dispersion,
            adev_slope: slope(cut),
        });
        if dispersion.is_some_and(|d| d <= POOR_DISPERSION) {
            let mut id = fit?;
            id.tau_min.tries = tries;
            id.minimum = minimum;
            return Ok(id);
        }
        fits.push(fit);
    }
    // None fits: the first tau whose fit has the smallest dispersion (the short-tau
    // region left out as far as that helps; the misfit that remains is elsewhere).
    let best = tries
        .iter()
        .enumerate()
        .filter_map(|(i, t)| t.dispersion.map(|d| (i, d)))
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
        .map_or(0, |(i, _)| i);
    let mut id = fits.swap_remove(best)?;
    id.tau_min.tries = tries;
    id.tau_min.none_adequate = true;
    id.minimum = minimum;
    Ok(id)
}

/// The fit and term selection on the points `pts` (every one of them).
fn fit_range(
    what: &str,
    pts: &[AvarPoint],
    n_samples: usize,
    rate_hz: f64,
    opts: &Options,
) -> Result<Identification> {
    let mut cands = opts.candidates.clone();
    cands.sort();
    cands.dedup();
    let problem = fit::Problem::new(pts, n_samples);
    let penalty = opts.penalty.unwrap_or((pts.len() as f64).ln());
    let fits = fit::all_subsets(&problem, &cands);
    // Each fit's covariance allowing for correlated taus; a subset is kept only when
    // every squared coefficient is at least two standard uncertainties above zero.
    let mut scored: Vec<(f64, fit::SubsetFit)> = fits
        .into_iter()
        .filter(|f| f.n_params() < pts.len())
        .filter_map(|mut f| {
            f.cov = fit::sandwich_cov(&problem, &f)?;
            // Before the dispersion: a model that misfits has a large one, which would
            // make every term of a richer (better) model look insignificant.
            let k = f.cov.len().isqrt();
            let significant =
                (0..f.terms.len()).all(|j| f.coef_sq[j] >= MIN_Z * f.cov[j * k + j].sqrt());
            let visible = f.hump_visible(&problem);
            (significant && visible).then(|| (f.deviance + penalty * f.n_params() as f64, f))
        })
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let Some((_, best)) = scored.first() else {
        return Err(Error::Data(format!(
            "{what}: no combination of the candidate noise terms fits the Allan variance"
        )));
    };
    let dof = pts.len() as i64 - best.n_params() as i64;
    let dispersion = if dof > 0 {
        (best.pearson / dof as f64).max(1.0)
    } else {
        1.0
    };
    let k = best.cov.len().isqrt();
    let terms = best
        .terms
        .iter()
        .enumerate()
        .map(|(j, &term)| {
            let c2 = best.coef_sq[j];
            let u2 = (best.cov[j * k + j] * dispersion).sqrt();
            let c = c2.sqrt();
            let corr_time_s = (term == Term::GaussMarkov).then(|| {
                let v = best.cov[(k - 1) * k + (k - 1)] * dispersion;
                Estimate {
                    value: best.corr_time_s,
                    unc: best.corr_time_s * v.sqrt(),
                }
            });
            Identified {
                term,
                coef: Estimate {
                    value: c,
                    unc: u2 / (2.0 * c),
                },
                coef_sq: Estimate { value: c2, unc: u2 },
                corr_time_s,
            }
        })
        .collect();
    let points = pts
        .iter()
        .enumerate()
        .map(|(i, p)| FitPoint {
            m: p.m,
            tau_s: p.tau_s,
            avar: p.avar,
            edf: best.edf[i],
            model: best.model[i],
        })
        .collect();
    let candidates = scored
        .iter()
        .take(10)
        .map(|(crit, f)| Candidate {
            terms: f.terms.iter().map(|t| t.kind_name()).collect(),
            deviance: f.deviance,
            criterion: *crit,
        })
        .collect();
    Ok(Identification {
        terms,
        points,
        deviance: best.deviance,
        pearson: best.pearson,
        dof,
        dispersion,
        penalty,
        candidates,
        n_samples,
        rate_hz,
        tau_min: TauMinChoice {
            tau_s: pts[0].tau_s,
            automatic: true,
            tries: Vec::new(),
            none_adequate: false,
        },
        minimum: None,
    })
}
