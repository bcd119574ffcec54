//! What a fit returns: the fitted model with its report (the GCV table, the
//! alternation's history, notes and timings).

use super::params::{FitPath, Init};
use crate::estimator::problem::GridFit;

/// One row of the GCV table.
#[derive(Clone, Debug, PartialEq)]
pub struct GcvRow {
    /// The rung: h_j = 1.1^-j range/2 (j = 0..20 the paper's ladder; below 0 and
    /// above 20 its extensions).
    pub j: i32,
    pub bandwidth: f64,
    pub rss: f64,
    pub trace: f64,
    /// (RSS/m) / (1 - tr/m)^2; infinite when some grid point has no fit.
    pub gcv: f64,
    /// Grid points without a fit at this bandwidth.
    pub n_failed: usize,
}

/// Wall-clock seconds of the steps of one alternation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AlternationTiming {
    /// The f-step: moment tables (or KD-tree gathers) and local solves, GCV excluded.
    pub f_step_s: f64,
    /// GCV ladders run in this alternation (the first one, and re-checks after
    /// convergence), tables and solves for every bandwidth included.
    pub gcv_s: f64,
    /// The b-step (Gauss-Newton or one least-squares step); on the Gauss-Newton path
    /// it ends with the residual recursion and the RSS ([`super::ma_step`]).
    pub b_step_s: f64,
    /// Residual recursion and RSS after a least-squares b-step (`Init::Literal`); 0 on
    /// the Gauss-Newton path, where the b-step holds them.
    pub residuals_s: f64,
}

impl AlternationTiming {
    pub fn total_s(&self) -> f64 {
        self.f_step_s + self.gcv_s + self.b_step_s + self.residuals_s
    }
}

/// Where the time of a fit went (wall clock, seconds), for benchmarks and logs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FitTimings {
    /// Mean, checks, range, quantiles, grid.
    pub prepare_s: f64,
    /// Linear ARMA start and the first residuals.
    pub start_s: f64,
    /// One entry per alternation.
    pub alternations: Vec<AlternationTiming>,
    /// Final fit, trace and standard errors at the chosen bandwidth.
    pub final_s: f64,
    pub total_s: f64,
}

/// A fitted FARMA model.
#[derive(Clone, Debug)]
pub struct FittedFarma {
    pub p: usize,
    pub q: usize,
    pub d: usize,
    /// Mean subtracted before fitting (0 without demeaning).
    pub mean: f64,
    pub grid: Vec<f64>,
    /// Local fits at the chosen bandwidth; failed points filled by interpolation.
    pub coef: GridFit,
    /// Pointwise standard error of f_m at the grid points (G x p), sigma times the
    /// sandwich factor; NaN at filled points. For a returned linear start, the
    /// least-squares standard error of the constant a_m with the MA part taken as a
    /// known offset, sigma sqrt([(X'X)^-1]_mm) with X the lagged values, at every
    /// grid point.
    pub se: Vec<f64>,
    /// Grid points whose f was filled from their neighbours (status not Ok).
    pub filled: Vec<bool>,
    pub b: Vec<f64>,
    pub bandwidth: f64,
    pub rss: f64,
    pub sigma2: f64,
    /// Trace of the smoother at the chosen bandwidth (effective degrees of freedom);
    /// p when the fit returned its linear start (constant f_m, see the module doc).
    pub trace: f64,
    /// GCV = (RSS/m) / (1 - trace/m)^2, m = N - max(p,q,d), of the returned model:
    /// its own RSS (`rss`) and the smoother's trace at its bandwidth (NaN where a
    /// grid point has no local fit there). The GCV table's rows are the ladder's
    /// criterion instead (the RSS of each rung's smoother on that ladder's
    /// residuals), so the chosen row's value differs from this one slightly.
    pub gcv: f64,
    pub gcv_table: Vec<GcvRow>,
    /// Whether the ladder was extended beyond the paper's 21 bandwidths.
    pub ladder_extended: bool,
    pub iterations: usize,
    pub converged: bool,
    /// RSS after the start and after each alternation.
    pub rss_history: Vec<f64>,
    pub init: Init,
    pub path: FitPath,
    /// Samples in the series and rows in the regression.
    pub n: usize,
    pub n_rows: usize,
    /// Residuals e_t for every t.
    pub residuals: Vec<f64>,
    /// Whether the fit returned its linear ARMA start (the alternation ended above it:
    /// constant f_m, no local systems); `farma update` has no local fits to continue.
    pub linear_start: bool,
    /// Messages for the user (ladder extensions, filled points).
    pub notes: Vec<String>,
    /// Where the time went.
    pub timings: FitTimings,
}

impl FittedFarma {
    /// The fitted model alone (what `check`, prediction and the simulator read).
    pub fn model(&self) -> crate::model::Farma {
        crate::model::Farma {
            order: crate::model::Order::new(self.p, self.q, self.d),
            mean: self.mean,
            b: self.b.clone(),
            sigma2: self.sigma2,
            bandwidth: self.bandwidth,
            coef: crate::model::Coef {
                grid: self.grid.clone(),
                grid_shift: 0.0,
                f: self.coef.f.clone(),
                se: self.se.clone(),
                filled: self.filled.clone(),
            },
        }
    }
}
