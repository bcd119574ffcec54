//! Online updates (recursive least squares): with lambda = 1 the update equals the
//! batch local fits on the concatenated data (same residuals, same bandwidth, direct
//! KD-tree path); with lambda < 1 it equals a brute-force exponentially weighted least
//! squares over the new rows; the state file round-trips bit for bit.

use farma::estimator::direct::{DirectIndex, fit_grid};
use farma::estimator::kernel::biweight;
use farma::estimator::linalg::spd_solve_inverse;
use farma::estimator::update::{state_from_fit, state_from_fit_direct, update};
use farma::estimator::{FarmaParams, FitPath, PointStatus, VcProblem, fit};
use farma::model::ChannelState;
use farma::model::folder::state_file::{read_state, write_state};
use farma::model::{Farma, FitReport};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// FARMA(2,1,1): f_1(z) = 0.3 + 0.4 exp(-z^2), f_2(z) = -0.2 + 0.1 tanh(z), b_1 = -0.5.
fn simulate(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let burn = 200;
    let mut x = vec![0.0; n + burn];
    let mut e = vec![0.0; n + burn];
    for t in 0..n + burn {
        e[t] = StandardNormal.sample(&mut rng);
        let z = if t >= 1 { x[t - 1] } else { 0.0 };
        let mut s = e[t] + 0.2;
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

fn fitted(x: &[f64], q: usize) -> (Farma, FitReport) {
    let params = FarmaParams {
        p: 2,
        q,
        d: 1,
        grid_size: 25,
        bandwidth: Some(1.2),
        path: FitPath::Direct,
        ..FarmaParams::default()
    }
    .validate(x.len())
    .unwrap();
    fit(x, &params).unwrap()
}

fn scale_of(f: &[f64]) -> f64 {
    f.iter()
        .filter(|v| v.is_finite())
        .fold(0.0f64, |a, v| a.max(v.abs()))
}

#[test]
fn update_without_forgetting_equals_batch_on_concatenated_data() {
    let x = simulate(4000, 11);
    let (old, new) = x.split_at(2500);
    for q in [1usize, 0] {
        let m = fitted(old, q);
        let st = state_from_fit("x", old, &m.0, &m.1);
        // the state's normal equations reproduce the batch fit at the fit's residuals
        let xc: Vec<f64> = old.iter().map(|v| v - m.0.mean).collect();
        let prob = VcProblem::new(&xc, &m.1.residuals, &m.0.b, 2, 1);
        let start_fit = fit_grid(
            &prob,
            &DirectIndex::build(&prob),
            &m.0.coef.grid,
            m.0.bandwidth,
        );
        let up = update(&st, new, 1.0).unwrap();
        assert_eq!(up.2.residuals.len(), new.len());
        assert_eq!(up.1.n, 4000);

        // batch reference: direct path on the concatenated series, residuals as the
        // update produced them, the updated b, the same bandwidth
        let xa: Vec<f64> = x.iter().map(|v| v - m.0.mean).collect();
        let mut ea = m.1.residuals.clone();
        ea.extend(&up.2.residuals);
        let prob = VcProblem::new(&xa, &ea, &up.0.b, 2, 1);
        let batch = fit_grid(
            &prob,
            &DirectIndex::build(&prob),
            &m.0.coef.grid,
            m.0.bandwidth,
        );
        let scale = scale_of(&batch.f);
        let (mut worst, mut moved, mut compared) = (0.0f64, 0.0f64, 0);
        for g in 0..m.0.coef.grid.len() {
            assert_eq!(batch.status[g], up.2.local.status[g], "status at {g}");
            assert_eq!(batch.n_support[g], up.2.local.n_support[g]);
            if batch.status[g] != PointStatus::Ok {
                continue;
            }
            for k in 0..2 {
                let (a, b) = (up.2.local.f[g * 2 + k], batch.f[g * 2 + k]);
                worst = worst.max((a - b).abs() / scale);
                let (sa, sb) = (up.2.local.slope[g * 2 + k], batch.slope[g * 2 + k]);
                worst = worst.max((sa - sb).abs() * m.0.bandwidth / scale);
                if start_fit.status[g] == PointStatus::Ok {
                    moved = moved.max((start_fit.f[g * 2 + k] - b).abs() / scale);
                    compared += 1;
                }
            }
        }
        eprintln!("q = {q}: worst relative difference {worst:.3e}, the fit moved by {moved:.3e}");
        assert!(compared > 20);
        assert!(worst < 1e-8, "q = {q}: RLS vs batch {worst:e}");
        assert!(
            moved > 1e-3,
            "the new samples must change the fit ({moved:e})"
        );

        // b: RLS from the fitted b with the fitted rows' information, against the
        // closed form (S_0 + sum phi phi')^-1 (S_0 b_0 + sum phi w)
        if q == 1 {
            let (mut s, mut r) = (st.b_gram[0], st.b_gram[0] * m.0.b[0]);
            for (k, w) in up.2.w.iter().enumerate() {
                let phi = ea[2500 + k - 1];
                s += phi * phi;
                r += phi * w;
            }
            let want = r / s;
            assert!(
                (up.0.b[0] - want).abs() < 1e-10 * want.abs(),
                "b {:?} vs {want}",
                up.0.b
            );
            assert!((up.0.b[0] - m.0.b[0]).abs() > 1e-6);
        } else {
            // without an MA part the a priori residual is w_t itself
            assert_eq!(up.2.residuals, up.2.w);
        }
        // sigma^2 = RSS / (N - max(p,q,d)) over all samples
        let rss: f64 = ea[2..].iter().map(|v| v * v).sum();
        assert!((up.2.rss - rss).abs() < 1e-10 * rss);
        assert!((up.0.sigma2 - rss / 3998.0).abs() < 1e-10 * up.0.sigma2);
    }
}

/// Brute force: (l^n S_0 + sum_k l^(n-1-k) K z z')^-1 (l^n C_0 + sum_k l^(n-1-k) K z r') (1, -b)'
/// at grid point g, over all new rows (no tree).
fn brute_ewls(
    st: &ChannelState,
    new: &[f64],
    e_new: &[f64],
    b: &[f64],
    lam: f64,
    g: usize,
) -> Option<Vec<f64>> {
    let (p, q, d) = (st.p, st.q, st.d);
    let (n, nc) = (2 * p, 1 + q);
    let lag = p.max(q).max(d);
    let mut x = st.x_tail.clone();
    x.extend(new.iter().map(|v| v - st.mean));
    let mut e = st.e_tail.clone();
    e.extend(e_new);
    let nn = new.len();
    let ln = lam.powi(nn as i32);
    let mut s: Vec<f64> = st.gram[g * n * n..(g + 1) * n * n]
        .iter()
        .map(|v| v * ln)
        .collect();
    let mut c: Vec<f64> = st.cross[g * n * nc..(g + 1) * n * nc]
        .iter()
        .map(|v| v * ln)
        .collect();
    let (ug, h) = (st.grid[g], st.bandwidth);
    for k in 0..nn {
        let t = lag + k;
        let u = x[t - d];
        if !(ug - h <= u && u < ug + h) {
            continue;
        }
        let w = (u - ug) / h;
        let kw = biweight(w) * lam.powi((nn - 1 - k) as i32);
        let z: Vec<f64> = (0..n)
            .map(|i| {
                if i < p {
                    x[t - 1 - i]
                } else {
                    w * x[t - 1 - (i - p)]
                }
            })
            .collect();
        let mut r = vec![x[t]];
        r.extend((0..q).map(|j| e[t - 1 - j]));
        for i in 0..n {
            for j in 0..n {
                s[i * n + j] += kw * z[i] * z[j];
            }
            for col in 0..nc {
                c[i * nc + col] += kw * z[i] * r[col];
            }
        }
    }
    let rhs: Vec<f64> = (0..n)
        .map(|i| c[i * nc] - (0..q).map(|j| b[j] * c[i * nc + 1 + j]).sum::<f64>())
        .collect();
    spd_solve_inverse(&s, &rhs, n).map(|(z, _, _)| z)
}

#[test]
fn update_with_forgetting_equals_exponentially_weighted_least_squares() {
    let x = simulate(3200, 5);
    let (old, new) = x.split_at(2000);
    let m = fitted(old, 1);
    let st = state_from_fit("x", old, &m.0, &m.1);
    let lam = 0.998;
    let up = update(&st, new, lam).unwrap();
    let scale = scale_of(&up.2.local.f);
    let mut worst = 0.0f64;
    let mut checked = 0;
    let mut unforgotten = 0.0f64;
    let plain = update(&st, new, 1.0).unwrap();
    for g in 0..st.n_grid() {
        if up.2.local.status[g] != PointStatus::Ok {
            continue;
        }
        let want = brute_ewls(&st, new, &up.2.residuals, &up.0.b, lam, g).unwrap();
        for k in 0..2 {
            worst = worst.max((up.2.local.f[g * 2 + k] - want[k]).abs() / scale);
            worst =
                worst.max((up.2.local.slope[g * 2 + k] * st.bandwidth - want[2 + k]).abs() / scale);
            unforgotten = unforgotten.max((plain.2.local.f[g * 2 + k] - want[k]).abs() / scale);
        }
        checked += 1;
    }
    eprintln!(
        "lambda = {lam}: worst {worst:.3e} over {checked} points; without forgetting {unforgotten:.3e} away"
    );
    assert!(checked > 10);
    assert!(
        worst < 1e-8,
        "RLS with forgetting vs brute force: {worst:e}"
    );
    assert!(unforgotten > 1e-3, "forgetting must matter");
    // b: closed form of the exponentially weighted regression of w on e_{t-1}
    let nn = new.len();
    let (mut s, mut r) = (
        st.b_gram[0] * lam.powi(nn as i32),
        st.b_gram[0] * m.0.b[0] * lam.powi(nn as i32),
    );
    let mut e = st.e_tail.clone();
    e.extend(&up.2.residuals);
    for k in 0..nn {
        let phi = e[2 + k - 1];
        let wt = lam.powi((nn - 1 - k) as i32);
        s += wt * phi * phi;
        r += wt * phi * up.2.w[k];
    }
    assert!(
        (up.0.b[0] - r / s).abs() < 1e-10,
        "{:?} vs {}",
        up.0.b,
        r / s
    );
    // the state after the update holds the discounted normal equations
    let want = brute_ewls(&st, new, &up.2.residuals, &up.0.b, lam, 12).unwrap();
    let n = 4;
    let s12 = &up.1.gram[12 * n * n..13 * n * n];
    let rhs: Vec<f64> = (0..n)
        .map(|i| up.1.cross[12 * n * 2 + i * 2] - up.0.b[0] * up.1.cross[12 * n * 2 + i * 2 + 1])
        .collect();
    let (sol, _, _) = spd_solve_inverse(s12, &rhs, n).unwrap();
    for i in 0..n {
        assert!(
            (sol[i] - want[i]).abs() < 1e-10 * scale,
            "{sol:?} vs {want:?}"
        );
    }
}

/// A long update with forgetting: the recursion's P / lambda amplifies its rounding as
/// lambda^-k (Ljung and Ljung 1985), so P and Theta are derived afresh from the
/// discounted normal equations whenever the amplification since the last derivation
/// passes 1e4, and the written f are solved from those normal equations. Without the
/// re-derivation, 12,000 new rows at lambda = 0.99 end about 1e2 away from the brute
/// force, and 0.99^74000 underflows, failing the update as "samples far off the
/// model's scale".
#[test]
fn a_long_update_with_forgetting_stays_with_the_weighted_least_squares() {
    let x = simulate(14_000, 8);
    let (old, new) = x.split_at(2000);
    let m = fitted(old, 1);
    let st = state_from_fit("x", old, &m.0, &m.1);
    for lam in [0.99, 0.95] {
        let up = update(&st, new, lam).unwrap();
        let scale = scale_of(&up.2.local.f);
        let mut worst = 0.0f64;
        let mut checked = 0;
        for g in 0..st.n_grid() {
            if up.2.local.status[g] != PointStatus::Ok {
                continue;
            }
            let Some(want) = brute_ewls(&st, new, &up.2.residuals, &up.0.b, lam, g) else {
                continue;
            };
            for (f, w) in up.2.local.f[g * 2..g * 2 + 2].iter().zip(&want) {
                worst = worst.max((f - w).abs() / scale);
            }
            checked += 1;
        }
        eprintln!(
            "lambda = {lam}: worst {worst:.3e} over {checked} points, sigma2 {}",
            up.0.sigma2
        );
        assert!(checked > 10, "lambda {lam}: {checked} points");
        assert!(worst < 1e-8, "lambda {lam}: worst {worst:e}");
        assert!(up.0.sigma2 < 2.0, "lambda {lam}: sigma2 {}", up.0.sigma2);
        // b: the closed form of the exponentially weighted regression of w on e_{t-1}
        let nn = new.len();
        let ln = lam.powi(nn as i32);
        let (mut s, mut r) = (st.b_gram[0] * ln, st.b_gram[0] * m.0.b[0] * ln);
        let mut e = st.e_tail.clone();
        e.extend(&up.2.residuals);
        for k in 0..nn {
            let wt = lam.powi((nn - 1 - k) as i32);
            s += wt * e[2 + k - 1] * e[2 + k - 1];
            r += wt * e[2 + k - 1] * up.2.w[k];
        }
        assert!(
            (up.0.b[0] - r / s).abs() < 1e-10,
            "lambda {lam}: b {:?} vs {}",
            up.0.b,
            r / s
        );
    }
}

#[test]
fn two_updates_equal_one_and_the_state_file_round_trips() {
    let x = simulate(3000, 8);
    let m = fitted(&x[..2000], 1);
    let st = state_from_fit("gyro", &x[..2000], &m.0, &m.1);
    for lam in [1.0, 0.999] {
        let once = update(&st, &x[2000..], lam).unwrap();
        let first = update(&st, &x[2000..2400], lam).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.parquet");
        write_state(&path, &[&first.1], &[("order", "2,1,1".into())]).unwrap();
        let (back, md) = read_state(&path).unwrap();
        assert_eq!(back.len(), 1);
        assert_eq!(back[0], first.1, "bit-exact round trip");
        assert!(md.iter().any(|(k, v)| k == "order" && v == "2,1,1"));
        let twice = update(&back[0], &x[2400..], lam).unwrap();
        let scale = scale_of(&once.2.local.f);
        for (a, b) in once.2.local.f.iter().zip(&twice.2.local.f) {
            assert!((a - b).abs() < 1e-9 * scale, "{a} vs {b}");
        }
        for (a, b) in once.2.residuals[400..].iter().zip(&twice.2.residuals) {
            assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        }
        assert!((once.0.b[0] - twice.0.b[0]).abs() < 1e-10);
        assert_eq!(twice.1.n, 3000);
        assert_eq!(twice.2.first_t, 2400);
    }
    // bad input
    assert!(update(&st, &x[2000..], 1.5).is_err());
    assert!(update(&st, &x[2000..], 0.0).is_err());
    assert!(update(&st, &[], 1.0).is_err());
    assert!(update(&st, &[1.0, f64::NAN], 1.0).is_err());
}

/// A state file with one field of channel "gyro" edited: read_state must reject it
/// with an error (exit 2) naming the file, the channel and the field, and `update`
/// on the edited state must return an error, never panic.
#[test]
fn corrupt_state_fields_are_rejected_naming_file_channel_and_field() {
    let x = simulate(2000, 21);
    let m = fitted(&x, 1);
    let st = state_from_fit("gyro", &x, &m.0, &m.1);
    let new = simulate(300, 22);
    type Edit = Box<dyn Fn(&mut ChannelState)>;
    let cases: Vec<(&str, Edit, &str)> = vec![
        ("mean NaN", Box::new(|s| s.mean = f64::NAN), "'mean'"),
        ("mean inf", Box::new(|s| s.mean = f64::INFINITY), "'mean'"),
        ("mean 1e300", Box::new(|s| s.mean = 1e300), "'mean'"),
        (
            "x_tail NaN",
            Box::new(|s| s.x_tail[1] = f64::NAN),
            "'x_tail'",
        ),
        (
            "e_tail NaN",
            Box::new(|s| s.e_tail[0] = f64::NAN),
            "'e_tail'",
        ),
        ("b NaN", Box::new(|s| s.b[0] = f64::NAN), "'b'"),
        ("b not invertible", Box::new(|s| s.b[0] = -1.5), "'b'"),
        (
            "grid inf",
            Box::new(|s| *s.grid.last_mut().unwrap() = f64::INFINITY),
            "'grid'",
        ),
        ("gram NaN", Box::new(|s| s.gram[5] = f64::NAN), "'gram'"),
        ("rss negative", Box::new(|s| s.rss = -1.0), "'rss'"),
        ("rows zero", Box::new(|s| s.rows = 0.0), "'rows'"),
        (
            "forgetting NaN",
            Box::new(|s| s.forgetting = f64::NAN),
            "'forgetting'",
        ),
        (
            "forgetting 2",
            Box::new(|s| s.forgetting = 2.0),
            "'forgetting'",
        ),
        ("n zero", Box::new(|s| s.n = 0), "'n'"),
        ("n below the tails", Box::new(|s| s.n = 2), "'n'"),
        (
            "kernel mass negative",
            Box::new(|s| s.kernel_mass[3] = -1.0),
            "'kernel_mass'",
        ),
        (
            "n_support above n",
            Box::new(|s| s.n_support[3] = 1 << 40),
            "'n_support'",
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (what, edit, field) in &cases {
        let mut bad = st.clone();
        edit(&mut bad);
        let path = dir.path().join("state.parquet");
        write_state(&path, &[&bad], &[]).unwrap();
        let err = read_state(&path).expect_err(what).to_string();
        assert!(
            err.contains("state.parquet") && err.contains("'gyro'") && err.contains(field),
            "{what}: {err}"
        );
        let e = read_state(&path).unwrap_err();
        assert_eq!(e.exit_code(), 2, "{what}: {err}");
        // the library entry point checks too (no panic on a NaN index value)
        assert!(
            update(&bad, &new, 1.0).is_err(),
            "{what}: update accepted it"
        );
    }
    // two rows for one channel
    let path = dir.path().join("dup.parquet");
    let mut other = st.clone();
    other.mean += 1.0;
    write_state(&path, &[&st, &other], &[]).unwrap();
    let err = read_state(&path).unwrap_err().to_string();
    assert!(
        err.contains("dup.parquet") && err.contains("'gyro'") && err.contains("more than one"),
        "{err}"
    );
    // the unedited state still reads back
    write_state(&path, &[&st], &[]).unwrap();
    assert_eq!(read_state(&path).unwrap().0[0], st);
    // a state marked linear_start round-trips with it; a state file without the column
    // (written before it) reads as false
    let mut lin = st.clone();
    lin.linear_start = true;
    write_state(&path, &[&lin], &[]).unwrap();
    assert!(read_state(&path).unwrap().0[0].linear_start);
    let table = farma::model::folder::state_file::state_table(&[&st]).unwrap();
    let old = table
        .project(
            &(0..table.num_columns())
                .filter(|&i| table.schema().field(i).name() != "linear_start")
                .collect::<Vec<_>>(),
        )
        .unwrap();
    assert_eq!(old.num_columns() + 1, table.num_columns());
    farma::output::write_parquet(
        &path,
        &old,
        &farma::model::folder::state_file::state_metadata(&[]),
    )
    .unwrap();
    let back = read_state(&path).unwrap().0;
    assert!(!back[0].linear_start);
    assert_eq!(back[0], st);
}

/// New samples far off the model's scale make the RLS recursions non-finite: the
/// update must fail naming the problem, not return NaN coefficients.
#[test]
fn update_on_samples_far_off_the_models_scale_fails_instead_of_returning_nan() {
    let x = simulate(3000, 31);
    let m = fitted(&x[..2000], 1);
    let st = state_from_fit("gyro", &x[..2000], &m.0, &m.1);
    for scale in [1e12, 1e20, 1e100] {
        let new: Vec<f64> = x[2000..].iter().map(|v| v * scale).collect();
        match update(&st, &new, 1.0) {
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains("non-finite") && msg.contains("scale"), "{msg}");
                assert_eq!(e.exit_code(), 2);
            }
            Ok(u) => {
                // a finite result is allowed only if it is finite everywhere
                let m = &u.0;
                assert!(
                    m.b.iter().all(|v| v.is_finite())
                        && m.sigma2.is_finite()
                        && u.2.local.f.iter().all(|v| v.is_finite())
                        && u.1.check().is_ok(),
                    "scale {scale}: non-finite model returned: b = {:?}, sigma2 = {}",
                    m.b,
                    m.sigma2
                );
                assert!(!u.2.notes.is_empty(), "scale {scale}: no note");
            }
        }
    }
    // an overflow of new - mean is an error too
    let mut st2 = st.clone();
    st2.mean = -1e308;
    st2.grid.iter_mut().for_each(|g| *g *= 1e300);
    let r = update(&st2, &[1.7e308, 1.7e308], 1.0);
    assert!(r.is_err());
}

/// Strong forgetting leaves the local fits too few samples: the update says so in its
/// notes (and sigma^2's rise); mild forgetting and none add no such note.
#[test]
fn strong_forgetting_and_a_level_shift_are_noted() {
    let x = simulate(3000, 41);
    let m = fitted(&x[..2000], 1);
    let st = state_from_fit("gyro", &x[..2000], &m.0, &m.1);
    let new = &x[2000..];
    let strong = update(&st, new, 0.9).unwrap();
    let notes = strong.2.notes.join("\n");
    assert!(notes.contains("forgetting factor 0.9"), "{notes}");
    assert!(notes.contains("effective memory"), "{notes}");
    for lam in [1.0, 0.999] {
        let u = update(&st, new, lam).unwrap();
        assert!(
            u.2.notes.iter().all(|n| !n.contains("forgetting factor")
                && !n.contains("sigma2 rose")
                && !n.contains("not invertible")
                && !n.contains("outside the reach")),
            "lambda {lam}: {:?}",
            u.2.notes
        );
    }
    // sigma^2 rise: a new log with ten times the noise
    let loud: Vec<f64> = new.iter().map(|v| 30.0 * v).collect();
    let u = update(&st, &loud, 1.0).unwrap();
    assert!(
        u.2.notes.iter().any(|n| n.contains("sigma2 rose")),
        "{:?}",
        u.2.notes
    );
    // a level shift far beyond the grid: noted, and a non-invertible b noted if any
    let shift = x[..2000].iter().fold(0.0f64, |a, v| a.max(v.abs())) * 10.0;
    let shifted: Vec<f64> = new.iter().map(|v| v + shift).collect();
    let u = update(&st, &shifted, 1.0).unwrap();
    let notes = u.2.notes.join("\n");
    assert!(notes.contains("outside the reach"), "{notes}");
    let invertible = farma::estimator::arma::ma_invertible(&u.0.b);
    assert_eq!(
        notes.contains("not invertible"),
        !invertible,
        "b = {:?}: {notes}",
        u.0.b
    );
}

/// The fast path's state (its normal equations from moment tables) equals the direct
/// pass's, its slow twin, for several orders, delays and bandwidths (GCV's and fixed,
/// wide and narrow): S, S2 and C to 1e-11 of each matrix's scale, the kernel mass to
/// 1e-12 relative, the support counts exactly; and the update from it gives the
/// update from the direct state.
#[test]
fn the_tables_state_equals_the_direct_pass_state() {
    let x = simulate(6000, 23);
    let (old, new) = x.split_at(5000);
    for (p, q, d, h) in [
        (2, 1, 1, None),
        (1, 0, 1, Some(0.3)),
        (2, 2, 2, Some(2.5)),
        (3, 1, 1, None),
    ] {
        let params = FarmaParams {
            p,
            q,
            d,
            grid_size: 41,
            bandwidth: h,
            ..FarmaParams::default()
        }
        .validate(old.len())
        .unwrap();
        let m = fit(old, &params).unwrap();
        assert_eq!(m.1.path, FitPath::Fast);
        let fast = state_from_fit("x", old, &m.0, &m.1);
        let slow = state_from_fit_direct("x", old, &m.0, &m.1);
        let what = format!("p {p} q {q} d {d} h {}", m.0.bandwidth);
        assert_eq!(fast.n_support, slow.n_support, "{what}");
        let close = |a: &[f64], b: &[f64], per: usize, name: &str| {
            for (k, (ca, cb)) in a.chunks(per).zip(b.chunks(per)).enumerate() {
                let scale = scale_of(cb).max(f64::MIN_POSITIVE);
                for (u, v) in ca.iter().zip(cb) {
                    assert!(
                        (u - v).abs() <= 1e-11 * scale,
                        "{what}: {name} at grid point {k}: {u} against {v}"
                    );
                }
            }
        };
        let n = 2 * p;
        close(&fast.gram, &slow.gram, n * n, "gram");
        close(&fast.gram2, &slow.gram2, n * n, "gram2");
        close(&fast.cross, &slow.cross, n * (1 + q), "cross");
        for (u, v) in fast.kernel_mass.iter().zip(&slow.kernel_mass) {
            assert!(
                (u - v).abs() <= 1e-12 * v.abs().max(1e-300),
                "{what}: mass {u} {v}"
            );
        }
        let (uf, us) = (
            update(&fast, new, 1.0).unwrap(),
            update(&slow, new, 1.0).unwrap(),
        );
        for (u, v) in uf.2.local.f.iter().zip(&us.2.local.f) {
            assert!(
                (u - v).abs() <= 1e-9 * (1.0 + v.abs()),
                "{what}: updated f {u} {v}"
            );
        }
        assert!((uf.0.sigma2 - us.0.sigma2).abs() <= 1e-10 * us.0.sigma2);
    }
}
