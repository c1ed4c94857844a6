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
use crate::io::csv_fields::CsvFields;
use crate::io::joints_csv::check_unique_columns;
use crate::limits::{MAX_CSV_BYTES, MAX_CSV_COLUMNS, MAX_CSV_FIELD_BYTES, MAX_CSV_ROWS};
use std::io::{BufRead, BufReader, Read};

/// The measurements of the plain CSV file `path`, or `None` when the file is not plain or
/// anything in it is wrong (then the whole-text reader says what).
pub(super) fn read_plain(
    path: &Path,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Option<MeasurementSet> {
    let origin = path.display().to_string();
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
    let stated = parse_units_header(&above, &origin).ok()?;
    drop(above);
    check_unique_columns(&headers, &format!("{origin}:{header_line}")).ok()?;
    let place = HeaderPlace {
        places: Places::Lines,
        origin: &origin,
        line: header_line,
    };
    let mut rows = SetBuilder::start(&headers, &stated, place, tree, model, options).ok()?;
    // About the number of rows, from the size of the file and of its header.
    let guess = usize::try_from(size / (lines.read + 1)).unwrap_or(0);
    rows.reserve(guess.min(MAX_CSV_ROWS));
    let mut row = CsvFields::new(headers, header_line);
    while let Some((line, text)) = lines.next_or_end()? {
        if !plain_record(text)? {
            continue;
        }
        if rows.len() == MAX_CSV_ROWS {
            return None;
        }
        row.clear();
        row.push_row(line, text.split(',').map(str::trim), &origin)
            .ok()?;
        rows.push(row.row(0)).ok()?;
    }
    if rows.len() == 0 {
        return None;
    }
    let mut set = rows.finish().ok()?;
    set.measurements.shrink_to_fit();
    set.ids.shrink_to_fit();
    set.lines.shrink_to_fit();
    Some(set)
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
