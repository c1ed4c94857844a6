//! Standard output and standard error as Unix tools use them: a reader that stops early
//! (`treecal inspect | head -1`) ends the output quietly instead of a panic, and a closed or
//! full standard error never stops a run.

use std::io::Write;
use treecal::{Error, Result};

/// Prints `text` on standard output. A closed pipe is not an error (the reader has what it
/// wanted); any other failure (a full disk behind a redirection) is.
pub fn print(text: &str) -> Result<()> {
    let text = crate::settings::with_flags(text);
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

/// Prints `treecal: {text}` on standard error, the settings it names spelled as flags;
/// failures are ignored (there is nowhere left to report them).
pub fn note(text: impl std::fmt::Display) {
    let text = crate::settings::with_flags(&text.to_string());
    let _ = writeln!(std::io::stderr().lock(), "treecal: {text}");
}
