//! Candidate effects: what a spec may be missing, with parameters estimated on the
//! training part of the real log only.
//!
//! Every component kind of contracts.md section 2 that the spec's target channel does
//! not have is a candidate to add; every component it has, whose signal is linear in a
//! size parameter, is a candidate to recalibrate (`recalibrate:<kind>`). Estimation
//! (all on the training blocks):
//! - deterministic effects by least squares of the residual r_t = x_t - xbar_t (the real
//!   log minus the ensemble mean, which is the spec's deterministic part plus averaged
//!   noise) on the effect's own signal, simulated with a unit parameter, plus an
//!   intercept: constant_bias (mean of r), rate_ramp, warmup (amplitude for each of a
//!   log grid of tau_s, the best by residual sum of squares, refined by golden-section
//!   search between its grid neighbours), sinusoid (frequency of
//!   the largest peak of the training-masked periodogram of r, refined by a
//!   golden-section search of the least-squares power; amplitude and phase by least
//!   squares), temperature_bias (coefficients of T - Tm and (T - Tm)^2), thermal_rate
//!   (coefficient for each smoothing of a grid, the best by residual sum of squares);
//! - noise effects from the Allan variance, which adds over independent processes:
//!   with A(m) the pooled training AVAR of the real log, E(m) the ensemble's mean and
//!   U(m) the candidate simulated with a unit coefficient (mean over replicas),
//!   c^2 = argmin sum_m w_m (A - E - c^2 U)^2, w_m = 1 / (m A(m)^2) (the relative
//!   variance of an AVAR estimate grows like m / N), c^2 >= 0: white_noise,
//!   quantization, bias_instability, rate_random_walk, gauss_markov (tau_s by the best
//!   fit over a log grid), and recalibration of a noise component (A - E + V_k
//!   against V_k, its own AVAR, giving the factor s^2 on its size);
//! - outliers from spikes: the local second difference s_t = x_t - (x_{t-1} + x_{t+1})/2,
//!   spikes where |s_t| exceeds 6 robust standard deviations (1.4826 MAD) and is a local
//!   maximum; the excess count over the ensemble's gives the rate, and the mean square
//!   of the spikes, read as a normal sample truncated at the threshold
//!   (E[Z^2 | |Z| > c] = 1 + c phi(c) / Q(c)), gives the scale and the share detected;
//! - heteroskedastic: the regression of d_t^2 (d the first difference) on T - Tm gives
//!   E[d^2] = a (1 + 2 phi slope (T - Tm)) to first order, phi being the share of the
//!   modulated component in the variance of d (from the ensemble);
//! - cross_axis: gain = cov(d_x, d_o) / var(d_o) over the training part, for each other
//!   channel o of the spec present in the log.
//!
//! Candidates that mimic each other are told apart by the scoring, not here: each is
//! scored on every statistic family of the withheld part, and pays for widening the
//! ensemble's band (the spread term of `distance`), so a slow temperature drift (which
//! moves the temperature family as well as the long-tau Allan deviation) beats a rate
//! random walk, which matches the Allan curve and the window means only by letting
//! them wander from one simulation to the next; T beats dT/dt where the mean
//! by temperature bin moves, and the other way round; a ramp and a warm-up differ in
//! the time family's window means.

use std::ops::Range;

use serde_json::{Value, json};

use super::ensemble::SimBase;
use super::features::{Layout, Temperature};
use crate::error::Result;
use crate::estimator::linalg::normal_equations;
use crate::simulator::{Component, Kind, Spec};
use crate::stats::special::normal_cdf;

/// How a candidate changes every replica's target channel.
#[derive(Clone, Debug)]
pub enum Delta {
    /// The same signal in every replica (deterministic effects).
    Same(Vec<f64>),
    /// One signal per replica.
    Each(Vec<Vec<f64>>),
}

impl Delta {
    pub fn get(&self, r: usize) -> &[f64] {
        match self {
            Delta::Same(v) => v,
            Delta::Each(v) => &v[r],
        }
    }
}

/// A proposed change of the spec.
#[derive(Clone, Debug)]
pub struct Proposal {
    /// A component kind, or `recalibrate:<kind>`.
    pub kind: String,
    /// The component added, or the replacement of component `replaces`.
    pub component: Component,
    pub replaces: Option<usize>,
    pub params: Value,
    pub delta: Delta,
    /// How the parameters were estimated.
    pub note: String,
}

/// A candidate that could not be tried, and why.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NotTried {
    pub kind: String,
    pub reason: String,
}

