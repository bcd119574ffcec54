//! The simulator (`farma simulate`, `farma::simulator::generate`): each component
//! against its theory, determinism, thread-count independence, the CLI.
//!
//! Statistical checks use fixed seeds and a tolerance of 5 standard errors of the
//! estimate at the sample size used (the standard error's formula is given at each
//! check), so they fail only when the generator is wrong.

use std::path::Path;

use crate::common;
use farma::simulator::generate::markov::{FlickerBank, bias_instability_bank};
use farma::simulator::generate::streams::CHUNK;
use farma::simulator::generate::thermal;
use farma::simulator::{SimRequest, Simulator, Spec, component_signal, parse_spec, simulate};
use farma::stats::adev::edf_greenhall;

const FS: f64 = 10.0;

fn spec(text: &str) -> Spec {
    parse_spec(text, Path::new("test.toml")).unwrap()
}

/// A one-channel spec `x` at 10 Hz, seed 11, with the given component tables.
fn one(components: &str) -> Spec {
    spec(&format!(
        "sample_rate_hz = 10.0\nseed = 11\ntemperature_channel = \"temp\"\n[[channel]]\nname = \"x\"\n{components}"
    ))
}

fn run1(s: &Spec, n: usize) -> Vec<f64> {
    simulate(s, &SimRequest::new(n, FS)).unwrap().channels[0]
        .1
        .clone()
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

fn var(x: &[f64]) -> f64 {
    let m = mean(x);
    x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (x.len() - 1) as f64
}

/// Sample autocovariance at `lag` (divisor n).
fn acov(x: &[f64], lag: usize) -> f64 {
    let m = mean(x);
    let n = x.len();
    (0..n - lag)
        .map(|i| (x[i] - m) * (x[i + lag] - m))
        .sum::<f64>()
        / n as f64
}

/// Overlapping Allan deviation of rate samples `y` at averaging factor `m`, straight
/// from the definition on the phase x_k = sum_{i<k} y_i dt (the slow, obvious way).
fn oadev(y: &[f64], m: usize, fs: f64) -> f64 {
    let dt = 1.0 / fs;
    let mut x = vec![0.0; y.len() + 1];
    for (i, v) in y.iter().enumerate() {
        x[i + 1] = x[i] + v * dt;
    }
    let tau = m as f64 * dt;
    let n = x.len() - 2 * m;
    let s: f64 = (0..n)
        .map(|k| {
            let d = x[k + 2 * m] - 2.0 * x[k + m] + x[k];
            d * d
        })
        .sum();
    (s / (2.0 * tau * tau * n as f64)).sqrt()
}

/// Five standard errors of an overlapping ADEV estimate: the relative standard
/// deviation of a deviation from a chi-squared variance with `edf` degrees of freedom
/// is about 1 / sqrt(2 edf); edf by Greenhall's algorithm for noise type `alpha`.
fn tol5(alpha: i32, m: usize, n: usize) -> f64 {
    let edf = edf_greenhall(alpha, 2, m, n + 1, true, false).unwrap();
    5.0 / (2.0 * edf).sqrt()
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

// ---------------------------------------------------------------------------------
// Each component against its theory.

#[test]
fn white_noise_variance_and_allan_deviation() {
    let n_coef = 0.02;
    let n = 200_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"white_noise\"\nn = {n_coef}\n"
        )),
        n,
    );
    // Sample variance n^2 fs; relative standard error sqrt(2 / N) = 0.32 %.
    let v = var(&y);
    assert!(
        rel(v, n_coef * n_coef * FS) < 5.0 * (2.0 / n as f64).sqrt(),
        "var {v}"
    );
    for m in [1, 10, 100, 1000] {
        let tau = m as f64 / FS;
        let a = oadev(&y, m, FS);
        let want = n_coef / tau.sqrt();
        assert!(rel(a, want) < tol5(0, m, n), "m {m}: adev {a} vs {want}");
    }
}

#[test]
fn quantization_allan_curve_and_bounded_angle() {
    let q = 0.001;
    let n = 100_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"quantization\"\nq = {q}\n"
        )),
        n,
    );
    // The integrated angle is e_k - e_{-1}: within one quantum sqrt(12) q of zero.
    let quantum = 12f64.sqrt() * q;
    // Its range is the quantum: e_k fills [-Q/2, Q/2) over 1e5 samples.
    let mut angle = 0.0;
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for v in &y {
        angle += v / FS;
        lo = lo.min(angle);
        hi = hi.max(angle);
    }
    assert!(
        hi - lo <= quantum * (1.0 + 1e-9),
        "angle spread {} > quantum",
        hi - lo
    );
    assert!(
        hi - lo > 0.999 * quantum,
        "angle spread {} < quantum",
        hi - lo
    );
    // ADEV = sqrt(3) q / tau exactly in expectation; white phase noise: edf ~ N / 2
    // at every m, relative standard error ~ 1 / sqrt(N) = 0.3 %; 2 % is > 5 SE.
    for m in [1, 3, 10, 100] {
        let tau = m as f64 / FS;
        let a = oadev(&y, m, FS);
        let want = 3f64.sqrt() * q / tau;
        assert!(rel(a, want) < 0.02, "m {m}: adev {a} vs {want}");
    }
}

