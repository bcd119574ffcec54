//! `farma prep`: Pauta against planted outliers and the clean-data rate, the
//! reverse-arrangement statistic against its null mean and variance, and the command.

use crate::common::{assert_refused_file_output, farma, fixture, stderr, stdout};
use farma::workflow::pauta::{Replace, pauta};
use farma::workflow::stationarity::{
    SegmentStat, reverse_arrangement_series, reverse_arrangement_test, reverse_arrangements,
};
use farma::workflow::{ALPHA, rejects};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

fn gauss(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
}

#[test]
fn pauta_finds_every_planted_outlier_and_keeps_the_time_base() {
    let n = 20_000;
    let mut x = gauss(n, 3);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut planted = std::collections::BTreeSet::new();
    while planted.len() < 40 {
        planted.insert(rng.random_range(0..n));
    }
    for &i in &planted {
        let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
        x[i] = sign * rng.random_range(6.0..20.0);
    }
    let r = pauta(&x, 3.0, Replace::Interpolate, 100);
    let found: std::collections::BTreeSet<usize> = r.replaced.iter().map(|v| v.index).collect();
    for i in &planted {
        assert!(found.contains(i), "planted outlier at {i} not found");
    }
    // Beyond the planted ones: the clean-data rate of the iterated rule, 0.31 % of
    // 19,960 = 63 expected (sd 8); allow 4 sd.
    let extra = found.len() - planted.len();
    assert!(extra <= 95, "{extra} clean samples rejected");
    assert_eq!(r.cleaned.len(), n);
    for v in &r.replaced {
        assert!(r.cleaned[v.index].abs() < 4.0, "{v:?}");
    }
    // an isolated replacement is the midpoint of its neighbours
    let iso = r
        .replaced
        .iter()
        .find(|v| {
            v.index > 0
                && v.index + 1 < n
                && !found.contains(&(v.index - 1))
                && !found.contains(&(v.index + 1))
        })
        .unwrap();
    let mid = 0.5 * (x[iso.index - 1] + x[iso.index + 1]);
    assert!((iso.replacement - mid).abs() < 1e-15);
}

#[test]
fn pauta_rate_on_clean_gaussian_data_is_the_3_sigma_rate() {
    // 200,000 clean N(0,1) samples: the iterated rule settles at c' = 2.954 sigma,
    // expected rate 0.314 % (628 samples, sd 25); a single pass would give 0.27 % (540).
    let x = gauss(200_000, 11);
    let r = pauta(&x, 3.0, Replace::Interpolate, 100);
    let k = r.replaced.len() as f64;
    assert!((528.0..=728.0).contains(&k), "{k} rejected of 200,000");
    // and the first pass alone is the 0.27 % rate: rejections of pass 1
    let first = r.replaced.iter().filter(|v| v.pass == 1).count() as f64;
    assert!((440.0..=640.0).contains(&first), "{first} in pass 1");
}

#[test]
fn reverse_arrangements_have_the_null_mean_and_variance_on_white_noise() {
    // K = 30 iid values, 4000 replications: E[A] = K(K-1)/4 = 217.5,
    // Var[A] = K(2K+5)(K-1)/72 = 785.42.
    let k = 30usize;
    let reps = 4000;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let a: Vec<f64> = (0..reps)
        .map(|_| {
            let y: Vec<f64> = (0..k).map(|_| StandardNormal.sample(&mut rng)).collect();
            reverse_arrangements(&y) as f64
        })
        .collect();
    let mean = a.iter().sum::<f64>() / reps as f64;
    let var = a.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (reps - 1) as f64;
    let (m0, v0) = (217.5, 30.0 * 65.0 * 29.0 / 72.0);
    // sd of the mean: sqrt(785/4000) = 0.44; of the variance about v0 sqrt(2/4000) = 17.6
    assert!((mean - m0).abs() < 4.0 * 0.443, "mean {mean} vs {m0}");
    assert!((var - v0).abs() < 4.0 * 17.6, "variance {var} vs {v0}");
    let r = reverse_arrangement_test(&[1.0; 30]);
    assert_eq!((r.mean, r.variance), (m0, v0));
    // level: white-noise series of 20 segments reject at about 5 %
    let mut rej = 0;
    for _ in 0..400 {
        let x: Vec<f64> = (0..2000).map(|_| StandardNormal.sample(&mut rng)).collect();
        if rejects(
            reverse_arrangement_series(&x, 20, SegmentStat::Mean).p_value,
            ALPHA,
        ) {
            rej += 1;
        }
    }
    // binomial(400, 0.05): 20 expected, sd 4.4
    assert!((5..=38).contains(&rej), "{rej} of 400 rejected");
    // a trend is found
    let x: Vec<f64> = gauss(2000, 8)
        .iter()
        .enumerate()
        .map(|(t, v)| v + 0.002 * t as f64)
        .collect();
    assert!(reverse_arrangement_series(&x, 20, SegmentStat::Mean).p_value < 1e-6);
}

#[test]
fn prep_command_writes_the_clean_log_and_reports_and_rejects_bad_flags() {
    let dir = tempfile::tempdir().unwrap();
    let log = fixture("multiaxis.csv");
    let out = dir.path().join("p");
    let o = farma(
        &[
            "prep",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x,gyro_y",
            "--nonstationary",
            "diff",
            "--json",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let lines: Vec<serde_json::Value> = stdout(&o)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2);
    for v in &lines {
        for k in [
            "channel",
            "replaced",
            "stationarity",
            "steps",
            "stationary",
            "n",
        ] {
            assert!(v.get(k).is_some(), "key {k} missing: {v}");
        }
        // every channel has the same length (gyro_y is differenced on this log,
        // so both lose a row)
        assert_eq!(v["n"], 3999, "{v}");
    }
    let store = farma::store::Store::open(&out.join("clean.arrow")).unwrap();
    assert_eq!(store.n_samples(), 3999);
    let y = store.column("gyro_y").unwrap();
    assert!(y.iter().sum::<f64>().abs() < 1e-9);
    assert!(out.join("prep.parquet").exists() && out.join("replaced.parquet").exists());
    // bad input: exit 2, message names the channel
    let o = farma(
        &[
            "prep",
            log.to_str().unwrap(),
            "--channel",
            "nope",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("nope"));
    let o = farma(
        &[
            "prep",
            log.to_str().unwrap(),
            "--segments",
            "2",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--segments"));
    // -o naming a file: exit 2 before the work, the file untouched
    let file = dir.path().join("taken");
    std::fs::write(&file, "keep me").unwrap();
    let o = farma(
        &["prep", log.to_str().unwrap(), "-o", file.to_str().unwrap()],
        dir.path(),
    );
    assert_refused_file_output(&o, &file, "keep me");
}
