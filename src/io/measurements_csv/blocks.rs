//! A plain measurement CSV's data lines read in blocks and handled in parallel: the reading
//! thread only cuts the file into blocks of whole lines and counts their line breaks; checking,
//! splitting and parsing the lines run on rayon's workers, a batch of blocks at a time, and the
//! blocks' results are merged in file order. Every row is read as the line-by-line reader read
//! it, so the result is the same whatever the number of threads.
//!
//! "Plain" is the common case: valid UTF-8, no quote character, line breaks `\n` or `\r\n`, at
//! most one leading byte-order mark. Any problem (the file is not plain, a row is wrong) gives
//! `None`: the caller then reads the file again sequentially ([`super::stream`]), so that an
//! error names the first wrong line of the file, whichever block it is in.

use crate::io::bounded::open_regular;
use crate::io::csv_fields::{CsvFields, CsvRow};
use crate::io::joints_csv::check_unique_columns;
use crate::limits::{MAX_CSV_BYTES, MAX_CSV_COLUMNS, MAX_CSV_FIELD_BYTES, MAX_CSV_ROWS};
use rayon::prelude::*;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// About the bytes of one block (whole lines; a longer line makes a longer block).
const BLOCK_BYTES: usize = 1 << 20;

/// Blocks parsed at once: the text and results held besides the merged rows.
const BATCH_BLOCKS: usize = 16;

