//! Unit tests of the fit's steps against slow, obviously-correct twins.

use super::bstep::{gn_b_step, ma_cls, ma_step, predicted_decrease};
use super::grid::{quantiles, total_order_key};
use super::notes::{missing_se_note, reselection_limit_note};
use super::params::FarmaParams;
use super::passes::{
    FILTER_CHUNK, SpanFill, ma_filter_rss, residuals, residuals_indexed, rss_from, w_indexed_filler,
};
use super::start::{arma_residuals_rss, linear_start, linear_start_into, same_bits};
use super::{fit, went_back};
use crate::estimator::arma::arma_pass;
use crate::estimator::linalg::normal_equations;
use crate::estimator::moments::IntervalIndex;
use crate::estimator::moments::breakpoints;
use crate::estimator::problem::GridFit;
use crate::estimator::problem::PointStatus;
use crate::estimator::problem::VcProblem;
use crate::estimator::series::Centred;

fn uniform(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect()
}

#[test]
fn indexed_residuals_equal_the_searched_ones() {
    let x = uniform(200_000, 5);
    let grid: Vec<f64> = (0..31).map(|k| -0.4 + 0.025 * k as f64).collect();
    // every specialised w pass (p <= 4) and the general one
    for p in [1, 2, 3, 4, 5] {
        let mut coef = GridFit::new(grid.len(), p, 0.1);
        for (i, f) in coef.f.iter_mut().enumerate() {
            *f = 0.3 * ((i * 7 % 13) as f64 / 13.0 - 0.5);
        }
        for d in [1, 2] {
            let prob = VcProblem::new(&x, &[], &[], p, d);
            let ix = IntervalIndex::build(&prob, breakpoints(&grid, &[0.07])).unwrap();
            let (mut e1, mut e2) = (vec![0.0; x.len()], vec![0.0; x.len()]);
            residuals(&x, d, &grid, &coef, &[-0.4], &mut e1);
            residuals_indexed(&x, d, &grid, &coef, &[-0.4], &mut e2, &ix);
            assert_eq!(e1, e2, "p = {p}, d = {d}");
        }
    }
}

#[test]
fn one_gauss_newton_step_near_the_optimum_is_the_converged_b() {
    // w from an MA(1) with b = -0.6: from a start near the optimum one step (and
    // the filter) gives ma_cls's b and the residuals and RSS at it
    let z = uniform(100_000, 9);
    let w: Vec<f64> = (0..z.len())
        .map(|t| z[t] - 0.6 * if t > 0 { z[t - 1] } else { 0.0 })
        .collect();
    let b_opt = ma_cls(&w, 1, &[0.0]);
    assert!((b_opt[0] + 0.6).abs() < 0.02, "{b_opt:?}");
    // Gauss-Newton on a problem with residuals converges linearly: one step cuts
    // the start's error about 200-fold here (3e-3 off leaves 1.0e-5, 1e-4 off
    // 6e-7); an alternation moves b by ~1e-5, and each one takes a step
    for (off, tol) in [(3e-3, 3e-5), (1e-4, 1e-6)] {
        let mut buf = w.clone();
        let (b, _) = ma_step(&mut buf, 1, &[b_opt[0] + off], |_| {
            panic!("no refill near the optimum")
        });
        assert!((b[0] - b_opt[0]).abs() < tol, "{b:?} vs {b_opt:?}");
    }
    let mut buf = w.clone();
    let (b, rss) = ma_step(&mut buf, 1, &[b_opt[0] + 1e-4], |_| {
        panic!("no refill near the optimum")
    });
    let mut e = w.clone();
    let rss_e = ma_filter_rss(&mut e, &b, 1, |_| unreachable!("q = 1, N below two chunks"));
    assert_eq!(buf, e);
    assert_eq!(rss.to_bits(), rss_e.to_bits());
    assert_eq!(rss.to_bits(), rss_from(&e, 1).to_bits());
    // far from it: one step still lowers the RSS, and the returned RSS is the one
    // at the returned b; had the step raised it, ma_step would refill w and run
    // ma_cls (no start tried here, for MA(1) or MA(2), made the step raise it)
    for b_far in [0.95, 0.9, 0.7, 0.5] {
        let mut buf = w.clone();
        let (b, rss) = ma_step(&mut buf, 1, &[b_far], |v: &mut [f64]| v.copy_from_slice(&w));
        let (r_far, _, _) = arma_pass(&w, 1, &[], &[b_far]);
        let (r_new, _, _) = arma_pass(&w, 1, &[], &b);
        assert!(r_new < r_far, "{b:?}");
        assert_eq!(rss.to_bits(), r_new.to_bits());
    }
}

