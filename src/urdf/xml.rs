//! A minimal XML element scanner with byte spans, and the one structural check every command
//! applies to a URDF before anything else reads it.
//!
//! urdf-rs (through its XML parser) gives values but no positions, drops whatever it does
//! not model (`<transmission>`, `<gazebo>`, comments, attribute order) and silently ignores
//! whatever follows the first root element, so treecal scans the text itself: to check its
//! structure (one root, end tags that match, nothing after the root, bounded nesting), to hand
//! urdf-rs only the kinematic elements, and to edit the original text in place on export.
//! Comments, CDATA sections, processing instructions and declarations are skipped; attribute
//! values may use either quote and contain `>`.

use crate::error::{Error, Result};
use std::ops::Range;

/// One attribute of a start tag.
#[derive(Debug, Clone)]
pub(crate) struct Attribute {
    /// The attribute name as written.
    pub name: String,
    /// The value's bytes, inside the quotes.
    pub value: Range<usize>,
}

/// One element's start tag.
#[derive(Debug, Clone)]
pub(crate) struct Element {
    /// The tag name as written.
    pub name: String,
    /// Byte offset of the `<`.
    pub start: usize,
    /// Byte offset just past the end of the last attribute (or of the name): where a new
    /// attribute is inserted.
    pub attributes_end: usize,
    /// Byte offset just past the start tag's `>`.
    pub tag_end: usize,
    /// Whether the tag is `<name …/>`.
    pub self_closing: bool,
    /// The attributes in file order.
    pub attributes: Vec<Attribute>,
    /// The enclosing element, by index in the scan result.
    pub parent: Option<usize>,
    /// Byte offset just past the element's end (its end tag, or the `/>` of a self-closing
    /// tag).
    pub end: usize,
}

impl Element {
    /// The attribute called `name`, if any.
    pub fn attribute(&self, name: &str) -> Option<&Attribute> {
        self.attributes.iter().find(|a| a.name == name)
    }
}

