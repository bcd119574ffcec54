//! The multivariate index: f_m depends on U_t = (x_{t-d}, z_{t-d2}), the model's own
//! lagged value and another channel z of the log (for example temperature):
//! x_t = sum_m f_m(x_{t-d}, z_{t-d2}) x_{t-m} + e_t + sum_m b_m e_{t-m}.
//!
//! The fitted model is the one [`crate::model::Farma`], its coefficients on the 2-D
//! grid ([`crate::model::Coef::second`]); the report is a
//! [`crate::model::report::FitReport2`]. The local fits are in
//! `estimator/fit/grid2.rs`, the smoother under the alternation and the fit ([`fit2`])
//! in `estimator/fit/smoother2.rs`, the tables those of the lag index
//! ([`crate::model::folder::tables`], with the 2-D index's columns); all re-exported here.

pub use super::fit::grid2::{
    Grid2, Grid2Fit, Index2, Vc2Problem, fill_failed2, fit_grid2, residuals2, rss_trace2,
    se_factors2,
};
pub use super::fit::smoother2::fit2;
pub use super::fit::{Farma2Params, MAX_GRID2_POINTS, check_fit2, check_grid2};
