//! Re-estimation of the effects the search keeps: an effect estimated while another
//! one was still in the residual comes out biased (a Gauss-Markov process takes a
//! sinusoid's variance, a temperature bias the part of a thermal-rate drift that
//! follows the temperature), and greedy forward steps never revisit it. After each
//! addition, each earlier effect is estimated again with the others in place
//! (one Gauss-Seidel sweep of backfitting: Hastie and Tibshirani 1990, "Generalized
//! Additive Models", section 4.3), on both folds as a forward step estimates it, and
//! replaces the old estimate when the withheld gap falls; when one did, the newest
//! effect is estimated again as well, since it was fitted against the old one.
//!
//! Which effect a round adds is judged the same way: the round's best and its rivals
//! ([`rivals`]: the round's runner-up and the first round's candidates, each of which
//! shrank the gap by `min_shrink` on its own when it was scored) are each added, on a
//! copy of the search, with the earlier effects re-estimated, and the one with the
//! lowest joint gap is kept. A candidate the log showed evidence for at the start
//! (a sinusoid, a thermal-rate drift) that an earlier effect partly absorbed (a
//! Gauss-Markov process taking the sinusoid's variance, a temperature bias the part
//! of the drift that follows the temperature) ranks low on its own in later rounds,
//! but wins once the earlier effect is estimated again beside it.

use super::candidates::output_path::Asked;
use super::candidates::{self, Context, Proposal};
use super::ensemble::{self, SimBase};
use super::features::{Layout, Temperature};
use super::{
    Effect, EnsembleStats, JointBest, Round, SCREEN_RATIO, Slot, State, Statistic, Step, apply,
    form, pair_across_forms, pair_by, pair_key, refits_path, removable, take_back,
};
use crate::error::Result;
use crate::simulator::{Component, Kind};

/// Most candidates besides a round's best tried with the earlier effects re-estimated
/// (each costs a copy of both folds' ensembles and one re-estimation per kept effect).
pub(super) const RIVALS: usize = 4;

/// A round's rivals of its best (`round[0]`; `round` and `first`, the first round's
/// candidates, sorted best first): the round's runner-up when its gap is within
/// `admissible[0]`, then the first round's candidates whose gap was within
/// `admissible[1]`, none of the best's kind, of a kind kept in `added`, or on the
/// output path, each (kind, replaced component, form) once, at most [`RIVALS`].
pub(super) fn rivals<'e>(
    round: &'e [Effect],
    first: &'e [Effect],
    added: &[Effect],
    admissible: [f64; 2],
) -> Vec<&'e Effect> {
    let Some(best) = round.first() else {
        return Vec::new();
    };
    let key = |e: &Effect| (e.kind.clone(), e.replaces, form(&e.component));
    let mut out: Vec<&Effect> = Vec::new();
    let runner_up = round.get(1).filter(|e| e.gap_after <= admissible[0]);
    for e in runner_up
        .into_iter()
        .chain(first.iter().filter(|e| e.gap_after <= admissible[1]))
    {
        if e.kind == best.kind
            || added.iter().any(|a| a.kind == e.kind)
            || e.component.kind().is_output_path()
            || out.iter().any(|o| key(o) == key(e))
        {
            continue;
        }
        out.push(e);
        if out.len() == RIVALS {
            break;
        }
    }
    out
}

/// The steps of the kept effects that [`Refit::bounds_again`] estimates again, other
/// than the round's addition `newest` (none when `newest` was taken back): those with
/// a parameter at the edge of its search range or not determined by the data
/// (`undetermined`), and a heteroskedastic scale when `newest` is a random noise
/// ([`reads_other_noise`]).
pub(super) fn bounds(added: &[Effect], newest: usize) -> Vec<usize> {
    let Some(new) = added.iter().find(|e| e.step == Some(newest)) else {
        return Vec::new();
    };
    let noise_added = !ensemble::is_deterministic(&new.component)
        && !new.component.kind().is_output_path()
        && !reads_other_noise(new);
    added
        .iter()
        .filter(|e| {
            !e.at_edge.is_empty()
                || !e.undetermined.is_empty()
                || (noise_added && reads_other_noise(e))
        })
        .filter_map(|e| e.step)
        .filter(|&id| id != newest)
        .collect()
}

/// Whether `e`'s estimate reads the variance of the differences that the other noise
/// components leave: a heteroskedastic scale, whose level and floor are fitted to the
/// squared differences less that variance (`candidates::temperature`), so that a
/// random noise added after it (a bias instability whose differences the clamped
/// scale's floor had taken) leaves it biased until it is estimated again.
fn reads_other_noise(e: &Effect) -> bool {
    matches!(e.component, Component::Heteroskedastic { .. })
}

