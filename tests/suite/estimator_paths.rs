//! The fast exact path (moment tables) equals the direct path (KD-tree + WLS), and the
//! direct path equals a brute-force sum over all rows, on random and adversarial data.

use farma::estimator::direct::{DirectIndex, fit_grid, rss_trace};
use farma::estimator::kernel::biweight;
use farma::estimator::moments::{MomentTable, breakpoints};
use farma::estimator::{GridFit, PointStatus, VcProblem};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

fn farma211(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut x = vec![0.0; n];
    let mut e = vec![0.0; n];
    for t in 0..n {
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
    (x, e)
}

fn ladder(x: &[f64], j: usize) -> Vec<f64> {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    (0..j)
        .map(|k| 1.1f64.powi(-(k as i32)) * (hi - lo) / 2.0)
        .collect()
}

fn uniform_grid(lo: f64, hi: f64, g: usize) -> Vec<f64> {
    (0..g)
        .map(|k| lo + (hi - lo) * k as f64 / (g - 1) as f64)
        .collect()
}

/// Brute force: every row, no tree.
fn brute_point(prob: &VcProblem, ug: f64, h: f64) -> (Vec<f64>, Vec<f64>, u64) {
    let p = prob.p;
    let n = 2 * p;
    let mut s = vec![0.0; n * n];
    let mut r = vec![0.0; n];
    let mut c = 0;
    for t in prob.start..prob.x.len() {
        let u = prob.u(t);
        if !(ug - h <= u && u < ug + h) {
            continue;
        }
        let w = (u - ug) / h;
        c += 1;
        let k = biweight(w);
        let mut z = vec![0.0; n];
        for m in 0..p {
            z[m] = prob.xr(t, m);
            z[p + m] = w * prob.xr(t, m);
        }
        for i in 0..n {
            for j in 0..n {
                s[i * n + j] += k * z[i] * z[j];
            }
            r[i] += k * z[i] * prob.y(t);
        }
    }
    (s, r, c)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
}

/// Largest relative difference, each point's divided by its allowance: 1e-9 for a
/// local system of condition number up to 1e6; beyond, the backward-error bound
/// cond x 1e-15 (entries of S agree to ~1e-15 relative; the solve amplifies by cond).
/// f is compared on the scale of the point's coefficient vector, max_m |f_m| (the
/// solve's error bound is norm-wise, Higham 2002, sec. 7.1): a component near zero
/// beside a large one has no relative accuracy in either path. (On the adversarial
/// data, f = (-0.0012327, 0.8632) at h = 2: the paths differ by 1.7e-12 in the small
/// component, 1.3e-9 of it, 1.9e-12 of the vector.) Slopes, likewise, on the scale of f.
fn compare(fast: &GridFit, direct: &GridFit, what: &str) -> f64 {
    let mut worst = 0.0f64;
    // Statuses agree, except for systems of condition above 1e10: their entries
    // agree to ~1e-13 relative in the two paths (edge samples with K = 0 cancel in the
    // moment sums only to rounding), which moves the condition by more than the
    // singularity threshold (1e14) allows, so they may fall on either side of it.
    for g in 0..fast.n_grid() {
        let near = |f: &GridFit| f.status[g] == PointStatus::Ok && f.cond[g] > 1e10;
        let flip = (fast.status[g] == PointStatus::Singular && near(direct))
            || (direct.status[g] == PointStatus::Singular && near(fast));
        assert!(
            fast.status[g] == direct.status[g] || flip,
            "{what}: grid point {g}: {:?} vs {:?}",
            fast.status[g],
            direct.status[g]
        );
    }
    assert_eq!(
        fast.n_support, direct.n_support,
        "{what}: support counts differ"
    );
    for g in 0..fast.n_grid() {
        if fast.status[g] != PointStatus::Ok || direct.status[g] != PointStatus::Ok {
            assert!(fast.status[g] == PointStatus::Ok || fast.f[g * fast.p].is_nan());
            continue;
        }
        let allow = (direct.cond[g] * 1e-15).max(1e-9) / 1e-9;
        let point = g * fast.p..(g + 1) * fast.p;
        let f_scale = fast.f[point.clone()]
            .iter()
            .chain(&direct.f[point])
            .fold(1e-300f64, |a, v| a.max(v.abs()));
        for m in 0..fast.p {
            let i = g * fast.p + m;
            worst = worst.max((fast.f[i] - direct.f[i]).abs() / f_scale / allow);
            // slopes are compared on the scale of f: a slope near zero has no relative accuracy
            let scale = fast.f[i]
                .abs()
                .max(direct.slope[i].abs() * fast.bandwidth)
                .max(1e-300);
            worst =
                worst.max((fast.slope[i] - direct.slope[i]).abs() * fast.bandwidth / scale / allow);
        }
        worst = worst.max(rel(fast.kernel_mass[g], direct.kernel_mass[g]));
    }
    worst
}

#[allow(clippy::too_many_arguments)]
fn check_paths(
    x: &[f64],
    e: &[f64],
    b: &[f64],
    p: usize,
    d: usize,
    grid: &[f64],
    hs: &[f64],
    label: &str,
) -> usize {
    let prob = VcProblem::new(x, e, b, p, d);
    let (umin, umax) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let table = MomentTable::build(&prob, breakpoints(grid, hs), umin, umax, 6);
    let fast = table.fit_ladder(grid, hs);
    let index = DirectIndex::build(&prob);
    let mut n_non_ok = 0;
    for (j, &h) in hs.iter().enumerate() {
        let direct = fit_grid(&prob, &index, grid, h);
        let worst = compare(&fast[j], &direct, &format!("{label} h_{j}"));
        assert!(
            worst <= 1e-9,
            "{label} h_{j}: fast vs direct rel diff {worst:e}"
        );
        n_non_ok += direct
            .status
            .iter()
            .filter(|s| **s != PointStatus::Ok)
            .count();
        // direct vs brute force at a few grid points
        for g in (0..grid.len()).step_by(7) {
            let (s, r, c) = brute_point(&prob, grid[g], h);
            let mut one = GridFit::new(1, p, h);
            one.set_point(0, &s, &r, c, 0.0);
            if one.status[0] == PointStatus::Ok && direct.status[g] == PointStatus::Ok {
                for m in 0..p {
                    assert!(
                        rel(one.f[m], direct.f[g * p + m]) <= 1e-10,
                        "{label}: brute vs direct"
                    );
                }
            }
        }
        // standard-error factors, both paths (on the fast path's fit, so only the S2 sums differ)
        let se_table = MomentTable::build(&prob, breakpoints(grid, &[h]), umin, umax, 10);
        let se_fast = se_table.se_factors(grid, &fast[j]);
        let se_direct = farma::estimator::direct::se_factors(&prob, &index, grid, &fast[j]);
        for g in 0..grid.len() {
            if fast[j].status[g] == PointStatus::Ok {
                for m in 0..p {
                    let (a, b) = (se_fast[g * p + m], se_direct[g * p + m]);
                    let allow = (fast[j].cond[g].powi(2) * 1e-15).max(1e-9);
                    assert!(
                        rel(a, b) <= allow,
                        "{label} h_{j} g {g}: se factor {a} vs {b}"
                    );
                }
            }
        }
        if direct.all_ok() {
            let (r1, t1) = table.rss_trace(grid, &fast[j]);
            let (r2, t2) = rss_trace(&prob, grid, &direct);
            assert!(rel(r1, r2) <= 1e-9, "{label} h_{j}: rss {r1} vs {r2}");
            assert!(rel(t1, t2) <= 1e-9, "{label} h_{j}: trace {t1} vs {t2}");
        }
    }
    n_non_ok
}

#[test]
fn fast_equals_direct_on_farma_data_with_ma_part() {
    let (x, e) = farma211(6000, 3);
    let grid = uniform_grid(-2.0, 2.0, 41);
    let hs = ladder(&x, 21);
    check_paths(&x, &e, &[-0.5], 2, 1, &grid, &hs, "farma211");
    // p = 3, d = 2, q = 2
    check_paths(&x, &e, &[0.3, -0.2], 3, 2, &grid, &hs, "p3q2d2");
}

#[test]
fn fast_equals_direct_with_empty_sparse_and_singular_supports() {
    // Index values in two clusters with an empty stretch between them, a lone
    // outlier, and quantized values (many ties): empty supports, supports with fewer
    // samples than unknowns, and singular local designs (all U equal in a window).
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let n = 4000;
    let mut x = Vec::with_capacity(n);
    for t in 0..n {
        let z: f64 = StandardNormal.sample(&mut rng);
        let v = if t % 2 == 0 {
            -3.0 + 0.2 * z
        } else {
            3.0 + (0.2 * z / 0.05).round() * 0.05
        };
        x.push(v);
    }
    x[1000] = 0.0; // lone point in the gap
    let e = vec![0.0; n];
    let grid = uniform_grid(-4.0, 4.0, 81);
    let hs = vec![2.0, 0.5, 0.1, 0.02, 0.004];
    let n_bad = check_paths(&x, &e, &[], 2, 2, &grid, &hs, "adversarial");
    assert!(
        n_bad > 50,
        "the adversarial data should produce non-Ok points, got {n_bad}"
    );
}

#[test]
fn well_conditioned_farma_points_agree_to_1e9_without_allowance() {
    let (x, e) = farma211(6000, 5);
    let prob = VcProblem::new(&x, &e, &[-0.5], 2, 1);
    let grid = uniform_grid(-2.0, 2.0, 41);
    let hs = ladder(&x, 21);
    let table = MomentTable::build(&prob, breakpoints(&grid, &hs), -100.0, 100.0, 6);
    let fast = table.fit_ladder(&grid, &hs);
    let index = DirectIndex::build(&prob);
    let mut checked = 0;
    for (j, &h) in hs.iter().enumerate() {
        let direct = fit_grid(&prob, &index, &grid, h);
        for g in 0..grid.len() {
            if direct.status[g] == PointStatus::Ok && direct.cond[g] <= 1e6 {
                for m in 0..2 {
                    assert!(rel(fast[j].f[g * 2 + m], direct.f[g * 2 + m]) <= 1e-9);
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 800, "{checked}");
}

#[test]
fn reused_left_hand_sides_give_the_one_bandwidth_fit() {
    // The f-step's path: S_g from a full table, the right-hand sides from a table of
    // the X_a y families only. It must equal a full one-bandwidth fit bit for bit, and
    // the direct path to the usual allowance.
    use farma::estimator::moments::Families;
    let (x, e) = farma211(6000, 7);
    let b = [-0.5];
    let prob = VcProblem::new(&x, &e, &b, 2, 1);
    let grid = uniform_grid(-2.0, 2.0, 41);
    let index = DirectIndex::build(&prob);
    for h in [0.05, 0.3, 1.5] {
        let breaks = breakpoints(&grid, &[h]);
        let full = MomentTable::build(&prob, breaks.clone(), -100.0, 100.0, 6);
        let sys = full.local_systems(&grid, h);
        let resp = MomentTable::build_families(&prob, breaks, -100.0, 100.0, 6, Families::Response);
        let reused = resp.fit_response(&sys);
        let one = full.fit_ladder(&grid, &[h]).remove(0);
        assert_eq!(reused.status, one.status, "h {h}");
        assert_eq!(reused.n_support, one.n_support, "h {h}");
        for (a, c) in reused.f.iter().zip(&one.f) {
            assert!(
                a.to_bits() == c.to_bits() || (a.is_nan() && c.is_nan()),
                "h {h}: {a} vs {c}"
            );
        }
        let direct = fit_grid(&prob, &index, &grid, h);
        let worst = compare(&reused, &direct, &format!("reused h {h}"));
        assert!(worst <= 1e-9, "h {h}: {worst:e}");
    }
}

#[test]
fn a_bandwidth_below_the_grid_values_resolution_gives_empty_windows() {
    // u_g + h rounds to u_g for h = 1e-16 at u_g = 1 (and u_g - h does not): the
    // windows hold only the samples in [fl(u_g - h), fl(u_g + h)), never a whole cell.
    let n = 3000;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut x: Vec<f64> = (0..n)
        .map(|_| {
            let z: f64 = StandardNormal.sample(&mut rng);
            z
        })
        .collect();
    x[100] = 1.0 - 1e-16; // = 0.9999999999999999, inside [fl(1 - 1e-16), 1)
    let e = vec![0.0; n];
    let prob = VcProblem::new(&x, &e, &[], 2, 1);
    let grid = vec![0.5, 1.0, 1.5];
    let hs = vec![1e-16, 0.4];
    let table = MomentTable::build(&prob, breakpoints(&grid, &hs), -10.0, 10.0, 6);
    let fits = table.fit_ladder(&grid, &hs);
    for (j, &h) in hs.iter().enumerate() {
        for (g, &ug) in grid.iter().enumerate() {
            let (lo, hi) = (ug - h, ug + h);
            let brute = (2..n).filter(|&t| x[t - 1] >= lo && x[t - 1] < hi).count() as u64;
            assert_eq!(fits[j].n_support[g], brute, "h {h} u {ug}");
        }
    }
    assert_eq!(fits[0].n_support[1], 1);
}
