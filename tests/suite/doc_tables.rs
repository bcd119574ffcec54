//! docs/contracts.md section 5 lists every Parquet table's columns: each command that
//! writes tables is run on the bundled fixture (a folder or file output, as the
//! section's "written by" names it), and every file it writes is read back: its column
//! names, in order, are the docs' list for that table and subcommand (of its variants,
//! the one whose list it is). Every row of the
//! section is met by at least one written file, so a stale row fails too.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::common::{farma, fixture, root, stderr};

/// A row of section 5: the file name, its variant (the parenthesised words after it,
/// if any), the commands that write it, the columns.
#[derive(Debug)]
struct DocTable {
    file: String,
    variant: String,
    commands: Vec<String>,
    columns: Vec<String>,
}

/// The backticked spans of a markdown cell, in order.
fn backticked(cell: &str) -> Vec<String> {
    cell.split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// Section 5's table, parsed: the rows between its header and the next heading.
fn doc_tables() -> Vec<DocTable> {
    let text = std::fs::read_to_string(root().join("docs/contracts.md")).unwrap();
    let start = text
        .find("\n## 5. Tables")
        .expect("docs/contracts.md has section 5, the tables");
    let section = &text[start + 1..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    let mut out = Vec::new();
    for line in section.lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = line.trim_matches('|').split(" | ").collect();
        assert_eq!(cells.len(), 3, "a row of three cells: {line}");
        let file = backticked(cells[0]).remove(0);
        let variant = cells[0]
            .split_once('(')
            .map_or("", |(_, v)| v.trim_end_matches(')').trim())
            .to_string();
        out.push(DocTable {
            file,
            variant,
            commands: backticked(cells[1]),
            columns: backticked(cells[2]),
        });
    }
    assert!(out.len() > 20, "section 5 parsed to {} rows", out.len());
    out
}

/// The subcommand of a "written by" entry (`fit --index` -> `fit`): a table is looked
/// up among the rows its subcommand writes, and the variant is the one whose columns
/// match.
fn first(command: &str) -> &str {
    command.split(' ').next().unwrap_or(command)
}

fn columns_of(path: &Path) -> Vec<String> {
    let f = std::fs::File::open(path).unwrap();
    let b = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(f)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    b.schema()
        .fields()
        .iter()
        .map(|f| f.name().clone())
        .collect()
}

/// Every Parquet file under `dir` (or `dir` itself when it is one), recursively.
fn parquet_files(dir: &Path) -> Vec<PathBuf> {
    if dir.is_file() {
        return vec![dir.to_path_buf()];
    }
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "parquet") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn every_written_table_has_the_columns_docs_contracts_lists() {
    let docs = doc_tables();
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name);
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let log = s(&fixture("multiaxis.csv"));
    let spec = d("white.toml");
    std::fs::write(
        &spec,
        "sample_rate_hz = 10.0\n[[channel]]\nname = \"gyro_x\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 0.01\n",
    )
    .unwrap();
    let job = d("job.toml");
    std::fs::write(
        &job,
        format!("output = \"unused\"\n[[inputs]]\npaths = [{log:?}]\n[[tasks]]\nkind = \"psd\"\n"),
    )
    .unwrap();
    // (the docs' command, the arguments, the output it writes)
    let runs: Vec<(&str, Vec<String>, PathBuf)> = vec![
        (
            "fit",
            vec![
                "fit".into(),
                log.clone(),
                "--channel".into(),
                "gyro_x".into(),
                "--order".into(),
                "1,0,1".into(),
                "-o".into(),
                s(&d("fit")),
                "--save-state".into(),
                "--residuals".into(),
            ],
            d("fit"),
        ),
        (
            "fit --index",
            vec![
                "fit".into(),
                log.clone(),
                "--channel".into(),
                "gyro_x".into(),
                "--order".into(),
                "1,0,1".into(),
                "--index".into(),
                "lag,temp_c".into(),
                "--index-grid".into(),
                "11,11".into(),
                "-o".into(),
                s(&d("fit2")),
            ],
            d("fit2"),
        ),
        (
            "update",
            vec![
                "update".into(),
                s(&d("fit")),
                log.clone(),
                "-o".into(),
                s(&d("upd")),
                "--residuals".into(),
                "--no-time-check".into(),
            ],
            d("upd"),
        ),
        (
            "analyze",
            vec![
                "analyze".into(),
                log.clone(),
                "--channel".into(),
                "gyro_x".into(),
                "-o".into(),
                s(&d("ana")),
            ],
            d("ana"),
        ),
        (
            "prep",
            vec!["prep".into(), log.clone(), "-o".into(), s(&d("prep"))],
            d("prep"),
        ),
        (
            "select",
            vec![
                "select".into(),
                log.clone(),
                "--channel".into(),
                "gyro_x".into(),
                "-o".into(),
                s(&d("sel")),
            ],
            d("sel"),
        ),
        (
            "check",
            vec![
                "check".into(),
                s(&d("fit")),
                log.clone(),
                "-o".into(),
                s(&d("chk")),
            ],
            d("chk"),
        ),
        (
            "adev -o DIR",
            vec!["adev".into(), log.clone(), "-o".into(), s(&d("adev"))],
            d("adev"),
        ),
        (
            "adev -o FILE.parquet",
            vec![
                "adev".into(),
                log.clone(),
                "-o".into(),
                s(&d("allan.parquet")),
            ],
            d("allan.parquet"),
        ),
        (
            "adev --terms-out FILE.parquet",
            vec![
                "adev".into(),
                log.clone(),
                "--terms-out".into(),
                s(&d("noise_terms.parquet")),
            ],
            d("noise_terms.parquet"),
        ),
        (
            "psd -o FILE.parquet",
            vec!["psd".into(), log.clone(), "-o".into(), s(&d("psd.parquet"))],
            d("psd.parquet"),
        ),
        (
            "acf -o FILE.parquet",
            vec!["acf".into(), log.clone(), "-o".into(), s(&d("acf.parquet"))],
            d("acf.parquet"),
        ),
        (
            "gap -o DIR",
            vec![
                "gap".into(),
                "--real".into(),
                log.clone(),
                "--sim".into(),
                s(&spec),
                "--channel".into(),
                "gyro_x".into(),
                "-o".into(),
                s(&d("gap")),
                "--replicas".into(),
                "5".into(),
            ],
            d("gap"),
        ),
        (
            "batch",
            vec!["batch".into(), s(&job), "-o".into(), s(&d("batch"))],
            d("batch"),
        ),
    ];
    let mut met = BTreeSet::new();
    for (command, args, out) in &runs {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = farma(&args, dir.path());
        assert!(o.status.success(), "{command}: {}", stderr(&o));
        let files = parquet_files(out);
        assert!(!files.is_empty(), "{command} wrote no table");
        for f in files {
            let name = f.file_name().unwrap().to_str().unwrap().to_string();
            // the batch's tables are the commands' own, under hive partitions; its
            // unit rows are the manifest's
            let name = match *command {
                "batch" if f.parent().unwrap().ends_with("_manifest") => {
                    "manifest.parquet".to_string()
                }
                "batch" if name == "part-0.parquet" => continue,
                _ => name,
            };
            let have = columns_of(&f);
            let rows: Vec<(usize, &DocTable)> = docs
                .iter()
                .enumerate()
                .filter(|(_, t)| {
                    t.file == name && t.commands.iter().any(|c| first(c) == first(command))
                })
                .collect();
            assert!(
                !rows.is_empty(),
                "{command} wrote {} ({name}), which docs/contracts.md section 5 does not list for `{command}`",
                f.display()
            );
            // where the docs have variants, the one whose columns match
            let hit = rows.iter().find(|(_, t)| t.columns == have);
            match hit {
                Some((i, _)) => {
                    met.insert(*i);
                }
                None => panic!(
                    "{command}: {} has the columns\n  {}\nbut docs/contracts.md section 5 lists for {name}:\n{}",
                    f.display(),
                    have.join(", "),
                    rows.iter()
                        .map(|(_, t)| format!("  ({}) {}", t.variant, t.columns.join(", ")))
                        .collect::<Vec<_>>()
                        .join("\n")
                ),
            }
        }
    }
    let stale: Vec<String> = docs
        .iter()
        .enumerate()
        .filter(|(i, _)| !met.contains(i))
        .map(|(_, t)| format!("{} ({})", t.file, t.variant))
        .collect();
    assert!(stale.is_empty(), "rows no command run wrote: {stale:?}");
}