/// What estimation needs to know about the current state.
pub struct Context<'a> {
    pub spec: &'a Spec,
    pub channel: usize,
    pub sim: &'a SimBase<'a>,
    pub train: &'a Layout,
    pub real: &'a [f64],
    pub temperature: Option<&'a Temperature>,
    /// Other spec channels present in the real log: (name, real values).
    pub others: &'a [(String, &'a [f64])],
    /// Per replica, the target channel's simulation.
    pub target: &'a [Vec<f64>],
    /// Per replica, per spec component of the target channel, its signal.
    pub parts: &'a [Vec<Vec<f64>>],
}

impl Context<'_> {
    fn rate_hz(&self) -> f64 {
        self.sim.rate_hz
    }
    fn ranges(&self) -> &[Range<usize>] {
        self.train.ranges()
    }
    fn n_train(&self) -> usize {
        self.ranges().iter().map(|r| r.len()).sum()
    }
    fn avar(&self, x: &[f64]) -> Vec<f64> {
        self.train.ln_avar(x).into_iter().map(f64::exp).collect()
    }
    fn mean_avar<'b>(&self, xs: impl Iterator<Item = &'b [f64]>) -> Vec<f64> {
        let mut acc: Vec<f64> = Vec::new();
        let mut n = 0.0f64;
        for x in xs {
            let a = self.avar(x);
            if acc.is_empty() {
                acc = a;
            } else {
                for (s, v) in acc.iter_mut().zip(a) {
                    *s += v;
                }
            }
            n += 1.0;
        }
        acc.iter().map(|s| s / n.max(1.0)).collect()
    }
}

/// Weighted least squares of y on u with the coefficient >= 0: (c, weighted RSS).
fn fit_nonneg(y: &[f64], u: &[f64], a: &[f64], ms: &[usize]) -> (f64, f64) {
    let w: Vec<f64> = ms
        .iter()
        .zip(a)
        .map(|(m, a)| 1.0 / (*m as f64 * a * a).max(f64::MIN_POSITIVE))
        .collect();
    let suu: f64 = (0..y.len()).map(|i| w[i] * u[i] * u[i]).sum();
    let suy: f64 = (0..y.len()).map(|i| w[i] * u[i] * y[i]).sum();
    let c = if suu > 0.0 { (suy / suu).max(0.0) } else { 0.0 };
    let rss = (0..y.len()).map(|i| w[i] * (y[i] - c * u[i]).powi(2)).sum();
    (c, rss)
}

/// Least squares of y on the regressors (and an intercept) over `ranges`:
/// (coefficients of the regressors, RSS).
fn ls(
    y: &[f64],
    regs: &[&[f64]],
    intercept: bool,
    ranges: &[Range<usize>],
) -> Option<(Vec<f64>, f64)> {
    let k = regs.len() + usize::from(intercept);
    let mut ata = vec![0.0; k * k];
    let mut aty = vec![0.0; k];
    let mut row = vec![0.0; k];
    for r in ranges {
        for t in r.clone() {
            let mut j = 0;
            if intercept {
                row[0] = 1.0;
                j = 1;
            }
            for g in regs {
                row[j] = g[t];
                j += 1;
            }
            for a in 0..k {
                aty[a] += row[a] * y[t];
                for b in 0..k {
                    ata[a * k + b] += row[a] * row[b];
                }
            }
        }
    }
    let beta = normal_equations(&ata, &aty, k)?;
    let mut rss = 0.0;
    for r in ranges {
        for t in r.clone() {
            let mut f = if intercept { beta[0] } else { 0.0 };
            for (j, g) in regs.iter().enumerate() {
                f += beta[j + usize::from(intercept)] * g[t];
            }
            rss += (y[t] - f).powi(2);
        }
    }
    let coefs = beta[usize::from(intercept)..].to_vec();
    Some((coefs, rss))
}

fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1).max(1) as f64))
        .collect()
}

/// The size parameter of a component scaled by `s` (None: no such parameter).
pub fn scaled(c: &Component, s: f64) -> Option<Component> {
    use Component as C;
    let s_pos = s.max(0.0);
    Some(match c {
        C::ConstantBias { value } => C::ConstantBias { value: value * s },
        C::WhiteNoise { n } => C::WhiteNoise { n: n * s_pos },
        C::Quantization { q } => C::Quantization { q: q * s_pos },
        C::BiasInstability {
            b,
            tau_min_s,
            tau_max_s,
        } => C::BiasInstability {
            b: b * s_pos,
            tau_min_s: *tau_min_s,
            tau_max_s: *tau_max_s,
        },
        C::RateRandomWalk { k } => C::RateRandomWalk { k: k * s_pos },
        C::RateRamp { r } => C::RateRamp { r: r * s },
        C::GaussMarkov { sigma, tau_s } => C::GaussMarkov {
            sigma: sigma * s_pos,
            tau_s: *tau_s,
        },
        C::Sinusoid {
            amplitude,
            freq_hz,
            phase_rad,
        } => C::Sinusoid {
            amplitude: amplitude * s_pos,
            freq_hz: *freq_hz,
            phase_rad: *phase_rad,
        },
        C::Arma { ar, ma, sigma } => C::Arma {
            ar: ar.clone(),
            ma: ma.clone(),
            sigma: sigma * s_pos,
        },
        C::TemperatureBias {
            coeffs,
            reference_c,
        } => C::TemperatureBias {
            coeffs: coeffs.iter().map(|v| v * s).collect(),
            reference_c: *reference_c,
        },
        C::ThermalRate { coeff, smoothing_s } => C::ThermalRate {
            coeff: coeff * s,
            smoothing_s: *smoothing_s,
        },
        C::Warmup { amplitude, tau_s } => C::Warmup {
            amplitude: amplitude * s,
            tau_s: *tau_s,
        },
        C::Outliers { rate_hz, scale } => C::Outliers {
            rate_hz: *rate_hz,
            scale: scale * s_pos,
        },
        C::CrossAxis { from, gain } => C::CrossAxis {
            from: from.clone(),
            gain: gain * s,
        },
        C::Farma(_) | C::Heteroskedastic { .. } => return None,
    })
}

