//! The parameters of a fit, checked once ([`FarmaParams::validate`]), and the magnitudes
//! of the values each path can take.

use crate::error::Error;
use crate::error::Result;

/// How the alternation starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Init {
    /// Linear ARMA(p,q) by conditional least squares; b by Gauss-Newton in each b-step.
    Arma,
    /// The paper's literal scheme: AR(p) least squares, b = 0, b by one LS step.
    Literal,
}

/// Which computation gives the local fits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitPath {
    /// One-pass exact moment tables (every bandwidth of the ladder at once).
    Fast,
    /// KD-tree gather and dense least squares per grid point and bandwidth.
    Direct,
}

/// Parameters of a fit; check them with [`FarmaParams::validate`].
#[derive(Clone, Debug)]
pub struct FarmaParams {
    pub p: usize,
    pub q: usize,
    pub d: usize,
    /// Grid points over the central quantiles of the index values.
    pub grid_size: usize,
    /// Quantiles of U_t the grid spans.
    pub grid_quantiles: (f64, f64),
    /// A fixed bandwidth instead of GCV.
    pub bandwidth: Option<f64>,
    pub init: Init,
    pub path: FitPath,
    pub max_iter: usize,
    /// Relative RSS change that ends the alternation.
    pub tol: f64,
    /// Subtract the mean before fitting (recorded in the model).
    pub demean: bool,
}

impl Default for FarmaParams {
    fn default() -> Self {
        FarmaParams {
            p: 2,
            q: 1,
            d: 1,
            grid_size: 201,
            grid_quantiles: (0.01, 0.99),
            bandwidth: None,
            init: Init::Arma,
            path: FitPath::Fast,
            max_iter: 50,
            tol: 1e-6,
            demean: true,
        }
    }
}

/// Parameters that passed validation for a series of `n` samples.
#[derive(Clone, Debug)]
pub struct ValidParams(FarmaParams);

/// Most grid points of a fit: each GCV rung sums, for every grid point, the cells of
/// its window, so the ladder's cost grows with the square of the grid (on a 2,000-
/// sample channel `farma fit` took 12.0 s with 2,001 grid points, 0.57 s with the
/// default 201; one run each, 2026-11-23).
pub const MAX_GRID: usize = 5000;

impl FarmaParams {
    /// Checks the parameters against a series of `n` samples.
    pub fn validate(self, n: usize) -> Result<ValidParams> {
        let bad = |m: String| Err(Error::Usage(m));
        if self.p == 0 || self.d == 0 {
            return bad(format!(
                "--order: p and d must be at least 1 (got p = {}, d = {})",
                self.p, self.d
            ));
        }
        if self.p > 6 || self.q > 6 || self.d > 1000 {
            return bad(format!(
                "--order: p, q at most 6 and d at most 1000 (got {},{},{})",
                self.p, self.q, self.d
            ));
        }
        if self.grid_size < 3 || self.grid_size > MAX_GRID {
            return bad(format!(
                "--grid: 3 to {MAX_GRID} points (got {}; a few hundred resolve the coefficient functions, and the GCV ladder's cost grows with the square of the grid)",
                self.grid_size
            ));
        }
        if self.tol.is_infinite() {
            return bad("--tol must be finite".into());
        }
        let (lo, hi) = self.grid_quantiles;
        if !(0.0..0.5).contains(&lo) || !(0.5..=1.0).contains(&hi) {
            return bad(format!(
                "grid quantiles ({lo}, {hi}) must satisfy 0 <= lo < 0.5 <= hi <= 1"
            ));
        }
        if let Some(h) = self.bandwidth
            && !(h.is_finite() && h > 0.0)
        {
            return bad(format!("--bandwidth: {h} is not a positive number"));
        }
        if self.tol.is_nan() || self.tol <= 0.0 || self.max_iter == 0 {
            return bad("--tol must be positive and --max-iter at least 1".into());
        }
        let pp = self.p.max(self.q).max(self.d);
        let need = (20 * (2 * self.p + self.q) + pp + 1).max(100);
        if n < need {
            return Err(Error::TooShort {
                what: format!("FARMA({},{},{}) fit", self.p, self.q, self.d),
                need: need as u64,
                have: n as u64,
            });
        }
        Ok(ValidParams(self))
    }
}

impl ValidParams {
    pub fn params(&self) -> &FarmaParams {
        &self.0
    }
}

