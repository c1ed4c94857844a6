//! The tools and targets a measurement CSV names, read without a robot model.

// The parent's types, constants and imports.
use super::blocks::{read_plain_blocks, BlockRows, PlainHeader};
use super::*;

/// The distinct links named in the `tool` column of measurement CSV `text`, in order of first
/// appearance: the measured tools, read without a robot model (so that the arms can be built
/// from them). An error when there is no `tool` column or no data row.
pub fn measured_tool_names(text: &str, origin: &str) -> Result<Vec<String>> {
    let table = parse_csv_fields(text, origin).map_err(super::read::without_header)?;
    let mut names = ToolNames::start(&table.headers, table.header_line, origin)?;
    for row in table.rows() {
        names.see(row, origin)?;
    }
    names.finish(origin)
}

/// The tool names of a measurement CSV, gathered row by row.
struct ToolNames {
    column: usize,
    names: Vec<String>,
}

impl ToolNames {
    fn start(headers: &[String], header_line: usize, origin: &str) -> Result<Self> {
        let column =
            headers
                .iter()
                .position(|h| h == "tool")
                .ok_or_else(|| Error::InvalidData {
                    origin: format!("{origin}:{header_line}"),
                    message: "the header has no 'tool' column; add one naming the measured tool \
                    link of each row"
                        .into(),
                })?;
        Ok(Self {
            column,
            names: Vec::new(),
        })
    }

    fn see(&mut self, row: CsvRow<'_>, origin: &str) -> Result<()> {
        let (line, name) = (row.line, row.field(self.column));
        if name.is_empty() {
            return Err(Error::InvalidData {
                origin: format!("{origin}:{line}:tool"),
                message: "the tool is empty; name the measured tool link".into(),
            });
        }
        if !self.names.iter().any(|n| n == name) {
            self.names.push(name.to_owned());
        }
        Ok(())
    }

    fn finish(self, origin: &str) -> Result<Vec<String>> {
        if self.names.is_empty() {
            return Err(Error::InvalidData {
                origin: origin.to_owned(),
                message: "the file has a header but no data rows; add one row per measurement"
                    .into(),
            });
        }
        Ok(self.names)
    }
}

/// The distinct `(tool, point)` pairs the rows of measurement CSV `text` name, in order of
/// first appearance, read without a robot model: `None` for a missing `tool` column (the
/// tool then comes from `--tools`) and for a missing or empty `point`.
pub fn measured_targets(text: &str, origin: &str) -> Result<Vec<(Option<String>, Option<String>)>> {
    let table = parse_csv_fields(text, origin).map_err(super::read::without_header)?;
    let mut targets = Targets::start(&table.headers);
    for row in table.rows() {
        targets.see(row, origin)?;
    }
    Ok(targets.pairs)
}

/// The `(tool, point)` pairs of a measurement CSV, gathered row by row.
struct Targets {
    tool: Option<usize>,
    point: Option<usize>,
    pairs: Vec<(Option<String>, Option<String>)>,
}

impl Targets {
    fn start(headers: &[String]) -> Self {
        let column = |name: &str| headers.iter().position(|h| h == name);
        Self {
            tool: column("tool"),
            point: column(POINT_COLUMN),
            pairs: Vec::new(),
        }
    }

    fn see(&mut self, row: CsvRow<'_>, origin: &str) -> Result<()> {
        let line = row.line;
        let value = |c: Option<usize>| {
            c.map(|c| row.field(c))
                .filter(|v| !v.is_empty())
                .map(str::to_owned)
        };
        let pair = (value(self.tool), value(self.point));
        if self.tool.is_some() && pair.0.is_none() {
            return Err(Error::InvalidData {
                origin: format!("{origin}:{line}:tool"),
                message: "the tool is empty; name the measured tool link".into(),
            });
        }
        if !self.pairs.contains(&pair) {
            self.pairs.push(pair);
        }
        Ok(())
    }
}

/// The pairs of one block, then of the file so far, with the file's name (an empty tool is
/// left to the whole-text reader).
struct PlainTargets<'o>(Targets, &'o str);

impl BlockRows for PlainTargets<'_> {
    type Part = Targets;

    fn part(&self) -> Targets {
        Targets {
            pairs: Vec::new(),
            ..self.0
        }
    }

    fn row(&self, part: &mut Targets, row: CsvRow<'_>) -> Option<()> {
        part.see(row, self.1).ok()
    }

    fn merge(&mut self, part: Targets) -> Option<()> {
        for pair in part.pairs {
            if !self.0.pairs.contains(&pair) {
                self.0.pairs.push(pair);
            }
        }
        Some(())
    }
}

/// The tool names of one block, then of the file so far, with the file's name.
struct PlainToolNames<'o>(ToolNames, &'o str);

impl BlockRows for PlainToolNames<'_> {
    type Part = ToolNames;

    fn part(&self) -> ToolNames {
        ToolNames {
            column: self.0.column,
            names: Vec::new(),
        }
    }

    fn row(&self, part: &mut ToolNames, row: CsvRow<'_>) -> Option<()> {
        part.see(row, self.1).ok()
    }

    fn merge(&mut self, part: ToolNames) -> Option<()> {
        for name in part.names {
            if !self.0.names.contains(&name) {
                self.0.names.push(name);
            }
        }
        Some(())
    }
}

/// Reads a measurement CSV file's tool and point columns; see [`measured_targets`]. A plain
/// file is read in blocks of lines (`measurements_csv::blocks`), anything else as one text.
pub fn read_measured_targets(path: &Path) -> Result<Vec<(Option<String>, Option<String>)>> {
    let origin = path.display().to_string();
    let start =
        |header: PlainHeader<'_>| Some(PlainTargets(Targets::start(header.headers), &origin));
    if let Some(targets) = read_plain_blocks(path, &origin, start) {
        return Ok(targets.0.pairs);
    }
    let text = crate::limits::read_text(path, crate::limits::MAX_CSV_BYTES)?;
    measured_targets(&text, &origin)
}

/// Reads a measurement CSV file's tool column; see [`measured_tool_names`]. A plain file is
/// read in blocks of lines (`measurements_csv::blocks`), anything else as one text.
pub fn read_measured_tool_names(path: &Path) -> Result<Vec<String>> {
    let origin = path.display().to_string();
    let start = |header: PlainHeader<'_>| {
        let names = ToolNames::start(header.headers, header.line, &origin).ok()?;
        Some(PlainToolNames(names, &origin))
    };
    if let Some(names) = read_plain_blocks(path, &origin, start) {
        if let Ok(names) = names.0.finish(&origin) {
            return Ok(names);
        }
    }
    let text = crate::limits::read_text(path, crate::limits::MAX_CSV_BYTES)?;
    measured_tool_names(&text, &origin)
}
