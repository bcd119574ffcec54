//! The HTML pages: self-contained (the plots' SVG inline, one small inline style, no
//! script, nothing fetched), the verdict first and the detail below.

use std::fmt::Write as _;

/// Escapes text for HTML.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Marks the start and the end of a page's body, so that another page can take it in
/// ([`body_of`]).
pub const BODY_START: &str = "<!-- farma:body -->";
pub const BODY_END: &str = "<!-- /farma:body -->";

const STYLE: &str = "body{font-family:sans-serif;margin:1.5em auto;max-width:1180px;color:#222}\
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:1.6em}\
h3{font-size:1.05em}.verdict{background:#f4f7fb;border:1px solid #c9d6e8;padding:.6em 1em}\
.warn{color:#a33}table{border-collapse:collapse;margin:.5em 0}\
td,th{border:1px solid #ccc;padding:2px 7px;text-align:left;font-size:.92em}\
th{background:#f2f2f2}pre{background:#f8f8f8;padding:.5em;overflow-x:auto}\
.plot{display:inline-block;margin:4px;vertical-align:top}.note{color:#555;font-size:.92em}";

/// A page being built.
#[derive(Default)]
pub struct Page {
    body: String,
}

impl Page {
    /// A page whose first line is `h1`.
    pub fn new(h1: &str) -> Page {
        let mut p = Page::default();
        let _ = writeln!(p.body, "<h1>{}</h1>", esc(h1));
        p
    }

    /// Raw HTML (already escaped).
    pub fn raw(&mut self, html: &str) -> &mut Self {
        self.body.push_str(html);
        self.body.push('\n');
        self
    }

    pub fn h2(&mut self, t: &str) -> &mut Self {
        let _ = writeln!(self.body, "<h2>{}</h2>", esc(t));
        self
    }

    pub fn h3(&mut self, t: &str) -> &mut Self {
        let _ = writeln!(self.body, "<h3>{}</h3>", esc(t));
        self
    }

    /// A paragraph of text (escaped), of class `class` when not empty.
    pub fn p(&mut self, class: &str, t: &str) -> &mut Self {
        if class.is_empty() {
            let _ = writeln!(self.body, "<p>{}</p>", esc(t));
        } else {
            let _ = writeln!(self.body, "<p class=\"{class}\">{}</p>", esc(t));
        }
        self
    }

    /// The verdict box: one line per item (escaped); lines starting with `!` are
    /// warnings.
    pub fn verdict(&mut self, lines: &[String]) -> &mut Self {
        self.body
            .push_str("<div class=\"verdict\"><strong>Verdict</strong><ul>\n");
        for l in lines {
            match l.strip_prefix('!') {
                Some(w) => {
                    let _ = writeln!(self.body, "<li class=\"warn\">{}</li>", esc(w));
                }
                None => {
                    let _ = writeln!(self.body, "<li>{}</li>", esc(l));
                }
            }
        }
        self.body.push_str("</ul></div>\n");
        self
    }

    /// Preformatted text (escaped).
    pub fn pre(&mut self, t: &str) -> &mut Self {
        let _ = writeln!(self.body, "<pre>{}</pre>", esc(t));
        self
    }

    /// A table: a header row and rows of cells (escaped).
    pub fn table(&mut self, head: &[&str], rows: &[Vec<String>]) -> &mut Self {
        self.body.push_str("<table><tr>");
        for h in head {
            let _ = write!(self.body, "<th>{}</th>", esc(h));
        }
        self.body.push_str("</tr>\n");
        for r in rows {
            self.body.push_str("<tr>");
            for c in r {
                let _ = write!(self.body, "<td>{}</td>", esc(c));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
        self
    }

    /// A plot (an SVG from `super::svg`), inline.
    pub fn plot(&mut self, svg: &str) -> &mut Self {
        let svg = svg.trim_start();
        // an XML declaration cannot stand inside HTML
        let svg = match svg.strip_prefix("<?xml") {
            Some(rest) => rest.split_once("?>").map_or(svg, |(_, s)| s.trim_start()),
            None => svg,
        };
        let _ = writeln!(self.body, "<div class=\"plot\">{svg}</div>");
        self
    }

    /// The body as it stands (for another page to take in).
    pub fn body(&self) -> &str {
        &self.body
    }

    /// The whole page, titled `title`.
    pub fn finish(&self, title: &str) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{BODY_START}\n{}{BODY_END}\n<p class=\"note\">Written by farma {} (self-contained: no script, nothing fetched).</p>\n</body>\n</html>\n",
            esc(title),
            self.body,
            env!("CARGO_PKG_VERSION")
        )
    }
}

/// The body of a page written by [`Page::finish`] (None when it has no markers).
pub fn body_of(page: &str) -> Option<&str> {
    let a = page.find(BODY_START)? + BODY_START.len();
    let b = page[a..].find(BODY_END)? + a;
    Some(page[a..b].trim_matches('\n'))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_page_escapes_and_its_body_is_found_again() {
        let mut p = Page::new("a <b>");
        p.verdict(&["fine".into(), "!bad & worse".into()]);
        let html = p.finish("t");
        assert!(html.contains("a &lt;b&gt;"));
        assert!(html.contains("<li class=\"warn\">bad &amp; worse</li>"));
        assert_eq!(body_of(&html), Some(p.body().trim_matches('\n')));
    }
}
