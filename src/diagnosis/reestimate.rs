//! Re-estimation of the effects the search keeps: an effect estimated while another
//! one was still in the residual comes out biased (a Gauss-Markov process takes a
//! sinusoid's variance, a temperature bias the part of a thermal-rate drift that
//! follows the temperature), and greedy forward steps never revisit it. After each
//! addition, each earlier effect is estimated again with the others in place
//! (one Gauss-Seidel sweep of backfitting: Hastie and Tibshirani 1990, "Generalized
//! Additive Models", section 4.3), on both folds as a forward step estimates it, and
//! replaces the old estimate when the withheld gap falls; when one did, the newest
//! effect is estimated again as well, since it was fitted against the old one.

use super::candidates::{self, Context, Proposal};
use super::ensemble::SimBase;
use super::features::{Layout, Temperature};
use super::{
    Effect, EnsembleStats, Round, Slot, State, Statistic, Step, apply, pair_key, removable,
    take_back,
};
use crate::error::Result;

/// The replicas' features of both folds' states, each state's sum plus the given
/// change (one signal per replica) when there is one.
pub(super) type FeatsFn<'a> = dyn Fn(&[State; 2], [Option<&[&[f64]]>; 2]) -> Vec<Vec<f64>> + 'a;
/// The withheld score of the replicas' features: gap, ensemble statistics, family gaps.
pub(super) type ScoreFn<'a> =
    dyn Fn(&[Vec<f64>]) -> (f64, EnsembleStats, Vec<(Statistic, f64)>) + 'a;

/// What re-estimation reads from the diagnosis: the log and the simulation base the
/// forward steps estimate on, and the scoring they use.
pub(super) struct Refit<'a> {
    pub channel: usize,
    pub replicas: usize,
    pub sim: &'a SimBase<'a>,
    /// The withheld layouts of fold 1 and fold 2 (each fold trains on the other's).
    pub withheld: &'a [Layout; 2],
    pub real: &'a [f64],
    pub temperature: Option<&'a Temperature>,
    pub others: &'a [(String, &'a [f64])],
    pub sim_others: &'a [Vec<Vec<f64>>],
    pub feats: &'a FeatsFn<'a>,
    pub score: &'a ScoreFn<'a>,
}

/// Where the search stands: both folds' states, the slots and effects kept (in the
/// order they were added), the gap and ensemble statistics of the joint model, and the
/// steps so far.
pub(super) struct Search<'s> {
    pub sts: &'s mut [State; 2],
    pub slots: &'s mut Vec<[Slot; 2]>,
    pub added: &'s mut Vec<Effect>,
    pub gap_now: &'s mut f64,
    pub ens_now: &'s mut EnsembleStats,
    pub steps: &'s mut Vec<Step>,
}

impl Refit<'_> {
    /// Fold f's estimation context for state `st`: it trains on the other fold's
    /// withheld part, as the forward steps do.
    fn cx<'b>(&'b self, st: &'b State, f: usize) -> Context<'b> {
        Context {
            spec: &st.spec,
            channel: self.channel,
            sim: self.sim,
            train: &self.withheld[1 - f],
            real: self.real,
            temperature: self.temperature,
            others: self.others,
            sim_others: self.sim_others,
            target: &st.target,
            parts: &st.parts,
        }
    }

    /// After an addition (the last of `s.added`): each earlier effect re-estimated in
    /// turn, from the earliest, then the newest when any earlier one changed. Each
    /// re-estimation that lowers the gap is a step `reestimate`; the effect moves to
    /// the end of the kept list (its step is the re-estimation's).
    pub fn after_addition(&self, s: &mut Search) -> Result<()> {
        let Some(newest) = s.added.last().and_then(|e| e.step) else {
            return Ok(());
        };
        let earlier: Vec<usize> = s.added.iter().filter_map(|e| e.step).collect();
        let mut changed = false;
        for id in earlier.into_iter().filter(|&id| id != newest) {
            changed |= self.one(s, id)?;
        }
        if changed {
            self.one(s, newest)?;
        }
        Ok(())
    }

    /// Re-estimates the kept effect added at step `id` (when it can be taken back and
    /// is not an output-path effect, whose estimation depends on the path); returns
    /// whether it was replaced.
    fn one(&self, s: &mut Search, id: usize) -> Result<bool> {
        let Some(i) = s.added.iter().position(|e| e.step == Some(id)) else {
            return Ok(false);
        };
        if !removable(s.slots, i) || s.slots[i][0].path || s.slots[i][1].path {
            return Ok(false);
        }
        let kind = s.added[i].kind.clone();
        // both folds' states with the effect taken out, the others in
        let mut trial = s.sts.clone();
        let mut trial_slots = s.slots.clone();
        let [s0, s1] = trial_slots.remove(i);
        take_back(
            &mut trial[0],
            self.channel,
            s0,
            trial_slots.iter_mut().map(|x| &mut x[0]),
        );
        take_back(
            &mut trial[1],
            self.channel,
            s1,
            trial_slots.iter_mut().map(|x| &mut x[1]),
        );
        let (gap_without, _, _) = (self.score)(&(self.feats)(&trial, [None, None]));
        let mut props: [Vec<Proposal>; 2] = Default::default();
        {
            let [p0, p1] = &mut props;
            candidates::propose_kind_folds(
                [&self.cx(&trial[0], 0), &self.cx(&trial[1], 1)],
                &kind,
                [&mut |p| p0.push(p), &mut |p| p1.push(p)],
            )?;
        }
        let [ps0, mut ps1] = props;
        let mut round = Round::default();
        for p in ps0 {
            let Some(j) = ps1.iter().position(|q| pair_key(q) == pair_key(&p)) else {
                continue;
            };
            let q = ps1.remove(j);
            let d0: Vec<&[f64]> = (0..self.replicas).map(|r| p.delta.get(r)).collect();
            let d1: Vec<&[f64]> = (0..self.replicas).map(|r| q.delta.get(r)).collect();
            let f = (self.feats)(&trial, [Some(&d0), Some(&d1)]);
            let scored = (self.score)(&f);
            round.offer([p, q], f, scored, gap_without);
        }
        let Some((mut eff, e, [p0, p1], _)) = round.best else {
            return Ok(false);
        };
        if eff.gap_after >= *s.gap_now {
            return Ok(false);
        }
        trial_slots.push([
            apply(&mut trial[0], self.channel, p0),
            apply(&mut trial[1], self.channel, p1),
        ]);
        *s.sts = trial;
        *s.slots = trial_slots;
        s.steps.push(Step {
            action: "reestimate",
            kind: eff.kind.clone(),
            gap_before: *s.gap_now,
            gap_after: eff.gap_after,
            runner_up: None,
            runner_up_gap_after: None,
            difference_sd: None,
            tie: false,
        });
        eff.step = Some(s.steps.len());
        *s.gap_now = eff.gap_after;
        *s.ens_now = e;
        s.added.remove(i);
        s.added.push(eff);
        Ok(true)
    }
}