/// The serial MA recursion, the general loop (the chunked filter's slow twin).
fn serial_filter(w: &[f64], b: &[f64]) -> Vec<f64> {
    let mut e = w.to_vec();
    for t in 0..e.len() {
        let mut s = e[t];
        for (m, bm) in b.iter().enumerate() {
            if t > m {
                s -= bm * e[t - m - 1];
            }
        }
        e[t] = s;
    }
    e
}

#[test]
fn chunked_ma_filter_is_the_serial_recursion_bit_for_bit() {
    // three chunks and a short fourth: every e_t the serial recursion's, the RSS
    // rss_from's (its chunked order) and within rounding of a plain sum, for 1 and
    // 2 threads; b near the edge of invertibility (0.9999^4096 = 0.66: the chunk
    // states cannot agree) refills w and runs serially, with the same results
    // (and a last chunk of 100 rows, fewer than the lead: exact from its re-run,
    // no refill even for b = 0.99, whose zero start needs thousands of rows)
    for (n, b) in [
        (3 * FILTER_CHUNK + 12_345, vec![-0.6]),
        (3 * FILTER_CHUNK + 12_345, vec![0.5, -0.3]),
        (3 * FILTER_CHUNK + 12_345, vec![0.9999]),
        (3 * FILTER_CHUNK + 12_345, vec![-1.2, 0.36]),
        (2 * FILTER_CHUNK + 100, vec![0.99]),
    ] {
        let w = uniform(n, 21);
        let want = serial_filter(&w, &b);
        let plain: f64 = want[2..].iter().map(|v| v * v).sum();
        let near_edge = b == [0.9999];
        let mut outs = Vec::new();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut buf = w.clone();
            let mut refills = 0;
            let rss = pool.install(|| {
                ma_filter_rss(&mut buf, &b, 2, |v: &mut [f64]| {
                    refills += 1;
                    v.copy_from_slice(&w)
                })
            });
            assert_eq!(refills, usize::from(near_edge), "b = {b:?}");
            assert!(same_bits(&buf, &want), "b = {b:?}");
            assert_eq!(rss.to_bits(), rss_from(&want, 2).to_bits(), "b = {b:?}");
            assert!((rss - plain).abs() <= 1e-12 * plain, "{rss} vs {plain}");
            outs.push(rss.to_bits());
        }
        assert_eq!(outs[0], outs[1]);
    }
}

