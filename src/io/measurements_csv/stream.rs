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

use super::blocks::PlainHeader;
use super::read::{HeaderPlace, SetBuilder};
use super::*;

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
