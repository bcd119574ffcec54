//! The diagnosis on the project's own bank (src/diagnosis/bank.rs): each effect hidden
//! in turn must be ranked first and, once added, bring the withheld-part gap within
//! twice the noise floor; a spec that matches its log must report nothing.

use farma::diagnosis::bank::{self, CHANNEL, Case};
use farma::diagnosis::{Diagnosis, GapParams, RealLog, diagnose};

fn run(case: &Case, n: usize, seed: u64, replicas: usize) -> Diagnosis {
    let (x, temp) = bank::real_log(case, n, seed).unwrap();
    let real = RealLog {
        channel: CHANNEL.into(),
        x: &x,
        rate_hz: case.spec.sample_rate_hz,
        temperature_c: temp.as_deref(),
        others: vec![],
        spec_dir: None,
    };
    let prm = GapParams {
        replicas,
        ..GapParams::default()
    };
    diagnose(&real, &case.spec, &prm).unwrap()
}

#[test]
fn bank_ranks_the_hidden_effect_first_and_closes_the_gap() {
    let rate_hz = 10.0;
    let n = 36_000; // one hour
    let cases = bank::cases(rate_hz);
    let mut top1 = 0;
    let mut closed = 0;
    let mut lines = Vec::new();
    for (i, case) in cases.iter().enumerate() {
        let d = run(case, n, 1000 + i as u64, 12);
        let first = d.effects.first().map(|e| e.kind.clone()).unwrap_or_default();
        let after_first = d.effects.first().map(|e| e.gap_after).unwrap_or(f64::NAN);
        let ok = first == case.expect;
        let near = after_first <= 2.0 * d.noise_floor;
        top1 += usize::from(ok);
        closed += usize::from(ok && near);
        lines.push(format!(
            "{:<26} first {:<26} gap {:>8.2} -> {:>6.2} (floor {:.2}) added {:?}",
            case.expect,
            first,
            d.gap_before,
            after_first,
            d.noise_floor,
            d.added.iter().map(|e| e.kind.as_str()).collect::<Vec<_>>()
        ));
    }
    let report = lines.join("\n");
    eprintln!("{report}");
    let n_cases = cases.len();
    assert!(
        top1 * 10 >= 9 * n_cases,
        "top-1 attribution {top1}/{n_cases}:\n{report}"
    );
    assert!(
        closed * 10 >= 9 * n_cases,
        "gap within 2x the floor after the right effect in {closed}/{n_cases}:\n{report}"
    );
}

#[test]
fn a_matching_spec_reports_nothing_and_adds_nothing() {
    for (seed, temp) in [(77, false), (78, true)] {
        let spec = bank::base_spec(10.0, temp);
        let case = Case {
            expect: String::new(),
            spec: spec.clone(),
            truth: spec,
        };
        let d = run(&case, 36_000, seed, 12);
        assert!(d.added.is_empty(), "added {:?}", d.added.iter().map(|e| &e.kind).collect::<Vec<_>>());
        assert!(d.where_before.is_empty(), "regions {:?}", d.where_before);
        assert!(d.gap_before <= d.gap_threshold, "{} > {}", d.gap_before, d.gap_threshold);
        assert!(!d.effects.is_empty(), "candidates are still listed");
    }
}