/// `origin:line:column` of byte offset `at`.
pub(crate) fn position(text: &str, origin: &str, at: usize) -> String {
    let before = &text[..at.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map_or(0, |n| n + 1) + 1;
    format!("{origin}:{line}:{column}")
}

/// The 1-based line of byte offset `at`.
pub(crate) fn line_at(text: &str, at: usize) -> usize {
    text[..at.min(text.len())].matches('\n').count() + 1
}

/// The deepest element nesting accepted. Real URDFs nest about six deep; urdf-rs and its XML
/// parser recurse once per level and overflow the stack (an abort, not an error) a few
/// thousand levels down.
pub(crate) const MAX_NESTING: usize = 256;

/// Every element of `text` in document order, after checking the document's structure: one
/// `<robot>` root element, every end tag matching its start tag, nothing but comments and
/// processing instructions after the root, at most [`MAX_NESTING`] levels. Errors name
/// `origin:line`.
///
/// This is the one structural check: loading (`inspect`, `calibrate`, …) and `export` both
/// go through it, so a file one command accepts is never refused by another for its shape.
pub(crate) fn scan(text: &str, origin: &str) -> Result<Vec<Element>> {
    let fail = |at: usize, message: String| Error::UrdfParse {
        origin: format!("{origin}:{}", line_at(text, at)),
        message,
    };
    let mut elements: Vec<Element> = Vec::new();
    let mut open: Vec<usize> = Vec::new();
    // Where the root element was closed, once it has been.
    let mut root_closed: Option<usize> = None;
    let mut from = 0;
    loop {
        let next = text[from..]
            .find('<')
            .map_or(text.len(), |found| from + found);
        if open.is_empty() {
            outside_root(text, from, next, root_closed, &fail)?;
        }
        if next == text.len() {
            break;
        }
        let at = next;
        let rest = &text[at..];
        let past = |end: &str, what: &str| {
            rest.find(end)
                .map(|e| at + e + end.len())
                .ok_or_else(|| fail(at, format!("unterminated {what}")))
        };
        if rest.starts_with("<!--") {
            from = past("-->", "comment")?;
        } else if rest.starts_with("<![CDATA[") {
            from = past("]]>", "CDATA section")?;
        } else if rest.starts_with("<?") {
            from = past("?>", "processing instruction")?;
        } else if rest.starts_with("<!") {
            // A declaration; an internal DTD subset ends with "]>".
            let bracket = rest.find('[');
            let close = rest.find('>');
            from = match (bracket, close) {
                (Some(b), Some(c)) if b < c => past("]>", "declaration")?,
                _ => past(">", "declaration")?,
            };
        } else if let Some(tag) = rest.strip_prefix("</") {
            from = past(">", "end tag")?;
            let name = tag[..from - at - 3].trim_end();
            let Some(index) = open.pop() else {
                return Err(fail(
                    at,
                    format!("end tag </{name}> has no matching start tag"),
                ));
            };
            let element = &mut elements[index];
            if element.name != name {
                return Err(fail(
                    at,
                    format!(
                        "end tag </{name}> closes <{}>, opened at line {}; check the elements between them",
                        element.name,
                        line_at(text, element.start)
                    ),
                ));
            }
            element.end = from;
            if open.is_empty() {
                root_closed = Some(at);
            }
        } else {
            if let Some(closed) = root_closed {
                return Err(after_root(text, at, closed, &fail));
            }
            let element = start_tag(text, at, open.last().copied())
                .ok_or_else(|| fail(at, "malformed start tag".into()))?;
            from = element.tag_end;
            if element.self_closing {
                root_closed = root_closed.or(open.is_empty().then_some(at));
            } else {
                open.push(elements.len());
                if open.len() > MAX_NESTING {
                    return Err(fail(
                        at,
                        format!("elements are nested more than {MAX_NESTING} levels deep; a URDF needs only a few levels"),
                    ));
                }
            }
            elements.push(element);
        }
    }
    if let Some(&index) = open.last() {
        let element = &elements[index];
        return Err(fail(
            element.start,
            format!("element <{}> is never closed", element.name),
        ));
    }
    match elements.first() {
        None => Err(Error::UrdfParse {
            origin: origin.to_owned(),
            message: "no XML element found; a URDF is a <robot> element".into(),
        }),
        Some(root) if root.name != "robot" => Err(fail(
            root.start,
            format!(
                "the root element is <{}>; a URDF's root element is <robot>",
                root.name
            ),
        )),
        Some(_) => Ok(elements),
    }
}

/// Checks the text between elements outside the root (`from..to`): only white space.
fn outside_root(
    text: &str,
    from: usize,
    to: usize,
    root_closed: Option<usize>,
    fail: &impl Fn(usize, String) -> Error,
) -> Result<()> {
    let between = &text[from..to];
    let Some(offset) = between.find(|c: char| !c.is_whitespace() && c != '\u{feff}') else {
        return Ok(());
    };
    let at = from + offset;
    Err(match root_closed {
        Some(closed) => after_root(text, at, closed, fail),
        None => fail(
            at,
            "text before the root element; a URDF starts with <?xml …?> or <robot>".into(),
        ),
    })
}

/// The error for content at `at` after the root element ended at `closed`.
fn after_root(
    text: &str,
    at: usize,
    closed: usize,
    fail: &impl Fn(usize, String) -> Error,
) -> Error {
    let snippet: String = text[at..]
        .chars()
        .take_while(|c| *c != '\n')
        .take(40)
        .collect();
    fail(
        at,
        format!(
            "content after the root element, which ended at line {}: '{}'; a URDF has exactly one root element (a stray end tag there would silently drop everything after it)",
            line_at(text, closed),
            snippet.trim_end()
        ),
    )
}

fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | b'\n')
}

