//! The HTML reports of `analyze`, `adev` and `gap` (src/report/): each command writes
//! `report.html` beside its tables; the page is self-contained (no script, nothing
//! fetched: no http(s) src/href), holds its plots as inline SVG, each plot's SVG is
//! well-formed XML and carries axis titles with units (`[s]`, `[deg/s]`, ...).
//! (`farma gap`'s report is checked by the gap CLI test, `gap::`, with [`check_report`].)

use std::path::Path;

use crate::common::{farma, fixture, stderr};

/// A tiny XML well-formedness check of one SVG: tags balanced and properly nested,
/// attributes quoted, no stray `<` or `&` in text. Returns the texts of the `<text>`
/// elements with whether each is rotated (a y-axis title).
fn parse_svg(svg: &str) -> Result<Vec<(String, bool)>, String> {
    let mut stack: Vec<String> = Vec::new();
    let mut texts = Vec::new();
    let mut rest = svg;
    let mut current_text: Option<(String, bool)> = None;
    while let Some(lt) = rest.find('<') {
        let text = &rest[..lt];
        check_text(text)?;
        if let Some(t) = current_text.as_mut() {
            t.0.push_str(text);
        }
        rest = &rest[lt..];
        if rest.starts_with("<!--") {
            let end = rest.find("-->").ok_or("an unclosed comment")?;
            rest = &rest[end + 3..];
            continue;
        }
        let gt = tag_end(rest).ok_or("an unclosed tag")?;
        let tag = &rest[1..gt];
        rest = &rest[gt + 1..];
        if let Some(name) = tag.strip_prefix('/') {
            let name = name.trim();
            let open = stack.pop().ok_or(format!("</{name}> closes nothing"))?;
            if open != name {
                return Err(format!("<{open}> closed by </{name}>"));
            }
            if name == "text"
                && let Some(t) = current_text.take()
            {
                texts.push(t);
            }
            continue;
        }
        if tag.starts_with('?') || tag.starts_with('!') {
            continue;
        }
        let self_closing = tag.ends_with('/');
        let body = tag.trim_end_matches('/');
        let name: String = body.chars().take_while(|c| !c.is_whitespace()).collect();
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == ':' || c == '-')
        {
            return Err(format!("a bad tag name in <{tag}>"));
        }
        check_attributes(&body[name.len()..])?;
        if !self_closing {
            if name == "text" {
                current_text = Some((String::new(), body.contains("rotate(")));
            }
            stack.push(name);
        }
    }
    check_text(rest)?;
    if let Some(open) = stack.pop() {
        return Err(format!("<{open}> never closed"));
    }
    Ok(texts)
}

/// The index of the `>` that ends the tag starting `s` (quotes skipped).
fn tag_end(s: &str) -> Option<usize> {
    let mut quote: Option<char> = None;
    for (i, c) in s.char_indices().skip(1) {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (None, '>') => return Some(i),
            (None, '<') => return None,
            _ => {}
        }
    }
    None
}

fn check_attributes(attrs: &str) -> Result<(), String> {
    let mut s = attrs.trim();
    while !s.is_empty() {
        let eq = s
            .find('=')
            .ok_or(format!("an attribute without a value: {s}"))?;
        let name = s[..eq].trim();
        if name.is_empty() || name.contains(char::is_whitespace) {
            return Err(format!("a bad attribute name '{name}'"));
        }
        let v = s[eq + 1..].trim_start();
        let q = v.chars().next().ok_or("an attribute without a value")?;
        if q != '"' && q != '\'' {
            return Err(format!("attribute {name} not quoted"));
        }
        let end = v[1..]
            .find(q)
            .ok_or(format!("attribute {name} not closed"))?;
        check_text(&v[1..1 + end])?;
        s = v[end + 2..].trim_start();
    }
    Ok(())
}

/// Text holds no `<` and every `&` starts an entity.
fn check_text(t: &str) -> Result<(), String> {
    if t.contains('<') {
        return Err("a '<' in text".into());
    }
    for (i, _) in t.match_indices('&') {
        let ent = &t[i + 1..];
        let semi = ent.find(';').ok_or("an '&' that starts no entity")?;
        let name = &ent[..semi];
        let ok = ["amp", "lt", "gt", "quot", "apos"].contains(&name)
            || name.strip_prefix('#').is_some_and(|n| {
                n.strip_prefix('x').map_or_else(
                    || n.chars().all(|c| c.is_ascii_digit()),
                    |h| h.chars().all(|c| c.is_ascii_hexdigit()),
                )
            });
        if !ok || name.is_empty() {
            return Err(format!("an unknown entity &{name};"));
        }
    }
    Ok(())
}

/// The inline SVGs of a page.
fn svgs(html: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = html;
    while let Some(a) = rest.find("<svg") {
        let Some(b) = rest[a..].find("</svg>") else {
            panic!("an <svg> without its </svg>");
        };
        out.push(&rest[a..a + b + "</svg>".len()]);
        rest = &rest[a + b..];
    }
    out
}

