//! A joint-value CSV read record by record, in memory bounded by one record
//! ([`CsvRecords`]), for `treecal fk` on files of any length. It accepts what
//! [`super::parse_csv`] accepts and names the same lines: `#` comment lines and blank lines
//! skipped, fields trimmed, line breaks `\n`, `\r\n` or a lone `\r`, a byte-order mark
//! ignored, quoted fields (also over several lines).

use crate::error::{Error, Result};
use crate::limits::{
    check_count, MAX_CSV_BYTES, MAX_CSV_COLUMNS, MAX_CSV_FIELD_BYTES, MAX_CSV_RECORD_BYTES,
    MAX_CSV_ROWS,
};
use std::collections::VecDeque;
use std::io::{BufRead, BufReader};
use std::path::Path;

/// Opens the CSV file at `path` as a stream of records (its header read).
pub fn open_csv_records(path: &Path) -> Result<CsvRecords<BufReader<std::fs::File>>> {
    let file = std::fs::File::open(path).map_err(|source| Error::Io {
        path: path.to_owned(),
        source,
    })?;
    CsvRecords::open(BufReader::new(file), &path.display().to_string())
}

/// The records of a CSV stream: [`Self::open`] reads the header, [`Self::next_record`] the
/// data rows with their 1-based lines.
pub struct CsvRecords<R> {
    lines: PhysicalLines<R>,
    origin: String,
    headers: Vec<String>,
    header_line: usize,
    rows: usize,
    splitter: FieldSplitter,
}

impl<R: BufRead> CsvRecords<R> {
    /// Reads up to and including the header row (the first record that is not blank): an
    /// empty file or a repeated column name is an error naming `origin`.
    pub fn open(reader: R, origin: &str) -> Result<Self> {
        let mut records = Self {
            lines: PhysicalLines::new(reader, origin),
            origin: origin.to_owned(),
            headers: Vec::new(),
            header_line: 0,
            rows: 0,
            splitter: FieldSplitter::default(),
        };
        let (line, headers) = records.next_fields()?.ok_or_else(|| Error::InvalidData {
            origin: origin.to_owned(),
            message: "the file is empty or has only comment (`#`) and blank lines; it needs a \
                      header row naming joints"
                .into(),
        })?;
        super::joints_csv::check_header(&headers, &format!("{origin}:{line}"))?;
        records.headers = headers;
        records.header_line = line;
        Ok(records)
    }

    /// The column names, trimmed.
    pub fn headers(&self) -> &[String] {
        &self.headers
    }

    /// The 1-based line of the header row.
    pub fn header_line(&self) -> usize {
        self.header_line
    }

    /// The next data row `(line, fields)`, `None` at the end; a row with another number of
    /// fields than the header, or beyond [`MAX_CSV_ROWS`], is an error naming its line.
    pub fn next_record(&mut self) -> Result<Option<(usize, Vec<String>)>> {
        let Some((line, fields)) = self.next_fields()? else {
            return Ok(None);
        };
        if fields.len() != self.headers.len() {
            return Err(Error::InvalidData {
                origin: format!("{}:{line}", self.origin),
                message: format!(
                    "row has {} fields but the header has {}",
                    fields.len(),
                    self.headers.len()
                ),
            });
        }
        self.rows += 1;
        if self.rows > MAX_CSV_ROWS {
            check_count(
                self.rows,
                MAX_CSV_ROWS,
                &format!("{}:{line}", self.origin),
                "data rows",
            )?;
        }
        Ok(Some((line, fields)))
    }

    /// The next record that is neither blank nor a comment, as trimmed fields.
    fn next_fields(&mut self) -> Result<Option<(usize, Vec<String>)>> {
        while let Some((line, text)) = self.lines.next_record()? {
            if text.first() == Some(&b'#') {
                continue;
            }
            let fields = self.fields(line, &text)?;
            if !fields.iter().all(String::is_empty) {
                return Ok(Some((line, fields)));
            }
        }
        Ok(None)
    }

