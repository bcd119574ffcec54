//! The 2-D index (x_{t-d}, z_{t-d2}): the KD-tree path equals brute-force weighted
//! least squares over all rows, the trace of the smoother equals the sum of the hat
//! matrix's diagonal computed column by column, and a FARMA(1,0,1) whose f_1 depends
//! on temperature is recovered by the 2-D fit and not by the 1-D fit.

use farma::estimator::kernel::biweight;
use farma::estimator::linalg::spd_solve_inverse;
use farma::estimator::multivariate::{
    Farma2Params, Grid2, Index2, Vc2Problem, fit_grid2, fit2, rss_trace2,
};
use farma::estimator::{FarmaParams, PointStatus, fit};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A series with a temperature-like channel: z a slow sinusoid plus a random walk.
fn data(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut x = vec![0.0f64; n];
    let mut e = vec![0.0; n];
    let mut z = vec![0.0; n];
    let mut walk = 0.0;
    for t in 0..n {
        let g: f64 = StandardNormal.sample(&mut rng);
        walk += 0.05 * g;
        z[t] = 25.0 + 2.0 * (t as f64 / 300.0).sin() + walk;
        e[t] = StandardNormal.sample(&mut rng);
        let mut s = e[t];
        if t >= 2 {
            let f1 = 0.4 + 0.2 * (z[t - 1] - 25.0).tanh() + 0.1 * (-x[t - 1] * x[t - 1]).exp();
            s += f1 * x[t - 1] - 0.2 * x[t - 2] + 0.3 * e[t - 1];
        }
        x[t] = s;
    }
    (x, z, e)
}

/// Brute force at point c: sum over every row (no tree), response y(t).
fn brute(
    prob: &Vc2Problem,
    c: (f64, f64),
    h: (f64, f64),
    y: &dyn Fn(usize) -> f64,
) -> Option<(Vec<f64>, u64)> {
    let p = prob.p;
    let n = 3 * p;
    let mut s = vec![0.0; n * n];
    let mut r = vec![0.0; n];
    let mut count = 0;
    for t in prob.start..prob.x.len() {
        let (u1, u2) = prob.u(t);
        if !(c.0 - h.0 <= u1 && u1 < c.0 + h.0 && c.1 - h.1 <= u2 && u2 < c.1 + h.1) {
            continue;
        }
        count += 1;
        let (w1, w2) = ((u1 - c.0) / h.0, (u2 - c.1) / h.1);
        let k = biweight(w1) * biweight(w2);
        let mut zz = vec![0.0; n];
        for m in 0..p {
            zz[m] = prob.xr(t, m);
            zz[p + m] = w1 * zz[m];
            zz[2 * p + m] = w2 * zz[m];
        }
        for i in 0..n {
            for j in 0..n {
                s[i * n + j] += k * zz[i] * zz[j];
            }
            r[i] += k * zz[i] * y(t);
        }
    }
    if (count as usize) < n {
        return None;
    }
    spd_solve_inverse(&s, &r, n).map(|(sol, _, _)| (sol, count))
}

#[test]
fn kd_tree_path_equals_brute_force_at_every_grid_point() {
    let (x, z, e) = data(3000, 3);
    let b = [0.3];
    let prob = Vc2Problem {
        x: &x,
        z: &z,
        e: &e,
        b: &b,
        p: 2,
        d: 1,
        d2: 2,
        start: 2,
    };
    let grid = Grid2 {
        g1: vec![-2.0, -1.0, 0.0, 0.7, 1.5, 3.0],
        g2: vec![23.0, 24.5, 25.0, 26.2, 27.5],
    };
    let index = Index2::build(&prob, (4.0, 3.0));
    let (mut worst, mut ok, mut not_ok) = (0.0f64, 0, 0);
    // a square box in scaled units, a flat one, a tall one
    for h in [(0.8, 0.6), (2.5, 0.3), (0.4, 2.0)] {
        let fit = fit_grid2(&prob, &index, &grid, h);
        for g in 0..grid.len() {
            let c = grid.point(g);
            let want = brute(&prob, c, h, &|t| prob.y(t));
            match (want, fit.status[g]) {
                (Some((sol, count)), PointStatus::Ok) => {
                    assert_eq!(count, fit.n_support[g]);
                    for m in 0..2 {
                        let scale = sol[m].abs().max(1.0);
                        worst = worst.max((fit.f[g * 2 + m] - sol[m]).abs() / scale);
                        worst = worst.max((fit.slope1[g * 2 + m] * h.0 - sol[2 + m]).abs() / scale);
                        worst = worst.max((fit.slope2[g * 2 + m] * h.1 - sol[4 + m]).abs() / scale);
                    }
                    ok += 1;
                }
                (None, s) => {
                    assert_ne!(s, PointStatus::Ok, "point {g} at {h:?}");
                    not_ok += 1;
                }
                (Some(_), s) => {
                    panic!("point {g} at {h:?}: brute force solves, tree path says {s:?}")
                }
            }
        }
    }
    eprintln!("worst {worst:.3e}, {ok} points ok, {not_ok} without a fit");
    assert!(ok > 40 && not_ok > 0);
    assert!(worst < 1e-10, "{worst:e}");
}