#[test]
fn the_one_pass_b_step_filters_as_the_serial_recursion_and_sums_as_arma_pass() {
    // e and the RSS the serial recursion's bit for bit (one chunk, several with a
    // short last one, a last chunk of lead rows only), the Gauss-Newton sums
    // arma_pass's to rounding (other grouping), w written by `fill` chunk by chunk
    // or already in the buffer, 1 and 2 threads; b near the edge of invertibility
    // refills w and runs serially, with the same results
    for (n, b) in [
        (5_000, vec![-0.6]),
        (3 * FILTER_CHUNK + 12_345, vec![-0.6]),
        (3 * FILTER_CHUNK + 12_345, vec![0.5, -0.3]),
        (3 * FILTER_CHUNK + 12_345, vec![0.9999]),
        (2 * FILTER_CHUNK + 100, vec![0.99]),
    ] {
        let w = uniform(n, 31);
        let want = serial_filter(&w, &b);
        let (rss_want, jtj_want, jte_want) = arma_pass(&w, 2, &[], &b);
        let near_edge = b == [0.9999];
        let fill = |t0: usize, rows: &mut [f64]| rows.copy_from_slice(&w[t0..t0 + rows.len()]);
        let mut outs = Vec::new();
        for threads in [1, 2] {
            for chunked_fill in [false, true] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut buf = if chunked_fill {
                    vec![f64::NAN; n]
                } else {
                    w.clone()
                };
                let mut refills = 0;
                let f: Option<&SpanFill<'_>> = if chunked_fill { Some(&fill) } else { None };
                let (rss, b1, dec) = pool
                    .install(|| {
                        gn_b_step(&mut buf, 2, &b, f, |v: &mut [f64]| {
                            refills += 1;
                            v.copy_from_slice(&w)
                        })
                    })
                    .unwrap();
                assert_eq!(refills, usize::from(near_edge), "b = {b:?}");
                assert!(same_bits(&buf, &want), "b = {b:?}");
                assert_eq!(rss.to_bits(), rss_from(&want, 2).to_bits(), "b = {b:?}");
                assert!((rss - rss_want).abs() <= 1e-12 * rss_want);
                // the step from arma_pass's normal equations
                let step = normal_equations(&jtj_want, &jte_want, b.len()).unwrap();
                for i in 0..b.len() {
                    let s = b1[i] - b[i];
                    assert!(
                        (s - step[i]).abs() <= 1e-9 * (1e-6 + step[i].abs()),
                        "{s} vs {}",
                        step[i]
                    );
                }
                let dec_want = predicted_decrease(&step, &jte_want);
                assert!((dec - dec_want).abs() <= 1e-6 * dec_want.abs() + 1e-9 * rss_want);
                outs.push((
                    rss.to_bits(),
                    b1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                ));
            }
        }
        assert!(outs.iter().all(|o| *o == outs[0]), "b = {b:?}");
    }
    // only q = 1 and 2
    let mut buf = uniform(100, 1);
    assert!(gn_b_step(&mut buf, 3, &[0.1, 0.1, 0.1], None, |_| {}).is_none());
}

#[test]
fn the_reselection_limit_note_names_a_swing_back() {
    let f = |h: f64| format!("{h}");
    let on = reselection_limit_note(5, &[0.5, 0.25, 0.125], f);
    assert!(on.contains("(0.5 -> 0.25 -> 0.125)") && on.contains("bandwidth 0.125,"));
    assert!(!on.contains("swung back"), "{on}");
    let back = reselection_limit_note(7, &[0.5, 0.25, 0.5], f);
    assert!(
        back.contains("alternation 7:") && back.contains("swung back"),
        "{back}"
    );
}

#[test]
fn a_fit_returns_the_residuals_and_rss_of_its_own_f_and_b() {
    // FARMA(2,1,1) long enough for the chunked one-pass b-step (more than two
    // filter chunks): whichever b-step made the returned iterate, its residuals are
    // the recursion's at the returned (f, b), bit for bit, and its RSS theirs
    let n = 2 * FILTER_CHUNK + 50_000;
    let z = uniform(n, 77);
    let mut x = vec![0.0; n];
    let (mut x1, mut x2, mut e1) = (0.0f64, 0.0f64, 0.0f64);
    for t in 0..n {
        let e = 3.4 * z[t];
        let f1 = 0.3 + 0.4 * (-x1 * x1).exp();
        let f2 = -0.2 + 0.1 * x1.tanh();
        x[t] = f1 * x1 + f2 * x2 + e - 0.5 * e1;
        (x2, x1, e1) = (x1, x[t], e);
    }
    let params = FarmaParams {
        grid_size: 41,
        ..FarmaParams::default()
    }
    .validate(n)
    .unwrap();
    let m = fit(&x, &params).unwrap();
    assert!(m.1.iterations >= 2, "{}", m.1.iterations);
    assert!((m.0.b[0] + 0.5).abs() < 0.05, "{:?}", m.0.b);
    let xc: Vec<f64> = x.iter().map(|v| v - m.0.mean).collect();
    let mut e = vec![0.0; n];
    residuals(&xc, 1, &m.0.coef.grid, &m.1.local, &m.0.b, &mut e);
    assert!(same_bits(&e, &m.1.residuals));
    assert_eq!(m.1.rss.to_bits(), rss_from(&e, 2).to_bits());
}