/// What a plain file's rows are gathered into: each block's rows into a [`Self::Part`] (in
/// parallel, reading `self` only), then the parts merged into `self` in file order.
pub(super) trait BlockRows: Sync {
    /// What one block's rows give.
    type Part: Send;
    /// An empty part.
    fn part(&self) -> Self::Part;
    /// Adds data row `row` to `part`; `None` when the row is wrong.
    fn row(&self, part: &mut Self::Part, row: CsvRow<'_>) -> Option<()>;
    /// Merges the next block's part; `None` when the rows so far are wrong together.
    fn merge(&mut self, part: Self::Part) -> Option<()>;
    /// After the last part: `None` when the rows are wrong together.
    fn end(&mut self) -> Option<()> {
        Some(())
    }
}

/// Reads the plain CSV file `path` (named `origin`): `start` with its header, then every data
/// row into the state it gives, block by block ([`BlockRows`]). `None` when the file is not
/// plain, is past a limit, has no header, or when `start`, a row or a merge gives `None`.
pub(super) fn read_plain_blocks<S: BlockRows>(
    path: &Path,
    origin: &str,
    start: impl FnOnce(PlainHeader<'_>) -> Option<S>,
) -> Option<S> {
    let (file, size) = open_regular(path, MAX_CSV_BYTES).ok()?;
    let mut lines = PlainLines::new(BufReader::with_capacity(
        1 << 16,
        file.take(MAX_CSV_BYTES + 1),
    ));
    // The comment and blank lines above the header, and the header: the units comment.
    let mut above = String::new();
    let (header_line, headers): (usize, Vec<String>) = loop {
        let (line, text) = lines.next()?;
        above.push_str(text);
        above.push('\n');
        let mut fields = Vec::new();
        if plain_record(text, &mut fields)? {
            break (line, fields.into_iter().map(str::to_owned).collect());
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
    let mut blocks = Blocks {
        reader: lines.reader,
        carry: Vec::new(),
        read: lines.read,
        next_line: header_line + 1,
        ended: false,
    };
    let place = RowPlace {
        headers: &headers,
        header_line,
        origin,
    };
    // The next batch is read on its own thread while this one is parsed (one batch ahead:
    // the channel holds none, so the reader waits for the parse to take what it read).
    std::thread::scope(|scope| {
        let (sender, batches) = std::sync::mpsc::sync_channel(0);
        scope.spawn(move || loop {
            let batch = blocks.batch();
            let more = matches!(&batch, Some(batch) if !batch.is_empty());
            if sender.send(batch).is_err() || !more {
                break;
            }
        });
        let mut count = 0;
        loop {
            let batch = batches.recv().ok()??;
            if batch.is_empty() {
                state.end()?;
                return Some(state);
            }
            let parts: Vec<Option<(S::Part, usize)>> = batch
                .par_iter()
                .map(|block| parse_block(&state, block, place))
                .collect();
            drop(batch);
            for part in parts {
                let (part, rows) = part?;
                count += rows;
                if count > MAX_CSV_ROWS {
                    return None;
                }
                state.merge(part)?;
            }
        }
    })
}

/// The header a block's rows are read against, and the file's name.
#[derive(Clone, Copy)]
struct RowPlace<'a> {
    headers: &'a [String],
    header_line: usize,
    origin: &'a str,
}

/// Whole lines of the file and the 1-based number of the first.
struct Block {
    text: Vec<u8>,
    first_line: usize,
    /// Whether the text ends the file (its last line may lack a line break).
    last: bool,
}

/// The rest of a plain file after its header, cut into [`Block`]s.
struct Blocks<R> {
    reader: R,
    /// The start of a line not yet ended, from the previous read.
    carry: Vec<u8>,
    /// Bytes read so far.
    read: u64,
    /// The number of the next block's first line.
    next_line: usize,
    ended: bool,
}

impl<R: Read> Blocks<R> {
    /// Up to [`BATCH_BLOCKS`] blocks (none at the end); `None` as for [`Self::next`].
    fn batch(&mut self) -> Option<Vec<Block>> {
        let mut batch = Vec::with_capacity(BATCH_BLOCKS);
        while batch.len() < BATCH_BLOCKS {
            match self.next()? {
                Some(block) => batch.push(block),
                None => break,
            }
        }
        Some(batch)
    }

    /// `Some(Some(block))`, `Some(None)` at the end, `None` past the size limit or when the
    /// file cannot be read.
    fn next(&mut self) -> Option<Option<Block>> {
        if self.ended {
            return Some(None);
        }
        let mut text = std::mem::take(&mut self.carry);
        loop {
            let before = text.len();
            // `read_to_end` fills the spare capacity without zeroing it first.
            text.reserve(BLOCK_BYTES);
            let count = (&mut self.reader)
                .take(BLOCK_BYTES as u64)
                .read_to_end(&mut text)
                .ok()?;
            self.read += count as u64;
            if self.read > MAX_CSV_BYTES {
                return None;
            }
            if count == 0 {
                self.ended = true;
                if text.is_empty() {
                    return Some(None);
                }
                return Some(Some(self.block(text, true)));
            }
            if let Some(end) = memchr::memrchr(b'\n', &text[before..]) {
                self.carry = text[before + end + 1..].to_vec();
                text.truncate(before + end + 1);
                return Some(Some(self.block(text, false)));
            }
        }
    }

    fn block(&mut self, text: Vec<u8>, last: bool) -> Block {
        let first_line = self.next_line;
        self.next_line += memchr::memchr_iter(b'\n', &text).count();
        Block {
            text,
            first_line,
            last,
        }
    }
}

/// The rows of `block` gathered into a part of `state`, and their count; the line checks are
/// [`PlainLines`]'s.
fn parse_block<S: BlockRows>(
    state: &S,
    block: &Block,
    place: RowPlace<'_>,
) -> Option<(S::Part, usize)> {
    let mut part = state.part();
    let mut row = CsvFields::new(place.headers.to_vec(), place.header_line);
    let mut count = 0;
    // A line's trimmed fields, split once for the record test and the row.
    let mut line_fields: Vec<&str> = Vec::new();
    let pieces = block.text.split_inclusive(|&b| b == b'\n');
    for (k, piece) in pieces.enumerate() {
        let line = block.first_line + k;
        let mut bytes = piece.strip_suffix(b"\n").unwrap_or(piece);
        if let Some(rest) = bytes.strip_suffix(b"\r") {
            // A `\r` at the very end of the file (no `\n` after it) is a lone one.
            if block.last && bytes.len() == piece.len() {
                return None;
            }
            bytes = rest;
        }
        if memchr::memchr2(b'"', b'\r', bytes).is_some() {
            return None;
        }
        let text = std::str::from_utf8(bytes).ok()?;
        if !plain_record(text, &mut line_fields)? {
            continue;
        }
        count += 1;
        row.clear();
        row.push_row(line, line_fields.iter().copied(), place.origin)
            .ok()?;
        state.row(&mut part, row.row(0))?;
    }
    Some((part, count))
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

/// The comma-separated fields of a plain line (`str::split(',')`, by a byte scan: faster on
/// the short fields of a measurement file).
fn fields(text: &str) -> impl Iterator<Item = &str> {
    let mut rest = Some(text);
    std::iter::from_fn(move || {
        let text = rest?;
        match memchr::memchr(b',', text.as_bytes()) {
            Some(comma) => {
                rest = text.get(comma + 1..);
                text.get(..comma)
            }
            None => {
                rest = None;
                Some(text)
            }
        }
    })
}

/// Whether a plain line is a record (not a comment, not only empty fields), its trimmed
/// fields put in `trimmed` (emptied first; left empty for a comment); `None` if it is past a
/// limit (too many columns, a field too long).
pub(super) fn plain_record<'t>(text: &'t str, trimmed: &mut Vec<&'t str>) -> Option<bool> {
    trimmed.clear();
    if text.starts_with('#') {
        return Some(false);
    }
    for field in fields(text) {
        if field.len() > MAX_CSV_FIELD_BYTES || trimmed.len() == MAX_CSV_COLUMNS {
            return None;
        }
        trimmed.push(field.trim());
    }
    Some(trimmed.iter().any(|f| !f.is_empty()))
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

#[cfg(test)]
mod tests {
    #[test]
    fn fields_split_as_str_split_does() {
        for text in [
            "",
            ",",
            "a",
            "a,,b,",
            ",x",
            "é,ü,ß",
            " 1.5 , -2e3,id 7",
            "a,b,c,d,e,f,g",
        ] {
            let ours: Vec<&str> = super::fields(text).collect();
            let std: Vec<&str> = text.split(',').collect();
            assert_eq!(ours, std, "{text:?}");
        }
    }

    use super::*;

    /// Gathers every row's line and first field.
    struct Firsts(Vec<(usize, String)>);

    impl BlockRows for Firsts {
        type Part = Vec<(usize, String)>;
        fn part(&self) -> Self::Part {
            Vec::new()
        }
        fn row(&self, part: &mut Self::Part, row: CsvRow<'_>) -> Option<()> {
            (row.field(0) != "bad").then(|| part.push((row.line, row.field(0).to_owned())))
        }
        fn merge(&mut self, part: Self::Part) -> Option<()> {
            self.0.extend(part);
            Some(())
        }
    }

    fn plain_rows(text: &str) -> Option<Vec<(usize, String)>> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.csv");
        std::fs::write(&path, text).unwrap();
        let start = |header: PlainHeader<'_>| (header.headers[0] == "a").then(|| Firsts(vec![]));
        read_plain_blocks(&path, "f", start).map(|f| f.0)
    }

    #[test]
    fn blocks_give_every_row_with_its_line_in_order() {
        let expected = vec![(3, "1".to_owned()), (6, "3".to_owned())];
        let plain = "# units: length=mm\na,b\n 1 ,2\n,\n\n3,4\n";
        assert_eq!(plain_rows(plain), Some(expected.clone()));
        assert_eq!(plain_rows(&plain.replace('\n', "\r\n")), Some(expected));
        for other in [
            "a,b\n\"1\",2\n",
            "a,b\r1,2\n",
            "a,b\n1,2\r",
            "a,a\n1,2\n",
            "",
        ] {
            assert_eq!(plain_rows(other), None, "{other:?}");
        }
        // Many blocks: every line numbered as a line-by-line read numbers it.
        let mut text = String::from("a,b\n");
        let rows = 3 * BLOCK_BYTES / 20;
        for i in 0..rows {
            text.push_str(&format!("{i:012},{}\n", i % 7));
        }
        let read = plain_rows(&text).unwrap();
        assert_eq!(read.len(), rows);
        assert!(read
            .iter()
            .enumerate()
            .all(|(i, (line, first))| *line == i + 2 && *first == format!("{i:012}")));
        // A wrong row in a late block fails the whole read.
        text.push_str("bad,1\n");
        assert_eq!(plain_rows(&text), None);
    }
}
