//! Workflows: one library call per job of the command line, `XxxConfig` (plain data, `Default`
//! = the CLI's defaults) → `xxx(&config)` (computes everything, writes nothing) → an outcome
//! with the notes the CLI prints, the JSON and text it shows, and `write(out)` for its files.
//! See docs/workflows.md.

pub mod check;
pub mod checker;
pub mod checks;
pub mod plan;
pub mod simulate;
pub mod source;

use serde::Serialize;

/// How much a [`Note`] matters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NoteLevel {
    /// Worth knowing.
    Note,
    /// Probably not what the user meant; the job went on.
    Warning,
    /// Something failed; the job went on where it could.
    Error,
}

/// One message the CLI prints on stderr (`treecal: <level>: <text>`), in order.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Note {
    /// How much it matters.
    pub level: NoteLevel,
    /// The message.
    pub text: String,
}

impl Note {
    /// A note.
    pub fn note(text: impl Into<String>) -> Self {
        Self {
            level: NoteLevel::Note,
            text: text.into(),
        }
    }

    /// A warning.
    pub fn warning(text: impl Into<String>) -> Self {
        Self {
            level: NoteLevel::Warning,
            text: text.into(),
        }
    }
}

impl std::fmt::Display for Note {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let level = match self.level {
            NoteLevel::Note => "note",
            NoteLevel::Warning => "warning",
            NoteLevel::Error => "error",
        };
        write!(f, "{level}: {}", self.text)
    }
}

/// How far a long job is: `done` of `total` `unit` (e.g. 40 of 100 trials), for a progress
/// bar or a log line. `stage` names the part of a job with several (a planning stage).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress<'a> {
    /// The part of the job, if it has several.
    pub stage: Option<&'a str>,
    /// Units done.
    pub done: usize,
    /// Units in all.
    pub total: usize,
    /// What is counted (`trials`, `candidates`).
    pub unit: &'a str,
}

/// A progress callback; called from worker threads.
pub type ProgressFn<'a> = &'a (dyn Fn(Progress<'_>) + Sync);

/// The callback that shows nothing.
pub fn no_progress(_: Progress<'_>) {}