#[test]
fn w_written_span_by_span_is_the_indexed_residuals_w() {
    let x = uniform(300_000, 8);
    let grid: Vec<f64> = (0..31).map(|k| -0.4 + 0.025 * k as f64).collect();
    for p in [1, 2, 3, 4] {
        let mut coef = GridFit::new(grid.len(), p, 0.1);
        for (i, f) in coef.f.iter_mut().enumerate() {
            *f = 0.3 * ((i * 7 % 13) as f64 / 13.0 - 0.5);
        }
        for d in [1, 3] {
            let prob = VcProblem::new(&x, &[], &[], p, d);
            let ix = IntervalIndex::build(&prob, breakpoints(&grid, &[0.07])).unwrap();
            let mut want = vec![0.0; x.len()];
            residuals_indexed(&x, d, &grid, &coef, &[], &mut want, &ix);
            let fill = w_indexed_filler(Centred::plain(&x), d, &grid, &coef, &ix).unwrap();
            let mut got = vec![f64::NAN; x.len()];
            for (c, rows) in got.chunks_mut(70_001).enumerate() {
                fill(c * 70_001, rows);
            }
            assert!(same_bits(&got, &want), "p = {p}, d = {d}");
        }
    }
    let coef = GridFit::new(grid.len(), 5, 0.1);
    let prob = VcProblem::new(&x, &[], &[], 5, 1);
    let ix = IntervalIndex::build(&prob, breakpoints(&grid, &[0.07])).unwrap();
    assert!(w_indexed_filler(Centred::plain(&x), 1, &grid, &coef, &ix).is_none());
}

#[test]
fn the_starts_parallel_residuals_are_the_serial_recursions_bit_for_bit() {
    // one chunk (serial filter) and several chunks with a short last one
    for n in [5_000, 3 * FILTER_CHUNK + 123] {
        let w = uniform(n, 17);
        let orders: [(&[f64], &[f64]); 5] = [
            (&[0.36, -0.2], &[-0.48]),
            (&[0.5], &[0.3, -0.2]),
            (&[0.2, 0.1, -0.1], &[0.1, 0.05, 0.02]),
            (&[0.4, -0.1], &[]),
            (&[], &[0.6]),
        ];
        for (a, b) in orders {
            let start = a.len().max(b.len()).max(1);
            let mut want = vec![0.0; n];
            super::super::arma::arma_residuals(&w, a, b, &mut want);
            let rss_want = rss_from(&want, start);
            let (got, rss) = arma_residuals_rss(Centred::plain(&w), a, b, start);
            assert!(same_bits(&got, &want), "n = {n}, a = {a:?}, b = {b:?}");
            assert_eq!(
                rss.to_bits(),
                rss_want.to_bits(),
                "n = {n}, a = {a:?}, b = {b:?}"
            );
        }
    }
}

