//! Checking a fitted FARMA model: residual whiteness ([`super::ljung_box`]), hold-out
//! prediction against the linear ARMA baseline, and polynomial fits of the f_m.
//!
//! Prediction. The series y (channel minus the model's mean) is run through the
//! model's residual recursion e_t = y_t - yhat_t,
//! yhat_t = sum_m f_m(y_{t-d}) y_{t-m} + sum_m b_m e_{t-m}, so yhat_t is the one-step
//! prediction from the observed past. The k-step prediction from origin s (data known
//! up to s) iterates the model with the unknown future innovations set to 0 and the
//! predicted values standing in for unobserved y, in the index too:
//! ytilde_{s+j} = sum_m f_m(ytilde_{s+j-d}) ytilde_{s+j-m} + sum_m b_m etilde_{s+j-m},
//! ytilde = y and etilde = e up to s, etilde = 0 after. Every target t in the hold-out
//! (the last `holdout` samples) is predicted k steps ahead from origin s = t - k (which
//! may lie before the hold-out: those data are observed, not fitted); RMSE per k.
//! The baseline is the same with constant f = the ARMA's a and its b.
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
use crate::estimator::FittedFarma;
use crate::estimator::linalg::normal_equations;

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

/// A linear model for prediction: f constant = ar.
pub struct Linear<'a> {
    pub ar: &'a [f64],
    pub ma: &'a [f64],
}

/// What k-step prediction needs of a model (FARMA or linear).
pub trait Predictor {
    fn p(&self) -> usize;
    fn d(&self) -> usize;
    fn b(&self) -> &[f64];
    fn f(&self, u: f64, out: &mut [f64]);
}

impl Predictor for FittedFarma {
    fn p(&self) -> usize {
        self.p
    }
    fn d(&self) -> usize {
        self.d
    }
    fn b(&self) -> &[f64] {
        &self.b
    }
    fn f(&self, u: f64, out: &mut [f64]) {
        self.coef.eval(&self.grid, u, out)
    }
}

impl Predictor for Linear<'_> {
    fn p(&self) -> usize {
        self.ar.len()
    }
    fn d(&self) -> usize {
        1
    }
    fn b(&self) -> &[f64] {
        self.ma
    }
    fn f(&self, _u: f64, out: &mut [f64]) {
        out.copy_from_slice(self.ar)
    }
}

/// Residuals of a model on centred values `y` by its recursion (zeros before the start).
pub fn residuals_of(m: &dyn Predictor, y: &[f64]) -> Vec<f64> {
    let (p, d, b) = (m.p(), m.d(), m.b());
    let mut f = vec![0.0; p];
    let mut e = vec![0.0; y.len()];
    for t in 0..y.len() {
        m.f(if t >= d { y[t - d] } else { 0.0 }, &mut f);
        let mut s = y[t];
        for k in 0..p.min(t) {
            s -= f[k] * y[t - k - 1];
        }
        for (k, bk) in b.iter().enumerate() {
            if t > k {
                s -= bk * e[t - k - 1];
            }
        }
        e[t] = s;
    }
    e
}

/// Squared errors of the k-step predictions of the last `holdout` samples of `y`
/// (centred), summed per horizon k = 1..=kmax (index k-1), and their counts.
pub fn kstep(m: &dyn Predictor, y: &[f64], holdout: usize, kmax: usize) -> (Vec<f64>, Vec<usize>) {
    let n = y.len();
    let (p, d, b) = (m.p(), m.d(), m.b());
    let lag = p.max(d).max(b.len());
    let e = residuals_of(m, y);
    let h0 = n - holdout;
    let mut sse = vec![0.0; kmax];
    let mut cnt = vec![0usize; kmax];
    let mut f = vec![0.0; p];
    let mut yt = vec![0.0; lag + kmax];
    let mut et = vec![0.0; lag + kmax];
    // origin s: known up to s (also before the hold-out: those data are observed);
    // forecasts s+1 .. s+kmax, scored where they fall inside [h0, n)
    for s in h0.saturating_sub(kmax)..n - 1 {
        if s + 1 < lag {
            continue;
        }
        for i in 0..lag {
            yt[i] = y[s + 1 - lag + i];
            et[i] = e[s + 1 - lag + i];
        }
        for j in 1..=kmax {
            let t = s + j;
            if t >= n {
                break;
            }
            let i = lag + j - 1;
            m.f(yt[i - d], &mut f);
            let mut v = 0.0;
            for k in 0..p {
                v += f[k] * yt[i - k - 1];
            }
            for (k, bk) in b.iter().enumerate() {
                v += bk * et[i - k - 1];
            }
            yt[i] = v;
            et[i] = 0.0;
            if t >= h0 {
                sse[j - 1] += (y[t] - v).powi(2);
                cnt[j - 1] += 1;
            }
        }
    }
    (sse, cnt)
}

/// Hold-out prediction of the last `holdout` samples of `x` (channel units) by the
/// FARMA model (fitted to x - `model_mean`) and the linear baseline (fitted with mean `arma_mean`), at horizons
/// `ks` (those up to the hold-out length).
pub fn predict_holdout(
    model: &dyn Predictor,
    model_mean: f64,
    lin: &Linear,
    arma_mean: f64,
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
    let y: Vec<f64> = x.iter().map(|v| v - model_mean).collect();
    let ya: Vec<f64> = x.iter().map(|v| v - arma_mean).collect();
    let (sf, cf) = kstep(model, &y, holdout, kmax);
    let (sa, ca) = kstep(lin, &ya, holdout, kmax);
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

/// Polynomial fits of every f_m of `model`, weighted by the pointwise standard errors.
pub fn poly_fits(model: &FittedFarma, max_degree: usize) -> Vec<PolyFit> {
    let p = model.p;
    (0..p)
        .map(|m| {
            let keep: Vec<usize> = (0..model.grid.len())
                .filter(|&g| !model.filled[g])
                .collect();
            let grid: Vec<f64> = keep.iter().map(|&g| model.grid[g]).collect();
            let f: Vec<f64> = keep.iter().map(|&g| model.coef.f[g * p + m]).collect();
            let se: Vec<f64> = keep.iter().map(|&g| model.se[g * p + m]).collect();
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

/// Whiteness of the model's residuals (rows t >= max(p,q,d)), with Ljung-Box at
/// lags 5, 10, 20 (and ln n), model_df = p + q.
pub fn check_whiteness(model: &FittedFarma, maxlag: usize) -> Whiteness {
    let start = model.p.max(model.q).max(model.d);
    let e = &model.residuals[start..];
    let ln = (e.len() as f64).ln().round() as usize;
    let mut lags = vec![5, 10, 20, ln.max(1)];
    lags.retain(|l| *l <= maxlag);
    lags.sort_unstable();
    lags.dedup();
    whiteness(e, maxlag, &lags, model.p + model.q)
}
