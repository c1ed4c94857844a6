//! JSON for reports with many rows: pretty-printed near the top, one line per row below.
//!
//! `serde_json`'s pretty printer puts every number of a 10⁵-row report on a line of its own
//! (report.json of a 10⁵-configuration calibration: 124 MB). Here containers opened at nesting
//! depth ≤ [`PRETTY_DEPTH`] are indented as usual and anything deeper is written on one line
//! (`"position_mm": {"before": 1.2, "after": 0.01}`, a posture's joint values), so a report
//! row is a few lines: half the bytes, and still readable and diffable. The text is rendered twice, to
//! count and then into a buffer of exactly that size (no doubling of a 60 MB string).

use crate::error::{Error, Result};
use serde_json::ser::Formatter;
use std::io::Write;

/// Containers opened at this depth or less are indented (1: the top-level object).
pub const PRETTY_DEPTH: usize = 5;

/// Serialises `value` as JSON indented to `PRETTY_DEPTH` (5), one line per deeper container,
/// with a final newline.
pub fn to_json_rows<T: serde::Serialize>(value: &T) -> Result<String> {
    let mut counter = Counter(0);
    render(value, &mut counter)?;
    let mut bytes = Vec::with_capacity(counter.0 + 1);
    render(value, &mut bytes)?;
    bytes.push(b'\n');
    String::from_utf8(bytes).map_err(|e| invalid(e.to_string()))
}

/// As [`to_json_rows`], written to `out` as it is rendered (the same bytes, never held whole).
pub fn write_json_rows<T: serde::Serialize>(value: &T, out: &mut dyn Write) -> Result<()> {
    render(value, out)?;
    out.write_all(b"\n").map_err(|e| invalid(e.to_string()))
}

/// `value` as [`to_json_rows`] lays it out where it opens inside `depth` containers (the
/// top-level object is depth 1): the text of an element of an array at that depth, without
/// the separator before it (its array writes that).
pub fn json_at_depth<T: serde::Serialize>(value: &T, depth: usize) -> Result<String> {
    let mut bytes = Vec::new();
    let formatter = Shallow {
        depth,
        has_value: false,
    };
    let mut serializer = serde_json::Serializer::with_formatter(&mut bytes, formatter);
    value
        .serialize(&mut serializer)
        .map_err(|e| invalid(e.to_string()))?;
    String::from_utf8(bytes).map_err(|e| invalid(e.to_string()))
}

/// Text that is one JSON value already (rendered by [`json_at_depth`]), written by
/// serde_json's serialisers as it is. serde_json's own `RawValue::from_string` parses the text
/// again to check it: about a second of CPU for report.json's 2·10⁶ rows at 10⁶
/// configurations. Serialised as `RawValue` serialises itself (a struct under serde_json's
/// raw-value name, whose one field is the text), which its serialisers write verbatim; any
/// other serialiser sees a struct with one string field.
pub struct Verbatim<'a>(pub &'a str);

/// serde_json's name for a raw value (`serde_json::raw::TOKEN`, with its `raw_value`
/// feature): the test `verbatim_text_is_written_as_it_is` fails if it ever changes.
const RAW_VALUE_TOKEN: &str = "$serde_json::private::RawValue";

impl serde::Serialize for Verbatim<'_> {
    fn serialize<S: serde::Serializer>(
        &self,
        serializer: S,
    ) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut raw = serializer.serialize_struct(RAW_VALUE_TOKEN, 1)?;
        raw.serialize_field(RAW_VALUE_TOKEN, self.0)?;
        raw.end()
    }
}

fn render<T: serde::Serialize, W: Write + ?Sized>(value: &T, out: &mut W) -> Result<()> {
    let mut serializer = serde_json::Serializer::with_formatter(out, Shallow::default());
    value
        .serialize(&mut serializer)
        .map_err(|e| invalid(e.to_string()))
}

fn invalid(message: String) -> Error {
    Error::InvalidData {
        origin: "JSON output".into(),
        message,
    }
}

/// A writer that only counts.
struct Counter(usize);

impl Write for Counter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0 += buf.len();
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The formatter: `serde_json`'s `PrettyFormatter` (two spaces) to [`PRETTY_DEPTH`], then
/// `", "` and `": "` on one line.
#[derive(Default)]
struct Shallow {
    depth: usize,
    has_value: bool,
}

impl Shallow {
    fn pretty(&self) -> bool {
        self.depth <= PRETTY_DEPTH
    }

    fn separate<W: ?Sized + Write>(&self, writer: &mut W, first: bool) -> std::io::Result<()> {
        if self.pretty() {
            writer.write_all(if first { b"\n" } else { b",\n" })?;
            indent(writer, self.depth)
        } else if first {
            Ok(())
        } else {
            writer.write_all(b", ")
        }
    }

