//! The multivariate index: f_m depends on U_t = (x_{t-d}, z_{t-d2}), the model's own
//! lagged value and another channel z of the log (for example temperature):
//! x_t = sum_m f_m(x_{t-d}, z_{t-d2}) x_{t-m} + e_t + sum_m b_m e_{t-m}.
//!
//! Here is the fitted model with a 2-D index ([`Fitted2`]); its local fits are in
//! `estimator/fit/grid2.rs`, its smoother under the alternation and its fit ([`fit2`])
//! in `estimator/fit/smoother2.rs`, its tables in [`super::tables`] (all re-exported
//! here).

pub use super::fit::grid2::{
    Grid2, Grid2Fit, Index2, Vc2Problem, fill_failed2, fit_grid2, residuals2, rss_trace2,
    se_factors2,
};
pub use super::fit::smoother2::{Farma2Params, MAX_GRID2_POINTS, check_fit2, check_grid2, fit2};
pub use super::tables::{coef_table2, gcv_table2, params_table2};

/// One row of the 2-D GCV table.
#[derive(Clone, Debug, PartialEq)]
pub struct Gcv2Row {
    pub j: i32,
    pub bandwidth: (f64, f64),
    pub rss: f64,
    pub trace: f64,
    pub gcv: f64,
    pub n_failed: usize,
}

/// A fitted FARMA model with a 2-D index.
#[derive(Clone, Debug)]
pub struct Fitted2 {
    pub p: usize,
    pub q: usize,
    pub d: usize,
    pub d2: usize,
    pub mean: f64,
    pub grid: Grid2,
    pub coef: Grid2Fit,
    /// sigma times the sandwich factor, G x p; NaN at filled points. For a returned
    /// linear start, the least-squares standard errors of its constant a_m (as the
    /// 1-D fit's).
    pub se: Vec<f64>,
    pub filled: Vec<bool>,
    pub b: Vec<f64>,
    pub bandwidth: (f64, f64),
    pub rss: f64,
    pub sigma2: f64,
    /// Trace of the smoother at the bandwidths; p when the fit returned its linear
    /// start (constant f_m).
    pub trace: f64,
    /// GCV = (RSS/m) / (1 - trace/m)^2 of the returned model, from its own RSS
    /// (`rss`) and the smoother's trace at its bandwidths, as the 1-D fit's.
    pub gcv: f64,
    pub gcv_table: Vec<Gcv2Row>,
    pub ladder_extended: bool,
    pub iterations: usize,
    pub converged: bool,
    pub n: usize,
    pub n_rows: usize,
    pub residuals: Vec<f64>,
    pub notes: Vec<String>,
}