#[test]
fn radix_selected_quantiles_equal_those_of_a_full_sort_over_signs_and_scales() {
    // values of both signs over many binades, both zeros, ties, and a bucket of
    // the key's top bits holding most of the values
    let u = uniform(30_001, 9);
    let v: Vec<f64> = u
        .iter()
        .enumerate()
        .map(|(i, w)| match i % 7 {
            0 => 0.0,
            1 => -0.0,
            2 => (w - 0.5) * 1e-300,
            3 => (w - 0.5) * 1e12,
            4 => 1.0 + w * 1e-9,
            _ => w - 0.5,
        })
        .collect();
    let mut sorted = v.clone();
    sorted.sort_by(f64::total_cmp);
    let qs = [0.0, 1e-5, 0.01, 0.1, 0.2857, 0.5, 0.71, 0.9, 0.99, 1.0];
    let got = quantiles(|t| v[t], 0..v.len(), &qs);
    for (q, g) in qs.iter().zip(&got) {
        let pos = q * (sorted.len() - 1) as f64;
        let (i, frac) = (pos.floor() as usize, pos - pos.floor());
        let want = match sorted.get(i + 1) {
            Some(next) => sorted[i] + frac * (next - sorted[i]),
            None => sorted[i],
        };
        assert_eq!(g.to_bits(), want.to_bits(), "q = {q}");
    }
    let mut keys: Vec<u64> = v.iter().map(|x| total_order_key(*x)).collect();
    keys.sort_unstable();
    let by_key: Vec<u64> = sorted.iter().map(|x| total_order_key(*x)).collect();
    assert_eq!(keys, by_key, "the keys' order is total_cmp's");
}

#[test]
fn the_starts_residuals_from_its_last_pass_are_those_filled_afresh() {
    // linear_start_into's last pass over every sample (several chunks) writes the
    // residuals at the (a, b) it returns: bit for bit those of arma_residuals_rss,
    // and rss_from gives its RSS; the same (a, b) as linear_start
    let x: Vec<f64> = {
        let w = uniform(600_000, 21);
        let mut x = vec![0.0; w.len()];
        for t in 2..w.len() {
            x[t] = 0.5 * x[t - 1] - 0.2 * x[t - 2] + w[t] - 0.4 * w[t - 1];
        }
        x
    };
    for (p, q) in [(2, 1), (1, 2), (3, 1)] {
        let start = p.max(q);
        let mut e = vec![0.0; x.len()];
        let (a, b, holds) =
            linear_start_into(Centred::plain(&x), p, q, start, Some(&mut e)).unwrap();
        assert!(
            holds,
            "({p}, {q}): the last pass evaluated the returned (a, b)"
        );
        let (a2, b2) = linear_start(&x, p, q, start).unwrap();
        assert!(same_bits(&a, &a2) && same_bits(&b, &b2));
        let (want, rss) = arma_residuals_rss(Centred::plain(&x), &a, &b, start);
        assert!(same_bits(&e, &want), "({p}, {q})");
        assert_eq!(rss_from(&e, start).to_bits(), rss.to_bits());
    }
}

/// A sandwich variance that rounds to 0 or below is NaN, not 0, and the note counts
/// the fitted points without one. (A 2-level channel with 1e-6 noise has condition
/// numbers near 9e11 to 4.2e12: at `--bandwidth 0.5 --grid 1000`, 29 of its fitted
/// points have NaN se rather than a se of exactly 0.)
#[test]
fn a_standard_error_lost_to_rounding_is_nan_and_noted() {
    use super::super::moments::sandwich_diag;
    let q = [1.0, 0.0, 0.0, 1.0];
    assert_eq!(sandwich_diag(&q, &[4.0, 0.0, 0.0, 1.0], 2, 1), vec![2.0]);
    assert!(sandwich_diag(&q, &[0.0, 0.0, 0.0, 1.0], 2, 1)[0].is_nan());
    assert!(sandwich_diag(&q, &[-1e-30, 0.0, 0.0, 1.0], 2, 1)[0].is_nan());
    let status = [PointStatus::Ok, PointStatus::Ok, PointStatus::Singular];
    let cond = [10.0, 4.2e12, f64::NAN];
    let se = [0.1, 0.2, 0.3, f64::NAN, f64::NAN, f64::NAN];
    let note = missing_se_note(&status, &cond, &se, 2).unwrap();
    assert!(note.starts_with("1 fitted grid point(s)"), "{note}");
    assert!(note.contains("4.2e12"), "{note}");
    assert_eq!(
        missing_se_note(&status, &cond, &[0.1, 0.2, 0.3, 0.4, f64::NAN, f64::NAN], 2),
        None
    );
}

