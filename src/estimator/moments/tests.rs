//! Tests of the moment tables against direct sums: the same fits, RSS, trace and
//! standard errors, bit for bit where the module promises it.

use super::*;
use crate::estimator::problem::{GridFit, VcProblem};

#[test]
fn a_coarsened_index_has_the_intervals_of_one_built_by_search() {
    let (x, _) = series(50_000, 12);
    let grid: Vec<f64> = (0..21).map(|k| -0.8 + 0.08 * k as f64).collect();
    let hs = [0.5, 0.3, 0.11, 0.05];
    let prob = VcProblem::new(&x, &[], &[], 2, 1);
    let fine = IntervalIndex::build(&prob, breakpoints(&grid, &hs)).unwrap();
    for h in hs {
        let coarse = fine.coarsened(breakpoints(&grid, &[h])).unwrap();
        let built = IntervalIndex::build(&prob, breakpoints(&grid, &[h])).unwrap();
        assert_eq!(coarse.breaks, built.breaks);
        assert!((prob.start..x.len()).all(|t| coarse.interval(t) == built.interval(t)));
        // coarsened twice (fine -> two bandwidths -> one): the same intervals
        let mid = fine.coarsened(breakpoints(&grid, &[h, 0.05])).unwrap();
        let twice = mid.coarsened(breakpoints(&grid, &[h])).unwrap();
        assert!((prob.start..x.len()).all(|t| twice.interval(t) == built.interval(t)));
        // a table over the coarsened index is the one over the searched index
        let span = (-3.0, 3.0);
        let a = MomentTable::build_indexed(&prob, &coarse, span.0, span.1, 6, Families::All);
        let b = MomentTable::build_indexed(&prob, &built, span.0, span.1, 6, Families::All);
        assert_eq!(bits(&a), bits(&b));
    }
    // a bandwidth the fine index does not hold
    assert!(fine.coarsened(breakpoints(&grid, &[0.2])).is_none());
}

#[test]
fn interval_lookup_equals_binary_search() {
    // uneven breakpoints (a grid and its windows), values inside, outside, on breaks
    let grid: Vec<f64> = (0..21).map(|k| -1.3 + 0.13 * k as f64).collect();
    let hs: Vec<f64> = (0..21).map(|j| 1.1f64.powi(-j) * 1.7).collect();
    let mut b = breakpoints(&grid, &hs);
    b.sort_by(f64::total_cmp);
    b.dedup();
    let lk = IntervalLookup::new(&b);
    let mut us: Vec<f64> = b.clone();
    us.extend(b.iter().map(|v| v.next_up()));
    us.extend(b.iter().map(|v| v.next_down()));
    us.extend((0..20_001).map(|i| -6.0 + 12.0 * i as f64 / 20_000.0));
    us.extend([
        f64::MAX,
        f64::MIN,
        0.0,
        -0.0,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ]);
    for u in us {
        assert_eq!(lk.find(u), b.partition_point(|v| *v <= u), "u = {u}");
    }
    let one = [0.5];
    let lk = IntervalLookup::new(&one);
    for u in [0.0, 0.5, 1.0] {
        assert_eq!(lk.find(u), one.partition_point(|v| *v <= u));
    }
}

/// An AR(2)-like series with uniform innovations, residuals and b for tables.
fn series(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut s = seed;
    let mut next = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut x = vec![0.0f64; n];
    for t in 2..n {
        x[t] = 0.5 * x[t - 1] - 0.2 * x[t - 2] + next();
    }
    let e: Vec<f64> = (0..n).map(|_| next()).collect();
    (x, e)
}

fn bits(m: &MomentTable) -> (Vec<u64>, Vec<u64>) {
    (m.m.iter().map(|v| v.to_bits()).collect(), m.count.clone())
}

