//! GCV's limit h -> infinity (`estimator::fit::global`): chosen on a linear series, where
//! the minimum runs off the top of the ladder; written as bandwidth +inf (j null in
//! gcv.parquet, bandwidth null in the JSON); kept out by `--save-state`; not chosen
//! where f_m depends on the state.

use std::path::Path;

use arrow_array::{Array, BooleanArray, Float64Array, Int64Array};

use crate::common::{farma, stderr, stdout};

/// x_t = sum_m f_m(x_(t-1)) x_(t-m) + e_t + 0.4 e_(t-1), unit Gaussian e from a fixed
/// xorshift, written as a 100 Hz CSV with the column `x`.
fn write_series(path: &Path, n: usize, f1: impl Fn(f64) -> f64) {
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    let mut normal = move || {
        let mut u = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let (a, b) = (u().max(1e-300), u());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    };
    let (mut x, mut e) = (vec![0.0f64; n + 200], vec![0.0f64; n + 200]);
    for t in 2..n + 200 {
        e[t] = normal();
        x[t] = f1(x[t - 1]) * x[t - 1] - 0.3 * x[t - 2] + e[t] + 0.4 * e[t - 1];
    }
    let mut csv = String::from("time_s,x\n");
    for (k, v) in x[200..].iter().enumerate() {
        csv.push_str(&format!("{},{v}\n", k as f64 / 100.0));
    }
    std::fs::write(path, csv).unwrap();
}

fn table(path: &Path) -> arrow_array::RecordBatch {
    crate::common::parquet_table(path)
}

fn col<'a, T: 'static>(b: &'a arrow_array::RecordBatch, name: &str) -> &'a T {
    b.column_by_name(name)
        .unwrap_or_else(|| panic!("no column {name}"))
        .as_any()
        .downcast_ref::<T>()
        .unwrap()
}

fn fit(log: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "fit",
        log.to_str().unwrap(),
        "--channel",
        "x",
        "--order",
        "2,1,1",
        "--grid",
        "41",
        "--json",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = farma(&args, out.parent().unwrap());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    o
}

#[test]
fn a_linear_series_gets_the_ladders_limit_and_save_state_keeps_a_finite_bandwidth() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("arma.csv");
    write_series(&log, 20_000, |_| 0.5);
    let out = dir.path().join("fit");
    let o = fit(&log, &out, &[]);
    assert!(
        stderr(&o).contains("GCV minimum at the ladder's limit h -> infinity"),
        "{}",
        stderr(&o)
    );
    let params = table(&out.join("params.parquet"));
    let h = col::<Float64Array>(&params, "bandwidth").value(0);
    assert!(h.is_infinite() && h > 0.0, "bandwidth {h}");
    let trace = col::<Float64Array>(&params, "trace").value(0);
    // 2p = 4 parameters, a little less for the rows beyond the grid (f constant there);
    // or p = 2 where no f-step beat the linear ARMA start, which is then returned (with
    // the bandwidth GCV chose: on this series, where the start is the least-squares fit
    // of a linear model, it is)
    let returned_start = stderr(&o).contains("the linear start is returned");
    assert!(
        if returned_start {
            trace == 2.0
        } else {
            trace > 3.5 && trace <= 4.0
        },
        "trace {trace}"
    );
    let gcv = table(&out.join("gcv.parquet"));
    let (j, bw) = (
        col::<Int64Array>(&gcv, "j"),
        col::<Float64Array>(&gcv, "bandwidth"),
    );
    let chosen = col::<BooleanArray>(&gcv, "chosen");
    assert!(j.is_null(0) && bw.value(0).is_infinite() && chosen.value(0));
    assert!(
        (1..gcv.num_rows()).all(|r| !j.is_null(r) && bw.value(r).is_finite() && !chosen.value(r))
    );
    // the limit's GCV below the largest rung's (h_0), and the ladder not extended upwards
    let g = col::<Float64Array>(&gcv, "gcv");
    assert!(g.value(0) < g.value(1));
    assert_eq!((1..gcv.num_rows()).map(|r| j.value(r)).min(), Some(0));
    // f_m is a line in the index: equal steps between equally spaced grid points
    let coef = table(&out.join("coef.parquet"));
    let f = col::<Float64Array>(&coef, "f");
    let m = col::<Int64Array>(&coef, "m");
    let f1: Vec<f64> = (0..coef.num_rows())
        .filter(|&r| m.value(r) == 1)
        .map(|r| f.value(r))
        .collect();
    let step = f1[1] - f1[0];
    assert!(
        f1.windows(2).all(|w| ((w[1] - w[0]) - step).abs() < 1e-12),
        "{f1:?}"
    );
    assert!((f1[20] - 0.5).abs() < 0.05, "f_1 at the centre {}", f1[20]);
    // JSON has no infinity: the bandwidth is null there
    let json: serde_json::Value = serde_json::from_str(stdout(&o).lines().next().unwrap()).unwrap();
    assert!(json["bandwidth"].is_null(), "{json}");

    // --save-state: a finite bandwidth (the ladder extended upwards instead)
    let out2 = dir.path().join("fit_state");
    fit(&log, &out2, &["--save-state"]);
    let params = table(&out2.join("params.parquet"));
    let h2 = col::<Float64Array>(&params, "bandwidth").value(0);
    assert!(h2.is_finite(), "bandwidth {h2} with --save-state");
    let gcv = table(&out2.join("gcv.parquet"));
    assert_eq!(col::<Int64Array>(&gcv, "j").null_count(), 0);
}

#[test]
fn a_state_dependent_series_keeps_a_finite_bandwidth() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("farma.csv");
    write_series(&log, 20_000, |u| 0.2 + 0.6 * (-u * u).exp());
    let out = dir.path().join("fit");
    fit(&log, &out, &[]);
    let params = table(&out.join("params.parquet"));
    let h = col::<Float64Array>(&params, "bandwidth").value(0);
    assert!(h.is_finite(), "bandwidth {h}");
}

/// A state taken from a model at the limit (bandwidth +inf, not a returned linear
/// start) has no kernel windows: `update` refuses it, saying how to get one it can take.
#[test]
fn an_update_of_a_model_at_the_limit_is_refused_with_the_way_out() {
    use farma::estimator::update::{state_from_fit, update};
    use farma::estimator::{FarmaParams, fit};
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("arma.csv");
    write_series(&log, 5_000, |_| 0.5);
    let text = std::fs::read_to_string(&log).unwrap();
    let x: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    let prm = FarmaParams {
        grid_size: 31,
        ..FarmaParams::default()
    };
    let (mut m, mut r) = fit(&x, &prm.validate(x.len()).unwrap()).unwrap();
    m.bandwidth = f64::INFINITY;
    r.linear_start = false;
    let st = state_from_fit("x", &x, &m, &r);
    let Err(err) = update(&st, &x[..10], 1.0) else {
        panic!("an update of a state at h = inf was accepted");
    };
    let err = err.to_string();
    assert!(
        err.contains("limit h -> infinity") && err.contains("--save-state"),
        "{err}"
    );
}