/// Exact Allan variance at tau [s] of the interval averages of a flicker bank: per
/// Gauss-Markov process (variance s^2, correlation time T) (4 D(tau) - D(2 tau)) /
/// (2 tau^2), D(u) = 2 s^2 (T u - T^2 (1 - exp(-u / T))) the structure function of its
/// angle (the double integral of its autocovariance), plus n^2 / tau for the white fill.
fn bank_avar(bank: &FlickerBank, tau: f64) -> f64 {
    let mut total = bank.white_n2 / tau;
    for &(t, s) in &bank.processes {
        let d = |u: f64| 2.0 * s * s * (t * u + t * t * (-u / t).exp_m1());
        total += (4.0 * d(tau) - d(2.0 * tau)) / (2.0 * tau * tau);
    }
    total
}

const FLOOR: f64 = 0.664_282_470_267_960_1; // sqrt(2 ln 2 / pi)

#[test]
fn bias_instability_bank_has_the_flicker_floor() {
    // The approximation itself, exactly: ADEV within 0.1 % of 0.664 b at octave taus
    // in [tau_min, tau_max / 4] and within 0.3 % up to tau_max (markov.rs: 0.06 % and
    // 0.23 % computed).
    let b = 1.0;
    assert!(
        rel(
            FLOOR,
            (2.0 * std::f64::consts::LN_2 / std::f64::consts::PI).sqrt()
        ) < 1e-15
    );
    for (lo, hi) in [(1.0, 1000.0), (0.1, 1e4), (0.01, 2621.44), (0.5, 100.0)] {
        let bank = bias_instability_bank(b, lo, hi);
        let mut tau = lo;
        while tau <= hi * (1.0 + 1e-9) {
            let a = bank_avar(&bank, tau).sqrt();
            let tol = if tau <= hi / 4.0 { 1e-3 } else { 3e-3 };
            assert!(rel(a, FLOOR * b) < tol, "[{lo}, {hi}] tau {tau}: {a}");
            // The library's exact AVAR (sum s^2 g(tau / T)) agrees.
            assert!(rel(bank.avar(tau), a * a) < 1e-7, "tau {tau}");
            tau *= 2.0;
        }
    }
}

#[test]
fn bias_instability_matches_the_exact_allan_variance_of_its_bank() {
    let b = 0.003;
    let n = 300_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"bias_instability\"\nb = {b}\ntau_min_s = 0.5\ntau_max_s = 100.0\n"
        )),
        n,
    );
    let bank = bias_instability_bank(b, 0.5, 100.0);
    for m in [1, 5, 20, 100, 500] {
        let want = bank_avar(&bank, m as f64 / FS).sqrt();
        let a = oadev(&y, m, FS);
        assert!(rel(a, want) < tol5(-1, m, n), "m {m}: adev {a} vs {want}");
    }
}

/// The default flicker band starts at one sample interval: the simulated curve is on
/// the floor 0.664 b from tau = dt (the first generator, point samples of a bank from
/// dt / 10, was 1.44 times the floor at tau = dt, 1.22 at 2 dt, 1.11 at 4 dt: white
/// noise aliased from its fastest processes).
#[test]
fn bias_instability_is_on_its_floor_from_one_sample() {
    let b = 0.01;
    let n = 1 << 17;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"bias_instability\"\nb = {b}\n"
        )),
        n,
    );
    for m in [1, 2, 4, 8, 64, 512] {
        let a = oadev(&y, m, FS);
        assert!(
            rel(a, FLOOR * b) < tol5(-1, m, n),
            "m {m}: adev {a} vs floor {}",
            FLOOR * b
        );
    }
}

#[test]
fn rate_random_walk_allan_deviation() {
    let k = 0.001;
    let n = 200_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"rate_random_walk\"\nk = {k}\n"
        )),
        n,
    );
    for m in [1, 2, 10, 100, 1000] {
        let tau = m as f64 / FS;
        // Interval averages: k sqrt(tau / 3) at every m (point samples of the random
        // walk would give k^2 tau / 3 (1 + 1 / (2 m^2)): 22 % more ADEV at m = 1).
        let want = k * (tau / 3.0).sqrt();
        let a = oadev(&y, m, FS);
        assert!(rel(a, want) < tol5(-2, m, n), "m {m}: adev {a} vs {want}");
    }
}