#[test]
fn indexed_and_refreshed_tables_equal_fresh_ones_bit_for_bit() {
    // N above one block, so that several block tables are added
    let (x, e) = series(300_000, 11);
    let e2: Vec<f64> = e.iter().map(|v| 0.5 * v + 0.01).collect();
    let grid: Vec<f64> = (0..41).map(|k| -0.6 + 0.03 * k as f64).collect();
    let hs = [0.25, 0.1];
    for p in [1, 2, 3, 4] {
        let prob = VcProblem::new(&x, &e, &[-0.4], p, 1);
        let breaks = breakpoints(&grid, &hs);
        let ix = IntervalIndex::build(&prob, breaks.clone()).unwrap();
        for t in [p, p + 1, 1000, x.len() - 1] {
            let b = &ix.breaks;
            assert_eq!(ix.interval(t), b.partition_point(|v| *v <= x[t - 1]));
        }
        for (fam, deg) in [(Families::All, 6), (Families::Response, 5)] {
            let a = MomentTable::build_families(&prob, breaks.clone(), -2.0, 2.0, deg, fam);
            let b = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, deg, fam);
            assert_eq!(bits(&a), bits(&b), "p = {p}, {fam:?}");
        }
        // the X_a y families alone (the specialised pass for p <= 3) against the
        // same families of the full table (the general pass)
        let all = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 6, Families::All);
        let xy = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 6, Families::Response);
        let (wa, wx) = (all.nfam * 7, xy.nfam * 7);
        for e in 0..all.n_intervals() {
            for a in 0..p {
                let fa = all.fam(a, p);
                let ra = &all.m[e * wa + fa * 7..e * wa + (fa + 1) * 7];
                let rx = &xy.m[e * wx + a * 7..e * wx + (a + 1) * 7];
                assert!(ra.iter().zip(rx).all(|(u, v)| u.to_bits() == v.to_bits()));
            }
        }
        // new residuals and b: the refreshed table is the fresh one
        let prob2 = VcProblem {
            e: &e2,
            b: &[0.3],
            ..prob
        };
        let fresh = MomentTable::build(&prob2, breaks.clone(), -2.0, 2.0, 6);
        // with the cell sums of the grid kept from the first table: the y
        // families' are summed anew, and all equal a fresh table's
        let _ = all.cells(&grid);
        let cell_bits = |t: &MomentTable| {
            let c = t.cells(&grid);
            let b = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
            (
                b(&c.prefix),
                b(&c.suffix),
                b(&c.prefix_scale),
                c.prefix_count.clone(),
            )
        };
        for index in [Some(&ix), None] {
            let refreshed = all.with_response(&prob2, index, (-2.0, 2.0));
            assert_eq!(bits(&refreshed), bits(&fresh), "p = {p}");
            assert!(cell_bits(&refreshed) == cell_bits(&fresh), "p = {p}");
        }
        let moved = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 6, Families::All);
        let _ = moved.cells(&grid);
        let moved = moved.into_response(&prob2, Some(&ix), (-2.0, 2.0));
        assert_eq!(bits(&moved), bits(&fresh), "p = {p}");
        assert!(cell_bits(&moved) == cell_bits(&fresh), "p = {p}");
    }
}

#[test]
fn a_design_table_gives_the_full_tables_trace_and_standard_errors() {
    // the final step's table: the design's families alone, degree 10. Its local
    // systems, trace and standard-error factors must be the full table's, bit for
    // bit (they do not depend on y), and its pass must not read the residuals
    let (x, e) = series(200_000, 5);
    let grid: Vec<f64> = (0..31).map(|k| -0.45 + 0.03 * k as f64).collect();
    let h = 0.12;
    for p in [1, 2, 3] {
        let prob = VcProblem::new(&x, &e, &[-0.4], p, 1);
        let ix = IntervalIndex::build(&prob, breakpoints(&grid, &[h])).unwrap();
        let full = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 10, Families::All);
        let fit = full.fit_ladder(&grid, &[h]).remove(0);
        assert!(fit.all_ok());
        // other residuals: the design table is the same
        let e_other: Vec<f64> = e.iter().map(|v| 3.0 * v - 1.0).collect();
        let prob_other = VcProblem {
            e: &e_other,
            b: &[0.7],
            ..prob
        };
        let design = MomentTable::build_indexed(&prob_other, &ix, -2.0, 2.0, 10, Families::Design);
        assert_eq!(design.nfam, p * (p + 1) / 2 + 1);
        let dfit = design.local_systems(&grid, h).design_fit();
        assert_eq!(dfit.status, fit.status);
        let sinv = |f: &GridFit| f.s_inv.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(sinv(&dfit), sinv(&fit), "p = {p}");
        let (_, trace) = full.rss_trace(&grid, &fit);
        assert_eq!(
            design.trace(&grid, &dfit).to_bits(),
            trace.to_bits(),
            "p = {p}"
        );
        assert_eq!(full.trace(&grid, &fit).to_bits(), trace.to_bits());
        let se = |v: Vec<f64>| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            se(design.se_factors(&grid, &dfit)),
            se(full.se_factors(&grid, &fit)),
            "p = {p}"
        );
    }
}

#[test]
fn tables_of_other_families_are_summed_in_the_same_blocks() {
    // many intervals and N large enough that the blocks are above their minimum
    // size (here N/4): a table of fewer families or a lower degree must still be
    // cut into the same blocks, or its sums (and the refreshed table) lose the
    // bits (the formula that followed each table's own length gave the X_a y
    // table of degree 5 blocks of 2^17 rows, the full table N/4)
    let (x, e) = series(700_000, 13);
    let grid: Vec<f64> = (0..101).map(|k| -0.6 + 0.012 * k as f64).collect();
    let hs: Vec<f64> = (0..13).map(|j| 0.3 * 1.1f64.powi(-j)).collect();
    let prob = VcProblem::new(&x, &e, &[-0.4], 1, 1);
    let breaks = breakpoints(&grid, &hs);
    let ix = IntervalIndex::build(&prob, breaks.clone()).unwrap();
    let all = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 6, Families::All);
    let xy = MomentTable::build_indexed(&prob, &ix, -2.0, 2.0, 5, Families::Response);
    let f = all.fam(0, 1);
    let (wa, wx) = (all.nfam * 7, 6);
    for e in 0..all.n_intervals() {
        let ra = &all.m[e * wa + f * 7..e * wa + f * 7 + 6];
        let rx = &xy.m[e * wx..e * wx + 6];
        assert!(ra.iter().zip(rx).all(|(u, v)| u.to_bits() == v.to_bits()));
    }
    let e2: Vec<f64> = e.iter().map(|v| 0.5 * v).collect();
    let prob2 = VcProblem { e: &e2, ..prob };
    let fresh = MomentTable::build(&prob2, breaks, -2.0, 2.0, 6);
    let refreshed = all.with_response(&prob2, Some(&ix), (-2.0, 2.0));
    assert_eq!(bits(&refreshed), bits(&fresh));
}