#[test]
fn a_non_finite_rss_always_goes_back_to_the_least_one() {
    let tol = 1e-6;
    assert!(!went_back(100.0, 100.0, tol));
    assert!(!went_back(100.00001, 100.0, tol), "within tol");
    assert!(went_back(100.001, 100.0, tol));
    assert!(!went_back(99.0, 100.0, tol), "below the least");
    // inf - 100 > tol inf and NaN > x are both false: the plain difference would
    // return these iterates
    assert!(went_back(f64::INFINITY, 100.0, tol));
    assert!(went_back(f64::NAN, 100.0, tol));
    assert!(went_back(f64::NEG_INFINITY, 100.0, tol));
}

#[test]
fn quantiles_by_selection_equal_those_of_a_full_sort() {
    // increasing, decreasing and repeated levels, with ties in the data
    let v: Vec<f64> = uniform(10_001, 4)
        .iter()
        .map(|u| (u * 50.0).round())
        .collect();
    let mut sorted = v.clone();
    sorted.sort_by(f64::total_cmp);
    let by_sort = |q: f64| {
        let pos = q * (sorted.len() - 1) as f64;
        let (i, frac) = (pos.floor() as usize, pos - pos.floor());
        match sorted.get(i + 1) {
            Some(next) => sorted[i] + frac * (next - sorted[i]),
            None => sorted[i],
        }
    };
    for qs in [
        vec![0.1, 0.9],
        vec![0.9, 0.1],
        vec![0.0, 0.5, 0.5, 1.0],
        vec![0.33],
    ] {
        let got = quantiles(|t| v[t], 0..v.len(), &qs);
        for (q, g) in qs.iter().zip(&got) {
            assert_eq!(g.to_bits(), by_sort(*q).to_bits(), "q = {q} of {qs:?}");
        }
    }
}

/// A 2-D fit whose residuals turn non-finite (here by the test hook, as an overflow
/// would leave them) does not stop there: the f-step raised the RSS (to NaN), so the
/// damped step goes back towards the iterate before it (module doc), whose residuals
/// are finite; the alternation goes on from whichever iterate that gives, its RSS
/// never above the one before by more than tol, and returns finite residuals that are
/// its own. (Before the damped step it stopped there, not converged, and returned the
/// iterate of least RSS.)
#[test]
fn a_2d_fit_damps_a_step_to_non_finite_residuals_and_goes_on() {
    use super::params::Farma2Params;
    use super::smoother2::{NAN_RESIDUALS_AT, fit2};
    // FARMA(1,1,1) whose f_1 follows a slow temperature-like channel
    let n = 3000;
    let a = uniform(n, 11);
    let temp: Vec<f64> = (0..n)
        .map(|t| 25.0 + 5.0 * (t as f64 / 400.0).sin())
        .collect();
    let mut x = vec![0.0; n];
    for t in 1..n {
        let f = 0.5 + 0.3 * (temp[t - 1] - 25.0).tanh();
        x[t] = f * x[t - 1] + a[t] + 0.4 * a[t - 1];
    }
    let params = |max_iter| Farma2Params {
        base: FarmaParams {
            p: 1,
            q: 1,
            d: 1,
            max_iter,
            ..Default::default()
        },
        index2: "temp".into(),
        d2: 1,
        grid: (7, 7),
        bandwidth: None,
    };
    // the first two iterates (the start and alternation 1) and their least-RSS one
    let one = fit2(&x, &temp, &params(1)).unwrap();
    let clean = fit2(&x, &temp, &params(20)).unwrap();
    assert!(clean.1.iterations > 2, "{}", clean.1.iterations);
    NAN_RESIDUALS_AT.set(Some(2));
    let m = fit2(&x, &temp, &params(20));
    NAN_RESIDUALS_AT.set(None);
    let (m, r) = m.unwrap();
    assert!(r.converged, "{:?}", r.notes);
    assert!(r.iterations >= 2, "{}", r.iterations);
    assert!(
        r.notes
            .iter()
            .any(|s| s.starts_with("alternation 2: the f-step")
                && s.contains("raised the RSS (NaN >"))
            || r.notes
                .iter()
                .any(|s| s.contains("f-step(s) raised the RSS and were damped")),
        "{:?}",
        r.notes
    );
    assert!(
        r.rss_history.iter().all(|v| v.is_finite()),
        "{:?}",
        r.rss_history
    );
    for w in r.rss_history.windows(2) {
        assert!(w[1] - w[0] <= 1e-6 * w[1], "{:?}", r.rss_history);
    }
    assert!(r.rss.is_finite() && r.residuals.iter().all(|v| v.is_finite()));
    assert!(m.coef.f.iter().all(|v| v.is_finite()));
    // no worse than the fit of one alternation
    assert!(
        r.rss <= one.1.rss * (1.0 + 1e-6),
        "{} vs {}",
        r.rss,
        one.1.rss
    );
    let pp = 1;
    let rss: f64 = r.residuals[pp..].iter().map(|v| v * v).sum();
    assert_eq!(rss.to_bits(), r.rss.to_bits());
}