    fn close<W: ?Sized + Write>(&mut self, writer: &mut W, bracket: &[u8]) -> std::io::Result<()> {
        let was_pretty = self.pretty();
        self.depth -= 1;
        if was_pretty && self.has_value {
            writer.write_all(b"\n")?;
            indent(writer, self.depth)?;
        }
        writer.write_all(bracket)
    }
}

fn indent<W: ?Sized + Write>(writer: &mut W, depth: usize) -> std::io::Result<()> {
    for _ in 0..depth {
        writer.write_all(b"  ")?;
    }
    Ok(())
}

impl Formatter for Shallow {
    fn begin_array<W: ?Sized + Write>(&mut self, writer: &mut W) -> std::io::Result<()> {
        self.depth += 1;
        self.has_value = false;
        writer.write_all(b"[")
    }

    fn end_array<W: ?Sized + Write>(&mut self, writer: &mut W) -> std::io::Result<()> {
        self.close(writer, b"]")
    }

    fn begin_array_value<W: ?Sized + Write>(
        &mut self,
        writer: &mut W,
        first: bool,
    ) -> std::io::Result<()> {
        self.separate(writer, first)
    }

    fn end_array_value<W: ?Sized + Write>(&mut self, _writer: &mut W) -> std::io::Result<()> {
        self.has_value = true;
        Ok(())
    }

    fn begin_object<W: ?Sized + Write>(&mut self, writer: &mut W) -> std::io::Result<()> {
        self.depth += 1;
        self.has_value = false;
        writer.write_all(b"{")
    }

    fn end_object<W: ?Sized + Write>(&mut self, writer: &mut W) -> std::io::Result<()> {
        self.close(writer, b"}")
    }

    fn begin_object_key<W: ?Sized + Write>(
        &mut self,
        writer: &mut W,
        first: bool,
    ) -> std::io::Result<()> {
        self.separate(writer, first)
    }

    fn begin_object_value<W: ?Sized + Write>(&mut self, writer: &mut W) -> std::io::Result<()> {
        writer.write_all(b": ")
    }

    fn end_object_value<W: ?Sized + Write>(&mut self, _writer: &mut W) -> std::io::Result<()> {
        self.has_value = true;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A [`Verbatim`] text is written as it is, inside containers at any depth, by both of
    /// this module's layouts: the bytes of the parsed value serialised the same way.
    #[test]
    fn verbatim_text_is_written_as_it_is() {
        let element =
            serde_json::json!({"id": "r1", "position_mm": {"before": 1.25, "after": 0.5}});
        // `levels` of `{"k": [...]}` around the element: it opens inside twice as many
        // containers.
        for levels in [0, 2, 3] {
            let text = json_at_depth(&element, 2 * levels).expect("text");
            let mut typed = element.clone();
            for _ in 0..levels {
                typed = serde_json::json!({ "k": [typed] });
            }
            struct Nest<'a>(usize, &'a str);
            impl serde::Serialize for Nest<'_> {
                fn serialize<S: serde::Serializer>(
                    &self,
                    serializer: S,
                ) -> std::result::Result<S::Ok, S::Error> {
                    use serde::ser::SerializeMap;
                    if self.0 == 0 {
                        return Verbatim(self.1).serialize(serializer);
                    }
                    let mut map = serializer.serialize_map(Some(1))?;
                    map.serialize_entry("k", &[Nest(self.0 - 1, self.1)])?;
                    map.end()
                }
            }
            let mut spliced = Vec::new();
            write_json_rows(&Nest(levels, &text), &mut spliced).expect("spliced");
            let expected = to_json_rows(&typed).expect("typed");
            assert_eq!(String::from_utf8(spliced).expect("utf-8"), expected);
        }
        // serde_json's compact writer too.
        let compact = serde_json::to_string(&Verbatim("[1, {\"a\": 2}]")).expect("compact");
        assert_eq!(compact, "[1, {\"a\": 2}]");
    }

    #[test]
    fn deep_containers_are_one_line_and_the_value_round_trips() {
        let value = serde_json::json!({
            "a": 1.5,
            "empty": [],
            "rows": [{"arm": "l", "rows": [{"id": "1", "p": {"before": 2.0, "after": [0.5, {}]}}, {"id": "2", "p": {}}]}],
        });
        let text = to_json_rows(&value).unwrap();
        let expected = "{\n  \"a\": 1.5,\n  \"empty\": [],\n  \"rows\": [\n    {\n      \"arm\": \"l\",\n      \"rows\": [\n        {\n          \"id\": \"1\",\n          \"p\": {\"before\": 2.0, \"after\": [0.5, {}]}\n        },\n        {\n          \"id\": \"2\",\n          \"p\": {}\n        }\n      ]\n    }\n  ]\n}\n";
        assert_eq!(text, expected);
        let back: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back, value);
    }
}