#[test]
fn a_rung_has_the_same_bits_in_any_ladder() {
    // the whole cells of each side are summed nearest first in their own sum, so a
    // window does not depend on the narrower ones summed before it
    let (x, e) = series(50_000, 23);
    let grid: Vec<f64> = (0..41).map(|k| -0.6 + 0.03 * k as f64).collect();
    let hs: Vec<f64> = (0..12).map(|j| 0.9 * 1.1f64.powi(-j)).collect();
    let prob = VcProblem::new(&x, &e, &[-0.4], 2, 1);
    let table = MomentTable::build(&prob, breakpoints(&grid, &hs), -2.0, 2.0, 6);
    let fbits = |f: &GridFit| -> Vec<u64> { f.f.iter().map(|v| v.to_bits()).collect() };
    let all = table.fit_ladder(&grid, &hs);
    for (k, &h) in hs.iter().enumerate() {
        let alone = table.fit_ladder(&grid, &[h]).remove(0);
        assert_eq!(fbits(&alone), fbits(&all[k]), "h_{k}");
        let some = table.fit_ladder(&grid, &[hs[0], h, hs[hs.len() - 1]]);
        assert_eq!(fbits(&some[1]), fbits(&all[k]), "h_{k}");
        // and the f-step's path: kept left-hand sides, the right-hand sides alone
        let sys = table.local_systems(&grid, h);
        assert_eq!(fbits(&table.fit_response(&sys)), fbits(&all[k]), "h_{k}");
    }
}

#[test]
fn a_ladder_on_kept_left_hand_sides_has_the_full_ladders_bits() {
    // the re-check's path: the left-hand sides of a first ladder (X and U only),
    // new residuals and b in the y families, the right-hand sides alone, against
    // the full ladder on the refreshed table, for every p of the fixed passes
    let (x, e) = series(60_000, 29);
    let e2: Vec<f64> = e.iter().map(|v| 0.7 * v - 0.02).collect();
    let grid: Vec<f64> = (0..41).map(|k| -0.6 + 0.03 * k as f64).collect();
    let hs: Vec<f64> = (0..12).map(|j| 0.9 * 1.1f64.powi(-j)).collect();
    let fbits = |f: &GridFit| -> Vec<u64> {
        f.f.iter()
            .chain(&f.slope)
            .chain(&f.s_inv)
            .map(|v| v.to_bits())
            .collect()
    };
    for p in [1, 2, 3] {
        let prob = VcProblem::new(&x, &e, &[-0.4], p, 1);
        let table = MomentTable::build(&prob, breakpoints(&grid, &hs), -2.0, 2.0, 6);
        let (_, systems) = table.fit_ladder_systems(&grid, &hs);
        // the kept left-hand sides are those of local_systems at each h
        for (sys, &h) in systems.iter().zip(&hs) {
            let alone = table.local_systems(&grid, h);
            assert_eq!(sys.h, h);
            for (a, b) in sys.points.iter().zip(&alone.points) {
                assert_eq!(a.1, b.1);
                assert_eq!(a.2.to_bits(), b.2.to_bits());
                assert!(
                    a.0.iter()
                        .zip(&b.0)
                        .all(|(u, v)| u.to_bits() == v.to_bits())
                );
            }
        }
        let prob2 = VcProblem {
            e: &e2,
            b: &[0.3],
            ..prob
        };
        let fresh = table.with_response(&prob2, None, (-2.0, 2.0));
        let full = fresh.fit_ladder(&grid, &hs);
        // every rung, and a subset in another order
        let all: Vec<&LocalSystems> = systems.iter().collect();
        let kept = fresh.fit_ladder_response(&all);
        for (k, f) in kept.iter().enumerate() {
            assert_eq!(fbits(f), fbits(&full[k]), "p = {p}, h_{k}");
            assert_eq!(f.status, full[k].status);
            assert_eq!(f.n_support, full[k].n_support);
        }
        let some = fresh.fit_ladder_response(&[&systems[7], &systems[2]]);
        assert_eq!(fbits(&some[0]), fbits(&full[7]), "p = {p}");
        assert_eq!(fbits(&some[1]), fbits(&full[2]), "p = {p}");
        // the residuals changed, so the fits did
        assert_ne!(
            fbits(&kept[3]),
            fbits(&table.fit_ladder(&grid, &[hs[3]])[0])
        );
    }
}
