//! The parameters of a fit, checked once ([`FarmaParams::validate`]; on a 2-D index
//! [`Farma2Params`], [`check_fit2`]), and the magnitudes of the values each path can
//! take.

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
    /// GCV may choose the ladder's limit h -> infinity, the global fit with f_m linear
    /// in the index (`fit::global`). Off for a fit whose online state is kept
    /// (`farma fit --save-state`): the state holds kernel windows of a finite h.
    pub bandwidth_limit: bool,
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
            bandwidth_limit: true,
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

/// The most grid points (G1 x G2) of a 2-D index. Every rung of the GCV ladders
/// keeps its local fits (an inverse 3p x 3p system per point: 2.6 kB at p = 6) and
/// gathers every point's support, so memory and time grow with G1 x G2: 200 x 200
/// is about 100 MB per rung at p = 6, and 100,000 x 100,000 would have the allocator
/// abort the process.
pub const MAX_GRID2_POINTS: usize = 40_000;

/// `--index-grid N1,N2`: at least 3 points per coordinate and at most
/// [`MAX_GRID2_POINTS`] in all (a usage error, before any work).
pub fn check_grid2((g1, g2): (usize, usize)) -> Result<()> {
    if g1 < 3 || g2 < 3 {
        return Err(Error::Usage(format!(
            "--index-grid: at least 3 points per coordinate (got {g1},{g2})"
        )));
    }
    match g1.checked_mul(g2) {
        Some(g) if g <= MAX_GRID2_POINTS => Ok(()),
        _ => Err(Error::Usage(format!(
            "--index-grid {g1},{g2}: at most {MAX_GRID2_POINTS} grid points in all (G1 x G2, e.g. 200,200; the default 21,21 has 441): every rung of the GCV ladders keeps a local fit per point and gathers its support, so memory and time grow with G1 x G2"
        ))),
    }
}

/// Parameters of a fit with a 2-D index.
#[derive(Clone, Debug)]
pub struct Farma2Params {
    /// p, q, d, tolerances, demeaning, grid quantiles (grid_size and bandwidth unused).
    pub base: FarmaParams,
    /// The second index channel's name (the model records it).
    pub index2: String,
    /// Lag of the second index channel.
    pub d2: usize,
    /// Grid points per coordinate (G1, G2).
    pub grid: (usize, usize),
    /// A fixed bandwidth pair instead of GCV.
    pub bandwidth: Option<(f64, f64)>,
}

pub(super) fn range_of(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        })
}

/// The checks of a 2-D fit of `n` samples on the index channel `z` that do not depend
/// on the fitted channel: the index lag, the grid and the bandwidths, the length, and
/// the index channel (finite, not constant). [`super::smoother2::fit2`] makes them; a run over several
/// channels makes them once before, so that such a problem is said once, not once per
/// channel.
pub fn check_fit2(n: usize, z: &[f64], params: &Farma2Params) -> Result<()> {
    let prm = &params.base;
    let (p, q, d, d2) = (prm.p, prm.q, prm.d, params.d2);
    let bad = |m: String| Err(Error::Usage(m));
    if d2 > 1000 {
        return bad(format!("--index-lag: at most 1000 (got {d2})"));
    }
    check_grid2(params.grid)?;
    if let Some((a, b)) = params.bandwidth
        && !(a.is_finite() && a > 0.0 && b.is_finite() && b > 0.0)
    {
        return bad(format!(
            "--bandwidth: ({a}, {b}) is not a pair of positive numbers"
        ));
    }
    let pp = p.max(q).max(d).max(d2);
    let need = (20 * (3 * p + q) + pp + 1).max(100);
    if n < need {
        return Err(Error::TooShort {
            what: format!("FARMA({p},{q},{d}) fit with a 2-D index"),
            need: need as u64,
            have: n as u64,
        });
    }
    if z.iter().any(|v| !v.is_finite()) {
        return bad("the index channel holds NaN or infinite values".into());
    }
    let (z_lo, z_hi) = range_of(z);
    if z_hi - z_lo <= 0.0 {
        return bad("the index channel is constant: it cannot index anything".into());
    }
    Ok(())
}
