//! Checking a fitted FARMA model: residual whiteness ([`super::ljung_box`]), hold-out
//! prediction against the linear ARMA baseline, and polynomial fits of the f_m.
//!
//! Prediction. The series y (channel minus the model's mean) is run through the
//! model's residual recursion and k-step prediction ([`Farma::kstep`], documented in
//! [`crate::model`]): every target t in the hold-out (the last `holdout` samples) is
//! predicted k steps ahead from origin s = t - k; RMSE per k. The baseline is the same
//! with constant f = the ARMA's a and its b ([`Farma::linear`]).
//!
//! Polynomial fits. f_m at the grid points with a local fit (not filled, finite
//! pointwise standard error se_g) is fitted by weighted least squares in z = u / s
//! (u = x_{t-d} - mean, s = max |u_g|), weights 1 / se_g^2, for degrees
//! 0 ..= min(max, G - 2). The degree minimises a BIC with the estimation noise as the
//! error scale: chi2_k + (degree + 1) ln G_eff, chi2_k = sum_g ((f_g - poly_k(u_g)) / se_g)^2,
//! G_eff = (grid span) / h the number of roughly independent local estimates (the
//! grid points within one bandwidth share their data), clamped to [2, G].
//! Coefficients are reported for powers of u (the model's centred index).

use super::ljung_box::{Whiteness, whiteness};
use crate::estimator::linalg::normal_equations;
use crate::model::Farma;

/// One horizon of the hold-out prediction.
#[derive(Clone, Debug, PartialEq)]
pub struct HorizonRow {
    pub k: usize,
    /// Forecasts scored.
    pub n: usize,
    pub rmse_farma: f64,
    pub rmse_arma: f64,
}

/// Hold-out prediction.
#[derive(Clone, Debug)]
pub struct Prediction {
    pub holdout: usize,
    pub horizons: Vec<HorizonRow>,
    /// Standard deviation of the hold-out (the error of predicting the mean).
    pub holdout_std: f64,
}

/// A polynomial fit of one f_m.
#[derive(Clone, Debug)]
pub struct PolyFit {
    pub m: usize,
    pub degree: usize,
    /// Coefficients of 1, u, u^2, ... (u = index minus the model's mean).
    pub coef: Vec<f64>,
    /// Root mean square residual on the grid, weighted by 1/se^2.
    pub wrms: f64,
    /// The criterion of degrees 0 .. (smallest chosen).
    pub criterion: Vec<f64>,
}

/// Hold-out prediction of the last `holdout` samples of `x` (channel units) by the
/// FARMA model and the linear baseline (each centring x with its own mean), at
/// horizons `ks` (those up to the hold-out length).
pub fn predict_holdout(
    model: &Farma,
    lin: &Farma,
    x: &[f64],
    holdout: usize,
    ks: &[usize],
) -> Prediction {
    let kmax = ks
        .iter()
        .copied()
        .filter(|k| *k <= holdout)
        .max()
        .unwrap_or(1);
    let y: Vec<f64> = x.iter().map(|v| v - model.mean).collect();
    let ya: Vec<f64> = x.iter().map(|v| v - lin.mean).collect();
    let (sf, cf) = model.kstep(&y, holdout, kmax);
    let (sa, ca) = lin.kstep(&ya, holdout, kmax);
    let ho = &x[x.len() - holdout..];
    let mu = ho.iter().sum::<f64>() / holdout as f64;
    let sd = (ho.iter().map(|v| (v - mu).powi(2)).sum::<f64>() / holdout as f64).sqrt();
    Prediction {
        holdout,
        horizons: ks
            .iter()
            .filter(|k| **k >= 1 && **k <= kmax)
            .map(|&k| HorizonRow {
                k,
                n: cf[k - 1],
                rmse_farma: (sf[k - 1] / cf[k - 1] as f64).sqrt(),
                rmse_arma: (sa[k - 1] / ca[k - 1] as f64).sqrt(),
            })
            .collect(),
        holdout_std: sd,
    }
}

/// Polynomial fits of every f_m of `model` in the centred index, weighted by the
/// pointwise standard errors (filled grid points left out).
pub fn poly_fits(model: &Farma, max_degree: usize) -> Vec<PolyFit> {
    let c = &model.coef;
    let p = model.p();
    (0..p)
        .map(|m| {
            let keep: Vec<usize> = (0..c.n_grid()).filter(|&g| !c.filled[g]).collect();
            let grid: Vec<f64> = keep.iter().map(|&g| c.centred_grid(g)).collect();
            let f: Vec<f64> = keep.iter().map(|&g| c.f[g * p + m]).collect();
            let se: Vec<f64> = keep.iter().map(|&g| c.se[g * p + m]).collect();
            poly_fit_curve(m + 1, &grid, &f, &se, model.bandwidth, max_degree)
        })
        .collect()
}

