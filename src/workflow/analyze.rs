//! The whole workflow for one prepared channel: select the order (with the ARMA
//! baseline, F-tests and the constancy test) on the training part, then check the
//! selected model: residual whiteness, prediction of the hold-out (the last samples,
//! never seen by the fits), polynomial fits of the f_m.

use super::check::{CheckReport, check_model};
use super::constancy::{Constancy, ConstancyTest, run_test};
use super::prep::ChannelPrep;
use super::select::{Selection, select};
use crate::error::{Error, Result};
use crate::estimator::FarmaParams;
use crate::model::Farma;

/// Parameters of the analysis after preparation.
#[derive(Clone, Debug)]
pub struct AnalyzeParams {
    pub orders: Vec<(usize, usize, usize)>,
    /// Grid, method and the rest of every FARMA fit.
    pub farma: FarmaParams,
    /// The constancy test at the selected order.
    pub constancy: ConstancyTest,
    pub seed: u64,
    /// Samples held out at the end for prediction.
    pub holdout: usize,
    /// Largest lag of the residual ACF.
    pub maxlag: usize,
    /// Largest degree of the polynomial fits.
    pub max_degree: usize,
}

/// Order selection and the constancy test `test` at the selected order (at the user's
/// fixed bandwidth if any: the chi2 test otherwise fixes its own, the bootstrap runs
/// GCV again on every replicate; see constancy.rs: a GCV choice held fixed
/// over-rejects).
pub fn select_with_constancy(
    x: &[f64],
    orders: &[(usize, usize, usize)],
    base: &FarmaParams,
    test: ConstancyTest,
    seed: u64,
) -> Result<(Selection, Option<Constancy>)> {
    let sel = select(x, orders, base)?;
    let r = &sel.rows[sel.selected];
    let farma = FarmaParams {
        p: r.order.0,
        q: r.order.1,
        d: r.order.2,
        bandwidth: base.bandwidth,
        ..base.clone()
    };
    let con = run_test(x, test, &farma, seed)?;
    Ok((sel, con))
}

/// The analysis of one channel.
#[derive(Clone, Debug)]
pub struct ChannelAnalysis {
    pub name: String,
    pub prep: ChannelPrep,
    /// Samples the models were fitted on (the rest is the hold-out).
    pub n_train: usize,
    pub selection: Selection,
    pub constancy: Option<Constancy>,
    pub check: CheckReport,
}

/// Analyses one prepared channel.
pub fn analyze_channel(prep: ChannelPrep, prm: &AnalyzeParams) -> Result<ChannelAnalysis> {
    let x = &prep.values;
    let n = x.len();
    if prm.holdout >= n / 2 {
        return Err(Error::Usage(format!(
            "the hold-out ({} samples) must be less than half of the channel ({n} samples): lower --holdout-s",
            prm.holdout
        )));
    }
    let n_train = n - prm.holdout;
    let train = &x[..n_train];
    let (selection, constancy) =
        select_with_constancy(train, &prm.orders, &prm.farma, prm.constancy, prm.seed)?;
    let (model, report) = &selection.fits[selection.selected];
    let row = &selection.rows[selection.selected];
    let baseline = Farma::linear(&row.arma_ar, &row.arma_ma, model.mean, f64::NAN);
    let check = check_model(
        model,
        &report.residuals,
        &baseline,
        x,
        prm.holdout,
        prm.maxlag,
        prm.max_degree,
    );
    Ok(ChannelAnalysis {
        name: prep.name.clone(),
        prep,
        n_train,
        selection,
        constancy,
        check,
    })
}