#[test]
fn gauss_markov_variance_and_correlation_at_tau() {
    let (sigma, tau_s) = (0.01, 2.0);
    let n = 200_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"gauss_markov\"\nsigma = {sigma}\ntau_s = {tau_s}\n"
        )),
        n,
    );
    let phi: f64 = (-1.0 / (FS * tau_s)).exp();
    let dt = 1.0 / FS;
    // Each sample is the process averaged over its interval: variance
    // sigma^2 (2 T / dt^2) (dt - T (1 - phi)) (1.6 % below sigma^2 here), autocovariance
    // at lag L >= 1 sigma^2 (T / dt)^2 (1 - phi)^2 phi^(L - 1).
    let want_var = sigma * sigma * 2.0 * tau_s / (dt * dt) * (dt - tau_s * (1.0 - phi));
    // Variance: effective sample size N (1 - phi^2) / (1 + phi^2) ~ 5000 here (Bartlett),
    // relative standard error sqrt(2 / N_eff) = 2 %.
    let n_eff = n as f64 * (1.0 - phi * phi) / (1.0 + phi * phi);
    let v = var(&y);
    assert!(rel(v, want_var) < 5.0 * (2.0 / n_eff).sqrt(), "var {v}");
    // Autocorrelation at lag tau_s; Bartlett's standard error of r_k for an AR(1) is
    // below sqrt((1 + phi^2) / ((1 - phi^2) N)) = 1 %.
    let lag = (tau_s * FS) as usize;
    let want_r =
        sigma * sigma * (tau_s / dt).powi(2) * (1.0 - phi).powi(2) * phi.powi(lag as i32 - 1)
            / want_var;
    let r = acov(&y, lag) / acov(&y, 0);
    let se = ((1.0 + phi * phi) / ((1.0 - phi * phi) * n as f64)).sqrt();
    assert!((r - want_r).abs() < 5.0 * se, "r({lag}) = {r} vs {want_r}");
    // Allan deviation: IEEE Std 952's sigma^2 g(tau / T) at every tau = m dt, from
    // the angle's structure function D(u) = 2 sigma^2 (T u - T^2 (1 - exp(-u / T)))
    // (point samples of the process would give 1.5 times the Allan variance at m = 1).
    let d = |u: f64| 2.0 * sigma * sigma * (tau_s * u + tau_s * tau_s * (-u / tau_s).exp_m1());
    for m in [1, 4, 20, 100] {
        let tau = m as f64 * dt;
        let want = ((4.0 * d(tau) - d(2.0 * tau)) / (2.0 * tau * tau)).sqrt();
        let a = oadev(&y, m, FS);
        assert!(rel(a, want) < tol5(-2, m, n), "m {m}: adev {a} vs {want}");
    }
}

/// psi weights of an ARMA(p,q): x = sum_j psi_j e_{t-j}.
fn psi(ar: &[f64], ma: &[f64], len: usize) -> Vec<f64> {
    let mut p = vec![0.0; len];
    for j in 0..len {
        let mut v = if j == 0 {
            1.0
        } else {
            ma.get(j - 1).copied().unwrap_or(0.0)
        };
        for (i, a) in ar.iter().enumerate() {
            if j > i {
                v += a * p[j - 1 - i];
            }
        }
        p[j] = v;
    }
    p
}

#[test]
fn arma_autocovariances_match_the_closed_form() {
    let (ar, ma, sigma) = ([0.6, -0.2], [0.3], 0.5);
    let n = 200_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"arma\"\nar = [{}, {}]\nma = [{}]\nsigma = {sigma}\n",
            ar[0], ar[1], ma[0]
        )),
        n,
    );
    let w = psi(&ar, &ma, 400);
    let gamma = |k: usize| sigma * sigma * (0..400 - k).map(|j| w[j] * w[j + k]).sum::<f64>();
    for k in 0..4 {
        // Bartlett: Var(gamma_hat(k)) ~ (1/N) sum_j (gamma_j^2 + gamma_{j+k} gamma_{j-k}).
        let se = ((-60i64..=60)
            .map(|j| {
                let g = |l: i64| gamma(l.unsigned_abs() as usize);
                g(j) * g(j) + g(j + k as i64) * g(j - k as i64)
            })
            .sum::<f64>()
            / n as f64)
            .sqrt();
        let got = acov(&y, k);
        assert!(
            (got - gamma(k)).abs() < 5.0 * se,
            "gamma({k}) {got} vs {}",
            gamma(k)
        );
    }
}

/// Innovations recovered from a FARMA output by running the model backwards
/// (zeros before the first sample); skips the first `skip` values.
fn farma_residuals(
    x: &[f64],
    d: usize,
    f: &dyn Fn(usize, f64) -> f64,
    p: usize,
    ma: &[f64],
    skip: usize,
) -> Vec<f64> {
    let mut e = vec![0.0; x.len()];
    for t in 0..x.len() {
        let u = if t >= d { x[t - d] } else { 0.0 };
        let mut v = x[t];
        for m in 1..=p {
            if t >= m {
                v -= f(m, u) * x[t - m];
            }
        }
        for (j, b) in ma.iter().enumerate() {
            if t > j {
                v -= b * e[t - 1 - j];
            }
        }
        e[t] = v;
    }
    e.split_off(skip)
}

#[test]
fn inline_farma_innovations_are_white_with_sigma() {
    let sigma = 0.2;
    let n = 100_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"farma\"\np = 2\nq = 1\nd = 1\nf = [[0.8, 0.0, -0.5], [0.1]]\nma = [0.2]\nsigma = {sigma}\n"
        )),
        n,
    );
    let poly = |m: usize, u: f64| match m {
        1 => 0.8 - 0.5 * u * u,
        _ => 0.1,
    };
    let e = farma_residuals(&y, 1, &poly, 2, &[0.2], 200);
    let v = var(&e);
    assert!(
        rel(v, sigma * sigma) < 5.0 * (2.0 / e.len() as f64).sqrt(),
        "var {v}"
    );
    let r1 = acov(&e, 1) / acov(&e, 0);
    assert!(r1.abs() < 5.0 / (e.len() as f64).sqrt(), "r1 {r1}");
    // The check discriminates: the linear model f_1 = 0.8 (the polynomial without its
    // u^2 term) leaves residuals far (> 10 standard errors) more variable.
    let lin = farma_residuals(
        &y,
        1,
        &|m, _| if m == 1 { 0.8 } else { 0.1 },
        2,
        &[0.2],
        200,
    );
    assert!(
        var(&lin) > v * (1.0 + 10.0 * (2.0 / e.len() as f64).sqrt()),
        "{} vs {v}",
        var(&lin)
    );
}

