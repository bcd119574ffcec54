//! Preparing a channel as the paper does before modelling: Pauta outlier rejection,
//! the reverse-arrangement stationarity test, trend removal or differencing when the
//! test rejects, and mean removal; every step recorded.
//!
//! Order of the steps, per channel:
//! 1. Pauta (3-sigma, iterated; [`super::pauta`]), rejected samples replaced;
//! 2. reverse-arrangement test on the cleaned series ([`super::stationarity`]);
//! 3. if p <= alpha ([`super::rejects`]): `trend` removes the least-squares line
//!    a + b t (default; the length stays), `diff` takes first differences (one sample
//!    shorter), `none` only records the rejection; then the test again on the result;
//! 4. the mean is subtracted (recorded, `keep_mean` skips it).

use super::pauta::{Replace, Replacement, pauta};
use super::stationarity::{ReverseArrangement, SegmentStat, reverse_arrangement_series};

/// What to do when the stationarity test rejects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Nonstationary {
    /// Remove the least-squares linear trend.
    Trend,
    /// First differences x_t - x_{t-1}.
    Diff,
    /// Record the rejection, change nothing.
    None,
}

/// Parameters of the preparation.
#[derive(Clone, Debug)]
pub struct PrepParams {
    /// Pauta threshold in standard deviations.
    pub sigma_c: f64,
    pub replace: Replace,
    pub max_passes: usize,
    /// Segments of the reverse-arrangement test.
    pub segments: usize,
    pub segment_stat: SegmentStat,
    /// Level of the stationarity test.
    pub alpha: f64,
    pub nonstationary: Nonstationary,
    /// Keep the mean (default: subtract it).
    pub keep_mean: bool,
}

impl Default for PrepParams {
    fn default() -> Self {
        PrepParams {
            sigma_c: 3.0,
            replace: Replace::Interpolate,
            max_passes: 100,
            segments: 20,
            segment_stat: SegmentStat::Mean,
            alpha: super::ALPHA,
            nonstationary: Nonstationary::Trend,
            keep_mean: false,
        }
    }
}

impl PrepParams {
    /// Checks the parameters against a series of `n` samples.
    pub fn validate(&self, n: usize) -> crate::Result<()> {
        let bad = |m: String| Err(crate::Error::Usage(m));
        if !(self.sigma_c.is_finite() && self.sigma_c > 0.0) {
            return bad(format!(
                "--sigma: {} is not a positive number",
                self.sigma_c
            ));
        }
        if self.segments < 3 {
            return bad(format!("--segments: at least 3 (got {})", self.segments));
        }
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return bad(format!("--alpha: {} is not in (0, 1)", self.alpha));
        }
        if n < 2 * self.segments.max(10) {
            return Err(crate::Error::TooShort {
                what: format!("preparation with {} segments", self.segments),
                need: 2 * self.segments.max(10) as u64,
                have: n as u64,
            });
        }
        Ok(())
    }
}

/// One recorded step.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// `pauta`, `stationarity`, `detrend`, `difference`, `stationarity_after`,
    /// `mean_removal`, `row_dropped`.
    pub step: String,
    /// Samples affected (replaced, dropped), where it applies.
    pub count: Option<u64>,
    pub statistic: Option<f64>,
    pub z: Option<f64>,
    pub p_value: Option<f64>,
    /// A value the step removed (the mean; the trend's slope per sample).
    pub value: Option<f64>,
    pub detail: String,
}

impl Step {
    fn new(step: &str, detail: String) -> Step {
        Step {
            step: step.into(),
            count: None,
            statistic: None,
            z: None,
            p_value: None,
            value: None,
            detail,
        }
    }
}

/// A prepared channel.
#[derive(Clone, Debug)]
pub struct ChannelPrep {
    pub name: String,
    /// The prepared series (one shorter than the input after differencing).
    pub values: Vec<f64>,
    pub replaced: Vec<Replacement>,
    pub before: ReverseArrangement,
    pub after: Option<ReverseArrangement>,
    pub differenced: bool,
    pub steps: Vec<Step>,
}

impl ChannelPrep {
    /// Whether the series that leaves preparation passed the stationarity test.
    pub fn stationary(&self, alpha: f64) -> bool {
        !super::rejects(self.after.as_ref().unwrap_or(&self.before).p_value, alpha)
    }
}

