//! A scan of CSV text before the csv crate builds any record: the column and field limits
//! ([`MAX_CSV_COLUMNS`], [`MAX_CSV_FIELD_BYTES`]) apply while reading, so that a header of
//! 100 MB of commas is refused at once instead of after the 4 GB its record would take.
//!
//! The scan follows csv-core's rules as far as they matter for counting: `#` at the start of a
//! record begins a comment line, a `"` at the start of a field quotes it (`""` inside is one
//! quote), and records end at line breaks outside quotes.

use crate::error::{Error, Result};
use crate::limits::{MAX_CSV_COLUMNS, MAX_CSV_FIELD_BYTES};

/// Fails, naming the line, if a record has more than [`MAX_CSV_COLUMNS`] fields or a field
/// more than [`MAX_CSV_FIELD_BYTES`] bytes.
pub(crate) fn check_csv_shape(text: &str, origin: &str) -> Result<()> {
    let fail = |line: usize, message: String| Error::InvalidData {
        origin: format!("{origin}:{line}"),
        message: format!("{message} (docs/file-formats.md, \"Limits\")"),
    };
    let bytes = text.as_bytes();
    let mut line = 1;
    let mut i = 0;
    while i < bytes.len() {
        // A record (or comment line) starts at `i`.
        let record_line = line;
        if bytes[i] == b'#' {
            while i < bytes.len() && bytes[i] != b'\n' && bytes[i] != b'\r' {
                i += 1;
            }
        }
        let mut fields = 1usize;
        let mut field_start = i;
        let mut at_field_start = true;
        let mut quoted = false;
        while i < bytes.len() {
            let b = bytes[i];
            if quoted {
                if b == b'"' {
                    if bytes.get(i + 1) == Some(&b'"') {
                        i += 1;
                    } else {
                        quoted = false;
                    }
                } else if b == b'\n' {
                    line += 1;
                }
            } else if b == b'"' && at_field_start {
                quoted = true;
            } else if b == b',' || b == b'\n' || b == b'\r' {
                if i - field_start > MAX_CSV_FIELD_BYTES {
                    return Err(fail(
                        record_line,
                        format!(
                            "field {fields} has {} bytes, more than the limit of \
                             {MAX_CSV_FIELD_BYTES}",
                            i - field_start
                        ),
                    ));
                }
                if b != b',' {
                    break;
                }
                fields += 1;
                if fields > MAX_CSV_COLUMNS {
                    return Err(fail(
                        record_line,
                        format!("the row has more than the limit of {MAX_CSV_COLUMNS} columns"),
                    ));
                }
                field_start = i + 1;
                at_field_start = true;
                i += 1;
                continue;
            }
            at_field_start = false;
            i += 1;
        }
        if i - field_start > MAX_CSV_FIELD_BYTES && i == bytes.len() {
            return Err(fail(
                record_line,
                format!("a field has more than the limit of {MAX_CSV_FIELD_BYTES} bytes"),
            ));
        }
        // The line break: `\r\n`, `\n` or a lone `\r`.
        if i < bytes.len() {
            if bytes[i] == b'\r' && bytes.get(i + 1) == Some(&b'\n') {
                i += 1;
            }
            i += 1;
            line += 1;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_columns_and_field_bytes_outside_quotes_and_comments() {
        let good = "# a, b, c\nid,\"x,y\",z\r\n1,\"a\"\"b\n,c\",3\n";
        assert!(check_csv_shape(good, "f").is_ok());
        let wide = format!("id{}\n", ",".repeat(MAX_CSV_COLUMNS));
        let error = check_csv_shape(&wide, "f").unwrap_err().to_string();
        assert!(error.starts_with("f:1: the row has more than"), "{error}");
        let comment = format!("# {}\nid\n", ",".repeat(MAX_CSV_COLUMNS));
        assert!(check_csv_shape(&comment, "f").is_ok());
        let long = format!("id\n1\n{}\n", "9".repeat(MAX_CSV_FIELD_BYTES + 1));
        let error = check_csv_shape(&long, "f").unwrap_err().to_string();
        assert!(error.starts_with("f:3: "), "{error}");
        let long_quoted = format!("id,x\n\"{}\",1\n", "9".repeat(MAX_CSV_FIELD_BYTES + 1));
        assert!(check_csv_shape(&long_quoted, "f").is_err());
    }
}