#[test]
fn deterministic_components_are_exact() {
    let n = 150_000;
    let s = one(
        "[[channel.component]]\nkind = \"constant_bias\"\nvalue = -0.25\n\
         [[channel.component]]\nkind = \"rate_ramp\"\nr = 2e-4\n\
         [[channel.component]]\nkind = \"sinusoid\"\namplitude = 0.3\nfreq_hz = 0.7\nphase_rad = 1.1\n\
         [[channel.component]]\nkind = \"warmup\"\namplitude = 0.5\ntau_s = 300.0\n",
    );
    let req = SimRequest::new(n, FS);
    let sim = Simulator::new(&s, req).unwrap();
    let parts: Vec<Vec<f64>> = (0..4)
        .map(|k| sim.component_signal(0, k).unwrap())
        .collect();
    let total = sim.run().unwrap().channels[0].1.clone();
    for (k, v) in total.iter().enumerate() {
        let t = k as f64 / FS;
        let want = [
            -0.25,
            2e-4 * t,
            0.3 * (2.0 * std::f64::consts::PI * 0.7 * t + 1.1).sin(),
            0.5 * (-t / 300.0).exp(),
        ];
        for (c, w) in want.iter().enumerate() {
            assert!(
                (parts[c][k] - w).abs() <= 1e-12 * (1.0 + w.abs()),
                "component {c} at {k}"
            );
        }
        assert!((v - want.iter().sum::<f64>()).abs() < 1e-12, "sum at {k}");
    }
}

#[test]
fn outlier_rate_and_size() {
    let (rate_hz, scale) = (0.5, 2.0);
    let n = 200_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"outliers\"\nrate_hz = {rate_hz}\nscale = {scale}\n"
        )),
        n,
    );
    let hits: Vec<f64> = y.iter().copied().filter(|v| *v != 0.0).collect();
    // Binomial(N, p = rate / fs): mean N p = 10000, standard deviation sqrt(N p (1-p)).
    let p = rate_hz / FS;
    let expect = n as f64 * p;
    let sd = (n as f64 * p * (1.0 - p)).sqrt();
    assert!(
        (hits.len() as f64 - expect).abs() < 5.0 * sd,
        "{} outliers",
        hits.len()
    );
    // Spikes are scale * N(0,1): variance scale^2, relative SE sqrt(2 / count).
    let v = hits.iter().map(|h| h * h).sum::<f64>() / hits.len() as f64;
    assert!(
        rel(v, scale * scale) < 5.0 * (2.0 / hits.len() as f64).sqrt(),
        "var {v}"
    );
}

#[test]
fn outliers_with_dof_have_student_t_amplitudes() {
    let (rate_hz, scale, dof) = (0.5, 2.0, 6.0);
    let n = 400_000;
    let y = run1(
        &one(&format!(
            "[[channel.component]]\nkind = \"outliers\"\nrate_hz = {rate_hz}\nscale = {scale}\ndof = {dof}\n"
        )),
        n,
    );
    let hits: Vec<f64> = y.iter().copied().filter(|v| *v != 0.0).collect();
    let k = hits.len() as f64;
    // scale * T_6: variance scale^2 dof / (dof - 2) = 1.5 scale^2 (kurtosis 6, so the
    // relative SE of the mean square is sqrt((6 - 1) / count))
    let v = hits.iter().map(|h| h * h).sum::<f64>() / k;
    let want = scale * scale * dof / (dof - 2.0);
    assert!(rel(v, want) < 4.0 * (5.0 / k).sqrt(), "var {v} vs {want}");
    // the tail: P(|T_6| > 3.143) = 0.02 (t table), far above the normal's 0.0017
    let beyond = hits.iter().filter(|h| h.abs() > 3.143 * scale).count() as f64 / k;
    assert!(
        (beyond - 0.02).abs() < 5.0 * (0.02 * 0.98 / k).sqrt(),
        "share {beyond}"
    );
}

fn temperature(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let t = k as f64 / FS;
            20.0 + 5.0 * (t / 400.0).sin() + 0.01 * t / 10.0 + 0.3 * ((k * 7919) % 13) as f64 / 13.0
        })
        .collect()
}

