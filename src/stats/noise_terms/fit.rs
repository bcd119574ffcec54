//! The fit: maximum likelihood of the Allan-variance model on octave taus, every subset
//! of the candidate terms, and the subset chosen by a penalised deviance.
//!
//! Likelihood: at each octave tau the overlapping AVAR estimate a_i is taken as
//! mu_i chi^2(nu_i) / nu_i, mu_i the model's AVAR and nu_i Greenhall's equivalent
//! degrees of freedom for the noise type that dominates the model there (SP 1065
//! section 5.3; [`crate::stats::adev::edf_greenhall`]). That is a Gamma law with shape
//! nu_i / 2 and mean mu_i; the model is linear in the squared coefficients, so its
//! maximum-likelihood estimate is found by iteratively reweighted least squares with
//! weights w_i = nu_i / (2 mu_i^2) (the Gamma GLM with identity link; P. McCullagh,
//! J. A. Nelder, "Generalized Linear Models", 2nd ed., 1989: iteratively reweighted
//! least squares, and chapter 8 on the Gamma family). The deviance
//! D = sum_i nu_i [(a_i - mu_i) / mu_i - ln(a_i / mu_i)] (the Gamma deviance with
//! shape nu_i / 2) measures the misfit.
//!
//! Non-negativity: each subset is fitted without constraints and kept only when every
//! squared coefficient comes out positive; a subset whose fit wants a negative term is
//! the business of a smaller subset, which is fitted too. Over all subsets this is the
//! non-negative fit.
//!
//! Term selection: a subset is admissible when every squared coefficient is at least
//! [`super::MIN_Z`] = 2 standard uncertainties above zero (a term must earn its place)
//! and a Gauss-Markov hump shows as one in the model (`SubsetFit::hump_visible`: a
//! hump the curve does not show is not read off it); among those, the one with the smallest D + penalty * (number of parameters), the
//! Gauss-Markov hump counting two (sigma and T); the default penalty is ln(number of
//! taus), the Bayesian information criterion (G. Schwarz, Ann. Statist. 6, 1978).
//!
//! Correlation between taus: overlapping estimates at neighbouring taus share data. The
//! fit uses octave taus only (m = 1, 2, 4, ...), where the correlation of neighbours is
//! moderate, and fits them as if independent (the estimate); the uncertainty then
//! allows for their correlation (see `sandwich_cov`, correlations measured by Monte
//! Carlo). Without that step the reported uncertainties are too small: in the tests
//! (tests/suite/noise_terms.rs) three of 21 coefficients fall 3.1 to 3.3 of them from the
//! truth, and a rate random walk often takes a spurious ramp beside it. Any remaining
//! misfit shows in the Pearson statistic X^2 = sum_i w_i (a_i - mu_i)^2, and the
//! covariance is multiplied by the dispersion max(1, X^2 / (n_taus - n_params))
//! (the moment estimate of the dispersion, McCullagh and Nelder).
//!
//! Uncertainty: the covariance of the squared coefficients (and of ln T for the hump)
//! is the sandwich of `sandwich_cov` times the dispersion; a coefficient's standard
//! uncertainty follows by the delta method, u(c) = u(c^2) / (2 c), and u(T) = T u(ln T).

use super::model::Term;
use super::wls;
use crate::stats::adev::edf_greenhall;

/// One octave point of the measured Allan variance.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct AvarPoint {
    /// Averaging factor (samples).
    pub m: usize,
    /// Averaging time, s.
    pub tau_s: f64,
    /// Overlapping Allan variance, u^2.
    pub avar: f64,
}

/// A fitted subset.
#[derive(Clone, Debug)]
pub(crate) struct SubsetFit {
    pub terms: Vec<Term>,
    /// Squared coefficients, in the order of `terms`.
    pub coef_sq: Vec<f64>,
    /// Gauss-Markov correlation time when the subset has the hump.
    pub corr_time_s: f64,
    /// Covariance of (coef_sq..., ln T if the hump), before the dispersion.
    pub cov: Vec<f64>,
    pub deviance: f64,
    pub pearson: f64,
    pub edf: Vec<f64>,
    pub model: Vec<f64>,
    /// Alpha of the dominant term at each point.
    pub alpha: Vec<i32>,
}

impl SubsetFit {
    pub fn n_params(&self) -> usize {
        self.terms.len() + usize::from(self.terms.contains(&Term::GaussMarkov))
    }

