//! A plain measurement CSV read line by line, each row turned into its measurement at once:
//! memory is the measurements and one line, not the file's text (867 MB at 10⁶ configurations)
//! and every field's text besides.
//!
//! "Plain" is the common case: valid UTF-8, no quote character, line breaks `\n` or `\r\n`, at
//! most one leading byte-order mark. Then a line is a record, a record's fields are its
//! comma-separated pieces, trimmed, as the csv crate reads them. Anything else, and every
//! error, is left to the whole-text reader ([`super::read`]): [`read_plain`] gives `None` and
//! the caller reads the file again that way, so that messages name the same place with the
//! same words whichever reader found the problem.

use super::read::{HeaderPlace, SetBuilder};
use super::*;
use crate::io::bounded::open_regular;
use crate::io::csv_fields::{CsvFields, CsvRow};
use crate::io::joints_csv::check_unique_columns;
use crate::limits::{MAX_CSV_BYTES, MAX_CSV_COLUMNS, MAX_CSV_FIELD_BYTES, MAX_CSV_ROWS};
use std::io::{BufRead, BufReader, Read};

/// Reads a measurement CSV file; see [`super::parse_measurements`]. A plain file is read line
/// by line, anything else (and any file with an error) as one text.
pub fn read_measurements(
    path: &Path,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Result<MeasurementSet> {
    match read_plain(path, tree, model, options) {
        Some(set) => Ok(set),
        // Not plain, or something is wrong: the whole-text reader names the place.
        None => super::read::read_whole(path, tree, model, options),
    }
}

/// The measurements of the plain CSV file `path`, or `None` when the file is not plain or
/// anything in it is wrong (then the whole-text reader says what).
fn read_plain(
    path: &Path,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Option<MeasurementSet> {
    let origin = path.display().to_string();
    let start = |header: PlainHeader<'_>| {
        let stated = parse_units_header(header.above, &origin).ok()?;
        let place = HeaderPlace {
            places: Places::Lines,
            origin: &origin,
            line: header.line,
        };
        let mut rows =
            SetBuilder::start(header.headers, &stated, place, tree, model, options).ok()?;
        rows.reserve(header.rows_guess);
        Some(rows)
    };
    let each = |rows: &mut SetBuilder<'_>, row: CsvRow<'_>| rows.push(row).ok();
    let rows = for_each_plain_row(path, &origin, start, each)?;
    if rows.len() == 0 {
        return None;
    }
    let mut set = rows.finish().ok()?;
    set.measurements.shrink_to_fit();
    set.ids.shrink_to_fit();
    set.lines.shrink_to_fit();
    Some(set)
}

/// The header of a plain file, as [`for_each_plain_row`] gives it.
pub(super) struct PlainHeader<'h> {
    /// The column names, trimmed.
    pub(super) headers: &'h [String],
    /// The 1-based line of the header.
    pub(super) line: usize,
    /// The text above the header and the header (for the units comment).
    pub(super) above: &'h str,
    /// About the number of data rows, from the size of the file and of its header.
    pub(super) rows_guess: usize,
}