#[test]
fn temperature_bias_and_thermal_rate_are_exact() {
    let n = 20_000;
    let temp = temperature(n);
    let s = one(
        "[[channel.component]]\nkind = \"temperature_bias\"\ncoeffs = [0.012, -0.0004, 1e-5]\nreference_c = 21.0\n\
         [[channel.component]]\nkind = \"temperature_bias\"\ncoeffs = [0.05]\n\
         [[channel.component]]\nkind = \"thermal_rate\"\ncoeff = 0.3\nsmoothing_s = 30.0\n",
    );
    let mut req = SimRequest::new(n, FS);
    req.temperature_c = Some(&temp);
    let sim = Simulator::new(&s, req).unwrap();
    let tb = sim.component_signal(0, 0).unwrap();
    let tb_mean_ref = sim.component_signal(0, 1).unwrap();
    let tr = sim.component_signal(0, 2).unwrap();
    let tmean = mean(&temp);
    // Slow twin of the thermal rate: direct window sums, then central differences.
    let h = 150; // round(30 s * 10 Hz / 2)
    let smooth: Vec<f64> = (0..n)
        .map(|k| {
            let lo = k.saturating_sub(h);
            let hi = (k + h + 1).min(n);
            temp[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
        })
        .collect();
    for k in 0..n {
        let u = temp[k] - 21.0;
        let want = 0.012 * u - 0.0004 * u.powi(2) + 1e-5 * u.powi(3);
        assert!((tb[k] - want).abs() < 1e-14, "temperature_bias at {k}");
        assert!((tb_mean_ref[k] - 0.05 * (temp[k] - tmean)).abs() < 1e-14);
        let d = if k == 0 {
            (smooth[1] - smooth[0]) * FS
        } else if k == n - 1 {
            (smooth[n - 1] - smooth[n - 2]) * FS
        } else {
            (smooth[k + 1] - smooth[k - 1]) * FS / 2.0
        };
        assert!(
            (tr[k] - 0.3 * d).abs() < 1e-10,
            "thermal_rate at {k}: {} vs {}",
            tr[k],
            0.3 * d
        );
    }
    // A linear temperature ramp gives exactly coeff * slope away from the ends.
    let ramp: Vec<f64> = (0..n).map(|k| 15.0 + 0.002 * k as f64 / FS).collect();
    let mut out = vec![0.0; n];
    thermal::thermal_rate(&mut out, 0.3, 30.0, FS, &ramp);
    for v in &out[h + 1..n - h - 1] {
        assert!((v - 0.3 * 0.002).abs() < 1e-9, "{v}");
    }
}

#[test]
fn heteroskedastic_scales_its_noise_exactly() {
    let n = 70_000;
    let temp = temperature(n);
    let s = one(
        "[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"white_noise\"\nslope = 0.05\n\
         [[channel.component]]\nkind = \"white_noise\"\nn = 0.01\n",
    );
    let mut req = SimRequest::new(n, FS);
    req.temperature_c = Some(&temp);
    let sim = Simulator::new(&s, req.clone()).unwrap();
    let white = sim.component_signal(0, 1).unwrap();
    let out = simulate(&s, &req).unwrap().channels[0].1.clone();
    let tmean = mean(&temp);
    for k in 0..n {
        let scale = (1.0 + 0.05 * (temp[k] - tmean)).max(0.0);
        assert_eq!(out[k], scale * white[k], "sample {k}");
    }
    // The component's own signal is (scale - 1) times the noise.
    let h = sim.component_signal(0, 0).unwrap();
    for k in (0..n).step_by(997) {
        let scale = 1.0 + 0.05 * (temp[k] - tmean);
        assert!((h[k] - (scale - 1.0) * white[k]).abs() < 1e-15);
    }
}

/// With a floor the scale is max(floor, 1 + slope (T - mean T)), exactly, and the floor
/// acts: the temperature's range takes 1 + slope (T - mean T) below it.
#[test]
fn heteroskedastic_scale_levels_off_at_its_floor() {
    let n = 70_000;
    let temp = temperature(n);
    let tmean = mean(&temp);
    assert_eq!(
        thermal::scale(0.2, 0.3, 20.0, &[10.0, 16.0, 20.0, 30.0]),
        vec![0.3, 0.3, 1.0, 3.0]
    );
    let s = one(
        "[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"white_noise\"\nslope = 0.2\nfloor = 0.3\n\
         [[channel.component]]\nkind = \"white_noise\"\nn = 0.01\n",
    );
    let mut req = SimRequest::new(n, FS);
    req.temperature_c = Some(&temp);
    let sim = Simulator::new(&s, req.clone()).unwrap();
    let white = sim.component_signal(0, 1).unwrap();
    let out = simulate(&s, &req).unwrap().channels[0].1.clone();
    let mut at_floor = 0;
    for k in 0..n {
        let line = 1.0 + 0.2 * (temp[k] - tmean);
        at_floor += usize::from(line < 0.3);
        assert_eq!(out[k], line.max(0.3) * white[k], "sample {k}");
    }
    assert!(
        at_floor > n / 20 && at_floor < n - n / 20,
        "{at_floor} of {n}"
    );
}

const TWO_AXES: &str = r#"
sample_rate_hz = 10.0
seed = 5
[[channel]]
name = "gx"
[[channel.component]]
kind = "white_noise"
n = 0.01
[[channel.component]]
kind = "cross_axis"
from = "gy"
gain = 0.02
[[channel.component]]
kind = "gauss_markov"
sigma = 0.003
tau_s = 20.0
[[channel]]
name = "gy"
[[channel.component]]
kind = "rate_random_walk"
k = 0.001
[[channel.component]]
kind = "cross_axis"
from = "gx"
gain = -0.5
"#;

#[test]
fn cross_axis_adds_the_other_channels_own_signal() {
    let s = spec(TWO_AXES);
    let n = 50_000;
    let sim = Simulator::new(&s, SimRequest::new(n, FS)).unwrap();
    let out = sim.run().unwrap();
    let (own_x, own_y) = (sim.own_signal(0).unwrap(), sim.own_signal(1).unwrap());
    let (gx, gy) = (out.channel("gx").unwrap(), out.channel("gy").unwrap());
    for k in 0..n {
        assert_eq!(gx[k], own_x[k] + 0.02 * own_y[k]);
        assert_eq!(gy[k], own_y[k] + -0.5 * own_x[k]);
    }
    // The sum of the component signals is the channel (up to rounding).
    let parts: Vec<Vec<f64>> = (0..3)
        .map(|c| sim.component_signal(0, c).unwrap())
        .collect();
    for k in (0..n).step_by(101) {
        let sum: f64 = parts.iter().map(|p| p[k]).sum();
        assert!((sum - gx[k]).abs() < 1e-12, "{sum} vs {}", gx[k]);
    }
    // A subset: gx alone is bit-identical to gx of the whole run.
    let mut req = SimRequest::new(n, FS);
    req.channels = Some(vec!["gx".into()]);
    let only = simulate(&s, &req).unwrap();
    assert_eq!(only.channels.len(), 1);
    assert_eq!(only.channel("gx").unwrap(), gx);
    // The free function agrees with the simulator.
    let c = component_signal(&s, "gx", 2, &SimRequest::new(n, FS)).unwrap();
    assert_eq!(c, parts[2]);
}

// ---------------------------------------------------------------------------------
// Determinism.

/// Every kind that needs no fitted model, long enough to span several chunks.
fn everything() -> (Spec, Vec<f64>) {
    let text = std::fs::read_to_string(common::fixture("specs/every_component.toml")).unwrap();
    // The fitted model is replaced by an inline FARMA (this test needs no fit output).
    let text = text.replace(
        "model = \"fits/gyro_y\"            # an output folder of `farma fit`\nchannel = \"gyro_y\"               # optional: which fitted channel",
        "p = 1\nq = 0\nd = 1\nf = [[0.3, 0.05]]\nma = []\nsigma = 0.002",
    );
    assert!(
        !text.contains("model = \"fits/gyro_y\""),
        "fixture changed; update this test"
    );
    let s = spec(&text);
    let n = 2 * CHUNK + 12_345;
    (s, temperature(n))
}

#[test]
fn same_seed_same_bits_other_seed_or_replica_differs() {
    let (s, temp) = everything();
    let n = temp.len();
    let mut req = SimRequest::new(n, FS);
    req.temperature_c = Some(&temp);
    let a = simulate(&s, &req).unwrap();
    let b = simulate(&s, &req).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.seed, 7);
    let mut other = req.clone();
    other.seed = Some(8);
    let c = simulate(&s, &other).unwrap();
    let mut rep = req.clone();
    rep.replica = 1;
    let d = simulate(&s, &rep).unwrap();
    for (x, y) in [(&a, &c), (&a, &d), (&c, &d)] {
        for ((_, u), (_, v)) in x.channels.iter().zip(&y.channels) {
            let same = u.iter().zip(v).filter(|(p, q)| p == q).count();
            assert!(same < n / 100, "{same} equal samples");
        }
    }
}

