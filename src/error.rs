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
    /// A configuration vector has the wrong size.
    #[error("configuration has {got} values but the robot has {expected} independent joints")]
    ConfigurationSize {
        /// Number of independent joints of the tree.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
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
}
