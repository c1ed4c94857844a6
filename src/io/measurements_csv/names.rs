//! The tools and targets a measurement CSV names, read without a robot model.

// The parent's types, constants and imports.
use super::*;

/// The distinct links named in the `tool` column of measurement CSV `text`, in order of first
/// appearance: the measured tools, read without a robot model (so that the arms can be built
/// from them). An error when there is no `tool` column or no data row.
pub fn measured_tool_names(text: &str, origin: &str) -> Result<Vec<String>> {
    let table = parse_csv_fields(text, origin)?;
    let column = table
        .headers
        .iter()
        .position(|h| h == "tool")
        .ok_or_else(|| Error::InvalidData {
            origin: format!("{origin}:{}", table.header_line),
            message: "the header has no 'tool' column; add one naming the measured tool link \
                of each row"
                .into(),
        })?;
    let mut names: Vec<String> = Vec::new();
    for row in table.rows() {
        let (line, name) = (row.line, row.field(column));
        if name.is_empty() {
            return Err(Error::InvalidData {
                origin: format!("{origin}:{line}:tool"),
                message: "the tool is empty; name the measured tool link".into(),
            });
        }
        if !names.iter().any(|n| n == name) {
            names.push(name.to_owned());
        }
    }
    if names.is_empty() {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: "the file has a header but no data rows; add one row per measurement".into(),
        });
    }
    Ok(names)
}

/// The distinct `(tool, point)` pairs the rows of measurement CSV `text` name, in order of
/// first appearance, read without a robot model: `None` for a missing `tool` column (the
/// tool then comes from `--tools`) and for a missing or empty `point`.
pub fn measured_targets(text: &str, origin: &str) -> Result<Vec<(Option<String>, Option<String>)>> {
    let table = parse_csv_fields(text, origin)?;
    let column = |name: &str| table.headers.iter().position(|h| h == name);
    let (tool, point) = (column("tool"), column(POINT_COLUMN));
    let mut pairs: Vec<(Option<String>, Option<String>)> = Vec::new();
    for row in table.rows() {
        let line = row.line;
        let value = |c: Option<usize>| {
            c.map(|c| row.field(c))
                .filter(|v| !v.is_empty())
                .map(str::to_owned)
        };
        let pair = (value(tool), value(point));
        if tool.is_some() && pair.0.is_none() {
            return Err(Error::InvalidData {
                origin: format!("{origin}:{line}:tool"),
                message: "the tool is empty; name the measured tool link".into(),
            });
        }
        if !pairs.contains(&pair) {
            pairs.push(pair);
        }
    }
    Ok(pairs)
}

/// Reads a measurement CSV file's tool and point columns; see [`measured_targets`].
pub fn read_measured_targets(path: &Path) -> Result<Vec<(Option<String>, Option<String>)>> {
    let text = crate::limits::read_text(path, crate::limits::MAX_CSV_BYTES)?;
    measured_targets(&text, &path.display().to_string())
}

/// Reads a measurement CSV file's tool column; see [`measured_tool_names`].
pub fn read_measured_tool_names(path: &Path) -> Result<Vec<String>> {
    let text = crate::limits::read_text(path, crate::limits::MAX_CSV_BYTES)?;
    measured_tool_names(&text, &path.display().to_string())
}