#[test]
fn thread_count_does_not_change_a_bit() {
    let (s, temp) = everything();
    let n = temp.len();
    let mut req = SimRequest::new(n, FS);
    req.temperature_c = Some(&temp);
    let pool = |k| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(k)
            .build()
            .unwrap()
    };
    let one_thread = pool(1).install(|| simulate(&s, &req).unwrap());
    let three = pool(3).install(|| simulate(&s, &req).unwrap());
    assert_eq!(one_thread, three);
    for (_, v) in &one_thread.channels {
        assert!(v.iter().all(|x| x.is_finite()));
    }
}

#[test]
fn bad_requests_are_clear_errors() {
    let s = one("[[channel.component]]\nkind = \"temperature_bias\"\ncoeffs = [0.01]\n");
    let err = simulate(&s, &SimRequest::new(100, FS)).unwrap_err();
    assert_eq!(err.exit_code(), 2);
    assert!(
        err.to_string().contains("needs a temperature series"),
        "{err}"
    );
    let temp = vec![20.0; 99];
    let mut req = SimRequest::new(100, FS);
    req.temperature_c = Some(&temp);
    let err = simulate(&s, &req).unwrap_err();
    assert!(err.to_string().contains("99 values"), "{err}");
    let s = one(
        "[[channel.component]]\nkind = \"sinusoid\"\namplitude = 1.0\nfreq_hz = 3.0\nphase_rad = 0.0\n",
    );
    let err = simulate(&s, &SimRequest::new(100, 5.0)).unwrap_err();
    assert!(err.to_string().contains("Nyquist"), "{err}");
    let err = simulate(&s, &SimRequest::new(0, FS)).unwrap_err();
    assert_eq!(err.exit_code(), 2);
    let mut req = SimRequest::new(10, FS);
    req.channels = Some(vec!["nope".into()]);
    let err = simulate(&s, &req).unwrap_err();
    assert!(err.to_string().contains("no channel 'nope'"), "{err}");
}

