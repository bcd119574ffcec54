//! Order selection, the constancy test and the check on simulated data: FARMA(2,1,1)
//! data select (2,1,1) and reject constant coefficients; linear ARMA(2,1) data do not
//! reject; k-step prediction against the closed form of an AR(1); polynomial fits
//! recover a polynomial. The level and power over repeated simulations are measured in
//! benches/constancy.rs (figures in BENCHMARKS.md).

use farma::estimator::{FarmaParams, fit};
use farma::model::Farma;
use farma::workflow::analyze::select_with_constancy;
use farma::workflow::check::{poly_fits, predict_holdout, residual_whiteness};
use farma::workflow::constancy::ConstancyTest::{Bootstrap, Chi2};
use farma::workflow::select::PAPER_ORDERS;
use farma::workflow::{ALPHA, rejects};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// FARMA(2,1,1): f_1(z) = 0.2 + 0.6 exp(-z^2), f_2(z) = -0.25 + 0.15 tanh(z), b = 0.4.
fn farma211(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let burn = 500;
    let (mut x, mut e) = (vec![0.0; n + burn], vec![0.0; n + burn]);
    for t in 0..n + burn {
        e[t] = StandardNormal.sample(&mut rng);
        let mut s = e[t];
        if t >= 2 {
            let z = x[t - 1];
            s += (0.2 + 0.6 * f64::exp(-z * z)) * x[t - 1]
                + (-0.25 + 0.15 * z.tanh()) * x[t - 2]
                + 0.4 * e[t - 1];
        }
        x[t] = s;
    }
    x.split_off(burn)
}

/// ARMA(2,1): a = (0.5, -0.3), b = 0.4.
fn arma21(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let burn = 500;
    let (mut x, mut e) = (vec![0.0; n + burn], vec![0.0; n + burn]);
    for t in 0..n + burn {
        e[t] = StandardNormal.sample(&mut rng);
        let mut s = e[t];
        if t >= 2 {
            s += 0.5 * x[t - 1] - 0.3 * x[t - 2] + 0.4 * e[t - 1];
        }
        x[t] = s;
    }
    x.split_off(burn)
}

fn base() -> FarmaParams {
    FarmaParams {
        grid_size: 31,
        ..FarmaParams::default()
    }
}

#[test]
fn farma211_data_select_211_and_reject_constancy() {
    let x = farma211(3000, 21);
    let (sel, con) = select_with_constancy(&x, &PAPER_ORDERS, &base(), Bootstrap(39), 5).unwrap();
    for r in &sel.rows {
        eprintln!(
            "{:?} rss {:.2} df {:.2} aicc {:.5} arma_rss {:.2}",
            r.order, r.rss, r.df, r.aicc, r.arma_rss
        );
    }
    eprintln!("{}", sel.reason);
    assert_eq!(sel.rows[sel.selected].order, (2, 1, 1), "{}", sel.reason);
    let con = con.unwrap();
    eprintln!("constancy T = {}, p = {}", con.statistic, con.p_value);
    assert!(rejects(con.p_value, ALPHA), "constancy p = {}", con.p_value);
    // the FARMA(2,1,1) fits better than its ARMA(2,1), significantly
    let r = &sel.rows[sel.selected];
    assert!(r.rss < r.arma_rss && r.p_vs_arma < 0.01);
}

/// The default test (chi2 at a fixed bandwidth): FARMA(2,1,1) data reject constant
/// coefficients, ARMA(2,1) data do not; its degrees of freedom are the smoother's
/// trace less p, at 0.5 sd of the series.
#[test]
fn the_chi2_constancy_test_rejects_farma_data_and_not_arma_data() {
    let nl = farma211(3000, 21);
    let (sel, con) = select_with_constancy(&nl, &[(2, 1, 1)], &base(), Chi2, 0).unwrap();
    let con = con.unwrap();
    eprintln!(
        "FARMA data: T = {}, df = {}, p = {}",
        con.statistic, con.df, con.p_value
    );
    assert_eq!(con.method, "chi2");
    assert!(rejects(con.p_value, ALPHA), "p = {}", con.p_value);
    assert!((con.df - (con.trace - 2.0)).abs() < 1e-12 && con.df > 1.0);
    assert_eq!(con.min_p(), 0.0);
    assert!(sel.rows[sel.selected].bandwidth != con.bandwidth);
    let x = arma21(3000, 22);
    let (_, con) = select_with_constancy(&x, &[(2, 1, 1)], &base(), Chi2, 0).unwrap();
    let con = con.unwrap();
    eprintln!(
        "ARMA data: T = {}, df = {}, p = {}",
        con.statistic, con.df, con.p_value
    );
    assert!(!rejects(con.p_value, ALPHA), "p = {}", con.p_value);
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
    assert!((con.bandwidth - 0.5 * sd).abs() < 1e-12 * sd);
}

