//! report.json assembled from typed parts: the report's small keys are a `serde_json::Value`
//! (workflow steps add keys to it), while its per-row arrays — every arm's `rows` and every
//! tool's identification `postures` — stay typed and are serialised straight into the file.
//!
//! As `serde_json::Value`s (maps keeping their key order) those arrays were most of the peak
//! memory of a large calibration (10⁵ configurations: 125 MB of postures and about as much of
//! rows, beside the 93 MB file). The file is the same byte for byte: the typed parts go
//! through the same serialiser and formatter, in the same key order (a posture's joints by
//! name, as the `BTreeMap` they were written from).

use crate::error::{Error, Result};
use crate::report::{ArmReport, CalibrationSummary, RowErrors};
use serde::ser::{SerializeMap, SerializeSeq};
use serde::{Serialize, Serializer};
use serde_json::Value;

/// The report.json key.
pub const POSTURES_KEY: &str = "identification_postures";

/// The report.json keys whose arms carry `rows`, in [`ReportParts::rows`] order.
const ROW_SETS: [&str; 2] = ["identification", "validation"];

/// The per-row arrays of report.json, kept typed; [`render`] writes them at their places.
#[derive(Debug, Default, Clone)]
pub(crate) struct ReportParts {
    /// Per set of [`ROW_SETS`], per arm (in the report's order), its rows.
    rows: [Vec<Vec<RowErrors>>; 2],
    /// Per tool of `"identification_postures"`, its postures.
    pub postures: Vec<ToolPostures>,
}

/// One tool's identification postures, written as labelled maps (joint name → value).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ToolPostures {
    /// The joint names in the order the maps list them (sorted), each with the index of its
    /// value in a posture.
    order: Vec<(String, usize)>,
    /// Per identification row of the tool, one value per joint (rad, m).
    postures: Vec<Vec<f64>>,
}

impl ToolPostures {
    /// The postures of a chain whose joints are `names` (a posture's values in that order).
    pub fn new(names: &[String], postures: Vec<Vec<f64>>) -> Self {
        let mut order: Vec<(String, usize)> = names
            .iter()
            .cloned()
            .enumerate()
            .map(|(i, n)| (n, i))
            .collect();
        order.sort();
        Self { order, postures }
    }
}

/// The report value of `summary` with every arm's `rows` empty, and the rows themselves.
pub(crate) fn summary_value(mut summary: CalibrationSummary) -> Result<(Value, ReportParts)> {
    let take = |arms: &mut Vec<ArmReport>| -> Vec<Vec<RowErrors>> {
        arms.iter_mut()
            .map(|a| std::mem::take(&mut a.rows))
            .collect()
    };
    let rows = [
        take(&mut summary.identification),
        take(&mut summary.validation),
    ];
    let value = serde_json::to_value(&summary).map_err(json_error)?;
    Ok((
        value,
        ReportParts {
            rows,
            postures: Vec::new(),
        },
    ))
}

/// report.json's text: `report` with `parts` at their places, laid out by
/// [`crate::io::to_json_rows`].
pub(crate) fn render(report: &Value, parts: &ReportParts) -> Result<String> {
    crate::io::to_json_rows(&Spliced::text(report, parts))
}

/// As [`render`], written to `out` as it is rendered ([`crate::io::write_json_rows`]).
pub(crate) fn write(
    report: &Value,
    parts: &ReportParts,
    out: &mut dyn std::io::Write,
) -> Result<()> {
    crate::io::write_json_rows(&Spliced::text(report, parts), out)
}

/// report.json's value: `report` with `parts` at their places.
pub(crate) fn value(report: &Value, parts: &ReportParts) -> Result<Value> {
    let typed = Spliced {
        report,
        parts,
        text: false,
    };
    serde_json::to_value(typed).map_err(json_error)
}

fn json_error(e: serde_json::Error) -> Error {
    Error::InvalidData {
        origin: "report.json".into(),
        message: e.to_string(),
    }
}

/// The report with its parts.
struct Spliced<'a> {
    report: &'a Value,
    parts: &'a ReportParts,
    /// Whether the serialiser is [`crate::io::to_json_rows`]'s: the parts' elements are then
    /// rendered in parallel ([`rendered_seq`]), else serialised one by one.
    text: bool,
}

impl<'a> Spliced<'a> {
    fn text(report: &'a Value, parts: &'a ReportParts) -> Self {
        Self {
            report,
            parts,
            text: true,
        }
    }
}

/// The nesting depth of an arm's `rows` array in report.json (the top-level object is 1): a
/// row object opens at 5, indented, its values on one line ([`crate::io::PRETTY_DEPTH`]).
const ROWS_DEPTH: usize = 4;

/// The nesting depth of a tool's `postures` array (in `identification_postures.tools`).
const POSTURES_DEPTH: usize = 5;

/// Elements rendered to text at once (a few MB), before they are written in order.
const RENDERED_CHUNK: usize = 8192;