// ---------------------------------------------------------------------------------
// A fitted model, and the command line.

/// Fits gyro_y of the bundled multi-axis log into `dir/fits/gyro_y` with `farma fit`;
/// returns its JSON line.
fn fit_gyro_y(dir: &Path) -> serde_json::Value {
    let out = dir.join("fits").join("gyro_y");
    let o = common::farma(
        &[
            "fit",
            common::fixture("multiaxis.csv").to_str().unwrap(),
            "--channel",
            "gyro_y",
            "--order",
            "2,1,1",
            "--grid",
            "41",
            "--json",
            "-o",
            out.to_str().unwrap(),
        ],
        dir,
    );
    assert_eq!(o.status.code(), Some(0), "{}", common::stderr(&o));
    serde_json::from_str(common::stdout(&o).trim()).unwrap()
}

#[test]
fn fitted_model_loads_back_and_drives_the_recursion() {
    use farma::model::folder::ModelDir;
    let dir = tempfile::tempdir().unwrap();
    let fit = fit_gyro_y(dir.path());
    let folder = ModelDir::new(dir.path().join("fits/gyro_y"));
    let (name, m) = folder.load(None).unwrap();
    assert_eq!((m.p(), m.q(), m.d()), (2, 1, 1));
    assert_eq!(name, "gyro_y");
    assert_eq!(m.sigma2, fit["sigma2"].as_f64().unwrap());
    assert_eq!(m.mean, fit["mean"].as_f64().unwrap());
    let b: Vec<f64> = fit["b"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(m.b, b);
    assert_eq!(m.coef.n_grid(), 41);
    // The grid is read in channel units; f is linear between grid points, constant
    // beyond, at centred index values.
    let g = &m.coef.grid;
    let f1 = |u: f64| {
        let mut out = [0.0; 2];
        m.f(u - m.mean, &mut out);
        out[0]
    };
    assert_eq!(f1(g[3]), m.coef.at(3, 1));
    let mid = 0.25 * g[3] + 0.75 * g[4];
    assert!((f1(mid) - (0.25 * m.coef.at(3, 1) + 0.75 * m.coef.at(4, 1))).abs() < 1e-12);
    assert_eq!(f1(g[0] - 10.0), m.coef.at(0, 1));
    assert_eq!(f1(g[40] + 10.0), m.coef.at(40, 1));
    // A spec naming an unknown fitted channel is a clear error.
    assert!(
        folder
            .load(Some("gyro_q"))
            .unwrap_err()
            .to_string()
            .contains("no fitted channel 'gyro_q'")
    );

    // Simulate the model; running it backwards recovers white innovations of
    // variance sigma2 (relative standard error sqrt(2 / N)).
    let s = spec(
        "sample_rate_hz = 10.0\nseed = 2\n[[channel]]\nname = \"gyro_y\"\n[[channel.component]]\nkind = \"farma\"\nmodel = \"fits/gyro_y\"\n",
    );
    let n = 60_000;
    let mut req = SimRequest::new(n, FS);
    req.base_dir = Some(dir.path().to_path_buf());
    let y = simulate(&s, &req).unwrap().channels[0].1.clone();
    let z: Vec<f64> = y.iter().map(|v| v - m.mean).collect();
    let f = |k: usize, u: f64| {
        let mut out = [0.0; 2];
        m.f(u, &mut out);
        out[k - 1]
    };
    let e = farma_residuals(&z, 1, &f, 2, &m.b, 500);
    let v = var(&e);
    assert!(
        rel(v, m.sigma2) < 5.0 * (2.0 / e.len() as f64).sqrt(),
        "{v} vs {}",
        m.sigma2
    );
    let r1 = acov(&e, 1) / acov(&e, 0);
    assert!(r1.abs() < 5.0 / (e.len() as f64).sqrt(), "r1 {r1}");
    // The output is in channel units: its mean is the fitted mean (standard error by
    // batch means: 60 batches of 1000 samples, far longer than the correlation).
    let batches: Vec<f64> = y.chunks(1000).map(mean).collect();
    let se = (var(&batches) / batches.len() as f64).sqrt();
    assert!(
        (mean(&y) - m.mean).abs() < 5.0 * se,
        "mean {} vs {} (se {se})",
        mean(&y),
        m.mean
    );
}

/// Files left in `dir` besides `keep` (temporary files included).
fn leftovers(dir: &Path, keep: &[&str]) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect()
}