#[test]
fn trace_equals_the_hat_matrix_diagonal_and_rss_a_direct_sum() {
    let (x, z, e) = data(400, 9);
    let b = [0.3];
    let prob = Vc2Problem {
        x: &x,
        z: &z,
        e: &e,
        b: &b,
        p: 1,
        d: 1,
        d2: 1,
        start: 1,
    };
    let grid = Grid2 {
        g1: vec![-1.5, 0.0, 1.5],
        g2: vec![24.0, 25.0, 26.0],
    };
    let h = (2.5, 1.5);
    let fit = fit_grid2(&prob, &Index2::build(&prob, (3.0, 2.0)), &grid, h);
    assert!(fit.all_ok());
    let (rss, tr) = rss_trace2(&prob, &grid, &fit);
    // column t of the hat matrix: the fit of the unit response at t, evaluated at t
    let yhat_at = |t: usize, y: &dyn Fn(usize) -> f64| {
        let (u1, u2) = prob.u(t);
        let mut v = 0.0;
        for (g, w) in grid.corners(u1, u2) {
            if w != 0.0 {
                let (sol, _) = brute(&prob, grid.point(g), h, y).unwrap();
                v += w * sol[0];
            }
        }
        v * prob.xr(t, 0)
    };
    let mut want_tr = 0.0;
    let mut want_rss = 0.0;
    for t in 1..400 {
        want_tr += yhat_at(t, &|s| if s == t { 1.0 } else { 0.0 });
        let r = prob.y(t) - yhat_at(t, &|s| prob.y(s));
        want_rss += r * r;
    }
    eprintln!("trace {tr} vs {want_tr}, rss {rss} vs {want_rss}");
    assert!((tr - want_tr).abs() < 1e-10 * want_tr);
    assert!((rss - want_rss).abs() < 1e-10 * want_rss);
    assert!(tr > 3.0); // more than a global linear fit's one parameter
}

/// FARMA(1,0,1) with f_1(u, T) = 0.5 + 0.3 tanh(T - 25), T a slow sinusoid.
fn temperature_model(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut x = vec![0.0; n];
    let temp: Vec<f64> = (0..n)
        .map(|t| 25.0 + 2.0 * (2.0 * std::f64::consts::PI * t as f64 / 4000.0).sin())
        .collect();
    for t in 0..n {
        let e: f64 = StandardNormal.sample(&mut rng);
        x[t] = e + if t >= 1 {
            (0.5 + 0.3 * (temp[t - 1] - 25.0).tanh()) * x[t - 1]
        } else {
            0.0
        };
    }
    (x, temp)
}

