//! Joint pairs of deterministic biases: two effects estimated together on the training
//! residual, offered as one candidate.
//!
//! A greedy step estimates each bias against a residual that still holds every other
//! missing effect. Two biases that overlap in time (a warm-up and a thermal rate on a
//! temperature ramp that starts with the log, a temperature bias and a rate ramp)
//! bend each other's single fits: each alone can leave the withheld gap wider than
//! nothing at all, while a third kind (a temperature bias, with a free reference)
//! stands in for both and is added first.
//!
//! Every pair of the six biases (constant bias, rate ramp, warm-up, sinusoid,
//! temperature bias, thermal rate) that both folds estimate alone is ranked by the
//! training residual sum of squares of both single signals fitted at once (each
//! rescaled, no intercept: a level the pair leaves counts against it), over the best
//! single's. The [`JOINT_PAIRS`] best are fitted together:
//! the first member from its single fit, then the second beside the first, and for
//! each further pass the first beside the second and the second again (`PASSES`
//! passes). Each fit is the member's own estimator (its intercept, grids and
//! golden-section searches included) with the other member's signal as one more
//! regressor of its least squares, its size free (variable projection: Golub and
//! Pereyra 1973); the constant bias and the sinusoid, whose estimators are no such
//! least squares, are fitted to the residual less the other (backfitting: Buja,
//! Hastie and Tibshirani 1989, "Linear smoothers and additive models", Ann. Statist.
//! 17). After each pass both sizes are fitted at once by least squares on the two
//! signals (with an intercept unless a member is the constant bias, which is one).
//! Plain backfitting alone converged slowly where the two signals overlap
//! (BENCHMARKS.md, the twenty-eighth session). The diagnosis scores each pair on the
//! withheld part like any other candidate and adds the better pair only when it beats
//! the round's best single effect by the margin a forward step needs and by more than
//! a tie (`GapParams::joint_pairs`, on by default).

use serde_json::Value;

use super::{Context, Found, Proposal, Step, Training, bias_steps, run_step};
use crate::error::Result;

/// Passes over a pair (each pass estimates both members once; a third pass changed
/// nothing in the unit test).
const PASSES: usize = 2;

/// The most pairs a round scores, the lowest training residual first.
pub const JOINT_PAIRS: usize = 2;

/// Whether the least squares of `step` take a co-regressor ([`Training::regs`]).
fn takes_co(step: &Step) -> bool {
    matches!(
        step,
        Step::RateRamp | Step::Warmup | Step::TemperatureBias | Step::ThermalRate
    )
}

/// One fold's estimate of `step` beside the other member `other` (None: alone): the
/// first proposal the step hands (each of these steps hands at most one), when its
/// signal is the same in every replica. A step whose least squares take a
/// co-regressor fits the training residual with the other's signal beside its own,
/// the other's size free (variable projection: Golub and Pereyra 1973, "The
/// differentiation of pseudo-inverses and nonlinear least squares problems", SIAM J.
/// Numer. Anal. 10); the others (the constant bias, the sinusoid's periodogram) fit the
/// residual less the other's signal.
fn estimate(
    cx: &Context,
    base: &Training,
    step: &Step,
    other: Option<&Proposal>,
) -> Result<Option<Proposal>> {
    let tr = match other {
        None => base.with_res(base.res.clone(), None),
        Some(o) if takes_co(step) && !is_constant(o) => {
            base.with_res(base.res.clone(), Some(signal(o).to_vec()))
        }
        Some(o) => base.with_res(less(&base.res, &[signal(o)]), None),
    };
    let mut got: Option<Proposal> = None;
    let mut sink = |p: Proposal| {
        if got.is_none() {
            got = Some(p)
        }
    };
    let mut out = Found {
        sink: &mut sink,
        skipped: Vec::new(),
    };
    run_step(cx, &tr, step, &mut out)?;
    Ok(got.filter(|p| matches!(p.delta, super::Delta::Same(_))))
}

/// Whether `p` is a constant bias, whose signal is the intercept of every least
/// squares here: beside it, another member is fitted to the residual less it (its own
/// intercept takes the level), and the joint sizes take no intercept.
fn is_constant(p: &Proposal) -> bool {
    matches!(
        p.component,
        crate::simulator::Component::ConstantBias { .. }
    )
}