#[test]
fn cli_simulates_every_component_like_a_real_log_and_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fit_gyro_y(d);
    let spec_path = d.join("every.toml");
    std::fs::copy(common::fixture("specs/every_component.toml"), &spec_path).unwrap();
    let real = common::fixture("multiaxis.csv");
    let cache = d.join("cache");
    for ext in ["parquet", "arrow", "csv"] {
        let out = d.join(format!("sim.{ext}"));
        let o = common::farma(
            &[
                "simulate",
                spec_path.to_str().unwrap(),
                "--like",
                real.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--json",
            ],
            &cache,
        );
        assert_eq!(o.status.code(), Some(0), "{}", common::stderr(&o));
        let v: serde_json::Value = serde_json::from_str(common::stdout(&o).trim()).unwrap();
        assert_eq!(v["n_samples"], 4000);
        assert_eq!(v["sample_rate_hz"], 10.0);
        assert_eq!(v["seed"], 7);
        assert_eq!(v["channels"].as_array().unwrap().len(), 3);
        let o = common::farma(&["info", out.to_str().unwrap(), "--json"], &cache);
        assert_eq!(o.status.code(), Some(0), "{}", common::stderr(&o));
        let info: serde_json::Value = serde_json::from_str(common::stdout(&o).trim()).unwrap();
        assert_eq!(info["n_samples"], 4000);
        assert_eq!(info["sample_rate_hz"], 10.0);
        let names: Vec<&str> = info["channels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["name"].as_str().unwrap())
            .collect();
        assert_eq!(names, ["gyro_x", "gyro_y", "gyro_z", "temp_c"]);
        let o = common::farma(
            &[
                "adev",
                out.to_str().unwrap(),
                "--channel",
                "gyro_x",
                "--json",
            ],
            &cache,
        );
        assert_eq!(o.status.code(), Some(0), "{}", common::stderr(&o));
    }
    // The store holds exactly what the library simulates, and the real temperature.
    let store = farma::store::Store::open(&d.join("sim.arrow")).unwrap();
    let spec = farma::simulator::load_spec(&spec_path).unwrap();
    let (_, cols) = common::reference_parse_csv(&real);
    let temp = cols[4].clone();
    let mut req = SimRequest::new(4000, FS);
    req.temperature_c = Some(&temp);
    req.base_dir = Some(d.to_path_buf());
    let lib = simulate(&spec, &req).unwrap();
    for (name, v) in &lib.channels {
        assert_eq!(store.column(name).unwrap(), v.as_slice(), "{name}");
    }
    assert_eq!(store.column("temp_c").unwrap(), temp.as_slice());
    let t = store.column("time").unwrap();
    assert_eq!(t[0], 0.0);
    assert_eq!(t[3999], 399.9);
    // CSV cells are the shortest round-trip decimal: the values read back exactly.
    let (names, csv) = common::reference_parse_csv(&d.join("sim.csv"));
    assert_eq!(names[0], "time");
    assert_eq!(csv[1], lib.channels[0].1);
}

#[test]
fn cli_refuses_bad_requests_with_exit_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cache = d.join("cache");
    std::fs::create_dir(&cache).unwrap();
    let every = common::fixture("specs/every_component.toml");
    let simple = d.join("simple.toml");
    std::fs::write(
        &simple,
        "sample_rate_hz = 10.0\n[[channel]]\nname = \"x\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.1\n",
    )
    .unwrap();
    let no_temp_log = d.join("notemp.csv");
    std::fs::write(&no_temp_log, "time,gyro_x\n0,1\n0.1,2\n0.2,3\n").unwrap();
    let out = d.join("out.parquet");
    let (e, s, o, nt) = (
        every.to_str().unwrap(),
        simple.to_str().unwrap(),
        out.to_str().unwrap(),
        no_temp_log.to_str().unwrap(),
    );
    let txt = d.join("out.txt");
    let bad_spec = common::fixture("specs/bad")
        .read_dir()
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["simulate", s, "-o", o], "--duration"),
        (vec!["simulate", s, "--duration=-5", "-o", o], "--duration"),
        (
            vec!["simulate", s, "--duration", "0.01", "-o", o],
            "less than one sample",
        ),
        (
            vec![
                "simulate",
                s,
                "--duration",
                "10",
                "-o",
                txt.to_str().unwrap(),
            ],
            ".parquet",
        ),
        (
            vec![
                "simulate",
                s,
                "--duration",
                "10",
                "--channel",
                "nope",
                "-o",
                o,
            ],
            "no channel 'nope'",
        ),
        (vec!["simulate", e, "--duration", "10", "-o", o], "--like"),
        (vec!["simulate", e, "--like", nt, "-o", o], "temp_c"),
        (
            vec![
                "simulate",
                bad_spec.to_str().unwrap(),
                "--duration",
                "10",
                "-o",
                o,
            ],
            "",
        ),
        (
            vec![
                "simulate",
                "/no/such/spec.toml",
                "--duration",
                "10",
                "-o",
                o,
            ],
            "spec.toml",
        ),
    ];
    for (args, needle) in cases {
        let r = common::farma(&args, &cache);
        let err = common::stderr(&r);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        let left = leftovers(d, &["cache", "simple.toml", "notemp.csv"]);
        assert!(left.is_empty(), "{args:?} left {left:?}");
    }
}

#[test]
fn only_the_channels_simulated_need_a_temperature() {
    let (s, _) = everything();
    let mut req = SimRequest::new(1000, FS);
    req.channels = Some(vec!["gyro_z".into()]);
    let out = simulate(&s, &req).unwrap();
    assert_eq!(out.channels.len(), 1);
    // gyro_y couples gyro_x, whose temperature effects need the series.
    req.channels = Some(vec!["gyro_y".into()]);
    let err = simulate(&s, &req).unwrap_err();
    assert!(
        err.to_string().contains("needs a temperature series"),
        "{err}"
    );
}
