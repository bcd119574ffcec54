//! `ROOT/index.html`: one self-contained page over a batch's units (the report page's
//! style, [`crate::report::html`]; no script, nothing fetched): per log and task its
//! status, the error of a failed unit or the reason of a skipped one, a link to the
//! unit's `report.html` where its task writes one (relative to the root, so the folder
//! can be moved or served as it is) and that report's verdict, taken from the page.
//! Rewritten from the manifest rows at the end of every run (of every shard), so it
//! lists every unit that has a row, whichever shard ran it; it holds no times, so an
//! unchanged dataset gives the same bytes.

use std::path::Path;

use super::manifest::{self, Row};
use crate::error::Result;
use crate::report::html::{Page, esc};

/// The file name at the root.
pub const INDEX: &str = "index.html";

/// The verdict box of a page written by [`Page::verdict`]: its `<ul>` as written (the
/// page's own escaped HTML), None when the page has none.
pub fn verdict_of(page: &str) -> Option<&str> {
    let a = page.find("<div class=\"verdict\">")?;
    let ul = page[a..].find("<ul>")? + a;
    let end = page[ul..].find("</ul>")? + ul + "</ul>".len();
    Some(&page[ul..end])
}

/// The page over `rows` (by log, then task); `report_of` reads a unit's report page
/// given its path relative to the root (None when it cannot be read).
pub fn page(rows: &[Row], report_of: &dyn Fn(&str) -> Option<String>) -> String {
    let mut rows: Vec<&Row> = rows.iter().collect();
    rows.sort_by(|a, b| (&a.log_id, &a.task).cmp(&(&b.log_id, &b.task)));
    let count = |s: &str| rows.iter().filter(|r| r.status == s).count();
    let mut p = Page::new("farma batch");
    p.verdict(&[format!(
        "{} units: {} done, {} failed, {} skipped",
        rows.len(),
        count(manifest::DONE),
        count(manifest::FAILED),
        count(manifest::SKIPPED)
    )]);
    p.h2("Units");
    let mut html = String::from(
        "<table><tr><th>log</th><th>task</th><th>status</th><th>report</th><th>verdict, or why not done</th></tr>\n",
    );
    for r in &rows {
        let report = r
            .files
            .split(';')
            .find(|f| f.ends_with(crate::report::REPORT));
        let link = report.map_or(String::from("-"), |f| {
            format!("<a href=\"{}\">report.html</a>", esc(f))
        });
        let detail = if r.status == manifest::DONE {
            report
                .and_then(report_of)
                .and_then(|page| verdict_of(&page).map(str::to_string))
                .unwrap_or_default()
        } else {
            format!("<span class=\"warn\">{}</span>", esc(&r.error))
        };
        let status = if r.status == manifest::DONE {
            esc(&r.status)
        } else {
            format!("<span class=\"warn\">{}</span>", esc(&r.status))
        };
        html.push_str(&format!(
            "<tr><td title=\"{}\">{}</td><td>{} ({})</td><td>{status}</td><td>{link}</td><td>{detail}</td></tr>\n",
            esc(&r.log_path),
            esc(&r.log_id),
            esc(&r.task),
            esc(&r.kind)
        ));
    }
    html.push_str("</table>");
    p.raw(&html);
    p.p(
        "note",
        "The tables of every unit are in the dataset under this folder (ROOT/<table>/task=<task>/log_id=<id>/part-0.parquet); manifest.parquet has each unit's row.",
    );
    p.finish("farma batch")
}

/// Rewrites `ROOT/index.html` from the manifest rows under `root` (atomically).
pub fn write(root: &Path) -> Result<()> {
    let rows = manifest::read_rows(root)?;
    let html = page(&rows, &|rel| std::fs::read_to_string(root.join(rel)).ok());
    crate::output::write_text(&root.join(INDEX), &html)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(log: &str, task: &str, status: &str, files: &str, error: &str) -> Row {
        Row {
            unit: format!("{log}.{task}"),
            log_id: log.into(),
            log_path: format!("/logs/{log}.csv"),
            task: task.into(),
            kind: task.into(),
            log_size: 1,
            log_mtime_ns: 0,
            log_hash: String::new(),
            options_hash: String::new(),
            status: status.into(),
            error: error.into(),
            started_unix_s: 0.0,
            finished_unix_s: 0.0,
            farma_version: String::new(),
            farma_commit: String::new(),
            files: files.into(),
        }
    }

    #[test]
    fn the_index_links_each_report_with_its_verdict_and_names_failures() {
        let mut report = Page::new("r");
        report.verdict(&["white noise n = 1 <u>".into(), "!poor fit".into()]);
        let report = report.finish("r");
        let rows = [
            row(
                "b",
                "adev",
                manifest::DONE,
                "allan/task=adev/log_id=b/part-0.parquet;_files/task=adev/log_id=b/report.html",
                "",
            ),
            row("a", "adev", manifest::FAILED, "", "a.csv: no <time> column"),
            row(
                "c",
                "fit",
                manifest::DONE,
                "coef/task=fit/log_id=c/part-0.parquet",
                "",
            ),
        ];
        let html = page(&rows, &|rel| {
            (rel == "_files/task=adev/log_id=b/report.html").then(|| report.clone())
        });
        assert!(
            html.contains("3 units: 2 done, 1 failed, 0 skipped"),
            "{html}"
        );
        assert!(html.contains("<a href=\"_files/task=adev/log_id=b/report.html\">"));
        // the report's verdict, as the report escaped it, warnings kept
        assert!(html.contains("white noise n = 1 &lt;u&gt;"), "{html}");
        assert!(html.contains("<li class=\"warn\">poor fit</li>"));
        // the failure with its error, escaped; logs in order
        assert!(html.contains("a.csv: no &lt;time&gt; column"));
        let (a, b) = (html.find(">a</td>").unwrap(), html.find(">b</td>").unwrap());
        assert!(a < b);
        // a unit without a report has no link
        let c = html.find(">c</td>").unwrap();
        assert!(
            html[c..]
                .split("</tr>")
                .next()
                .unwrap()
                .contains("<td>-</td>")
        );
        // self-contained
        assert!(!html.contains("<script") && !html.contains("http"));
    }
}
