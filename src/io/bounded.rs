//! The one reader of every file treecal opens (URDF, CSV, YAML, meshes): regular files only,
//! each kind with its size limit ([`crate::limits`]), checked before anything is allocated or
//! parsed.
//!
//! A FIFO, a device such as `/dev/zero` or a folder is refused with an error naming the file
//! (a FIFO would block the command until someone writes to it, `/dev/zero` would be read until
//! memory runs out); a file larger than its limit is refused from its size alone, and a file
//! that grows while it is read is cut off one byte past the limit.

use crate::error::{Error, Result};
use std::io::Read;
use std::path::Path;

/// The bytes of the regular file `path`, at most `max_bytes` of them (else an error naming
/// the file, its size and the limit).
pub fn read_bytes(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    let (file, size) = open_regular(path, max_bytes)?;
    // The size can change between the check and the read.
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|source| Error::Io {
            path: path.to_owned(),
            source,
        })?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_big(path, bytes.len() as u64, max_bytes));
    }
    Ok(bytes)
}

/// The regular file `path` opened for reading, and its size, at most `max_bytes` (else the
/// errors of [`read_bytes`]). A reader must still stop one byte past `max_bytes`: the file
/// can grow after the check.
pub fn open_regular(path: &Path, max_bytes: u64) -> Result<(std::fs::File, u64)> {
    let io = |source| Error::Io {
        path: path.to_owned(),
        source,
    };
    // Checked before opening: opening a FIFO for reading blocks until a writer appears.
    ensure_regular(path, &std::fs::metadata(path).map_err(io)?)?;
    let file = std::fs::File::open(path).map_err(io)?;
    // And again on what was opened, in case the name was replaced in between.
    let metadata = file.metadata().map_err(io)?;
    ensure_regular(path, &metadata)?;
    let size = metadata.len();
    if size > max_bytes {
        return Err(too_big(path, size, max_bytes));
    }
    Ok((file, size))
}

/// The error of a file of `size` bytes, more than `max_bytes`.
fn too_big(path: &Path, size: u64, max_bytes: u64) -> Error {
    Error::InvalidData {
        origin: path.display().to_string(),
        message: format!(
            "the file has {size} bytes, more than the limit of {max_bytes} for this kind of \
             file (docs/file-formats.md, \"Limits\")"
        ),
    }
}

/// The text of the regular file `path`, at most `max_bytes` long; see [`read_bytes`]. UTF-8,
/// or UTF-16 with its byte-order mark (what a spreadsheet's "Unicode text" export writes). A
/// leading UTF-8 byte-order mark is dropped (spreadsheet programs write one), so that it hides
/// no first-line comment or key.
pub fn read_text(path: &Path, max_bytes: u64) -> Result<String> {
    let mut text = decode(read_bytes(path, max_bytes)?).map_err(|message| Error::Io {
        path: path.to_owned(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, message),
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// UTF-8 bytes, or UTF-16 after a byte-order mark, as text; else what the bytes are and how
/// to save them.
fn decode(bytes: Vec<u8>) -> std::result::Result<String, String> {
    let utf16 = |rest: &[u8], unit: fn([u8; 2]) -> u16| {
        let units: Vec<u16> = rest
            .chunks(2)
            .map(|c| unit([c[0], *c.get(1).unwrap_or(&0)]))
            .collect();
        String::from_utf16(&units).map_err(|e| format!("not valid UTF-16 text ({e})"))
    };
    match bytes.as_slice() {
        [0xFF, 0xFE, rest @ ..] => utf16(rest, u16::from_le_bytes),
        [0xFE, 0xFF, rest @ ..] => utf16(rest, u16::from_be_bytes),
        _ => {
            const SAVE: &str = "save it as UTF-8 text (a spreadsheet's \"CSV UTF-8\")";
            let text = String::from_utf8(bytes)
                .map_err(|e| format!("not UTF-8 text ({}); {SAVE}", e.utf8_error()))?;
            // Text files hold no NUL; UTF-16 without its mark is ASCII with a NUL in between.
            match text.find('\0') {
                Some(at) => Err(format!(
                    "a NUL byte at byte {at}: not UTF-8 text (UTF-16 without a byte-order mark?); {SAVE}"
                )),
                None => Ok(text),
            }
        }
    }
}

fn ensure_regular(path: &Path, metadata: &std::fs::Metadata) -> Result<()> {
    if metadata.is_file() {
        return Ok(());
    }
    let what = if metadata.is_dir() {
        "a folder"
    } else {
        "not a regular file (a pipe, socket or device)"
    };
    Err(Error::InvalidData {
        origin: path.display().to_string(),
        message: format!("is {what}; treecal reads only regular files: give a file's path"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_devices_folders_and_large_files() {
        let dir = tempfile::tempdir().unwrap();
        let folder = read_text(dir.path(), 100).unwrap_err().to_string();
        assert!(folder.contains("is a folder"), "{folder}");
        if Path::new("/dev/zero").exists() {
            let zero = read_bytes(Path::new("/dev/zero"), 100)
                .unwrap_err()
                .to_string();
            assert!(
                zero.starts_with("/dev/zero: is not a regular file"),
                "{zero}"
            );
        }
        let file = dir.path().join("f.yaml");
        std::fs::write(&file, "\u{feff}# units: length=mm\nabc").unwrap();
        assert_eq!(read_text(&file, 100).unwrap(), "# units: length=mm\nabc");
        let big = read_text(&file, 10).unwrap_err().to_string();
        // UTF-16 with its byte-order mark, either order, reads as the UTF-8 text.
        for (bom, unit) in [
            ([0xFF, 0xFE], u16::to_le_bytes as fn(u16) -> [u8; 2]),
            ([0xFE, 0xFF], u16::to_be_bytes),
        ] {
            let mut bytes = bom.to_vec();
            bytes.extend("id,x\n1,2\n".encode_utf16().flat_map(unit));
            std::fs::write(&file, bytes).unwrap();
            assert_eq!(read_text(&file, 100).unwrap(), "id,x\n1,2\n");
        }
        let wide: Vec<u8> = "id,x\n1,2\n"
            .encode_utf16()
            .flat_map(u16::to_le_bytes)
            .collect();
        std::fs::write(&file, wide).unwrap();
        let error = read_text(&file, 100).unwrap_err().to_string();
        assert!(
            error.contains("UTF-16 without a byte-order mark?") && error.contains("CSV UTF-8"),
            "{error}"
        );
        assert!(big.contains("more than the limit of 10"), "{big}");
    }
}