/// Whether the size of a component acts through the Allan variance (noise) or through
/// the mean (deterministic).
fn is_noise(c: &Component) -> bool {
    matches!(
        c,
        Component::WhiteNoise { .. }
            | Component::Quantization { .. }
            | Component::BiasInstability { .. }
            | Component::RateRandomWalk { .. }
            | Component::GaussMarkov { .. }
            | Component::Arma { .. }
    )
}

/// The parameters of a component as JSON (the keys of contracts.md section 2).
pub fn params_json(c: &Component) -> Value {
    use Component as C;
    match c {
        C::ConstantBias { value } => json!({ "value": value }),
        C::WhiteNoise { n } => json!({ "n": n }),
        C::Quantization { q } => json!({ "q": q }),
        C::BiasInstability {
            b,
            tau_min_s,
            tau_max_s,
        } => json!({ "b": b, "tau_min_s": tau_min_s, "tau_max_s": tau_max_s }),
        C::RateRandomWalk { k } => json!({ "k": k }),
        C::RateRamp { r } => json!({ "r": r }),
        C::GaussMarkov { sigma, tau_s } => json!({ "sigma": sigma, "tau_s": tau_s }),
        C::Sinusoid {
            amplitude,
            freq_hz,
            phase_rad,
        } => json!({ "amplitude": amplitude, "freq_hz": freq_hz, "phase_rad": phase_rad }),
        C::Arma { ar, ma, sigma } => json!({ "ar": ar, "ma": ma, "sigma": sigma }),
        C::Farma(_) => json!({}),
        C::TemperatureBias {
            coeffs,
            reference_c,
        } => json!({ "coeffs": coeffs, "reference_c": reference_c }),
        C::ThermalRate { coeff, smoothing_s } => {
            json!({ "coeff": coeff, "smoothing_s": smoothing_s })
        }
        C::Warmup { amplitude, tau_s } => json!({ "amplitude": amplitude, "tau_s": tau_s }),
        C::Outliers { rate_hz, scale } => json!({ "rate_hz": rate_hz, "scale": scale }),
        C::Heteroskedastic { of, slope } => json!({ "of": of.as_str(), "slope": slope }),
        C::CrossAxis { from, gain } => json!({ "from": from, "gain": gain }),
    }
}

