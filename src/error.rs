//! The one error type of the library.

use std::path::PathBuf;

/// Everything that can go wrong in treecal, with the place it went wrong.
///
/// Messages are lower-case sentences that name the file, element or parameter and, where
/// there is one, what to do about it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The URDF is not well-formed XML or not a URDF that urdf-rs understands.
    #[error("{origin}: not a readable URDF: {message}")]
    UrdfParse {
        /// The file (or `<string>`).
        origin: String,
        /// The parser's message.
        message: String,
    },
    /// The URDF parses but describes something treecal cannot use.
    #[error("{origin}: {message}")]
    InvalidRobot {
        /// The file (or `<string>`), with a line number where known.
        origin: String,
        /// What is wrong and with which element.
        message: String,
    },
    /// A link name was given (on the command line or in a file) that the robot does not have.
    #[error("unknown link '{name}'{hint}")]
    UnknownLink {
        /// The name as given.
        name: String,
        /// A hint such as "; did you mean 'left_tool'?".
        hint: String,
    },
    /// A joint name was given that the robot does not have.
    #[error("unknown joint '{name}'{hint}")]
    UnknownJoint {
        /// The name as given.
        name: String,
        /// A hint such as "; did you mean 'left_joint1'?".
        hint: String,
    },
    /// The branches of the robot could not be determined.
    #[error("branch detection: {0}")]
    Branches(String),
    /// An MCPC table or parameter set is inconsistent.
    #[error("{origin}: {message}")]
    InvalidTable {
        /// The file, with a line number where known.
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// A data file (CSV, YAML) has a bad value.
    #[error("{origin}: {message}")]
    InvalidData {
        /// The file with line and column where known, e.g. `joints.csv:4:left_joint2`.
        origin: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A setting (a field of a workflow config: a CLI flag, a Python keyword) has a bad value.
    ///
    /// `setting` is the setting's snake_case name (`length_unit`); the message names other
    /// settings in backticks (`` `joint_length_unit` ``) so that each front end can show its
    /// own spelling (`--joint-length-unit` on the command line, `joint_length_unit=` in Python).
    #[error("`{setting}`: {message}")]
    InvalidSetting {
        /// The setting's snake_case name, e.g. `length_unit`.
        setting: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// Something that cannot happen did: a bug in treecal, not in the input.
    #[error(
        "internal error (a bug in treecal; please report it with the command that caused it): {0}"
    )]
    Internal(String),
    /// A configuration vector has the wrong size.
    #[error("configuration has {got} values but the robot has {expected} independent joints")]
    ConfigurationSize {
        /// Number of independent joints of the tree.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
}

impl Error {
    /// An [`Error::InvalidSetting`] for `setting` (snake_case, e.g. `length_unit`).
    pub fn setting(setting: &str, message: impl Into<String>) -> Self {
        Error::InvalidSetting {
            setting: setting.to_owned(),
            message: message.into(),
        }
    }
}

/// `text` with each setting it names in backticks (`` `length_unit` ``) spelled as a front end
/// spells it: `spell` gives the front end's name (`--length-unit`, `length_unit`) or `None` for
/// text that is not one of its settings, which is left as it is.
pub fn name_settings(text: &str, spell: impl Fn(&str) -> Option<String>) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(start) = rest.find('`') {
        out.push_str(&rest[..start]);
        let after = &rest[start + 1..];
        let end = after
            .find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_'))
            .unwrap_or(after.len());
        let name = &after[..end];
        match spell(name).filter(|_| !name.is_empty() && after[end..].starts_with('`')) {
            Some(spelled) => {
                out.push_str(&spelled);
                rest = &after[end + 1..];
            }
            None => {
                out.push('`');
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// Shorthand for results of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Returns "; did you mean 'x'?" for the candidate closest to `name`, or "" when nothing is close.
pub(crate) fn did_you_mean<'a>(
    name: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> String {
    let best = candidates
        .into_iter()
        .map(|c| (edit_distance(name, c), c))
        .min_by_key(|(d, _)| *d);
    match best {
        Some((d, c)) if d <= (name.len() / 3).max(2) => format!("; did you mean '{c}'?"),
        _ => String::new(),
    }
}

/// The candidate closest to `name` (fewest edits; the first of equals), `None` if there are
/// none.
pub(crate) fn closest<'a>(
    name: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    candidates
        .into_iter()
        .min_by_key(|c| edit_distance(name, c))
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut previous: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut current = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let substitution = previous[j] + usize::from(ca != *cb);
            current[j + 1] = substitution.min(previous[j + 1] + 1).min(current[j] + 1);
        }
        previous = current;
    }
    previous[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggests_close_names_only() {
        let names = ["left_joint1", "left_joint2", "right_joint1"];
        assert_eq!(
            did_you_mean("left_jiont1", names),
            "; did you mean 'left_joint1'?"
        );
        assert_eq!(did_you_mean("completely_else", names), "");
    }

    #[test]
    fn settings_are_spelled_by_the_front_end() {
        let spell = |name: &str| (name == "length_unit").then(|| "--length-unit".to_owned());
        let error = Error::setting("length_unit", "'cm' is not a length unit; see `fit`");
        assert_eq!(
            name_settings(&error.to_string(), spell),
            "--length-unit: 'cm' is not a length unit; see `fit`"
        );
        assert_eq!(
            name_settings("give `length_unit` mm, `length_unit`, `", spell),
            "give --length-unit mm, --length-unit, `"
        );
        assert_eq!(name_settings("`length_unit", spell), "`length_unit");
    }
}
