//! What a workflow has to tell its user besides its result: the lines the CLI prints on
//! stderr (`treecal: warning: …`), kept in the outcome because the library prints nothing.

use crate::calibration::{Finding, Status};
use serde::Serialize;

/// How serious a [`Note`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum NoteLevel {
    /// Information.
    Note,
    /// Accepted, but look at it.
    Warning,
    /// The result must not be used (a failed verdict's reasons).
    Error,
}

impl NoteLevel {
    /// `note`, `warning` or `error`, as the CLI labels its lines.
    pub fn as_str(self) -> &'static str {
        match self {
            NoteLevel::Note => "note",
            NoteLevel::Warning => "warning",
            NoteLevel::Error => "error",
        }
    }
}

/// One message of a workflow, in the order it arose.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Note {
    /// How serious it is.
    pub level: NoteLevel,
    /// The message, without the `treecal: level:` prefix.
    pub text: String,
}

impl Note {
    /// A note (level [`NoteLevel::Note`]).
    pub fn info(text: impl Into<String>) -> Self {
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

    /// An error (the result is still returned, e.g. with a failed verdict).
    pub fn error(text: impl Into<String>) -> Self {
        Self {
            level: NoteLevel::Error,
            text: text.into(),
        }
    }
}

/// `level: text`, as the CLI prints it after `treecal: `.
impl std::fmt::Display for Note {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.level.as_str(), self.text)
    }
}

/// A verdict's reason as the CLI prints it: `ok` findings are notes, `failed` ones errors.
impl From<&Finding> for Note {
    fn from(finding: &Finding) -> Self {
        let level = match finding.status {
            Status::Ok => NoteLevel::Note,
            Status::Warning => NoteLevel::Warning,
            Status::Failed => NoteLevel::Error,
        };
        Self {
            level,
            text: finding.message.clone(),
        }
    }
}