/// The model a 2-D fit returns gives, by its own plain residual recursion with the
/// index channel ([`Farma::residuals2`]), the residuals of the fit's pass
/// (`grid2::residuals2`), bit for bit: f on the 2-D grid, its second index (channel,
/// delay d2 = 2, both bandwidths) and b are what the fit used. The table functions'
/// `grid` axis and the model's agree with the fit's grid.
#[test]
fn a_2d_model_gives_the_residuals_of_its_fit() {
    use super::params::Farma2Params;
    use super::smoother2::fit2;
    let n = 2000;
    let a = uniform(n, 5);
    let temp: Vec<f64> = (0..n)
        .map(|t| 20.0 + 4.0 * (t as f64 / 300.0).sin())
        .collect();
    let mut x = vec![3.0; n];
    for t in 2..n {
        let f = 0.4 + 0.3 * (temp[t - 2] - 20.0).tanh();
        x[t] = 3.0 + f * (x[t - 1] - 3.0) - 0.1 * (x[t - 2] - 3.0) + a[t] + 0.3 * a[t - 1];
    }
    let params = Farma2Params {
        base: FarmaParams {
            p: 2,
            q: 1,
            d: 1,
            ..Default::default()
        },
        index2: "temp".into(),
        d2: 2,
        grid: (6, 5),
        bandwidth: None,
    };
    let (m, r) = fit2(&x, &temp, &params).unwrap();
    let second = m.second().expect("a 2-D index");
    assert_eq!((second.channel.as_str(), second.lag), ("temp", 2));
    assert_eq!(
        (m.coef.grid.len(), second.grid.len(), m.coef.n_grid()),
        (6, 5, 30)
    );
    assert_eq!(
        r.gcv_table
            .iter()
            .filter(|g| (g.bandwidth, g.bandwidth2) == m.bandwidths())
            .count(),
        1
    );
    let y: Vec<f64> = x.iter().map(|v| v - m.mean).collect();
    let e = m.residuals2(&y, &temp);
    assert_eq!(e.len(), r.residuals.len());
    for (t, (a, b)) in e.iter().zip(&r.residuals).enumerate() {
        assert_eq!(a.to_bits(), b.to_bits(), "t = {t}: {a} vs {b}");
    }
    // f on the model's grid is the local fit's there (filled points included)
    let mut f = [0.0; 2];
    for g in 0..m.coef.n_grid() {
        m.f2(
            m.coef.centred_grid(g),
            m.coef.second_grid(g).unwrap(),
            &mut f,
        );
        assert_eq!(f, [r.local.f[2 * g], r.local.f[2 * g + 1]]);
    }
}