/// The signal of a deterministic proposal.
fn signal(p: &Proposal) -> &[f64] {
    p.delta.get(0)
}

/// x less each signal in `sigs`.
fn less(x: &[f64], sigs: &[&[f64]]) -> Vec<f64> {
    let mut out = x.to_vec();
    for s in sigs {
        for (a, v) in out.iter_mut().zip(s.iter()) {
            *a -= v;
        }
    }
    out
}

/// The weighted training residual sum of squares of `x` about its weighted mean.
fn rss(tr: &Training, x: &[f64]) -> f64 {
    super::lsq::ls_weighted(x, &[], true, &tr.ranges, tr.w()).map_or(f64::INFINITY, |(_, r)| r)
}

/// One fold's single estimates of [`bias_steps`] that `only` keeps (None where a step
/// gives none), with the fold's training part.
fn fold_singles(
    cx: &Context,
    only: Option<&[String]>,
) -> Result<(Training, Vec<Option<Proposal>>)> {
    let tr = Training::light(cx);
    let comps = &cx.spec.channels[cx.channel].components;
    let mut singles = Vec::new();
    for s in &bias_steps() {
        let asked =
            only.is_none_or(|ks| super::step_kind(s, comps).is_some_and(|k| ks.contains(&k)));
        singles.push(if asked {
            estimate(cx, &tr, s, None)?
        } else {
            None
        });
    }
    Ok((tr, singles))
}

/// The training RSS of the residual less the best single estimate of `singles`.
fn best_single_rss(tr: &Training, singles: &[Option<Proposal>]) -> f64 {
    singles
        .iter()
        .flatten()
        .map(|p| rss(tr, &less(&tr.res, &[signal(p)])))
        .fold(f64::INFINITY, f64::min)
}

/// The cheap ranking of pair (i, j) in one fold: the training RSS of the residual on
/// both single estimates' signals at once (each rescaled: their shapes as each fitted
/// alone), over the best single's RSS. No intercept: the signals are added as they
/// are, so a level they leave counts against them, as it does on the withheld part
/// (where a constant bias the spec lacks shows in every window's mean); with one, a
/// pair with the constant bias ranked as its other member alone.
fn proxy_ratio(
    tr: &Training,
    singles: &[Option<Proposal>],
    (i, j): (usize, usize),
    best: f64,
) -> Option<f64> {
    let (a, b) = (singles[i].as_ref()?, singles[j].as_ref()?);
    super::lsq::ls_weighted(&tr.res, &[signal(a), signal(b)], false, &tr.ranges, tr.w())
        .map(|(_, r)| r / best)
}

/// A pair fitted in one fold: both members' proposals and the training RSS over the
/// best single's.
type Fitted = ([Proposal; 2], f64);

/// Pair (i, j) fitted in one fold, from the single estimate of i: j beside i
/// ([`estimate`]), then for each further pass i beside j and j beside i ([`PASSES`]
/// passes), both sizes fitted at once after each pass ([`rescaled_jointly`]); the
/// proposals and their training RSS over the best single's.
fn fit_pair(
    cx: &Context,
    tr: &Training,
    singles: &[Option<Proposal>],
    (i, j): (usize, usize),
    best: f64,
) -> Result<Option<Fitted>> {
    let steps = bias_steps();
    let Some(mut a) = singles[i].clone() else {
        return Ok(None);
    };
    let mut b: Option<Proposal> = None;
    for pass in 0..PASSES {
        if pass > 0 {
            let Some(bb) = b.as_ref() else { break };
            match estimate(cx, tr, &steps[i], Some(bb))? {
                Some(p) => a = p,
                None => return Ok(None),
            }
        }
        let Some(bb) = estimate(cx, tr, &steps[j], Some(&a))? else {
            return Ok(None);
        };
        let (a2, b2) = rescaled_jointly(tr, a, bb);
        a = a2;
        b = Some(b2);
    }
    let Some(b) = b else { return Ok(None) };
    let r = rss(tr, &less(&tr.res, &[signal(&a), signal(&b)]));
    Ok(Some(([a, b], r / best)))
}

