//! Candidate effects: what a spec may be missing, with parameters estimated on the
//! training part of the real log only.
//!
//! Every component kind of contracts.md section 2 that the spec's target channel does
//! not have is a candidate to add; every component it has, whose signal is linear in a
//! size parameter, is a candidate to recalibrate (`recalibrate:<kind>`). Estimation
//! (all on the training blocks):
//! - deterministic effects by least squares of the residual r_t = x_t - xbar_t (the real
//!   log minus the ensemble mean, which is the spec's deterministic part plus averaged
//!   noise) on the effect's own signal, simulated with a unit parameter, plus an
//!   intercept: constant_bias (mean of r), rate_ramp, warmup (amplitude for each of a
//!   log grid of tau_s, the best by residual sum of squares, refined by golden-section
//!   search between its grid neighbours), sinusoid (frequency of
//!   the largest peak, relative to its neighbours, of the periodogram of r on the
//!   training blocks, each less its own mean, refined by a
//!   golden-section search of the least-squares power; amplitude and phase by least
//!   squares, then the output filter's gain and phase at that frequency undone, the
//!   component going in before it), temperature_bias (coefficients of T - Tm and (T - Tm)^2), thermal_rate
//!   (coefficient for each smoothing and first-order lag of a grid, the best by
//!   residual sum of squares, its lag refined by golden section);
//! - noise effects from the Allan variance, which adds over independent processes:
//!   with A(m) the pooled training AVAR of the real log, E(m) the ensemble's mean and
//!   U(m) the candidate simulated with a unit coefficient (mean over replicas; for
//!   gauss_markov its exact closed form),
//!   c^2 = argmin sum_m w_m (A - E - c^2 U)^2, w_m = 1 / (m A(m)^2) (the relative
//!   variance of an AVAR estimate grows like m / N), c^2 >= 0: white_noise,
//!   quantization, bias_instability, rate_random_walk, gauss_markov (tau_s by the best
//!   fit over a log grid, refined by golden section), and recalibration of a noise
//!   component (A - E + V_k against V_k, its own AVAR, giving the factor s^2 on its
//!   size); A(m) is of the log with the residual's line taken out first when the
//!   periodogram shows one beyond doubt (a line is not noise, and its Allan variance
//!   is a bump that a Gauss-Markov or a bias instability would take as its own);
//! - outliers from spikes: the local second difference s_t = x_t - (x_{t-1} + x_{t+1})/2,
//!   spikes where |s_t| exceeds 6 robust standard deviations (1.4826 MAD) and is a local
//!   maximum; the excess count over the ensemble's gives the rate, and the spikes' sizes,
//!   read as a normal (by their mean square, E[Z^2 | |Z| > c] = 1 + c phi(c) / Q(c)) or
//!   a Student-t sample (by maximum likelihood, when the sizes say so) truncated at the
//!   threshold, give the amplitude distribution and the share detected;
//! - heteroskedastic: the regression of d_t^2 (d the first difference) on T - Tm and
//!   (T - Tm)^2 gives E[d^2] = v_other + v_mod (1 + slope (T - Tm))^2, v_other being
//!   the other components' variance of d (from the ensemble): the slope and the
//!   modulated component's level (rescaled with the scale added);
//! - cross_axis: gain = cov(d_x, d_o) / var(d_o) over the training part, for each other
//!   channel o of the spec present in the log.
//!
//! Candidates that mimic each other are told apart by the scoring, not here: each is
//! scored on every statistic family of the withheld part, and pays for widening the
//! ensemble's band (the spread term of `distance`), so a slow temperature drift (which
//! moves the temperature family as well as the long-tau Allan deviation) beats a rate
//! random walk, which matches the Allan curve and the window means only by letting
//! them wander from one simulation to the next; T beats dT/dt where the mean
//! by temperature bin moves, and the other way round; a ramp and a warm-up differ in
//! the time family's window means.
//!
//! One file per kind of effect, in the order [`propose`] tries them:
//! `deterministic.rs` (constant_bias, rate_ramp, warmup, sinusoid), `temperature.rs`
//! (temperature_bias, thermal_rate, heteroskedastic), `noise.rs` (the power-law terms
//! and gauss_markov), `outliers.rs`, `cross_axis.rs`, then `recalibrate.rs`; `lsq.rs`
//! holds the least squares and searches they share, `params.rs` a component's size and
//! JSON parameters, `resolution.rs` the output resolution of a log. The output path's
//! candidates (`output_path.rs`: output_filter, saturation, output_resolution; and
//! `path_fit.rs`, the filter fitted by simulation beside a coarse resolution) change
//! the path every replica's sum goes through, not the sum; the diagnosis asks for
//! them after [`propose`].

mod cross_axis;
mod deterministic;
mod farma;
pub mod joint;
mod lsq;
mod noise;
mod outliers;
pub mod output_path;
mod params;
pub mod path_fit;
mod recalibrate;
mod resolution;
mod temperature;

use std::ops::Range;
use std::sync::{Arc, OnceLock};

use rayon::prelude::*;
use serde_json::Value;

use super::ensemble::SimBase;
use super::features::{Layout, Temperature};
use crate::error::Result;
use crate::simulator::{Component, Kind, Spec};

pub use params::{params_json, scaled};
pub use resolution::output_resolution;

/// How a candidate changes every replica's target channel.
#[derive(Clone, Debug)]
pub enum Delta {
    /// The same signal in every replica (deterministic effects).
    Same(Vec<f64>),
    /// One signal per replica.
    Each(Vec<Vec<f64>>),
}

impl Delta {
    pub fn get(&self, r: usize) -> &[f64] {
        match self {
            Delta::Same(v) => v,
            Delta::Each(v) => &v[r],
        }
    }
}

/// A proposed change of the spec.
#[derive(Clone, Debug)]
pub struct Proposal {
    /// A component kind, or `recalibrate:<kind>`.
    pub kind: String,
    /// The component added, or the replacement of component `replaces`.
    pub component: Component,
    pub replaces: Option<usize>,
    /// A component of the spec put in place of component `.0` along with the one
    /// added (a heteroskedastic scale's level on the noise it modulates; for a filter
    /// fitted by simulation, the output resolution in the rounding form fitted with it,
    /// which the diagnosis puts in the path beside the filter); the change of its
    /// signal, if any, is in `delta`, with the added component's.
    pub rescales: Option<(usize, Component)>,
    pub params: Value,
    pub delta: Delta,
    /// How the parameters were estimated.
    pub note: String,
    /// A second change made with this one, as one candidate (the output filter with
    /// the white noise refitted before it, see `output_path::proposals`).
    pub also: Option<Also>,
}

impl Proposal {
    /// Drops the full-length signals that [`Proposal::restore`] rebuilds bit for bit
    /// from `cx`, the state the proposal was estimated on: a joint candidate's second
    /// change (a rescale of one of the parts, [`Also::build`]), a cross_axis delta
    /// taken from the ensemble's simulations of the other channel
    /// (`cross_axis::cached_signal`) and a noise component's recalibration (its part
    /// times the size factor less one). Any other delta is kept. A shed delta is an
    /// `Each` of no replica, which no estimate gives (an ensemble has at least one).
    pub fn shed(&mut self, cx: &Context) {
        if let Some(a) = self.also.as_mut() {
            a.shed();
        }
        if cross_axis::rebuild_source(cx, self).is_some() || self.rescaled_part().is_some() {
            self.delta = Delta::Each(Vec::new());
        }
    }

    /// For the recalibration of a noise component (`recalibrate:<kind>` with a delta per
    /// replica): the component's index k and s - 1, its size factor less one; the delta
    /// `recalibrate.rs` builds is `parts[r][k][t] * (s - 1)`, rebuilt bit for
    /// bit from the same parts.
    fn rescaled_part(&self) -> Option<(usize, f64)> {
        let k = self.replaces?;
        if !self.kind.starts_with("recalibrate:") || !matches!(self.delta, Delta::Each(_)) {
            return None;
        }
        let s = self.params.get("factor")?.as_f64()?;
        Some((k, s - 1.0))
    }