/// A sequence of `items` as [`crate::io::to_json_rows`] lays it out, its elements rendered to
/// text by `render` ([`crate::io::json_at_depth`] at the sequence's depth) in parallel, a
/// chunk at a time, then written in order as raw JSON: the same bytes as serialising them one
/// by one.
fn rendered_seq<S: Serializer, T: Sync>(
    serializer: S,
    items: &[T],
    render: impl Fn(&T) -> Result<String> + Sync,
) -> std::result::Result<S::Ok, S::Error> {
    use rayon::prelude::*;
    use serde::ser::Error as _;
    let mut seq = serializer.serialize_seq(Some(items.len()))?;
    for chunk in items.chunks(RENDERED_CHUNK) {
        let texts: Vec<String> = chunk
            .par_iter()
            .map(&render)
            .collect::<Result<_>>()
            .map_err(S::Error::custom)?;
        for text in &texts {
            seq.serialize_element(&crate::io::Verbatim(text))?;
        }
    }
    seq.end()
}

impl Serialize for Spliced<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        let Value::Object(map) = self.report else {
            return self.report.serialize(serializer);
        };
        let mut out = serializer.serialize_map(Some(map.len()))?;
        for (key, value) in map {
            if let Some(set) = ROW_SETS.iter().position(|s| s == key) {
                let arms = Each {
                    value,
                    part: |i: usize| {
                        self.parts.rows[set]
                            .get(i)
                            .map(|rows| ("rows", Part::Rows(rows, self.text)))
                    },
                };
                out.serialize_entry(key, &arms)?;
            } else if key == POSTURES_KEY {
                out.serialize_entry(
                    key,
                    &Postures {
                        value,
                        parts: self.parts,
                        text: self.text,
                    },
                )?;
            } else {
                out.serialize_entry(key, value)?;
            }
        }
        out.end()
    }
}

/// A typed part, and whether it is rendered as text ([`Spliced::text`]).
#[derive(Clone, Copy)]
enum Part<'a> {
    Rows(&'a [RowErrors], bool),
    Postures(&'a ToolPostures, bool),
}

impl Serialize for Part<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        match *self {
            Part::Rows(rows, true) => rendered_seq(serializer, rows, |row| {
                crate::io::json_at_depth(row, ROWS_DEPTH)
            }),
            Part::Rows(rows, false) => rows.serialize(serializer),
            Part::Postures(tool, true) => rendered_seq(serializer, &tool.postures, |posture| {
                crate::io::json_at_depth(&Labelled { tool, posture }, POSTURES_DEPTH)
            }),
            Part::Postures(tool, false) => {
                let mut seq = serializer.serialize_seq(Some(tool.postures.len()))?;
                for posture in &tool.postures {
                    seq.serialize_element(&Labelled { tool, posture })?;
                }
                seq.end()
            }
        }
    }
}

/// One posture as a map joint name → value.
struct Labelled<'a> {
    tool: &'a ToolPostures,
    posture: &'a [f64],
}

impl Serialize for Labelled<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.tool.order.len()))?;
        for (name, index) in &self.tool.order {
            map.serialize_entry(name, &self.posture.get(*index))?;
        }
        map.end()
    }
}

/// An array of objects whose `i`-th element has the key `part(i).0` replaced by `part(i).1`
/// (other values as they are).
struct Each<'a, F> {
    value: &'a Value,
    part: F,
}

impl<'a, F: Fn(usize) -> Option<(&'static str, Part<'a>)>> Serialize for Each<'a, F> {
    fn serialize<S: Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        let Value::Array(items) = self.value else {
            return self.value.serialize(serializer);
        };
        let mut seq = serializer.serialize_seq(Some(items.len()))?;
        for (i, item) in items.iter().enumerate() {
            match (item, (self.part)(i)) {
                (Value::Object(map), Some((name, part))) => {
                    seq.serialize_element(&With { map, name, part })?
                }
                _ => seq.serialize_element(item)?,
            }
        }
        seq.end()
    }
}

/// An object with the value of key `name` replaced by `part`.
struct With<'a> {
    map: &'a serde_json::Map<String, Value>,
    name: &'static str,
    part: Part<'a>,
}

impl Serialize for With<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        let mut out = serializer.serialize_map(Some(self.map.len()))?;
        for (key, value) in self.map {
            if key == self.name {
                out.serialize_entry(key, &self.part)?;
            } else {
                out.serialize_entry(key, value)?;
            }
        }
        out.end()
    }
}

/// `"identification_postures"`: its `tools` with their postures.
struct Postures<'a> {
    value: &'a Value,
    parts: &'a ReportParts,
    /// As [`Spliced::text`].
    text: bool,
}

impl Serialize for Postures<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        let Value::Object(map) = self.value else {
            return self.value.serialize(serializer);
        };
        let mut out = serializer.serialize_map(Some(map.len()))?;
        for (key, value) in map {
            if key == "tools" {
                let tools = Each {
                    value,
                    part: |i: usize| {
                        self.parts
                            .postures
                            .get(i)
                            .map(|tool| ("postures", Part::Postures(tool, self.text)))
                    },
                };
                out.serialize_entry(key, &tools)?;
            } else {
                out.serialize_entry(key, value)?;
            }
        }
        out.end()
    }
}

