//! The local-linear fits equal the brute-force numpy reference
//! (`shared/reference/ref_farma.py`, `local_linear`) at the same grid and bandwidth,
//! by both computation paths. Golden values: fixtures/golden/farma_local_linear.csv,
//! made by fixtures/golden/make_farma_golden.py.

use farma::estimator::direct::{DirectIndex, fit_grid};
use farma::estimator::moments::{MomentTable, breakpoints};
use farma::estimator::{PointStatus, VcProblem};

#[test]
fn grid_fits_match_ref_farma_local_linear_to_1e10() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/golden/farma_local_linear.csv"
    ))
    .unwrap();
    let (mut x, mut e) = (Vec::new(), Vec::new());
    let mut fits: Vec<(f64, f64, f64, f64)> = Vec::new();
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let f: Vec<&str> = line.split(',').collect();
        let v = |i: usize| f[i].parse::<f64>().unwrap();
        match f[0] {
            "x" => {
                x.push(v(2));
                e.push(v(3));
            }
            "fit" => fits.push((v(1), v(2), v(3), v(4))),
            _ => panic!("bad line {line}"),
        }
    }
    let b = [-0.5];
    let prob = VcProblem::new(&x, &e, &b, 2, 1);
    let mut hs: Vec<f64> = fits.iter().map(|f| f.0).collect();
    hs.dedup();
    let grid: Vec<f64> = fits.iter().filter(|f| f.0 == hs[0]).map(|f| f.1).collect();
    assert_eq!((hs.len(), grid.len()), (3, 15));
    let (umin, umax) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let table = MomentTable::build(&prob, breakpoints(&grid, &hs), umin, umax, 6);
    let fast = table.fit_ladder(&grid, &hs);
    let index = DirectIndex::build(&prob);
    let mut worst = 0.0f64;
    for (j, &h) in hs.iter().enumerate() {
        let direct = fit_grid(&prob, &index, &grid, h);
        for (g, want) in fits.iter().filter(|f| f.0 == h).enumerate() {
            for fit in [&fast[j], &direct] {
                assert_eq!(fit.status[g], PointStatus::Ok);
                for (m, w) in [want.2, want.3].iter().enumerate() {
                    let got = fit.f[g * 2 + m];
                    let r = (got - w).abs() / w.abs().max(1e-300);
                    worst = worst.max(r);
                    assert!(
                        r <= 1e-10,
                        "h {h} grid {} f{}: {got} vs reference {w}",
                        want.1,
                        m + 1
                    );
                }
            }
        }
    }
    eprintln!("worst relative difference to ref_farma.local_linear: {worst:e}");
}
