//! How a model came to be: the report of a fit (the GCV table, the alternation's
//! history, the local fits' diagnostics, notes, timings) or of an online update. The
//! model itself is [`super::Farma`]; the tables and `--json` of `fit` and `update`
//! read both.
//!
//! One [`FitReport`] for both indexes, generic over the local fits at the grid points
//! alone: on the lag index a [`GridFit`] (the default), on a 2-D index a
//! [`Grid2Fit`] (a slope per coordinate, 3p x 3p local systems). Those are the
//! estimator's own working types, different in shape, and the fit of an index knows
//! which it made; a GCV row records one bandwidth, or two ([`GcvRow::bandwidth2`]).

use crate::estimator::multivariate::Grid2Fit;
use crate::estimator::problem::GridFit;
use crate::estimator::{FitPath, Init};

/// One row of the GCV table.
#[derive(Clone, Debug, PartialEq)]
pub struct GcvRow {
    /// The rung: h_j = 1.1^-j range/2 (j = 0..20 the paper's ladder; below 0 and
    /// above 20 its extensions).
    pub j: i32,
    /// h, or h_1 on a 2-D index.
    pub bandwidth: f64,
    /// h_2 on a 2-D index (the rung scales both: h_j = 1.1^-j (range_1/2,
    /// range_2/2)); None on the lag index.
    pub bandwidth2: Option<f64>,
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
    /// it ends with the residual recursion and the RSS (`estimator::fit::ma_step`).
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

/// The report of a fit: everything `farma fit` says besides the model. `L` is the
/// index's local fits (module documentation).
#[derive(Clone, Debug)]
pub struct FitReport<L = GridFit> {
    /// The local fits at the chosen bandwidth: f (as in the model), slopes, supports,
    /// kernel masses, condition numbers and statuses per grid point.
    pub local: L,
    pub rss: f64,
    /// Trace of the smoother at the chosen bandwidth (effective degrees of freedom);
    /// p when the fit returned its linear start (constant f_m).
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
    /// Why the linear start was returned (Some exactly when `linear_start`), for the
    /// order table to count; the notes say it in words.
    pub returned_start_reason: Option<StartReason>,
    /// Messages for the user (ladder extensions, filled points).
    pub notes: Vec<String>,
    /// Where the time went (the lag index's fit; zeros on a 2-D index, whose fit
    /// does not time its steps).
    pub timings: FitTimings,
}

/// Why a fit returned its linear ARMA start (module doc of `estimator::fit`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StartReason {
    /// No local fit lowered the RSS below the start's: the first f-step, damped down
    /// to the smallest step tried, did not (the alternation stalled there).
    NoDescent,
    /// The alternation moved off the start but ended above it by more than the
    /// tolerance, and no iterate in between was below it.
    EndedAbove,
}

impl StartReason {
    /// The machine-readable name (JSON, tables).
    pub fn as_str(self) -> &'static str {
        match self {
            StartReason::NoDescent => "no_descent",
            StartReason::EndedAbove => "ended_above",
        }
    }

    /// In words.
    pub fn words(self) -> &'static str {
        match self {
            StartReason::NoDescent => {
                "no local fit at any tried step lowered the RSS below the linear start's"
            }
            StartReason::EndedAbove => {
                "the alternation ended above the linear start and no iterate on the way was below it"
            }
        }
    }
}

/// The report of a fit on a 2-D index.
pub type FitReport2 = FitReport<Grid2Fit>;

/// The report of an online update (`farma update`): the recursion over the new
/// samples; trace and GCV need the old data and are not known.
#[derive(Clone, Debug)]
pub struct UpdateReport {
    /// The local fits solved from the updated normal equations (as [`FitReport::local`]).
    pub local: GridFit,
    /// Residual sum of squares (discounted with the forgetting factor).
    pub rss: f64,
    /// Samples seen (fit plus updates) and rows behind the residuals.
    pub n: usize,
    pub n_rows: usize,
    /// Residuals of the new samples.
    pub residuals: Vec<f64>,
    /// w_t = x_t - sum f_m(U_t) x_{t-m} of the new samples (a priori, current f).
    pub w: Vec<f64>,
    /// Index of the first new sample in the whole series.
    pub first_t: u64,
    /// The forgetting factor lambda.
    pub forgetting: f64,
    pub notes: Vec<String>,
}

