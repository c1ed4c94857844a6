//! A plain measurement CSV read block by block (`super::blocks`), each row turned into its
//! measurement at once, the blocks in parallel: memory is the measurements and a batch of
//! blocks, not the file's text (867 MB at 10⁶ configurations) and every field's text besides.
//!
//! "Plain" is the common case: valid UTF-8, no quote character, line breaks `\n` or `\r\n`, at
//! most one leading byte-order mark. Then a line is a record, a record's fields are its
//! comma-separated pieces, trimmed, as the csv crate reads them. Anything else, and every
//! error, is left to the whole-text reader ([`super::read`]): [`read_plain`] gives `None` and
//! the caller reads the file again that way, so that messages name the same place with the
//! same words whichever reader found the problem.

use super::read::{HeaderPlace, SetBuilder};
use super::*;
use crate::limits::{MAX_CSV_BYTES, MAX_CSV_COLUMNS, MAX_CSV_FIELD_BYTES};
use std::io::BufRead;

/// Reads a measurement CSV file; see [`super::parse_measurements`]. A plain file is read in
/// blocks of lines, anything else (and any file with an error) as one text.
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
    let rows = super::blocks::read_plain_blocks(path, &origin, start)?;
    if rows.len() == 0 {
        return None;
    }
    let mut set = rows.finish().ok()?;
    set.measurements.shrink_to_fit();
    set.ids.shrink_to_fit();
    set.lines.shrink_to_fit();
    Some(set)
}

/// The header of a plain file, as [`super::blocks::read_plain_blocks`] gives it.
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

/// Whether a plain line is a record (not a comment, not only empty fields); `None` if it is
/// past a limit (too many columns, a field too long).
pub(super) fn plain_record(text: &str) -> Option<bool> {
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
pub(super) struct PlainLines<R> {
    pub(super) reader: R,
    buffer: Vec<u8>,
    /// The 1-based number of the last line given.
    line: usize,
    /// Bytes read so far.
    pub(super) read: u64,
}

impl<R: BufRead> PlainLines<R> {
    /// The lines of `reader`.
    pub(super) fn new(reader: R) -> Self {
        Self {
            reader,
            buffer: Vec::new(),
            line: 0,
            read: 0,
        }
    }

    /// The next line and its number; `None` at the end, or when the file is not plain.
    pub(super) fn next(&mut self) -> Option<(usize, &str)> {
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