/// The polynomial fit of one curve: values `f` at ascending centred `grid` points with
/// standard errors `se` (points with a non-finite or zero se are left out), for a
/// model of bandwidth `h`.
pub fn poly_fit_curve(
    m: usize,
    grid: &[f64],
    f: &[f64],
    se: &[f64],
    h: f64,
    max_degree: usize,
) -> PolyFit {
    let pts: Vec<usize> = (0..grid.len())
        .filter(|&g| se[g].is_finite() && se[g] > 0.0 && f[g].is_finite())
        .collect();
    let gn = pts.len();
    let none = PolyFit {
        m,
        degree: 0,
        coef: vec![f64::NAN],
        wrms: f64::NAN,
        criterion: vec![],
    };
    if gn < 3 {
        return none;
    }
    let scale = pts
        .iter()
        .map(|&g| grid[g].abs())
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let span = grid[pts[gn - 1]] - grid[pts[0]];
    let g_eff = if h > 0.0 {
        (span / h).clamp(2.0, gn as f64)
    } else {
        gn as f64
    };
    let w: Vec<f64> = pts.iter().map(|&g| se[g].powi(-2)).collect();
    let wsum: f64 = w.iter().sum();
    let maxdeg = max_degree.min(gn - 2);
    let mut best: Option<(f64, usize, Vec<f64>, f64)> = None;
    let mut crit = Vec::new();
    for deg in 0..=maxdeg {
        let k = deg + 1;
        let mut ata = vec![0.0; k * k];
        let mut aty = vec![0.0; k];
        for (&g, wg) in pts.iter().zip(&w) {
            let z = grid[g] / scale;
            let pw: Vec<f64> = (0..k).map(|i| z.powi(i as i32)).collect();
            for i in 0..k {
                for j in 0..k {
                    ata[i * k + j] += wg * pw[i] * pw[j];
                }
                aty[i] += wg * pw[i] * f[g];
            }
        }
        let Some(c) = normal_equations(&ata, &aty, k) else {
            crit.push(f64::NAN);
            continue;
        };
        let chi2: f64 = pts
            .iter()
            .zip(&w)
            .map(|(&g, wg)| {
                let z = grid[g] / scale;
                let fit: f64 = (0..k).map(|i| c[i] * z.powi(i as i32)).sum();
                wg * (f[g] - fit).powi(2)
            })
            .sum();
        let cr = chi2 + k as f64 * g_eff.ln();
        crit.push(cr);
        if best.as_ref().is_none_or(|bb| cr < bb.0) {
            let coef: Vec<f64> = (0..k).map(|i| c[i] / scale.powi(i as i32)).collect();
            best = Some((cr, deg, coef, (chi2 / wsum).sqrt()));
        }
    }
    match best {
        Some((_, degree, coef, wrms)) => PolyFit {
            m,
            degree,
            coef,
            wrms,
            criterion: crit,
        },
        None => none,
    }
}

/// Everything `check` reports for one channel.
#[derive(Clone, Debug)]
pub struct CheckReport {
    pub whiteness: Whiteness,
    pub prediction: Option<Prediction>,
    pub poly: Vec<PolyFit>,
}

/// The default prediction horizons (samples).
pub const HORIZONS: [usize; 12] = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000];

/// Whiteness of a model's residuals `residuals` (from t = 0; rows t >= max(p,q,d)
/// are tested), with Ljung-Box at lags 5, 10, 20 and ln n (those up to `maxlag`),
/// model_df = p + q.
pub fn residual_whiteness(model: &Farma, residuals: &[f64], maxlag: usize) -> Whiteness {
    let e = &residuals[model.order.lag().min(residuals.len())..];
    let ln = (e.len() as f64).ln().round() as usize;
    let mut lags = vec![5, 10, 20, ln.max(1)];
    lags.retain(|l| *l <= maxlag);
    lags.sort_unstable();
    lags.dedup();
    whiteness(e, maxlag, &lags, model.p() + model.q())
}

/// The check of one channel's model on its series `x` (channel units), the one
/// `farma check` and `farma analyze` run: the whiteness of `residuals` (the model's
/// residuals on x before the hold-out, from t = 0), the prediction of the last
/// `holdout` samples against the linear `baseline` (none when `holdout` is 0), and
/// polynomial fits of the f_m up to `max_degree`.
pub fn check_model(
    model: &Farma,
    residuals: &[f64],
    baseline: &Farma,
    x: &[f64],
    holdout: usize,
    maxlag: usize,
    max_degree: usize,
) -> CheckReport {
    CheckReport {
        whiteness: residual_whiteness(model, residuals, maxlag),
        prediction: (holdout > 0).then(|| predict_holdout(model, baseline, x, holdout, &HORIZONS)),
        poly: poly_fits(model, max_degree),
    }
}