    /// Rebuilds what [`Proposal::shed`] dropped, from the same state `cx`.
    pub fn restore(&mut self, cx: &Context) {
        if let Some(a) = self.also.as_mut()
            && a.delta.is_shed()
        {
            a.build(cx.parts);
        }
        if self.delta.is_shed()
            && let Some(u) = cross_axis::rebuild_source(cx, self)
                .and_then(|(j, from, gain)| cross_axis::cached_signal(cx, j, from, gain))
        {
            self.delta = Delta::Each(u);
        }
        if self.delta.is_shed()
            && let Some((k, c)) = self.rescaled_part()
        {
            self.delta = Delta::Each(
                cx.parts
                    .iter()
                    .map(|p| p[k].iter().map(|v| v * c).collect())
                    .collect(),
            );
        }
    }
}

impl Proposal {
    /// Each replica's change of its sum, as the signal and the coefficient it enters
    /// with (`x + coef * signal`), read without building what [`Proposal::shed`]
    /// dropped: a cross_axis delta is the gain times the other channel's simulation in
    /// `cx` (`cross_axis::cached_signal`, whose `0 + gain v` is `gain v` bit for bit),
    /// a noise recalibration's the component's part with coefficient s - 1 (`v * (s -
    /// 1)`, the product the built delta holds), any other delta its own signal with
    /// coefficient 1. `cx` is the state the
    /// proposal was estimated on.
    pub fn change<'s>(&'s self, cx: &Context<'s>) -> (Vec<&'s [f64]>, f64) {
        let m = cx.sim.replicas;
        if self.delta.is_shed()
            && let Some((j, _, gain)) = cross_axis::rebuild_source(cx, self)
        {
            return (
                cx.sim_others.iter().map(|chs| chs[j].as_slice()).collect(),
                gain,
            );
        }
        if self.delta.is_shed()
            && let Some((k, c)) = self.rescaled_part()
        {
            return (cx.parts.iter().map(|p| p[k].as_slice()).collect(), c);
        }
        ((0..m).map(|r| self.delta.get(r)).collect(), 1.0)
    }

    /// A joint candidate's second change ([`Also`]) as each replica's signal and the
    /// coefficient it enters with: its factor times the rescaled component's signal in
    /// `parts` (what [`Also::build`] holds, `v * factor`, bit for bit), without building
    /// it; None for a proposal with no second change.
    pub fn also_change<'s>(
        &'s self,
        parts: &'s [Vec<std::sync::Arc<Vec<f64>>>],
    ) -> Option<(Vec<&'s [f64]>, f64)> {
        let a = self.also.as_ref()?;
        Some((
            parts.iter().map(|p| p[a.comp].as_slice()).collect(),
            a.factor,
        ))
    }
}

impl Delta {
    /// A delta dropped by [`Proposal::shed`] (an `Each` of no replica).
    pub fn is_shed(&self) -> bool {
        matches!(self, Delta::Each(v) if v.is_empty())
    }
}

/// The second change of a joint candidate: component `comp` of the channel replaced by
/// `component`, the same component rescaled, so that each replica's signal of it
/// changes by `factor` times itself.
#[derive(Clone, Debug)]
pub struct Also {
    pub comp: usize,
    pub component: Component,
    /// The rescale's factor minus one: s - 1 for the component's size times s.
    pub factor: f64,
    /// Each replica's change, `d_r[t] = factor * x_r[t]` with x_r replica r's signal of
    /// `comp` ([`Also::build`]); empty while shed ([`Also::shed`]).
    pub delta: Delta,
}

impl Also {
    /// The rescale of component `comp` by 1 + `factor` in the state whose per-replica
    /// component signals are `parts`, with its change built.
    pub fn new(
        comp: usize,
        component: Component,
        factor: f64,
        parts: &[Vec<std::sync::Arc<Vec<f64>>>],
    ) -> Also {
        let mut a = Also {
            comp,
            component,
            factor,
            delta: Delta::Each(Vec::new()),
        };
        a.build(parts);
        a
    }

    /// Drops the change's signals (a proposal waiting to be paired holds none); the
    /// same `parts` rebuild them bit for bit ([`Also::build`]).
    pub fn shed(&mut self) {
        self.delta = Delta::Each(Vec::new());
    }

    /// Builds the change from `parts`, the per-replica component signals of the state
    /// the candidate was estimated on: `d_r[t] = factor * parts[r][comp][t]` (every
    /// replica holds its own signal of a rescaled noise component).
    pub fn build(&mut self, parts: &[Vec<std::sync::Arc<Vec<f64>>>]) {
        let f = self.factor;
        self.delta = Delta::Each(
            parts
                .iter()
                .map(|p| p[self.comp].iter().map(|v| v * f).collect())
                .collect(),
        );
    }
}

/// A candidate that could not be tried, and why.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NotTried {
    pub kind: String,
    pub reason: String,
}

/// What estimation needs to know about the current state.
pub struct Context<'a> {
    pub spec: &'a Spec,
    pub channel: usize,
    pub sim: &'a SimBase<'a>,
    pub train: &'a Layout,
    pub real: &'a [f64],
    /// The channel's samples after `real` that no part scores, training data only
    /// ([`crate::diagnosis::RealLog::beyond`]); empty for a whole log.
    pub beyond: &'a [f64],
    pub temperature: Option<&'a Temperature>,
    /// Other spec channels present in the real log: (name, real values).
    pub others: &'a [(String, &'a [f64])],
    /// Per replica, the simulated channels of `others` (same order).
    pub sim_others: &'a [Vec<Vec<f64>>],
    /// Per replica, the target channel's simulation.
    pub target: &'a [std::sync::Arc<Vec<f64>>],
    /// Per replica, per spec component of the target channel, its signal.
    pub parts: &'a [Vec<std::sync::Arc<Vec<f64>>>],
}