/// Both members' sizes fitted at once: the least squares of the training residual on
/// the two signals with an intercept, `res ~ c + s_a a + s_b b`, each member's size
/// parameter scaled by its factor ([`super::scaled`]). The shapes (time constants,
/// lags, frequencies) stay as their own fits left them; this step settles the sizes
/// that plain backfitting approaches only slowly when the two signals overlap. Left as
/// they are when a factor is not positive or a member has no size to scale.
fn rescaled_jointly(tr: &Training, a: Proposal, b: Proposal) -> (Proposal, Proposal) {
    let intercept = !is_constant(&a) && !is_constant(&b);
    let Some((beta, _)) = super::lsq::ls_weighted(
        &tr.res,
        &[signal(&a), signal(&b)],
        intercept,
        &tr.ranges,
        tr.w(),
    ) else {
        return (a, b);
    };
    let k = usize::from(intercept);
    let (sa, sb) = (beta[k], beta[k + 1]);
    if !(sa > 0.0 && sb > 0.0 && sa.is_finite() && sb.is_finite()) {
        return (a, b);
    }
    match (rescale(&a, sa), rescale(&b, sb)) {
        (Some(a2), Some(b2)) => (a2, b2),
        _ => (a, b),
    }
}

/// Proposal `p` with its size scaled by `s` > 0: its component's size parameter
/// ([`super::scaled`]) and its signal; the search flags its parameters carried over.
fn rescale(p: &Proposal, s: f64) -> Option<Proposal> {
    let component = super::scaled(&p.component, s)?;
    let mut params = super::params_json(&component);
    if let (Value::Object(new), Value::Object(old)) = (&mut params, &p.params) {
        for key in ["at_search_edge", "undetermined"] {
            if let Some(v) = old.get(key) {
                new.insert(key.into(), v.clone());
            }
        }
    }
    let sig: Vec<f64> = signal(p).iter().map(|v| v * s).collect();
    Some(Proposal {
        params,
        component,
        delta: super::Delta::Same(sig),
        ..p.clone()
    })
}

/// The pairs to score, for both folds' states (`cxs[f]` trains on the other fold's
/// withheld part; the two folds estimate in parallel): every pair of `bias_steps`
/// kinds that `only` keeps (when given) and that both folds estimate alone is ranked
/// by the larger of the two folds' `proxy_ratio`; the [`JOINT_PAIRS`] lowest are
/// fitted by `fit_pair` in both folds and returned, `[fold 1's, fold 2's]`, whenever
/// both folds fit them (the withheld score judges them against the single effects; a
/// training RSS about the mean cannot see the level a constant bias sets).
pub fn joint_pairs(cxs: [&Context; 2], only: Option<&[String]>) -> Result<Vec<[[Proposal; 2]; 2]>> {
    let (f0, f1) = rayon::join(|| fold_singles(cxs[0], only), || fold_singles(cxs[1], only));
    let folds = [f0?, f1?];
    let bests = folds.each_ref().map(|(tr, s)| best_single_rss(tr, s));
    let n = bias_steps().len();
    let mut ranked: Vec<(f64, (usize, usize))> = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let r = (0..2).map(|f| proxy_ratio(&folds[f].0, &folds[f].1, (i, j), bests[f]));
            if let Some(worst) = r.collect::<Option<Vec<f64>>>().map(|v| v[0].max(v[1])) {
                ranked.push((worst, (i, j)));
            }
        }
    }
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    let keys: Vec<(usize, usize)> = ranked.iter().take(JOINT_PAIRS).map(|r| r.1).collect();
    let fit = |f: usize| -> Result<Vec<Option<Fitted>>> {
        keys.iter()
            .map(|&k| fit_pair(cxs[f], &folds[f].0, &folds[f].1, k, bests[f]))
            .collect()
    };
    let (p0, p1) = rayon::join(|| fit(0), || fit(1));
    let mut out = Vec::new();
    for (a, b) in p0?.into_iter().zip(p1?) {
        if let (Some((p, _)), Some((q, _))) = (a, b) {
            out.push([p, q]);
        }
    }
    Ok(out)
}
