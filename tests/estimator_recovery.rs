//! The estimator recovers a known FARMA(2,1,1): f_1(z) = 0.3 + 0.4 exp(-z^2),
//! f_2(z) = -0.2 + 0.1 tanh(z), b_1 = -0.5, d = 1, unit innovations, N = 1e5.

use farma::estimator::{FarmaParams, FitPath, Init, fit};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

fn simulate(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let burn = 500;
    let mut x = vec![0.0; n + burn];
    let mut e = vec![0.0; n + burn];
    for t in 0..n + burn {
        e[t] = StandardNormal.sample(&mut rng);
        let z = if t >= 1 { x[t - 1] } else { 0.0 };
        let mut s = e[t];
        if t >= 1 {
            s += (0.3 + 0.4 * f64::exp(-z * z)) * x[t - 1] - 0.5 * e[t - 1];
        }
        if t >= 2 {
            s += (-0.2 + 0.1 * z.tanh()) * x[t - 2];
        }
        x[t] = s;
    }
    x.split_off(burn)
}

fn max_error_central80(m: &farma::estimator::FittedFarma, x: &[f64]) -> f64 {
    let mut u: Vec<f64> = x[..x.len() - 1].to_vec();
    u.sort_by(f64::total_cmp);
    let (lo, hi) = (u[u.len() / 10] - m.mean, u[u.len() * 9 / 10] - m.mean);
    let mut worst = 0.0f64;
    let mut f = [0.0; 2];
    for k in 0..=400 {
        let z = lo + (hi - lo) * k as f64 / 400.0;
        m.coef.eval(&m.grid, z, &mut f);
        let zt = z + m.mean; // the model is fitted to x - mean
        let t1 = 0.3 + 0.4 * f64::exp(-zt * zt);
        let t2 = -0.2 + 0.1 * zt.tanh();
        worst = worst.max((f[0] - t1).abs()).max((f[1] - t2).abs());
    }
    worst
}

#[test]
fn recovers_farma211_at_1e5() {
    let x = simulate(100_000, 42);
    let params = FarmaParams {
        p: 2,
        q: 1,
        d: 1,
        ..FarmaParams::default()
    }
    .validate(x.len())
    .unwrap();
    let m = fit(&x, &params).unwrap();
    let err = max_error_central80(&m, &x);
    eprintln!(
        "b = {:?}, h = {:.4}, iterations {}, converged {}, max |f - f_true| = {err:.4}, notes {:?}",
        m.b, m.bandwidth, m.iterations, m.converged, m.notes
    );
    eprintln!("rss history {:?}", m.rss_history);
    assert!(m.converged);
    assert!((m.b[0] + 0.5).abs() <= 0.03, "b = {:?}", m.b);
    assert!(err <= 0.08, "max |f - f_true| = {err}");
    assert!((m.sigma2 - 1.0).abs() < 0.05, "sigma2 = {}", m.sigma2);
}

#[test]
fn literal_scheme_stays_further_from_b_than_the_arma_start() {
    let x = simulate(20_000, 7);
    let lit = FarmaParams {
        init: Init::Literal,
        max_iter: 20,
        ..FarmaParams::default()
    }
    .validate(x.len())
    .unwrap();
    let arma = FarmaParams {
        max_iter: 20,
        ..FarmaParams::default()
    }
    .validate(x.len())
    .unwrap();
    let (ml, ma) = (fit(&x, &lit).unwrap(), fit(&x, &arma).unwrap());
    eprintln!(
        "literal: b = {:?} iterations {} converged {}",
        ml.b, ml.iterations, ml.converged
    );
    eprintln!(
        "arma start: b = {:?} iterations {} converged {}",
        ma.b, ma.iterations, ma.converged
    );
    assert_eq!(ml.init, Init::Literal);
    assert!((ma.b[0] + 0.5).abs() < (ml.b[0] + 0.5).abs());
}

#[test]
fn fast_and_direct_fits_agree_end_to_end() {
    let x = simulate(3_000, 9);
    let mk = |path| {
        FarmaParams {
            grid_size: 31,
            path,
            ..FarmaParams::default()
        }
        .validate(x.len())
        .unwrap()
    };
    let a = fit(&x, &mk(FitPath::Fast)).unwrap();
    let b = fit(&x, &mk(FitPath::Direct)).unwrap();
    assert_eq!(a.bandwidth, b.bandwidth);
    assert_eq!(a.iterations, b.iterations);
    assert!(
        (a.rss - b.rss).abs() <= 1e-9 * a.rss,
        "{} vs {}",
        a.rss,
        b.rss
    );
    assert!((a.trace - b.trace).abs() <= 1e-9 * a.trace);
    assert!(
        (a.b[0] - b.b[0]).abs() <= 1e-9,
        "b {:?} vs {:?}, rss {} vs {}, it {} {}",
        a.b,
        b.b,
        a.rss,
        b.rss,
        a.iterations,
        b.iterations
    );
}