/// A calibration's report.json as `verify` and `compare` read it: any layout of
/// [`crate::report::REPORT_SCHEMA_VERSIONS`] (version 1 has no `schema_version`; the
/// versions differ in keys and in the spelling of values neither command reads). A newer or
/// unknown version is refused, naming the file.
pub(crate) fn read_calibration_report(path: &std::path::Path) -> Result<Value> {
    let origin = path.display().to_string();
    let text = crate::io::read_text(path, crate::limits::MAX_CSV_BYTES)?;
    let report: Value = serde_json::from_str(&text).map_err(|e| Error::InvalidData {
        origin: origin.clone(),
        message: e.to_string(),
    })?;
    check_schema_version(&report).map_err(|message| Error::InvalidData { origin, message })?;
    Ok(report)
}

/// `Ok` when `report`'s `schema_version` is one this treecal reads, else what is wrong.
fn check_schema_version(report: &Value) -> std::result::Result<(), String> {
    let versions = crate::report::REPORT_SCHEMA_VERSIONS;
    let Some(found) = report.get("schema_version") else {
        return Ok(());
    };
    let version = found
        .as_str()
        .and_then(|s| s.strip_prefix("treecal.report/"))
        .and_then(|n| n.parse::<u32>().ok());
    match version {
        Some(v) if versions.contains(&v) => Ok(()),
        _ => Err(format!(
            "schema_version {found} is not a report.json layout this treecal reads \
             (treecal.report/{} to /{}): a report of a newer treecal, or not a `treecal \
             calibrate` report.json",
            versions.start(),
            versions.end()
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The parts rendered in parallel as raw text give the bytes of the typed serialisation,
    /// across a chunk boundary, with optional fields present and absent.
    #[test]
    fn parts_rendered_in_parallel_are_the_typed_bytes() {
        use crate::calibration::Stratum;
        use crate::report::BeforeAfter;
        let row = |i: usize| RowErrors {
            id: format!("r{i}"),
            index: i,
            position_mm: BeforeAfter {
                before: 1.0 / (i + 1) as f64,
                after: 0.1 * i as f64,
            },
            orientation_deg: (i % 2 == 0).then_some(BeforeAfter {
                before: 0.3,
                after: 1e-17 * i as f64,
            }),
            predicted_sd_mm: (i % 3 == 0).then_some(0.001),
            stratum: (i % 5 == 0).then_some(Stratum::Inside),
            outlier: i % 7 == 0,
            weight: (i % 11 == 0).then_some(0.5),
        };
        let rows: Vec<RowErrors> = (0..RENDERED_CHUNK + 3).map(row).collect();
        let postures: Vec<Vec<f64>> = (0..RENDERED_CHUNK + 2)
            .map(|i| vec![i as f64 * 0.001, -0.5, 2.0])
            .collect();
        let names = ["b".to_owned(), "a".to_owned(), "c".to_owned()];
        let parts = ReportParts {
            rows: [vec![rows[..5].to_vec()], vec![rows.clone(), Vec::new()]],
            postures: vec![ToolPostures::new(&names, postures)],
        };
        let report = serde_json::json!({
            "verdict": {"status": "ok"},
            "identification": [{"arm": "left", "rows": []}],
            "validation": [{"arm": "left", "rows": []}, {"arm": "right", "rows": []}],
            POSTURES_KEY: {"joints": 3, "tools": [{"tool": "t", "postures": []}]},
        });
        let typed = Spliced {
            report: &report,
            parts: &parts,
            text: false,
        };
        let expected = crate::io::to_json_rows(&typed).unwrap();
        assert_eq!(render(&report, &parts).unwrap(), expected);
        let mut written = Vec::new();
        write(&report, &parts, &mut written).unwrap();
        assert_eq!(String::from_utf8(written).unwrap(), expected);
        assert!(
            expected.contains("\"id\": \"r8194\""),
            "{}",
            &expected[..400]
        );
    }

    #[test]
    fn every_report_version_up_to_this_one_is_read_and_newer_ones_are_refused() {
        let with = |v: &str| serde_json::json!({ "schema_version": v, "parameters": [] });
        assert!(check_schema_version(&serde_json::json!({ "parameters": [] })).is_ok());
        for v in [
            "treecal.report/1",
            "treecal.report/2",
            crate::report::REPORT_SCHEMA,
        ] {
            assert!(check_schema_version(&with(v)).is_ok(), "{v}");
        }
        for v in [
            "treecal.report/4",
            crate::report::RESULTS_SCHEMA,
            "report",
            "treecal.report/x",
        ] {
            let message = check_schema_version(&with(v)).unwrap_err();
            assert!(message.contains("treecal.report/1 to /3"), "{message}");
        }
    }
}
