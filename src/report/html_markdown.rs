//! Markdown as HTML for the pages (`html_page`'s whole reports, and the sections of
//! calibrate's page that are report.md's own text): headings, paragraphs, lists, tables and
//! `code` spans, escaped.

use super::html_escape::escape;
use std::fmt::Write;

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

/// Text with markdown `code` spans as escaped `<code>`, the rest rendered by `plain`.
pub(super) fn inline_with(text: &str, plain: impl Fn(&str) -> String) -> String {
    let mut out = String::new();
    for (i, part) in text.split('`').enumerate() {
        if i % 2 == 1 {
            let _ = write!(out, "<code>{}</code>", escape(part));
        } else {
            out.push_str(&plain(part));
        }
    }
    out
}