/// How a model was made, as the tables and `--json` of `fit`, `update` and `analyze`
/// read it: a fit's report (on the lag index or a 2-D index) or an update's.
#[derive(Clone, Copy, Debug)]
pub enum Report<'a> {
    Fit(&'a FitReport),
    Fit2(&'a FitReport2),
    Update(&'a UpdateReport),
}

/// The field `$f` of a fit's report, on either index; `$update` for an update's.
macro_rules! of_fit {
    ($r:expr, $f:ident, $update:expr) => {
        match $r {
            Report::Fit(r) => r.$f,
            Report::Fit2(r) => r.$f,
            Report::Update(_) => $update,
        }
    };
}

impl Report<'_> {
    pub fn rss(&self) -> f64 {
        match self {
            Report::Fit(r) => r.rss,
            Report::Fit2(r) => r.rss,
            Report::Update(r) => r.rss,
        }
    }

    /// The smoother's trace; NaN after an update (it needs the old data).
    pub fn trace(&self) -> f64 {
        of_fit!(self, trace, f64::NAN)
    }

    /// GCV of the model; NaN after an update.
    pub fn gcv(&self) -> f64 {
        of_fit!(self, gcv, f64::NAN)
    }

    /// The GCV table (none after an update: the bandwidth is held).
    pub fn gcv_table(&self) -> &[GcvRow] {
        match self {
            Report::Fit(r) => &r.gcv_table,
            Report::Fit2(r) => &r.gcv_table,
            Report::Update(_) => &[],
        }
    }

    /// Alternations run (0 for an update).
    pub fn iterations(&self) -> usize {
        of_fit!(self, iterations, 0)
    }

    /// Whether the alternation converged (an update's recursion always ends).
    pub fn converged(&self) -> bool {
        of_fit!(self, converged, true)
    }

    pub fn ladder_extended(&self) -> bool {
        of_fit!(self, ladder_extended, false)
    }

    /// Why a fit returned its linear start (None for a local fit and for an update).
    pub fn returned_start_reason(&self) -> Option<StartReason> {
        of_fit!(self, returned_start_reason, None)
    }

    /// How it started: `arma` or `literal` for a fit, `state` for an update.
    pub fn init_name(&self) -> &'static str {
        match self {
            Report::Fit(FitReport { init, .. }) | Report::Fit2(FitReport { init, .. }) => {
                match init {
                    Init::Arma => "arma",
                    Init::Literal => "literal",
                }
            }
            Report::Update(_) => "state",
        }
    }

    /// The computation: `fast` or `direct` for a fit, `rls` for an update.
    pub fn method_name(&self) -> &'static str {
        match self {
            Report::Fit(FitReport { path, .. }) | Report::Fit2(FitReport { path, .. }) => {
                match path {
                    FitPath::Fast => "fast",
                    FitPath::Direct => "direct",
                }
            }
            Report::Update(_) => "rls",
        }
    }

    pub fn n(&self) -> usize {
        match self {
            Report::Fit(r) => r.n,
            Report::Fit2(r) => r.n,
            Report::Update(r) => r.n,
        }
    }

    pub fn n_rows(&self) -> usize {
        match self {
            Report::Fit(r) => r.n_rows,
            Report::Fit2(r) => r.n_rows,
            Report::Update(r) => r.n_rows,
        }
    }

    pub fn notes(&self) -> &[String] {
        match self {
            Report::Fit(r) => &r.notes,
            Report::Fit2(r) => &r.notes,
            Report::Update(r) => &r.notes,
        }
    }
}