/// Whether `t` names a unit in brackets: `... [unit]` with something inside.
fn has_unit(t: &str) -> bool {
    t.rfind('[')
        .and_then(|a| t[a..].find(']').map(|b| b > 1))
        .unwrap_or(false)
}

/// Checks the `report.html` at `path`: self-contained, with at least `min_plots`
/// plots, each well-formed with an x-axis and a (rotated) y-axis title with a unit;
/// the verdict before the first plot. Returns the page.
pub fn check_report(path: &Path, min_plots: usize) -> String {
    let html = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(
        html.starts_with("<!DOCTYPE html>"),
        "{}",
        &html[..80.min(html.len())]
    );
    let lower = html.to_ascii_lowercase();
    for bad in [
        "src=\"http",
        "src='http",
        "href=\"http",
        "href='http",
        "<script",
        "<link",
        "@import",
        "url(http",
    ] {
        assert!(
            !lower.contains(bad),
            "{}: not self-contained: {bad}",
            path.display()
        );
    }
    let verdict = html.find("class=\"verdict\"").expect("a verdict");
    let first = html.find("<svg").expect("an inline <svg>");
    assert!(verdict < first, "the verdict comes first");
    let plots = svgs(&html);
    assert!(
        plots.len() >= min_plots,
        "{}: {} plots, expected at least {min_plots}",
        path.display(),
        plots.len()
    );
    for (k, svg) in plots.iter().enumerate() {
        let texts = parse_svg(svg)
            .unwrap_or_else(|e| panic!("{}: plot {k} is not well-formed XML: {e}", path.display()));
        assert!(
            texts.iter().any(|(t, rot)| !rot && has_unit(t)),
            "{}: plot {k} has no x-axis title with a unit: {texts:?}",
            path.display()
        );
        assert!(
            texts.iter().any(|(t, rot)| *rot && has_unit(t)),
            "{}: plot {k} has no y-axis title with a unit: {texts:?}",
            path.display()
        );
    }
    html
}

#[test]
fn the_svg_check_finds_broken_svg() {
    let good = r#"<svg a="1"><text x="1">tau [s]</text><text transform="rotate(270, 1, 1)">dev [deg/s]</text><rect/></svg>"#;
    let t = parse_svg(good).unwrap();
    assert_eq!(
        t,
        vec![("tau [s]".into(), false), ("dev [deg/s]".into(), true)]
    );
    for bad in [
        "<svg><g></svg>",
        "<svg><text>a</g></svg>",
        "<svg a=1></svg>",
        "<svg><text>a & b</text></svg>",
        "<svg><text>a < b</text></svg>",
        "<svg",
    ] {
        assert!(parse_svg(bad).is_err(), "{bad}");
    }
    assert!(!has_unit("tau"));
    assert!(!has_unit("tau []"));
    assert!(has_unit("tau [s]"));
}

#[test]
fn analyze_writes_a_self_contained_report_with_every_plot() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a");
    let o = farma(
        &[
            "analyze",
            fixture("multiaxis.csv").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        &dir.path().join("cache"),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // three gyro axes: per axis f_1..f_p (p >= 1), two order plots, the prediction and
    // the RMSE per horizon, the residual ACF and histogram
    let html = check_report(&out.join("report.html"), 3 * 7);
    for axis in ["gyro_x", "gyro_y", "gyro_z"] {
        assert!(html.contains(&format!("channel {axis}")), "{axis} missing");
    }
    for title in [
        "AICc per order",
        "RSS per order",
        "residual ACF",
        "histogram of the residuals",
        "one step ahead",
        "hold-out RMSE per horizon",
        ": f_1",
    ] {
        assert!(html.contains(title), "no plot '{title}'");
    }
    // each channel folder has its own page
    let ch = out.join("channels").join("gyro_x").join("report.html");
    check_report(&ch, 7);
    // the stdout is the results alone: no HTML there
    assert!(!crate::common::stdout(&o).contains("<svg"));
}

#[test]
fn adev_writes_its_folder_and_report_when_o_is_a_folder() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let log = fixture("multiaxis.csv");
    let out = dir.path().join("adev_out");
    let o = farma(
        &[
            "adev",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x,gyro_y",
            "--kind",
            "all",
            "-o",
            out.to_str().unwrap(),
        ],
        &cache,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["allan.parquet", "noise_terms.parquet", "report.html"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    // per channel the Allan plot and the PSD
    let html = check_report(&out.join("report.html"), 4);
    for t in [
        "Allan deviation",
        "modified Allan deviation",
        "Hadamard deviation",
        "sum of the noise terms",
        "power spectral density",
        "averaging time tau [s]",
        "frequency f [Hz]",
    ] {
        assert!(html.contains(t), "no '{t}' in the adev report");
    }
    // `-o OUT.parquet` stays the table alone
    let pq = dir.path().join("t.parquet");
    let o = farma(
        &[
            "adev",
            log.to_str().unwrap(),
            "--channel",
            "gyro_x",
            "-o",
            pq.to_str().unwrap(),
        ],
        &cache,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(pq.is_file());
    assert!(!dir.path().join("report.html").exists());
}