    /// Whether a Gauss-Markov hump of the fit shows as one: the model's AVAR has a
    /// local maximum inside the fitted taus (on a grid of 8 points per octave). A hump
    /// that the sum of the terms does not show is not read off the curve: it only
    /// bends the others, and takes the place of a bias instability (a flicker floor is
    /// a sum of many such processes, Kasdin 1995) or a rate random walk there. True
    /// for a fit without the hump.
    pub fn hump_visible(&self, pr: &Problem) -> bool {
        if !self.terms.contains(&Term::GaussMarkov) {
            return true;
        }
        let (Some(first), Some(last)) = (pr.points.first(), pr.points.last()) else {
            return false;
        };
        let step = std::f64::consts::LN_2 / 8.0;
        let n = ((last.tau_s / first.tau_s).ln() / step).floor() as usize + 1;
        let model: Vec<f64> = (0..n)
            .map(|i| {
                let tau = first.tau_s * (i as f64 * step).exp();
                model_at(&self.terms, &self.coef_sq, self.corr_time_s, tau)
            })
            .collect();
        model.windows(3).any(|w| w[1] > w[0] && w[1] > w[2])
    }
}

/// Model AVAR at tau for terms with squared coefficients.
pub(crate) fn model_at(terms: &[Term], coef_sq: &[f64], corr_time_s: f64, tau_s: f64) -> f64 {
    terms
        .iter()
        .zip(coef_sq)
        .map(|(t, c)| c * t.basis(tau_s, corr_time_s))
        .sum()
}

/// The measured curve with Greenhall's EDF of every point for each alpha in -2..=2
/// (computed once: the fit asks for them many times).
#[derive(Clone, Debug)]
pub(crate) struct Problem {
    pub points: Vec<AvarPoint>,
    /// edf[i][alpha + 2]; NaN where Greenhall's algorithm has no case.
    pub edf: Vec<[f64; 5]>,
}

impl Problem {
    pub fn new(points: &[AvarPoint], n_samples: usize) -> Problem {
        let edf = points
            .iter()
            .map(|p| {
                let mut e = [f64::NAN; 5];
                for (j, alpha) in (-2..=2).enumerate() {
                    e[j] = edf_greenhall(alpha, 2, p.m, n_samples + 1, true, false)
                        .filter(|v| v.is_finite() && *v > 0.0)
                        .unwrap_or(f64::NAN);
                }
                e
            })
            .collect();
        Problem {
            points: points.to_vec(),
            edf,
        }
    }

    /// EDF at point i for the dominant term of the model there; alpha 0 (white noise)
    /// when there is no model yet, and where Greenhall's algorithm has no case for the
    /// dominant type (white PM at the largest taus).
    fn edf_at(
        &self,
        i: usize,
        terms: &[Term],
        coef_sq: Option<&[f64]>,
        corr_time_s: f64,
    ) -> Option<f64> {
        let p = &self.points[i];
        let alpha = match coef_sq {
            None => 0,
            Some(c) => {
                let (best, _) = terms.iter().zip(c).fold((None, -1.0), |(bt, bv), (t, &c)| {
                    let v = c * t.basis(p.tau_s, corr_time_s);
                    if v > bv { (Some(*t), v) } else { (bt, bv) }
                });
                best.map_or(0, |t| t.alpha(p.tau_s, corr_time_s))
            }
        };
        let e = self.edf[i][(alpha + 2) as usize];
        let e = if e.is_nan() { self.edf[i][2] } else { e };
        (!e.is_nan()).then_some(e)
    }
}

