//! A CSV table held compactly: every data field's text in one buffer, found by its end offset.
//!
//! [`super::CsvTable`] keeps a `String` per field (at 10⁵ measurement rows of 25 columns that
//! is 5·10⁶ allocations and about 1.4 KB per row); here a row costs its text plus 4 bytes per
//! field. The measurement CSV is read this way ([`parse_csv_fields`]); other readers convert
//! with [`CsvFields::into_table`].

use crate::error::{Error, Result};
use std::ops::Index;

/// A CSV table as read: header and records with their 1-based line numbers.
#[derive(Debug, Clone)]
pub struct CsvTable {
    /// Column names, trimmed.
    pub headers: Vec<String>,
    /// The 1-based line of the header row.
    pub header_line: usize,
    /// `(line, fields)` of every data row.
    pub records: Vec<(usize, Vec<String>)>,
}

/// A CSV table as read: the header, and every data row's line and fields (trimmed).
#[derive(Debug, Clone, Default)]
pub struct CsvFields {
    /// Column names, trimmed.
    pub headers: Vec<String>,
    /// The 1-based line of the header row (0 for a table not read from a file).
    pub header_line: usize,
    /// The fields of every data row, one after the other.
    text: String,
    /// The end in `text` of every data field, `headers.len()` per row.
    ends: Vec<u32>,
    /// The 1-based line (or row number) of every data row.
    lines: Vec<usize>,
}

/// One data row of a [`CsvFields`]: its line and its fields (`row[column]` is a `&str`).
#[derive(Debug, Clone, Copy)]
pub struct CsvRow<'a> {
    /// The 1-based line of the row (or its row number for a table not read from a file).
    pub line: usize,
    text: &'a str,
    /// Where the row's first field starts in `text`.
    start: u32,
    ends: &'a [u32],
}

impl CsvFields {
    /// An empty table with these columns (`header_line` 0 when not read from a file).
    pub fn new(headers: Vec<String>, header_line: usize) -> Self {
        Self {
            headers,
            header_line,
            ..Self::default()
        }
    }

    /// Appends a data row at `line`; `fields` must yield one field per column. An error
    /// (naming `origin:line`) when the fields' text passes 4 GiB or the count is wrong.
    pub fn push_row<'f>(
        &mut self,
        line: usize,
        fields: impl IntoIterator<Item = &'f str>,
        origin: &str,
    ) -> Result<()> {
        let before = self.ends.len();
        for field in fields {
            self.text.push_str(field);
            let end = u32::try_from(self.text.len()).map_err(|_| Error::InvalidData {
                origin: format!("{origin}:{line}"),
                message: "the table's text passes 4 GiB; split the data into several files".into(),
            })?;
            self.ends.push(end);
        }
        let count = self.ends.len() - before;
        if count != self.headers.len() {
            self.ends.truncate(before);
            self.text
                .truncate(self.row_start(self.lines.len()) as usize);
            return Err(Error::InvalidData {
                origin: format!("{origin}:{line}"),
                message: format!(
                    "row has {count} fields but the header has {}",
                    self.headers.len()
                ),
            });
        }
        self.lines.push(line);
        Ok(())
    }

    /// Drops every data row (the columns stay), keeping the buffers' room.
    pub fn clear(&mut self) {
        self.text.clear();
        self.ends.clear();
        self.lines.clear();
    }

    /// Number of data rows.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// Whether there are no data rows.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// Where row `row` starts in `text`.
    fn row_start(&self, row: usize) -> u32 {
        match row * self.headers.len() {
            0 => 0,
            k => self.ends[k - 1],
        }
    }

    /// Data row `row` (0-based).
    pub fn row(&self, row: usize) -> CsvRow<'_> {
        let n = self.headers.len();
        CsvRow {
            line: self.lines[row],
            text: &self.text,
            start: self.row_start(row),
            ends: &self.ends[row * n..(row + 1) * n],
        }
    }

    /// The data rows in order.
    pub fn rows(&self) -> impl ExactSizeIterator<Item = CsvRow<'_>> + '_ {
        (0..self.len()).map(|row| self.row(row))
    }

    /// The table with a `String` per field, as the other readers take it.
    pub fn into_table(self) -> CsvTable {
        let records = self
            .rows()
            .map(|row| (row.line, row.fields().map(str::to_owned).collect()))
            .collect();
        CsvTable {
            headers: self.headers,
            header_line: self.header_line,
            records,
        }
    }
}

impl<'a> CsvRow<'a> {
    /// Number of fields (the table's columns).
    fn len(&self) -> usize {
        self.ends.len()
    }