fn ra_step(step: &str, r: &ReverseArrangement, alpha: f64, stat: SegmentStat) -> Step {
    let verdict = if super::rejects(r.p_value, alpha) {
        "rejects stationarity"
    } else {
        "does not reject stationarity"
    };
    Step {
        count: Some(r.segments as u64),
        statistic: Some(r.statistic as f64),
        z: Some(r.z),
        p_value: Some(r.p_value),
        ..Step::new(
            step,
            format!(
                "reverse arrangements of {} segment {}s: A = {} (E = {}, sd = {:.3}), {verdict} at {alpha}",
                r.segments,
                stat.as_str(),
                r.statistic,
                r.mean,
                r.variance.sqrt()
            ),
        )
    }
}

/// Prepares one channel.
pub fn prep_channel(name: &str, x: &[f64], prm: &PrepParams) -> ChannelPrep {
    let mut steps = Vec::new();
    let pa = pauta(x, prm.sigma_c, prm.replace, prm.max_passes);
    steps.push(Step {
        count: Some(pa.replaced.len() as u64),
        value: Some(pa.std),
        ..Step::new(
            "pauta",
            format!(
                "{} sample(s) beyond {} sigma rejected in {} pass(es) (final mean {:.6e}, std {:.6e}), replaced by {}",
                pa.replaced.len(),
                prm.sigma_c,
                pa.passes,
                pa.mean,
                pa.std,
                prm.replace.as_str()
            ),
        )
    });
    let mut v = pa.cleaned;
    let before = reverse_arrangement_series(&v, prm.segments, prm.segment_stat);
    steps.push(ra_step(
        "stationarity",
        &before,
        prm.alpha,
        prm.segment_stat,
    ));
    let mut after = None;
    let mut differenced = false;
    if super::rejects(before.p_value, prm.alpha) && prm.nonstationary != Nonstationary::None {
        match prm.nonstationary {
            Nonstationary::Trend => {
                // least squares of v on (1, t), t centred
                let n = v.len() as f64;
                let tc = (n - 1.0) / 2.0;
                let mv = v.iter().sum::<f64>() / n;
                let (mut sxy, mut sxx) = (0.0, 0.0);
                for (t, y) in v.iter().enumerate() {
                    let dt = t as f64 - tc;
                    sxy += dt * (y - mv);
                    sxx += dt * dt;
                }
                let slope = sxy / sxx;
                for (t, y) in v.iter_mut().enumerate() {
                    *y -= slope * (t as f64 - tc);
                }
                steps.push(Step {
                    count: Some(v.len() as u64),
                    value: Some(slope),
                    ..Step::new(
                        "detrend",
                        format!("least-squares linear trend removed: slope {slope:.6e} per sample"),
                    )
                });
            }
            Nonstationary::Diff => {
                v = v.windows(2).map(|w| w[1] - w[0]).collect();
                differenced = true;
                steps.push(Step {
                    count: Some(1),
                    ..Step::new(
                        "difference",
                        "first differences x_t - x_(t-1): one sample shorter".into(),
                    )
                });
            }
            Nonstationary::None => unreachable!(),
        }
        let r = reverse_arrangement_series(&v, prm.segments, prm.segment_stat);
        steps.push(ra_step(
            "stationarity_after",
            &r,
            prm.alpha,
            prm.segment_stat,
        ));
        after = Some(r);
    } else if super::rejects(before.p_value, prm.alpha) {
        steps.push(Step::new(
            "nonstationary_kept",
            "stationarity rejected; --nonstationary none: series kept as it is".into(),
        ));
    }
    if !prm.keep_mean {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        v.iter_mut().for_each(|y| *y -= m);
        steps.push(Step {
            count: Some(v.len() as u64),
            value: Some(m),
            ..Step::new("mean_removal", format!("mean {m:.6e} subtracted"))
        });
    }
    ChannelPrep {
        name: name.to_string(),
        values: v,
        replaced: pa.replaced,
        before,
        after,
        differenced,
        steps,
    }
}

/// Brings prepared channels to a common length: when any was differenced, the others
/// lose their first sample too (recorded), so the rows keep one time base.
/// Returns the number of rows dropped at the start (0 or 1).
pub fn align(channels: &mut [ChannelPrep]) -> usize {
    if !channels.iter().any(|c| c.differenced) {
        return 0;
    }
    for c in channels.iter_mut().filter(|c| !c.differenced) {
        c.values.remove(0);
        c.steps.push(Step {
            count: Some(1),
            ..Step::new(
                "row_dropped",
                "first sample dropped to keep the rows aligned with a differenced channel".into(),
            )
        });
    }
    1
}
