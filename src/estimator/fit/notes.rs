//! The notes a fit gives its user: a bandwidth not re-checked, an MA part near the edge
//! of invertibility, an outlier that stretches the ladder, missing standard errors, an
//! undefined trace.

use crate::estimator::arma::ma_root_modulus;
use crate::estimator::problem::PointStatus;

/// Above this modulus of the MA part's largest root ([`ma_root_modulus`]), 0.99,
/// [`ma_edge_note`] says that b is near the edge of invertibility. Measured
/// (2026-11-26, FARMA(2,1,1)): differenced white noise (true b_1 = -1) gave b_1 =
/// -0.9947 and -0.9869 on 4,000 samples (two series: a short one can stay below the
/// edge), below -0.99 on 20,000 (tests/suite/estimator_recovery.rs); a step in a constant
/// channel -0.99999999939.
pub const MA_EDGE: f64 = 0.99;

/// The note of a fit whose RSS settled at a bandwidth GCV had re-selected twice, the
/// most the alternation makes: GCV is not run again at the final residuals, so the
/// bandwidth is not confirmed there, and a choice that swung back to one it had left
/// says so. `chosen` holds the bandwidths GCV chose in order (its last is the model's),
/// `fmt` writes one (a pair for the 2-D index).
pub fn reselection_limit_note<H: PartialEq + Copy>(
    iterations: usize,
    chosen: &[H],
    fmt: impl Fn(H) -> String,
) -> String {
    let (at, swung) = match chosen.split_last() {
        Some((last, before)) => (format!(" {}", fmt(*last)), before.contains(last)),
        None => (String::new(), false),
    };
    format!(
        "alternation {iterations}: the RSS settled at bandwidth{at}, GCV's second re-selection ({}); GCV is not run a third time at these residuals, so it may prefer another bandwidth there{}; a fixed --bandwidth settles the choice",
        chosen
            .iter()
            .map(|h| fmt(*h))
            .collect::<Vec<_>>()
            .join(" -> "),
        if swung {
            ", and it had swung back to a bandwidth it left before"
        } else {
            ""
        }
    )
}

/// A note when the MA part `b` is near the edge of invertibility (its largest root's
/// modulus above [`MA_EDGE`]): what an over-differenced channel (differencing white
/// noise gives b_1 = -1), or a step or trend left in it, gives. None otherwise.
pub fn ma_edge_note(b: &[f64]) -> Option<String> {
    let modulus = ma_root_modulus(b);
    (modulus > MA_EDGE).then(|| {
        format!(
            "the MA part b = {b:?} is near the edge of invertibility (its largest root has modulus {modulus:.10}, 1 - {:.1e}): an over-differenced channel (differencing white noise gives b_1 = -1), or a step or trend that removing the mean leaves; `farma prep` tests stationarity and differences or detrends only where needed",
            1.0 - modulus
        )
    })
}

/// Above this ratio of an index's span (max - min) to the spread of its central
/// values (the grid's quantiles), [`stretched_ladder_note`] says that an outlier
/// stretches the bandwidth ladder. Ratios without outliers, measured with numpy
/// (2026-11-26, span over the 1 %-99 % quantile range, one draw each): Gaussian 2.12
/// at 1e6 samples and 2.24 at 1e7, Laplace 3.40 and 3.79, uniform 1.02; the gyro
/// channels of the real ADIS16405 static runs 1.8-2.2 (and 5.3 and 17.8 in the run
/// with a bump of -17 deg/s, README).
pub const STRETCH_RATIO: f64 = 10.0;

/// A note when the span `lo..hi` of an index (named by `what`) is more than
/// [`STRETCH_RATIO`] times the spread of its central values `qlo..qhi` (quantiles
/// `qs`): the ladder h_j = 1.1^-j span/2 then starts far above the bandwidths the data
/// can use, and GCV may end at a bandwidth wider than the central values' spread; an
/// outlier, which `farma prep` removes. None otherwise.
pub fn stretched_ladder_note(
    what: &str,
    (lo, hi): (f64, f64),
    (qlo, qhi): (f64, f64),
    qs: (f64, f64),
) -> Option<String> {
    let ratio = (hi - lo) / (qhi - qlo);
    (ratio > STRETCH_RATIO).then(|| {
        format!(
            "{what} span {:.6e} (from {lo:.6e} to {hi:.6e}), {ratio:.0} times the spread of their central values (quantiles {} to {}: {qlo:.6e} to {qhi:.6e}): an outlier? It stretches the bandwidth ladder, which starts at half the span; `farma prep` removes outliers",
            hi - lo,
            qs.0,
            qs.1
        )
    })
}

/// A note on the grid points with a local fit (`status` Ok) but no standard error
/// (`se` NaN: [`crate::estimator::moments::sandwich_diag`]), naming how many and the largest
/// condition number among them; None when there are none. `se` and `cond` as the
/// coefficient table's: p values per grid point, one condition number per point.
pub fn missing_se_note(
    status: &[PointStatus],
    cond: &[f64],
    se: &[f64],
    p: usize,
) -> Option<String> {
    let missing: Vec<usize> = (0..status.len())
        .filter(|&g| {
            status[g] == PointStatus::Ok && se[g * p..(g + 1) * p].iter().any(|v| v.is_nan())
        })
        .collect();
    if missing.is_empty() {
        return None;
    }
    let worst = missing.iter().map(|&g| cond[g]).fold(0.0f64, f64::max);
    Some(format!(
        "{} fitted grid point(s) have no standard error (se NaN): their local systems (condition number up to {worst:.1e}) are too ill-conditioned for the sandwich form, which squares it",
        missing.len()
    ))
}

/// The note of a model whose trace and GCV are not defined: grid points without a
/// local fit (`status`) at the bandwidth(s) `at`.
pub fn undefined_trace_note(status: &[PointStatus], at: &str) -> String {
    let failed = status.iter().filter(|s| **s != PointStatus::Ok).count();
    format!(
        "trace and GCV not defined: {failed} grid point(s) have no local fit at {at} (see status)"
    )
}