/// Parses the start tag at `at` (the `<`); `None` if it is malformed.
fn start_tag(text: &str, at: usize, parent: Option<usize>) -> Option<Element> {
    let bytes = text.as_bytes();
    let name_end = (at + 1..bytes.len())
        .find(|&k| is_space(bytes[k]) || bytes[k] == b'/' || bytes[k] == b'>')?;
    if name_end == at + 1 {
        return None;
    }
    let mut element = Element {
        name: text[at + 1..name_end].to_owned(),
        start: at,
        attributes_end: name_end,
        tag_end: 0,
        self_closing: false,
        attributes: Vec::new(),
        parent,
        end: 0,
    };
    let mut k = name_end;
    loop {
        while k < bytes.len() && is_space(bytes[k]) {
            k += 1;
        }
        match bytes.get(k)? {
            b'>' => {
                element.tag_end = k + 1;
                return Some(element);
            }
            b'/' => {
                if bytes.get(k + 1) != Some(&b'>') {
                    return None;
                }
                element.self_closing = true;
                element.tag_end = k + 2;
                element.end = k + 2;
                return Some(element);
            }
            _ => {
                let name_start = k;
                while k < bytes.len() && !is_space(bytes[k]) && !matches!(bytes[k], b'=' | b'>') {
                    k += 1;
                }
                let name = text[name_start..k].to_owned();
                while k < bytes.len() && is_space(bytes[k]) {
                    k += 1;
                }
                if bytes.get(k) != Some(&b'=') {
                    return None;
                }
                k += 1;
                while k < bytes.len() && is_space(bytes[k]) {
                    k += 1;
                }
                let quote = *bytes.get(k)?;
                if quote != b'"' && quote != b'\'' {
                    return None;
                }
                let value_start = k + 1;
                let value_end = value_start + text[value_start..].find(quote as char)?;
                element.attributes.push(Attribute {
                    name,
                    value: value_start..value_end,
                });
                k = value_end + 1;
                element.attributes_end = k;
            }
        }
    }
}

/// An attribute value with the five predefined entities and character references replaced.
pub(crate) fn unescape(raw: &str) -> String {
    let mut out = String::with_capacity(raw.len());
    let mut rest = raw;
    while let Some(amp) = rest.find('&') {
        out.push_str(&rest[..amp]);
        let after = &rest[amp..];
        let Some(semi) = after.find(';') else {
            out.push_str(after);
            return out;
        };
        let entity = &after[1..semi];
        let decoded = match entity {
            "lt" => Some('<'),
            "gt" => Some('>'),
            "amp" => Some('&'),
            "quot" => Some('"'),
            "apos" => Some('\''),
            _ => entity
                .strip_prefix("#x")
                .map(|h| u32::from_str_radix(h, 16))
                .or_else(|| entity.strip_prefix('#').map(str::parse::<u32>))
                .and_then(|n| n.ok())
                .and_then(char::from_u32),
        };
        match decoded {
            Some(c) => {
                out.push(c);
                rest = &after[semi + 1..];
            }
            None => {
                out.push('&');
                rest = &after[1..];
            }
        }
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_spans_past_comments_cdata_and_quotes() {
        let text = "<?xml version='1.0'?>\n<!-- <joint name=\"no\"> -->\n<robot name='r'>\
                    <![CDATA[<joint>]]><joint type=\"fixed\" name='a&amp;b' x=\"1>2\">\
                    <origin rpy = '0 0 0'/></joint></robot>";
        let elements = scan(text, "t").unwrap();
        let names: Vec<&str> = elements.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["robot", "joint", "origin"]);
        let joint = &elements[1];
        assert_eq!(joint.parent, Some(0));
        let name = joint.attribute("name").unwrap();
        assert_eq!(unescape(&text[name.value.clone()]), "a&b");
        assert_eq!(&text[joint.attribute("x").unwrap().value.clone()], "1>2");
        let origin = &elements[2];
        assert!(origin.self_closing);
        assert_eq!(origin.parent, Some(1));
        assert_eq!(
            &text[origin.attribute("rpy").unwrap().value.clone()],
            "0 0 0"
        );
        assert_eq!(&text[origin.attributes_end..origin.tag_end], "/>");
    }

    #[test]
    fn reports_where_a_tag_is_unterminated() {
        let error = scan("<robot>\n  <!-- open", "f.urdf").unwrap_err();
        assert!(error.to_string().contains("f.urdf:2:"), "{error}");
    }
}
