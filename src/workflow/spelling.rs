//! The settings a report names, spelled as the front end that writes it spells them: the
//! library names a setting by its snake_case name in backticks (`` `model` offsets ``); the
//! command line passes its flags (`--model offsets`), and the reports it writes (report.md,
//! report.html) say those. The front end owns the table ([`Spelling`]); nothing here knows
//! a flag.

use crate::error::name_settings;

/// How a front end spells the library's settings: `spell(name)` gives its name of setting
/// `name` (`model` → `--model`), or `None` for a name that is not one of its settings.
pub type Spelling<'a> = &'a dyn Fn(&str) -> Option<String>;

/// Markdown `text` with the settings in its code spans spelled by `spell`
/// ([`name_settings`]).
pub(crate) fn spelled_markdown(text: &str, spell: Spelling<'_>) -> String {
    name_settings(text, spell)
}

/// HTML `text` with the settings in its `<code>` elements (a markdown code span on the page)
/// spelled by `spell`: `<code>model</code>` → `<code>--model</code>`.
pub(crate) fn spelled_html(text: &str, spell: Spelling<'_>) -> String {
    const OPEN: &str = "<code>";
    const CLOSE: &str = "</code>";
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(start) = rest.find(OPEN) {
        let (before, after) = rest.split_at(start + OPEN.len());
        out.push_str(before);
        rest = after;
        let Some(end) = rest.find(CLOSE) else { break };
        let name = &rest[..end];
        let setting = !name.is_empty()
            && name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
        if let Some(spelled) = spell(name).filter(|_| setting) {
            // Escaped as the page escapes text (a flag has no character that needs it).
            out.push_str(&crate::report::escape(&spelled));
            rest = &rest[end..];
        }
    }
    out.push_str(rest);
    out
}

/// report.md and report.html among `files` (an output folder's, by name) with their settings
/// spelled by `spell`: what a front end applies to `verify`'s and `compare`'s files before
/// writing them (`calibrate` does it itself, before provenance.yaml hashes its outputs).
pub fn spell_reports(files: &mut [(String, Vec<u8>)], spell: Spelling<'_>) {
    for (name, bytes) in files {
        let spelled = match (name.as_str(), std::str::from_utf8(bytes)) {
            ("report.md", Ok(text)) => spelled_markdown(text, spell),
            ("report.html", Ok(text)) => spelled_html(text, spell),
            _ => continue,
        };
        *bytes = spelled.into_bytes();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flag(setting: &str) -> Option<String> {
        ["model", "add_tool_links"]
            .contains(&setting)
            .then(|| format!("--{}", setting.replace('_', "-")))
    }

    #[test]
    fn settings_in_code_are_spelled_and_nothing_else() {
        assert_eq!(
            spelled_markdown("calibrate with `model` offsets; `report.md`, `x`", &flag),
            "calibrate with --model offsets; `report.md`, `x`"
        );
        assert_eq!(
            spelled_html(
                "<p><code>model</code> offsets, <code>add_tool_links</code>, <code>x</code>, <code>model.x</code>, <code></code><code>",
                &flag
            ),
            "<p><code>--model</code> offsets, <code>--add-tool-links</code>, <code>x</code>, <code>model.x</code>, <code></code><code>"
        );
    }
}
