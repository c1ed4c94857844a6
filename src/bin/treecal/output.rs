//! Standard output and standard error as Unix tools use them: a reader that stops early
//! (`treecal inspect | head -1`) ends the output quietly instead of a panic, and a closed or
//! full standard error never stops a run.

use std::io::Write;
use treecal::{Error, Result};

/// Prints `text` on standard output. A closed pipe is not an error (the reader has what it
/// wanted); any other failure (a full disk behind a redirection) is.
pub fn print(text: &str) -> Result<()> {
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
    {
        Err(error) if error.kind() != std::io::ErrorKind::BrokenPipe => Err(Error::Io {
            path: "standard output".into(),
            source: error,
        }),
        _ => Ok(()),
    }
}

/// Prints `treecal: {text}` on standard error; failures are ignored (there is nowhere left to
/// report them).
pub fn note(text: impl std::fmt::Display) {
    let _ = writeln!(std::io::stderr().lock(), "treecal: {text}");
}