/// Maximum-likelihood fit of `terms` (Gauss-Markov T fixed at `corr_time_s`) by IRLS.
/// None when a squared coefficient is not positive, or the design is degenerate.
pub(crate) fn fit_fixed(pr: &Problem, terms: &[Term], corr_time_s: f64) -> Option<SubsetFit> {
    let points = &pr.points;
    let n = points.len();
    let k = terms.len();
    if k == 0 || n < k {
        return None;
    }
    let design: Vec<Vec<f64>> = points
        .iter()
        .map(|p| {
            terms
                .iter()
                .map(|t| t.basis(p.tau_s, corr_time_s))
                .collect()
        })
        .collect();
    let a: Vec<f64> = points.iter().map(|p| p.avar).collect();
    let mut coef: Option<Vec<f64>> = None;
    let mut model: Vec<f64> = a.clone();
    let mut edf = vec![0.0; n];
    let mut sol = None;
    for _ in 0..60 {
        for (i, e) in edf.iter_mut().enumerate() {
            *e = pr.edf_at(i, terms, coef.as_deref(), corr_time_s)?;
        }
        let w: Vec<f64> = (0..n)
            .map(|i| edf[i] / (2.0 * model[i] * model[i]))
            .collect();
        let s = wls::solve(&design, &a, &w)?;
        if s.coef.iter().any(|&c| c.is_nan() || c <= 0.0) {
            return None;
        }
        let new_model: Vec<f64> = design
            .iter()
            .map(|row| row.iter().zip(&s.coef).map(|(g, c)| g * c).sum())
            .collect();
        let change = new_model
            .iter()
            .zip(&model)
            .map(|(x, y)| ((x - y) / y).abs())
            .fold(0.0, f64::max);
        model = new_model;
        coef = Some(s.coef.clone());
        sol = Some(s);
        if change < 1e-10 {
            break;
        }
    }
    let sol = sol?;
    for (i, e) in edf.iter_mut().enumerate() {
        *e = pr.edf_at(i, terms, Some(&sol.coef), corr_time_s)?;
    }
    let deviance = (0..n)
        .map(|i| edf[i] * ((a[i] - model[i]) / model[i] - (a[i] / model[i]).ln()))
        .sum();
    let alpha: Vec<i32> = points
        .iter()
        .map(|p| dominant_alpha(terms, &sol.coef, corr_time_s, p.tau_s))
        .collect();
    let pearson = (0..n)
        .map(|i| edf[i] / 2.0 * ((a[i] - model[i]) / model[i]).powi(2))
        .sum();
    Some(SubsetFit {
        terms: terms.to_vec(),
        coef_sq: sol.coef,
        corr_time_s,
        cov: sol.cov,
        deviance,
        pearson,
        edf,
        model,
        alpha,
    })
}

fn dominant_alpha(terms: &[Term], coef_sq: &[f64], corr_time_s: f64, tau_s: f64) -> i32 {
    let (best, _) = terms
        .iter()
        .zip(coef_sq)
        .fold((None, -1.0), |(bt, bv), (t, &c)| {
            let v = c * t.basis(tau_s, corr_time_s);
            if v > bv { (Some(*t), v) } else { (bt, bv) }
        });
    best.map_or(0, |t| t.alpha(tau_s, corr_time_s))
}

/// Correlation of the overlapping AVAR estimates at octave taus d steps apart when the
/// noise of PSD exponent `alpha` dominates both. Measured by Monte Carlo (300 series of
/// 2^14 samples each, correlation of ln AVAR between octave taus;
/// fixtures/golden/octave_avar_correlation.py): white PM (alpha 2) about 0.45 at every distance; white FM
/// 0.55 per step (0.22 at two steps); flicker FM 0.65 (0.25); random-walk FM 0.88
/// (0.66). Modelled as 0.45 (white PM) and rho^d with rho = 0.55, 0.65, 0.88.
fn corr_one(alpha: i32, d: usize) -> f64 {
    if d == 0 {
        return 1.0;
    }
    match alpha {
        a if a >= 1 => 0.45,
        0 => 0.55f64.powi(d as i32),
        -1 => 0.65f64.powi(d as i32),
        _ => 0.88f64.powi(d as i32),
    }
}

/// Correlation between points i and j (geometric mean of the two noise types' models).
fn corr(alpha_i: i32, alpha_j: i32, d: usize) -> f64 {
    (corr_one(alpha_i, d) * corr_one(alpha_j, d)).sqrt()
}

