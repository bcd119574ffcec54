//! The committed fixtures are what the generator makes.

use crate::common::{self, fixtures_gen};

#[test]
#[ignore = "writes fixtures/; run by hand to regenerate"]
fn regenerate_fixtures() {
    fixtures_gen::write_all(&common::root().join("fixtures"));
}

#[test]
fn committed_fixtures_match_the_generator() {
    let dir = tempfile::tempdir().unwrap();
    fixtures_gen::write_all(dir.path());
    let fresh = std::fs::read_to_string(dir.path().join("multiaxis.csv")).unwrap();
    let committed = std::fs::read_to_string(common::fixture("multiaxis.csv")).unwrap();
    assert_eq!(fresh.lines().count(), committed.lines().count());
    // Values equal to 1e-12 relative (libm's exp/tanh may differ in the last bit across
    // platforms); headers and comments exactly.
    for (a, b) in fresh.lines().zip(committed.lines()) {
        if a.starts_with('#') || a.starts_with("time") {
            assert_eq!(a, b);
            continue;
        }
        for (x, y) in a.split(',').zip(b.split(',')) {
            let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
            assert!((x - y).abs() <= 1e-12 * x.abs().max(1.0), "{a} vs {b}");
        }
    }
    for (name, text) in fixtures_gen::bad_csv_files() {
        let committed = std::fs::read_to_string(common::fixture(&format!("bad/{name}"))).unwrap();
        assert_eq!(
            committed, text,
            "fixtures/bad/{name} differs from the generator"
        );
    }
}
