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