impl Context<'_> {
    fn rate_hz(&self) -> f64 {
        self.sim.rate_hz
    }
    fn ranges(&self) -> &[Range<usize>] {
        self.train.ranges()
    }
    fn n_train(&self) -> usize {
        self.ranges().iter().map(|r| r.len()).sum()
    }
    fn avar(&self, x: &[f64]) -> Vec<f64> {
        self.train.ln_avar(x).into_iter().map(f64::exp).collect()
    }
    /// The mean over the series `xs` of their training AVAR (each series' AVAR computed
    /// in parallel, the mean summed in the series' order).
    fn mean_avar<'b>(&self, xs: impl Iterator<Item = &'b [f64]>) -> Vec<f64> {
        let xs: Vec<&[f64]> = xs.collect();
        mean_in_order(xs.par_iter().map(|x| self.avar(x)).collect())
    }

    /// [`Context::mean_avar`] over the replicas' series `of(r)`, each made, read and
    /// dropped in turn (as [`Context::target_as_output`] and
    /// [`Context::part_as_output`] make them), not all held at once.
    fn mean_avar_of<'b>(
        &'b self,
        of: impl Fn(usize) -> std::borrow::Cow<'b, [f64]> + Sync,
    ) -> Vec<f64> {
        mean_in_order(
            (0..self.target.len())
                .into_par_iter()
                .map(|r| self.avar(&of(r)))
                .collect(),
        )
    }
    /// Replica `r`'s signal of the target channel's component `k` as the output shows
    /// it: through the channel's output filter (a low-pass or a FIR: the path's linear
    /// stage; the saturation and the resolution act on the sum and are left out), from
    /// rest as the simulator runs it; the signal itself when the channel has no filter.
    /// A noise fit that compares the log's short-time variance with a component's must
    /// read the component here: a filter that cuts the log's high frequencies cuts the
    /// component's too, and its unfiltered variance would put the filter's loss on the
    /// component's size.
    fn part_as_output(&self, r: usize, k: usize) -> std::borrow::Cow<'_, [f64]> {
        let filters: Vec<Component> = self.spec.channels[self.channel]
            .components
            .iter()
            .filter(|c| c.kind() == Kind::OutputFilter)
            .cloned()
            .collect();
        self.through(&filters, &self.parts[r][k])
    }

    /// Replica `r`'s output of the target channel: its pre-path sum through the
    /// channel's output path (filter, saturation, resolution), from rest as the
    /// simulator runs it; the sum itself when the channel has no path. What the log's
    /// statistics are compared with.
    fn target_as_output(&self, r: usize) -> std::borrow::Cow<'_, [f64]> {
        self.through(
            &self.spec.channels[self.channel].components,
            &self.target[r],
        )
    }

    /// The gain g and phase shift dphi (rad) of the channel's output filter at
    /// `freq_hz`: its output for the input sin(2 pi f t / fs) is g sin(2 pi f t / fs +
    /// dphi) once the start's transient is over; None without a filter. Read off the
    /// filter itself ([`Context::through`], the path's linear stages as
    /// [`Context::part_as_output`] takes them): the least-squares fit of a sin + b cos
    /// to the filtered unit sinusoid over its last three quarters (at least 4096
    /// samples), g = hypot(a, b), dphi = atan2(b, a).
    fn filter_response(&self, freq_hz: f64) -> Option<(f64, f64)> {
        let filters: Vec<Component> = self.spec.channels[self.channel]
            .components
            .iter()
            .filter(|c| c.kind() == Kind::OutputFilter)
            .cloned()
            .collect();
        if filters.is_empty() {
            return None;
        }
        let w = 2.0 * std::f64::consts::PI * freq_hz / self.rate_hz();
        let n = self.real.len().max(4 * 4096);
        let x: Vec<f64> = (0..n).map(|t| (w * t as f64).sin()).collect();
        let y = self.through(&filters, &x);
        let (mut ss, mut cc, mut sc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for t in n / 4..n {
            let (st, ct) = ((w * t as f64).sin(), (w * t as f64).cos());
            ss += st * st;
            cc += ct * ct;
            sc += st * ct;
            ys += y[t] * st;
            yc += y[t] * ct;
        }
        let det = ss * cc - sc * sc;
        if det <= 0.0 {
            return None;
        }
        let a = (ys * cc - yc * sc) / det;
        let b = (yc * ss - ys * sc) / det;
        Some((a.hypot(b), b.atan2(a)))
    }

    /// `x` through the output-path stages among `comps` ([`super::path::PathStage`]),
    /// from rest; `x` itself when there is none.
    fn through<'b>(&self, comps: &[Component], x: &'b [f64]) -> std::borrow::Cow<'b, [f64]> {
        let path = super::path::PathStage::of(comps, self.rate_hz());
        if path.is_empty() {
            return std::borrow::Cow::Borrowed(x);
        }
        let mut y = x.to_vec();
        path.apply(&mut y);
        std::borrow::Cow::Owned(y)
    }

    /// The signal of `c` added to the target channel, simulated once (deterministic
    /// effects: the same in every replica).
    fn unit(&self, c: Component) -> Result<Vec<f64>> {
        Ok(self
            .sim
            .extra_signal(self.spec, self.channel, &c)?
            .pop()
            .unwrap_or_default())
    }
}

/// The element-wise mean of the vectors `vs`, summed in their order (the first one,
/// then each next added), divided by their count.
fn mean_in_order(vs: Vec<Vec<f64>>) -> Vec<f64> {
    let mut acc: Vec<f64> = Vec::new();
    let mut n = 0.0f64;
    for a in vs {
        if acc.is_empty() {
            acc = a;
        } else {
            for (s, v) in acc.iter_mut().zip(a) {
                *s += v;
            }
        }
        n += 1.0;
    }
    acc.iter().map(|s| s / n.max(1.0)).collect()
}

/// What every estimate reads from the training part, computed once per [`propose`].
struct Training {
    /// Samples in the log.
    n: usize,
    /// Sample rate (Hz) and the log's duration (s).
    fs: f64,
    duration_s: f64,
    /// The residual r_t = x_t - xbar_t against the ensemble mean.
    res: Vec<f64>,
    /// The training blocks.
    ranges: Vec<Range<usize>>,
    /// A(m), the pooled training AVAR of the real log, at the cluster sizes `ms`.
    a_real: Vec<f64>,
    ms: Vec<usize>,
    /// A(m) - E(m), E the ensemble's mean training AVAR.
    excess: Vec<f64>,
    /// Each sample's weight in the deterministic fits ([`noise_weights`]) when the
    /// spec's channel has a heteroskedastic noise; None: every sample alike.
    weights: Option<Vec<f64>>,
    /// The training residual's largest line ([`Training::line`]), found on first use.
    line: OnceLock<Option<deterministic::Line>>,
    /// What the noise fits read ([`Training::noise_avar`]), computed on first use.
    noise: OnceLock<NoiseAvar>,
    /// Another effect's signal that the least squares of the deterministic fits take
    /// as one more regressor, its size free ([`Training::regs`]): the joint fit of a
    /// pair ([`joint`]) by variable projection. None: the effect alone.
    co: Option<Vec<f64>>,
}

/// The training Allan variance the noise fits read: A(m) and A(m) - E(m) of the real
/// log with a significant line of the residual taken out first (`line_hz`), else the
/// log's own.
pub(super) struct NoiseAvar {
    pub a_real: Vec<f64>,
    pub excess: Vec<f64>,
    pub line_hz: Option<f64>,
}

impl NoiseAvar {
    /// What a noise proposal's note adds when a line was taken out.
    pub fn note(&self) -> String {
        match self.line_hz {
            Some(f) => format!(
                ", with the training residual's line at {} Hz taken out of the log first",
                crate::fmt::num(f)
            ),
            None => String::new(),
        }
    }
}

impl Training {
    fn new(cx: &Context) -> Self {
        let mut tr = Training::light(cx);
        tr.a_real = cx.avar(cx.real);
        // the ensemble's outputs, as the log shows its own (through the output path)
        let a_ens = cx.mean_avar_of(|r| cx.target_as_output(r));
        tr.ms = cx.train.adev_factors().to_vec();
        tr.excess = tr.a_real.iter().zip(&a_ens).map(|(a, e)| a - e).collect();
        tr
    }

    /// What the deterministic fits read, without the Allan variances the noise fits
    /// read (`a_real`, `ms` and `excess` empty): the residual, the training blocks and
    /// the weights, as [`Training::new`] computes them.
    fn light(cx: &Context) -> Self {
        let m_reps = cx.target.len();
        let n = cx.real.len();
        let fs = cx.rate_hz();
        let mut xbar = vec![0.0; n];
        for t in cx.target {
            for (a, v) in xbar.iter_mut().zip(t.iter()) {
                *a += v / m_reps as f64;
            }
        }
        let res: Vec<f64> = cx.real.iter().zip(&xbar).map(|(a, b)| a - b).collect();
        let ranges = cx.ranges().to_vec();
        let weights = heteroskedastic_in(cx).then(|| noise_weights(cx.target, &ranges));
        Training {
            n,
            fs,
            duration_s: n as f64 / fs,
            res,
            ranges,
            a_real: Vec::new(),
            ms: Vec::new(),
            excess: Vec::new(),
            weights,
            line: OnceLock::new(),
            noise: OnceLock::new(),
            co: None,
        }
    }

    /// The same training part with the residual `res` in place of its own and the
    /// co-regressor `co` (for the deterministic fits of [`joint`]: the residual less
    /// another effect's signal, or the residual with that signal's shape beside).
    fn with_res(&self, res: Vec<f64>, co: Option<Vec<f64>>) -> Self {
        Training {
            n: self.n,
            fs: self.fs,
            duration_s: self.duration_s,
            res,
            ranges: self.ranges.clone(),
            a_real: self.a_real.clone(),
            ms: self.ms.clone(),
            excess: self.excess.clone(),
            weights: self.weights.clone(),
            line: OnceLock::new(),
            noise: OnceLock::new(),
            co,
        }
    }