/// The largest magnitudes of a channel's centred values that a fast-path fit
/// (`FitPath::Fast`) accepts: its moment tables carry the local systems' entries as
/// sums of products of up to the 8th power of the values (x_a x_b (U - u_g)^k, shifted
/// between centres by the binomial theorem), which overflow or lose their digits to
/// underflow far enough from 1. The direct path (a KD-tree gather and a dense solve
/// per grid point, squares of the values at most) reaches further,
/// [`DIRECT_MAGNITUDE_LIMITS`]: the same fit at k = -55, -45, 40 and 60 below.
/// Measured (`farma fit --order 2,1,1` on a Gaussian series of 5,000 samples
/// scaled by 10^k, its largest magnitude 3.9 10^k): the same b to 4e-12 relative and
/// sigma^2 / 10^2k, trace and GCV / 10^2k to 1e-14 for k = -35, -30, -20, -10, 0, 10,
/// 20, 25, 30, 35; at k = -40 the trace off by 2e-9;
/// at k = -45 127 of 201 grid points without a local fit; at k = -50 the linear start
/// returned; at k = 40 and -55 no local fit at all. The limits keep 5 orders of
/// margin (sums over up to 1e10 samples).
pub const MAGNITUDE_LIMITS: (f64, f64) = (1e-30, 1e30);

/// The largest magnitudes of a channel's centred values that a direct-path fit
/// (`FitPath::Direct`, and the 2-D index's fit) accepts: its sums are of squares of
/// the values (the linear start's normal equations, the local systems, the RSS), which
/// leave f64's range near 1e+-154 for one value, less the log10 of the number of
/// samples. Measured (`farma fit --order 2,1,1 --method direct --grid 31` on an
/// ARMA(1,1) series of 3,000 samples scaled by 10^k, 2026-11-26): the same b, trace
/// and sigma^2 / 10^2k for k = -150, -140, -100, -60, 60, 100, 140, 150; at k = 155,
/// 160 .. 190 and -160 .. -190 the linear start fails (its sums overflow, or underflow
/// to zero), and at k = -155 sigma^2 is subnormal. The limits keep sums over up to
/// 1e10 samples inside f64's normal range.
pub const DIRECT_MAGNITUDE_LIMITS: (f64, f64) = (1e-140, 1e140);

/// Refuses values (centred, from `lo` to `hi`) when their largest magnitude is
/// outside the limits of `path` ([`MAGNITUDE_LIMITS`] for the fast path,
/// [`DIRECT_MAGNITUDE_LIMITS`] for the direct one), naming `what` and the power of ten
/// to rescale by.
pub fn check_magnitude(
    what: &str,
    lo: f64,
    hi: f64,
    path: FitPath,
) -> std::result::Result<(), String> {
    let (min, max) = match path {
        FitPath::Fast => MAGNITUDE_LIMITS,
        FitPath::Direct => DIRECT_MAGNITUDE_LIMITS,
    };
    let mag = lo.abs().max(hi.abs());
    if (min..=max).contains(&mag) {
        return Ok(());
    }
    let (verb, after, spike) = if mag > max {
        (
            "reaches",
            "",
            "; a single spike: `farma prep` removes outliers",
        )
    } else {
        ("reaches only", " after removing the mean", "")
    };
    let (dmin, dmax) = DIRECT_MAGNITUDE_LIMITS;
    let why = match path {
        FitPath::Fast if (dmin..=dmax).contains(&mag) => format!(
            "the fast path's moment tables sum products of up to the 8th power of the values, which leave f64's range outside {min:.0e}..{max:.0e} in magnitude"
        ),
        FitPath::Fast => format!(
            "the fast path's moment tables sum products of up to the 8th power of the values, which leave f64's range outside {min:.0e}..{max:.0e} in magnitude, and the direct path's sums of squares outside {dmin:.0e}..{dmax:.0e}"
        ),
        FitPath::Direct => format!(
            "the fit's sums of squares of the values leave f64's range outside {min:.0e}..{max:.0e} in magnitude"
        ),
    };
    let direct = if path == FitPath::Fast && (dmin..=dmax).contains(&mag) {
        format!(", or fit with `--method direct` (slower; it takes {dmin:.0e}..{dmax:.0e})")
    } else {
        String::new()
    };
    Err(format!(
        "{what} {verb} {mag:.3e} in magnitude{after}: {why}; express it in other units (scaled by about 1e{}){spike}{direct}",
        -mag.log10().round() as i64
    ))
}
