//! `report.html` for the commands whose report is a markdown page with plots (`verify`,
//! `compare`): the same self-contained style as calibrate's page ([`super::html`]), the
//! markdown's headings, paragraphs, lists and tables as HTML and the SVG plots inline. Nothing is
//! loaded from anywhere.

use super::html::{escape, inline_with, STYLE};
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

/// `markdown`'s headings, paragraphs, lists and tables as HTML, appended to `out` (also the
/// sections of calibrate's page that are report.md's text: the strata, the outputs as written).
pub(super) fn markdown_body(out: &mut String, markdown: &str) {
    let lines: Vec<&str> = markdown.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i].trim_end();
        if line.trim().is_empty() {
            i += 1;
        } else if let Some(level) = heading_level(line) {
            let text = line[level..].trim();
            let _ = writeln!(out, "<h{level}>{}</h{level}>", inline(text));
            i += 1;
        } else if line.starts_with('|') {
            let end = block_end(&lines, i, |l| l.starts_with('|'));
            table(out, &lines[i..end]);
            i = end;
        } else if is_item(line) {
            let end = block_end(&lines, i, is_item);
            out.push_str("<ul>\n");
            for item in &lines[i..end] {
                let _ = writeln!(out, "<li>{}</li>", inline(item.trim_start()[2..].trim()));
            }
            out.push_str("</ul>\n");
            i = end;
        } else {
            let end = block_end(&lines, i, |l| {
                !l.trim().is_empty()
                    && heading_level(l).is_none()
                    && !l.starts_with('|')
                    && !is_item(l)
            });
            let text: Vec<&str> = lines[i..end].iter().map(|l| l.trim()).collect();
            let _ = writeln!(out, "<p>{}</p>", inline(&text.join(" ")));
            i = end;
        }
    }
}

fn heading_level(line: &str) -> Option<usize> {
    let level = line.chars().take_while(|&c| c == '#').count();
    (1..=6)
        .contains(&level)
        .then_some(level)
        .filter(|&l| line[l..].starts_with(' '))
}

fn is_item(line: &str) -> bool {
    let trimmed = line.trim_start();
    trimmed.starts_with("- ") || trimmed.starts_with("* ")
}

/// The first line from `start` on that does not belong to the block.
fn block_end(lines: &[&str], start: usize, belongs: impl Fn(&str) -> bool) -> usize {
    (start + 1..lines.len())
        .find(|&j| !belongs(lines[j].trim_end()))
        .unwrap_or(lines.len())
}

/// A markdown table (header, separator, rows) as an HTML table.
fn table(out: &mut String, rows: &[&str]) {
    out.push_str("<table>\n");
    for (k, row) in rows.iter().enumerate() {
        let cells: Vec<&str> = row.trim().trim_matches('|').split('|').collect();
        if cells
            .iter()
            .all(|c| c.trim().chars().all(|ch| matches!(ch, '-' | ':' | ' ')))
        {
            continue;
        }
        let tag = if k == 0 { "th" } else { "td" };
        out.push_str("<tr>");
        for cell in cells {
            let _ = write!(out, "<{tag}>{}</{tag}>", inline(cell.trim()));
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</table>\n");
}

/// Escaped text with markdown `code` spans as `<code>` and `**bold**` as `<strong>`.
fn inline(text: &str) -> String {
    inline_with(text, |part| {
        let mut out = String::new();
        for (j, piece) in escape(part).split("**").enumerate() {
            if j % 2 == 1 {
                let _ = write!(out, "<strong>{piece}</strong>");
            } else {
                out.push_str(piece);
            }
        }
        out
    })
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