/// Reads the plain CSV file `path` (named `origin`): `start` with its header, then `each`
/// with every data row. `None` when the file is not plain, is past a limit, has no header, or
/// when `start` or `each` gives `None`.
pub(super) fn for_each_plain_row<S>(
    path: &Path,
    origin: &str,
    start: impl FnOnce(PlainHeader<'_>) -> Option<S>,
    mut each: impl FnMut(&mut S, CsvRow<'_>) -> Option<()>,
) -> Option<S> {
    let (file, size) = open_regular(path, MAX_CSV_BYTES).ok()?;
    let mut lines = PlainLines {
        reader: BufReader::with_capacity(1 << 16, file.take(MAX_CSV_BYTES + 1)),
        buffer: Vec::new(),
        line: 0,
        read: 0,
    };
    // The comment and blank lines above the header, and the header: the units comment.
    let mut above = String::new();
    let (header_line, headers): (usize, Vec<String>) = loop {
        let (line, text) = lines.next()?;
        above.push_str(text);
        above.push('\n');
        if plain_record(text)? {
            break (line, text.split(',').map(|f| f.trim().to_owned()).collect());
        }
    };
    if above.starts_with('\u{feff}') {
        // Two byte-order marks: the whole-text reader drops both.
        return None;
    }
    check_unique_columns(&headers, &format!("{origin}:{header_line}")).ok()?;
    let rows_guess = usize::try_from(size / (lines.read + 1)).unwrap_or(0);
    let mut state = start(PlainHeader {
        headers: &headers,
        line: header_line,
        above: &above,
        rows_guess: rows_guess.min(MAX_CSV_ROWS),
    })?;
    drop(above);
    let (mut row, mut count) = (CsvFields::new(headers, header_line), 0);
    while let Some((line, text)) = lines.next_or_end()? {
        if !plain_record(text)? {
            continue;
        }
        if count == MAX_CSV_ROWS {
            return None;
        }
        count += 1;
        row.clear();
        row.push_row(line, text.split(',').map(str::trim), origin)
            .ok()?;
        each(&mut state, row.row(0))?;
    }
    Some(state)
}

/// Whether a plain line is a record (not a comment, not only empty fields); `None` if it is
/// past a limit (too many columns, a field too long).
fn plain_record(text: &str) -> Option<bool> {
    if text.starts_with('#') {
        return Some(false);
    }
    let (mut count, mut any) = (0, false);
    for field in text.split(',') {
        if field.len() > MAX_CSV_FIELD_BYTES || count == MAX_CSV_COLUMNS {
            return None;
        }
        count += 1;
        any |= !field.trim().is_empty();
    }
    Some(any)
}

/// The lines of a plain file, their line breaks taken off.
struct PlainLines<R> {
    reader: R,
    buffer: Vec<u8>,
    /// The 1-based number of the last line given.
    line: usize,
    /// Bytes read so far.
    read: u64,
}

impl<R: BufRead> PlainLines<R> {
    /// The next line and its number; `None` at the end, or when the file is not plain.
    fn next(&mut self) -> Option<(usize, &str)> {
        self.next_or_end().flatten()
    }

    /// `Some(Some((number, line)))`, `Some(None)` at the end of the file, `None` when the file
    /// is not plain (a quote, a lone `\r`, not UTF-8, past the size limit) or cannot be read.
    fn next_or_end(&mut self) -> Option<Option<(usize, &str)>> {
        self.buffer.clear();
        let count = self.reader.read_until(b'\n', &mut self.buffer).ok()?;
        if count == 0 {
            return Some(None);
        }
        self.read += count as u64;
        if self.read > MAX_CSV_BYTES {
            return None;
        }
        self.line += 1;
        let mut bytes = self.buffer.as_slice();
        bytes = bytes.strip_suffix(b"\n").unwrap_or(bytes);
        if let Some(rest) = bytes.strip_suffix(b"\r") {
            // A `\r` at the very end (no `\n` after it) is a lone one.
            if count == bytes.len() {
                return None;
            }
            bytes = rest;
        }
        if bytes.iter().any(|&b| b == b'"' || b == b'\r') {
            return None;
        }
        let text = std::str::from_utf8(bytes).ok()?;
        let text = match self.line {
            1 => text.strip_prefix('\u{feff}').unwrap_or(text),
            _ => text,
        };
        Some(Some((self.line, text)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The data rows' lines and first fields, if the file with `text` is read as plain.
    fn plain_rows(text: &str) -> Option<Vec<(usize, String)>> {
        let dir = std::env::temp_dir().join(format!("treecal-plain-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("{}.csv", text.len()));
        std::fs::write(&path, text).unwrap();
        let start = |header: PlainHeader<'_>| (header.headers[0] == "a").then(Vec::new);
        let each = |rows: &mut Vec<(usize, String)>, row: CsvRow<'_>| {
            rows.push((row.line, row.field(0).to_owned()));
            Some(())
        };
        let rows = for_each_plain_row(&path, "f", start, each);
        std::fs::remove_file(&path).unwrap();
        rows
    }

    #[test]
    fn plain_files_are_read_line_by_line_and_others_are_not() {
        let expected = vec![(3, "1".to_owned()), (6, "3".to_owned())];
        let plain = "# units: length=mm\na,b\n 1 ,2\n,\n\n3,4\n";
        assert_eq!(plain_rows(plain), Some(expected.clone()));
        assert_eq!(
            plain_rows(&plain.replace('\n', "\r\n")),
            Some(expected.clone())
        );
        assert_eq!(plain_rows(&format!("\u{feff}{plain}")), Some(expected));
        for other in [
            "a,b\n\"1\",2\n",
            "a,b\r1,2\n",
            "a,b\n1,2\r",
            "\u{feff}\u{feff}a,b\n1,2\n",
            "a,a\n1,2\n",
            "",
        ] {
            assert_eq!(plain_rows(other), None, "{other:?}");
        }
    }
}
