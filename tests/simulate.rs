//! The simulator (`farma simulate`, `farma::simulator::generate`): each component
//! against its theory, determinism, thread-count independence, the CLI.
//!
//! Statistical checks use fixed seeds and a tolerance of 5 standard errors of the
//! estimate at the sample size used (the standard error's formula is given at each
//! check), so they fail only when the generator is wrong.

mod common;

use std::path::Path;

use farma::simulator::generate::markov::bias_instability_bank;
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

/// Exact Allan variance at averaging factor m of a sum of stationary AR(1)
/// processes with stationary variance s^2 and phi = exp(-dt / T): Var(mean of m) -
/// Cov(adjacent means) from the autocovariance s^2 phi^|j|.
fn bank_avar(bank: &[(f64, f64)], fs: f64, m: usize) -> f64 {
    let mut total = 0.0;
    for &(t, s) in bank {
        let phi = (-1.0 / (fs * t)).exp();
        let r = |j: usize| s * s * phi.powi(j as i32);
        let mf = m as f64;
        let mut var = mf * r(0);
        for j in 1..m {
            var += 2.0 * (mf - j as f64) * r(j);
        }
        let mut cov = 0.0;
        for j in 1..2 * m {
            cov += j.min(2 * m - j) as f64 * r(j);
        }
        total += (var - cov) / (mf * mf);
    }
    total
}

#[test]
fn bias_instability_bank_has_the_flicker_floor() {
    // The approximation itself, exactly: ADEV within 8 % of 0.664 b on [tau_min, tau_max].
    let b = 1.0;
    let floor = (2.0 * std::f64::consts::LN_2 / std::f64::consts::PI).sqrt() * b;
    let bank = bias_instability_bank(b, 1.0, 1000.0);
    for tau in [1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0] {
        let a = bank_avar(&bank, FS, (tau * FS) as usize).sqrt();
        assert!(rel(a, floor) < 0.08, "tau {tau}: {a} vs floor {floor}");
    }
    // And the floor is flat in the middle of the range (within 2 %).
    let mid = bank_avar(&bank, FS, 300).sqrt();
    assert!(rel(mid, floor) < 0.02, "mid {mid}");
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
    for m in [5, 20, 100, 500] {
        let want = bank_avar(&bank, FS, m).sqrt();
        let a = oadev(&y, m, FS);
        assert!(rel(a, want) < tol5(-1, m, n), "m {m}: adev {a} vs {want}");
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
    for m in [10, 100, 1000] {
        let tau = m as f64 / FS;
        // Discrete-time exact: k^2 tau / 3 (1 + 1 / (2 m^2)).
        let want = (k * k * tau / 3.0 * (1.0 + 0.5 / (m * m) as f64)).sqrt();
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
    // Variance: effective sample size N (1 - phi^2) / (1 + phi^2) ~ 5000 here (Bartlett),
    // relative standard error sqrt(2 / N_eff) = 2 %.
    let n_eff = n as f64 * (1.0 - phi * phi) / (1.0 + phi * phi);
    let v = var(&y);
    assert!(
        rel(v, sigma * sigma) < 5.0 * (2.0 / n_eff).sqrt(),
        "var {v}"
    );
    // Autocorrelation at lag tau_s is exp(-1); Bartlett's standard error of r_k for an
    // AR(1) is below sqrt((1 + phi^2) / ((1 - phi^2) N)) = 1 %.
    let lag = (tau_s * FS) as usize;
    let r = acov(&y, lag) / acov(&y, 0);
    let se = ((1.0 + phi * phi) / ((1.0 - phi * phi) * n as f64)).sqrt();
    assert!((r - (-1f64).exp()).abs() < 5.0 * se, "r({lag}) = {r}");
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
        !text.contains("fits/gyro_y"),
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