    fn fields(&mut self, line: usize, text: &[u8]) -> Result<Vec<String>> {
        let place = || format!("{}:{line}", self.origin);
        let fields = self.splitter.split(text);
        if fields.len() > MAX_CSV_COLUMNS {
            check_count(fields.len(), MAX_CSV_COLUMNS, &place(), "columns")?;
        }
        let mut record = Vec::with_capacity(fields.len());
        for (position, field) in fields.iter().enumerate() {
            let field = std::str::from_utf8(field).map_err(|e| Error::InvalidData {
                origin: place(),
                message: format!(
                    "not readable as CSV: field {} is not UTF-8 ({e}); save the file as UTF-8",
                    position + 1
                ),
            })?;
            let field = field.trim();
            if field.len() > MAX_CSV_FIELD_BYTES {
                return Err(Error::InvalidData {
                    origin: place(),
                    message: format!(
                        "field {} has {} bytes, more than the limit of {MAX_CSV_FIELD_BYTES} \
                         (docs/file-formats.md, \"Limits\")",
                        position + 1,
                        field.len()
                    ),
                });
            }
            record.push(field.to_owned());
        }
        Ok(record)
    }
}

/// Splits one record's text into its fields (quotes removed), with one CSV parser and its
/// buffers kept across records: building a parser costs far more than parsing a short row.
struct FieldSplitter {
    parser: csv_core::Reader,
    output: Vec<u8>,
    ends: Vec<usize>,
}

impl Default for FieldSplitter {
    fn default() -> Self {
        Self {
            // `new` builds the parser's state machine (`Reader::default` does not).
            parser: csv_core::Reader::new(),
            output: Vec::new(),
            ends: Vec::new(),
        }
    }
}

impl FieldSplitter {
    /// The fields of `text` (one record without its line break) as byte slices. The parser's
    /// field ends count from the start of the record's output, across calls.
    fn split(&mut self, text: &[u8]) -> Vec<&[u8]> {
        self.parser.reset();
        // Unquoting never lengthens a field, and a record has at most one field per byte + 1.
        self.output.resize(text.len() + 1, 0);
        self.ends.resize(text.len() + 2, 0);
        let (mut input, mut written, mut fields) = (text, 0, 0);
        loop {
            let (result, read, out, ends) = self.parser.read_record(
                input,
                &mut self.output[written..],
                &mut self.ends[fields..],
            );
            (input, written, fields) = (&input[read..], written + out, fields + ends);
            match result {
                // An empty input tells the parser the record has ended.
                csv_core::ReadRecordResult::InputEmpty => input = &[],
                csv_core::ReadRecordResult::OutputFull => {
                    self.output.resize(2 * self.output.len() + 1, 0)
                }
                csv_core::ReadRecordResult::OutputEndsFull => {
                    self.ends.resize(2 * self.ends.len() + 1, 0)
                }
                csv_core::ReadRecordResult::Record | csv_core::ReadRecordResult::End => break,
            }
        }
        let mut start = 0;
        self.ends[..fields]
            .iter()
            .map(|&end| {
                let field = &self.output[start..end];
                start = end;
                field
            })
            .collect()
    }
}

/// Physical lines of a byte stream (`\n`, `\r\n` or a lone `\r` end one), joined into
/// records while a quoted field is open; each line and record is bounded.
struct PhysicalLines<R> {
    reader: R,
    origin: String,
    /// The 1-based number of the next line to hand out.
    line: usize,
    /// Lines already split off the last read (a lone `\r` inside it).
    pending: VecDeque<Vec<u8>>,
    bytes: u64,
    started: bool,
}

impl<R: BufRead> PhysicalLines<R> {
    fn new(reader: R, origin: &str) -> Self {
        Self {
            reader,
            origin: origin.to_owned(),
            line: 1,
            pending: VecDeque::new(),
            bytes: 0,
            started: false,
        }
    }

    /// The next record's first line and its text (its lines joined by `\n` while a quote is
    /// open), without the line break.
    fn next_record(&mut self) -> Result<Option<(usize, Vec<u8>)>> {
        let first = self.line;
        let Some(mut text) = self.next_line()? else {
            return Ok(None);
        };
        while quote_open(&text) {
            let Some(more) = self.next_line()? else {
                break;
            };
            text.push(b'\n');
            text.extend_from_slice(&more);
            if text.len() > MAX_CSV_RECORD_BYTES {
                return Err(self.too_long(first, "record"));
            }
        }
        Ok(Some((first, text)))
    }

