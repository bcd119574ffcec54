//! The sensor's output path as a stage of the diagnosis's ensemble: each replica keeps
//! the pre-path sum of its components (everything but `output_filter`, `saturation`
//! and `output_resolution`), and its output is that sum passed through the path, in
//! the simulator's order filter -> saturation -> resolution
//! ([`crate::simulator::generate::output`], exactly what `farma simulate` applies).
//!
//! A candidate of the output path changes the path, not the sum: it is scored by
//! passing every replica's sum through the path with the candidate in it, and taking
//! it back is taking its component out of the path. The path is a function of the
//! channel's components alone ([`PathStage::of`]), so adding and taking back restore
//! it exactly.

use crate::simulator::Component;
use crate::simulator::generate::output::OutputPath;

/// The output-path components of the diagnosed channel, applied to a replica's sum.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PathStage {
    comps: Vec<Component>,
    rate_hz: f64,
}

impl PathStage {
    /// The path of a channel with `components`, sampled at `rate_hz`.
    pub fn of(components: &[Component], rate_hz: f64) -> Self {
        PathStage {
            comps: components
                .iter()
                .filter(|c| c.kind().is_output_path())
                .cloned()
                .collect(),
            rate_hz,
        }
    }

    /// The path of `components` without component `skip` (an index in `components`).
    pub fn without(components: &[Component], skip: usize, rate_hz: f64) -> Self {
        let rest: Vec<Component> = components
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != skip)
            .map(|(_, c)| c.clone())
            .collect();
        PathStage::of(&rest, rate_hz)
    }

    /// This path with `c` (an output-path component) in it, in place of a component of
    /// the same kind if it has one.
    pub fn with(&self, c: &Component) -> Self {
        let mut comps: Vec<Component> = self
            .comps
            .iter()
            .filter(|o| o.kind() != c.kind())
            .cloned()
            .collect();
        comps.push(c.clone());
        PathStage {
            comps,
            rate_hz: self.rate_hz,
        }
    }

    /// No stage: a replica's output is its sum.
    pub fn is_empty(&self) -> bool {
        self.comps.is_empty()
    }

    /// The sample rate the path runs at, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// The components of the path.
    pub fn components(&self) -> &[Component] {
        &self.comps
    }

    /// Passes the whole series `x` (a replica's sum) through the path, in place, from
    /// a fresh state (the filter at rest, no carried rounding error), as the simulator
    /// does from the first sample.
    pub fn apply(&self, x: &mut [f64]) {
        if !self.comps.is_empty() {
            OutputPath::of(&self.comps, self.rate_hz, None).apply(x);
        }
    }
}

/// A replica's output as the features of one part read it: the sum `x`, plus
/// `coef * d` when a change `(d, coef)` is given, through `path`, rounded to the
/// printed precision `printed` when there is one, on the samples of `ranges` only
/// (everything the part's features read; see [`super::features`]). Through a path the
/// prefix up to the end of the last range is passed (every stage is causal: a sample
/// depends on the samples before it only), without one the ranges alone. `buf` is the
/// scratch the series is built in, grown to `x.len()` once and reused: the samples
/// outside what is built are left as they were. Returns `x` itself when nothing
/// changes it. [`whole_output`] is its slow twin.
pub fn part_output<'a>(
    x: &'a [f64],
    change: Option<(&[f64], f64)>,
    path: &PathStage,
    printed: Option<f64>,
    ranges: &[std::ops::Range<usize>],
    buf: &'a mut Vec<f64>,
) -> &'a [f64] {
    if change.is_none() && printed.is_none() && path.is_empty() {
        return x;
    }
    if buf.len() < x.len() {
        buf.resize(x.len(), 0.0);
    }
    let fill = |buf: &mut [f64], r: std::ops::Range<usize>| match change {
        Some((d, coef)) => {
            for ((y, a), b) in buf[r.clone()].iter_mut().zip(&x[r.clone()]).zip(&d[r]) {
                *y = a + coef * b;
            }
        }
        None => buf[r.clone()].copy_from_slice(&x[r]),
    };
    let round = |buf: &mut [f64], r: std::ops::Range<usize>| {
        if let Some(step) = printed {
            super::features::round_in_place(&mut buf[r], step);
        }
    };
    if path.is_empty() {
        for r in ranges {
            fill(buf, r.clone());
            round(buf, r.clone());
        }
    } else {
        let end = ranges.iter().map(|r| r.end).max().unwrap_or(0);
        fill(buf, 0..end);
        path.apply(&mut buf[..end]);
        round(buf, 0..end);
    }
    &buf[..x.len()]
}