/// Every candidate for the current state: proposals to score, and those not tried.
pub fn propose(cx: &Context) -> Result<(Vec<Proposal>, Vec<NotTried>)> {
    let mut props = Vec::new();
    let mut skipped = Vec::new();
    let comps = &cx.spec.channels[cx.channel].components;
    let has = |k: Kind| comps.iter().any(|c| c.kind() == k);
    let m_reps = cx.target.len();
    let n = cx.real.len();
    let fs = cx.rate_hz();
    let duration_s = n as f64 / fs;

    // residual against the ensemble mean
    let mut xbar = vec![0.0; n];
    for t in cx.target {
        for (a, v) in xbar.iter_mut().zip(t) {
            *a += v / m_reps as f64;
        }
    }
    let res: Vec<f64> = cx.real.iter().zip(&xbar).map(|(a, b)| a - b).collect();
    let ranges = cx.ranges().to_vec();

    let a_real = cx.avar(cx.real);
    let a_ens = cx.mean_avar(cx.target.iter().map(|v| v.as_slice()));
    let ms = cx.train.adev_factors().to_vec();
    let excess: Vec<f64> = a_real.iter().zip(&a_ens).map(|(a, e)| a - e).collect();

    let mut skip = |k: &str, why: &str| {
        skipped.push(NotTried {
            kind: k.into(),
            reason: why.into(),
        })
    };

    // -- deterministic additions
    let unit = |c: Component| -> Result<Vec<f64>> {
        Ok(cx
            .sim
            .extra_signal(cx.spec, cx.channel, &c)?
            .pop()
            .unwrap_or_default())
    };
    let mut det = |kind: &str, c: Component, sig: Vec<f64>, note: String| {
        props.push(Proposal {
            kind: kind.into(),
            params: params_json(&c),
            component: c,
            replaces: None,
            delta: Delta::Same(sig),
            note,
        })
    };
    if !has(Kind::ConstantBias) {
        let s: f64 = ranges
            .iter()
            .map(|r| res[r.clone()].iter().sum::<f64>())
            .sum();
        let v = s / cx.n_train() as f64;
        let c = Component::ConstantBias { value: v };
        det(
            "constant_bias",
            c,
            vec![v; n],
            "mean of the training residual".into(),
        );
    }
    if !has(Kind::RateRamp) {
        let u = unit(Component::RateRamp { r: 1.0 })?;
        if let Some((b, _)) = ls(&res, &[&u], true, &ranges) {
            let sig: Vec<f64> = u.iter().map(|v| v * b[0]).collect();
            det(
                "rate_ramp",
                Component::RateRamp { r: b[0] },
                sig,
                "least-squares slope of the training residual on time".into(),
            );
        }
    }
    if !has(Kind::Warmup) {
        let rss_at = |tau: f64| -> Result<Option<(f64, f64, Vec<f64>)>> {
            let u = unit(Component::Warmup {
                amplitude: 1.0,
                tau_s: tau,
            })?;
            Ok(ls(&res, &[&u], true, &ranges).map(|(b, rss)| (b[0], rss, u)))
        };
        let grid = log_grid(5.0 / fs.min(1.0), duration_s / 2.0, 24);
        let mut best: Option<(usize, f64)> = None;
        for (i, &tau) in grid.iter().enumerate() {
            if let Some((_, rss, _)) = rss_at(tau)?
                && best.is_none_or(|x| rss < x.1)
            {
                best = Some((i, rss));
            }
        }
        // refine ln(tau) between the grid neighbours of the best point
        let refined = match best {
            Some((i, _)) => {
                let lo = grid[i.saturating_sub(1)].ln();
                let hi = grid[(i + 1).min(grid.len() - 1)].ln();
                let ln_tau = golden_min(lo, hi, 30, |v| {
                    rss_at(v.exp())
                        .ok()
                        .flatten()
                        .map_or(f64::INFINITY, |x| x.1)
                });
                let tau = ln_tau.exp();
                rss_at(tau)?.map(|(a, _, u)| (a, tau, u))
            }
            None => None,
        };
        if let Some((a, tau, u)) = refined {
            let sig: Vec<f64> = u.iter().map(|v| v * a).collect();
            det(
                "warmup",
                Component::Warmup {
                    amplitude: a,
                    tau_s: tau,
                },
                sig,
                "least squares over a log grid of 24 time constants, refined by golden section"
                    .into(),
            );
        }
    }
    if !has(Kind::Sinusoid) {
        if let Some((amp, f, ph)) = find_sinusoid(&res, &ranges, fs) {
            let c = Component::Sinusoid {
                amplitude: amp,
                freq_hz: f,
                phase_rad: ph,
            };
            let sig = unit(c.clone())?;
            det(
                "sinusoid",
                c,
                sig,
                "largest peak of the training periodogram, refined by least squares".into(),
            );
        } else {
            skip("sinusoid", "no periodogram peak in the training residual");
        }
    }
    match cx.temperature {
        None => {
            for k in ["temperature_bias", "thermal_rate", "heteroskedastic"] {
                skip(
                    k,
                    "the log has no temperature channel (temperature_channel in the spec)",
                );
            }
        }
        Some(tp) => {
            let tm = tp.t_c.iter().sum::<f64>() / n as f64;
            if !has(Kind::TemperatureBias) {
                let u1 = unit(Component::TemperatureBias {
                    coeffs: vec![1.0],
                    reference_c: Some(tm),
                })?;
                let u2 = unit(Component::TemperatureBias {
                    coeffs: vec![0.0, 1.0],
                    reference_c: Some(tm),
                })?;
                if let Some((b, _)) = ls(&res, &[&u1, &u2], true, &ranges) {
                    let sig: Vec<f64> = u1
                        .iter()
                        .zip(&u2)
                        .map(|(a, c)| b[0] * a + b[1] * c)
                        .collect();
                    det(
                        "temperature_bias",
                        Component::TemperatureBias {
                            coeffs: b.clone(),
                            reference_c: Some(tm),
                        },
                        sig,
                        "least squares on T - Tm and (T - Tm)^2".into(),
                    );
                }
            }
            if !has(Kind::ThermalRate) {
                let mut best: Option<(f64, f64, f64, Vec<f64>)> = None;
                for sm in [0.0, 10.0, 30.0, 100.0, 300.0] {
                    let u = unit(Component::ThermalRate {
                        coeff: 1.0,
                        smoothing_s: sm,
                    })?;
                    if let Some((b, rss)) = ls(&res, &[&u], true, &ranges)
                        && best.as_ref().is_none_or(|x| rss < x.2)
                    {
                        best = Some((b[0], sm, rss, u));
                    }
                }
                if let Some((cf, sm, _, u)) = best {
                    let sig: Vec<f64> = u.iter().map(|v| v * cf).collect();
                    det(
                        "thermal_rate",
                        Component::ThermalRate {
                            coeff: cf,
                            smoothing_s: sm,
                        },
                        sig,
                        "least squares on dT/dt, smoothing chosen over 0, 10, 30, 100, 300 s"
                            .into(),
                    );
                }
            }
            if !has(Kind::Heteroskedastic) {
                match heteroskedastic(cx, tp, tm)? {
                    Some(p) => props.push(p),
                    None => skip(
                        "heteroskedastic",
                        "the spec's channel has no noise component to modulate",
                    ),
                }
            }
        }
    }

    // -- noise additions, from the training Allan variance
    // (coefficient, weighted RSS of the fit, unit signals)
    let noise_add = |unit_c: Component| -> Result<(f64, f64, Vec<Vec<f64>>)> {
        let u = cx.sim.extra_signal(cx.spec, cx.channel, &unit_c)?;
        let g = cx.mean_avar(u.iter().map(|v| v.as_slice()));
        let (c2, wrss) = fit_nonneg(&excess, &g, &a_real, &ms);
        Ok((c2.sqrt(), wrss, u))
    };
    let noise_kinds: [(Kind, Component); 4] = [
        (Kind::WhiteNoise, Component::WhiteNoise { n: 1.0 }),
        (Kind::Quantization, Component::Quantization { q: 1.0 }),
        (
            Kind::BiasInstability,
            Component::BiasInstability {
                b: 1.0,
                tau_min_s: None,
                tau_max_s: None,
            },
        ),
        (Kind::RateRandomWalk, Component::RateRandomWalk { k: 1.0 }),
    ];
    for (kind, unit_c) in noise_kinds {
        if has(kind) {
            continue;
        }
        {
            let (c, _, u) = noise_add(unit_c.clone())?;
            if c <= 0.0 {
                skip(
                    kind.as_str(),
                    "no excess Allan variance where this term shows",
                );
                continue;
            }
            let comp = scaled(&unit_c, c).expect("noise kinds scale");
            props.push(Proposal {
                kind: kind.as_str().into(),
                params: params_json(&comp),
                component: comp,
                replaces: None,
                delta: Delta::Each(
                    u.into_iter()
                        .map(|v| v.iter().map(|e| e * c).collect())
                        .collect(),
                ),
                note: "weighted least squares on the excess training Allan variance".into(),
            });
        }
    }
    if !has(Kind::GaussMarkov) {
        let max_tau = cx.train.adev_factors().last().copied().unwrap_or(1) as f64 / fs;
        let mut best: Option<(f64, f64, f64, Vec<Vec<f64>>)> = None;
        for tau in log_grid(2.0 / fs, max_tau.max(4.0 / fs), 8) {
            let unit_c = Component::GaussMarkov {
                sigma: 1.0,
                tau_s: tau,
            };
            let (c, wrss, u) = noise_add(unit_c)?;
            if c > 0.0 && best.as_ref().is_none_or(|b| wrss < b.2) {
                best = Some((c, tau, wrss, u));
            }
        }
        match best {
            Some((c, tau, _, u)) => {
                let comp = Component::GaussMarkov {
                    sigma: c,
                    tau_s: tau,
                };
                props.push(Proposal {
                    kind: "gauss_markov".into(),
                    params: params_json(&comp),
                    component: comp,
                    replaces: None,
                    delta: Delta::Each(
                        u.into_iter()
                            .map(|v| v.iter().map(|e| e * c).collect())
                            .collect(),
                    ),
                    note: "excess training Allan variance, tau_s over a log grid of 8".into(),
                });
            }
            None => skip(
                "gauss_markov",
                "no excess Allan variance where this term shows",
            ),
        }
    }
    if !has(Kind::Outliers) {
        match outliers(cx)? {
            Some(p) => props.push(p),
            None => skip(
                "outliers",
                "no more spikes in the training part than in the simulations",
            ),
        }
    }
    if !has(Kind::CrossAxis) {
        if cx.others.is_empty() {
            skip("cross_axis", "no other channel of the spec in the log");
        }
        for (name, o) in cx.others {
            let dx: Vec<f64> = diff(&res);
            let dob: Vec<f64> = diff(o);
            if let Some((b, _)) = ls(&dx, &[&dob], true, &shrink_ranges(&ranges)) {
                let comp = Component::CrossAxis {
                    from: name.clone(),
                    gain: b[0],
                };
                let u = cx.sim.extra_signal(cx.spec, cx.channel, &comp)?;
                props.push(Proposal {
                    kind: "cross_axis".into(),
                    params: params_json(&comp),
                    component: comp,
                    replaces: None,
                    delta: Delta::Each(u),
                    note: format!("regression of the differences on those of '{name}'"),
                });
            }
        }
    }
    for k in [Kind::Arma, Kind::Farma] {
        if !has(k) {
            skip(
                k.as_str(),
                "not estimated as an added effect: the state statistic shows state-dependent dynamics; fit them with `farma fit` and add the model",
            );
        }
    }

    // -- recalibration of what the spec has
    for (k, c) in comps.iter().enumerate() {
        let kind = format!("recalibrate:{}", c.kind());
        if scaled(c, 1.0).is_none() {
            continue;
        }
        let s = if is_noise(c) {
            let vk = cx.mean_avar(cx.parts.iter().map(|p| p[k].as_slice()));
            let y: Vec<f64> = excess.iter().zip(&vk).map(|(e, v)| e + v).collect();
            let (s2, _) = fit_nonneg(&y, &vk, &a_real, &ms);
            s2.sqrt()
        } else if matches!(c, Component::Outliers { .. }) {
            continue;
        } else {
            let sig = &cx.parts[0][k];
            let intercept = !matches!(c, Component::ConstantBias { .. });
            match ls(&res, &[sig], intercept, &ranges) {
                Some((b, _)) => 1.0 + b[0],
                None => continue,
            }
        };
        let Some(comp) = scaled(c, s) else { continue };
        let delta = if super::ensemble::is_deterministic(c) {
            Delta::Same(cx.parts[0][k].iter().map(|v| v * (s - 1.0)).collect())
        } else {
            Delta::Each(
                cx.parts
                    .iter()
                    .map(|p| p[k].iter().map(|v| v * (s - 1.0)).collect())
                    .collect(),
            )
        };
        let mut params = params_json(&comp);
        if let Value::Object(m) = &mut params {
            m.insert("factor".into(), json!(s));
            m.insert("component".into(), json!(k + 1));
        }
        props.push(Proposal {
            kind,
            params,
            component: comp,
            replaces: Some(k),
            delta,
            note: if is_noise(c) {
                "size factor from the training Allan variance".into()
            } else {
                "size factor by least squares on the training residual".into()
            },
        });
    }
    Ok((props, skipped))
}