/// The replicas' features of both folds' states, each state's sum plus the given
/// change (one signal per replica) when there is one.
pub(super) type FeatsFn<'a> = dyn Fn(&[State; 2], [Option<&[&[f64]]>; 2]) -> Vec<Vec<f64>> + 'a;
/// The withheld score of the replicas' features: gap, ensemble statistics, family gaps.
pub(super) type ScoreFn<'a> =
    dyn Fn(&[Vec<f64>]) -> (f64, EnsembleStats, Vec<(Statistic, f64)>) + 'a;

/// What re-estimation reads from the diagnosis: the log and the simulation base the
/// forward steps estimate on, and the scoring they use.
pub(super) struct Refit<'a> {
    /// False: no rivals, and only the effects estimated at the edge of a search range
    /// are estimated again after an addition ([`Refit::bounds_again`]).
    pub enabled: bool,
    pub channel: usize,
    pub replicas: usize,
    pub sim: &'a SimBase<'a>,
    /// The withheld layouts of fold 1 and fold 2 (each fold trains on the other's).
    pub withheld: &'a [Layout; 2],
    pub real: &'a [f64],
    /// The channel's samples after `real` that only train ([`crate::diagnosis::RealLog::beyond`]).
    pub beyond: &'a [f64],
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

/// The most passes over the kept effects, each estimated again in turn, of
/// [`Refit::backfit`] (after an earlier bias is taken back or exchanged): backfitting
/// (Buja, Hastie and Tibshirani 1989), stopped early when a pass changes nothing.
const BACKFIT_PASSES: usize = 3;

/// An owned copy of the search's state ([`Search`]), for trying an addition.
#[derive(Clone)]
struct Trial {
    sts: [State; 2],
    slots: Vec<[Slot; 2]>,
    added: Vec<Effect>,
    gap_now: f64,
    ens_now: EnsembleStats,
    steps: Vec<Step>,
}

impl Trial {
    fn of(s: &Search) -> Self {
        Trial {
            sts: s.sts.clone(),
            slots: s.slots.clone(),
            added: s.added.clone(),
            gap_now: *s.gap_now,
            ens_now: s.ens_now.clone(),
            steps: s.steps.clone(),
        }
    }

    fn search(&mut self) -> Search<'_> {
        Search {
            sts: &mut self.sts,
            slots: &mut self.slots,
            added: &mut self.added,
            gap_now: &mut self.gap_now,
            ens_now: &mut self.ens_now,
            steps: &mut self.steps,
        }
    }

    fn write_back(self, s: &mut Search) {
        *s.sts = self.sts;
        *s.slots = self.slots;
        *s.added = self.added;
        *s.gap_now = self.gap_now;
        *s.ens_now = self.ens_now;
        *s.steps = self.steps;
    }
}

/// A round's best candidate: its proposals (fold 1's, fold 2's), effect, ensemble
/// statistics and the `add` step that reports it.
pub(super) type Added = ([Proposal; 2], Effect, EnsembleStats, Step);

