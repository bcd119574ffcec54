//! The simulation ensemble of a spec on a real log's time base, kept component by
//! component so that a candidate effect is scored by adding one more signal to a
//! cached sum (nothing that does not change is simulated or summed again).
//!
//! Replica r of the ensemble is replica r of the spec's seed (see
//! [`crate::simulator::generate`]): the target channel is the sum, in spec order, of its
//! components' signals, each simulated alone by [`Simulator::component_signal`]; a
//! candidate effect is appended to the target channel's components, so its random
//! streams are its own and adding it to the spec gives `farma simulate` exactly the
//! signal the diagnosis scored.

use rayon::prelude::*;

use crate::error::Result;
use crate::simulator::generate::{SimRequest, Simulator};
use crate::simulator::{Component, Spec};

/// Where and how the ensemble is simulated.
#[derive(Clone, Debug)]
pub struct SimBase<'a> {
    pub n_samples: usize,
    pub rate_hz: f64,
    pub temperature_c: Option<&'a [f64]>,
    pub seed: u64,
    pub replicas: usize,
    pub base_dir: Option<std::path::PathBuf>,
}

impl<'a> SimBase<'a> {
    fn request(&self) -> SimRequest<'a> {
        let mut req = SimRequest::new(self.n_samples, self.rate_hz);
        req.temperature_c = self.temperature_c;
        req.seed = Some(self.seed);
        req.base_dir = self.base_dir.clone();
        req
    }

    /// Signals of components `comps` of channel `channel` of `spec`, for every replica:
    /// out\[r\]\[j\] is component comps\[j\] in replica r.
    pub fn component_signals(
        &self,
        spec: &Spec,
        channel: usize,
        comps: &[usize],
    ) -> Result<Vec<Vec<Vec<f64>>>> {
        (0..self.replicas)
            .into_par_iter()
            .map(|r| {
                let mut s = Simulator::new(spec, self.request())?;
                s.set_replica(r as u64);
                comps
                    .iter()
                    .map(|&k| s.component_signal(channel, k))
                    .collect::<Result<Vec<_>>>()
            })
            .collect()
    }

    /// The signal of `extra`, appended as a new component of channel `channel` of `spec`,
    /// in every replica (one vector when the component is deterministic).
    pub fn extra_signal(
        &self,
        spec: &Spec,
        channel: usize,
        extra: &Component,
    ) -> Result<Vec<Vec<f64>>> {
        let mut s2 = spec.clone();
        s2.channels[channel].components.push(extra.clone());
        let k = s2.channels[channel].components.len() - 1;
        let reps = if is_deterministic(extra) {
            1
        } else {
            self.replicas
        };
        let one = SimBase {
            replicas: reps,
            ..self.clone()
        };
        Ok(one
            .component_signals(&s2, channel, &[k])?
            .into_iter()
            .map(|mut v| v.pop().unwrap_or_default())
            .collect())
    }

    /// `f` of the signal of `extra`, appended as a new component of channel `channel` of
    /// `spec`, in every replica (once when the component is deterministic): the same
    /// signals as [`SimBase::extra_signal`], each dropped once `f` has read it, so that
    /// no more than a few are held at once.
    pub fn extra_map<T: Send>(
        &self,
        spec: &Spec,
        channel: usize,
        extra: &Component,
        f: impl Fn(&[f64]) -> T + Sync,
    ) -> Result<Vec<T>> {
        let mut s2 = spec.clone();
        s2.channels[channel].components.push(extra.clone());
        let k = s2.channels[channel].components.len() - 1;
        let reps = if is_deterministic(extra) {
            1
        } else {
            self.replicas
        };
        (0..reps)
            .into_par_iter()
            .map(|r| {
                let mut s = Simulator::new(&s2, self.request())?;
                s.set_replica(r as u64);
                Ok(f(&s.component_signal(channel, k)?))
            })
            .collect()
    }

    /// The whole simulated channels `names` of `spec` in every replica.
    pub fn channels(&self, spec: &Spec, names: &[String]) -> Result<Vec<Vec<Vec<f64>>>> {
        if names.is_empty() {
            return Ok(vec![Vec::new(); self.replicas]);
        }
        (0..self.replicas)
            .into_par_iter()
            .map(|r| {
                let mut req = self.request();
                req.replica = r as u64;
                req.channels = Some(names.to_vec());
                let out = Simulator::new(spec, req)?.run()?;
                Ok(names
                    .iter()
                    .map(|n| out.channel(n).map(|v| v.to_vec()).unwrap_or_default())
                    .collect())
            })
            .collect()
    }
}

/// Components whose signal does not depend on the replica.
pub fn is_deterministic(c: &Component) -> bool {
    matches!(
        c,
        Component::ConstantBias { .. }
            | Component::RateRamp { .. }
            | Component::Sinusoid { .. }
            | Component::Warmup { .. }
            | Component::TemperatureBias { .. }
            | Component::ThermalRate { .. }
    )
}