    /// The regressors `regs` of a deterministic fit, followed by the co-regressor when
    /// there is one ([`Training::co`]): its coefficient comes last, after the fit's own.
    fn regs<'a>(&'a self, regs: &[&'a [f64]]) -> Vec<&'a [f64]> {
        let mut v = regs.to_vec();
        v.extend(self.co.as_deref());
        v
    }

    /// The weights of the deterministic fits ([`Training::weights`]), if any.
    fn w(&self) -> Option<&[f64]> {
        self.weights.as_deref()
    }

    /// The largest line of the training residual ([`deterministic::find_sinusoid`]),
    /// significant or not; None when the periodogram has no peak.
    fn line(&self) -> Option<&deterministic::Line> {
        self.line
            .get_or_init(|| deterministic::find_sinusoid(&self.res, &self.ranges, self.fs))
            .as_ref()
    }

    /// The training Allan variance the noise fits read ([`NoiseAvar`]). A sinusoid's
    /// Allan variance, A^2 sin^4(pi f tau) / (pi f tau)^2, is a bump near tau = 0.37 / f
    /// that a Gauss-Markov or a bias instability fitted to the excess takes as its own;
    /// a line the periodogram shows beyond doubt ([`deterministic::Line::is_significant`])
    /// is not noise, so it is taken out of the real log before A(m) is computed:
    /// A'(m) = AVAR(x_t - line_t), excess A'(m) - E(m).
    fn noise_avar(&self, cx: &Context) -> &NoiseAvar {
        self.noise
            .get_or_init(|| match self.line().filter(|l| l.is_significant()) {
                Some(l) => {
                    let clean: Vec<f64> = cx
                        .real
                        .iter()
                        .enumerate()
                        .map(|(t, x)| x - l.at(t, self.fs))
                        .collect();
                    let a_clean = cx.avar(&clean);
                    let excess = a_clean
                        .iter()
                        .zip(self.a_real.iter().zip(&self.excess))
                        .map(|(c, (a, e))| c - (a - e))
                        .collect();
                    NoiseAvar {
                        a_real: a_clean,
                        excess,
                        line_hz: Some(l.freq_hz),
                    }
                }
                None => NoiseAvar {
                    a_real: self.a_real.clone(),
                    excess: self.excess.clone(),
                    line_hz: None,
                },
            })
    }
}

/// Whether the channel of `cx`'s spec has a heteroskedastic noise component.
fn heteroskedastic_in(cx: &Context) -> bool {
    cx.spec.channels[cx.channel]
        .components
        .iter()
        .any(|c| matches!(c, Component::Heteroskedastic { .. }))
}

/// Samples on each side of a sample in the window [`noise_weights`] averages over.
const WEIGHT_HALF_WINDOW: usize = 128;

/// Each sample's weight w_t = 1 / v_t for least squares under the ensemble's noise,
/// scaled to mean 1 over `ranges`: v_t is the mean over the replicas and over the
/// samples within [`WEIGHT_HALF_WINDOW`] of t of the squared first difference
/// (x_s - x_{s-1})^2. A first difference holds the white part of the noise (twice its
/// variance) and almost none of the slow parts (a random walk's or a flicker's
/// increments are far smaller per sample), so v_t follows a noise level that changes
/// with temperature (a heteroskedastic white noise) and not the spread of the slow
/// parts, whose samples are correlated and which a weight per sample cannot describe.
fn noise_weights(target: &[Arc<Vec<f64>>], ranges: &[Range<usize>]) -> Vec<f64> {
    let n = target.first().map_or(0, |t| t.len());
    let m = target.len().max(1) as f64;
    // mean squared first difference per sample (the first sample takes the second's)
    let mut d2 = vec![0.0; n];
    for x in target {
        for t in 1..n {
            d2[t] += (x[t] - x[t - 1]).powi(2) / m;
        }
    }
    if n > 1 {
        d2[0] = d2[1];
    }
    let mut prefix = vec![0.0; n + 1];
    for t in 0..n {
        prefix[t + 1] = prefix[t] + d2[t];
    }
    let mut w: Vec<f64> = (0..n)
        .map(|t| {
            let lo = t.saturating_sub(WEIGHT_HALF_WINDOW);
            let hi = (t + WEIGHT_HALF_WINDOW + 1).min(n);
            let v = (prefix[hi] - prefix[lo]) / (hi - lo) as f64;
            if v > 0.0 { 1.0 / v } else { 0.0 }
        })
        .collect();
    let (sum, count) = ranges
        .iter()
        .flat_map(|r| r.clone())
        .fold((0.0, 0usize), |(s, c), t| (s + w[t], c + 1));
    if sum > 0.0 && count > 0 {
        let k = count as f64 / sum;
        w.iter_mut().for_each(|v| *v *= k);
    } else {
        w.iter_mut().for_each(|v| *v = 1.0);
    }
    w
}

/// The candidates found so far: each proposal handed to the caller's sink as soon as
/// it is estimated (so that only the ones the caller keeps stay in memory), and those
/// not tried.
struct Found<'s> {
    sink: &'s mut dyn FnMut(Proposal),
    skipped: Vec<NotTried>,
}

impl Found<'_> {
    fn push(&mut self, p: Proposal) {
        (self.sink)(p)
    }

    fn skip(&mut self, kind: &str, why: &str) {
        self.skipped.push(NotTried {
            kind: kind.into(),
            reason: why.into(),
        })
    }

    /// A deterministic addition: component `c`, the same signal `sig` in every replica.
    fn same(&mut self, kind: &str, c: Component, sig: Vec<f64>, note: String) {
        self.push(same(kind, c, sig, note))
    }
}

/// A deterministic addition: component `c`, the same signal `sig` in every replica.
fn same(kind: &str, c: Component, sig: Vec<f64>, note: String) -> Proposal {
    added(kind, c, Delta::Same(sig), note)
}

/// An addition of component `c` (nothing replaced or rescaled) whose signal is `delta`.
fn added(kind: &str, c: Component, delta: Delta, note: String) -> Proposal {
    Proposal {
        also: None,
        kind: kind.into(),
        params: params_json(&c),
        component: c,
        replaces: None,
        rescales: None,
        delta,
        note,
    }
}

/// One step of [`propose`]: the estimation of one kind of effect (or of the
/// recalibration of one component), in the order the steps are tried.
#[derive(Clone, Debug)]
enum Step {
    ConstantBias,
    RateRamp,
    Warmup,
    Sinusoid,
    TemperatureBias,
    ThermalRate,
    Heteroskedastic,
    PowerLaw(Kind, Component),
    GaussMarkov,
    Outliers,
    CrossAxis,
    Arma,
    Farma,
    /// Recalibration of the target channel's component with this index.
    Recalibrate(usize),
}

/// The steps that estimate a bias, a deterministic signal fitted to the residual's
/// mean, in [`propose`]'s order: the kinds an exchange step and a joint pair
/// ([`joint`]) are made of.
fn bias_steps() -> [Step; 6] {
    [
        Step::ConstantBias,
        Step::RateRamp,
        Step::Warmup,
        Step::Sinusoid,
        Step::TemperatureBias,
        Step::ThermalRate,
    ]
}

/// The kinds of [`bias_steps`], in the same order (contracts.md section 2 names).
pub(crate) fn bias_kinds() -> [&'static str; 6] {
    bias_steps().map(|s| {
        match s {
            Step::ConstantBias => Kind::ConstantBias,
            Step::RateRamp => Kind::RateRamp,
            Step::Warmup => Kind::Warmup,
            Step::Sinusoid => Kind::Sinusoid,
            Step::TemperatureBias => Kind::TemperatureBias,
            Step::ThermalRate => Kind::ThermalRate,
            _ => unreachable!("bias_steps holds the six biases only"),
        }
        .as_str()
    })
}