/// The selection keeps the residuals of its selected fit alone (the others' are
/// dropped as each fit ends: N values per order), and those are the residuals a fit at
/// the selected order returns, bit for bit (they are recomputed from its f and b).
#[test]
fn a_selection_keeps_the_selected_fits_residuals_alone_and_they_are_the_fits_own() {
    use farma::workflow::select::select;
    let x = farma211(6000, 24);
    let orders = [(1, 1, 1), (2, 1, 1), (3, 2, 2)];
    let sel = select(&x, &orders, &base()).unwrap();
    let (p, q, d) = sel.rows[sel.selected].order;
    let direct = fit(
        &x,
        &FarmaParams { p, q, d, ..base() }.validate(x.len()).unwrap(),
    )
    .unwrap();
    assert_eq!(direct.1.residuals.len(), x.len());
    let kept = &sel.fits[sel.selected].1.residuals;
    assert_eq!(kept.len(), x.len());
    let differ = kept
        .iter()
        .zip(&direct.1.residuals)
        .position(|(a, b)| a.to_bits() != b.to_bits());
    assert_eq!(
        differ,
        None,
        "order {:?}: first residual that differs",
        (p, q, d)
    );
    for (i, f) in sel.fits.iter().enumerate() {
        if i != sel.selected {
            assert!(f.1.residuals.is_empty(), "order {:?}", sel.rows[i].order);
        }
    }
}

#[test]
fn arma21_data_do_not_reject_constancy_and_results_ignore_thread_count() {
    let x = arma21(3000, 22);
    let b = FarmaParams {
        p: 2,
        q: 1,
        d: 1,
        ..base()
    };
    let run = || select_with_constancy(&x, &[(2, 1, 1)], &b, Bootstrap(39), 6).unwrap();
    let (_, con) = run();
    let con = con.unwrap();
    eprintln!("constancy T = {}, p = {}", con.statistic, con.p_value);
    assert!(
        !rejects(con.p_value, ALPHA),
        "constancy p = {}",
        con.p_value
    );
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(run);
    assert_eq!(one.1.unwrap().t_boot, con.t_boot);
}

#[test]
fn kstep_prediction_of_an_ar1_is_the_closed_form() {
    // AR(1) with a = 0.7: the k-step prediction from origin s is a^k y_s.
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let n = 600;
    let mut y = vec![0.0; n];
    for t in 1..n {
        let v: f64 = StandardNormal.sample(&mut rng);
        y[t] = 0.7 * y[t - 1] + v;
    }
    let lin = Farma::linear(&[0.7], &[], 0.0, 1.0);
    let holdout = 100;
    let (sse, cnt) = lin.kstep(&y, holdout, 10);
    for k in 1..=10 {
        let mut s = 0.0;
        let mut c = 0;
        for t in n - holdout..n {
            if t >= k {
                s += (y[t] - 0.7f64.powi(k as i32) * y[t - k]).powi(2);
                c += 1;
            }
        }
        assert_eq!(cnt[k - 1], c, "k = {k}");
        assert!(
            (sse[k - 1] - s).abs() < 1e-9 * s,
            "k = {k}: {} vs {s}",
            sse[k - 1]
        );
    }
}

#[test]
fn check_of_a_fitted_farma_model() {
    let x = farma211(3000, 23);
    let (train, _) = x.split_at(2500);
    let prm = FarmaParams {
        p: 2,
        q: 1,
        d: 1,
        ..base()
    }
    .validate(train.len())
    .unwrap();
    let fitted = fit(train, &prm).unwrap();
    let (mut m, fitted) = fitted;
    let w = residual_whiteness(&m, &fitted.residuals, 20);
    eprintln!("{:?}", w.ljung_box);
    assert!(
        w.ljung_box.iter().all(|b| b.p_value > 0.01),
        "{:?}",
        w.ljung_box
    );
    let arma = farma::estimator::arma::fit_arma(
        &train.iter().map(|v| v - m.mean).collect::<Vec<_>>(),
        2,
        1,
    )
    .unwrap();
    let lin = Farma::linear(&arma.ar, &arma.ma, m.mean, f64::NAN);
    let pr = predict_holdout(&m, &lin, &x, 500, &[1, 2, 5, 10, 1000]);
    assert_eq!(pr.horizons.len(), 4); // k = 1000 exceeds the hold-out
    let one = &pr.horizons[0];
    eprintln!("{:?}", pr.horizons);
    // one-step errors are the innovations (sd 1) up to estimation error
    assert!((one.rmse_farma - 1.0).abs() < 0.1, "{one:?}");
    assert!(one.rmse_farma < one.rmse_arma, "{one:?}");
    // far horizons approach the series' spread
    assert!(pr.horizons[3].rmse_farma > one.rmse_farma);
    // polynomial fits: overwrite f with exact polynomials; they are recovered
    let p = m.p();
    for g in 0..m.coef.n_grid() {
        let u = m.coef.grid[g];
        m.coef.f[g * p] = 0.5 - 0.2 * u + 0.1 * u * u;
        m.coef.f[g * p + 1] = -0.3;
    }
    let pf = poly_fits(&m, 6);
    assert_eq!((pf[0].degree, pf[1].degree), (2, 0), "{pf:?}");
    for (c, want) in pf[0].coef.iter().zip([0.5, -0.2, 0.1]) {
        assert!((c - want).abs() < 1e-9, "{pf:?}");
    }
    assert!((pf[1].coef[0] + 0.3).abs() < 1e-12);
}
