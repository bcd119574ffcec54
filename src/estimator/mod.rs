//! The FARMA(p,q,d) estimator: x_t = sum_m f_m(x_{t-d}) x_{t-m} + e_t + sum_m b_m e_{t-m}.
//!
//! The coefficient functions f_m are local-linear Biweight fits at grid points of the
//! index variable U_t = x_{t-d}; they are computed two ways that must agree:
//! [`direct`] (KD-tree gather + dense weighted least squares per grid point, any
//! evaluation point) and [`moments`] (one pass builds exact polynomial moment tables,
//! from which every grid point and every bandwidth of the GCV ladder is solved; see
//! `shared/design/fast-exact-fits.md`). [`problem`] defines the regression both solve,
//! [`kernel`] the Biweight, [`linalg`] the small dense solves (faer).
//! [`fit`](mod@fit) is the alternation (start, f-step by a smoother, b-step, GCV) with two
//! smoothers: the lag index x_{t-d} and the 2-D index (x_{t-d}, z_{t-d2}), z another
//! channel such as temperature ([`multivariate`]). [`update`] continues a fit over new
//! samples by recursive least squares. What they make, the fitted model, its report,
//! the update state and the model folder, lives in [`crate::model`].

#![allow(clippy::needless_range_loop)] // numeric kernels index several arrays in step

pub mod arma;
pub mod buffers;
pub mod direct;
pub mod fit;
pub mod kernel;
pub mod linalg;
pub mod moments;
pub mod multivariate;
pub mod problem;
pub mod series;
pub mod update;

pub use fit::{
    AlternationTiming, FarmaParams, FitPath, FitReport, FitTimings, Init, ValidParams, fit,
};
pub use problem::{GridFit, PointStatus, VcProblem};
