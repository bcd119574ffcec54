//! Golden values from outside (fixtures/golden/make_workflow_golden.py): the sample ACF
//! and Ljung-Box against statsmodels 0.15.0, the linear ARMA(2,1) baseline against
//! conditional least squares by scipy (and the exact MLE of statsmodels SARIMAX).

use crate::common::fixture;
use farma::estimator::arma::{arma_residuals, fit_arma};
use farma::workflow::ljung_box::{acf, ljung_box};
use std::collections::HashMap;

fn load() -> (Vec<f64>, HashMap<(String, String), f64>) {
    let x: Vec<f64> = std::fs::read_to_string(fixture("golden/workflow_input.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.trim().parse().unwrap())
        .collect();
    let mut g = HashMap::new();
    for l in std::fs::read_to_string(fixture("golden/workflow_golden.csv"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
    {
        let v: Vec<&str> = l.split(',').collect();
        g.insert((v[0].to_string(), v[1].to_string()), v[2].parse().unwrap());
    }
    (x, g)
}

fn close(a: f64, b: f64, rel: f64, what: &str) {
    assert!(
        (a - b).abs() <= rel * b.abs().max(1e-300),
        "{what}: farma {a:e} vs golden {b:e}"
    );
}

#[test]
fn acf_and_ljung_box_match_statsmodels() {
    let (x, g) = load();
    assert_eq!(x.len(), 2000);
    let r = acf(&x, 20);
    for k in 1..=20 {
        close(
            r[k - 1],
            g[&("acf".into(), k.to_string())],
            1e-12,
            &format!("acf {k}"),
        );
    }
    for (df, tag) in [(0usize, "df0"), (3, "df3")] {
        let lags: Vec<usize> = if df == 0 {
            vec![1, 5, 10, 20]
        } else {
            vec![5, 10, 20]
        };
        let lb = ljung_box(&r, x.len(), &lags, df);
        assert_eq!(lb.len(), lags.len());
        for b in &lb {
            close(
                b.q,
                g[&(format!("lb_q_{tag}"), b.lag.to_string())],
                1e-12,
                "Q",
            );
            close(
                b.p_value,
                g[&(format!("lb_p_{tag}"), b.lag.to_string())],
                1e-9,
                "p",
            );
        }
    }
    // on the CLS residuals (moderate p-values)
    let coef = |k: &str| g[&("cls".to_string(), k.to_string())];
    let mut e = vec![0.0; x.len()];
    arma_residuals(&x, &[coef("ar1"), coef("ar2")], &[coef("ma1")], &mut e);
    let e = &e[2..];
    let lb = ljung_box(&acf(e, 20), e.len(), &[5, 10, 20], 3);
    for b in &lb {
        close(
            b.q,
            g[&("lb_q_resid".into(), b.lag.to_string())],
            1e-10,
            "Q resid",
        );
        close(
            b.p_value,
            g[&("lb_p_resid".into(), b.lag.to_string())],
            1e-9,
            "p resid",
        );
    }
}

#[test]
fn arma_baseline_matches_scipy_cls_and_is_near_the_statsmodels_mle() {
    let (x, g) = load();
    let m = fit_arma(&x, 2, 1).unwrap();
    let cls = |k: &str| g[&("cls".to_string(), k.to_string())];
    // same criterion, same recursion: the optimum agrees to the optimiser's precision
    close(m.ar[0], cls("ar1"), 1e-6, "ar1");
    close(m.ar[1], cls("ar2"), 1e-6, "ar2");
    close(m.ma[0], cls("ma1"), 1e-6, "ma1");
    close(m.rss, cls("rss"), 1e-10, "rss");
    // the exact Gaussian likelihood differs by O(1/N) (N = 2000)
    let mle = |k: &str| g[&("mle_statsmodels".to_string(), k.to_string())];
    assert!((m.ar[0] - mle("ar1")).abs() < 0.01);
    assert!((m.ar[1] - mle("ar2")).abs() < 0.01);
    assert!((m.ma[0] - mle("ma1")).abs() < 0.01);
    close(m.rss / (x.len() - 2) as f64, mle("sigma2"), 0.01, "sigma2");
}
