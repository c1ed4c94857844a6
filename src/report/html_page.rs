//! `report.html` for the commands whose report is a markdown page with plots (`verify`,
//! `compare`): the same self-contained style as calibrate's page ([`super::html`]), the
//! markdown's headings, paragraphs, lists and tables as HTML and the SVG plots inline. Nothing is
//! loaded from anywhere.

use super::html::{escape, STYLE};
use super::html_markdown::markdown_body;
use std::fmt::Write;

/// The page titled `title` holding `markdown` (the report.md text) and then `plots` (SVG
/// documents, inline).
pub fn markdown_page(title: &str, markdown: &str, plots: &[&str]) -> String {
    let mut out = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>\n{STYLE}</style>\n</head>\n<body>\n",
        escape(title)
    );
    markdown_body(&mut out, markdown);
    for plot in plots {
        let _ = writeln!(out, "<figure>{}</figure>", strip_xml_declaration(plot));
    }
    out.push_str("<p>Written by treecal; the same figures are in report.md and report.json.</p>\n</body>\n</html>\n");
    out
}

fn strip_xml_declaration(svg: &str) -> &str {
    match svg.find("<svg") {
        Some(start) => &svg[start..],
        None => svg,
    }
}

#[cfg(test)]
mod tests {
    use super::markdown_page;

    #[test]
    fn headings_tables_lists_and_plots_become_html() {
        let page = markdown_page(
            "Verify <robot>",
            "# Verify\n\nVerdict: **failed** (`3.3 mm`)\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\n- one\n- two\n",
            &["<?xml version=\"1.0\"?><svg></svg>"],
        );
        assert!(page.contains("<title>Verify &lt;robot&gt;</title>"));
        assert!(page.contains("<h1>Verify</h1>"));
        assert!(page.contains("<p>Verdict: <strong>failed</strong> (<code>3.3 mm</code>)</p>"));
        assert!(page.contains("<tr><th>a</th><th>b</th></tr>\n<tr><td>1</td><td>2</td></tr>"));
        assert!(page.contains("<li>one</li>\n<li>two</li>"));
        assert!(page.contains("<figure><svg></svg></figure>"));
        assert!(!page.contains("<?xml"));
        assert!(!page.contains("http"), "no outside reference");
    }
}
