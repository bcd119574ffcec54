//! The time column: nominal sampling interval, and the intervals that break it.
//!
//! The nominal interval `dt` is the median of the intervals (of an even stride of at
//! most 100,000 of them on long logs). An interval `d` is regular when
//! `|d - dt| <= tol * dt`; `d <= 0` is always an error (a timestamp that goes back or
//! repeats); `d > 1.5 dt` is reported as a gap of `round(d / dt) - 1` missing samples.

use crate::error::Error;
use crate::store::Segment;

/// At most this many segments under `--gaps split`.
const MAX_SEGMENTS: usize = 100_000;

/// Result of checking a time column.
#[derive(Clone, Debug)]
pub(crate) struct TimeCheck {
    /// Nominal interval, seconds.
    pub dt_s: f64,
    /// Number of irregular intervals.
    pub irregular_count: u64,
    /// The first few irregular intervals: (row after the interval, interval length).
    pub first_irregular: Vec<(usize, f64)>,
    /// Number of gaps (irregular intervals longer than 1.5 dt) and missing samples.
    pub gaps: u64,
    pub missing_samples: u64,
    /// Largest interval: (row after it, its length).
    pub largest: (usize, f64),
    tol: f64,
}

/// A timestamp problem no policy repairs.
pub(crate) enum TimeProblem {
    Backwards(usize, f64, f64),
    Duplicate(usize, f64),
    ZeroSpan,
}

impl TimeProblem {
    pub fn into_error(
        self,
        path: &std::path::Path,
        col: &str,
        locate: &dyn Fn(u64) -> String,
    ) -> Error {
        let msg = match self {
            TimeProblem::Backwards(r, prev, t) => format!(
                "time column '{col}' is not increasing: {} has {t} after {prev}",
                locate(r as u64)
            ),
            TimeProblem::Duplicate(r, t) => format!(
                "time column '{col}' repeats the timestamp {t} at {} (duplicated row?)",
                locate(r as u64)
            ),
            TimeProblem::ZeroSpan => format!("time column '{col}' does not advance"),
        };
        Error::timestamps(path, msg)
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    *m
}

/// Checks `t` (finite, at least two values).
pub(crate) fn check_times(t: &[f64], tol: f64) -> Result<TimeCheck, TimeProblem> {
    let n = t.len();
    for i in 1..n {
        let d = t[i] - t[i - 1];
        if d < 0.0 {
            return Err(TimeProblem::Backwards(i, t[i - 1], t[i]));
        }
        if d == 0.0 {
            return Err(TimeProblem::Duplicate(i, t[i]));
        }
    }
    let stride = ((n - 1) / 100_000).max(1);
    let sample: Vec<f64> = (1..n).step_by(stride).map(|i| t[i] - t[i - 1]).collect();
    let dt = median(sample);
    if dt.is_nan() || dt <= 0.0 {
        return Err(TimeProblem::ZeroSpan);
    }
    let mut c = TimeCheck {
        dt_s: dt,
        irregular_count: 0,
        first_irregular: Vec::new(),
        gaps: 0,
        missing_samples: 0,
        largest: (1, t[1] - t[0]),
        tol,
    };
    for i in 1..n {
        let d = t[i] - t[i - 1];
        if d > c.largest.1 {
            c.largest = (i, d);
        }
        if (d - dt).abs() > tol * dt {
            c.irregular_count += 1;
            if c.first_irregular.len() < 5 {
                c.first_irregular.push((i, d));
            }
            if d > 1.5 * dt {
                c.gaps += 1;
                c.missing_samples += ((d / dt).round() as u64).saturating_sub(1);
            }
        }
    }
    Ok(c)
}

impl TimeCheck {
    /// Rate of a regular column: (n - 1) / (t_last - t_first).
    pub fn rate_hz_regular(&self, t: &[f64]) -> f64 {
        (t.len() - 1) as f64 / (t[t.len() - 1] - t[0])
    }

    fn is_regular(&self, d: f64) -> bool {
        (d - self.dt_s).abs() <= self.tol * self.dt_s
    }

    /// One line: counts, gaps, the first irregular intervals, the largest.
    pub fn describe(&self, locate: &dyn Fn(u64) -> String) -> String {
        let first: Vec<String> = self
            .first_irregular
            .iter()
            .map(|(r, d)| format!("{} ({d} s)", locate(*r as u64)))
            .collect();
        format!(
            "nominal interval {} s; {} irregular interval(s), {} gap(s) with about {} missing sample(s); first at {}; largest {} s at {}",
            self.dt_s,
            self.irregular_count,
            self.gaps,
            self.missing_samples,
            first.join(", "),
            self.largest.1,
            locate(self.largest.0 as u64)
        )
    }

    /// Uniform segments between irregular intervals.
    pub fn segments(&self, t: &[f64]) -> Result<Vec<Segment>, String> {
        let mut segs = Vec::new();
        let mut start = 0usize;
        for i in 1..t.len() {
            if !self.is_regular(t[i] - t[i - 1]) {
                segs.push(Segment {
                    start: start as u64,
                    len: (i - start) as u64,
                    t0_s: t[start],
                });
                start = i;
                if segs.len() >= MAX_SEGMENTS {
                    return Err(format!(
                        "more than {MAX_SEGMENTS} segments: the sampling is irregular throughout; use --gaps interpolate or a wider --time-tol"
                    ));
                }
            }
        }
        segs.push(Segment {
            start: start as u64,
            len: (t.len() - start) as u64,
            t0_s: t[start],
        });
        Ok(segs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_jittered_gap_and_errors() {
        let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
        let c = check_times(&t, 0.05).ok().unwrap();
        assert_eq!(c.irregular_count, 0);
        assert!((c.rate_hz_regular(&t) - 10.0).abs() < 1e-9);

        let mut g = t.clone();
        for v in g.iter_mut().skip(50) {
            *v += 0.3; // three samples missing after row 49
        }
        let c = check_times(&g, 0.05).ok().unwrap();
        assert_eq!((c.irregular_count, c.gaps, c.missing_samples), (1, 1, 3));
        let segs = c.segments(&g).unwrap();
        assert_eq!(segs.len(), 2);
        assert_eq!((segs[1].start, segs[1].len), (50, 50));

        let mut d = t.clone();
        d[10] = d[9];
        assert!(matches!(
            check_times(&d, 0.05),
            Err(TimeProblem::Duplicate(10, _))
        ));
        let mut b = t.clone();
        b[10] = 0.5;
        assert!(matches!(
            check_times(&b, 0.05),
            Err(TimeProblem::Backwards(10, _, _))
        ));
    }
}
