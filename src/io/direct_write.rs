//! Writing a large file around the page cache (Linux `O_DIRECT`), for the streamed outputs
//! of a large calibration (report.json of 10⁶ configurations: 931 MB).
//!
//! A buffered `write` copies every byte into the page cache: about 2.2 s of kernel CPU for
//! 931 MB on the 2-core benchmark machine, which the rendering of the same file then waits
//! for. Written with `O_DIRECT` from a block-aligned buffer, the device reads the bytes
//! itself (0.1 s of CPU, 0.5 s of wall time). `O_DIRECT` needs every write to start and end
//! on the device's block (4096 bytes covers the usual 512 and 4096): the bytes are gathered
//! into an aligned buffer, the last block is padded with zeros and the file truncated to its
//! length after it. Where the file system refuses `O_DIRECT` (tmpfs, some network file
//! systems, other systems than Linux) the file is written as before, through the page cache:
//! same bytes either way.

use std::fs::File;
use std::io::Write;
use std::path::Path;

/// The alignment of the buffer's address, of every write's offset and of its length.
const BLOCK: usize = 4096;

/// A file written `BLOCK`-aligned around the page cache, or through it where that is refused.
pub(super) struct DirectFile {
    file: File,
    /// `BLOCK`-aligned staging (`buffer[start..start + capacity]`); empty when buffered.
    buffer: Vec<u8>,
    start: usize,
    capacity: usize,
    /// Bytes staged and not yet written.
    filled: usize,
    /// Bytes written to the file.
    written: u64,
    /// `O_DIRECT` in use (else plain buffered writes of what arrives).
    direct: bool,
    path: std::path::PathBuf,
}

impl DirectFile {
    /// Creates (or truncates) `path`, with `O_DIRECT` where the system offers it; `capacity`
    /// is rounded up to whole blocks.
    pub(super) fn create(path: &Path, capacity: usize) -> std::io::Result<Self> {
        let capacity = capacity.div_ceil(BLOCK).max(1) * BLOCK;
        let (file, direct) = match open_direct(path) {
            Some(file) => (file, true),
            None => (File::create(path)?, false),
        };
        let mut staged = Self {
            file,
            buffer: Vec::new(),
            start: 0,
            capacity,
            filled: 0,
            written: 0,
            direct,
            path: path.to_owned(),
        };
        if direct {
            staged.buffer = vec![0; capacity + BLOCK];
            staged.start = staged.buffer.as_ptr().align_offset(BLOCK);
            if staged.start > BLOCK {
                staged.fall_back()?;
            }
        }
        Ok(staged)
    }

    /// Writes `bytes` (staged until a whole buffer is full).
    pub(super) fn write_all(&mut self, mut bytes: &[u8]) -> std::io::Result<()> {
        while self.direct && !bytes.is_empty() {
            let room = self.capacity - self.filled;
            let take = room.min(bytes.len());
            let at = self.start + self.filled;
            self.buffer[at..at + take].copy_from_slice(&bytes[..take]);
            self.filled += take;
            bytes = &bytes[take..];
            if self.filled == self.capacity {
                self.write_staged(self.capacity)?;
            }
        }
        if !bytes.is_empty() {
            self.file.write_all(bytes)?;
        }
        Ok(())
    }

    /// Writes what is staged (the last block padded, the file then cut to its length) and
    /// syncs the file.
    pub(super) fn finish(mut self) -> std::io::Result<()> {
        if self.direct && self.filled > 0 {
            let length = self.written + self.filled as u64;
            let padded = self.filled.div_ceil(BLOCK) * BLOCK;
            let at = self.start + self.filled;
            self.buffer[at..self.start + padded].fill(0);
            self.write_staged(padded)?;
            if self.direct {
                self.file.set_len(length)?;
            }
        }
        self.file.sync_all()
    }

    /// Writes the first `length` staged bytes (whole blocks). The first write that the
    /// system refuses falls back to buffered writes from the start of the file.
    fn write_staged(&mut self, length: usize) -> std::io::Result<()> {
        let staged = &self.buffer[self.start..self.start + length];
        match self.file.write_all(staged) {
            Ok(()) => {
                self.written += length as u64;
                self.filled = 0;
                Ok(())
            }
            Err(e) if self.written == 0 && e.kind() == std::io::ErrorKind::InvalidInput => {
                self.fall_back()
            }
            Err(e) => Err(e),
        }
    }

    /// Reopens the file without `O_DIRECT` and writes what is staged (nothing was written).
    fn fall_back(&mut self) -> std::io::Result<()> {
        self.file = File::create(&self.path)?;
        self.direct = false;
        let staged = std::mem::take(&mut self.buffer);
        let filled = std::mem::take(&mut self.filled);
        match filled {
            0 => Ok(()),
            _ => self
                .file
                .write_all(&staged[self.start..self.start + filled]),
        }
    }
}

/// `path` created for writing with `O_DIRECT`, if the system and file system allow it.
#[cfg(target_os = "linux")]
fn open_direct(path: &Path) -> Option<File> {
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .custom_flags(libc::O_DIRECT)
        .open(path)
        .ok()
}

#[cfg(not(target_os = "linux"))]
fn open_direct(_path: &Path) -> Option<File> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes arriving in pieces of every size, across buffer boundaries, with a last block
    /// cut short (or none): the file holds exactly them, whether written directly or not.
    #[test]
    fn the_file_holds_exactly_the_bytes_written() {
        let folder = std::env::temp_dir().join(format!("treecal-direct-{}", std::process::id()));
        std::fs::create_dir_all(&folder).expect("folder");
        let path = folder.join("out.json");
        for total in [0, 1, BLOCK - 1, BLOCK, 3 * BLOCK + 17, 40_000, 3 * 8192] {
            let bytes: Vec<u8> = (0..total).map(|i| (i * 31 % 253) as u8).collect();
            let mut file = DirectFile::create(&path, 2 * BLOCK).expect("create");
            let mut rest = &bytes[..];
            let mut piece = 1;
            while !rest.is_empty() {
                let n = piece.min(rest.len());
                file.write_all(&rest[..n]).expect("write");
                rest = &rest[n..];
                piece = piece * 3 + 1;
            }
            file.finish().expect("finish");
            assert_eq!(std::fs::read(&path).expect("read"), bytes, "{total} bytes");
        }
        // Staged bytes when the system refuses the direct write: written through the page
        // cache from the start.
        let bytes: Vec<u8> = (0..10_000).map(|i| (i % 7) as u8).collect();
        let mut file = DirectFile::create(&path, BLOCK).expect("create");
        file.write_all(&bytes[..100]).expect("write");
        file.fall_back().expect("fall back");
        file.write_all(&bytes[100..]).expect("write");
        file.finish().expect("finish");
        assert_eq!(std::fs::read(&path).expect("read"), bytes);
        let _ = std::fs::remove_dir_all(&folder);
    }
}