impl Refit<'_> {
    /// Adds `a` to the search: its proposals applied to both folds' states, its step
    /// recorded, then the earlier effects re-estimated ([`Refit::after_addition`]).
    pub fn add(&self, s: &mut Search, a: Added) -> Result<()> {
        self.push(s, a);
        if self.enabled {
            self.after_addition(s)?;
        }
        Ok(())
    }

    /// Adds `a` to the search (its proposals applied to both folds' states, its step
    /// recorded), nothing estimated again.
    fn push(&self, s: &mut Search, a: Added) {
        let ([p0, p1], mut eff, e, step) = a;
        s.slots.push([
            apply(&mut s.sts[0], self.channel, p0),
            apply(&mut s.sts[1], self.channel, p1),
        ]);
        s.steps.push(step);
        eff.step = Some(s.steps.len());
        *s.ens_now = e;
        *s.gap_now = eff.gap_after;
        s.added.push(eff);
    }

    /// Without re-estimation (the default): once a round's addition and backward steps
    /// are done, the earlier effects whose estimate stopped at the edge of its search
    /// range (`at_edge`) and that the backward steps kept are estimated again with the
    /// newest in place, then the newest when one of them changed. A bound, not an
    /// estimate, is what an effect missing from the residual often leaves behind in
    /// another's fit (a thermal rate whose lag and smoothing run to the top of their
    /// ranges while it stands in for part of a temperature bias); the others keep their
    /// estimates, and the states are copied only for these. `newest`: the step that
    /// added the round's effect (nothing is done when it was taken back).
    pub fn bounds_again(&self, s: &mut Search, newest: usize) -> Result<()> {
        let mut changed = false;
        for id in bounds(s.added, newest) {
            changed |= self.one(s, id)?;
        }
        if changed {
            self.one(s, newest)?;
        }
        Ok(())
    }

    /// Adds the round's best `best`, or, when the search already keeps effects, the
    /// one of `best` and `rivals` ([`rivals`]) whose joint gap with the earlier
    /// effects re-estimated is lowest (at equal gaps the earlier ranks first). Returns
    /// a note when a rival was added instead of the best.
    pub fn add_best_of(
        &self,
        s: &mut Search,
        best: Added,
        rivals: &[&Effect],
    ) -> Result<Option<String>> {
        if !self.enabled || s.added.is_empty() || rivals.is_empty() {
            self.add(s, best)?;
            return Ok(None);
        }
        let (best_kind, best_gap) = (best.1.kind.clone(), best.1.gap_after);
        let mut won = Trial::of(s);
        self.add(&mut won.search(), best)?;
        let mut winner: Option<&Effect> = None;
        for r in rivals {
            let mut t = Trial::of(s);
            let Some(a) = self.estimate(&t, r, &best_kind, best_gap)? else {
                continue;
            };
            self.add(&mut t.search(), a)?;
            if t.gap_now < won.gap_now {
                won = t;
                winner = Some(r);
            }
        }
        let note = winner.map(|r| {
            format!(
                "{} added instead of {} (the round's best, gap {:.3}): with the earlier effects estimated again beside it, the joint gap is {:.3}",
                r.kind, best_kind, best_gap, won.gap_now
            )
        });
        won.write_back(s);
        Ok(note)
    }

    /// When the round's best (`best`: its kind and gap) shrinks the gap too little:
    /// the rival whose joint gap, added with the earlier effects re-estimated, is
    /// lowest and within `needed`, added; returns a note, or None (nothing added)
    /// when no rival reaches `needed` or the search keeps no effect yet.
    pub fn rival_instead(
        &self,
        s: &mut Search,
        rivals: &[&Effect],
        best: (&str, f64),
        needed: f64,
    ) -> Result<Option<String>> {
        if !self.enabled || s.added.is_empty() {
            return Ok(None);
        }
        let mut won: Option<(Trial, &Effect)> = None;
        for &r in rivals {
            let mut t = Trial::of(s);
            let Some(a) = self.estimate(&t, r, best.0, best.1)? else {
                continue;
            };
            self.add(&mut t.search(), a)?;
            if t.gap_now <= needed && won.as_ref().is_none_or(|w| t.gap_now < w.0.gap_now) {
                won = Some((t, r));
            }
        }
        let Some((t, r)) = won else {
            return Ok(None);
        };
        let note = format!(
            "{} added though the round's best ({}, gap {:.3}) shrinks the gap too little: with the earlier effects estimated again beside it, the joint gap is {:.3}",
            r.kind, best.0, best.1, t.gap_now
        );
        t.write_back(s);
        Ok(Some(note))
    }

    /// The pair of a coarse output resolution and a filter fitted with it (by
    /// simulation, [`candidates::path_fit`], or to the PSD's roll-off), tried on a copy
    /// of the search when the round proposed the resolution (`res`, the better of its
    /// rounding forms) and the spec has none: with the rounding coarse against the
    /// log's short-term noise, neither shows alone (the rounding of an unfiltered
    /// simulation leaves many more level changes than the real log's few; a filter
    /// without the rounding leaves every value off the grid), so a greedy step takes
    /// neither or another effect first. The resolution is estimated again and added on
    /// the copy, then the filters fitted by simulation beside it (each with the
    /// rounding in its fitted form) and, when the spec has no filter, those read off
    /// the PSD's roll-off (and the MA(1) FIR) with the rounding in the spec are scored;
    /// the best is kept when its joint gap is below `below` (the round's best single
    /// effect's gap and the margin a forward step needs) and below the resolution's own
    /// gap by `min_shrink`, the margin its own forward step would need. Two steps are
    /// recorded, one per effect, and each can be taken back like any other (the
    /// resolution only after the filter, which set its rounding form). Returns a note,
    /// or None when the pair is not kept (or not tried: a rounding that is not
    /// coarse, [`candidates::path_fit::coarse`], in either fold).
    pub fn path_pair(
        &self,
        s: &mut Search,
        res: &Effect,
        best: (&str, f64),
        below: f64,
        min_shrink: f64,
    ) -> Result<Option<String>> {
        let Component::OutputResolution { quantum, .. } = res.component else {
            return Ok(None);
        };
        let has = |st: &State, k: Kind| {
            st.spec.channels[self.channel]
                .components
                .iter()
                .any(|c| c.kind() == k)
        };
        if has(&s.sts[0], Kind::OutputResolution)
            || !(0..2).all(|f| {
                candidates::path_fit::coarse(self.real, self.withheld[1 - f].ranges(), quantum)
            })
        {
            return Ok(None);
        }
        // fold 1's and fold 2's output-path proposals of `kind` on `sts` that `keep`
        // keeps, paired by form, else by kind, each pair scored through the path it
        // sets (applied to a copy of the states: a path component moves no sum, so the
        // copy shares the sums) and offered to a round
        let scored_pairs = |sts: &[State; 2],
                            gap_ref: f64,
                            asked: Asked,
                            kind: &str,
                            keep: &dyn Fn(&Proposal) -> bool|
         -> Result<Round> {
            // each held shed (`Proposal::shed`: a white noise refitted beside a filter
            // is a signal per replica, rebuilt from the state), restored to be scored,
            // and the round's best restored once all are scored
            let cxs = [self.cx(&sts[0], 0), self.cx(&sts[1], 1)];
            let mut props: [Vec<Proposal>; 2] = Default::default();
            for (f, ps) in props.iter_mut().enumerate() {
                candidates::output_path::proposals(&cxs[f], true, asked, &mut |mut p| {
                    if p.kind == kind && keep(&p) {
                        p.shed(&cxs[f]);
                        ps.push(p)
                    }
                })?;
            }
            // by form first, then the rest across forms, as a round pairs them
            let [ps0, mut ps1] = props;
            let (mut pairs, left) = pair_by(ps0, &mut ps1, pair_key);
            pairs.extend(pair_across_forms(left, &mut ps1).0);
            let mut round = Round::default();
            for (mut p, mut q) in pairs {
                p.restore(&cxs[0]);
                q.restore(&cxs[1]);
                let mut copy = sts.clone();
                apply(&mut copy[0], self.channel, p.clone());
                apply(&mut copy[1], self.channel, q.clone());
                let f = (self.feats)(&copy, [None, None]);
                drop(copy);
                let scored = (self.score)(&f);
                p.shed(&cxs[0]);
                q.shed(&cxs[1]);
                round.offer([p, q], f, scored, gap_ref);
            }
            if let Some((_, _, pq, _)) = round.best.as_mut() {
                pq[0].restore(&cxs[0]);
                pq[1].restore(&cxs[1]);
            }
            Ok(round)
        };
        let mut t = Trial::of(s);
        let gap_was = t.gap_now;
        // the resolution in the rounding form of `res`
        let round = scored_pairs(
            &t.sts,
            gap_was,
            Asked::Resolution,
            "output_resolution",
            &|p| form(&p.component) == form(&res.component),
        )?;
        let Some((res_eff, e, props, _)) = round.best else {
            return Ok(None);
        };
        let gap_res = res_eff.gap_after;
        let step = Step {
            runner_up: Some(best.0.to_string()),
            runner_up_gap_after: Some(best.1),
            ..Step::plain("add", res_eff.kind.clone(), gap_was, gap_res)
        };
        self.add(&mut t.search(), (props, res_eff, e, step))?;
        // the filters with the rounding now in the spec: those fitted by simulation
        // (which set the rounding's form, `Proposal::rescales`) and, when the spec has
        // no filter, those read off the PSD's roll-off, each scored on the withheld
        // part (the fit by simulation reads a few replicas and can miss a form the
        // roll-off gives)
        let kind = if has(&t.sts[0], Kind::OutputFilter) {
            "recalibrate:output_filter"
        } else {
            "output_filter"
        };
        let round = scored_pairs(&t.sts, gap_res, Asked::All, kind, &|_| true)?;
        let Some((eff, e, props, _)) = round.best else {
            return Ok(None);
        };
        if !(eff.gap_after < below && eff.gap_after <= gap_res * (1.0 - min_shrink)) {
            return Ok(None);
        }
        let step = Step::plain("add", eff.kind.clone(), gap_res, eff.gap_after);
        let gap_pair = eff.gap_after;
        // a filter fitted by simulation sets the rounding's form beside it (the
        // proposal's `rescales`), as the round's candidates tell it
        let how = if refits_path(&props[0]) {
            "by simulation"
        } else if matches!(eff.component, Component::OutputFir { .. }) {
            "as the MA(1) FIR"
        } else {
            "to the PSD's roll-off"
        };
        let filter = eff.kind.clone();
        self.add(&mut t.search(), (props, eff, e, step))?;
        t.write_back(s);
        Ok(Some(format!(
            "output_resolution and {filter} added as a pair: the rounding alone takes the gap from {gap_was:.3} to {gap_res:.3}, with the filter fitted beside it ({how}) to {gap_pair:.3} (the round's best single effect, {}, to {:.3})",
            best.0, best.1
        )))
    }

    /// Adds the round's best joint pair of biases `j` ([`candidates::joint`]), which the
    /// caller found to beat the round's best single effect (`best`: its kind and gap)
    /// by the margin a forward step needs: two steps, one per member, each an effect
    /// that reports the pair's gap and can be taken back like any other. Returns the
    /// note that says so.
    pub fn joint_pair(&self, s: &mut Search, j: JointBest, best: (&str, f64)) -> Result<String> {
        let JointBest {
            gap_after: g,
            ens,
            families,
            props: [[a0, b0], [a1, b1]],
            ..
        } = j;
        let gap_was = *s.gap_now;
        let (ka, kb) = (a0.kind.clone(), b0.kind.clone());
        let joint = |mut eff: Effect, other: &str| {
            eff.note = format!(
                "{}; estimated jointly with {other} (each with the other's signal beside its own on the training residual) and added with it as a pair",
                eff.note
            );
            eff
        };
        let ea = joint(
            Round::effect_of(&[a0.clone(), a1.clone()], g, families.clone(), gap_was),
            &kb,
        );
        let eb = joint(
            Round::effect_of(&[b0.clone(), b1.clone()], g, families, gap_was),
            &ka,
        );
        let step_a = Step {
            runner_up: Some(best.0.to_string()),
            runner_up_gap_after: Some(best.1),
            ..Step::plain("add", ka.clone(), gap_was, g)
        };
        // the first member alone is not scored: the state is re-estimated (with
        // --reestimate) only once both are in
        self.push(s, ([a0, a1], ea, ens.clone(), step_a));
        self.add(s, ([b0, b1], eb, ens, Step::plain("add", kb.clone(), g, g)))?;
        Ok(format!(
            "{ka} and {kb} added as a pair, estimated jointly: together they take the gap from {gap_was:.3} to {g:.3} (the round's best single effect, {}, to {:.3})",
            best.0, best.1
        ))
    }

    /// Rival `r` of a round estimated again on both folds' states of `t` (its kind
    /// proposed, the pair of its form kept) and scored; its `add` step names the
    /// round's best as the runner-up.
    fn estimate(
        &self,
        t: &Trial,
        r: &Effect,
        best_kind: &str,
        best_gap: f64,
    ) -> Result<Option<Added>> {
        self.estimate_on(&t.sts, t.gap_now, r, best_kind, best_gap)
    }

    /// The round's runner-up `r`, estimated again on the search's states and scored as
    /// [`Refit::estimate`] does, to be added in place of the round's best (its kind and
    /// gap, `best`) when the two tie and `r` is the simpler explanation. None when its
    /// kind gives no proposal of that form now. Works with re-estimation off as well.
    pub fn simpler(&self, s: &Search, r: &Effect, best: (&str, f64)) -> Result<Option<Added>> {
        self.estimate_on(s.sts, *s.gap_now, r, best.0, best.1)
    }

    /// [`Refit::estimate`] on the states `sts` whose joint gap is `gap_now`.
    fn estimate_on(
        &self,
        sts: &[State; 2],
        gap_now: f64,
        r: &Effect,
        best_kind: &str,
        best_gap: f64,
    ) -> Result<Option<Added>> {
        let mut props: [Vec<Proposal>; 2] = Default::default();
        {
            let [p0, p1] = &mut props;
            candidates::propose_kind_folds(
                [&self.cx(&sts[0], 0), &self.cx(&sts[1], 1)],
                &r.kind,
                [&mut |p| p0.push(p), &mut |p| p1.push(p)],
            )?;
        }
        let [ps0, mut ps1] = props;
        let same =
            |p: &Proposal| p.replaces == r.replaces && form(&p.component) == form(&r.component);
        let Some(mut p) = ps0.into_iter().find(|p| same(p)) else {
            return Ok(None);
        };
        let Some(j) = ps1.iter().position(|q| pair_key(q) == pair_key(&p)) else {
            return Ok(None);
        };
        let mut q = ps1.swap_remove(j);
        p.restore(&self.cx(&sts[0], 0));
        q.restore(&self.cx(&sts[1], 1));
        let d0: Vec<&[f64]> = (0..self.replicas).map(|k| p.delta.get(k)).collect();
        let d1: Vec<&[f64]> = (0..self.replicas).map(|k| q.delta.get(k)).collect();
        let f = (self.feats)(sts, [Some(&d0), Some(&d1)]);
        let scored = (self.score)(&f);
        let mut round = Round::default();
        round.offer([p, q], f, scored, gap_now);
        let Some((eff, e, props, _)) = round.best else {
            return Ok(None);
        };
        let step = Step {
            action: "add",
            kind: eff.kind.clone(),
            gap_before: gap_now,
            gap_after: eff.gap_after,
            runner_up: Some(best_kind.to_string()),
            runner_up_gap_after: Some(best_gap),
            difference_sd: None,
            tie: false,
        };
        Ok(Some((props, eff, e, step)))
    }

    /// Fold f's estimation context for state `st`: it trains on the other fold's
    /// withheld part, as the forward steps do.
    fn cx<'b>(&'b self, st: &'b State, f: usize) -> Context<'b> {
        Context {
            spec: &st.spec,
            channel: self.channel,
            sim: self.sim,
            train: &self.withheld[1 - f],
            real: self.real,
            beyond: self.beyond,
            temperature: self.temperature,
            others: self.others,
            sim_others: self.sim_others,
            target: &st.target,
            parts: &st.parts,
        }
    }

    /// Exchange steps (sequential replacement: Miller 2002, "Subset Selection in
    /// Regression", 2nd ed., chapter 3): after a round's addition (step `newest`; the
    /// caller asks only when it is a bias itself, the one kind of addition that changes
    /// the residual's mean, which the biases are fitted to), each
    /// earlier kept bias of [`candidates::bias_kinds`] (not a recalibration or a replacement)
    /// is first taken back outright with the others estimated again without it
    /// ([`Refit::take_back_refitted`]); when that leaves it, it is taken out of both
    /// folds' states and every other kind of [`candidates::bias_kinds`]
    /// the channel then lacks is estimated in its place, with the later effects in the
    /// residual. The best of these, when its gap is within [`SCREEN_RATIO`] times the
    /// gap now, is made on a copy of the search, and the kept effects are backfitted
    /// beside it, the newcomer last ([`Refit::backfit`]);
    /// the copy replaces the search when its joint withheld gap is below the gap now by
    /// at least `min_shrink` (the margin a forward step needs). A forward step
    /// estimates an effect against a residual that still holds the effects added after
    /// it: a rate ramp that ties with a temperature bias (and wins the tie by having
    /// fewer parameters) while a warm-up is still in the residual gives way to the
    /// temperature bias once the warm-up is in. Each exchange is two steps, a `remove`
    /// and an `add`, and each removal a `remove`; returns a note for each.
    pub fn exchange(&self, s: &mut Search, newest: usize, min_shrink: f64) -> Result<Vec<String>> {
        let ids: Vec<usize> = s
            .added
            .iter()
            .filter(|e| {
                e.step != Some(newest)
                    && e.replaces.is_none()
                    && candidates::bias_kinds().contains(&e.kind.as_str())
            })
            .filter_map(|e| e.step)
            .collect();
        let mut notes = Vec::new();
        for id in ids {
            let Some(i) = s.added.iter().position(|e| e.step == Some(id)) else {
                continue;
            };
            if !removable(s.slots, i) || s.slots[i][0].path || s.slots[i][1].path {
                continue;
            }
            let kind = s.added[i].kind.clone();
            let (mut trial, mut trial_slots) = self.without(s, i);
            let (gap_without, ens_without, _) = (self.score)(&(self.feats)(&trial, [None, None]));
            let taken_back = (trial.clone(), trial_slots.clone(), gap_without, ens_without);
            if let Some(note) = self.take_back_refitted(s, i, taken_back, min_shrink)? {
                notes.push(note);
                continue;
            }
            let present = |k: &str| {
                trial.iter().any(|st| {
                    st.spec.channels[self.channel]
                        .components
                        .iter()
                        .any(|c| c.kind().as_str() == k)
                })
            };
            let others: Vec<&str> = candidates::bias_kinds()
                .into_iter()
                .filter(|&k| k != kind && !present(k))
                .collect();
            if others.is_empty() {
                continue;
            }
            let mut round = Round::default();
            for k in others {
                self.offer_kind(&trial, k, gap_without, &mut round)?;
            }
            let Some((mut eff, e, [p0, p1], _)) = round.best else {
                continue;
            };
            if eff.gap_after >= SCREEN_RATIO * *s.gap_now {
                continue;
            }
            // the exchange made on a copy of the search, the kept effects backfitted
            // beside the newcomer
            let gap_was = *s.gap_now;
            let mut t = Trial::of(s);
            trial_slots.push([
                apply(&mut trial[0], self.channel, p0),
                apply(&mut trial[1], self.channel, p1),
            ]);
            t.sts = trial;
            t.slots = trial_slots;
            t.steps
                .push(Step::plain("remove", kind.clone(), gap_was, gap_without));
            t.steps.push(Step::plain(
                "add",
                eff.kind.clone(),
                gap_without,
                eff.gap_after,
            ));
            let new_id = t.steps.len();
            eff.step = Some(new_id);
            let new_kind = eff.kind.clone();
            t.gap_now = eff.gap_after;
            t.ens_now = e;
            t.added.remove(i);
            t.added.push(eff);
            self.backfit(&mut t, Some(new_id))?;
            if t.gap_now >= gap_was * (1.0 - min_shrink) {
                continue;
            }
            notes.push(format!(
                "{kind} exchanged for {new_kind}: with the later effects in place and estimated again beside it, {new_kind} in its stead brings the gap from {gap_was:.3} to {:.3}",
                t.gap_now
            ));
            t.write_back(s);
        }
        Ok(notes)
    }

    /// Backfitting of the kept effects of `t` (Buja, Hastie and Tibshirani 1989): each
    /// estimated again in turn ([`Refit::one`]), `last` (when given) after the others,
    /// for up to [`BACKFIT_PASSES`] passes or until a pass changes nothing; a
    /// re-estimate is kept only when it lowers the joint gap, so the gap never rises.
    /// Returns whether any changed.
    fn backfit(&self, t: &mut Trial, last: Option<usize>) -> Result<bool> {
        let mut changed = false;
        for _ in 0..BACKFIT_PASSES {
            let ids: Vec<usize> = t
                .added
                .iter()
                .filter_map(|e| e.step)
                .filter(|&o| Some(o) != last)
                .collect();
            let mut this_pass = false;
            for o in ids {
                this_pass |= self.one(&mut t.search(), o)?;
            }
            // (once estimated again, `last` has a new step id and is one of the others)
            if let Some(id) = last
                && this_pass
            {
                self.one(&mut t.search(), id)?;
            }
            changed |= this_pass;
            if !this_pass {
                break;
            }
        }
        Ok(changed)
    }

    /// Kept slot `i` taken back outright on a copy of the search, and the other kept
    /// effects estimated again without it ([`Refit::backfit`]): the copy replaces the
    /// search when the slot's share of the gap is then below `min_shrink`, the margin by
    /// which a backward step takes an effect back (a backward step keeps the others as
    /// they were, estimated beside the slot). `taken_back` is both folds' states and
    /// slots without the slot ([`Refit::without`]), their gap and ensemble statistics.
    /// Returns the note of a removal.
    fn take_back_refitted(
        &self,
        s: &mut Search,
        i: usize,
        taken_back: ([State; 2], Vec<[Slot; 2]>, f64, EnsembleStats),
        min_shrink: f64,
    ) -> Result<Option<String>> {
        let kind = s.added[i].kind.clone();
        let (trial, trial_slots, gap_without, ens_without) = taken_back;
        let gap_was = *s.gap_now;
        let mut added = s.added.clone();
        added.remove(i);
        let mut steps = s.steps.clone();
        steps.push(Step::plain("remove", kind.clone(), gap_was, gap_without));
        let mut t = Trial {
            sts: trial,
            slots: trial_slots,
            added,
            gap_now: gap_without,
            ens_now: ens_without,
            steps,
        };
        let changed = self.backfit(&mut t, None)?;
        let share = 1.0 - gap_was / t.gap_now;
        if !changed || share >= min_shrink {
            return Ok(None);
        }
        let note = format!(
            "{kind} taken back: with the other kept effects estimated again without it, its share of the gap is {:.1} %, less than {:.0} % (gap {gap_was:.3} -> {:.3})",
            100.0 * share,
            100.0 * min_shrink,
            t.gap_now
        );
        t.write_back(s);
        Ok(Some(note))
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

    /// Both folds' states and slots of `s` with kept slot `i` taken back (the others
    /// in place).
    fn without(&self, s: &Search, i: usize) -> ([State; 2], Vec<[Slot; 2]>) {
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
        (trial, trial_slots)
    }

    /// Every candidate of kind `kind` estimated on both folds' states `trial` (fold
    /// 1's and fold 2's estimates paired by [`pair_key`]), scored and offered to
    /// `round`, each against the gap `gap_ref` of `trial`.
    fn offer_kind(
        &self,
        trial: &[State; 2],
        kind: &str,
        gap_ref: f64,
        round: &mut Round,
    ) -> Result<()> {
        let mut props: [Vec<Proposal>; 2] = Default::default();
        {
            let [p0, p1] = &mut props;
            candidates::propose_kind_folds(
                [&self.cx(&trial[0], 0), &self.cx(&trial[1], 1)],
                kind,
                [&mut |p| p0.push(p), &mut |p| p1.push(p)],
            )?;
        }
        let [ps0, mut ps1] = props;
        for mut p in ps0 {
            let Some(j) = ps1.iter().position(|q| pair_key(q) == pair_key(&p)) else {
                continue;
            };
            let mut q = ps1.remove(j);
            p.restore(&self.cx(&trial[0], 0));
            q.restore(&self.cx(&trial[1], 1));
            let d0: Vec<&[f64]> = (0..self.replicas).map(|r| p.delta.get(r)).collect();
            let d1: Vec<&[f64]> = (0..self.replicas).map(|r| q.delta.get(r)).collect();
            let f = (self.feats)(trial, [Some(&d0), Some(&d1)]);
            let scored = (self.score)(&f);
            round.offer([p, q], f, scored, gap_ref);
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
        let (mut trial, mut trial_slots) = self.without(s, i);
        let (gap_without, _, _) = (self.score)(&(self.feats)(&trial, [None, None]));
        let mut round = Round::default();
        self.offer_kind(&trial, &kind, gap_without, &mut round)?;
        let Some((mut eff, e, [p0, p1], _)) = round.best else {
            return Ok(false);
        };
        // a fall within rounding (the same estimate found again) changes nothing
        if eff.gap_after >= *s.gap_now * (1.0 - 1e-9) {
            return Ok(false);
        }
        trial_slots.push([
            apply(&mut trial[0], self.channel, p0),
            apply(&mut trial[1], self.channel, p1),
        ]);
        *s.sts = trial;
        *s.slots = trial_slots;
        s.steps.push(Step::plain(
            "reestimate",
            eff.kind.clone(),
            *s.gap_now,
            eff.gap_after,
        ));
        eff.step = Some(s.steps.len());
        *s.gap_now = eff.gap_after;
        *s.ens_now = e;
        s.added.remove(i);
        s.added.push(eff);
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kept(kind: &str, component: Component, step: usize) -> Effect {
        Effect {
            kind: kind.into(),
            gap_after: 1.0,
            shrink: 0.0,
            params: serde_json::json!({}),
            note: String::new(),
            families: Vec::new(),
            contribution: None,
            step: Some(step),
            at_edge: Vec::new(),
            undetermined: Vec::new(),
            component,
            replaces: None,
        }
    }

    #[test]
    fn a_heteroskedastic_scale_is_estimated_again_after_a_random_noise_only() {
        let hetero = kept(
            "heteroskedastic",
            Component::Heteroskedastic {
                of: Kind::WhiteNoise,
                slope: 0.03,
                floor: 0.15,
                reference_c: Some(25.0),
            },
            1,
        );
        let bias = kept("constant_bias", Component::ConstantBias { value: 0.1 }, 2);
        let flicker = kept(
            "bias_instability",
            Component::BiasInstability {
                b: 0.1,
                tau_min_s: None,
                tau_max_s: None,
            },
            2,
        );
        // a noise added after it: the scale again, not the noise itself
        assert_eq!(bounds(&[hetero.clone(), flicker.clone()], 2), vec![1]);
        // a bias leaves the differences' variance as it was
        assert!(bounds(&[hetero.clone(), bias], 2).is_empty());
        // the newest taken back: nothing
        assert!(bounds(std::slice::from_ref(&hetero), 2).is_empty());
        // a noise kept before the scale is not estimated again for it
        let mut first = flicker;
        first.step = Some(1);
        let mut second = hetero;
        second.step = Some(2);
        assert!(bounds(&[first, second], 2).is_empty());
    }
}