fn diff(x: &[f64]) -> Vec<f64> {
    let mut d = vec![0.0; x.len()];
    for (t, v) in d.iter_mut().enumerate().skip(1) {
        *v = x[t] - x[t - 1];
    }
    d
}

/// Ranges without their first sample (where a difference would cross a block edge).
fn shrink_ranges(r: &[Range<usize>]) -> Vec<Range<usize>> {
    r.iter().map(|r| (r.start + 1)..r.end).collect()
}

/// The step of the grid the values of `x` sit on, when they sit on one: an output
/// resolution (LSB) in the rate itself, which no component of the spec contract
/// reproduces (`quantization` is the IEEE 952 angle quantization, white in the
/// angle). The distinct values are sorted; the step is the smallest gap between
/// neighbours, and a grid is reported only when there are at most 1 % as many distinct
/// values as samples and every gap between neighbours is an integer multiple of the
/// step to 1e-6 of the step.
pub fn output_resolution(x: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = x.iter().copied().filter(|a| a.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    if v.len() < 2 || v.len() as f64 > 0.01 * x.len() as f64 {
        return None;
    }
    let step = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    if !step.is_finite() || step <= 0.0 {
        return None;
    }
    let on_grid = v.windows(2).all(|w| {
        let k = (w[1] - w[0]) / step;
        (k - k.round()).abs() <= 1e-6 * k.round().max(1.0)
    });
    on_grid.then_some(step)
}

/// The minimiser of a unimodal `f` on [lo, hi] by golden-section search (`iters`
/// steps, each shrinking the bracket by 0.618; Kiefer 1953).
fn golden_min(mut lo: f64, mut hi: f64, iters: usize, f: impl Fn(f64) -> f64) -> f64 {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut a = hi - g * (hi - lo);
    let mut b = lo + g * (hi - lo);
    let (mut fa, mut fb) = (f(a), f(b));
    for _ in 0..iters {
        if fa < fb {
            hi = b;
            b = a;
            fb = fa;
            a = hi - g * (hi - lo);
            fa = f(a);
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + g * (hi - lo);
            fb = f(b);
        }
    }
    0.5 * (lo + hi)
}

/// The sinusoid that best explains `res` on `ranges`: (amplitude, freq_hz, phase_rad).
fn find_sinusoid(res: &[f64], ranges: &[Range<usize>], fs: f64) -> Option<(f64, f64, f64)> {
    let n = res.len();
    let mut masked = vec![0.0; n];
    let mut cnt = 0.0;
    let mut mean = 0.0;
    for r in ranges {
        for t in r.clone() {
            mean += res[t];
            cnt += 1.0;
        }
    }
    mean /= cnt;
    for r in ranges {
        for t in r.clone() {
            masked[t] = res[t] - mean;
        }
    }
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    fft.process(&mut masked, &mut spec).ok()?;
    // skip the lowest bins: a few cycles per log are drift, not a sinusoid
    let k0 = 8.min(spec.len() - 1);
    let (kbest, _) = spec
        .iter()
        .enumerate()
        .skip(k0)
        .take(spec.len().saturating_sub(k0 + 1))
        .max_by(|a, b| a.1.norm_sqr().total_cmp(&b.1.norm_sqr()))?;
    let df = fs / n as f64;
    let power = |f: f64| -> (f64, f64, f64) {
        // least squares of res on sin, cos at f over ranges
        let w = 2.0 * std::f64::consts::PI * f / fs;
        let (mut ss, mut sc, mut cc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for r in ranges {
            for t in r.clone() {
                let (s, c) = (w * t as f64).sin_cos();
                let y = res[t] - mean;
                ss += s * s;
                sc += s * c;
                cc += c * c;
                ys += y * s;
                yc += y * c;
            }
        }
        let det = ss * cc - sc * sc;
        if det <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let a = (ys * cc - yc * sc) / det;
        let b = (yc * ss - ys * sc) / det;
        (a * ys + b * yc, a, b)
    };
    let (mut lo, mut hi) = ((kbest as f64 - 1.0) * df, (kbest as f64 + 1.0) * df);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..40 {
        let a = hi - g * (hi - lo);
        let b = lo + g * (hi - lo);
        if power(a).0 > power(b).0 {
            hi = b;
        } else {
            lo = a;
        }
    }
    let f = 0.5 * (lo + hi);
    if !(f > 0.0 && f < fs / 2.0) {
        return None;
    }
    let (_, a, b) = power(f);
    // a sin + b cos = A sin(w t + phi)
    Some((a.hypot(b), f, b.atan2(a)))
}

fn spikes(x: &[f64], ranges: &[Range<usize>]) -> (usize, f64, f64) {
    let s_at = |t: usize| x[t] - 0.5 * (x[t - 1] + x[t + 1]);
    let mut all: Vec<f64> = ranges
        .iter()
        .flat_map(|r| {
            (r.start + 1..r.end - 1).map(move |t| (x[t] - 0.5 * (x[t - 1] + x[t + 1])).abs())
        })
        .collect();
    if all.is_empty() {
        return (0, 0.0, 0.0);
    }
    let mid = all.len() / 2;
    all.select_nth_unstable_by(mid, f64::total_cmp);
    let sd = 1.4826 * all[mid];
    let thr = 6.0 * sd;
    let (mut count, mut sum_sq) = (0usize, 0.0);
    for r in ranges {
        for t in r.start + 2..r.end.saturating_sub(2) {
            let s = s_at(t).abs();
            if s > thr && s >= s_at(t - 1).abs() && s >= s_at(t + 1).abs() {
                count += 1;
                sum_sq += s * s;
            }
        }
    }
    (count, sum_sq, thr)
}

/// Upper tail of the standard normal, Q(c) = 1 - Phi(c) = Phi(-c).
fn normal_tail(c: f64) -> f64 {
    normal_cdf(-c)
}

fn outliers(cx: &Context) -> Result<Option<Proposal>> {
    let ranges = cx.ranges();
    let (c_real, ss_real, thr) = spikes(cx.real, ranges);
    let c_ens = cx
        .target
        .iter()
        .map(|t| spikes(t, ranges).0 as f64)
        .sum::<f64>()
        / cx.target.len() as f64;
    let excess = c_real as f64 - c_ens;
    if excess < 3.0 || c_real == 0 || thr <= 0.0 {
        return Ok(None);
    }
    let m2 = ss_real / c_real as f64;
    // solve m2 = scale^2 (1 + c phi(c) / Q(c)), c = thr / scale, by bisection on ln scale
    let f = |scale: f64| {
        let c = thr / scale;
        let phi = (-0.5 * c * c).exp() / (2.0 * std::f64::consts::PI).sqrt();
        let q = normal_tail(c).max(1e-300);
        scale * scale * (1.0 + c * phi / q) - m2
    };
    let (mut lo, mut hi) = ((thr * 1e-3).ln(), (m2.sqrt() * 10.0).max(thr).ln());
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f(mid.exp()) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let scale = (0.5 * (lo + hi)).exp();
    let p_detect = (2.0 * normal_tail(thr / scale)).max(1e-6);
    let t_train = cx.n_train() as f64 / cx.rate_hz();
    let rate_hz = (excess / (t_train * p_detect)).min(cx.rate_hz());
    let comp = Component::Outliers { rate_hz, scale };
    let u = cx.sim.extra_signal(cx.spec, cx.channel, &comp)?;
    Ok(Some(Proposal {
        kind: "outliers".into(),
        params: params_json(&comp),
        component: comp,
        replaces: None,
        delta: Delta::Each(u),
        note: format!(
            "{c_real} spikes above 6 robust sd in the training part against {c_ens:.1} in the simulations"
        ),
    }))
}

fn heteroskedastic(cx: &Context, tp: &Temperature, tm: f64) -> Result<Option<Proposal>> {
    let comps = &cx.spec.channels[cx.channel].components;
    let ranges = shrink_ranges(cx.ranges());
    // the noise component with the largest share of the variance of the differences
    let var_d = |x: &[f64]| -> f64 {
        let mut s = 0.0;
        let mut c = 0.0f64;
        for r in &ranges {
            for t in r.clone() {
                let d = x[t] - x[t - 1];
                s += d * d;
                c += 1.0;
            }
        }
        s / c.max(1.0)
    };
    let total: f64 = cx.target.iter().map(|t| var_d(t)).sum::<f64>();
    let mut best: Option<(usize, f64)> = None;
    for (k, c) in comps.iter().enumerate() {
        if !c.kind().is_noise() || matches!(c, Component::Farma(_)) {
            continue;
        }
        let v: f64 = cx.parts.iter().map(|p| var_d(&p[k])).sum::<f64>();
        if best.is_none_or(|b| v > b.1) {
            best = Some((k, v));
        }
    }
    let Some((k, v)) = best else { return Ok(None) };
    let of = comps[k].kind();
    let phi = (v / total.max(f64::MIN_POSITIVE)).clamp(1e-6, 1.0);
    let d2: Vec<f64> = {
        let mut d = vec![0.0; cx.real.len()];
        for (t, v) in d.iter_mut().enumerate().skip(1) {
            *v = (cx.real[t] - cx.real[t - 1]).powi(2);
        }
        d
    };
    let dt: Vec<f64> = tp.t_c.iter().map(|t| t - tm).collect();
    let Some((b, _)) = ls(&d2, &[&dt], true, &ranges) else {
        return Ok(None);
    };
    // intercept = mean of d2 where dT = 0: the regression's mean minus slope * mean dT
    let (mut sd2, mut sdt, mut c) = (0.0, 0.0, 0.0);
    for r in &ranges {
        for t in r.clone() {
            sd2 += d2[t];
            sdt += dt[t];
            c += 1.0;
        }
    }
    let a = (sd2 - b[0] * sdt) / c;
    if a <= 0.0 {
        return Ok(None);
    }
    let slope = b[0] / (2.0 * a * phi);
    let comp = Component::Heteroskedastic { of, slope };
    let u = cx.sim.extra_signal(cx.spec, cx.channel, &comp)?;
    Ok(Some(Proposal {
        kind: "heteroskedastic".into(),
        params: params_json(&comp),
        component: comp,
        replaces: None,
        delta: Delta::Each(u),
        note: format!(
            "regression of the squared differences on temperature; {} carries {:.0} % of their variance",
            of.as_str(),
            100.0 * phi
        ),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_resolution_finds_the_lsb() {
        // rates rounded to a 0.05 grid, as an ADIS16405 writes them
        let x: Vec<f64> = (0..5000)
            .map(|k| (((k as f64 * 0.37).sin() * 0.8) / 0.05).round() * 0.05 + 0.4)
            .collect();
        let q = output_resolution(&x).unwrap();
        assert!((q - 0.05).abs() < 1e-9, "{q}");
        // continuous values: none
        let y: Vec<f64> = (0..5000).map(|k| (k as f64 * 0.37).sin()).collect();
        assert_eq!(output_resolution(&y), None);
    }

    #[test]
    fn golden_section_finds_the_minimum() {
        // near a quadratic minimum f changes by (dx)^2, below rounding once dx is under
        // sqrt(eps) ~ 1.5e-8: that is as close as any comparison search can get
        let x = golden_min(0.0, 4.0, 60, |v| (v - 1.3).powi(2) + 2.0);
        assert!((x - 1.3).abs() < 1e-7, "{x}");
        // at an end of the bracket it converges to that end
        let y = golden_min(0.0, 1.0, 60, |v| v);
        assert!(y < 1e-9, "{y}");
    }
}