/// The steps of [`propose`] for a target channel of `n_comps` components.
fn steps(n_comps: usize) -> Vec<Step> {
    let mut s = bias_steps().to_vec();
    s.push(Step::Heteroskedastic);
    s.extend(
        noise::unit_components()
            .into_iter()
            .map(|(k, c)| Step::PowerLaw(k, c)),
    );
    s.extend([
        Step::GaussMarkov,
        Step::Outliers,
        Step::CrossAxis,
        Step::Arma,
        Step::Farma,
    ]);
    s.extend((0..n_comps).map(Step::Recalibrate));
    s
}

/// Runs `step` for the state `cx`, handing what it estimates to `out`.
fn run_step(cx: &Context, tr: &Training, step: &Step, out: &mut Found) -> Result<()> {
    let comps = &cx.spec.channels[cx.channel].components;
    let has = |k: Kind| comps.iter().any(|c| c.kind() == k);
    let no_temperature = "the log has no temperature channel (temperature_channel in the spec)";
    let tm = |tp: &Temperature| tp.t_c.iter().sum::<f64>() / tr.n as f64;
    match step {
        Step::ConstantBias if !has(Kind::ConstantBias) => {
            deterministic::constant_bias(cx, tr, out);
        }
        Step::RateRamp if !has(Kind::RateRamp) => deterministic::rate_ramp(cx, tr, out)?,
        Step::Warmup if !has(Kind::Warmup) => deterministic::warmup(cx, tr, out)?,
        Step::Sinusoid if !has(Kind::Sinusoid) => deterministic::sinusoid(cx, tr, out)?,
        Step::TemperatureBias | Step::ThermalRate | Step::Heteroskedastic => {
            let (kind, k) = match step {
                Step::TemperatureBias => ("temperature_bias", Kind::TemperatureBias),
                Step::ThermalRate => ("thermal_rate", Kind::ThermalRate),
                _ => ("heteroskedastic", Kind::Heteroskedastic),
            };
            match cx.temperature {
                None => out.skip(kind, no_temperature),
                Some(_) if has(k) => {}
                Some(tp) => match step {
                    Step::TemperatureBias => temperature::temperature_bias(cx, tr, tm(tp), out)?,
                    Step::ThermalRate => temperature::thermal_rate(cx, tr, out)?,
                    _ => temperature::heteroskedastic(cx, tp, tm(tp), out)?,
                },
            }
        }
        Step::PowerLaw(kind, unit_c) if !has(*kind) => {
            noise::power_law(cx, tr, *kind, unit_c.clone(), out)?
        }
        Step::GaussMarkov if !has(Kind::GaussMarkov) => noise::gauss_markov(cx, tr, out)?,
        Step::Outliers if !has(Kind::Outliers) => outliers::outliers(cx, out)?,
        Step::CrossAxis => cross_axis::cross_axis(cx, tr, out)?,
        Step::Arma if !has(Kind::Arma) => out.skip(
            "arma",
            "not estimated as an added effect: fit the drift with `farma fit` and add the model",
        ),
        Step::Farma if !has(Kind::Farma) => farma::farma(cx, tr, out)?,
        Step::Recalibrate(k) => recalibrate::recalibrate(cx, tr, *k, out)?,
        _ => {}
    }
    Ok(())
}

/// Every candidate for the current state, each handed to `sink` as it is estimated;
/// returns those not tried. Each kind of component the target channel lacks is tried
/// as an addition, in this order, then every component it has is tried for
/// recalibration.
pub fn propose(cx: &Context, sink: &mut dyn FnMut(Proposal)) -> Result<Vec<NotTried>> {
    let tr = Training::new(cx);
    let mut out = Found {
        sink,
        skipped: Vec::new(),
    };
    for step in steps(cx.spec.channels[cx.channel].components.len()) {
        run_step(cx, &tr, &step, &mut out)?;
    }
    Ok(out.skipped)
}

/// [`propose`] for two states at once, step by step: each step runs for `cxs[0]`, then
/// for `cxs[1]`, so that a caller pairing the two states' estimates of one kind holds
/// the first state's only until the second's of the same step arrive (not all of
/// them). Each state's proposals reach its sink in the order [`propose`] hands them,
/// and its candidates not tried are the same; [`propose`] is its slow twin.
pub fn propose_folds(
    cxs: [&Context; 2],
    sinks: [&mut dyn FnMut(Proposal); 2],
) -> Result<[Vec<NotTried>; 2]> {
    propose_folds_of(cxs, None, sinks)
}

/// [`propose_folds`] with, when `only` is given, just the steps that estimate an
/// effect of one of those kinds for either state: each state's sink is handed those
/// kinds' proposals that [`propose_folds`] hands it (it may hand a step's other kinds
/// too: the caller filters), in the same order.
pub fn propose_folds_of(
    cxs: [&Context; 2],
    only: Option<&[String]>,
    sinks: [&mut dyn FnMut(Proposal); 2],
) -> Result<[Vec<NotTried>; 2]> {
    let [s0, s1] = sinks;
    let mut outs = [
        Found {
            sink: s0,
            skipped: Vec::new(),
        },
        Found {
            sink: s1,
            skipped: Vec::new(),
        },
    ];
    run_folds(cxs, only, &mut outs)?;
    let [o0, o1] = outs;
    Ok([o0.skipped, o1.skipped])
}

/// The steps of [`propose_folds`] for both states, each step for `cxs[0]` then
/// `cxs[1]`; with `only`, just the
/// steps that estimate an effect of one of those kinds for either state ([`step_kind`]).
///
/// The two states' estimates of a step are independent: they run at once (each
/// collecting its proposals and skips), and are then handed to the sinks as the
/// sequential order has them, the first state's before the second's.
fn run_folds(cxs: [&Context; 2], only: Option<&[String]>, outs: &mut [Found; 2]) -> Result<()> {
    let (tr0, tr1) = rayon::join(|| Training::new(cxs[0]), || Training::new(cxs[1]));
    let trs = [tr0, tr1];
    let comps = cxs.map(|cx| cx.spec.channels[cx.channel].components.as_slice());
    let n_comps = comps.iter().map(|c| c.len()).max().unwrap_or(0);
    // one state's estimates of `step`: its proposals in order, and its skips
    let estimate = |f: usize, step: &Step| {
        collected(|sink| {
            let mut out = Found {
                sink,
                skipped: Vec::new(),
            };
            run_step(cxs[f], &trs[f], step, &mut out)?;
            Ok(out.skipped)
        })
    };
    for step in steps(n_comps) {
        let skip = |kind: &str| {
            comps
                .iter()
                .all(|c| step_kind(&step, c).as_deref() != Some(kind))
        };
        if only.is_some_and(|ks| ks.iter().all(|k| skip(k))) {
            continue;
        }
        let (a, b) = rayon::join(|| estimate(0, &step), || estimate(1, &step));
        for (out, got) in outs.iter_mut().zip([a?, b?]) {
            let (found, skipped) = got;
            found.into_iter().for_each(|p| out.push(p));
            out.skipped.extend(skipped);
        }
    }
    Ok(())
}

/// What `estimate` hands its sink, collected in order, beside what it returns: an
/// estimation that can run beside another and hand its proposals on afterwards.
pub fn collected<R>(
    estimate: impl FnOnce(&mut dyn FnMut(Proposal)) -> Result<R>,
) -> Result<(Vec<Proposal>, R)> {
    let mut found = Vec::new();
    let r = estimate(&mut |p| found.push(p))?;
    Ok((found, r))
}

