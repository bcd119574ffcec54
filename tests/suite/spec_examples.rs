//! Every example spec in `fixtures/specs/` runs as shipped: each names its command on a
//! `# Run: farma ...` line (from the repository's root, `-o sim.csv`), and that command
//! simulates every channel of the spec.

use crate::common::{farma, root, stderr};

#[test]
fn every_example_spec_runs_with_the_command_it_names() {
    let dir = tempfile::tempdir().unwrap();
    let specs: Vec<_> = std::fs::read_dir(root().join("fixtures/specs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    assert!(specs.len() >= 2, "{specs:?}");
    for spec in specs {
        let text = std::fs::read_to_string(&spec).unwrap();
        let run = text
            .lines()
            .find_map(|l| l.strip_prefix("# Run: farma "))
            .unwrap_or_else(|| panic!("{}: no '# Run: farma ...' line", spec.display()));
        let out = dir.path().join(format!(
            "{}.csv",
            spec.file_stem().unwrap().to_string_lossy()
        ));
        let args: Vec<String> = run
            .split_whitespace()
            .map(|a| match a {
                "sim.csv" => out.to_string_lossy().into_owned(),
                a => a.to_string(),
            })
            .collect();
        assert!(args.iter().any(|a| *a == out.to_string_lossy()), "{run}");
        // paths in the command are relative to the repository's root
        let args: Vec<String> = args
            .into_iter()
            .map(|a| match a.starts_with("fixtures/") {
                true => root().join(&a).to_string_lossy().into_owned(),
                false => a,
            })
            .collect();
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = farma(&refs, dir.path());
        assert_eq!(
            o.status.code(),
            Some(0),
            "{}: {}",
            spec.display(),
            stderr(&o)
        );
        // every channel of the spec is a column of the simulated log
        let header = std::fs::read_to_string(&out)
            .unwrap()
            .lines()
            .find(|l| !l.starts_with('#'))
            .unwrap()
            .to_string();
        for name in text.lines().filter_map(|l| {
            l.trim()
                .strip_prefix("name = \"")
                .and_then(|r| r.split('"').next())
        }) {
            assert!(
                header.split(',').any(|c| c == name),
                "{}: channel {name} not in {header}",
                spec.display()
            );
        }
    }
}