#[test]
fn a_fit_reading_the_mapped_column_while_its_pages_are_released_is_the_copys_fit() {
    // the fit of a store's column read in place, less its mean, while another thread
    // drops the column's pages all the time (every pass faults them back in), against
    // the fit of a centred copy (`fit`, the in-memory path): the same fit, bit for
    // bit. FARMA(2,1,1) plus a constant, long enough for the chunked passes (more
    // than two filter chunks)
    use crate::store::{STORE_FORMAT_VERSION, Segment, Store, StoreMeta, StoreWriter};
    use std::sync::atomic::{AtomicUsize, Ordering};
    let n = 2 * FILTER_CHUNK + 50_000;
    let z = uniform(n, 78);
    let mut x = vec![0.0; n];
    let (mut x1, mut x2, mut e1) = (0.0f64, 0.0f64, 0.0f64);
    for t in 0..n {
        let e = 3.4 * z[t];
        let f1 = 0.3 + 0.4 * (-x1 * x1).exp();
        let f2 = -0.2 + 0.1 * x1.tanh();
        let v = f1 * x1 + f2 * x2 + e - 0.5 * e1;
        x[t] = v + 0.25;
        (x2, x1, e1) = (x1, v, e);
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.arrow");
    let names = vec!["x".to_string()];
    let mut w = StoreWriter::create(&path, &names, n).unwrap();
    w.columns_mut()[0].copy_from_slice(&x);
    let meta = StoreMeta {
        format_version: STORE_FORMAT_VERSION,
        farma_version: env!("CARGO_PKG_VERSION").to_string(),
        sample_rate_hz: 100.0,
        time_source: "flag".into(),
        time_col: None,
        segments: vec![Segment {
            start: 0,
            len: n as u64,
            t0_s: 0.0,
        }],
        repairs: vec![],
        source: "test".into(),
        source_format: "arrow".into(),
        source_size: 0,
        source_mtime_ns: 0,
        nonfinite: vec![],
    };
    w.finish(&meta).unwrap();
    let store = Store::open(&path).unwrap();
    let col = store.column("x").unwrap();
    assert!(same_bits(col, &x));
    for init in [super::Init::Arma, super::Init::Literal] {
        let params = FarmaParams {
            grid_size: 41,
            init,
            ..FarmaParams::default()
        }
        .validate(n)
        .unwrap();
        let want = fit(&x, &params).unwrap();
        let released = AtomicUsize::new(0);
        let release = || {
            store.release(col);
            released.fetch_add(1, Ordering::Relaxed);
        };
        let got = super::fit_releasing(col, &params, release, std::time::Duration::ZERO).unwrap();
        assert!(released.load(Ordering::Relaxed) > 10, "{released:?}");
        let (m, r) = (&got.0, &got.1);
        let (mw, rw) = (&want.0, &want.1);
        assert!(rw.iterations >= 2, "{}", rw.iterations);
        assert_eq!(m.mean.to_bits(), mw.mean.to_bits());
        assert!(same_bits(&m.coef.grid, &mw.coef.grid));
        assert!(same_bits(&m.coef.f, &mw.coef.f));
        assert!(same_bits(&m.coef.se, &mw.coef.se));
        assert!(same_bits(&r.local.slope, &rw.local.slope));
        assert!(same_bits(&m.b, &mw.b));
        assert_eq!(m.bandwidth.to_bits(), mw.bandwidth.to_bits());
        assert_eq!(m.sigma2.to_bits(), mw.sigma2.to_bits());
        assert_eq!(r.rss.to_bits(), rw.rss.to_bits());
        assert_eq!(r.trace.to_bits(), rw.trace.to_bits());
        assert_eq!(r.gcv.to_bits(), rw.gcv.to_bits());
        assert!(same_bits(&r.rss_history, &rw.rss_history));
        assert!(same_bits(&r.residuals, &rw.residuals));
        assert_eq!(format!("{:?}", r.gcv_table), format!("{:?}", rw.gcv_table));
        assert_eq!(r.iterations, rw.iterations);
        assert_eq!(r.notes, rw.notes);
    }
}