/// The kind of effect `step` estimates for a target channel with components `comps`:
/// a component kind, or `recalibrate:<kind>` (none for a recalibration of a component
/// the channel does not have).
fn step_kind(step: &Step, comps: &[Component]) -> Option<String> {
    let k = match step {
        Step::ConstantBias => Kind::ConstantBias,
        Step::RateRamp => Kind::RateRamp,
        Step::Warmup => Kind::Warmup,
        Step::Sinusoid => Kind::Sinusoid,
        Step::TemperatureBias => Kind::TemperatureBias,
        Step::ThermalRate => Kind::ThermalRate,
        Step::Heteroskedastic => Kind::Heteroskedastic,
        Step::PowerLaw(k, _) => *k,
        Step::GaussMarkov => Kind::GaussMarkov,
        Step::Outliers => Kind::Outliers,
        Step::CrossAxis => Kind::CrossAxis,
        Step::Arma => Kind::Arma,
        Step::Farma => Kind::Farma,
        Step::Recalibrate(i) => {
            return comps.get(*i).map(|c| format!("recalibrate:{}", c.kind()));
        }
    };
    Some(k.as_str().to_string())
}

/// [`propose_folds`] for the steps that estimate an effect of kind `kind` only (a
/// component kind or `recalibrate:<kind>`): the re-estimation of one kept effect with
/// the others in place. Each state's sink is handed the proposals of that kind that
/// [`propose_folds`] hands it, in the same order; [`propose_folds`] with its proposals
/// filtered by kind is its slow twin.
pub fn propose_kind_folds(
    cxs: [&Context; 2],
    kind: &str,
    sinks: [&mut dyn FnMut(Proposal); 2],
) -> Result<()> {
    let [s0, s1] = sinks;
    let mut f0 = |p: Proposal| {
        if p.kind == kind {
            s0(p)
        }
    };
    let mut f1 = |p: Proposal| {
        if p.kind == kind {
            s1(p)
        }
    };
    let mut outs = [
        Found {
            sink: &mut f0,
            skipped: Vec::new(),
        },
        Found {
            sink: &mut f1,
            skipped: Vec::new(),
        },
    ];
    run_folds(cxs, Some(&[kind.to_string()]), &mut outs)
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;
    use std::sync::Arc;

    use super::*;
    use crate::diagnosis::blocks::Blocks;
    use crate::simulator::ChannelSpec;

    fn spec(x: Vec<Component>) -> Spec {
        Spec {
            sample_rate_hz: 100.0,
            temperature_channel: None,
            seed: Some(5),
            channels: vec![
                ChannelSpec {
                    name: "x".into(),
                    components: x,
                },
                ChannelSpec {
                    name: "y".into(),
                    components: vec![Component::WhiteNoise { n: 0.02 }],
                },
            ],
        }
    }

    #[test]
    fn noise_weights_follow_the_white_noise_level_and_not_a_slow_part() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let n = 20_000;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        // white noise of sd 1 in the first half, 2 in the second, plus a random walk
        // whose spread across replicas grows along the log
        let target: Vec<Arc<Vec<f64>>> = (0..20)
            .map(|_| {
                let mut walk = 0.0;
                Arc::new(
                    (0..n)
                        .map(|t| {
                            let e: f64 = StandardNormal.sample(&mut rng);
                            let d: f64 = StandardNormal.sample(&mut rng);
                            walk += 0.01 * d;
                            walk + if t < n / 2 { e } else { 2.0 * e }
                        })
                        .collect(),
                )
            })
            .collect();
        let ranges = [0..n / 2, n / 2..n];
        let w = noise_weights(&target, &ranges);
        let mean = w.iter().sum::<f64>() / n as f64;
        assert!((mean - 1.0).abs() < 1e-12, "{mean}");
        // away from the change, 1 / v: 4 times less weight where the sd is twice
        let (a, b) = (w[n / 4], w[3 * n / 4]);
        assert!((a / b / 4.0 - 1.0).abs() < 0.1, "{a} {b}");
        // the level 1 / v: v = 2 sd^2 (a difference of white noise) within 10 %
        let early: f64 = w[1000..4000].iter().sum::<f64>() / 3000.0;
        assert!((early / mean / 1.6 - 1.0).abs() < 0.1, "{early}");
    }

    /// What a sink is handed, bit for bit: the component, the parameters, the
    /// replaced index and every replica's delta (none when it comes shed).
    fn record(p: &Proposal, m: usize) -> String {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let delta: Vec<Vec<u64>> = match &p.delta {
            Delta::Same(v) => vec![bits(v)],
            Delta::Each(v) if v.is_empty() => Vec::new(),
            Delta::Each(_) => (0..m).map(|r| bits(p.delta.get(r))).collect(),
        };
        format!(
            "{} {:?} {} {:?} {:?} {}",
            p.kind, p.component, p.params, p.replaces, delta, p.note
        )
    }

    /// [`record`] with a joint candidate's second change, bit for bit.
    fn record_all(p: &Proposal, m: usize) -> String {
        let also = p.also.as_ref().map(|a| {
            let d: Vec<Vec<u64>> = (0..m)
                .map(|r| a.delta.get(r).iter().map(|x| x.to_bits()).collect())
                .collect();
            format!("{} {:?} {} {d:?}", a.comp, a.component, a.factor)
        });
        format!("{} {also:?}", record(p, m))
    }

    /// Every proposal of each state, and a joint rescale of its first component:
    /// the cross_axis ones (taken from the ensemble's other channels) come shed; shed
    /// and restored, each is the proposal as restored, bit for bit; the cross_axis and
    /// the joint one shed; and what scoring reads of a shed one without building it
    /// (`Proposal::change`, `Proposal::also_change`) changes every replica's sum
    /// exactly as the built change does.
    fn shed_and_restored_case(cxs: &[Context], m: usize) {
        for cx in cxs {
            let mut got = Vec::new();
            propose(cx, &mut |p| got.push(p)).unwrap();
            let mut joint = got[0].clone();
            joint.also = Some(Also::new(
                0,
                Component::WhiteNoise { n: 0.07 },
                0.4,
                cx.parts,
            ));
            got.push(joint);
            let mut n_shed = 0;
            for p in &got {
                assert_eq!(p.delta.is_shed(), p.kind == "cross_axis", "{}", p.kind);
                let mut full = p.clone();
                full.restore(cx);
                let mut q = full.clone();
                q.shed(cx);
                let shed = q.delta.is_shed() || q.also.as_ref().is_some_and(|a| a.delta.is_shed());
                n_shed += usize::from(shed);
                let noise_recalibration =
                    p.kind.starts_with("recalibrate:") && matches!(p.delta, Delta::Each(_));
                assert_eq!(
                    shed,
                    p.kind == "cross_axis" || p.also.is_some() || noise_recalibration,
                    "{}",
                    p.kind
                );
                // x + coef * signal, as the scoring adds it, against x + the built change
                let same_sums = |(sig, coef): (Vec<&[f64]>, f64), built: &Delta| {
                    assert_eq!(sig.len(), m, "{}", p.kind);
                    for (r, s) in sig.iter().enumerate() {
                        let d = built.get(r);
                        assert_eq!(s.len(), d.len(), "{}", p.kind);
                        for (t, ((x, v), b)) in cx.target[r].iter().zip(*s).zip(d).enumerate() {
                            assert_eq!(
                                (x + coef * v).to_bits(),
                                (x + 1.0 * b).to_bits(),
                                "{} replica {r} sample {t}",
                                p.kind
                            );
                        }
                    }
                };
                same_sums(q.change(cx), &full.delta);
                if let Some(a) = &full.also {
                    same_sums(q.also_change(cx.parts).unwrap(), &a.delta);
                }
                q.restore(cx);
                assert_eq!(record_all(&q, m), record_all(&full, m), "{}", p.kind);
            }
            assert!(n_shed >= 2, "{n_shed}");
        }
    }

    #[test]
    fn two_folds_step_by_step_propose_what_each_proposes_alone() {
        let n = 20_000;
        let m = 5;
        let names = vec!["y".to_string()];
        let sim = SimBase {
            n_samples: n,
            rate_hz: 100.0,
            temperature_c: None,
            seed: 5,
            replicas: m,
            base_dir: None,
        };
        // the "real" log: more noise, a random walk, a bias and a ramp than either state
        let truth = spec(vec![
            Component::WhiteNoise { n: 0.06 },
            Component::RateRandomWalk { k: 0.01 },
            Component::ConstantBias { value: 0.3 },
            Component::RateRamp { r: 1e-4 },
        ]);
        let real_sim = SimBase {
            replicas: 1,
            seed: 9,
            ..sim.clone()
        };
        let real = real_sim
            .channels(&truth, &["x".to_string(), "y".to_string()])
            .unwrap()
            .pop()
            .unwrap();
        let others = vec![("y".to_string(), real[1].as_slice())];
        let blocks = Blocks::interleaved(n, 8, 0.5).unwrap();
        let trains = [true, false].map(|t| Layout::new(&blocks, t, 100.0, None, &names));
        let bi = |b: f64| Component::BiasInstability {
            b,
            tau_min_s: None,
            tau_max_s: None,
        };
        // two states with as many components (the unit signals of an added component
        // are the same in both: gauss_markov's grid is simulated once for both), and
        // two with a different count
        for specs in [
            [
                spec(vec![
                    Component::WhiteNoise { n: 0.05 },
                    Component::ConstantBias { value: 0.1 },
                    bi(0.004),
                ]),
                spec(vec![
                    Component::WhiteNoise { n: 0.04 },
                    Component::ConstantBias { value: 0.2 },
                    bi(0.01),
                ]),
            ],
            [
                spec(vec![
                    Component::WhiteNoise { n: 0.05 },
                    Component::ConstantBias { value: 0.1 },
                ]),
                spec(vec![
                    Component::WhiteNoise { n: 0.04 },
                    Component::ConstantBias { value: 0.2 },
                    bi(0.01),
                ]),
            ],
        ] {
            two_folds_case(&specs, &sim, &real, &others, &trains, &names, m, n);
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn two_folds_case(
        specs: &[Spec; 2],
        sim: &SimBase,
        real: &[Vec<f64>],
        others: &[(String, &[f64])],
        trains: &[Layout; 2],
        names: &[String],
        m: usize,
        n: usize,
    ) {
        let ens: Vec<_> = specs
            .iter()
            .map(|sp| {
                let k: Vec<usize> = (0..sp.channels[0].components.len()).collect();
                let sig = sim.component_signals(sp, 0, &k).unwrap();
                let target: Vec<std::sync::Arc<Vec<f64>>> = sig
                    .iter()
                    .map(|p| {
                        std::sync::Arc::new(
                            (0..n)
                                .map(|t| p.iter().fold(0.0, |a, v| a + v[t]))
                                .collect(),
                        )
                    })
                    .collect();
                let parts: Vec<Vec<Arc<Vec<f64>>>> = sig
                    .into_iter()
                    .map(|p| p.into_iter().map(Arc::new).collect())
                    .collect();
                (target, parts, sim.channels(sp, names).unwrap())
            })
            .collect();
        let cxs: Vec<Context> = (0..2)
            .map(|f| Context {
                spec: &specs[f],
                channel: 0,
                sim,
                train: &trains[f],
                real: &real[0],
                beyond: &[],
                temperature: None,
                others,
                sim_others: &ens[f].2,
                target: &ens[f].0,
                parts: &ens[f].1,
            })
            .collect();
        shed_and_restored_case(&cxs, m);
        // each state alone
        let alone: Vec<(Vec<String>, Vec<String>)> = cxs
            .iter()
            .map(|cx| {
                let mut got = Vec::new();
                let skipped = propose(cx, &mut |p| got.push(record(&p, m))).unwrap();
                (got, skipped.iter().map(|s| format!("{s:?}")).collect())
            })
            .collect();
        assert!(alone.iter().all(|(g, _)| g.len() >= 5));
        assert!(
            alone
                .iter()
                .all(|(g, _)| g.iter().any(|p| p.starts_with("gauss_markov")))
        );
        // both, step by step: the order in which the two sinks are handed proposals
        let order: RefCell<Vec<usize>> = RefCell::new(Vec::new());
        let mut got: [Vec<String>; 2] = Default::default();
        let [g0, g1] = &mut got;
        let skipped = propose_folds(
            [&cxs[0], &cxs[1]],
            [
                &mut |p| {
                    order.borrow_mut().push(0);
                    g0.push(record(&p, m))
                },
                &mut |p| {
                    order.borrow_mut().push(1);
                    g1.push(record(&p, m))
                },
            ],
        )
        .unwrap();
        for f in 0..2 {
            assert_eq!(got[f], alone[f].0, "fold {f}");
            let s: Vec<String> = skipped[f].iter().map(|s| format!("{s:?}")).collect();
            assert_eq!(s, alone[f].1, "fold {f}");
        }
        // interleaved: the first state's proposals do not all come before the second's
        let order = order.into_inner();
        let last0 = order.iter().rposition(|&f| f == 0).unwrap();
        let first1 = order.iter().position(|&f| f == 1).unwrap();
        assert!(first1 < last0, "{order:?}");
        // one kind at a time: what the two states are handed of that kind
        let kind_of = |r: &String| r.split(' ').next().unwrap_or("").to_string();
        let mut kinds: Vec<String> = got.iter().flatten().map(kind_of).collect();
        kinds.sort();
        kinds.dedup();
        assert!(kinds.len() >= 5, "{kinds:?}");
        for kind in &kinds {
            let mut one: [Vec<String>; 2] = Default::default();
            let [o0, o1] = &mut one;
            propose_kind_folds(
                [&cxs[0], &cxs[1]],
                kind,
                [&mut |p| o0.push(record(&p, m)), &mut |p| {
                    o1.push(record(&p, m))
                }],
            )
            .unwrap();
            for f in 0..2 {
                let want: Vec<String> = got[f]
                    .iter()
                    .filter(|r| &kind_of(r) == kind)
                    .cloned()
                    .collect();
                assert_eq!(one[f], want, "fold {f}, kind {kind}");
            }
        }
    }

    /// What [`gm_state`] builds: the ensemble's base, the training layout, the
    /// replicas' sums and their component signals.
    type GmState = (
        SimBase<'static>,
        Layout,
        Vec<Arc<Vec<f64>>>,
        Vec<Vec<Arc<Vec<f64>>>>,
    );

    /// A state of `spec`'s ensemble (M replicas on n samples at 100 Hz) against the
    /// real log `real`, trained on the first half of 8 blocks.
    /// Channel "x" of `truth` simulated once at `rate_hz` (no temperature): a test's
    /// real log.
    fn real_of(truth: &Spec, n: usize, rate_hz: f64, seed: u64) -> Vec<f64> {
        SimBase {
            n_samples: n,
            rate_hz,
            temperature_c: None,
            seed,
            replicas: 1,
            base_dir: None,
        }
        .channels(truth, &["x".to_string()])
        .unwrap()
        .pop()
        .unwrap()
        .pop()
        .unwrap()
    }

    /// The estimation context of channel 0 of `spec` against `real` on the state `st`
    /// ([`gm_state`]): no temperature, no other channel.
    fn cx_of<'a>(spec: &'a Spec, real: &'a [f64], st: &'a GmState) -> Context<'a> {
        Context {
            spec,
            channel: 0,
            sim: &st.0,
            train: &st.1,
            real,
            beyond: &[],
            temperature: None,
            others: &[],
            sim_others: &[],
            target: &st.2,
            parts: &st.3,
        }
    }

    fn gm_state(spec: &Spec, real: &[f64], m: usize) -> GmState {
        let n = real.len();
        let sim = SimBase {
            n_samples: n,
            rate_hz: 100.0,
            temperature_c: None,
            seed: 11,
            replicas: m,
            base_dir: None,
        };
        let train = Layout::new(
            &Blocks::interleaved(n, 8, 0.5).unwrap(),
            true,
            100.0,
            None,
            &[],
        );
        let k: Vec<usize> = (0..spec.channels[0].components.len()).collect();
        let sig = sim.component_signals(spec, 0, &k).unwrap();
        let target = sig
            .iter()
            .map(|p| Arc::new((0..n).map(|t| p.iter().map(|v| v[t]).sum()).collect()))
            .collect();
        let parts = sig
            .into_iter()
            .map(|p| p.into_iter().map(Arc::new).collect())
            .collect();
        (sim, train, target, parts)
    }

    /// A warm-up and a rate ramp missing at once: each single fit bends towards the
    /// other (the ramp's slope takes the warm-up's decay as a fall, the warm-up's
    /// amplitude the ramp's early rise); backfitted as a pair ([`joint::joint_pairs`])
    /// both come back near the truth, nearer than either fitted alone (single fits on
    /// this log: r 0.000145 for 0.0005, amplitude 0.143 for 0.3; joint: 0.000467,
    /// 0.284, tau 75.7 s for 80 s; with plain backfitting instead of the variable
    /// projection, four passes reached only 0.000434, 0.279 and 65 s).
    #[test]
    fn a_warmup_and_a_ramp_missing_together_are_fitted_jointly() {
        let n = 60_000;
        let base = spec(vec![
            Component::ConstantBias { value: 0.0 },
            Component::WhiteNoise { n: 0.02 },
        ]);
        let mut truth = base.clone();
        truth.channels[0].components.extend([
            Component::Warmup {
                amplitude: 0.3,
                tau_s: 80.0,
            },
            Component::RateRamp { r: 0.0005 },
        ]);
        let real = real_of(&truth, n, 100.0, 4);
        let st = gm_state(&base, &real, 10);
        let cx = cx_of(&base, &real, &st);
        let ramp_of = |p: &Proposal| match p.component {
            Component::RateRamp { r } => Some(r),
            _ => None,
        };
        let warmup_of = |p: &Proposal| match p.component {
            Component::Warmup { amplitude, tau_s } => Some((amplitude, tau_s)),
            _ => None,
        };
        // the single fits
        let mut singles = Vec::new();
        propose(&cx, &mut |p| singles.push(p)).unwrap();
        let r1 = singles.iter().find_map(ramp_of).unwrap();
        let (a1, _) = singles.iter().find_map(warmup_of).unwrap();
        // the pair
        let pairs = joint::joint_pairs([&cx, &cx], None).unwrap();
        let pair = pairs
            .iter()
            .find(|p| ramp_of(&p[0][0]).is_some() && warmup_of(&p[0][1]).is_some())
            .expect("the ramp and the warm-up as a pair");
        assert_eq!(pair[0][0].params, pair[1][0].params, "the same state twice");
        let r2 = ramp_of(&pair[0][0]).unwrap();
        let (a2, tau2) = warmup_of(&pair[0][1]).unwrap();
        let rel = |x: f64, t: f64| (x / t - 1.0).abs();
        assert!(rel(r2, 0.0005) < 0.1, "joint r {r2}");
        assert!(rel(a2, 0.3) < 0.1, "joint amplitude {a2}");
        assert!(rel(tau2, 80.0) < 0.1, "joint tau {tau2}");
        assert!(
            rel(r1, 0.0005) > 2.0 * rel(r2, 0.0005),
            "single r {r1}, joint {r2}"
        );
        assert!(
            rel(a1, 0.3) > rel(a2, 0.3),
            "single amplitude {a1}, joint {a2}"
        );
    }

    /// A constant bias and a rate ramp missing together (a spec without a constant
    /// bias): the pair is among those fitted jointly, with both sizes near the truth.
    /// Ranked with an intercept, the pair scored as the ramp alone (the constant is the
    /// intercept) and was not among the two fitted.
    #[test]
    fn a_constant_bias_and_a_ramp_missing_together_are_fitted_as_a_pair() {
        let n = 60_000;
        let base = spec(vec![Component::WhiteNoise { n: 0.02 }]);
        let mut truth = base.clone();
        truth.channels[0].components.extend([
            Component::ConstantBias { value: -0.05 },
            Component::RateRamp { r: 0.0002 },
        ]);
        let real = real_of(&truth, n, 100.0, 5);
        let st = gm_state(&base, &real, 10);
        let cx = cx_of(&base, &real, &st);
        let pairs = joint::joint_pairs([&cx, &cx], None).unwrap();
        let of = |p: &[Proposal; 2]| {
            let mut c = None;
            let mut r = None;
            for q in p {
                match q.component {
                    Component::ConstantBias { value } => c = Some(value),
                    Component::RateRamp { r: v } => r = Some(v),
                    _ => {}
                }
            }
            c.zip(r)
        };
        let (c, r) = pairs
            .iter()
            .find_map(|p| of(&p[0]))
            .expect("the constant bias and the ramp as a pair");
        let rel = |x: f64, t: f64| (x / t - 1.0).abs();
        assert!(rel(c, -0.05) < 0.1, "joint constant {c}");
        assert!(rel(r, 0.0002) < 0.1, "joint r {r}");
    }

    #[test]
    fn the_closed_form_gauss_markov_avar_is_the_simulated_mean_and_finds_tau() {
        let n = 40_000;
        let base = spec(vec![Component::WhiteNoise { n: 0.02 }]);
        let mut truth = base.clone();
        truth.channels[0].components.push(Component::GaussMarkov {
            sigma: 0.05,
            tau_s: 3.0,
        });
        let real = SimBase {
            n_samples: n,
            rate_hz: 100.0,
            temperature_c: None,
            seed: 3,
            replicas: 1,
            base_dir: None,
        }
        .channels(&truth, &["x".to_string()])
        .unwrap()
        .pop()
        .unwrap()
        .pop()
        .unwrap();
        let m = 40;
        let (sim, train, target, parts) = gm_state(&base, &real, m);
        let cx = Context {
            spec: &base,
            channel: 0,
            sim: &sim,
            train: &train,
            real: &real,
            beyond: &[],
            temperature: None,
            others: &[],
            sim_others: &[],
            target: &target,
            parts: &parts,
        };
        let tr = Training::new(&cx);
        // the slow twin: the mean over 40 replicas of the simulated unit signal's
        // training AVAR, within its sampling error where a block holds 20 clusters or
        // more (relative sd about sqrt(m / n_block / M) there)
        let block = cx.ranges().iter().map(|r| r.len()).min().unwrap();
        for tau in [0.05, 0.8, 3.0, 20.0] {
            let closed = noise::gm_unit_avar(&tr.ms, 100.0, tau);
            let simulated = noise::unit_mean_avar(&cx, &noise::gm_unit(tau)).unwrap();
            for (i, &mm) in tr.ms.iter().enumerate() {
                if 20 * mm > block {
                    continue;
                }
                let rel = simulated[i] / closed[i] - 1.0;
                let sd = (mm as f64 / block as f64 / m as f64).sqrt();
                assert!(rel.abs() < 0.05 + 4.0 * sd, "tau {tau}, m {mm}: {rel}");
            }
        }
        // the estimate: tau and sigma near the truth, inside the range, not flagged
        let mut got = Vec::new();
        let mut out = Found {
            sink: &mut |p: Proposal| got.push(p),
            skipped: Vec::new(),
        };
        noise::gauss_markov(&cx, &tr, &mut out).unwrap();
        drop(out);
        let Some(Component::GaussMarkov { sigma, tau_s }) = got.first().map(|p| &p.component)
        else {
            panic!("no gauss_markov proposal");
        };
        assert!((tau_s / 3.0).ln().abs() < 0.4, "tau_s {tau_s}");
        assert!((sigma / 0.05).ln().abs() < 0.2, "sigma {sigma}");
        assert!(got[0].params.get("at_search_edge").is_none());
        // the grid's best of the slow twin lies within a grid step or two of it
        let grid = lsq::log_grid(0.02, 50.0, 12);
        let (_, tau_sim, _) = noise::gauss_markov_by_simulation(&cx, &tr, &grid)
            .unwrap()
            .unwrap();
        let step = (50.0f64 / 0.02).ln() / 11.0;
        assert!(
            (tau_sim / tau_s).ln().abs() <= 2.0 * step,
            "{tau_sim} vs {tau_s}"
        );
    }
}