    fn next_line(&mut self) -> Result<Option<Vec<u8>>> {
        if self.pending.is_empty() && !self.read_more()? {
            return Ok(None);
        }
        self.line += 1;
        Ok(self.pending.pop_front())
    }

    /// Reads up to the next `\n` and splits what it read at lone `\r`s; false at the end.
    fn read_more(&mut self) -> Result<bool> {
        let mut buffer = Vec::new();
        let limit = MAX_CSV_RECORD_BYTES as u64 + 1;
        let read = <&mut R as std::io::Read>::take(&mut self.reader, limit)
            .read_until(b'\n', &mut buffer)
            .map_err(|source| Error::Io {
                path: self.origin.clone().into(),
                source,
            })?;
        if read == 0 {
            return Ok(false);
        }
        self.bytes += read as u64;
        if self.bytes > MAX_CSV_BYTES {
            return Err(Error::InvalidData {
                origin: self.origin.clone(),
                message: format!(
                    "the file is longer than the limit of {MAX_CSV_BYTES} bytes \
                     (docs/file-formats.md, \"Limits\")"
                ),
            });
        }
        if buffer.len() as u64 >= limit && buffer.last() != Some(&b'\n') {
            return Err(self.too_long(self.line, "line"));
        }
        if !self.started {
            self.started = true;
            if buffer.starts_with(b"\xEF\xBB\xBF") {
                buffer.drain(..3);
            }
        }
        if buffer.last() == Some(&b'\n') {
            buffer.pop();
            if buffer.last() == Some(&b'\r') {
                buffer.pop();
            }
        }
        self.pending
            .extend(buffer.split(|&b| b == b'\r').map(<[u8]>::to_vec));
        Ok(true)
    }

    fn too_long(&self, line: usize, what: &str) -> Error {
        Error::InvalidData {
            origin: format!("{}:{line}", self.origin),
            message: format!(
                "the {what} is longer than the limit of {MAX_CSV_RECORD_BYTES} bytes \
                 (docs/file-formats.md, \"Limits\")"
            ),
        }
    }
}

/// Whether `text` ends inside a quoted field (an odd number of `"`: an escaped `""` counts
/// twice).
fn quote_open(text: &[u8]) -> bool {
    text.iter().filter(|&&b| b == b'"').count() % 2 == 1
}

#[cfg(test)]
mod tests {
    use super::*;

    type Row = (usize, Vec<String>);

    fn rows(text: &str) -> Result<(Vec<String>, Vec<Row>)> {
        let mut records = CsvRecords::open(text.as_bytes(), "t.csv")?;
        let mut rows = Vec::new();
        while let Some(row) = records.next_record()? {
            rows.push(row);
        }
        Ok((records.headers().to_vec(), rows))
    }

    /// The streamed records equal the whole-text parser's, lines included.
    #[test]
    fn streamed_records_equal_the_whole_text_parser() {
        for text in [
            "a,b\n1,2\n3,4\n",
            "\u{feff}# c\n\n a , b \r\n1,2\r\n\r\n# x\r\n3,4",
            "a,b\r1,2\r\r3,4\r",
            "a,\"b\nc\"\n1,\"2\n\"\n# comment\n3,4\n",
            "a,b\n,\n1,2\n",
        ] {
            let table = super::super::parse_csv(text, "t.csv").unwrap();
            let (headers, records) = rows(text).unwrap();
            assert_eq!(headers, table.headers, "{text:?}");
            assert_eq!(records, table.records, "{text:?}");
        }
    }

    #[test]
    fn errors_name_the_line() {
        let error = rows("a,b\n1,2\n1\n").unwrap_err().to_string();
        assert!(
            error.contains("t.csv:3") && error.contains("1 fields"),
            "{error}"
        );
        let error = rows("# only\n\n").unwrap_err().to_string();
        assert!(error.contains("empty"), "{error}");
        let error = rows("a,a\n").unwrap_err().to_string();
        assert!(error.contains("appears twice"), "{error}");
    }
}