    /// Feeds `state` the row's fields but column `skip` (their text and lengths, so that
    /// fields that only split the same text differently differ): two rows equal in every other
    /// column feed the same, in three writes whatever the number of columns.
    pub fn hash_without(&self, skip: Option<usize>, state: &mut impl std::hash::Hasher) {
        let end = self.ends.last().copied().unwrap_or(self.start);
        let (before, after) = match skip.filter(|&c| c < self.len()) {
            Some(c) => {
                let field_start = if c == 0 { self.start } else { self.ends[c - 1] };
                (field_start, self.ends[c])
            }
            None => (end, end),
        };
        state.write(&self.text.as_bytes()[self.start as usize..before as usize]);
        state.write(&self.text.as_bytes()[after as usize..end as usize]);
        // The lengths, 64 fields at a time.
        let mut lengths = [0u8; 256];
        let mut previous = self.start;
        for (column, &field_end) in self.ends.iter().enumerate() {
            let length = if Some(column) == skip {
                0
            } else {
                field_end - previous
            };
            let at = 4 * (column % 64);
            lengths[at..at + 4].copy_from_slice(&length.to_le_bytes());
            previous = field_end;
            if column % 64 == 63 {
                state.write(&lengths);
            }
        }
        state.write(&lengths[..4 * (self.len() % 64)]);
    }

    /// The field in column `column`.
    pub fn field(&self, column: usize) -> &'a str {
        let start = match column {
            0 => self.start,
            c => self.ends[c - 1],
        };
        &self.text[start as usize..self.ends[column] as usize]
    }

    /// The fields in column order.
    pub fn fields(self) -> impl Iterator<Item = &'a str> {
        (0..self.len()).map(move |column| self.field(column))
    }
}

impl Index<usize> for CsvRow<'_> {
    type Output = str;

    fn index(&self, column: usize) -> &str {
        self.field(column)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows equal but in the skipped column hash alike; the same text split differently, or
    /// another value anywhere else, does not.
    #[test]
    fn rows_hash_alike_only_when_equal_but_the_skipped_column() {
        use std::hash::{DefaultHasher, Hasher};
        let wide: Vec<String> = (0..70).map(|c| format!("c{c}")).collect();
        let mut table = CsvFields::new(wide.clone(), 1);
        let row = |id: &str, last: &str| {
            let mut fields: Vec<String> = (0..70).map(|c| format!("{c}")).collect();
            fields[3] = id.to_owned();
            fields[69] = last.to_owned();
            fields
        };
        for (line, fields) in [row("a", "x"), row("b", "x"), row("a", "y")]
            .iter()
            .enumerate()
        {
            table
                .push_row(line + 2, fields.iter().map(String::as_str), "f")
                .unwrap();
        }
        let mut split = CsvFields::new(vec!["a".into(), "b".into(), "id".into()], 1);
        split.push_row(2, ["1", "23", "p"], "f").unwrap();
        split.push_row(3, ["12", "3", "q"], "f").unwrap();
        let digest = |row: CsvRow<'_>, skip: usize| {
            let mut state = DefaultHasher::new();
            row.hash_without(Some(skip), &mut state);
            state.finish()
        };
        assert_eq!(digest(table.row(0), 3), digest(table.row(1), 3));
        assert_ne!(digest(table.row(0), 3), digest(table.row(2), 3));
        assert_ne!(digest(table.row(0), 4), digest(table.row(1), 4));
        assert_ne!(digest(split.row(0), 2), digest(split.row(1), 2));
    }

    #[test]
    fn rows_give_back_their_fields_and_lines() {
        let mut table = CsvFields::new(vec!["a".into(), "b".into()], 1);
        table.push_row(2, ["", "x"], "f").unwrap();
        table.push_row(4, ["äö", ""], "f").unwrap();
        let error = table.push_row(5, ["1"], "f").unwrap_err().to_string();
        assert!(error.starts_with("f:5: row has 1 fields"), "{error}");
        table.push_row(6, ["3", "4"], "f").unwrap();
        let rows: Vec<(usize, Vec<&str>)> = table
            .rows()
            .map(|r| (r.line, r.fields().collect()))
            .collect();
        assert_eq!(
            rows,
            [(2, vec!["", "x"]), (4, vec!["äö", ""]), (6, vec!["3", "4"])]
        );
        assert_eq!(&table.row(1)[0], "äö");
        let records = table.into_table().records;
        assert_eq!(records[2], (6, vec!["3".to_string(), "4".to_string()]));
    }
}