#[test]
fn two_d_fit_recovers_a_temperature_dependent_coefficient_and_1d_cannot() {
    let (x, temp) = temperature_model(16_000, 21);
    let base = FarmaParams {
        p: 1,
        q: 0,
        d: 1,
        ..FarmaParams::default()
    };
    let m2 = fit2(
        &x,
        &temp,
        &Farma2Params {
            base: base.clone(),
            index2: "temp".into(),
            d2: 1,
            grid: (9, 9),
            bandwidth: None,
        },
    )
    .unwrap();
    let m1 = fit(
        &x,
        &FarmaParams {
            grid_size: 41,
            ..base
        }
        .validate(x.len())
        .unwrap(),
    )
    .unwrap();
    // error over the central part of the grid (rows 2..=6 of both coordinates)
    let (mut err2, mut err1) = (0.0f64, 0.0f64);
    let mut f1 = [0.0];
    for i in 2..=6 {
        for j in 2..=6 {
            let g = i * 9 + j;
            let (u, tt) = (m2.0.coef.centred_grid(g), m2.0.coef.second_grid(g).unwrap());
            let truth = 0.5 + 0.3 * (tt - 25.0).tanh();
            err2 = err2.max((m2.0.coef.f[g] - truth).abs());
            m1.1.local.eval(&m1.0.coef.grid, u, &mut f1);
            err1 = err1.max((f1[0] - truth).abs());
        }
    }
    eprintln!(
        "2-D: h = {:?}, max error {err2:.3}, sigma2 {:.4}; 1-D: h = {:.3}, max error {err1:.3}, sigma2 {:.4}; notes {:?}",
        m2.0.bandwidths(),
        m2.0.sigma2,
        m1.0.bandwidth,
        m1.0.sigma2,
        m2.1.notes
    );
    assert!(err2 < 0.1, "2-D fit misses f_1(u, T) by {err2}");
    assert!(err1 > 0.2, "the 1-D fit cannot see temperature ({err1})");
    assert!(m2.0.sigma2 < m1.0.sigma2 * 0.97);
    // the slope in temperature is positive at T = 25 (0.3 tanh' = 0.3)
    let centre = 4 * 9 + 4;
    assert!(
        (m2.1.local.slope2[centre] - 0.3).abs() < 0.15,
        "{}",
        m2.1.local.slope2[centre]
    );
}

/// A linear AR(1) with an unrelated second index: GCV keeps choosing the widest
/// bandwidths, the ladder is extended upwards to its limit, and the fit says that the
/// optimum may lie beyond (as the 1-D fit does); gcv.parquet's `j` is the rung the
/// notes name, not the row number (as in 1-D).
#[test]
fn a_2d_ladder_ending_at_its_widest_extension_says_so_and_names_its_rungs() {
    let n = 3000;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (mut x, mut z) = (vec![0.0f64; n], vec![0.0f64; n]);
    for t in 1..n {
        let g: f64 = StandardNormal.sample(&mut rng);
        let w: f64 = StandardNormal.sample(&mut rng);
        x[t] = 0.5 * x[t - 1] + g;
        z[t] = z[t - 1] + 0.1 * w;
    }
    let m = fit2(
        &x,
        &z,
        &Farma2Params {
            base: FarmaParams {
                p: 1,
                q: 0,
                d: 1,
                ..FarmaParams::default()
            },
            index2: "z".into(),
            d2: 1,
            grid: (7, 7),
            bandwidth: None,
        },
    )
    .unwrap();
    let rows = &m.1.gcv_table;
    let best = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.gcv.is_finite())
        .min_by(|a, b| a.1.gcv.total_cmp(&b.1.gcv))
        .map(|(i, _)| i)
        .unwrap();
    eprintln!(
        "best j {} of {:?}; notes {:?}",
        rows[best].j,
        rows.iter().map(|r| r.j).collect::<Vec<_>>(),
        m.1.notes
    );
    assert_eq!(best, 0, "the widest rung is chosen");
    assert!(rows[0].j < 0, "the ladder was extended upwards");
    assert!(
        m.1.notes
            .iter()
            .any(|s| s.contains("the end of the ladder's extensions")),
        "{:?}",
        m.1.notes
    );
    let table = farma::model::folder::tables::gcv_table(&[(
        "x".to_string(),
        &m.0,
        farma::model::Report::Fit2(&m.1),
    )])
    .unwrap();
    let j = table
        .column_by_name("j")
        .unwrap()
        .as_any()
        .downcast_ref::<arrow_array::Int64Array>()
        .unwrap();
    let want: Vec<i64> = rows.iter().map(|r| r.j as i64).collect();
    assert_eq!(j.values().to_vec(), want);
}