/// The covariance of the parameters (squared coefficients, then ln T for the hump)
/// allowing for the correlation of the octave estimates: the sandwich
/// A^{-1} (J^T W C W J) A^{-1}, A = J^T W J, W = diag(1 / V_i), V_i = 2 mu_i^2 / nu_i
/// the variance of point i, C_ij = corr_ij sqrt(V_i V_j) (see [`corr_one`]). With
/// C = diag(V) it is the inverse Fisher information of the independent-points fit.
pub(crate) fn sandwich_cov(pr: &Problem, fit: &SubsetFit) -> Option<Vec<f64>> {
    let points = &pr.points;
    let n = points.len();
    let gm = fit.terms.contains(&Term::GaussMarkov);
    let t = fit.corr_time_s;
    let h = 1e-4f64;
    let jac: Vec<Vec<f64>> = points
        .iter()
        .map(|p| {
            let mut row: Vec<f64> = fit.terms.iter().map(|tm| tm.basis(p.tau_s, t)).collect();
            if gm {
                let up = model_at(&fit.terms, &fit.coef_sq, t * h.exp(), p.tau_s);
                let dn = model_at(&fit.terms, &fit.coef_sq, t * (-h).exp(), p.tau_s);
                row.push((up - dn) / (2.0 * h));
            }
            row
        })
        .collect();
    let k = jac[0].len();
    let v: Vec<f64> = (0..n)
        .map(|i| 2.0 * fit.model[i] * fit.model[i] / fit.edf[i])
        .collect();
    let w: Vec<f64> = v.iter().map(|x| 1.0 / x).collect();
    let ainv = wls::solve(&jac, &vec![0.0; n], &w)?.cov;
    // B = J^T W C W J; (W J)_i = J_i / V_i, C_ij = corr sqrt(V_i V_j).
    let mut b = vec![0.0; k * k];
    for i in 0..n {
        for j in 0..n {
            let c = corr(fit.alpha[i], fit.alpha[j], i.abs_diff(j)) * (v[i] * v[j]).sqrt()
                / (v[i] * v[j]);
            for p in 0..k {
                for q in 0..k {
                    b[p * k + q] += jac[i][p] * c * jac[j][q];
                }
            }
        }
    }
    let mul = |x: &[f64], y: &[f64]| {
        let mut out = vec![0.0; k * k];
        for p in 0..k {
            for q in 0..k {
                out[p * k + q] = (0..k).map(|r| x[p * k + r] * y[r * k + q]).sum();
            }
        }
        out
    };
    Some(mul(&mul(&ainv, &b), &ainv))
}

/// Fits `terms`; with the Gauss-Markov hump among them, T is searched on a log grid
/// (8 points per octave from twice the smallest tau to half the largest: a hump whose
/// correlation time lies outside is white noise or a rate random walk over the fitted
/// taus) and refined by a
/// golden-section search on ln T, minimising the deviance.
pub(crate) fn fit_subset(pr: &Problem, terms: &[Term]) -> Option<SubsetFit> {
    if !terms.contains(&Term::GaussMarkov) {
        return fit_fixed(pr, terms, 1.0);
    }
    let points = &pr.points;
    let lo = (points.first()?.tau_s * 2.0).ln();
    let hi = (points.last()?.tau_s / 2.0).ln();
    if hi <= lo {
        return None;
    }
    let step = std::f64::consts::LN_2 / 8.0;
    let dev = |lnt: f64| {
        fit_fixed(pr, terms, lnt.exp())
            .map(|f| f.deviance)
            .unwrap_or(f64::INFINITY)
    };
    let n_grid = ((hi - lo) / step).ceil() as usize + 1;
    let grid: Vec<f64> = (0..n_grid).map(|i| lo + i as f64 * step).collect();
    let vals: Vec<f64> = grid.iter().map(|&g| dev(g)).collect();
    let (ib, &vb) = vals.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    if !vb.is_finite() {
        return None;
    }
    // Golden section on [grid[ib-1], grid[ib+1]].
    let (mut a, mut b) = (grid[ib.saturating_sub(1)], grid[(ib + 1).min(n_grid - 1)]);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (dev(c), dev(d));
    for _ in 0..40 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = dev(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = dev(d);
        }
    }
    let mut best_lnt = if fc < fd { c } else { d };
    if vb < fc.min(fd) {
        best_lnt = grid[ib];
    }
    let t = best_lnt.exp();
    let fit = fit_fixed(pr, terms, t)?;
    // The covariance (over ln T too) is [`sandwich_cov`]'s, computed by the caller.
    Some(fit)
}

/// Every non-empty subset of `candidates`, fitted; the feasible ones.
pub(crate) fn all_subsets(pr: &Problem, candidates: &[Term]) -> Vec<SubsetFit> {
    use rayon::prelude::*;
    let c = candidates.len();
    (1u32..(1 << c))
        .into_par_iter()
        .filter_map(|mask| {
            let terms: Vec<Term> = (0..c)
                .filter(|j| mask & (1 << j) != 0)
                .map(|j| candidates[j])
                .collect();
            fit_subset(pr, &terms)
        })
        .collect()
}