/// The whole output series of [`part_output`]: `x + coef * d` over every sample,
/// through the whole path, rounded.
pub fn whole_output(
    x: &[f64],
    change: Option<(&[f64], f64)>,
    path: &PathStage,
    printed: Option<f64>,
) -> Vec<f64> {
    let mut y: Vec<f64> = match change {
        Some((d, coef)) => x.iter().zip(d).map(|(a, b)| a + coef * b).collect(),
        None => x.to_vec(),
    };
    path.apply(&mut y);
    if let Some(step) = printed {
        super::features::round_in_place(&mut y, step);
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filter(bw: f64) -> Component {
        Component::OutputFilter {
            order: 1,
            bandwidth_hz: bw,
            damping: None,
            discretization: Default::default(),
        }
    }

    #[test]
    fn with_replaces_a_same_kind_stage_and_without_drops_one() {
        let comps = vec![
            Component::WhiteNoise { n: 1.0 },
            filter(3.0),
            Component::Saturation { limit: 2.0 },
        ];
        let p = PathStage::of(&comps, 100.0);
        assert_eq!(p.components().len(), 2);
        let q = p.with(&filter(5.0));
        assert_eq!(q.components().len(), 2);
        assert!(q.components().contains(&filter(5.0)));
        assert!(!q.components().contains(&filter(3.0)));
        let r = PathStage::without(&comps, 1, 100.0);
        assert_eq!(r.components(), &[Component::Saturation { limit: 2.0 }]);
        assert!(PathStage::without(&comps, 0, 100.0) == p);
        assert!(PathStage::of(&comps[..1], 100.0).is_empty());
    }

    #[test]
    fn a_parts_features_of_its_own_samples_are_those_of_the_whole_output() {
        use crate::diagnosis::blocks::Blocks;
        use crate::diagnosis::features::{Layout, Temperature};
        let n = 20_000;
        let rate_hz = 10.0;
        let x: Vec<f64> = (0..n)
            .map(|k| (k as f64 * 0.37).sin() * 0.8 + (k as f64 * 0.0011).cos())
            .collect();
        let d: Vec<f64> = (0..n).map(|k| ((k * 7919) % 101) as f64 * 1e-3).collect();
        let t_c: Vec<f64> = (0..n)
            .map(|k| 20.0 + 5.0 * (k as f64 * 1e-4).sin())
            .collect();
        let other: Vec<f64> = (0..n).map(|k| (k as f64 * 0.05).cos()).collect();
        let temperature = Temperature::new(t_c, rate_hz);
        let blocks = Blocks::interleaved(n, 6, 0.5).unwrap();
        let names = vec!["other".to_string()];
        let paths = [
            PathStage::default(),
            PathStage::of(
                &[
                    filter(0.8),
                    Component::OutputResolution {
                        quantum: 0.01,
                        on_angle: true,
                    },
                ],
                rate_hz,
            ),
        ];
        let mut buf = Vec::new();
        for training in [false, true] {
            let layout = Layout::new(&blocks, training, rate_hz, Some(&temperature), &names);
            let sides = layout.others(&[&other]);
            for path in &paths {
                for change in [None, Some((d.as_slice(), 1.0)), Some((d.as_slice(), -1.0))] {
                    for printed in [None, Some(1e-3)] {
                        let whole = whole_output(&x, change, path, printed);
                        let want = layout.compute_with(&whole, Some(&temperature), &sides);
                        // the scratch holds the previous series outside the ranges
                        let y = part_output(&x, change, path, printed, layout.ranges(), &mut buf);
                        let got = layout.compute_with(y, Some(&temperature), &sides);
                        let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                        assert_eq!(
                            bits(&got),
                            bits(&want),
                            "{training} {path:?} {change:?} {printed:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_path_is_the_simulators_on_a_whole_series() {
        let comps = vec![
            filter(4.0),
            Component::OutputResolution {
                quantum: 0.1,
                on_angle: true,
            },
        ];
        let x0: Vec<f64> = (0..5000).map(|k| (k as f64 * 0.37).sin() * 0.8).collect();
        let mut a = x0.clone();
        PathStage::of(&comps, 100.0).apply(&mut a);
        let mut b = x0;
        OutputPath::of(&comps, 100.0, None).apply(&mut b);
        assert!(a == b);
    }
}