/// A fit whose RSS settles, after which GCV picks other bandwidths and the
/// alternation goes on: its notes say what happened, and only a converged fit's notes
/// say it converged: a fit that then runs into --max-iter without settling again does
/// not say "bandwidths re-selected after convergence". (The data: a 3-level
/// temperature, on which GCV swings between two pairs.)
#[test]
fn a_2d_bandwidth_reselection_is_described_truthfully_converged_or_not() {
    let n = 1500;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (mut x, mut e) = (vec![0.0f64; n], vec![0.0f64; n]);
    for t in 0..n {
        e[t] = StandardNormal.sample(&mut rng);
        if t >= 2 {
            x[t] = 0.5 * (-x[t - 1] * x[t - 1]).exp() * x[t - 1] - 0.2 * x[t - 2]
                + e[t]
                + 0.3 * e[t - 1];
        }
    }
    let z = data(n, 1).1;
    let run = |max_iter: usize| {
        fit2(
            &x,
            &z,
            &Farma2Params {
                base: FarmaParams {
                    p: 1,
                    q: 1,
                    d: 1,
                    max_iter,
                    ..FarmaParams::default()
                },
                index2: "z".into(),
                d2: 1,
                grid: (9, 9),
                bandwidth: None,
            },
        )
        .unwrap()
    };
    // with room to settle again: converged, the re-selection named with its alternation
    let full = run(50);
    eprintln!("{} alternations: {:?}", full.1.iterations, full.1.notes);
    assert!(full.1.converged);
    let settled_at = full
        .1
        .notes
        .iter()
        .find_map(|s| {
            s.strip_prefix("alternation ")?
                .split(':')
                .next()?
                .parse::<usize>()
                .ok()
                .filter(|_| s.contains("GCV at those residuals chose"))
        })
        .expect("a bandwidth re-selection in this fit");
    assert!(settled_at + 1 < full.1.iterations);
    assert!(!full.1.notes.iter().any(|s| s.contains("NOT converged")));
    // --max-iter ends it after the re-selection, before it settles again
    let cut = run(settled_at + 2);
    eprintln!("{:?}", cut.1.notes);
    assert!(!cut.1.converged);
    assert!(
        !cut.1.notes.iter().any(|s| s.contains("after convergence")),
        "{:?}",
        cut.1.notes
    );
    assert!(
        cut.1.notes.iter().any(|s| s.starts_with(
            "NOT converged: after 1 bandwidth re-selection(s) the alternation did not settle again within --max-iter"
        )),
        "{:?}",
        cut.1.notes
    );
    // --max-iter ends it at the alternation that settled: the model stays at the
    // bandwidths it settled at, and says so
    let at = run(settled_at);
    assert!(!at.1.converged);
    assert!(
        at.1.notes
            .iter()
            .any(|s| s.contains("ends the alternation here: NOT converged")),
        "{:?}",
        at.1.notes
    );
    assert_ne!(at.0.bandwidths(), cut.0.bandwidths());
    let chosen =
        at.1.gcv_table
            .iter()
            .filter(|r| (r.bandwidth, r.bandwidth2) == at.0.bandwidths())
            .count();
    assert_eq!(chosen, 1, "gcv.parquet's chosen row is the model's pair");
}

/// A spike in the temperature channel stretches the second coordinate's bandwidth
/// ladder (it starts at half the span): the fit says so and names the outlier's reach;
/// the same data without the spike gets no such note (on the multiaxis fixture with a
/// 1000-degree spike in temp_c, GCV ends at h_2 = 250 degrees, the central values
/// spanning 5: a fit that must not pass without a word).
#[test]
fn a_spike_in_the_index_channel_is_named_as_stretching_its_ladder() {
    let (x, mut temp) = temperature_model(4_000, 5);
    let params = Farma2Params {
        base: FarmaParams {
            p: 1,
            q: 0,
            d: 1,
            ..FarmaParams::default()
        },
        index2: "temp".into(),
        d2: 1,
        grid: (7, 7),
        bandwidth: None,
    };
    let clean = fit2(&x, &temp, &params).unwrap();
    assert!(
        !clean.1.notes.iter().any(|n| n.contains("outlier")),
        "{:?}",
        clean.1.notes
    );
    temp[2000] = 1000.0;
    let m = fit2(&x, &temp, &params).unwrap();
    let note =
        m.1.notes
            .iter()
            .find(|n| n.contains("the index channel's values"))
            .unwrap_or_else(|| panic!("no note: {:?}", m.1.notes));
    assert!(
        note.contains("to 1.000000e3") && note.contains("stretches the bandwidth ladder"),
        "{note}"
    );
    assert!(
        !m.1.notes.iter().any(|n| n.contains("x_(t-1)")),
        "{:?}",
        m.1.notes
    );
}
